"""Compiled (numba) kernels for the point passes of the grid: bounds, cell keys,
cell-local moment sums (or, on a dense grid, keys, counts and moments in one fused
pass: :func:`fused_index_and_moments`), distance sums (which turn keys, or a finer
grid's rows, into rows on their way).

The NumPy functions of :mod:`rough_viewer.grid.cells` are the reference; these
kernels do the same arithmetic in the same order, point by point, without the
full-length temporaries of the bincount pipeline:

- cell keys ``floor((p - o) / g) - index_min`` per axis, combined x fastest, with the
  same floating-point operations, so every point lands in the same cell;
- moment sums and distance sums are accumulated block by block with the reference's
  chunk length (:func:`rough_viewer.grid.keys.chunk_size`), each cell's sum within
  a block taken in the points' order from 0.0 and each block's partial sums added to
  the totals in block order, exactly as ``np.bincount`` per chunk does. As many
  blocks as there are threads run at once (each into its own partial arrays), and
  the partials are still added in block order, so the result does not depend on
  the number of threads.

The results therefore equal the reference to the last bit; the tests hold them to
1e-12 relative on random, UTM-offset, tilted and degenerate clouds.

numba is a dependency of the default install; :func:`available` says whether it
can be imported here. The kernels are compiled once per machine and kept in numba's
on-disk cache: next to this module, or in ``$ROUGH_VIEWER_CACHE/numba`` (see
:func:`rough_viewer.io.cache.cache_dir`) when the package folder cannot be written;
``$NUMBA_CACHE_DIR`` overrides both. Loading them costs a fixed ~0.2 s per process
(:func:`preload` overlaps it with reading the input).
"""

from __future__ import annotations

import contextlib
import functools
import importlib.abc
import importlib.util
import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rough_viewer.grid.keys import chunk_size as _chunk_size
from rough_viewer.grid.keys import decode_keys as _decode_keys
from rough_viewer.grid.keys import dense_bookkeeping
from rough_viewer.vocabulary import Engine, InputError

#: Environment variable that overrides ``engine="auto"`` (``numpy`` or ``numba``).
ENGINE_ENV = "ROUGH_VIEWER_ENGINE"
#: Per-thread key counts (one int64 per grid cell and thread) are kept up to this
#: many cells of the grid; beyond, the keys are counted on one thread.
THREAD_COUNT_CELLS = 1 << 22
#: ``engine="auto"`` loads no kernels for clouds smaller than this: importing numba
#: and loading the cached kernels costs a fixed ~0.2 s per process, which they earn
#: back (~15 ns a point against the reference's ~60) on clouds of a few million
#: points. Once loaded in a process they are used for any size.
AUTO_MIN_POINTS = 3_000_000

#: The interpreter's switch interval, seconds, while :func:`preload` loads the kernels.
PRELOAD_SWITCH_S = 2e-4

_lock = threading.RLock()
_loaded: dict[str, Any] = {}
_failure: list[str] = []
_preloading: list[threading.Thread] = []


@functools.cache
def available() -> bool:
    """Whether numba is installed (the compiled engine can be asked for); finding it
    imports nothing."""
    return importlib.util.find_spec("numba") is not None


def loaded() -> bool:
    """Whether the kernels are loaded in this process (a call costs nothing more)."""
    return bool(_loaded)


