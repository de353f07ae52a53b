"""The compiled kernels (grid/fast.py) against the NumPy reference (grid/cells.py)."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

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


def test_several_blocks_and_thread_counts_give_the_same_bits():
    """More points than one reference chunk (2**21): the block partial sums are added in
    block order, on one thread or two, to the reference's last bit."""
    from rough_viewer.grid.cells import _chunk_size

    rng = np.random.default_rng(11)
    n = _chunk_size(0) * 2 + 12_345
    xyz = rough_surface(n, seed=5, size=3.0) @ random_rotation(6).T + UTM
    order = np.lexsort((xyz[:, 2], np.floor(xyz[:, 0] / 0.05)))  # scan columns: long runs
    for cloud in (xyz[order], xyz[rng.permutation(n)]):  # and no runs at all
        ref = grid_roughness(cloud, 0.5, engine="numpy")
        one = _on_threads(1, lambda c=cloud: grid_roughness(c, 0.5, engine="numba"))
        two = grid_roughness(cloud, 0.5, engine="numba")
        for res in (one, two):
            assert_same(res, ref, rtol=0.0)


def _on_threads(n, run):
    with fast.threads(n):
        return run()


def test_sparse_bookkeeping_and_bounds():
    """A grid too large for dense bookkeeping takes the sort path; the same cells and
    sums as the reference. Bounds in one pass; NaN where a coordinate is NaN."""
    from rough_viewer.grid import cells

    rng = np.random.default_rng(2)
    xyz = rng.uniform(0, 1, (5_000, 3)) * [1000.0, 1000.0, 50.0] + UTM
    x, y, z = (np.ascontiguousarray(xyz[:, a]) for a in range(3))
    lo, hi = fast.bounds(x, y, z)
    np.testing.assert_array_equal(lo, xyz.min(axis=0))
    np.testing.assert_array_equal(hi, xyz.max(axis=0))
    grid = cells.make_grid(lo, hi, 0.5)
    assert not cells.dense_bookkeeping(grid.n_cells, 5_000, 0)
    index, mom = cells.index_and_moments(x, y, z, grid, dense_limit=0)
    ref_index = cells.index_points(x, y, z, grid, engine="numpy", dense_limit=0)
    ref_mom = cells.cell_moments(x, y, z, ref_index, engine="numpy")
    np.testing.assert_array_equal(index.ijk, ref_index.ijk)
    np.testing.assert_array_equal(index.point_cell, ref_index.point_cell)
    np.testing.assert_array_equal(mom.s1, ref_mom.s1)
    np.testing.assert_array_equal(mom.s2, ref_mom.s2)
    y[17] = np.nan
    assert np.isnan(fast.bounds(x, y, z)[0]).all()


def test_direct_semivariogram_count_matches_numpy_bit_for_bit(monkeypatch):
    from rough_viewer.grid.variogram import semivariogram

    rng = np.random.default_rng(4)
    ijk = np.unique(rng.integers(0, 40, (3_000, 3)), axis=0)
    values = rng.lognormal(size=len(ijk))
    values[::7] = np.nan
    for dims, bin_width in ((3, None), (2, 1.7)):
        cells = np.unique(ijk[:, :dims], axis=0)
        vals = values[: len(cells)]
        got = {}
        for engine in ("numba", "numpy"):
            monkeypatch.setenv(fast.ENGINE_ENV, engine)
            got[engine] = semivariogram(cells, vals, 0.25, bin_width=bin_width, method="pairs")
        np.testing.assert_array_equal(got["numba"].pairs, got["numpy"].pairs)
        np.testing.assert_array_equal(got["numba"].gamma, got["numpy"].gamma)
        assert got["numpy"].pairs.sum() > 10_000


def test_kernels_load_without_scipy_and_scipy_still_imports():
    """numba's CPU target imports scipy.linalg (0.2 s) when it sets up; the kernels
    never need it, so it is not imported while they load, and imports as usual after."""
    code = ("import sys; from rough_viewer.grid import fast; fast._kernels(); "
            "print('scipy' in sys.modules); import scipy.linalg; print(scipy.linalg.det([[2.0]]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    assert out == ["False", "2.0"]


def test_preload_loads_the_kernels_on_a_thread(monkeypatch):
    code = ("from rough_viewer.grid import fast; fast.preload(); t = fast._preloading[0]; "
            "t.join(60); print(t.name, fast.loaded())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    assert out == ["rough_viewer-kernels", "True"]
    code = "from rough_viewer.grid import fast; fast.preload(); print(fast._preloading)"
    env = dict(os.environ, **{fast.ENGINE_ENV: "numpy"})
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True, env=env).stdout.split()
    assert out == ["[]"]  # nothing loaded for the NumPy engine


def test_kernel_cache_goes_to_the_user_folder_when_the_package_is_read_only(tmp_path):
    """A copy of the package whose folder cannot be written (a system-wide install):
    numba's cache goes to $ROUGH_VIEWER_CACHE/numba, and a compiled function of a
    read-only module is cached there (a probe: our kernels take long to compile)."""
    site = tmp_path / "site"
    shutil.copytree(Path(fast.__file__).parents[1], site / "rough_viewer",
                    ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc"))
    (site / "probe.py").write_text("from numba import njit\n\n\n@njit(cache=True)\n"
                                   "def double(x):\n    return 2.0 * x\n")
    cache = tmp_path / "user-cache"
    code = ("import sys; sys.meta_path[:] = [f for f in sys.meta_path "  # not an editable
            "if 'editable' not in getattr(f, '__module__', '')]; "                 # install's finder
            "from rough_viewer.grid import fast; where = fast.configure_cache(); "
            "import probe; print(probe.double(2.0), where, fast.__file__)")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(PYTHONPATH=str(site), ROUGH_VIEWER_CACHE=str(cache))
    argv = [sys.executable, "-c", code]
    if os.geteuid() == 0:  # root writes anywhere: make the copy a read-only mount
        if shutil.which("unshare") is None:
            pytest.skip("running as root without unshare: no read-only folder to test with")
        script = (f"mount --bind {site} {site} && mount -o remount,bind,ro {site} && "
                  f"exec {shlex.join(argv)}")
        argv = ["unshare", "-rm", "sh", "-c", script]
        if subprocess.run(["unshare", "-rm", "true"], capture_output=True).returncode != 0:
            pytest.skip("unshare is not permitted here")
    else:
        for p in sorted(site.rglob("*"), reverse=True):
            p.chmod(p.stat().st_mode & ~0o222)
        site.chmod(0o555)
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=120, env=env,
                              cwd=tmp_path)
    finally:
        for p in [site, *site.rglob("*")]:
            p.chmod(p.stat().st_mode | 0o200)
    assert done.returncode == 0, done.stderr[-2000:]
    value, where, module = done.stdout.split()
    assert Path(module).is_relative_to(site)  # the read-only copy was imported
    assert float(value) == 4.0 and Path(where) == cache / "numba"
    assert list((cache / "numba").rglob("probe.double-*.nbi"))
    assert not list(site.rglob("*.nbi"))
