"""LAS/LAZ out: every input point with per-point fields added as LAS extra bytes
(CloudCompare shows them as scalar fields, QGIS and PDAL as dimensions).

Two cases (:func:`write_las_fields` picks):

- the cloud was read from a LAS/LAZ file (:func:`copy_las_with_fields`): the file is
  copied point by point, in chunks (memory stays bounded), every point in file
  order with every original dimension byte for byte (coordinates at the same scales
  and offsets, intensity, classification, returns, GPS time, RGB, existing extra
  bytes with their descriptors), the same point format, the input's VLRs (the CRS
  included) and EVLRs. The version becomes 1.4 when it was older: PDAL and QGIS read
  extra-bytes descriptions only from LAS 1.4 files, and EVLRs need 1.4; the point
  format, and so every standard dimension, stays the same.
- any other input (:func:`write_las_points`): a LAS 1.4 point-format-6 file with x,
  y, z (and intensity where the cloud has it) at the scale of
  :func:`coordinate_scale` (1e-6 of the coordinate unit where the extent allows).

Rows of the input whose coordinates are not finite are not in the cloud; in a
copied LAS they are kept with each field's fill value (NaN roughness, no cell).

A cropped cloud (:mod:`rough_viewer.io.crop`) is written with ``keep=`` its mask over
the cloud read from the file: the copy then holds the kept points only (rows with
non-finite coordinates, which no crop can keep, are left out too), every dimension
byte for byte as above.
"""

from __future__ import annotations

import copy
import datetime as _dt
import math
import os
from pathlib import Path

import numpy as np

from rough_viewer._version import __version__
from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.formats.las import laz_backend, open_las
from rough_viewer.io.formats.point_fields import PointFields
from rough_viewer.io.output import write_path_atomic
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError, ProgressFn, error_line, foreign_errors

#: Points per chunk of the streamed copy.
COPY_CHUNK = 1_000_000

#: Finest coordinate scale of LAS files made from non-LAS inputs (coordinate units).
FINEST_SCALE = 1e-6

LAS_SUFFIXES = (".las", ".laz")


def check_las_output(path: str | os.PathLike[str], option: str = "--las-out") -> None:
    """Raise InputError unless ``path`` ends in ``.las`` or ``.laz``."""
    if Path(path).suffix.lower() not in LAS_SUFFIXES:
        raise InputError(f"{option} must end in .las or .laz, got {path}")


def _software() -> str:
    return f"rough_viewer {__version__}"[:32]


def _extra_bytes_params(fields: PointFields) -> list:
    import laspy

    return [laspy.ExtraBytesParams(name=f.name, type=f.dtype, description=f.description)
            for f in fields.fields]


def coordinate_scale(lo: np.ndarray, hi: np.ndarray, offset: np.ndarray) -> float:
    """Scale of the LAS integer coordinates for points in ``[lo, hi]`` stored from
    ``offset``: :data:`FINEST_SCALE`, or the finest coarser power of ten at which the
    farthest coordinate still fits a signed 32-bit integer."""
    reach = float(np.max(np.maximum(np.abs(hi - offset), np.abs(lo - offset))))
    limit = 2**31 - 2
    exponent = round(math.log10(FINEST_SCALE))
    while reach / 10.0**exponent > limit:
        exponent += 1
    return float(10.0**exponent)


def write_las_fields(
    path: str | os.PathLike[str],
    cloud: PointCloud,
    fields: PointFields,
    *,
    progress: ProgressFn | None = None,
    chunk_points: int = COPY_CHUNK,
    keep: np.ndarray | None = None,
) -> str:
    """Write ``cloud`` with per-point ``fields`` as LAS (``.las``) or LAZ (``.laz``),
    atomically. A cloud read from a LAS/LAZ file is copied from that file
    (:func:`copy_las_with_fields`; ``keep`` is the crop's mask over the cloud read
    from it, when ``cloud`` is a crop); any other is written from its coordinates
    (:func:`write_las_points`: a cropped cloud is written as it is).

    Returns
    -------
    str
        One line saying what was written (version, point format, scale).
    """
    check_las_output(path, "output")
    source = Path(cloud.source) if cloud.source else None
    if source is not None and source.suffix.lower() in LAS_SUFFIXES and source.is_file():
        return copy_las_with_fields(source, path, cloud, fields, progress=progress,
                                    chunk_points=chunk_points, keep=keep)
    return write_las_points(path, cloud, fields, progress=progress, chunk_points=chunk_points)


