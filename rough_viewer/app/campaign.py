"""Serving a COPC campaign larger than memory: an overview drawn, the map from every point.

``rough-viewer serve CAMPAIGN.copc.laz`` on a file whose points do not fit the
server's memory (``serve --memory``; or more than ``--overview-points``) opens it
from its hierarchy (:func:`rough_viewer.io.copc.reader.open_copc`: no point read)
and reads only an *overview*: the nodes of the hierarchy's top levels, whole levels,
shallowest first, while their points stay under a cap (:func:`overview_rows`;
:data:`OVERVIEW_POINTS`, or what the memory budget allows). The overview is the
app's cloud: what clicks, profiles, selections and the distance colour layer read.
The browser tabs draw the file's own octree (:meth:`CampaignCloud.lod_nodes`, level
of detail within each tab's point budget): the overview's nodes from its rows, the
deeper ones decoded on demand in the reader sandbox
(:mod:`rough_viewer.app.campaign_nodes`).

Every grid result the app shows (colours, histogram, Table 1, semivariogram, zones,
sets, the trend across the presets) comes from **every point of the file**:
:class:`CampaignStore` computes it with :func:`rough_viewer.scale.tiles.copc_roughness`
(by spatial tiles, each node decoded once in the reader sandbox, memory under the
server's budget), the app's presets of one axis and minimum points in one pass, and
then gives each overview point the row of its cell (the overview's points are points
of the file, so each one's cell is among the result's). The cells are cached on disk
(:func:`cells_path`, under :func:`rough_viewer.io.cache.cache_dir`), so the next open
of the same file shows its map without reading a point beyond the overview.

Left out: clicks, profiles, the cell report and crops on every point (they use
the overview's points; a crop is refused); the map coloured tile by tile while it is
computed (the status line shows the pass's progress).
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import threading
import zipfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rough_viewer.app.cache import ByteBudget
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.limits import APP_BYTES_PER_POINT, APP_CACHE_BYTES_PER_POINT, APP_FIXED_BYTES
from rough_viewer.app.settings import MapSettings, check_settings
from rough_viewer.app.store import CloudStore, InMemoryStore
from rough_viewer.app.units import Units
from rough_viewer.grid.cells import GridSpec, index_points, make_grid
from rough_viewer.grid.planes import PlaneFit
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.spacing import default_cell_size, median_cell_count, nice_ceil
from rough_viewer.io import PointCloud
from rough_viewer.io.copc.reader import CopcFile
from rough_viewer.io.crop import CropBox
from rough_viewer.memory import format_bytes
from rough_viewer.scale.sources import Source
from rough_viewer.vocabulary import UNIT_METRES, InputError, ProgressFn

if TYPE_CHECKING:
    from rough_viewer.app.campaign_nodes import CopcNodes

#: Most points of the overview (the app's cloud) unless ``serve --overview-points``
#: or ``$ROUGH_VIEWER_OVERVIEW_POINTS`` says otherwise (and the memory budget allows).
OVERVIEW_POINTS = 4_000_000
#: The environment variable that overrides :data:`OVERVIEW_POINTS`.
OVERVIEW_ENV = "ROUGH_VIEWER_OVERVIEW_POINTS"
#: Points decoded per piece of the overview's read (its progress steps).
OVERVIEW_PIECE_POINTS = 1_000_000
#: Share of the memory left beside :data:`APP_FIXED_BYTES` that the overview may hold
#: (the rest: the map's pass over the tiles and its cells).
OVERVIEW_SHARE = 0.5
#: Smallest memory the campaign's map is computed in (the tiles and the cells).
MIN_COMPUTE_BYTES = 128 << 20
#: Share of what a pass keeps for cells (``copc_roughness``: the half of its memory
#: beside the tile) that the presets computed together (and the first map) may be
#: expected to take: the rest for the points held on seams and the estimate's error
#: (:func:`expected_cells` fell 15-30 % short at the finest presets of 20 M- and
#: 100 M-point faces).
CELLS_SHARE = 0.5
#: Format of a cells file on disk (changed whenever what it holds changes).
CELLS_VERSION = "campaign-cells-v1"
#: Folder, under the cache folder, of the campaign cells (a dot name: the decode
#: cache's eviction leaves it alone; :data:`CELLS_KEPT` bounds it).
CELLS_FOLDER = ".campaign-cells"
#: Cells files kept (the least recently used go first).
CELLS_KEPT = 64

_MODELS = ("odr", "ols", "hybrid")


def overview_cap(memory: float | None, asked: int | None = None) -> int:
    """Most points of a campaign's overview: ``asked`` (``--overview-points``), else
    ``$ROUGH_VIEWER_OVERVIEW_POINTS``, else :data:`OVERVIEW_POINTS`; at most what
    :data:`OVERVIEW_SHARE` of the budget ``memory`` (bytes, None: none) beside
    :data:`APP_FIXED_BYTES` holds at :data:`APP_BYTES_PER_POINT` +
    :data:`APP_CACHE_BYTES_PER_POINT` a point.

    Raises InputError when the budget leaves no room for a map's pass."""
    cap = asked
    if cap is None:
        text = os.environ.get(OVERVIEW_ENV, "").strip()
        cap = int(text) if text.isdigit() and int(text) > 0 else OVERVIEW_POINTS
    if memory is None:
        return cap
    room = memory - APP_FIXED_BYTES
    if room < 2 * MIN_COMPUTE_BYTES:
        raise InputError(f"--memory {format_bytes(memory)} is too small to serve a COPC "
                         f"campaign: give at least {format_bytes(APP_FIXED_BYTES + 2 * MIN_COMPUTE_BYTES)}")
    return max(1, min(cap, int(OVERVIEW_SHARE * room
                                / (APP_BYTES_PER_POINT + APP_CACHE_BYTES_PER_POINT))))