def resolve_engine(engine: Engine = "auto", *, n_points: int | None = None) -> Engine:
    """The engine that runs: ``"numba"`` or ``"numpy"``.

    ``"auto"`` is ``$ROUGH_VIEWER_ENGINE`` when set, else numba when it is installed
    and works, and the kernels are loaded already, or ``n_points`` is unknown or at
    least :data:`AUTO_MIN_POINTS`.

    Raises
    ------
    InputError
        For an unknown name, or ``"numba"`` when numba is not installed or does
        not work here.
    """
    if engine == "auto":
        env = os.environ.get(ENGINE_ENV, "").strip().lower()
        if env in ("numpy", "numba"):
            engine = env  # type: ignore[assignment]
        else:
            if not available() or _failure:
                return "numpy"
            big = n_points is None or n_points >= AUTO_MIN_POINTS
            if not (loaded() or big or _preloading):
                return "numpy"
            try:
                _kernels()
            except InputError:  # numba installed but broken (e.g. built for another numpy)
                return "numpy"
            return "numba"
    if engine == "numpy":
        return "numpy"
    if engine == "numba":
        if not available():
            raise InputError("engine 'numba' needs numba: pip install numba")
        _kernels()
        return "numba"
    raise InputError(f"unknown engine {engine!r}; expected auto, numpy or numba")


class _NoLinalg(importlib.abc.MetaPathFinder):
    """Refuses ``scipy`` (not yet imported) to one thread while numba sets up: its CPU
    target imports ``scipy.linalg`` (0.2 s) only to learn whether BLAS can back
    ``np.dot`` inside compiled code, which these kernels never call; numba then
    uses its own loops there (and imports scipy itself if compiled code ever needs
    BLAS). Other threads import scipy as usual."""

    def __init__(self) -> None:
        self.thread = threading.get_ident()

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> None:
        if name.partition(".")[0] == "scipy" and threading.get_ident() == self.thread:
            raise ModuleNotFoundError(f"{name} is not imported while numba loads its kernels")
        return None


def _writable(folder: Path) -> bool:
    """Whether a file can be made in ``folder`` (created if missing): numba's own test."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def kernel_cache_dir() -> Path | None:
    """Where numba keeps the compiled kernels: ``None`` for numba's own choice (the
    ``__pycache__`` folder beside :mod:`rough_viewer.grid._kernels`, writable), else
    ``$NUMBA_CACHE_DIR``, else ``numba/`` in the rough_viewer cache folder
    (:func:`rough_viewer.io.cache.cache_dir`), else a folder in the temporary
    directory. The package folder of a system-wide install is not writable."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    if _writable(Path(__file__).resolve().parent / "__pycache__"):
        return None
    from rough_viewer.io.cache import cache_dir

    for folder in (cache_dir() / "numba",
                   Path(tempfile.gettempdir()) / f"rough_viewer-numba-{getattr(os, 'getuid', int)()}"):
        if _writable(folder):
            return folder
    return None


def configure_cache() -> Path | None:
    """Point numba's disk cache at :func:`kernel_cache_dir` (through
    ``NUMBA_CACHE_DIR``, which child processes inherit) before the kernels load;
    returns the folder, or None where numba's own choice stands."""
    where = kernel_cache_dir()
    if where is not None:
        os.environ.setdefault("NUMBA_CACHE_DIR", str(where))
        if "numba" in sys.modules:  # imported already: its configuration is read
            sys.modules["numba"].config.CACHE_DIR = str(where)
    return where


def _kernels() -> dict[str, Any]:
    """The compiled kernels, loaded once per process (from numba's disk cache, compiled
    there the first time; see :func:`kernel_cache_dir`).

    Raises
    ------
    InputError
        numba is not installed or cannot compile here.
    """
    if _loaded:
        return _loaded
    with _lock:
        if _loaded:
            return _loaded
        if _failure:
            raise InputError(_failure[0])
        guard = None if "scipy.linalg" in sys.modules else _NoLinalg()
        try:
            configure_cache()
            if guard is not None:
                sys.meta_path.insert(0, guard)
            from rough_viewer.grid import _kernels as k
        except Exception as exc:  # ImportError, or numba unable to compile or cache
            from rough_viewer.vocabulary import error_line

            _failure.append(f"the compiled engine (numba) cannot run here: {error_line(exc)}")
            raise InputError(_failure[0]) from None
        finally:
            if guard is not None:
                sys.meta_path.remove(guard)
        _loaded.update(bounds=k.bounds, keys=k.keys, keys_count=k.keys_count, count=k.count,
                       relabel=k.relabel, moments=k.moments, distances=k.distances,
                       pair_sums=k.pair_sums, fused=k.fused,
                       morton_buckets=k.morton_buckets, morton_scatter=k.morton_scatter,
                       sort_buckets=k.sort_buckets, rows_and_boxes=k.rows_and_boxes,
                       octree_level=k.octree_level, count_runs=k.count_runs,
                       voxel_sample=k.voxel_sample)
    return _loaded


