"""Roughness-length method on exact fractional Brownian motion and against brute force.

Accuracy measured (100 seeds per H, 2048-sample fBm, default windows 3-30 % in log):
the per-profile error of D has a bias of +0.014 (H 0.3) to +0.031 (H 0.8) and a standard
deviation of 0.052 (H 0.3) to 0.084 (H 0.8) (the paper's 3-10 %: +0.008 to +0.027,
0.050 to 0.088); the mean over 16 seeds is therefore within about +-0.07 of 2 - H,
which is what the test asserts.
"""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.profiles.fractal import (
    detrend,
    parse_windows,
    plausibility,
    roughness_length,
    roughness_length_2d,
    window_std_1d,
    window_std_2d,
)
from rough_viewer.synthetic.fbm import fbm_profile
from rough_viewer.vocabulary import InputError


def brute_std_1d(h: np.ndarray, m: int) -> np.ndarray:
    """Detrended RMS residual of every window by np.polyfit, one window at a time."""
    out = np.full(h.size - m + 1, np.nan)
    x = np.arange(m, dtype=float)
    for i in range(out.size):
        w = h[i : i + m]
        if np.all(np.isfinite(w)):
            r = w - np.polyval(np.polyfit(x, w, 1), x)
            out[i] = np.sqrt(np.mean(r**2))
    return out


def brute_std_2d(z: np.ndarray, m: int) -> np.ndarray:
    out = np.full((z.shape[0] - m + 1, z.shape[1] - m + 1), np.nan)
    yy, xx = np.indices((m, m), dtype=float)
    a = np.column_stack([np.ones(m * m), xx.ravel(), yy.ravel()])
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            w = z[i : i + m, j : j + m].ravel()
            if np.all(np.isfinite(w)):
                coef, *_ = np.linalg.lstsq(a, w, rcond=None)
                out[i, j] = np.sqrt(np.mean((w - a @ coef) ** 2))
    return out


# ----------------------------------------------------------------------------- fBm


@pytest.mark.parametrize("hurst", [0.3, 0.4, 0.5, 0.6, 0.7, 0.8])
def test_dimension_of_fbm_profiles(hurst: float) -> None:
    dims = np.array(
        [roughness_length(fbm_profile(2048, hurst, rng=seed), 1e-3).dimension for seed in range(16)]
    )
    assert abs(dims.mean() - (2 - hurst)) < 0.07
    assert np.all(np.abs(dims - (2 - hurst)) < 0.35)


def test_amplitude_and_hurst_scale_properly() -> None:
    h = fbm_profile(2048, 0.6, rng=7)
    base = roughness_length(h, 1e-3)
    scaled = roughness_length(5.0 * h + 0.2 + 0.03 * np.arange(h.size), 1e-3)
    assert scaled.hurst == pytest.approx(base.hurst, abs=1e-9)
    assert scaled.amplitude == pytest.approx(5.0 * base.amplitude, rel=1e-9)
    # s = A w^H reproduces the fitted points within the fit's scatter
    pred = base.amplitude * base.windows**base.hurst
    assert np.all(np.abs(np.log(pred / base.s)) < 0.2)
    assert 0.9 < base.r2 <= 1.0


def test_default_windows() -> None:
    r = roughness_length(np.random.default_rng(0).normal(size=1001), 1e-3)
    # 8 lengths evenly in log from 3 % to 30 % of 1.000 m: 30, 41.6, ..., 300 mm
    lengths = 0.03 * 10.0 ** (np.arange(8) / 7)
    np.testing.assert_array_equal(r.window_samples, np.rint(lengths / 1e-3).astype(int) + 1)
    np.testing.assert_allclose(r.windows, (r.window_samples - 1) * 1e-3)
    np.testing.assert_array_equal(r.n_windows, 1001 - r.window_samples + 1)
    assert r.ndim == 1 and r.dimension == pytest.approx(2 - r.hurst)


def test_paper_windows_and_given_windows() -> None:
    h = np.random.default_rng(0).normal(size=1001)
    # the paper's: 8 lengths from 3 % to 10 % of 1.000 m = 30, 40, ..., 100 mm: 31..101 samples
    r = roughness_length(h, 1e-3, windows="paper")
    np.testing.assert_array_equal(r.window_samples, np.arange(31, 102, 10))
    np.testing.assert_allclose(r.windows, np.arange(0.03, 0.1001, 0.01))
    given = roughness_length(h, 1e-3, windows=parse_windows("20,50,100", 1e-3))
    np.testing.assert_array_equal(given.window_samples, [21, 51, 101])
    assert parse_windows(" Paper ") == "paper" and parse_windows("default") == "default"
    for bad in ("", "5", "1,-2", "a,b", "1,nan"):
        with pytest.raises(InputError, match="two or more positive lengths"):
            parse_windows(bad)
    with pytest.raises(InputError, match="unknown window rule"):
        roughness_length(h, 1e-3, windows="wide")


