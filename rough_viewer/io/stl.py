"""STL meshes (ASCII or binary): the mesh's vertices, each once (:func:`read_stl`),
or its vertices and triangles (:func:`read_stl_mesh`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.vocabulary import InputError

_STL_DTYPE = np.dtype([("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def _corners(p: Path) -> np.ndarray:
    """(3 T, 3) float64 corners of the file's T triangles, three rows per triangle in
    the file's order (non-finite ones included)."""
    size = p.stat().st_size
    with open(p, "rb") as fh:
        head = fh.read(84)
    binary = False
    if len(head) >= 84:
        n_tri = int(np.frombuffer(head[80:84], dtype="<u4")[0])
        binary = size == 84 + 50 * n_tri
    if binary:
        tri = np.fromfile(p, dtype=_STL_DTYPE, offset=84, count=n_tri)
        verts = tri["v"].reshape(-1, 3).astype(np.float64)
    else:
        if not head.lstrip().lower().startswith(b"solid"):
            raise InputError(f"not an STL file (neither binary nor ASCII 'solid'): {p}")
        text = p.read_text(encoding="ascii", errors="replace")
        tokens = text.split()
        arr = np.array(tokens, dtype=object)
        at = np.flatnonzero(arr == "vertex")
        if at.size == 0:
            raise InputError(f"no vertices in {p}")
        if at[-1] + 3 >= arr.size:
            raise InputError(f"STL file is truncated: {p}")
        try:
            verts = np.array(
                [arr[at + 1], arr[at + 2], arr[at + 3]], dtype=np.float64
            ).T
        except ValueError:
            raise InputError(f"malformed vertex line in {p}") from None
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
