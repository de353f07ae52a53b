"""What a file's header says is parsed in the reader child or bounded in bytes before
it is read (issue 36): a WKT of megabytes, a million VLRs, a GeoTIFF tag of tens of
megabytes leave the reading process (the server's own) as it was; a child may take
its limit, the parent may not grow. Peak memory is measured in a fresh process
(:func:`tests.io.crafted.parent_peak`)."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.io import load_points
from rough_viewer.io.formats.crs import read_crs
from rough_viewer.io.formats.las import MAX_CRS_RECORD_BYTES, MAX_VLRS, check_las_layout
from rough_viewer.io.sandbox import isolate
from rough_viewer.vocabulary import InputError
from tests.io import crafted
from tests.io.test_crs import WKT_FT

#: Growth of the parent's peak allowed over a small file's, bytes: the bombs below
#: cost it 474 MB (WKT), 66 MB (VLRs) and 41 MB (a tag) before issue 36.
SLACK = 8 << 20


def test_a_wkt_evlr_of_2_mb_is_refused_by_its_size_before_it_is_parsed(tmp_path):
    """2 MiB of '[': parsed at ~240 bytes a byte it took 0.5 GB; now the record's
    length is read from its header and refused (a WKT is a few kilobytes)."""
    small = crafted.with_evlr(crafted.las_14(tmp_path / "small.las"), WKT_FT.encode())
    bomb = crafted.with_evlr(crafted.las_14(tmp_path / "bomb.laz", compress=True),
                             b"[" * (2 << 20))
    ok, base = crafted.parent_peak(small)
    outcome, peak = crafted.parent_peak(bomb)
    assert ok == "ok"
    assert outcome == (f"error the CRS record 2112 of {bomb} holds {2 << 20:,} bytes; a CRS "
                       f"takes a few kilobytes (at most {MAX_CRS_RECORD_BYTES:,} are read): a "
                       "damaged or crafted file")
    assert peak - base < SLACK


def test_a_wkt_in_an_evlr_gives_the_unit_and_one_past_the_limit_does_not_load(tmp_path):
    path = crafted.with_evlr(crafted.las_14(tmp_path / "ft.las"), WKT_FT.encode() + b"\0")
    info = read_crs(path)
    assert info.unit == "us-ft" and info.epsg == 2227 and info.source == "wkt"
    cloud = load_points(path)
    assert cloud.source_unit == "us-ft"
    np.testing.assert_allclose(float(cloud.x.max()), 10.0 * 1200 / 3937, rtol=1e-3)
    # exactly the limit is read (and is no CRS: 64 KiB of spaces), one byte more is not
    at_limit = crafted.with_evlr(crafted.las_14(tmp_path / "at.las"), b" " * MAX_CRS_RECORD_BYTES)
    assert read_crs(at_limit).unit is None
    past = crafted.with_evlr(crafted.las_14(tmp_path / "past.las"),
                             b" " * (MAX_CRS_RECORD_BYTES + 1))
    with pytest.raises(InputError, match=r"the CRS record 2112 of .*past\.las holds 65,537 bytes"):
        load_points(past)


def test_a_wkt_in_a_file_not_named_projection_is_not_read(tmp_path):
    path = crafted.with_evlr(crafted.las_14(tmp_path / "other.las"), b"[" * (1 << 20),
                             user_id=b"SomeVendor")
    assert check_las_layout(path).crs_records == ()
    assert read_crs(path).unit is None and load_points(path).n == 2000


def test_a_las_of_a_million_empty_vlrs_is_refused_from_its_header(tmp_path):
    """1 M empty VLRs (54 MB) took 272 MB and 7.7 s in laspy; the count is refused
    from the raw header (a file needs a few), 300,000 here (16 MB; they took 66 MB
    in this process's read_crs) to stay quick."""
    small = crafted.las_many_vlrs(tmp_path / "few.las", 3)
    bomb = crafted.las_many_vlrs(tmp_path / "vlrs.las", 300_000)
    ok, base = crafted.parent_peak(small, "read_crs")
    outcome, peak = crafted.parent_peak(bomb, "read_crs")
    assert ok == "ok"
    assert outcome == (f"error the header of {bomb} declares 300,000 variable-length records; "
                       f"a LAS file holds a few (at most {MAX_VLRS:,} are read): a damaged or "
                       "crafted header")
    assert peak - base < SLACK
    assert load_points(crafted.las_many_vlrs(tmp_path / "many.las", MAX_VLRS)).n == 2000


@pytest.mark.skipif(not isolate.available(), reason="the tags are parsed in the reader child")
@pytest.mark.parametrize("tag", [34736, 34735])
def test_a_geotiff_tag_of_16_mb_is_parsed_in_the_child_only(tmp_path, tag):
    """GeoDoubleParams of 16 MB (2 M doubles) or a GeoKeyDirectory of 16 MB: tifffile
    parses them in the reader child; this process gets the CRS's few fields."""
    pytest.importorskip("tifffile")
    n = 2 << 20 if tag == 34736 else 8 << 20
    values = (np.ones(n, dtype=np.float64) if tag == 34736
              else np.r_[[1, 1, 0, 1, 3072, 0, 1, 32611],
                         np.zeros(n - 8, dtype=np.uint16)].astype(np.uint16))
    small = crafted.geotiff_with_tag(tmp_path / "small.tif", tag, values[:1024])
    bomb = crafted.geotiff_with_tag(tmp_path / "bomb.tif", tag, values)
    ok, base = crafted.parent_peak(small, "read_crs")
    outcome, peak = crafted.parent_peak(bomb, "read_crs")
    assert ok == outcome == "ok"
    assert read_crs(bomb).epsg == 32611
    assert peak - base < SLACK


def test_a_replaced_file_has_its_crs_read_again(tmp_path):
    """The child's answer is kept for the file's identity (name, inode, size, time)."""
    from tests.io.test_crs import WKT2_M

    path = crafted.with_evlr(crafted.las_14(tmp_path / "crs.las"), WKT_FT.encode())
    assert read_crs(path).unit == "us-ft"
    crafted.with_evlr(crafted.las_14(tmp_path / "crs.las"), WKT2_M.encode())
    info = read_crs(path)
    assert info.unit == "m" and info.epsg == 32610


def test_a_vlr_whose_length_runs_past_the_point_data_is_refused(tmp_path):
    import struct

    path = crafted.las_many_vlrs(tmp_path / "long.las", 1)
    raw = bytearray(path.read_bytes())
    header_size, offset = struct.unpack_from("<HI", raw, 94)
    struct.pack_into("<H", raw, header_size + 20, 65535)
    path.write_bytes(bytes(raw))
    with pytest.raises(InputError) as info:
        load_points(path)
    assert str(info.value) == (
        f"the header of {path} declares variable-length records reaching byte "
        f"{header_size + 54 + 65535:,}, past the {offset:,} where they must end (the point "
        "data, the 16,777,216 bytes of VLRs read, or the file's end): a damaged or crafted "
        "header")
