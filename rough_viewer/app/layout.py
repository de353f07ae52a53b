"""The viser GUI: which controls exist, their labels, ranges and order.

:func:`build_gui` only creates widgets (on the server-level ``server.gui``, so
every browser tab shares them); :mod:`rough_viewer.app.server` wires them to the
worker. Labels here are what users and the browser tests look for.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

import plotly.graph_objects as go
import viser

from rough_viewer.app.state import (
    MAX_CELL_SIZE,
    MIN_CELL_SIZE,
    MODEL_LABELS,
    DisplayMode,
    Units,
    ViewSettings,
)
from rough_viewer.visual import colormaps
from rough_viewer.visual.app import PANEL_WIDTH, panel_aspect
from rough_viewer.vocabulary import (
    AXIS_CHOICES,
    COLOUR_LAYER_LABELS,
    COLOUR_LAYERS,
    UNITS,
    AxisChoice,
    ColourLayerName,
    MapName,
)

if TYPE_CHECKING:
    from viser._gui_handles import GuiProgressBarHandle

#: Width of the control panel, px: its plots are about PANEL_WIDTH + 60 px wide
#: less the panel's padding (issue 13: at least ~480 px at a 1600 x 1000 window).
CONTROL_WIDTH = PANEL_WIDTH + 80
#: Colour-map dropdown: "auto" = the map's own (viridis; magma for e_ols).
COLORMAP_OPTIONS: tuple[str, ...] = ("auto", *colormaps.COLORMAP_NAMES)
MODEL_OPTIONS: tuple[str, ...] = tuple(MODEL_LABELS.values())
MODEL_BY_LABEL: dict[str, MapName] = {label: name for name, label in MODEL_LABELS.items()}
DISPLAY_BY_NAME: dict[str, DisplayMode] = {"continuous": "continuous", "binary": "binary"}
DISPLAY_OPTIONS: tuple[str, ...] = tuple(DISPLAY_BY_NAME)
AXIS_BY_NAME: dict[str, AxisChoice] = {a: a for a in AXIS_CHOICES}
AXIS_OPTIONS: tuple[str, ...] = tuple(AXIS_BY_NAME)
LAYER_BY_LABEL: dict[str, ColourLayerName] = {COLOUR_LAYER_LABELS[n]: n for n in COLOUR_LAYERS}
#: Colour stretch dropdown: robust percentiles of the cells, or absolute limits.
STRETCH_OPTIONS: tuple[str, ...] = colormaps.STRETCH_MODES
#: Camera presets (button group).
VIEW_OPTIONS: tuple[str, ...] = ("face-on", "top", "side")
#: File tab's unit choice: "auto" = the CRS's unit of a LAS file, else metres.
UNIT_OPTIONS: tuple[str, ...] = ("auto", *UNITS)

#: Labels (the browser tests find controls by these). Labels with a unit are made
#: by the functions below (the unit is the loaded cloud's).
#: Plotly options of every panel: no mode bar (it covered the plots' titles at the top
#: right; dragging still zooms, a double click resets, and the Export folder saves
#: figures), no plotly logo.
PLOTLY_CONFIG: dict[str, object] = {"displayModeBar": False, "displaylogo": False}

L_MODEL = "Model"
L_AXIS = "Dependent axis"
L_DISPLAY = "Display"
L_THRESHOLD = "Threshold"
L_MIN_POINTS = "Min points per cell"
L_POINT_SIZE = "Point size"
L_COLORMAP = "Colour map"
L_LAYER = "Colour by"
L_STRETCH = "Colour stretch"
L_LOG = "Log colour scale"
L_PERCENTILES = "Percentiles"
L_TOGGLE = "Toggle ODR / OLS"
L_SHOW_AXIS = "Show dependent axis"
L_VIEW = "View"
L_PATH = "File path"
L_UNITS = "Units"
L_LOAD = "Load file"
L_UPLOAD = "Upload file"
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


METRES = Units("m")

#: The labels of a metric cloud (what most tests use).
L_GRID = l_grid(METRES)
L_GRID_FREE = l_grid_free(METRES)
L_RANGE_LO = l_range_lo(METRES)
L_RANGE_HI = l_range_hi(METRES)


T = TypeVar("T")


def assign(handle: Any, value: T) -> None:
    """Set a GUI handle's value (its callbacks run at once, on this thread).

    viser 1.1's type hints make ``handle.value`` read-only for mypy although
    viser assigns it at run time; this one function is where the app does.
    """
    setattr(handle, "value", value)  # noqa: B010 - see the docstring


@contextlib.contextmanager
def quietly(local: threading.local) -> Iterator[None]:
    """Set controls inside the block without their callbacks queuing work: the
    callbacks see ``local.syncing`` True on this thread (nested blocks keep it)."""
    before = bool(getattr(local, "syncing", False))
    local.syncing = True
    try:
        yield
    finally:
        local.syncing = before


def resolve_colormap(choice: str, model: str) -> str:
    """Colour map actually used: ``auto`` -> the map's own
    (:func:`rough_viewer.visual.colormaps.default_colormap`: magma, a sequential map,
    for e_ols; viridis for the roughness maps)."""
    if choice == "auto":
        return colormaps.default_colormap(model)
    return choice


def grid_options(presets: tuple[float, ...], units: Units) -> dict[str, float]:
    """Grid dropdown entries (the presets in the cloud's unit, as text) -> metres."""
    return {f"{units.length(g):g}": g for g in presets}


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


def _empty_figure(title: str) -> go.Figure:
    fig = go.Figure()
    fig.update_layout(title=dict(text=title, font=dict(size=12)), height=200,
                      margin=dict(l=10, r=10, t=30, b=10))
    return fig


@dataclass
class Gui:
    """Handles of every control and panel."""

    status: viser.GuiMarkdownHandle
    error: viser.GuiMarkdownHandle
    notice: viser.GuiMarkdownHandle
    """Warnings that stay (reader warnings, a grid where most cells have no value)."""
    progress: GuiProgressBarHandle
    colour_bar: viser.GuiPlotlyHandle
    layer: viser.GuiDropdownHandle[str]
    grid: viser.GuiDropdownHandle[str]
    grid_free: viser.GuiNumberHandle[float]
    model: viser.GuiDropdownHandle[str]
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
    range_lo: viser.GuiNumberHandle[float]
    range_hi: viser.GuiNumberHandle[float]
    point_size: viser.GuiSliderHandle[float]
    camera: viser.GuiButtonGroupHandle
    pick: viser.GuiMarkdownHandle
    scales: viser.GuiPlotlyHandle
    """Roughness of the clicked point's cells against grid size (a placeholder until
    a click)."""
    histogram: viser.GuiPlotlyHandle
    variogram: viser.GuiPlotlyHandle
    summary: viser.GuiPlotlyHandle
    face_scales: viser.GuiPlotlyHandle
    """Whole-face mean roughness and binary share against grid size."""
    path: viser.GuiTextHandle
    units: viser.GuiDropdownHandle[str]
    load: viser.GuiButtonHandle
    upload: viser.GuiUploadButtonHandle
    tabs: viser.GuiTabGroupHandle
    grid_values: dict[str, float]
    """Grid dropdown entry -> cell size in metres (the loaded cloud's presets)."""
    length_units: Units
    """Units of the labels now shown."""

    def inputs(self) -> tuple[Any, ...]:
        """The controls a browser may set (the upload button sends files instead)."""
        return (self.layer, self.grid, self.grid_free, self.model, self.toggle, self.axis,
                self.show_axis, self.display, self.threshold, self.min_points,
                self.point_size, self.colormap, self.stretch, self.log, self.percentiles,
                self.range_lo, self.range_hi, self.camera, self.path, self.units, self.load)


def build_gui(
    server: viser.ViserServer,
    settings: ViewSettings,
    *,
    point_size: float,
    source: str,
    presets: tuple[float, ...],
    units: Units = METRES,
    layers: tuple[ColourLayerName, ...] = ("roughness", "distance"),
    file_units: str = "auto",
    upload_limit: str = "",
) -> Gui:
    """Create the controls (initial values from ``settings``) and empty panels.

    The control panel floats at the top right and is :data:`CONTROL_WIDTH` px wide,
    so every plot in it is at least :data:`rough_viewer.visual.app.PANEL_WIDTH` px
    wide; the person can move or minimise it. (Docking it, viser's other layout,
    makes its plotly panels throw errors in the browser when the page loads.)
    """
    gui = server.gui
    gui.configure_theme(control_width="large", show_share_button=False)
    gui.main_panel.set_width(CONTROL_WIDTH)
    status = gui.add_markdown("Loading…")
    error = gui.add_markdown("", visible=False)
    notice = gui.add_markdown("", visible=False)
    progress = gui.add_progress_bar(0.0, visible=False, animated=True)
    colour_bar = gui.add_plotly(_empty_figure("colour bar"), config=PLOTLY_CONFIG,
                                aspect=0.27)  # height = width * aspect
    values = grid_options(presets, units)
    preset = f"{units.length(settings.cell_size):g}"
    lo_mm, hi_mm = _absolute_limits(settings.stretch, units)

    tabs = gui.add_tab_group()
    with tabs.add_tab("Map"):
        # what a click reports comes first: it is what the person looks for next
        pick = gui.add_markdown(PICK_PROMPT)
        # never hidden: viser's client fails to lay out a plot that was created hidden
        placeholder = scales_placeholder()
        scales = gui.add_plotly(placeholder, config=PLOTLY_CONFIG, aspect=panel_aspect(placeholder))
        layer = gui.add_dropdown(
            L_LAYER, tuple(COLOUR_LAYER_LABELS[n] for n in layers),
            initial_value=COLOUR_LAYER_LABELS[settings.layer if settings.layer in layers
                                              else "roughness"],
            hint="The roughness map, or the rock itself: scan colours, intensity, or "
            "the distance to the whole-cloud face plane.")
        grid = gui.add_dropdown(
            l_grid(units), (*values, "free"),
            initial_value=preset if preset in values else "free",
            hint="Cell edge of the roughness grid: presets from the point spacing "
            "(the finest holds about 16 points in a typical cell); 'free' uses the "
            "number below.",
        )
        grid_free = gui.add_number(
            l_grid_free(units), units.length(settings.cell_size),
            min=units.length(MIN_CELL_SIZE), max=units.length(MAX_CELL_SIZE), step=0.001,
            hint="Any cell size (switches the grid size to 'free').",
        )
        model = gui.add_dropdown(L_MODEL, MODEL_OPTIONS, initial_value=MODEL_LABELS[settings.model])
        toggle = gui.add_button(L_TOGGLE, hint="Same cells, other reference plane.")
        axis = gui.add_dropdown(L_AXIS, AXIS_OPTIONS, initial_value=settings.axis,
                                hint="Dependent variable of the OLS and hybrid fits.")
        axis_note = gui.add_markdown("")
        show_axis = gui.add_checkbox(L_SHOW_AXIS, True)
        display = gui.add_dropdown(L_DISPLAY, DISPLAY_OPTIONS, initial_value=settings.mode)
        threshold = gui.add_slider(L_THRESHOLD, min=0.0, max=1.0, step=0.01,
                                   initial_value=settings.threshold,
                                   hint="Binary view: cells with normalised roughness ≥ this are rough.")
        min_points = gui.add_number(L_MIN_POINTS, int(settings.min_points), min=3, max=100000, step=1)
        colormap = gui.add_dropdown(L_COLORMAP, COLORMAP_OPTIONS, initial_value="auto",
                                    hint="auto: viridis for roughness, magma for e_ols.")
        st = settings.stretch
        stretch = gui.add_dropdown(
            L_STRETCH, STRETCH_OPTIONS, initial_value=st.mode,
            hint="percentile: the colours span these percentiles of the cells (robust "
            "to a few extreme cells); absolute: fixed limits, so one colour means one "
            "roughness on every grid and file.")
        log = gui.add_checkbox(L_LOG, bool(st.log),
                               hint="Equal ratios of roughness get equal colour steps.")
        percentiles = gui.add_multi_slider(
            L_PERCENTILES, min=0.0, max=100.0, step=0.5, min_range=1.0,
            initial_value=(st.lo, st.hi) if st.mode == "percentile" else (2.0, 98.0),
            hint="Percentiles of the cells with a value at the first and last colour.")
        range_lo = gui.add_number(l_range_lo(units), lo_mm, min=0.0, max=1e9, step=0.001,
                                  hint="Roughness at the first colour; typing here pins "
                                  "the colours (absolute stretch).")
        range_hi = gui.add_number(l_range_hi(units), hi_mm, min=0.0, max=1e9, step=0.001,
                                  hint="Roughness at the last colour (absolute stretch).")
        size_handle = gui.add_slider(L_POINT_SIZE, min=point_size / 10, max=point_size * 10,
                                     step=point_size / 10, initial_value=point_size)
        camera = gui.add_button_group(L_VIEW, VIEW_OPTIONS,
                                      hint="Look at the face straight on, from above, "
                                      "or from the side.")
    with tabs.add_tab("Panels"):
        histogram = gui.add_plotly(_empty_figure("histogram"), config=PLOTLY_CONFIG, aspect=0.85)
        variogram = gui.add_plotly(_empty_figure("semivariogram"), config=PLOTLY_CONFIG, aspect=0.81)
        summary = gui.add_plotly(_empty_figure("summary"), config=PLOTLY_CONFIG, aspect=0.44)
        face_scales = gui.add_plotly(_empty_figure("roughness against grid size"),
                                     config=PLOTLY_CONFIG, aspect=1.16)
    with tabs.add_tab("File"):
        path = gui.add_text(L_PATH, source,
                            hint="A file in the server's data folder (--data-dir); relative "
                            "paths start there.")
        unit_choice = gui.add_dropdown(
            L_UNITS, UNIT_OPTIONS, initial_value=file_units,
            hint="Unit of the file's coordinates: auto = the unit of a LAS file's CRS, "
            "else metres.")
        load = gui.add_button(L_LOAD)
        upload = gui.add_upload_button(
            L_UPLOAD, hint=f"Send a point-cloud file from this computer{upload_limit}.")
    return Gui(status=status, error=error, notice=notice, progress=progress,
               colour_bar=colour_bar, layer=layer, grid=grid, grid_free=grid_free,
               model=model, toggle=toggle, axis=axis, axis_note=axis_note,
               show_axis=show_axis, display=display, threshold=threshold,
               min_points=min_points, colormap=colormap, stretch=stretch, log=log,
               percentiles=percentiles, range_lo=range_lo, range_hi=range_hi,
               point_size=size_handle, camera=camera, pick=pick, scales=scales,
               histogram=histogram, variogram=variogram, summary=summary,
               face_scales=face_scales, path=path, units=unit_choice, load=load,
               upload=upload, tabs=tabs, grid_values=values, length_units=units)


def _absolute_limits(stretch: colormaps.Stretch, units: Units) -> tuple[float, float]:
    """The lowest and highest roughness fields' first values (roughness unit)."""
    if stretch.mode == "absolute":
        return round_limit(units.rough(stretch.lo)), round_limit(units.rough(stretch.hi))
    return 0.0, 0.0


def limit_step(value: float) -> float:
    """The step of a colour-limit field holding ``value``: its third significant
    digit (the field shows as many decimals as its step has), at most 0.001.

    >>> limit_step(6.22), limit_step(0.00131), limit_step(0.0)
    (0.001, 1e-05, 0.001)
    """
    v = abs(float(value))
    if not v or v != v:
        return 0.001
    return min(0.001, 10.0 ** (math.floor(math.log10(v)) - 2))


def round_limit(value: float) -> float:
    """A colour limit as typed: 3 significant digits (0 and NaN stay 0)."""
    v = float(value)
    return float(f"{v:.3g}") if v == v and v != 0 else 0.0
