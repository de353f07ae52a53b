"""The files of one merged cloud, and reading them in chunks of points.

A :class:`Source` is one input file with what its header says (point count,
bounding box, unit); :func:`open_sources` checks a list of them; :func:`chunk_plan`
cuts them into :class:`Chunk` s (file, first point, end) that any process can read
on its own with :func:`read_chunk` (LAS/LAZ seek to the chunk's first point; LAZ
decodes through the parallel lazrs backend). Coordinates come out in metres with the
same arithmetic as :func:`rough_viewer.io.load.load_points` (``X * scale + offset``,
then the unit's metres-per-unit factor), so a chunk's points are bit for bit the
points the in-memory path reads.

Only LAS/LAZ files stream. Other formats have no random access, so each is one
chunk, read whole (it must fit in the memory budget by itself).
"""

from __future__ import annotations

import os
from collections.abc import Generator, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, check_input_file
from rough_viewer.io.load import check_coordinates
from rough_viewer.vocabulary import (
    UNIT_METRES,
    InputError,
    ProgressFn,
    Unit,
    error_line,
    foreign_errors,
)

#: Suffixes read in chunks straight from the file.
STREAMED = (".las", ".laz")


@dataclass(frozen=True)
class Source:
    """One input file of a merged cloud, as its header describes it."""

    path: str
    """The file."""
    n_points: int
    """Points in the file (LAS header count; for other formats the finite points)."""
    bounds_min: np.ndarray
    """(3,) smallest x, y, z, metres (LAS: from the header; checked while reading)."""
    bounds_max: np.ndarray
    """(3,) largest x, y, z, metres."""
    unit: str
    """Unit of the file's coordinates (``m``, ``mm``, ``ft``, ``us-ft``)."""
    streamed: bool
    """True for LAS/LAZ (read chunk by chunk); False: read whole."""
    dropped_nonfinite: int = 0
    """Rows with NaN or infinite coordinates (formats other than LAS), dropped."""
    warnings: tuple[str, ...] = ()
    """What the user should know about this file (units against its CRS, ...)."""
    z_unit: str | None = None
    """Unit of the file's z where its CRS gives a vertical unit unlike ``unit``
    (:func:`rough_viewer.io.load.axis_units`); None: ``unit``."""
    max_points: int | None = None
    """The decompression-bomb guard's limit its reads use (``--max-points``; None:
    :data:`rough_viewer.io.estimates.DEFAULT_MAX_POINTS`)."""

    @property
    def factor(self) -> float:
        """Metres per unit of the file's x and y."""
        return UNIT_METRES[self.unit]

    @property
    def z_factor(self) -> float:
        """Metres per unit of the file's z."""
        return UNIT_METRES[self.z_unit or self.unit]


@dataclass(frozen=True)
class Chunk:
    """Points ``[start, stop)`` of source number ``source``."""

    source: int
    start: int
    stop: int

    @property
    def n(self) -> int:
        """Number of points."""
        return self.stop - self.start


def _las_source(p: Path, unit: str, notes: tuple[str, ...], z_unit: str | None = None,
                max_points: int | None = None) -> Source:

    from rough_viewer.io.estimates import estimate_las
    from rough_viewer.io.formats.las import laz_backend, open_las

    estimate_las(p, max_points)  # the raw header's checks and the decompression-bomb guard
    with open_las(p, laz_backend=laz_backend()) as reader:  # header only: no decoding
        hdr = reader.header
        n = int(hdr.point_count)
        lo = np.asarray(hdr.mins, dtype=np.float64)
        hi = np.asarray(hdr.maxs, dtype=np.float64)
    if n < 1:
        raise InputError(f"no points in {p}")
    f = np.array([UNIT_METRES[unit]] * 2 + [UNIT_METRES[z_unit or unit]])
    check_coordinates(tuple(np.array([lo[k], hi[k]]) for k in range(3)), p,
                      factor=float(f.max()))
    lo, hi = lo * f, hi * f
    return Source(path=str(p), n_points=n, bounds_min=lo, bounds_max=hi, unit=unit,
                  streamed=True, warnings=notes, z_unit=None if z_unit == unit else z_unit,
                  max_points=max_points)


