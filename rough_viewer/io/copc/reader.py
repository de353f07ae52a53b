"""Reading a COPC file by its index: the header, the hierarchy, and the points of
chosen nodes.

:func:`open_copc` parses what the file says of itself (LAS 1.4 header, the COPC info
VLR, the laszip VLR and the hierarchy EVLR with its pages) in pure Python, checking
every offset and count against the file before it is used, so a damaged or hostile
file is one :class:`~rough_viewer.vocabulary.InputError` line: a node or page past
the end of the file, a page listed twice (a loop), a key outside its depth, a node
listed twice, more entries than the file could hold. Nothing native runs on the file
here.

:func:`decode_nodes` decodes the LAZ chunks of some nodes with lazrs (native code:
run it in a child process, :func:`decode_tiles` through
:func:`rough_viewer.io.sandbox.isolate.stream_isolated`, or in a worker process) and
gives x, y, z in the file's units with the arithmetic of
:func:`rough_viewer.scale.sources._file_columns` (``X * scale + offset``), so the
points are bit for bit those laspy reads.

Only x, y, z are decompressed (lazrs's selective decompression of point formats 6-10
reads the other layers' bytes but not their arithmetic).
"""

from __future__ import annotations

import math
import os
import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rough_viewer.vocabulary import InputError, ProgressFn

#: One hierarchy entry: VoxelKey (depth, x, y, z int32), offset uint64, byte size
#: int32, point count int32 (-1: the entry points at a child page).
ENTRY_DTYPE = np.dtype([("depth", "<i4"), ("x", "<i4"), ("y", "<i4"), ("z", "<i4"),
                        ("offset", "<u8"), ("size", "<i4"), ("count", "<i4")])
#: Deepest level read (19 bits a coordinate in :func:`pack_key`; writers stop
#: near 14-16: a level-19 node of a 10 km cube is 2 cm wide).
MAX_DEPTH = 19
#: Most hierarchy entries read (32 bytes each: 320 MB of hierarchy).
MAX_ENTRIES = 10_000_000
_HEADER = struct.Struct("<4sHH16sBB32s32sHHHIIBHI5I3d3d6dQQIQ15Q")
_VLR = struct.Struct("<H16sHH32s")
_EVLR = struct.Struct("<H16sHQ32s")
_INFO = struct.Struct("<5d2Q2d")


@dataclass(frozen=True)
class CopcFile:
    """What a COPC file says of itself, checked against its size.

    Attributes
    ----------
    path : str
    n_points : int
        Points the header declares.
    point_format : int
        6, 7, 8 (or 9, 10).
    record_size : int
        Bytes of one point record.
    scales, offsets : (3,) float64
        ``x = X * scale + offset`` (file units).
    mins, maxs : (3,) float64
        The header's bounding box, file units.
    center : (3,) float64
        Centre of the octree's root cube, file units.
    halfsize : float
        Half the root cube's edge, file units.
    laz_vlr : bytes
        The laszip VLR's data (what lazrs decodes with).
    nodes : structured array of :data:`ENTRY_DTYPE`
        Every node that holds points (count > 0), in file order.
    spacing : float
        The root node's spacing the info VLR declares, file units (0: not given).
    """

    path: str
    n_points: int
    point_format: int
    record_size: int
    scales: np.ndarray
    offsets: np.ndarray
    mins: np.ndarray
    maxs: np.ndarray
    center: np.ndarray
    halfsize: float
    laz_vlr: bytes
    nodes: np.ndarray
    spacing: float = 0.0

    @property
    def cube_min(self) -> np.ndarray:
        """(3,) lowest corner of the root cube, file units."""
        return self.center - self.halfsize


