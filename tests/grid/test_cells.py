"""The one grid: cell indices, occupied cells and moment sums against brute force."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.cells import cell_moments, coarsen, index_points, make_grid
from rough_viewer.vocabulary import InputError
from tests.helpers import random_rotation, rough_surface

UTM = np.array([512_000.0, 4_170_000.0, 100.0])


def _cloud(n=20_000, seed=0):
    return rough_surface(n, seed=seed, size=3.0) @ random_rotation(seed).T + UTM


@pytest.mark.parametrize("g", [0.1, 0.37, 1.0])
def test_cell_index_is_floor_of_offset_over_size(g):
    xyz = _cloud()
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    grid = make_grid(lo, hi, g, n_points=len(xyz))
    index = index_points(*xyz.T.copy(), grid)
    expected = np.floor((xyz - lo) / g).astype(np.int64)
    np.testing.assert_array_equal(index.ijk[index.point_cell], expected)
    keys, counts = np.unique(expected, axis=0, return_counts=True)
    assert index.n_cells == len(keys)
    order = np.lexsort(index.ijk.T)  # occupied cells sorted by key, x fastest
    np.testing.assert_array_equal(order, np.arange(index.n_cells))
    got = {tuple(k): c for k, c in zip(index.ijk, index.counts, strict=True)}
    assert got == {tuple(k): c for k, c in zip(keys, counts, strict=True)}
    np.testing.assert_allclose(grid.centres(index.ijk[:1])[0], lo + (index.ijk[0] + 0.5) * g)


def test_sparse_sort_path_equals_dense_path(monkeypatch):
    import rough_viewer.grid.cells as cells

    xyz = _cloud(5_000, seed=3)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    grid = make_grid(lo, hi, 0.05)
    dense = index_points(*xyz.T.copy(), grid)
    monkeypatch.setattr(cells, "DENSE_LIMIT", 0)  # force the sort path (grid > 4 N cells)
    assert grid.n_cells > 4 * len(xyz)
    sparse = index_points(*xyz.T.copy(), grid)
    np.testing.assert_array_equal(dense.ijk, sparse.ijk)
    np.testing.assert_array_equal(dense.point_cell, sparse.point_cell)


def test_moments_equal_direct_sums_in_cell_local_coordinates():
    xyz = _cloud(8_000, seed=5)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    g = 0.5
    grid = make_grid(lo, hi, g)
    index = index_points(*xyz.T.copy(), grid)
    mom = cell_moments(*xyz.T.copy(), index)
    for c in range(0, index.n_cells, max(1, index.n_cells // 25)):
        pts = xyz[index.point_cell == c] - grid.centres(index.ijk[c:c + 1])[0]
        np.testing.assert_allclose(mom.s1[c], pts.sum(axis=0), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(mom.s2[c], pts.T @ pts, rtol=1e-12, atol=1e-12)
        if len(pts) > 1:
            np.testing.assert_allclose(mom.covariance()[c], np.cov(pts.T, bias=True),
                                       rtol=1e-9, atol=1e-15)


def test_coarsen_equals_indexing_the_coarse_grid():
    xyz = _cloud(10_000, seed=8)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    fine = make_grid(lo, hi, 0.2)
    index = index_points(*xyz.T.copy(), fine)
    c_index, c_mom = coarsen(index, cell_moments(*xyz.T.copy(), index), 3)
    direct_grid = make_grid(lo, hi, 0.6)
    direct = index_points(*xyz.T.copy(), direct_grid)
    np.testing.assert_array_equal(c_index.ijk, direct.ijk)
    np.testing.assert_array_equal(c_index.point_cell, direct.point_cell)
    # UTM northings carry ~5e-10 m of rounding per point (their ULP), so the two ways
    # of reaching a coarse cell's local coordinates agree to ~1e-8 relative, not more.
    np.testing.assert_allclose(c_mom.s2, cell_moments(*xyz.T.copy(), direct).s2,
                               rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize("g", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_cell_sizes_are_refused(g):
    with pytest.raises(InputError, match="grid size"):
        make_grid(np.zeros(3), np.ones(3), g)


def test_grid_too_fine_for_the_extent_is_refused():
    with pytest.raises(InputError, match="choose a larger grid size"):
        make_grid(np.zeros(3), np.full(3, 1e6), 1e-9)


@pytest.mark.parametrize("g", [1e300, 1e6])
def test_grid_far_larger_than_the_cloud_is_refused(g):
    """A 270 m scan: 1e300 m overflowed the moments (a traceback), 1e6 m left the
    whole-cloud cell without an ODR plane; 1000 x the extent is the limit."""
    lo, hi = np.array([5e5, 4e6, 0.0]), np.array([5e5 + 270.0, 4e6 + 280.0, 129.0])
    with pytest.raises(InputError, match=r"more than 1000 times the cloud's extent \(280 m\)"):
        make_grid(lo, hi, g)
    assert make_grid(lo, hi, 280_000.0).shape == (1, 1, 1)  # at the limit: one cell


def test_one_huge_cell_equals_the_whole_cloud_fit():
    """At the limit (1000 x the extent, UTM offsets) the one cell still gives the
    whole cloud's ODR roughness (an SVD of the centred points) to 1e-6."""
    from rough_viewer.grid.roughness import grid_roughness

    rng = np.random.default_rng(5)
    n = 5000
    xyz = np.column_stack([rng.uniform(0, 2, n), rng.uniform(0, 2, n),
                           0.3 * rng.uniform(0, 2, n) + 0.002 * rng.standard_normal(n)])
    xyz += [5e5, 4e6, 100.0]
    res = grid_roughness(xyz, 1000 * float(np.ptp(xyz, axis=0).max()), models=("odr",))
    centred = xyz - xyz.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    d = centred @ normal
    want = np.std(np.abs(d))
    assert res.n_cells == 1
    assert res.values("odr")[0] == pytest.approx(want, rel=1e-6)


def test_an_origin_too_far_to_place_points_in_their_cells_is_refused():
    """Issue 36: ``--origin`` at -1e15 m changed the cells silently (541 instead of 525,
    median ODR +6 %): offsets from it resolve 0.125 m. It is refused; an origin whose
    offsets resolve the cells gives the cells a brute-force floor gives."""
    lo, hi = np.array([500_000.0, 4_000_000.0, 100.0]), np.array([500_050.0, 4_000_020.0, 110.0])
    with pytest.raises(InputError, match=r"grid origin is 1e\+15 m from the cloud: offsets "
                                          r"there resolve only 0.125 m"):
        make_grid(lo, hi, 0.25, origin=np.array([-1e15, 0.0, 0.0]))
    grid = make_grid(lo, hi, 0.25, origin=np.zeros(3))  # UTM offsets resolve 1e-9 m
    pts = np.random.default_rng(0).uniform(lo, hi, (1000, 3))
    ijk = np.floor(pts / 0.25)
    assert np.all(ijk.min(axis=0) >= grid.index_min)
    assert np.all(ijk.max(axis=0) < grid.index_min + np.array(grid.shape))
