"""Readers: every format gives the same points and the same roughness."""

from __future__ import annotations

import struct

import laspy
import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud, load_points, read_las_extra, write_las
from rough_viewer.vocabulary import InputError
from tests.helpers import rough_surface

SCALE = 1e-4


@pytest.fixture(scope="module")
def cloud() -> PointCloud:
    # coordinates on the LAS integer lattice (1e-4 m) so every format stores them exactly
    xyz = rough_surface(3000, seed=8, size=3.0) + np.array([523_456.0, 4_123_456.0, 800.0])
    xyz = np.round(xyz / SCALE) * SCALE
    return PointCloud.from_xyz(xyz, intensity=np.arange(3000) % 4000)


def _write_all(tmp_path, cloud):
    xyz = cloud.xyz()
    files = {}
    write_las(tmp_path / "c.las", cloud, scale=SCALE)
    write_las(tmp_path / "c.laz", cloud, scale=SCALE)
    files["las"] = tmp_path / "c.las"
    files["laz"] = tmp_path / "c.laz"
    np.save(tmp_path / "c.npy", xyz)
    files["npy"] = tmp_path / "c.npy"
    rows = "\n".join(f"{a!r} {b!r} {c!r} 17" for a, b, c in xyz.tolist())
    (tmp_path / "c.xyz").write_text(rows + "\n")
    files["xyz"] = tmp_path / "c.xyz"
    rows = "\n".join(f"{a!r},{b!r},{c!r}" for a, b, c in xyz.tolist())
    (tmp_path / "c.csv").write_text("x,y,z\n" + rows + "\n")
    files["csv"] = tmp_path / "c.csv"
    head = f"ply\nformat ascii 1.0\nelement vertex {len(xyz)}\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nend_header\n"
    (tmp_path / "a.ply").write_text(head + "\n".join(f"{a!r} {b!r} {c!r} 5" for a, b, c in xyz.tolist()) + "\n")
    files["ply-ascii"] = tmp_path / "a.ply"
    for end, name in (("<", "binary_little_endian"), (">", "binary_big_endian")):
        head = (f"ply\nformat {name} 1.0\ncomment made by a test\nelement vertex {len(xyz)}\n"
                "property float64 x\nproperty float64 y\nproperty float64 z\nproperty float nx\n"
                "element face 1\nproperty list uchar int vertex_indices\nend_header\n")
        rec = np.zeros(len(xyz), dtype=[("x", end + "f8"), ("y", end + "f8"), ("z", end + "f8"), ("nx", end + "f4")])
        rec["x"], rec["y"], rec["z"] = xyz.T
        face = struct.pack(end + "Biii", 3, 0, 1, 2)
        path = tmp_path / f"{name}.ply"
        path.write_bytes(head.encode() + rec.tobytes() + face)
        files[f"ply-{name}"] = path
    return files


def test_every_format_gives_identical_points_and_roughness(tmp_path, cloud):
    files = _write_all(tmp_path, cloud)
    ref = grid_roughness(cloud, 0.5)
    order = np.lexsort(cloud.xyz().T[::-1])
    for kind, path in files.items():
        got = load_points(path, cache=False)
        assert got.n == cloud.n, kind
        np.testing.assert_allclose(got.xyz()[np.lexsort(got.xyz().T[::-1])], cloud.xyz()[order],
                                   rtol=0, atol=1e-9, err_msg=kind)
        res = grid_roughness(got, 0.5)
        for name in ("odr", "ols", "hybrid", "e_ols"):
            a, b = np.sort(res.values(name)), np.sort(ref.values(name))
            np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-12, err_msg=f"{kind} {name}")
    las = load_points(files["las"])
    np.testing.assert_array_equal(las.intensity, cloud.intensity)


