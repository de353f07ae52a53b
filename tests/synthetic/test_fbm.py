"""Exact fBm by circulant embedding: increment covariance and variance growth."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.synthetic.fbm import fbm_profile, fgn_autocovariance


def test_fbm_increments_have_the_fgn_covariance() -> None:
    """The generator is exact: sample covariance of the increments over many profiles
    matches g(k) = (|k+1|^2H - 2|k|^2H + |k-1|^2H) / 2 (scaled)."""
    h, n = 0.3, 64
    inc = np.stack([np.diff(fbm_profile(n, h, spacing=1.0, sigma=1.0, rng=s)) for s in range(3000)])
    emp = np.array([np.mean(inc[:, : n - 1 - k] * inc[:, k:]) for k in range(4)])
    np.testing.assert_allclose(emp, fgn_autocovariance(4, h), atol=0.04)
    # variance of B(n-1) = (n-1)^(2H)
    end = np.array([fbm_profile(n, h, spacing=1.0, sigma=1.0, rng=s)[-1] for s in range(3000)])
    assert np.var(end) == pytest.approx((n - 1) ** (2 * h), rel=0.08)


def test_scaling_and_errors() -> None:
    a = fbm_profile(100, 0.5, spacing=1e-3, sigma=2e-3, rng=4)
    b = fbm_profile(100, 0.5, spacing=1.0, sigma=1.0, rng=4)
    np.testing.assert_allclose(a, b * 2e-3 * 1e-3**0.5, rtol=1e-12)
    assert a[0] == 0.0 and a.shape == (100,)
    with pytest.raises(ValueError):
        fbm_profile(100, 1.0)


def test_fbm_sheet_has_its_two_exponents_and_scale() -> None:
    """The sheet is exact: over many sheets, the variance of an increment of r steps
    along x at distance y from the x axis is sigma^2 r^2Hx y^2Hy (in metres), and
    along y likewise with the exponents swapped: both exponents and the scale."""
    from rough_viewer.synthetic.fbm import fbm_sheet

    hx, hy, n, spacing, sigma = 0.3, 0.7, 13, 0.01, 2.0
    lags = np.array([1, 2, 4, 8])
    along_x = np.zeros(lags.size)
    along_y = np.zeros(lags.size)
    runs = 2000
    for s in range(runs):
        z = fbm_sheet((n, n), hx, hy, spacing=spacing, sigma=sigma, rng=s)
        along_x += (z[4, 4 + lags] - z[4, 4]) ** 2
        along_y += (z[4 + lags, 4] - z[4, 4]) ** 2
    along_x /= runs
    along_y /= runs
    # z[i, j] lies at x = (n + j) spacing, y = (n + i) spacing from the sheet's axes
    x0 = y0 = (n + 4) * spacing
    r = lags * spacing
    np.testing.assert_allclose(along_x, sigma**2 * r ** (2 * hx) * y0 ** (2 * hy), rtol=0.12)
    np.testing.assert_allclose(along_y, sigma**2 * r ** (2 * hy) * x0 ** (2 * hx), rtol=0.12)
    assert np.polyfit(np.log(r), np.log(along_x), 1)[0] / 2 == pytest.approx(hx, abs=0.03)
    assert np.polyfit(np.log(r), np.log(along_y), 1)[0] / 2 == pytest.approx(hy, abs=0.03)


def test_fbm_surface_is_isotropic_with_the_rms_asked() -> None:
    from rough_viewer.synthetic.fbm import fbm_surface

    sf = np.zeros(3)
    for s in range(40):
        z = fbm_surface((64, 64), 0.6, rms=1e-3, rng=s)
        assert np.sqrt(np.mean(z * z)) == pytest.approx(1e-3) and abs(z.mean()) < 1e-15
        # squared increments over 4 steps along x, along y and over (3, 3) along a diagonal
        sf += [np.mean((z[:, 4:] - z[:, :-4]) ** 2), np.mean((z[4:] - z[:-4]) ** 2),
               np.mean((z[3:, 3:] - z[:-3, :-3]) ** 2)]
    np.testing.assert_allclose(sf[1:] / sf[0], [1.0, (np.hypot(3, 3) / 4) ** 1.2], rtol=0.1)
