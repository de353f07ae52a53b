"""PLY point files: reading ASCII or binary (either byte order) vertex ``x``, ``y``,
``z`` (:func:`read_ply`) or the vertices with their faces (:func:`read_ply_mesh`);
writing binary little-endian PLY with per-point fields (through plyfile).

One reader of the format, this one, for the points and for the faces alike: its
header parser bounds every line and count before anything is read, and it is faster
than plyfile (docs/export.md); plyfile only writes."""

from __future__ import annotations

import os
from collections.abc import Collection, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.io.formats.point_fields import PointFields
from rough_viewer.io.output import write_path_atomic
from rough_viewer.memory import require
from rough_viewer.vocabulary import UNIT_METRES, InputError

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


#: Longest line a PLY header may hold, bytes (a comment of 600 MB was read whole
#: and split into words: 26 times the file's size in memory).
MAX_HEADER_LINE = 64 << 10
#: Largest PLY header, bytes.
MAX_HEADER_BYTES = 1 << 20


@dataclass(frozen=True)
class HeaderElement:
    """One element of a PLY header: its name, count and properties."""

    name: str
    count: int
    properties: tuple[tuple[str, str | None, str], ...]
    """``(name, list count type or None, value type)`` of each property."""


@dataclass(frozen=True)
class PlyHeader:
    """What a PLY header declares."""

    format: str
    """``ascii``, ``binary_little_endian`` or ``binary_big_endian``."""
    elements: tuple[HeaderElement, ...]
    data_offset: int
    """Byte where the data start (after ``end_header``)."""

    @property
    def vertex(self) -> HeaderElement:
        """The vertex element."""
        return next(e for e in self.elements if e.name == "vertex")


def _header_lines(fh: BinaryIO, p: Path) -> Iterator[list[str]]:
    """The words of every header line after the magic one but comments and blank
    lines, up to ``end_header`` (the caller stops there); refuses a header without
    it, a line longer than :data:`MAX_HEADER_LINE` or a header longer than
    :data:`MAX_HEADER_BYTES`."""
    while True:
        raw = fh.readline(MAX_HEADER_LINE + 1)
        if not raw:
            raise InputError(f"PLY header has no end_header: {p}")
        if len(raw) > MAX_HEADER_LINE or fh.tell() > MAX_HEADER_BYTES:
            raise InputError(f"PLY header of {p} has a line longer than {MAX_HEADER_LINE:,} "
                             f"bytes or is longer than {MAX_HEADER_BYTES:,}: not a PLY file, "
                             "or a damaged one")
        parts = raw.decode("ascii", errors="replace").split()
        if parts and parts[0] not in ("comment", "obj_info"):
            yield parts


def _header_line(parts: list[str], fmt: str | None,
                 elements: list[tuple[str, int, list[tuple[str, str | None, str]]]],
                 p: Path) -> str | None:
    """Read one header line's words: a ``format`` line gives the format returned (else
    ``fmt``), an ``element`` or ``property`` line goes into ``elements`` (in place)."""
    if parts[0] == "format":
        return parts[1]
    if parts[0] == "element":
        count = int(parts[2])
        if count < 0:
            raise InputError(f"PLY element {parts[1]!r} of {p} declares {count:,} "
                             "records: a damaged header")
        elements.append((parts[1], count, []))
    elif parts[0] == "property":
        if not elements:
            raise InputError(f"PLY property before any element: {p}")
        if parts[1] == "list":
            elements[-1][2].append((parts[4], parts[2], parts[3]))
        else:
            elements[-1][2].append((parts[2], None, parts[1]))
    return fmt


def read_ply_header(fh: BinaryIO, p: Path) -> PlyHeader:
    """Parse a PLY header from ``fh`` (at the file's start), leaving ``fh`` at the data.

    Raises
    ------
    InputError
        No ``ply`` magic line, no ``end_header``, a line or header too long, an element
        count that is not a whole number >= 0, a property before any element, an
        unsupported format, no vertex element or one without x, y, z.
    """
    if fh.readline(8).strip() != b"ply":
        raise InputError(f"not a PLY file (no 'ply' magic line): {p}")
    fmt = None
    elements: list[tuple[str, int, list[tuple[str, str | None, str]]]] = []
    for parts in _header_lines(fh, p):
        if parts[0] == "end_header":
            break
        try:
            fmt = _header_line(parts, fmt, elements, p)
        except InputError:
            raise
        except (IndexError, ValueError):
            raise InputError(f"malformed PLY header line {' '.join(parts)[:80]!r} in {p}") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise InputError(f"unsupported PLY format {fmt!r} in {p}")
    if "vertex" not in [e[0] for e in elements]:
        raise InputError(f"PLY file has no vertex element: {p}")
    header = PlyHeader(fmt, tuple(HeaderElement(n, c, tuple(q)) for n, c, q in elements), fh.tell())
    if not all(k in [q[0] for q in header.vertex.properties] for k in "xyz"):
        raise InputError(f"PLY vertex element lacks x, y, z properties: {p}")
    return header


