"""``rough-viewer index``: COPC files read back by laspy's CopcReader, checked
against the inputs by brute force."""

from __future__ import annotations

import numpy as np
import pytest

laspy = pytest.importorskip("laspy")
pytest.importorskip("lazrs")

from laspy.copc import Bounds  # noqa: E402

from rough_viewer.cli import main  # noqa: E402
from rough_viewer.io.copc import octree  # noqa: E402

WKT = ('PROJCS["WGS 84 / UTM zone 10N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",'
       '6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],'
       'PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",-123],'
       'PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],'
       'PARAMETER["false_northing",0],UNIT["metre",1],AUTHORITY["EPSG","32610"]]')


def _make(path, fmt, n, x0, seed, *, extra=True):
    rng = np.random.default_rng(seed)
    h = laspy.LasHeader(point_format=fmt, version="1.4")
    h.scales = np.array([0.001, 0.001, 0.001])
    h.offsets = np.array([500.0, 4000.0, 10.0])
    if extra:
        h.add_extra_dim(laspy.ExtraBytesParams(name="amp", type=np.float32))
    h.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(WKT))
    las = laspy.LasData(h)
    t = rng.random(n) * 4
    las.x = 500 + x0 + t
    las.y = 4000 + rng.random(n) * 4
    las.z = 10 + np.sin(t) + rng.normal(0, 0.01, n)
    las.intensity = rng.integers(0, 60000, n)
    las.classification = rng.integers(0, 20, n)
    las.return_number = rng.integers(1, 4, n)
    las.number_of_returns = np.full(n, 3)
    las.user_data = rng.integers(0, 255, n)
    las.point_source_id = rng.integers(0, 9, n)
    las.gps_time = rng.random(n) * 1000
    if fmt == 3:
        las.scan_angle_rank = rng.integers(-90, 90, n)
        las.red = rng.integers(0, 65535, n)
        las.green = rng.integers(0, 65535, n)
        las.blue = rng.integers(0, 65535, n)
    else:
        las.scan_angle = rng.integers(-15000, 15000, n)
    if extra:
        las.amp = rng.random(n).astype(np.float32)
    las.write(path)
    return laspy.read(path)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("campaign")
    ins = [_make(d / "a.laz", 6, 30_000, 0.0, 1), _make(d / "b.laz", 6, 20_000, 3.0, 2),
           _make(d / "c.laz", 3, 25_000, 1.5, 3)]
    out = d / "all.copc.laz"
    # a small budget: several buckets, several depths
    assert main(["index", str(d / "*.laz"), "--out", str(out), "--memory", "8MB", "--quiet"]) == 0
    return d, ins, out


def _sorted(x, y, z):
    o = np.lexsort((z, y, x))
    return np.stack([x[o], y[o], z[o]], axis=1), o


def test_every_point_and_dimension_read_back(campaign):
    _, ins, out = campaign
    with laspy.CopcReader.open(out) as r:
        assert r.header.point_format.id == 7  # the format 3 input has colours
        assert r.header.point_count == 75_000
        got = r.query()
    assert len(got) == 75_000
    X = np.concatenate([np.asarray(s.X) for s in ins])
    Y = np.concatenate([np.asarray(s.Y) for s in ins])
    Z = np.concatenate([np.asarray(s.Z) for s in ins])
    want, wo = _sorted(X, Y, Z)
    have, ho = _sorted(np.asarray(got.X), np.asarray(got.Y), np.asarray(got.Z))
    np.testing.assert_array_equal(have, want)  # same integers: same scale and offset
    for name in ("intensity", "classification", "return_number", "number_of_returns",
                 "user_data", "point_source_id", "gps_time", "amp"):
        src = np.concatenate([np.asarray(s[name]) for s in ins])
        np.testing.assert_array_equal(np.asarray(got[name])[ho], src[wo], err_msg=name)
    colour = np.concatenate([np.zeros(50_000), np.asarray(ins[2].red)])
    np.testing.assert_array_equal(np.asarray(got.red)[ho], colour[wo])
    angle = np.concatenate([np.asarray(ins[0].scan_angle), np.asarray(ins[1].scan_angle),
                            np.round(np.asarray(ins[2].scan_angle_rank) / 0.006)])
    np.testing.assert_array_equal(np.asarray(got.scan_angle)[ho], angle[wo])


