"""The Map tab's controls: added, and wired so that each submits a job."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

import viser

from rough_viewer.app import scene as scene_mod
from rough_viewer.app.detail import BudgetJob, CameraJob, CameraWatch
from rough_viewer.app.features.map.binding import (
    CAMERA_PRESETS,
    COLORMAP_OPTIONS,
    L_AXIS,
    L_BUDGET,
    L_CAMERA,
    L_COLORMAP,
    L_DISPLAY,
    L_KEEP_OUTLIERS,
    L_LAYER,
    L_LOG,
    L_MIN_POINTS,
    L_MODEL,
    L_PCT_HI,
    L_PCT_LO,
    L_PERCENTILES,
    L_POINT_SIZE,
    L_SHOW_AXIS,
    L_STRETCH,
    L_THRESHOLD,
    L_TOGGLE,
    MAX_BUDGET,
    MAX_MIN_POINTS,
    MIN_BUDGET,
    MODEL_OPTIONS,
    PERCENTILE_MARKS,
    PICK_PROMPT,
    MapBinding,
    MapTab,
    grid_step,
    l_grid,
    l_grid_free,
    l_range_hi,
    l_range_lo,
    scales_placeholder,
)
from rough_viewer.app.features.map.pick import PickJob, valid_ray
from rough_viewer.app.features.map.render import RenderJob
from rough_viewer.app.host import Host
from rough_viewer.app.layout import PLOTLY_CONFIG, empty_figure
from rough_viewer.app.settings import (
    AXIS_BY_NAME,
    DISPLAY_BY_NAME,
    FORM_FIELDS,
    MAX_CELL_SIZE,
    MIN_CELL_SIZE,
    GridChoices,
    MapForm,
    form_of,
    grid_options,
)
from rough_viewer.app.worker import Job, Run
from rough_viewer.visual import colormaps
from rough_viewer.visual.app import (
    panel_aspect,
)
from rough_viewer.vocabulary import (
    COLOUR_LAYER_LABELS,
)

# ----------------------------------------------------------------------------- scene


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


# ----------------------------------------------------------------------------- mount


M = TypeVar("M", bound=MapTab)


def add_controls(host: Host, kind: type[M]) -> M:
    """The colour bar above the tabs and the Map tab's controls, as a ``kind``
    (the mounted feature); browsers may set them."""
    gui = host.gui
    loaded = host.session.shown.loaded
    assert loaded.presets is not None
    colour_bar = gui.add_plotly(empty_figure("colour bar"), config=PLOTLY_CONFIG,
                                aspect=0.27)  # height = width * aspect
    with host.tab("Map"):
        # what a click reports comes first: it is what the person looks for next
        pick = gui.add_markdown(PICK_PROMPT)
        # never hidden: viser's client fails to lay out a plot that was created hidden
        placeholder = scales_placeholder()
        scales = gui.add_plotly(placeholder, config=PLOTLY_CONFIG, aspect=panel_aspect(placeholder))
        form = _first_form(host)
        handles = {**_grid_controls(host, form), **_colour_controls(host, form),
                   **_view_controls(host)}
        m = kind(host=host, colour_bar=colour_bar, pick=pick, scales=scales, **handles)
    m.binding = MapBinding(m, loaded.presets, loaded.units)
    host.allow(*m.inputs())
    return m


def _first_form(host: Host) -> MapForm:
    """What the Map tab's controls hold first: the shown settings as a form
    (:func:`rough_viewer.app.settings.form_of`, the rule every later show follows)."""
    loaded, settings = host.session.shown.loaded, host.session.shown.settings
    assert loaded.presets is not None
    layers = tuple(COLOUR_LAYER_LABELS[n] for n in loaded.layers)
    return form_of(settings, GridChoices.of(loaded.presets, loaded.units), MapForm(),
                   layers=layers)


def _grid_controls(host: Host, form: MapForm) -> dict[str, Any]:
    """What colours the points, the grid, the model, its axis and the binary view."""
    gui = host.gui
    loaded = host.session.shown.loaded
    units = loaded.units
    assert loaded.presets is not None
    values = grid_options(loaded.presets, units)
    return dict(
        layer=gui.add_dropdown(
            L_LAYER, tuple(COLOUR_LAYER_LABELS[n] for n in loaded.layers),
            initial_value=form.layer,
            hint="The roughness map, or the rock itself: scan colours, intensity, or "
            "the distance to the whole-cloud face plane."),
        grid=gui.add_dropdown(
            l_grid(units), (*values, "free"), initial_value=form.grid,
            hint="Cell edge of the roughness grid: presets from the point spacing "
            "(the finest holds about 16 points in a typical cell); 'free' uses the "
            "number below."),
        grid_free=gui.add_number(
            l_grid_free(units), form.grid_free,
            min=units.length(MIN_CELL_SIZE), max=units.length(MAX_CELL_SIZE),
            step=grid_step(loaded.presets, units),
            hint="Any cell size (switches the grid size to 'free')."),
        model=gui.add_dropdown(L_MODEL, MODEL_OPTIONS, initial_value=form.model),
        keep_outliers=gui.add_checkbox(
            L_KEEP_OUTLIERS, form.keep_outliers,
            hint="Hybrid or OLS roughness larger than the cell (a plane nearly along "
            "the dependent axis) is an outlier of the definition, not rock: left "
            "out of the colours, panels and zones and drawn in cyan unless kept."),
        toggle=gui.add_button(L_TOGGLE, hint="Same cells, other reference plane."),
        axis=gui.add_dropdown(L_AXIS, tuple(AXIS_BY_NAME), initial_value=form.axis,
                              hint="Dependent variable of the OLS and hybrid fits."),
        axis_note=gui.add_markdown(""),
        show_axis=gui.add_checkbox(L_SHOW_AXIS, True),
        display=gui.add_dropdown(L_DISPLAY, tuple(DISPLAY_BY_NAME),
                                 initial_value=form.display),
        threshold=gui.add_slider(
            L_THRESHOLD, min=0.0, max=1.0, step=0.01, initial_value=form.threshold,
            hint="Binary view: cells with normalised roughness ≥ this are rough."),
        min_points=gui.add_number(L_MIN_POINTS, form.min_points, min=3,
                                  max=MAX_MIN_POINTS, step=1),
    )


def _colour_controls(host: Host, form: MapForm) -> dict[str, Any]:
    """The colour map and its stretch: percentiles (slider and typed) or limits."""
    gui = host.gui
    units = host.session.shown.loaded.units
    return dict(
        colormap=gui.add_dropdown(L_COLORMAP, COLORMAP_OPTIONS, initial_value=form.colormap,
                                  hint="auto: viridis for roughness, magma for e_ols."),
        stretch=gui.add_dropdown(
            L_STRETCH, colormaps.STRETCH_MODES, initial_value=form.stretch,
            hint="percentile: the colours span these percentiles of the cells (robust "
            "to a few extreme cells); absolute: fixed limits, so one colour means one "
            "roughness on every grid and file."),
        log=gui.add_checkbox(L_LOG, form.log,
                             hint="Equal ratios of roughness get equal colour steps."),
        percentiles=gui.add_multi_slider(
            L_PERCENTILES, min=0.0, max=100.0, step=0.5, min_range=1.0,
            initial_value=form.percentiles, marks=PERCENTILE_MARKS,
            hint="Percentiles of the cells with a value at the first and last colour."),
        pct_lo=gui.add_number(L_PCT_LO, form.pct_lo, min=0.0, max=100.0, step=0.5,
                              hint="The percentile at the first colour (typed)."),
        pct_hi=gui.add_number(L_PCT_HI, form.pct_hi, min=0.0, max=100.0, step=0.5,
                              hint="The percentile at the last colour (typed)."),
        range_lo=gui.add_number(l_range_lo(units), form.range_lo, min=0.0, max=1e9, step=0.001,
                                hint="Roughness at the first colour; typing here pins "
                                "the colours (absolute stretch)."),
        range_hi=gui.add_number(l_range_hi(units), form.range_hi, min=0.0, max=1e9, step=0.001,
                                hint="Roughness at the last colour (absolute stretch)."),
    )


def _view_controls(host: Host) -> dict[str, Any]:
    """The point size, the point budget and the camera presets."""
    gui = host.gui
    point_size = scene_mod.default_point_size(host.session.shown.loaded)
    return dict(
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


def wire(host: Host, m: MapTab) -> None:
    """Every control submits a job naming itself; clicks on the scene submit a pick."""
    b = m.binding
    names = (*FORM_FIELDS, "toggle")  # every control of the form, and the toggle
    by_handle = {id(getattr(m, n)): n for n in names}
    b.on_change([getattr(m, n) for n in names], lambda handle: host.submit(
        RenderJob(m, changes=((by_handle[id(handle)], handle.value),))))
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