def open_sources(paths: Sequence[str | os.PathLike[str]], *, units: Unit | None = None,
                 max_points: int | None = None) -> list[Source]:
    """Describe the files of one merged cloud from their headers.

    LAS/LAZ headers give the point count and bounding box without decoding a
    point; other formats are read once here (whole) for theirs.

    Parameters
    ----------
    paths : sequence of path-like
        The files (any format :func:`~rough_viewer.io.load.load_points` reads).
    units : {"m", "mm", "ft", "us-ft"}, optional
        Unit of every file's coordinates; default each file's CRS unit, else metres.
    max_points : int, optional
        The decompression-bomb guard's limit (``--max-points``), kept in each
        :class:`Source` for its later reads.

    Raises
    ------
    InputError
        A file that cannot be read, has no points, or none at all given.
    """
    from rough_viewer.io.load import SUPPORTED_SUFFIXES, axis_units, load_points

    if not paths:
        raise InputError("no input files")
    notes = check_compatible(paths, units=units)
    out: list[Source] = []
    for path in paths:
        p = Path(path)
        suffix = p.suffix.lower()
        if suffix in STREAMED:
            check_input_file(p)
            with foreign_errors(f"cannot read {p}"):
                unit, z_unit, notes_p = axis_units(p, units)
                out.append(_las_source(p, unit, notes_p, z_unit, max_points))
        else:
            if suffix not in SUPPORTED_SUFFIXES:
                load_points(p)  # raises the one message for unknown types
            cloud = load_points(p, units=units, max_points=max_points)
            lo, hi = cloud.bounds()
            out.append(Source(path=str(p), n_points=cloud.n, bounds_min=lo, bounds_max=hi,
                              unit=cloud.source_unit, streamed=False,
                              dropped_nonfinite=cloud.dropped_nonfinite,
                              warnings=tuple(cloud.warnings), max_points=max_points))
    notes += overlap_warnings([(s.path, s.bounds_min, s.bounds_max) for s in out])
    if notes:
        out[0] = replace(out[0], warnings=out[0].warnings + notes)
    return out


def chunk_plan(sources: Sequence[Source], chunk_points: int) -> list[Chunk]:
    """Cut every streamed file into chunks of at most ``chunk_points`` points (other
    files are one chunk each), in file order."""
    size = max(1, int(chunk_points))
    chunks: list[Chunk] = []
    for i, s in enumerate(sources):
        if not s.streamed:
            chunks.append(Chunk(i, 0, s.n_points))
            continue
        for start in range(0, s.n_points, size):
            chunks.append(Chunk(i, start, min(s.n_points, start + size)))
    return chunks


Columns = tuple[np.ndarray, np.ndarray, np.ndarray]


def _file_columns(points, hdr) -> Columns:
    """x, y, z as stored (the file's unit) from a laspy point record:
    ``X * scale + offset`` per axis, as :func:`rough_viewer.io.formats.las.read_las` computes."""
    scale = np.asarray(hdr.scales, dtype=np.float64)
    offset = np.asarray(hdr.offsets, dtype=np.float64)
    cols = []
    for raw, k in ((points.X, 0), (points.Y, 1), (points.Z, 2)):
        col = np.multiply(raw, scale[k])
        col += offset[k]
        cols.append(col)
    return cols[0], cols[1], cols[2]


def _metres(cols: Columns, factor: float, z_factor: float | None = None) -> Columns:
    """Columns in metres (times metres-per-unit, z by its own where given, as
    ``PointCloud.scaled``)."""
    fz = factor if z_factor is None else z_factor
    if factor == 1.0 and fz == 1.0:
        return cols
    return (cols[0] * factor if factor != 1.0 else cols[0],
            cols[1] * factor if factor != 1.0 else cols[1], cols[2] * fz if fz != 1.0 else cols[2])


def _uses_cache(source: Source) -> bool:
    """LAZ files go through the decode cache (as in :func:`~rough_viewer.io.load.load_points`)."""
    return source.streamed and source.path.lower().endswith(".laz")


def _from_cache(source: Source, chunk: Chunk) -> Columns | None:
    from rough_viewer.io.cache import cache_read_slice, cached_points

    p = Path(source.path)
    if not _uses_cache(source) or cached_points(p) != source.n_points:
        return None
    cols = cache_read_slice(p, chunk.start, chunk.stop)
    return None if cols is None else _metres(cols, source.factor, source.z_factor)


