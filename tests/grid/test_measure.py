"""Measure: distances against the closed form; the dip and dip direction of planted
planes within 0.5 degrees, from a selected region and from the cells' planes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rough_viewer.grid.measure import plane_orientation, point_distance, region_plane
from rough_viewer.grid.orientation import cell_orientation
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.lod.camera import ViewCamera, screen_rect_mask
from rough_viewer.vocabulary import InputError
from tests.helpers import UTM


def planted(dip_deg: float, dd_deg: float, n: int, *, noise: float, seed: int,
            size: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Points on a plane of the given dip and dip direction (upward normal
    (sin d sin a, sin d cos a, cos d)), with Gaussian noise along the normal."""
    d, a = math.radians(dip_deg), math.radians(dd_deg)
    normal = np.array([math.sin(d) * math.sin(a), math.sin(d) * math.cos(a), math.cos(d)])
    u = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    rng = np.random.default_rng(seed)
    st = rng.uniform(-size / 2, size / 2, (n, 2))
    xyz = st[:, :1] * u + st[:, 1:] * v + rng.normal(0, noise, (n, 1)) * normal
    return xyz + UTM, normal


def angle_between(dip1, dd1, dip2, dd2) -> float:
    """Degrees between the upward normals of two planes."""
    def n(dip, dd):
        d, a = math.radians(dip), math.radians(dd)
        return np.array([math.sin(d) * math.sin(a), math.sin(d) * math.cos(a), math.cos(d)])
    return math.degrees(math.acos(min(1.0, float(n(dip1, dd1) @ n(dip2, dd2)))))


def test_distance_matches_the_closed_form():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a, b = rng.uniform(-50, 50, 3) + UTM, rng.uniform(-50, 50, 3) + UTM
        d = point_distance(a, b)
        dx, dy, dz = b - a
        assert d.distance_m == pytest.approx(math.sqrt(dx * dx + dy * dy + dz * dz), rel=1e-12)
        assert d.horizontal_m == pytest.approx(math.hypot(dx, dy), rel=1e-12)
        assert d.vertical_m == pytest.approx(dz, rel=1e-12)
        assert d.plunge_deg == pytest.approx(math.degrees(math.atan2(abs(dz), math.hypot(dx, dy))))
        down = (b - a) if dz < 0 else (a - b)  # trend: azimuth of the downward direction
        assert d.trend_deg == pytest.approx(math.degrees(math.atan2(down[0], down[1])) % 360)
    flat = point_distance((0, 0, 0), (-1, -1, 0))
    assert flat.trend_deg == pytest.approx(45.0) and flat.plunge_deg == 0.0
    assert math.isnan(point_distance((1, 2, 3), (1, 2, 3)).trend_deg)


@pytest.mark.parametrize("dip, dd", [(35.0, 120.0), (5.0, 300.0), (62.0, 10.0), (88.0, 215.0),
                                     (0.0, 0.0)])
def test_region_plane_of_a_planted_plane_within_half_a_degree(dip, dd):
    xyz, _ = planted(dip, dd, 4_000, noise=0.003, seed=int(dip + dd))
    m = region_plane(xyz)
    assert angle_between(m.dip_deg, m.dip_direction_deg, dip, dd) < 0.5
    assert abs(m.dip_deg - dip) < 0.5
    if dip >= 5:  # the azimuth of a nearly flat plane is poorly defined; its normal is not
        assert abs((m.dip_direction_deg - dd + 180) % 360 - 180) < 0.5
    assert m.rms_m == pytest.approx(0.003, rel=0.05)  # the planted noise
    assert m.n_points == 4_000 and m.normal[2] >= 0
    assert np.allclose(m.centroid, xyz.mean(axis=0), atol=1e-6)


def test_vertical_plane_takes_the_viewers_side():
    xyz, normal = planted(90.0, 30.0, 2_000, noise=0.0, seed=1)
    toward = np.array([math.sin(math.radians(30)), math.cos(math.radians(30)), 0.0])
    m = region_plane(xyz, toward=toward)
    assert m.dip_deg == pytest.approx(90.0, abs=1e-6)
    assert m.dip_direction_deg == pytest.approx(30.0, abs=1e-6)
    other = region_plane(xyz, toward=-toward)
    assert other.dip_direction_deg == pytest.approx(210.0, abs=1e-6)
    assert m.rms_m < 1e-9
    assert plane_orientation(-normal, toward) == pytest.approx((90.0, 30.0), abs=1e-6)


def test_region_selected_on_screen_ignores_the_rest():
    """A planted plane beside a steeper one: the points picked by a screen rectangle
    give the first plane's orientation."""
    a, _ = planted(40.0, 180.0, 3_000, noise=0.002, seed=2)
    b, _ = planted(75.0, 90.0, 3_000, noise=0.002, seed=3)
    b += [10.0, 0.0, 0.0]
    both = np.vstack([a, b])
    cam = ViewCamera.looking_at(UTM + [5.0, -30.0, 5.0], UTM + [5.0, 0.0, 0.0], aspect=1.5)
    u, _, _ = cam.project(UTM[None] + [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    mid = float(u.mean()) / cam.width_px
    pick = screen_rect_mask(cam, both, (0.0, 0.0), (mid, 1.0))
    assert pick[:3_000].all() and not pick[3_000:].any()
    m = region_plane(both, pick)
    assert angle_between(m.dip_deg, m.dip_direction_deg, 40.0, 180.0) < 0.5


def test_cells_of_a_planted_plane_have_its_dip_and_dip_direction():
    """The cell report's dip and dip direction (every cell's ODR plane): cells the
    plane crosses fully (a sliver across a corner fits a tiny patch, less well)."""
    xyz, _ = planted(35.0, 120.0, 40_000, noise=0.002, seed=4, size=4.0)
    result = grid_roughness(xyz, 0.5)
    dip, dd = cell_orientation(result)
    full = result.n_points >= 500
    assert full.sum() > 20
    assert np.all(np.abs(dip[full] - 35.0) < 0.5)
    assert np.all(np.abs((dd[full] - 120.0 + 180) % 360 - 180) < 0.5)
    valued = np.isfinite(dip) & (result.n_points >= 200)
    assert max(angle_between(a, b, 35.0, 120.0) for a, b in zip(dip[valued], dd[valued],
                                                                  strict=True)) < 0.5


def test_too_few_or_collinear_points_are_refused():
    with pytest.raises(InputError, match="at least 3 selected points, got 2"):
        region_plane(np.zeros((5, 3)) + UTM, np.array([True, True, False, False, False]))
    line = np.column_stack([np.linspace(0, 1, 10)] * 3) + UTM
    with pytest.raises(InputError, match="lie on a line"):
        region_plane(line)
    with pytest.raises(InputError, match="two points"):
        point_distance((0, 0), (1, 1, 1))
