"""Signed distances to a plane against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.planes import PlaneFit, signed_distance, whole_cloud_plane
from rough_viewer.io import PointCloud
from tests.helpers import UTM, random_rotation


def test_signed_distance_of_points_offset_along_a_tilted_normal():
    rot = random_rotation(7)
    rng = np.random.default_rng(1)
    uv = rng.uniform(-3, 3, (5000, 2))
    offset = rng.normal(0, 0.01, 5000)
    local = np.column_stack([uv, offset])
    pts = local @ rot.T + UTM  # a plane through UTM with normal rot[:, 2]
    plane = PlaneFit(centroid=UTM.copy(), normal=rot[:, 2] * 3.0,  # not unit: normalised
                     eigenvalues=np.ones(3), axes=rot)
    np.testing.assert_allclose(signed_distance(pts, plane), offset, atol=1e-9)
    cloud = PointCloud.from_xyz(pts)
    np.testing.assert_allclose(signed_distance(cloud, plane), offset, atol=1e-9)


def test_whole_cloud_plane_distances_sum_to_zero_and_follow_the_normal():
    rng = np.random.default_rng(2)
    x, z = rng.uniform(0, 4, (2, 20_000))
    y = 7.0 + 0.003 * rng.standard_normal(20_000)
    pts = np.column_stack([x, y, z])
    plane = whole_cloud_plane(pts)
    d = signed_distance(pts, plane)
    assert abs(d.mean()) < 1e-12
    # reference: the plane of the points by SVD, its normal turned to +y
    centred = pts - pts.mean(axis=0)
    normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    normal *= np.sign(normal[1])
    np.testing.assert_allclose(d, centred @ normal, atol=1e-9)
    assert plane.normal[1] > 0  # orient_normal: +y for a face parallel to xz


def test_plane_without_normal_is_refused():
    bad = PlaneFit(np.zeros(3), np.zeros(3), np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match="no normal"):
        signed_distance(np.zeros((3, 3)), bad)
