"""Roughness across scales, checked against grids computed directly at each size."""

from __future__ import annotations

import doctest

import numpy as np
import pytest

from rough_viewer.grid import scales as scales_module
from rough_viewer.grid.roughness import coarsen_prepared, grid_roughness, prepare_grid
from rough_viewer.grid.scales import face_scales, point_scales, point_scales_from_prepared
from rough_viewer.vocabulary import MAPS
from tests.helpers import face_cloud, rough_surface

SIZES = (0.125, 0.25, 0.5, 1.0)


@pytest.fixture(scope="module")
def cloud():
    return face_cloud(60_000, seed=4)


@pytest.fixture(scope="module")
def nested(cloud):
    """The app's way: the finest grid prepared once, the others coarsened from it."""
    fine = prepare_grid(cloud, SIZES[0])
    grids = [fine] + [coarsen_prepared(fine, int(round(g / SIZES[0]))) for g in SIZES[1:]]
    results = [grid_roughness(cloud, p.cell_size, prepared=p, axis="auto") for p in grids]
    return grids, results


@pytest.fixture(scope="module")
def direct(cloud):
    """Brute force: every grid computed from the points, nothing shared."""
    return [grid_roughness(cloud, g) for g in SIZES]


def test_module_examples_run():
    assert doctest.testmod(scales_module).failed == 0


def test_point_scales_equal_each_grid_computed_directly(cloud, nested, direct):
    _, results = nested
    rng = np.random.default_rng(0)
    for p in rng.integers(0, cloud.n, 25):
        got = point_scales(results[::-1], int(p))  # any order in, finest first out
        np.testing.assert_array_equal(got.cell_sizes, SIZES)
        for k, res in enumerate(direct):
            c = res.point_cell[p]
            assert got.n_points[k] == res.n_points[c]
            for name in MAPS:
                np.testing.assert_allclose(got.values(name)[k], res.values(name)[c],
                                           rtol=1e-9, atol=1e-15)
    assert got.axis == "y" and got.min_points == 4  # the default


def test_point_scales_brute_force_on_the_points_of_each_cell(cloud, nested):
    """Independent reference: fit the plane of the cell's points with numpy and take the
    std of the absolute orthogonal distances (SCIENCE.md section 1)."""
    _, results = nested
    xyz = cloud.xyz()
    p = 31_337
    got = point_scales(results, p)
    for k, g in enumerate(SIZES):
        cell = np.floor((xyz - xyz.min(axis=0)) / g).astype(int)
        members = xyz[np.all(cell == cell[p], axis=1)]
        assert members.shape[0] == got.n_points[k]
        d = members - members.mean(axis=0)
        normal = np.linalg.svd(d, full_matrices=False)[2][-1]
        dist = np.abs(d @ normal)
        assert got.theta_odr[k] == pytest.approx(dist.std(), rel=1e-6)
        # hybrid: the same distances along y (the auto axis of a face looking along y)
        assert got.theta_hybrid[k] == pytest.approx(dist.std() / abs(normal[1]), rel=1e-6)


def test_point_scales_from_prepared_equal_the_full_maps(cloud, nested):
    grids, results = nested
    for p in (0, 777, cloud.n - 1):
        full = point_scales(results, p)
        local = point_scales_from_prepared(cloud, grids, p, axis=full.axis)
        np.testing.assert_array_equal(local.cell, full.cell)
        np.testing.assert_array_equal(local.n_points, full.n_points)
        for name in MAPS:
            np.testing.assert_allclose(local.values(name), full.values(name), rtol=1e-9,
                                       atol=1e-15)


def test_cells_below_min_points_have_no_value():
    pts = rough_surface(400, seed=2, size=4.0)
    pts = np.vstack([pts, [[10.0, 10.0, 0.0]]])  # a lone point far away
    lone = pts.shape[0] - 1
    results = [grid_roughness(pts, g, axis="z", min_points=4) for g in (0.5, 1.0)]
    got = point_scales(results, lone)
    assert np.isnan(got.theta_odr).all() and (got.n_points == 1).all()
    prepared = [prepare_grid(pts, g) for g in (0.5, 1.0)]
    local = point_scales_from_prepared(pts, prepared, lone, axis="z", min_points=4)
    assert np.isnan(local.theta_ols).all() and (local.n_points == 1).all()


def test_bad_inputs_are_refused(cloud, nested):
    grids, results = nested
    with pytest.raises(ValueError, match="not in the cloud"):
        point_scales(results, cloud.n)
    with pytest.raises(ValueError, match="at least one grid"):
        point_scales([], 0)
    other = grid_roughness(face_cloud(1000, seed=1), 0.5)
    with pytest.raises(ValueError, match="different clouds"):
        point_scales([results[0], other], 0)
    with pytest.raises(ValueError, match="dependent axes"):
        point_scales([results[0], grid_roughness(cloud, 0.5, axis="z")], 0)
    with pytest.raises(ValueError, match="axis"):
        point_scales_from_prepared(cloud, grids, 0, axis="auto")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="another cloud"):
        point_scales_from_prepared(face_cloud(1000, seed=1), grids, 0, axis="y")


def test_face_scales_are_table_1_and_binary_shares_of_each_grid(nested, direct):
    _, results = nested
    fs = face_scales(results, threshold=0.05)
    np.testing.assert_array_equal(fs.cell_sizes, SIZES)
    for k, res in enumerate(direct):
        for name in MAPS:
            v = res.values(name)
            v = v[np.isfinite(v)]
            assert fs.statistic(name, "mean")[k] == pytest.approx(v.mean(), rel=1e-9)
            assert fs.statistic(name, "std")[k] == pytest.approx(v.std(), rel=1e-6)
            assert fs.statistic(name, "cells")[k] == v.size
            rough = (v - v.min()) / (v.max() - v.min()) >= 0.05
            assert fs.rough_share[name][k] == pytest.approx(rough.mean(), abs=1.5 / v.size)
    # the face's noise grows with x: coarser cells take in more of the wave, so the
    # mean roughness grows with the grid size (the paper's Table-1 trend)
    assert np.all(np.diff(fs.statistic("odr", "mean")) > 0)
    assert fs.axis == "y" and fs.n_points == results[0].n_points_total
    with pytest.raises(ValueError, match="threshold"):
        face_scales(results, threshold=1.5)
    with pytest.raises(ValueError, match="statistic"):
        fs.statistic("odr", "median")
