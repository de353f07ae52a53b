"""The viser GUI: which controls exist, their labels, ranges and order.

:func:`build_gui` only creates widgets (on the server-level ``server.gui``, so
every browser tab shares them); :mod:`rough_viewer.app.server` wires them to the
worker. Labels here are what users and the browser tests look for.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

import plotly.graph_objects as go
import viser

from rough_viewer.app.state import (
    MIN_CELL_SIZE,
    MODEL_LABELS,
    PRESET_CELL_SIZES,
    DisplayMode,
    ViewSettings,
)
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import AXIS_CHOICES, AxisChoice, MapName

if TYPE_CHECKING:
    from viser._gui_handles import GuiProgressBarHandle

#: Grid-size dropdown entries: the presets as text, then "free" (use the number field).
GRID_PRESET_OPTIONS: tuple[str, ...] = tuple(f"{g:g}" for g in PRESET_CELL_SIZES) + ("free",)
#: Colour-map dropdown: "auto" = viridis for roughness, coolwarm (diverging) for e_ols.
COLORMAP_OPTIONS: tuple[str, ...] = ("auto", *colormaps.COLORMAP_NAMES)
MODEL_OPTIONS: tuple[str, ...] = tuple(MODEL_LABELS.values())
MODEL_BY_LABEL: dict[str, MapName] = {label: name for name, label in MODEL_LABELS.items()}
DISPLAY_BY_NAME: dict[str, DisplayMode] = {"continuous": "continuous", "binary": "binary"}
DISPLAY_OPTIONS: tuple[str, ...] = tuple(DISPLAY_BY_NAME)
AXIS_BY_NAME: dict[str, AxisChoice] = {a: a for a in AXIS_CHOICES}
AXIS_OPTIONS: tuple[str, ...] = tuple(AXIS_BY_NAME)

#: Labels (the browser tests find controls by these).
L_GRID = "Grid size (m)"
L_GRID_FREE = "Free grid size (m)"
L_MODEL = "Model"
L_AXIS = "Dependent axis"
L_DISPLAY = "Display"
L_THRESHOLD = "Threshold"
L_MIN_POINTS = "Min points per cell"
L_POINT_SIZE = "Point size"
L_COLORMAP = "Colour map"
L_CLIP = "Colour range"
L_TOGGLE = "Toggle ODR / OLS"
L_SHOW_AXIS = "Show dependent axis"
L_PATH = "File path"
L_LOAD = "Load file"
L_UPLOAD = "Upload file"


T = TypeVar("T")


def assign(handle: Any, value: T) -> None:
    """Set a GUI handle's value (its callbacks run at once, on this thread).

    viser 1.1's type hints make ``handle.value`` read-only for mypy although
    viser assigns it at run time; this one function is where the app does.
    """
    setattr(handle, "value", value)  # noqa: B010 - see the docstring


def resolve_colormap(choice: str, model: str) -> str:
    """Colour map actually used: ``auto`` -> coolwarm for e_ols, viridis otherwise."""
    if choice == "auto":
        return "coolwarm" if model == "e_ols" else "viridis"
    return choice


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
    progress: GuiProgressBarHandle
    colour_bar: viser.GuiPlotlyHandle
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
    point_size: viser.GuiSliderHandle[float]
    colormap: viser.GuiDropdownHandle[str]
    clip: viser.GuiMultiSliderHandle[float]
    pick: viser.GuiMarkdownHandle
    histogram: viser.GuiPlotlyHandle
    variogram: viser.GuiPlotlyHandle
    summary: viser.GuiPlotlyHandle
    path: viser.GuiTextHandle
    load: viser.GuiButtonHandle
    upload: viser.GuiUploadButtonHandle
    tabs: viser.GuiTabGroupHandle

    def inputs(self) -> tuple[Any, ...]:
        """The controls a browser may set (the upload button sends files instead)."""
        return (self.grid, self.grid_free, self.model, self.toggle, self.axis,
                self.show_axis, self.display, self.threshold, self.min_points,
                self.point_size, self.colormap, self.clip, self.path, self.load)


def build_gui(
    server: viser.ViserServer,
    settings: ViewSettings,
    *,
    point_size: float,
    source: str,
    upload_limit: str = "",
) -> Gui:
    """Create the controls (initial values from ``settings``) and empty panels."""
    gui = server.gui
    gui.configure_theme(control_width="large", show_share_button=False)
    status = gui.add_markdown("Loading…")
    error = gui.add_markdown("", visible=False)
    progress = gui.add_progress_bar(0.0, visible=False, animated=True)
    colour_bar = gui.add_plotly(_empty_figure("colour bar"), aspect=0.34)  # viser 1.1: height = width * aspect

    tabs = gui.add_tab_group()
    with tabs.add_tab("Map"):
        preset = f"{settings.cell_size:g}"
        grid = gui.add_dropdown(
            L_GRID, GRID_PRESET_OPTIONS,
            initial_value=preset if preset in GRID_PRESET_OPTIONS else "free",
            hint="Cell edge of the roughness grid; 'free' uses the number below.",
        )
        grid_free = gui.add_number(
            L_GRID_FREE, float(settings.cell_size), min=MIN_CELL_SIZE, max=100.0, step=0.001,
            hint="Any cell size in metres (switches the grid size to 'free').",
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
        colormap = gui.add_dropdown(L_COLORMAP, COLORMAP_OPTIONS, initial_value="auto")
        clip = gui.add_multi_slider(L_CLIP, min=0.0, max=1.0, step=0.01,
                                    initial_value=tuple(settings.clip), min_range=0.01,
                                    hint="Normalised roughness spread over the colour map.")
        size_handle = gui.add_slider(L_POINT_SIZE, min=point_size / 10, max=point_size * 10,
                                     step=point_size / 10, initial_value=point_size)
        pick = gui.add_markdown("Click a point to see its cell.")
    with tabs.add_tab("Panels"):
        histogram = gui.add_plotly(_empty_figure("histogram"), aspect=0.95)
        variogram = gui.add_plotly(_empty_figure("semivariogram"), aspect=0.95)
        summary = gui.add_plotly(_empty_figure("summary"), aspect=0.75)
    with tabs.add_tab("File"):
        path = gui.add_text(L_PATH, source,
                            hint="A file in the server's data folder (--data-dir); relative "
                            "paths start there.")
        load = gui.add_button(L_LOAD)
        upload = gui.add_upload_button(
            L_UPLOAD, hint=f"Send a point-cloud file from this computer{upload_limit}.")
    return Gui(status, error, progress, colour_bar, grid, grid_free, model, toggle, axis,
               axis_note, show_axis, display, threshold, min_points, size_handle, colormap,
               clip, pick, histogram, variogram, summary, path, load, upload, tabs)
