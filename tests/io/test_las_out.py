"""LAS/LAZ out: every original point and dimension, the VLRs (CRS) and EVLRs survive;
the added extra dimensions equal the cell table (issue 15)."""

from __future__ import annotations

import csv
import errno
import struct

import laspy
import numpy as np
import pytest
from laspy.vlrs.vlrlist import VLRList

from rough_viewer.cli import main
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.table import NO_CELL, POINT_FIELD_NAMES, point_fields
from rough_viewer.io import load_points
from rough_viewer.io.formats.las_out import coordinate_scale, copy_las_with_fields, write_las_fields
from rough_viewer.io.formats.point_fields import CellField, PointFields
from rough_viewer.vocabulary import InputError
from tests.helpers import rough_surface

GRID = 0.5

#: NAD83 / UTM zone 11N as GeoTIFF keys: model type projected, raster type pixel-is-area,
#: projected CRS EPSG 26911.
GEOKEYS = struct.pack("<16H", 1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 26911)
WKT = b'PROJCS["NAD83 / UTM zone 11N",AUTHORITY["EPSG","26911"]]\x00'


def _surface(n: int, seed: int) -> np.ndarray:
    return rough_surface(n, seed=seed, size=3.0) + np.array([238_000.0, 3_765_000.0, 250.0])


def make_pf3(path, n: int = 3000, seed: int = 1) -> None:
    """LAS 1.2 point format 3: RGB, GPS time, returns, classification, a GeoTIFF CRS and
    a private VLR; coordinates at 1 cm as airborne lidar usually is."""
    rng = np.random.default_rng(seed)
    header = laspy.LasHeader(version="1.2", point_format=3)
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.array([238_000.0, 3_765_000.0, 0.0])
    header.vlrs.append(laspy.VLR("LASF_Projection", 34735, "GeoTIFF GeoKeyDirectoryTag", GEOKEYS))
    header.vlrs.append(laspy.VLR("NIIRS10", 4, "private", b"\x01\x02\x03\x04\x05"))
    las = laspy.LasData(header)
    xyz = _surface(n, seed)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.intensity = rng.integers(0, 65535, n, dtype=np.uint16)
    las.return_number = rng.integers(1, 4, n, dtype=np.uint8)
    las.number_of_returns = np.full(n, 3, dtype=np.uint8)
    las.classification = rng.integers(0, 10, n, dtype=np.uint8)
    las.gps_time = 1e5 + np.cumsum(rng.uniform(0, 1e-3, n))
    las.red = rng.integers(0, 65535, n, dtype=np.uint16)
    las.green = rng.integers(0, 65535, n, dtype=np.uint16)
    las.blue = rng.integers(0, 65535, n, dtype=np.uint16)
    las.point_source_id = rng.integers(0, 100, n, dtype=np.uint16)
    las.scan_angle_rank = rng.integers(-20, 20, n, dtype=np.int8)
    las.write(str(path))


def make_pf6(path, n: int = 3000, seed: int = 2) -> None:
    """LAS 1.4 point format 6 with an existing extra dimension, a WKT CRS and an EVLR."""
    rng = np.random.default_rng(seed)
    header = laspy.LasHeader(version="1.4", point_format=6)
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.array([238_000.0, 3_765_000.0, 200.0])
    header.add_extra_dims([laspy.ExtraBytesParams("amplitude", np.float64,
                                                  description="echo amplitude (dB)")])
    header.vlrs.append(laspy.VLR("LASF_Projection", 2112, "OGC WKT", WKT))
    header.global_encoding.wkt = True
    las = laspy.LasData(header)
    xyz = _surface(n, seed)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.intensity = rng.integers(0, 65535, n, dtype=np.uint16)
    las.return_number = np.ones(n, dtype=np.uint8)
    las.number_of_returns = np.ones(n, dtype=np.uint8)
    las.classification = rng.integers(0, 30, n, dtype=np.uint8)
    las.gps_time = 3e8 + np.arange(n) * 1e-4
    las.amplitude = rng.normal(10.0, 2.0, n)
    las.evlrs = VLRList([laspy.VLR("rough_test", 9, "an EVLR", b"evlr payload" * 10)])
    las.write(str(path))


def _vlr_bytes(vlr) -> bytes:
    return vlr.record_data_bytes() if hasattr(vlr, "record_data_bytes") else vlr.record_data


def _vlr_set(vlrs) -> set[tuple[str, int, bytes]]:
    skip = ("LasZipVlr", "ExtraBytesVlr")
    return {(v.user_id, v.record_id, _vlr_bytes(v)) for v in vlrs if type(v).__name__ not in skip}


def _read(path) -> laspy.LasData:
    with laspy.open(path) as reader:
        return reader.read()


