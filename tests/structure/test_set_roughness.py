"""Roughness of each joint set (issue 30 item 4): a set of planted corrugated joints
against the closed forms of a sinusoid (ODR roughness, Z2, Delta-T), its dip and
strike told apart, a planar set beside it, the pooled facets against the
whole-surface TIN parameters, the cell statistics against numpy, and the bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io.formats.mesh import TriangleMesh
from rough_viewer.profiles.jrc import jrc_from_z2
from rough_viewer.structure.set_roughness import cell_odr_statistics, set_roughness
from rough_viewer.structure.sets import joint_sets
from rough_viewer.synthetic.joints import RockMassSetSpec, RockMassSpec, generate_rock_mass
from rough_viewer.tin.directional import directional_roughness, facet_roughness
from rough_viewer.tin.surface import facets
from tests.helpers import axis_angle

G = 0.25
#: Corrugations of set 1: 4 mm amplitude, 80 mm wavelength along the dip.
A, WAVE = 0.004, 0.08


@pytest.fixture(scope="module")
def corrugated():
    """A 2 m block of two sets of three joints 0.6 m apart, 1 cm point spacing, no
    noise: set 40/120 corrugated (crests along its strike), set 70/250 planar
    (234 k points)."""
    spec = RockMassSpec(size_m=2.0, point_spacing_m=0.01, noise_m=0.0, sets=(
        RockMassSetSpec(40.0, 120.0, joints=3, spacing_m=0.6, corrugation_m=A,
                        corrugation_wavelength_m=WAVE),
        RockMassSetSpec(70.0, 250.0, joints=3, spacing_m=0.6)))
    rm = generate_rock_mass(spec)
    result = grid_roughness(rm.cloud, G, models=("odr",))
    sets = joint_sets(result, rm.cloud)
    assert sets.n_sets == 2 and sets.n_joints_per_set.tolist() == [3, 3]
    match = [int(np.argmin([axis_angle(n, m) for m in rm.set_normal])) for n in sets.normal]
    assert sorted(match) == [0, 1]
    return rm, result, sets, match.index(0), match.index(1)


def test_odr_of_a_corrugated_set_is_the_sinusoids(corrugated):
    """ODR roughness (the standard deviation of |distance| to the cell's plane) of
    ``A sin`` over whole periods: ``A sqrt(1/2 - 4/pi^2)`` (mean |sin| = 2/pi, mean
    sin^2 = 1/2). A cell holds 3 to 4 periods; the part of a period left over makes
    single cells differ by +-10 %, their mean by less."""
    _, result, sets, rough, flat = corrugated
    planted = A * math.sqrt(0.5 - 4.0 / math.pi**2)  # 1.231 mm
    r = sets.roughness
    assert r.odr_cells[rough] == sets.cells[rough]
    assert r.odr_mean[rough] == pytest.approx(planted, rel=0.05)
    assert r.odr_median[rough] == pytest.approx(planted, rel=0.03)
    assert 0.0 < r.odr_std[rough] < 0.5 * planted
    # the planar set, without noise, is flat in most of its cells (those crossed by a
    # corrugated joint at a corner carry a little of it)
    assert r.odr_median[flat] < 1e-6
    assert r.odr_mean[flat] < 0.3 * planted
    # the same numbers, by brute force from the cells whose poles made the set
    mine = sets.planar & (sets.cell_set == rough + 1)
    assert r.odr_mean[rough] == pytest.approx(np.mean(result.theta_odr[mine]), rel=1e-12)
    assert r.odr_std[rough] == pytest.approx(np.std(result.theta_odr[mine]), rel=1e-9)


def test_the_dip_is_rough_and_the_strike_smooth(corrugated):
    """Crests along the strike: profiles down the dip see the sinusoid, whose Z2
    sampled every ``dx`` is ``sqrt(2) A sin(k dx / 2) / dx`` (mean of
    ``(2 A cos(.) sin(k dx/2))^2 / dx^2`` over a period), profiles along the strike
    see only its slope across their band; the facets' Delta-T down the dip is the
    area-weighted mean of ``atan(f')`` over the half of the surface rising along
    it."""
    _, _, sets, rough, flat = corrugated
    r = sets.roughness
    assert r.joints_measured.tolist() == [3, 3]
    assert r.profiles_dip[rough] >= 30 and r.profiles_strike[rough] >= 30
    dx = r.sample_spacing[rough]
    k = 2.0 * math.pi / WAVE
    z2_planted = math.sqrt(2.0) * A * math.sin(k * dx / 2.0) / dx
    assert r.z2_dip[rough] == pytest.approx(z2_planted, rel=0.10)
    assert r.jrc_estimate_dip[rough] == pytest.approx(jrc_from_z2(z2_planted), abs=1.5)
    assert r.z2_strike[rough] < 0.4 * r.z2_dip[rough]
    assert r.jrc_estimate_strike[rough] < r.jrc_estimate_dip[rough] - 10.0
    assert r.rms_dip[rough] == pytest.approx(A / math.sqrt(2.0), rel=0.10)
    assert r.rms_strike[rough] < 0.3 * r.rms_dip[rough]
    x = np.linspace(0.0, WAVE, 400_001)
    slope = A * k * np.cos(k * x)
    w = np.sqrt(1.0 + slope**2)
    up = slope >= 0
    delta_t = float(np.sum(np.degrees(np.arctan(slope[up])) * w[up]) / np.sum(w[up]))  # 11.3
    assert r.delta_t_dip[rough] == pytest.approx(delta_t, rel=0.06)
    assert r.delta_t_strike[rough] < 0.2 * r.delta_t_dip[rough]
    assert r.theta_max_c1_dip[rough] > 5.0 * r.theta_max_c1_strike[rough]
    # the planar set is smooth both ways
    for v in (r.delta_t_dip, r.delta_t_strike, r.theta_max_c1_dip, r.theta_max_c1_strike):
        assert v[flat] < 1.0
    assert r.z2_dip[flat] < 0.1 * r.z2_dip[rough]  # a few cells hold a corner of a corrugated joint
    # named an estimate, with its sampling
    assert any("JRC estimates" in w and "12" in w for w in r.warnings)
    t = sets.set_table(1e-3)
    assert t["odr_mean"][rough] == pytest.approx(r.odr_mean[rough] * 1e3)
    assert t["jrc_estimate_dip"][rough] == r.jrc_estimate_dip[rough]


def test_work_is_bounded(corrugated):
    """One joint per set: fewer measured, said in a warning; few points per set:
    shared out among the joints, each measured on the disc about its centroid."""
    rm, result, sets, rough, _ = corrugated
    pj = sets.cell_joint[result.point_cell].astype(np.int64) - 1
    xyz = (rm.cloud.x, rm.cloud.y, rm.cloud.z)
    args = (np.where(sets.planar, sets.cell_set, 0), result.theta_odr, sets.n_sets,
            sets.joints, pj, xyz)
    one = set_roughness(*args, max_joints=1)
    assert one.joints_measured.tolist() == [1, 1]
    assert any("beyond the 1 largest" in w for w in one.warnings)
    few = set_roughness(*args, max_points=30_000)  # 10,000 points of each joint
    assert few.joints_measured.tolist() == [3, 3]
    assert np.all(few.points_measured == 30_000)
    assert any("6 joints measured on the disc" in w for w in few.warnings)
    # the disc keeps the point spacing: the corrugations still read the same
    assert few.z2_dip[rough] == pytest.approx(sets.roughness.z2_dip[rough], rel=0.15)
    assert np.array_equal(one.odr_mean, sets.roughness.odr_mean, equal_nan=True)
    cells_only = set_roughness(*args, directional=False)
    assert np.array_equal(cells_only.odr_median, sets.roughness.odr_median)
    assert np.isnan(cells_only.delta_t_dip).all() and not cells_only.joints_measured.any()


def test_pooled_facets_are_the_whole_surfaces_parameters():
    """The facets of a rough mesh turned into two frames (the mesh as it is, and
    rotated by 35 degrees about a tilted axis, each measured in its own plane's
    frame) pool to one distribution: twice the same facets give the mesh's own
    theta*max/(C+1) and Delta-T."""
    rng = np.random.default_rng(3)
    x, y = np.meshgrid(np.arange(40.0), np.arange(30.0))
    z = 0.3 * np.sin(x / 3.0) + 0.2 * rng.standard_normal(x.shape)
    i = np.arange(x.size).reshape(x.shape)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    flat = TriangleMesh(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), faces)
    from rough_viewer.grid.maps import FacePlane

    plane = FacePlane(centroid=np.zeros(3), normal=np.array([0.0, 0.0, 1.0]))
    ref = directional_roughness(flat, [0, 90, 180, 270], plane=plane)
    f = facets(flat, toward=np.array([0.0, 0.0, 1.0]))
    turned = f.normals @ _rotation(np.array([1.0, 1.0, 0.3]), 35.0).T
    back = turned @ _rotation(np.array([1.0, 1.0, 0.3]), 35.0)  # the second joint's frame
    pooled = facet_roughness(np.vstack([f.normals, back]), np.concatenate([f.areas, f.areas]),
                             np.zeros(2 * f.areas.size, dtype=np.int64), 1, [0, 90, 180, 270])
    assert pooled["theta_max_c1"][0] == pytest.approx(ref.theta_max_c1, rel=1e-9)
    assert pooled["delta_t"][0] == pytest.approx(ref.delta_t, rel=1e-9)
    assert pooled["facing"][0].tolist() == (2 * ref.facing).tolist()
    # two groups: each its own
    two = facet_roughness(np.vstack([f.normals, f.normals[:, [0, 1, 2]] * [1, -1, 1]]),
                          np.concatenate([f.areas, f.areas]),
                          np.repeat([0, 1], f.areas.size), 2, [90])
    assert two["delta_t"][0, 0] == pytest.approx(ref.delta_t[1], rel=1e-9)
    assert two["delta_t"][1, 0] == pytest.approx(ref.delta_t[3], rel=1e-9)  # mirrored in y


def _rotation(axis: np.ndarray, angle_deg: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    t = math.radians(angle_deg)
    return np.eye(3) + math.sin(t) * kx + (1.0 - math.cos(t)) * kx @ kx


def test_cell_statistics_are_numpys():
    rng = np.random.default_rng(5)
    cell_set = rng.integers(0, 5, 2_000)
    theta = rng.gamma(2.0, 1e-3, 2_000)
    theta[rng.uniform(size=2_000) < 0.1] = np.nan
    mean, median, std, n = cell_odr_statistics(cell_set, theta, 5)
    for s in range(1, 6):
        v = theta[(cell_set == s) & np.isfinite(theta)]
        if s == 5:
            assert n[s - 1] == 0 and math.isnan(mean[s - 1]) and math.isnan(median[s - 1])
            continue
        assert n[s - 1] == v.size
        assert mean[s - 1] == pytest.approx(v.mean(), rel=1e-12)
        assert median[s - 1] == pytest.approx(np.median(v), rel=1e-12)
        assert std[s - 1] == pytest.approx(v.std(), rel=1e-9)