def preload() -> None:
    """Start loading the kernels on a background thread and return at once, so that
    reading the input (which mostly waits on the disk and on NumPy, without the
    interpreter lock) hides the ~0.2 s. Does nothing when numba is not installed,
    ``$ROUGH_VIEWER_ENGINE`` is ``numpy``, or the kernels are loaded. The first
    kernel call waits for the thread."""
    if loaded() or _preloading or not available() or _failure:
        return
    if os.environ.get(ENGINE_ENV, "").strip().lower() == "numpy":
        return

    def load() -> None:
        # numba's loading holds the interpreter lock for long stretches: a reader on
        # the main thread, which takes the lock back between its NumPy calls, would
        # wait up to the switch interval (5 ms) each time; 0.2 ms while this runs
        before = sys.getswitchinterval()
        sys.setswitchinterval(min(before, PRELOAD_SWITCH_S))
        try:
            with contextlib.suppress(InputError):
                _kernels()
        finally:
            sys.setswitchinterval(before)

    thread = threading.Thread(target=load, name="rough_viewer-kernels", daemon=True)
    _preloading.append(thread)
    thread.start()


@contextlib.contextmanager
def threads(n: int) -> Iterator[None]:
    """Run the compiled kernels of this thread on ``n`` threads inside the block (0:
    all); for callers that parallelise over chunks themselves (Dask workers)."""
    if n <= 0 or not available() or _failure:
        yield
        return
    import numba

    old = numba.get_num_threads()
    numba.set_num_threads(min(n, int(numba.config.NUMBA_NUM_THREADS)))  # type: ignore[attr-defined]
    try:
        yield
    finally:
        numba.set_num_threads(old)


def _threads() -> int:
    import numba

    return int(numba.get_num_threads())


#: Every block of a pass gets its own partial sums (one parallel step over all the
#: blocks, then one over the cells, instead of a step and a wait per round of as
#: many blocks as threads) while they take at most this many bytes or 4 bytes a
#: point, whichever is larger: on a busy machine each wait costs a time slice.
ALL_BLOCKS_BYTES = 64 << 20


