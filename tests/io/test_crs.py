"""io/formats/crs.py: the CRS and linear unit of LAS/LAZ files, from WKT and GeoTIFF records
written here byte by byte."""

from __future__ import annotations

import struct

import laspy
import numpy as np
import pytest

from rough_viewer.io.formats import crs as crs_module
from rough_viewer.io.formats.crs import CrsInfo, parse_geotiff_keys, parse_wkt_crs, read_crs

WKT_FT = (
    'PROJCS["NAD83 / California zone 3 (ftUS)",GEOGCS["NAD83",DATUM["North_American_Datum_1983",'
    'SPHEROID["GRS 1980",6378137,298.257222101]],PRIMEM["Greenwich",0],'
    'UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4269"]],'
    'PROJECTION["Lambert_Conformal_Conic_2SP"],UNIT["US survey foot",0.304800609601219,'
    'AUTHORITY["EPSG","9003"]],AUTHORITY["EPSG","2227"]]'
)
WKT2_M = (
    'PROJCRS["WGS 84 / UTM zone 10N",BASEGEOGCRS["WGS 84",DATUM["World Geodetic System 1984",'
    'ELLIPSOID["WGS 84",6378137,298.257223563,LENGTHUNIT["metre",1]]],'
    'ANGLEUNIT["degree",0.0174532925199433]],CONVERSION["UTM zone 10N",METHOD["Transverse Mercator"]],'
    'CS[Cartesian,2],AXIS["easting",east,ORDER[1],LENGTHUNIT["metre",1]],'
    'AXIS["northing",north,ORDER[2],LENGTHUNIT["metre",1]],ID["EPSG",32610]]'
)


#: A compound CRS (WKT 1): UTM 11N in metres, NAVD88 heights in US survey feet.
WKT_COMPOUND = (
    'COMPD_CS["NAD83 / UTM zone 11N + NAVD88 height (ftUS)",PROJCS["NAD83 / UTM zone 11N",'
    'GEOGCS["NAD83",DATUM["North_American_Datum_1983",SPHEROID["GRS 1980",6378137,298.257222101]],'
    'PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],'
    'PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",-117],'
    'PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],'
    'PARAMETER["false_northing",0],UNIT["metre",1],AUTHORITY["EPSG","26911"]],'
    'VERT_CS["NAVD88 height (ftUS)",VERT_DATUM["North American Vertical Datum 1988",2005],'
    'UNIT["US survey foot",0.304800609601219],AXIS["Up",UP]]]'
)
#: The same in WKT 2.
WKT2_COMPOUND = (
    'COMPOUNDCRS["UTM 10N + height (ft)",' + WKT2_M + ','
    'VERTCRS["NAVD88 height (ft)",VDATUM["North American Vertical Datum 1988"],'
    'CS[vertical,1],AXIS["gravity-related height (H)",up,LENGTHUNIT["foot",0.3048]]]]'
)


@pytest.fixture(params=["pyproj", "fallback"])
def wkt_reader(request, monkeypatch):
    """Each CRS test twice: through pyproj (where installed) and through the reader
    here, pyproj forced off."""
    if request.param == "pyproj":
        pytest.importorskip("pyproj")
    else:
        monkeypatch.setattr(crs_module, "_pyproj", lambda: None)
    return request.param


def _geokeys(entries: list[tuple[int, int, int, int]]) -> bytes:
    words = [1, 1, 0, len(entries)] + [v for e in entries for v in e]
    return struct.pack(f"<{len(words)}H", *words)


def _las_with(tmp_path, name: str, vlrs: list[laspy.VLR], *, version="1.2", fmt=3):
    hdr = laspy.LasHeader(point_format=fmt, version=version)
    hdr.scales = np.array([0.01, 0.01, 0.01])
    for v in vlrs:
        hdr.vlrs.append(v)
    las = laspy.LasData(hdr)
    las.x = np.array([0.0, 1.0, 2.0])
    las.y = np.array([0.0, 1.0, 0.0])
    las.z = np.array([0.0, 0.0, 1.0])
    path = tmp_path / name
    las.write(str(path))
    return path


