"""LAS/LAZ: reading points in chunks (LAZ through the parallel lazrs backend, with the
decode cache) and writing clouds with extra dimensions."""

from __future__ import annotations

import datetime as _dt
import math
import os
import struct
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rough_viewer.io.cache import cache_read, cache_write
from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.io.costs import COSTS
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError, ProgressFn, foreign_errors

#: Points per chunk when reading LAS/LAZ.
LAS_CHUNK = 2_000_000


def laz_backend():
    import laspy

    available = laspy.LazBackend.detect_available()
    for b in (laspy.LazBackend.LazrsParallel, laspy.LazBackend.Lazrs):
        if b in available:
            return b
    return None


#: Smallest LAS header (versions 1.0-1.2), bytes; a VLR header is 54 bytes, an EVLR's 60.
LAS_MIN_HEADER = 227
VLR_HEADER_BYTES = 54
EVLR_HEADER_BYTES = 60
#: Most VLRs, and most EVLRs, a LAS/LAZ file may declare (files carry a few: the LASzip
#: record, the CRS, extra bytes); laspy holds each as an object (1 M empty VLRs: 272 MB
#: and 7.7 s in the process that opened the file).
MAX_VLRS = 10_000
#: Most bytes the VLRs together may hold (laspy reads them all on opening the file).
MAX_VLR_BYTES = 16 << 20
#: Most bytes of one CRS record (WKT, GeoKey directory, double or ASCII parameters):
#: a WKT is a few kilobytes; parsing costs ~240 bytes of memory a byte.
MAX_CRS_RECORD_BYTES = 64 << 10
#: Record ids of the CRS records (user id ``LASF_Projection``): the OGC WKT, then the
#: GeoKey directory, double and ASCII parameters.
CRS_RECORD_IDS = (2112, 34735, 34736, 34737)


@dataclass(frozen=True)
class LasLayout:
    """What a LAS/LAZ header says about the file's size, read from its raw bytes."""

    size: int
    """Bytes of the file."""
    point_count: int
    """Points the header declares (LAS 1.4's 64-bit count where it has one)."""
    record_length: int
    """Bytes of one point record (uncompressed)."""
    compressed: bool
    """True for LAZ (the point format's compression bit)."""
    data_offset: int
    """Byte where the point data start."""
    crs_records: tuple[tuple[int, int, int], ...] = ()
    """The CRS records (``LASF_Projection``, :data:`CRS_RECORD_IDS`) among the VLRs and
    EVLRs: (record id, byte where its data start, bytes), in file order."""


