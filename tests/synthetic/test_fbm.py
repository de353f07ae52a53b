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
