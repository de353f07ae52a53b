"""Point spacing and the default grid a cloud calls for.

A cell's roughness is a standard deviation of point-to-plane distances, and a
standard deviation from few points is mostly noise: with ``n`` points and the 3
parameters of the plane fitted, ``n - 3`` degrees of freedom remain and the relative
standard error of the standard deviation is about ``1 / sqrt(2 (n - 3))``. The
default grid is chosen so that the typical (median) occupied cell holds at least
:data:`TARGET_POINTS` = 16 points: 13 degrees of freedom, a relative error of about
20 %. (Below about 8 points the error passes 30 %; 3 points fit exactly.)

Method:

1. point spacing ``s`` = median distance from the points to their 4th nearest
   neighbour (on a square lattice of pitch ``a`` this is ``a`` exactly; for points
   placed at random on a surface of density ``rho`` it is about ``1.08 / sqrt(rho)``);
2. first guess ``g = s sqrt(16)``: a cell whose face cut holds ``g^2 / s^2`` points;
3. the guess is refined on the real grid: the median points per occupied cell ``c``
   is counted and ``g`` scaled by ``sqrt(16 / c)`` (a surface's count grows as
   ``g^2``), at most :data:`REFINE_STEPS` times;
4. ``g`` is rounded UP to a readable size (1, 1.25, 1.5, 2, 2.5, 3, 4, 5, 6 or 8
   times a power of ten), which only adds points per cell.

Presets (:func:`preset_cell_sizes`) are that size times powers of two (``8g, 4g,
2g, g``), so every coarser grid is nested in the finest and can be derived from it
without another pass over the points (:func:`rough_viewer.grid.roughness.coarsen_prepared`).

Cost: a KD-tree of at most :data:`TREE_POINTS` points (a random subset of a larger
cloud, whose spacing is then scaled by ``sqrt(subset / N)``, the surface law) and
5000 queries; the cell counts use at most :data:`COUNT_POINTS` points likewise.

>>> import numpy as np
>>> a = 0.02                                      # a 2 cm lattice on a plane
>>> i, j = np.meshgrid(np.arange(100), np.arange(100))
>>> xyz = np.column_stack([a * i.ravel(), a * j.ravel(), np.zeros(i.size)])
>>> round(point_spacing(xyz), 6), round(default_cell_size(xyz), 6)
(0.02, 0.08)
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from rough_viewer.io.cloud import PointCloud, as_columns
from rough_viewer.memory import require
from rough_viewer.vocabulary import UNIT_METRES, InputError

#: Points the typical (median) occupied cell of the default grid holds at least.
TARGET_POINTS = 16
#: Neighbour whose distance measures the spacing (4: the lattice pitch on a square
#: lattice).
SPACING_NEIGHBOUR = 4
#: Points queried for the spacing (evenly strided).
SPACING_QUERIES = 5000
#: Largest KD-tree built for the spacing; larger clouds use a random subset.
TREE_POINTS = 2_000_000
#: Largest point set counted per cell when refining the grid.
COUNT_POINTS = 5_000_000
#: Cells of the grid's box per counted point up to which the cells are counted in
#: one array over the box (a bincount: the same counts as sorting the keys, several
#: times faster; 4 x 8 bytes per point at most, within the 64 the count asks for).
DENSE_CELLS_PER_POINT = 4
#: Refinement steps on the real grid.
REFINE_STEPS = 4
#: Readable mantissas the default grid is rounded up to.
NICE = (1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0)
#: Number of preset grid sizes (the default and three coarser ones).
N_PRESETS = 4


def neighbour_distance(xyz: np.ndarray, *, k: int = SPACING_NEIGHBOUR) -> float:
    """Median distance from the points (N, 2 or 3) to their ``k``-th nearest
    neighbour, in the points' units. At most :data:`SPACING_QUERIES` evenly strided
    points are queried (against all points)."""
    xyz = np.asarray(xyz, dtype=np.float64)
    if xyz.shape[0] <= k:
        raise InputError(f"need more than {k} points to estimate the point spacing")
    require(xyz.shape[0] * 80.0, f"a neighbour search over {xyz.shape[0]:,} points")
    # a sliding-midpoint tree without shrunk node boxes: 2.5x faster to build for the
    # few thousand queries, the same (exact) neighbours
    tree = cKDTree(xyz, balanced_tree=False, compact_nodes=False)
    step = max(1, xyz.shape[0] // SPACING_QUERIES)
    dist, _ = tree.query(xyz[::step], k=k + 1)
    value = float(np.median(dist[:, k]))
    if not value > 0:
        raise InputError("points are coincident: cannot estimate the point spacing")
    return value


def _subset(cloud: PointCloud | np.ndarray, most: int) -> tuple[np.ndarray, float]:
    """(about ``most`` points as (n, 3), a uniform random subset of a larger cloud;
    the fraction of the cloud they are)."""
    x, y, z = as_columns(cloud)
    n = int(x.shape[0])
    if n <= most:
        return np.column_stack([x, y, z]), 1.0
    # each point kept with probability most / n (a uniform random subset, as a draw
    # of exactly ``most`` without replacement, which shuffled every index: 1 s at 20 M)
    pick = np.flatnonzero(np.random.default_rng(0).random(n, dtype=np.float32) < most / n)
    # the fraction each point is kept with: a median count of 16 in the subset reads
    # as exactly 64 at a quarter, as before (the realised share wobbles by 1e-4)
    return np.column_stack([x[pick], y[pick], z[pick]]), most / n


def point_spacing(cloud: PointCloud | np.ndarray) -> float:
    """Typical distance between neighbouring points, metres: the median distance to
    the 4th nearest neighbour (see the module docstring); for clouds larger than
    :data:`TREE_POINTS`, measured on a random subset and scaled by
    ``sqrt(fraction)`` (points on a surface)."""
    pts, fraction = _subset(cloud, TREE_POINTS)
    return neighbour_distance(pts) * math.sqrt(fraction)


def median_cell_count(cloud: PointCloud | np.ndarray, cell_size: float) -> float:
    """Median number of points per occupied cell on the grid of edge ``cell_size``
    (metres, origin at the bounding-box minimum); counted on at most
    :data:`COUNT_POINTS` points, scaled to the whole cloud."""
    pts, fraction = _subset(cloud, COUNT_POINTS)
    return _median_count(pts, _lowest(pts), fraction, cell_size)


def _lowest(pts: np.ndarray) -> np.ndarray:
    """The (3,) minimum of (n, 3) points, column by column (the same numbers as
    ``pts.min(axis=0)``, several times faster)."""
    return np.array([pts[:, a].min() for a in range(pts.shape[1])], dtype=pts.dtype)


def _median_count(pts: np.ndarray, lo: np.ndarray, fraction: float, cell_size: float) -> float:
    """:func:`median_cell_count` on a subset already drawn (``pts``, their minimum
    ``lo``, the share of the cloud they are)."""
    require(pts.shape[0] * 64.0, f"counting {pts.shape[0]:,} points per cell")
    keys = np.floor((pts - lo) / cell_size).astype(np.int64)
    dims = np.array([keys[:, a].max() for a in range(3)]) + 1  # per column: faster
    cells = float(np.prod(dims.astype(np.float64)))
    if cells <= DENSE_CELLS_PER_POINT * pts.shape[0]:  # a count per cell of the box
        flat = (keys[:, 0] * dims[1] + keys[:, 1]) * dims[2] + keys[:, 2]
        del keys
        counts = np.bincount(flat, minlength=int(cells))
        counts = counts[counts > 0]
    elif cells < 2.0**62:  # one int64 key per cell
        flat = (keys[:, 0] * dims[1] + keys[:, 1]) * dims[2] + keys[:, 2]
        _, counts = np.unique(flat, return_counts=True)
    else:
        _, counts = np.unique(keys, axis=0, return_counts=True)
    return float(np.median(counts)) / fraction


def nice_ceil(value: float) -> float:
    """The smallest readable size >= ``value`` (a :data:`NICE` mantissa times a power
    of ten).

    >>> nice_ceil(0.0731), nice_ceil(0.08), nice_ceil(1.6)
    (0.08, 0.08, 2.0)
    """
    if not value > 0:
        raise InputError(f"size must be positive, got {value}")
    exponent = math.floor(math.log10(value))
    for mantissa in NICE:
        candidate = round(mantissa * 10.0**exponent, 12)
        if candidate >= value * (1 - 1e-9):
            return candidate
    return round(10.0 ** (exponent + 1), 12)


def default_cell_size(cloud: PointCloud | np.ndarray, *, target: int = TARGET_POINTS,
                      unit: str | None = None) -> float:
    """Grid cell edge, metres, at which the median occupied cell holds at least
    ``target`` points (module docstring: why 16 and how), a readable size
    (:func:`nice_ceil`) in ``unit``.

    Parameters
    ----------
    cloud : PointCloud or (N, 3) array
        Points, metres.
    target : int
        Points wanted in the typical occupied cell.
    unit : str, optional
        Unit the size is readable in (``m``, ``mm``, ``ft``, ``us-ft``); default a
        cloud's own (``PointCloud.source_unit``: a scan in US survey feet gets 4, 8,
        16, 32 US ft, not 16 and 32 m shown as 52.4933 and 104.987), else metres.
    """
    per = UNIT_METRES[unit if unit is not None else
                      cloud.source_unit if isinstance(cloud, PointCloud) else "m"]

    def nice(size: float) -> float:
        return nice_ceil(size) if per == 1.0 else round(nice_ceil(size / per) * per, 12)

    if target < 3:
        raise InputError(f"target points per cell must be at least 3, got {target}")
    pts, fraction = _subset(cloud, COUNT_POINTS)  # drawn once for every count below
    # A cloud of fewer points than the target can hold no more than all of them in
    # one cell: ask for that (asking for more grew the cell without end, issue 36).
    target = min(target, int(round(pts.shape[0] / fraction)))
    g = point_spacing(cloud) * math.sqrt(target)
    lo = _lowest(pts)
    extent = float(np.max(np.max(pts, axis=0) - lo))
    for _ in range(REFINE_STEPS):
        count = _median_count(pts, lo, fraction, g)
        if target <= count <= 1.5 * target:
            break
        g *= float(np.clip(math.sqrt(target / max(count, 1.0)), 0.5, 2.0))
    g = nice(g)
    # rounding and the median's steps; a cell wider than the cloud holds every point
    while g <= extent and _median_count(pts, lo, fraction, g) < target:
        g = nice(g * 1.01)
    return g


def preset_cell_sizes(cloud: PointCloud | np.ndarray, *, n: int = N_PRESETS) -> tuple[float, ...]:
    """``n`` nested grid sizes, coarsest first: the default cell size times
    ``2^(n-1), ..., 2, 1`` (metres)."""
    return cell_sizes_from(default_cell_size(cloud), n=n)


def cell_sizes_from(finest: float, *, n: int = N_PRESETS) -> tuple[float, ...]:
    """``finest`` times ``2^(n-1), ..., 2, 1``, coarsest first (nested grids)."""
    return tuple(round(finest * 2.0**k, 12) for k in range(n - 1, -1, -1))
