"""Where the scanner stood: one position per scan, and which scan every point came from.

A cloud knows its scanners through two of its fields
(:class:`~rough_viewer.io.cloud.PointCloud`): ``scanner_positions`` (S, 3), metres in
the cloud's frame, and ``scan_index`` (N,), the row of ``scanner_positions`` each
point belongs to. They come from

- E57 files: every scan's pose (its translation is the scanner's origin), read by
  :func:`rough_viewer.io.formats.e57.read_e57`;
- one position given for the whole cloud (``--scanner X,Y,Z``):
  :func:`with_scanner`;
- a table of positions by LAS ``point_source_id`` (``--scanners FILE``, a CSV of
  ``point_source_id, x, y, z``): :func:`read_scanner_table`, the points' ids from
  :func:`point_source_ids` (LAS/LAZ, or a text cloud with a ``point_source_id``
  column), joined by :func:`assign_scanners`.

:func:`cloud_scanners` returns them checked, or None for a cloud without positions.

>>> import numpy as np
>>> from rough_viewer.io.cloud import PointCloud
>>> cloud = with_scanner(PointCloud.from_xyz(np.zeros((3, 3))), (1.0, 2.0, 3.0))
>>> positions, scan = cloud_scanners(cloud)
>>> positions.tolist(), scan.tolist()
([[1.0, 2.0, 3.0]], [0, 0, 0])
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import MAX_COORDINATE_M, PointCloud
from rough_viewer.memory import require
from rough_viewer.vocabulary import UNIT_METRES, InputError, error_line, foreign_errors

#: Columns of a scanner table, in order (the ``--scanners`` contract).
SCANNER_TABLE_COLUMNS = ("point_source_id", "x", "y", "z")

#: Largest LAS point source id (an unsigned 16-bit field).
MAX_POINT_SOURCE_ID = 65535

#: Sentence shown wherever a cloud has no scanner positions.
NO_POSITIONS = ("no scanner positions: give --scanner X,Y,Z (one scanner) or --scanners "
                "FILE (point_source_id,x,y,z); E57 files give theirs by their poses")


@dataclass(frozen=True)
class ScannerTable:
    """Scanner positions by LAS point source id (the ``--scanners`` CSV)."""

    ids: np.ndarray
    """(S,) int64 point source ids, ascending, distinct."""
    positions: np.ndarray
    """(S, 3) float64 positions, metres, in the order of ``ids``."""
    source: str
    """The file read."""


def read_scanner_table(path: str | os.PathLike[str], *, unit: str = "m") -> ScannerTable:
    """Read a CSV of ``point_source_id, x, y, z``: one scanner position a line.

    Separators: commas, semicolons or whitespace; ``#`` comments and blank lines are
    skipped, and so is a first line that is not numbers (a header). Ids are whole
    numbers 0 to 65535 (the LAS field), each at most once; positions are finite
    and in ``unit``.

    Raises
    ------
    InputError
        The file is missing or unreadable, a line does not hold four numbers, an id
        is not a whole number in range or repeats, or there is no line at all; the
        message names the file and the line.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"scanner table not found: {p}")
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"cannot read {p}: {error_line(exc)}") from None
    if unit not in UNIT_METRES:
        raise InputError(f"unknown unit {unit!r}; expected one of {', '.join(UNIT_METRES)}")
    rows: list[tuple[int, float, float, float]] = []
    first = True
    for no, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0].strip()
        if not body:
            continue
        fields = [f for f in re.split(r"[,;\s]+", body) if f]
        try:
            values = [float(f) for f in fields]
        except ValueError:
            if first:  # a header line
                first = False
                continue
            raise InputError(f"{p} line {no}: expected numbers point_source_id, x, y, z, "
                             f"got {body!r}") from None
        first = False
        if len(values) != 4:
            raise InputError(f"{p} line {no}: expected 4 columns (point_source_id, x, y, z), "
                             f"found {len(values)}")
        sid = values[0]
        if not (math.isfinite(sid) and sid == math.floor(sid) and 0 <= sid <= MAX_POINT_SOURCE_ID):
            raise InputError(f"{p} line {no}: point_source_id must be a whole number from 0 "
                             f"to {MAX_POINT_SOURCE_ID}, got {fields[0]}")
        if not all(math.isfinite(v) for v in values[1:]):
            raise InputError(f"{p} line {no}: the position must be three finite numbers")
        if max(abs(v) for v in values[1:]) * UNIT_METRES[unit] > MAX_COORDINATE_M:
            raise InputError(f"{p} line {no}: the position reaches beyond "
                             f"{MAX_COORDINATE_M:g} m (the limit of cloud coordinates)")
        rows.append((int(sid), values[1], values[2], values[3]))
    if not rows:
        raise InputError(f"no scanner positions in {p} (expected lines of point_source_id, "
                         "x, y, z)")
    ids = np.array([r[0] for r in rows], dtype=np.int64)
    seen, counts = np.unique(ids, return_counts=True)
    if np.any(counts > 1):
        raise InputError(f"{p}: point_source_id {int(seen[counts > 1][0])} is given more than "
                         "once")
    order = np.argsort(ids)
    positions = np.array([r[1:] for r in rows], dtype=np.float64)[order] * UNIT_METRES[unit]
    return ScannerTable(ids=ids[order], positions=positions, source=str(p))


