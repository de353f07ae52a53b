"""Zones tab: fracture and rubble zones of the shown map, in the scene and as a table.

A zone (:mod:`rough_viewer.structure.zones`, docs/zones.md) is a connected group of
cells whose normalised roughness is at or above a threshold. The tab follows the
view: zones are always of the **Map tab's** map (model), grid and binary
threshold, so moving the threshold slider (on the Map tab, or its twin here)
re-labels the zones live. The tab adds connectivity and a minimum zone size.

Scene. "Show zones" swaps the map's cloud for a second cloud of the same
displayed points coloured by zone (:func:`rough_viewer.visual.colormaps.
zone_colours`; light grey: a cell with a value in no zone; neutral grey: no
value). Both clouds stay on the browser; switching is a ``visible`` flag, and a
re-label sends only the zone cloud's colours (3 bytes a point). The selected
zone is drawn on top as a small third cloud of its own points (magenta, larger
points, following the map's point size) with its name at its centroid.

Selecting. A click on the rock (the host's click event) or the "Selected
zone" dropdown selects a zone (viser 1.1's plotly element reports no clicks,
so the table cannot be clicked). A selection is kept as a point of the cloud
(the anchor), so it follows the zone under that point through re-labels,
connectivity and grid changes; its numbers, its table row and its poles on the
stereonet are highlighted.

Jobs (on the app's worker; callbacks only submit them):

==============  ===========================================  =======================
job             stages                                       lane (cancels)
==============  ===========================================  =======================
ZonesJob        basis, label, colours (queues ZoneTableJob)  zones (zones-table)
ZoneTableJob    measure, table, stereonet                    zones-table
SelectZoneJob   select                                       zones-select
==============  ===========================================  =======================

Per grid result and map, :class:`ZoneBasis` (the :class:`~rough_viewer.structure.zones.
ZoneLabeller`, built once, and the cell of every displayed point) is kept in a
byte-bounded cache (:class:`~rough_viewer.app.cache.ByteCache`, at most half of the
app's one cache budget, which the grids and the sets share), so a threshold change
only re-labels and recolours.

Saved views read and restore the zone settings with :meth:`ZonesFeature.snapshot`
and :meth:`ZonesFeature.restore` (:class:`rough_viewer.report.view.ZoneSettings`).
"""

from __future__ import annotations

import time
from collections import deque
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
from rough_viewer.app.layout import PLOTLY_CONFIG
from rough_viewer.app.limits import MAX_TIMINGS
from rough_viewer.app.markup import md
from rough_viewer.app.settings import MODEL_LABELS
from rough_viewer.app.units import Units
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.orientation import Stereonet, cell_stereonet
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.threshold import map_threshold_advice, zone_threshold
from rough_viewer.io.formats.point_fields import CellField
from rough_viewer.memory import require
from rough_viewer.report.view import View, ZoneSettings
from rough_viewer.structure.zones import ZoneLabeller, Zones
from rough_viewer.visual import colormaps
from rough_viewer.visual.zones import (
    COMPACT_COLUMNS,
    azimuth_text,
    stereonet_figure,
    zones_table_figure,
)
from rough_viewer.vocabulary import (
    CONNECTIVITIES,
    DEFAULT_MIN_CELLS,
    DEFAULT_THRESHOLD,
    MAP_LABELS,
    MAPS,
    Connectivity,
    InputError,
    MapName,
)

#: Labels (the browser tests find controls by these).
L_ON = "Show zones"
L_THRESHOLD = "Zone threshold"
L_CONNECTIVITY = "Connectivity"
L_MIN_CELLS = "Min zone cells"
L_SELECTED = "Selected zone"
L_RULE = "Zone threshold rule"

#: "Zone threshold rule" entries: the data's own threshold when the paper's 0.05 (the
#: slider left at it) flags more than half of the cells (``rough-viewer zones``
#: without ``--threshold``: :func:`rough_viewer.grid.threshold.zone_threshold`), or
#: the slider's value as it is (``--threshold``; 0.05 is the paper's).
RULE_AUTO = f"data's own when {DEFAULT_THRESHOLD:g} flags over half"
RULE_SLIDER = f"the slider's ({DEFAULT_THRESHOLD:g}: the paper's)"
RULES: tuple[str, ...] = (RULE_AUTO, RULE_SLIDER)

#: Connectivity dropdown entries.
CONNECTIVITY_LABELS: dict[Connectivity, str] = {
    "vertex": "vertex (26)", "edge": "edge (18)", "face": "face (6)"}
