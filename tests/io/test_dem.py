"""io/formats/dem.py: elevation rasters as points, each cell centre one point, nodata dropped,
the georeferencing honoured; files written here byte by byte (ESRI ASCII) or with
tifffile's writer and the GeoTIFF tags set by hand."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.io import load_points
from rough_viewer.io.formats.crs import read_crs
from rough_viewer.io.formats.ply import MAX_HEADER_BYTES, MAX_HEADER_LINE
from rough_viewer.vocabulary import InputError
from tests.io import crafted

Z = np.array([[1.0, 2.0, 3.0, 4.0], [5.0, -9999.0, 7.0, 8.0], [9.0, 10.0, np.nan, 12.0]])


def centres(x0: float, y_top: float, dx: float, dy: float) -> tuple[np.ndarray, np.ndarray]:
    """Brute force: the centre of every cell, row 0 at the top, row-major."""
    xs, ys = [], []
    for r in range(Z.shape[0]):
        for c in range(Z.shape[1]):
            xs.append(x0 + c * dx)
            ys.append(y_top - r * dy)
    return np.array(xs), np.array(ys)


def write_asc(path, corner: bool = True) -> None:
    ll = ("xllcorner 1000.0\nyllcorner 2000.0\n" if corner
          else "xllcenter 1002.5\nyllcenter 2002.5\n")
    rows = "\n".join(" ".join("nan" if np.isnan(v) else f"{v:g}" for v in row) for row in Z)
    path.write_text(f"ncols 4\nnrows 3\n{ll}cellsize 5\nNODATA_value -9999\n{rows}\n")


@pytest.mark.parametrize("corner", [True, False])
def test_esri_ascii_cell_centres_and_nodata(tmp_path, corner):
    path = tmp_path / "dem.asc"
    write_asc(path, corner)
    cloud = load_points(path)
    x, y = centres(1002.5, 2012.5, 5.0, 5.0)  # the top row's centre is 2.5 m below its top
    keep = np.isfinite(Z.ravel()) & (Z.ravel() != -9999.0)
    np.testing.assert_array_equal(cloud.x, x[keep])
    np.testing.assert_array_equal(cloud.y, y[keep])
    np.testing.assert_array_equal(cloud.z, Z.ravel()[keep])
    assert cloud.n == 10 and cloud.dropped_nonfinite == 2
    assert read_crs(path).unit is None  # no .prj beside it


def test_esri_ascii_prj_gives_the_crs_and_its_unit(tmp_path):
    path = tmp_path / "dem.asc"
    write_asc(path)
    (tmp_path / "dem.prj").write_text(
        'PROJCS["NAD83 / California zone 3 (ftUS)",GEOGCS["NAD83",UNIT["degree",'
        '0.0174532925199433]],UNIT["US survey foot",0.304800609601219],'
        'AUTHORITY["EPSG","2227"]]')
    info = read_crs(path)
    assert info.unit == "us-ft" and info.epsg == 2227
    cloud = load_points(path)
    assert cloud.source_unit == "us-ft"
    np.testing.assert_allclose(cloud.x[0], 1002.5 * 1200 / 3937)


@pytest.mark.parametrize(("text", "message"), [
    ("ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n3\n", "holds 3 values"),
    ("ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\n1 2\n3 4\n", "positive cellsize"),
    ("ncols 2\nnrows 2\nxllcorner 0\ncellsize 1\n1 2\n3 4\n", "yllcorner or yllcenter"),
    ("ncols 2\nrows 2\n1 2\n", "unknown header line"),
    ("ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 x\n3 4\n", "cannot read the values"),
    ("ncols inf\nnrows 2\n1 2\n", "no whole ncols"),  # issue 36: OverflowError
    ("ncols 2\nnrows inf\n1 2\n", "no whole nrows"),
    ("ncols 2\nnrows nan\n1 2\n", "no whole nrows"),
])
def test_esri_ascii_errors_are_one_line(tmp_path, text, message):
    path = tmp_path / "bad.asc"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as info:
        load_points(path)
    assert "\n" not in str(info.value) and "bad.asc" in str(info.value)


# ----------------------------------------------------------------------------- GeoTIFF


def geokeys(*entries: tuple[int, int, int, int]) -> tuple[int, ...]:
    return (1, 1, 0, len(entries), *[v for e in entries for v in e])


def write_tif(path, *, point: bool = False, transform: np.ndarray | None = None,
              vertical: int | None = None, nodata: str | None = "-9999") -> None:
    tifffile = pytest.importorskip("tifffile")
    keys = [(1024, 0, 1, 1), (1025, 0, 1, 2 if point else 1), (3072, 0, 1, 32611)]
    if vertical is not None:
        keys.append((4099, 0, 1, vertical))
    directory = geokeys(*keys)
    tags = [(34735, "H", len(directory), directory, True)]
    if transform is None:
        tags += [(33550, "d", 3, (5.0, 5.0, 0.0), True),
                 (33922, "d", 6, (0.0, 0.0, 0.0, 1000.0, 2015.0, 0.0), True)]
    else:
        tags.append((34264, "d", 16, tuple(transform.ravel()), True))
    if nodata is not None:
        tags.append((42113, "s", 0, nodata, True))
    tifffile.imwrite(path, Z.astype(np.float32), extratags=tags)


def test_geotiff_pixel_is_area_and_point(tmp_path):
    area, point = tmp_path / "area.tif", tmp_path / "point.tif"
    write_tif(area)
    write_tif(point, point=True)
    keep = np.isfinite(Z.ravel()) & (Z.ravel() != -9999.0)
    a = load_points(area)
    x, y = centres(1002.5, 2012.5, 5.0, 5.0)  # the tie point is the top-left corner
    np.testing.assert_array_equal(a.x, x[keep])
    np.testing.assert_array_equal(a.y, y[keep])
    np.testing.assert_array_equal(a.z, Z.ravel()[keep])
    assert a.dropped_nonfinite == 2
    p = load_points(point)
    x, y = centres(1000.0, 2015.0, 5.0, 5.0)  # the tie point is the top-left centre
    np.testing.assert_array_equal(p.x, x[keep])
    np.testing.assert_array_equal(p.y, y[keep])
    info = read_crs(area)
    assert info.epsg == 32611 and info.unit == "m" and info.source == "geotiff"


def test_geotiff_transformation_matrix_with_rotation(tmp_path):
    """ModelTransformationTag: raster (i, j) -> model by an affine matrix (rotation
    30 degrees, 2 m pixels); centres at (c + 0.5, r + 0.5)."""
    a = np.radians(30)
    m = np.eye(4)
    m[:2, :2] = 2.0 * np.array([[np.cos(a), -np.sin(a)], [-np.sin(a), -np.cos(a)]])
    m[:2, 3] = (500.0, 800.0)
    path = tmp_path / "rot.tif"
    write_tif(path, transform=m, nodata=None)
    cloud = load_points(path)
    keep = np.isfinite(Z.ravel())
    r, c = np.divmod(np.arange(Z.size), Z.shape[1])
    model = m @ np.vstack([c + 0.5, r + 0.5, np.zeros(Z.size), np.ones(Z.size)])
    np.testing.assert_allclose(cloud.x, model[0][keep], rtol=1e-14)
    np.testing.assert_allclose(cloud.y, model[1][keep], rtol=1e-14)
    assert cloud.n == 11  # -9999 stays a height without a nodata tag


def test_geotiff_vertical_feet_are_converted(tmp_path, capsys):
    path = tmp_path / "usft.tif"
    write_tif(path, vertical=9003)
    cloud = load_points(path)
    np.testing.assert_allclose(cloud.z[:3], np.array([1.0, 2.0, 3.0]) * 1200 / 3937)
    assert "z in US ft but x, y in m: z is converted to m" in cloud.warnings[0]
    assert main(["compute", str(path), "--grid", "20", "--summary-json",
                 str(tmp_path / "s.json"), "--quiet"]) == 0
    assert capsys.readouterr().err.count("z is converted") == 1


def test_geotiff_without_georeferencing_or_without_tifffile(tmp_path, monkeypatch):
    tifffile = pytest.importorskip("tifffile")
    path = tmp_path / "plain.tif"
    tifffile.imwrite(path, Z.astype(np.float32))
    with pytest.raises(InputError, match="TIFF without georeferencing"):
        load_points(path)
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "tifffile" else real(name, *a))
    with pytest.raises(InputError, match=r"needs the optional package tifffile: pip install "
                       r"'rough_viewer\[dem\]'"):
        load_points(path)


def test_dem_through_compute(tmp_path, capsys):
    """A 60 x 80 ESRI grid of a tilted plane with a bump: compute reads it like any
    cloud (one point per cell centre)."""
    rows, cols = 60, 80
    r, c = np.mgrid[0:rows, 0:cols]
    z = 0.1 * c + 0.05 * r + 0.2 * np.exp(-((c - 40) ** 2 + (r - 30) ** 2) / 50.0)
    path = tmp_path / "plane.asc"
    body = "\n".join(" ".join(f"{v:.6f}" for v in row) for row in z)
    path.write_text(f"ncols {cols}\nnrows {rows}\nxllcorner 0\nyllcorner 0\ncellsize 1\n{body}\n")
    assert main(["compute", str(path), "--grid", "10", "--summary-json",
                 str(tmp_path / "s.json"), "--quiet"]) == 0
    assert "4,800 points, grid 10 m" in capsys.readouterr().out
    assert struct.calcsize("<H") == 2  # GeoKeys are little-endian uint16 words


def _peak_rss_reading(path) -> tuple[int, str]:
    """(peak resident bytes of a fresh process that reads ``path``, its error line)."""
    import subprocess
    import sys

    script = ("import resource, sys\n"
              "from rough_viewer.io import load_points\n"
              "from rough_viewer.vocabulary import InputError\n"
              "try:\n    load_points(sys.argv[1])\n    said = 'read'\n"
              "except InputError as e:\n    said = str(e)\n"
              "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)\n"
              "print(said)\n")
    done = subprocess.run([sys.executable, "-c", script, str(path)], capture_output=True,
                          text=True, timeout=120, env={**__import__("os").environ,
                                                       "ROUGH_VIEWER_ISOLATE": "0"})
    assert done.returncode == 0, done.stderr[-2000:]
    peak, said = done.stdout.splitlines()[-2:]
    return int(peak), said


def test_an_esri_header_line_bomb_is_refused_without_reading_it(tmp_path):
    """Issue 36: a header line of letters was read whole (512 MB took the process to
    1.1 GB). 48 MB of it now costs the reading process less than 16 MB more than a
    valid grid, and says so in one line."""
    good = tmp_path / "good.asc"
    write_asc(good)
    bomb = tmp_path / "bomb.asc"
    with open(bomb, "w") as fh:
        fh.write("ncols ")
        fh.write("x" * (48 << 20))
        fh.write("\nnrows 2\n")
    base, said = _peak_rss_reading(good)
    assert said == "read"
    peak, said = _peak_rss_reading(bomb)
    assert "header line longer than 65,536 bytes" in said and "bomb.asc" in said
    assert peak - base < 16 << 20, (peak - base) / 2**20


def test_an_esri_value_line_bomb_is_read_in_pieces(tmp_path):
    """A data line of 48 MB without a break is one value too long: read in 1 MiB pieces,
    never whole."""
    good = tmp_path / "good.asc"
    write_asc(good)
    bomb = tmp_path / "bomb.asc"
    with open(bomb, "w") as fh:
        fh.write("ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n")
        fh.write("1" * (48 << 20))
    base, _ = _peak_rss_reading(good)
    peak, said = _peak_rss_reading(bomb)
    assert "holds a value longer than 1,048,576 characters" in said
    assert peak - base < 16 << 20, (peak - base) / 2**20


def test_an_esri_grid_on_one_long_line_reads_as_one_row_a_line(tmp_path):
    """Values may all stand on one line longer than a piece (1.3 MB here): the values
    cut at a piece's end are joined again, so both layouts give the same points."""
    rows, cols = 400, 400
    z = np.round(np.random.default_rng(3).uniform(100, 999, (rows, cols)), 3)
    head = f"ncols {cols}\nnrows {rows}\nxllcorner 0\nyllcorner 0\ncellsize 1\n"
    by_row, one_line = tmp_path / "rows.asc", tmp_path / "line.asc"
    by_row.write_text(head + "\n".join(" ".join(f"{v:.3f}" for v in r) for r in z) + "\n")
    one_line.write_text(head + " ".join(f"{v:.3f}" for v in z.ravel()))
    assert one_line.stat().st_size > 1 << 20
    a, b = load_points(by_row), load_points(one_line)
    assert a.n == b.n == rows * cols
    np.testing.assert_array_equal(a.z, b.z)
    np.testing.assert_array_equal(np.sort(a.z), np.sort(z.ravel()))


