"""Colour the map: :class:`RenderJob`, the render stages, the colour bar, the
status line and the notices; a saved view's map."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import numpy as np
import plotly.graph_objects as go

from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import Colouring, MapStats, by_cell, cell_colours, map_stats
from rough_viewer.app.features.map.binding import (
    BIG_CLOUD,
    MAX_MIN_POINTS,
    Changes,
    MapTab,
)
from rough_viewer.app.host import Host
from rough_viewer.app.markup import md
from rough_viewer.app.session import Shown
from rough_viewer.app.settings import (
    MAX_CELL_SIZE,
    MIN_CELL_SIZE,
    MODEL_LABELS,
    MapSettings,
    check_settings,
)
from rough_viewer.app.store import COARSE_ALONE_POINTS
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.outliers import outlier_text
from rough_viewer.grid.roughness import GridRoughness, exact_fit_text
from rough_viewer.lod.select import DEFAULT_BUDGET
from rough_viewer.report.view import Camera, View
from rough_viewer.visual.app import (
    category_legend_figure,
    colour_bar_figure,
    colour_scale_figure,
    panel_aspect,
)
from rough_viewer.visual.layers import ColourLayer
from rough_viewer.vocabulary import (
    COLOUR_LAYER_LABELS,
    TRUST_FIELDS,
    TRUST_LABELS,
    InputError,
)


def check_view_for_app(view: View, source: str) -> MapSettings:
    """The map settings of a saved view, refused (one line naming ``source``) where
    the Map tab's controls cannot take them."""
    where = f"view file {source}:"
    if not MIN_CELL_SIZE <= view.cell_size_m <= MAX_CELL_SIZE:
        raise InputError(f"{where} grid.cell_size_m {view.cell_size_m:g} is outside the "
                         f"app's range [{MIN_CELL_SIZE:g}, {MAX_CELL_SIZE:g}] m")
    if view.min_points > MAX_MIN_POINTS:
        raise InputError(f"{where} grid.min_points {view.min_points} is more than the app's "
                         f"{MAX_MIN_POINTS:,}")
    settings = settings_of_view(view)
    try:
        check_settings(settings)
    except InputError as exc:
        raise InputError(f"{where} {exc}") from None
    return settings


def settings_of_view(view: View) -> MapSettings:
    """The map settings a saved view asks for (grid, model, threshold, colours)."""
    c = view.colour
    return MapSettings(cell_size=float(view.cell_size_m), model=view.model, axis=view.axis,
                       min_points=int(view.min_points), display=c.mode,
                       threshold=float(view.threshold), colormap=c.colormap,
                       stretch=c.stretch, layer=c.layer)


# ----------------------------------------------------------------------------- render


@dataclass(frozen=True)
class RenderJob(Job[Host]):
    """Colour the map: with ``settings``, or with what the controls show once the
    controls that follow ``changes`` have moved (:meth:`MapBinding.settle`)."""

    m: MapTab = field(compare=False)
    settings: MapSettings | None = None
    changes: Changes = ()
    """(control, value) changed since the last render, oldest first."""
    lane: ClassVar[str] = "render"
    cancels: ClassVar[frozenset[str]] = frozenset({"panels"})

    @property
    def title(self) -> str:
        return "map" if self.settings is None else f"grid {self.settings.cell_size:g} m"

    def absorb(self, newer: Job[Host]) -> Job[Host] | None:
        if isinstance(newer, RenderJob):
            return merged(newer, self)
        return None

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        settings = resolve(self.m, self.settings, self.changes)
        if settings is None:
            return
        if self.settings is not None:
            self.m.binding.show(settings)
        yield from render_stages(self.m, run, settings)


def merged(newer: RenderJob, older: RenderJob) -> RenderJob:
    """``newer`` with the changes ``older`` carried before its own."""
    return replace(newer, changes=older.changes + newer.changes)


def resolve(m: MapTab, settings: MapSettings | None,
            changes: Changes) -> MapSettings | None:
    """``settings``, or the controls' settings once ``changes`` are in them and the
    controls that follow moved; None (with the error shown and the controls put
    back) when unusable."""
    if settings is not None:
        return settings
    m.binding.settle(changes)
    try:
        return m.binding.read()
    except InputError as exc:
        reject(m, str(exc))
        return None


def reject(m: MapTab, message: str) -> None:
    """Show an error and put the controls back to the shown map."""
    m.host.show_error(message)
    m.binding.show(m.host.session.shown.settings)


