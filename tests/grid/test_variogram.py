"""Tests of rough_viewer.grid.variogram against a brute-force loop over all pairs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rough_viewer.grid.maps import face_frame
from rough_viewer.grid.variogram import (
    MEMORY_BUDGET,
    face_semivariogram,
    plan_semivariogram,
    semivariogram,
)
from rough_viewer.vocabulary import InputError


def brute_force(ijk, values, g, *, w=None, max_lag=None):
    """Obviously-correct reference: every unordered pair, one at a time."""
    ijk = np.asarray(ijk)
    values = np.asarray(values, dtype=float)
    ok = np.isfinite(values)
    ijk, values = ijk[ok], values[ok]
    w = g if w is None else w
    if max_lag is None:
        max_lag = 0.5 * g * max(ijk.max(axis=0) - ijk.min(axis=0) + 1)
    n_bins = int(np.floor(max_lag / w + 1e-9))
    pairs = np.zeros(n_bins, dtype=np.int64)
    total = np.zeros(n_bins)
    pos = ijk * g
    for i in range(len(values)):
        for j in range(i + 1, len(values)):
            d = float(np.sqrt(np.sum((pos[i] - pos[j]) ** 2)))
            k = int(np.floor(d / w + 0.5))
            if 1 <= k <= n_bins:
                pairs[k - 1] += 1
                total[k - 1] += (values[i] - values[j]) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        gamma = np.where(pairs > 0, total / (2 * pairs), np.nan)
    return pairs, gamma


def random_masked(rng, shape, fill, offset=0.0):
    occupied = np.argwhere(rng.random(shape) < fill)
    values = offset + rng.normal(size=len(occupied))
    return occupied + rng.integers(-50, 50, size=len(shape)), values


@pytest.mark.parametrize("shape", [(13, 9), (21, 4), (7, 6, 5), (11, 3, 8)])
@pytest.mark.parametrize("seed", [0, 1])
def test_equals_brute_force(shape, seed):
    rng = np.random.default_rng(seed)
    ijk, values = random_masked(rng, shape, 0.45, offset=1000.0)  # big mean: tests centring
    g = 0.125
    vg = semivariogram(ijk, values, g)
    pairs, gamma = brute_force(ijk, values, g)
    assert vg.pairs.dtype == np.int64
    np.testing.assert_array_equal(vg.pairs, pairs)
    np.testing.assert_allclose(vg.gamma, gamma, rtol=1e-9, atol=0)
    np.testing.assert_allclose(vg.lag, g * np.arange(1, len(pairs) + 1))
    np.testing.assert_allclose(vg.gamma_normalised, gamma / np.var(values), rtol=1e-9)
    assert vg.n_cells == len(values)


def test_brute_force_with_nan_custom_bins_and_max_lag():
    rng = np.random.default_rng(5)
    ijk, values = random_masked(rng, (9, 8, 4), 0.5)
    values[rng.random(len(values)) < 0.2] = np.nan
    g = 0.5
    for w, max_lag in [(0.75, 3.0), (0.3, 2.0), (1.0, 100.0)]:
        vg = semivariogram(ijk, values, g, bin_width=w, max_lag=max_lag)
        pairs, gamma = brute_force(ijk, values, g, w=w, max_lag=max_lag)
        np.testing.assert_array_equal(vg.pairs, pairs)
        np.testing.assert_allclose(vg.gamma, gamma, rtol=1e-9)
        assert vg.n_cells == int(np.isfinite(values).sum())


def test_pair_counts_of_a_full_grid_closed_form():
    n = 30
    ijk = np.argwhere(np.ones((n, n), bool))
    vg = semivariogram(ijk, np.arange(n * n, dtype=float), 1.0)
    # bin 1 = [0.5, 1.5): lags (1,0), (0,1) and the diagonals (sqrt 2)
    assert vg.pairs[0] == 2 * n * (n - 1) + 2 * (n - 1) ** 2
    # every pair of the grid closer than 15.5 cells, against a direct lag-vector count
    hx, hy = np.meshgrid(np.arange(-(n - 1), n), np.arange(-(n - 1), n), indexing="ij")
    per_lag = (n - np.abs(hx)) * (n - np.abs(hy))
    k = np.floor(np.hypot(hx, hy) + 0.5).astype(int)
    expected = [per_lag[k == b].sum() // 2 for b in range(1, 16)]
    np.testing.assert_array_equal(vg.pairs, expected)


def test_white_noise_is_flat_near_one():
    rng = np.random.default_rng(42)
    ijk = np.argwhere(np.ones((80, 80), bool))
    vg = semivariogram(ijk, rng.normal(size=len(ijk)), 0.25)
    assert len(vg.lag) == 40
    assert np.all(vg.pairs > 3000)
    assert np.all(np.abs(vg.gamma_normalised - 1.0) < 0.05)


def test_linear_trend_grows_as_lag_squared():
    # 1-D transect: (Z_i - Z_j)^2 = a^2 d^2 exactly, so gamma = a^2 h^2 / 2
    a, g = 0.3, 0.5
    n = 64
    ijk = np.column_stack([np.arange(n), np.zeros(n, int)])
    vg = semivariogram(ijk, a * g * ijk[:, 0], g)
    np.testing.assert_allclose(vg.gamma, 0.5 * a * a * vg.lag**2, rtol=1e-9)
    np.testing.assert_array_equal(vg.pairs, n - np.arange(1, len(vg.lag) + 1))
    # 2-D plane with a trend along x: log-log slope 2
    ijk = np.argwhere(np.ones((60, 60), bool))
    vg = semivariogram(ijk, a * g * ijk[:, 0], g)
    slope = np.polyfit(np.log(vg.lag[3:]), np.log(vg.gamma[3:]), 1)[0]
    assert abs(slope - 2.0) < 0.05


def test_too_few_cells_and_constant_map():
    vg = semivariogram(np.array([[0, 0, 0]]), np.array([1.0]), 1.0)
    assert vg.lag.size == 0 and vg.pairs.size == 0 and vg.n_cells == 1
    vg = semivariogram(np.array([[0, 0], [0, 1], [0, 2]]), np.full(3, 2.0), 1.0)
    np.testing.assert_array_equal(vg.pairs, [2])
    assert vg.gamma[0] == 0.0 and np.isnan(vg.gamma_normalised[0])


def test_bad_arguments():
    with pytest.raises(ValueError):
        semivariogram(np.zeros((3, 4), int), np.zeros(3), 1.0)
    with pytest.raises(ValueError):
        semivariogram(np.zeros((3, 3), int), np.zeros(2), 1.0)
    with pytest.raises(ValueError):
        semivariogram(np.zeros((3, 3)), np.zeros(3), 1.0)
    with pytest.raises(ValueError):
        semivariogram(np.zeros((3, 3), int), np.zeros(3), 0.0)


def test_face_semivariogram_is_the_2d_variogram_of_the_face_pixels():
    rng = np.random.default_rng(3)
    normal = np.array([0.3, 0.9, 0.2])
    normal /= np.linalg.norm(normal)
    plane = SimpleNamespace(centroid=np.array([500.0, 200.0, 30.0]), normal=normal)
    frame = face_frame(plane)
    g = 0.25
    ab = np.argwhere(rng.random((15, 10)) < 0.6)
    values = rng.normal(size=len(ab))
    # cells at pixel centres, pushed off the plane along the normal (ignored)
    centres = (plane.centroid + ((ab[:, :1] + 0.5) * g) * frame.u_axis
               + ((ab[:, 1:] + 0.5) * g) * frame.v_axis
               + rng.normal(scale=0.4, size=(len(ab), 1)) * normal)
    vg = face_semivariogram(centres, values, g, plane)
    ref = semivariogram(ab, values, g)
    assert vg.space == "plane"
    np.testing.assert_array_equal(vg.pairs, ref.pairs)
    np.testing.assert_allclose(vg.gamma, ref.gamma, rtol=1e-9)
    # a second cell behind the first one in the same pixel: the pixel takes the mean
    doubled = np.vstack([centres, centres[:1] + 0.3 * normal])
    vg2 = face_semivariogram(doubled, np.append(values, values[0] + 2.0), g, plane)
    moved = values.copy()
    moved[0] += 1.0
    ref2 = semivariogram(ab, moved, g)
    np.testing.assert_array_equal(vg2.pairs, ref2.pairs)
    np.testing.assert_allclose(vg2.gamma, ref2.gamma, rtol=1e-9)


def _two_patches(gap: int, side: int = 12, seed: int = 3):
    """Two square patches of cells (a 2.5-D surface each) ``gap`` cells apart in x."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    patch = np.column_stack([i.ravel(), j.ravel(), (i.ravel() // 4)])
    ijk = np.vstack([patch, patch + np.array([gap, 3, 1])])
    return ijk, rng.normal(size=len(ijk))