@pytest.mark.parametrize("nodata, fill", [
    ("-9999.9", np.float32(-9999.9)),
    ("-3.40282e+38", np.float32(-3.4028234663852886e38)),  # GDAL's float32 lowest, printed
    ("-3.4028234663852886e+38", np.float32(-3.4028234663852886e38)),
])
def test_geotiff_nodata_is_compared_in_the_bands_type(tmp_path, nodata, fill):
    """Issue 36: a float32 band's GDAL_NODATA compared in float64 kept its nodata cells
    as points at -9999.9 (or refused the file at -3.4e38 m). Compared as GDAL does, the
    cells that hold it are dropped and the others kept exactly."""
    tifffile = pytest.importorskip("tifffile")
    band = np.arange(12, dtype=np.float32).reshape(3, 4) + 100.25
    band[0, 1] = band[2, 3] = fill
    tags = [(34735, "H", 8, geokeys((1024, 0, 1, 1)), True),
            (33550, "d", 3, (1.0, 1.0, 0.0), True),
            (33922, "d", 6, (0.0, 0.0, 0.0, 0.0, 3.0, 0.0), True),
            (42113, "s", 0, nodata, True)]
    path = tmp_path / "band.tif"
    tifffile.imwrite(path, band, extratags=tags)
    cloud = load_points(path)
    keep = band.ravel() != fill
    assert cloud.n == 10 and cloud.dropped_nonfinite == 2
    np.testing.assert_array_equal(cloud.z, band.ravel()[keep].astype(np.float64))


