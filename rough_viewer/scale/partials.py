"""Per-cell partial sums of a chunk of points, and their reduction by addition.

Every per-cell quantity the grid needs is a sum over the cell's points: the point
count, the cell-local sums of x, y, z and of their six products (moments), and the
sums of ``|D|`` and ``D^2`` (distances). Sums over disjoint sets of points add, so a
cell whose points are spread over several chunks and files is merged exactly by
adding the rows with the same cell key. Cell keys are global (from one grid whose
origin and extent are fixed before the first pass), and the sums are taken relative
to the cell's centre, which depends only on the key, so rows from any chunk add
without any shift.

A :class:`Partial` is a table: sorted unique keys and one row of sums per key.
:func:`merge` adds two tables; :func:`reduce_partials` adds many in a fixed
binary tree (the same tree whatever ran the chunks, so the result does not depend
on the order in which chunks finish or on the number of workers).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Partial:
    """Sums per cell over some of the points."""

    keys: np.ndarray
    """(M,) int64 global cell keys, sorted, unique."""
    values: np.ndarray
    """(M, K) float64 sums per cell (columns fixed by the pass that made them)."""
    n_points: int = 0
    """Points summed."""
    bounds_min: np.ndarray | None = None
    """(3,) smallest x, y, z of the points summed, metres (None when empty)."""
    bounds_max: np.ndarray | None = None
    """(3,) largest x, y, z, metres."""
    outside: bool = False
    """Some points fell outside the grid the pass was given (their sums are missing:
    the pass must be run again on the measured bounds)."""

    @property
    def n_cells(self) -> int:
        """Number of cells (rows)."""
        return int(self.keys.shape[0])

    @property
    def nbytes(self) -> int:
        """Bytes held by the table."""
        return int(self.keys.nbytes + self.values.nbytes)


def _bounds(a: np.ndarray | None, b: np.ndarray | None, fn) -> np.ndarray | None:
    if a is None:
        return b
    if b is None:
        return a
    return fn(a, b)


def merge(a: Partial, b: Partial) -> Partial:
    """The table of the points of both: rows of equal keys added, ``a``'s first.

    Keys present in one table only are copied; the sum of a key present in both is
    ``a_row + b_row`` (one addition, so merging is as exact as the sums themselves).
    """
    lo = _bounds(a.bounds_min, b.bounds_min, np.minimum)
    hi = _bounds(a.bounds_max, b.bounds_max, np.maximum)
    n = a.n_points + b.n_points
    out = a.outside or b.outside
    if a.n_cells == 0:
        return Partial(b.keys, b.values, n, lo, hi, out)
    if b.n_cells == 0:
        return Partial(a.keys, a.values, n, lo, hi, out)
    keys = np.union1d(a.keys, b.keys)
    values = np.zeros((keys.shape[0], a.values.shape[1]))
    ia = np.searchsorted(keys, a.keys)
    ib = np.searchsorted(keys, b.keys)
    values[ia] = a.values
    values[ib] += b.values  # keys are unique within b: no repeated index
    return Partial(keys, values, n, lo, hi, out)


def reduce_partials(parts: Sequence[Partial]) -> Partial:
    """Add many tables pairwise in a fixed binary tree: ``((p0 + p1) + (p2 + p3)) ...``.

    The tree depends on the number of tables only, so the same chunks give the same
    bits however they were computed.
    """
    if not parts:
        raise ValueError("no partial sums to reduce")
    level = list(parts)
    while len(level) > 1:
        level = [merge(level[i], level[i + 1]) if i + 1 < len(level) else level[i]
                 for i in range(0, len(level), 2)]
    return level[0]


class TreeReducer:
    """Adds tables as they arrive, in the same binary tree as :func:`reduce_partials`
    when they arrive in order, holding at most ``log2(count)`` tables at once (a
    binary counter)."""

    def __init__(self) -> None:
        self._stack: list[tuple[int, Partial]] = []  # (tree level, table)

    def add(self, part: Partial) -> None:
        """Add the next table (in chunk order)."""
        level, item = 0, part
        while self._stack and self._stack[-1][0] == level:
            _, left = self._stack.pop()
            item = merge(left, item)
            level += 1
        self._stack.append((level, item))

    @property
    def nbytes(self) -> int:
        """Bytes held by the pending tables."""
        return sum(p.nbytes for _, p in self._stack)

    def result(self) -> Partial:
        """The sum of every table added (the pending subtrees, right to left)."""
        if not self._stack:
            raise ValueError("no partial sums to reduce")
        item = self._stack[-1][1]
        for _, left in reversed(self._stack[:-1]):
            item = merge(left, item)
        return item
