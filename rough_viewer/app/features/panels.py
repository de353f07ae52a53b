"""The Panels tab: histogram, semivariogram, Table 1 and the whole-face trend of the
map on screen.

The panels are the report's figures (:mod:`rough_viewer.visual.grid`) fed with core
results (:func:`rough_viewer.grid.summary.histogram`, :func:`summarise`,
:func:`rough_viewer.grid.variogram.semivariogram`); nothing is recomputed here. The
whole-face trend against grid size is :func:`rough_viewer.grid.scales.face_scales`
drawn by :func:`rough_viewer.visual.scales.face_scales_figure`.

After every map the tab queues a :class:`PanelsJob` (lane ``panels``, cancelled by the
next map), once the features that follow the map quickly have queued theirs, so a
slow semivariogram never delays the map or the zones. It is progressive, every
stage a place where a newer map stops it:

1. the histogram and Table 1 (one pass over the cells), shown at once;
2. a first semivariogram within :data:`FIRST_BUDGET` seconds of the cost model
   (exact where that is cheap, else a sampled estimate with error bars, the same
   pairs for all its maps: :func:`rough_viewer.grid.variogram.semivariograms`);
3. the trend across the preset grids (when the axis, minimum points or threshold
   changed), redrawn as each preset's grid arrives;
4. when the first semivariogram was a sample, the refined one within
   :data:`REFINE_BUDGET` seconds (exact if that fits, else a larger sample).

The grid's panels count as shown (``session.panel_key``) once the last of them
is; a job stopped before that is redone, quick stages included, by the next map.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import plotly.graph_objects as go
import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.host import Host
from rough_viewer.app.layout import PLOTLY_CONFIG, empty_figure
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.scales import face_scales
from rough_viewer.grid.summary import histogram, normalise, summarise
from rough_viewer.grid.threshold import map_threshold_advice
from rough_viewer.grid.variogram import Semivariogram, semivariograms
from rough_viewer.visual.grid import histogram_figure, summary_table_figure, variogram_figure
from rough_viewer.visual.scales import face_scales_figure
from rough_viewer.vocabulary import HISTOGRAM_BIN, MAPS, InputError, MapName, ProgressFn

#: Cost-model seconds (all maps of the panel together) of the first semivariogram
#: and of its refinement (:func:`rough_viewer.grid.variogram.semivariograms`'s
#: ``time_budget``): the first is exact only where that is cheap.
FIRST_BUDGET = 0.3
REFINE_BUDGET = 3.0

#: Names of the analysis panels a saved view lists (the app draws all of them).
PANEL_NAMES: tuple[str, ...] = ("histogram", "variogram", "summary")


@dataclass(frozen=True)
class Distribution:
    """The histogram and Table 1 summary figures of one grid result and model."""

    histogram: go.Figure
    summary: go.Figure


def histogram_maps(model: MapName) -> tuple[MapName, ...]:
    """Maps in the histogram: ODR and OLS (2011 Fig. 3), plus the current one."""
    base: tuple[MapName, ...] = ("odr", "ols")
    return base + (() if model in base else (model,))


def variogram_maps(model: MapName) -> tuple[MapName, ...]:
    """Maps in the semivariogram: the current one, ODR, OLS and e_ols (2011 Fig. 4)."""
    others: tuple[MapName, ...] = ("odr", "ols", "e_ols")
    return (model,) + tuple(m for m in others if m != model)


def _figure_kw(result: GridRoughness, unit: str = "m") -> dict[str, Any]:
    return dict(grid_size=result.grid.cell_size, axis=result.axis,
                n_points=result.n_points_total, unit=unit)


def distribution_figures(result: GridRoughness, settings: MapSettings, *,
                         unit: str = "m") -> Distribution:
    """Histogram of normalised roughness (0.05 bins, with the binary threshold and
    each map's suggested threshold) and the summary table (Table 1), outliers left
    out unless ``settings.keep_outliers``; lengths in ``unit`` (the cloud's),
    roughness in its roughness unit."""
    kw = _figure_kw(result, unit)
    summary = summary_table_figure(
        {m: summarise(result, m, keep_outliers=settings.keep_outliers) for m in MAPS}, **kw)
    return Distribution(histogram_of(result, settings, unit=unit), summary)


def histogram_of(result: GridRoughness, settings: MapSettings, *, unit: str = "m") -> go.Figure:
    """The histogram panel: normalised roughness of ODR, OLS and the shown map (0.05
    bins), the binary threshold and each map's suggested threshold as lines."""
    keep = settings.keep_outliers
    maps = histogram_maps(settings.model)
    return histogram_figure(
        {m: histogram(normalise(analysed_values(result, m, keep_outliers=keep)), HISTOGRAM_BIN)
         for m in maps}, threshold=settings.threshold,
        suggestions={m: map_threshold_advice(result, m, settings.threshold,
                                             keep_outliers=keep).suggested for m in maps},
        **_figure_kw(result, unit))




def variograms(
    result: GridRoughness,
    maps: tuple[MapName, ...],
    *,
    is_stale: Callable[[], bool] = lambda: False,
    progress: ProgressFn | None = None,
    keep_outliers: bool = False,
    time_budget: float | None = None,
) -> dict[str, Semivariogram] | None:
    """Semivariogram of each map of ``result`` (3-D cell lags, bin width = cell
    size), all within ``time_budget`` seconds of the cost model (exact where that
    fits, else one sample of pairs for all of them), or None if ``is_stale()``
    turned True first. ``progress`` is passed on (called between FFT blocks and
    sample chunks; an exception from it stops the computation). Raises InputError
    when a semivariogram cannot fit in memory."""
    values = {str(m): analysed_values(result, m, keep_outliers=keep_outliers) for m in maps}
    if is_stale():
        return None
    return semivariograms(result.ijk, values, result.grid.cell_size, time_budget=time_budget,
                          progress=progress)


def variogram_figure_of(
    result: GridRoughness,
    settings: MapSettings,
    *,
    is_stale: Callable[[], bool] = lambda: False,
    progress: ProgressFn | None = None,
    unit: str = "m",
    time_budget: float | None = None,
) -> tuple[go.Figure, bool] | None:
    """The semivariogram panel and whether it is exact (False: a sampled estimate),
    or None if ``is_stale()`` turned True on the way."""
    vgs = variograms(result, variogram_maps(settings.model), is_stale=is_stale,
                     progress=progress, keep_outliers=settings.keep_outliers,
                     time_budget=time_budget)
    if vgs is None:
        return None
    exact = all(vg.exact for vg in vgs.values())
    return variogram_figure(vgs, **_figure_kw(result, unit)), exact


def face_scales_figure_of(results: Sequence[GridRoughness], *, threshold: float,
                          unit: str = "m", keep_outliers: bool = False) -> go.Figure:
    """The whole face against grid size (2011 Table 1 as a picture): mean roughness
    and the share of binary cells of ODR, OLS and hybrid on each grid of ``results``
    (the presets: nested, one axis and minimum points; outliers left out unless kept)."""
    return face_scales_figure(face_scales(results, threshold=threshold,
                                          keep_outliers=keep_outliers), unit=unit)


# ----------------------------------------------------------------------------- the tab


@dataclass(eq=False)
class PanelsFeature:
    """The Panels tab's plots."""

    host: Host
    histogram: viser.GuiPlotlyHandle
    variogram: viser.GuiPlotlyHandle
    summary: viser.GuiPlotlyHandle
    face_scales: viser.GuiPlotlyHandle
    """Whole-face mean roughness and binary share against grid size."""
    binding: Binding = dataclasses.field(default_factory=Binding)

    def panel_key(self, settings: MapSettings) -> tuple[object, ...]:
        """What the grid's panels (histogram, semivariogram, Table 1) depend on."""
        return (settings.grid_key, settings.model, settings.keep_outliers,
                self.host.options.variogram)

    def after_render(self) -> None:
        """A map was coloured: queue its panels unless they are on screen (worker)."""
        shown, session = self.host.session.shown, self.host.session
        if shown.result is None:
            return
        s = shown.settings
        if self.panel_key(s) != session.panel_key or face_key(s) != session.face_key:
            record = self.host.last_render()
            self.host.submit(PanelsJob(self, s, shown.result, record))

    # ------------------------------------------------------------------ saved views
    def snapshot(self) -> dict[str, Any]:
        return {"panels": PANEL_NAMES if self.host.options.variogram else PANEL_NAMES[::2]}

    def restore(self, view: object) -> None:
        return None  # the tab always draws every panel

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        return {"histogram": self.histogram,
                "variogram": self.variogram,
                "summary": self.summary,
                "face_scales": self.face_scales}


def face_key(settings: MapSettings) -> tuple[object, ...]:
    """What the whole-face trend against the preset grids depends on."""
    return (settings.axis, settings.min_points, settings.threshold, settings.keep_outliers)


@dataclass(frozen=True)
class PanelsJob(Job[Host]):
    """Histogram, summary table and semivariogram of the shown grid and model, and
    the whole face's roughness against the preset grid sizes."""

    p: PanelsFeature = dataclasses.field(compare=False)
    settings: MapSettings
    result: GridRoughness = dataclasses.field(compare=False)
    record: dict[str, object] = dataclasses.field(compare=False)
    """The map's timing record (gets ``panels_s``)."""
    lane: ClassVar[str] = "panels"

    @property
    def title(self) -> str:
        return f"panels of grid {self.settings.cell_size:g} m"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        p, session, t0 = self.p, ctx.session, time.perf_counter()
        if session.shown.result is not self.result:
            return
        s, key = self.settings, self.p.panel_key(self.settings)
        exact = True
        loaded = session.shown.loaded
        if key != session.panel_key:
            unit = loaded.units.unit  # made once for every analysis showing this grid
            dist = loaded.derived(("distribution", s, unit),
                                  lambda: distribution_figures(self.result, s, unit=unit))
            assert dist is not None
            p.binding.show_figure(p.histogram, dist.histogram)
            p.binding.show_figure(p.summary, dist.summary)
            yield "distribution"
            if ctx.options.variogram:
                exact = self._variogram(ctx, run, FIRST_BUDGET)
                yield "variogram" if exact else "variogram estimate"
        if face_key(s) != session.face_key and session.shown.loaded.presets:
            yield from self._trend(ctx, run, key)
        if not exact:
            self._variogram(ctx, run, REFINE_BUDGET)
            yield "variogram"
        session.panel_key = key
        self.record["panels_s"] = time.perf_counter() - t0

    def _variogram(self, ctx: Host, run: Run, budget: float) -> bool:
        """Compute and show the semivariogram panel within ``budget`` seconds of the
        cost model; True when it is exact, or cannot be had (nothing to refine)."""
        p, loaded, s = self.p, ctx.session.shown.loaded, self.settings
        unit = loaded.units.unit
        try:  # made once for every analysis showing this grid (a classroom's tabs)
            got = loaded.derived(
                ("variogram", s.grid_key, s.model, s.keep_outliers, unit, budget),
                lambda: variogram_figure_of(self.result, s, is_stale=lambda: run.cancelled,
                                            progress=run.progress(), unit=unit,
                                            time_budget=budget))
        except (InputError, MemoryError) as exc:
            what = "not enough memory" if isinstance(exc, MemoryError) else str(exc)
            ctx.show_error(f"semivariogram of grid {loaded.units.size_text(self.settings.cell_size)}"
                           f": {what}", kept="The map and the other panels are shown.")
            return True
        if got is None:  # cancelled before it started
            run.check()
            return True
        p.binding.show_figure(p.variogram, got[0])
        return got[1]

    def _trend(self, ctx: Host, run: Run, key: tuple[object, ...]) -> Iterator[str]:
        """The whole face against the preset grids, redrawn as each grid arrives
        (cached after prefetching; each stops if cancelled)."""
        p, session, s = self.p, ctx.session, self.settings
        loaded = session.shown.loaded
        unit = loaded.units.unit
        results, presets = [], loaded.presets or ()
        for g in presets:
            results.append(loaded.cell_result(s.with_(cell_size=g), progress=run.progress()))
            if len(results) > 1 or len(presets) == 1:  # a line once it has two
                p.binding.show_figure(p.face_scales, face_scales_figure_of(
                    results, threshold=s.threshold, unit=unit, keep_outliers=s.keep_outliers))
            yield f"grid {g:g}"
        session.face_key = face_key(s)
        yield "grid sizes"
        if key == session.panel_key:  # the threshold's line moved
            p.binding.show_figure(p.histogram, histogram_of(self.result, s, unit=unit))
            yield "histogram"


def mount(host: Host) -> PanelsFeature:
    """The Panels tab; its job follows every map."""
    gui = host.gui
    with host.tab("Panels"):
        p = PanelsFeature(
            host=host,
            histogram=gui.add_plotly(empty_figure("histogram"), config=PLOTLY_CONFIG,
                                     aspect=0.85),
            variogram=gui.add_plotly(empty_figure("semivariogram"), config=PLOTLY_CONFIG,
                                     aspect=0.81),
            summary=gui.add_plotly(empty_figure("summary"), config=PLOTLY_CONFIG, aspect=0.44),
            face_scales=gui.add_plotly(empty_figure("roughness against grid size"),
                                       config=PLOTLY_CONFIG, aspect=1.16),
        )
    host.on_render(p.after_render, late=True)
    return p
