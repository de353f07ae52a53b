"""Per-cell scanner geometry: range, incidence, density ratio, occlusion, scans."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.scanner.geometry import plane_cut_area, points_extent_area, scan_geometry
from rough_viewer.synthetic.board import PAPER_ROTATIONS_DEG, board_scan
from rough_viewer.vocabulary import InputError
from tests.helpers import ray_grid, scan_plane

STEP = 1.0e-3  # angular step of the synthetic scans, radians

# a plane tilted 30 degrees about x and 20 about z, 12 m from the scanner
SCANNER = np.array([1.0, -2.0, 1.5])
TILT = np.radians([30.0, 20.0])
NORMAL = np.array([np.sin(TILT[1]) * np.cos(TILT[0]), -np.cos(TILT[1]) * np.cos(TILT[0]),
                   np.sin(TILT[0])])
CENTRE = np.array([3.0, 10.0, 2.5])


def tilted_scan(noise: float):
    rays = ray_grid(SCANNER, CENTRE, 0.12)
    pts = scan_plane(SCANNER, CENTRE, NORMAL, rays, extent=1.2, noise=noise)
    res = grid_roughness(pts, 0.4, models=("odr",))
    return pts, res, scan_geometry(pts, res, SCANNER[None, :], angular_step_rad=STEP)


@pytest.fixture(scope="module")
def tilted():
    return tilted_scan(0.001)


@pytest.mark.parametrize("noise", [0.0, 0.001])
def test_tilted_plane_range_and_incidence_equal_the_geometry(noise):
    """Every cell of a plane tilted 30 and 20 degrees, scanned from a known position:
    range to its centroid and incidence against the plane's normal (brute force, one
    cell at a time) within 1 mm and 0.1 degree; with 1 mm of range noise, every cell
    of at least 100 points."""
    pts, res, geo = tilted_scan(noise)
    ok = np.isfinite(res.theta_odr) & (res.n_points >= (100 if noise else 4))
    assert ok.sum() > 30
    for row in np.flatnonzero(ok):  # brute force, one cell at a time
        cell = pts[res.point_cell == row]
        c = cell.mean(axis=0)
        r = np.linalg.norm(c - SCANNER)
        inc = np.degrees(np.arccos(abs(NORMAL @ (c - SCANNER)) / r))
        assert geo.range_m[row] == pytest.approx(r, abs=1e-3)
        assert geo.incidence_deg[row] == pytest.approx(inc, abs=0.1)
    assert np.all(geo.scans[ok] == 1)
    # the incidences span the face
    assert np.ptp(geo.incidence_deg[ok]) > 5.0


def test_tilted_plane_density_follows_n0_cos_over_r2(tilted):
    pts, res, geo = tilted
    full = np.isfinite(geo.density_ratio) & (res.n_points > 100)
    # cells the face crosses whole: one point per ray, the ratio is 1 (Poisson-free)
    assert np.median(geo.density_ratio[full]) == pytest.approx(1.0, abs=0.01)
    assert np.sum(res.n_points[full]) / np.sum(geo.expected_points[full]) == pytest.approx(
        1.0, abs=0.01)
    # N0 fitted (no angular step) recovers 1 / step^2 within 1 %
    fitted = scan_geometry(pts, res, SCANNER[None, :])
    assert fitted.n0_source == "fitted" and geo.n0_source == "angular step"
    assert fitted.n0[0] == pytest.approx(1.0 / STEP**2, rel=0.01)
    # a plane seen evenly has no occlusion
    assert np.nanmedian(geo.occlusion[full]) < 0.03


def test_occlusion_behind_a_protrusion():
    """A block standing 1 m proud of a wall shadows the wall beside it, away from the
    scanner: the cell the shadow's edge crosses lacks points against its neighbour
    along the beam, by the share of it in the shadow."""
    scanner = np.array([0.0, 0.0, 1.0])
    wall = np.array([3.0, 8.0, 1.0])
    normal = np.array([0.0, -1.0, 0.0])
    rays = ray_grid(scanner, wall, 0.2, step=1e-3)
    t = ((wall - scanner) @ normal) / (rays @ normal)
    # block x in [2.0, 2.4], y in [7.0, 8.0]: rays meet its front face y = 7 or its
    # side x = 2 (the side x = 2.4 faces away from the scanner)
    t_front = (7.0 - scanner[1]) / rays[:, 1]
    x_front = scanner[0] + t_front * rays[:, 0]
    t_side = (2.0 - scanner[0]) / rays[:, 0]
    y_side = scanner[1] + t_side * rays[:, 1]
    front = (x_front >= 2.0) & (x_front <= 2.4)
    side = ~front & (y_side > 7.0) & (y_side < 8.0) & (t_side > 0)
    t = np.where(front, t_front, np.where(side, t_side, t))
    pts = scanner + t[:, None] * rays
    pts = pts[np.abs(pts[:, 0] - 3.0) < 1.5]
    res = grid_roughness(pts, 0.1, origin=(1.5, 6.95, -1.05), models=("odr",))
    geo = scan_geometry(pts, res, scanner[None, :], angular_step_rad=1e-3)
    on_wall = np.isfinite(geo.occlusion) & (np.abs(res.centroid[:, 1] - 8.0) < 0.01) \
        & (np.abs(res.centroid[:, 2] - 1.0) < 0.3)
    x = res.centre[:, 0]
    # the shadow on the wall runs from x = 2.4 to 2.4 * 8 / 7 = 2.743 m: the cell
    # [2.7, 2.8] is 43 % in it, [2.8, 2.9] clear
    edge = on_wall & np.isclose(x, 2.75)
    clear = on_wall & (x > 2.8)
    assert edge.sum() >= 4 and clear.sum() > 20
    np.testing.assert_allclose(geo.occlusion[edge], (2.4 * 8 / 7 - 2.7) / 0.1, atol=0.05)
    # clear cells: only the lattice's whole columns of points per cell (11 or 12 here)
    assert np.median(geo.occlusion[clear]) < 0.05 and np.max(geo.occlusion[clear]) < 0.15
    # where the scanner saw the cell, it saw it as densely as anywhere
    np.testing.assert_allclose(geo.density_ratio[edge], 1.0, atol=0.1)


def test_two_scanners_are_weighted_by_their_points():
    rays_a = ray_grid(np.array([-3.0, 0.0, 0.0]), np.array([0.0, 10.0, 0.0]), 0.15)
    rays_b = ray_grid(np.array([3.0, 0.0, 0.0]), np.array([0.0, 10.0, 0.0]), 0.15, step=2e-3)
    n = np.array([0.0, -1.0, 0.0])
    pa = scan_plane(np.array([-3.0, 0.0, 0.0]), np.array([0.0, 10.0, 0.0]), n, rays_a, extent=1.0)
    pb = scan_plane(np.array([3.0, 0.0, 0.0]), np.array([0.0, 10.0, 0.0]), n, rays_b, extent=1.0)
    pts = np.vstack([pa, pb])
    scan = np.r_[np.zeros(len(pa), int), np.ones(len(pb), int)]
    positions = np.array([[-3.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    res = grid_roughness(pts, 0.5, origin=(-1.0, 9.5, -1.0), models=("odr",))
    geo = scan_geometry(pts, res, positions, scan)
    ok = np.isfinite(res.theta_odr)
    assert np.all(geo.scans[ok] == 2)
    for row in np.flatnonzero(ok):
        c = pts[res.point_cell == row].mean(axis=0)
        k = np.bincount(scan[res.point_cell == row], minlength=2)
        r = np.linalg.norm(c - positions, axis=1)
        inc = np.degrees(np.arccos(np.abs((c - positions) @ n) / r))
        assert geo.range_m[row] == pytest.approx(k @ r / k.sum(), abs=1e-9)
        assert geo.incidence_deg[row] == pytest.approx(k @ inc / k.sum(), abs=1e-6)
    # scan b steps twice as coarsely: its fitted N0 is a quarter of a's
    assert geo.n0[1] / geo.n0[0] == pytest.approx(0.25, rel=0.03)
    assert np.nanmedian(geo.density_ratio[ok]) == pytest.approx(1.0, abs=0.02)


@pytest.mark.parametrize("alpha", PAPER_ROTATIONS_DEG)
@pytest.mark.parametrize("beta", PAPER_ROTATIONS_DEG)
def test_board_rotations_give_the_expected_incidence_and_density(alpha, beta):
    """The 2012 board at its 25 rotations: every cell's incidence is the angle between
    the beam and the board's own normal (hemispheres tilt a cell's plane a little),
    and the points follow N0 cos(i) / r^2 (the paper's N0 cos(alpha) cos(beta))."""
    scan = board_scan(alpha, beta, spacing=0.005)  # the 2012 geometry, fewer rays
    res = grid_roughness(scan.cloud, 0.2, models=("odr",))
    geo = scan_geometry(scan.cloud, res, scan.scanner[None, :],
                        angular_step_rad=scan.angular_step_rad)
    ok = np.isfinite(geo.density_ratio)
    assert ok.sum() >= 25
    v = res.centroid[ok] - scan.scanner
    expected = np.degrees(np.arccos(np.abs(v @ scan.normal) / np.linalg.norm(v, axis=1)))
    w = res.n_points[ok]
    assert np.median(geo.incidence_deg[ok] - expected) == pytest.approx(0.0, abs=0.5)
    assert np.average(geo.incidence_deg[ok], weights=w) == pytest.approx(
        np.average(expected, weights=w), abs=1.0)
    # the board centre is seen at arccos(cos alpha cos beta)
    centre = np.argmin(np.linalg.norm(res.centroid[ok] - scan.centre, axis=1))
    cc = np.cos(np.radians(alpha)) * np.cos(np.radians(beta))
    assert expected[centre] == pytest.approx(np.degrees(np.arccos(cc)), abs=2.5)
    assert np.median(geo.density_ratio[ok]) == pytest.approx(1.0, abs=0.04)
    assert w.sum() / geo.expected_points[ok].sum() == pytest.approx(1.0, abs=0.035)
    assert np.all(geo.scans[ok] == 1)


def test_plane_cut_area_equals_monte_carlo():
    rng = np.random.default_rng(5)
    n = rng.normal(size=(4, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    p = rng.uniform(0.2, 0.8, (4, 3))
    area = plane_cut_area(n, p, np.zeros((4, 3)), 1.0)
    x = rng.uniform(0.0, 1.0, (2_000_000, 3))
    h = 4e-3
    for k in range(4):  # the area is the volume of a thin slab over its thickness
        slab = np.count_nonzero(np.abs((x - p[k]) @ n[k]) < h / 2) / x.shape[0] / h
        assert area[k] == pytest.approx(slab, rel=0.03)
    # a plane on a face of the cube, and one that misses it
    face = plane_cut_area(np.array([[0.0, 0.0, 1.0]] * 2), np.array([[0.5, 0.5, 0.0],
                                                                     [0.5, 0.5, 3.0]]),
                          np.zeros((2, 3)), 2.0)
    assert face.tolist() == [pytest.approx(4.0), 0.0]


def test_points_extent_area_of_a_lattice_is_exact():
    """k x k points on a lattice of spacing s cover k^2 s^2 (Sheppard's correction)."""
    for k in (4, 10, 40):
        g = (np.arange(k) + 0.5) * 0.01
        u, v = np.meshgrid(g, g)
        pts = np.column_stack([u.ravel(), v.ravel(), np.zeros(k * k)])
        lam = np.linalg.eigvalsh(np.cov(pts.T, bias=True))[::-1][None, :]
        area = points_extent_area(lam, np.array([k * k]))[0]
        assert area == pytest.approx((k * 0.01) ** 2, rel=1e-9)


def test_refuses_what_it_cannot_use(tilted):
    pts, res, _ = tilted
    with pytest.raises(ValueError, match="point scans") as bug:  # the caller's, not the user's
        scan_geometry(pts, res, np.zeros((2, 3)), np.full(len(pts), 2))
    assert type(bug.value) is ValueError
    with pytest.raises(InputError, match="needs the points"):
        scan_geometry(pts[:-1], res, np.zeros((1, 3)))
    with pytest.raises(InputError, match="angular step"):
        scan_geometry(pts, res, np.zeros((1, 3)), angular_step_rad=0.0)