CONNECTIVITY_BY_LABEL: dict[str, Connectivity] = {v: k for k, v in CONNECTIVITY_LABELS.items()}
#: The "Selected zone" entry for no selection.
NO_ZONE = "none"
#: Zones listed in the table and the dropdown (the largest; a zone picked in the
#: scene beyond them is added to the dropdown).
MAX_ZONE_ROWS = 50
#: The points downloads' description of ``zone`` (LAS extra bytes: 32 characters).
ZONE_DESCRIPTION = "roughness zone id (0 = none)"
#: Largest "Min zone cells" value.
MAX_MIN_CELLS = 1_000_000
#: Colour of a displayed point in a cell with a value but in no zone (as the zone
#: map figure's light grey); cells without a value keep the neutral grey.
NO_ZONE_RGB: tuple[int, int, int] = (227, 227, 227)
#: Colour of the selected zone's points (not in the zone palette).
HIGHLIGHT_RGB: tuple[int, int, int] = (255, 0, 255)
#: Selected-zone points are drawn this much larger than the cloud's.
HIGHLIGHT_SIZE = 1.6
#: Poles drawn per stereonet trace in the panel (the density uses every cell).
PANEL_POLES = 5000
#: Zones highlighted on the stereonet when none is selected (the largest).
NET_ZONES = 6
#: Scene nodes of the tab.
NODE_SELECTED = "/zones/selected"
NODE_LABEL = "/zones/label"


# ----------------------------------------------------------------------------- plain data


@dataclass(frozen=True)
class ZoneParams:
    """How the shown zones were formed."""

    map_name: MapName
    threshold: float
    """Cells with normalised roughness ``>= threshold`` are rough (the Map tab's)."""
    connectivity: Connectivity
    min_cells: int
    keep_outliers: bool = False
    """Cells larger than the cell take part (the Map tab's *Keep outlier cells*)."""
    reason: str = ""
    """Why ``threshold`` is not the slider's (the data's own), or empty."""


def effective_threshold(result: GridRoughness | None, map_name: MapName, slider: float,
                        rule: str, *, keep_outliers: bool = False) -> tuple[float, str]:
    """The threshold the zones use and why when it is not ``slider``: under
    :data:`RULE_AUTO` with the slider at the paper's 0.05 (not moved), the rule of
    ``rough-viewer zones`` (:func:`rough_viewer.grid.threshold.zone_threshold`);
    otherwise the slider's value."""
    if rule != RULE_AUTO or slider != DEFAULT_THRESHOLD or result is None:
        return float(slider), ""
    chosen = zone_threshold(result, map_name, keep_outliers=keep_outliers)
    reason = chosen.reason()
    if reason:
        reason += (f"; choose “{RULE_SLIDER}” in {L_RULE} for the paper's "
                   f"{DEFAULT_THRESHOLD:g}")
    return chosen.value, reason


@dataclass(frozen=True, eq=False)
class ZoneBasis:
    """What zones of one grid result and map need, computed once (cached)."""

    labeller: ZoneLabeller
    display_cell: np.ndarray
    """(K,) cell row of every displayed point."""
    valid: np.ndarray
    """(M,) bool: the cell has a value (a plane and the map)."""


def _same_result(a: GridRoughness, b: GridRoughness) -> bool:
    """Whether two results of one grid key hold the same cells, values and points'
    rows: the store may hand out the same grid as a new object (rebuilt from its
    cached cells after the full result left the cache, the same bits)."""
    if a is b:
        return True
    return (a.grid == b.grid and a.ijk.shape == b.ijk.shape
            and all(np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True)
                    for f in ("ijk", "theta_odr", "theta_ols", "theta_hybrid", "e_ols",
                              "point_cell")))


def zone_basis(result: GridRoughness, map_name: MapName, display_index: np.ndarray, *,
               keep_outliers: bool = False) -> ZoneBasis:
    """Build the labeller of ``result``'s map (outlier cells left out unless kept) and
    the cells of the displayed points."""
    # the cells of the shown points (int32), and a colour and a zone id per point per
    # re-label
    require(16.0 * display_index.shape[0], f"zones of {display_index.shape[0]:,} shown points")
    labeller = ZoneLabeller.build(result, map_name, keep_outliers=keep_outliers)
    valid = np.zeros(result.n_cells, dtype=bool)
    valid[labeller.rows] = True
    cell = result.point_cell[display_index]
    if result.n_cells < 2**31:
        cell = cell.astype(np.int32, copy=False)
    return ZoneBasis(labeller, cell, valid)