def compute_memory(memory: float | None, overview_points: int) -> int | None:
    """Bytes the campaign's map may take (the tiles in flight and the cells): the
    budget less :data:`APP_FIXED_BYTES`, what the overview holds and the bound of the
    decoded nodes the tabs draw
    (:data:`rough_viewer.app.campaign_nodes.NODE_CACHE_BYTES`) (None: no
    budget, the tiles' default size); at least :data:`MIN_COMPUTE_BYTES`."""
    if memory is None:
        return None
    from rough_viewer.app.campaign_nodes import NODE_CACHE_BYTES

    held = (APP_FIXED_BYTES + (APP_BYTES_PER_POINT + APP_CACHE_BYTES_PER_POINT) * overview_points
            + NODE_CACHE_BYTES)
    return int(max(MIN_COMPUTE_BYTES, memory - held))


@dataclass(frozen=True)
class Campaign:
    """A COPC file served as a campaign: its hierarchy and its header, no point."""

    path: Path
    copc: CopcFile
    source: Source
    memory_bytes: int | None = None
    """What its map's pass may take, bytes (:func:`compute_memory`; None: no budget)."""

    @property
    def n_points(self) -> int:
        return int(self.copc.n_points)


def open_campaign(path: str | os.PathLike[str], *, units: str | None = None,
                  max_points: int | None = None) -> Campaign:
    """The hierarchy and header of the COPC file ``path`` (every offset and page
    checked against the file; no point decoded). Raises InputError (one line naming
    the file) for a damaged file: a node past the end, a hierarchy loop, ..."""
    from rough_viewer.io.copc.reader import open_copc
    from rough_viewer.scale.sources import open_sources

    p = Path(path)
    copc = open_copc(p)
    source = open_sources([p], units=units, max_points=max_points)[0]  # type: ignore[arg-type]
    if copc.n_points < 3 or copc.nodes.shape[0] == 0:
        raise InputError(f"{p}: needs at least 3 points, has {copc.n_points}")
    return Campaign(path=p, copc=copc, source=source)


def overview_rows(copc: CopcFile, cap: int) -> np.ndarray:
    """Rows of ``copc.nodes`` of the overview: whole levels of the hierarchy,
    shallowest first, while their points stay at most ``cap`` (the shallowest level
    always, whatever it holds).

    >>> from rough_viewer.io.copc.reader import ENTRY_DTYPE
    >>> nodes = np.array([(0, 0, 0, 0, 0, 1, 10), (1, 0, 0, 0, 0, 1, 30),
    ...                   (1, 1, 0, 0, 0, 1, 5), (2, 0, 0, 0, 0, 1, 90)], dtype=ENTRY_DTYPE)
    >>> c = CopcFile("f", 135, 6, 30, np.ones(3), np.zeros(3), np.zeros(3), np.ones(3),
    ...              np.full(3, 0.5), 0.5, b"", nodes)
    >>> overview_rows(c, 50).tolist(), overview_rows(c, 44).tolist(), overview_rows(c, 5).tolist()
    ([0, 1, 2], [0], [0])
    """
    depth = copc.nodes["depth"].astype(np.int64)
    counts = copc.nodes["count"].astype(np.int64)
    levels = np.unique(depth)
    per_level = np.array([int(counts[depth == d].sum()) for d in levels], dtype=np.int64)
    total = np.cumsum(per_level)
    keep = max(1, int(np.searchsorted(total, cap, side="right")))
    return np.flatnonzero(depth <= levels[keep - 1])