def _open_las(path: str, *, parallel: bool = True):
    import laspy

    from rough_viewer.io.formats.las import _selection, laz_backend, open_las

    backend = laz_backend()
    if not parallel and backend == laspy.LazBackend.LazrsParallel:
        backend = laspy.LazBackend.Lazrs
    reader = open_las(path, laz_backend=backend)
    reader.decompression_selection = _selection(reader.header.point_format)
    return reader


#: Arrays a decoded chunk may hold.
_CHUNK_ARRAYS = frozenset({"x", "y", "z", "intensity", "rgb"})


def decode_las_chunks(p: Path, *, progress: ProgressFn | None = None,
                      plan: Sequence[Sequence[int]] = (), parallel: bool = True,
                      extras: bool = False, total: int = 0) -> Iterator[dict[str, np.ndarray]]:
    """Decode the points ``[start, stop)`` of each entry of ``plan`` from one open
    reader (seeking only where a range does not follow the last): x, y, z as stored
    (the file's unit), and intensity and RGB with ``extras`` (where the point format
    has them). The generator :func:`read_chunk` and :func:`iter_chunks` run in a
    child process (:func:`rough_viewer.io.sandbox.isolate.stream_isolated`).

    Raises InputError naming the file when it ends before a range (``total``: the
    points its header declares)."""
    with foreign_errors(f"cannot read {p}"), _open_las(str(p), parallel=parallel) as reader:
        dims = tuple(reader.header.point_format.dimension_names)
        at = 0
        for start, stop in plan:
            if start != at:
                reader.seek(start)
            points = reader.read_points(stop - start)
            if len(points) != stop - start:
                raise InputError(f"{p} ended after {start + len(points):,} of "
                                 f"the {total:,} points its header declares")
            x, y, z = _file_columns(points, reader.header)
            item = {"x": x, "y": y, "z": z}
            if extras and "intensity" in dims:
                item["intensity"] = np.asarray(points.intensity, dtype=np.uint16)
            if extras and "red" in dims:
                item["rgb"] = np.column_stack([points.red, points.green, points.blue]
                                              ).astype(np.uint16)
            del points
            yield item
            at = stop


def _decoded(source: Source, plan: list[Chunk], *, parallel: bool = True,
             extras: bool = False) -> Generator[dict[str, np.ndarray], None, None]:
    """:func:`decode_las_chunks` of ``plan``, in a child process where reads are
    isolated (memory for the largest chunk, time per chunk)."""
    from rough_viewer.io.costs import COSTS
    from rough_viewer.io.load import reader_for
    from rough_viewer.io.sandbox import isolate

    ranges = [[c.start, c.stop] for c in plan]
    options = {"plan": ranges, "parallel": parallel, "extras": extras,
               "total": source.n_points}
    reader = reader_for(source.path)
    if not isolate.available() or reader is None or not reader.untrusted:
        yield from decode_las_chunks(Path(source.path), **options)  # type: ignore[arg-type]
        return
    biggest = max((c.n for c in plan), default=0)
    kind = "laz" if source.path.lower().endswith(".laz") else "las"
    need = COSTS[kind].per_point * biggest
    limits = isolate.limits_for(need, biggest * 8)
    yield from isolate.stream_isolated(
        f"{__name__}:decode_las_chunks", source.path, label=reader.label, limits=limits,
        names=_CHUNK_ARRAYS, options=options)


def _checked(source: Source, item: dict[str, np.ndarray]) -> Columns:
    """A decoded chunk's coordinates in metres, after the magnitude check."""
    from rough_viewer.io.load import check_coordinates

    cols = (item["x"], item["y"], item["z"])
    check_coordinates(cols, source.path, factor=max(source.factor, source.z_factor))
    return _metres(cols, source.factor, source.z_factor)


