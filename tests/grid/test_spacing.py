"""grid/spacing.py: point spacing and the default grid of clouds of known spacing."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.spacing import (
    TARGET_POINTS,
    default_cell_size,
    median_cell_count,
    nice_ceil,
    point_spacing,
    preset_cell_sizes,
)
from tests.helpers import random_rotation


def lattice(pitch: float, n: int, *, rotate: int | None = None) -> np.ndarray:
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    xyz = np.column_stack([pitch * i.ravel(), pitch * j.ravel(), np.zeros(i.size)])
    if rotate is not None:
        xyz = xyz @ random_rotation(rotate).T
    return xyz + np.array([512_000.0, 4_100_000.0, 300.0])


def test_lattice_spacing_is_its_pitch_and_default_cell_holds_16_points():
    xyz = lattice(0.02, 150)
    assert point_spacing(xyz) == pytest.approx(0.02, rel=1e-9)
    g = default_cell_size(xyz)
    assert g == pytest.approx(0.08)  # 4 x 4 lattice points: exactly 16 per cell
    res = grid_roughness(xyz, g)
    assert np.median(res.n_points) == TARGET_POINTS
    assert preset_cell_sizes(xyz) == pytest.approx((0.64, 0.32, 0.16, 0.08))


def test_random_points_of_known_density_on_a_tilted_face():
    # 2500 points per square metre (spacing about 2 cm) on a face tilted in space
    rng = np.random.default_rng(1)
    n = 250_000
    uv = rng.uniform(0.0, 10.0, (n, 2))
    xyz = np.column_stack([uv, 0.003 * rng.standard_normal(n)]) @ random_rotation(5).T
    assert point_spacing(xyz) == pytest.approx(1.08 / np.sqrt(2500.0), rel=0.08)
    g = default_cell_size(xyz)
    assert median_cell_count(xyz, g) >= TARGET_POINTS
    # not needlessly coarse: one readable step finer would miss the target
    assert median_cell_count(xyz, g / 1.34) < TARGET_POINTS or g <= 0.1
    assert 0.06 <= g <= 0.2
    assert nice_ceil(g) == g


def test_units_do_not_change_the_number_of_points_per_cell():
    xyz = lattice(0.02, 100, rotate=3)
    g_m = default_cell_size(xyz)
    g_mm = default_cell_size(xyz * 1000.0)
    assert g_mm == pytest.approx(1000.0 * g_m, rel=0.35)
    assert median_cell_count(xyz * 1000.0, g_mm) >= TARGET_POINTS


@pytest.mark.parametrize("n", [5, 8, 15])
def test_a_cloud_smaller_than_the_target_gets_one_cell_of_every_point(n):
    """Issue 36: 5-15 points can never fill a median cell of 16; the cell grew until it
    was infinite (OverflowError). The default now asks for all the points in one cell."""
    import math

    from rough_viewer.grid.spacing import default_cell_size

    rng = np.random.default_rng(n)
    pts = np.column_stack([rng.uniform(0, 3, (n, 2)), 0.01 * rng.standard_normal(n)])
    g = default_cell_size(pts)
    assert math.isfinite(g) and g < 20.0  # the cloud spans 3 m
    keys = np.floor((pts - pts.min(axis=0)) / g)
    assert np.all(keys == 0)  # brute force: every point in the first cell


def test_a_cloud_in_us_feet_gets_round_sizes_in_us_feet():
    """Issue 31 item 9: presets of a cloud in US survey feet were nice in metres (16
    and 32 m read 52.4933 and 104.987 US ft); they are round in its own unit now,
    with at least the target points per typical cell, in the app and the report."""
    from dataclasses import replace

    from rough_viewer.app.cloud import grid_presets
    from rough_viewer.app.units import Units
    from rough_viewer.io import PointCloud
    from rough_viewer.report.build import default_report_grids
    from rough_viewer.vocabulary import UNIT_METRES

    per = UNIT_METRES["us-ft"]
    xyz = lattice(0.9 * per, 150)  # a lattice of 0.9 US ft, given in metres
    cloud = replace(PointCloud.from_xyz(xyz), source_unit="us-ft")
    g = default_cell_size(cloud)
    assert g / per == pytest.approx(4.0, rel=1e-9)  # 4 x 4 lattice points, 4 US ft
    assert median_cell_count(xyz, g) >= TARGET_POINTS
    assert default_cell_size(xyz) == pytest.approx(1.25)  # read in metres: 1.25 m
    shown = [Units("us-ft").size_text(s) for s in grid_presets(cloud)]
    assert shown == ["32 US ft", "16 US ft", "8 US ft", "4 US ft"]
    assert [round(s / per, 9) for s in preset_cell_sizes(cloud)] == [32.0, 16.0, 8.0, 4.0]
    assert all(float(f"{s / per:.9g}").is_integer() for s in default_report_grids(cloud))


def test_dense_cell_count_equals_sorted_keys(monkeypatch):
    """The cells counted in one array over the grid's box (a bincount) give the same
    median as sorting the cell keys, and the spacing's tree the same neighbours as a
    brute-force search."""
    from rough_viewer.grid import spacing

    rng = np.random.default_rng(3)
    pts = np.column_stack([rng.uniform(0, 3, 20_000), 0.01 * rng.standard_normal(20_000),
                           rng.uniform(0, 2, 20_000)])
    lo = pts.min(axis=0)
    dense = [spacing._median_count(pts, lo, 0.5, g) for g in (0.05, 0.1, 0.3)]
    monkeypatch.setattr(spacing, "DENSE_CELLS_PER_POINT", 0)
    assert dense == [spacing._median_count(pts, lo, 0.5, g) for g in (0.05, 0.1, 0.3)]
    assert dense[0] != dense[1]
    few = pts[:3000]
    d = np.sqrt(((few[:, None, :] - few[None, :, :]) ** 2).sum(axis=2))  # every point queried
    assert spacing.neighbour_distance(few) == float(np.median(np.sort(d, axis=1)[:, 4]))