def test_a_complex_geotiff_is_refused_in_one_line(tmp_path):
    """Issue 36: a complex64 band was read as its real part without a word."""
    tifffile = pytest.importorskip("tifffile")
    path = tmp_path / "c.tif"
    tifffile.imwrite(path, np.ones((3, 4), dtype=np.complex64), extratags=[
        (34735, "H", 8, geokeys((1024, 0, 1, 1)), True),
        (33550, "d", 3, (1.0, 1.0, 0.0), True),
        (33922, "d", 6, (0.0, 0.0, 0.0, 0.0, 3.0, 0.0), True)])
    with pytest.raises(InputError, match="complex64 values, not heights") as info:
        load_points(path)
    assert "\n" not in str(info.value) and "c.tif" in str(info.value)


def test_a_prj_bomb_beside_a_grid_is_refused_before_it_is_read(tmp_path):
    """Issue 36: a .prj's WKT was read and parsed whole (about 240 bytes of memory a
    byte); over 64 KiB it is refused in one line naming it."""
    path = tmp_path / "dem.asc"
    write_asc(path)
    (tmp_path / "dem.prj").write_text("[" * (1 << 20))
    with pytest.raises(InputError, match=r"dem.prj is longer than the 65,536 bytes a CRS"):
        read_crs(path)
