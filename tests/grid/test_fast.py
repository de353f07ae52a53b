"""The compiled kernels (grid/fast.py) against the NumPy reference (grid/cells.py)."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid import fast
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.vocabulary import InputError
from tests.helpers import UTM, random_rotation, rough_surface

pytestmark = pytest.mark.skipif(not fast.available(), reason="numba is not installed")

FIELDS = ("theta_odr", "theta_ols", "theta_hybrid", "e_ols", "normal", "centroid")


def assert_same(fast_res, ref, rtol=1e-12):
    """Same cells, same counts; every value within ``rtol`` relative (NaN where NaN)."""
    np.testing.assert_array_equal(fast_res.ijk, ref.ijk)
    np.testing.assert_array_equal(fast_res.n_points, ref.n_points)
    np.testing.assert_array_equal(fast_res.point_cell, ref.point_cell)
    assert fast_res.axis == ref.axis
    for name in FIELDS:
        a, b = getattr(fast_res, name), getattr(ref, name)
        np.testing.assert_array_equal(np.isnan(a), np.isnan(b), err_msg=name)
        ok = ~np.isnan(b)
        np.testing.assert_allclose(a[ok], b[ok], rtol=rtol, atol=0, err_msg=name)


def both(cloud, g, **kw):
    return (grid_roughness(cloud, g, engine="numba", **kw),
            grid_roughness(cloud, g, engine="numpy", **kw))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_clouds(seed):
    rng = np.random.default_rng(seed)
    xyz = rng.uniform(-3, 5, (20_000, 3)) * [1.0, 1.0, 0.2]
    for g in (0.5, 1.7):
        f, r = both(xyz, g)
        assert r.n_cells > 20
        assert_same(f, r)


@pytest.mark.parametrize("seed", [3, 4])
def test_utm_offset_rotated_surfaces(seed):
    xyz = rough_surface(30_000, seed=seed) @ random_rotation(seed).T + UTM
    for g in (0.25, 1.0):
        for residual in ("absolute", "signed"):
            f, r = both(xyz, g, residual=residual, axis="auto")
            assert np.isfinite(r.theta_odr).sum() > 20
            assert_same(f, r)


def test_degenerate_cells():
    """Coincident, collinear, exactly planar and 3-point cells: the same NaNs and zeros."""
    rng = np.random.default_rng(7)
    blocks = [
        np.repeat([[0.5, 0.5, 0.5]], 10, axis=0),                          # coincident
        np.column_stack([np.linspace(1.1, 1.9, 12), np.full(12, 0.5), np.full(12, 0.5)]),
        np.column_stack([rng.uniform(2, 3, 30), rng.uniform(0, 1, 30), np.full(30, 0.25)]),
        rng.uniform([3, 0, 0], [4, 1, 1], (3, 3)),                          # three points
        np.column_stack([np.full(20, 4.5), rng.uniform(0, 1, 20), rng.uniform(0, 1, 20)]),
        rng.uniform([5, 0, 0], [6, 1, 1], (200, 3)),                        # a normal cell
    ]
    xyz = np.vstack(blocks) + UTM
    for axis in ("auto", "x", "z"):
        f, r = both(xyz, 1.0, axis=axis, origin=UTM)
        assert_same(f, r)
        assert r.n_cells == 6
        assert np.isnan(r.theta_odr[:2]).all()      # coincident and collinear: no plane
        assert r.theta_odr[2] == 0.0 and r.theta_odr[4] == 0.0   # exactly planar
        if axis == "z":   # a horizontal plane has an OLS fit along z, a vertical one none
            assert r.theta_ols[2] == 0.0 and np.isnan(r.theta_ols[4])
        if axis == "x":
            assert np.isnan(r.theta_ols[2]) and r.theta_ols[4] == 0.0
        assert np.isnan(r.theta_odr[3]) and r.theta_odr[5] > 0.1   # 3 points: below min 4
        f3, r3 = both(xyz, 1.0, axis=axis, origin=UTM, min_points=3)
        assert_same(f3, r3)
        assert r3.theta_odr[3] < 1e-15   # 3 points fix a plane: 0 by construction


def test_engine_names():
    assert fast.resolve_engine("numba") == "numba"
    assert fast.resolve_engine("numpy") == "numpy"
    with pytest.raises(InputError, match="unknown engine"):
        fast.resolve_engine("cuda")  # type: ignore[arg-type]


def test_env_overrides_auto(monkeypatch):
    monkeypatch.setenv(fast.ENGINE_ENV, "numpy")
    assert fast.resolve_engine("auto") == "numpy"
    monkeypatch.setenv(fast.ENGINE_ENV, "numba")
    assert fast.resolve_engine("auto") == "numba"