def test_bounds_and_level_queries_equal_brute_force(campaign):
    _, ins, out = campaign
    X = np.concatenate([np.asarray(s.X) for s in ins])
    Y = np.concatenate([np.asarray(s.Y) for s in ins])
    Z = np.concatenate([np.asarray(s.Z) for s in ins])
    rng = np.random.default_rng(7)
    with laspy.CopcReader.open(out) as r:
        sc, of = r.header.scales, r.header.offsets
        for _ in range(5):
            lo = np.array([500.0, 4000.0, 9.0]) + rng.random(3) * [4, 3, 1]
            hi = lo + rng.random(3) * [3, 2, 1.5]
            ilo, ihi = np.round((lo - of) / sc), np.round((hi - of) / sc)
            inside = ((X >= ilo[0]) & (X <= ihi[0]) & (Y >= ilo[1]) & (Y <= ihi[1])
                      & (Z >= ilo[2]) & (Z <= ihi[2]))
            got = r.query(bounds=Bounds(mins=lo, maxs=hi))
            want, _ = _sorted(X[inside], Y[inside], Z[inside])
            have, _ = _sorted(np.asarray(got.X), np.asarray(got.Y), np.asarray(got.Z))
            np.testing.assert_array_equal(have, want)
        depths = sorted({k.level for k in r.root_page.entries})
        assert len(depths) >= 3
        per_level = [r.query(level=d) for d in depths]
        cube = octree.Cube(tuple(r.copc_info.center), r.copc_info.halfsize)
    assert sum(len(p) for p in per_level) == 75_000
    # level 0: one point per level-of-detail cell of the root (an even subset)
    root = per_level[0]
    q = octree.quantize(np.stack([root.x, root.y, root.z], axis=1), cube)
    cells = octree.cell_codes(q, 0)
    assert np.unique(cells).size == cells.size
    q_all = octree.quantize(np.stack([X * sc[0] + of[0], Y * sc[1] + of[1],
                                      Z * sc[2] + of[2]], axis=1), cube)
    assert cells.size == np.unique(octree.cell_codes(q_all, 0)).size  # every cell filled