def check_las_layout(path: str | os.PathLike[str]) -> LasLayout:
    """Refuse a LAS/LAZ file whose header cannot describe the file, from its raw
    bytes, before laspy reads it: laspy walks the declared records, so a 34 KB file
    declaring 4e9 VLRs grew the reader past several GB (and a file that only starts
    with ``LASF`` did the same).

    Checked: the signature, the header size, the point-data offset within the file,
    the VLRs fitting between the header and the point data, coordinate scales and
    offsets that can place points (a finite, non-zero scale; a finite offset), and
    (LAS 1.4) the EVLRs fitting after the point data.

    Returns
    -------
    LasLayout
        The point count, record length and compression the header declares.

    Raises
    ------
    InputError
        One line naming the file and what its header gets wrong.
    """

    p = Path(path)
    try:
        size = p.stat().st_size
        with open(p, "rb") as fh:
            head = fh.read(375)
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or type(exc).__name__}") from None
    bad = f"the header of {p}"
    if len(head) < LAS_MIN_HEADER or head[:4] != b"LASF":
        raise InputError(f"{p} is not a LAS/LAZ file (no LAS header)")
    minor = head[25]
    header_size, data_offset, n_vlrs = struct.unpack_from("<HII", head, 94)
    if not LAS_MIN_HEADER <= header_size <= min(size, data_offset):
        raise InputError(f"{bad} gives a header size of {header_size:,} bytes, impossible in "
                         f"a file of {size:,} bytes with point data at {data_offset:,}: "
                         "a damaged or lying header")
    if data_offset > size:
        raise InputError(f"{bad} puts the point data at byte {data_offset:,}, past the end of "
                         f"the file ({size:,} bytes): the file is truncated or damaged")
    room = data_offset - header_size
    if n_vlrs * VLR_HEADER_BYTES > room:
        raise InputError(f"{bad} declares {n_vlrs:,} variable-length records, more than the "
                         f"{room:,} bytes before its point data can hold: a damaged or lying "
                         "header")
    coords = struct.unpack_from("<6d", head, 131)  # x, y, z scale factors, then offsets
    for k, v in enumerate(coords):
        if not math.isfinite(v) or (k < 3 and v == 0):
            # a scale of 0 puts every point on the offset; NaN or inf put none anywhere
            what = "scale factor" if k < 3 else "offset"
            raise InputError(f"{bad} gives the {'xyz'[k % 3]} {what} {v:g}: the coordinates "
                             "cannot be read (a damaged or lying header)")
    if minor >= 4 and len(head) >= 247:
        evlr_start, n_evlrs = struct.unpack_from("<QI", head, 235)
        if n_evlrs and (evlr_start < data_offset
                        or evlr_start + n_evlrs * EVLR_HEADER_BYTES > size):
            raise InputError(f"{bad} declares {n_evlrs:,} extended records from byte "
                             f"{evlr_start:,}, outside the file ({size:,} bytes): a damaged "
                             "or lying header")
    point_format, record_length, legacy_count = struct.unpack_from("<BHI", head, 104)
    count = legacy_count
    if minor >= 4 and len(head) >= 255:
        count = struct.unpack_from("<Q", head, 247)[0] or legacy_count
    evlr_start, n_evlrs = (struct.unpack_from("<QI", head, 235) if minor >= 4 and len(head) >= 247
                           else (0, 0))
    crs = _walk_records(p, header_size, data_offset, n_vlrs, evlr_start, n_evlrs, size)
    return LasLayout(size=size, point_count=int(count), record_length=int(record_length),
                     compressed=bool(point_format & 0xC0), data_offset=int(data_offset),
                     crs_records=crs)


def _walk_records(p: Path, header_size: int, data_offset: int, n_vlrs: int, evlr_start: int,
                  n_evlrs: int, size: int) -> tuple[tuple[int, int, int], ...]:
    """Check the VLR and EVLR tables from their raw headers (at most :data:`MAX_VLRS`
    each, the VLRs within :data:`MAX_VLR_BYTES` and before the point data, each EVLR
    within the file) and find the CRS records; no record's data is read."""
    bad = f"the header of {p}"
    crs: list[tuple[int, int, int]] = []
    tables = (  # what, first byte, count, header bytes, length's format, end allowed
        ("variable-length", header_size, n_vlrs, VLR_HEADER_BYTES, "<H",
         min(data_offset, header_size + MAX_VLR_BYTES)),
        ("extended variable-length", evlr_start, n_evlrs, EVLR_HEADER_BYTES, "<Q", size))
    try:
        with open(p, "rb") as fh:
            for what, at, n, head_bytes, length_format, end in tables:
                if n > MAX_VLRS:
                    raise InputError(f"{bad} declares {n:,} {what} records; a LAS file holds a "
                                     f"few (at most {MAX_VLRS:,} are read): a damaged or "
                                     "crafted header")
                for _ in range(n):
                    fh.seek(at)
                    raw = fh.read(head_bytes)
                    if len(raw) < head_bytes:
                        break
                    length = int(struct.unpack_from(length_format, raw, 20)[0])
                    record_id = int(struct.unpack_from("<H", raw, 18)[0])
                    if raw[2:18].rstrip(b"\0") == b"LASF_Projection" \
                            and record_id in CRS_RECORD_IDS:
                        crs.append((record_id, at + head_bytes, length))
                    at += head_bytes + length
                    if at > end:
                        raise InputError(
                            f"{bad} declares {what} records reaching byte {at:,}, past the "
                            f"{end:,} where they must end (the point data, the "
                            f"{MAX_VLR_BYTES:,} bytes of VLRs read, or the file's end): a "
                            "damaged or crafted header")
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or type(exc).__name__}") from None
    return tuple(crs)