def _width(n: int, chunk: int, n_cells: int, row_bytes: int) -> int:
    """How many blocks run at once: all of them where their partial sums fit in
    :data:`ALL_BLOCKS_BYTES` (or 4 bytes a point), else the thread count, bounded by
    the blocks there are and by memory for the per-thread partial sums. The partial
    sums are added in block order either way, so the result does not change."""
    from rough_viewer.memory import require

    n_chunks = max(1, -(-n // chunk))
    width = max(1, min(_threads(), n_chunks))
    if n_chunks * n_cells * row_bytes <= max(ALL_BLOCKS_BYTES, 4 * n):
        width = n_chunks
    require(width * n_cells * row_bytes, f"partial sums of {n_cells:,} cells in {width} blocks",
            hint="choose a larger grid size")
    return width


def _f8(a: np.ndarray) -> np.ndarray:
    """``a`` as C-contiguous float64 (no copy when it is already)."""
    return np.ascontiguousarray(a, dtype=np.float64)


def _i8(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.int64)


def bounds(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box ``(min, max)`` of the points, each (3,), metres, in one pass over
    the coordinates on all threads; NaN when any coordinate is NaN (as ``x.min()``)."""
    lo, hi, _ = bounds_at(x, y, z)
    return lo, hi


def bounds_at(x: np.ndarray, y: np.ndarray,
              z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`bounds` and (6,) int64 the index of a point on each face of the box
    (min x, y, z, max x, y, z; -1 where a coordinate is NaN)."""
    out = np.empty((max(1, 4 * _threads()), 13))
    _kernels()["bounds"](_f8(x), _f8(y), _f8(z), out)
    if out[:, 6].sum() > 0:
        return np.full(3, np.nan), np.full(3, np.nan), np.full(6, -1, dtype=np.int64)
    live = out[:, 7] >= 0  # tasks with points
    part = out[live]
    lo_t = np.argmin(part[:, :3], axis=0)  # first task of the smallest: the first point
    hi_t = np.argmax(part[:, 3:6], axis=0)
    at = np.concatenate([part[lo_t, [7, 8, 9]], part[hi_t, [10, 11, 12]]]).astype(np.int64)
    return part[:, :3].min(axis=0), part[:, 3:6].max(axis=0), at


def cell_keys(x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: np.ndarray, cell_size: float,
              index_min: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
    """(N,) int64 linear cell keys ``i + nx (j + ny k)`` relative to ``index_min``;
    the same keys as :func:`rough_viewer.grid.cells.index_points` computes."""
    out = np.empty(x.shape[0], dtype=np.int64)
    _kernels()["keys"](_f8(x), _f8(y), _f8(z), _f8(origin), float(cell_size), _f8(index_min),
                       int(shape[0]), int(shape[1]), out)
    return out


def dense_counts(key: np.ndarray, total: int) -> np.ndarray:
    """(total,) int64 number of keys equal to each value (``np.bincount``)."""
    return _kernels()["count"](_i8(key), int(total))


def relabel(key: np.ndarray, lookup: np.ndarray) -> None:
    """``key[:] = lookup[key]`` in place, on all threads (``key`` int64, C order)."""
    _kernels()["relabel"](key, _i8(lookup))


def relabel_into(key: np.ndarray, lookup: np.ndarray, rows: np.ndarray) -> None:
    """``rows[:] = lookup[key]`` (``rows`` may be ``key``), on all threads."""
    if rows is not key:
        rows[:] = key
    relabel(rows, lookup)


_NO_LOOKUP = np.empty(0, dtype=np.int64)


def _centre_columns(centre: np.ndarray) -> list[np.ndarray]:
    return [np.ascontiguousarray(centre[:, a], dtype=np.float64) for a in range(3)]


def moment_sums(x: np.ndarray, y: np.ndarray, z: np.ndarray, point_cell: np.ndarray,
                centre: np.ndarray, chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """Sums of cell-local coordinates and of their products per cell.

    Parameters
    ----------
    x, y, z : (N,) float64
        Coordinates, metres.
    point_cell : (N,) int64
        Row of each point's cell.
    centre : (M, 3) float64
        Cell centres, metres.
    chunk : int
        Points per partial sum (the reference's chunk length).

    Returns
    -------
    s1 : (M, 3)
        Sums of local x, y, z, metres.
    s2 : (M, 3, 3)
        Sums of products of local coordinates, square metres.
    """
    m = int(centre.shape[0])
    total = np.zeros((m, 9))
    partial = np.empty((_width(x.shape[0], chunk, m, 72), m, 9))
    _kernels()["moments"](_f8(x), _f8(y), _f8(z), _i8(point_cell), _NO_LOOKUP,
                          *_centre_columns(centre), int(chunk), total, partial)
    del partial
    s1 = np.ascontiguousarray(total[:, :3])
    s2 = np.empty((m, 3, 3))
    for col, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)), start=3):
        s2[:, a, b] = total[:, col]
        s2[:, b, a] = total[:, col]
    return s1, s2


def distance_sums(x: np.ndarray, y: np.ndarray, z: np.ndarray, point_cell: np.ndarray,
                  centre: np.ndarray, vectors: np.ndarray, offsets: np.ndarray,
                  chunk: int, *, lookup: np.ndarray | None = None,
                  rows: np.ndarray | None = None) -> np.ndarray:
    """Per-cell sums of ``|D|`` and ``D^2``, ``D = v . local - offset``.

    Parameters
    ----------
    x, y, z, point_cell, centre, chunk
        As :func:`moment_sums`.
    vectors : (Q, M, 3) float64
        Per-cell vector of each of Q distance kinds.
    offsets : (Q, M) float64
        ``v . c_local`` per cell (metres times the unit of ``v``).
    lookup : (K,) int64, optional
        When given, ``point_cell`` holds keys (or a finer grid's rows) and the row of
        point ``i`` is ``lookup[point_cell[i]]``, written to ``rows`` during the
        first pass (``rows`` may be ``point_cell`` itself, C-order int64).

    Returns
    -------
    (Q, 2, M) float64
        ``[q, 0]`` sums of ``|D|``, ``[q, 1]`` sums of ``D^2``.
    """
    q_all, m = int(vectors.shape[0]), int(centre.shape[0])
    out = np.empty((q_all, 2, m))
    pc = _i8(point_cell)
    table = _NO_LOOKUP if lookup is None else _i8(lookup)
    written = pc if rows is None else rows
    if lookup is not None and q_all == 0:
        relabel_into(pc, table, written)
    centres = _centre_columns(centre)
    partial = np.empty((_width(x.shape[0], chunk, m, 32), m, 4))
    for first in range(0, q_all, 2):  # two kinds per pass over the points
        cols = (_f8(x), _f8(y), _f8(z), pc, table, written, *centres)
        pc, table = written, _NO_LOOKUP  # rows are written by the first pass
        two = first + 1 < q_all
        v = np.zeros((m, 8))
        for j in range(2 if two else 1):
            v[:, 4 * j:4 * j + 3] = vectors[first + j]
            v[:, 4 * j + 3] = offsets[first + j]
        total = np.zeros((m, 4))
        _kernels()["distances"](*cols, v, two, int(chunk), total, partial)
        out[first, 0], out[first, 1] = total[:, 0], total[:, 1]
        if two:
            out[first + 1, 0], out[first + 1, 1] = total[:, 2], total[:, 3]
    return out


def index_and_moments(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: Any, *,
                      dense_limit: int
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~rough_viewer.grid.cells.index_points` and
    :func:`~rough_viewer.grid.cells.cell_moments` in two passes over the points: keys
    and their counts together (per thread), then the moments, which turn each
    point's key into its cell's row on the way. The same cells, rows and sums as the
    reference, bit for bit: ``(ijk, counts, point_cell, s1, s2)``, the fields of
    :class:`~rough_viewer.grid.cells.CellIndex` and :class:`~rough_viewer.grid.cells.
    CellMoments` (:func:`rough_viewer.grid.cells.index_and_moments` makes them).

    Parameters
    ----------
    x, y, z : (N,) float64
        Coordinates, metres.
    grid : rough_viewer.grid.cells.GridSpec
        The grid over these points' bounds.
    dense_limit : int
        As :func:`~rough_viewer.grid.cells.index_points`.
    """
    k = _kernels()
    x, y, z = _f8(x), _f8(y), _f8(z)
    n = int(x.shape[0])
    total = grid.n_cells
    args = (x, y, z, _f8(grid.origin), float(grid.cell_size), _f8(grid.index_min),
            int(grid.shape[0]), int(grid.shape[1]))
    key = np.empty(n, dtype=np.int64)
    if dense_bookkeeping(total, n, dense_limit):
        if total <= THREAD_COUNT_CELLS:
            per_thread = np.zeros((min(_threads(), max(1, n)), total), dtype=np.int64)
            k["keys_count"](*args, key, per_thread)
            counts_dense = per_thread.sum(axis=0) if per_thread.shape[0] > 1 else per_thread[0]
            del per_thread
        else:
            k["keys"](*args, key)
            counts_dense = k["count"](key, int(total))
        occupied = np.flatnonzero(counts_dense)
        counts = counts_dense[occupied]
        del counts_dense
        lookup = np.full(total, -1, dtype=np.int64)
        lookup[occupied] = np.arange(occupied.shape[0], dtype=np.int64)
        keys_occ = occupied.astype(np.int64)
    else:
        k["keys"](*args, key)
        keys_occ, key, counts = np.unique(key, return_inverse=True, return_counts=True)
        key = _i8(key)
        lookup = _NO_LOOKUP
    ijk = _decode_keys(keys_occ, grid.shape, grid.index_min)
    m = int(keys_occ.shape[0])
    chunk = _chunk_size(m)
    total_sums = np.zeros((m, 9))
    partial = np.empty((_width(n, chunk, m, 72), m, 9))
    k["moments"](x, y, z, key, lookup, *_centre_columns(grid.centres(ijk)), int(chunk),
                 total_sums, partial)
    del partial, lookup
    counts = counts.astype(np.int64)
    s2 = np.empty((m, 3, 3))
    for col, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)), start=3):
        s2[:, a, b] = total_sums[:, col]
        s2[:, b, a] = total_sums[:, col]
    return ijk, counts, key, np.ascontiguousarray(total_sums[:, :3]), s2


#: The fused pass (:func:`fused_index_and_moments`) keeps the sums of every cell of
#: the bounding grid, occupied or not, per thread (80 bytes a cell): it is used up
#: to this many grid cells (no more than one reference chunk, so the chunk length is
#: known before the cells are counted) ...
FUSED_MAX_CELLS = 1 << 20
#: ... and while those per-thread sums take at most this many bytes or 8 bytes a
#: point (the size of the keys), whichever is larger.
FUSED_MIN_BYTES = 64 << 20
#: Bytes per grid cell and thread of the fused pass's partial sums (10 float64).
FUSED_CELL_BYTES = 80


def fused_fits(n_cells: int, n_points: int) -> bool:
    """Whether a grid of ``n_cells`` bounding cells is dense enough for the fused
    pass over ``n_points`` points (:data:`FUSED_MAX_CELLS`, :data:`FUSED_MIN_BYTES`)."""
    if n_cells > FUSED_MAX_CELLS or n_points < 1:
        return False
    chunk = _chunk_size(n_cells)
    width = max(1, min(_threads(), -(-n_points // chunk)))
    return (width + 1) * n_cells * FUSED_CELL_BYTES <= max(FUSED_MIN_BYTES, 8 * n_points)


@dataclass(frozen=True)
class Fused:
    """What :func:`fused_index_and_moments` found."""

    ijk: np.ndarray
    """(M, 3) int64 indices of the occupied cells, in key order."""
    counts: np.ndarray
    """(M,) int64 points per occupied cell."""
    key: np.ndarray
    """(N,) int64 key of every point's cell (its row is ``lookup[key]``)."""
    lookup: np.ndarray
    """(K,) int64 row of every key of the bounding grid (-1 where unoccupied)."""
    s1: np.ndarray
    """(M, 3) sums of cell-local coordinates, metres."""
    s2: np.ndarray
    """(M, 3, 3) sums of their products, square metres."""
    inside: bool
    """Every point lay inside the bounds given (none NaN); where False, the fields
    above must not be used. (With a point on each face of the box, the bounds were
    the points'.)"""


def fused_index_and_moments(x: np.ndarray, y: np.ndarray, z: np.ndarray, grid: Any,
                            lo: np.ndarray, hi: np.ndarray) -> Fused:
    """Cell keys, counts and moment sums in one pass over the points, on a dense grid
    (:func:`fused_fits`), the points checked on the way against the bounds ``lo, hi``
    the grid was made over (:attr:`Fused.inside`).

    The same operations in the same order as the reference (:func:`rough_viewer.grid.
    cells.index_points` and :func:`~rough_viewer.grid.cells.cell_moments`): the keys
    ``floor((p - o) / g) - index_min``, each cell's sums point by point in the points'
    order within a block of the reference's chunk length (2^21 points: every grid
    the pass takes has fewer cells), from 0.0, and the blocks' sums added in block
    order. Cell centres come per axis (``o + (i + 0.5) g``, as
    :meth:`~rough_viewer.grid.cells.GridSpec.centres` computes them), so no key
    has to be decoded on the way. Sums are kept for every cell of the bounding grid,
    per thread; the occupied ones are picked out after.

    Memory: the keys (8 bytes a point) and ``(threads + 1) * 80`` bytes a grid cell.

    Parameters
    ----------
    x, y, z : (N,) float64
        Coordinates, metres.
    grid : rough_viewer.grid.cells.GridSpec
        The grid made over ``lo, hi``.
    lo, hi : (3,) float64
        The bounds, metres, which may be a hint (:func:`rough_viewer.io.cloud.
        known_bounds`): where :attr:`Fused.inside` is False they were not these
        points' and nothing else of the result may be used.
    """
    k = _kernels()
    x, y, z = _f8(x), _f8(y), _f8(z)
    n = int(x.shape[0])
    total_cells = grid.n_cells
    chunk = _chunk_size(total_cells)
    assert total_cells <= FUSED_MAX_CELLS <= chunk
    n_chunks = max(1, -(-n // chunk))
    nx, ny, nz = (int(v) for v in grid.shape)
    g = float(grid.cell_size)
    axes = [grid.origin[a] + ((np.arange(m, dtype=np.int64) + grid.index_min[a])
                              .astype(np.float64) + 0.5) * g
            for a, m in enumerate((nx, ny, nz))]
    key = np.empty(n, dtype=np.int64)
    total = np.zeros((total_cells, 10))
    partial = np.empty((_width(n, chunk, total_cells, FUSED_CELL_BYTES), total_cells, 10))
    state = np.zeros(n_chunks)
    box = np.concatenate([np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)])
    k["fused"](x, y, z, _f8(grid.origin), g, _f8(grid.index_min), nx, ny, nz,
               *(_f8(a) for a in axes), box, int(chunk), key, total, partial, state)
    del partial
    counts_dense = total[:, 9]
    occupied = np.flatnonzero(counts_dense)
    lookup = np.full(total_cells, -1, dtype=np.int64)
    lookup[occupied] = np.arange(occupied.shape[0], dtype=np.int64)
    rows = total[occupied]
    del total
    s2 = np.empty((rows.shape[0], 3, 3))
    for col, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)), start=3):
        s2[:, a, b] = rows[:, col]
        s2[:, b, a] = rows[:, col]
    return Fused(ijk=_decode_keys(occupied.astype(np.int64), grid.shape, grid.index_min),
                 counts=rows[:, 9].astype(np.int64), key=key, lookup=lookup,
                 s1=np.ascontiguousarray(rows[:, :3]), s2=s2,
                 inside=bool(state.sum() == 0))


def pair_sums(pos: np.ndarray, z: np.ndarray, scale: float, n_bins: int, rows: int,
              first: int, last: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-chunk pair counts and sums of squared differences of the direct
    semivariogram count, row chunks ``first .. last - 1``; see
    :func:`rough_viewer.grid._kernels.pair_sums`.

    Parameters
    ----------
    pos : (M, D) float64, D = 2 or 3
        Cell indices.
    z : (M,) float64
        Centred values.

    Returns
    -------
    ordered, sums : (last - first, n_bins + 1) float64
        Row ``c``: chunk ``first + c``; column ``k``: lag bin ``k`` (0 unused).
    """
    n = last - first
    ordered = np.empty((n, n_bins + 1))
    sums = np.empty((n, n_bins + 1))
    cols = [_f8(pos[:, a]) for a in range(pos.shape[1])]
    if len(cols) == 2:
        cols.append(np.zeros(pos.shape[0]))
    _kernels()["pair_sums"](*cols, _f8(z), float(scale), int(n_bins), int(rows), int(first),
                            int(last), ordered, sums)
    return ordered, sums