def is_copc(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a LAS 1.4 file whose first VLR is the COPC info (user
    ``copc``, record 1), as the COPC 1.0 specification places it."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(375 + _VLR.size)
    except OSError:
        return False
    if len(head) < 375 + _VLR.size or head[:4] != b"LASF" or head[24:26] != b"\x01\x04":
        return False
    header_size = struct.unpack_from("<H", head, 94)[0]
    if header_size != 375:
        return False
    _, user, record, _, _ = _VLR.unpack_from(head, 375)
    return user.rstrip(b"\0") == b"copc" and record == 1


def _fail(path: str, what: str) -> InputError:
    return InputError(f"{path} is not a readable COPC file: {what}")


def open_copc(path: str | os.PathLike[str], *, max_entries: int = MAX_ENTRIES) -> CopcFile:
    """Parse and check a COPC file's header, VLRs and hierarchy (no point decoded).

    Raises
    ------
    InputError
        One line naming the file and what is wrong with it.
    """
    p = os.fspath(path)
    try:
        size = Path(p).stat().st_size
        with open(p, "rb") as fh:
            return _parse(p, fh, size, max_entries)
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or exc}") from None
    except struct.error:
        raise _fail(p, "it ends inside its header or VLRs") from None


def _parse(p: str, fh, size: int, max_entries: int) -> CopcFile:
    raw = fh.read(_HEADER.size)
    if len(raw) < _HEADER.size or raw[:4] != b"LASF":
        raise _fail(p, "no LAS 1.4 header")
    h = _HEADER.unpack(raw)
    version = (h[4], h[5])
    header_size, point_start, n_vlrs, fmt_byte, record_size = h[10], h[11], h[12], h[13], h[14]
    fmt = fmt_byte & 0x3F
    scales, offsets = np.array(h[21:24], dtype=np.float64), np.array(h[24:27], dtype=np.float64)
    maxs = np.array([h[27], h[29], h[31]], dtype=np.float64)
    mins = np.array([h[28], h[30], h[32]], dtype=np.float64)
    evlr_at, n_points = h[34], h[36]
    if version != (1, 4) or header_size != 375:
        raise _fail(p, f"LAS {version[0]}.{version[1]} (COPC is LAS 1.4)")
    if fmt not in (6, 7, 8, 9, 10) or not fmt_byte & 0x80:
        raise _fail(p, f"point format {fmt} is not a compressed format 6-10")
    if not (np.all(np.isfinite(scales)) and np.all(scales > 0) and np.all(np.isfinite(offsets))):
        raise _fail(p, "its scales or offsets are not finite positive numbers")
    if point_start > size or evlr_at > size:
        raise _fail(p, "its point data or EVLRs start past the end of the file")
    info = laz = None
    at = header_size
    for _ in range(n_vlrs):
        fh.seek(at)
        head = fh.read(_VLR.size)
        if len(head) < _VLR.size:
            raise _fail(p, "it ends inside its VLRs")
        _, user, record, length, _ = _VLR.unpack(head)
        if at + _VLR.size + length > point_start:
            raise _fail(p, "a VLR runs into the point data")
        user = user.rstrip(b"\0")
        if user == b"copc" and record == 1:
            info = fh.read(length)
        elif user == b"laszip encoded" and record == 22204:
            laz = fh.read(length)
        at += _VLR.size + length
    if info is None or len(info) < _INFO.size:
        raise _fail(p, "no COPC info VLR")
    if laz is None:
        raise _fail(p, "no laszip VLR")
    cx, cy, cz, halfsize, spacing, root_at, root_size, _, _ = _INFO.unpack_from(info)
    center = np.array([cx, cy, cz], dtype=np.float64)
    if not (np.all(np.isfinite(center)) and np.isfinite(halfsize) and halfsize > 0):
        raise _fail(p, "its octree cube is not finite")
    nodes = _hierarchy(p, fh, size, point_start, root_at, root_size, max_entries)
    total = int(nodes["count"].sum(dtype=np.int64))
    if total != n_points:
        raise _fail(p, f"its nodes hold {total:,} points, its header declares {n_points:,}")
    return CopcFile(path=p, n_points=int(n_points), point_format=fmt, record_size=int(record_size),
                    scales=scales, offsets=offsets, mins=mins, maxs=maxs, center=center,
                    halfsize=float(halfsize), laz_vlr=bytes(laz), nodes=nodes,
                    spacing=float(spacing) if math.isfinite(spacing) and spacing > 0 else 0.0)


