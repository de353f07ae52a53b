"""The sampled semivariogram (rough_viewer.grid.variogram_sample) against the exact
one, and the cost-based choice between the exact methods and a sample."""

from __future__ import annotations

import numpy as np
import pytest

import rough_viewer.grid.variogram as vmod
from rough_viewer.grid.variogram import plan_semivariogram, semivariogram, semivariograms
from tests.grid.test_variogram import brute_force


def fractal_surface_cells(n: int, seed: int, *, hurst: float = 0.7, holes: float = 0.2,
                          relief: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """Cells of a self-affine (fractal) surface ``n x n`` cells in plan, its heights
    rounded to cells (a 3-D surface a few cells thick), a share ``holes`` of the
    cells left out; values: |height| plus noise (a skewed map, like roughness)."""
    rng = np.random.default_rng(seed)
    kx = np.fft.fftfreq(n)[:, None]
    ky = np.fft.rfftfreq(n)[None, :]
    k = np.hypot(kx, ky)
    k[0, 0] = 1.0
    amp = k ** (-(hurst + 1.0))
    amp[0, 0] = 0.0
    spec = amp * (rng.normal(size=k.shape) + 1j * rng.normal(size=k.shape))
    h = np.fft.irfftn(spec, s=(n, n), axes=(0, 1))
    h = (h - h.mean()) / h.std()
    ii, jj = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    ijk = np.column_stack([ii.ravel(), jj.ravel(), np.floor(relief * h.ravel()).astype(int)])
    values = np.abs(h.ravel()) + 0.1 * rng.normal(size=n * n)
    keep = rng.random(n * n) >= holes
    return ijk[keep], values[keep]


@pytest.mark.parametrize("method", ["fft", "pairs", "auto"])
@pytest.mark.parametrize("shape", [(40, 3), (33, 2, 4), (5, 30, 3)])
def test_exact_methods_equal_brute_force_on_anisotropic_boxes_with_holes(method, shape):
    rng = np.random.default_rng(sum(shape))
    occupied = np.argwhere(rng.random(shape) < 0.55)  # holes: 45 % of the box empty
    values = 50.0 + rng.normal(size=len(occupied))
    values[rng.random(len(values)) < 0.1] = np.nan  # missing values: more holes
    g = 0.2
    for w in (None, 0.3):
        vg = semivariogram(occupied, values, g, bin_width=w, method=method)
        pairs, gamma = brute_force(occupied, values, g, w=w)
        assert vg.exact and vg.gamma_se is None and vg.sampled is None
        plan = plan_semivariogram(occupied, values, g, bin_width=w, method=method)
        assert vg.method == plan.method == (method if method != "auto" else plan.method)
        np.testing.assert_array_equal(vg.pairs, pairs)
        np.testing.assert_allclose(vg.gamma, gamma, rtol=1e-9)


def test_sampled_estimate_is_within_its_standard_error_of_the_exact_one():
    z_scores = []
    for surface in range(3):
        ijk, values = fractal_surface_cells(64, surface)
        exact = semivariogram(ijk, values, 0.1, method="fft")
        assert exact.method == "fft"
        for seed in range(6):
            est = semivariogram(ijk, values, 0.1, method="sample", time_budget=0.02,
                                seed=seed)
            assert est.method == "sample" and not est.exact
            np.testing.assert_allclose(est.lag, exact.lag)
            assert est.sampled is not None and est.gamma_se is not None
            assert est.sampled.min() >= 200  # every bin sampled, the short ones too
            assert np.all(est.sampled <= est.sampled.max())
            # the pair counts are estimated within a few per cent
            assert np.max(np.abs(est.pairs / exact.pairs - 1.0)) < 0.25
            z_scores.append((est.gamma - exact.gamma) / est.gamma_se)
            # the normalised curve's error bar is the same relative size
            np.testing.assert_allclose(est.gamma_normalised_se * est.variance, est.gamma_se)
    z = np.concatenate(z_scores)
    assert np.all(np.isfinite(z))
    # honest error bars: about 68 % within 1 SE and 95 % within 2, z-scores of unit spread
    assert 0.60 <= np.mean(np.abs(z) < 1.0) <= 0.76
    assert 0.91 <= np.mean(np.abs(z) < 2.0) <= 0.985
    assert 0.85 <= np.sqrt(np.mean(z * z)) <= 1.15
    assert abs(np.mean(z)) < 0.15  # no bias


def test_a_larger_budget_gives_a_smaller_error_and_the_same_seed_the_same_estimate():
    ijk, values = fractal_surface_cells(48, 7)
    small = semivariogram(ijk, values, 0.1, method="sample", time_budget=0.01, seed=3)
    again = semivariogram(ijk, values, 0.1, method="sample", time_budget=0.01, seed=3)
    large = semivariogram(ijk, values, 0.1, method="sample", time_budget=0.2, seed=3)
    np.testing.assert_array_equal(small.gamma, again.gamma)
    assert np.median(large.gamma_se / small.gamma_se) < 0.5
    assert np.median(large.sampled) > 4 * np.median(small.sampled)


def test_maps_share_the_sample_and_keep_their_own_missing_cells_and_extent():
    ijk, values = fractal_surface_cells(48, 2, holes=0.0)
    other = values.copy()
    other[ijk[:, 0] >= 24] = np.nan  # half the map missing: half the extent along x
    got = semivariograms(ijk, {"a": values, "b": other}, 0.1, method="sample",
                         time_budget=0.05, seed=1)
    exact_b = semivariogram(ijk, other, 0.1)
    assert got["b"].n_cells == exact_b.n_cells
    assert got["b"].variance == pytest.approx(exact_b.variance)
    assert len(got["b"].lag) == len(exact_b.lag) == 24  # its own default lag
    assert len(got["a"].lag) == 24  # half of 48 cells along x and y
    z = (got["b"].gamma - exact_b.gamma) / got["b"].gamma_se
    assert np.sqrt(np.mean(z * z)) < 2.0
    assert np.all(got["b"].pairs > 0)


def test_the_method_follows_the_cost_estimate(monkeypatch):
    monkeypatch.setenv("ROUGH_VIEWER_ENGINE", "numpy")  # the NumPy count's cost
    # few cells: the direct count (M^2 pairs) is cheap
    rng = np.random.default_rng(0)
    few = np.argwhere(rng.random((30, 30)) < 0.5)
    plan = plan_semivariogram(few, np.ones(len(few)), 0.1)
    assert plan.method == "pairs" and plan.seconds == pytest.approx(
        vmod.PAIR_SECONDS * len(few) * (len(few) - 1))
    # a compact full box of 40,000 cells: the FFT of its box is cheaper than 1.6e9 pairs
    full = np.argwhere(np.ones((200, 200), bool))
    plan = plan_semivariogram(full, np.ones(len(full)), 0.1)
    assert plan.method == "fft" and plan.seconds < vmod.PAIR_SECONDS * len(full) ** 2
    # the same grid for four maps under a budget below the FFT's estimate: a sample
    # sized to the budget, at the full lag
    tight = plan.seconds * 4 / 2
    sampled = plan_semivariogram(full, np.ones(len(full)), 0.1, n_maps=4, time_budget=tight)
    assert sampled.method == "sample" and sampled.seconds <= tight * 1.001
    assert sampled.max_lag == plan.max_lag and not sampled.lag_limited
    assert plan_semivariogram(full, np.ones(len(full)), 0.1, n_maps=4,
                              time_budget=plan.seconds * 4 * 1.01).method == "fft"
    # the choice is the cost model's, not a timing: a dearer frame cell flips it
    monkeypatch.setattr(vmod, "FRAME_SECONDS", 1.0)
    assert plan_semivariogram(full, np.ones(len(full)), 0.1).method == "sample"
    monkeypatch.setattr(vmod, "PAIR_SECONDS", 1e-15)
    assert plan_semivariogram(full, np.ones(len(full)), 0.1).method == "pairs"
    # the compiled count's rate where it runs
    from rough_viewer.grid import fast

    if fast.available():
        monkeypatch.setenv("ROUGH_VIEWER_ENGINE", "numba")
        plan = plan_semivariogram(few, np.ones(len(few)), 0.1)
        assert plan.seconds == pytest.approx(
            vmod.PAIR_SECONDS_COMPILED * len(few) * (len(few) - 1))


def test_a_fine_face_is_planned_fast_and_sampled_within_its_memory_estimate():
    import time
    import tracemalloc

    # a 3-D face 600 x 500 cells in plan, a few cells thick: 300,000 cells, far too
    # many for either exact method within the default budget
    ijk, values = fractal_surface_cells(560, 4, holes=0.05, relief=2.0)
    t0 = time.process_time()
    plan = plan_semivariogram(ijk, values, 0.05, n_maps=1)
    assert time.process_time() - t0 < 5.0  # the plan draws nothing
    assert plan.method == "sample" and plan.n_bins == 280
    tracemalloc.start()
    vg = semivariogram(ijk, values, 0.05, time_budget=0.2)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert peak <= plan.bytes
    assert vg.method == "sample" and np.all(vg.sampled > 50)


def test_a_raising_progress_stops_the_sample():
    ijk, values = fractal_surface_cells(48, 1)
    calls: list[tuple[int, int]] = []

    class Stop(Exception):
        pass

    def stop(done: int, total: int) -> None:
        calls.append((done, total))
        if done > 0:
            raise Stop

    with pytest.raises(Stop):
        semivariogram(ijk, values, 0.1, method="sample", time_budget=0.5, progress=stop)
    assert calls[0][0] == 0 and len(calls) == 2