@dataclass(frozen=True, eq=False)
class Labelling:
    """The zones on screen: the labels of one grid result under :class:`ZoneParams`."""

    loaded: LoadedCloud
    result: GridRoughness
    grid_key: tuple[object, ...]
    """The view's grid key (cell size, axis, min points) of ``result``."""
    basis: ZoneBasis
    params: ZoneParams
    labels: np.ndarray
    """(M,) int32 zone id of every cell (0 = none), ids 1..Z by size."""

    @property
    def n_zones(self) -> int:
        return int(self.labels.max()) if self.labels.size else 0

    def zone_at(self, point: int | None) -> int:
        """Zone id of cloud point ``point`` (0: none, or no point)."""
        if point is None or not 0 <= point < self.result.point_cell.shape[0]:
            return 0
        return int(self.labels[self.result.point_cell[point]])

    def anchor_of(self, zone: int) -> int | None:
        """A cloud point of zone ``zone`` (in its cell nearest the zone's mean cell
        centre), or None when there is no such zone."""
        cells = np.flatnonzero(self.labels == zone) if zone > 0 else np.zeros(0, np.int64)
        if cells.size == 0:
            return None
        centre = self.result.centre[cells]
        c = int(cells[np.argmin(((centre - centre.mean(axis=0)) ** 2).sum(axis=1))])
        return int(np.argmax(self.result.point_cell == c))

    def display_mask(self, zone: int) -> np.ndarray:
        """(K,) bool: displayed points in zone ``zone``."""
        return self.labels[self.basis.display_cell] == zone


