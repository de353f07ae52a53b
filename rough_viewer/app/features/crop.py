"""The Select tab: select points on the rock, measure their plane, crop the cloud.

- **Select**: Shift-drag a rectangle over the rock. Every point of the cloud (not
  only those a tab draws) whose projection falls in the rectangle, through the whole
  depth, is selected (:func:`rough_viewer.lod.camera.rect_select`, from the camera of
  the tab that dragged it) and drawn in magenta over the map, with its bounding box.
- **Plane of the selection**: its ODR plane, dip, dip direction and RMS residual
  (:func:`rough_viewer.grid.measure.region_plane`; the conventions of docs/zones.md).
- **Crop**: "Keep selection" keeps the points in the selection's bounding box,
  "Crop to selection (exact points)" exactly the selected points (the box of a
  selection holds more: 239,125 points for a selection of 226,861), "Remove
  selection" drops the box's points; a box typed as ``compute --crop`` takes
  (``xmin,ymin,zmin,xmax,ymax,zmax`` in the cloud's unit) does the same. Every
  analysis (the map, panels, zones, sets, profiles, bias, exports) then runs on the
  kept points, and saved views hold the crop, which ``compute``, ``report`` and
  ``zones --crop-file`` read. One crop at a time: a new crop is applied to the whole
  cloud and replaces the last (a saved view and ``--crop`` hold one box). "Undo crop"
  shows every point again, with the whole cloud's grids still cached.

The crop is a box, not the rectangle itself, so that ``--crop`` gives the same cells;
an exact crop is the selection's points, and a saved view (and ``--crop-file``)
holds their bounding box, which the Select tab says.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import Colouring
from rough_viewer.app.host import Host
from rough_viewer.app.markup import md
from rough_viewer.app.session import Selection
from rough_viewer.app.units import Units
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.measure import PlaneMeasure, region_plane
from rough_viewer.io.crop import CROP_MODES, CropBox, CropMode, parse_box
from rough_viewer.lod.camera import ViewCamera, rect_select
from rough_viewer.memory import require
from rough_viewer.report.view import SelectionView, View
from rough_viewer.vocabulary import InputError

L_KEEP = "Keep selection"
L_EXACT = "Crop to selection (exact points)"
L_REMOVE = "Remove selection"
L_CLEAR = "Clear selection"
L_BOX = "Crop box"
L_MODE = "Crop mode"
L_APPLY = "Apply crop box"
L_UNDO = "Undo crop"
PROMPT = ("**Shift-drag** a rectangle over the rock to select every point under it "
          "(through the whole depth).")
#: Colour of the selected points.
HIGHLIGHT = np.array([255, 0, 255], dtype=np.uint8)
#: Longest crop box text accepted from a browser, characters.
MAX_BOX_TEXT = 300


def box_text(box: CropBox, units: Units) -> str:
    """A box as ``--crop`` takes it, in the cloud's unit."""
    return ",".join(f"{v / units.per:.6f}".rstrip("0").rstrip(".")
                    for v in (*box.lo, *box.hi))


def plane_text(plane: PlaneMeasure, units: Units) -> str:
    """One line: the plane's dip, dip direction, RMS residual (Markdown)."""
    return (f"**Plane** (ODR, {plane.n_points:,} points): dip {plane.dip_deg:.1f}°, dip "
            f"direction {plane.dip_direction_deg:05.1f}°, RMS residual "
            f"{units.rough(plane.rms_m):.4g} {units.rough_label} (largest "
            f"{units.rough(plane.max_abs_m):.4g} {units.rough_label})")


def crop_text(loaded: LoadedCloud) -> str:
    """What the crop of ``loaded`` kept (Markdown), or that there is none."""
    if loaded.crop is None or loaded.uncropped is None:
        return "No crop: every point is used."
    u = loaded.units
    if loaded.crop_exact:
        return (f"**Cropped to the selection's {loaded.cloud.n:,} points** (exactly; of "
                f"{loaded.uncropped.n_total:,}) used by every analysis. A saved view "
                f"holds their bounding box ({md(box_text(loaded.crop, u))} {u.label}), "
                "which keeps every point in it. A new crop replaces this one.")
    return (f"**{md(loaded.crop.describe(u.per, u.label).capitalize())}**: "
            f"{loaded.cloud.n:,} of {loaded.uncropped.n_total:,} points are used by every "
            "analysis. A new crop replaces this one.")


