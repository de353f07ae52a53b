"""Synthetic scans: the 2012 hemisphere board and the generator of the demo outcrop."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.synthetic import (
    PAPER_ROTATIONS_DEG,
    PAPER_THEORETICAL_ROUGHNESS_M,
    board_scan,
    board_theoretical_roughness,
    hemisphere_board,
    hemisphere_roughness,
)
from rough_viewer.synthetic.outcrop import (
    FACE_BEND,
    FACE_CURVE,
    FACE_MAIN,
    OUTCROP_SMALL,
    TRUTH_ROCK,
    face_part,
    face_trace,
    generate_outcrop,
    outcrop_relief,
)

# ----------------------------------------------------------------------------- board


def test_closed_form_roughness_reproduces_the_papers_monte_carlo_value():
    # 2012 paper: 132 hemispheres, r = 0.019 m, 1 m^2 board -> 3.60756e-3 m (Monte Carlo,
    # converged to 1e-9 m). SCIENCE.md: the signed variant gives about 4.84e-3 m.
    theta = hemisphere_roughness(132, 0.019, 1.0)
    assert theta == pytest.approx(PAPER_THEORETICAL_ROUGHNESS_M, abs=5e-8)
    assert hemisphere_roughness(132, 0.019, 1.0, residual="signed") == pytest.approx(
        4.84e-3, abs=5e-6
    )


def test_closed_form_roughness_matches_a_dense_raster_of_the_board():
    # Independent reference: sample the board on a 1 mm raster, z = sqrt(r^2 - d^2)
    # around the nearest occupied node, std of |z - mean z| (raster error ~4e-4).
    board = hemisphere_board()
    step = 0.001
    c = np.arange(-0.5 + step / 2, 0.5, step)
    u, v = np.meshgrid(c, c, indexing="ij")
    g = board.node_spacing_m
    i = np.rint((u + 0.5) / g).astype(int)
    j = np.rint((v + 0.5) / g).astype(int)
    occ = np.zeros((21, 21), dtype=bool)
    occ[board.node_ij[:, 0], board.node_ij[:, 1]] = True
    d2 = (u - (-0.5 + i * g)) ** 2 + (v - (-0.5 + j * g)) ** 2
    r = board.radius_m
    z = np.where(occ[i, j] & (d2 < r * r), np.sqrt(np.maximum(r * r - d2, 0.0)), 0.0)
    theta_raster = np.abs(z - z.mean()).std()
    assert board_theoretical_roughness(board) == pytest.approx(theta_raster, rel=1e-3)


def test_board_layout_is_the_papers_and_deterministic():
    b = hemisphere_board()
    assert b.n_spheres == 132
    assert len({tuple(ij) for ij in b.node_ij.tolist()}) == 132  # distinct nodes
    # interior nodes only: every hemisphere lies wholly on the board
    assert np.all(np.abs(b.centres_uv) + b.radius_m <= 0.5)
    assert np.array_equal(hemisphere_board().node_ij, b.node_ij)
    assert not np.array_equal(hemisphere_board(seed=1).node_ij, b.node_ij)


def _brute_force_range(scan, dirs: np.ndarray) -> np.ndarray:
    """Nearest hit of each ray with the board square and all 132 spheres (no culling)."""
    s, c, ax = scan.scanner, scan.centre, scan.axes
    eu, ev, ew = ax[:, 0], ax[:, 1], ax[:, 2]
    t_plane = ((c - s) @ ew) / (dirs @ ew)
    hit = s + t_plane[:, None] * dirs - c
    inside = (np.abs(hit @ eu) <= 0.5) & (np.abs(hit @ ev) <= 0.5)
    best = np.where(inside, t_plane, np.inf)
    b = scan.board
    centres = c + b.centres_uv[:, :1] * eu + b.centres_uv[:, 1:] * ev  # (K, 3)
    oc = s - centres  # (K, 3)
    bq = dirs @ oc.T  # (M, K)
    cq = np.sum(oc * oc, axis=1) - b.radius_m**2
    disc = bq * bq - cq
    t = -bq - np.sqrt(np.where(disc >= 0, disc, 0.0))
    pts = s + t[..., None] * dirs[:, None, :]
    front = (pts - c) @ ew >= 0
    t = np.where((disc >= 0) & front, t, np.inf)
    return np.minimum(best, t.min(axis=1))


def test_board_scan_matches_brute_force_ray_casting():
    scan = board_scan(33.75, 22.5, spacing=0.004)
    xyz = scan.cloud.xyz()
    rel = xyz - scan.scanner
    rng_m = np.linalg.norm(rel, axis=1)
    pick = np.random.default_rng(0).choice(xyz.shape[0], 3000, replace=False)
    ref = _brute_force_range(scan, rel[pick] / rng_m[pick, None])
    np.testing.assert_allclose(rng_m[pick], ref, atol=1e-9)


def test_board_scan_at_zero_rotation_gives_the_theoretical_roughness():
    scan = board_scan(0.0, 0.0)
    r = grid_roughness(scan.cloud, 5.0, axis="y")  # one cell: the whole board
    assert r.n_cells == 1
    # 2 mm rays from 4.5 m sample the board like the paper's Monte Carlo: within 0.5 %.
    assert r.theta_odr[0] == pytest.approx(scan.theoretical_roughness, rel=5e-3)
    assert r.theta_ols[0] == pytest.approx(r.theta_odr[0], rel=1e-3)
    assert r.theta_hybrid[0] == pytest.approx(r.theta_odr[0], rel=1e-3)


def test_board_rotations_reproduce_the_2012_findings():
    # The whole board is one cell, dependent axis y (normal of the baseline orientation),
    # as in the paper. 5 mm spacing keeps the 25 scans fast; the geometry is the same.
    rows = {}
    for a in PAPER_ROTATIONS_DEG:
        for b in PAPER_ROTATIONS_DEG:
            scan = board_scan(a, b, spacing=0.005)
            r = grid_roughness(scan.cloud, 5.0, axis="y")
            assert r.n_cells == 1
            rows[a, b] = (r.theta_odr[0], r.theta_ols[0], r.theta_hybrid[0], scan.cloud.n)
    odr0, ols0, hyb0, n0 = rows[0.0, 0.0]
    for (a, b), (odr, ols, hyb, n) in rows.items():
        cc = np.cos(np.radians(a)) * np.cos(np.radians(b))
        # ODR stays within 10 % of its (0, 0) value (occlusion lowers it a little) ...
        assert abs(odr / odr0 - 1) < 0.10
        # ... the hybrid distance along y is the orthogonal one over |n_y| = cos a cos b ...
        assert hyb == pytest.approx(odr / cc, rel=0.01)
        # ... OLS follows the hybrid model closely (2012 Table 1) ...
        assert ols == pytest.approx(hyb, rel=0.01)
        # ... and the point count falls as N0 cos(alpha) cos(beta) (perspective: +3 %).
        assert n / (n0 * cc) == pytest.approx(1.0, abs=0.04)
    # OLS and hybrid grow with each rotation angle.
    for a in PAPER_ROTATIONS_DEG:
        seq = [rows[a, b][1] for b in PAPER_ROTATIONS_DEG]
        assert np.all(np.diff(seq) > 0)
        seq = [rows[b, a][2] for b in PAPER_ROTATIONS_DEG]
        assert np.all(np.diff(seq) > 0)
    assert rows[45.0, 45.0][1] > 1.8 * ols0
    # Occlusion at the largest rotation makes the board look smoother (2012: -8 %).
    assert rows[45.0, 45.0][0] < 0.98 * odr0


def test_board_occlusion_hides_board_behind_the_hemispheres():
    flat = board_scan(0.0, 0.0, spacing=0.004)
    tilted = board_scan(45.0, 45.0, spacing=0.004)
    # The hemispheres' share of the points grows as they shadow the board behind them.
    assert flat.on_sphere.mean() == pytest.approx(0.15, abs=0.01)
    assert tilted.on_sphere.mean() > flat.on_sphere.mean() + 0.05


def test_board_scan_noise_and_cache():
    a = board_scan(11.25, 0.0, spacing=0.004)
    assert board_scan(11.25, 0.0, spacing=0.004) is a  # cached
    assert not a.on_sphere.flags.writeable
    noisy = board_scan(11.25, 0.0, spacing=0.004, noise=0.002, seed=3)
    assert noisy.cloud.n == a.cloud.n
    moved = np.linalg.norm(noisy.cloud.xyz() - a.cloud.xyz(), axis=1)
    assert moved.mean() == pytest.approx(0.002 * np.sqrt(2 / np.pi), rel=0.05)


# --------------------------------------------------------------------------- outcrop


def test_face_trace_turns_by_the_bend_angle_and_is_continuous():
    spec = OUTCROP_SMALL
    s = np.linspace(0.0, spec.length_m, 20001)
    x, y, nx, ny = face_trace(spec, s)
    np.testing.assert_allclose(np.hypot(nx, ny), 1.0)
    step = np.hypot(np.diff(x), np.diff(y))
    np.testing.assert_allclose(step, s[1] - s[0], rtol=1e-6)  # unit speed: s is arc length
    assert np.degrees(np.arctan2(-nx[-1], -ny[-1])) == pytest.approx(spec.bend_deg)
    parts = face_part(spec, s)
    assert parts[0] == FACE_MAIN and parts[-1] == FACE_BEND
    assert np.any(parts == FACE_CURVE)
    assert np.all(y[s <= spec.main_length_m] == 0.0)


TINY = dataclasses.replace(
    OUTCROP_SMALL, main_length_m=3.0, curve_length_m=1.0, bend_length_m=2.0, height_m=6.0,
    buttresses=((1.5, 0.6, 0.4, 4.0),), angular_step_rad=3e-3,
)


def test_outcrop_generator_is_deterministic():
    a = generate_outcrop(TINY)
    b = generate_outcrop(TINY)
    assert a.cloud.n > 10_000
    for f in ("x", "y", "z", "intensity"):
        assert np.array_equal(getattr(a.cloud, f), getattr(b.cloud, f))
    assert np.array_equal(a.truth, b.truth)
    other = generate_outcrop(dataclasses.replace(TINY, seed=TINY.seed + 1))
    assert other.cloud.n != a.cloud.n or not np.array_equal(other.cloud.x, a.cloud.x)


def test_outcrop_has_every_truth_class_and_face_part():
    scan = generate_outcrop(TINY)
    assert set(np.unique(scan.truth).tolist()) == {0, 1, 2, 3}
    assert set(np.unique(scan.face).tolist()) == {FACE_MAIN, FACE_CURVE, FACE_BEND}


def test_outcrop_points_are_not_hidden_by_the_rock():
    # A point must be visible: walking from it back towards the scanner, the ray never
    # goes behind the rock surface (the relief model the generator sampled). Only
    # "mixed pixels" at sharp edges may leak (measured: 0.07 % of points deeper than
    # 1 cm); a z-buffer keeping any but the nearest sample would hide several percent.
    spec = TINY
    scan = generate_outcrop(spec)
    xyz = scan.cloud.xyz()
    main = np.flatnonzero((scan.face == FACE_MAIN) & (xyz[:, 0] > 0.2))
    pick = np.random.default_rng(1).choice(main, 2000, replace=False)
    p = xyz[pick]
    sc = np.asarray(spec.scanner)
    u = (sc - p) / np.linalg.norm(sc - p, axis=1)[:, None]
    relief = outcrop_relief(spec)
    t = np.arange(0.03, 0.8, 0.005)
    q = p[:, None, :] + t[None, :, None] * u[:, None, :]  # (P, T, 3) points on the rays
    h_surface, _ = relief(q[..., 0].ravel(), q[..., 2].ravel())
    inside = h_surface.reshape(q.shape[:2]) > -q[..., 1] + 0.01  # main face: h = -y
    assert inside.any(axis=1).mean() < 0.005


def test_outcrop_density_follows_range_and_incidence():
    # Rays on a regular angular grid: a patch of area A at range R, incidence g and
    # elevation e receives A cos(g) / (R^2 step^2 cos(e)) points.
    spec = TINY
    scan = generate_outcrop(spec)
    xyz = scan.cloud.xyz()
    sc = np.asarray(spec.scanner)
    ratios = []
    for x0 in (0.0, 2.2):
        for z0 in (0.5, 1.5, 2.5, 5.0):
            box = (
                (scan.face == FACE_MAIN) & (xyz[:, 0] >= x0) & (xyz[:, 0] < x0 + 0.5)
                & (xyz[:, 2] >= z0) & (xyz[:, 2] < z0 + 0.5)
            )
            v = np.array([x0 + 0.25, 0.0, z0 + 0.25]) - sc
            rng_m = np.linalg.norm(v)
            expected = 0.25 * (v[1] / rng_m) / (
                rng_m**2 * spec.angular_step_rad**2 * (np.hypot(v[0], v[1]) / rng_m)
            )
            if np.mean(scan.truth[box] == TRUTH_ROCK) > 0.9:
                ratios.append(box.sum() / expected)
    assert len(ratios) >= 4
    assert np.all((np.array(ratios) > 0.85) & (np.array(ratios) < 1.1))
