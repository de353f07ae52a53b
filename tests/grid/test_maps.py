"""Tests of rough_viewer.grid.maps: face-plane frame, rasterising, binary maps."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rough_viewer.grid.maps import face_frame, face_image, face_maps, face_raster


def plane(normal, centroid=(0.0, 0.0, 0.0)):
    return SimpleNamespace(centroid=np.asarray(centroid, float), normal=np.asarray(normal, float))


@pytest.mark.parametrize(
    ("normal", "u", "v"),
    [
        ((0, 1, 0), (1, 0, 0), (0, 0, 1)),  # face parallel to xz (Box Canyon): u = x, v = z
        ((0, -1, 0), (1, 0, 0), (0, 0, 1)),  # normal sign does not mirror the map
        ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
        ((0, 0, 1), (1, 0, 0), (0, 1, 0)),  # horizontal: plan view
        ((0, 0, -1), (1, 0, 0), (0, 1, 0)),
    ],
)
def test_frame_axes(normal, u, v):
    f = face_frame(plane(normal))
    np.testing.assert_allclose(f.u_axis, u, atol=1e-12)
    np.testing.assert_allclose(f.v_axis, v, atol=1e-12)


def test_frame_is_orthonormal_for_a_tilted_plane():
    n = np.array([0.2, 0.7, 0.4])
    f = face_frame(plane(n))
    basis = np.vstack([f.u_axis, f.v_axis, f.normal])
    np.testing.assert_allclose(basis @ basis.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(f.normal, n / np.linalg.norm(n))
    assert f.v_axis[2] > 0  # "up the face" points up


def test_raster_places_cells_in_their_pixels():
    g = 0.5
    p = plane((0, 1, 0), centroid=(10.0, 3.0, 2.0))
    # cell centres (x, y, z): u = x - 10, v = z - 2; y (through the face) is ignored
    centres = np.array([
        [10.25, 3.0, 2.25],   # u 0.25, v 0.25 -> absolute pixel (0, 0)
        [11.25, 5.0, 2.25],   # u 1.25 -> (2, 0)
        [9.75, 1.0, 3.75],    # u -0.25, v 1.75 -> (-1, 3)
        [10.40, 3.7, 2.10],   # same pixel as the first
    ])
    r = face_raster(centres, p, g)
    np.testing.assert_allclose(r.uv, [[0.25, 0.25], [1.25, 0.25], [-0.25, 1.75], [0.4, 0.1]])
    np.testing.assert_array_equal(r.offset, [-1, 0])
    np.testing.assert_array_equal(r.pixel, [[1, 0], [3, 0], [0, 3], [1, 0]])
    assert r.shape == (4, 4)

    values = np.array([1.0, 2.0, 3.0, 5.0])
    img = face_image(r, values, reduce="max")
    expected = np.full((4, 4), np.nan)
    expected[0, 1] = 5.0
    expected[0, 3] = 2.0
    expected[3, 0] = 3.0
    np.testing.assert_array_equal(img.image, expected)
    np.testing.assert_allclose(img.u, [-0.25, 0.25, 0.75, 1.25])
    np.testing.assert_allclose(img.v, [0.25, 0.75, 1.25, 1.75])
    assert img.count[0, 1] == 2 and img.count.sum() == 4

    mean = face_image(r, values, reduce="mean")
    assert mean.image[0, 1] == 3.0
    # a NaN cell is no cell
    nan_img = face_image(r, np.array([1.0, np.nan, 3.0, 5.0]))
    assert np.isnan(nan_img.image[0, 3]) and nan_img.count[0, 3] == 0


def test_binary_map_at_threshold():
    g = 1.0
    p = plane((0, 0, 1))
    centres = np.array([[0.5, 0.5, 0], [1.5, 0.5, 0], [2.5, 0.5, 0], [0.5, 1.5, 0], [1.5, 1.5, 0]])
    normalised = np.array([0.0, 0.049, 0.05, 1.0, np.nan])
    maps = face_maps(face_raster(centres, p, g), normalised, threshold=0.05)
    np.testing.assert_array_equal(maps.normalised.image, [[0.0, 0.049, 0.05], [1.0, np.nan, np.nan]])
    np.testing.assert_array_equal(maps.binary.image, [[0.0, 0.0, 1.0], [1.0, np.nan, np.nan]])
    assert maps.threshold == 0.05


def test_bad_values_shape_and_reduce():
    r = face_raster(np.zeros((2, 3)), plane((0, 0, 1)), 1.0)
    with pytest.raises(ValueError):
        face_image(r, np.zeros(3))
    with pytest.raises(ValueError):
        face_image(r, np.zeros(2), reduce="median")