def las_crs_records(p: Path, layout: LasLayout) -> dict[int, bytes]:
    """The data of a LAS/LAZ file's CRS records (record id -> bytes; the last of an id
    wins, so an EVLR replaces a VLR), each at most :data:`MAX_CRS_RECORD_BYTES`.

    Raises
    ------
    InputError
        A CRS record longer than that (a WKT is a few kilobytes).
    """
    raw: dict[int, bytes] = {}
    try:
        with open(p, "rb") as fh:
            for record_id, start, length in layout.crs_records:
                if length > MAX_CRS_RECORD_BYTES:
                    raise InputError(
                        f"the CRS record {record_id} of {p} holds {length:,} bytes; a CRS takes "
                        f"a few kilobytes (at most {MAX_CRS_RECORD_BYTES:,} are read): a damaged "
                        "or crafted file")
                fh.seek(start)
                raw[record_id] = fh.read(length)
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or type(exc).__name__}") from None
    return raw


def open_las(path: str | os.PathLike[str], **kwargs):
    """``laspy.open`` for reading, after :func:`check_las_layout`; the EVLRs are not
    read (they may hold gigabytes of waveforms) unless ``read_evlrs=True``."""
    import laspy

    check_las_layout(path)
    kwargs.setdefault("read_evlrs", False)
    return laspy.open(path, **kwargs)


#: Bytes held per point while reading (measured: :data:`rough_viewer.io.estimates.COSTS`).
READ_BYTES_PER_POINT = COSTS["laz"].per_point


def _selection(point_format):
    """What the LAZ decoder must decompress: x, y, z, intensity and RGB where the
    point format has them. (LAS 1.4 formats 6-10 compress each of these in its own
    layer; ``DecompressionSelection.base()`` alone leaves out Z.)"""
    import laspy

    sel = (laspy.DecompressionSelection.XY_RETURNS_CHANNEL
           | laspy.DecompressionSelection.Z
           | laspy.DecompressionSelection.INTENSITY)
    if "red" in point_format.dimension_names:
        sel |= laspy.DecompressionSelection.RGB
    return sel


def data_point_capacity(p: Path, header, laz_vlr=None) -> tuple[int, bool]:
    """How many points the file's point data can hold, judged from the data, not
    the header's count: ``(count, exact)``.

    LAS: the bytes between the start of the point data and the first extended VLR,
    the internal waveform packets or the end of the file, divided by the record
    length (exact). LAZ: the chunk
    table's point counts (exact for variable-size chunks such as COPC, an upper
    bound of ``chunks x chunk size`` for fixed-size chunks); ``laz_vlr`` is the
    file's ``lazrs.LazVlr``. ``(-1, False)`` when the data cannot be measured (no
    or a damaged chunk table).
    """
    size = p.stat().st_size
    start = int(header.offset_to_point_data)
    if not header.are_points_compressed:
        end = size
        first_evlr = int(getattr(header, "start_of_first_evlr", 0) or 0)
        if getattr(header, "number_of_evlrs", 0) and start < first_evlr <= size:
            end = first_evlr
        waveforms = int(getattr(header, "start_of_waveform_data_packet_record", 0) or 0)
        if start < waveforms < end:  # LAS 1.3 waveform packets stored after the points
            end = waveforms
        return max(0, end - start) // int(header.point_format.size), True
    if laz_vlr is None:
        return -1, False
    try:
        import lazrs

        with open(p, "rb") as fh:
            fh.seek(start)
            table = lazrs.read_chunk_table(fh, laz_vlr)
    except Exception:  # no or damaged chunk table
        return -1, False
    counts = [int(c[0]) for c in table]
    variable = int(laz_vlr.chunk_size()) == 0xFFFFFFFF
    return sum(counts), variable


def _laz_vlr(header):
    """The file's ``lazrs.LazVlr`` (chunk size, item layout), or None for LAS."""
    if not header.are_points_compressed:
        return None
    try:
        import lazrs

        return lazrs.LazVlr(header.vlrs.get("LasZipVlr")[0].record_data_bytes())
    except Exception:  # no or a damaged LasZip record: the decoder will say so
        return None


