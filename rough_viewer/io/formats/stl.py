"""STL meshes (ASCII or binary): the mesh's vertices, each once (:func:`read_stl`),
or its vertices and triangles (:func:`read_stl_mesh`)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.vocabulary import InputError

_STL_DTYPE = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])

#: An ASCII STL vertex line, and any line that starts with the keyword.
_VERTEX = re.compile(rb"(?im)^[ \t]*vertex[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)[ \t]*\r?$")
_VERTEX_WORD = re.compile(rb"(?im)^[ \t]*vertex\b")
#: Bytes of an ASCII STL parsed at a time (its text never held whole: the old
#: reader split it into Python words, 28 times the file's size).
ASCII_BLOCK = 8 << 20


def stl_layout(p: Path) -> tuple[bool, int]:
    """``(binary, triangles)`` of an STL file: binary when its size is exactly the 84-byte
    header plus 50 bytes per triangle it declares (``triangles`` is 0 for ASCII).

    Raises InputError for a file that is neither binary nor ASCII ``solid``."""
    size = p.stat().st_size
    with open(p, "rb") as fh:
        head = fh.read(84)
    if len(head) >= 84:
        n_tri = int(np.frombuffer(head[80:84], dtype="<u4")[0])
        if size == 84 + 50 * n_tri:
            return True, n_tri
    if not head.lstrip().lower().startswith(b"solid"):
        raise InputError(f"not an STL file (neither binary nor ASCII 'solid'): {p}")
    return False, 0


def _corners(p: Path) -> np.ndarray:
    """(3 T, 3) float64 corners of the file's T triangles, three rows per triangle in
    the file's order (non-finite ones included)."""
    binary, n_tri = stl_layout(p)
    if binary:
        tri = np.fromfile(p, dtype=_STL_DTYPE, offset=84, count=n_tri)
        verts = tri["v"].reshape(-1, 3).astype(np.float64)
    else:
        verts = _ascii_vertices(p)
    if verts.shape[0] == 0:
        raise InputError(f"no points in {p}")
    return verts


def read_stl(p: Path) -> PointCloud:
    verts = _corners(p)
    verts = verts[np.all(np.isfinite(verts), axis=1)] if not np.all(np.isfinite(verts)) else verts
    uniq = np.unique(verts, axis=0)
    return finite_cloud(uniq[:, 0].copy(), uniq[:, 1].copy(), uniq[:, 2].copy(), None, p)


def read_stl_mesh(p: Path) -> tuple[np.ndarray, np.ndarray]:
    """The mesh of an STL file: ``(vertices, faces)``.

    ``vertices`` (V, 3) float64 are the distinct corners, sorted as :func:`read_stl`
    sorts its points (for a file whose corners are all finite the two agree row for
    row); ``faces``
    (T, 3) int64 index them, one row per triangle of the file whose three corners
    are finite, in the file's order and corner order (its winding).
    """
    corners = _corners(p)
    tri = corners.reshape(-1, 3, 3)
    tri = tri[np.all(np.isfinite(tri), axis=(1, 2))]
    if tri.shape[0] == 0:
        raise InputError(f"no triangle with finite corners in {p}")
    vertices, inverse = np.unique(tri.reshape(-1, 3), axis=0, return_inverse=True)
    return vertices, np.asarray(inverse, dtype=np.int64).reshape(-1, 3)


def _ascii_vertices(p: Path) -> np.ndarray:
    """(V, 3) float64 vertices of an ASCII STL, its text parsed a block of lines at a
    time.

    Raises InputError when a ``vertex`` line does not hold three numbers (a malformed
    or truncated file) or the file has no vertices."""
    parts: list[np.ndarray] = []
    carry = b""
    with open(p, "rb") as fh:
        while True:
            block = fh.read(ASCII_BLOCK)
            data = carry + block
            if block:
                cut = data.rfind(b"\n") + 1
                carry, data = data[cut:], data[:cut]
            else:
                carry = b""
            found = _VERTEX.findall(data)
            if len(found) != len(_VERTEX_WORD.findall(data)):
                raise InputError(f"malformed or truncated vertex line in {p}")
            if found:
                try:
                    parts.append(np.array(found, dtype=np.float64))
                except ValueError:
                    raise InputError(f"malformed vertex line in {p}") from None
            del found, data
            if not block:
                break
    if not parts:
        raise InputError(f"no vertices in {p}")
    return np.concatenate(parts) if len(parts) > 1 else parts[0]
