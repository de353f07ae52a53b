"""Compiled (numba) kernels for the three point passes of the grid: cell keys,
cell-local moment sums, distance sums.

The NumPy functions of :mod:`rough_viewer.grid.cells` are the reference; these
kernels do the same arithmetic in the same order, point by point, without the
full-length temporaries of the bincount pipeline:

- cell keys ``floor((p - o) / g) - index_min`` per axis, combined x fastest, with the
  same floating-point operations, so every point lands in the same cell;
- moment sums and distance sums are accumulated chunk by chunk with the reference's
  chunk length (:func:`rough_viewer.grid.cells._chunk_size`), each chunk's partial
  sums added to the totals in chunk order, exactly as ``np.bincount`` per chunk does.
  Two chunks at a time run on two threads (each into its own partial arrays), and
  the partials are still added in chunk order, so the result does not depend on
  the number of threads.

The results therefore equal the reference to the last bit in practice; the tests
hold them to 1e-12 relative on random, UTM-offset and degenerate clouds.

numba is an optional dependency (``pip install rough_viewer[fast]``);
:func:`available` says whether it is installed. Kernels are compiled on first use
and cached on disk (numba's ``cache=True``).
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Iterator
from typing import Any

import numpy as np

from rough_viewer.vocabulary import Engine, InputError

#: Environment variable that overrides ``engine="auto"`` (``numpy`` or ``numba``).
ENGINE_ENV = "ROUGH_VIEWER_ENGINE"
#: ``engine="auto"`` compiles nothing for clouds smaller than this: loading numba and
#: its cached kernels costs a fixed ~0.6 s per process, which the kernels earn back
#: (~60 ns per point on two cores) only on clouds of several million points. Once
#: loaded in a process they are used for any size.
AUTO_MIN_POINTS = 5_000_000


@functools.cache
def available() -> bool:
    """Whether numba can be imported (the compiled engine is usable)."""
    try:
        import numba  # noqa: F401
    except Exception:  # ImportError, or a numba built for another numpy
        return False
    return True


def resolve_engine(engine: Engine = "auto", *, n_points: int | None = None) -> Engine:
    """The engine that runs: ``"numba"`` or ``"numpy"``.

    ``"auto"`` is ``$ROUGH_VIEWER_ENGINE`` when set, else numba when installed and
    the kernels are loaded already or ``n_points`` is unknown or at least
    :data:`AUTO_MIN_POINTS`.

    Raises
    ------
    InputError
        For an unknown name, or ``"numba"`` when numba is not installed.
    """
    if engine == "auto":
        env = os.environ.get(ENGINE_ENV, "").strip().lower()
        if env in ("numpy", "numba"):
            engine = env  # type: ignore[assignment]
        else:
            if not available():
                return "numpy"
            loaded = _kernels.cache_info().currsize > 0
            big = n_points is None or n_points >= AUTO_MIN_POINTS
            return "numba" if loaded or big else "numpy"
    if engine == "numpy":
        return "numpy"
    if engine == "numba":
        if not available():
            raise InputError("engine 'numba' needs numba: pip install 'rough_viewer[fast]'")
        return "numba"
    raise InputError(f"unknown engine {engine!r}; expected auto, numpy or numba")


@functools.cache
def _kernels() -> dict[str, Any]:
    """The compiled kernels (numba is imported here only; compiled on first use and
    cached on disk next to :mod:`rough_viewer.grid._kernels`)."""
    import numba

    from rough_viewer.grid import _kernels as k

    return {"keys": k.keys, "count": k.count, "relabel": k.relabel, "moments": k.moments,
            "distances": k.distances, "threads": int(numba.get_num_threads())}


@contextlib.contextmanager
def threads(n: int) -> Iterator[None]:
    """Run the compiled kernels of this thread on ``n`` threads inside the block (0:
    all); for callers that parallelise over chunks themselves (Dask workers)."""
    if n <= 0 or not available():
        yield
        return
    import numba

    old = numba.get_num_threads()
    numba.set_num_threads(min(n, int(numba.config.NUMBA_NUM_THREADS)))  # type: ignore[attr-defined]
    try:
        yield
    finally:
        numba.set_num_threads(old)


def _width(n: int, chunk: int, n_cells: int, row_bytes: int) -> int:
    """How many chunks run at once: the thread count, bounded by the chunks there are
    and by memory for the per-thread partial sums (at most one chunk's worth)."""
    from rough_viewer.memory import require

    n_chunks = max(1, -(-n // chunk))
    import numba

    width = max(1, min(int(numba.get_num_threads()), n_chunks))
    require(width * n_cells * row_bytes, f"partial sums of {n_cells:,} cells on {width} threads",
            hint="choose a larger grid size")
    return width


def cell_keys(x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: np.ndarray, cell_size: float,
              index_min: np.ndarray, shape: tuple[int, int, int]) -> np.ndarray:
    """(N,) int64 linear cell keys ``i + nx (j + ny k)`` relative to ``index_min``;
    the same keys as :func:`rough_viewer.grid.cells.index_points` computes."""
    out = np.empty(x.shape[0], dtype=np.int64)
    _kernels()["keys"](x, y, z, np.asarray(origin, dtype=np.float64), float(cell_size),
                       np.asarray(index_min, dtype=np.float64), int(shape[0]), int(shape[1]),
                       out)
    return out


def dense_counts(key: np.ndarray, total: int) -> np.ndarray:
    """(total,) int64 number of keys equal to each value (``np.bincount``)."""
    return _kernels()["count"](key, int(total))


def relabel(key: np.ndarray, lookup: np.ndarray) -> None:
    """``key[:] = lookup[key]`` in place, on all threads."""
    _kernels()["relabel"](key, lookup)


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
    cols = [np.ascontiguousarray(centre[:, a]) for a in range(3)]
    _kernels()["moments"](x, y, z, point_cell, *cols, int(chunk), total, partial)
    del partial
    s1 = np.ascontiguousarray(total[:, :3])
    s2 = np.empty((m, 3, 3))
    for col, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)), start=3):
        s2[:, a, b] = total[:, col]
        s2[:, b, a] = total[:, col]
    return s1, s2


def distance_sums(x: np.ndarray, y: np.ndarray, z: np.ndarray, point_cell: np.ndarray,
                  centre: np.ndarray, vectors: np.ndarray, offsets: np.ndarray,
                  chunk: int) -> np.ndarray:
    """Per-cell sums of ``|D|`` and ``D^2``, ``D = v . local - offset``.

    Parameters
    ----------
    x, y, z, point_cell, centre, chunk
        As :func:`moment_sums`.
    vectors : (Q, M, 3) float64
        Per-cell vector of each of Q distance kinds.
    offsets : (Q, M) float64
        ``v . c_local`` per cell (metres times the unit of ``v``).

    Returns
    -------
    (Q, 2, M) float64
        ``[q, 0]`` sums of ``|D|``, ``[q, 1]`` sums of ``D^2``.
    """
    q, m = int(vectors.shape[0]), int(centre.shape[0])
    total = np.zeros((q, 2, m))
    partial = np.empty((_width(x.shape[0], chunk, m, 16 * q), q, 2, m))
    cols = [np.ascontiguousarray(centre[:, a]) for a in range(3)]
    _kernels()["distances"](x, y, z, point_cell, *cols, np.ascontiguousarray(vectors),
                            np.ascontiguousarray(offsets), int(chunk), total, partial)
    return total
