import numpy as np
import pytest

from rough_viewer.visual import colormaps


def test_luts_have_anchor_colours_at_the_ends():
    v = colormaps.lut("viridis")
    assert v.shape == (256, 3) and v.dtype == np.uint8
    assert tuple(v[0]) == (0x44, 0x01, 0x54)
    assert tuple(v[-1]) == (0xFD, 0xE7, 0x25)
    # halfway between two anchors is their mean (linear interpolation)
    c = colormaps.lut("gray")
    assert abs(int(c[128][0]) - round(0x1A + (0xF0 - 0x1A) * 128 / 255)) <= 1


def test_viridis_lightness_increases():
    v = colormaps.lut("viridis").astype(float)
    luma = v @ [0.2126, 0.7152, 0.0722]
    assert np.all(np.diff(luma[::16]) > 0)


def test_apply_maps_range_clips_and_marks_nan():
    vals = np.array([0.0, 0.5, 1.0, -3.0, 7.0, np.nan])
    rgb = colormaps.apply(vals, "viridis", vmin=0.0, vmax=1.0)
    lut = colormaps.lut("viridis")
    assert np.array_equal(rgb[0], lut[0]) and np.array_equal(rgb[2], lut[255])
    assert np.array_equal(rgb[1], lut[128])  # round(0.5 * 255) = 128
    assert np.array_equal(rgb[3], lut[0]) and np.array_equal(rgb[4], lut[255])
    assert tuple(rgb[5]) == colormaps.NEUTRAL_RGB


def test_apply_with_clip_range():
    lut = colormaps.lut("cividis")
    rgb = colormaps.apply(np.array([0.2, 0.3, 0.6]), "cividis", vmin=0.2, vmax=0.6)
    assert np.array_equal(rgb[0], lut[0]) and np.array_equal(rgb[2], lut[255])
    assert np.array_equal(rgb[1], lut[round(0.25 * 255)])


def test_binary_two_colours_and_neutral():
    rgb = colormaps.apply_binary(np.array([True, False, True]), np.array([True, True, False]))
    lut = colormaps.lut("viridis")
    assert np.array_equal(rgb[0], lut[-1]) and np.array_equal(rgb[1], lut[0])
    assert tuple(rgb[2]) == colormaps.NEUTRAL_RGB


def test_unknown_name_and_plotly_scale():
    with pytest.raises(ValueError, match="unknown colour map"):
        colormaps.lut("jet")
    scale = colormaps.plotly_colorscale("magma", 3)
    assert scale[0] == [0.0, "rgb(0,0,4)"] and scale[-1][1] == "rgb(252,253,191)"