def test_hierarchy_consistent(campaign):
    _, _, out = campaign
    with laspy.CopcReader.open(out) as r:
        entries = r.root_page.entries
        info = r.copc_info
        size = out.stat().st_size
    assert sum(e.point_count for e in entries.values()) == 75_000
    keys = {(k.level, k.x, k.y, k.z) for k in entries}
    for d, x, y, z in keys:
        assert 0 <= x < 2 ** d and 0 <= y < 2 ** d and 0 <= z < 2 ** d
        if d:
            assert (d - 1, x // 2, y // 2, z // 2) in keys
    spans = sorted((e.offset, e.offset + e.byte_size) for e in entries.values())
    assert all(a[1] <= b[0] for a, b in zip(spans, spans[1:], strict=False))  # no overlap
    assert spans[-1][1] < info.hierarchy_root_offset < size
    assert info.spacing == pytest.approx(2 * info.halfsize / 128)


def test_crs_kept_and_copc_vlr_first(campaign):
    _, _, out = campaign
    with laspy.open(out) as r:
        vlrs = r.header.vlrs
        assert vlrs[0].user_id == "copc" and vlrs[0].record_id == 1
        wkt = [v for v in vlrs if v.record_id == 2112]
        assert wkt and "EPSG\",\"32610" in wkt[0].string
        assert r.header.version.minor == 4
        assert r.header.global_encoding.wkt


def test_existing_output_refused_without_force(campaign, capsys):
    d, _, out = campaign
    before = out.read_bytes()
    assert main(["index", str(d / "a.laz"), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "exists" in err and "--force" in err and len(err.strip().splitlines()) == 1
    assert out.read_bytes() == before
    other = d / "forced.copc.laz"
    other.write_bytes(b"old")
    assert main(["index", str(d / "a.laz"), "--out", str(other), "--force", "--quiet"]) == 0
    with laspy.CopcReader.open(other) as r:
        assert len(r.query()) == 30_000


def test_bad_input_one_line_no_output(tmp_path, capsys):
    good = tmp_path / "good.laz"
    _make(good, 6, 1000, 0.0, 4, extra=False)
    bad = tmp_path / "bad.laz"
    bad.write_bytes(good.read_bytes()[:2000])  # cut short: the points cannot be decoded
    out = tmp_path / "o.copc.laz"
    assert main(["index", str(good), str(bad), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rough-viewer: error:") and "bad.laz" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.laz", "good.laz"]


def test_subtree_places_every_point_once():
    rng = np.random.default_rng(0)
    q = rng.integers(0, 2 ** octree.BITS, (20_000, 3))
    q[:5000] = q[0]  # duplicates: kept at the deepest level
    tree = octree.build_subtree(q, 0, leaf_points=500)
    assert np.array_equal(np.sort(tree.order), np.arange(20_000))
    assert tree.counts.sum() == 20_000
    start = 0
    for d, key, n in zip(tree.depths, tree.keys, tree.counts, strict=True):
        idx = tree.order[start:start + n]
        start += n
        assert (q[idx] >> (octree.BITS - d) == key).all()  # inside its node
        if n > 500 and d < octree.MAX_DEPTH:
            cells = octree.cell_codes(q[idx], d)
            assert np.unique(cells).size == n  # an inner node: one point per cell


def test_oversized_buckets_split_again_by_streaming(campaign, tmp_path):
    """Pass 1 with no bucket levels and a bucket budget below the cloud: the one
    bucket is split by streaming (several times) and every point still lands once."""
    from dataclasses import replace

    from rough_viewer.io.copc.index import build_copc, plan_index

    d, ins, _ = campaign
    paths = sorted(d.glob("[abc].laz"))
    plan = replace(plan_index(paths, memory_bytes=8_000_000), bucket_depth=0,
                   bucket_points=10_000, chunk_points=7_000)
    out = tmp_path / "split.copc.laz"
    summary = build_copc(plan, out, work_dir=tmp_path)
    assert summary.count == 75_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["split.copc.laz"]  # no leftovers
    with laspy.CopcReader.open(out) as r:
        got = r.query()
        keys = {(k.level, k.x, k.y, k.z) for k in r.root_page.entries}
    for dd, x, y, z in keys:
        assert dd == 0 or (dd - 1, x // 2, y // 2, z // 2) in keys
    X = np.concatenate([np.asarray(s.X) for s in ins])
    Y = np.concatenate([np.asarray(s.Y) for s in ins])
    Z = np.concatenate([np.asarray(s.Z) for s in ins])
    np.testing.assert_array_equal(_sorted(np.asarray(got.X), np.asarray(got.Y),
                                          np.asarray(got.Z))[0], _sorted(X, Y, Z)[0])


def _plain(path, n, seed, *, scale, offset, fmt=3, version="1.2", crs=None):
    rng = np.random.default_rng(seed)
    h = laspy.LasHeader(point_format=fmt, version=version)
    h.scales = np.full(3, scale)
    h.offsets = np.asarray(offset, float)
    if crs is not None:
        h.add_crs(crs)
    las = laspy.LasData(h)
    las.x = 300 + rng.random(n) * 5
    las.y = 600 + rng.random(n) * 5
    las.z = 20 + rng.random(n)
    las.write(path)
    return laspy.read(path)


def test_geotiff_keys_become_wkt(tmp_path):
    pyproj = pytest.importorskip("pyproj")
    from rough_viewer.io.formats.crs import read_crs

    src = tmp_path / "keys.laz"
    _plain(src, 5000, 5, scale=0.001, offset=(300, 600, 0), crs=pyproj.CRS.from_epsg(26911))
    assert read_crs(src).source == "geotiff"
    out = tmp_path / "k.copc.laz"
    assert main(["index", str(src), "--out", str(out), "--quiet"]) == 0
    got = read_crs(out)
    assert (got.source, got.epsg) == ("wkt", 26911)
    with laspy.open(out) as r:
        assert r.header.point_format.id == 7 and r.header.global_encoding.wkt  # 3: colours


def test_different_scales_requantized_to_the_finest(tmp_path):
    a = _plain(tmp_path / "a.laz", 4000, 6, scale=0.01, offset=(300, 600, 0))
    b = _plain(tmp_path / "b.laz", 4000, 7, scale=0.001, offset=(0, 0, 0))
    out = tmp_path / "o.copc.laz"
    assert main(["index", str(tmp_path / "a.laz"), str(tmp_path / "b.laz"), "--out", str(out),
                 "--quiet"]) == 0
    with laspy.CopcReader.open(out) as r:
        np.testing.assert_allclose(r.header.scales, 0.001)
        got = r.query()
    # both inputs lie on the 1 mm lattice: the output holds the same points exactly
    want = [np.round((np.r_[a[k], b[k]] - o) / 0.001).astype(np.int64)
            for k, o in (("x", 300), ("y", 600), ("z", 0))]
    have = [np.asarray(got[k], np.int64) for k in "XYZ"]
    np.testing.assert_array_equal(_sorted(*have)[0], _sorted(*want)[0])


def test_header_bounds_that_lie_refused(tmp_path, capsys):
    src = tmp_path / "lies.las"
    _plain(src, 2000, 8, scale=0.001, offset=(300, 600, 0))
    data = bytearray(src.read_bytes())
    import struct

    struct.pack_into("<d", data, 179, 301.0)  # max x: points reach 305
    src.write_bytes(bytes(data))
    out = tmp_path / "o.copc.laz"
    assert main(["index", str(src), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bounding box" in err[0]
    assert not out.exists()


def test_workers_write_the_same_points(campaign, tmp_path):
    d, _, out = campaign
    par = tmp_path / "par.copc.laz"
    assert main(["index", str(d / "[abc].laz"), "--out", str(par), "--memory", "8MB",
                 "--workers", "2", "--quiet"]) == 0
    with laspy.CopcReader.open(par) as r1, laspy.CopcReader.open(out) as r2:
        assert len(r1.root_page.entries) > 8  # several buckets on the workers
        a, b = r1.query().array, r2.query().array
    # the workers' smaller buckets give other nodes, with the same records in them
    oa = np.lexsort((a["gps_time"], a["Z"], a["Y"], a["X"]))
    ob = np.lexsort((b["gps_time"], b["Z"], b["Y"], b["X"]))
    assert a.dtype == b.dtype and np.array_equal(a[oa], b[ob])


def test_memory_too_small_refused(campaign, tmp_path, capsys):
    d, _, _ = campaign
    out = tmp_path / "o.copc.laz"
    assert main(["index", str(d / "a.laz"), "--out", str(out), "--memory", "1MB",
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--memory" in err[0] and "too small" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_no_points_refused(tmp_path, capsys):
    src = tmp_path / "empty.laz"
    _plain(src, 0, 9, scale=0.001, offset=(0, 0, 0))
    out = tmp_path / "o.copc.laz"
    assert main(["index", str(src), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["rough-viewer: error: the inputs hold no points"]
    assert not out.exists()


def test_disk_too_small_refused(campaign, tmp_path, monkeypatch, capsys):
    import shutil
    from collections import namedtuple

    d, _, _ = campaign
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda _p: usage(10**9, 10**9 - 10**5, 10**5))
    out = tmp_path / "o.copc.laz"
    assert main(["index", str(d / "a.laz"), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "disk" in err[0] and "0.0 GB free" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_decompression_bomb_refused_before_decoding(tmp_path, capsys):
    """A LAZ declaring 50 M points in a few hundred kB: refused from its header by the
    guard every command applies; with --max-points raised, one line when its data end."""
    import struct

    src = tmp_path / "small.laz"
    _make(src, 6, 3_000, 0.0, 4, extra=False)
    data = bytearray(src.read_bytes())
    struct.pack_into("<Q", data, 247, 50_000_000)  # LAS 1.4 point count
    bomb = tmp_path / "bomb.laz"
    bomb.write_bytes(bytes(data))
    out = tmp_path / "out.copc.laz"
    assert main(["index", str(bomb), "--out", str(out), "--quiet"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "decompression bomb" in err and str(bomb) in err
    assert not out.exists()
    assert main(["index", str(bomb), "--out", str(out), "--max-points", "60000000",
                 "--quiet"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(bomb) in err and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.glob("*.tmp*"))