#: A grid not yet computed on at least this many points takes more than about 0.5 s
#: (the grid core: about 0.25 us per point on 2 cores): the map shows a coarse map
#: first (:func:`_coarse_first`) and says how far the chosen grid has come.
PREVIEW_POINTS = COARSE_ALONE_POINTS


def render_stages(m: MapTab, run: Run, settings: MapSettings, *,
                  keep_error: bool = False) -> Iterator[str]:
    """Check the settings, compute (or fetch) the grid, colour the points (by the
    roughness map or a colour layer), update the colour bar, status and notices,
    then tell the features that follow the map. ``keep_error``: leave an error shown
    by an earlier stage on screen.

    A grid that takes a while (not cached, :data:`PREVIEW_POINTS` or more points)
    comes coarse first: the first map of a cloud is coloured from its coarsest preset
    (stage ``preview``) while the chosen grid is computed; a grid change keeps the old
    colours meanwhile. The status line says which, with the chosen grid's progress."""
    host = m.host
    loaded = host.session.shown.loaded
    try:
        check_settings(settings)
        if settings.layer not in loaded.layers:
            loaded.layer(settings.layer)  # InputError: the cloud lacks it
        if settings.layer != "roughness" and settings.layer not in TRUST_FIELDS:
            loaded.layer(settings.layer)
    except InputError as exc:
        reject(m, str(exc))
        return
    yield "check"
    cached = loaded.is_cached(settings)
    waiting = None
    if not cached and loaded.n_total >= PREVIEW_POINTS:
        waiting = _coarse_first(m, run, loaded, settings)
        if waiting is not None and waiting.startswith(COARSE):
            yield "preview"
    t0 = time.perf_counter()
    result = _grid(m, run, loaded, settings, cached, waiting)
    if result is None:
        if waiting is not None:  # what is on the points stays the map shown
            _say_shown(m, coarse=waiting.startswith(COARSE))
        return
    yield "grid"
    stats = map_stats(result, settings)
    try:
        colouring = _colouring(loaded, settings, result, stats)
    except InputError as exc:
        reject(m, str(exc))
        return
    m.colouring = colouring
    if m.overlay is None:  # a feature that colours the points recolours them itself
        host.scene.colour_by(colouring)
    host.session.shown = Shown(loaded, settings, result, stats)
    loaded.mark_shown(settings, host.session)
    t_colours = time.perf_counter() - t0
    # the colour bar and status always go with the colours (no stage in between)
    if not keep_error:
        host.clear_error()
    _show_map_text(m, loaded, result, stats, settings, t_colours, cached)
    m.timings.append({"cell_size": settings.cell_size, "model": settings.model,
                      "layer": settings.layer, "cached": cached, "colours_s": t_colours})
    if stats.sparse and not cached:
        host.notify("Most cells have no value", sparse_message(loaded, stats, settings),
                    color="yellow", seconds=10.0)
    host.rendered()  # features that follow the map (zones, the panels)
    yield "colours"


#: How the status line starts while the coarse map is up.
COARSE = "coarse preview"


def _colouring(loaded: LoadedCloud, settings: MapSettings, result: GridRoughness,
               stats: MapStats) -> Colouring:
    """The colours of the points for ``settings`` on ``result`` (InputError: a colour
    layer the cloud lacks)."""
    if settings.layer == "roughness":
        return by_cell(cell_colours(result, settings, colours_range=stats.colour_range),
                       result)
    return loaded.layer_colouring(settings.layer, result)


def _coarse_first(m: MapTab, run: Run, loaded: LoadedCloud,
                  settings: MapSettings) -> str | None:
    """Before a grid that takes a while: what the status line says is on the points
    while it is computed. A grid change on a coloured cloud keeps its colours
    (``"ODR, grid 0.32 m shown"``); the first map of a cloud is coloured from its
    coarsest preset (with the chosen settings otherwise: ``"coarse preview, grid
    0.64 m"``), whose grid is then cached as any other. None: nothing to show first
    (the chosen grid is the coarsest, or the coarse map failed)."""
    host = m.host
    u = loaded.units
    shown = host.session.shown
    if shown.result is not None and shown.loaded is loaded:
        return f"{MODEL_LABELS[shown.settings.model]}, grid {u.size_text(shown.settings.cell_size)} shown"
    assert loaded.presets is not None
    coarse = settings.with_(cell_size=loaded.presets[0])
    if coarse.grid_key == settings.grid_key:
        return None
    try:
        result = loaded.result(coarse, progress=run.progress())
        stats = map_stats(result, coarse)
        colouring = _colouring(loaded, coarse, result, stats)
    except (InputError, MemoryError):
        return None  # the chosen grid says what is wrong
    m.colouring = colouring
    if m.overlay is None:
        host.scene.colour_by(colouring)
    host.session.shown = Shown(loaded, coarse, result, stats)
    loaded.mark_shown(coarse, host.session)
    fig = colour_bar_of(loaded, result, stats, coarse)
    m.binding.write(m.colour_bar, figure=fig, aspect=panel_aspect(fig))
    m.previews.append({"cell_size": coarse.cell_size, "for": settings.cell_size,
                       "at": time.perf_counter()})
    return f"{COARSE}, grid {u.size_text(coarse.cell_size)}"