def _hierarchy(p: str, fh, size: int, point_start: int, root_at: int, root_size: int,
               max_entries: int) -> np.ndarray:
    """Every node with points, from the root page and the pages it points at (each
    page read once: a page listed twice is a loop)."""
    pages = [(root_at, root_size)]
    seen: set[int] = set()
    found: list[np.ndarray] = []
    n = 0
    while pages:
        at, length = pages.pop()
        if at in seen:
            raise _fail(p, f"its hierarchy lists the page at byte {at:,} twice (a loop)")
        seen.add(at)
        if length < 0 or length % ENTRY_DTYPE.itemsize or at < point_start or at + length > size:
            raise _fail(p, f"a hierarchy page (byte {at:,}, {length:,} bytes) lies outside "
                        "the file or is not whole entries")
        n += length // ENTRY_DTYPE.itemsize
        if n > max_entries:
            raise _fail(p, f"its hierarchy has more than {max_entries:,} entries")
        fh.seek(at)
        data = fh.read(length)
        if len(data) != length:
            raise _fail(p, "it ends inside its hierarchy")
        page = np.frombuffer(data, dtype=ENTRY_DTYPE)
        child = page["count"] == -1
        pages.extend((int(e["offset"]), int(e["size"])) for e in page[child])
        found.append(page[~child])
    nodes = np.concatenate(found) if found else np.empty(0, dtype=ENTRY_DTYPE)
    d = nodes["depth"].astype(np.int64)
    if nodes.size and (d.min() < 0 or d.max() > MAX_DEPTH):
        raise _fail(p, f"a node's depth is outside 0-{MAX_DEPTH}")
    lim = np.left_shift(np.int64(1), d)
    keys = np.stack([nodes["x"], nodes["y"], nodes["z"]], axis=1).astype(np.int64)
    if nodes.size and (keys.min() < 0 or np.any(keys >= lim[:, None])):
        raise _fail(p, "a node's key lies outside its depth's cube")
    if np.any(nodes["count"] < -1):
        raise _fail(p, "a node has a negative point count")
    nodes = nodes[nodes["count"] > 0]
    off = nodes["offset"].astype(np.int64)
    end = off + nodes["size"].astype(np.int64)
    if nodes.size and (off.min() < point_start or end.max() > size or nodes["size"].min() <= 0):
        bad = nodes[(off < point_start) | (end > size) | (nodes["size"] <= 0)][0]
        raise _fail(p, f"node {bad['depth']}-{bad['x']}-{bad['y']}-{bad['z']} lies past the end "
                    "of the file or outside the point data")
    codes = node_codes(nodes)
    if np.unique(codes).size != codes.size:
        raise _fail(p, "its hierarchy lists a node twice")
    return np.sort(nodes, order="offset")


def node_codes(nodes: np.ndarray) -> np.ndarray:
    """(N,) int64 codes of nodes' keys (:func:`pack_key`)."""
    return pack_key(nodes["depth"].astype(np.int64), nodes["x"].astype(np.int64),
                    nodes["y"].astype(np.int64), nodes["z"].astype(np.int64))