def with_scanner(cloud: PointCloud, position_m: tuple[float, float, float] | np.ndarray
                 ) -> PointCloud:
    """The cloud with one scanner at ``position_m`` (metres, the cloud's frame) for
    every point (replacing any positions it had)."""
    pos = np.asarray(position_m, dtype=np.float64).reshape(-1)
    if pos.shape != (3,) or not np.all(np.isfinite(pos)):
        raise InputError(f"a scanner position needs three finite coordinates, got {position_m!r}")
    if float(np.max(np.abs(pos))) > MAX_COORDINATE_M:
        raise InputError(f"a scanner position reaches beyond {MAX_COORDINATE_M:g} m (the limit "
                         f"of cloud coordinates), got {position_m!r}")
    return replace(cloud, scanner_positions=pos[None, :].copy(),
                   scan_index=np.zeros(cloud.n, dtype=np.int32))


def assign_scanners(cloud: PointCloud, point_ids: np.ndarray, table: ScannerTable) -> PointCloud:
    """The cloud with each point's scanner looked up by its point source id.

    Parameters
    ----------
    cloud : PointCloud
        The points.
    point_ids : (N,) integer array
        Every point's LAS ``point_source_id`` (:func:`point_source_ids`), in the
        cloud's order.
    table : ScannerTable
        The positions by id; ``scanner_positions`` becomes ``table.positions`` and
        ``scan_index`` the row of each point's id.

    Raises
    ------
    InputError
        The ids do not match the cloud's points, or some points have an id the table
        does not list (the message gives the ids and how many points each).
    """
    ids = np.asarray(point_ids)
    if ids.shape != (cloud.n,):
        raise InputError(f"{ids.shape[0]:,} point source ids for a cloud of {cloud.n:,} points "
                         "(did the file change?)")
    row = np.searchsorted(table.ids, ids)
    row_c = np.minimum(row, table.ids.shape[0] - 1)
    missing = table.ids[row_c] != ids
    if np.any(missing):
        absent, n = np.unique(ids[missing], return_counts=True)
        listed = ", ".join(f"{int(a)} ({int(k):,} points)" for a, k in zip(absent[:5], n[:5],
                                                                          strict=True))
        more = f" and {absent.shape[0] - 5} more" if absent.shape[0] > 5 else ""
        raise InputError(f"{table.source} has no position for point_source_id {listed}{more}")
    return replace(cloud, scanner_positions=table.positions.copy(),
                   scan_index=row_c.astype(np.int32))


def cloud_scanners(cloud: PointCloud) -> tuple[np.ndarray, np.ndarray] | None:
    """The cloud's scanner positions and each point's scan, checked.

    Returns
    -------
    (positions, scan) or None
        ``positions`` (S, 3) metres; ``scan`` (N,) int64 rows of ``positions``.
        None when the cloud has no positions (:data:`NO_POSITIONS` says what to do).

    Raises
    ------
    InputError
        Positions that are not finite, or scan indices out of range.
    """
    pos = cloud.scanner_positions
    if pos is None or np.size(pos) == 0:
        return None
    pos = np.asarray(pos, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(pos)):
        raise InputError(f"scanner positions of {cloud.source or 'the cloud'} are not finite")
    if pos.size and float(np.max(np.abs(pos))) > MAX_COORDINATE_M:
        raise InputError(f"scanner positions of {cloud.source or 'the cloud'} reach beyond "
                         f"{MAX_COORDINATE_M:g} m (the limit of cloud coordinates)")
    if cloud.scan_index is None:
        if pos.shape[0] != 1:
            raise InputError(f"{pos.shape[0]} scanner positions but no scan index per point")
        return pos, np.zeros(cloud.n, dtype=np.int64)
    scan = np.asarray(cloud.scan_index).astype(np.int64, copy=False)
    if scan.shape != (cloud.n,):
        raise InputError(f"scan index of {scan.shape[0]:,} points for a cloud of {cloud.n:,}")
    if scan.size and (scan.min() < 0 or scan.max() >= pos.shape[0]):
        raise InputError(f"scan index out of range for {pos.shape[0]} scanner positions")
    return pos, scan


# ----------------------------------------------------------------------------- point ids

#: Bytes per point while reading point source ids: the ids (uint16 and int64), the
#: coordinates of one chunk for the finite-row check.
IDS_BYTES_PER_POINT = 2 + 8


