"""Plane fits: single point sets, the whole cloud, and the batched per-cell fits,
against numpy SVD and least squares."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.planes import (
    PlaneFit,
    dominant_axis,
    fit_plane,
    odr_from_covariance,
    ols_from_covariance,
    orient_normal,
    signed_distance,
    whole_cloud_plane,
)
from rough_viewer.io import PointCloud
from tests.helpers import UTM, random_rotation, rough_surface


def _svd_normal(p):
    return np.linalg.svd(p - p.mean(axis=0))[2][2]


def test_fit_plane_matches_svd():
    p = rough_surface(2_000, seed=1) @ random_rotation(2).T
    fit = fit_plane(p)
    assert abs(abs(fit.normal @ _svd_normal(p)) - 1) < 1e-12
    np.testing.assert_allclose(fit.centroid, p.mean(axis=0))
    assert np.all(np.diff(fit.eigenvalues) <= 0)  # descending
    np.testing.assert_allclose(fit.axes[:, 2], fit.normal)
    np.testing.assert_allclose(fit.eigenvalues, np.linalg.svd(p - p.mean(axis=0))[1] ** 2 / len(p),
                               rtol=1e-9)


def test_whole_cloud_plane_on_utm_coordinates_in_chunks(monkeypatch):
    import rough_viewer.grid.planes as planes

    local = rough_surface(30_000, seed=4) @ random_rotation(5).T
    utm = local + [4.5e5, 5.1e6, 1.2e3]
    monkeypatch.setattr(planes, "_PLANE_CHUNK", 7_000)  # several chunks, one partial
    whole = whole_cloud_plane(PointCloud.from_xyz(utm))
    ref = fit_plane(local)
    assert abs(abs(whole.normal @ ref.normal) - 1) < 1e-10
    np.testing.assert_allclose(whole.centroid - [4.5e5, 5.1e6, 1.2e3], ref.centroid, atol=1e-8)
    np.testing.assert_allclose(whole.eigenvalues, ref.eigenvalues, rtol=1e-7)
    assert whole.normal[np.argmax(np.abs(whole.normal))] > 0  # orientation convention


def test_orient_normal_and_dominant_axis():
    np.testing.assert_array_equal(orient_normal(np.array([0.1, -0.9, 0.2])), [-0.1, 0.9, -0.2])
    assert dominant_axis(np.array([0.1, -0.9, 0.2])) == "y"
    assert dominant_axis(np.array([0.0, 0.0, -1.0])) == "z"


def test_batched_odr_matches_per_cell_svd_and_flags_degenerate_cells():
    rng = np.random.default_rng(3)
    sets = [rng.normal(size=(50, 3)) * [1.0, 0.5, 0.01] @ random_rotation(k).T for k in range(6)]
    sets.append(np.outer(np.linspace(0, 1, 10), [1.0, 2.0, 3.0]))  # collinear
    sets.append(np.ones((5, 3)))  # coincident
    cov = np.stack([np.cov(p.T, bias=True) for p in sets])
    normal, eig, valid = odr_from_covariance(cov)
    for k in range(6):
        assert abs(abs(normal[k] @ _svd_normal(sets[k])) - 1) < 1e-9
        assert np.all(np.diff(eig[k]) <= 0)
    assert valid[:6].all() and not valid[6] and not valid[7]


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_batched_ols_matches_lstsq(axis):
    a = "xyz".index(axis)
    u, v = [i for i in range(3) if i != a]
    rng = np.random.default_rng(11)
    sets = [rng.normal(size=(40, 3)) @ random_rotation(k + 20).T for k in range(5)]
    cov = np.stack([np.cov(p.T, bias=True) for p in sets])
    w, valid = ols_from_covariance(cov, axis)
    assert valid.all()
    for k, p in enumerate(sets):
        q = p - p.mean(axis=0)
        A = np.column_stack([np.ones(len(q)), q[:, u], q[:, v]])
        coef, *_ = np.linalg.lstsq(A, q[:, a], rcond=None)
        np.testing.assert_allclose(q @ w[k], q[:, a] - A @ coef, atol=1e-12)


# ----------------------------------------------------------------------------- signed distance


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