def _say_shown(m: MapTab, *, coarse: bool) -> None:
    """The status line of the map shown, once the grid computed after it failed; a
    coarse first map becomes the map shown (the features that follow the map follow
    it)."""
    shown = m.host.session.shown
    if shown.result is None or shown.stats is None:
        return
    m.host.say(status_text(shown.loaded, shown.result, shown.stats, shown.settings, 0.0,
                           True, budget=m.host.scene.budget))
    if coarse:
        m.host.rendered()


def pending_text(loaded: LoadedCloud, waiting: str, settings: MapSettings,
                 percent: float, *, budget: int = DEFAULT_BUDGET) -> str:
    """Markdown of the status line while a grid is computed: what the points show
    meanwhile (``waiting``) and how far the grid has come."""
    name = md(loaded.label or Path(loaded.cloud.source).name or "in-memory cloud",
              max_chars=120)
    return "\n".join([
        f"**{name}**: {loaded.n_total:,} points, each tab draws up to {budget:,} where it "
        "looks  ",
        f"{waiting}; computing grid {loaded.units.size_text(settings.cell_size)}… "
        f"{percent:.0f} %",
    ])


def _grid(m: MapTab, run: Run, loaded: LoadedCloud, settings: MapSettings,
          cached: bool, waiting: str | None = None) -> GridRoughness | None:
    host = m.host
    notes = []
    if not cached:
        host.progress(0.0)
        if waiting is not None:
            host.say(pending_text(loaded, waiting, settings, 0.0, budget=host.scene.budget))
        if loaded.n_total > BIG_CLOUD:
            notes = [c.add_notification("Computing", f"grid {settings.cell_size:g} m on "
                                        f"{loaded.n_total:,} points", loading=True,
                                        with_close_button=False)
                     for c in host.clients().values()]

    def report(done: int, total: int) -> None:
        if total > 0:
            host.progress(100.0 * done / total)
            if waiting is not None:
                host.say(pending_text(loaded, waiting, settings, 100.0 * done / total,
                                      budget=host.scene.budget))

    try:
        return loaded.result(settings, progress=None if cached else run.progress(report))
    except (InputError, MemoryError) as exc:
        what = "not enough memory" if isinstance(exc, MemoryError) else str(exc)
        reject(m, f"grid {settings.cell_size:g} m: {what}")
        return None
    finally:
        host.progress(None)
        for n in notes:
            n.remove()


def _show_map_text(m: MapTab, loaded: LoadedCloud, result: GridRoughness, stats: MapStats,
                   settings: MapSettings, seconds: float, cached: bool) -> None:
    fig = colour_bar_of(loaded, result, stats, settings)
    m.binding.write(m.colour_bar, figure=fig, aspect=panel_aspect(fig))
    if (settings.layer == "roughness" and settings.display == "continuous"
            and settings.stretch.mode == "percentile"):
        m.binding.show_range(stats.colour_range)  # the typed limits start from what is shown
    m.host.say(status_text(loaded, result, stats, settings, seconds, cached,
                           budget=m.host.scene.budget))
    m.host.warn(notice_text(loaded, stats, settings, result))
    m.binding.write(m.axis_note, content=f"auto chose **{loaded.auto_axis}** (closest to "
                    f"the whole-cloud normal); using **{result.axis}**")
    m.host.scene.draw_axis(loaded, result.axis, chosen=settings.axis != "auto",
                           visible=bool(m.show_axis.value))


