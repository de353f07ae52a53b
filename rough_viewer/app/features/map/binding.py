"""The Map tab's handles, their labels, and the binding between them and
:class:`~rough_viewer.app.state.MapSettings`."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import plotly.graph_objects as go
import viser

from rough_viewer.app.binding import Binding, assign
from rough_viewer.app.host import Host
from rough_viewer.app.layout import limit_step, round_limit
from rough_viewer.app.limits import MAX_TIMINGS
from rough_viewer.app.state import (
    MAX_CELL_SIZE,
    MIN_CELL_SIZE,
    MODEL_LABELS,
    Colouring,
    DisplayMode,
    LoadedCloud,
    MapSettings,
    Units,
)
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import (
    AXIS_CHOICES,
    COLOUR_LAYER_LABELS,
    COLOUR_LAYERS,
    AxisChoice,
    ColourLayerName,
    InputError,
    MapName,
)

#: Notify every browser while computing a grid on more points than this.
BIG_CLOUD = 1_000_000

#: Colour-map dropdown: "auto" = the map's own (viridis; magma for e_ols).
COLORMAP_OPTIONS: tuple[str, ...] = ("auto", *colormaps.COLORMAP_NAMES)
MODEL_OPTIONS: tuple[str, ...] = tuple(MODEL_LABELS.values())
MODEL_BY_LABEL: dict[str, MapName] = {label: name for name, label in MODEL_LABELS.items()}
DISPLAY_BY_NAME: dict[str, DisplayMode] = {"continuous": "continuous", "binary": "binary"}
AXIS_BY_NAME: dict[str, AxisChoice] = {a: a for a in AXIS_CHOICES}
LAYER_BY_LABEL: dict[str, ColourLayerName] = {COLOUR_LAYER_LABELS[n]: n for n in COLOUR_LAYERS}
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


def resolve_colormap(choice: str, model: str) -> str:
    """Colour map actually used: ``auto`` -> the map's own
    (:func:`rough_viewer.visual.colormaps.default_colormap`: magma, a sequential map,
    for e_ols; viridis for the roughness maps)."""
    if choice == "auto":
        return colormaps.default_colormap(model)
    return choice


def grid_options(presets: tuple[float, ...], units: Units) -> dict[str, float]:
    """Grid dropdown entries (the presets in the cloud's unit, as text) -> metres.

    >>> grid_options((0.5, 0.25), Units("m"))
    {'0.5': 0.5, '0.25': 0.25}
    """
    return {f"{units.length(g):g}": g for g in presets}


def grid_step(presets: tuple[float, ...], units: Units) -> float:
    """The free grid field's step, in the cloud's unit: the finest preset's third
    significant digit, at most 0.001 (the field shows as many decimals).

    >>> grid_step((0.64, 0.08), Units("m")), grid_step((0.0032, 0.0004), Units("m"))
    (0.0001, 1e-06)
    """
    finest = units.length(min(presets))
    return min(0.001, 10.0 ** (math.floor(math.log10(finest)) - 2)) if finest > 0 else 0.001


def grid_choice(cell_size: float, options: dict[str, float]) -> str:
    """The grid dropdown entry for a cell size (metres): a preset, or ``free``.

    >>> grid_choice(0.25, {"0.5": 0.5, "0.25": 0.25}), grid_choice(0.3, {"0.5": 0.5})
    ('0.25', 'free')
    """
    for text, size in options.items():
        if abs(size - cell_size) <= 1e-9 * max(size, 1e-12):
            return text
    return "free"


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


# ----------------------------------------------------------------------------- the binding

Changes = tuple[tuple[str, object], ...]
"""(control's name on :class:`MapTab`, its value), oldest first."""



class MapBinding(Binding):
    """The Map tab's controls and :class:`~rough_viewer.app.state.MapSettings`."""

    def __init__(self, m: MapTab, presets: tuple[float, ...], units: Units) -> None:
        self.m = m
        self.units = units
        """The unit of the lengths the controls show (the shown cloud's)."""
        self.grid_values = grid_options(presets, units)
        """Grid dropdown entry -> cell size, metres (the shown cloud's presets)."""

    # ------------------------------------------------------------------ read
    def read(self) -> MapSettings:
        """The settings the controls ask for (InputError if a control holds a value
        the app cannot use). Lengths typed in the cloud's unit become metres."""
        m, u = self.m, self.units
        if m.grid.value == "free":
            cell = float(m.grid_free.value) * u.per
        else:
            preset = self.grid_values.get(m.grid.value)
            if preset is None:
                raise InputError("the grid size is not one of this cloud's presets")
            cell = preset
        model = MODEL_BY_LABEL.get(m.model.value)
        axis = AXIS_BY_NAME.get(m.axis.value)
        display = DISPLAY_BY_NAME.get(m.display.value)
        layer = LAYER_BY_LABEL.get(m.layer.value)
        if model is None or axis is None or display is None or layer is None:
            raise InputError("a control holds a value that is not one of its options")
        return MapSettings(cell_size=cell, model=model, axis=axis,
                           min_points=int(m.min_points.value), display=display,
                           threshold=float(m.threshold.value),
                           colormap=resolve_colormap(m.colormap.value, model),
                           stretch=self.read_stretch(), layer=layer,
                           keep_outliers=bool(m.keep_outliers.value))

    def read_stretch(self) -> colormaps.Stretch:
        """The colour stretch the controls ask for: percentiles of the cells, or the
        absolute limits typed in the roughness unit (InputError if unusable)."""
        m = self.m
        log = bool(m.log.value)
        if m.stretch.value == "absolute":
            per = self.units.rough_per
            lo, hi = float(m.range_lo.value), float(m.range_hi.value)
            if log and lo <= 0:
                raise InputError("a log colour scale needs a lowest θ above 0")
            return colormaps.Stretch("absolute", lo * per, hi * per, log=log)
        p_lo, p_hi = (float(v) for v in m.percentiles.value)
        return colormaps.Stretch("percentile", p_lo, p_hi, log=log)

    def settle(self, changes: Changes) -> None:
        """Put each change's value back into its control (the app may have shown
        another since: a colour range after a map), then move the controls that follow
        the last changed one of their group (worker)."""
        m = self.m
        with self.quietly():
            for name, value in changes:
                if name == "toggle":
                    assign(m.model, "OLS" if m.model.value == "ODR" else "ODR")
                elif getattr(m, name).value != value:
                    assign(getattr(m, name), value)
        last = {name: k for k, (name, _value) in enumerate(changes)}
        grid, free = last.get("grid", -1), last.get("grid_free", -1)
        if free > grid:
            self.set(m.grid, "free")
        elif grid >= 0:
            size = self.grid_values.get(m.grid.value)
            if size is not None:
                self.set(m.grid_free, self.units.length(size))
        typed = max(last.get("pct_lo", -1), last.get("pct_hi", -1))
        if typed > last.get("percentiles", -1):  # typed percentiles move the slider
            lo, hi = sorted((float(m.pct_lo.value), float(m.pct_hi.value)))
            self.set(m.percentiles, (lo, hi))
        stretch = {k: last.get(k, -1)
                   for k in ("stretch", "percentiles", "pct_lo", "pct_hi", "range_lo", "range_hi")}
        latest = max(stretch, key=lambda k: stretch[k])
        if stretch[latest] >= 0 and latest != "stretch":
            absolute = latest in ("range_lo", "range_hi")
            self.set(m.stretch, "absolute" if absolute else "percentile")
        self.show_percentiles()

    def show_percentiles(self) -> None:
        """The typed fields show the slider's two ends."""
        lo, hi = (float(v) for v in self.m.percentiles.value)
        self.set(self.m.pct_lo, lo)
        self.set(self.m.pct_hi, hi)

    # ------------------------------------------------------------------ show
    def show(self, settings: MapSettings) -> None:
        """Show ``settings`` in the controls without queuing work (after an error, a
        restored view, or a cloud with other presets)."""
        m, u = self.m, self.units
        with self.quietly():
            assign(m.grid, grid_choice(settings.cell_size, self.grid_values))
            assign(m.grid_free, u.length(settings.cell_size))
            assign(m.model, MODEL_LABELS[settings.model])
            assign(m.keep_outliers, bool(settings.keep_outliers))
            assign(m.axis, settings.axis)
            assign(m.min_points, int(settings.min_points))
            assign(m.display, settings.display)
            assign(m.threshold, float(settings.threshold))
            auto = resolve_colormap("auto", settings.model)
            assign(m.colormap, "auto" if settings.colormap == auto else settings.colormap)
            label = COLOUR_LAYER_LABELS[settings.layer]
            if label in m.layer.options:
                assign(m.layer, label)
            st = settings.stretch
            assign(m.stretch, st.mode)
            assign(m.log, bool(st.log))
            if st.mode == "absolute":
                for handle, metres in ((m.range_lo, st.lo), (m.range_hi, st.hi)):
                    value = round_limit(u.rough(metres))
                    handle.step = limit_step(value)
                    assign(handle, value)
            else:
                assign(m.percentiles, (float(st.lo), float(st.hi)))
        self.show_percentiles()

    def show_range(self, colour_range: colormaps.ColourRange) -> None:
        """Put the roughness range the colours span into the lowest/highest fields
        (roughness unit, 3 digits), so switching to an absolute stretch pins it."""
        m, u = self.m, self.units
        lo, hi = round_limit(u.rough(colour_range.lo)), round_limit(u.rough(colour_range.hi))
        if hi <= lo:
            return
        with self.quietly():
            # the fields show as many decimals as their step has: 3 digits of each
            for handle, value in ((m.range_lo, lo), (m.range_hi, hi)):
                handle.step = limit_step(value)
                assign(handle, value)

    def follow(self, loaded: LoadedCloud, point_size: float) -> None:
        """The grid presets, unit labels, colour layers and point-size range of a
        new cloud (without queuing work)."""
        m = self.m
        u = loaded.units
        assert loaded.presets is not None
        self.units = u
        self.grid_values = grid_options(loaded.presets, u)
        with self.quietly():
            m.grid.options = (*self.grid_values, "free")
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


@dataclass(eq=False)
class MapTab:
    """The Map tab (handles, its binding) and the map's record of what it showed
    (the mounted feature, :class:`~rough_viewer.app.features.map.MapFeature`, is one)."""

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
        self.binding.write(self.colour_bar, visible=False)
        self.host.scene.colour_by(colouring)

    def give_back_overlay(self, owner: object) -> None:
        """``owner`` no longer colours the points: the map's colours and colour bar
        come back (worker)."""
        if self.overlay is owner:
            self.overlay, self._release = None, lambda: None
            self.binding.write(self.colour_bar, visible=True)
            if self.colouring is not None:
                self.host.scene.colour_by(self.colouring)

    def forget_pick(self, text: str) -> None:
        """Drop the clicked point's marker, report and across-scales plot; the click
        report then reads ``text`` (worker)."""
        self.host.scene.remove(self.pick_nodes)
        self.pick_nodes = []
        self.host.session.forget_pick()
        self.binding.write(self.pick, content=text)
        self.binding.show_figure(self.scales, scales_placeholder())

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        return {"colour_bar": self.colour_bar,
                "scales": self.scales}


#: Largest "Min points per cell" the Map tab's control takes.
MAX_MIN_POINTS = 100_000

