"""Files crafted to break readers (issue 21), made by the tests in a temporary folder:
each is a small valid file with the bytes an attacker (or a damaged download) would
change.

A normal module: tests import what they need.
"""

from __future__ import annotations

import io
import struct
from pathlib import Path

import numpy as np


def small_laz(path: Path, *, point_format: int = 1, version: str = "1.2", n: int = 100,
              seed: int = 0) -> Path:
    """A valid LAZ of ``n`` random points (one chunk), written by laspy/lazrs."""
    import laspy

    hdr = laspy.LasHeader(point_format=point_format, version=version)
    hdr.scales, hdr.offsets = [0.001] * 3, [0.0, 0.0, 0.0]
    las = laspy.LasData(hdr)
    rng = np.random.default_rng(seed)
    las.x, las.y, las.z = rng.uniform(0.0, 1.0, (3, n))
    las.write(str(path), do_compress=True, laz_backend=laspy.LazBackend.Lazrs)
    return path


def _data_offset(data: bytes | bytearray) -> int:
    return int(struct.unpack_from("<I", data, 96)[0])


def laz_ff_chunk(path: Path, *, n_ff: int = 4096) -> Path:
    """A point-format-1 LAZ whose one chunk is ``n_ff`` bytes of 0xFF, with a chunk
    table that says so: lazrs recurses without end (SIGSEGV)."""
    import laspy
    import lazrs

    src = small_laz(path.with_name(path.stem + "_src.laz"))
    data = bytearray(src.read_bytes())
    off = _data_offset(data)
    with laspy.open(src) as reader:
        vlr = lazrs.LazVlr(reader.header.vlrs.get("LasZipVlr")[0].record_data_bytes())
        n = reader.header.point_count
    body = b"\xff" * n_ff
    table = io.BytesIO()
    lazrs.write_chunk_table(table, [(n, len(body))], vlr)
    path.write_bytes(bytes(data[:off]) + struct.pack("<q", off + 8 + len(body)) + body
                     + table.getvalue())
    src.unlink()
    return path


def laz_huge_chunk_table(path: Path) -> Path:
    """A LAZ whose chunk table claims 0xFFFFFFFF chunks: lazrs allocates 64 GiB for
    it and aborts."""
    data = bytearray(small_laz(path).read_bytes())
    table_at = struct.unpack_from("<q", data, _data_offset(data))[0]
    struct.pack_into("<I", data, table_at + 4, 0xFFFFFFFF)
    path.write_bytes(bytes(data))
    return path


def laz_huge_layer(path: Path) -> Path:
    """A LAS 1.4 LAZ (point format 6) whose first chunk declares a 4 GiB z layer:
    lazrs zero-fills 4 GiB for it (a 1 KB file peaked at 4.2 GB)."""
    data = bytearray(small_laz(path, point_format=6, version="1.4").read_bytes())
    # chunk: offset to the chunk table (8), the first point raw (30), its count (4),
    # then one size per layer: x/y/returns, z, ...
    at = _data_offset(data) + 8 + 30 + 4
    struct.pack_into("<I", data, at + 4, 0xFFFFFFFF)
    path.write_bytes(bytes(data))
    return path


def laz_zero_items(path: Path) -> Path:
    """A LAZ whose LasZip record declares 0 items: lazrs panics (PanicException, a
    BaseException) dividing by the record's item count."""
    data = bytearray(small_laz(path).read_bytes())
    pos = struct.unpack_from("<H", data, 94)[0]
    for _ in range(struct.unpack_from("<I", data, 100)[0]):
        user = bytes(data[pos + 2:pos + 18]).rstrip(b"\0")
        length = struct.unpack_from("<H", data, pos + 20)[0]
        if user == b"laszip encoded":
            struct.pack_into("<H", data, pos + 54 + 32, 0)
        pos += 54 + length
    path.write_bytes(bytes(data))
    return path


def laz_declaring(path: Path, declared: int, *, n: int = 1000) -> Path:
    """A small LAZ whose header declares ``declared`` points (a decompression bomb's
    header: 0.34 MB declaring 50 M points grew the server past 3 GB)."""
    data = bytearray(small_laz(path, n=n).read_bytes())
    struct.pack_into("<I", data, 107, declared)
    path.write_bytes(bytes(data))
    return path