@dataclass(eq=False)
class CropFeature:
    """The Select tab's controls, the selection and its scene nodes."""

    restore_order: ClassVar[int] = -1
    """A saved view's crop is put back before the other parts (they run on it)."""

    host: Host
    note: viser.GuiMarkdownHandle
    keep: viser.GuiButtonHandle
    exact: viser.GuiButtonHandle
    remove: viser.GuiButtonHandle
    clear: viser.GuiButtonHandle
    box: viser.GuiTextHandle
    mode: viser.GuiDropdownHandle[str]
    apply: viser.GuiButtonHandle
    undo: viser.GuiButtonHandle
    status: viser.GuiMarkdownHandle
    binding: Binding = field(default_factory=Binding)
    nodes: list[viser.SceneNodeHandle] = field(default_factory=list)
    """The selection's bounding box."""

    @property
    def selection(self) -> Selection | None:
        """The points selected on the shown cloud: the session's (it holds the
        analysis), read anywhere."""
        return self.host.session.selection

    @selection.setter
    def selection(self, value: Selection | None) -> None:
        self.host.session.selection = value  # worker only (the session checks)

    # ------------------------------------------------------------------ selection
    def select(self, mask: np.ndarray, made_by: SelectionView | None = None) -> None:
        """Select the shown cloud's points ``mask`` (worker), made by ``made_by``'s
        camera and rectangle."""
        loaded = self.host.session.shown.loaded
        self.drop_selection()
        if not mask.any():
            self.binding.write(self.note, content="No point in the rectangle. " + PROMPT)
            return
        box = CropBox.around(loaded.cloud, mask)
        try:
            plane, error = region_plane(loaded.cloud, mask, toward=loaded.plane.normal), ""
        except InputError as exc:
            plane, error = None, str(exc)
        self.selection = Selection(loaded, mask, box, plane, error, made_by)
        u = loaded.units
        self.binding.set(self.box, box_text(box, u))
        lines = [f"**{self.selection.count:,} points selected**, in the box "
                 f"({md(box_text(box, u))}) {u.label}.",
                 plane_text(plane, u) if plane is not None else f"No plane: {md(error)}.",
                 "*Keep selection* or *Remove selection* crops the cloud to that box, "
                 f"*{L_EXACT}* to these {self.selection.count:,} points."]
        self.binding.write(self.note, content="  \n".join(lines))
        self.nodes = [self.host.scene.lines("/selection/box", _box_segments(loaded, box),
                                            (255, 0, 255))]
        self.host.take_overlay(self, self.let_go, self.colouring())

    def colouring(self) -> Colouring:
        """The map's colours with the selected points in magenta."""
        assert self.selection is not None
        mask, base = self.selection.mask, self.host.map_colouring()

        def colours(idx: np.ndarray) -> np.ndarray:
            c = (np.array(base(idx), dtype=np.uint8) if base is not None
                 else np.full((len(idx), 3), 200, dtype=np.uint8))
            c[mask[idx]] = HIGHLIGHT
            return c

        return colours

    def drop_selection(self) -> None:
        """No selection: its colours and box go (worker)."""
        self.host.scene.remove(self.nodes)
        self.nodes = []
        self.selection = None
        self.host.give_back_overlay(self)
        self.binding.write(self.note, content=PROMPT)

    def let_go(self) -> None:
        """Another feature colours the points now: the selection goes (worker)."""
        self.host.scene.remove(self.nodes)
        self.nodes = []
        self.selection = None
        self.binding.write(self.note, content=PROMPT)

    def on_render(self) -> None:
        """A new map: the selection is drawn over its colours (worker)."""
        if self.selection is not None and self.host.holds_overlay(self):
            self.host.scene.colour_by(self.colouring())

    def on_cloud(self) -> None:
        """Another cloud (or a crop) is shown: the selection was of the old one."""
        self.drop_selection()
        self.binding.write(self.status, content=crop_text(self.host.session.shown.loaded))

    # ------------------------------------------------------------------ saved views
    def snapshot(self) -> dict[str, Any]:
        sel = self.selection
        return {"crop": self.host.session.shown.loaded.crop,
                "selection": sel.made_by if sel is not None else None}

    def restore(self, view: View) -> Job[Host] | None:
        crop = None if view.crop == self.host.session.shown.loaded.crop else \
            CropJob(self, view.crop, render=False)
        if view.selection is None:
            return crop
        return RestoreSelectionJob(self, crop, view.selection)