def _output_header(header_in, fields: PointFields, source: Path):
    """The input's header with the fields added as extra bytes, version >= 1.4."""
    import laspy
    from laspy.header import Version

    present = set(header_in.point_format.dimension_names)
    clash = [f.name for f in fields.fields if f.name in present]
    if clash:
        raise InputError(f"{source} already has a dimension named {clash[0]!r} (an earlier "
                         "rough_viewer export?); compute from the original scan")
    encoding = header_in.global_encoding
    if header_in.point_format.id in (4, 5, 9, 10) and getattr(
            encoding, "waveform_data_packets_internal", False):
        raise InputError(f"{source} stores waveform packets inside the file; they cannot be "
                         "carried over (export from a copy without waveforms)")
    header = copy.deepcopy(header_in)
    original_structs = []
    if header.vlrs.get("ExtraBytesVlr"):
        original_structs = list(header.vlrs.get("ExtraBytesVlr")[0].extra_bytes_structs)
    if header.version.minor < 4:
        header.version = Version(1, 4)
    header.add_extra_dims(_extra_bytes_params(fields))
    # keep the input's own descriptors (their no-data, min, max, options) as they were
    eb = header.vlrs.get("ExtraBytesVlr")[0]
    eb.extra_bytes_structs[: len(original_structs)] = original_structs
    header.generating_software = _software()
    header.creation_date = _dt.date.today()
    if not isinstance(header.point_format, laspy.PointFormat):  # pragma: no cover
        raise InputError(f"unexpected point format in {source}")
    return header


def copy_las_with_fields(
    source: str | os.PathLike[str],
    path: str | os.PathLike[str],
    cloud: PointCloud,
    fields: PointFields,
    *,
    progress: ProgressFn | None = None,
    chunk_points: int = COPY_CHUNK,
    keep: np.ndarray | None = None,
) -> str:
    """Copy a LAS/LAZ file point by point, in chunks, adding ``fields`` as extra bytes.

    Parameters
    ----------
    source : path-like
        The LAS/LAZ file ``cloud`` was read from.
    path : path-like
        Output ``.las`` or ``.laz`` (compressed with lazrs).
    cloud : PointCloud
        The points read from ``source`` (its finite rows, in file order).
    fields : PointFields
        One value per cloud point and field.
    progress : callable, optional
        ``progress(done, total)`` in points.
    chunk_points : int
        Points per chunk (memory grows with it).
    keep : (M,) bool array, optional
        A crop: which points of the cloud read from ``source`` (its finite rows, in
        file order) to write; ``cloud`` and ``fields`` are then the kept points.
        Rows with non-finite coordinates are left out.

    Returns
    -------
    str
        One line: version, point format, VLRs and EVLRs carried over.
    """
    src = Path(source)
    out = Path(path)
    check_las_output(out, "output")
    keep, read_n = _checked_counts(cloud, fields, keep)
    chunk_points = max(1, int(chunk_points))
    with foreign_errors(f"cannot read {src}"):
        reader_cm = open_las(src, laz_backend=laz_backend(), read_evlrs=True)
    with reader_cm as reader:
        header_in = reader.header
        n_file = int(header_in.point_count)
        if n_file != read_n + cloud.dropped_nonfinite:
            hint = "" if keep is not None else "; a cropped cloud needs its crop mask (keep=)"
            raise InputError(f"{src} has {n_file:,} points but the cloud read from it has "
                             f"{read_n + cloud.dropped_nonfinite:,} (did the file change?{hint})")
        header = _output_header(header_in, fields, src)
        m = min(chunk_points, max(n_file, 1))
        # input and output records, coordinates for the finite check, gathered fields
        # a crop copies the kept records once more
        copies = 2.0 if keep is None else 3.0
        require(m * (2.0 * header_in.point_format.size + copies * header.point_format.size
                     + 40.0 + 2.0 * fields.bytes_per_point),
                f"copying {src.name} in chunks of {m:,} points",
                hint="a smaller chunk size needs less")
        evlrs = header_in.evlrs

        def write_to(tmp: Path) -> None:
            _copy_points(reader, tmp, header, m, fields, src=src, keep=keep, read_n=read_n,
                         compress=out.suffix.lower() == ".laz", progress=progress)

        try:
            write_path_atomic(out, write_to)
        except InputError:
            raise
        except Exception as exc:  # laspy and lazrs raise their own types
            if type(exc).__module__.startswith(("laspy", "lazrs")) or "Laz" in type(exc).__name__:
                raise InputError(f"cannot copy {src} to {out}: {error_line(exc)}") from None
            raise
    n_vlrs = len(header_in.vlrs) - len(header_in.vlrs.get("LasZipVlr"))
    # a crop writes its kept rows only: say those, not the source file's count
    written = (f"{n_file:,} points" if keep is None
               else f"{cloud.n:,} points (the crop's, of {n_file:,})")
    return (f"LAS {header.version} point format {header.point_format.id}, {written}, "
            f"{n_vlrs} VLRs and {len(evlrs or [])} EVLRs of {src.name} kept, "
            f"{len(fields.fields)} extra dimensions added")