def check_header(p: Path, header, *, extra_bytes_per_point: int = 0) -> tuple[int, list[str]]:
    """The number of points to read and warnings, after checking the header's count
    against the data (:func:`data_point_capacity`) and against available memory.

    Raises
    ------
    InputError
        The header declares more points than the data hold, or they cannot fit.
    """
    n = int(header.point_count)
    laz_vlr = _laz_vlr(header)
    capacity, exact = data_point_capacity(p, header, laz_vlr)
    if capacity >= 0 and n > capacity:
        raise InputError(
            f"the header of {p} declares {n:,} points but its point data hold "
            f"{'' if exact else 'at most '}{capacity:,}: the file is truncated or damaged"
        )
    warnings = []
    chunk_size = int(laz_vlr.chunk_size()) if laz_vlr is not None else 1
    if capacity > n and (exact or capacity - n >= chunk_size):
        warnings.append(
            f"the header of {p} declares {n:,} points but its point data hold "
            f"{'' if exact else 'up to '}{capacity:,}; only the declared {n:,} were read"
        )
    require(n * (READ_BYTES_PER_POINT + extra_bytes_per_point), f"reading {n:,} points from {p}",
            hint="use a smaller file or a machine with more memory")
    return n, warnings


def read_las(p: Path, *, progress: ProgressFn | None, cache: bool) -> PointCloud:
    """Read a LAS/LAZ (COPC included: read as plain LAZ) file's x, y, z (metres as
    stored), intensity and RGB (where the point format has them).

    The header's point count is checked against what the data can hold before
    anything is decoded: more than the data hold is an InputError (a truncated or
    lying header); fewer gives a warning on the cloud. The declared count is then
    checked against available memory (:func:`rough_viewer.memory.require`).
    """

    if cache:
        cached = cache_read(p)
        if cached is not None:
            if progress:
                progress(cached.n, cached.n)
            return cached
    # laspy reads the header on open and builds the decoder on the first read, so
    # the data are measured and the decompression selection set in between.
    with open_las(p, laz_backend=laz_backend()) as reader:
        hdr = reader.header
        n, warnings = check_header(p, hdr)
        reader.decompression_selection = _selection(hdr.point_format)
        has_rgb = "red" in hdr.point_format.dimension_names
        scale = np.asarray(hdr.scales, dtype=np.float64)
        offset = np.asarray(hdr.offsets, dtype=np.float64)
        x = np.empty(n)
        y = np.empty(n)
        z = np.empty(n)
        inten = np.empty(n, dtype=np.uint16)
        rgb = np.empty((n, 3), dtype=np.uint16) if has_rgb else None
        done = 0
        if progress:
            progress(0, n)
        for chunk in reader.chunk_iterator(LAS_CHUNK):
            m = len(chunk)
            sl = slice(done, done + m)
            for col, raw, k in ((x, chunk.X, 0), (y, chunk.Y, 1), (z, chunk.Z, 2)):
                np.multiply(raw, scale[k], out=col[sl])
                col[sl] += offset[k]
            inten[sl] = chunk.intensity
            if rgb is not None:
                rgb[sl, 0] = chunk.red
                rgb[sl, 1] = chunk.green
                rgb[sl, 2] = chunk.blue
            done += m
            if progress:
                progress(done, n)
        if done < n:
            warnings.append(f"{p} ended after {done:,} of the {n:,} points its header declares")
            x, y, z, inten = x[:done], y[:done], z[:done], inten[:done]
            rgb = None if rgb is None else rgb[:done]
    cloud = finite_cloud(x, y, z, inten, p, rgb=rgb).with_warnings(*warnings)
    if cache:
        cache_write(p, cloud)
    return cloud


def write_las(
    path: str | os.PathLike[str],
    cloud: PointCloud,
    *,
    scale: float = 1e-4,
    extra: Mapping[str, np.ndarray] | None = None,
    creation_date: _dt.date | None = None,
) -> None:
    """Write a cloud as LAS (``.las``) or LAZ (``.laz``, lazrs).

    Parameters
    ----------
    path : path-like
        Output file; its suffix chooses compression.
    cloud : PointCloud
        Points (intensity written when present).
    scale : float
        Coordinate resolution, metres (LAS stores scaled integers).
    extra : mapping, optional
        Extra per-point dimensions, name -> (N,) array (e.g. ground-truth labels).
    creation_date : datetime.date, optional
        Header date; default 2000-01-01 so that the same points give the same bytes.
    """
    import laspy

    hdr = laspy.LasHeader(point_format=1, version="1.2")
    lo, _ = cloud.bounds()
    hdr.offsets = np.floor(lo)
    hdr.scales = np.array([scale, scale, scale])
    hdr.creation_date = creation_date or _dt.date(2000, 1, 1)
    hdr.generating_software = "rough_viewer"
    extra = dict(extra or {})
    if extra:
        hdr.add_extra_dims(
            [laspy.ExtraBytesParams(name=k, type=np.asarray(v).dtype) for k, v in extra.items()]
        )
    las = laspy.LasData(hdr)
    las.x = cloud.x
    las.y = cloud.y
    las.z = cloud.z
    if cloud.intensity is not None:
        las.intensity = np.clip(np.asarray(cloud.intensity), 0, 65535).astype(np.uint16)
    for k, v in extra.items():
        las[k] = np.asarray(v)
    p = Path(path)
    las.write(str(p), do_compress=p.suffix.lower() == ".laz", laz_backend=laz_backend())