def _stl_binary(path, tris):
    rec = np.zeros(len(tris), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tris
    path.write_bytes(b"\0" * 80 + struct.pack("<I", len(tris)) + rec.tobytes())


def test_stl_ascii_and_binary_give_each_vertex_once(tmp_path):
    # a 6 x 6 vertex sheet triangulated: 50 triangles sharing 36 vertices
    g = np.arange(6, dtype=np.float32) * 0.25
    vx, vy = np.meshgrid(g, g, indexing="ij")
    vz = (0.1 * np.sin(vx) * np.cos(vy)).astype(np.float32)
    V = np.stack([vx, vy, vz], axis=-1)
    tris = []
    for i in range(5):
        for j in range(5):
            tris.append([V[i, j], V[i + 1, j], V[i, j + 1]])
            tris.append([V[i + 1, j], V[i + 1, j + 1], V[i, j + 1]])
    tris = np.array(tris, dtype=np.float32)
    _stl_binary(tmp_path / "b.stl", tris)
    lines = ["solid sheet"]
    for t in tris:
        lines += ["facet normal 0 0 1", " outer loop"]
        lines += [f"  vertex {a!r} {b!r} {c!r}" for a, b, c in t.astype(np.float64).tolist()]
        lines += [" endloop", "endfacet"]
    (tmp_path / "a.stl").write_text("\n".join(lines + ["endsolid sheet"]) + "\n")
    expected = np.unique(V.reshape(-1, 3).astype(np.float64), axis=0)
    for name in ("a.stl", "b.stl"):
        got = load_points(tmp_path / name)
        assert got.n == 36
        np.testing.assert_array_equal(got.xyz(), expected)


def test_laz_cache_makes_second_read_identical(tmp_path, cloud, monkeypatch):
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    write_las(tmp_path / "c.laz", cloud, scale=SCALE)
    first = load_points(tmp_path / "c.laz")
    assert any((tmp_path / "cache").iterdir())
    second = load_points(tmp_path / "c.laz")
    np.testing.assert_array_equal(first.xyz(), second.xyz())
    np.testing.assert_array_equal(first.intensity, second.intensity)


def test_extra_dimension_round_trip_and_deterministic_bytes(tmp_path, cloud):
    labels = (np.arange(cloud.n) % 3).astype(np.uint8)
    write_las(tmp_path / "a.laz", cloud, extra={"truth": labels})
    write_las(tmp_path / "b.laz", cloud, extra={"truth": labels})
    np.testing.assert_array_equal(read_las_extra(tmp_path / "a.laz", "truth"), labels)
    assert (tmp_path / "a.laz").read_bytes() == (tmp_path / "b.laz").read_bytes()
    assert laspy.read(tmp_path / "a.laz").header.point_count == cloud.n


def test_nonfinite_rows_dropped_and_counted(tmp_path):
    xyz = rough_surface(50, seed=1)
    xyz[3, 0] = np.nan
    xyz[7, 2] = np.inf
    np.save(tmp_path / "n.npy", xyz)
    got = load_points(tmp_path / "n.npy")
    assert got.n == 48 and got.dropped_nonfinite == 2


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("missing.las", None, "file not found"),
        ("cloud.obj", "v 1 2 3\n", "unknown file type"),
        ("empty.xyz", "", "no points"),
        ("two.xyz", "0 0 0\n1 1 1\n", "only 2 point"),
        ("cols.xyz", "1 2\n3 4\n5 6\n", "at least 3 columns"),
        ("bad.csv", "x,y,z\n1,2,3\n4,five,6\n7,8,9\n", "cannot parse"),
        ("nan.xyz", "nan 1 2\n1 nan 2\n", "no points"),
        ("junk.las", "this is not a las file", "not a LAS/LAZ file"),
        ("junk.laz", "this is not a laz file", "not a LAS/LAZ file"),
        ("junk.ply", "plx\n", "not a PLY"),
        ("junk.stl", "hello", "not an STL"),
        ("junk.npy", "nope", "not a NumPy .npy array"),
    ],
)
def test_bad_files_raise_one_line_errors_naming_the_file(tmp_path, name, content, message):
    path = tmp_path / name
    if content is not None:
        path.write_text(content)
    with pytest.raises(InputError) as exc:
        load_points(path)
    text = str(exc.value)
    assert message in text and name in text and "\n" not in text


# ----------------------------------------------------------------------------- LAS 1.4


def _las14(path, fmt: int, n: int = 120_000, seed: int = 3, compress: bool = True):
    """A LAS 1.4 file of point format ``fmt`` written by laspy: z varies point to point
    (a wavy surface), intensity and (where the format has it) RGB random."""
    rng = np.random.default_rng(seed)
    xyz = rough_surface(n, seed=seed, size=20.0) + np.array([600_000.0, 4_100_000.0, 50.0])
    hdr = laspy.LasHeader(point_format=fmt, version="1.4")
    hdr.scales = np.array([1e-3, 1e-3, 1e-3])
    hdr.offsets = np.floor(xyz.min(axis=0))
    las = laspy.LasData(hdr)
    las.x, las.y, las.z = xyz.T
    las.intensity = rng.integers(0, 65535, n, dtype=np.uint16)
    if "red" in las.point_format.dimension_names:
        for band in ("red", "green", "blue"):
            las[band] = rng.integers(0, 65535, n, dtype=np.uint16)
    las.write(str(path), do_compress=compress)
    return path


