"""Z2 and the JRC estimate of Tse and Cruden (1979) (issue 25)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rough_viewer.profiles.jrc import (
    JRC_INTERCEPT,
    JRC_SLOPE,
    jrc_from_z2,
    jrc_warnings,
    z2,
)
from rough_viewer.vocabulary import InputError


def test_z2_of_a_sawtooth_is_the_tangent_of_its_flanks():
    """Every interval of a sawtooth with 20-degree flanks rises or falls by
    tan(20) spacings: Z2 = tan(20 degrees), whatever the spacing."""
    for spacing in (0.5e-3, 1e-3, 0.01):
        h = spacing * math.tan(math.radians(20.0)) * np.array([0, 1, 2, 1, 0, 1, 2, 1, 0.0])
        assert z2(h, spacing) == pytest.approx(math.tan(math.radians(20.0)), rel=1e-12)


def test_z2_skips_intervals_across_gaps_and_is_the_rms_slope():
    rng = np.random.default_rng(2)
    h = rng.standard_normal(500) * 1e-3
    expected = math.sqrt(np.mean((np.diff(h) / 1e-3) ** 2))
    assert z2(h, 1e-3) == pytest.approx(expected, rel=1e-12)
    g = h.copy()
    g[100:110] = np.nan  # 11 intervals touch the gap: left out, never bridged
    d = np.diff(g)
    d = d[np.isfinite(d)]
    assert d.size == 499 - 11
    assert z2(g, 1e-3) == pytest.approx(math.sqrt(np.mean((d / 1e-3) ** 2)), rel=1e-12)
    assert math.isnan(z2(np.full(5, np.nan), 1e-3))


def test_jrc_formula_of_tse_and_cruden():
    """JRC = 32.2 + 32.47 log10(Z2) (Tse and Cruden 1979, Int. J. Rock Mech. Min.
    Sci. 16, 303-307). Its two constants fix where Barton's 0-20 scale falls:
    JRC 0 at Z2 = 10^(-32.2/32.47) = 0.1020 and JRC 20 at 10^(-12.2/32.47) = 0.4209,
    each decade of Z2 adding 32.47."""
    assert (JRC_INTERCEPT, JRC_SLOPE) == (32.2, 32.47)
    assert jrc_from_z2(1.0) == pytest.approx(32.2)
    assert jrc_from_z2(0.1020) == pytest.approx(0.0, abs=0.02)
    assert jrc_from_z2(0.4209) == pytest.approx(20.0, abs=0.01)
    assert jrc_from_z2(0.5) - jrc_from_z2(0.05) == pytest.approx(32.47)
    z = np.array([0.1, 0.2, 0.0, np.nan])
    out = jrc_from_z2(z)
    np.testing.assert_allclose(out[:2], 32.2 + 32.47 * np.log10(z[:2]))
    assert np.isnan(out[2:]).all()


def test_jrc_warns_outside_the_sampling_it_was_calibrated_for():
    for fine in (0.46e-3, 0.5e-3, 0.7e-3, 1e-3, 1.08e-3):  # "about": 10 % either side
        assert jrc_warnings(fine) == ()
    (line,) = jrc_warnings(0.2e-3)
    assert "0.5-1 mm" in line and "0.2 mm" in line
    assert jrc_warnings(5e-3)


def test_bad_profiles_are_one_line_errors():
    with pytest.raises(InputError, match="one-dimensional"):
        z2(np.zeros((3, 3)), 1e-3)
    with pytest.raises(InputError, match="spacing"):
        z2(np.zeros(3), 0.0)