def test_wkt_units_by_conversion_factor(wkt_reader):
    assert parse_wkt_crs(WKT_FT).unit == "us-ft"
    assert parse_wkt_crs(WKT_FT).epsg == 2227
    info = parse_wkt_crs(WKT2_M)
    assert (info.unit, info.epsg, info.geographic) == ("m", 32610, False)
    geo = parse_wkt_crs('GEOGCS["WGS 84",UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]')
    assert (geo.unit, geo.epsg, geo.geographic) == (None, 4326, True)
    ft = parse_wkt_crs('PROJCS["x",GEOGCS["y",UNIT["degree",0.01745]],UNIT["foot",0.3048]]')
    assert ft.unit == "ft" and ft.epsg is None


def test_geotiff_keys_units_and_codes(wkt_reader):
    # projected, EPSG 2227, ProjLinearUnits 9003 (US survey foot), vertical 9002 (foot)
    info = parse_geotiff_keys(_geokeys([(1024, 0, 1, 1), (3072, 0, 1, 2227), (3076, 0, 1, 9003),
                                        (4099, 0, 1, 9002)]))
    assert (info.unit, info.epsg, info.vertical_unit) == ("us-ft", 2227, "ft")
    assert info.description == "EPSG:2227"
    # citation in the ASCII params, user-defined CRS code, metres
    text = b"my local grid|\0"
    info = parse_geotiff_keys(_geokeys([(1024, 0, 1, 1), (3072, 0, 1, 32767), (3076, 0, 1, 9001),
                                        (3073, 34737, len(text) - 1, 0)]), b"", text)
    assert (info.unit, info.epsg, info.description) == ("m", None, "my local grid")
    # a UTM code alone gives metres
    assert parse_geotiff_keys(_geokeys([(1024, 0, 1, 1), (3072, 0, 1, 32611)])).unit == "m"


def test_compound_crs_gives_its_vertical_unit(wkt_reader):
    info = parse_wkt_crs(WKT_COMPOUND)
    assert (info.unit, info.vertical_unit, info.epsg, info.geographic) == ("m", "us-ft", 26911, False)
    info = parse_wkt_crs(WKT2_COMPOUND)
    assert (info.unit, info.vertical_unit, info.epsg, info.geographic) == ("m", "ft", 32610, False)
    vertical = parse_wkt_crs('VERT_CS["h",VERT_DATUM["d",2005],UNIT["foot",0.3048]]')
    assert vertical.vertical_unit == "ft"


def test_pyproj_reads_what_the_fallback_cannot():
    """A bound CRS (WKT 1 with TOWGS84) whose unit sits after a nested GEOGCS, and a
    GeoTIFF vertical CRS given by its EPSG code alone: PROJ knows both."""
    pytest.importorskip("pyproj")
    bound = parse_wkt_crs(
        'PROJCS["x",GEOGCS["g",DATUM["d",SPHEROID["s",6378137,298.25],TOWGS84[0,0,0,0,0,0,0]],'
        'PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],'
        'PROJECTION["Transverse_Mercator"],UNIT["foot",0.3048],AUTHORITY["EPSG","2229"]]')
    assert (bound.unit, bound.epsg, bound.geographic) == ("ft", 2229, False)
    # VerticalCSTypeGeoKey 6360 (NAVD88 height (ftUS)), no VerticalUnitsGeoKey
    keys = parse_geotiff_keys(_geokeys([(1024, 0, 1, 1), (3072, 0, 1, 26911), (4096, 0, 1, 6360)]))
    assert (keys.unit, keys.vertical_unit) == ("m", "us-ft")


def test_a_las_compound_crs_is_parsed_in_the_reader_child(tmp_path, monkeypatch):
    """With reads isolated, the WKT of a LAS file (pyproj or not) is parsed in the
    child: the parent's parser is never called, and z in US feet converts."""
    pytest.importorskip("pyproj")
    from rough_viewer.io.load import axis_units
    from rough_viewer.io.sandbox import isolate

    if not isolate.available():
        pytest.skip("reads are not isolated here")

    def not_here():
        raise AssertionError("pyproj asked for in the parent")

    monkeypatch.setattr(crs_module, "_pyproj", not_here)
    path = _las_with(tmp_path, "compound.las",
                     [laspy.VLR("LASF_Projection", 2112, "", WKT_COMPOUND.encode() + b"\0")],
                     version="1.4", fmt=6)
    info = read_crs(path)
    assert (info.unit, info.vertical_unit, info.epsg, info.source) == ("m", "us-ft", 26911, "wkt")
    assert axis_units(path, None)[:2] == ("m", "us-ft")
    gt = _las_with(tmp_path, "gt.las", [laspy.VLR("LASF_Projection", 34735, "", _geokeys(
        [(1024, 0, 1, 1), (3072, 0, 1, 26911), (4096, 0, 1, 6360)]))])
    assert read_crs(gt).vertical_unit == "us-ft"  # the EPSG look-up ran in the child too