def point_source_ids(path: str | os.PathLike[str]) -> np.ndarray:
    """Every point's LAS ``point_source_id``, for the rows :func:`rough_viewer.io.load
    .load_points` keeps (finite coordinates), in file order.

    LAS/LAZ files store the id in every point record. A text cloud may carry it as a
    column whose header names it (``point_source_id``, ``Point Source ID``, ...).

    Raises
    ------
    InputError
        Another format, or a text cloud without such a column: the message says to
        give ``--scanner X,Y,Z`` for one scanner instead.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix in (".las", ".laz"):
        with foreign_errors(f"cannot read the point source ids of {p}"):
            return _isolated_ids(p)
    if suffix in (".xyz", ".txt", ".csv", ".pts"):
        ids = _text_ids(p)
        if ids is not None:
            return ids
        raise InputError(f"{p} has no point_source_id column (a header naming it is needed) "
                         "for --scanners; give --scanner X,Y,Z for one scanner")
    raise InputError(f"{p} carries no point_source_id for --scanners (LAS/LAZ files and text "
                     "with a point_source_id column do); give --scanner X,Y,Z for one scanner")


def _isolated_ids(p: Path) -> np.ndarray:
    """:func:`_las_ids` in a child process where reads are isolated
    (:mod:`rough_viewer.io.sandbox.isolate`): lazrs decodes the file again, another layer."""
    from rough_viewer.io.formats.las import LAS_CHUNK, check_las_layout
    from rough_viewer.io.sandbox import isolate

    if not isolate.available():
        return _las_ids(p)
    layout = check_las_layout(p)
    n = layout.point_count
    need = n * IDS_BYTES_PER_POINT + min(n, LAS_CHUNK) * 90.0
    limits = isolate.limits_for(need, layout.size)
    items = isolate.stream_isolated(f"{__name__}:_las_id_items", p, label="LAS/LAZ",
                                    limits=limits, names=frozenset({"ids"}))
    try:
        return next(items)["ids"]
    finally:
        items.close()


def _las_id_items(p: Path, *, progress: object = None) -> Iterator[dict[str, np.ndarray]]:
    """The ids as one item of a stream (what the child process runs)."""
    yield {"ids": _las_ids(p)}


def _las_ids(p: Path) -> np.ndarray:
    import laspy

    from rough_viewer.io.formats.las import LAS_CHUNK, laz_backend, open_las

    with open_las(p, laz_backend=laz_backend()) as reader:
        hdr = reader.header
        n = int(hdr.point_count)
        require(n * IDS_BYTES_PER_POINT + min(n, LAS_CHUNK) * 48.0,
                f"reading the point source ids of {n:,} points from {p}")
        reader.decompression_selection = (laspy.DecompressionSelection.XY_RETURNS_CHANNEL
                                          | laspy.DecompressionSelection.Z
                                          | laspy.DecompressionSelection.POINT_SOURCE_ID)
        scale = np.asarray(hdr.scales, dtype=np.float64)
        offset = np.asarray(hdr.offsets, dtype=np.float64)
        parts = []
        done = 0
        for chunk in reader.chunk_iterator(LAS_CHUNK):
            m = len(chunk)
            if m == 0:
                continue
            m = min(m, n - done)
            if m <= 0:
                break
            ok = np.ones(m, dtype=bool)
            for raw, k in ((chunk.X, 0), (chunk.Y, 1), (chunk.Z, 2)):
                with np.errstate(over="ignore", invalid="ignore"):
                    v = np.multiply(np.asarray(raw)[:m], scale[k], dtype=np.float64)
                    v += offset[k]
                ok &= np.isfinite(v)
            parts.append(np.asarray(chunk.point_source_id)[:m][ok].astype(np.int64))
            done += m
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


def _normal_name(name: str) -> str:
    return re.sub(r"[^a-z]", "", name.lower())


def _text_ids(p: Path) -> np.ndarray | None:
    """The ``point_source_id`` column of a text cloud with a header naming it, or None."""
    from rough_viewer.io.formats.text import SEPARATORS, _fields, _significant_lines

    lines = _significant_lines(p, 2)
    if len(lines) < 2:
        return None
    first_no, first = lines[0]
    delim = next((d for d in SEPARATORS if d in first), None)
    names = [_normal_name(f) for f in _fields(first.lstrip("/"), delim)]
    if "pointsourceid" not in names:
        return None
    col = names.index("pointsourceid")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            data = np.loadtxt(p, delimiter=delim, usecols=(0, 1, 2, col), skiprows=first_no + 1,
                              dtype=np.float64, comments="#", ndmin=2)
    except ValueError as exc:
        raise InputError(f"cannot parse the point_source_id column of {p}: "
                         f"{error_line(exc)}") from None
    ok = np.all(np.isfinite(data[:, :3]), axis=1)
    ids = data[ok, 3]
    if not np.all((ids == np.floor(ids)) & (ids >= 0) & (ids <= MAX_POINT_SOURCE_ID)):
        raise InputError(f"{p}: point_source_id values must be whole numbers from 0 to "
                         f"{MAX_POINT_SOURCE_ID}")
    return ids.astype(np.int64)