def zone_cell_colours(labels: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(M, 3) uint8 colour of every cell: its zone's colour, :data:`NO_ZONE_RGB` with a
    value in no zone, the neutral grey without a value."""
    per_cell = colormaps.zone_colours(labels, none_rgb=NO_ZONE_RGB)
    per_cell[~valid] = np.asarray(colormaps.NEUTRAL_RGB, dtype=np.uint8)
    return per_cell


def zone_point_colours(labels: np.ndarray, valid: np.ndarray, display_cell: np.ndarray) -> np.ndarray:
    """(K, 3) uint8 colour of every displayed point: its cell's zone colour,
    :data:`NO_ZONE_RGB` in a cell with a value in no zone, the neutral grey in a
    cell without a value.

    Parameters
    ----------
    labels : (M,) int
        Zone id of every cell (0 = none).
    valid : (M,) bool
        Cells with a value.
    display_cell : (K,) int
        Cell row of every displayed point.
    """
    return zone_cell_colours(labels, valid)[display_cell]


def zone_option(zone: int, cells: int) -> str:
    """The dropdown entry of a zone."""
    return f"Zone {zone} — {cells:,} cells"


def zone_options(zones: Zones, selected: int = 0) -> tuple[str, ...]:
    """Dropdown entries: none, then the :data:`MAX_ZONE_ROWS` largest zones (and the
    selected one if it is smaller)."""
    n = min(zones.n_zones, MAX_ZONE_ROWS)
    options = [NO_ZONE] + [zone_option(k, int(zones.cells[k - 1])) for k in range(1, n + 1)]
    if selected > n and selected <= zones.n_zones:
        options.append(zone_option(selected, int(zones.cells[selected - 1])))
    return tuple(options)


def describe_params(p: ZoneParams) -> str:
    """Markdown of the zone settings (escaped)."""
    return md(f"{MAP_LABELS[p.map_name]} normalised ≥ {p.threshold:g}, {p.connectivity} "
              f"connectivity, ≥ {p.min_cells} cells")


def status_markdown(lab: Labelling, seconds: float, cached: bool) -> str:
    """The tab's status line: zone count and cells in zones."""
    valid = int(lab.basis.valid.sum())
    in_zones = int((lab.labels > 0).sum())
    share = 100.0 * in_zones / valid if valid else 0.0
    how = "labeller cached" if cached else "labeller built"
    zones = "1 zone" if lab.n_zones == 1 else f"{lab.n_zones:,} zones"
    p = lab.params
    advice = map_threshold_advice(lab.result, p.map_name, p.threshold,
                                  keep_outliers=p.keep_outliers)
    judged = f"  \n{'⚠ ' if advice.most else ''}{md(advice.text(lab.loaded.units.unit))}"
    if p.reason:
        judged = f"  \nℹ {md(p.reason[0].upper() + p.reason[1:])}" + judged
    return (f"**{zones}** at {describe_params(lab.params)}, grid "
            f"{lab.loaded.units.size_text(lab.result.grid.cell_size)}: "
            f"{in_zones:,} of {valid:,} cells with a value "
            f"({share:.1f} %)  \nre-labelled and coloured in {seconds:.2f} s ({how}){judged}")


def zone_markdown(zones: Zones, zone: int, units: Units | None = None) -> str:
    """Markdown of one zone's numbers: lengths and areas in the cloud's unit (m, m²
    by default), angles °, roughness in its roughness unit (mm for metric input)."""
    if not 1 <= zone <= zones.n_zones:
        return "No zone selected: click a zone on the rock or pick one in the list."
    i = zone - 1
    u = units or Units("m")
    c = zones.centroid[i] / u.per
    lw = f"{u.length(zones.length_m[i]):.3g} × {u.length(zones.width_m[i]):.3g} {u.label}"
    rows = [
        ("cells / points", f"{int(zones.cells[i]):,} / {int(zones.points[i]):,}"),
        ("area on the face", f"{zones.area_m2[i] / u.per**2:.3g} {u.label}²"),
        ("length × width", lw),
        ("trace azimuth / plunge",
         f"{azimuth_text(zones.trace_azimuth_deg[i])}° / {zones.trace_plunge_deg[i]:02.0f}°"),
        ("dip / dip direction",
         f"{zones.dip_deg[i]:02.0f}° / {azimuth_text(zones.dip_direction_deg[i])}°"),
        (f"mean / max θ {MAP_LABELS[zones.map_name]}",
         f"{u.rough(zones.mean_theta[i]):.3g} / {u.rough(zones.max_theta[i]):.3g} "
         f"{u.rough_label}"),
        ("centroid x, y, z", f"{c[0]:.2f}, {c[1]:.2f}, {c[2]:.2f} {u.label}"),
    ]
    lines = [f"**Zone {zone}** of {zones.n_zones:,}", "", "| | |", "|---|---|"]
    lines += [f"| {md(k)} | {md(v)} |" for k, v in rows]
    return "\n".join(lines)


def table_aspect(n_rows: int) -> float:
    """Height / width of the table panel for ``n_rows`` rows: the title and the
    header about 170 px, a row up to 44 px (two lines), in a panel about 360 px
    wide; at most 2.2 (longer tables scroll)."""
    return float(min(2.2, (170 + 44 * max(n_rows, 1)) / 360))


# ----------------------------------------------------------------------------- the tab


class ZonesBinding(Binding):
    """The tab's controls and :class:`ZoneParams` (the map and threshold are the Map
    tab's)."""

    def __init__(self, z: ZonesFeature) -> None:
        self.z = z

    def read(self) -> ZoneParams:
        """The zones the controls and the shown map ask for."""
        z = self.z
        shown = z.host.session.shown.settings
        conn = CONNECTIVITY_BY_LABEL.get(z.connectivity.value)
        if conn is None:
            raise InputError("the connectivity control holds a value that is not one of its "
                             "options")
        if z.rule.value not in RULES:
            raise InputError("the zone threshold rule holds a value that is not one of its "
                             "options")
        keep = bool(shown.keep_outliers)
        threshold, reason = effective_threshold(
            z.host.session.shown.result, shown.model, float(shown.threshold), z.rule.value,
            keep_outliers=keep)
        return ZoneParams(map_name=shown.model, threshold=threshold,
                          connectivity=conn, min_cells=int(z.min_cells.value),
                          keep_outliers=keep, reason=reason)

    def show(self, zones: ZoneSettings | None) -> None:
        """Saved zone settings in the controls (None: "Show zones" off)."""
        z = self.z
        if zones is None:
            self.set(z.on, False)
            return
        self.set(z.connectivity, CONNECTIVITY_LABELS[zones.connectivity])
        self.set(z.rule, RULE_AUTO if zones.threshold_rule == "auto" else RULE_SLIDER)
        self.set(z.min_cells, int(zones.min_cells))
        self.set(z.on, True)

    def follow_map(self) -> None:
        """The twin slider shows the Map tab's threshold."""
        self.set(self.z.threshold, float(self.z.host.session.shown.settings.threshold))

    def show_threshold(self, threshold: float) -> None:
        """The twin slider shows the threshold the zones use (the data's own under
        :data:`RULE_AUTO`; moving it chooses a threshold)."""
        self.set(self.z.threshold, float(threshold))

    def show_selection(self, zones: Zones, zone: int) -> None:
        """The dropdown lists the largest zones and shows ``zone``."""
        z = self.z
        options = zone_options(zones, zone)
        value = zone_option(zone, int(zones.cells[zone - 1])) if zone else NO_ZONE
        with self.quietly():
            if tuple(z.selected.options) != options:
                z.selected.options = options
            if z.selected.value != value:
                assign(z.selected, value)


def check_zone_settings(zones: ZoneSettings) -> None:
    """Raise InputError for saved zone settings the tab cannot show."""
    if zones.map not in MAPS or zones.connectivity not in CONNECTIVITY_LABELS:
        raise InputError("zone settings name an unknown map or connectivity")
    if not 1 <= int(zones.min_cells) <= MAX_MIN_CELLS:
        raise InputError(f"min zone cells must lie in [1, {MAX_MIN_CELLS:,}]")
    if zones.selected is not None and int(zones.selected) < 1:
        raise InputError("a selected zone id starts at 1")


@dataclass(eq=False)
class ZonesFeature:
    """Handles and state of the Zones tab (the state is changed by the worker only)."""

    host: Host
    on: viser.GuiCheckboxHandle
    threshold: viser.GuiSliderHandle[float]
    """Twin of the Map tab's threshold slider (moving either moves both)."""
    connectivity: viser.GuiDropdownHandle[str]
    min_cells: viser.GuiNumberHandle[int]
    status: viser.GuiMarkdownHandle
    rule: viser.GuiDropdownHandle[str]
    """:data:`RULE_AUTO` (the data's own threshold when 0.05 flags most) or
    :data:`RULE_SLIDER`."""
    selected: viser.GuiDropdownHandle[str]
    numbers: viser.GuiMarkdownHandle
    table: viser.GuiPlotlyHandle
    stereonet: viser.GuiPlotlyHandle
    binding: ZonesBinding = field(init=False)
    labelling: Labelling | None = None
    """The zones on screen (None before the first labelling)."""
    zones: Zones | None = None
    """The table of :attr:`labelling` (None until :class:`ZoneTableJob` has run)."""
    anchor: int | None = None
    """Cloud point of the selected zone (None: no selection)."""
    pending_selection: int | None = None
    """Zone id to select at the next labelling (a restored view's)."""
    timings: deque[dict[str, float]] = field(default_factory=lambda: deque(maxlen=MAX_TIMINGS))
    """One record per labelling: ``label_s`` (labels), ``colours_s`` (labels and the
    scene's colours), ``basis_s`` (0 when cached), ``done`` (``perf_counter`` when the
    colours were assigned); ``table_s`` is added by the table job."""
    colouring: Colouring | None = None
    """The points' colours by zone of :attr:`labelling` (shown while the zones are)."""
    cloud_for: LoadedCloud | None = None
    """The loaded cloud whose grids :attr:`cache` holds."""
    selected_nodes: list[viser.SceneNodeHandle] = field(default_factory=list)
    cache: ByteCache[tuple[object, ...], ZoneBasis | Stereonet] = field(
        default_factory=lambda: ByteCache(0))

    def __post_init__(self) -> None:
        self.binding = ZonesBinding(self)

    @property
    def active(self) -> bool:
        """Zones are shown ("Show zones" ticked)."""
        return bool(self.on.value)

    def table_columns(self, result: GridRoughness) -> dict[str, np.ndarray]:
        """The exported cell table's ``zone`` column (every cell's zone id, 0 for
        none, as ``zones --cells-out``) while the zones of ``result`` are shown."""
        lab = self.labelling
        if not self.active or lab is None or lab.result is not result:
            return {}
        return {"zone": lab.labels}

    def point_fields_of(self, result: GridRoughness) -> tuple[CellField, ...]:
        """The points downloads' ``zone`` (int32 zone id of each point's cell, 0 =
        none) while the zones of ``result`` are shown."""
        return tuple(CellField("zone", np.asarray(v, dtype=np.int32), ZONE_DESCRIPTION,
                               np.int32(0)) for v in self.table_columns(result).values())

    def params(self) -> ZoneParams:
        """The zones the controls and the shown map ask for."""
        return self.binding.read()

    # ------------------------------------------------------------------ saved views
    def settings(self) -> ZoneSettings:
        """The zone settings on screen: the map (the Map tab's model), connectivity,
        minimum cells and the selected zone id (or None)."""
        lab = self.labelling
        selected = self.pending_selection
        if selected is None and lab is not None:
            selected = lab.zone_at(self.anchor) or None
        p = self.params()
        return ZoneSettings(map=p.map_name, connectivity=p.connectivity,
                            min_cells=p.min_cells, selected=selected,
                            threshold_rule="auto" if self.rule.value == RULE_AUTO else "slider")

    def snapshot(self) -> dict[str, Any]:
        return {"zones": self.settings() if self.active else None}

    def restore(self, view: View) -> Job[Host] | None:
        if view.zones is None:
            return None
        try:
            check_zone_settings(view.zones)
        except InputError as exc:
            raise InputError(f"zones: {exc}") from None
        return RestoreZonesJob(self, view.zones)

    def apply(self, zones: ZoneSettings | None) -> None:
        """Show saved zone settings (None: hide the zones), with the Map tab on their
        map. Raises InputError for settings the tab cannot show."""
        if zones is not None:
            check_zone_settings(zones)
            if self.host.settings().model != zones.map:
                self.host.request(model=MODEL_LABELS[zones.map])
        self.host.submit(RestoreZonesJob(self, zones))

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        return {"zones_table": self.table,
                "zones_stereonet": self.stereonet}

    # ------------------------------------------------------------------ worker side
    def basis(self, loaded: LoadedCloud, result: GridRoughness, map_name: MapName,
              grid_key: tuple[object, ...], keep_outliers: bool = False
              ) -> tuple[ZoneBasis, bool]:
        """The cached :class:`ZoneBasis` of ``result`` and ``map_name`` (built if
        needed); True when it was cached."""
        self._own(loaded)
        key = ("basis", grid_key, map_name, keep_outliers)
        hit = self.cache.get(key)
        if isinstance(hit, ZoneBasis) and _same_result(hit.labeller.result, result):
            return hit, True
        basis = zone_basis(result, map_name, loaded.display_index, keep_outliers=keep_outliers)
        self.cache.put(key, basis)
        return basis, False

    def net(self, lab: Labelling) -> Stereonet:
        """The stereonet of every cell's pole of the labelling's grid (cached)."""
        key = ("net", lab.grid_key)
        hit = self.cache.get(key)
        if isinstance(hit, Stereonet) and hit.rows.shape[0] <= lab.result.n_cells:
            return hit
        net = cell_stereonet(lab.result)
        self.cache.put(key, net)
        return net

    def _own(self, loaded: LoadedCloud) -> None:
        """Forget the cache when another cloud is shown."""
        if self.cloud_for is not loaded:
            self.cache = ByteCache(self.host.options.cache_pool,
                                   most=self.host.options.cache_bytes // 2)
            self.cloud_for = loaded
            self.labelling, self.zones = None, None

    def show_colours(self) -> None:
        """Colour the points by zone (the map's colours and colour bar give way)."""
        assert self.colouring is not None
        self.host.take_overlay(self, self.let_go, self.colouring)

    def hide(self) -> None:
        """Show the map's cloud again; hide the zones."""
        self._hide_nodes()
        self.host.give_back_overlay(self)

    def let_go(self) -> None:
        """Another feature colours the points now: "Show zones" goes off (worker)."""
        self.binding.set(self.on, False)
        self._hide_nodes()

    def _hide_nodes(self) -> None:
        self._clear_highlight()

    def _clear_highlight(self) -> None:
        self.host.scene.remove(self.selected_nodes)
        self.selected_nodes = []

    def draw_highlight(self) -> int:
        """Draw the selected zone's displayed points; returns its id (0: none)."""
        lab = self.labelling
        self._clear_highlight()
        if lab is None or not self.active:
            return 0
        zone = lab.zone_at(self.anchor)
        if zone == 0:
            return 0
        mask = lab.display_mask(zone)
        pts = lab.loaded.display_points[mask]
        if pts.shape[0] == 0:
            return zone
        rgb = np.tile(np.asarray(HIGHLIGHT_RGB, dtype=np.uint8), (pts.shape[0], 1))
        centre = pts.astype(np.float64).mean(axis=0)
        scene = self.host.scene
        self.selected_nodes = [
            scene.add_points(NODE_SELECTED, pts, rgb, size_factor=HIGHLIGHT_SIZE),
            scene.add_label(NODE_LABEL, f"Zone {zone}", centre),
        ]
        return zone

    def show_selection(self) -> None:
        """The selected zone's numbers, its row in the table, its poles on the
        stereonet and the dropdown (when the table is of the shown labelling)."""
        lab, zones = self.labelling, self.zones
        if lab is None or zones is None or zones.labels is not lab.labels:
            return
        zone = lab.zone_at(self.anchor)
        units = lab.loaded.units
        self.binding.write(self.numbers, content=zone_markdown(zones, zone, units))
        res = lab.result
        self.binding.write(self.table, figure=_compact(zones_table_figure(
            zones, grid_size=res.grid.cell_size, axis=res.axis, n_points=res.n_points_total,
            selected=zone or None, max_rows=MAX_ZONE_ROWS, columns=COMPACT_COLUMNS,
            unit=units.unit)))
        self.binding.write(self.table, aspect=table_aspect(min(zones.n_zones, MAX_ZONE_ROWS)))
        self.binding.show_selection(zones, zone)

    def show_stereonet(self, net: Stereonet) -> None:
        """The stereonet with the selected zone's poles (or the largest zones')."""
        lab = self.labelling
        if lab is None:
            return
        zone = lab.zone_at(self.anchor)
        ids = [zone] if zone else list(range(1, min(lab.n_zones, NET_ZONES) + 1))
        res = lab.result
        fig = stereonet_figure(
            net, grid_size=res.grid.cell_size, axis=res.axis, n_points=res.n_points_total,
            highlight={f"zone {k}": lab.labels == k for k in ids},
            colours={f"zone {k}": colormaps.zone_colour(k) for k in ids},
            max_poles=PANEL_POLES, unit=lab.loaded.units.unit)
        self.binding.write(self.stereonet, figure=_compact(fig))

    def on_pick(self, pick: Pick) -> bool:
        """A click while zones are shown selects the zone under it (none on a point
        in no zone; worker). False when zones are hidden."""
        if not self.active or self.labelling is None:
            return False
        lab = self.labelling
        self.anchor = pick.point if lab.zone_at(pick.point) else None
        self.pending_selection = None
        self.draw_highlight()
        self.show_selection()
        if self.zones is not None and self.zones.labels is lab.labels:
            self.host.submit(SelectZoneJob(self, lab, lab.zone_at(self.anchor),
                                           stereonet_only=True))
        return True

    def on_render(self) -> None:
        """After every map (new grid, model, threshold or cloud): the twin slider
        follows, and the zones are labelled again when shown (worker)."""
        self.binding.follow_map()
        if self.active:
            self.host.submit(ZonesJob(self))


def _compact(fig: go.Figure) -> go.Figure:
    """A report figure fitted to the control panel (smaller title and margins)."""
    fig.update_layout(width=None, height=None, margin={"l": 4, "r": 4, "t": 56, "b": 4},
                      title_font_size=11)
    return fig


# ----------------------------------------------------------------------------- jobs


@dataclass(frozen=True)
class ZonesJob(Job[Host]):
    """Label the zones of the shown map and colour the zone cloud (or hide the
    zones when "Show zones" is off); then queue the table."""

    z: ZonesFeature = field(compare=False)
    lane: ClassVar[str] = "zones"
    cancels: ClassVar[frozenset[str]] = frozenset({"zones-table", "zones-select"})

    @property
    def title(self) -> str:
        return "zones"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        z, shown = self.z, ctx.session.shown
        if not z.active:
            z.hide()
            yield "hide"
            return
        if shown.result is None:
            return
        try:
            params = z.params()
        except InputError as exc:
            ctx.show_error(str(exc))
            return
        lab = z.labelling
        if (lab is not None and lab.result is shown.result and lab.params == params
                and lab.loaded is shown.loaded and z.colouring is not None
                and z.pending_selection is None):
            z.show_colours()  # e.g. after "Show zones" off and on
            if not z.selected_nodes:
                z.draw_highlight()
            yield "unchanged"
            return
        t0 = time.perf_counter()
        basis, cached = z.basis(shown.loaded, shown.result, params.map_name,
                                shown.settings.grid_key, params.keep_outliers)
        t_basis = time.perf_counter() - t0
        yield "basis"
        t1 = time.perf_counter()
        labels = basis.labeller.label(params.threshold, connectivity=params.connectivity,
                                      min_cells=params.min_cells)
        t_label = time.perf_counter() - t1
        yield "label"
        lab = Labelling(shown.loaded, shown.result, shown.settings.grid_key, basis, params,
                        labels)
        z.colouring = by_cell(zone_cell_colours(labels, basis.valid), shown.result)
        z.show_colours()
        z.labelling, z.zones = lab, None
        if z.pending_selection is not None:
            z.anchor = lab.anchor_of(z.pending_selection)
            z.pending_selection = None
        z.draw_highlight()
        z.binding.show_threshold(params.threshold)
        done = time.perf_counter()
        z.binding.write(z.status, content=status_markdown(lab, done - t0, cached))
        record = {"basis_s": 0.0 if cached else t_basis, "label_s": t_label,
                  "colours_s": done - t1, "done": done}
        z.timings.append(record)
        yield "colours"
        ctx.submit(ZoneTableJob(z, lab, record))


@dataclass(frozen=True)
class ZoneTableJob(Job[Host]):
    """The zone table, the selected zone's numbers and the stereonet of ``labelling``."""

    z: ZonesFeature = field(compare=False)
    labelling: Labelling = field(compare=False)
    record: dict[str, float] = field(compare=False)
    lane: ClassVar[str] = "zones-table"

    @property
    def title(self) -> str:
        return "zone table"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        z, lab = self.z, self.labelling
        if z.labelling is not lab:
            return
        t0 = time.perf_counter()
        p = lab.params
        zones = lab.basis.labeller.measure(lab.labels, threshold=p.threshold,
                                           connectivity=p.connectivity, min_cells=p.min_cells)
        yield "measure"
        z.zones = zones
        z.show_selection()
        yield "table"
        z.show_stereonet(z.net(lab))
        self.record["table_s"] = time.perf_counter() - t0
        yield "stereonet"


@dataclass(frozen=True)
class SelectZoneJob(Job[Host]):
    """Select zone ``zone`` of ``labelling`` (0: none): highlight it in the scene,
    its numbers, its table row and its poles on the stereonet."""

    z: ZonesFeature = field(compare=False)
    labelling: Labelling = field(compare=False)
    zone: int
    stereonet_only: bool = False
    """The scene, numbers and table are drawn already (a click): only the stereonet."""
    lane: ClassVar[str] = "zones-select"

    @property
    def title(self) -> str:
        return "zone selection"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        z = self.z
        if z.labelling is not self.labelling:
            return  # re-labelled since: the ids the user saw are gone
        if not self.stereonet_only:
            z.anchor = self.labelling.anchor_of(self.zone)
            z.pending_selection = None
            z.draw_highlight()
            z.show_selection()
        yield "select"
        if z.zones is not None and z.zones.labels is self.labelling.labels:
            z.show_stereonet(z.net(self.labelling))
        yield "stereonet"


@dataclass(frozen=True)
class RestoreZonesJob(Job[Host]):
    """Saved zone settings in the tab (None: zones hidden), then the zones; the
    saved selection is selected once they are labelled."""

    z: ZonesFeature = field(compare=False)
    zones: ZoneSettings | None
    lane: ClassVar[str] = "zones-restore"

    @property
    def title(self) -> str:
        return "the saved view's zones"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        z = self.z
        z.binding.show(self.zones)
        if self.zones is not None:
            z.pending_selection = self.zones.selected
            z.anchor = None
        yield "settings"
        ctx.submit(ZonesJob(z))


# ----------------------------------------------------------------------------- mount


def _empty(title: str) -> go.Figure:
    fig = go.Figure()
    fig.update_layout(title={"text": title, "font": {"size": 12}},
                      margin={"l": 10, "r": 10, "t": 30, "b": 10})
    return fig


def mount(host: Host) -> ZonesFeature:
    """Add the Zones tab; zones follow every map and take scene clicks while shown."""
    gui = host.gui
    with host.tab("Zones"):
        z = ZonesFeature(
            host=host,
            on=gui.add_checkbox(L_ON, False, hint="Colour the rock by fracture zone: connected "
                                "cells at or above the threshold (Map tab's model and grid)."),
            threshold=gui.add_slider(L_THRESHOLD, min=0.0, max=1.0, step=0.01,
                                     initial_value=float(host.settings().threshold),
                                     hint="The Map tab's threshold: cells with normalised "
                                     "roughness ≥ this are rough."),
            connectivity=gui.add_dropdown(L_CONNECTIVITY, tuple(CONNECTIVITY_LABELS.values()),
                                          initial_value=CONNECTIVITY_LABELS[CONNECTIVITIES[0]],
                                          hint="Rough cells touching by a corner, an edge or "
                                          "a face belong to one zone."),
            rule=gui.add_dropdown(L_RULE, RULES, initial_value=RULE_AUTO,
                                  hint=f"With the slider at the paper's {DEFAULT_THRESHOLD:g}: "
                                  "use the data's own threshold (Otsu's split) when 0.05 "
                                  "flags more than half of the cells (rough-viewer zones' "
                                  "default), or the slider's value as it is."),
            min_cells=gui.add_number(L_MIN_CELLS, DEFAULT_MIN_CELLS, min=1, max=MAX_MIN_CELLS,
                                     step=1, hint="Smaller groups of rough cells are no zone."),
            status=gui.add_markdown("Tick **Show zones** to label the fracture and rubble "
                                    "zones of the map."),
            selected=gui.add_dropdown(L_SELECTED, (NO_ZONE,), initial_value=NO_ZONE,
                                      hint="Or click a zone on the rock."),
            numbers=gui.add_markdown(""),
            table=gui.add_plotly(_empty("zones"), config=PLOTLY_CONFIG, aspect=0.4),
            stereonet=gui.add_plotly(_empty("stereonet"), config=PLOTLY_CONFIG, aspect=0.95),
        )
    z.cache = ByteCache(host.options.cache_pool, most=host.options.cache_bytes // 2)
    host.allow(z.on, z.threshold, z.connectivity, z.min_cells, z.selected, z.rule)
    b = z.binding
    b.on_change([z.on, z.connectivity, z.min_cells, z.rule],
                lambda _h: host.submit(ZonesJob(z)))
    # the twin moves the Map tab's slider; the map's render moves the twin back
    b.on_change([z.threshold],
                lambda _h: host.request(threshold=float(z.threshold.value)))

    def select(_handle: object) -> None:
        lab = z.labelling
        if lab is None:
            return
        value = z.selected.value
        zone = 0 if value == NO_ZONE else _zone_of_option(value)
        if zone is not None:
            host.submit(SelectZoneJob(z, lab, zone))

    b.on_change([z.selected], select)
    host.on_click(z.on_pick)
    host.on_render(z.on_render)
    return z


def _zone_of_option(value: str) -> int | None:
    """Zone id of a dropdown entry (``Zone 3 — 412 cells``), None if it is not one."""
    parts = value.split(" ", 2)
    if len(parts) >= 2 and parts[0] == "Zone" and parts[1].isdigit():
        return int(parts[1])
    return None


__all__ = ["ZonesFeature", "ZoneParams", "ZoneBasis", "Labelling", "ZonesJob", "ZoneTableJob",
           "SelectZoneJob", "RestoreZonesJob", "mount", "zone_point_colours", "zone_basis"]
