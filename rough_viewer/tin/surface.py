"""Triangulated surfaces for the TIN roughness parameters: a cloud triangulated in
its best-fit plane, and the facets (unit normals, areas, centroids) of a mesh.

Triangulating a cloud: the points are projected onto the plane of the face (the
whole-cloud ODR plane, :func:`rough_viewer.grid.planes.whole_cloud_plane`, in the
frame of :func:`rough_viewer.grid.maps.face_frame`) and triangulated there by
Delaunay (``scipy.spatial.Delaunay``, Qhull); each triangle keeps its corners'
3-D positions. A Delaunay triangulation covers the convex hull of the points, so it
also bridges holes (shadows behind asperities, gaps between scans) and the hull's
concave bays with long, thin triangles that are no rock: a triangle with an edge
longer than ``max_edge`` in the plane (default :data:`MAX_EDGE_SPACINGS` point
spacings) is dropped. Repeated points (same plane position) are merged by Qhull
and never make a triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.maps import Plane, face_frame
from rough_viewer.grid.planes import whole_cloud_plane
from rough_viewer.grid.spacing import neighbour_distance
from rough_viewer.io.cloud import PointCloud, as_xyz
from rough_viewer.io.formats.mesh import TriangleMesh, check_mesh
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError, error_line

#: Default longest triangle edge kept, in point spacings (median 4th-neighbour
#: distance in the plane): Delaunay's own triangles on a scan are 1-2 spacings long.
MAX_EDGE_SPACINGS = 5.0
#: Peak bytes per point of a planar Delaunay triangulation (Qhull's working memory
#: and scipy's arrays; measured about 720 on a million random points).
DELAUNAY_BYTES_PER_POINT = 800.0
#: Bytes per triangle of :func:`facets` (normals, areas, centroids, temporaries).
FACET_BYTES = 12 * 8


@dataclass(frozen=True)
class Facets:
    """Per-triangle geometry of a mesh (metres)."""

    normals: np.ndarray
    """(T, 3) unit normals, oriented to the side of ``toward`` (see :func:`facets`)."""
    areas: np.ndarray
    """(T,) areas, square metres."""
    centroids: np.ndarray
    """(T, 3) centroids, metres."""
    index: np.ndarray
    """(T,) row of each facet in the mesh's faces (triangles of zero area are left
    out)."""


def triangulate_cloud(
    points: PointCloud | np.ndarray,
    *,
    plane: Plane | None = None,
    max_edge: float | None = None,
) -> TriangleMesh:
    """Triangulate a cloud in its best-fit plane (see the module docstring).

    Parameters
    ----------
    points : PointCloud or (N, 3) array
        Points, metres.
    plane : Plane, optional
        The plane to triangulate in (default: the whole-cloud ODR plane).
    max_edge : float, optional
        Longest in-plane edge of a triangle kept, metres (default
        :data:`MAX_EDGE_SPACINGS` times the point spacing); ``inf`` keeps every
        Delaunay triangle.

    Returns
    -------
    TriangleMesh
        The cloud's points as vertices (in their order) and the triangles kept.

    Examples
    --------
    A 3 x 3 grid of points makes 8 triangles:

    >>> g = np.stack(np.meshgrid(np.arange(3.0), np.arange(3.0)), -1).reshape(-1, 2)
    >>> mesh = triangulate_cloud(np.column_stack([g, 0.1 * g[:, 0] ** 2]))
    >>> mesh.n_faces
    8
    """
    xyz = as_xyz(points)
    n = xyz.shape[0]
    if n < 3:
        raise InputError(f"triangulating needs at least 3 points, got {n}")
    frame = face_frame(plane if plane is not None else whole_cloud_plane(xyz))
    require(n * DELAUNAY_BYTES_PER_POINT, f"triangulating {n:,} points",
            hint="crop the cloud or thin it first")
    rel = xyz - frame.origin
    uv = np.column_stack([rel @ frame.u_axis, rel @ frame.v_axis])
    del rel
    from scipy.spatial import Delaunay, QhullError

    try:
        tri = Delaunay(uv)
    except QhullError as exc:  # all points on a line, too few distinct points
        raise InputError("cannot triangulate the cloud in its plane (its points are on a "
                         f"line or coincide): {error_line(exc)}") from None
    faces = np.asarray(tri.simplices, dtype=np.int64)
    del tri
    if max_edge is None:
        max_edge = MAX_EDGE_SPACINGS * neighbour_distance(uv, k=4)
    if not max_edge > 0:
        raise InputError(f"max_edge must be a positive length in metres, got {max_edge}")
    c = uv[faces]  # (T, 3, 2)
    edges = np.stack([c[:, 1] - c[:, 0], c[:, 2] - c[:, 1], c[:, 0] - c[:, 2]], axis=1)
    longest = np.sqrt(np.max(np.sum(edges * edges, axis=2), axis=1))
    faces = faces[longest <= max_edge]
    if faces.shape[0] == 0:
        raise InputError(f"no triangle has all edges shorter than {max_edge:.4g} m: the "
                         "points are too far apart for their spacing")
    source = points.source if isinstance(points, PointCloud) else ""
    unit = points.source_unit if isinstance(points, PointCloud) else "m"
    mesh = check_mesh(xyz, faces, "triangulated cloud")
    return TriangleMesh(vertices=mesh.vertices, faces=mesh.faces, source=source,
                        source_unit=unit)


def facets(mesh: TriangleMesh, *, toward: np.ndarray | None = None) -> Facets:
    """Unit normals, areas and centroids of a mesh's triangles.

    Parameters
    ----------
    mesh : TriangleMesh
        The surface (metres).
    toward : (3,) array, optional
        Every normal is turned to this side (``n . toward >= 0``), so a mesh's
        winding does not matter; default the mesh's own whole-vertex ODR normal
        (:func:`rough_viewer.grid.planes.whole_cloud_plane`, whose sign convention is
        :func:`rough_viewer.grid.planes.orient_normal`).

    Triangles of zero area have no normal and are left out (``Facets.index`` says
    which faces are kept).
    """
    t = mesh.n_faces
    require(t * FACET_BYTES, f"the facets of {t:,} triangles")
    v = mesh.vertices
    f = mesh.faces
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    cross = np.cross(b - a, c - a)
    twice = np.sqrt(np.sum(cross * cross, axis=1))
    keep = twice > 0
    up = np.asarray(toward if toward is not None else whole_cloud_plane(v).normal,
                    dtype=np.float64)
    normals = cross[keep] / twice[keep, None]
    normals *= np.where(normals @ up < 0, -1.0, 1.0)[:, None]
    return Facets(normals=normals, areas=0.5 * twice[keep],
                  centroids=((a + b + c) / 3.0)[keep], index=np.flatnonzero(keep))


