"""The exposure face a scanner saw, and how far a joint set's planes lie from it
(issue 31 item 2).

A scan sees rock only where it is exposed, so the exposure itself (a quarry wall, a
road cut, a hillside) is a surface of many planar cells. When it is planar, or
planar over a few metres, its cells gather into a density peak and ``sets`` finds
it as a "set", with a "spacing" that only measures how far its patches stand out of
one another. A real joint set is seen as many parallel, offset faces crossing the
exposure; the exposure is their envelope. Two tests, one angle each:

- **whole-cloud face**: the best-fit (ODR) plane of the whole cloud
  (:attr:`~rough_viewer.grid.roughness.GridRoughness.whole_plane`), when the cloud is
  a surface: ``sqrt(l3 / l2) <= FACE_SURFACE_RATIO`` (``l1 >= l2 >= l3`` its covariance
  eigenvalues: the cloud's thickness across its plane is under that share of its
  narrower extent; a see-through block or a cloud wrapped round a corner is no
  face). Angle: the axial angle between the set's mean pole and that plane's normal.
- **local face**: around a cell, the ODR plane of the centroids of every occupied
  cell within ``radius`` of its centroid (each cell once: the face's area, not the
  scanner's point density), a face when it holds at least :data:`FACE_MIN_CELLS`
  cells and passes the same surface test. Angle of a set: the median, over its cells
  (at most :data:`FACE_SAMPLE_CELLS` of them, evenly spread in cell order), of the
  axial angle between the set's mean pole and the cell's local face normal (a cell
  with no local face counts 90 degrees), i.e. the set is parallel to its local face
  when the majority of its cells are.

``face_angle_deg`` is the smaller of the two (NaN when neither face exists) and a set
is ``face_parallel`` when it is at most the tolerance (default
:data:`DEFAULT_FACE_TOLERANCE_DEG`). The neighbourhood is much larger than a cell
(default :data:`DEFAULT_FACE_RADIUS_CELLS` cells): a joint face much wider than it is,
around its cells, the exposure itself, and is flagged (a larger radius, or a scan from
another side, tells).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.memory import require

#: Default tolerance (degrees) between a set's mean pole and the face normal within
#: which the set is parallel to the face.
DEFAULT_FACE_TOLERANCE_DEG = 10.0
#: Default radius of the local face's neighbourhood, in cells.
DEFAULT_FACE_RADIUS_CELLS = 12.0
#: A point set is a face (a surface) when its thickness across its ODR plane is at
#: most this share of its narrower in-plane extent: ``sqrt(l3 / l2)``.
FACE_SURFACE_RATIO = 0.5
#: Least occupied cells of a local face's neighbourhood.
FACE_MIN_CELLS = 12
#: Most cells of a set whose local face is fitted (evenly spread in cell order).
FACE_SAMPLE_CELLS = 1000


@dataclass(frozen=True, eq=False)
class LocalFaces:
    """The local face around each of a set of query points."""

    normal: np.ndarray
    """(Q, 3) unit normal of the local face (NaN where there is none)."""
    thickness_ratio: np.ndarray
    """(Q,) ``sqrt(l3 / l2)`` of the neighbourhood (NaN with under 3 cells)."""
    cells: np.ndarray
    """(Q,) int64 occupied cells in the neighbourhood."""


def is_surface(eigenvalues: np.ndarray) -> bool:
    """Whether a point set of covariance ``eigenvalues`` (descending, square metres)
    is a face: ``sqrt(l3 / l2) <= FACE_SURFACE_RATIO``.

    >>> is_surface(np.array([9.0, 4.0, 0.01])), is_surface(np.array([3.0, 3.0, 2.0]))
    (True, False)
    """
    e = np.asarray(eigenvalues, dtype=np.float64)
    return bool(e[1] > 0 and np.sqrt(max(e[2], 0.0) / e[1]) <= FACE_SURFACE_RATIO)


def local_faces(centroids: np.ndarray, query: np.ndarray, radius: float) -> LocalFaces:
    """The ODR plane of the ``centroids`` within ``radius`` of every ``query`` point.

    Parameters
    ----------
    centroids : (M, 3) array
        Finite cell centroids, metres.
    query : (Q, 3) array
        Where the local faces are wanted, metres.
    radius : float
        Radius of the neighbourhood, metres.

    Returns
    -------
    LocalFaces
        Normals (NaN where the neighbourhood holds fewer than
        :data:`FACE_MIN_CELLS` cells or is no surface, :func:`is_surface`).
    """
    from scipy.spatial import cKDTree

    q = np.asarray(query, dtype=np.float64).reshape(-1, 3)
    n_q = q.shape[0]
    normal = np.full((n_q, 3), np.nan)
    ratio = np.full(n_q, np.nan)
    if n_q == 0 or centroids.shape[0] == 0:
        return LocalFaces(normal, ratio, np.zeros(n_q, dtype=np.int64))
    tree = cKDTree(centroids)
    counts = np.asarray(tree.query_ball_point(q, radius, return_length=True), dtype=np.int64)
    # the queries in chunks of at most _CHUNK_PAIRS neighbours (a query more, at most)
    bounds = [0]
    run = np.cumsum(counts)
    while bounds[-1] < n_q:
        done = run[bounds[-1] - 1] if bounds[-1] else 0
        nxt = int(np.searchsorted(run, done + _CHUNK_PAIRS, side="right"))
        bounds.append(min(max(nxt, bounds[-1] + 1), n_q))
    # per neighbour of a chunk: two indices, a distance, three differences, temporaries
    require(min(int(counts.sum()), _CHUNK_PAIRS + int(counts.max())) * 120.0,
            f"local faces of {n_q:,} cells", hint="choose a smaller face radius")
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        nrm, rat = _fit_local(centroids, tree, q[lo:hi], radius)
        normal[lo:hi], ratio[lo:hi] = nrm, rat
    return LocalFaces(normal, ratio, counts)


#: Most neighbours (query-cell pairs) of one chunk of :func:`local_faces`.
_CHUNK_PAIRS = 500_000


def _fit_local(centroids: np.ndarray, tree, q: np.ndarray, radius: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Normals and thickness ratios of the local faces of the queries ``q``."""
    from scipy.spatial import cKDTree

    n_q = q.shape[0]
    normal = np.full((n_q, 3), np.nan)
    ratio = np.full(n_q, np.nan)
    pairs = cKDTree(q).sparse_distance_matrix(tree, radius, output_type="ndarray")
    i = pairs["i"].astype(np.int64)
    d = centroids[pairs["j"]] - q[i]  # differences: no precision lost on UTM coordinates
    del pairs
    n = np.bincount(i, minlength=n_q).astype(np.float64)
    safe = np.maximum(n, 1.0)
    mean = np.column_stack([np.bincount(i, weights=d[:, a], minlength=n_q) for a in range(3)]
                           ) / safe[:, None]
    cov = np.zeros((n_q, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            v = np.bincount(i, weights=d[:, a] * d[:, b], minlength=n_q) / safe
            cov[:, a, b] = cov[:, b, a] = v - mean[:, a] * mean[:, b]
    evals, evecs = np.linalg.eigh(cov)  # ascending
    enough = n >= 3
    ratio[enough] = np.sqrt(np.maximum(evals[enough, 0], 0.0)
                            / np.maximum(evals[enough, 1], np.finfo(float).tiny))
    face = (n >= FACE_MIN_CELLS) & (ratio <= FACE_SURFACE_RATIO)
    normal[face] = evecs[face, :, 0]
    return normal, ratio


def axial_angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between the axes of unit vectors ``a`` (K, 3) and ``b`` (3,): (K,);
    NaN where ``a`` is NaN."""
    c = np.abs(np.asarray(a, dtype=np.float64) @ np.asarray(b, dtype=np.float64))
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def sample_rows(rows: np.ndarray, most: int = FACE_SAMPLE_CELLS) -> np.ndarray:
    """At most ``most`` of ``rows``, evenly spread (deterministic).

    >>> sample_rows(np.arange(10), 4).tolist()
    [0, 3, 6, 9]
    """
    if rows.shape[0] <= most:
        return rows
    return rows[np.round(np.linspace(0, rows.shape[0] - 1, most)).astype(np.int64)]


@dataclass(frozen=True, eq=False)
class FaceAngles:
    """Every set's angles to the exposure face (module docstring), degrees."""

    whole_deg: np.ndarray
    """(S,) axial angle between the mean pole and the whole-cloud plane's normal (NaN
    when the whole cloud is no surface)."""
    local_deg: np.ndarray
    """(S,) median over the set's cells of the angle between the mean pole and the
    local face normal (a cell with no local face counts 90; NaN for a set of no cell)."""
    tolerance_deg: float
    """The tolerance."""
    radius: float
    """The local face's radius, metres."""

    @property
    def angle_deg(self) -> np.ndarray:
        """(S,) the smaller of the two (NaN where both are)."""
        both = np.vstack([self.whole_deg, self.local_deg])
        out = np.full(both.shape[1], np.nan)
        has = np.isfinite(both).any(axis=0)
        out[has] = np.nanmin(both[:, has], axis=0)
        return out

    @property
    def parallel(self) -> np.ndarray:
        """(S,) bool: the set lies within the tolerance of the face."""
        a = self.angle_deg
        return np.isfinite(a) & (a <= self.tolerance_deg)

    def by_local(self, k: int) -> bool:
        """Whether set ``k`` (0-based) is parallel by the local face (not only the
        whole cloud's)."""
        return bool(np.isfinite(self.local_deg[k]) and self.local_deg[k] <= self.tolerance_deg)


def face_angles(mean_pole: np.ndarray, cell_set: np.ndarray, centroid: np.ndarray,
                whole_normal: np.ndarray, whole_eigenvalues: np.ndarray, *, radius: float,
                tolerance_deg: float = DEFAULT_FACE_TOLERANCE_DEG) -> FaceAngles:
    """The angles of every set to the whole-cloud face and its local face.

    Parameters
    ----------
    mean_pole : (S, 3) array
        Unit mean pole of every set.
    cell_set : (M,) int array
        Set of every cell, 1..S (0 = none).
    centroid : (M, 3) array
        Cell centroids, metres (NaN rows are no cell of the face).
    whole_normal, whole_eigenvalues : (3,) arrays
        The whole cloud's ODR normal and covariance eigenvalues (descending).
    radius : float
        The local face's radius, metres.
    tolerance_deg : float
        A set is parallel to the face within this angle.
    """
    s = mean_pole.shape[0]
    whole = np.full(s, np.nan)
    if s and is_surface(whole_eigenvalues):
        whole = axial_angle_deg(mean_pole, whole_normal)
    local = np.full(s, np.nan)
    finite = np.all(np.isfinite(centroid), axis=1)
    pts = centroid[finite]
    samples = [sample_rows(np.flatnonzero((cell_set == k + 1) & finite)) for k in range(s)]
    rows = np.concatenate(samples) if samples else np.zeros(0, dtype=np.int64)
    if rows.shape[0]:
        faces = local_faces(pts, centroid[rows], radius)
        start = 0
        for k, mine in enumerate(samples):
            nrm = faces.normal[start:start + mine.shape[0]]
            start += mine.shape[0]
            if mine.shape[0]:
                a = axial_angle_deg(nrm, mean_pole[k])
                local[k] = float(np.median(np.where(np.isfinite(a), a, 90.0)))
    return FaceAngles(whole_deg=whole, local_deg=local, tolerance_deg=float(tolerance_deg),
                      radius=float(radius))