def read_chunk(source: Source, chunk: Chunk, *, parallel: bool = True) -> Columns:
    """The points of one chunk as three float64 columns, metres.

    Reads the decode cache's columns where the LAZ file has a complete entry; else
    decodes the chunk's points only (in a child process: a damaged file cannot take
    this one down; on all cores unless ``parallel`` is False); a file of another
    format is read whole (it is one chunk).
    """
    if not source.streamed:
        from rough_viewer.io.load import load_points

        # a z in its own vertical unit comes from the CRS again, not from --units
        cloud = load_points(source.path, units=None if source.z_unit else source.unit,  # type: ignore[arg-type]
                            max_points=source.max_points)
        return (cloud.x[chunk.start:chunk.stop], cloud.y[chunk.start:chunk.stop],
                cloud.z[chunk.start:chunk.stop])
    cached = _from_cache(source, chunk)
    if cached is not None:
        return cached
    decoded = _decoded(source, [chunk], parallel=parallel)
    try:
        return _checked(source, next(decoded))
    finally:
        decoded.close()


def iter_chunks(source: Source, index: int, chunk_points: int, *, fill_cache: bool = False
                ) -> Iterator[tuple[Chunk, Columns]]:
    """The chunks of one file in order, from one open reader (the sequential path);
    the same chunks and points as :func:`chunk_plan` and :func:`read_chunk`.

    A LAZ file with a complete decode-cache entry is read from the cache. Without
    one, ``fill_cache`` writes the entry while decoding (chunk by chunk, nothing held
    beyond the chunk), so the next pass and the next run read the cache instead of
    decoding again.
    """
    if not source.streamed:
        c = Chunk(index, 0, source.n_points)
        yield c, read_chunk(source, c)
        return
    size = max(1, int(chunk_points))
    plan = [Chunk(index, a, min(source.n_points, a + size))
            for a in range(0, source.n_points, size)]
    first = _from_cache(source, plan[0])
    if first is not None:
        yield plan[0], first
        del first
        for c in plan[1:]:
            cols = _from_cache(source, c)
            if cols is None:
                raise InputError(f"the decode cache of {source.path} changed or was damaged "
                                 "while reading it; run again to decode the file")
            yield c, cols
        return
    writer = None
    decoded: Generator[dict[str, np.ndarray], None, None] | None = None
    try:
        if fill_cache and _uses_cache(source):
            from rough_viewer.io.cache import cache_writer

            with _open_las(source.path) as reader:  # the header only: no decoding here
                dims = tuple(reader.header.point_format.dimension_names)
            writer = cache_writer(Path(source.path), source.n_points,
                                  intensity="intensity" in dims, rgb="red" in dims)
        decoded = _decoded(source, plan, extras=writer is not None)
        for c in plan:
            item = next(decoded)
            cols = _checked(source, item)
            if writer is not None:
                writer.append(item["x"], item["y"], item["z"],
                              intensity=item.get("intensity"), rgb=item.get("rgb"))
            del item
            yield c, cols
        if writer is not None:
            writer.commit()
            writer = None
    except InputError:
        raise
    except Exception as exc:  # laspy and lazrs raise their own types
        raise InputError(f"cannot read {source.path}: {error_line(exc)}") from None
    finally:
        if decoded is not None:
            decoded.close()
        if writer is not None:  # abandoned or failed: no half entry
            writer.abort()


def _crs_name(info) -> str:
    if info.epsg is not None:
        return f"EPSG:{info.epsg}"
    text = str(info.description or "")
    return text if len(text) <= 60 else text[:57] + "..."


