"""The map: the cloud coloured by cell roughness, and the Map tab's controls.

The Map tab chooses what colours the points (the roughness map of a grid, model,
dependent axis and minimum points, continuous or binary, its colour map and
stretch; or a colour layer), the point size and the camera preset; a click on a
point reports its cell. Everything the tab does is a job on the worker:

=============  =======================================================  =================
job            stages                                                    lane (cancels)
=============  =======================================================  =================
ShowJob        show (a cloud into the scene), then RenderJob's           load (render,
                                                                         panels, pick)
LoadJob        read, prepare, show, then RenderJob's                     load (render,
                                                                         panels, pick)
RenderJob      check, grid, colours                                      render (panels)
PickJob        pick, cell and across scales, or a feature's handler      pick, keep all
AxisJob        axis                                                      axis
CameraJob      camera (a preset view)                                    camera
PointSizeJob   points                                                    points
=============  =======================================================  =================

A control change submits a :class:`RenderJob` naming the control and its new value
(its callbacks do nothing else); on the worker, :meth:`MapBinding.settle` puts the
value back if the app showed another meanwhile, moves the controls that follow it (a typed free size picks the "free" grid, a preset shows its size, dragged
percentiles or typed limits pick that stretch) and reads the controls. A pending
RenderJob or LoadJob merges a newer RenderJob (the changes it carries), so a load
followed at once by a control change shows the new file with the new settings.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np
import plotly.graph_objects as go
import viser

from rough_viewer.app import scene as scene_mod
from rough_viewer.app.binding import Binding, assign
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import (
    CellInfo,
    Colouring,
    MapStats,
    by_cell,
    cell_colours,
    cell_info,
    map_stats,
)
from rough_viewer.app.host import Host, Pick
from rough_viewer.app.layout import PLOTLY_CONFIG, limit_step, set_figure
from rough_viewer.app.limits import MAX_TIMINGS
from rough_viewer.app.markup import md
from rough_viewer.app.picking import pick_cloud_point
from rough_viewer.app.session import Shown
from rough_viewer.app.settings import (
    AXIS_BY_NAME,
    DISPLAY_BY_NAME,
    FORM_FIELDS,
    MAX_CELL_SIZE,
    MIN_CELL_SIZE,
    MODEL_LABELS,
    GridChoices,
    MapForm,
    MapSettings,
    check_settings,
    form_of,
    grid_options,
    round_limit,
    settings_of,
    settle,
)
from rough_viewer.app.units import Units
from rough_viewer.app.worker import Job, Run
from rough_viewer.bias.trust import CellTrust
from rough_viewer.grid.outliers import outlier_text
from rough_viewer.grid.roughness import GridRoughness, exact_fit_text
from rough_viewer.grid.scales import PointScales, point_scales_from_prepared
from rough_viewer.io import PointCloud
from rough_viewer.lod.select import DEFAULT_BUDGET
from rough_viewer.report.view import Camera, ColourSettings, View
from rough_viewer.visual import colormaps
from rough_viewer.visual.app import (
    category_legend_figure,
    colour_bar_figure,
    colour_scale_figure,
    panel_aspect,
)
from rough_viewer.visual.layers import ColourLayer
from rough_viewer.visual.scales import point_scales_figure
from rough_viewer.vocabulary import (
    COLOUR_LAYER_LABELS,
    TRUST_FIELDS,
    TRUST_LABELS,
    UNITS,
    InputError,
    Unit,
)

#: Notify every browser while computing a grid on more points than this.
BIG_CLOUD = 1_000_000

#: Colour-map dropdown: "auto" = the map's own (viridis; magma for e_ols).
COLORMAP_OPTIONS: tuple[str, ...] = ("auto", *colormaps.COLORMAP_NAMES)
MODEL_OPTIONS: tuple[str, ...] = tuple(MODEL_LABELS.values())
#: Camera presets (the "View" button group).
CAMERA_PRESETS: tuple[str, ...] = ("face-on", "top", "side")

#: Labels (the browser tests find controls by these). Labels with a unit are made
#: by the functions below (the unit is the loaded cloud's).
L_MODEL = "Model"
L_AXIS = "Dependent axis"
L_DISPLAY = "Display"
L_THRESHOLD = "Threshold"
L_MIN_POINTS = "Min points per cell"
L_POINT_SIZE = "Point size"
L_BUDGET = "Point budget"
#: The point budget control's range.
MIN_BUDGET = 10_000
MAX_BUDGET = 50_000_000
L_COLORMAP = "Colour map"
L_LAYER = "Colour by"
L_STRETCH = "Colour stretch"
L_LOG = "Log colour scale"
L_PERCENTILES = "Percentiles"
L_PCT_LO = "Lowest percentile"
L_PCT_HI = "Highest percentile"
#: Numbers under the percentiles slider.
PERCENTILE_MARKS: tuple[tuple[float, str], ...] = tuple((v, f"{v:g}") for v in (0, 25, 50, 75, 100))
L_TOGGLE = "Toggle ODR / OLS"
L_SHOW_AXIS = "Show dependent axis"
L_KEEP_OUTLIERS = "Keep outlier cells"
L_CAMERA = "View"
#: What the Map tab says before a click.
PICK_PROMPT = "Click a point to see its cell and its roughness across grid sizes."


def l_grid(units: Units) -> str:
    """``"Grid size (m)"``."""
    return f"Grid size ({units.label})"


def l_grid_free(units: Units) -> str:
    return f"Free grid size ({units.label})"


def l_range_lo(units: Units) -> str:
    """``"Lowest θ (mm)"``: the roughness at the first colour."""
    return f"Lowest θ ({units.rough_label})"


def l_range_hi(units: Units) -> str:
    return f"Highest θ ({units.rough_label})"


def grid_step(presets: tuple[float, ...], units: Units) -> float:
    """The free grid field's step, in the cloud's unit: the finest preset's third
    significant digit, at most 0.001 (the field shows as many decimals).

    >>> grid_step((0.64, 0.08), Units("m")), grid_step((0.0032, 0.0004), Units("m"))
    (0.0001, 1e-06)
    """
    finest = units.length(min(presets))
    return min(0.001, 10.0 ** (math.floor(math.log10(finest)) - 2)) if finest > 0 else 0.001


def scales_placeholder() -> go.Figure:
    """The across-scales panel before a click: one line of title, no axes."""
    fig = go.Figure()
    fig.update_layout(
        title={"text": "Roughness of a clicked point's cells across grid sizes<br><sup>"
               "click a point on the rock</sup>", "font": {"size": 12}, "x": 0.01,
               "xanchor": "left"},
        height=56, margin={"l": 10, "r": 10, "t": 44, "b": 4},
        xaxis={"visible": False}, yaxis={"visible": False}, plot_bgcolor="white")
    return fig


def empty_figure(title: str) -> go.Figure:
    """A titled panel with nothing in it yet."""
    fig = go.Figure()
    fig.update_layout(title=dict(text=title, font=dict(size=12)), height=200,
                      margin=dict(l=10, r=10, t=30, b=10))
    return fig


# ----------------------------------------------------------------------------- the binding

Changes = tuple[tuple[str, object], ...]
"""(control's name on :class:`MapFeature`, its value), oldest first."""



class MapBinding(Binding):
    """Between the Map tab's controls and :class:`~rough_viewer.app.settings.MapForm`:
    it copies the controls into a form and a form into the controls, and nothing
    else; what a change means (the twin controls, the settings asked for) is
    :mod:`rough_viewer.app.settings`' pure functions."""

    def __init__(self, m: MapFeature, presets: tuple[float, ...], units: Units) -> None:
        self.m = m
        self.choices = GridChoices.of(presets, units)
        """The shown cloud's grid entries and the unit of the lengths the controls show."""

    @property
    def units(self) -> Units:
        """The unit of the lengths the controls show (the shown cloud's)."""
        return self.choices.units

    # ------------------------------------------------------------------ controls <-> form
    def handles(self) -> dict[str, Any]:
        """Field of :class:`MapForm` -> its control."""
        return {name: getattr(self.m, name) for name in FORM_FIELDS}

    def read_form(self) -> MapForm:
        """What the controls hold now."""
        return MapForm(**{name: h.value for name, h in self.handles().items()})

    def show_form(self, form: MapForm) -> None:
        """Put ``form`` into the controls quietly (only the ones that differ; a colour
        limit's step follows its value)."""
        with self.quietly():
            for name, handle in self.handles().items():
                value = getattr(form, name)
                if name in ("range_lo", "range_hi") and handle.value != value:
                    handle.step = limit_step(value)
                if handle.value != value:
                    assign(handle, value)

    # ------------------------------------------------------------------ read
    def read(self) -> MapSettings:
        """The settings the controls ask for (InputError if a control holds a value
        the app cannot use). Lengths typed in the cloud's unit become metres."""
        return settings_of(self.read_form(), self.choices)

    def settle(self, changes: Changes) -> None:
        """Put each change's value back into its control (the app may have shown
        another since: a colour range after a map) and move the controls that follow
        it (:func:`rough_viewer.app.settings.settle`; worker)."""
        self.show_form(settle(self.read_form(), changes, self.choices))

    # ------------------------------------------------------------------ show
    def show(self, settings: MapSettings) -> None:
        """Show ``settings`` in the controls without queuing work (after an error, a
        restored view, or a cloud with other presets)."""
        self.show_form(form_of(settings, self.choices, self.read_form(),
                               layers=tuple(self.m.layer.options)))

    def show_range(self, colour_range: colormaps.ColourRange) -> None:
        """Put the roughness range the colours span into the lowest/highest fields
        (roughness unit, 3 digits), so switching to an absolute stretch pins it."""
        u = self.units
        lo, hi = round_limit(u.rough(colour_range.lo)), round_limit(u.rough(colour_range.hi))
        if hi > lo:
            self.show_form(replace(self.read_form(), range_lo=lo, range_hi=hi))

    def follow(self, loaded: LoadedCloud, point_size: float) -> None:
        """The grid presets, unit labels, colour layers and point-size range of a
        new cloud (without queuing work)."""
        m = self.m
        u = loaded.units
        assert loaded.presets is not None
        self.choices = GridChoices.of(loaded.presets, u)
        with self.quietly():
            m.grid.options = (*self.choices.values, "free")
            m.grid.label = l_grid(u)
            m.grid_free.label = l_grid_free(u)
            m.grid_free.min, m.grid_free.max = u.length(MIN_CELL_SIZE), u.length(MAX_CELL_SIZE)
            m.grid_free.step = grid_step(loaded.presets, u)
            m.range_lo.label = l_range_lo(u)
            m.range_hi.label = l_range_hi(u)
            m.layer.options = tuple(COLOUR_LAYER_LABELS[n] for n in loaded.layers)
            m.point_size.min, m.point_size.max = point_size / 10, point_size * 10
            m.point_size.step = point_size / 10
            assign(m.point_size, point_size)


# ----------------------------------------------------------------------------- the feature


class CloudSource(Protocol):
    """Where a :class:`LoadJob` gets its points."""

    @property
    def title(self) -> str:
        """How the source is named to the user (a path as typed, an upload's name)."""
        ...

    def read(self, host: Host, run: Run) -> PointCloud:
        """The points (InputError naming the file as the user knows it)."""
        ...

    def release(self) -> None:
        """Free what the source holds (an upload's file); safe to call twice."""
        ...


@dataclass(frozen=True)
class InMemory:
    """A cloud already in memory (the command line's, a script's)."""

    cloud: PointCloud

    @property
    def title(self) -> str:
        return self.cloud.source or "a cloud"

    def read(self, host: Host, run: Run) -> PointCloud:
        return self.cloud

    def release(self) -> None:
        pass


@dataclass(eq=False)
class MapFeature:
    """The Map tab (handles, its binding) and the map's record of what it showed."""

    host: Host
    colour_bar: viser.GuiPlotlyHandle
    pick: viser.GuiMarkdownHandle
    scales: viser.GuiPlotlyHandle
    """Roughness of the clicked point's cells against grid size (a placeholder until
    a click)."""
    layer: viser.GuiDropdownHandle[str]
    grid: viser.GuiDropdownHandle[str]
    grid_free: viser.GuiNumberHandle[float]
    model: viser.GuiDropdownHandle[str]
    keep_outliers: viser.GuiCheckboxHandle
    """Cells whose roughness is larger than the cell take part (default: left out,
    in their own colour)."""
    toggle: viser.GuiButtonHandle
    axis: viser.GuiDropdownHandle[str]
    axis_note: viser.GuiMarkdownHandle
    show_axis: viser.GuiCheckboxHandle
    display: viser.GuiDropdownHandle[str]
    threshold: viser.GuiSliderHandle[float]
    min_points: viser.GuiNumberHandle[int]
    colormap: viser.GuiDropdownHandle[str]
    stretch: viser.GuiDropdownHandle[str]
    log: viser.GuiCheckboxHandle
    percentiles: viser.GuiMultiSliderHandle[float]
    pct_lo: viser.GuiNumberHandle[float]
    """The slider's lower end, typed (the two follow each other)."""
    pct_hi: viser.GuiNumberHandle[float]
    range_lo: viser.GuiNumberHandle[float]
    range_hi: viser.GuiNumberHandle[float]
    point_size: viser.GuiSliderHandle[float]
    budget: viser.GuiNumberHandle[int]
    """Most points a browser tab shows at once (level of detail)."""
    camera: viser.GuiButtonGroupHandle
    binding: MapBinding = field(init=False)
    timings: deque[dict[str, object]] = field(default_factory=lambda: deque(maxlen=MAX_TIMINGS))
    """One record per shown map: seconds to colours (``colours_s``) and to panels
    (``panels_s``), cached or not; the last :data:`MAX_TIMINGS`."""
    pick_timings: deque[dict[str, object]] = field(
        default_factory=lambda: deque(maxlen=MAX_TIMINGS))
    """One record per reported click: seconds to the cell report and the
    across-scales plot (``pick_s``); the last :data:`MAX_TIMINGS`."""
    pick_nodes: list[viser.SceneNodeHandle] = field(default_factory=list)
    """The clicked point's marker and its cell's outline."""
    overlay: object | None = None
    """The feature whose colours are on the points instead of the map's (the zones,
    the joint sets), or None."""
    colouring: Colouring | None = None
    """The map's colours of the points (shown unless a feature holds them)."""
    _release: Callable[[], None] = field(default=lambda: None, repr=False)

    def inputs(self) -> tuple[Any, ...]:
        """The controls a browser may set."""
        return (self.layer, self.grid, self.grid_free, self.model, self.keep_outliers,
                self.toggle, self.axis,
                self.show_axis, self.display, self.threshold, self.min_points,
                self.point_size, self.colormap, self.stretch, self.log, self.percentiles,
                self.pct_lo, self.pct_hi, self.range_lo, self.range_hi, self.budget,
                self.camera)

    # ------------------------------------------------------------------ for other features
    def request(self, **changes: object) -> int:
        """Queue the map the controls show once the named controls hold these values
        (as a person sets them: a control's own change, or another tab's twin of a
        control); ``toggle=True`` flips ODR and OLS."""
        return self.host.submit(RenderJob(self, changes=tuple(changes.items())))

    def settings(self) -> MapSettings:
        """The settings the controls ask for, or the shown ones if a control is
        unusable."""
        try:
            return self.binding.read()
        except InputError:
            return self.host.session.shown.settings

    def take_overlay(self, owner: object, release: Callable[[], None],
                     colouring: Colouring) -> None:
        """``owner`` colours the points with ``colouring`` instead of the map: the
        colour bar hides, and a feature that held the points before is told to let go
        (``release`` is how ``owner`` will be told; worker)."""
        if self.overlay is not None and self.overlay is not owner:
            self._release()
        self.overlay, self._release = owner, release
        self.colour_bar.visible = False
        self.host.scene.colour_by(colouring)

    def give_back_overlay(self, owner: object) -> None:
        """``owner`` no longer colours the points: the map's colours and colour bar
        come back (worker)."""
        if self.overlay is owner:
            self.overlay, self._release = None, lambda: None
            self.colour_bar.visible = True
            if self.colouring is not None:
                self.host.scene.colour_by(self.colouring)

    def forget_pick(self, text: str) -> None:
        """Drop the clicked point's marker, report and across-scales plot; the click
        report then reads ``text`` (worker)."""
        self.host.scene.remove(self.pick_nodes)
        self.pick_nodes = []
        self.host.session.forget_pick()
        self.pick.content = text
        set_figure(self.scales, scales_placeholder())

    # ------------------------------------------------------------------ saved views
    def snapshot(self) -> dict[str, Any]:
        s = self.host.session.shown.settings
        unit = self.host.session.shown.loaded.cloud.source_unit
        units: Unit = unit if unit in UNITS else "m"
        return {"cell_size_m": float(s.cell_size), "min_points": int(s.min_points),
                "axis": s.axis, "model": s.model, "units": units,
                "threshold": float(s.threshold),
                "colour": ColourSettings(colormap=s.colormap, mode=s.display,
                                         stretch=s.stretch, layer=s.layer)}

    def restore(self, view: View) -> Job[Host]:
        return RestoreMapJob(self, check_view_for_app(view, "saved view"), view.camera)

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        return {"colour_bar": self.colour_bar,
                "scales": self.scales}


#: Largest "Min points per cell" the Map tab's control takes.
MAX_MIN_POINTS = 100_000


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

    m: MapFeature = field(compare=False)
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


def merged(newer: RenderJob, older: RenderJob | LoadJob) -> RenderJob:
    """``newer`` with the changes ``older`` carried before its own."""
    return replace(newer, changes=older.changes + newer.changes)


def resolve(m: MapFeature, settings: MapSettings | None,
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


def reject(m: MapFeature, message: str) -> None:
    """Show an error and put the controls back to the shown map."""
    m.host.show_error(message)
    m.binding.show(m.host.session.shown.settings)


def render_stages(m: MapFeature, run: Run, settings: MapSettings, *,
                  keep_error: bool = False) -> Iterator[str]:
    """Check the settings, compute (or fetch) the grid, colour the points (by the
    roughness map or a colour layer), update the colour bar, status and notices,
    then tell the features that follow the map. ``keep_error``: leave an error shown
    by an earlier stage on screen."""
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
    t0 = time.perf_counter()
    cached = loaded.is_cached(settings)
    result = _grid(m, run, loaded, settings, cached)
    if result is None:
        return
    yield "grid"
    stats = map_stats(result, settings)
    if settings.layer == "roughness":
        colouring: Colouring = by_cell(
            cell_colours(result, settings, colours_range=stats.colour_range), result.point_cell)
    else:
        try:
            colouring = loaded.layer_colouring(settings.layer, result)
        except InputError as exc:
            reject(m, str(exc))
            return
    m.colouring = colouring
    if m.overlay is None:  # a feature that colours the points recolours them itself
        host.scene.colour_by(colouring)
    host.session.shown = Shown(loaded, settings, result, stats)
    loaded.mark_shown(settings)
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


def _grid(m: MapFeature, run: Run, loaded: LoadedCloud, settings: MapSettings,
          cached: bool) -> GridRoughness | None:
    host = m.host
    notes = []
    if not cached:
        host.progress(0.0)
        if loaded.n_total > BIG_CLOUD:
            notes = [c.add_notification("Computing", f"grid {settings.cell_size:g} m on "
                                        f"{loaded.n_total:,} points", loading=True,
                                        with_close_button=False)
                     for c in host.clients().values()]

    def report(done: int, total: int) -> None:
        if total > 0:
            host.progress(100.0 * done / total)

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


def _show_map_text(m: MapFeature, loaded: LoadedCloud, result: GridRoughness, stats: MapStats,
                   settings: MapSettings, seconds: float, cached: bool) -> None:
    fig = colour_bar_of(loaded, result, stats, settings)
    m.colour_bar.figure = fig
    m.colour_bar.aspect = panel_aspect(fig)
    if (settings.layer == "roughness" and settings.display == "continuous"
            and settings.stretch.mode == "percentile"):
        m.binding.show_range(stats.colour_range)  # the typed limits start from what is shown
    m.host.say(status_text(loaded, result, stats, settings, seconds, cached,
                           budget=m.host.scene.budget))
    m.host.warn(notice_text(loaded, stats, settings, result))
    m.axis_note.content = (f"auto chose **{loaded.auto_axis}** (closest to the whole-cloud "
                           f"normal); using **{result.axis}**")
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


# ----------------------------------------------------------------------------- clouds


@dataclass(frozen=True)
class LoadJob(Job[Host]):
    """Show another cloud from ``source`` (a file, an upload, points in memory)."""

    m: MapFeature = field(compare=False)
    source: CloudSource = field(compare=False)
    settings: MapSettings | None = None
    """Settings to show it with (None: the controls', read when the job runs)."""
    changes: Changes = ()
    lane: ClassVar[str] = "load"
    cancels: ClassVar[frozenset[str]] = frozenset({"render", "panels", "pick"})

    @property
    def title(self) -> str:
        return f"loading {self.source.title}"

    def absorb(self, newer: Job[Host]) -> Job[Host] | None:
        if isinstance(newer, RenderJob):
            return replace(self, settings=newer.settings, changes=self.changes + newer.changes)
        return None

    def release(self) -> None:
        self.source.release()

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        settings = resolve(self.m, self.settings, self.changes) \
            or ctx.session.shown.settings
        return load_stages(self.m, run, lambda r: self.source.read(ctx, r), settings)


def load_stages(m: MapFeature, run: Run, read: Callable[[Run], PointCloud],
                settings: MapSettings, *, stash: bool = False,
                label: str = "") -> Iterator[str]:
    """Read a cloud, prepare it for display, put it in the scene, then show it with
    ``settings`` at its own default grid (its presets come from its point spacing).

    ``stash``: put the scan shown now aside (:attr:`Session.stashed`) instead of
    dropping it, so it can be shown again as it was (the board lesson); a load
    without it drops anything put aside. A cloud that cannot be read or prepared
    leaves the old one shown (with the error) and shows ``settings`` on it, so
    control changes merged into the load are not lost. ``label``: the status line's
    name of a cloud that is no file (:attr:`LoadedCloud.label`).
    """
    host = m.host
    try:
        cloud = read(run)
        yield "read"
        loaded = LoadedCloud(cloud, max_display=host.options.max_display,
                             cache_bytes=host.options.cache_bytes, label=label,
                             trust_settings=host.options.trust)
    except (InputError, MemoryError) as exc:
        host.show_error(str(exc) if isinstance(exc, InputError) else "not enough memory "
                        "to load this cloud")
        yield "read failed"
        m.binding.show(settings)
        yield from render_stages(m, run, settings, keep_error=True)
        return
    yield "prepare"
    if stash:
        host.session.put_aside()
    else:
        host.session.stashed = None
    layer = settings.layer if settings.layer in loaded.layers else "roughness"
    settings = settings.with_(cell_size=loaded.default_cell_size, layer=layer)
    show_cloud(m, loaded, settings)
    for warning in cloud.warnings[:10]:
        host.notify("Warning", warning, color="yellow", seconds=12.0)
    yield "show"
    yield from render_stages(m, run, settings)


def show_cloud(m: MapFeature, loaded: LoadedCloud, settings: MapSettings, *,
               frame: bool = True) -> None:
    """Replace the cloud in the scene (and forget the old cloud's pick and panels);
    the grid presets, unit labels and colour layers follow the new cloud, and the
    controls show ``settings`` (worker). ``frame``: every browser's camera frames
    it (False: the cameras and point size stay, as for a crop of the cloud shown)."""
    host = m.host
    host.session.new_cloud(loaded, settings)
    size = scene_mod.default_point_size(loaded) if frame else float(host.scene.point_size)
    m.binding.follow(loaded, size)
    m.binding.show(settings)
    host.scene.show_cloud(loaded, size)
    m.forget_pick(PICK_PROMPT)
    if frame:
        host.scene.frame(loaded)
    host.cloud_shown()


@dataclass(frozen=True)
class ShowJob(Job[Host]):
    """Show a prepared cloud with ``settings`` (the app's first cloud; a scan put
    aside, shown again with its cached grids)."""

    m: MapFeature = field(compare=False)
    loaded: LoadedCloud = field(compare=False)
    settings: MapSettings
    lane: ClassVar[str] = "load"
    cancels: ClassVar[frozenset[str]] = frozenset({"render", "panels", "pick"})

    @property
    def title(self) -> str:
        return "showing the cloud"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        show_cloud(self.m, self.loaded, self.settings)
        yield "show"
        yield from render_stages(self.m, run, self.settings)


@dataclass(frozen=True)
class RestoreMapJob(Job[Host]):
    """A saved view's map: its settings in the controls and on the points, and its
    camera in every browser."""

    m: MapFeature = field(compare=False)
    settings: MapSettings
    camera: Camera | None = None
    lane: ClassVar[str] = "render"
    cancels: ClassVar[frozenset[str]] = frozenset({"panels"})

    @property
    def title(self) -> str:
        return "the saved view's map"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        if self.camera is not None:
            loaded = ctx.session.shown.loaded
            c = self.camera
            eye, look = np.asarray(c.position) - loaded.origin, np.asarray(c.look_at) - loaded.origin
            framed = scene_mod.camera_pose(loaded)  # clipping planes for the cloud's extent
            far = max(framed.far, 100.0 * float(np.linalg.norm(eye - look)))
            ctx.scene.set_camera(eye, look, c.up, float(np.radians(c.fov_deg)),
                                 near=framed.near, far=far)
        self.m.binding.show(self.settings)
        yield "camera"
        yield from render_stages(self.m, run, self.settings)


# ----------------------------------------------------------------------------- scene


@dataclass(frozen=True)
class CameraJob(Job[Host]):
    """Move every browser's camera to a preset view of the cloud."""

    preset: str
    """``"face-on"``, ``"top"`` or ``"side"`` (:func:`rough_viewer.app.scene.camera_pose`)."""
    lane: ClassVar[str] = "camera"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        ctx.scene.move_cameras(ctx.session.shown.loaded, self.preset)
        yield "camera"


@dataclass(frozen=True)
class AxisJob(Job[Host]):
    """Show or hide the dependent-axis marker."""

    visible: bool
    lane: ClassVar[str] = "axis"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        shown = ctx.session.shown
        if shown.result is not None:
            ctx.scene.draw_axis(shown.loaded, shown.result.axis,
                                chosen=shown.settings.axis != "auto", visible=self.visible)
        yield "axis"


@dataclass(frozen=True)
class PointSizeJob(Job[Host]):
    """The points' size (the map's and every cloud that follows it)."""

    size: float
    lane: ClassVar[str] = "points"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        ctx.scene.set_point_size(self.size)
        yield "points"


# ----------------------------------------------------------------------------- level of detail

#: Seconds a camera rests before its tab chooses its nodes again (and, while it
#: moves, the longest wait between two choices).
CAMERA_REST_S = 0.15
CAMERA_MOVING_S = 0.5


@dataclass(frozen=True)
class RefineJob(Job[Host]):
    """Browser tabs choose their nodes for their cameras (level of detail)."""

    clients: frozenset[int]
    lane: ClassVar[str] = "lod"

    @property
    def title(self) -> str:
        return "level of detail"

    def absorb(self, newer: Job[Host]) -> Job[Host] | None:
        if isinstance(newer, RefineJob):
            return RefineJob(self.clients | newer.clients)
        return None

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        for cid in sorted(self.clients):
            ctx.scene.refine(cid)
        yield "refine"


#: Seconds after a tab left when the heap is trimmed a second time (its connection's
#: buffers are freed after the tab is dropped).
GIVE_BACK_AFTER_S = 2.0


@dataclass(frozen=True)
class DropTabJob(Job[Host]):
    """A browser tab left: its nodes are forgotten."""

    client_id: int
    lane: ClassVar[str] = "lod-drop"
    keep_all: ClassVar[bool] = True

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        from rough_viewer.memory import give_back

        ctx.scene.drop_tab(self.client_id)
        yield "drop"
        # its messages' memory, freed in pieces the heap keeps (issue 36 item 19): now,
        # and once its connection's last buffers are gone too
        give_back()
        later = threading.Timer(GIVE_BACK_AFTER_S, give_back)
        later.daemon = True
        later.start()
        yield "give back"


@dataclass(frozen=True)
class BudgetJob(Job[Host]):
    """Every tab's point budget."""

    budget: int
    lane: ClassVar[str] = "budget"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        ctx.scene.set_budget(self.budget)
        yield "budget"


class CameraWatch:
    """Debounces the cameras of the browser tabs: a tab chooses its nodes again once
    its camera has rested :data:`CAMERA_REST_S` (and every :data:`CAMERA_MOVING_S`
    while it moves), as a :class:`RefineJob` on the worker."""

    def __init__(self, host: Host) -> None:
        self._host = host
        self._lock = threading.Lock()
        self._timers: dict[int, threading.Timer] = {}
        self._last: dict[int, float] = {}

    def moved(self, client_id: int) -> None:
        """A tab's camera changed (viser's thread pool)."""
        now = time.monotonic()
        with self._lock:
            timer = self._timers.pop(client_id, None)
            if timer is not None:
                timer.cancel()
            due = now - self._last.get(client_id, 0.0) >= CAMERA_MOVING_S
            if due:
                self._last[client_id] = now
            timer = threading.Timer(CAMERA_REST_S, self._rested, args=(client_id,))
            timer.daemon = True
            self._timers[client_id] = timer
            timer.start()
        if due:
            self._host.submit(RefineJob(frozenset({client_id})))

    def _rested(self, client_id: int) -> None:
        with self._lock:
            self._timers.pop(client_id, None)
            self._last[client_id] = time.monotonic()
        self._host.submit(RefineJob(frozenset({client_id})))

    def left(self, client_id: int) -> None:
        with self._lock:
            timer = self._timers.pop(client_id, None)
            self._last.pop(client_id, None)
        if timer is not None:
            timer.cancel()
        self._host.submit(DropTabJob(client_id))


# ----------------------------------------------------------------------------- pick


@dataclass(frozen=True)
class PickJob(Job[Host]):
    """A click in the scene: pick the point under the ray, then report its cell (or
    hand it to a feature that takes clicks, e.g. the Profile tab)."""

    m: MapFeature = field(compare=False)
    origin: tuple[float, float, float]
    direction: tuple[float, float, float]
    lane: ClassVar[str] = "pick"
    keep_all: ClassVar[bool] = True

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        on_click(self.m, self.origin, self.direction)
        yield "pick"


def valid_ray(origin: object, direction: object) -> bool:
    """Both are 3 finite numbers and the direction is not zero (a client's ray)."""
    try:
        o = np.asarray(origin, dtype=np.float64)
        d = np.asarray(direction, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return (o.shape == (3,) and d.shape == (3,) and bool(np.all(np.isfinite(o)))
            and bool(np.all(np.isfinite(d))) and float(np.linalg.norm(d)) > 0)


def on_click(m: MapFeature, origin: object, direction: object) -> CellInfo | None:
    """Pick the displayed point under a click ray; let a feature take it, or report
    its cell and the roughness of its cells on every preset grid (returned: the
    cell report). Worker."""
    host = m.host
    shown = host.session.shown
    if shown.result is None or not valid_ray(origin, direction):
        return None
    t0 = time.perf_counter()
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    loaded = shown.loaded
    i = pick_cloud_point(loaded.cloud, loaded.to_file_frame(o), d)  # every point, not a sample
    if i is None:  # the earlier point's report and plot go with it
        m.forget_pick("No point under the click.")
        return None
    xyz = np.array([loaded.cloud.x[i], loaded.cloud.y[i], loaded.cloud.z[i]], dtype=np.float64)
    pick = Pick(int(i), xyz, loaded.to_local(xyz))
    local = pick.local
    if host.picked(pick):
        return None
    info = cell_info(shown.result, pick.point, pick.xyz)
    g = shown.result.grid.cell_size
    u = shown.loaded.units
    host.session.last_pick = info
    m.pick.content = format_cell_info(info, g, u, trust=shown.loaded.trust(shown.result))
    host.scene.remove(m.pick_nodes)
    m.pick_nodes = host.scene.mark_pick(shown.loaded, info, local, g)
    t_cell = time.perf_counter() - t0
    scales = across_scales(shown.loaded, shown.settings, shown.result, pick.point)
    fig = point_scales_figure(scales, point_xyz=pick.xyz.tolist(), n_points=shown.loaded.n_total,
                              unit=u.unit)
    set_figure(m.scales, fig)
    host.session.pick_scales = scales
    m.pick_timings.append({"cell_s": t_cell, "pick_s": time.perf_counter() - t0,
                           "grids": len(scales.cell_sizes)})
    return info


def across_scales(loaded: LoadedCloud, settings: MapSettings, result: GridRoughness,
                  point: int) -> PointScales:
    """ODR, OLS, hybrid roughness and e_ols of the cells holding cloud point ``point``
    on every preset grid (with the shown axis and minimum points): only those cells
    are evaluated, on the nested grids' cell membership (the finest preset's,
    coarsened), so a click costs milliseconds."""
    assert loaded.presets is not None
    grids = [loaded.prepared(g) for g in loaded.presets]
    return point_scales_from_prepared(loaded.cloud, grids, point, axis=result.axis,
                                      min_points=settings.min_points)


def _orientation(dip: float, direction: float) -> str:
    """"dip 26.6°, dip direction 180.0°" (docs/zones.md), or a dash."""
    if not (math.isfinite(dip) and math.isfinite(direction)):
        return "dip —"
    return f"dip {dip:.1f}°, dip direction {direction:05.1f}°"


def format_cell_info(info: CellInfo, cell_size: float, units: Units | None = None, *,
                     trust: CellTrust | None = None) -> str:
    """Markdown of a picked cell (roughness in the roughness unit, mm for metric
    input; coordinates and the grid in the cloud's unit), with the scanner's figures
    of the cell where the cloud has scanner positions (``trust``)."""
    u = units or Units("m")

    rough = u.rough_text  # every model and e_ols to the same 3 significant digits

    n = info.normal
    normal = "—" if not np.all(np.isfinite(n)) else f"({n[0]:.3f}, {n[1]:.3f}, {n[2]:.3f})"
    p = [c / u.per for c in info.point]
    return "\n".join([
        f"**Cell {info.ijk}** ({u.size_text(cell_size)}), {info.n_points} points  ",
        f"point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) {u.label}  ",
        f"θ ODR {rough(info.theta['odr'])}, OLS ({info.axis}) {rough(info.theta['ols'])}  ",
        f"θ hybrid {rough(info.theta['hybrid'])}, e_ols {rough(info.theta['e_ols'])}  ",
        f"normal {normal}  ",
        f"plane {_orientation(info.dip_deg, info.dip_direction_deg)}",
        *(f"  \nscanner: {md(line)}" for line in
          (trust.lines(info.cell, u.unit) if trust is not None else ())),
    ])


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
            shown.loaded.result(candidate, progress=run.progress())
            # a grid that does not fit the cache budget is not prefetched again
            return shown.loaded.is_cached(candidate)
    return False


# ----------------------------------------------------------------------------- mount


def mount(host: Host) -> MapFeature:
    """The colour bar above the tabs and the Map tab; every control queues a job."""
    m = _add_controls(host)
    _wire(host, m)
    host.on_idle(lambda run: prefetch_presets(host, run))
    return m


def _add_controls(host: Host) -> MapFeature:
    gui = host.gui
    shown = host.session.shown
    loaded, settings = shown.loaded, shown.settings
    units = loaded.units
    assert loaded.presets is not None
    layers = loaded.layers
    point_size = scene_mod.default_point_size(loaded)
    colour_bar = gui.add_plotly(empty_figure("colour bar"), config=PLOTLY_CONFIG,
                                aspect=0.27)  # height = width * aspect
    values = grid_options(loaded.presets, units)
    preset = f"{units.length(settings.cell_size):g}"
    st = settings.stretch
    pct = (st.lo, st.hi) if st.mode == "percentile" else (2.0, 98.0)
    if st.mode == "absolute":
        lo_r, hi_r = round_limit(units.rough(st.lo)), round_limit(units.rough(st.hi))
    else:
        lo_r = hi_r = 0.0
    with host.tab("Map"):
        # what a click reports comes first: it is what the person looks for next
        pick = gui.add_markdown(PICK_PROMPT)
        # never hidden: viser's client fails to lay out a plot that was created hidden
        placeholder = scales_placeholder()
        scales = gui.add_plotly(placeholder, config=PLOTLY_CONFIG, aspect=panel_aspect(placeholder))
        m = MapFeature(
            host=host, colour_bar=colour_bar, pick=pick, scales=scales,
            layer=gui.add_dropdown(
                L_LAYER, tuple(COLOUR_LAYER_LABELS[n] for n in layers),
                initial_value=COLOUR_LAYER_LABELS[settings.layer if settings.layer in layers
                                                  else "roughness"],
                hint="The roughness map, or the rock itself: scan colours, intensity, or "
                "the distance to the whole-cloud face plane."),
            grid=gui.add_dropdown(
                l_grid(units), (*values, "free"),
                initial_value=preset if preset in values else "free",
                hint="Cell edge of the roughness grid: presets from the point spacing "
                "(the finest holds about 16 points in a typical cell); 'free' uses the "
                "number below."),
            grid_free=gui.add_number(
                l_grid_free(units), units.length(settings.cell_size),
                min=units.length(MIN_CELL_SIZE), max=units.length(MAX_CELL_SIZE),
                step=grid_step(loaded.presets, units),
                hint="Any cell size (switches the grid size to 'free')."),
            model=gui.add_dropdown(L_MODEL, MODEL_OPTIONS,
                                   initial_value=MODEL_LABELS[settings.model]),
            keep_outliers=gui.add_checkbox(
                L_KEEP_OUTLIERS, bool(settings.keep_outliers),
                hint="Hybrid or OLS roughness larger than the cell (a plane nearly along "
                "the dependent axis) is an outlier of the definition, not rock: left "
                "out of the colours, panels and zones and drawn in cyan unless kept."),
            toggle=gui.add_button(L_TOGGLE, hint="Same cells, other reference plane."),
            axis=gui.add_dropdown(L_AXIS, tuple(AXIS_BY_NAME), initial_value=settings.axis,
                                  hint="Dependent variable of the OLS and hybrid fits."),
            axis_note=gui.add_markdown(""),
            show_axis=gui.add_checkbox(L_SHOW_AXIS, True),
            display=gui.add_dropdown(L_DISPLAY, tuple(DISPLAY_BY_NAME),
                                     initial_value=settings.display),
            threshold=gui.add_slider(
                L_THRESHOLD, min=0.0, max=1.0, step=0.01, initial_value=settings.threshold,
                hint="Binary view: cells with normalised roughness ≥ this are rough."),
            min_points=gui.add_number(L_MIN_POINTS, int(settings.min_points), min=3,
                                      max=MAX_MIN_POINTS, step=1),
            colormap=gui.add_dropdown(L_COLORMAP, COLORMAP_OPTIONS, initial_value="auto",
                                      hint="auto: viridis for roughness, magma for e_ols."),
            stretch=gui.add_dropdown(
                L_STRETCH, colormaps.STRETCH_MODES, initial_value=st.mode,
                hint="percentile: the colours span these percentiles of the cells (robust "
                "to a few extreme cells); absolute: fixed limits, so one colour means one "
                "roughness on every grid and file."),
            log=gui.add_checkbox(L_LOG, bool(st.log),
                                 hint="Equal ratios of roughness get equal colour steps."),
            percentiles=gui.add_multi_slider(
                L_PERCENTILES, min=0.0, max=100.0, step=0.5, min_range=1.0,
                initial_value=pct, marks=PERCENTILE_MARKS,
                hint="Percentiles of the cells with a value at the first and last colour."),
            pct_lo=gui.add_number(L_PCT_LO, pct[0], min=0.0, max=100.0, step=0.5,
                                  hint="The percentile at the first colour (typed)."),
            pct_hi=gui.add_number(L_PCT_HI, pct[1], min=0.0, max=100.0, step=0.5,
                                  hint="The percentile at the last colour (typed)."),
            range_lo=gui.add_number(l_range_lo(units), lo_r, min=0.0, max=1e9, step=0.001,
                                    hint="Roughness at the first colour; typing here pins "
                                    "the colours (absolute stretch)."),
            range_hi=gui.add_number(l_range_hi(units), hi_r, min=0.0, max=1e9, step=0.001,
                                    hint="Roughness at the last colour (absolute stretch)."),
            point_size=gui.add_slider(L_POINT_SIZE, min=point_size / 10, max=point_size * 10,
                                      step=point_size / 10, initial_value=point_size),
            budget=gui.add_number(
                L_BUDGET, int(host.scene.budget), min=MIN_BUDGET, max=MAX_BUDGET, step=100_000,
                hint="Most points each browser tab shows: where the camera looks, every "
                "point up to this many (a slower GPU wants fewer)."),
            camera=gui.add_button_group(L_CAMERA, CAMERA_PRESETS,
                                        hint="Look at the face straight on, from above, "
                                        "or from the side."),
        )
    m.binding = MapBinding(m, loaded.presets, units)
    host.allow(*m.inputs())
    return m


def _wire(host: Host, m: MapFeature) -> None:
    """Every control submits a job naming itself; clicks on the scene submit a pick."""
    b = m.binding
    names = ("layer", "grid", "grid_free", "model", "keep_outliers", "axis", "display",
             "threshold",
             "min_points", "colormap", "stretch", "log", "percentiles", "pct_lo", "pct_hi",
             "range_lo", "range_hi", "toggle")
    by_handle = {id(getattr(m, n)): n for n in names}
    b.on_change([getattr(m, n) for n in names],
                lambda handle: m.request(**{by_handle[id(handle)]: handle.value}))
    b.on_change([m.point_size], lambda _h: host.submit(PointSizeJob(float(m.point_size.value))))
    b.on_change([m.budget], lambda _h: host.submit(BudgetJob(int(m.budget.value))))
    watch = CameraWatch(host)

    def connected(client: viser.ClientHandle) -> None:
        cid = client.client_id
        client.camera.on_update(lambda _camera: watch.moved(cid))
        watch.moved(cid)  # its first camera may have come before this callback

    host.on_connect(connected)
    host.on_disconnect(lambda client: watch.left(client.client_id))
    b.on_change([m.show_axis], lambda _h: host.submit(AxisJob(bool(m.show_axis.value))))

    def camera(_handle: object) -> None:
        if m.camera.value in CAMERA_PRESETS:
            host.submit(CameraJob(m.camera.value))

    b.on_change([m.camera], camera)

    def clicked(event: viser.SceneClickEvent) -> None:
        if valid_ray(event.ray_origin, event.ray_direction):
            o, d = event.ray_origin, event.ray_direction
            host.submit(PickJob(m, (float(o[0]), float(o[1]), float(o[2])),
                                (float(d[0]), float(d[1]), float(d[2]))))

    host.scene.on_click(clicked)