def test_warnings_are_one_short_line_in_words() -> None:
    """A fold (D < 1) and white noise on a short profile (D > 2): one line each, in the
    words of the controls (windows, trend, de-noising), no function names."""
    x = np.arange(2000) * 1e-3
    fold = 0.5 * x**2 + fbm_profile(2000, 0.7, spacing=1e-3, sigma=1e-5, rng=3)
    (low,) = roughness_length(fold, 1e-3).warnings
    assert low.startswith("D = ") and "is below 1" in low and "remove the trend" in low
    (high,) = plausibility(2.31, -0.31, 1)
    assert high.startswith("D = 2.31 is above 2") and "larger windows" in high
    assert plausibility(1.5, 0.5, 1) == () and "is below 2" in plausibility(1.9, 1.1, 2)[0]
    for line in (low, high):
        assert len(line.split()) <= 40 and "fractal." not in line and "--" not in line


# ----------------------------------------------------------------------------- brute force


@pytest.mark.parametrize("m", [3, 7, 40])
def test_window_std_1d_matches_brute_force(m: int) -> None:
    rng = np.random.default_rng(m)
    h = 100.0 + np.cumsum(rng.normal(size=300)) * 1e-3  # large offset: conditioning
    h[120:123] = np.nan
    std, valid = window_std_1d(h, m)
    ref = brute_std_1d(h, m)
    assert np.array_equal(valid, np.isfinite(ref))
    np.testing.assert_allclose(std[valid], ref[valid], rtol=1e-7, atol=1e-12)


def test_profile_with_gap_averages_valid_windows_only() -> None:
    h = fbm_profile(1000, 0.5, rng=3)
    h[500:510] = np.nan
    r = roughness_length(h, 1e-3, windows=[0.01, 0.02, 0.04])
    for m, s, k in zip(r.window_samples, r.s, r.n_windows, strict=True):
        ref = brute_std_1d(h, int(m))
        assert k == np.isfinite(ref).sum()
        assert s == pytest.approx(np.nanmean(ref), rel=1e-7)


@pytest.mark.parametrize("m", [3, 6])
def test_window_std_2d_matches_brute_force(m: int) -> None:
    rng = np.random.default_rng(m)
    z = 5.0 + rng.normal(size=(17, 23)) * 1e-3 + 0.01 * np.arange(23)[None, :]
    z[4, 9] = np.nan
    std, valid = window_std_2d(z, m)
    ref = brute_std_2d(z, m)
    assert np.array_equal(valid, np.isfinite(ref))
    np.testing.assert_allclose(std[valid], ref[valid], rtol=1e-7, atol=1e-12)


def test_patch_of_ridges_has_the_profile_hurst() -> None:
    """A surface constant across one axis: every square window's plane residual is the
    1-D line residual, so the patch H equals the profile H exactly and D = 3 - H."""
    h = fbm_profile(200, 0.6, rng=3)
    patch = np.tile(h, (200, 1))
    r2d = roughness_length_2d(patch, 1e-3)
    r1d = roughness_length(h, 1e-3)
    assert r2d.hurst == pytest.approx(r1d.hurst, abs=1e-9)
    assert r2d.dimension == pytest.approx(3 - r1d.hurst, abs=1e-9)
    assert r2d.ndim == 2


def test_isotropic_spectral_surface_dimension() -> None:
    """Spectral synthesis (power ~ k^-(2H+2)) is only approximately self-affine;
    measured error of D over seeds: -0.08 (H 0.3) to +0.03 (H 0.8)."""
    n = 128
    k = np.hypot(*np.meshgrid(np.fft.fftfreq(n), np.fft.fftfreq(n)))
    k[0, 0] = 1.0
    for hurst in (0.3, 0.8):
        amp = k ** (-(hurst + 1.0))
        amp[0, 0] = 0.0
        rng = np.random.default_rng(1)
        z = np.fft.ifft2(amp * (rng.normal(size=(n, n)) + 1j * rng.normal(size=(n, n)))).real
        assert roughness_length_2d(z, 1e-3).dimension == pytest.approx(3 - hurst, abs=0.15)


def test_errors() -> None:
    with pytest.raises(ValueError, match="window"):
        roughness_length(np.ones(20), 1e-3)
    with pytest.raises(ValueError, match="spacing"):
        roughness_length(np.ones(2000), 0.0)
    with pytest.raises(ValueError, match="positive"):
        roughness_length(np.arange(2000.0), 1e-3)  # a straight line: s(w) = 0
    with pytest.raises(ValueError, match="2-D"):
        roughness_length_2d(np.ones(100), 1e-3)


def test_an_array_as_the_spacing_is_an_input_error():
    """A notebook slip (the distances given as the spacing) raised a bare TypeError."""
    distances = np.arange(200) * 0.01
    heights = np.sin(distances * 7)
    with pytest.raises(InputError, match=r"spacing must be one number .* of shape \(200,\)"):
        roughness_length(distances, heights)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="spacing must be one number"):
        detrend(heights, "1cm")  # type: ignore[arg-type]