def check_compatible(paths: Sequence[str | os.PathLike[str]], *, units: Unit | None = None
                     ) -> tuple[str, ...]:
    """Refuse files that cannot be one cloud: different CRSs or different units.

    Two files differ in CRS when both declare one (LAS/LAZ WKT or GeoTIFF keys, read
    by :func:`rough_viewer.io.formats.crs.read_crs`) and their EPSG codes (or, without
    codes, their descriptions) differ; in unit when the units they are read in
    (``units``, else each CRS's linear unit, else metres) differ.

    Files that declare no CRS (no unit) beside files that do are refused unless
    ``units`` is given: their unit would be a guess.

    Returns
    -------
    tuple of str
        Warnings: files that declare no CRS beside files that do (``units`` given).

    Raises
    ------
    InputError
        Naming the two files and what differs.
    """
    from rough_viewer.io.formats.crs import read_crs
    from rough_viewer.io.load import resolve_units

    if len(paths) < 2:
        return ()
    for path in paths:
        check_input_file(Path(path))
    first_crs: tuple[Path, object] | None = None
    first_unit: tuple[Path, str] | None = None
    bare: list[Path] = []
    for path in paths:
        p = Path(path)
        info = read_crs(p)
        unit, _ = resolve_units(p, units)
        if first_unit is None:
            first_unit = (p, unit)
        elif unit != first_unit[1]:
            raise InputError(
                f"{p} is in {unit} but {first_unit[0]} is in {first_unit[1]}: files of "
                "different units cannot be merged into one cloud (convert them, or give "
                "--units if the CRS records are wrong)")
        if info.epsg is None and not info.description:
            bare.append(p)
            continue
        if first_crs is None:
            first_crs = (p, info)
            continue
        ref = first_crs[1]
        same = (info.epsg == ref.epsg if info.epsg is not None and ref.epsg is not None  # type: ignore[attr-defined]
                else info.description == ref.description)  # type: ignore[attr-defined]
        if not same:
            raise InputError(
                f"{p} is in {_crs_name(info)} but {first_crs[0]} is in {_crs_name(ref)}: "
                "files of different coordinate systems cannot be merged into one cloud "
                "(reproject them to one CRS first)")
    if first_crs is not None and bare:
        names = ", ".join(str(b) for b in bare[:3]) + (" ..." if len(bare) > 3 else "")
        if units is None:
            raise InputError(
                f"{names} declare{'s' if len(bare) == 1 else ''} no CRS or unit but "
                f"{first_crs[0]} is in {_crs_name(first_crs[1])} "
                f"({first_unit[1] if first_unit else 'm'}): give --units to say which unit "
                "every file is in, and merge only files of one coordinate system")
        return (f"{names} declare{'s' if len(bare) == 1 else ''} no CRS; taken to be in "
                f"{_crs_name(first_crs[1])} like {first_crs[0]}",)
    return ()


#: Boxes closer than this share of the larger one's diagonal count as touching.
OVERLAP_MARGIN = 0.1


def overlap_warnings(boxes: Sequence[tuple[str, np.ndarray, np.ndarray]]) -> tuple[str, ...]:
    """A warning when the files of a merged cloud fall into groups that do not touch.

    Two files touch when their bounding boxes, each grown by :data:`OVERLAP_MARGIN`
    of the larger box's diagonal, intersect (tiles side by side touch; a lab scan in
    millimetres beside an airborne tile in UTM does not). Groups are the connected
    sets of touching files.

    Parameters
    ----------
    boxes : sequence of (name, (3,) min, (3,) max)
        Each file's name and bounding box, metres.

    >>> a = ("a.laz", np.array([0.0, 0, 0]), np.array([100.0, 100, 10]))
    >>> b = ("b.laz", np.array([100.0, 0, 0]), np.array([200.0, 100, 10]))
    >>> c = ("c.stl", np.array([5e5, 4e6, 0]), np.array([5e5 + 0.03, 4e6 + 0.03, 0.01]))
    >>> overlap_warnings([a, b]), len(overlap_warnings([a, b, c]))
    ((), 1)
    """
    n = len(boxes)
    if n < 2:
        return ()
    lo = np.array([b[1] for b in boxes], dtype=np.float64)
    hi = np.array([b[2] for b in boxes], dtype=np.float64)
    diag = np.linalg.norm(hi - lo, axis=1)
    margin = OVERLAP_MARGIN * np.maximum(diag[:, None], diag[None, :])
    touch = np.all((lo[:, None, :] <= hi[None, :, :] + margin[..., None])
                   & (lo[None, :, :] <= hi[:, None, :] + margin[..., None]), axis=2)
    from scipy.sparse.csgraph import connected_components

    groups, label = connected_components(touch, directed=False)
    if groups < 2:
        return ()
    span = float(np.linalg.norm(hi.max(axis=0) - lo.min(axis=0)))
    parts = []
    for g in range(min(groups, 3)):
        members = np.flatnonzero(label == g)
        glo, ghi = lo[members].min(axis=0), hi[members].max(axis=0)
        centre = ", ".join(f"{v:.6g}" for v in 0.5 * (glo + ghi))
        names = boxes[members[0]][0] + (f" and {members.size - 1} more" if members.size > 1
                                         else "")
        parts.append(f"{names}: {_length(float(np.linalg.norm(ghi - glo)))} across at "
                     f"({centre})")
    return (f"the inputs do not overlap: they form {groups} separate groups ("
            + "; ".join(parts) + (" ..." if groups > 3 else "")
            + f"), so the merged cloud is {_length(span)} across; check that the files "
            "belong together and share one coordinate system",)


