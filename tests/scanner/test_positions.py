"""Scanner positions: E57 poses, one position, a table by LAS point source id."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud, load_points
from rough_viewer.scanner.geometry import scan_geometry
from rough_viewer.scanner.positions import (
    assign_scanners,
    cloud_scanners,
    point_source_ids,
    read_scanner_table,
    with_scanner,
)
from rough_viewer.vocabulary import InputError
from tests.helpers import ray_grid, scan_plane


def _quaternion_z(angle: float) -> np.ndarray:
    return np.array([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)])


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_two_posed_e57_scans_give_the_right_scan_counts(tmp_path):
    """Two scanners 6 m apart scan a wall 10 m away; each sees x in [-2, 1] or
    [-1, 2]: cells of x in [-1, 1] are seen by both, the others by one. The scans are
    stored in each scanner's own frame (turned about z) with their poses."""
    pye57 = pytest.importorskip("pye57")
    wall = np.array([0.0, 10.0, 0.0])
    normal = np.array([0.0, -1.0, 0.0])
    scanners = [np.array([-3.0, 0.0, 0.0]), np.array([3.0, 0.0, 0.0])]
    spans = [(-2.0, 1.0), (-1.0, 2.0)]
    turns = [0.3, -0.5]
    path = tmp_path / "two.e57"
    writer = pye57.E57(str(path), mode="w")
    for s, (lo, hi), turn in zip(scanners, spans, turns, strict=True):
        rays = ray_grid(s, wall, 0.3, step=2e-3)
        pts = scan_plane(s, wall, normal, rays, extent=2.5)
        pts = pts[(pts[:, 0] >= lo) & (pts[:, 0] < hi) & (np.abs(pts[:, 2]) < 1.0)]
        local = (pts - s) @ _rot_z(turn)  # the scanner's frame: R^T (p - t)
        writer.write_scan_raw({"cartesianX": local[:, 0], "cartesianY": local[:, 1],
                               "cartesianZ": local[:, 2]},
                              rotation=_quaternion_z(turn), translation=s)
    writer.close()
    cloud = load_points(path)
    positions, scan = cloud_scanners(cloud)
    np.testing.assert_allclose(positions, np.array(scanners))
    res = grid_roughness(cloud, 0.5, origin=(-2.0, 9.75, -1.0), models=("odr",))
    geo = scan_geometry(cloud, res, positions, scan)
    ok = np.isfinite(res.theta_odr)
    x = res.centre[:, 0]
    both = ok & (x > -1.0) & (x < 1.0)
    assert both.sum() == 16 and ok.sum() == 32  # 4 x 8 cells of 0.5 m, 4 x 4 in both
    np.testing.assert_array_equal(geo.scans[both], 2)
    np.testing.assert_array_equal(geo.scans[ok & ~both], 1)
    # the left cells are seen by the left scanner only: its range to their centroids
    left = ok & (x < -1.0)
    d = res.centroid[left] - scanners[0]
    np.testing.assert_allclose(geo.range_m[left], np.linalg.norm(d, axis=1), atol=1e-4)


def test_one_position_and_its_checks():
    cloud = with_scanner(PointCloud.from_xyz(np.zeros((4, 3))), (1.0, 2.0, 3.0))
    pos, scan = cloud_scanners(cloud)
    assert pos.tolist() == [[1.0, 2.0, 3.0]] and scan.tolist() == [0, 0, 0, 0]
    assert cloud_scanners(PointCloud.from_xyz(np.zeros((4, 3)))) is None
    with pytest.raises(InputError, match="three finite"):
        with_scanner(cloud, (1.0, np.nan, 3.0))
    bad = PointCloud.from_xyz(np.zeros((2, 3)), scan_index=np.array([0, 2]),
                              scanner_positions=np.zeros((2, 3)))
    with pytest.raises(InputError, match="out of range"):
        cloud_scanners(bad)


def _las_with_ids(path, xyz, ids):
    import laspy

    hdr = laspy.LasHeader(point_format=6, version="1.4")
    hdr.offsets = np.floor(xyz.min(axis=0))
    hdr.scales = np.array([1e-4] * 3)
    las = laspy.LasData(hdr)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.point_source_id = ids
    las.write(str(path))


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_scanner_table_joins_las_point_source_ids(tmp_path, suffix):
    rng = np.random.default_rng(0)
    xyz = rng.uniform(0, 5, (500, 3))
    ids = rng.choice([7, 12, 30], 500).astype(np.uint16)
    path = tmp_path / f"tiles{suffix}"
    _las_with_ids(path, xyz, ids)
    table_file = tmp_path / "scanners.csv"
    table_file.write_text("point_source_id,x,y,z\n# station 30 first\n30, 1, 2, 3\n"
                          "7;-1;-2;-3\n12 10 20 30\n")
    table = read_scanner_table(table_file, unit="ft")
    assert table.ids.tolist() == [7, 12, 30]
    np.testing.assert_allclose(table.positions[2], np.array([1, 2, 3]) * 0.3048)
    got = point_source_ids(path)
    np.testing.assert_array_equal(got, ids)
    cloud = assign_scanners(load_points(path), got, table)
    pos, scan = cloud_scanners(cloud)
    np.testing.assert_allclose(pos[scan], table.positions[np.searchsorted([7, 12, 30], ids)])


def test_missing_ids_and_bad_tables_are_one_line(tmp_path):
    path = tmp_path / "a.las"
    _las_with_ids(path, np.random.default_rng(1).uniform(0, 1, (50, 3)),
                  np.r_[np.full(40, 1), np.full(10, 2)].astype(np.uint16))
    (tmp_path / "s.csv").write_text("1,0,0,0\n")
    table = read_scanner_table(tmp_path / "s.csv")
    with pytest.raises(InputError, match=r"no position for point_source_id 2 \(10 points\)"):
        assign_scanners(load_points(path), point_source_ids(path), table)
    for text, message in [("1,0,0\n", "expected 4 columns"), ("1,0,0,0\n1,1,1,1\n", "more than once"),
                          ("x,y,z,w\n", "no scanner positions"), ("1.5,0,0,0\n", "whole number"),
                          ("1,0,nan,0\n", "finite"), ("id,x,y,z\n1,a,0,0\n", "line 2")]:
        (tmp_path / "t.csv").write_text(text)
        with pytest.raises(InputError, match=message) as exc:
            read_scanner_table(tmp_path / "t.csv")
        assert "t.csv" in str(exc.value) and "\n" not in str(exc.value)


def test_text_point_source_id_column(tmp_path):
    path = tmp_path / "cloud.txt"
    path.write_text("//X,Y,Z,Intensity,Point Source ID\n0,0,0,5,3\n1,0,nan,5,4\n0,1,0,5,4\n"
                    "1,1,1,5,3\n")
    ids = point_source_ids(path)
    assert ids.tolist() == [3, 4, 3]  # the row with a NaN coordinate is not in the cloud
    assert load_points(path).n == 3
    (tmp_path / "plain.xyz").write_text("0 0 0\n1 0 0\n0 1 0\n")
    with pytest.raises(InputError, match="no point_source_id column.*--scanner X,Y,Z"):
        point_source_ids(tmp_path / "plain.xyz")
    with pytest.raises(InputError, match="carries no point_source_id"):
        point_source_ids(tmp_path / "cloud.ply")
