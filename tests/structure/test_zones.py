"""Fracture zones: planted bands on faces of known orientation, connectivity on
hand-made grids (against scipy.ndimage.label), the zone table against direct
computation, and the demo outcrop against its ground truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.structure.zones import ZONE_COLUMNS, ZoneLabeller, face_coverage, find_zones
from rough_viewer.synthetic.demos import load_demo_with_truth
from rough_viewer.vocabulary import InputError
from tests.helpers import banded_face, face_axes

G = 0.2
#: (s, t, length, width, angle from strike towards down-dip), metres and degrees:
#: three bands at least 0.6 m (3 cells) apart, of decreasing area.
BANDS = [(-1.3, -1.6, 5.0, 0.6, 0.0), (2.3, 1.0, 3.4, 0.6, 60.0), (-2.2, 1.6, 2.8, 0.4, -30.0)]
FACES = [(35.0, 120.0), (60.0, 250.0), (80.0, 10.0), (20.0, 300.0), (89.0, 45.0), (5.0, 200.0),
         (45.0, 0.0)]


def angle_between_axes(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two lines (either sense), degrees."""
    c = abs(float(a @ b)) / (np.linalg.norm(a) * np.linalg.norm(b))
    return math.degrees(math.acos(min(1.0, c)))


@pytest.mark.parametrize(("dip", "direction"), FACES)
def test_planted_bands_give_their_zones(dip, direction):
    pts, band = banded_face(dip, direction, BANDS, rough=0.01, n=150_000)
    res = grid_roughness(pts, G)
    zones = ZoneLabeller.build(res).zones(0.2)
    assert zones.n_zones == len(BANDS)  # count exact
    assert np.all(np.diff(zones.cells) <= 0)  # ids by size, largest first
    strike, down, normal = face_axes(dip, direction)
    point_zone = zones.labels[res.point_cell]
    # the band whose points each zone holds: one zone per band, the largest first
    held = [int(np.bincount(band[point_zone == k + 1] + 1).argmax()) - 1 for k in range(3)]
    assert sorted(held) == [0, 1, 2] and held[0] == 0
    for k, b in enumerate(held):
        _, _, length, width, angle = BANDS[b]
        a = math.radians(angle)
        trace = math.cos(a) * strike + math.sin(a) * down
        assert angle_between_axes(zones.axis[k], trace) < 3.0
        # trend and plunge of the trace from the closed form
        down_trace = trace if trace[2] <= 0 else -trace
        plunge = math.degrees(math.asin(-down_trace[2]))
        assert zones.trace_plunge_deg[k] == pytest.approx(plunge, abs=3.0)
        if plunge < 80.0:
            trend = math.degrees(math.atan2(down_trace[0], down_trace[1])) % 360.0
            if plunge < 1.0:  # horizontal: trend in [0, 180)
                trend %= 180.0
            diff = (zones.trace_azimuth_deg[k] - trend + 180.0) % 360.0 - 180.0
            if plunge < 1.0:
                diff = (diff + 90.0) % 180.0 - 90.0
            assert abs(diff) < 3.0 / max(0.2, math.cos(math.radians(plunge)))
        # the face's orientation: normals within 1.5 degrees, the numbers within 1.5
        # degrees of dip and (where the dip direction is defined, dip >= 20) of direction
        assert angle_between_axes(zones.normal[k], normal) < 1.5
        assert zones.dip_deg[k] == pytest.approx(dip, abs=1.5)
        if dip >= 20.0:
            diff = (zones.dip_direction_deg[k] - direction + 180.0) % 360.0 - 180.0
            assert abs(diff) < 1.5
        # extents: the band's, plus one cell, give or take two cells (cells the band
        # edge crosses are rough too); the area between the band's and that bound
        assert abs(zones.length_m[k] - (length + G)) <= 2 * G
        assert abs(zones.width_m[k] - (width + G)) <= 2 * G
        assert length * width <= zones.area_m2[k] <= (length + 2 * G) * (width + 2 * G)


#: One patch of 30 points in cell-local units: a 6 x 5 lattice at mid-height with a
#: fixed pattern of heights, so every rough cell has the same roughness (and so has
#: every smooth cell).
_U, _V = np.meshgrid(np.linspace(0.1, 0.9, 6), np.linspace(0.1, 0.9, 5))
_PATTERN = np.clip(np.random.default_rng(12345).standard_normal(30), -3.0, 3.0)


