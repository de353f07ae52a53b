"""PLY out: binary little-endian, x, y, z float64 and the per-point fields; read back
by plyfile and by load_points (issue 15)."""

from __future__ import annotations

import numpy as np
from plyfile import PlyData

from rough_viewer.cli import main
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.table import POINT_FIELD_NAMES, point_fields
from rough_viewer.io import PointCloud, load_points
from rough_viewer.io.formats.ply import write_ply_fields
from tests.helpers import rough_surface

OFFSET = np.array([512_000.123456789, 4_170_000.987654321, 100.5])


def test_ply_round_trip(tmp_path):
    xyz = rough_surface(4000, seed=9, size=3.0) + OFFSET
    cloud = PointCloud.from_xyz(xyz, intensity=np.arange(4000) % 3000)
    result = grid_roughness(cloud, 0.5)
    path = tmp_path / "out.ply"
    info = write_ply_fields(path, cloud, point_fields(result), comments=["grid 0.5 m"])
    assert "4,000 vertices" in info
    with open(path, "rb") as fh:
        head = fh.read(300)
    assert b"format binary_little_endian 1.0" in head and b"property double x" in head
    ply = PlyData.read(str(path))
    v = ply["vertex"].data
    assert ply.comments == ["grid 0.5 m", "rough_viewer.unit m (x, y, z)"]  # its unit
    # coordinates bit for bit, properties equal to the result's per-point values
    np.testing.assert_array_equal(np.column_stack([v["x"], v["y"], v["z"]]), xyz)
    np.testing.assert_array_equal(v["intensity"], cloud.intensity)
    cell = result.point_cell
    for name, values in (("theta_odr", result.theta_odr), ("theta_ols", result.theta_ols),
                         ("theta_hybrid", result.theta_hybrid), ("e_ols", result.e_ols)):
        assert v[name].dtype == np.dtype("<f4")
        np.testing.assert_array_equal(v[name], values[cell].astype(np.float32))
    np.testing.assert_array_equal(v["cell_ix"], result.ijk[cell, 0])
    np.testing.assert_array_equal(v["cell_iz"], result.ijk[cell, 2])
    np.testing.assert_array_equal(v["cell_points"], result.n_points[cell])
    assert v["cell_points"].dtype == np.dtype("<u4")
    # and our reader reads it back as the same cloud
    back = load_points(path)
    np.testing.assert_array_equal(back.xyz(), xyz)


def test_compute_ply_out_several_grids(tmp_path):
    xyz = rough_surface(3000, seed=2, size=2.0) + OFFSET
    src = tmp_path / "face.xyz"
    src.write_text("\n".join(f"{a!r} {b!r} {c!r}" for a, b, c in xyz.tolist()) + "\n")
    out = tmp_path / "face.ply"
    assert main(["compute", str(src), "--grid", "0.5", "--grid", "0.25", "--ply-out", str(out),
                 "--quiet"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["face.xyz", "face_g0.25.ply",
                                                          "face_g0.5.ply"]
    for g in (0.5, 0.25):
        v = PlyData.read(str(tmp_path / f"face_g{g:g}.ply"))["vertex"].data
        assert [p for p in v.dtype.names if p not in "xyz"] == list(POINT_FIELD_NAMES)
        ref = grid_roughness(xyz, g)
        np.testing.assert_array_equal(v["theta_odr"],
                                      ref.theta_odr[ref.point_cell].astype(np.float32))


def test_ply_in_millimetres_says_so(tmp_path):
    """Issue 31 item 9: a PLY in the cloud's unit: coordinates and the length fields
    divided by the unit's metres, the unit in a comment."""
    from rough_viewer.grid.table import POINT_LENGTH_FIELDS

    xyz = rough_surface(2000, seed=3, size=0.1)
    cloud = PointCloud.from_xyz(xyz)
    result = grid_roughness(cloud, 0.02)
    path = tmp_path / "mm.ply"
    write_ply_fields(path, cloud, point_fields(result), unit="mm", lengths=POINT_LENGTH_FIELDS)
    ply = PlyData.read(str(path))
    v = ply["vertex"].data
    np.testing.assert_allclose(np.column_stack([v["x"], v["y"], v["z"]]), xyz * 1000.0,
                               rtol=1e-15)
    cell = result.point_cell
    np.testing.assert_allclose(v["theta_odr"], (result.theta_odr[cell] / 1e-3)
                               .astype(np.float32), rtol=1e-6)
    np.testing.assert_array_equal(v["cell_ix"], result.ijk[cell, 0])  # not a length
    assert ply.comments[-1] == "rough_viewer.unit mm (x, y, z, theta_odr, theta_ols, " \
        "theta_hybrid, e_ols)"