def constant_laz(path: Path, n: int) -> Path:
    """A genuine LAZ of ``n`` identical points: 0.008 bytes a point, as small as a bomb."""
    import laspy

    hdr = laspy.LasHeader(point_format=1, version="1.2")
    hdr.scales, hdr.offsets = [0.001] * 3, [0.0, 0.0, 0.0]
    las = laspy.LasData(hdr)
    las.x = las.y = las.z = np.zeros(n)
    las.write(str(path), do_compress=True, laz_backend=laspy.LazBackend.Lazrs)
    return path


# ----------------------------------------------------------------------------- E57


def _crc32c_table() -> np.ndarray:
    table = np.zeros(256, dtype=np.uint32)
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
        table[i] = c
    return table


_CRC32C = _crc32c_table()


def crc32c_pages(pages: np.ndarray) -> np.ndarray:
    """CRC-32C (Castagnoli) of each row of ``pages`` (P, L) uint8, all rows at once."""
    c = np.full(pages.shape[0], 0xFFFFFFFF, dtype=np.uint32)
    for j in range(pages.shape[1]):
        c = _CRC32C[(c ^ pages[:, j]) & 0xFF] ^ (c >> np.uint32(8))
    return c ^ np.uint32(0xFFFFFFFF)


def e57_bytes(xml: bytes) -> bytes:
    """An E57 file holding ``xml`` and no binary sections: a 48-byte header in page 0,
    the XML from page 1, pages of 1020 bytes plus their big-endian CRC-32C (what
    libE57Format checks)."""
    n_pages = 1 + -(-len(xml) // 1020)
    logical = bytearray(n_pages * 1020)
    logical[1020:1020 + len(xml)] = xml
    logical[:48] = b"ASTM-E57" + struct.pack("<IIQQQQ", 1, 0, n_pages * 1024, 1024, len(xml), 1024)
    pages = np.frombuffer(bytes(logical), dtype=np.uint8).reshape(n_pages, 1020)
    out = np.empty((n_pages, 1024), dtype=np.uint8)
    out[:, :1020] = pages
    out[:, 1020:] = crc32c_pages(pages).astype(">u4").view(np.uint8).reshape(n_pages, 4)
    return out.tobytes()


_E57_HEAD = ('<?xml version="1.0" encoding="UTF-8"?>\n<e57Root type="Structure" '
             'xmlns="http://www.astm.org/COMMIT/E57/2010-e57-v1.0">'
             '<formatName type="String"><![CDATA[ASTM E57 3D Imaging Data File]]></formatName>'
             '<guid type="String"><![CDATA[{00000000-0000-0000-0000-000000000000}]]></guid>'
             '<versionMajor type="Integer">1</versionMajor><versionMinor type="Integer"/>')


def nested_e57(path: Path, depth: int = 160_000) -> Path:
    """An E57 whose XML nests ``depth`` structures (3.9 MB at 160,000): libE57Format
    is busy for a minute, then crashes."""
    xml = _E57_HEAD + '<a type="Structure">' * depth + "</a>" * depth + "</e57Root>"
    path.write_bytes(e57_bytes(xml.encode()))
    return path


def e57_without_data(path: Path) -> Path:
    """A well-formed E57 without the data3D its reader asks for (libE57Format's
    ErrorPathUndefined)."""
    path.write_bytes(e57_bytes((_E57_HEAD + "</e57Root>").encode()))
    return path


#: What :func:`parent_peak` runs: ``load_points`` (or ``read_crs``) of a file in a fresh
#: interpreter, then that interpreter's own peak resident memory (its reader child, where
#: reads are isolated, is another process and not counted).
_PEAK_SCRIPT = """
import resource, sys
from rough_viewer.io import load_points, read_crs
from rough_viewer.vocabulary import InputError
try:
    {call}(sys.argv[1])
    print("ok")
except InputError as exc:
    print("error", exc)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)
"""


def parent_peak(path: Path, call: str = "load_points") -> tuple[str, int]:
    """(the outcome's first line: ``ok`` or ``error <message>``, the peak resident
    memory in bytes) of ``call(path)`` in a fresh Python process."""
    import os
    import subprocess
    import sys

    root = str(Path(__file__).parents[2])
    done = subprocess.run([sys.executable, "-c", _PEAK_SCRIPT.format(call=call), str(path)],
                          capture_output=True, text=True, timeout=300, cwd=root,
                          env=dict(os.environ, PYTHONPATH=root), check=True)
    lines = done.stdout.strip().splitlines()
    return lines[0], int(lines[-1])


def asc_header_bomb(path: Path, n_bytes: int) -> Path:
    """An ESRI grid whose first line is ``ncols`` and ``n_bytes`` of letters."""
    with open(path, "wb") as fh:
        fh.write(b"ncols ")
        block = b"a" * (1 << 20)
        for _ in range(n_bytes >> 20):
            fh.write(block)
        fh.write(b"\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n3 4\n")
    return path


def las_14(path: Path, *, n: int = 2000, compress: bool = False) -> Path:
    """A valid LAS (or LAZ) 1.4 of ``n`` points on a plane, point format 6, no records."""
    import laspy

    hdr = laspy.LasHeader(point_format=6, version="1.4")
    hdr.scales, hdr.offsets = [0.001] * 3, [0.0, 0.0, 0.0]
    las = laspy.LasData(hdr)
    rng = np.random.default_rng(1)
    x, y = rng.uniform(0.0, 10.0, (2, n))
    las.x, las.y, las.z = x, y, 0.1 * x
    las.write(str(path), do_compress=compress,
              laz_backend=laspy.LazBackend.Lazrs if compress else None)
    return path


def with_evlr(path: Path, data: bytes, *, user_id: bytes = b"LASF_Projection",
              record_id: int = 2112) -> Path:
    """Append one EVLR to the LAS 1.4 file ``path`` (and count it in its header)."""
    raw = bytearray(path.read_bytes())
    start, count = struct.unpack_from("<QI", raw, 235)
    if count == 0:
        start = len(raw)
    struct.pack_into("<QI", raw, 235, start, count + 1)
    evlr = struct.pack("<H16sHQ32s", 0, user_id, record_id, len(data), b"crafted") + data
    path.write_bytes(bytes(raw) + evlr)
    return path


def las_many_vlrs(path: Path, n_vlrs: int) -> Path:
    """A valid LAS 1.4 of 2,000 points with ``n_vlrs`` empty VLRs after its header."""
    las_14(path)
    raw = bytearray(path.read_bytes())
    header_size = struct.unpack_from("<H", raw, 94)[0]
    offset = _data_offset(raw)
    vlr = struct.pack("<H16sHH32s", 0, b"crafted", 1, 0, b"")
    body = bytes(raw[:offset]) + vlr * n_vlrs + bytes(raw[offset:])
    out = bytearray(body)
    struct.pack_into("<II", out, 96, offset + len(vlr) * n_vlrs,
                     struct.unpack_from("<I", raw, 100)[0] + n_vlrs)
    assert header_size <= offset
    path.write_bytes(bytes(out))
    return path


def geotiff_with_tag(path: Path, tag: int, values: np.ndarray) -> Path:
    """A 3 x 4 float32 GeoTIFF (1 m pixels) carrying ``values`` as tag ``tag`` (float64
    values as 'd', uint16 as 'H')."""
    import tifffile

    code = "d" if values.dtype == np.float64 else "H"
    directory = np.array([1, 1, 0, 1, 3072, 0, 1, 32611], dtype=np.uint16)
    tags = [(33550, "d", 3, (1.0, 1.0, 0.0), True),
            (33922, "d", 6, (0.0, 0.0, 0.0, 0.0, 3.0, 0.0), True)]
    if tag != 34735:
        tags.append((34735, "H", directory.size, tuple(directory.tolist()), True))
    tags.append((tag, code, int(values.size), values, True))
    tifffile.imwrite(path, np.arange(12, dtype=np.float32).reshape(3, 4), extratags=tags)
    return path
