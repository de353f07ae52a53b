"""Triangle meshes: a surface as vertices and triangles, read from the formats that
carry faces (STL, PLY with a face element).

The mesh is in metres, like every cloud: a file's coordinates are read in
``units`` when given, else metres (STL and PLY declare no CRS). Meshes are what the
TIN roughness parameters (:mod:`rough_viewer.tin`) measure; a cloud without faces
is triangulated there, in its best-fit plane.

>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> _ = (folder / "two.stl").write_text(
...     "solid t\\n"
...     "facet normal 0 0 1\\n outer loop\\n vertex 0 0 0\\n vertex 1 0 0\\n vertex 0 1 0\\n"
...     " endloop\\nendfacet\\n"
...     "facet normal 0 0 1\\n outer loop\\n vertex 1 0 0\\n vertex 1 1 0\\n vertex 0 1 0\\n"
...     " endloop\\nendfacet\\nendsolid t\\n")
>>> mesh = load_mesh(folder / "two.stl", units="mm")
>>> mesh.n_vertices, mesh.n_faces, float(mesh.vertices.max())
(4, 2, 0.001)
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, check_input_file
from rough_viewer.io.sandbox import isolate
from rough_viewer.memory import require
from rough_viewer.vocabulary import UNIT_METRES, InputError, Unit, foreign_errors

#: Formats whose files may carry triangles.
MESH_SUFFIXES = (".stl", ".ply")


@dataclass(frozen=True)
class TriangleMesh:
    """A triangulated surface: vertices in metres and triangles indexing them."""

    vertices: np.ndarray
    """(V, 3) float64 vertex coordinates, metres, the file's frame."""
    faces: np.ndarray
    """(T, 3) int64 vertex indices of each triangle (its winding as given)."""
    source: str = ""
    """Path of the file read, or ``""`` (a triangulated cloud, an in-memory mesh)."""
    source_unit: str = "m"
    """Unit the file's coordinates were in; the mesh itself is metres."""

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        """Number of triangles."""
        return int(self.faces.shape[0])

    def kept(self, mask: np.ndarray) -> TriangleMesh | None:
        """The mesh of the vertices ``mask`` keeps ((V,) bool; a crop of the cloud of
        its vertices): the triangles whose three corners are kept, indexing the kept
        vertices in their order. None when no triangle is left."""
        keep = np.asarray(mask, dtype=bool)
        if keep.shape != (self.n_vertices,):
            raise ValueError(f"a mask over {keep.shape[0]:,} points cannot crop a mesh of "
                             f"{self.n_vertices:,} vertices")
        faces = self.faces[keep[self.faces].all(axis=1)]
        if faces.shape[0] == 0:
            return None
        new_index = np.cumsum(keep, dtype=np.int64) - 1
        return TriangleMesh(vertices=self.vertices[keep], faces=new_index[faces],
                            source=self.source, source_unit=self.source_unit)

    def cloud(self) -> PointCloud:
        """The vertices as a point cloud (metres, the mesh's unit kept)."""
        from dataclasses import replace

        return replace(PointCloud.from_xyz(self.vertices, source=self.source),
                       source_unit=self.source_unit)


def check_mesh(vertices: np.ndarray, faces: np.ndarray, what: str = "mesh") -> TriangleMesh:
    """A :class:`TriangleMesh` of checked arrays: (V, 3) finite vertices, (T, 3) faces
    indexing them, at least one triangle (InputError naming ``what`` otherwise)."""
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise InputError(f"{what}: vertices must be an (V, 3) array, got shape {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise InputError(f"{what}: faces must be a (T, 3) array, got shape {f.shape}")
    if f.shape[0] == 0:
        raise InputError(f"{what}: no triangles")
    if f.min() < 0 or f.max() >= v.shape[0]:
        raise InputError(f"{what}: a face indexes a vertex that does not exist")
    if not np.all(np.isfinite(v[f])):
        raise InputError(f"{what}: a triangle has a non-finite corner")
    return TriangleMesh(vertices=v, faces=f)


def load_mesh(path: str | os.PathLike[str], *, units: Unit | None = None) -> TriangleMesh | None:
    """The triangles of an STL file or of a PLY file with faces, in metres; None for
    a file that carries no faces (another format, or a PLY of vertices only).

    Parameters
    ----------
    path : path-like
        The file.
    units : {"m", "mm", "ft", "us-ft"}, optional
        Unit of the file's coordinates (default metres).

    Raises
    ------
    InputError
        Missing or unreadable file, malformed faces.
    """
    from rough_viewer.io.formats.ply import read_ply_mesh
    from rough_viewer.io.formats.stl import read_stl_mesh

    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        return None
    check_input_file(p)
    if units is not None and units not in UNIT_METRES:
        raise InputError(f"unknown unit {units!r}; choose one of {', '.join(UNIT_METRES)}")
    # the file's bytes, a few copies of its corners and the faces
    require(8.0 * p.stat().st_size, f"reading the mesh of {p.name}")
    with foreign_errors(f"cannot read {p}", libraries=()):
        read = _read_isolated(p) if isolate.available() else \
            read_stl_mesh(p) if suffix == ".stl" else read_ply_mesh(p)
    if read is None:
        return None
    vertices, faces = read
    unit: Unit = units or "m"
    mesh = check_mesh(vertices * UNIT_METRES[unit], faces, str(p))
    return TriangleMesh(vertices=mesh.vertices, faces=mesh.faces, source=str(p),
                        source_unit=unit)


def _read_isolated(p: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """The mesh read in a child process (:mod:`rough_viewer.io.sandbox.isolate`): the PLY and
    STL parsers run on bytes anyone can craft."""
    size = p.stat().st_size
    items = isolate.stream_isolated(
        f"{__name__}:_mesh_items", p, label="PLY" if p.suffix.lower() == ".ply" else "STL",
        limits=isolate.limits_for(8.0 * size, size), names=frozenset({"vertices", "faces"}))
    try:
        item = next(items)
    finally:
        items.close()
    return (item["vertices"], item["faces"]) if item else None


def _mesh_items(p: Path, *, progress: object = None) -> Iterator[dict[str, np.ndarray]]:
    """The mesh as one item of a stream (empty: no faces), what the child runs."""
    from rough_viewer.io.formats.ply import read_ply_mesh
    from rough_viewer.io.formats.stl import read_stl_mesh

    read = read_stl_mesh(p) if p.suffix.lower() == ".stl" else read_ply_mesh(p)
    yield {} if read is None else {"vertices": read[0], "faces": read[1]}