def _cell_table(path) -> dict[tuple[int, int, int], dict[str, str]]:
    with open(path, newline="") as fh:
        return {(int(r["ix"]), int(r["iy"]), int(r["iz"])): r for r in csv.DictReader(fh)}


def _check_fields_equal_table(las: laspy.LasData, table, *, grid: float, origin: np.ndarray,
                              min_points: int = 3, xyz: np.ndarray | None = None) -> None:
    """Every point's added dimensions equal its cell's row of the cell table, and its cell
    index is floor((p - origin) / g) computed here from the coordinates (``xyz``: the
    unquantised ones where the file stores them rounded)."""
    if xyz is None:
        xyz = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])
    ijk = np.floor((xyz - origin) / grid).astype(np.int64)
    np.testing.assert_array_equal(ijk, np.column_stack([las.cell_ix, las.cell_iy, las.cell_iz]))
    counts: dict[tuple[int, int, int], int] = {}
    for key in map(tuple, ijk.tolist()):
        counts[key] = counts.get(key, 0) + 1
    for i, key in enumerate(map(tuple, ijk.tolist())):
        assert las.cell_points[i] == counts[key]
        row = table.get(key)
        if row is None:  # below min_points: not in the table, no value
            assert counts[key] < min_points
            for name in ("theta_odr", "theta_ols", "theta_hybrid", "e_ols"):
                assert np.isnan(las[name][i])
            continue
        for name in ("theta_odr", "theta_ols", "theta_hybrid", "e_ols"):
            want = np.float32(float(row[name])) if row[name] else np.float32(np.nan)
            got = las[name][i]
            assert (np.isnan(want) and np.isnan(got)) or got == want, (name, i)


@pytest.mark.parametrize("maker", [make_pf3, make_pf6], ids=["pf3-las12", "pf6-las14"])
@pytest.mark.parametrize("in_suffix", [".las", ".laz"])
@pytest.mark.parametrize("out_suffix", [".las", ".laz"])
def test_round_trip_keeps_everything(tmp_path, maker, in_suffix, out_suffix):
    src = tmp_path / f"scan{in_suffix}"
    maker(src)
    out = tmp_path / f"out{out_suffix}"
    cells = tmp_path / "cells.csv"
    assert main(["compute", str(src), "--grid", str(GRID), "--out", str(cells),
                 "--las-out", str(out), "--quiet"]) == 0
    a, b = _read(src), _read(out)
    # same points, same order, every original dimension (raw integers) unchanged
    assert len(b.points) == len(a.points)
    assert b.header.point_format.id == a.header.point_format.id
    assert str(b.header.version) == "1.4"
    np.testing.assert_array_equal(b.header.scales, a.header.scales)
    np.testing.assert_array_equal(b.header.offsets, a.header.offsets)
    for name in a.point_format.dimension_names:
        np.testing.assert_array_equal(np.asarray(b[name]), np.asarray(a[name]), err_msg=name)
    # the CRS and every other VLR and EVLR, byte for byte
    assert _vlr_set(a.header.vlrs) <= _vlr_set(b.header.vlrs)
    assert _vlr_set(a.header.evlrs or []) == _vlr_set(b.header.evlrs or [])
    assert b.header.global_encoding.value == a.header.global_encoding.value
    # added dimensions: types, descriptions, values = the cell table
    extra = {d.name: d for d in b.point_format.extra_dimensions}
    for name in a.point_format.extra_dimension_names:
        assert extra[name].description == {e.name: e for e in a.point_format.extra_dimensions}[
            name].description
    kinds = {"theta_odr": "f4", "theta_ols": "f4", "theta_hybrid": "f4", "e_ols": "f4",
             "cell_ix": "i4", "cell_iy": "i4", "cell_iz": "i4", "cell_points": "u4"}
    for name in POINT_FIELD_NAMES:
        assert np.dtype(extra[name].dtype).str[1:] == kinds[name], name
        assert extra[name].description
    origin = np.array([a.x.min(), a.y.min(), a.z.min()])
    _check_fields_equal_table(b, _cell_table(cells), grid=GRID, origin=origin)


def test_chunked_copy_equals_one_chunk(tmp_path):
    src = tmp_path / "scan.laz"
    make_pf3(src, n=2000)
    cloud = load_points(src, cache=False)
    fields = point_fields(grid_roughness(cloud, GRID))
    one, many = tmp_path / "one.las", tmp_path / "many.las"
    copy_las_with_fields(src, one, cloud, fields)
    copy_las_with_fields(src, many, cloud, fields, chunk_points=333)
    assert _read(one).points.array.tobytes() == _read(many).points.array.tobytes()