def _box_rule(value: Any) -> str:
    """A browser's crop box text: a string of at most :data:`MAX_BOX_TEXT` characters."""
    if not isinstance(value, str) or len(value) > MAX_BOX_TEXT:
        raise InputError(f"a crop box is at most {MAX_BOX_TEXT} characters of text")
    return value


def _box_segments(loaded: LoadedCloud, box: CropBox) -> np.ndarray:
    """(12, 2, 3) edges of ``box`` in the display frame."""
    lo, hi = np.asarray(box.lo), np.asarray(box.hi)
    corners = np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)] for k in range(8)])
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    return np.stack([loaded.to_local(corners[[a, b]]) for a, b in edges])


# ----------------------------------------------------------------------------- jobs


@dataclass(frozen=True)
class SelectJob(Job[Host]):
    """Select the points under a screen rectangle seen by ``camera`` (the file frame)."""

    f: CropFeature = field(compare=False)
    camera: ViewCamera = field(compare=False)
    corner_a: tuple[float, float]
    corner_b: tuple[float, float]
    lane: ClassVar[str] = "select"

    @property
    def title(self) -> str:
        return "selecting points"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        cloud = ctx.session.shown.loaded.cloud
        require(1.0 * cloud.n + 100.0 * min(cloud.n, 1 << 20), f"a selection of {cloud.n:,} points")
        mask = rect_select(self.camera, cloud.x, cloud.y, cloud.z, self.corner_a, self.corner_b)
        yield "select"
        self.f.select(mask, selection_view(self.camera, self.corner_a, self.corner_b))
        yield "show"


def selection_view(camera: ViewCamera, a: tuple[float, float], b: tuple[float, float]
                   ) -> SelectionView:
    """What a saved view holds of a selection: the camera and the rectangle."""
    p, q = camera.position, camera.wxyz
    return SelectionView(position=(float(p[0]), float(p[1]), float(p[2])),
                         wxyz=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
                         fov_rad=float(camera.fov_rad), aspect=float(camera.aspect),
                         height_px=int(camera.height_px), corner_a=a, corner_b=b)


@dataclass(frozen=True)
class RestoreSelectionJob(Job[Host]):
    """A saved view's crop (when it differs), then its selection: the points its
    camera's rectangle holds, selected again."""

    f: CropFeature = field(compare=False)
    crop: CropJob | None = field(compare=False)
    selection: SelectionView = field(compare=False)
    lane: ClassVar[str] = "load"

    @property
    def title(self) -> str:
        return "the saved view's selection"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        if self.crop is not None:
            yield from self.crop.stages(ctx, run)
        s = self.selection
        try:
            camera = ViewCamera(position=np.asarray(s.position), wxyz=np.asarray(s.wxyz),
                                fov_rad=s.fov_rad, aspect=s.aspect, height_px=s.height_px)
        except InputError as exc:
            ctx.show_error(f"saved view: selection: {exc}", kept="No points are selected.")
            return
        yield from SelectJob(self.f, camera, s.corner_a, s.corner_b).stages(ctx, run)


@dataclass(frozen=True)
class CropJob(Job[Host]):
    """Crop the whole cloud by ``box`` (None: undo the crop) and show what it keeps,
    with the map's settings (its grid stays); ``render`` False leaves the map to a
    saved view's map job queued after it."""

    f: CropFeature = field(compare=False)
    box: CropBox | None
    render: bool = True
    exact: Selection | None = field(default=None, compare=False)
    """Crop to exactly these selected points (``box`` is then their bounding box)."""
    lane: ClassVar[str] = "load"
    cancels: ClassVar[frozenset[str]] = frozenset({"render", "panels", "pick", "select"})

    @property
    def title(self) -> str:
        return "cropping the cloud" if self.box is not None else "undoing the crop"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        shown = ctx.session.shown
        loaded = shown.loaded
        if self.box is None:
            if loaded.uncropped is None:
                return
            target = loaded.uncropped
        else:
            try:
                if self.exact is not None:
                    if self.exact.loaded is not loaded:
                        ctx.show_error("crop: the selection was made on another cloud",
                                       kept="The cloud is not cropped again.")
                        return
                    target = loaded.cropped_exact(self.exact.mask)
                else:
                    target = loaded.cropped(self.box)
            except (InputError, MemoryError) as exc:
                ctx.show_error(f"crop: {exc}" if isinstance(exc, InputError)
                               else "crop: not enough memory for the kept points")
                return
        yield "crop"
        ctx.show_cloud(target, shown.settings, frame=False)
        yield "show"
        if self.render:
            yield from ctx.render(run, shown.settings)


