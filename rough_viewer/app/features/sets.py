"""The Sets tab: discontinuity (joint) sets of the shown grid, on the rock, on the
stereonet and as tables (:mod:`rough_viewer.structure.sets`, docs/sets.md).

The tab follows the map: its sets are of the Map tab's grid (its ODR planes), with
the tab's own settings (the largest roughness of a planar cell as a share of the
cell, the cone, the least angle between sets, the most sets). "Show sets" colours the
rock by set, by joint or by patch ("Colour sets by"; the map's colour bar hides; the
zones, if shown, go off: one feature colours the points at a time). A click on the
rock selects the set and the joint under it: the stereonet marks both, the set table
highlights the set, the joint line gives the joint's row (dip / dip direction,
patches, area, trace length, persistence) and the joint and plane tables list the
set's joints and patches; the "Selected set" list selects a set alone. The
stereonet shows a pole per planar cell, per patch or per joint ("Stereonet poles").
Under the status line: the rock-mass figures (Jv, block size index, RQD estimate)
of the sets, the very sentence ``rough-viewer sets`` prints
(:func:`rough_viewer.structure.joints.rock_mass_text`).

The Export folder downloads the sets' tables (:meth:`SetsFeature.download_tables`):
the Dips CSV, SETS.csv, PLANES.csv and JOINTS.csv of ``sets --dips-out``, ``--out``,
``--planes-out`` and ``--joints-out``; the cell table and the points carry
``set_id``, ``plane_id`` and ``joint_id`` while the sets are shown.

Jobs (on the worker; callbacks only submit them):

=============  ============================================  ===============
job            stages                                        lane
=============  ============================================  ===============
SetsJob        sets (cached per grid and settings), colours  sets (figures)
SetFiguresJob  stereonet, tables                             sets-figures
=============  ============================================  ===============
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import plotly.graph_objects as go
import viser

from rough_viewer.app.binding import Binding, assign
from rough_viewer.app.cache import ByteCache
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import Colouring, by_cell
from rough_viewer.app.host import Host, Pick
from rough_viewer.app.layout import PLOTLY_CONFIG, placeholder
from rough_viewer.app.markup import md
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io.formats.point_fields import CellField
from rough_viewer.report.view import (
    SET_COLOUR_BY,
    SET_CONE_DEG_RANGE,
    SET_MAX_SETS_RANGE,
    SET_MIN_ANGLE_DEG_RANGE,
    SET_ROUGHNESS_PCT_RANGE,
    SetPoles,
    SetsView,
    View,
)
from rough_viewer.structure.sets import (
    DEFAULT_CONE_DEG,
    DEFAULT_MAX_SETS,
    DEFAULT_MIN_ANGLE_DEG,
    DEFAULT_PLANAR_SHARE,
    JointSets,
    SetOptions,
    joint_sets,
    set_point_fields,
)
from rough_viewer.visual import colormaps
from rough_viewer.visual.app import panel_aspect
from rough_viewer.visual.sets import (
    joints_table_figure,
    planes_table_figure,
    sets_stereonet_figure,
    sets_table_figure,
)
from rough_viewer.vocabulary import InputError

#: Labels (the browser tests find controls by these).
L_ON = "Show sets"
L_COLOUR = "Colour sets by"  # "Colour by" is the Map tab's layer
L_POLES = "Stereonet poles"
L_ROUGHNESS = "Planar cells: roughness ≤ % of cell"
L_CONE = "Cone (°)"
L_MIN_ANGLE = "Least angle between sets (°)"
L_MAX_SETS = "Most sets"
L_SELECTED = "Selected set"
#: The "Selected set" entry for no selection.
NO_SET = "none"
#: "Colour sets by" entries and the labels each colours by (patch: a plane of PLANES.csv).
COLOUR_BY: tuple[str, ...] = SET_COLOUR_BY
COLOUR_LABELS = {"set": "set", "joint": "joint", "patch": "plane"}
#: "Stereonet poles" entries: one pole per planar cell, per patch or per joint.
POLES: tuple[str, ...] = ("per cell", "per patch", "per joint")
POLES_OF: dict[str, SetPoles] = {"per cell": "cell", "per patch": "patch",
                                  "per joint": "joint"}
#: The "Stereonet poles" entry of each kind of pole (a saved view's).
POLES_LABEL = {kind: label for label, kind in POLES_OF.items()}
#: The tables the Export folder downloads: title -> (file-name part, table).
DOWNLOAD_TABLES = {"Joint sets: Dips CSV (planes)": "dips", "Joint sets: SETS.csv": "sets",
                   "Joint sets: PLANES.csv": "planes", "Joint sets: JOINTS.csv": "joints"}


def set_option(sets: JointSets, k: int) -> str:
    """The dropdown entry of set ``k`` (1..S); "exposure face" marks a set parallel to
    the face the scanner saw (issue 31 item 2)."""
    face = " ⚠ exposure face" if sets.face_parallel[k - 1] else ""
    return (f"Set {k} — {sets.dip_deg[k - 1]:02.0f}/{sets.dip_direction_deg[k - 1]:03.0f}, "
            f"{int(sets.cells[k - 1]):,} cells{face}")


def set_of_option(value: str) -> int | None:
    """Set id of a dropdown entry (``Set 2 — 78/221, 412 cells``), None if it is not one."""
    parts = value.split(" ", 2)
    if len(parts) >= 2 and parts[0] == "Set" and parts[1].isdigit():
        return int(parts[1])
    return None


def overview_note(n_drawn: int, n_total: int) -> str:
    """The warning of sets found on a campaign's overview (issue 33): the cells are
    every point's, the planes' fits are not; '' when every point is in memory.

    >>> overview_note(5, 5)
    ''
    >>> overview_note(1_000, 60_000)[:60]
    "the cells are every point's, but the planes, joints, spacing"
    """
    if n_drawn >= n_total:
        return ""
    return (f"the cells are every point's, but the planes, joints, spacing and joint "
            f"roughness are fitted to the overview's {n_drawn:,} of the file's "
            f"{n_total:,} points: crop to a region (Select tab) to use every point there")


def status_markdown(sets: JointSets, cell_size_text: str, overview: str = "") -> str:
    """The tab's status line (escaped); ``overview``: :func:`overview_note`."""
    warn = f"\n\n**⚠ {md(overview)}**" if overview else ""
    if not sets.n_sets:
        return f"**No joint set** at grid {md(cell_size_text)}: {md(sets.note)}{warn}"
    planar = int(np.count_nonzero(sets.planar))
    n = sets.curved_groups
    curved = (f"; {n:,} curved group{' is' if n == 1 else 's are'} no plane" if n else "")
    n_j, n_p = sets.joints.n_joints, sets.planes.n_planes
    line = (f"**{sets.n_sets} set{'s' if sets.n_sets != 1 else ''}** at grid "
            f"{md(cell_size_text)}: {int(sets.cells.sum()):,} of {planar:,} planar cells in "
            f"sets, {n_j:,} joint{'s' if n_j != 1 else ''} of {n_p:,} "
            f"patch{'es' if n_p != 1 else ''} (planes){md(curved)}")
    if sets.face_note:  # a set parallel to the exposure face (issue 31 item 2)
        line += f"\n\n**⚠ {md(sets.face_note)}**"
    return line + warn