@pytest.mark.parametrize("fmt", [6, 7, 8])
def test_las14_laz_matches_laspy_full_decode(tmp_path, fmt):
    path = _las14(tmp_path / f"pf{fmt}.laz", fmt)
    full = laspy.read(path)  # laspy's own decode of every layer
    got = load_points(path, cache=False)
    np.testing.assert_array_equal(got.x, np.asarray(full.x))
    np.testing.assert_array_equal(got.y, np.asarray(full.y))
    np.testing.assert_array_equal(got.z, np.asarray(full.z))
    assert np.ptp(got.z) > 0.1  # the z layer really was decoded
    np.testing.assert_array_equal(got.intensity, np.asarray(full.intensity))
    if fmt == 6:
        assert got.rgb is None
    else:
        want = np.column_stack([np.asarray(full.red), np.asarray(full.green), np.asarray(full.blue)])
        np.testing.assert_array_equal(got.rgb, want)
    assert got.warnings == ()


def test_copc_like_laz_reads_as_plain_laz(tmp_path):
    # COPC = LAZ 1.4 PF 6-8 whose first record is the "copc" info VLR (160 bytes)
    rng = np.random.default_rng(5)
    xyz = rough_surface(5000, seed=5)
    hdr = laspy.LasHeader(point_format=7, version="1.4")
    hdr.scales = np.array([1e-4] * 3)
    hdr.vlrs.append(laspy.VLR("copc", 1, "COPC info", bytes(160)))
    las = laspy.LasData(hdr)
    las.x, las.y, las.z = xyz.T
    las.red = rng.integers(0, 65535, 5000, dtype=np.uint16)
    path = tmp_path / "cloud.copc.laz"
    las.write(str(path))
    got = load_points(path, cache=False)
    np.testing.assert_allclose(got.xyz(), xyz, atol=5.1e-5)
    np.testing.assert_array_equal(got.rgb[:, 0], np.asarray(las.red))


def _set_count(path, n: int) -> None:
    """Overwrite a LAS 1.4 header's point counts (legacy 32-bit at 107, 64-bit at 247)."""
    data = bytearray(path.read_bytes())
    struct.pack_into("<I", data, 107, 0)
    struct.pack_into("<Q", data, 247, n)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("compress", [True, False])
def test_header_declaring_more_points_than_the_data_is_one_line_error(tmp_path, compress):
    path = _las14(tmp_path / ("lie.laz" if compress else "lie.las"), 6, n=60_000, compress=compress)
    _set_count(path, 50_000_000)
    with pytest.raises(InputError) as exc:
        load_points(path, cache=False)
    text = str(exc.value)
    assert "50,000,000" in text and path.name in text and "\n" not in text


@pytest.mark.parametrize("value", [0.0, float("nan"), float("inf")])
@pytest.mark.parametrize("compress", [True, False])
def test_header_scale_that_cannot_place_points_is_refused(tmp_path, compress, value):
    """A z scale of 0 put every point on the offset (one cell, no values, exit 0)."""
    from rough_viewer.scale.sources import open_sources

    path = _las14(tmp_path / ("s.laz" if compress else "s.las"), 6, n=5_000, compress=compress)
    data = bytearray(path.read_bytes())
    struct.pack_into("<d", data, 147, value)  # z scale factor (x at 131, y at 139)
    path.write_bytes(bytes(data))
    for read in (lambda: load_points(path, cache=False), lambda: open_sources([path])):
        with pytest.raises(InputError) as exc:
            read()
        text = str(exc.value)
        assert path.name in text and "z scale factor" in text and "\n" not in text


def test_truncated_las_is_one_line_error(tmp_path):
    path = _las14(tmp_path / "cut.las", 6, n=10_000, compress=False)
    path.write_bytes(path.read_bytes()[:-30 * 1000])
    with pytest.raises(InputError, match="cut.las.*10,000 points but its point data hold 9,000"):
        load_points(path)


