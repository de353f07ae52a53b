"""Colour layers of the rock itself: scan RGB, intensity, distance to the face plane."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

from rough_viewer.visual import colormaps, layers
from rough_viewer.visual.layers import (
    face_plane_distance,
    intensity_layer,
    plane_distance_layer,
    rgb_bit_depth,
    rgb_colours,
    rgb_layer,
)
from tests.helpers import UTM


def test_module_examples_run():
    assert doctest.testmod(layers).failed == 0


EIGHT = np.array([[0, 0, 0], [255, 128, 1], [17, 200, 255]], dtype=np.uint8)


def test_eight_bit_rgb_is_shown_as_is():
    assert rgb_bit_depth(EIGHT) == 8
    np.testing.assert_array_equal(rgb_colours(EIGHT), EIGHT)
    out = rgb_layer(EIGHT)
    assert out.colours.dtype == np.uint8 and out.name == "rgb" and out.colour_range is None


@pytest.mark.parametrize("factor", [256, 257])
def test_sixteen_bit_rgb_scales_back_to_eight_bits(factor):
    """Writers scale 8-bit colours by 256 or by 257 (65535 / 255); both come back."""
    wide = EIGHT.astype(np.uint16) * factor
    assert rgb_bit_depth(wide) == 16
    np.testing.assert_array_equal(rgb_colours(wide), EIGHT)


def test_eight_bit_values_in_sixteen_bit_fields_are_detected():
    """Many LAS files store 0-255 in their 16-bit RGB fields; dividing by 256 would
    turn those scans black."""
    stored = EIGHT.astype(np.uint16)
    assert rgb_bit_depth(stored) == 8
    np.testing.assert_array_equal(rgb_colours(stored), EIGHT)
    np.testing.assert_array_equal(rgb_colours(stored.astype(np.int64)), EIGHT)
    # one value above 255 makes the whole array 16-bit: 256 >> 8 = 1
    mixed = np.vstack([stored, [[256, 0, 65535]]])
    np.testing.assert_array_equal(rgb_colours(mixed)[-1], [1, 0, 255])
    np.testing.assert_array_equal(rgb_colours(mixed)[:3], 0 * EIGHT + (EIGHT >> 8))


@pytest.mark.parametrize("bad", [
    np.zeros((4, 2), np.uint8), np.zeros((4, 3)), np.array([[0, -1, 3]]),
    np.array([[0, 70000, 3]]),
])
def test_bad_rgb_is_refused(bad):
    with pytest.raises(ValueError):
        rgb_colours(bad)


def test_intensity_is_stretched_to_grey_between_its_percentiles():
    intensity = np.r_[np.arange(1000, dtype=float), np.nan]
    out = intensity_layer(intensity)
    lo, hi = np.percentile(np.arange(1000), [2, 98])
    assert out.colour_range.lo == pytest.approx(lo) and out.colour_range.hi == pytest.approx(hi)
    grey = colormaps.lut("gray")
    np.testing.assert_array_equal(out.colours[0], grey[0])       # below the 2nd percentile
    np.testing.assert_array_equal(out.colours[999], grey[-1])    # above the 98th
    mid = int(round((499.5 - lo) / (hi - lo) * 255))
    assert abs(int(out.colours[500, 0]) - int(grey[mid, 0])) <= 2
    assert tuple(out.colours[-1]) == colormaps.NEUTRAL_RGB
    assert np.all(out.colours[:, 0] == out.colours[:, 1])        # grey
    # a range resolved elsewhere (all points) can colour a subset
    sub = intensity_layer(intensity[::10], colour_range=out.colour_range)
    np.testing.assert_array_equal(sub.colours, out.colours[::10])


def test_distance_layer_is_diverging_about_the_face_plane():
    rng = np.random.default_rng(0)
    x, z = rng.uniform(0, 4, (2, 10_001))
    bump = np.where((x - 2) ** 2 + (z - 2) ** 2 < 0.25, 0.02, 0.0)  # 20 mm proud disc
    pts = np.column_stack([x, bump + 0.0005 * rng.standard_normal(x.size), z]) + UTM
    d = face_plane_distance(pts)
    assert abs(d.mean()) < 1e-9
    np.testing.assert_allclose(d[bump > 0].mean() - d[bump == 0].mean(), 0.02, atol=5e-4)
    out = plane_distance_layer(d)
    r = out.colour_range
    assert r.lo == -r.hi and r.hi > 0
    assert out.colormap in colormaps.DIVERGING
    lut = colormaps.lut(out.colormap)
    np.testing.assert_array_equal(plane_distance_layer(np.array([0.0]), colour_range=r).colours[0],
                                  lut[128])  # 0 m: the middle colour
    proud = out.colours[bump > 0].astype(int)
    assert np.median(proud[:, 0] - proud[:, 2]) > 100  # red side of coolwarm
    with pytest.raises(ValueError, match="symmetric"):
        plane_distance_layer(d, stretch=colormaps.Stretch())
