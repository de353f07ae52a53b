"""Joint sets: the planted joint block (three sets of known orientation, scatter,
spacing and persistence), Fisher statistics against their closed forms and an
independent sampler, density peaks against a brute-force kernel sum, the sign and
quadrant conventions of the dip direction, hand-made planes, and clouds without
planes."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.stats import vonmises_fisher

from rough_viewer.grid.orientation import stereonet
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.structure.sets import (
    PLANE_COLUMNS,
    SET_COLUMNS,
    SetOptions,
    density_peaks,
    fisher_statistics,
    joint_sets,
    set_point_fields,
)
from rough_viewer.synthetic.joints import JOINT_BLOCK, generate_joint_block
from rough_viewer.vocabulary import InputError
from tests.helpers import axis_angle, face_axes

G = 0.25


@pytest.fixture(scope="module")
def block():
    scan = generate_joint_block(JOINT_BLOCK)
    result = grid_roughness(scan.cloud, G, models=("odr",))
    return scan, result, joint_sets(result, scan.cloud)


def _matching(scan, sets) -> list[int]:
    """The planted set (1..3) of every found set, by the nearest mean normal."""
    return [int(np.argmin([axis_angle(n, m) for m in scan.set_normal])) + 1 for n in sets.normal]


# ----------------------------------------------------------------------------- the block


def test_three_planted_sets_found_with_their_orientation_and_scatter(block):
    scan, _, sets = block
    assert sets.n_sets == 3 and sets.note == ""
    planted = _matching(scan, sets)
    assert sorted(planted) == [1, 2, 3]
    for k, p in enumerate(planted):
        spec = JOINT_BLOCK.sets[p - 1]
        # mean orientation within 2 degrees of the planted mean (as an axis, and as
        # the dip and dip direction numbers)
        assert axis_angle(sets.normal[k], scan.set_normal[p - 1]) < 2.0
        assert sets.dip_deg[k] == pytest.approx(spec.dip_deg, abs=2.0)
        diff = (sets.dip_direction_deg[k] - spec.dip_direction_deg + 180.0) % 360.0 - 180.0
        assert abs(diff) < 2.0
        # Fisher concentration within 25 % of the planted kappa
        assert sets.kappa[k] == pytest.approx(spec.kappa, rel=0.25)
        # the set's cells are the planted set's planes (the rough wall is no set)
        on = sets.cell_set[result_cells(block)] == k + 1
        assert np.mean(cell_truth(block)[on] == p) > 0.97


def result_cells(block) -> np.ndarray:
    return np.arange(block[1].n_cells)


def cell_truth(block) -> np.ndarray:
    """The planted set most points of every cell belong to (0: the wall)."""
    scan, result, _ = block
    counts = np.zeros((result.n_cells, 4))
    np.add.at(counts, (result.point_cell, scan.set_id.astype(np.int64)), 1.0)
    return np.argmax(counts, axis=1)


def test_planted_planes_spacing_and_persistence(block):
    scan, _, sets = block
    pl = sets.planes
    for k, p in enumerate(_matching(scan, sets)):
        spec = JOINT_BLOCK.sets[p - 1]
        planted = scan.spacings(p)
        assert sets.n_planes_per_set[k] == spec.planes
        # normal spacing within 5 % of the planted spacing (mean and median)
        assert sets.spacing_mean[k] == pytest.approx(planted.mean(), rel=0.05)
        assert sets.spacing_median[k] == pytest.approx(np.median(planted), rel=0.05)
        assert sets.spacing_std[k] == pytest.approx(planted.std(), abs=0.05)
        # persistence within 10 %: the set's mean, and every plane's two chords
        longer = max(spec.dip_length_m, spec.strike_length_m)
        assert sets.persistence_mean[k] == pytest.approx(longer, rel=0.10)
        mine = np.flatnonzero(pl.set_id == k + 1)
        assert pl.persistence_dip[mine] == pytest.approx(spec.dip_length_m, rel=0.10)
        assert pl.persistence_strike[mine] == pytest.approx(spec.strike_length_m, rel=0.10)
        # area within 5 % (the edge cells of fewer than 10 points join their plane)
        assert pl.area[mine] == pytest.approx(spec.dip_length_m * spec.strike_length_m,
                                              rel=0.05)
        # every plane is one planted plane, its ODR fit within 1 degree of it
        for i in mine:
            pts = sets.cell_plane[block[1].point_cell] == i + 1
            truth = np.bincount(scan.plane[pts] + 1).argmax() - 1
            assert np.mean(scan.plane[pts] == truth) > 0.99
            assert axis_angle(pl.normal[i], scan.planes.normal[truth]) < 1.0
            assert np.linalg.norm(pl.centroid[i] - scan.planes.centre[truth]) < 0.1
            assert pl.rms[i] < 0.003  # 2 mm of range noise, oblique


def test_tables_follow_the_contract(block):
    _, _, sets = block
    assert tuple(sets.set_table()) == SET_COLUMNS
    assert tuple(sets.plane_table()) == PLANE_COLUMNS
    mm = sets.plane_table(1e-3)
    m = sets.plane_table()
    assert mm["area"] == pytest.approx(m["area"] * 1e6)
    assert mm["persistence_dip"] == pytest.approx(m["persistence_dip"] * 1e3)
    assert mm["dip_deg"] == pytest.approx(m["dip_deg"])
    dips = sets.dips_table()
    assert list(dips)[:3] == ["Dip", "Dip Direction", "Quantity"]
    assert dips["Dip"] == pytest.approx(m["dip_deg"])


def test_point_fields_carry_each_points_cell_ids(block):
    _, result, sets = block
    fields = set_point_fields(sets, result)
    assert fields.names == ("set_id", "plane_id", "joint_id")
    set_values, plane_values, joint_values = fields.gather(0, fields.n_points)
    assert np.array_equal(set_values, sets.cell_set[result.point_cell])
    assert np.array_equal(plane_values, sets.cell_plane[result.point_cell])
    # a point's joint is its plane's (patch's) joint
    on = plane_values > 0
    assert np.array_equal(joint_values[on], sets.planes.joint_id[plane_values[on] - 1])
    assert np.all(joint_values[~on] == 0)


# ----------------------------------------------------------------------------- conventions


def test_sets_do_not_depend_on_the_sign_of_the_normals(block):
    scan, result, sets = block
    flip = np.where(np.random.default_rng(3).uniform(size=result.n_cells) < 0.5, -1.0, 1.0)
    flipped = dataclasses.replace(result, normal=result.normal * flip[:, None])
    again = joint_sets(flipped, scan.cloud)
    for name in ("dip_deg", "dip_direction_deg", "fisher_kappa", "spacing_mean",
                 "persistence_mean"):
        assert again.set_table()[name] == pytest.approx(sets.set_table()[name], rel=1e-9)
    assert np.array_equal(again.cell_plane, sets.cell_plane)


def tilted_plane(dip: float, direction: float, *, n: int = 30_000, seed: int = 0) -> np.ndarray:
    """Points of a 4 m x 4 m plane of the given dip and dip direction, 1 mm noise."""
    rng = np.random.default_rng(seed)
    strike, down, normal = face_axes(dip, direction)
    st = rng.uniform(-2.0, 2.0, (n, 2))
    return (st[:, :1] * strike + st[:, 1:] * down + 0.001 * rng.standard_normal((n, 1)) * normal
            + np.array([100.0, 200.0, 50.0]))


@pytest.mark.parametrize("direction", [45.0, 135.0, 225.0, 315.0])
def test_dip_direction_in_the_four_quadrants_for_either_sign(direction):
    pts = tilted_plane(40.0, direction)
    result = grid_roughness(pts, 0.5, models=("odr",))
    for sign in (1.0, -1.0):
        res = dataclasses.replace(result, normal=sign * result.normal)
        sets = joint_sets(res, pts)
        assert sets.n_sets == 1 and sets.planes.n_planes == 1
        assert sets.dip_deg[0] == pytest.approx(40.0, abs=0.2)
        assert sets.dip_direction_deg[0] == pytest.approx(direction, abs=0.2)
        assert sets.planes.dip_direction_deg[0] == pytest.approx(direction, abs=0.2)
        assert sets.planes.rms[0] == pytest.approx(0.001, rel=0.03)  # the noise
        assert sets.planes.persistence_strike[0] == pytest.approx(4.0, rel=0.02)
        # the pole is the downward normal: trend dip direction + 180
        assert sets.mean_pole[0, 2] < 0


# ----------------------------------------------------------------------------- Fisher


def test_fisher_statistics_match_their_closed_forms():
    rng = np.random.default_rng(5)
    v = vonmises_fisher(np.array([0.0, 0.6, 0.8]), 30.0).rvs(40, random_state=rng)
    n = v.shape[0]
    r = float(np.linalg.norm(v.sum(axis=0)))
    st = fisher_statistics(v)
    assert st.n == n and st.resultant == pytest.approx(r, rel=1e-12)
    assert st.kappa == pytest.approx((n - 1) / (n - r), rel=1e-12)
    alpha = math.degrees(math.acos(1 - (n - r) / r * (20.0 ** (1 / (n - 1)) - 1)))
    assert st.alpha95_deg == pytest.approx(alpha, rel=1e-12)
    assert st.mean == pytest.approx(v.sum(axis=0) / r)
    # weights: the weighted resultant's direction, R = N |sum w v| / sum w
    w = rng.uniform(1.0, 5.0, n)
    sw = (w[:, None] * v).sum(axis=0)
    rw = n * np.linalg.norm(sw) / w.sum()
    stw = fisher_statistics(v, w)
    assert stw.mean == pytest.approx(sw / np.linalg.norm(sw))
    assert stw.kappa == pytest.approx((n - 1) / (n - rw), rel=1e-12)
    # integer weights are repeated vectors for the mean direction
    k = rng.integers(1, 4, n)
    rep = fisher_statistics(np.repeat(v, k, axis=0))
    assert fisher_statistics(v, k.astype(float)).mean == pytest.approx(rep.mean)


def test_fisher_kappa_and_alpha95_on_samples_of_a_known_distribution():
    rng = np.random.default_rng(7)
    mu = np.array([0.3, -0.4, 0.866])
    mu /= np.linalg.norm(mu)
    big = vonmises_fisher(mu, 40.0).rvs(20_000, random_state=rng)
    assert fisher_statistics(big).kappa == pytest.approx(40.0, rel=0.03)
    # the true mean lies inside alpha95 in 95 % of samples (400 samples of 15:
    # binomial standard deviation 1.1 %)
    inside = 0
    for _ in range(400):
        s = fisher_statistics(vonmises_fisher(mu, 25.0).rvs(15, random_state=rng))
        inside += axis_angle(s.mean, mu) <= s.alpha95_deg
    assert inside / 400 == pytest.approx(0.95, abs=0.035)


# ----------------------------------------------------------------------------- density peaks


def brute_density(directions: np.ndarray, poles: np.ndarray, w: np.ndarray,
                  sigma_deg: float) -> np.ndarray:
    """The axial Fisher kernel summed pole by pole, in MUD (written out here)."""
    kappa = 1.0 / math.radians(sigma_deg) ** 2
    out = np.empty(directions.shape[0])
    for s in range(0, directions.shape[0], 2000):  # every pole at every direction
        out[s:s + 2000] = np.exp(kappa * (np.abs(directions[s:s + 2000] @ poles.T) - 1.0)) @ w
    return out / (w.sum() * (1.0 - math.exp(-kappa)) / kappa)


def cap(centre: np.ndarray, radius_deg: float, step_deg: float) -> np.ndarray:
    """Unit vectors on a square lattice of ``step_deg`` within ``radius_deg`` of ``centre``."""
    c = centre / np.linalg.norm(centre)
    u = np.cross(c, [1.0, 0.0, 0.0] if abs(c[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(c, u)
    t = np.radians(np.arange(-radius_deg, radius_deg + 1e-9, step_deg))
    a, b = np.meshgrid(t, t)
    keep = np.hypot(a, b) <= math.radians(radius_deg)
    d = c + np.tan(a[keep])[:, None] * u + np.tan(b[keep])[:, None] * v
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def unit(v: list[float]) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    return a / np.linalg.norm(a)


def test_density_peaks_are_the_brute_force_maxima():
    rng = np.random.default_rng(11)
    a = vonmises_fisher(unit([0.5, 0.1, -0.86]), 60.0).rvs(300, random_state=rng)
    b = vonmises_fisher(unit([0.0, -0.99, -0.14]), 120.0).rvs(200, random_state=rng)
    u = rng.normal(size=(300, 3))
    poles = np.vstack([a, b, u / np.linalg.norm(u, axis=1, keepdims=True)])
    poles *= np.where(poles[:, 2] > 0, -1.0, 1.0)[:, None]
    w = rng.uniform(1.0, 30.0, poles.shape[0])
    net = stereonet(poles, weights=w)
    peaks, dens = density_peaks(net, poles, w, min_density=3.0, min_angle_deg=30.0)
    assert peaks.shape == (2, 3) and np.all(np.diff(dens) <= 0)
    # the strongest peak is the brute-force maximum over the whole lower hemisphere
    fib = np.arange(40_000) + 0.5
    z = -fib / fib.size
    r = np.sqrt(1 - z * z)
    phi = math.pi * (3 - math.sqrt(5)) * fib
    hemi = np.column_stack([r * np.cos(phi), r * np.sin(phi), z])
    coarse = brute_density(hemi, poles, w, 6.0)
    assert axis_angle(hemi[np.argmax(coarse)], peaks[0]) < 1.0
    for p, d in zip(peaks, dens, strict=True):
        # the peak's density is the kernel sum, and nothing within 3 degrees is higher
        assert brute_density(p[None], poles, w, 6.0)[0] == pytest.approx(d, rel=1e-9)
        near = cap(p, 3.0, 0.05)
        fine = brute_density(near, poles, w, 6.0)
        assert fine.max() <= d * (1 + 1e-9)
        assert axis_angle(near[np.argmax(fine)], p) < 0.08
    # the two peaks are the two planted clusters
    planted = [unit([0.5, 0.1, -0.86]), unit([0.0, -0.99, -0.14])]
    assert sorted(int(np.argmin([axis_angle(p, q) for q in planted])) for p in peaks) == [0, 1]
    assert max(min(axis_angle(p, q) for q in planted) for p in peaks) < 3.0


def test_min_angle_and_max_sets_limit_the_peaks():
    rng = np.random.default_rng(2)
    a = vonmises_fisher(unit([0.0, 0.0, -1.0]), 200.0).rvs(300, random_state=rng)
    b = vonmises_fisher(unit([0.34, 0.0, -0.94]), 200.0).rvs(200, random_state=rng)  # 20 deg
    c = vonmises_fisher(unit([0.0, 0.9, -0.44]), 200.0).rvs(100, random_state=rng)
    poles = np.vstack([a, b, c])
    w = np.ones(poles.shape[0])
    net = stereonet(poles)
    assert density_peaks(net, poles, w, min_angle_deg=10.0)[0].shape[0] == 3
    two, _ = density_peaks(net, poles, w, min_angle_deg=30.0)  # b is too close to a
    assert two.shape[0] == 2 and axis_angle(two[1], [0.0, 0.9, -0.44]) < 2.0
    assert density_peaks(net, poles, w, min_angle_deg=10.0, max_peaks=1)[0].shape[0] == 1


# ----------------------------------------------------------------------------- planes


def test_a_step_gives_two_planes_one_spacing_apart():
    """Two treads dipping 10 degrees east, 0.3 m apart along their normal, joined by
    a rough riser: one set, two planes, spacing 0.3 m; each tread's chords are its
    extents (2 m down dip, 3 m along strike)."""
    rng = np.random.default_rng(4)
    strike, down, normal = face_axes(10.0, 90.0)
    n = 60_000
    s, d = rng.uniform(0.0, 3.0, n), rng.uniform(0.0, 4.0, n)
    h = np.where(d < 2.0, 0.3, 0.0) + 0.0005 * rng.standard_normal(n)
    m = 4000
    riser = (rng.uniform(0.0, 3.0, m)[:, None] * strike
             + (2.0 + 0.03 * rng.standard_normal(m))[:, None] * down
             + rng.uniform(0.0, 0.3, m)[:, None] * normal)
    pts = np.vstack([s[:, None] * strike + d[:, None] * down + h[:, None] * normal, riser])
    result = grid_roughness(pts, 0.2, models=("odr",))
    sets = joint_sets(result, pts)
    assert sets.n_sets == 1 and sets.planes.n_planes == 2
    assert sets.dip_deg[0] == pytest.approx(10.0, abs=0.2)
    assert sets.dip_direction_deg[0] == pytest.approx(90.0, abs=0.5)
    assert sets.spacing_mean[0] == pytest.approx(0.3, rel=0.02)
    pl = sets.planes
    # the cells where a tread meets the riser are rough (both in one cell): a tread
    # loses at most one cell (0.2 m) down its dip there, none along its strike
    assert np.all((pl.persistence_dip > 2.0 - 0.2) & (pl.persistence_dip <= 2.0))
    assert pl.persistence_strike == pytest.approx([3.0, 3.0], rel=0.02)
    assert np.all((pl.area > 6.0 - 3.0 * 0.2) & (pl.area < 6.0 * 1.02))
    assert np.all((pl.rms >= 0.0005 * 0.9) & (pl.rms < 0.001))  # a few riser points


def test_a_curved_surface_chained_cell_by_cell_is_no_plane():
    """A smooth vault (radius 6 m): its cells are planar and touch with small offset
    steps, but together they curve far more than the plane tolerance."""
    rng = np.random.default_rng(12)
    n = 120_000
    a = rng.uniform(-0.6, 0.6, n)  # radians along the arc
    y = rng.uniform(0.0, 6.0, n)
    r = 6.0 + 0.0005 * rng.standard_normal(n)
    pts = np.column_stack([r * np.sin(a), y, r * np.cos(a)])
    result = grid_roughness(pts, 0.25, models=("odr",))
    sets = joint_sets(result, pts)
    assert sets.n_sets >= 1 and sets.curved_groups >= 1
    assert sets.planes.n_planes == 0 and not sets.cell_plane.any()
    flat = tilted_plane(30.0, 100.0)
    assert joint_sets(grid_roughness(flat, 0.5), flat).curved_groups == 0


# ----------------------------------------------------------------------------- no planes


def test_a_rough_cloud_has_no_set_and_says_so():
    rng = np.random.default_rng(9)
    xy = rng.uniform(0.0, 4.0, (40_000, 2))
    pts = np.column_stack([xy, 0.05 * rng.standard_normal(40_000)])  # rubble, no plane
    result = grid_roughness(pts, 0.25, models=("odr",))
    sets = joint_sets(result, pts)
    assert sets.n_sets == 0 and sets.planes.n_planes == 0
    assert "no planar cell" in sets.note and "no joint set" in sets.note
    assert not sets.cell_set.any() and not sets.cell_plane.any()
    assert all(v.shape == (0,) for v in sets.set_table().values())


def test_a_smooth_sphere_has_no_preferred_plane():
    rng = np.random.default_rng(10)
    v = rng.normal(size=(200_000, 3))
    pts = 3.0 * v / np.linalg.norm(v, axis=1, keepdims=True)
    result = grid_roughness(pts, 0.3, models=("odr",))
    sets = joint_sets(result, pts)
    assert sets.planar.sum() > 500  # the sphere is smooth at the cell scale ...
    assert sets.n_sets == 0  # ... but no orientation is preferred
    assert "no density peak" in sets.note


def test_bad_options_are_refused():
    with pytest.raises(InputError, match="cone"):
        SetOptions(cone_deg=120.0)
    with pytest.raises(InputError, match="sets"):
        SetOptions(max_sets=0)
    with pytest.raises(InputError, match="planar cell"):
        SetOptions(min_planar_points=0)
    pts = tilted_plane(30.0, 90.0, n=5000)
    result = grid_roughness(pts, 0.5)
    with pytest.raises(InputError, match="points of the grid result"):
        joint_sets(result, pts[:100])
    with pytest.raises(InputError, match="roughness"):
        SetOptions(max_roughness=-1.0)