def test_header_declaring_fewer_points_is_a_warning(tmp_path):
    path = _las14(tmp_path / "few.las", 6, n=10_000, compress=False)
    _set_count(path, 9_000)
    got = load_points(path)
    assert got.n == 9_000
    assert len(got.warnings) == 1 and "few.las" in got.warnings[0] and "10,000" in got.warnings[0]


def test_declared_points_checked_against_memory_before_decoding(tmp_path, monkeypatch):
    import rough_viewer.memory as memory

    path = _las14(tmp_path / "big.laz", 6, n=20_000)
    monkeypatch.setattr(memory, "available_bytes", lambda: 100_000.0)
    with pytest.raises(InputError, match="reading 20,000 points from .*big.laz needs about"):
        load_points(path, cache=False)


def test_cache_key_changes_with_the_decoder_version(tmp_path, monkeypatch, cloud):
    import rough_viewer.io.cache as cache

    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    path = _las14(tmp_path / "pf6.laz", 6, n=5_000)
    key = cache.cache_key(path)
    # an entry of the old format (flat z, the bug) under the old key is never served
    monkeypatch.setattr(cache, "CACHE_VERSION", "v1")
    cache.cache_write(path, cloud)
    assert cache.cache_key(path) != key
    monkeypatch.undo()
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    got = load_points(path)
    np.testing.assert_array_equal(got.z, np.asarray(laspy.read(path).z))
    again = load_points(path)  # now from the v2 entry, RGB and all
    np.testing.assert_array_equal(again.z, got.z)


def _patched(tmp_path, name: str, offset: int, fmt: str, value: int, *, version="1.2"):
    """A valid 1,000-point LAS with one header field overwritten."""
    import laspy

    h = laspy.LasHeader(point_format=3 if version == "1.2" else 6, version=version)
    h.scales, h.offsets = [0.001] * 3, [0, 0, 0]
    las = laspy.LasData(h)
    rng = np.random.default_rng(0)
    las.x, las.y, las.z = rng.uniform(0, 10, 1000), rng.uniform(0, 10, 1000), rng.normal(0, .01, 1000)
    path = tmp_path / name
    las.write(str(path))
    data = bytearray(path.read_bytes())
    struct.pack_into(fmt, data, offset, value)
    path.write_bytes(bytes(data))
    return path


@pytest.mark.parametrize("name, offset, fmt, value, message", [
    ("vlrs.las", 100, "<I", 0xFFFFFFFF, "declares 4,294,967,295 variable-length records"),
    ("offset.las", 96, "<I", 10**9, "past the end of the file"),
    ("header.las", 94, "<H", 100, "header size of 100 bytes"),
])
def test_a_header_that_cannot_describe_its_file_is_refused_before_laspy(
        tmp_path, name, offset, fmt, value, message, monkeypatch):
    """A 34 KB LAS declaring 4e9 VLRs made laspy walk them, growing the server past
    GBs; every reader (points, streamed sources, the CRS) now refuses it from the
    raw header, before laspy opens the file."""
    from rough_viewer.io.load import resolve_units
    from rough_viewer.scale.sources import open_sources

    path = _patched(tmp_path, name, offset, fmt, value)

    def reached(*_args, **_kwargs):
        raise AssertionError("laspy was given the file")

    monkeypatch.setattr(laspy.LasReader, "__init__", reached)  # laspy.open and laspy.read
    for read in (lambda: load_points(path, cache=False), lambda: open_sources([path]),
                 lambda: resolve_units(path, None)):
        with pytest.raises(InputError) as exc:
            read()
        assert message in str(exc.value) and path.name in str(exc.value)


def test_evlrs_outside_the_file_and_lasf_junk_are_refused(tmp_path):
    path = _patched(tmp_path, "evlr.las", 243, "<I", 1_000_000, version="1.4")
    with pytest.raises(InputError, match="declares 1,000,000 extended records"):
        load_points(path, cache=False)
    junk = tmp_path / "junk.las"
    junk.write_bytes(b"LASF" + b"hunter2 secret " * 40)  # starts like LAS, is not
    with pytest.raises(InputError) as exc:
        load_points(junk, cache=False)
    assert "hunter2" not in str(exc.value) and "junk.las" in str(exc.value)