def read_overview(campaign: Campaign, cap: int, *,
                  progress: Callable[[int, int], None] | None = None) -> PointCloud:
    """The overview's points (:func:`overview_rows`), metres, decoded in the reader
    sandbox (:func:`rough_viewer.scale.tiles.decoded_tiles`: a node that crashes its
    decoder is one InputError line), as the app's cloud (``source``: the file).
    ``progress(done, total)`` in points."""
    from rough_viewer.scale.tiles import decoded_tiles

    copc = campaign.copc
    rows = overview_rows(copc, cap)
    counts = copc.nodes["count"][rows].astype(np.int64)
    n = int(counts.sum())
    pieces = np.split(rows, np.flatnonzero(np.diff(np.cumsum(counts) // OVERVIEW_PIECE_POINTS)) + 1)
    cols = [np.empty(n, dtype=np.float64) for _ in range(3)]
    done = 0
    if progress is not None:
        progress(0, n)
    for x, y, z in decoded_tiles(copc, campaign.source, [p for p in pieces if p.size]):
        m = int(x.shape[0])
        if done + m > n:
            raise InputError(f"{campaign.path}: its nodes hold more points than its "
                             "hierarchy says; the file is damaged")
        for col, part in zip(cols, (x, y, z), strict=True):
            col[done:done + m] = part
        done += m
        if progress is not None:
            progress(done, n)
    if done != n:
        raise InputError(f"{campaign.path}: its nodes hold {done:,} points where its "
                         f"hierarchy says {n:,}; the file is damaged")
    return PointCloud(x=cols[0], y=cols[1], z=cols[2], source=str(campaign.path),
                      source_unit=campaign.source.unit, warnings=campaign.source.warnings)


#: Most points of the nodes one spatial query of a campaign decodes (a profile's
#: patch: a few seconds of decoding in the reader sandbox).
QUERY_DECODE_POINTS = 25_000_000
#: Most points a query keeps (those inside its box), and the share of the map's pass
#: memory they may take at :data:`QUERY_BYTES_PER_POINT` (a query may run beside a
#: pass): the decoded pieces are cut to the box one at a time.
QUERY_POINTS = 10_000_000
QUERY_SHARE = 0.25
#: Bytes a kept point holds: its (3,) float64 row, and its copy when the pieces are
#: put together.
QUERY_BYTES_PER_POINT = 48
#: Points decoded per piece of a query.
QUERY_PIECE_POINTS = 500_000


def query_cap(campaign: Campaign) -> int:
    """Most points a spatial query of ``campaign`` keeps: :data:`QUERY_POINTS`, at
    most :data:`QUERY_SHARE` of its pass's memory at :data:`QUERY_BYTES_PER_POINT`."""
    if campaign.memory_bytes is None:
        return QUERY_POINTS
    return max(OVERVIEW_PIECE_POINTS,
               min(QUERY_POINTS, int(QUERY_SHARE * campaign.memory_bytes / QUERY_BYTES_PER_POINT)))


def points_in_box(campaign: Campaign, lo: np.ndarray, hi: np.ndarray, *,
                  most: int | None = None, decode_most: int = QUERY_DECODE_POINTS,
                  what: str = "this", hint: str = "choose a shorter line or a narrower band"
                  ) -> np.ndarray:
    """(K, 3) metres: every point of the campaign's file inside the box ``[lo, hi]``
    (metres), from the nodes of its hierarchy that meet the box
    (:func:`rough_viewer.io.copc.reader.nodes_in_box`), decoded in the reader
    sandbox in pieces, node after node in file order, each piece cut to the box.

    Raises InputError (one line; ``what`` names what asked, ``"the profile"``, and
    ``hint`` what to do) when those nodes hold more than ``decode_most`` points, or
    the box more than ``most`` (default :func:`query_cap`): before any is decoded
    where the nodes wholly inside the box already hold more, else once the pieces so
    far pass it."""
    from rough_viewer.io.copc.reader import node_boxes, nodes_in_box
    from rough_viewer.scale.tiles import decoded_tiles

    copc, source = campaign.copc, campaign.source
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    factor = np.array([source.factor, source.factor, source.z_factor])
    rows = nodes_in_box(copc, lo / factor, hi / factor)
    counts = copc.nodes["count"][rows].astype(np.int64)
    n = int(counts.sum())
    cap = query_cap(campaign) if most is None else int(most)
    if n > decode_most:
        raise InputError(f"{what} needs the nodes of {n:,} points of {campaign.path.name}, "
                         f"more than the {decode_most:,} the app decodes for one query: "
                         f"{hint}")
    nlo, nhi = node_boxes(copc)
    inner = np.all((nlo[rows] * factor >= lo) & (nhi[rows] * factor <= hi), axis=1)
    surely = int(counts[inner].sum())  # points of nodes wholly inside: all in the box
    too_many = (f"{what} needs more than {cap:,} points of {campaign.path.name} at once, "
                f"more than the app holds for one query: {hint}")
    if surely > cap:
        raise InputError(too_many)
    if n == 0:
        return np.empty((0, 3))
    pieces = np.split(rows, np.flatnonzero(np.diff(np.cumsum(counts) // QUERY_PIECE_POINTS)) + 1)
    kept: list[np.ndarray] = []
    held = 0
    for x, y, z in decoded_tiles(copc, source, [p for p in pieces if p.size]):
        inside = (x >= lo[0]) & (x <= hi[0])
        inside &= (y >= lo[1]) & (y <= hi[1])
        inside &= (z >= lo[2]) & (z <= hi[2])
        held += int(np.count_nonzero(inside))
        if held > cap:
            raise InputError(too_many)
        kept.append(np.column_stack([x[inside], y[inside], z[inside]]))
    return np.concatenate(kept)


def campaign_presets(overview: PointCloud, n_total: int) -> tuple[float, ...]:
    """The app's grid presets (metres, coarsest first) for the whole campaign: the
    default grid of its density (a typical occupied cell of about 16 points of the
    file, not of the overview), estimated from the overview (the hierarchy's levels
    thin the points evenly): the overview's default grid shrunk by the square root of
    its share of the points (a face: points per cell grow with the cell's area), a
    readable size in the cloud's unit, grown until the overview's median occupied
    cell scaled to the file holds 16 points."""
    from rough_viewer.app.settings import MIN_CELL_SIZE
    from rough_viewer.grid.spacing import TARGET_POINTS, cell_sizes_from

    per = UNIT_METRES[overview.source_unit]
    share = overview.n / max(n_total, 1)

    def nice(size: float) -> float:
        return nice_ceil(size) if per == 1.0 else round(nice_ceil(size / per) * per, 12)

    g = default_cell_size(overview)
    if share < 1.0:
        g = nice(g * math.sqrt(share))
        lo, hi = overview.bounds()
        extent = float(np.max(hi - lo))
        while g <= extent and median_cell_count(overview, g) / share < TARGET_POINTS:
            g = nice(g * 1.01)
    return cell_sizes_from(max(g, MIN_CELL_SIZE))


def cells_room(memory_bytes: int | None) -> float:
    """Cells one pass of :func:`rough_viewer.scale.tiles.copc_roughness` in
    ``memory_bytes`` (None: no budget) is expected to hold: :data:`CELLS_SHARE` of
    the half it keeps beside its tile, at its bytes a cell."""
    from rough_viewer.scale.tiles import BYTES_PER_CELL, TILE_SHARE

    if memory_bytes is None:
        return math.inf
    return CELLS_SHARE * (1 - TILE_SHARE) * memory_bytes / BYTES_PER_CELL


def first_grid(campaign: Campaign, overview: PointCloud, presets: Sequence[float]) -> float:
    """The first map's grid of a campaign (metres): the finest preset whose cells
    (:func:`expected_cells`) one pass in :attr:`Campaign.memory_bytes` holds, else
    the coarsest."""
    room = cells_room(campaign.memory_bytes)
    for g in sorted(presets):
        if expected_cells(overview, g, campaign.n_points) <= room:
            return float(g)
    return float(max(presets))


# ----------------------------------------------------------------------------- disk


def cells_path(path: Path, settings: MapSettings) -> Path:
    """Where the cells of ``settings``' grid of the campaign ``path`` are kept on
    disk: a name from the file's identity (resolved path, size, modification time,
    first and last bytes: :func:`rough_viewer.io.cache.cache_key`), the cell size,
    axis, minimum points and :data:`CELLS_VERSION`."""
    from rough_viewer.io.cache import cache_dir, cache_key

    size, axis, k = settings.grid_key
    ident = f"{cache_key(path)}|{size!r}|{axis}|{k}|{CELLS_VERSION}"
    return cache_dir() / CELLS_FOLDER / (hashlib.sha1(ident.encode()).hexdigest()[:24] + ".npz")


_ARRAYS = ("ijk", "centre", "n_points", "centroid", "normal", "theta_odr", "theta_ols",
           "theta_hybrid", "e_ols")


def save_cells(where: Path, res: GridRoughness) -> bool:
    """Write ``res``'s cells to ``where`` atomically (a temporary file in the same
    folder, flushed to disk, renamed into place); keeps the folder at
    :data:`CELLS_KEPT` files. False (nothing left behind) when it cannot."""
    arrays: dict[str, np.ndarray] = {name: np.asarray(getattr(res, name)) for name in _ARRAYS}
    w = res.whole_plane
    arrays.update(
        origin=res.grid.origin, cell_size=np.asarray(res.grid.cell_size, dtype=np.float64),
        index_min=res.grid.index_min, shape=np.asarray(res.grid.shape, dtype=np.int64),
        plane_centroid=w.centroid, plane_normal=w.normal, plane_eigenvalues=w.eigenvalues,
        plane_axes=w.axes, text=np.array([res.axis, res.axis_requested, res.residual,
                                          ",".join(res.models), CELLS_VERSION]),
        numbers=np.array([res.min_points, res.n_points_total], dtype=np.int64))
    from rough_viewer.io.output import write_path_atomic

    try:
        where.parent.mkdir(parents=True, exist_ok=True)
        write_path_atomic(where, lambda tmp: np.savez(tmp, **arrays))  # type: ignore[arg-type]
    except (OSError, InputError):
        return False
    _keep_newest(where.parent, CELLS_KEPT)
    return True


def _keep_newest(folder: Path, most: int) -> None:
    for pattern in ("*.npz", "*.nofit"):
        files = sorted(folder.glob(pattern), key=lambda p: p.stat().st_mtime, reverse=True)
        for old in files[most:]:
            with contextlib.suppress(OSError):
                old.unlink()


def save_no_fit(where: Path, memory_bytes: int, message: str) -> None:
    """Remember beside ``where`` (the grid's cells file) that its pass ran out of
    room in ``memory_bytes`` (and what it said), so that the next open does not run
    it again with no more memory (written atomically; a failure to write is
    ignored)."""
    import json

    from rough_viewer.io.output import write_path_atomic

    marker = where.with_suffix(".nofit")
    text = json.dumps({"version": CELLS_VERSION, "memory_bytes": int(memory_bytes),
                       "message": message})
    def write(tmp: Path) -> None:
        tmp.write_text(text)

    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        write_path_atomic(marker, write)
    except (OSError, InputError):
        return
    _keep_newest(marker.parent, CELLS_KEPT)


def load_no_fit(where: Path, memory_bytes: int) -> str | None:
    """What :func:`save_no_fit` kept beside ``where`` when that pass had at least
    ``memory_bytes``; None otherwise (a damaged marker is removed)."""
    import json

    marker = where.with_suffix(".nofit")
    if not marker.is_file():
        return None
    try:
        got = json.loads(marker.read_text())
        ok = got["version"] == CELLS_VERSION and isinstance(got["message"], str)
        had = int(got["memory_bytes"])
    except (OSError, ValueError, KeyError, TypeError):
        ok, had = False, 0
    if not ok:
        with contextlib.suppress(OSError):
            marker.unlink()
        return None
    return str(got["message"]) if had >= memory_bytes else None


def load_cells(where: Path, settings: MapSettings, n_total: int) -> GridRoughness | None:
    """The cells :func:`save_cells` wrote at ``where`` for ``settings``' grid of a
    campaign of ``n_total`` points, with an empty ``point_cell``; None when there are
    none, or when the file is damaged or not of this grid (then it is removed, and
    written again once computed)."""
    if not where.is_file():
        return None
    try:
        with np.load(where, allow_pickle=False) as z:
            got = {name: np.array(z[name]) for name in z.files}
        res = _cells_from(got, settings, n_total)
    except (OSError, ValueError, KeyError, IndexError, TypeError, EOFError,
            zipfile.BadZipFile):
        res = None
    if res is None:
        with contextlib.suppress(OSError):
            where.unlink()
        return None
    with contextlib.suppress(OSError):
        os.utime(where)  # recently used: the last to go
    return res


def _cells_from(got: dict[str, np.ndarray], settings: MapSettings,
                n_total: int) -> GridRoughness | None:
    axis, requested, residual, models, version = (str(t) for t in got["text"])
    min_points, total = (int(v) for v in got["numbers"])
    size = float(got["cell_size"])
    if (version != CELLS_VERSION or requested != settings.axis or axis not in "xyz"
            or min_points != settings.min_points or total != n_total
            or round(size, 9) != settings.grid_key[0] or residual not in ("absolute", "signed")):
        return None
    m = got["n_points"].shape
    if len(m) != 1 or got["ijk"].shape != (m[0], 3) or got["centre"].shape != (m[0], 3) \
            or got["centroid"].shape != (m[0], 3) or got["normal"].shape != (m[0], 3) \
            or any(got[name].shape != m for name in ("theta_odr", "theta_ols",
                                                     "theta_hybrid", "e_ols")) \
            or got["shape"].shape != (3,) or got["origin"].shape != (3,):
        return None
    if int(got["n_points"].sum()) != n_total:
        return None
    grid = GridSpec(origin=got["origin"].astype(np.float64), cell_size=size,
                    index_min=got["index_min"].astype(np.int64),
                    shape=(int(got["shape"][0]), int(got["shape"][1]), int(got["shape"][2])))
    plane = PlaneFit(centroid=got["plane_centroid"], normal=got["plane_normal"],
                     eigenvalues=got["plane_eigenvalues"], axes=got["plane_axes"])
    return GridRoughness(
        grid=grid, axis=axis, axis_requested=requested,  # type: ignore[arg-type]
        whole_plane=plane, min_points=min_points, residual=residual,  # type: ignore[arg-type]
        models=tuple(models.split(",")),  # type: ignore[arg-type]
        point_cell=np.empty(0, dtype=np.int64), n_points_total=total,
        **{name: got[name] for name in _ARRAYS})


# ----------------------------------------------------------------------------- store


def overview_cells(cloud: PointCloud, res: GridRoughness) -> np.ndarray:
    """(N,) int64 row of ``res``'s cells for every point of ``cloud`` (points of the
    campaign ``res`` was computed from, on its grid: each one's cell is among them).

    Raises InputError when a point's cell is not (the file's nodes hold points the
    map did not count: a damaged file)."""
    from rough_viewer.grid.cells import cell_keys_of, cell_rows

    rows = cell_rows(cloud.x, cloud.y, cloud.z, res.grid, cell_keys_of(res.ijk, res.grid))
    if rows.size and int(rows.min()) < 0:
        raise InputError(f"{cloud.source}: points of its overview lie in cells its map "
                         "lacks; the file is damaged")
    return rows


def expected_cells(overview: PointCloud, cell_size: float, n_total: int) -> float:
    """Occupied cells of the grid ``cell_size`` (metres) expected over a campaign of
    ``n_total`` points from its overview (an even thinning of them): the overview's
    ``C`` occupied cells of its ``n`` points are what ``K`` cells of Poisson counts
    leave occupied, ``C = K (1 - exp(-n / K))``, solved for ``K`` (at most
    ``n_total``; an overview too thin to tell gives ``n_total``).

    >>> pts = PointCloud.from_xyz(np.column_stack([np.arange(100.0) + 0.5,
    ...                                            np.zeros(100), np.zeros(100)]))
    >>> round(expected_cells(pts, 10.0, 1000))
    10
    """
    lo, hi = overview.bounds()
    grid = make_grid(lo, hi, cell_size)
    seen = float(index_points(overview.x, overview.y, overview.z, grid).n_cells)
    n = float(overview.n)
    cap = float(min(n_total, grid.n_cells))
    if seen >= cap or cap * (1.0 - math.exp(-n / cap)) <= seen:
        return cap
    a, b = seen, cap  # f(K) = K (1 - exp(-n / K)) grows with K
    for _ in range(60):
        k = math.sqrt(a * b)
        if k * (1.0 - math.exp(-n / k)) < seen:
            a = k
        else:
            b = k
    return b


class CampaignStore(InMemoryStore):
    """The store of a campaign: the overview's points in memory (octree, the
    nested grids that clicks read, scanner figures), every grid *result* from every
    point of the file (:func:`rough_viewer.scale.tiles.copc_roughness`), cached in
    memory and on disk (:func:`cells_path`).

    Attributes
    ----------
    computed : list of float
        Cell sizes (metres) computed from the file's points, in order (tests and the
        status: a second open of the same file computes none).
    from_disk : list of float
        Cell sizes read from the disk cache.
    """

    def __init__(self, campaign: Campaign, cloud: PointCloud, presets: tuple[float, ...],
                 pool: ByteBudget, *, most: int) -> None:
        super().__init__(cloud, presets, pool, most=most)
        self.campaign = campaign
        self.computed: list[float] = []
        self.from_disk: list[float] = []
        self._pass = threading.Lock()
        self._too_many: set[tuple[str, int]] = set()
        """(axis, minimum points) whose presets' cells did not fit one pass together."""
        self._expected_cells: dict[float, float] = {}
        self._failed: dict[tuple[float, str, int], str] = {}
        """Grids whose pass did not fit the memory, and what it said."""

    def result(self, settings: MapSettings, *,
               progress: ProgressFn | None = None) -> GridRoughness:
        """The grid of ``settings`` from every point of the file, with ``point_cell``
        for the overview's points; cached."""
        key = ("result", settings.grid_key)
        hit = self._cache.get(key)
        if isinstance(hit, GridRoughness):
            return hit
        light = self.cell_result(settings, progress=progress)
        full = replace(light, point_cell=overview_cells(self.cloud, light))
        self._cache.put(key, full)
        return full

    def cell_result(self, settings: MapSettings, *,
                    progress: ProgressFn | None = None) -> GridRoughness:
        """The cells of ``settings``' grid from every point of the file (no
        ``point_cell``): the memory cache, else the disk's, else a pass over the
        file's tiles that computes the app's presets not at hand together (one
        decode for them all) when ``settings``' grid is a preset and their cells fit
        the budget together (else this grid alone)."""
        key = ("cells", settings.grid_key)
        hit = self._cache.get(key)
        if isinstance(hit, GridRoughness):
            return hit
        check_settings(settings)
        with self._pass:  # one pass over the file at a time
            hit = self._cache.get(key)
            if isinstance(hit, GridRoughness):
                return hit
            got = self._from_disk(settings)
            if got is not None:
                return got
            failed = self._failed.get(settings.grid_key) or self._failed_before(settings)
            if failed is not None:  # the same pass would fail the same way
                raise InputError(failed)
            self._surely_too_many(settings)
            try:
                self._compute(settings, progress)
            except InputError as exc:
                if "memory" in str(exc):
                    self._failed[settings.grid_key] = str(exc)
                    if self.campaign.memory_bytes is not None:
                        save_no_fit(cells_path(self.campaign.path, settings),
                                    self.campaign.memory_bytes, str(exc))
                raise
            made = self._cache.get(key)
            assert isinstance(made, GridRoughness)
            return made

    def _from_disk(self, settings: MapSettings) -> GridRoughness | None:
        got = load_cells(cells_path(self.campaign.path, settings), settings,
                         self.campaign.n_points)
        if got is not None:
            self.from_disk.append(float(settings.cell_size))
            self._cache.put(("cells", settings.grid_key), got)
        return got

    def _compute(self, settings: MapSettings, progress: ProgressFn | None) -> None:
        from rough_viewer.scale.tiles import copc_roughness

        wanted = self._together(settings)
        group = (settings.axis, settings.min_points)
        c = self.campaign

        def run(sizes: Sequence[float]) -> list[GridRoughness]:
            return copc_roughness(c.copc, c.source, list(sizes), min_points=settings.min_points,
                                  axis=settings.axis, models=_MODELS,  # type: ignore[arg-type]
                                  memory_bytes=c.memory_bytes, progress=progress)

        try:
            results = run(wanted)
        except InputError as exc:
            if len(wanted) == 1 or "the cells" not in str(exc):
                raise
            # the presets' cells together do not fit the budget: this grid alone
            self._too_many.add(group)
            wanted = [settings.cell_size]
            results = run(wanted)
        for g, res in zip(wanted, results, strict=True):
            s = settings.with_(cell_size=g)
            self.computed.append(float(g))
            self._cache.put(("cells", s.grid_key), res)
            save_cells(cells_path(c.path, s), res)

    def _failed_before(self, settings: MapSettings) -> str | None:
        """What a pass of an earlier open said when it ran out of memory on this grid
        with no less memory than this one has (:func:`save_no_fit`), or None."""
        memory = self.campaign.memory_bytes
        if memory is None:
            return None
        said = load_no_fit(cells_path(self.campaign.path, settings), memory)
        if said is not None:
            self._failed[settings.grid_key] = said
        return said

    def _surely_too_many(self, settings: MapSettings) -> None:
        """Refuse, before a pass, a grid whose cells expected from the overview (an
        underestimate) alone exceed all that the pass keeps for cells."""
        from rough_viewer.scale.tiles import BYTES_PER_CELL

        room = cells_room(self.campaign.memory_bytes) / CELLS_SHARE
        expected = self._expected(settings.cell_size)
        if expected > room:
            u = Units(self.cloud.source_unit)
            raise InputError(
                f"grid {u.size_text(settings.cell_size)} has about {expected:,.0f} cells "
                f"(expected from the overview), which need about "
                f"{format_bytes(expected * BYTES_PER_CELL)} in the map's pass, more than "
                f"the {format_bytes(room * BYTES_PER_CELL)} --memory leaves it: give more "
                "memory or a larger grid")

    def _together(self, settings: MapSettings) -> list[float]:
        """The cell sizes one pass computes for ``settings``: its own, and where it is
        a preset the other presets not at hand (coarsest first) while their cells
        expected from the overview (:func:`expected_cells`) fit
        :data:`CELLS_SHARE` of what the pass keeps for cells, coarsest first."""
        mine = settings.grid_key[0]
        if mine not in {round(float(g), 9) for g in self.presets} \
                or (settings.axis, settings.min_points) in self._too_many:
            return [settings.cell_size]
        others = [g for g in self.presets if round(float(g), 9) != mine
                  and not self._at_hand(settings.with_(cell_size=g))]
        room = cells_room(self.campaign.memory_bytes)
        used = self._expected(settings.cell_size)
        out = [settings.cell_size]
        for g in sorted(others, reverse=True):
            more = self._expected(g)
            if used + more <= room:
                out.append(g)
                used += more
        return sorted(out, reverse=True)

    def _expected(self, cell_size: float) -> float:
        key = round(float(cell_size), 9)
        hit = self._expected_cells.get(key)
        if hit is None:
            hit = self._expected_cells[key] = expected_cells(self.cloud, cell_size,
                                                             self.campaign.n_points)
        return hit

    def _at_hand(self, settings: MapSettings) -> bool:
        """The cells of ``settings`` are in memory, or on disk (then read in)."""
        if ("cells", settings.grid_key) in self._cache:
            return True
        return self._from_disk(settings) is not None


_NODES_LOCK = threading.Lock()


@dataclass(eq=False)
class CampaignCloud(LoadedCloud):
    """A :class:`~rough_viewer.app.cloud.LoadedCloud` whose ``cloud`` is the overview
    of :attr:`campaign` and whose grid results come from every point of the file
    (:class:`CampaignStore`)."""

    campaign: Campaign | None = field(default=None, repr=False)
    _nodes: CopcNodes | None = field(default=None, init=False, repr=False)

    def lod_nodes(self) -> CopcNodes:
        """The level-of-detail tree of the file's hierarchy and its nodes' points for
        the browser tabs: the overview's nodes from this cloud's rows, the deeper ones
        decoded on demand in the reader sandbox (:mod:`rough_viewer.app.campaign_nodes`);
        made once."""
        with _NODES_LOCK:  # one per cloud, whichever thread asks first
            if self._nodes is None:
                from rough_viewer.app.campaign_nodes import campaign_nodes

                assert self.campaign is not None
                self._nodes = campaign_nodes(self.campaign.copc, self.campaign.source,
                                             self.cloud.n)
            return self._nodes

    def _make_store(self) -> CloudStore:
        assert self.campaign is not None and self.presets is not None
        return CampaignStore(self.campaign, self.cloud, self.presets,
                             self.cache_pool or ByteBudget(self.cache_bytes),
                             most=self.cache_bytes)

    @property
    def n_total(self) -> int:
        """Points the roughness is computed from: every point of the file."""
        assert self.campaign is not None
        return self.campaign.n_points

    def points_covering(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Every point of the file inside ``[lo, hi]`` (metres), not the overview's
        (:func:`points_in_box`): a profile on a campaign uses every point."""
        assert self.campaign is not None
        return points_in_box(self.campaign, lo, hi, what="the profile")

    @property
    def file_rows(self) -> bool:
        return False

    def cropped(self, box: CropBox) -> LoadedCloud:
        """Every point of the file inside ``box`` (a spatial query of its index,
        :func:`points_in_box`), held in memory as a cloud of its own: every analysis
        of the app then runs on every point there (its grid presets are the
        campaign's). Only ``keep`` boxes: removing a box keeps most of the file.

        Raises InputError (one line) for a remove box, a box of fewer than 3 points
        or more than :func:`crop_cap`."""
        assert self.campaign is not None
        name = self.campaign.path.name
        if box.mode != "keep":
            raise InputError(f"{name} is served as a campaign: a crop keeps the points "
                             "inside a box (removing one would keep most of the file)")
        cap = crop_cap(self.campaign)
        xyz = points_in_box(self.campaign, np.asarray(box.lo), np.asarray(box.hi), most=cap,
                            decode_most=max(QUERY_DECODE_POINTS, 4 * cap), what="the crop",
                            hint="choose a smaller box, or give serve more --memory")
        if xyz.shape[0] < 3:
            raise InputError(f"{box.describe(self.units.per, self.units.label)} keeps "
                             f"{xyz.shape[0]} of {self.n_total:,} points; a map needs at "
                             "least 3")
        c = self.cloud
        cloud = PointCloud(x=np.ascontiguousarray(xyz[:, 0]), y=np.ascontiguousarray(xyz[:, 1]),
                           z=np.ascontiguousarray(xyz[:, 2]), source=c.source,
                           source_unit=c.source_unit, warnings=c.warnings)
        del xyz
        return CampaignCrop(cloud, max_display=self.max_display, cache_bytes=self.cache_bytes,
                            cache_pool=self.store.pool, seed=self.seed, presets=self.presets,
                            trust_settings=self.trust_settings, crop=box,
                            uncropped=self, frame_origin=_frame(self))

    def cropped_exact(self, mask: np.ndarray) -> LoadedCloud:
        """A selection of the overview's points: every point of the file in their
        bounding box (:meth:`cropped`; the overview holds only some of the points
        there, so the crop is of the box, not of the points selected)."""
        keep = np.asarray(mask)
        if keep.dtype != np.bool_ or keep.shape != (self.cloud.n,):
            raise InputError(f"a selection of this cloud has one flag per point "
                             f"({self.cloud.n:,}), got {keep.shape}")
        return self.cropped(CropBox.around(self.cloud, keep))


def _frame(loaded: LoadedCloud) -> tuple[float, float, float]:
    return (float(loaded.origin[0]), float(loaded.origin[1]), float(loaded.origin[2]))


#: Most points of a campaign's crop without a memory budget.
CROP_POINTS = 20_000_000
#: Share of a campaign's pass memory its crop may hold (at the app's bytes a point):
#: while a crop is shown its grids are computed in memory, not by the pass.
CROP_SHARE = 0.5


def crop_cap(campaign: Campaign) -> int:
    """Most points a crop of ``campaign`` keeps: :data:`CROP_SHARE` of its pass's
    memory at the app's bytes a point (:data:`CROP_POINTS` without a budget)."""
    if campaign.memory_bytes is None:
        return CROP_POINTS
    return max(QUERY_PIECE_POINTS, int(CROP_SHARE * campaign.memory_bytes
                                       / (APP_BYTES_PER_POINT + APP_CACHE_BYTES_PER_POINT)))


@dataclass(eq=False)
class CampaignCrop(LoadedCloud):
    """Every point of a campaign's file inside a box (:meth:`CampaignCloud.cropped`),
    in memory: a cloud like any other, whose :attr:`uncropped` is the campaign."""

    @property
    def file_rows(self) -> bool:
        return False

    def cropped_exact(self, mask: np.ndarray) -> LoadedCloud:
        """Exactly the points ``mask`` selects of this crop (they are all in
        memory); :attr:`uncropped` stays the campaign."""
        keep = np.asarray(mask)
        if keep.dtype != np.bool_ or keep.shape != (self.cloud.n,):
            raise InputError(f"a selection of this cloud has one flag per point "
                             f"({self.cloud.n:,}), got {keep.shape}")
        kept = int(np.count_nonzero(keep))
        if kept < 3:
            raise InputError(f"the selection keeps {kept} points; a map needs at least 3")
        whole = self.uncropped
        assert whole is not None
        return CampaignCrop(self.cloud.subset(keep), max_display=self.max_display,
                            cache_bytes=self.cache_bytes, cache_pool=self.store.pool,
                            seed=self.seed, presets=self.presets, label=self.label,
                            trust_settings=self.trust_settings,
                            crop=CropBox.around(self.cloud, keep), uncropped=whole,
                            crop_exact=True, frame_origin=_frame(whole))


def overview_label(campaign: Campaign, overview: PointCloud) -> str:
    """What the status line calls a campaign: its file and how much of it is drawn."""
    return (f"{campaign.path.name} (campaign: {overview.n:,} of its points drawn, "
            "clicks on them; the map from every point)")


def campaign_cloud(campaign: Campaign, overview: PointCloud, *, presets: Sequence[float],
                   max_display: int, cache_bytes: int, cache_pool: ByteBudget | None,
                   trust_settings: object = None) -> CampaignCloud:
    """The campaign prepared for the app (the overview as its cloud)."""
    return CampaignCloud(overview, max_display=max_display, cache_bytes=cache_bytes,
                         cache_pool=cache_pool, presets=tuple(presets),
                         label=overview_label(campaign, overview),
                         trust_settings=trust_settings,  # type: ignore[arg-type]
                         campaign=campaign)


def describe_overview(campaign: Campaign, overview: PointCloud) -> str:
    """One line: ``overview: 3.9 M of 100 M points; roughness from every point``."""
    def short(n: int) -> str:
        return f"{n / 1e6:.3g} M" if n >= 100_000 else f"{n:,}"

    return (f"{campaign.path.name}: served as a campaign: drawn from an "
            f"overview of {short(overview.n)} of its {short(campaign.n_points)} points (the "
            "top levels of its hierarchy); roughness from every point")


__all__ = ["CELLS_VERSION", "Campaign", "CampaignCloud", "CampaignCrop", "crop_cap", "CampaignStore", "OVERVIEW_POINTS",
           "campaign_cloud", "campaign_presets", "cells_path", "compute_memory",
           "describe_overview", "expected_cells", "first_grid", "load_cells", "open_campaign", "overview_cap",
           "overview_cells", "overview_rows", "points_in_box", "query_cap", "read_overview",
           "save_cells"]
