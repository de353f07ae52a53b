"""Grid roughness of a merged cloud streamed in chunks: out of core, on one machine
or on Dask.

Two passes over the points (three when a LAS header's bounding box is wrong):

0. The grid: origin and extent from the files' headers (LAS/LAZ) or from a read of
   the other files; fixed before the first pass, so every chunk keys its cells on
   the same global grid.
1. Moments: every chunk gives, per cell it touches, the point count and the
   cell-local sums of x, y, z and their products
   (:func:`~rough_viewer.scale.passes.chunk_moments`); tables are added by cell key
   in a fixed binary tree (:mod:`~rough_viewer.scale.partials`). Each chunk also
   gives its exact bounding box; if the headers' box was wrong (a point outside it,
   or a different minimum where the minimum is the origin) the pass is repeated on
   the measured box.
2. Planes from the summed moments (:func:`~rough_viewer.grid.roughness.cell_planes`,
   the in-memory code), then distances: every chunk gives per cell the sums of
   ``|D|`` and ``D^2`` (:func:`~rough_viewer.scale.passes.chunk_distances`), added
   the same way; :func:`~rough_viewer.grid.roughness.assemble_roughness` turns them
   into the :class:`~rough_viewer.grid.roughness.GridRoughness` the in-memory path
   gives (without the per-point ``point_cell``).

A cell whose points straddle chunks or files is merged by adding its rows: the
sums are over disjoint sets of points, taken relative to the cell's centre (a
function of its global key alone), so the total is the in-memory sum up to the
order of additions (relative differences ~1e-15).

Memory: a chunk holds about :data:`BYTES_PER_POINT` bytes per point while it is
worked on; the cell tables about :data:`BYTES_PER_CELL` per occupied cell. With a
budget, chunks are sized to fit :data:`CHUNK_SHARE` of it and the cell tables must
fit the rest (else a clear InputError).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rough_viewer.grid.cells import GridSpec, make_grid
from rough_viewer.grid.fast import resolve_engine
from rough_viewer.grid.fast import threads as kernel_threads
from rough_viewer.grid.planes import PlaneFit, dominant_axis
from rough_viewer.grid.roughness import (
    CellPlanes,
    GridRoughness,
    assemble_roughness,
    cell_planes,
    check_options,
    whole_plane_from_moments,
)
from rough_viewer.memory import format_bytes
from rough_viewer.scale.partials import Partial, TreeReducer, merge
from rough_viewer.scale.passes import (
    OutsideGrid,
    PlaneTable,
    chunk_distances,
    chunk_moments,
    decode_keys,
    moments_of,
)
from rough_viewer.scale.sources import Chunk, Source, chunk_plan, iter_chunks
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

#: Bytes a chunk holds per point while it is read and worked on: the decoded LAS
#: record and its compressed bytes (~50), x, y, z (24), cell keys (8), dense cell
#: bookkeeping (up to 64) and slack.
BYTES_PER_POINT = 160
#: Bytes per occupied cell of the cell tables at their peak (sums, merges, planes,
#: the result arrays).
BYTES_PER_CELL = 400
#: Share of the memory budget given to the chunks in flight; the rest is for the
#: cell tables and fixed-size temporaries.
CHUNK_SHARE = 0.5
#: Fixed-size temporaries of one chunk's passes (the NumPy engine's sub-chunks).
FIXED_BYTES = 96 * 2**20
#: Points per chunk when no budget is given.
DEFAULT_CHUNK_POINTS = 4_000_000


def parse_bytes(text: str) -> int:
    """``"2GB"``, ``"512MB"``, ``"1.5GiB"``, ``"800M"`` or a plain number of bytes ->
    bytes (decimal units are powers of 1000, ``i`` units of 1024)."""
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([kmgt]?)(i?)b?\s*", text.lower())
    if not m:
        raise InputError(f"--memory expects a size such as 2GB or 512MB, got {text!r}")
    value, prefix, binary = float(m.group(1)), m.group(2), m.group(3)
    power = " kmgt".index(prefix) if prefix else 0
    n = int(value * (1024 if binary else 1000) ** power)
    if n <= 0:
        raise InputError(f"--memory must be positive, got {text!r}")
    return n


def chunk_points_for(memory_bytes: int | None, *, parallel: int = 1) -> int:
    """Points per chunk so that ``parallel`` chunks in flight fit
    :data:`CHUNK_SHARE` of ``memory_bytes`` (default :data:`DEFAULT_CHUNK_POINTS`).

    Raises
    ------
    InputError
        If the budget cannot hold even a small chunk.
    """
    if memory_bytes is None:
        return DEFAULT_CHUNK_POINTS
    room = CHUNK_SHARE * memory_bytes - FIXED_BYTES
    n = int(room / (BYTES_PER_POINT * max(1, parallel)))
    if n < 50_000:
        raise InputError(
            f"--memory {format_bytes(memory_bytes)} is too small to stream points "
            f"(a chunk needs about {format_bytes(FIXED_BYTES + 50_000 * BYTES_PER_POINT)}"
            f"{f' per worker thread, {parallel} threads' if parallel > 1 else ''}); "
            "give at least 256MB")
    return n


@dataclass(frozen=True)
class Pass1:
    """Pass 1 of every grid on one chunk (picklable: it travels to Dask workers)."""

    grids: tuple[GridSpec, ...]
    engine: Engine
    threads: int = 0
    """Threads of the compiled kernels (0: all; 1 under Dask, which runs chunks in
    parallel itself)."""

    def __call__(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> list[Partial]:
        lo = np.array([x.min(), y.min(), z.min()])
        hi = np.array([x.max(), y.max(), z.max()])
        out = []
        with kernel_threads(self.threads):
            for g in self.grids:
                try:
                    out.append(chunk_moments(x, y, z, g, self.engine))
                except OutsideGrid:
                    out.append(Partial(np.empty(0, dtype=np.int64), np.empty((0, 10)),
                                       int(x.shape[0]), lo, hi, outside=True))
        return out


@dataclass(frozen=True)
class Pass2:
    """Pass 2 of every grid on one chunk."""

    grids: tuple[GridSpec, ...]
    planes: tuple[PlaneTable, ...]
    engine: Engine
    threads: int = 0
    """As :attr:`Pass1.threads`."""

    def __call__(self, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> list[Partial]:
        with kernel_threads(self.threads):
            return [chunk_distances(x, y, z, g, p, self.engine)
                    for g, p in zip(self.grids, self.planes, strict=True)]


ChunkTask = Callable[[np.ndarray, np.ndarray, np.ndarray], list[Partial]]
ChunkDone = Callable[[Chunk], None]


class Runner(Protocol):
    """Runs a chunk task over every chunk and adds the tables per output."""

    def map_reduce(self, sources: Sequence[Source], chunk_points: int, task: ChunkTask,
                   n_out: int, on_chunk: ChunkDone, check: Callable[[int], None]
                   ) -> list[Partial]:
        """One table per output of ``task``, summed over all chunks in the fixed tree
        of :func:`~rough_viewer.scale.partials.reduce_partials` (chunk order)."""
        ...


class SequentialRunner:
    """Chunks one after the other in this process: at most one chunk in memory.

    Parameters
    ----------
    fill_cache : bool
        Fill the LAZ decode cache while decoding (default True), so the second pass
        (and the next run, in memory or streamed) reads decoded columns instead of
        decoding again. Needs disk room for 24-32 bytes per point.
    """

    def __init__(self, *, fill_cache: bool = True) -> None:
        self.fill_cache = fill_cache

    def map_reduce(self, sources: Sequence[Source], chunk_points: int, task: ChunkTask,
                   n_out: int, on_chunk: ChunkDone, check: Callable[[int], None]
                   ) -> list[Partial]:
        reducers = [TreeReducer() for _ in range(n_out)]
        for i, s in enumerate(sources):
            for chunk, (x, y, z) in iter_chunks(s, i, chunk_points, fill_cache=self.fill_cache):
                for r, part in zip(reducers, task(x, y, z), strict=True):
                    r.add(part)
                del x, y, z
                check(sum(r.nbytes for r in reducers))
                on_chunk(chunk)
        return [r.result() for r in reducers]


def chunked_roughness(
    sources: Sequence[Source],
    cell_sizes: Sequence[float],
    *,
    origin: np.ndarray | None = None,
    min_points: int = DEFAULT_MIN_POINTS,
    axis: AxisChoice = "auto",
    models: Sequence[Model] = MODELS,
    residual: Residual = "absolute",
    memory_bytes: int | None = None,
    chunk_points: int | None = None,
    engine: Engine = "auto",
    runner: Runner | None = None,
    progress: ProgressFn | None = None,
    file_progress: Sequence[ProgressFn] | None = None,
) -> list[GridRoughness]:
    """Grid roughness of the merged cloud of ``sources`` at every cell size, streamed.

    Equal to :func:`~rough_viewer.grid.roughness.grid_roughness` of the concatenated
    points cell by cell (relative 1e-9; in practice ~1e-15), with an empty
    ``point_cell``.

    Parameters
    ----------
    sources : sequence of Source
        From :func:`~rough_viewer.scale.sources.open_sources`.
    cell_sizes : sequence of float
        Grid cell edges, metres; one result per size, all from the same two passes.
    origin, min_points, axis, models, residual
        As :func:`~rough_viewer.grid.roughness.grid_roughness`.
    memory_bytes : int, optional
        Memory budget of a process, bytes: chunks are sized to fit it and the cell
        tables must fit it too. Default: chunks of :data:`DEFAULT_CHUNK_POINTS`.
    chunk_points : int, optional
        Points per chunk (overrides the size derived from ``memory_bytes``).
    engine : {"auto", "numpy", "numba"}
        Engine of the point passes.
    runner : Runner, optional
        Where chunks run: :class:`SequentialRunner` (default) or
        :class:`~rough_viewer.scale.dask_runner.DaskRunner`.
    progress : callable, optional
        ``progress(done, total)`` in points over all passes.
    file_progress : sequence of callable, optional
        One ``progress(done, total)`` per source, in its points over all passes.

    Returns
    -------
    list of GridRoughness
        One per cell size, in order.
    """
    models_t = check_options(models, axis, residual, min_points)
    sizes = list(cell_sizes)
    if not sources:
        raise InputError("no input files")
    n_total = sum(s.n_points for s in sources)
    if n_total < 3:
        raise InputError(f"need at least 3 points, got {n_total}")
    engine = resolve_engine(engine, n_points=n_total)
    run = runner or SequentialRunner()
    parallel = int(getattr(run, "parallel", 1))
    inner = int(getattr(run, "inner_threads", 0))
    if chunk_points is None:
        chunk_points = chunk_points_for(memory_bytes, parallel=parallel)
    check = _CellRoom(memory_bytes)
    on_chunk = _PassProgress(sources, n_total, progress, file_progress)
    if progress:
        progress(0, on_chunk.n_passes * n_total)
    grids, tables = _first_pass(run, sources, chunk_points, sizes, origin, engine, inner,
                                on_chunk, check)
    stages: list[_GridStage] = []
    for grid, table in zip(grids, tables, strict=True):
        check(0, table.n_cells)
        stages.append(_plan_distances(grid, table, axis, int(min_points), models_t))
    dist = run.map_reduce(sources, chunk_points,
                          Pass2(grids, tuple(st.table for st in stages), engine, inner),
                          len(grids), on_chunk, check)
    out = []
    for st, table in zip(stages, dist, strict=True):
        cols = np.zeros((st.ijk.shape[0], table.values.shape[1]))
        cols[table.keys] = table.values
        sums = {name: (cols[:, 2 * q], cols[:, 2 * q + 1])
                for q, name in enumerate(st.table.names)}
        out.append(assemble_roughness(
            st.grid, st.ijk, st.planes, sums, whole=st.whole, axis=st.axis,
            axis_requested=axis, min_points=int(min_points), residual=residual,
            models=models_t, point_cell=np.empty(0, dtype=np.int64), n_points_total=n_total))
    return out


class _CellRoom:
    """Refuses cell tables beyond the memory left for them: ``(1 - CHUNK_SHARE)`` of
    ``memory_bytes`` (no limit without one). Called with the bytes of the tables so
    far (counted three times: a merge holds two and makes one) or a number of cells."""

    def __init__(self, memory_bytes: int | None) -> None:
        self.memory_bytes = memory_bytes
        self.room = None if memory_bytes is None else (1 - CHUNK_SHARE) * memory_bytes

    def __call__(self, nbytes: int, cells: int | None = None) -> None:
        if self.room is None:
            return
        need = nbytes * 3 if cells is None else cells * BYTES_PER_CELL
        if need > self.room:
            raise InputError(
                f"the cell tables need about {format_bytes(need)}, more than the "
                f"{format_bytes(self.room)} of --memory {format_bytes(self.memory_bytes or 0)} "
                "left for them; give more memory or a larger grid size")


class _PassProgress:
    """Says the points done over all passes (``n_passes``: 2, 3 when the first pass
    runs again), overall and per source; called once per chunk read."""

    def __init__(self, sources: Sequence[Source], n_total: int, progress: ProgressFn | None,
                 file_progress: Sequence[ProgressFn] | None) -> None:
        self.sources, self.n_total = sources, n_total
        self.progress, self.file_progress = progress, file_progress
        self.n_passes = 2
        self.done_all = 0
        self.done_files = [0] * len(sources)

    def __call__(self, chunk: Chunk) -> None:
        self.done_all += chunk.n
        self.done_files[chunk.source] += chunk.n
        if self.progress:
            self.progress(self.done_all, self.n_passes * self.n_total)
        if self.file_progress:
            self.file_progress[chunk.source](self.done_files[chunk.source],
                                             self.n_passes * self.sources[chunk.source].n_points)


def _first_pass(run: Runner, sources: Sequence[Source], chunk_points: int, sizes: list[float],
                origin: np.ndarray | None, engine: Engine, inner: int,
                on_chunk: _PassProgress, check: _CellRoom
                ) -> tuple[tuple[GridSpec, ...], list[Partial]]:
    """Pass 1 (the moments of every cell) of every grid over the sources' header box;
    run again on the box measured when a header's box was wrong (a point outside it,
    or its lowest corner off where the origin follows it)."""
    lo = np.min([s.bounds_min for s in sources], axis=0)
    hi = np.max([s.bounds_max for s in sources], axis=0)
    for attempt in range(2):
        grids = tuple(make_grid(lo, hi, g, origin) for g in sizes)
        tables = run.map_reduce(sources, chunk_points, Pass1(grids, engine, inner), len(grids),
                                on_chunk, check)
        exact_lo, exact_hi = tables[0].bounds_min, tables[0].bounds_max
        assert exact_lo is not None and exact_hi is not None
        shifted = origin is None and not np.array_equal(exact_lo, lo)
        if not (shifted or any(t.outside for t in tables)):
            break
        if attempt:  # pragma: no cover - the measured box holds every point
            raise InputError("points moved between two reads of the same files")
        lo, hi = exact_lo, exact_hi  # a header's box was wrong: again, on the measured box
        on_chunk.n_passes = 3
    return grids, tables


@dataclass(frozen=True)
class _GridStage:
    """One grid between the passes: its cells, planes and what pass 2 needs."""

    grid: GridSpec
    ijk: np.ndarray
    whole: PlaneFit
    axis: Axis
    planes: CellPlanes
    table: PlaneTable


def _plan_distances(grid: GridSpec, moments_table: Partial, axis: AxisChoice, min_points: int,
                    models: tuple[Model, ...]) -> _GridStage:
    """Planes of every cell from the summed moments (the in-memory code)."""
    moments = moments_of(moments_table)
    ijk = decode_keys(moments_table.keys, grid)
    whole = whole_plane_from_moments(grid, ijk, moments)
    used_axis: Axis = dominant_axis(whole.normal) if axis == "auto" else axis
    planes = cell_planes(moments, whole.normal, used_axis, min_points, models,
                         cell_size=grid.cell_size)
    vectors = planes.distance_vectors()
    names = tuple(vectors)
    m = moments_table.n_cells
    table = PlaneTable(
        keys=moments_table.keys, names=names,
        vectors=np.stack([vectors[k][0] for k in names]) if names else np.empty((0, m, 3)),
        points=np.stack([vectors[k][1] for k in names]) if names else np.empty((0, m, 3)))
    return _GridStage(grid=grid, ijk=ijk, whole=whole, axis=used_axis, planes=planes,
                      table=table)


__all__ = ["BYTES_PER_CELL", "BYTES_PER_POINT", "Pass1", "Pass2", "Runner", "SequentialRunner",
           "chunk_points_for", "chunk_plan", "chunked_roughness", "merge", "parse_bytes"]
