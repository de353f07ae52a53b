"""The de-noising comparison: 16 variants in the paper's table order, one sigma."""

from __future__ import annotations

import numpy as np

from rough_viewer.profiles import wavelets as W
from rough_viewer.profiles.comparison import compare_denoising
from rough_viewer.profiles.fractal import roughness_length

X = np.arange(2048) * 1e-3


def noisy(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    clean = 0.004 * np.sin(2 * np.pi * X / 0.37) + np.cumsum(rng.normal(0, 2e-4, X.size))
    return clean + rng.normal(0, 1e-3, X.size)


def test_variants_order_and_values() -> None:
    h = noisy(0)
    cmp = compare_denoising(h, 1e-3)
    keys = [v.key for v in cmp.variants]
    assert len(keys) == 16 and keys[0] == "dwt_fixed_soft" and keys[-1] == "wp_penalized-high_hard"
    assert keys[4] == "dwt_fixed_hard" and keys[8] == "wp_fixed_soft"
    assert cmp.raw.dimension == roughness_length(h, 1e-3).dimension
    v = cmp.variant("wp", "penalized-low", "hard")
    ref = W.denoise(h, decomposition="wp", threshold="penalized-low", mode="hard")
    np.testing.assert_array_equal(v.denoised.heights, ref)
    assert v.fractal.dimension == roughness_length(ref, 1e-3).dimension
    assert v.rms_change == np.sqrt(np.mean((h - ref) ** 2))
    assert cmp.sigma == W.noise_sigma(h)
    assert cmp.thresholds()["wp"]["penalized-low"] == W.threshold_value(
        h, decomposition="wp", threshold="penalized-low")


def test_comparison_reports_the_sigma_its_thresholds_used() -> None:
    h = noisy(5)
    h[1000] = np.nan
    h[1020] = np.nan  # a 19-sample run: in noise_sigma, not in the decomposition
    cmp = compare_denoising(h, 1e-3, threshold_rules=("fixed",), modes=("hard",))
    assert len(cmp.variants) == 2
    assert cmp.sigma == cmp.variants[0].denoised.sigma != W.noise_sigma(h)
    assert cmp.thresholds()["dwt"]["fixed"] == W.fixed_threshold(
        cmp.sigma, cmp.variants[0].denoised.d, decomposition="dwt")


def test_comparison_memory_estimate_covers_the_measured_peak() -> None:
    """Issue 36 item 6: the profile check assumed 80 bytes a sample; comparing the 16
    variants peaks near 500 (tracemalloc). The estimate covers the measured peak and
    is not more than twice it."""
    import tracemalloc

    from rough_viewer.profiles.comparison import COMPARISON_BYTES_PER_SAMPLE

    n = 50_000
    h = np.cumsum(np.random.default_rng(3).normal(0.0, 1e-5, n))
    h[1000:1200] = np.nan
    peaks = []
    for _ in range(3):  # tracemalloc counts every thread's allocations: an app's
        tracemalloc.start()  # threads left by an earlier test add to one run's peak
        try:
            compare_denoising(h, 1e-4)
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
    peak = min(peaks)
    assert 0.5 * COMPARISON_BYTES_PER_SAMPLE * n < peak <= COMPARISON_BYTES_PER_SAMPLE * n