def rock_mass_markdown(sets: JointSets, unit: str) -> str:
    """The tab's rock-mass line (escaped): the sentence of ``rough-viewer sets``."""
    if not sets.n_sets:
        return ""
    return f"**Rock mass** (from the joint spacing): {md(sets.rock_mass_text(unit))}"


def joint_markdown(sets: JointSets, joint: int, set_id: int, unit: str) -> str:
    """The selected joint's row (escaped): dip / dip direction, patches, area, trace
    length, persistence along dip and strike, in ``unit``; or why there is none."""
    from rough_viewer.vocabulary import unit_scale

    per, u = unit_scale(unit)
    jt = sets.joints
    if not 1 <= joint <= jt.n_joints:
        where = f" (set {set_id})" if set_id else ""
        return f"_The clicked cell is in no joint{md(where)}._" if set_id else ""
    k = joint - 1
    return md(f"Joint {joint} (set {int(jt.set_id[k])}): {jt.dip_deg[k]:02.0f}/"
              f"{jt.dip_direction_deg[k]:03.0f}, {int(jt.patches[k]):,} "
              f"patch{'es' if jt.patches[k] != 1 else ''}, area {jt.area[k] / per**2:.3g} "
              f"{u}2, trace length {jt.trace_length[k] / per:.3g} {u}, persistence "
              f"{jt.persistence_dip[k] / per:.3g} {u} along dip x "
              f"{jt.persistence_strike[k] / per:.3g} {u} along strike, RMS "
              f"{jt.rms[k] / per:.3g} {u}")