def read_ply(p: Path) -> PointCloud:
    with open(p, "rb") as fh:
        header = read_ply_header(fh, p)
        fmt = header.format
        elements = [(e.name, e.count, list(e.properties)) for e in header.elements]
        vi = [e[0] for e in elements].index("vertex")
        _, n_vert, props = elements[vi]
        pnames = [q[0] for q in props]
        if fmt == "ascii":
            skip = sum(e[1] for e in elements[:vi])
            if any(q[1] is not None for q in props):
                raise InputError(f"PLY vertex element with list properties is not supported: {p}")
            for _ in range(skip):
                if not fh.readline():
                    raise InputError(f"PLY file is truncated: it ends before its vertices: {p}")
            cols = tuple(pnames.index(k) for k in "xyz")
            data = np.loadtxt(fh, usecols=cols, max_rows=n_vert, ndmin=2, dtype=np.float64)
            if data.shape[0] != n_vert:
                raise InputError(f"PLY file is truncated: {data.shape[0]} of {n_vert} vertices in {p}")
            x, y, z = (np.ascontiguousarray(data[:, k]) for k in range(3))
        else:
            end = "<" if fmt == "binary_little_endian" else ">"
            for name, count, eprops in elements[:vi]:
                if any(q[1] is not None for q in eprops):
                    raise InputError(
                        f"PLY element {name!r} with list properties before the vertices is not supported: {p}"
                    )
                fh.seek(count * sum(np.dtype(_PLY_TYPES[q[2]]).itemsize for q in eprops), 1)
            if any(q[1] is not None for q in props):
                raise InputError(f"PLY vertex element with list properties is not supported: {p}")
            try:
                dt = np.dtype([(q[0], end + _PLY_TYPES[q[2]]) for q in props])
            except KeyError as exc:
                raise InputError(f"unknown PLY property type {exc} in {p}") from None
            room = max(0, p.stat().st_size - fh.tell())
            if n_vert * dt.itemsize > room:
                raise InputError(f"PLY file is truncated: its header declares {n_vert:,} vertices "
                                 f"but the file holds at most {room // dt.itemsize:,}: {p}")
            require(dt.itemsize * n_vert + 24.0 * n_vert, f"reading {p.name}")
            rec = np.fromfile(fh, dtype=dt, count=n_vert)
            if rec.shape[0] < n_vert:
                raise InputError(f"PLY file is truncated: {rec.shape[0]} of {n_vert} vertices in {p}")
            x, y, z = (rec[k].astype(np.float64) for k in "xyz")
            del rec
    return finite_cloud(x, y, z, None, p)


#: Names a face element's list of vertex indices goes by.
_FACE_LISTS = ("vertex_indices", "vertex_index")