def pack_key(d: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Unique int64 code of node keys (depth at most :data:`MAX_DEPTH`): depth in
    bits 57-61, x, y, z in 19 bits each below."""
    return (np.asarray(d, dtype=np.int64) << 57) | (np.asarray(x, dtype=np.int64) << 38) \
        | (np.asarray(y, dtype=np.int64) << 19) | np.asarray(z, dtype=np.int64)


def node_boxes(copc: CopcFile) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) lowest and highest corners of the cube of every node of
    :attr:`CopcFile.nodes`, file units: the root cube halved ``depth`` times, at the
    node's key.

    >>> nodes = np.array([(0, 0, 0, 0, 0, 1, 10), (1, 1, 0, 1, 0, 1, 5)], dtype=ENTRY_DTYPE)
    >>> c = CopcFile("f", 15, 6, 30, np.ones(3), np.zeros(3), np.zeros(3), np.ones(3),
    ...              np.full(3, 2.0), 2.0, b"", nodes)
    >>> lo, hi = node_boxes(c)
    >>> lo.tolist(), hi.tolist()
    ([[0.0, 0.0, 0.0], [2.0, 0.0, 2.0]], [[4.0, 4.0, 4.0], [4.0, 2.0, 4.0]])
    """
    nodes = copc.nodes
    side = 2.0 * float(copc.halfsize) / np.exp2(nodes["depth"].astype(np.float64))
    key = np.column_stack([nodes["x"], nodes["y"], nodes["z"]]).astype(np.float64)
    lo = copc.cube_min + key * side[:, None]
    return lo, lo + side[:, None]


def nodes_in_box(copc: CopcFile, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Rows of :attr:`CopcFile.nodes` whose cubes meet the box ``[lo, hi]`` (file
    units; a point may sit one stored step outside its node's cube, so the cubes are
    taken that much larger), in file order: the nodes that hold every point of the
    file inside the box (a spatial query of the index)."""
    nlo, nhi = node_boxes(copc)
    step = np.asarray(copc.scales, dtype=np.float64)
    meets = np.all((nhi + step >= np.asarray(lo, float)) & (nlo - step <= np.asarray(hi, float)),
                   axis=1)
    return np.flatnonzero(meets)


def decode_integers(copc: CopcFile, rows: Sequence[int] | np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stored integers X, Y, Z (int32 views of the records) of the points of
    ``copc.nodes[rows]``, node after node in the order given.

    Raises
    ------
    InputError
        If a chunk does not decode to its count of points.
    """
    import lazrs

    sel = copc.nodes[np.asarray(rows, dtype=np.int64)]
    n = int(sel["count"].sum(dtype=np.int64))
    if n == 0:
        empty = np.empty(0)
        return empty, empty.copy(), empty.copy()
    sizes = sel["size"].astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    packed = np.empty(int(starts[-1]), dtype=np.uint8)  # the nodes' chunks, back to back
    with open(copc.path, "rb") as fh:
        for e, a, b in zip(sel, starts[:-1], starts[1:], strict=True):
            fh.seek(int(e["offset"]))
            if fh.readinto(packed[a:b].data) != b - a:
                raise _fail(copc.path, "it ends inside a node's chunk")
    out = np.empty(n * copc.record_size, dtype=np.uint8)
    table = [(int(e["count"]), int(e["size"])) for e in sel]
    selection = lazrs.DecompressionSelection(lazrs.SELECTIVE_DECOMPRESS_XY_RETURNS_CHANNEL
                                             | lazrs.SELECTIVE_DECOMPRESS_Z)
    try:
        lazrs.decompress_points_with_chunk_table(packed, copc.laz_vlr, out, table, selection)
    except lazrs.LazrsError as exc:
        raise _fail(copc.path, f"a node's chunk does not decode ({exc})") from None
    del packed
    rec = np.frombuffer(out, dtype=np.dtype({"names": ["X", "Y", "Z"],
                                             "formats": ["<i4", "<i4", "<i4"],
                                             "offsets": [0, 4, 8],
                                             "itemsize": copc.record_size}))
    return rec["X"], rec["Y"], rec["Z"]


def decode_nodes(copc: CopcFile, rows: Sequence[int] | np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y, z (file units, float64) of the points of ``copc.nodes[rows]``, node
    after node in the order given (:func:`decode_integers` scaled).

    Raises
    ------
    InputError
        If a chunk does not decode to its count of points.
    """
    return scaled(copc, *decode_integers(copc, rows))


def scaled(copc: CopcFile, ix: np.ndarray, iy: np.ndarray, iz: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y, z (file units, float64) of stored integers: ``X * scale + offset``, the
    arithmetic laspy uses, so the same bits."""
    cols = []
    for k, col_int in enumerate((ix, iy, iz)):
        col = np.multiply(col_int, copc.scales[k])
        col += copc.offsets[k]
        cols.append(col)
    return cols[0], cols[1], cols[2]


def decode_tiles(path: str, *, progress: ProgressFn | None = None,
                 plan: Sequence[Sequence[int]] = ()) -> Iterator[dict[str, np.ndarray]]:
    """For each entry of ``plan`` (rows of :attr:`CopcFile.nodes`), the stored integers
    X, Y, Z of those nodes (:func:`scaled` makes them x, y, z): the generator a child
    process runs
    (:func:`rough_viewer.io.sandbox.isolate.stream_isolated`)."""
    copc = open_copc(path)
    for rows in plan:
        ix, iy, iz = decode_integers(copc, rows)
        yield {"X": ix, "Y": iy, "Z": iz}  # scaled by the caller: half the bytes to send


__all__ = ["ENTRY_DTYPE", "CopcFile", "decode_integers", "decode_nodes", "decode_tiles", "is_copc",
           "node_boxes", "nodes_in_box",
           "node_codes",
           "open_copc", "pack_key", "scaled"]
