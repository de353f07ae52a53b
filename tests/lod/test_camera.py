"""The camera: viser's conventions, the projection, rectangle selection and the
reselection test."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rough_viewer.lod.camera import (
    ViewCamera,
    camera_moved,
    rotation_from_wxyz,
    screen_rect_mask,
    wxyz_from_rotation,
)
from rough_viewer.vocabulary import InputError


def test_rotation_matches_scipy_both_ways():
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        w, x, y, z = q
        ref = Rotation.from_quat([x, y, z, w]).as_matrix()
        assert np.allclose(rotation_from_wxyz(q), ref, atol=1e-12)
        back = wxyz_from_rotation(ref)
        assert np.allclose(back, q if w >= 0 else -q, atol=1e-12)


def test_viser_camera_maps_with_the_local_origin():
    """viser: wxyz is R_world_camera with +z forward, -y up; position is in the
    scene's (local) frame."""
    origin = np.array([512_000.0, 4_170_000.0, 100.0])
    look = ViewCamera.looking_at([2.0, -5.0, 1.0], [2.0, 0.0, 1.0])
    fake = SimpleNamespace(position=look.position, wxyz=look.wxyz, fov=look.fov_rad,
                           aspect=1.5, image_height=720)
    cam = ViewCamera.from_viser(fake, origin)
    assert np.allclose(cam.position, origin + [2.0, -5.0, 1.0])
    r = cam.rotation
    assert np.allclose(r[:, 2], [0, 1, 0]) and np.allclose(-r[:, 1], [0, 0, 1])
    assert cam.height_px == 720 and cam.width_px == 1080
    u, v, d = cam.project(origin + np.array([[2.0, 0.0, 1.0], [2.0, -10.0, 1.0]]))
    assert np.allclose([u[0], v[0], d[0]], [540.0, 360.0, 5.0]) and np.isnan(u[1])


def test_screen_rectangle_selects_what_projects_inside():
    cam = ViewCamera.looking_at([0.0, -10.0, 0.0], [0.0, 0.0, 0.0], aspect=1.0, height_px=1000)
    g = np.linspace(-3, 3, 61) + 0.05  # no point on the rectangle's edges
    xs, zs = np.meshgrid(g, g)
    pts = np.column_stack([xs.ravel(), np.zeros(xs.size), zs.ravel()])
    behind = pts * [1, 0, 1] + [0, -20, 0]
    mask = screen_rect_mask(cam, np.vstack([pts, behind]), (0.5, 0.5), (1.0, 0.0))
    f = 500 / math.tan(math.radians(25))
    half = 500 / f * 10  # metres at 10 m that reach the window's edge
    want = (pts[:, 0] >= 0) & (pts[:, 0] <= half) & (pts[:, 2] >= 0) & (pts[:, 2] <= half)
    assert np.array_equal(mask[: len(pts)], want) and not mask[len(pts):].any()


def test_camera_moved_counts_pixels():
    cam = ViewCamera.looking_at([0.0, -10.0, 0.0], [0.0, 0.0, 0.0], height_px=1000)
    f = cam.focal_px
    same = ViewCamera(cam.position.copy(), cam.wxyz.copy(), cam.fov_rad, cam.aspect, 1000)
    assert not camera_moved(cam, same, distance_m=10.0)
    step = 3.0 * 10.0 / f  # 3 pixels at 10 m
    moved = ViewCamera(cam.position + [step, 0, 0], cam.wxyz, cam.fov_rad, cam.aspect, 1000)
    assert camera_moved(cam, moved, distance_m=10.0)
    assert not camera_moved(cam, moved, distance_m=20.0)  # 1.5 pixels farther away
    turn = Rotation.from_rotvec([0, 0, 3.0 / f]).as_matrix() @ cam.rotation
    turned = ViewCamera(cam.position, wxyz_from_rotation(turn), cam.fov_rad, cam.aspect, 1000)
    assert camera_moved(cam, turned, distance_m=10.0)
    assert not camera_moved(cam, turned, distance_m=10.0, tolerance_px=4.0)
    zoomed = ViewCamera(cam.position, cam.wxyz, cam.fov_rad * 0.99, cam.aspect, 1000)
    assert camera_moved(cam, zoomed, distance_m=10.0)
    resized = ViewCamera(cam.position, cam.wxyz, cam.fov_rad, cam.aspect, 999)
    assert camera_moved(cam, resized, distance_m=10.0)


def test_bad_cameras_are_refused():
    with pytest.raises(InputError, match="field of view"):
        ViewCamera(np.zeros(3), np.array([1.0, 0, 0, 0]), 0.0, 1.0, 100)
    with pytest.raises(InputError, match="quaternion"):
        ViewCamera(np.zeros(3), np.zeros(4), 1.0, 1.0, 100)
    with pytest.raises(InputError, match="position"):
        ViewCamera(np.array([np.nan, 0, 0]), np.array([1.0, 0, 0, 0]), 1.0, 1.0, 100)
    with pytest.raises(InputError, match="own position"):
        ViewCamera.looking_at([1, 1, 1], [1, 1, 1])