def colour_bar_of(loaded: LoadedCloud, result: GridRoughness, stats: MapStats,
                  settings: MapSettings) -> go.Figure:
    """The colour bar of what colours the points: the roughness map (its stretch in
    the roughness unit; the binary transform's two colours), or a colour layer."""
    u = loaded.units
    scale = 1.0 / u.rough_per
    title = (f"{MODEL_LABELS[settings.model]} roughness · grid {u.size_text(settings.cell_size)}"
             f" · axis {result.axis} · {loaded.n_total:,} points")
    if settings.layer == "roughness":
        kept_out = 0 if settings.keep_outliers else stats.outliers
        if settings.display == "binary":
            return colour_bar_figure(
                colormap=settings.colormap, theta_min_m=stats.theta_min,
                theta_max_m=stats.theta_max, mode="binary", threshold=settings.threshold,
                title=title, no_value_cells=stats.cells - stats.valid_cells,
                unit=u.rough_label, scale=scale)
        return colour_scale_figure(stats.colour_range, colormap=settings.colormap, title=title,
                                   unit=u.rough_label, scale=scale,
                                   no_value=stats.cells - stats.valid_cells - kept_out,
                                   exact_fit=stats.exact_fit, outliers=kept_out)
    layer = layer_of(loaded, result, settings)
    shown = f"{loaded.n_total:,} points"
    if settings.layer in TRUST_FIELDS:
        assert layer.colour_range is not None and layer.colormap is not None
        what = f"{TRUST_LABELS[settings.layer]} · grid {u.size_text(settings.cell_size)} · {shown}"
        if layer.categories is not None:  # the trusted flag: two colours and a legend
            flag = loaded.trust(result)
            cells = (np.asarray(flag.layer(settings.layer), dtype=np.float64)
                     if flag is not None else np.zeros(0))
            counts = tuple(int(np.count_nonzero(cells == v)) for v, _n, _c in layer.categories)
            return category_legend_figure(
                layer.categories, title=f"Scanner: {what}", counts=counts,
                no_value=int(cells.size - sum(counts)))
        if settings.layer in TRUST_LENGTHS:  # ranges in the cloud's unit, bias in mm
            small = settings.layer != "range"
            return colour_scale_figure(
                layer.colour_range, colormap=layer.colormap, title=f"Scanner: {what}",
                quantity=settings.layer.replace("_", " "),
                unit=u.rough_label if small else u.label,
                scale=1.0 / (u.rough_per if small else u.per))
        return colour_scale_figure(layer.colour_range, colormap=layer.colormap,
                                   title=f"Scanner: {what}",
                                   quantity=settings.layer.replace("_", " "), unit="", scale=1.0)
    if layer.colour_range is None or layer.colormap is None:
        fig = go.Figure()
        fig.update_layout(
            title={"text": f"{layer.label[:1].upper()}{layer.label[1:]} · {shown}<br><sup>the scan's own "
                   "colours; no colour scale</sup>", "font": {"size": 12}, "x": 0.01,
                   "xanchor": "left"},
            height=70, margin={"l": 12, "r": 12, "t": 50, "b": 4},
            xaxis={"visible": False}, yaxis={"visible": False}, plot_bgcolor="white")
        return fig
    if settings.layer == "intensity":
        return colour_scale_figure(layer.colour_range, colormap=layer.colormap,
                                   title=f"Intensity as stored in the file · {shown}",
                                   quantity="intensity", unit="", scale=1.0)
    # distances in the roughness unit (mm) unless the face bends by metres
    big = abs(layer.colour_range.hi) / u.rough_per >= 1000.0
    return colour_scale_figure(
        layer.colour_range, colormap=layer.colormap,
        title=f"Distance to the whole-cloud face plane · {shown}",
        quantity="distance", unit=u.label if big else u.rough_label,
        scale=1.0 / u.per if big else scale)


#: Scanner figures that are lengths (metres in the cells' arrays).
TRUST_LENGTHS = frozenset({"range", "noise_pred", "smoothing_pred", "bias_pred"})


def layer_of(loaded: LoadedCloud, result: GridRoughness, settings: MapSettings) -> ColourLayer:
    """The colour layer that colours the points (not the roughness map): one of the
    cloud's own, or a scanner figure of the shown grid's cells."""
    if settings.layer in TRUST_FIELDS:
        return loaded.cell_layer(settings.layer, result)
    return loaded.layer(settings.layer)