def _checked_counts(cloud: PointCloud, fields: PointFields, keep: np.ndarray | None
                    ) -> tuple[np.ndarray | None, int]:
    """The crop mask as a bool array (None without a crop) and the number of finite
    points read from the source (the cloud's, or the mask's length), the counts of
    ``cloud``, ``fields`` and ``keep`` checked against one another."""
    if fields.n_points != cloud.n:
        raise InputError(f"{fields.n_points} per-point values for a cloud of {cloud.n} points")
    if keep is None:
        return None, cloud.n
    keep = np.asarray(keep, dtype=bool)
    if keep.ndim != 1 or int(np.count_nonzero(keep)) != cloud.n:
        raise InputError(f"the crop keeps {int(np.count_nonzero(keep)):,} points but the "
                         f"cropped cloud has {cloud.n:,}")
    return keep, int(keep.shape[0])


def _copy_points(reader, tmp: Path, header, m: int, fields: PointFields, *, src: Path,
                 keep: np.ndarray | None, read_n: int, compress: bool,
                 progress: ProgressFn | None) -> None:
    """Copy every record of the open ``reader`` to ``tmp`` under ``header`` (the
    input's with the fields' extra bytes), ``m`` points a chunk: the input's bytes,
    then the fields' values; with a crop (``keep``, over the ``read_n`` finite
    points) only the kept rows. Refuses a file (``src``) that changed since it was
    read."""
    import laspy

    header_in = reader.header
    n_file = int(header_in.point_count)
    size_in, size_out = header_in.point_format.size, header.point_format.size
    scales = np.asarray(header_in.scales, dtype=np.float64)
    offsets = np.asarray(header_in.offsets, dtype=np.float64)
    done = kept_total = finite_total = 0
    if progress:
        progress(0, n_file)
    with laspy.open(tmp, mode="w", header=header, do_compress=compress,
                    laz_backend=laz_backend()) as writer:
        for chunk in reader.chunk_iterator(m):
            k = len(chunk)
            if k == 0:
                continue
            record = laspy.PackedPointRecord.zeros(k, header.point_format)
            raw_in = np.ascontiguousarray(chunk.array).view(np.uint8).reshape(k, size_in)
            raw_out = record.array.view(np.uint8).reshape(k, size_out)
            raw_out[:, :size_in] = raw_in
            kept = _finite_rows(chunk, scales, offsets)
            n_finite = int(np.count_nonzero(kept))
            if keep is None:
                values = fields.gather_rows(kept, kept_total)
            else:  # a crop: the kept finite rows only
                if finite_total + n_finite > read_n:
                    raise InputError(f"{src} has more finite points than when it "
                                     "was read (did the file change?)")
                rows = kept.copy()
                rows[kept] = keep[finite_total:finite_total + n_finite]
                finite_total += n_finite
                n_rows = int(np.count_nonzero(rows))
                if n_rows < k:
                    record = record[rows]
                values = fields.gather(kept_total, kept_total + n_rows)
                kept = rows
            for f, v in zip(fields.fields, values, strict=True):
                record.array[f.name] = v
            if len(record):
                writer.write_points(record)
            kept_total += int(np.count_nonzero(kept))
            done += k
            if progress:
                progress(done, n_file)
        if header_in.evlrs:
            writer.write_evlrs(header_in.evlrs)
    if kept_total != fields.n_points or done != n_file or (
            keep is not None and finite_total != read_n):
        raise InputError(f"{src} gave {done:,} points ({kept_total:,} finite) on the "
                         f"second read, expected {n_file:,} ({fields.n_points:,} "
                         "finite): did the file change?")