# ----------------------------------------------------------------------------- hostile rasters


def test_an_esri_header_line_of_48_mb_is_refused_without_being_read(tmp_path):
    """The header is read in this process (for the memory estimate): a line is read
    at most 64 KiB far, so a 48 MB line costs this process nothing (it cost 2.2 bytes
    a byte of the line: about 105 MB here)."""
    small = crafted.asc_header_bomb(tmp_path / "small.asc", 1 << 20)
    bomb = crafted.asc_header_bomb(tmp_path / "bomb.asc", 48 << 20)
    outcome_small, base = crafted.parent_peak(small)
    outcome, peak = crafted.parent_peak(bomb)
    assert outcome == (f"error {bomb} is not an ESRI ASCII grid: a header line longer than "
                       f"{MAX_HEADER_LINE:,} bytes or a header longer than {MAX_HEADER_BYTES:,}")
    assert outcome_small.startswith("error ")
    assert peak - base < 8 << 20  # 48 MB of line: under 0.17 bytes a byte


def test_a_data_line_of_any_length_is_not_read_by_the_header(tmp_path):
    """A first row of 200,000 values (1.2 MB, longer than a header line may be) is data."""
    path = tmp_path / "wide.asc"
    cols = 200_000
    row = " ".join(["1.5"] * cols)
    path.write_text(f"ncols {cols}\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n{row}\n{row}\n")
    cloud = load_points(path)
    assert cloud.n == 2 * cols and float(cloud.z.min()) == float(cloud.z.max()) == 1.5