def cells_cloud(rough: list[tuple[int, int, int]], smooth: list[tuple[int, int, int]],
                *, g: float = 1.0) -> np.ndarray:
    """Points in hand-picked cells of the grid of edge ``g`` at origin 0: a horizontal
    patch at mid-height in every cell, rough (heights 10 % of g) or smooth (0.1 %)."""
    out = []
    for cells, amplitude in ((rough, 0.1), (smooth, 0.001)):
        patch = np.column_stack([_U.ravel(), _V.ravel(), 0.5 + amplitude * _PATTERN])
        out += [(patch + cell) * g for cell in cells]
    return np.concatenate(out)


def labels_of(rough, smooth, connectivity, min_cells=1, threshold=0.5):
    res = grid_roughness(cells_cloud(rough, smooth), 1.0, origin=np.zeros(3))
    lab = ZoneLabeller.build(res).label(threshold, connectivity=connectivity,
                                        min_cells=min_cells)
    return {tuple(int(v) for v in ijk): int(z) for ijk, z in zip(res.ijk, lab, strict=True)}


SMOOTH = [(5, 5, 5), (6, 5, 5), (5, 6, 5)]


@pytest.mark.parametrize(("pair", "joined"), [
    (((0, 0, 0), (1, 0, 0)), {"face", "edge", "vertex"}),   # share a face
    (((0, 0, 0), (1, 1, 0)), {"edge", "vertex"}),           # share an edge
    (((0, 0, 0), (0, 1, 1)), {"edge", "vertex"}),
    (((0, 0, 0), (1, 1, 1)), {"vertex"}),                   # share a corner
    (((0, 0, 0), (2, 0, 0)), set()),                        # a cell apart
])
def test_connectivity_on_two_cells(pair, joined):
    for conn in ("face", "edge", "vertex"):
        lab = labels_of(list(pair), SMOOTH, conn)
        a, b = (lab[c] for c in pair)
        assert a > 0 and b > 0
        assert (a == b) == (conn in joined), conn
        assert all(lab[c] == 0 for c in SMOOTH)
        # pairs of single cells vanish with min_cells = 2 unless joined
        lab2 = labels_of(list(pair), SMOOTH, conn, min_cells=2)
        assert (lab2[pair[0]] > 0) == (conn in joined)


def test_l_shape_and_min_cells():
    # an L of three face-neighbours, a diagonal tail of two, a lone corner cell
    rough = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (2, 2, 0), (3, 3, 0), (4, 4, 1)]
    face = labels_of(rough, SMOOTH, "face")
    edge = labels_of(rough, SMOOTH, "edge")
    vertex = labels_of(rough, SMOOTH, "vertex")
    assert len({face[c] for c in rough}) == 4  # L, then three single cells
    assert face[(0, 0, 0)] == 1  # the largest zone has id 1
    assert len({edge[c] for c in rough}) == 2  # L + tail, lone corner cell
    assert len({vertex[c] for c in rough}) == 1
    big = labels_of(rough, SMOOTH, "edge", min_cells=6)
    assert all(big[c] == 0 for c in rough)
    five = labels_of(rough, SMOOTH, "edge", min_cells=5)
    assert [five[c] for c in rough] == [1, 1, 1, 1, 1, 0]


@pytest.mark.parametrize(("connectivity", "rank"), [("face", 1), ("edge", 2), ("vertex", 3)])
def test_labels_match_scipy_ndimage_on_random_cells(connectivity, rank):
    rng = np.random.default_rng(rank)
    shape = (10, 9, 5)
    occupied = np.argwhere(rng.random(shape) < 0.45)
    is_rough = rng.random(occupied.shape[0]) < 0.5
    rough = [tuple(c) for c in occupied[is_rough]]
    smooth = [tuple(c) for c in occupied[~is_rough]]
    res = grid_roughness(cells_cloud(rough, smooth), 1.0, origin=np.zeros(3))
    labeller = ZoneLabeller.build(res)
    dense = np.zeros(shape, dtype=bool)
    dense[tuple(np.array(rough).T)] = True
    ref, n_ref = ndimage.label(dense, structure=ndimage.generate_binary_structure(3, rank))
    sizes = np.bincount(ref.ravel())
    for min_cells in (1, 3):
        lab = labeller.label(0.5, connectivity=connectivity, min_cells=min_cells)
        ours = lab
        theirs = ref[tuple(res.ijk.T)]
        kept = (theirs > 0) & (sizes[theirs] >= min_cells)
        np.testing.assert_array_equal(ours > 0, kept)
        # the same partition: a one-to-one map between their labels and ours
        pairs = set(zip(ours[kept].tolist(), theirs[kept].tolist(), strict=True))
        assert len(pairs) == len(set(ours[kept].tolist())) == len(set(theirs[kept].tolist()))
        # ids by size, ties in grid order (the first cell of each zone)
        counts = np.bincount(ours)[1:]
        first = np.array([np.flatnonzero(ours == z)[0] for z in range(1, counts.size + 1)])
        order = np.lexsort((first, -counts))
        np.testing.assert_array_equal(order, np.arange(counts.size))
    assert n_ref >= 3  # not one trivial blob


