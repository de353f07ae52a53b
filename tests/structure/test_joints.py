"""Joints from patches, their spacing and the rock-mass figures: a see-through rock
mass of three planted sets cutting each other (issue 30), one joint seen as three
separate exposures, pieces of a curved surface, and the Jv / RQD formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.structure.joints import RQD_INTERCEPT, RQD_SLOPE, rock_mass_figures
from rough_viewer.structure.sets import JOINT_COLUMNS, joint_sets
from rough_viewer.synthetic.joints import ROCK_MASS_SETS, RockMassSpec, generate_rock_mass
from tests.helpers import axis_angle, face_axes

G = 0.25


@pytest.fixture(scope="module")
def rock():
    """The block of issue 30: 6 m, sets 60/030, 45/150, 80/270 of 15, 9 and 11
    joints 0.5, 0.8 and 0.6 m apart, Fisher kappa 400, 2 mm noise (421 k points)."""
    rm = generate_rock_mass(RockMassSpec())
    result = grid_roughness(rm.cloud, G, models=("odr",))
    return rm, result, joint_sets(result, rm.cloud)


def _planted(rm, sets) -> list[int]:
    """The planted set (1..S) of every found set, by the nearest mean normal."""
    return [int(np.argmin([axis_angle(n, m) for m in rm.set_normal])) + 1 for n in sets.normal]


def test_the_cut_rock_mass_has_its_planted_joints_not_its_patches(rock):
    rm, _, sets = rock
    assert sets.n_sets == 3
    match = _planted(rm, sets)
    assert sorted(match) == [1, 2, 3]
    for k, p in enumerate(match):
        spec = ROCK_MASS_SETS[p - 1]
        # the other sets cut every joint into many patches ...
        assert sets.n_planes_per_set[k] > 3 * spec.joints
        # ... that are put together again: joints within 10 % of the planted number
        assert abs(sets.n_joints_per_set[k] - spec.joints) <= 0.1 * spec.joints
    # nearly every joint is one planted joint: its points are the planted one's
    point_joint = sets.cell_joint[rock[1].point_cell].astype(np.int64) - 1
    on = point_joint >= 0
    pairs = np.unique(point_joint[on] * 1000 + rm.joint[on], return_counts=True)
    joint_of, counts = pairs[0] // 1000, pairs[1]
    purity = np.zeros(sets.joints.n_joints)
    np.maximum.at(purity, joint_of, counts)
    assert np.median(purity / sets.joints.points) > 0.99


def test_spacing_both_ways_and_jv_are_the_planted_ones(rock):
    rm, _, sets = rock
    jv_planted = 0.0
    for k, p in enumerate(_planted(rm, sets)):
        planted = rm.spacings(p)
        jv_planted += 1.0 / planted.mean()
        assert sets.spacing_mean[k] == pytest.approx(planted.mean(), rel=0.05)
        # the median of 8 to 14 spacings, each measured on tilted joints: 10 %
        assert sets.spacing_median[k] == pytest.approx(np.median(planted), rel=0.10)
        assert sets.spacing_scanline_mean[k] == pytest.approx(planted.mean(), rel=0.05)
    f = sets.figures
    assert f.jv == pytest.approx(jv_planted, rel=0.10)
    assert f.jv == pytest.approx(np.sum(1.0 / sets.spacing_mean))
    assert f.block_size_index == pytest.approx(np.mean(sets.spacing_mean))
    assert f.rqd_estimate == pytest.approx(110.0 - 2.5 * f.jv)


def test_joint_table_follows_the_contract(rock):
    _, _, sets = rock
    t = sets.joint_table()
    assert tuple(t) == JOINT_COLUMNS
    jt = sets.joints
    assert list(t["joint_id"]) == list(range(1, jt.n_joints + 1))
    # patches and areas add up to those of the planes
    assert int(t["patches"].sum()) == sets.planes.n_planes
    assert t["area"].sum() == pytest.approx(sets.planes.area.sum())
    for j in range(jt.n_joints):
        mine = sets.planes.joint_id == j + 1
        assert int(mine.sum()) == t["patches"][j]
        assert set(sets.planes.set_id[mine]) == {t["set_id"][j]}
    mm = sets.joint_table(1e-3)
    assert mm["trace_length"] == pytest.approx(t["trace_length"] * 1e3)
    assert mm["area"] == pytest.approx(t["area"] * 1e6)
    assert np.array_equal(sets.plane_table()["joint_id"], sets.planes.joint_id)


def _exposures(offset_m: float, rng: np.random.Generator) -> np.ndarray:
    """One plane dipping 30/120 at ``offset_m`` along its normal, exposed in three
    2 x 2 m windows 3 m apart along strike (nothing between them)."""
    strike, down, normal = face_axes(30.0, 120.0)
    parts = []
    for start in (0.0, 5.0, 10.0):
        n = 16_000
        s = rng.uniform(start, start + 2.0, n)
        d = rng.uniform(0.0, 2.0, n)
        h = offset_m + 0.001 * rng.standard_normal(n)
        parts.append(s[:, None] * strike + d[:, None] * down + h[:, None] * normal)
    return np.vstack(parts)


def test_a_joint_seen_as_three_separate_exposures_is_one_joint():
    rng = np.random.default_rng(30)
    pts = np.vstack([_exposures(0.0, rng), _exposures(0.7, rng)])
    result = grid_roughness(pts, G, models=("odr",))
    sets = joint_sets(result, pts)
    assert sets.n_sets == 1 and sets.planes.n_planes == 6
    assert sets.n_joints_per_set.tolist() == [2]
    jt = sets.joints
    assert jt.patches.tolist() == [3, 3]
    # the joint runs over all three windows: 12 m along strike, 2 m down dip
    assert jt.persistence_strike == pytest.approx([12.0, 12.0], rel=0.03)
    assert jt.persistence_dip == pytest.approx([2.0, 2.0], rel=0.03)
    assert jt.trace_length == pytest.approx([12.0, 12.0], rel=0.03)
    assert jt.area == pytest.approx([12.0, 12.0], rel=0.05)
    assert jt.rms == pytest.approx([0.001, 0.001], rel=0.1)
    # the two joints, not the six patches, are 0.7 m apart both ways
    assert sets.spacing_mean[0] == pytest.approx(0.7, rel=0.01)
    assert sets.spacing_scanline_mean[0] == pytest.approx(0.7, rel=0.01)


def test_pieces_of_a_curved_surface_are_no_joint():
    """A vault of radius 4 m: whole, its cells chain into a curved group (no patch,
    no joint); cut by rough strips every metre of arc, each piece is planar enough to
    be a patch, but no two pieces lie on one plane, so no joint has two patches."""
    rng = np.random.default_rng(31)
    n = 150_000
    a = rng.uniform(-0.5, 0.5, n)
    y = rng.uniform(0.0, 4.0, n)
    r = 4.0 + 0.0005 * rng.standard_normal(n)
    whole = np.column_stack([r * np.sin(a), y, r * np.cos(a)])
    sets = joint_sets(grid_roughness(whole, G, models=("odr",)), whole)
    assert sets.n_sets >= 1 and sets.joints.n_joints == 0 and not sets.cell_joint.any()
    arc = a * 4.0
    strip = np.abs((arc + 2.0) % 1.0 - 0.5) < 0.15  # rough strips 0.3 m wide
    r_cut = r + np.where(strip, 0.05 * rng.standard_normal(n), 0.0)
    cut = np.column_stack([r_cut * np.sin(a), y, r_cut * np.cos(a)])
    sets = joint_sets(grid_roughness(cut, G, models=("odr",)), cut)
    assert sets.planes.n_planes >= 3
    assert sets.joints.n_joints == sets.planes.n_planes
    assert np.all(sets.joints.patches == 1)


def test_rqd_estimate_follows_palmstrom_and_is_clipped():
    for jv in (1.0, 4.0, 10.0, 44.0, 60.0):
        f = rock_mass_figures(np.array([3.0 / jv, 3.0 / jv, 3.0 / jv]))  # three equal sets
        assert f.jv == pytest.approx(jv)
        assert f.block_size_index == pytest.approx(3.0 / jv)
        assert f.rqd_estimate == pytest.approx(min(100.0, max(0.0, RQD_INTERCEPT
                                                              - RQD_SLOPE * jv)))
    assert rock_mass_figures(np.array([1.0 / 50.0])).rqd_estimate == 0.0
    assert rock_mass_figures(np.array([1.0])).rqd_estimate == 100.0
    none = rock_mass_figures(np.array([np.nan, np.nan]))
    assert none.sets_counted == 0 and math.isnan(none.jv) and math.isnan(none.rqd_estimate)
