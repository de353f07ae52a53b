"""The Map tab's handles, their labels, and the binding between them and
:class:`~rough_viewer.app.settings.MapSettings`."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import plotly.graph_objects as go
import viser

from rough_viewer.app.binding import Binding, assign
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import Colouring
from rough_viewer.app.host import Host
from rough_viewer.app.layout import limit_step
from rough_viewer.app.limits import MAX_TIMINGS
from rough_viewer.app.settings import (
    FORM_FIELDS,
    MAX_CELL_SIZE,
    MIN_CELL_SIZE,
    MODEL_LABELS,
    Change,
    GridChoices,
    MapForm,
    MapSettings,
    form_of,
    round_limit,
    settings_of,
    settle,
)
from rough_viewer.app.units import Units
from rough_viewer.app.worker import require_a_worker
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import COLOUR_LAYER_LABELS, InputError

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


# ----------------------------------------------------------------------------- the binding

Changes = tuple[Change, ...]
"""(control's name on :class:`MapTab`, its value), oldest first."""


class MapBinding(Binding):
    """Between the Map tab's controls and :class:`~rough_viewer.app.settings.MapForm`:
    it copies the controls into a form and a form into the controls, and nothing
    else; what a change means (the twin controls, the settings asked for) is
    :mod:`rough_viewer.app.settings`' pure functions."""

    def __init__(self, m: MapTab, presets: tuple[float, ...], units: Units) -> None:
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
        limit's step follows its value; worker)."""
        require_a_worker("the Map tab's controls")
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
        require_a_worker("the Map tab's controls")
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
    previews: deque[dict[str, object]] = field(default_factory=lambda: deque(maxlen=MAX_TIMINGS))
    """One record per coarse map shown while a slow first grid was computed
    (:func:`~.render.render_stages`): its ``cell_size``, the grid it stood ``for`` and
    when it was coloured (``at``, :func:`time.perf_counter`)."""
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