def test_zone_table_against_direct_computation():
    # one flat layer: a row of seven rough cells along x, a rough block of 2 x 3 cells
    # along y, and smooth cells around
    row = [(i, 2, 0) for i in range(1, 8)]
    block = [(i, j, 0) for j in (5, 6, 7) for i in (1, 2)]
    smooth = [(i, j, 0) for i in range(0, 9) for j in range(0, 9)
              if (i, j, 0) not in row + block]
    g = 0.5
    pts = cells_cloud(row + block, smooth, g=g)
    res = grid_roughness(pts, g, origin=np.zeros(3))
    zones = find_zones(res, 0.5, connectivity="face")
    assert zones.n_zones == 2
    table = zones.table()
    assert tuple(table) == ZONE_COLUMNS
    np.testing.assert_array_equal(table["zone"], [1, 2])
    np.testing.assert_array_equal(table["cells"], [7, 6])
    # the row: 7 cells along x (trend 90, horizontal), one cell wide, 7 g^2 of face
    assert table["length_m"][0] == pytest.approx(7 * g)
    assert table["width_m"][0] == pytest.approx(g)
    assert table["trace_azimuth_deg"][0] == pytest.approx(90.0, abs=1e-6)
    assert table["trace_plunge_deg"][0] == pytest.approx(0.0, abs=1e-6)
    assert table["area_m2"][0] == pytest.approx(7 * g * g, rel=0.01)  # planes tilt a little
    # the block: 3 cells along y (trend 0), 2 across, 6 g^2
    assert table["length_m"][1] == pytest.approx(3 * g)
    # (across is measured in the plane of the zone's mean normal, tilted 8 degrees by
    # the height pattern: cos 8 of the centres' spread)
    assert table["width_m"][1] == pytest.approx(2 * g, rel=0.01)
    assert table["trace_azimuth_deg"][1] == pytest.approx(0.0, abs=1e-6)
    assert table["area_m2"][1] == pytest.approx(6 * g * g, rel=0.01)
    # points, roughness, centroid and orientation against the cells and points directly
    point_zone = zones.labels[res.point_cell]
    for k in range(2):
        cells = zones.labels == k + 1
        assert table["points"][k] == np.count_nonzero(point_zone == k + 1)
        assert table["mean_theta"][k] == pytest.approx(res.theta_odr[cells].mean(), rel=1e-12)
        assert table["max_theta"][k] == res.theta_odr[cells].max()
        centroid = pts[point_zone == k + 1].mean(axis=0)
        for a, name in enumerate(("cx", "cy", "cz")):
            assert table[name][k] == pytest.approx(centroid[a], abs=1e-12)
        # horizontal patches: the mean normal is near vertical, dip near 0
        assert table["dip_deg"][k] < 10.0


def test_face_area_of_a_whole_face_at_any_orientation():
    for dip, direction in ((0.0, 0.0), (37.0, 100.0), (90.0, 45.0), (63.0, 300.0)):
        pts, _ = banded_face(dip, direction, [], size=(6.0, 5.0), n=120_000, smooth=0.001)
        res = grid_roughness(pts, 0.25)
        cover = face_coverage(res)
        zones = find_zones(res, 0.0, min_cells=1)
        assert zones.n_zones == 1
        # 30 m^2; the cells along the rim hold planes that reach past the face's
        # edge (22 m of rim, half a cell each on average)
        # (and rim cells with fewer than 3 points have no plane: a little less)
        assert 0.98 * 30.0 <= zones.area_m2[0] <= 30.0 + 22.0 * 0.5 * 0.25 * 1.2
        assert zones.area_m2[0] <= cover.cell_area.sum() + 1e-9