def _finite_rows(chunk, scales: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Rows of a chunk whose coordinates are finite, computed exactly as
    :func:`rough_viewer.io.formats.las.read_las` does, so rows line up with the cloud."""
    kept = np.ones(len(chunk), dtype=bool)
    if np.all(np.abs(scales) < 1e290) and np.all(np.abs(offsets) < 1e300):
        return kept  # 32-bit integers times a sane scale: always finite
    for raw, s, o in ((chunk.X, scales[0], offsets[0]), (chunk.Y, scales[1], offsets[1]),
                      (chunk.Z, scales[2], offsets[2])):
        with np.errstate(over="ignore", invalid="ignore"):
            v = np.multiply(raw, s, dtype=np.float64)
            v += o
        kept &= np.isfinite(v)
    return kept


def write_las_points(
    path: str | os.PathLike[str],
    cloud: PointCloud,
    fields: PointFields,
    *,
    progress: ProgressFn | None = None,
    chunk_points: int = COPY_CHUNK,
) -> str:
    """Write a cloud that was not read from LAS as LAS 1.4, point format 6, with
    ``fields`` as extra bytes.

    Coordinates are stored from an offset of the whole units below the bounding-box
    minimum at the scale of :func:`coordinate_scale`; intensity (clipped to 0..65535)
    where the cloud has it; one return per pulse.

    Returns
    -------
    str
        One line: version, point format and the coordinate scale used.
    """
    import laspy

    out = Path(path)
    check_las_output(out, "output")
    if fields.n_points != cloud.n:
        raise InputError(f"{fields.n_points} per-point values for a cloud of {cloud.n} points")
    lo, hi = cloud.bounds()
    offset = np.floor(lo)
    scale = coordinate_scale(lo, hi, offset)
    header = laspy.LasHeader(version="1.4", point_format=6)
    header.offsets = offset
    header.scales = np.array([scale, scale, scale])
    header.generating_software = _software()
    header.system_identifier = "rough_viewer export"
    header.creation_date = _dt.date.today()
    header.add_extra_dims(_extra_bytes_params(fields))
    n = cloud.n
    m = max(1, min(int(chunk_points), n))
    require(m * (2.0 * header.point_format.size + 48.0 + 2.0 * fields.bytes_per_point),
            f"writing {out.name} in chunks of {m:,} points")

    def write_to(tmp: Path) -> None:
        if progress:
            progress(0, n)
        with laspy.open(tmp, mode="w", header=header, do_compress=out.suffix.lower() == ".laz",
                        laz_backend=laz_backend()) as writer:
            for start in range(0, n, m):
                stop = min(n, start + m)
                record = laspy.ScaleAwarePointRecord.zeros(stop - start, header=header)
                record.x = cloud.x[start:stop]
                record.y = cloud.y[start:stop]
                record.z = cloud.z[start:stop]
                record.return_number = np.ones(stop - start, dtype=np.uint8)
                record.number_of_returns = np.ones(stop - start, dtype=np.uint8)
                if cloud.intensity is not None:
                    record.intensity = np.clip(np.asarray(cloud.intensity[start:stop]),
                                               0, 65535).astype(np.uint16)
                for f, v in zip(fields.fields, fields.gather(start, stop), strict=True):
                    record.array[f.name] = v
                writer.write_points(record)
                if progress:
                    progress(stop, n)

    write_path_atomic(out, write_to)
    return (f"LAS 1.4 point format 6, {n:,} points, coordinates at scale {scale:g} "
            f"from offset ({', '.join(f'{v:g}' for v in offset)}), "
            f"{len(fields.fields)} extra dimensions added")
