"""The Panels tab: histogram, semivariogram, Table 1 and the whole-face trend of the
map on screen.

The panels are the report's figures (:mod:`rough_viewer.visual.grid`) fed with core
results (:func:`rough_viewer.grid.summary.histogram`, :func:`summarise`,
:func:`rough_viewer.grid.variogram.semivariogram`); nothing is recomputed here. The
whole-face trend against grid size is :func:`rough_viewer.grid.scales.face_scales`
drawn by :func:`rough_viewer.visual.scales.face_scales_figure`.

After every map the tab queues a :class:`PanelsJob` (lane ``panels``, cancelled by the
next map), once the features that follow the map quickly have queued theirs, so a
slow semivariogram never delays the map or the zones. It builds the trend across the
preset grids (when the axis, minimum points or threshold changed), the histogram and
Table 1 (fast), then the semivariogram (seconds, or refused for memory, on fine
grids), and shows the grid's panels together.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import plotly.graph_objects as go
import viser

from rough_viewer.app.features.map import MapFeature, empty_figure
from rough_viewer.app.host import Host
from rough_viewer.app.layout import PLOTLY_CONFIG, set_figure
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.scales import face_scales
from rough_viewer.grid.summary import histogram, normalise, summarise
from rough_viewer.grid.threshold import map_threshold_advice
from rough_viewer.grid.variogram import Semivariogram, semivariogram
from rough_viewer.visual.grid import histogram_figure, summary_table_figure, variogram_figure
from rough_viewer.visual.scales import face_scales_figure
from rough_viewer.vocabulary import HISTOGRAM_BIN, MAPS, InputError, MapName, ProgressFn

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
) -> dict[str, Semivariogram] | None:
    """Semivariogram of each map of ``result`` (3-D cell lags, bin width = cell size),
    or None if ``is_stale()`` turned True between maps (fine grids take seconds).
    ``progress`` is passed to each :func:`~rough_viewer.grid.variogram.semivariogram`
    (called between its blocks; an exception from it stops the computation inside a
    map). Raises InputError when a semivariogram cannot fit in memory."""
    g = result.grid.cell_size
    out: dict[str, Semivariogram] = {}
    for m in maps:
        if is_stale():
            return None
        out[m] = semivariogram(result.ijk, analysed_values(result, m, keep_outliers=keep_outliers),
                               g, progress=progress)
    return out


def variogram_figure_of(
    result: GridRoughness,
    settings: MapSettings,
    *,
    is_stale: Callable[[], bool] = lambda: False,
    progress: ProgressFn | None = None,
    unit: str = "m",
) -> go.Figure | None:
    """The semivariogram panel, or None if ``is_stale()`` turned True on the way."""
    vgs = variograms(result, variogram_maps(settings.model), is_stale=is_stale,
                     progress=progress, keep_outliers=settings.keep_outliers)
    return None if vgs is None else variogram_figure(vgs, **_figure_kw(result, unit))


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
    map: MapFeature
    histogram: viser.GuiPlotlyHandle
    variogram: viser.GuiPlotlyHandle
    summary: viser.GuiPlotlyHandle
    face_scales: viser.GuiPlotlyHandle
    """Whole-face mean roughness and binary share against grid size."""

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
            record = self.map.timings[-1] if self.map.timings else {}
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
        loaded = session.shown.loaded
        unit = loaded.units.unit
        s = self.settings
        if face_key(s) != session.face_key and loaded.presets:
            results = []
            for g in loaded.presets:  # cached after prefetching; each stops if cancelled
                results.append(loaded.cell_result(s.with_(cell_size=g), progress=run.progress()))
                yield f"grid {g:g}"
            trend = face_scales_figure_of(results, threshold=s.threshold, unit=unit,
                                          keep_outliers=s.keep_outliers)
            set_figure(p.face_scales, trend)
            session.face_key = face_key(s)
            yield "grid sizes"
            if p.panel_key(s) == session.panel_key:  # the threshold's line moved
                set_figure(p.histogram, histogram_of(self.result, s, unit=unit))
                yield "histogram"
        if p.panel_key(s) == session.panel_key:
            return  # only the trend changed (the binary threshold)
        dist = distribution_figures(self.result, s, unit=unit)
        yield "distribution"
        fig = None
        if ctx.options.variogram:
            try:
                fig = variogram_figure_of(self.result, s, is_stale=lambda: run.cancelled,
                                          progress=run.progress(), unit=unit)
            except (InputError, MemoryError) as exc:
                what = "not enough memory" if isinstance(exc, MemoryError) else str(exc)
                ctx.show_error(f"semivariogram of grid {loaded.units.size_text(s.cell_size)}: "
                               f"{what}", kept="The map and the other panels are shown.")
            else:
                if fig is None:  # cancelled between maps
                    run.check()
                    return
            yield "variogram"
        # the grid's panels change together, as the grid they describe
        set_figure(p.histogram, dist.histogram)
        set_figure(p.summary, dist.summary)
        if fig is not None:
            set_figure(p.variogram, fig)
        session.panel_key = p.panel_key(s)
        self.record["panels_s"] = time.perf_counter() - t0


def mount(host: Host) -> PanelsFeature:
    """The Panels tab; its job follows every map."""
    gui = host.gui
    with host.tab("Panels"):
        p = PanelsFeature(
            host=host, map=host.feature(MapFeature),
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