@dataclass(frozen=True)
class CropSelectionJob(Job[Host]):
    """Crop to the selection's box in ``mode`` (``exact``: to its very points), or
    say that there is no selection yet."""

    f: CropFeature = field(compare=False)
    mode: CropMode
    exact: bool = False
    lane: ClassVar[str] = "crop"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        sel = self.f.selection
        if sel is None:
            ctx.notify("Crop", "Select points first: Shift-drag a rectangle over the rock.")
            return
        yield "selection"
        ctx.submit(CropJob(self.f, CropBox(sel.box.lo, sel.box.hi, self.mode),
                           exact=sel if self.exact else None))


@dataclass(frozen=True)
class TypedCropJob(Job[Host]):
    """Crop by a box typed as ``compute --crop`` takes it (the cloud's unit), or
    show why the text is no box."""

    f: CropFeature = field(compare=False)
    text: str
    mode: str
    lane: ClassVar[str] = "crop"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        u = ctx.session.shown.loaded.units
        try:
            lo, hi = parse_box(self.text, option="the crop box")
            box = CropBox(lo, hi, self.mode if self.mode in CROP_MODES else "keep")
        except InputError as exc:
            ctx.show_error(str(exc), kept="The cloud is not cropped again.")
            return
        yield "parse"
        ctx.submit(CropJob(self.f, box.scaled(u.per)))


# ----------------------------------------------------------------------------- mount


def mount(host: Host) -> CropFeature:
    """Add the Select tab: Shift-drag selects, buttons crop."""
    gui = host.gui
    with host.tab("Select"):
        f = CropFeature(
            host=host,
            note=gui.add_markdown(PROMPT),
            keep=gui.add_button(L_KEEP, hint="Keep the points in the selection's bounding "
                                "box; every analysis runs on them."),
            exact=gui.add_button(L_EXACT, hint="Keep exactly the selected points (the box "
                                 "holds every point inside it, more than the selection)."),
            remove=gui.add_button(L_REMOVE, hint="Drop the points in the selection's "
                                  "bounding box (vegetation, talus, the tripod)."),
            clear=gui.add_button(L_CLEAR),
            box=gui.add_text(L_BOX, "", hint="xmin,ymin,zmin,xmax,ymax,zmax in the cloud's "
                             "unit, as compute --crop takes it."),
            mode=gui.add_dropdown(L_MODE, CROP_MODES, initial_value="keep"),
            apply=gui.add_button(L_APPLY),
            undo=gui.add_button(L_UNDO, hint="Use every point again."),
            status=gui.add_markdown(crop_text(host.session.shown.loaded)),
        )
    host.allow(f.keep, f.exact, f.remove, f.clear, f.box, f.mode, f.apply, f.undo)
    host.rule(f.box, _box_rule)
    b = f.binding

    b.on_change([f.keep], lambda _h: host.submit(CropSelectionJob(f, "keep")))
    b.on_change([f.exact], lambda _h: host.submit(CropSelectionJob(f, "keep", exact=True)))
    b.on_change([f.remove], lambda _h: host.submit(CropSelectionJob(f, "remove")))
    b.on_change([f.clear], lambda _h: host.submit(ClearJob(f)))
    b.on_change([f.apply], lambda _h: host.submit(
        TypedCropJob(f, str(f.box.value), str(f.mode.value))))
    b.on_change([f.undo], lambda _h: host.submit(CropJob(f, None)))

    def rect(event: viser.SceneRectSelectEvent) -> None:
        try:
            loaded = host.session.shown.loaded
            camera = ViewCamera.from_viser(event.client.camera, loaded.origin)
            a = (float(event.screen_min[0]), float(event.screen_min[1]))
            c = (float(event.screen_max[0]), float(event.screen_max[1]))
        except (AssertionError, AttributeError, InputError, TypeError, ValueError,
                ZeroDivisionError, IndexError):
            return  # no camera yet, or a malformed rectangle
        if all(np.isfinite(v) for v in (*a, *c)):
            host.submit(SelectJob(f, camera, a, c))

    host.scene.on_rect_select(rect)
    host.on_render(f.on_render)
    host.on_cloud(f.on_cloud)
    return f


@dataclass(frozen=True)
class ClearJob(Job[Host]):
    """Drop the selection."""

    f: CropFeature = field(compare=False)
    lane: ClassVar[str] = "select"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        self.f.drop_selection()
        yield "clear"