@pytest.mark.filterwarnings("ignore:overflow:RuntimeWarning")
def test_nonfinite_rows_keep_their_place(tmp_path):
    """Rows whose coordinates overflow (an absurd x scale) are dropped by load_points but
    kept in the copy, with NaN and no cell; every other row gets its own value."""
    src = tmp_path / "odd.las"
    n = 50
    header = laspy.LasHeader(version="1.2", point_format=1)
    header.scales = np.array([1e300, 0.001, 0.001])
    header.offsets = np.zeros(3)
    las = laspy.LasData(header)
    raw_x = np.zeros(n, dtype=np.int32)
    bad = np.array([3, 17, 18, 49])
    raw_x[bad] = 2_000_000_000  # 2e9 * 1e300 overflows to inf
    las.X = raw_x
    las.Y = np.arange(n, dtype=np.int32) * 10
    las.Z = np.arange(n, dtype=np.int32) % 7
    las.write(str(src))
    cloud = load_points(src)
    assert cloud.n == n - len(bad) and cloud.dropped_nonfinite == len(bad)
    kept_rows = np.setdiff1d(np.arange(n), bad)
    # one "cell" per cloud point whose value is the point's row in the file
    fields = PointFields(
        fields=(CellField("row", kept_rows.astype(np.int32), "file row", np.int32(-1)),
                CellField("y_m", cloud.y.astype(np.float32), "y (m)", np.float32(np.nan))),
        point_cell=np.arange(cloud.n))
    out = tmp_path / "odd_out.laz"
    copy_las_with_fields(src, out, cloud, fields, chunk_points=7)
    b = _read(out)
    expect_row = np.full(n, -1)
    expect_row[kept_rows] = kept_rows
    np.testing.assert_array_equal(b.row, expect_row)
    np.testing.assert_array_equal(np.isnan(b.y_m), np.isin(np.arange(n), bad))
    np.testing.assert_allclose(b.y_m[kept_rows], np.asarray(b.y)[kept_rows], rtol=1e-6)
    np.testing.assert_array_equal(b.X, raw_x)


def test_non_las_input_gets_las14(tmp_path):
    xyz = _surface(2500, 5)
    xyz[[10, 400]] = np.nan  # dropped by load_points: LAS cannot hold them
    src = tmp_path / "face.npy"
    np.save(src, xyz)
    out, cells = tmp_path / "face.laz", tmp_path / "cells.csv"
    assert main(["compute", str(src), "--grid", str(GRID), "--out", str(cells),
                 "--las-out", str(out), "--quiet"]) == 0
    b = _read(out)
    assert str(b.header.version) == "1.4" and b.header.point_format.id == 6
    finite = xyz[np.isfinite(xyz).all(axis=1)]
    assert len(b.points) == len(finite)
    scale = b.header.scales[0]
    assert scale == coordinate_scale(finite.min(axis=0), finite.max(axis=0),
                                     np.floor(finite.min(axis=0))) == 1e-6
    got = np.column_stack([b.x, b.y, b.z])
    assert np.max(np.abs(got - finite)) <= scale / 2 + 1e-9
    assert set(b.return_number) == {1}
    _check_fields_equal_table(b, _cell_table(cells), grid=GRID, origin=finite.min(axis=0),
                              xyz=finite)


def test_coordinate_scale_coarsens_only_where_needed():
    lo, hi = np.zeros(3), np.array([10.0, 2000.0, 1.0])
    assert coordinate_scale(lo, hi, lo) == 1e-6
    assert coordinate_scale(lo, np.array([5e4, 1.0, 1.0]), lo) == 1e-4
    assert coordinate_scale(lo, np.array([3e6, 1.0, 1.0]), lo) == 1e-2


def test_earlier_export_as_input_is_refused(tmp_path):
    src = tmp_path / "scan.las"
    make_pf3(src, n=500)
    first = tmp_path / "first.las"
    assert main(["compute", str(src), "--grid", "1", "--las-out", str(first), "--quiet"]) == 0
    cloud = load_points(first)
    fields = point_fields(grid_roughness(cloud, 1.0))
    with pytest.raises(InputError, match="already has a dimension named 'theta_odr'"):
        write_las_fields(tmp_path / "second.las", cloud, fields)
    assert not (tmp_path / "second.las").exists()


def test_full_disk_mid_copy_leaves_nothing(tmp_path, monkeypatch):
    src = tmp_path / "scan.laz"
    make_pf3(src, n=3000)
    cloud = load_points(src)
    fields = point_fields(grid_roughness(cloud, GRID))
    calls = {"n": 0}
    real = laspy.LasWriter.write_points

    def failing(self, points):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, points)

    monkeypatch.setattr(laspy.LasWriter, "write_points", failing)
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(InputError) as info:
        copy_las_with_fields(src, tmp_path / "out.laz", cloud, fields, chunk_points=1000)
    assert str(info.value) == f"cannot write {tmp_path / 'out.laz'}: no space left on device"
    assert calls["n"] == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_no_cell_fill_value():
    assert NO_CELL == -(2**31)