def status_text(loaded: LoadedCloud, result: GridRoughness, stats: MapStats,
                settings: MapSettings, seconds: float, cached: bool, *,
                budget: int = DEFAULT_BUDGET) -> str:
    """Markdown of the status line (the file name escaped)."""
    where = "cached" if cached else f"computed in {seconds:.2f} s"
    name = md(loaded.label or Path(loaded.cloud.source).name or "in-memory cloud",
              max_chars=120)
    colours = "" if settings.layer == "roughness" else \
        f"; colours: {COLOUR_LAYER_LABELS[settings.layer]}"
    return "\n".join([
        f"**{name}**: {loaded.n_total:,} points, each tab draws up to {budget:,} where it "
        "looks  ",
        f"{MODEL_LABELS[settings.model]}, grid {loaded.units.size_text(settings.cell_size)}, "
        f"axis {result.axis}, {stats.valid_cells:,} of {stats.cells:,} cells with a value "
        f"({where}){colours}",
    ])


def sparse_message(loaded: LoadedCloud, stats: MapStats, settings: MapSettings) -> str:
    """Plain text: most occupied cells have no value, and which grid to try."""
    u = loaded.units
    share = 100.0 * stats.valid_cells / max(stats.cells, 1)
    presets = loaded.presets or ()
    larger = [g for g in sorted(presets) if g > settings.cell_size * (1 + 1e-9)
              and g >= loaded.default_cell_size]
    hint = (f"try grid {u.size_text(larger[0])}" if larger else
            "try a larger grid")
    return (f"only {stats.valid_cells:,} of {stats.cells:,} occupied cells ({share:.0f} %) "
            f"have a value at grid {u.size_text(settings.cell_size)}: too few points per cell "
            f"(at least {settings.min_points} needed); {hint} (the default, "
            f"{u.size_text(loaded.default_cell_size)}, holds about 16 points in a typical cell)")


def notice_text(loaded: LoadedCloud, stats: MapStats | None, settings: MapSettings,
                result: GridRoughness | None = None) -> str:
    """Markdown of the notices that stay on screen: the reader's warnings (escaped),
    outlier cells, what the binary threshold flags (with the data's own threshold;
    in the binary display, where it is used), a grid where most
    occupied cells have no value, and cells that fit their plane exactly. Empty when
    there is none."""
    lines = [f"**Warning:** {md(w, max_chars=400)}" for w in loaded.cloud.warnings[:10]]
    unit = loaded.units.unit
    if result is not None:
        text = outlier_text(result, settings.model, unit=unit, kept=settings.keep_outliers)
        if text is not None:
            how = ("*Keep outlier cells* is ticked: they take part" if settings.keep_outliers
                   else "they are left out and drawn in cyan; *Keep outlier cells* keeps them")
            lines.append(f"**Outliers:** {md(text)}; {how}.")
    if stats is not None and stats.advice is not None and settings.layer == "roughness" \
            and settings.display == "binary":  # where the threshold is used
        lines.append(f"**Threshold:** {md(stats.advice.text(unit))}.")
    if stats is not None and stats.sparse:
        lines.append(f"**Most cells have no value:** {md(sparse_message(loaded, stats, settings))}")
    if stats is not None and stats.exact_fit:
        lines.append(f"**Cells of roughness 0:** "
                     f"{md(exact_fit_text(stats.exact_fit, stats.valid_cells))} and take the "
                     "smoothest colour. A larger *Min points per cell* leaves them out.")
    return "  \n".join(lines)


@dataclass(frozen=True)
class RestoreMapJob(Job[Host]):
    """A saved view's map: its settings in the controls and on the points, and its
    camera in every browser."""

    m: MapTab = field(compare=False)
    settings: MapSettings
    camera: Camera | None = None
    lane: ClassVar[str] = "render"
    cancels: ClassVar[frozenset[str]] = frozenset({"panels"})

    @property
    def title(self) -> str:
        return "the saved view's map"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        if self.camera is not None:
            ctx.scene.place_camera(ctx.session.shown.loaded, self.camera)
        self.m.binding.show(self.settings)
        yield "camera"
        yield from render_stages(self.m, run, self.settings)


# ----------------------------------------------------------------------------- idle


def prefetch_presets(host: Host, run: Run) -> bool:
    """Compute one preset grid not yet cached; True if it did (call again)."""
    shown = host.session.shown
    if shown.result is None or shown.loaded.presets is None:
        return False
    for size in shown.loaded.presets:
        candidate = shown.settings.with_(cell_size=size)
        if not shown.loaded.is_cached(candidate):
            if run.cancelled:
                return False
            try:
                shown.loaded.result(candidate, progress=run.progress())
            except (InputError, MemoryError):  # it says so when asked for; not again now
                return False
            # a grid that does not fit the cache budget is not prefetched again
            return shown.loaded.is_cached(candidate)
    return False