def test_tiled_blocks_equal_brute_force_on_a_sparse_map():
    g = 0.5
    # far apart with short lags: tiles; closer with long lags: one box
    for gap, max_lag, blocks in ((512, 3.0, 2), (64, 40.0, 1)):
        ijk, values = _two_patches(gap=gap)
        plan = plan_semivariogram(ijk, values, g, max_lag=max_lag, method="fft")
        assert plan.n_blocks == blocks and not plan.lag_limited
        pairs, gamma = brute_force(ijk, values, g, max_lag=max_lag)
        for method in ("fft", "pairs", "auto"):
            vg = semivariogram(ijk, values, g, max_lag=max_lag, method=method)
            np.testing.assert_array_equal(vg.pairs, pairs)
            np.testing.assert_allclose(vg.gamma, gamma, rtol=1e-9)
    assert vg.pairs[60:70].sum() > 0  # cross-patch pairs (about 64 cells apart)


def test_sparse_two_patch_map_stays_within_its_memory_estimate():
    import tracemalloc

    # two patches 1.5 km apart at 0.05 m cells: the box between them would be
    # 30,000 cells long; the default lag (half of it) is shortened to fit
    ijk, values = _two_patches(gap=30_000, side=16)
    g = 0.05
    pairs, gamma = brute_force(ijk, values, g, max_lag=20 * g)
    for method in ("fft", "pairs", "auto"):
        plan = plan_semivariogram(ijk, values, g, method=method)
        assert plan.bytes <= MEMORY_BUDGET
        tracemalloc.start()
        vg = semivariogram(ijk, values, g, method=method)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert peak <= plan.bytes, (method, peak, plan.bytes)
        assert vg.max_lag == plan.max_lag
        # the tiled FFT shortens the lag; the direct count (few cells) reaches 750 m
        assert vg.lag_limited == (plan.method == "fft")
        # exact up to the lag reached: against the brute force on the first 20 bins
        np.testing.assert_array_equal(vg.pairs[:20], pairs)
        np.testing.assert_allclose(vg.gamma[:20], gamma, rtol=1e-9)
    assert plan.method == "pairs"  # 512 cells: the cost model picks the direct count


