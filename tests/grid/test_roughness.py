"""Grid roughness against a brute-force per-cell loop and closed-form references."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness, whole_cloud_axis
from rough_viewer.io import PointCloud
from tests.helpers import random_rotation, rough_surface

AX = {"x": 0, "y": 1, "z": 2}
#: Absolute floor of the comparisons, metres (a picometre): 3 points fix a plane
#: exactly, and both sides then return rounding noise (1e-17 to 1e-14 m, larger for
#: OLS along an axis nearly parallel to the plane) instead of 0.
ATOL = 1e-12


def brute_force(xyz, g, *, origin=None, axis="z", min_points=4, signed=False):
    """Per-cell loop with numpy SVD / lstsq: dict (i, j, k) -> (n, odr, ols, hybrid, normal)."""
    o = xyz.min(axis=0) if origin is None else np.asarray(origin)
    ijk = np.floor((xyz - o) / g).astype(np.int64)
    out = {}
    a = AX[axis]
    u, v = [i for i in range(3) if i != a]
    for key in {tuple(r) for r in ijk}:
        p = xyz[np.all(ijk == key, axis=1)]
        if len(p) < min_points:
            out[key] = (len(p), np.nan, np.nan, np.nan, None)
            continue
        # Shift by one of the cell's points first (an exact subtraction for nearby
        # floats): the mean of raw UTM coordinates is off by ~1e-9 m, which moves the
        # plane and the std of |D| by ~1e-8 relative.
        p = p - p[0]
        c = p.mean(axis=0)
        _, s, vt = np.linalg.svd(p - c)
        n = vt[2]
        d = (p - c) @ n
        q = p - c  # centred: lstsq on raw coordinates would lose precision
        A = np.column_stack([np.ones(len(p)), q[:, u], q[:, v]])
        coef, *_ = np.linalg.lstsq(A, q[:, a], rcond=None)
        r = q[:, a] - A @ coef
        dh = d / abs(n[a])
        if signed:
            t = (np.sqrt(np.mean(d**2)), np.sqrt(np.mean(r**2)), np.sqrt(np.mean(dh**2)))
        else:
            t = (np.abs(d).std(), np.abs(r).std(), np.abs(dh).std())
        out[key] = (len(p), *t, n)
    return out


def result_by_key(res):
    return {tuple(k): i for i, k in enumerate(res.ijk)}


@pytest.mark.parametrize("signed", [False, True])
@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_every_model_matches_brute_force(axis, signed):
    rng = np.random.default_rng(7)
    # a rough surface plus a blob of fully random 3-D points: varied, non-planar cells
    xyz = np.vstack([rough_surface(3000, seed=3, size=2.0), rng.uniform(0, 2.0, (600, 3))])
    xyz = xyz @ random_rotation(11).T + np.array([512_345.0, 4_765_432.0, 1234.0])
    g = 0.5
    res = grid_roughness(PointCloud.from_xyz(xyz), g, axis=axis,
                         residual="signed" if signed else "absolute")
    ref = brute_force(xyz, g, axis=axis, signed=signed)
    keys = result_by_key(res)
    assert set(keys) == set(ref)
    checked = 0
    for key, (n, t_odr, t_ols, t_hyb, normal) in ref.items():
        i = keys[key]
        assert res.n_points[i] == n
        if n < 4:  # the default min_points: 3 points fix a plane exactly
            assert np.isnan(res.theta_odr[i]) and np.isnan(res.theta_ols[i])
            continue
        np.testing.assert_allclose(res.theta_odr[i], t_odr, rtol=1e-9, atol=ATOL)
        np.testing.assert_allclose(res.theta_ols[i], t_ols, rtol=1e-9, atol=ATOL)
        np.testing.assert_allclose(res.theta_hybrid[i], t_hyb, rtol=1e-9, atol=ATOL)
        np.testing.assert_allclose(res.e_ols[i], abs(t_ols - t_odr), rtol=1e-6, atol=2 * ATOL)
        np.testing.assert_allclose(abs(res.normal[i] @ normal), 1.0, rtol=1e-9, atol=ATOL)
        checked += 1
    assert checked > 20
    # every point's cell is its floor((p - o) / g) cell
    o = xyz.min(axis=0)
    ijk = np.floor((xyz - o) / g).astype(np.int64)
    np.testing.assert_array_equal(res.ijk[res.point_cell], ijk)
    np.testing.assert_allclose(res.centre, o + (res.ijk + 0.5) * g)


def test_given_origin_and_min_points():
    xyz = rough_surface(2000, seed=5, size=2.0)
    origin = xyz.min(axis=0) - np.array([0.13, 0.07, 0.2])
    res = grid_roughness(PointCloud.from_xyz(xyz), 0.4, origin=origin, min_points=30, axis="z")
    ref = brute_force(xyz, 0.4, origin=origin, axis="z", min_points=30)
    keys = result_by_key(res)
    assert set(keys) == set(ref)
    for key, (n, t_odr, t_ols, *_rest) in ref.items():
        i = keys[key]
        assert res.n_points[i] == n
        if n < 30:
            assert np.isnan(res.theta_odr[i])
        else:
            np.testing.assert_allclose(res.theta_odr[i], t_odr, rtol=1e-9, atol=ATOL)
            np.testing.assert_allclose(res.theta_ols[i], t_ols, rtol=1e-9, atol=ATOL)


def test_odr_invariant_under_rotation_and_translation_ols_not():
    xyz = rough_surface(20_000, seed=2, size=1.0)
    big = 100.0  # one cell holds the whole cloud in any orientation
    base = grid_roughness(PointCloud.from_xyz(xyz), big, axis="z")
    assert base.n_cells == 1
    for seed in range(4):
        moved = xyz @ random_rotation(seed).T + np.array([3.0e5, -2.0e6, 45.0]) * (seed + 1)
        res = grid_roughness(PointCloud.from_xyz(moved), big, axis="z")
        assert res.n_cells == 1
        np.testing.assert_allclose(res.theta_odr[0], base.theta_odr[0], rtol=1e-9, atol=ATOL)
        assert abs(res.theta_ols[0] - base.theta_ols[0]) > 1e-3 * base.theta_ols[0]


@pytest.mark.parametrize("seed", range(3))
def test_flat_noisy_plane_gives_std_of_absolute_noise(seed):
    rng = np.random.default_rng(seed)
    n, sigma = 200_000, 0.004
    uv = rng.uniform(-1, 1, (n, 2))
    noise = rng.normal(0, sigma, n)
    R = random_rotation(100 + seed)
    xyz = np.column_stack([uv, noise]) @ R.T + rng.uniform(-1e3, 1e3, 3)
    res = grid_roughness(PointCloud.from_xyz(xyz), 1e3)
    assert res.n_cells == 1
    # against the sample statistic of the true noise, and the closed form sqrt(1 - 2/pi) sigma
    np.testing.assert_allclose(res.theta_odr[0], np.abs(noise).std(), rtol=2e-3)
    np.testing.assert_allclose(res.theta_odr[0], np.sqrt(1 - 2 / np.pi) * sigma, rtol=1e-2)
    np.testing.assert_allclose(abs(res.normal[0] @ R[:, 2]), 1.0, atol=1e-5)


def hemisphere_board(spacing=0.0005, seed=0):
    """The 2012 paper's board sampled on a regular raster: 132 hemispheres r = 0.019 m
    on randomly chosen nodes of a 0.05 m grid (nodes kept a radius from the edges)."""
    r = 0.019
    rng = np.random.default_rng(seed)
    nodes_1d = np.arange(1, 20) * 0.05  # interior nodes: hemispheres lie fully on the board
    ii, jj = np.meshgrid(nodes_1d, nodes_1d, indexing="ij")
    all_nodes = np.column_stack([ii.ravel(), jj.ravel()])
    nodes = all_nodes[rng.choice(len(all_nodes), 132, replace=False)]
    t = (np.arange(int(round(1 / spacing))) + 0.5) * spacing
    x, y = np.meshgrid(t, t, indexing="ij")
    x, y = x.ravel(), y.ravel()
    # nearest node on the 0.05 grid decides the hemisphere (spacing 0.05 > 2r: no overlap)
    node_idx = np.rint(x / 0.05).astype(int), np.rint(y / 0.05).astype(int)
    occupied = np.zeros((21, 21), bool)
    occupied[np.rint(nodes[:, 0] / 0.05).astype(int), np.rint(nodes[:, 1] / 0.05).astype(int)] = True
    d2 = (x - node_idx[0] * 0.05) ** 2 + (y - node_idx[1] * 0.05) ** 2
    inside = occupied[node_idx] & (d2 < r * r)
    z = np.where(inside, np.sqrt(np.clip(r * r - d2, 0, None)), 0.0)
    return np.column_stack([x, y, z])


def test_2012_board_reproduces_theoretical_roughness():
    xyz = hemisphere_board()
    res = grid_roughness(PointCloud.from_xyz(xyz), 2.0, axis="z")
    assert res.n_cells == 1
    # published theoretical roughness 3.60756e-3 m (2012 paper, Monte Carlo, 355 M points)
    np.testing.assert_allclose(res.theta_odr[0], 3.60756e-3, rtol=5e-4)
    np.testing.assert_allclose(res.theta_ols[0], 3.60756e-3, rtol=5e-4)
    signed = grid_roughness(PointCloud.from_xyz(xyz), 2.0, axis="z", residual="signed")
    np.testing.assert_allclose(signed.theta_odr[0], 4.84e-3, rtol=3e-3)


def test_axis_auto_picks_axis_closest_to_face_normal():
    xyz = rough_surface(5000, seed=4)
    # a vertical face parallel to xz: normal along y
    face = xyz[:, [0, 2, 1]]
    res = grid_roughness(PointCloud.from_xyz(face), 1.0)
    assert res.axis == "y" and res.axis_requested == "auto"
    assert whole_cloud_axis(PointCloud.from_xyz(face)) == "y"
    assert abs(res.whole_normal[1]) > 0.99


def test_degenerate_cells_get_no_value():
    # cell 0: 5 collinear points; cell 1: 4 coincident points; cell 2: a proper plane
    line = np.column_stack([np.linspace(0.1, 0.9, 5), np.full(5, 0.5), np.full(5, 0.5)])
    same = np.tile([[1.5, 0.5, 0.5]], (4, 1))
    rng = np.random.default_rng(0)
    plane = np.column_stack([rng.uniform(2, 3, 50), rng.uniform(0, 1, 50), rng.uniform(0, 1, 50) * 0.1])
    res = grid_roughness(PointCloud.from_xyz(np.vstack([line, same, plane])), 1.0, origin=[0, 0, 0], axis="z")
    by = result_by_key(res)
    assert np.isnan(res.theta_odr[by[(0, 0, 0)]]) and np.isnan(res.theta_ols[by[(0, 0, 0)]])
    assert np.isnan(res.theta_odr[by[(1, 0, 0)]])
    assert np.isfinite(res.theta_odr[by[(2, 0, 0)]])
    rep = res.cell_report("odr")
    assert rep == {"occupied": 3, "below_min_points": 0, "degenerate": 2, "with_value": 1,
                   "exact_fit": 0}


def test_repeated_points_fit_exactly_and_are_counted():
    """Airborne scans repeat points: a cell of 6 points holding 3 distinct ones fits
    its plane exactly (roughness 0 to round-off, per SCIENCE.md a value); the report
    counts such cells so Table 1's minimum of 0 is explained. UTM offsets keep the
    round-off realistic."""
    rng = np.random.default_rng(2)
    tri = np.array([[0.1, 0.2, 0.3], [0.8, 0.1, 0.35], [0.4, 0.9, 0.32]])
    doubled = np.vstack([tri, tri])                      # cell (0, 0, 0): 6 points, 3 distinct
    rough = np.column_stack([rng.uniform(1, 2, 40), rng.uniform(0, 1, 40),
                             0.3 + 0.01 * rng.standard_normal(40)])  # cell (1, 0, 0)
    xyz = np.vstack([doubled, rough]) + [5e5, 4.2e6, 100.0]
    res = grid_roughness(PointCloud.from_xyz(xyz), 1.0, origin=[5e5, 4.2e6, 100.0])
    by = result_by_key(res)
    exact = res.theta_odr[by[(0, 0, 0)]]
    assert 0 <= exact < 1e-9 and res.theta_odr[by[(1, 0, 0)]] > 1e-3
    rep = res.cell_report("odr")
    assert (rep["with_value"], rep["exact_fit"]) == (2, 1)
    assert res.cell_report("e_ols")["exact_fit"] == 0


@pytest.mark.parametrize("factor", [2, 4, 8])
def test_coarsened_grid_equals_direct_computation(factor):
    from rough_viewer.grid.roughness import coarsen_prepared, prepare_grid

    xyz = rough_surface(30_000, seed=21, size=3.0) @ random_rotation(3).T + [4.5e5, 5.1e6, 300.0]
    cloud = PointCloud.from_xyz(xyz)
    fine = prepare_grid(cloud, 0.125)
    coarse = coarsen_prepared(fine, factor)
    g = 0.125 * factor
    direct = grid_roughness(cloud, g)
    res = grid_roughness(cloud, g, prepared=coarse)
    assert res.grid.cell_size == g
    np.testing.assert_array_equal(res.ijk, direct.ijk)
    np.testing.assert_array_equal(res.n_points, direct.n_points)
    np.testing.assert_array_equal(res.point_cell, direct.point_cell)
    for name in ("odr", "ols", "hybrid", "e_ols"):
        np.testing.assert_allclose(res.values(name), direct.values(name), rtol=1e-9, atol=ATOL)
    np.testing.assert_allclose(res.centroid, direct.centroid, rtol=0, atol=1e-9)


def test_dem_lattice_cell_with_one_x_column_has_no_ols_or_hybrid_value():
    # A DEM lattice at UTM coordinates, 0.3 m in x and 0.05 m in y, cells of 0.25 m:
    # every cell holds one column of the lattice (x constant up to 1e-10 m of
    # round-off), so the OLS regression on (x, y) has no unique solution and the ODR
    # plane (x = const) contains the z axis.
    rng = np.random.default_rng(4)
    xs = 512_345.0 + 0.3 * np.arange(12) + 0.01
    ys = 4_765_432.0 + 0.05 * np.arange(60) + 0.001
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    x = gx.ravel() + rng.normal(0.0, 1e-10, gx.size)
    z = 100.0 + 0.002 * rng.standard_normal(gx.size)
    xyz = np.column_stack([x, gy.ravel(), z])
    res = grid_roughness(PointCloud.from_xyz(xyz), 0.25, axis="z")
    cols = np.array([len(np.unique(np.round(xyz[res.point_cell == i, 0], 6))) for i in range(res.n_cells)])
    assert np.all(cols == 1) and np.all(res.n_points >= 4)
    assert np.all(np.isnan(res.theta_ols)) and np.all(np.isnan(res.theta_hybrid))
    assert res.cell_report("ols")["degenerate"] == res.n_cells
    # the same lattice with two x columns per cell (0.1 m apart) gives OLS values
    xs2 = 512_345.0 + 0.1 * np.arange(30) + 0.01
    gx2, gy2 = np.meshgrid(xs2, ys, indexing="ij")
    xyz2 = np.column_stack([gx2.ravel(), gy2.ravel(), 100.0 + 0.002 * rng.standard_normal(gx2.size)])
    res2 = grid_roughness(PointCloud.from_xyz(xyz2), 0.25, axis="z")
    assert np.count_nonzero(np.isfinite(res2.theta_ols)) > 0.5 * res2.n_cells


def test_three_point_cells_have_no_value_by_default_and_min_points_3_is_accepted():
    # cells of 1 m on a 2 x 2 x 1 lattice of 3-point triangles and 5-point patches
    rng = np.random.default_rng(2)
    tri = np.array([[0.1, 0.1, 0.1], [0.8, 0.2, 0.3], [0.3, 0.9, 0.5]])
    five = rng.uniform(0.05, 0.95, (5, 3))
    xyz = np.vstack([tri, five + [1.0, 0.0, 0.0], tri + [0.0, 1.0, 0.0], five + [1.0, 1.0, 0.0]])
    res = grid_roughness(xyz, 1.0, origin=np.zeros(3))
    three = res.n_points == 3
    assert three.sum() == 2
    for name in ("odr", "ols", "hybrid", "e_ols"):
        assert np.all(np.isnan(res.values(name)[three]))
        assert np.all(np.isfinite(res.values(name)[~three]))
    assert res.cell_report("odr")["below_min_points"] == 2
    bare = grid_roughness(xyz, 1.0, origin=np.zeros(3), min_points=3)
    assert np.all(bare.theta_odr[bare.n_points == 3] < 1e-12)  # 0 by construction