@pytest.mark.parametrize("value", ["inf", "-inf", "nan", "1e400", "2.5", "0"])
def test_esri_ncols_or_nrows_not_a_whole_count_is_one_line(tmp_path, value):
    for key in ("ncols", "nrows"):
        path = tmp_path / f"{key}.asc"
        head = {"ncols": "2", "nrows": "2", key: value}
        path.write_text(f"ncols {head['ncols']}\nnrows {head['nrows']}\nxllcorner 0\n"
                        "yllcorner 0\ncellsize 1\n1 2\n3 4\n")
        with pytest.raises(InputError) as info:
            load_points(path)
        assert str(info.value).startswith(f"{path} is not an ESRI ASCII grid: no whole {key} "
                                          "in its header (it gives ")


def write_band(path, z: np.ndarray, nodata: str | None) -> None:
    """A GeoTIFF of ``z`` in its own dtype, 1 m pixels from (0, 0)."""
    tifffile = pytest.importorskip("tifffile")
    tags = [(33550, "d", 3, (1.0, 1.0, 0.0), True),
            (33922, "d", 6, (0.0, 0.0, 0.0, 0.0, float(z.shape[0]), 0.0), True)]
    if nodata is not None:
        tags.append((42113, "s", 0, nodata, True))
    tifffile.imwrite(path, z, extratags=tags)


@pytest.mark.parametrize(("dtype", "nodata", "cell"), [
    (np.float32, "-9999.9", np.float32(-9999.9)),
    (np.float32, "-3.40282e+38", np.float32(-3.40282e38)),
    (np.float32, "-3.4028234663852886e+38", np.finfo(np.float32).min),
    (np.float32, "-3.40282346638529e+38", np.finfo(np.float32).min),  # GDAL's rounding rule
    (np.float64, "-9999.9", -9999.9),
    (np.int16, "-32768", np.int16(-32768)),
    (np.uint8, "255", np.uint8(255)),
])
def test_geotiff_nodata_is_compared_in_the_bands_own_type(tmp_path, dtype, nodata, cell):
    z = np.arange(12, dtype=dtype).reshape(3, 4) + dtype(1)
    z[1, 2] = cell
    z[2, 0] = cell
    path = tmp_path / "band.tif"
    write_band(path, z, nodata)
    cloud = load_points(path)
    assert cloud.n == 10 and cloud.dropped_nonfinite == 2
    keep = np.ones(12, dtype=bool)
    keep[[6, 8]] = False
    np.testing.assert_array_equal(cloud.z, (np.arange(12) + 1.0)[keep])


@pytest.mark.parametrize(("dtype", "nodata"), [(np.int16, "-40000"), (np.int16, "-1.5"),
                                               (np.uint8, "-1"), (np.float32, "nan")])
def test_geotiff_nodata_outside_the_bands_type_marks_no_cell(tmp_path, dtype, nodata):
    z = np.arange(12, dtype=dtype).reshape(3, 4)
    path = tmp_path / "band.tif"
    write_band(path, z, nodata)
    cloud = load_points(path)
    assert cloud.n == 12 and cloud.dropped_nonfinite == 0


def test_a_complex_geotiff_is_refused_not_read_as_its_real_part(tmp_path):
    z = (np.arange(12) + 1j * np.arange(12)).astype(np.complex64).reshape(3, 4)
    path = tmp_path / "complex.tif"
    write_band(path, z, None)
    with pytest.raises(InputError) as info:
        load_points(path)
    assert str(info.value) == (f"{path} holds complex64 values, not heights (an elevation "
                               "raster holds real numbers): not read")