def test_read_crs_from_las_records(tmp_path):
    wkt = _las_with(tmp_path, "wkt.las", [laspy.VLR("LASF_Projection", 2112, "", WKT_FT.encode() + b"\0")],
                    version="1.4", fmt=6)
    assert read_crs(wkt).unit == "us-ft"
    gt = _las_with(tmp_path, "gt.las", [laspy.VLR("LASF_Projection", 34735, "",
                                                  _geokeys([(1024, 0, 1, 1), (3072, 0, 1, 26911),
                                                            (3076, 0, 1, 9002)]))])
    info = read_crs(gt)
    assert (info.unit, info.epsg, info.source) == ("ft", 26911, "geotiff")
    assert read_crs(_las_with(tmp_path, "none.las", [])) == CrsInfo()
    np.save(tmp_path / "p.npy", np.zeros((3, 3)))
    assert read_crs(tmp_path / "p.npy") == CrsInfo()


def test_unreadable_header_names_the_file(tmp_path):
    bad = tmp_path / "bad.las"
    bad.write_bytes(b"LASF" + b"\0" * 20)
    with pytest.raises(ValueError, match="bad.las"):
        read_crs(bad)


def test_units_warnings_name_the_files_own_units(tmp_path):
    """A metre CRS with metre heights read with --units ft: one warning (the
    contradiction), not a second one claiming the file gives x, y in feet; a file
    whose heights are in feet under a metre CRS gets its own warning."""
    from rough_viewer.io.load import resolve_units

    def keys(vertical: int) -> laspy.VLR:
        return laspy.VLR("LASF_Projection", 34735, "", _geokeys(
            [(1024, 0, 1, 1), (3072, 0, 1, 32611), (3076, 0, 1, 9001), (4099, 0, 1, vertical)]))

    metric = _las_with(tmp_path, "m.las", [keys(9001)])
    assert resolve_units(metric, None) == ("m", ())
    unit, notes = resolve_units(metric, "ft")
    assert unit == "ft" and len(notes) == 1
    assert "--units ft contradicts the CRS" in notes[0] and "m.las" in notes[0]
    mixed = _las_with(tmp_path, "mixed.las", [keys(9002)])
    unit, notes = resolve_units(mixed, None)
    assert unit == "m" and len(notes) == 1
    assert notes[0].endswith("gives z in ft but x, y in m: z is converted to m (x 0.3048), "
                             "as a reprojection would")


def test_a_vertical_unit_of_its_own_converts_z(tmp_path):
    """x, y in metres and z in US survey feet: z is converted by 1200/3937 (as a
    reprojection to a metre CRS would), in memory and in chunks alike; --units
    overrides both axes; the warning is said once."""
    from rough_viewer.io.load import axis_units, load_points
    from rough_viewer.scale.sources import chunk_plan, open_sources, read_chunk

    vlr = laspy.VLR("LASF_Projection", 34735, "", _geokeys(
        [(1024, 0, 1, 1), (3072, 0, 1, 32611), (3076, 0, 1, 9001), (4099, 0, 1, 9003)]))
    path = _las_with(tmp_path, "usft.las", [vlr])
    assert axis_units(path, None)[:2] == ("m", "us-ft")
    cloud = load_points(path)
    np.testing.assert_allclose(cloud.z, [0.0, 0.0, 1200 / 3937], rtol=1e-15)
    np.testing.assert_allclose(cloud.x, [0.0, 1.0, 2.0])
    assert cloud.source_unit == "m" and len(cloud.warnings) == 1
    assert "z in US ft but x, y in m: z is converted to m (x 0.3048006)" in cloud.warnings[0]
    sources = open_sources([path])
    (chunk,) = chunk_plan(sources, 10)
    x, y, z = read_chunk(sources[0], chunk)
    np.testing.assert_array_equal(z, cloud.z)
    np.testing.assert_allclose(sources[0].bounds_max, [2.0, 1.0, 1200 / 3937])
    asked = load_points(path, units="m")
    np.testing.assert_allclose(asked.z, [0.0, 0.0, 1.0])