def _length(metres: float) -> str:
    """A length for a message, in m or km."""
    return f"{metres / 1000:,.4g} km" if metres >= 10_000 else f"{metres:.4g} m"


def merge_clouds(clouds: Sequence[PointCloud]) -> PointCloud:
    """One cloud of the points of several, in order (coordinates in metres).

    Intensity and colour are kept where every cloud has them (colour of one dtype);
    scan indices are renumbered so that scans of different files stay apart.
    """
    from rough_viewer.memory import require

    if len(clouds) == 1:
        return clouds[0]
    n = sum(c.n for c in clouds)
    require(n * 3 * 8 + sum(c.x.nbytes for c in clouds[:1]),
            f"merging {len(clouds)} files ({n:,} points)",
            hint="give --memory to stream the files in chunks instead")

    def cat(get):
        parts = [get(c) for c in clouds]
        return None if any(p is None for p in parts) else np.concatenate(parts)

    rgb = None
    if all(c.rgb is not None for c in clouds) and len({c.rgb.dtype for c in clouds}) == 1:  # type: ignore[union-attr]
        rgb = np.concatenate([c.rgb for c in clouds if c.rgb is not None])
    scan_index = scanners = None
    if all(c.scan_index is not None and c.scanner_positions is not None for c in clouds):
        offsets: list[int] = np.cumsum(
            [0] + [len(c.scanner_positions) for c in clouds[:-1]]).tolist()  # type: ignore[arg-type]
        scan_index = np.concatenate([c.scan_index + o for c, o in zip(clouds, offsets, strict=True)])  # type: ignore[operator]
        scanners = np.concatenate([c.scanner_positions for c in clouds
                                   if c.scanner_positions is not None])
    units = {c.source_unit for c in clouds}
    return PointCloud(
        x=np.concatenate([c.x for c in clouds]),
        y=np.concatenate([c.y for c in clouds]),
        z=np.concatenate([c.z for c in clouds]),
        intensity=cat(lambda c: c.intensity),
        source=" + ".join(c.source for c in clouds),
        dropped_nonfinite=sum(c.dropped_nonfinite for c in clouds),
        rgb=rgb,
        scan_index=scan_index,
        scanner_positions=scanners,
        source_unit=units.pop() if len(units) == 1 else "m",
        warnings=tuple(w for c in clouds for w in c.warnings),
    )


def load_merged(paths: Sequence[str | os.PathLike[str]], *, units: Unit | None = None,
                progress: Sequence[ProgressFn] | None = None,
                max_points: int | None = None) -> PointCloud:
    """Read several files (after :func:`check_compatible`) as one cloud, in memory.

    Parameters
    ----------
    paths : sequence of path-like
        The files.
    units : {"m", "mm", "ft", "us-ft"}, optional
        Unit of their coordinates (default: each file's CRS unit, else metres).
    progress : sequence of callable, optional
        One ``progress(done, total)`` per file.
    max_points : int, optional
        The decompression-bomb guard's limit (``--max-points``; default
        :data:`rough_viewer.io.estimates.DEFAULT_MAX_POINTS`).
    """
    from rough_viewer.io.load import load_points

    if not paths:
        raise InputError("no input files")
    notes = check_compatible(paths, units=units)
    clouds = [load_points(p, units=units, progress=None if progress is None else progress[i],
                          max_points=max_points) for i, p in enumerate(paths)]
    if len(clouds) > 1:  # one file overlaps nothing: no pass over its points for it
        notes += overlap_warnings([(str(p), *_bounds(c)) for p, c in zip(paths, clouds,
                                                                         strict=True)])
    return merge_clouds(clouds).with_warnings(*notes)


def _bounds(cloud: PointCloud) -> tuple[np.ndarray, np.ndarray]:
    """The cloud's bounds: as its reader noted them, just now, else a pass."""
    from rough_viewer.io.cloud import known_bounds, on_faces

    noted = known_bounds(cloud.x, cloud.y, cloud.z)
    if noted is not None and on_faces(cloud.x, cloud.y, cloud.z, *noted):
        return noted[0], noted[1]
    return cloud.bounds()
