"""Grid roughness of a COPC file by spatial tiles: every point decoded once.

A COPC file (:mod:`rough_viewer.io.copc`) lists its octree's nodes and where each
node's points lie. The tiles are columns of that tree (:func:`plan_tiles`): at the
shallowest depth where every column fits ``tile_points``, the nodes at that depth
and below whose keys agree along two axes form one tile, whatever their key along
the third, the cloud's thinnest axis (a face is a thin slab: the octree's cubes cut
it across its thickness at its middle, which would put most of its cells on a seam).
The nodes above that depth are the *top*, decoded first and held. Tiles are taken in
Morton order, so neighbours are near in time.

Every cell (of every grid asked for) is computed once, from all of its points at
once, by the in-memory code (moments, planes, distances of
:mod:`rough_viewer.scale.passes`): so one decode serves both passes. Which tiles can
hold a cell's points follows from the cell's box against the tiles' cubes
(:meth:`TileContext.tiles_of`, with a margin of one coordinate step for points on a
boundary):

- a cell inside one tile's cube (most of them) is computed when that tile is, from
  the tile's points and the top points inside the cell;
- a cell on a seam between tiles (or in no tile: only top points) is *held*: its
  points wait until the last tile it touches is done, then the cell is computed
  from all of them. On Dask the seam points travel back to the client with the
  tile's per-cell rows (a few per cent of the points: about four cell edges over a
  tile's edge; 6.6 % of a 20 M-point face in 8 tiles at grid 0.25 m).

The cells' planes are found before the whole cloud's plane is known, so every tile
keeps the moments and, where OLS is asked for with ``axis="auto"``, the OLS
distance sums of all three axes; the whole plane, the dependent axis and the
normals' orientation come from the summed moments at the end (the in-memory code,
:func:`~rough_viewer.grid.roughness.cell_planes`), and only the chosen axis's sums
are kept. ``|D|`` and ``D^2`` do not depend on a normal's sign.

The result equals :func:`~rough_viewer.grid.roughness.grid_roughness` of all the
points cell by cell up to the order of additions inside a cell (relative ~1e-15).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from rough_viewer.grid.cells import (
    CellIndex,
    CellMoments,
    GridSpec,
    cell_moments,
    distance_sums,
    make_grid,
)
from rough_viewer.grid.fast import resolve_engine
from rough_viewer.grid.fast import threads as kernel_threads
from rough_viewer.grid.planes import dominant_axis
from rough_viewer.grid.roughness import (
    GridRoughness,
    assemble_roughness,
    cell_planes,
    check_options,
    whole_plane_from_moments,
)
from rough_viewer.io.copc.reader import CopcFile, scaled
from rough_viewer.memory import format_bytes
from rough_viewer.scale.chunked import BYTES_PER_CELL, BYTES_PER_POINT, CHUNK_SHARE
from rough_viewer.scale.partials import Partial
from rough_viewer.scale.passes import (
    MOMENT_COLUMNS,
    OutsideGrid,
    _chunk_index,
    decode_keys,
    global_keys,
    moment_columns,
    moments_of,
)
from rough_viewer.scale.sources import Columns, Source
from rough_viewer.vocabulary import (
    DEFAULT_MIN_POINTS,
    MODELS,
    Axis,
    AxisChoice,
    Engine,
    InputError,
    Model,
    ProgressFn,
    Residual,
)

#: Share of the memory budget for the tile in flight. A tile's bytes a point while it
#: is decoded and worked on, and a computed cell's, are a streamed chunk's
#: (:data:`~rough_viewer.scale.chunked.BYTES_PER_POINT`, ``BYTES_PER_CELL``: the same
#: arrays).
TILE_SHARE = CHUNK_SHARE
#: Bytes a held (top or seam) point costs: x, y, z and its tile number.
HELD_BYTES_PER_POINT = 32
#: Points of a tile without a memory budget.
DEFAULT_TILE_POINTS = 4_000_000


# ---------------------------------------------------------------------------
# the plan


@dataclass(frozen=True)
class TilePlan:
    """The tiles of a COPC file and the top nodes above them.

    A tile is a *column* of the octree at one depth: every node at ``depth`` (and
    below) whose key agrees on the two ``axes``, whatever its key along the third,
    the cloud's thinnest axis. A face is a thin slab: cutting it across its thickness
    (as the octree's cubes do at its middle) would put most of its cells on a seam.

    Attributes
    ----------
    top : (K,) int64
        Rows of ``copc.nodes`` above ``depth`` (decoded first, held).
    tiles : tuple of (n_i,) int64
        Rows of ``copc.nodes`` of each tile, in tile (Morton) order.
    depth : int
        Depth of the columns.
    axes : tuple of int
        The two axes a column's key is along (the third runs the cube's whole edge).
    key : (T, 2) int64
        Each tile's column key along ``axes``, at ``depth``.
    points : (T,) int64
        Points of each tile's nodes.
    """

    top: np.ndarray
    tiles: tuple[np.ndarray, ...]
    depth: int
    axes: tuple[int, int]
    key: np.ndarray
    points: np.ndarray

    @property
    def n_tiles(self) -> int:
        return len(self.tiles)


def _interleave(q: np.ndarray) -> np.ndarray:
    """Morton codes of (N, 2) non-negative integers below 2**30."""
    out = np.zeros(q.shape[0], dtype=np.int64)
    for b in range(30):
        for a in range(2):
            out |= ((q[:, a] >> b) & 1) << (2 * b + a)
    return out


def plan_tiles(copc: CopcFile, tile_points: int, *, thin: int | None = None) -> TilePlan:
    """Cut the octree into columns along its thinnest axis (``thin``; default the
    header box's thinnest) at the shallowest depth where every column holds at most
    ``tile_points`` points (else the depth of the smallest largest column).

    >>> import numpy as np
    >>> from rough_viewer.io.copc.reader import ENTRY_DTYPE
    >>> nodes = np.array([(0, 0, 0, 0, 0, 1, 10), (1, 0, 0, 0, 0, 1, 30),
    ...                   (1, 0, 1, 0, 0, 1, 5), (1, 1, 0, 0, 0, 1, 7)], dtype=ENTRY_DTYPE)
    >>> c = CopcFile("f", 52, 6, 30, np.ones(3), np.zeros(3), np.zeros(3), np.ones(3),
    ...              np.full(3, 0.5), 0.5, b"", nodes)
    >>> p = plan_tiles(c, 52, thin=1)
    >>> p.depth, [t.tolist() for t in p.tiles], p.top.tolist()
    (0, [[0, 1, 2, 3]], [])
    >>> p = plan_tiles(c, 40, thin=1)    # columns along y: nodes 1 and 2 share one
    >>> p.depth, [t.tolist() for t in p.tiles], p.top.tolist(), p.points.tolist()
    (1, [[1, 2], [3]], [0], [35, 7])
    """
    nodes = copc.nodes
    if thin is None:
        thin = int(np.argmin(copc.maxs - copc.mins))
    axes = (0, 1, 2)[:thin] + (0, 1, 2)[thin + 1:]
    d = nodes["depth"].astype(np.int64)
    keys = np.stack([nodes["x"], nodes["y"], nodes["z"]], axis=1).astype(np.int64)
    counts = nodes["count"].astype(np.int64)
    max_d = int(d.max()) if d.size else 0
    best: tuple[int, int] | None = None
    for level in range(max_d + 1):
        below = d >= level
        if not below.any():
            break
        col = keys[below][:, axes] >> (d[below] - level)[:, None]
        _, inv = np.unique(col[:, 0] << 31 | col[:, 1], return_inverse=True)
        biggest = int(np.bincount(inv, weights=counts[below]).max())
        if best is None or biggest < best[1]:
            best = (level, biggest)
        if biggest <= tile_points:
            break
    level = best[0] if best is not None else 0
    rows = np.flatnonzero(d >= level)
    col = keys[rows][:, axes] >> (d[rows] - level)[:, None]
    u, inv = np.unique(col[:, 0] << 31 | col[:, 1], return_inverse=True)
    ukeys = np.stack([u >> 31, u & ((1 << 31) - 1)], axis=1)
    order = np.argsort(_interleave(ukeys), kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    tile_of = rank[inv]
    srt = np.argsort(tile_of, kind="stable")
    cuts = np.searchsorted(tile_of[srt], np.arange(u.size + 1))
    tiles = tuple(np.sort(rows[srt[cuts[t]:cuts[t + 1]]]) for t in range(u.size))
    return TilePlan(top=np.flatnonzero(d < level), tiles=tiles, depth=level,
                    axes=(int(axes[0]), int(axes[1])), key=ukeys[order],
                    points=np.array([int(counts[t].sum()) for t in tiles], dtype=np.int64))


@dataclass(frozen=True)
class TileContext:
    """What a tile's work needs besides its points (picklable: sent to workers once).

    Attributes
    ----------
    grids : tuple of GridSpec
    cube_min : (3,) float64
        Lowest corner of the octree's root cube, metres.
    edge : (3,) float64
        Edge of the root cube, metres (per axis: z may have its own unit).
    margin : (3,) float64
        A cell's box is widened by this, metres (one coordinate step), so a point on a
        cube's face counts on both sides.
    depth : int
        Depth of the tiles' columns.
    axes : tuple of int
        The two axes of a column's key.
    codes : (T,) int64
        The sorted codes ``key0 << 31 | key1`` of the tiles' columns.
    numbers : (T,) int64
        The tile number of each code.
    ols_axes : tuple of str
        Axes whose OLS sums each cell keeps (all three under ``axis="auto"``).
    min_points : int
    models : tuple of str
    engine : str
    threads : int
        Kernel threads (0: all; 1 on Dask).
    """

    grids: tuple[GridSpec, ...]
    cube_min: np.ndarray
    edge: np.ndarray
    margin: np.ndarray
    depth: int
    axes: tuple[int, int]
    codes: np.ndarray
    numbers: np.ndarray
    ols_axes: tuple[Axis, ...]
    min_points: int
    models: tuple[Model, ...]
    engine: Engine
    threads: int = 0

    @property
    def names(self) -> tuple[str, ...]:
        """Distance kinds every row keeps: ``odr`` and ``ols-x`` ... as needed."""
        out = []
        if any(m in self.models for m in ("odr", "hybrid")):
            out.append("odr")
        out += [f"ols-{a}" for a in self.ols_axes]
        return tuple(out)

    @property
    def n_values(self) -> int:
        """Value columns of a row: the moments, then two sums per distance kind."""
        return MOMENT_COLUMNS + 2 * len(self.names)

    def tiles_of(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and last tile number whose column meets each box (``lo``, ``hi``:
        (M, 3) metres); -1, -1 where none does."""
        m = lo.shape[0]
        first = np.full(m, np.iinfo(np.int64).max)
        last = np.full(m, -1, dtype=np.int64)
        n = 1 << self.depth
        ax = list(self.axes)
        step = self.edge[ax] / n
        a = np.clip(np.floor((lo[:, ax] - self.margin[ax] - self.cube_min[ax]) / step), 0, n - 1)
        b = np.clip(np.floor((hi[:, ax] + self.margin[ax] - self.cube_min[ax]) / step), 0, n - 1)
        a, b = a.astype(np.int64), b.astype(np.int64)
        for c in range(4):
            k0 = b[:, 0] if c & 1 else a[:, 0]
            k1 = b[:, 1] if c & 2 else a[:, 1]
            code = k0 << 31 | k1
            pos = np.clip(np.searchsorted(self.codes, code), 0, self.codes.size - 1)
            hit = self.codes[pos] == code
            num = np.where(hit, self.numbers[pos], -1)
            last = np.maximum(last, num)
            first = np.where(hit, np.minimum(first, num), first)
        first[last < 0] = -1
        return first, last


def make_context(copc: CopcFile, source: Source, plan: TilePlan, grids: tuple[GridSpec, ...],
                 *, axis: AxisChoice, min_points: int, models: tuple[Model, ...],
                 engine: Engine, threads: int = 0) -> TileContext:
    """The :class:`TileContext` of a plan (cube and margins in metres)."""
    factor = np.array([source.factor, source.factor, source.z_factor])
    codes = plan.key[:, 0] << 31 | plan.key[:, 1]
    srt = np.argsort(codes)
    ols_axes: tuple[Axis, ...] = ()
    if "ols" in models or "hybrid" in models:
        ols_axes = ("x", "y", "z") if axis == "auto" else (axis,)
    return TileContext(
        grids=grids, cube_min=copc.cube_min * factor, edge=np.full(3, 2 * copc.halfsize) * factor,
        margin=copc.scales * factor, depth=plan.depth, axes=plan.axes, codes=codes[srt],
        numbers=srt.astype(np.int64), ols_axes=ols_axes, min_points=int(min_points), models=models,
        engine=engine, threads=threads)


# ---------------------------------------------------------------------------
# the work on points


@dataclass(frozen=True)
class Rows:
    """Computed cells of one grid: global keys and value columns
    (:attr:`TileContext.n_values`)."""

    keys: np.ndarray
    values: np.ndarray

    @staticmethod
    def empty(n_values: int) -> Rows:
        return Rows(np.empty(0, dtype=np.int64), np.empty((0, n_values)))


@dataclass(frozen=True)
class Held:
    """Points of one grid's seam cells: x, y, z (metres) and the last tile their
    cell touches."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    last: np.ndarray

    @property
    def n(self) -> int:
        return int(self.x.shape[0])


@dataclass(frozen=True)
class TileOut:
    """What a tile gives back, per grid: its complete cells and its seam points;
    and its points' bounding box (metres)."""

    rows: tuple[Rows, ...]
    held: tuple[Held, ...]
    n_points: int
    lo: np.ndarray
    hi: np.ndarray


def complete_rows(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec,
                  ctx: TileContext) -> Rows:
    """Rows of every cell of these points, which must be all of those cells' points:
    moments, the cells' planes (per OLS axis of ``ctx``) and their distance sums."""
    if x.shape[0] == 0:
        return Rows.empty(ctx.n_values)
    index = _chunk_index(x, y, z, grid, ctx.engine)
    return _rows_of(x, y, z, index, np.ones(index.n_cells, dtype=bool), grid, ctx)


def _rows_of(x: np.ndarray, y: np.ndarray, z: np.ndarray, index: CellIndex, keep: np.ndarray,
             grid: GridSpec, ctx: TileContext) -> Rows:
    """Rows of the cells ``keep`` (a mask over ``index``'s cells, each of which has all
    of its points here) from the points' one index: the other points go to a spare
    cell whose sums are dropped, so nothing is copied or indexed again."""
    m = int(np.count_nonzero(keep))
    if m == 0:
        return Rows.empty(ctx.n_values)
    remap = np.full(index.n_cells, m, dtype=np.int64)
    remap[keep] = np.arange(m)
    point_cell = remap[index.point_cell]
    ijk = index.ijk[keep]
    counts = index.counts[keep]
    sub = CellIndex(grid=index.grid, ijk=np.vstack([ijk, ijk[:1]]),
                    counts=np.append(counts, index.point_cell.shape[0] - int(counts.sum())),
                    point_cell=point_cell)
    keys = global_keys(ijk, grid)  # sorted: the index's cells are in linear key order
    summed = cell_moments(x, y, z, sub, engine=ctx.engine)
    moments = CellMoments(counts=counts, s1=np.ascontiguousarray(summed.s1[:m]),
                          s2=summed.s2[:m])  # the spare cell dropped
    values = np.empty((m, ctx.n_values))
    values[:, :MOMENT_COLUMNS] = moment_columns(moments)
    up = np.array([0.0, 0.0, 1.0])
    vectors: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    if "odr" in ctx.names:
        planes = cell_planes(moments, up, "z", ctx.min_points, ("odr",),
                             cell_size=grid.cell_size)
        vectors["odr"] = planes.distance_vectors()["odr"]
    for a in ctx.ols_axes:
        planes = cell_planes(moments, up, a, ctx.min_points, ("ols",), cell_size=grid.cell_size)
        vectors[f"ols-{a}"] = planes.distance_vectors()["ols"]
    if vectors:
        spare = np.zeros((1, 3))
        sums = distance_sums(x, y, z, sub, {k: (np.vstack([v, spare]), np.vstack([c, spare]))
                                            for k, (v, c) in vectors.items()},
                             engine=ctx.engine)
        for q, name in enumerate(vectors):
            values[:, MOMENT_COLUMNS + 2 * q] = sums[name][0][:m]
            values[:, MOMENT_COLUMNS + 2 * q + 1] = sums[name][1][:m]
    return Rows(keys, values)


def tile_cells(x: np.ndarray, y: np.ndarray, z: np.ndarray, number: int, ctx: TileContext,
               extra: Sequence[Columns] = ()) -> TileOut:
    """The work of tile ``number`` on its nodes' points (metres) and, per grid, the
    top points of its inner cells (``extra``): every inner cell's row, and the
    points of the other cells (held until their last tile is done).

    Raises
    ------
    InputError
        If a point's cell does not touch its tile's column (a damaged file).
    """
    rows, held = [], []
    los, his = [np.full(3, np.inf)], [np.full(3, -np.inf)]
    with kernel_threads(ctx.threads):
        for g, grid in enumerate(ctx.grids):
            gx, gy, gz = x, y, z
            if extra and extra[g][0].size:
                gx, gy, gz = (np.concatenate([a, b]) for a, b in zip((x, y, z), extra[g],
                                                                     strict=True))
            if gx.size == 0:
                rows.append(Rows.empty(ctx.n_values))
                held.append(_held_none())
                continue
            box = _bounds(gx, gy, gz, ctx.engine)
            index = _chunk_index(gx, gy, gz, grid, ctx.engine, box)
            if g == 0:
                los.append(box[0])
                his.append(box[1])
            lo = grid.origin + index.ijk * grid.cell_size
            first, last = ctx.tiles_of(lo, lo + grid.cell_size)
            if np.any((last < number) | (first > number)):
                raise InputError("a node of the COPC file holds points outside its cube; "
                                 "the file is damaged")
            inner = (first == last) & (last == number)
            rows.append(_rows_of(gx, gy, gz, index, inner, grid, ctx))
            out = ~inner[index.point_cell]
            held.append(Held(gx[out], gy[out], gz[out], last[index.point_cell[out]]))
    return TileOut(tuple(rows), tuple(held), int(x.shape[0]), np.min(los, axis=0),
                   np.max(his, axis=0))


def _bounds(x: np.ndarray, y: np.ndarray, z: np.ndarray, engine: Engine
            ) -> tuple[np.ndarray, np.ndarray]:
    """The points' box, metres: one compiled pass where the kernels run."""
    if engine == "numba":
        from rough_viewer.grid import fast

        return fast.bounds(x, y, z)
    return (np.array([x.min(), y.min(), z.min()]), np.array([x.max(), y.max(), z.max()]))


def _held_none() -> Held:
    e = np.empty(0)
    return Held(e, e, e, np.empty(0, dtype=np.int64))


def _point_tiles(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: GridSpec,
                 ctx: TileContext) -> tuple[np.ndarray, np.ndarray]:
    """First and last tile of every point's cell."""
    index = _chunk_index(x, y, z, grid, ctx.engine)
    lo = grid.origin + index.ijk * grid.cell_size
    first, last = ctx.tiles_of(lo, lo + grid.cell_size)
    return first[index.point_cell], last[index.point_cell]


def split_top(x: np.ndarray, y: np.ndarray, z: np.ndarray, ctx: TileContext
              ) -> tuple[TileOut, list[list[Columns]]]:
    """The top points, grid by grid: those of a cell inside one tile go with that tile
    (``per_tile[t][g]``); the others are held (the :class:`TileOut` of no tile)."""
    n_tiles = int(ctx.codes.size)
    per_tile: list[list[Columns]] = [[] for _ in range(n_tiles)]
    held = []
    for grid in ctx.grids:
        if x.size == 0:
            first = last = np.empty(0, dtype=np.int64)
        else:
            first, last = _point_tiles(x, y, z, grid, ctx)
        inner = (first == last) & (last >= 0)
        held.append(Held(x[~inner], y[~inner], z[~inner], last[~inner]))
        own = last[inner]
        order = np.argsort(own, kind="stable")
        ix, iy, iz, own = x[inner][order], y[inner][order], z[inner][order], own[order]
        cuts = np.searchsorted(own, np.arange(n_tiles + 1))
        for t in range(n_tiles):
            a, b = cuts[t], cuts[t + 1]
            per_tile[t].append((ix[a:b], iy[a:b], iz[a:b]))
    lo = np.array([x.min(), y.min(), z.min()]) if x.size else np.full(3, np.inf)
    hi = np.array([x.max(), y.max(), z.max()]) if x.size else np.full(3, -np.inf)
    out = TileOut(tuple(Rows.empty(ctx.n_values) for _ in ctx.grids), tuple(held),
                  int(x.shape[0]), lo, hi)
    return out, per_tile


# ---------------------------------------------------------------------------
# the driver


@dataclass
class _Gather:
    """Rows as tiles finish, and the seam points until their last tile is done."""

    ctx: TileContext
    budget: int | None
    rows: list[list[Rows]] = field(default_factory=list)
    held: list[dict[int, list[tuple[int, Held]]]] = field(default_factory=list)
    held_bytes: int = 0
    cells: int = 0
    done: set[int] = field(default_factory=set)
    prefix: int = -1
    lo: np.ndarray = field(default_factory=lambda: np.full(3, np.inf))
    hi: np.ndarray = field(default_factory=lambda: np.full(3, -np.inf))

    def __post_init__(self) -> None:
        self.rows = [[] for _ in self.ctx.grids]
        self.held = [{} for _ in self.ctx.grids]

    def add(self, number: int, out: TileOut) -> None:
        self.lo, self.hi = np.minimum(self.lo, out.lo), np.maximum(self.hi, out.hi)
        for g, (r, h) in enumerate(zip(out.rows, out.held, strict=True)):
            self._keep(g, r)
            if h.n:
                order = np.argsort(h.last, kind="stable")
                lasts, starts = np.unique(h.last[order], return_index=True)
                bounds = [*starts.tolist(), h.n]
                for i, t in enumerate(lasts.tolist()):
                    s = order[bounds[i]:bounds[i + 1]]
                    self.held[g].setdefault(t, []).append(
                        (number, Held(h.x[s], h.y[s], h.z[s], h.last[s])))
                self.held_bytes += h.n * HELD_BYTES_PER_POINT
        if number >= 0:
            self.done.add(number)
        while self.prefix + 1 in self.done:
            self.prefix += 1
        self._check()
        self.flush(self.prefix)

    def flush(self, upto: int) -> None:
        """Compute the held cells whose last tile is ``upto`` or before: the cells of
        one last tile at a time, their points in the order of the tiles they came
        from, so the sums are the same bits in whatever order the tiles finished."""
        with kernel_threads(self.ctx.threads):
            for g, grid in enumerate(self.ctx.grids):
                for t in sorted(t for t in self.held[g] if t <= upto):
                    parts = [h for _, h in sorted(self.held[g].pop(t), key=lambda p: p[0])]
                    x = np.concatenate([h.x for h in parts])
                    y = np.concatenate([h.y for h in parts])
                    z = np.concatenate([h.z for h in parts])
                    self.held_bytes -= x.shape[0] * HELD_BYTES_PER_POINT
                    del parts
                    self._keep(g, complete_rows(x, y, z, grid, self.ctx))

    def _keep(self, g: int, r: Rows) -> None:
        if r.keys.size:
            self.rows[g].append(r)
            self.cells += int(r.keys.size)

    def _check(self) -> None:
        if self.budget is None:
            return
        need = self.held_bytes + self.cells * BYTES_PER_CELL
        if need > (1 - TILE_SHARE) * self.budget:
            raise InputError(
                f"the cells and the points held on tile seams need about {format_bytes(need)}, "
                f"more than the {format_bytes(int((1 - TILE_SHARE) * self.budget))} of --memory "
                f"{format_bytes(self.budget)} left for them; give more memory or a larger grid")




class TileRunner:
    """Runs the tiles: in this process, one after the other (decoding them in a
    child process, :func:`rough_viewer.io.copc.reader.decode_tiles`)."""

    def run_tiles(self, copc: CopcFile, source: Source, plan: TilePlan, ctx: TileContext,
                  tops: list[list[Columns]], on_points: Callable[[int], None]
                  ) -> Iterator[tuple[int, TileOut]]:
        """Yield ``(tile number, TileOut)`` for every tile (any order); ``tops[t]``:
        per grid, the top points of tile ``t``'s inner cells."""
        for number, (x, y, z) in enumerate(decoded_tiles(copc, source, plan.tiles)):
            on_points(int(x.shape[0]))
            yield number, tile_cells(x, y, z, number, ctx, tops[number])


def decoded_tiles(copc: CopcFile, source: Source, groups: Sequence[np.ndarray]
                   ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """x, y, z (metres) of each group of nodes, decoded in a child process where
    reads are isolated."""
    from rough_viewer.io.load import reader_for
    from rough_viewer.io.sandbox import isolate
    from rough_viewer.scale.sources import _checked

    plan = [g.tolist() for g in groups]
    reader = reader_for(source.path)
    if not isolate.available() or reader is None or not reader.untrusted:
        from rough_viewer.io.copc.reader import decode_tiles

        items: Iterator[dict[str, np.ndarray]] = decode_tiles(source.path, plan=plan)
    else:
        biggest = max((int(copc.nodes["count"][g].sum()) for g in groups), default=0)
        size = max((int(copc.nodes["size"][g].astype(np.int64).sum()) for g in groups), default=0)
        need = biggest * (copc.record_size + 24) + size
        limits = isolate.limits_for(need, biggest * 8)
        items = isolate.stream_isolated(
            "rough_viewer.io.copc.reader:decode_tiles", source.path, label=reader.label,
            limits=limits, names=frozenset({"X", "Y", "Z"}), options={"plan": plan},
            ahead=True)
    try:
        for item in items:
            x, y, z = scaled(copc, item["X"], item["Y"], item["Z"])
            del item
            yield _checked(source, {"x": x, "y": y, "z": z})
    finally:
        close = getattr(items, "close", None)
        if close is not None:
            close()


def tile_task(path: str, source: Source, rows: np.ndarray, number: int, ctx: TileContext,
              extra: Sequence[Columns], sandbox: bool) -> TileOut:
    """One tile as a task of its own (a Dask worker, a pool process or a thread):
    read and decode the tile's nodes (in a child process where ``sandbox``: a thread
    of the command's own process), then :func:`tile_cells`."""
    from rough_viewer.io.copc.reader import decode_nodes, open_copc
    from rough_viewer.scale.sources import _checked

    copc = open_copc(path)
    if sandbox:
        x, y, z = next(iter(decoded_tiles(copc, source, [rows])))
    else:
        dx, dy, dz = decode_nodes(copc, rows)
        x, y, z = _checked(source, {"x": dx, "y": dy, "z": dz})
    return tile_cells(x, y, z, number, ctx, extra)


def tile_points_for(memory_bytes: int | None, *, parallel: int = 1) -> int:
    """Points per tile so that ``parallel`` tiles in flight fit :data:`TILE_SHARE` of
    ``memory_bytes`` (default :data:`DEFAULT_TILE_POINTS`)."""
    if memory_bytes is None:
        return DEFAULT_TILE_POINTS
    n = int(TILE_SHARE * memory_bytes / (BYTES_PER_POINT * max(1, parallel)))
    if n < 50_000:
        raise InputError(f"--memory {format_bytes(memory_bytes)} is too small to read a COPC "
                         "file by tiles; give at least 256MB")
    return n


def copc_roughness(
    copc: CopcFile,
    source: Source,
    cell_sizes: Sequence[float],
    *,
    origin: np.ndarray | None = None,
    min_points: int = DEFAULT_MIN_POINTS,
    axis: AxisChoice = "auto",
    models: Sequence[Model] = MODELS,
    residual: Residual = "absolute",
    memory_bytes: int | None = None,
    tile_points: int | None = None,
    engine: Engine = "auto",
    runner: object | None = None,
    progress: ProgressFn | None = None,
) -> list[GridRoughness]:
    """Grid roughness of a COPC file at every cell size, by tiles, each point
    decoded once (twice only where the header's bounding box is wrong).

    Parameters
    ----------
    copc : CopcFile
        From :func:`~rough_viewer.io.copc.reader.open_copc`.
    source : Source
        The same file from :func:`~rough_viewer.scale.sources.open_sources` (units,
        header box in metres).
    cell_sizes, origin, min_points, axis, models, residual
        As :func:`~rough_viewer.scale.chunked.chunked_roughness`.
    memory_bytes : int, optional
        Memory budget of a process, bytes: tiles are cut to fit half of it; the cells
        and the seam points must fit the rest.
    tile_points : int, optional
        Points per tile (overrides the size from ``memory_bytes``).
    engine : {"auto", "numpy", "numba"}
    runner : optional
        :class:`TileRunner` (default, this process) or a
        :class:`~rough_viewer.scale.dask_runner.DaskRunner` (one task per tile).
    progress : callable, optional
        ``progress(done, total)`` in points decoded.

    Returns
    -------
    list of GridRoughness
        One per cell size, in order, with an empty ``point_cell``.
    """
    models_t = check_options(models, axis, residual, min_points)
    n_total = copc.n_points
    if n_total < 3:
        raise InputError(f"need at least 3 points, got {n_total}")
    engine = resolve_engine(engine, n_points=n_total)
    parallel = int(getattr(runner, "parallel", 1))
    if tile_points is None:
        tile_points = tile_points_for(memory_bytes, parallel=parallel)
    plan = plan_tiles(copc, tile_points)
    biggest = int(plan.points.max()) if plan.n_tiles else 0
    if memory_bytes is not None and biggest > 1.25 * tile_points:
        raise InputError(f"{source.path} has a node column of {biggest:,} points at every "
                         f"depth of its octree, more than --memory "
                         f"{format_bytes(memory_bytes)} can hold at once; give more memory")
    top_n = int(copc.nodes["count"][plan.top].sum())
    # this process computes one tile while the reader child decodes the next on every
    # core: on one thread it leaves the cores to the decoding, the longer of the two
    # (100 M points, 2 cores: 15.2-16.1 s against 16.7-18.1 s on all threads)
    inner = int(getattr(runner, "inner_threads", 1 if plan.n_tiles > 1 else 0))
    if memory_bytes is not None and top_n * HELD_BYTES_PER_POINT > 0.25 * memory_bytes:
        raise InputError(f"the upper levels of {source.path} hold {top_n:,} points, more than "
                         f"--memory {format_bytes(memory_bytes)} can hold beside a tile; "
                         "give more memory")
    lo, hi = source.bounds_min, source.bounds_max
    for attempt in range(2):
        grids = tuple(make_grid(lo, hi, g, origin) for g in cell_sizes)
        ctx = make_context(copc, source, plan, grids, axis=axis, min_points=int(min_points),
                           models=models_t, engine=engine, threads=inner)
        try:
            gather = _run(copc, source, plan, ctx, runner, memory_bytes, progress,
                          n_total * (attempt + 1), n_total * attempt)
        except OutsideGrid:
            gather = None
        exact = _exact_box(copc, source, plan) if gather is None else (gather.lo, gather.hi)
        shifted = origin is None and not np.array_equal(exact[0], lo)
        if gather is not None and not shifted:
            break
        if attempt:  # pragma: no cover - the measured box holds every point
            raise InputError(f"the points of {source.path} moved between two reads")
        lo, hi = exact  # the header's box was wrong: again on the measured one
    assert gather is not None
    return [_assemble(g, grid, gather.rows[i], ctx, axis, int(min_points), models_t, residual,
                      n_total) for i, (g, grid) in enumerate(zip(cell_sizes, grids, strict=True))]


def _run(copc: CopcFile, source: Source, plan: TilePlan, ctx: TileContext, runner: object | None,
         memory_bytes: int | None, progress: ProgressFn | None, total: int, done0: int
         ) -> _Gather:
    done = [done0]

    def on_points(n: int) -> None:
        done[0] += n
        if progress:
            progress(done[0], total)

    if progress:
        progress(done0, total)
    gather = _Gather(ctx, memory_bytes)
    tx, ty, tz = next(decoded_tiles(copc, source, [plan.top])) if plan.top.size else \
        (np.empty(0), np.empty(0), np.empty(0))
    on_points(int(tx.shape[0]))
    first, tops = split_top(tx, ty, tz, ctx)
    del tx, ty, tz
    gather.add(-1, first)
    run = runner if runner is not None and hasattr(runner, "run_tiles") else TileRunner()
    for number, out in run.run_tiles(copc, source, plan, ctx, tops, on_points):
        tops[number] = []
        gather.add(number, out)
    gather.flush(plan.n_tiles)
    return gather


def _exact_box(copc: CopcFile, source: Source, plan: TilePlan) -> tuple[np.ndarray, np.ndarray]:
    """The points' bounding box, metres, from a read of every node."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    groups = [plan.top, *plan.tiles] if plan.top.size else list(plan.tiles)
    for x, y, z in decoded_tiles(copc, source, groups):
        if x.size:
            lo = np.minimum(lo, [x.min(), y.min(), z.min()])
            hi = np.maximum(hi, [x.max(), y.max(), z.max()])
    return lo, hi


def _assemble(size: float, grid: GridSpec, parts: list[Rows], ctx: TileContext,
              axis: AxisChoice, min_points: int, models: tuple[Model, ...], residual: Residual,
              n_total: int) -> GridRoughness:
    if parts:
        keys = np.concatenate([r.keys for r in parts])
        values = np.concatenate([r.values for r in parts])
    else:
        keys, values = np.empty(0, dtype=np.int64), np.empty((0, ctx.n_values))
    order = np.argsort(keys, kind="stable")
    keys, values = keys[order], values[order]
    if keys.size > 1 and np.any(keys[1:] == keys[:-1]):
        raise InputError("a cell of the COPC file was computed twice: its nodes hold points "
                         "outside their cubes; the file is damaged")
    table = Partial(keys, np.ascontiguousarray(values[:, :MOMENT_COLUMNS]), n_total)
    moments = moments_of(table)
    ijk = decode_keys(keys, grid)
    whole = whole_plane_from_moments(grid, ijk, moments)
    used: Axis = dominant_axis(whole.normal) if axis == "auto" else axis
    planes = cell_planes(moments, whole.normal, used, min_points, models, cell_size=grid.cell_size)
    col = {name: MOMENT_COLUMNS + 2 * q for q, name in enumerate(ctx.names)}
    sums: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    if "odr" in col:
        sums["odr"] = (values[:, col["odr"]], values[:, col["odr"] + 1])
    if f"ols-{used}" in col and "ols" in models:
        c = col[f"ols-{used}"]
        sums["ols"] = (values[:, c], values[:, c + 1])
    return assemble_roughness(grid, ijk, planes, sums, whole=whole, axis=used,
                              axis_requested=axis, min_points=min_points, residual=residual,
                              models=models, point_cell=np.empty(0, dtype=np.int64),
                              n_points_total=n_total)


__all__ = ["DEFAULT_TILE_POINTS", "Held", "Rows", "TileContext", "TileOut", "TilePlan",
           "TileRunner", "complete_rows", "copc_roughness", "decoded_tiles", "make_context",
           "plan_tiles", "split_top", "tile_cells", "tile_points_for", "tile_task"]
