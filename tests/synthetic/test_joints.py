"""The synthetic joint block: planted statistics exact, truth labels on their planes,
the scan's shadows, determinism and refused specs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rough_viewer.grid.orientation import dip_and_direction
from rough_viewer.synthetic.joints import (
    JOINT_BLOCK,
    JointBlockSpec,
    JointSetSpec,
    exact_fisher_normals,
    generate_joint_block,
)
from rough_viewer.vocabulary import InputError

SPEC = JointBlockSpec(angular_step_rad=3e-3)


@pytest.fixture(scope="module")
def scan():
    return generate_joint_block(SPEC)


def test_planted_planes_have_the_sets_statistics_exactly(scan):
    pl = scan.planes
    for k, s in enumerate(SPEC.sets, start=1):
        n = pl.normal[pl.set_id == k]
        assert n.shape[0] == s.planes
        m = n.sum(axis=0) / n.shape[0]
        r = float(np.linalg.norm(m))
        dip, dd = dip_and_direction(m[None])
        assert dip[0] == pytest.approx(s.dip_deg, abs=1e-9)
        assert dd[0] == pytest.approx(s.dip_direction_deg, abs=1e-9)
        assert 1.0 / (1.0 - r) == pytest.approx(s.kappa, rel=1e-9)
        spacing = scan.spacings(k)
        assert spacing.mean() == pytest.approx(s.spacing_m, rel=1e-12)
        assert np.all(np.abs(spacing / s.spacing_m - 1.0) <= 1.1 * s.spacing_jitter)
        assert pl.dip_length_m[pl.set_id == k] == pytest.approx(s.dip_length_m)
    # centres lie on the design face y = 0, axes are unit and orthogonal to the normal
    assert pl.centre[:, 1] == pytest.approx(0.0, abs=1e-12)
    for axis in (pl.dip_axis, pl.strike_axis):
        assert np.linalg.norm(axis, axis=1) == pytest.approx(1.0)
        assert np.einsum("ij,ij->i", axis, pl.normal) == pytest.approx(0.0, abs=1e-12)


def test_points_lie_on_their_planted_plane_within_the_noise(scan):
    xyz = scan.cloud.xyz()
    on = scan.plane >= 0
    p = scan.plane[on]
    dist = np.einsum("ij,ij->i", xyz[on] - scan.planes.centre[p], scan.planes.normal[p])
    assert np.std(dist) < SPEC.range_noise_m  # range noise, seen obliquely
    assert np.abs(dist).max() < 6 * SPEC.range_noise_m
    rel = xyz[on] - scan.planes.centre[p]
    a = np.einsum("ij,ij->i", rel, scan.planes.dip_axis[p])
    assert np.all(np.abs(a) <= 0.5 * scan.planes.dip_length_m[p] + 0.01)
    assert np.array_equal(scan.set_id[on], scan.planes.set_id[p])
    assert np.all(scan.set_id[~on] == 0)


def test_the_exposures_shadow_the_wall(scan):
    """Behind every exposure (seen from the scanner) the wall has no points."""
    spec = SPEC
    xyz = scan.cloud.xyz()
    lo = xyz.min(axis=0)
    hi = xyz.max(axis=0)
    scanner = np.array([0.5 * (lo[0] + hi[0] + 0.0), -spec.scanner_distance_m,
                        spec.scanner_height_m])
    wall = xyz[scan.plane < 0]
    c = scan.planes.centre[0]  # the ray through an exposure's centre hits no wall near it
    ray = (c - scanner) / np.linalg.norm(c - scanner)
    behind = wall - scanner
    along = behind @ ray
    off = np.linalg.norm(behind - along[:, None] * ray, axis=1)
    assert not np.any((off < 0.3) & (along > np.linalg.norm(c - scanner)))
    assert wall.shape[0] > 0 and np.mean(scan.plane >= 0) > 0.1


def test_the_same_spec_gives_the_same_points():
    a = generate_joint_block(SPEC)
    b = generate_joint_block(SPEC)
    assert np.array_equal(a.cloud.xyz(), b.cloud.xyz()) and np.array_equal(a.plane, b.plane)


def test_exact_fisher_normals_for_any_axis():
    rng = np.random.default_rng(0)
    axis = np.array([0.3, -0.2, 0.93])
    axis /= np.linalg.norm(axis)
    v = exact_fisher_normals(rng, axis, 80.0, 12)
    m = v.mean(axis=0)
    assert m / np.linalg.norm(m) == pytest.approx(axis)
    assert 1 / (1 - np.linalg.norm(m)) == pytest.approx(80.0)
    assert np.linalg.norm(v, axis=1) == pytest.approx(1.0)


@pytest.mark.parametrize("change", [
    {"planes": 0}, {"kappa": 0.5}, {"spacing_m": -1.0}, {"spacing_jitter": 1.0},
    {"dip_deg": 0.0},  # parallel to the wall's foot: it cannot be laid out on the face
    {"dip_length_m": 6.0},  # exposures far larger than the spacing overlap
])
def test_bad_specs_are_refused(change):
    sets = (dataclasses.replace(JOINT_BLOCK.sets[0], **change), *JOINT_BLOCK.sets[1:])
    with pytest.raises(InputError):
        generate_joint_block(dataclasses.replace(SPEC, sets=sets))
    assert isinstance(JOINT_BLOCK.sets[0], JointSetSpec)