def test_face_straddling_a_cell_boundary_is_counted_once():
    # a flat face at z = 1.0 +- 2 mm on a grid whose cell boundary is at z = 1.0:
    # every column of cells holds two cells, the face is counted once
    rng = np.random.default_rng(3)
    xy = rng.uniform(0.0, 2.0, (40_000, 2))
    pts = np.column_stack([xy, 1.0 + 0.002 * rng.standard_normal(40_000)])
    res = grid_roughness(pts, 0.25, origin=np.array([0.0, 0.0, 0.0]))
    assert res.n_cells == 128
    zones = find_zones(res, 0.0, min_cells=1)
    assert zones.area_m2[0] == pytest.approx(4.0)


def test_label_is_consistent_and_rejects_bad_options():
    pts, _ = banded_face(50.0, 80.0, BANDS, rough=0.01, n=60_000)
    res = grid_roughness(pts, G)
    labeller = ZoneLabeller.build(res)
    norm = labeller.normalised
    for threshold in (0.0, 0.05, 0.3, 1.0):
        lab = labeller.label(threshold)
        assert np.all((lab == 0) | (norm >= threshold))
        assert np.all(np.bincount(lab)[1:] >= 3)
    # threshold 0: every cell with a value is rough; 1: only the roughest cell, dropped
    assert labeller.label(1.0).max() == 0
    assert labeller.label(1.0, min_cells=1).max() == 1
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(InputError, match="threshold"):
            labeller.label(bad)
    with pytest.raises(InputError, match="connectivity"):
        labeller.label(0.2, connectivity="diagonal")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="min cells"):
        labeller.label(0.2, min_cells=0)
    with pytest.raises(InputError, match="map"):
        ZoneLabeller.build(res, "rms")  # type: ignore[arg-type]


def test_other_maps_and_no_zones():
    pts, _ = banded_face(50.0, 80.0, BANDS, rough=0.01, n=60_000)
    res = grid_roughness(pts, G)
    for name in ("ols", "hybrid", "e_ols"):
        zones = find_zones(res, 0.2, map_name=name)
        assert zones.map_name == name
        cells = zones.labels > 0
        assert np.all(res.values(name)[cells] >= np.nanmin(res.values(name)))
    flat = grid_roughness(banded_face(10.0, 0.0, [], n=20_000)[0], 0.5)
    none = ZoneLabeller.build(flat).zones(1.0)
    assert none.n_zones == 0 and all(v.shape[0] == 0 for v in none.table().values())


@pytest.mark.slow
def test_demo_outcrop_zones_against_ground_truth():
    """Measure: a cell is a truth fracture/rubble cell when at least 20 % of its
    points are fracture or rubble points; precision = share of zone cells that are
    truth cells, recall = share of truth cells in zones; and per class, the share of
    its points that lie in zones (ODR, g = 0.125 m, threshold 0.1, vertex, >= 3 cells)."""
    cloud, truth = load_demo_with_truth("outcrop-small")
    res = grid_roughness(cloud, 0.125)
    zones = ZoneLabeller.build(res).zones(0.1)
    valued = np.isfinite(res.theta_odr)
    broken = np.bincount(res.point_cell, weights=truth.labels > 0, minlength=res.n_cells)
    truth_cell = valued & (broken / res.n_points >= 0.2)
    in_zone = zones.labels > 0
    hits = np.count_nonzero(in_zone & truth_cell)
    precision = hits / np.count_nonzero(in_zone)
    recall = hits / np.count_nonzero(truth_cell)
    base_rate = np.count_nonzero(truth_cell) / np.count_nonzero(valued)
    assert precision >= 0.75 and recall >= 0.5  # measured 0.81, 0.59
    assert precision >= 2.0 * base_rate  # base rate 0.33
    point_zone = zones.labels[res.point_cell]
    share = {name: np.mean(point_zone[truth.labels == c] > 0)
             for c, name in enumerate(truth.names)}
    assert share["rubble"] >= 0.65  # measured 0.73
    assert share["column-bounding fracture"] >= 0.55  # 0.66
    assert share["column-normal fracture"] >= 0.55  # 0.64
    assert share["rock"] <= 0.15  # 0.11
    # the largest zone is the rubbly flow margin: mostly rubble points, its trace
    # near horizontal and along the face (which runs along x: azimuth 90)
    first = truth.labels[point_zone == 1]
    assert np.mean(first == truth.names.index("rubble")) >= 0.5
    assert zones.trace_plunge_deg[0] < 25.0
    assert abs(((zones.trace_azimuth_deg[0] - 90.0 + 90.0) % 180.0) - 90.0) < 30.0
