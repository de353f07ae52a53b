"""Orientation of planes and lines, and the Schmidt net, against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rough_viewer.grid.orientation import (
    cell_orientation,
    cell_stereonet,
    dip_and_direction,
    dip_strike_axes,
    kernel_density,
    kernel_peak,
    line_vectors,
    orient_normals,
    plane_normals,
    poles,
    schmidt,
    schmidt_inverse,
    stereonet,
    trend_and_plunge,
)
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.vocabulary import InputError
from tests.helpers import banded_face, face_axes

RNG = np.random.default_rng(7)
DIPS = RNG.uniform(0.5, 89.5, 40)
DIRECTIONS = RNG.uniform(0.0, 360.0, 40)


def test_dip_and_direction_of_known_planes_either_normal_sign():
    normals = np.array([face_axes(d, a)[2] for d, a in zip(DIPS, DIRECTIONS, strict=True)])
    for sign in (1.0, -1.0):
        dip, dd = dip_and_direction(sign * normals * 3.0)  # any length, either sense
        np.testing.assert_allclose(dip, DIPS, atol=1e-9)
        np.testing.assert_allclose(dd, DIRECTIONS, atol=1e-9)


def test_horizontal_and_vertical_planes():
    dip, dd = dip_and_direction(np.array([[0.0, 0.0, -2.0], [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0],
                                          [np.nan, 0.0, 1.0]]), toward=[1.0, 0.2, 0.0])
    assert dip[0] == 0.0 and dd[0] == 0.0
    # vertical planes: dip 90; the dip direction is the side of ``toward`` (east)
    np.testing.assert_allclose(dip[1:3], 90.0)
    np.testing.assert_allclose(dd[1:3], 90.0)
    assert np.isnan(dip[3]) and np.isnan(dd[3])
    n = orient_normals(np.array([[0.0, -1.0, 0.0]]), toward=[0.0, -1.0, 0.0])
    np.testing.assert_array_equal(n, [[0.0, -1.0, 0.0]])


def test_trend_and_plunge_closed_form():
    trend = RNG.uniform(0, 360, 50)
    plunge = RNG.uniform(0.1, 89.9, 50)
    t = np.radians(trend)
    p = np.radians(plunge)
    down = np.column_stack([np.cos(p) * np.sin(t), np.cos(p) * np.cos(t), -np.sin(p)])
    for v in (down, -down):  # either sense of the line
        tr, pl = trend_and_plunge(v)
        np.testing.assert_allclose(pl, plunge, atol=1e-9)
        np.testing.assert_allclose(tr, trend, atol=1e-9)
    np.testing.assert_allclose(line_vectors(trend, plunge), down, atol=1e-12)
    # horizontal lines: trend in [0, 180)
    tr, pl = trend_and_plunge(np.array([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [1.0, 1.0, 0.0]]))
    np.testing.assert_allclose(tr, [90.0, 0.0, 45.0])
    np.testing.assert_allclose(pl, 0.0)


def test_poles_are_the_downward_normals():
    normals = np.array([face_axes(d, a)[2] for d, a in zip(DIPS, DIRECTIONS, strict=True)])
    trend, plunge = poles(normals)
    tr2, pl2 = trend_and_plunge(-normals)  # the downward normal as a line
    np.testing.assert_allclose(plunge, pl2, atol=1e-9)
    np.testing.assert_allclose(np.cos(np.radians(trend - tr2)), 1.0, atol=1e-12)
    np.testing.assert_allclose(plunge, 90.0 - DIPS, atol=1e-9)


def test_schmidt_projection_of_known_poles_against_the_equal_area_formula():
    normals = np.array([face_axes(d, a)[2] for d, a in zip(DIPS, DIRECTIONS, strict=True)])
    net = stereonet(normals)
    # pole of a plane (dip d, direction a): trend a + 180, plunge 90 - d, so
    # r = sqrt(2) sin(d / 2) (equal area, radius 1), pointing away from the dip direction
    r = math.sqrt(2.0) * np.sin(np.radians(DIPS) / 2.0)
    a = np.radians(DIRECTIONS)
    np.testing.assert_allclose(net.x, -r * np.sin(a), atol=1e-12)
    np.testing.assert_allclose(net.y, -r * np.cos(a), atol=1e-12)
    # equal area: a cap of half-angle d round the downward vertical has solid angle
    # 2 pi (1 - cos d); the hemisphere (2 pi) maps onto the unit disc (pi), so the cap
    # maps onto a disc of area pi (1 - cos d): r^2 = 1 - cos d
    np.testing.assert_allclose(r**2, 1.0 - np.cos(np.radians(DIPS)), atol=1e-12)
    # and back
    back = schmidt_inverse(net.x, net.y)
    np.testing.assert_allclose(back, -normals, atol=1e-12)


def test_uniform_directions_fill_the_net_evenly():
    v = RNG.standard_normal((200_000, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    tr, pl = trend_and_plunge(v)
    x, y = schmidt(tr, pl)
    r = np.hypot(x, y)
    for radius in (0.3, 0.5, 0.7, 0.9):
        assert abs(np.mean(r <= radius) - radius**2) < 0.005
    net = stereonet(v, smoothing_deg=8.0)
    inside = np.isfinite(net.density)
    # multiples of a uniform distribution: ~1 everywhere for uniform poles
    assert abs(np.mean(net.density[inside]) - 1.0) < 0.03
    assert np.percentile(net.density[inside], 95) < 1.15


def test_density_peak_of_one_cluster():
    n = face_axes(40.0, 130.0)[2]
    net = stereonet(np.tile(n, (30, 1)), smoothing_deg=5.0, nodes=101)
    row, col = np.unravel_index(np.nanargmax(net.density), net.density.shape)
    px, py = schmidt(*poles(n[None]))
    # within one node spacing (0.02): the net stretches angles differently along and
    # across the radius, so the nearest node in angle need not be the nearest on paper
    assert abs(net.nodes[col] - px[0]) <= 0.02 and abs(net.nodes[row] - py[0]) <= 0.02
    # at the pole itself the density is the kernel's peak; at the best node, within
    # about 0.02 of it on paper (about 1.6 degrees), it has fallen by at most
    # exp(-kappa (1 - cos 1.6 deg))
    kappa = 1.0 / math.radians(5.0) ** 2
    assert net.density[row, col] <= kernel_peak(5.0) * (1 + 1e-9)
    assert net.density[row, col] >= kernel_peak(5.0) * math.exp(
        -kappa * (1 - math.cos(math.radians(1.6))))
    assert kernel_peak(5.0) == pytest.approx(kappa / (1 - math.exp(-kappa)))
    # outside the primitive circle there is no density
    assert np.isnan(net.density[0, 0])


def test_stereonet_skips_missing_normals_and_rejects_bad_options():
    normals = np.array([[0.0, 0.0, 1.0], [np.nan] * 3, [0.0, 1.0, 1.0]])
    net = stereonet(normals)
    np.testing.assert_array_equal(net.rows, [0, 2])
    assert stereonet(np.zeros((0, 3))).n_poles == 0
    with pytest.raises(InputError):
        stereonet(normals, smoothing_deg=0.0)
    with pytest.raises(InputError):
        stereonet(normals, nodes=2)


def test_cell_orientation_of_a_tilted_face():
    pts, _ = banded_face(35.0, 220.0, [], n=60_000, size=(4.0, 4.0))
    res = grid_roughness(pts, 0.5, min_points=50)  # corner cells with few points are not
    dip, dd = cell_orientation(res)
    ok = np.isfinite(dip)
    assert ok.sum() > 40
    np.testing.assert_allclose(dip[ok], 35.0, atol=1.0)  # 1 mm noise, slivers
    np.testing.assert_allclose(dd[ok], 220.0, atol=1.0)
    assert np.median(np.abs(dip[ok] - 35.0)) < 0.05
    net = cell_stereonet(res, np.flatnonzero(ok)[:10])
    np.testing.assert_array_equal(net.rows, np.flatnonzero(ok)[:10])
    px, py = schmidt(np.array([40.0]), np.array([55.0]))  # the pole: 220 - 180, 90 - 35
    np.testing.assert_allclose(net.x, px[0], atol=0.01)
    np.testing.assert_allclose(net.y, py[0], atol=0.01)


def test_weights_count_as_repeated_poles():
    rng = np.random.default_rng(3)
    n = rng.normal(size=(200, 3))
    k = rng.integers(1, 5, 200)
    weighted = stereonet(n, weights=k.astype(float), nodes=31)
    repeated = stereonet(np.repeat(n, k, axis=0), nodes=31)
    assert np.allclose(weighted.density, repeated.density, equal_nan=True)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    p = n / np.linalg.norm(n, axis=1, keepdims=True)
    assert np.allclose(kernel_density(d, p, k.astype(float)),
                       kernel_density(d, np.repeat(p, k, axis=0)))
    with pytest.raises(ValueError, match="weights") as bug:  # the caller's, not the user's
        stereonet(n, weights=np.ones(3))
    assert type(bug.value) is ValueError


def test_plane_normals_invert_dip_and_direction():
    rng = np.random.default_rng(4)
    dip = rng.uniform(1.0, 89.0, 100)
    dd = rng.uniform(0.0, 360.0, 100)
    n = plane_normals(dip, dd)
    assert np.all(n[:, 2] > 0)
    back_dip, back_dd = dip_and_direction(n)
    assert back_dip == pytest.approx(dip)
    assert back_dd == pytest.approx(dd)
    down, strike = dip_strike_axes(-n)  # either sign of the normal
    assert np.einsum("ij,ij->i", down, n) == pytest.approx(0.0, abs=1e-12)
    assert np.cross(down, strike) == pytest.approx(n)
    trend, plunge = trend_and_plunge(down)
    assert trend == pytest.approx(dd) and plunge == pytest.approx(dip)
    assert strike[:, 2] == pytest.approx(0.0, abs=1e-12)
    az = np.degrees(np.arctan2(strike[:, 0], strike[:, 1])) % 360.0
    assert (az - dd + 90.0 + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-9)  # RHR