def load_las_with_extra(
    path: str | os.PathLike[str], names: tuple[str, ...], *, trusted: bool = False
) -> tuple[PointCloud, dict[str, np.ndarray]]:
    """Read a LAS/LAZ file's points and some of its extra dimensions in one decode.

    Parameters
    ----------
    path : path-like
        A ``.las`` or ``.laz`` file.
    names : tuple of str
        Extra dimensions to return (e.g. ``("truth",)``).
    trusted : bool
        Decode in this process (files the package made itself, the bundled demos);
        else in a child process (:mod:`rough_viewer.io.sandbox.isolate`).

    Returns
    -------
    PointCloud, dict
        The points (metres, with intensity) and name -> (N,) array, row-aligned.
    """
    from rough_viewer.io.sandbox import isolate

    p = Path(path)
    if trusted or not isolate.available():
        return _load_las_with_extra(p, names)
    layout = check_las_layout(p)
    need = layout.point_count * (READ_BYTES_PER_POINT + 2.0 * layout.record_length)
    limits = isolate.limits_for(need, layout.size)
    items = isolate.stream_isolated(
        f"{__name__}:_extra_items", p, label="LAS/LAZ", limits=limits,
        names=frozenset({"x", "y", "z", "intensity", "dropped", *(f"extra.{n}" for n in names)}),
        options={"names": list(names)})
    try:
        item = next(items)
    finally:
        items.close()
    cloud = PointCloud(x=item["x"], y=item["y"], z=item["z"], intensity=item.get("intensity"),
                       source=str(p), dropped_nonfinite=int(item["dropped"][0]))
    return cloud, {n: item[f"extra.{n}"] for n in names}


def _extra_items(p: Path, *, progress: ProgressFn | None = None,
                 names: tuple[str, ...] = ()) -> Iterator[dict[str, np.ndarray]]:
    """:func:`_load_las_with_extra` as one item of a stream (the child process's part)."""
    cloud, extra = _load_las_with_extra(p, tuple(names))
    item: dict[str, np.ndarray] = {
        "x": cloud.x, "y": cloud.y, "z": cloud.z,
        "dropped": np.array([cloud.dropped_nonfinite], dtype=np.int64)}
    if cloud.intensity is not None:
        item["intensity"] = np.asarray(cloud.intensity)
    item.update({f"extra.{n}": v for n, v in extra.items()})
    yield item


def _load_las_with_extra(p: Path, names: tuple[str, ...]
                         ) -> tuple[PointCloud, dict[str, np.ndarray]]:
    with foreign_errors(f"cannot read {p}"), \
            open_las(p, laz_backend=laz_backend()) as reader:
        # the whole record is decoded too
        check_header(p, reader.header,
                     extra_bytes_per_point=int(reader.header.point_format.size))
        las = reader.read()
    present = list(las.point_format.extra_dimension_names)
    for name in names:
        if name not in present:
            raise InputError(f"no extra dimension {name!r} in {p}")
    x, y, z = (np.asarray(c, dtype=np.float64) for c in (las.x, las.y, las.z))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    cloud = finite_cloud(x, y, z, np.asarray(las.intensity), p)
    return cloud, {name: np.asarray(las[name])[ok] for name in names}


def read_las_extra(path: str | os.PathLike[str], name: str) -> np.ndarray:
    """Read one extra dimension (e.g. ``"truth"``) from a LAS/LAZ file."""
    return load_las_with_extra(path, (name,))[1][name]