class SetsBinding(Binding):
    """The tab's controls and :class:`~rough_viewer.structure.sets.SetOptions`."""

    def __init__(self, f: SetsFeature) -> None:
        self.f = f

    def read(self, cell_size: float) -> SetOptions:
        """The settings the controls ask for on a grid of ``cell_size`` metres
        (InputError for values the science refuses)."""
        f = self.f
        return SetOptions(max_roughness=float(f.roughness.value) / 100.0 * cell_size,
                          cone_deg=float(f.cone.value), min_angle_deg=float(f.min_angle.value),
                          max_sets=int(f.max_sets.value))

    def show_selection(self, sets: JointSets, k: int) -> None:
        f = self.f
        options = (NO_SET, *(set_option(sets, i) for i in range(1, sets.n_sets + 1)))
        with self.quietly():
            if tuple(f.selected.options) != options:
                f.selected.options = options
            value = set_option(sets, k) if 1 <= k <= sets.n_sets else NO_SET
            if f.selected.value != value:
                assign(f.selected, value)


@dataclass(eq=False)
class SetsFeature:
    """Handles and state of the Sets tab (the state is changed by the worker only)."""

    host: Host
    on: viser.GuiCheckboxHandle
    colour_by: viser.GuiDropdownHandle[str]
    poles: viser.GuiDropdownHandle[str]
    roughness: viser.GuiNumberHandle[float]
    cone: viser.GuiNumberHandle[float]
    min_angle: viser.GuiNumberHandle[float]
    max_sets: viser.GuiNumberHandle[int]
    status: viser.GuiMarkdownHandle
    rock_mass: viser.GuiMarkdownHandle
    selected: viser.GuiDropdownHandle[str]
    joint_info: viser.GuiMarkdownHandle
    stereonet: viser.GuiPlotlyHandle
    table: viser.GuiPlotlyHandle
    joints: viser.GuiPlotlyHandle
    planes: viser.GuiPlotlyHandle
    binding: SetsBinding = field(init=False)
    sets: JointSets | None = None
    """The sets on screen (of :attr:`result`)."""
    result: GridRoughness | None = None
    selected_set: int = 0
    """The selected set (0: none)."""
    selected_joint: int = 0
    """The selected joint (0: none; a click on the rock selects it)."""
    cache: ByteCache[tuple[object, ...], JointSets] = field(default_factory=lambda: ByteCache(0))
    cache_for: LoadedCloud | None = None
    pending_selection: tuple[int, int] | None = None
    """(set, joint) to select once the sets are next found (a restored view's; 0:
    none)."""

    def __post_init__(self) -> None:
        self.binding = SetsBinding(self)

    @property
    def active(self) -> bool:
        return bool(self.on.value)

    def table_columns(self, result: GridRoughness) -> dict[str, np.ndarray]:
        """The exported cell table's ``set_id``, ``plane_id`` and ``joint_id`` columns
        (0 = none, as ``sets --cells-out``) while the sets of ``result`` are shown."""
        if not self.active or self.sets is None or self.result is not result:
            return {}
        return {"set_id": self.sets.cell_set, "plane_id": self.sets.cell_plane,
                "joint_id": self.sets.cell_joint}

    def point_fields_of(self, result: GridRoughness) -> tuple[CellField, ...]:
        """The points downloads' ``set_id``, ``plane_id`` and ``joint_id`` (as ``sets
        --las-out``) while the sets of ``result`` are shown."""
        if not self.active or self.sets is None or self.result is not result:
            return ()
        return set_point_fields(self.sets, result).fields

    def download_tables(self) -> dict[str, str]:
        """The tables the Export folder offers: title -> file-name part."""
        return dict(DOWNLOAD_TABLES)

    def download_table(self, name: str, result: GridRoughness, unit: str
                       ) -> dict[str, np.ndarray]:
        """Table ``name`` (a value of :data:`DOWNLOAD_TABLES`) of the sets of
        ``result`` shown, lengths in ``unit``: the very columns ``rough-viewer sets``
        writes (InputError when no sets of ``result`` are shown)."""
        from rough_viewer.vocabulary import unit_scale

        sets = self.sets
        if not self.active or sets is None or self.result is not result:
            raise InputError("no joint sets are shown: tick Show sets in the Sets tab "
                             "first")
        per = unit_scale(unit)[0]
        tables = {"dips": sets.dips_table, "sets": sets.set_table,
                  "planes": sets.plane_table, "joints": sets.joint_table}
        if name not in tables:
            raise InputError(f"no such joint-set table: {name!r}")
        return tables[name](per)

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        return {"sets_stereonet": self.stereonet, "sets_table": self.table,
                "joints_table": self.joints, "planes_table": self.planes}

    # ------------------------------------------------------------------ saved views
    def snapshot(self) -> dict[str, Any]:
        """The tab's settings, whether the sets are shown, and the selected set and
        joint (while shown); None when the sets are hidden at the tab's defaults."""
        shown = self.active and self.sets is not None
        view = SetsView(
            shown=bool(self.on.value),
            colour_by=next((c for c in SET_COLOUR_BY if c == self.colour_by.value), "set"),
            poles=POLES_OF.get(self.poles.value, "cell"),
            roughness_pct=float(self.roughness.value), cone_deg=float(self.cone.value),
            min_angle_deg=float(self.min_angle.value), max_sets=int(self.max_sets.value),
            selected_set=(self.selected_set or None) if shown else None,
            selected_joint=(self.selected_joint or None) if shown else None)
        return {"sets": None if view == SetsView() else view}

    def restore(self, view: View) -> Job[Host] | None:
        return None if view.sets is None else RestoreSetsJob(self, view.sets)

    def take_selection(self, sets: JointSets) -> None:
        """Select the pending (restored) set and joint where ``sets`` has them: a
        joint only within the selected set (worker)."""
        assert self.pending_selection is not None
        k, j = self.pending_selection
        self.pending_selection = None
        self.selected_set = k if 1 <= k <= sets.n_sets else 0
        jt = sets.joints
        fits = self.selected_set and 1 <= j <= jt.n_joints and int(jt.set_id[j - 1]) == k
        self.selected_joint = j if fits else 0

    # ------------------------------------------------------------------ worker side
    def sets_of(self, loaded: LoadedCloud, result: GridRoughness, grid_key: tuple[object, ...],
                options: SetOptions) -> JointSets:
        """The sets of ``result`` with ``options`` (cached per grid and settings)."""
        if self.cache_for is not loaded:
            self.cache = ByteCache(self.host.options.cache_pool,
                                   most=self.host.options.cache_bytes // 4)
            self.cache_for = loaded
        key = (grid_key, options)
        hit = self.cache.get(key)
        if hit is not None:
            return hit
        made = joint_sets(result, loaded.cloud, options)
        self.cache.put(key, made)
        return made

    def colouring(self) -> Colouring:
        """The points' colours by the set, joint or patch of their cell."""
        from rough_viewer.visual.sets import cell_labels

        assert self.sets is not None and self.result is not None
        by = COLOUR_LABELS.get(self.colour_by.value, "set")
        labels = cell_labels(self.sets, by)  # type: ignore[arg-type]
        return by_cell(colormaps.zone_colours(labels), self.result)

    def show_colours(self) -> None:
        """Colour the points by set, joint or patch (the map's colours and colour bar
        give way)."""
        self.host.take_overlay(self, self.let_go, self.colouring())

    def hide(self) -> None:
        self.host.give_back_overlay(self)

    def let_go(self) -> None:
        """Another feature colours the points now: "Show sets" goes off (worker)."""
        self.binding.set(self.on, False)

    def show_figures(self) -> None:
        """The stereonet, the set table, the selected joint's row and the selected
        set's joints and planes."""
        sets, res = self.sets, self.result
        if sets is None or res is None:
            return
        unit = self.host.session.shown.loaded.units.unit
        own: dict[str, Any] = {"axis": res.axis, "n_points": res.n_points_total, "unit": unit}
        k = self.selected_set or None
        j = self.selected_joint or None
        poles = POLES_OF.get(self.poles.value, "cell")
        self.binding.write(self.stereonet, figure=_compact(sets_stereonet_figure(
            sets, selected=k, poles=poles, selected_joint=j, **own)))
        for handle, fig in ((self.table, sets_table_figure(sets, selected=k, **own)),
                            (self.joints, joints_table_figure(sets, set_id=k, selected=j,
                                                              **own)),
                            (self.planes, planes_table_figure(sets, set_id=k, **own))):
            # a table gets the height it was laid out for: every row shown (long
            # tables scroll within their most height)
            self.binding.write(handle, aspect=panel_aspect(fig, width=TABLE_PANEL_WIDTH),
                               figure=_compact(fig))
        self.binding.write(self.rock_mass, content=rock_mass_markdown(sets, unit))
        self.binding.write(self.joint_info, content=joint_markdown(
            sets, self.selected_joint, self.selected_set, unit))
        self.binding.show_selection(sets, self.selected_set)

    def select_cell(self, cell: int) -> None:
        """Select the set and the joint of cell ``cell`` (0 for none)."""
        assert self.sets is not None
        self.pending_selection = None
        self.selected_set = int(self.sets.cell_set[cell])
        self.selected_joint = int(self.sets.cell_joint[cell])

    def on_pick(self, pick: Pick) -> bool:
        """A click while sets are shown selects the set and the joint under it
        (worker)."""
        if not self.active or self.sets is None or self.result is None:
            return False
        self.select_cell(int(self.result.point_cell[pick.point]))
        self.host.submit(SetFiguresJob(self))
        return True

    def on_render(self) -> None:
        """After every map: the sets of its grid, when shown (worker)."""
        if self.active:
            self.host.submit(SetsJob(self))


#: Width the tables' heights are reckoned at, px: the narrowest panel (a 1280 x 800
#: window; wider panels give a little room to spare).
TABLE_PANEL_WIDTH = 460


def _compact(fig: go.Figure) -> go.Figure:
    fig.update_layout(width=None, margin={"l": 4, "r": 4, "t": 90, "b": 4}, title_font_size=11)
    return fig


@dataclass(frozen=True)
class SetsJob(Job[Host]):
    """Find the sets of the shown grid with the tab's settings and colour the rock by
    them (or hide them when "Show sets" is off); then queue the figures."""

    f: SetsFeature = field(compare=False)
    lane: ClassVar[str] = "sets"
    cancels: ClassVar[frozenset[str]] = frozenset({"sets-figures"})

    @property
    def title(self) -> str:
        return "joint sets"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f, shown = self.f, ctx.session.shown
        if not f.active:
            f.hide()
            yield "hide"
            return
        if shown.result is None:
            return
        options = f.binding.read(shown.result.grid.cell_size)  # InputError: named
        f.binding.write(f.status, content="_finding the joint sets…_")
        sets = f.sets_of(shown.loaded, shown.result, shown.settings.grid_key, options)
        yield "sets"
        if f.pending_selection is not None:  # a restored view's
            f.take_selection(sets)
        elif f.sets is not sets:  # other sets: the old joint ids mean nothing there
            f.selected_joint = 0
        if f.selected_set > sets.n_sets:
            f.selected_set = 0
        f.sets, f.result = sets, shown.result
        f.show_colours()
        f.binding.write(f.status, content=status_markdown(
            sets, shown.loaded.units.size_text(shown.result.grid.cell_size),
            overview_note(shown.loaded.cloud.n, shown.loaded.n_total)))
        yield "colours"
        ctx.submit(SetFiguresJob(f))


@dataclass(frozen=True)
class RestoreSetsJob(Job[Host]):
    """A saved view's Sets settings in the tab's controls, its selection pending, and
    the sets found (and shown, when they were) again."""

    f: SetsFeature = field(compare=False)
    view: SetsView
    lane: ClassVar[str] = "sets-restore"

    @property
    def title(self) -> str:
        return "the saved view's joint sets"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f, v = self.f, self.view
        b = f.binding
        b.set(f.colour_by, v.colour_by)
        b.set(f.poles, POLES_LABEL[v.poles])
        b.set(f.roughness, float(v.roughness_pct))
        b.set(f.cone, float(v.cone_deg))
        b.set(f.min_angle, float(v.min_angle_deg))
        b.set(f.max_sets, int(v.max_sets))
        b.set(f.on, bool(v.shown))
        f.pending_selection = ((v.selected_set or 0, v.selected_joint or 0) if v.shown
                               else None)
        yield "settings"
        ctx.submit(SetsJob(f))


@dataclass(frozen=True)
class SetFiguresJob(Job[Host]):
    """The stereonet and the tables of the sets on screen (the selection marked)."""

    f: SetsFeature = field(compare=False)
    lane: ClassVar[str] = "sets-figures"

    @property
    def title(self) -> str:
        return "joint set figures"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        self.f.show_figures()
        yield "figures"


def mount(host: Host) -> SetsFeature:
    """Add the Sets tab; the sets follow every map while shown and take clicks."""
    gui = host.gui
    with host.tab("Sets"):
        f = SetsFeature(
            host=host,
            on=gui.add_checkbox(L_ON, False, hint="Colour the rock by joint set: planar "
                                "cells (smooth ODR planes) grouped by the orientation of "
                                "their poles (the Map tab's grid)."),
            colour_by=gui.add_dropdown(L_COLOUR, COLOUR_BY, initial_value="set",
                                       hint="By set, by joint (a discontinuity: the "
                                       "coplanar patches of one set, touching or not) or "
                                       "by patch (touching coplanar cells)."),
            poles=gui.add_dropdown(L_POLES, POLES, initial_value=POLES[0],
                                   hint="One pole on the stereonet per planar cell, per "
                                   "patch or per joint (the density is the cells')."),
            roughness=gui.add_number(L_ROUGHNESS, 100.0 * DEFAULT_PLANAR_SHARE,
                                     min=SET_ROUGHNESS_PCT_RANGE[0],
                                     max=SET_ROUGHNESS_PCT_RANGE[1], step=0.1,
                                     hint="A cell is planar when its ODR roughness is at "
                                     "most this share of the cell's edge."),
            cone=gui.add_number(L_CONE, DEFAULT_CONE_DEG, min=SET_CONE_DEG_RANGE[0],
                                max=SET_CONE_DEG_RANGE[1], step=1.0,
                                hint="A planar cell joins the nearest set's peak within "
                                "this angle."),
            min_angle=gui.add_number(L_MIN_ANGLE, DEFAULT_MIN_ANGLE_DEG,
                                     min=SET_MIN_ANGLE_DEG_RANGE[0],
                                     max=SET_MIN_ANGLE_DEG_RANGE[1], step=1.0),
            max_sets=gui.add_number(L_MAX_SETS, DEFAULT_MAX_SETS, min=SET_MAX_SETS_RANGE[0],
                                    max=SET_MAX_SETS_RANGE[1], step=1),
            status=gui.add_markdown("Tick **Show sets** to find the joint sets of the map's "
                                    "grid."),
            rock_mass=gui.add_markdown(""),
            selected=gui.add_dropdown(L_SELECTED, (NO_SET,), initial_value=NO_SET,
                                      hint="Or click a set on the rock (that selects its "
                                      "joint too)."),
            joint_info=gui.add_markdown(""),
            stereonet=gui.add_plotly(placeholder("Stereonet of the planar cells' poles",
                                                 "tick Show sets"),
                                     config=PLOTLY_CONFIG, aspect=0.95),
            table=gui.add_plotly(placeholder("Joint sets"), config=PLOTLY_CONFIG, aspect=0.5),
            joints=gui.add_plotly(placeholder("Joints of the selected set"),
                                  config=PLOTLY_CONFIG, aspect=0.6),
            planes=gui.add_plotly(placeholder("Planes of the selected set"),
                                  config=PLOTLY_CONFIG, aspect=0.6),
        )
    f.cache = ByteCache(host.options.cache_pool, most=host.options.cache_bytes // 4)
    host.allow(f.on, f.colour_by, f.poles, f.roughness, f.cone, f.min_angle, f.max_sets,
               f.selected)
    b = f.binding
    b.on_change([f.on, f.colour_by, f.roughness, f.cone, f.min_angle, f.max_sets],
                lambda _h: host.submit(SetsJob(f)))

    def select(_handle: object) -> None:
        k = 0 if f.selected.value == NO_SET else set_of_option(f.selected.value)
        if k is not None:
            host.submit(SelectSetJob(f, k))

    b.on_change([f.selected], select)
    b.on_change([f.poles], lambda _h: host.submit(SetFiguresJob(f)))
    host.on_click(f.on_pick)
    host.on_render(f.on_render)
    return f


@dataclass(frozen=True)
class SelectSetJob(Job[Host]):
    """Select set ``k`` (0: none) from the list."""

    f: SetsFeature = field(compare=False)
    k: int
    lane: ClassVar[str] = "sets-select"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f = self.f
        if f.sets is None:
            return
        if not 0 <= self.k <= f.sets.n_sets:
            raise InputError(f"there is no set {self.k}")
        f.pending_selection = None
        if self.k != f.selected_set:
            f.selected_joint = 0  # a joint of the set before
        f.selected_set = self.k
        f.show_figures()
        yield "select"