def read_ply_mesh(p: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """The vertices and triangles of a PLY file, or None when it has no faces.

    The same reader as the points' (:func:`read_ply_header`, every count checked
    against the bytes the file holds before anything is allocated), walking the
    elements in their order.

    Returns
    -------
    (vertices, faces) or None
        ``vertices`` (V, 3) float64, the file's vertex ``x, y, z`` in its order;
        ``faces`` (T, 3) int64 indices into them. Polygons of more than three corners
        are split into a fan of triangles (corner 0 with each later edge); faces with
        an index outside the vertices, or a non-finite corner, are dropped. Vertices
        are kept as they are (an unused one changes nothing downstream).
    """
    with open(p, "rb") as fh:
        header = read_ply_header(fh, p)
        names = [e.name for e in header.elements]
        if "face" not in names or header.elements[names.index("face")].count == 0:
            return None
        face = header.elements[names.index("face")]
        key = next((q for q in face.properties if q[0] in _FACE_LISTS and q[1] is not None), None)
        if key is None:
            raise InputError(f"PLY face element has no vertex_indices list: {p}")
        read = _ascii_elements if header.format == "ascii" else _binary_elements
        found = read(fh, header, p)
    vertex, lists = found["vertex"], found["face"][key[0]]
    vertices = np.column_stack([np.asarray(vertex[k], dtype=np.float64) for k in "xyz"])
    if isinstance(lists, np.ndarray) and lists.dtype != object:  # (T, 3) already
        faces = np.asarray(lists, dtype=np.int64).reshape(-1, 3)
    else:
        faces = _fans(lists, p)
    ok = np.all((faces >= 0) & (faces < vertices.shape[0]), axis=1)
    faces = faces[ok]
    finite = np.all(np.isfinite(vertices), axis=1)
    faces = faces[np.all(finite[faces], axis=1)]
    return vertices, faces


def _ply_dtype(kind: str, p: Path, end: str = "<") -> np.dtype:
    try:
        return np.dtype(end + _PLY_TYPES[kind])
    except KeyError:
        raise InputError(f"unknown PLY property type {kind!r} in {p}") from None


def _binary_elements(fh: BinaryIO, header: PlyHeader, p: Path) -> dict[str, dict[str, object]]:
    """Every element of a binary PLY up to the last of vertex and face, as
    ``{element: {property: values}}``: a scalar property an array, a list property an
    (N, 3) array where every list holds 3 values, else a list of arrays."""
    end = "<" if header.format == "binary_little_endian" else ">"
    size = p.stat().st_size
    last = max(k for k, e in enumerate(header.elements) if e.name in ("vertex", "face"))
    out: dict[str, dict[str, object]] = {}
    for e in header.elements[: last + 1]:
        room = max(0, size - fh.tell())
        if all(q[1] is None for q in e.properties):
            dt = np.dtype([(q[0], _ply_dtype(q[2], p, end)) for q in e.properties])
            if e.count * dt.itemsize > room:
                raise _truncated(p, e, room // max(dt.itemsize, 1))
            require(2.0 * dt.itemsize * e.count, f"reading {p.name}")
            rec = np.fromfile(fh, dtype=dt, count=e.count)
            out[e.name] = {q[0]: rec[q[0]] for q in e.properties}
            continue
        least = sum(_ply_dtype(q[1] or q[2], p, end).itemsize for q in e.properties)
        if e.count * least > room:
            raise _truncated(p, e, room // max(least, 1))
        out[e.name] = _binary_lists(fh, e, end, p, room)
    return out


def _binary_lists(fh: BinaryIO, e: HeaderElement, end: str, p: Path, room: int
                  ) -> dict[str, object]:
    """An element with list properties: as fixed 3-lists when every list holds three
    values (one read), else record by record."""
    types = [(q[0], _ply_dtype(q[1], p, end) if q[1] else None, _ply_dtype(q[2], p, end))
             for q in e.properties]
    fixed = np.dtype([(n, v) if c is None else (n, [("n", c), ("v", v, (3,))])
                      for n, c, v in types])
    start = fh.tell()
    if e.count * fixed.itemsize <= room:
        require(2.0 * fixed.itemsize * e.count, f"reading {p.name}")
        rec = np.fromfile(fh, dtype=fixed, count=e.count)
        if rec.shape[0] == e.count and all(np.all(rec[n]["n"] == 3)
                                           for n, c, _ in types if c is not None):
            return {n: rec[n] if c is None else rec[n]["v"] for n, c, _ in types}
        fh.seek(start)
    data = fh.read(room)
    require(24.0 * len(data), f"the faces of {p.name}")
    cols: dict[str, list[object]] = {n: [] for n, _, _ in types}
    at = 0
    try:
        for _ in range(e.count):
            for n, c, v in types:
                if c is None:
                    cols[n].append(np.frombuffer(data, v, 1, at)[0])
                    at += v.itemsize
                    continue
                k = int(np.frombuffer(data, c, 1, at)[0])
                at += c.itemsize
                cols[n].append(np.frombuffer(data, v, k, at))
                at += k * v.itemsize
    except ValueError:  # a buffer too small: the file ends inside the element
        raise InputError(f"PLY file is truncated: it ends inside its {e.name} element: {p}") from None
    return dict(cols)


def _ascii_elements(fh: BinaryIO, header: PlyHeader, p: Path) -> dict[str, dict[str, object]]:
    """:func:`_binary_elements` of an ASCII PLY, one line a record (every list a list
    of arrays)."""
    last = max(k for k, e in enumerate(header.elements) if e.name in ("vertex", "face"))
    out: dict[str, dict[str, object]] = {}
    for e in header.elements[: last + 1]:
        cols: dict[str, list[object]] = {q[0]: [] for q in e.properties}
        kinds = [(n, c, _ply_dtype(v, p)) for n, c, v in e.properties]
        for _ in range(e.count):
            line = fh.readline(MAX_HEADER_LINE + 1)
            if not line:
                raise InputError(f"PLY file is truncated: it ends inside its {e.name} element: {p}")
            words = line.split()
            try:
                at = 0
                for name, count, kind in kinds:
                    k = 1 if count is None else int(words[at])
                    at += 0 if count is None else 1
                    if k < 0 or at + k > len(words):
                        raise ValueError(line)
                    values = np.array([float(w) for w in words[at:at + k]], dtype=np.float64)
                    cols[name].append(values[0] if count is None else values.astype(kind))
                    at += k
            except (IndexError, ValueError):
                raise InputError(f"malformed PLY {e.name} line {line[:80]!r} in {p}") from None
        out[e.name] = {n: np.asarray(cols[n], dtype=np.float64) if c is None else cols[n]
                       for n, c, _ in kinds}
    return out


def _truncated(p: Path, e: HeaderElement, holds: int) -> InputError:
    return InputError(f"PLY file is truncated: its header declares {e.count:,} {e.name} "
                      f"records but the file holds at most {holds:,}: {p}")


def _fans(lists: Any, p: Path) -> np.ndarray:
    """(T, 3) triangles of polygons given as a sequence of index arrays: a fan
    per polygon, (corner 0, corner j, corner j + 1) for j = 1 .. size - 2."""
    sizes = np.fromiter((len(f) for f in lists), dtype=np.int64, count=len(lists))
    require(48.0 * float(sizes.sum()), f"the faces of {p.name}")
    flat = np.concatenate([np.asarray(f, dtype=np.int64).ravel() for f in lists])
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    fans = np.clip(sizes - 2, 0, None)
    owner = np.repeat(np.arange(sizes.size), fans)
    j = np.arange(int(fans.sum())) - np.repeat(np.cumsum(fans) - fans, fans) + 1
    base = start[owner]
    return np.column_stack([flat[base], flat[base + j], flat[base + j + 1]])




def write_ply_fields(
    path: str | os.PathLike[str],
    cloud: PointCloud,
    fields: PointFields | None = None,
    *,
    comments: Sequence[str] = (),
    unit: str = "m",
    lengths: Collection[str] = (),
) -> str:
    """Write a cloud as binary little-endian PLY (plyfile), atomically.

    Vertex properties: ``x``, ``y``, ``z`` (float64, the cloud's coordinates in
    ``unit``), ``intensity`` (uint16) where the cloud has it, then each of ``fields``
    (float32 roughness, int32 cell indices, uint32 counts); the fields named in
    ``lengths`` (metres in the cells' arrays) in ``unit`` too. A last comment states
    the unit (``rough_viewer.unit mm``, as the tables' ``unit_m`` column and Parquet
    metadata do). CloudCompare shows the extra properties as scalar fields.

    Returns
    -------
    str
        One line saying what was written.
    """
    from plyfile import PlyData, PlyElement

    out = Path(path)
    if out.suffix.lower() != ".ply":
        raise InputError(f"PLY output must end in .ply, got {out}")
    n = cloud.n
    if fields is not None and fields.n_points != n:
        raise InputError(f"{fields.n_points} per-point values for a cloud of {n} points")
    dims: list[tuple[str, str]] = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    if cloud.intensity is not None:
        dims.append(("intensity", "<u2"))
    for f in fields.fields if fields is not None else ():
        dims.append((f.name, f.dtype.newbyteorder("<").str))
    dtype = np.dtype(dims)
    # the vertex array, plus plyfile's own copy while writing
    require(2.0 * n * dtype.itemsize, f"writing {out.name} ({n:,} points)")
    vertex = np.empty(n, dtype=dtype)
    if unit not in UNIT_METRES:
        raise InputError(f"unknown unit {unit!r}; expected one of {', '.join(UNIT_METRES)}")
    per = float(UNIT_METRES[unit])
    vertex["x"], vertex["y"], vertex["z"] = cloud.x / per, cloud.y / per, cloud.z / per
    if cloud.intensity is not None:
        vertex["intensity"] = np.clip(np.asarray(cloud.intensity), 0, 65535)
    if fields is not None:
        for f, v in zip(fields.fields, fields.gather(0, n), strict=True):
            vertex[f.name] = v / per if f.name in lengths and per != 1.0 else v
    scaled = [f.name for f in (fields.fields if fields is not None else ()) if f.name in lengths]
    said = f"rough_viewer.unit {unit} (x, y, z{''.join(', ' + n for n in scaled)})"
    ply = PlyData([PlyElement.describe(vertex, "vertex")], text=False, byte_order="<",
                  comments=[*comments, said])
    write_path_atomic(out, lambda tmp: ply.write(str(tmp)))
    n_fields = 0 if fields is None else len(fields.fields)
    return f"binary little-endian PLY, {n:,} vertices, {n_fields} scalar properties added"
