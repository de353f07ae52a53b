"""The COPC 1.0 file layout, written by hand on top of lazrs's LAZ chunk encoder.

::

    LAS 1.4 header (375 bytes)
    VLR "copc"/1: COPC info (160 bytes; the first VLR, its data at byte 429)
    VLR "laszip encoded"/22204: LAZ items, variable-size chunks
    other VLRs (extra bytes, CRS) copied from the inputs
    point data: offset to the chunk table (8 bytes), one LAZ chunk per octree node
    (in the order the hierarchy lists them), the chunk table
    EVLR "copc"/1000: the hierarchy, one 32-byte entry per node
    (VoxelKey d, x, y, z int32; offset uint64; byteSize int32; pointCount int32)

Every node's parent has an entry (a reader walks the tree from the root).
"""

from __future__ import annotations

import io
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import lazrs
import numpy as np

from rough_viewer.io.copc.octree import Cube

HEADER_SIZE = 375
VLR_HEADER = 54
EVLR_HEADER = 60
INFO_SIZE = 160
ENTRY = struct.Struct("<4iQii")


@dataclass(frozen=True)
class RawVlr:
    """A VLR as bytes: user id, record id, description, data."""

    user_id: str
    record_id: int
    description: str
    data: bytes


def laz_vlr(point_format: int, extra_bytes: int) -> lazrs.LazVlr:
    """The laszip VLR of a point format (6, 7 or 8) with ``extra_bytes`` bytes
    more per point, variable-size chunks."""
    return lazrs.LazVlr.new_for_compression(point_format, extra_bytes, True)


def compress_chunk(points: bytes, vlr: lazrs.LazVlr) -> bytes:
    """One LAZ chunk of packed point records (bytes, ``vlr``'s layout)."""
    buf = io.BytesIO()
    comp = lazrs.LasZipCompressor(buf, vlr)
    comp.reserve_offset_to_chunk_table()
    comp.compress_many(points)
    comp.done()
    data = buf.getvalue()
    table = struct.unpack("<q", data[:8])[0]
    return data[8:table]


def _vlr_bytes(v: RawVlr) -> bytes:
    head = struct.pack("<H16sHH32s", 0, v.user_id.encode()[:16], v.record_id, len(v.data),
                       v.description.encode()[:32])
    return head + v.data


def _info_bytes(cube: Cube, root_offset: int, root_size: int, gps: tuple[float, float]) -> bytes:
    data = struct.pack("<5d2Q2d", *cube.center, cube.halfsize, cube.spacing, root_offset,
                       root_size, gps[0], gps[1]) + bytes(88)
    assert len(data) == INFO_SIZE
    return data


@dataclass(frozen=True)
class Summary:
    """What the header states of the points written.

    Attributes
    ----------
    count : int
    mins, maxs : tuple of float
        Bounding box (units).
    by_return : tuple of int
        Points by return number 1..15.
    gps : tuple of float
        GPS time range.
    """

    count: int
    mins: tuple[float, float, float]
    maxs: tuple[float, float, float]
    by_return: tuple[int, ...]
    gps: tuple[float, float]


@dataclass
class CopcWriter:
    """Writes a COPC file node by node (:meth:`add_node`), then :meth:`close`.

    Parameters
    ----------
    path : Path
    point_format : int
        6, 7 or 8.
    record_size : int
        Bytes per point (the format's plus extra bytes).
    scales, offsets : tuple of float
    cube : Cube
    vlrs : list of RawVlr
        Extra bytes and CRS VLRs (written after the COPC and laszip ones).
    wkt : bool
        Whether the CRS is a WKT VLR (global encoding bit 4).
    """

    path: Path
    point_format: int
    record_size: int
    scales: tuple[float, float, float]
    offsets: tuple[float, float, float]
    cube: Cube
    vlrs: list[RawVlr]
    wkt: bool = True
    entries: list[tuple[int, int, int, int, int, int, int]] = field(default_factory=list)
    chunks: list[tuple[int, int]] = field(default_factory=list)
    _fh: BinaryIO | None = None

    def __post_init__(self) -> None:
        extra = self.record_size - {6: 30, 7: 36, 8: 38}[self.point_format]
        self.laz = laz_vlr(self.point_format, extra)
        self._fh = open(self.path, "wb")
        body = b"".join(_vlr_bytes(v) for v in self._all_vlrs(0, 0, (0.0, 0.0)))
        self._fh.write(bytes(HEADER_SIZE) + body)
        self.point_start = HEADER_SIZE + len(body)
        self._fh.write(bytes(8))

    def _all_vlrs(self, root_offset: int, root_size: int, gps: tuple[float, float]
                  ) -> list[RawVlr]:
        info = RawVlr("copc", 1, "COPC info", _info_bytes(self.cube, root_offset, root_size, gps))
        laz = RawVlr("laszip encoded", 22204, "lazrs variable chunks",
                     bytes(self.laz.record_data()))
        return [info, laz, *self.vlrs]

    def add_node(self, depth: int, key: tuple[int, int, int], count: int, chunk: bytes) -> None:
        """Append one node's LAZ chunk (:func:`compress_chunk`) of ``count`` points."""
        assert self._fh is not None
        offset = self._fh.tell()
        self._fh.write(chunk)
        self.entries.append((depth, *key, offset, len(chunk), count))
        self.chunks.append((count, len(chunk)))

    def close(self, summary: Summary) -> None:
        """Write the chunk table, the hierarchy and the final header."""
        fh = self._fh
        assert fh is not None
        table_at = fh.tell()
        lazrs.write_chunk_table(fh, self.chunks, self.laz)
        evlr_at = fh.tell()
        page = b"".join(ENTRY.pack(*e) for e in self.entries)
        fh.write(struct.pack("<H16sHQ32s", 0, b"copc", 1000, len(page), b"EPT hierarchy"))
        fh.write(page)
        fh.seek(self.point_start)
        fh.write(struct.pack("<q", table_at))
        fh.seek(0)
        fh.write(self._header(summary, evlr_at))
        fh.write(b"".join(_vlr_bytes(v) for v in self._all_vlrs(
            evlr_at + EVLR_HEADER, len(page), summary.gps)))
        fh.close()
        self._fh = None

    def abort(self) -> None:
        """Close the file without finishing it (the caller removes it)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def _header(self, s: Summary, evlr_at: int) -> bytes:
        by_return = list(s.by_return[:15]) + [0] * (15 - len(s.by_return[:15]))
        head = struct.pack(
            "<4sHH16sBB32s32sHHHIIBHI5I3d3d6dQQIQ15Q",
            b"LASF", 0, 16 if self.wkt else 0, bytes(16), 1, 4, b"rough-viewer".ljust(32, b"\0"),
            b"rough-viewer index (COPC 1.0)".ljust(32, b"\0"), 1, 2026, HEADER_SIZE,
            self.point_start, 2 + len(self.vlrs), 0x80 | self.point_format, self.record_size,
            0, 0, 0, 0, 0, 0, *self.scales, *self.offsets,
            s.maxs[0], s.mins[0], s.maxs[1], s.mins[1], s.maxs[2], s.mins[2],
            0, evlr_at, 1, s.count, *by_return)
        assert len(head) == HEADER_SIZE, len(head)
        return head


def scaled_extent(points: np.ndarray, scales: np.ndarray, offsets: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box (units) of packed records with integer fields X, Y, Z."""
    ints = np.stack([points["X"], points["Y"], points["Z"]], axis=1)
    lo = ints.min(axis=0) * scales + offsets
    hi = ints.max(axis=0) * scales + offsets
    return lo, hi