def test_explicit_max_lag_that_cannot_fit_is_refused(monkeypatch):
    import rough_viewer.memory as memory

    ijk, values = _two_patches(gap=100)
    monkeypatch.setattr(memory, "available_bytes", lambda: 1e5)
    with pytest.raises(InputError, match="semivariogram .* needs about"):
        semivariogram(ijk, values, 0.5, max_lag=40.0)


def test_progress_counts_blocks_and_chunks_and_a_raising_callback_stops_it(monkeypatch):
    import rough_viewer.grid.variogram as vmod

    g = 0.5
    ijk, values = _two_patches(gap=512)
    plan = plan_semivariogram(ijk, values, g, max_lag=3.0, method="fft")
    calls: list[tuple[int, int]] = []
    vg = semivariogram(ijk, values, g, max_lag=3.0, method="fft",
                       progress=lambda d, t: calls.append((d, t)))
    # one call before the first block and one after each of the plan's blocks
    assert calls == [(k, plan.n_blocks) for k in range(plan.n_blocks + 1)]
    same = semivariogram(ijk, values, g, max_lag=3.0, method="fft")
    np.testing.assert_array_equal(vg.pairs, same.pairs)
    # direct pairs: rows done out of all rows, a chunk at a time (chunks made small)
    monkeypatch.setattr(vmod, "PAIR_CHUNK_BYTES", 48 * len(values) * 100)
    rows: list[tuple[int, int]] = []
    semivariogram(ijk, values, g, max_lag=3.0, method="pairs",
                  progress=lambda d, t: rows.append((d, t)))
    n = len(values)
    assert rows == [(0, n)] + [(min(s + 100, n), n) for s in range(0, n, 100)]

    class Stop(Exception):
        pass

    seen: list[int] = []

    def stop_after_first_block(done: int, total: int) -> None:
        seen.append(done)
        if done >= 1:
            raise Stop

    with pytest.raises(Stop):
        semivariogram(ijk, values, g, max_lag=3.0, method="fft",
                      progress=stop_after_first_block)
    assert seen == [0, 1]  # stopped after the first of the plan's blocks
    with pytest.raises(Stop):  # the face semivariogram passes it on
        face_semivariogram(np.column_stack([ijk[:, 0], ijk[:, 1], np.zeros(len(ijk))]) * g,
                           values, g, SimpleNamespace(centroid=np.zeros(3),
                                                      normal=np.array([0.0, 0.0, 1.0])),
                           max_lag=3.0, progress=stop_after_first_block)
