"""What is computed from every point of a loaded cloud, behind one seam.

:class:`CloudStore` is what the app asks of a cloud's points beyond its overview
sample: the grid results of a setting, the nested grids they are made from, the
scanner figures of a grid and the level-of-detail octree, each cached under one byte
budget. :class:`InMemoryStore` holds the points in memory (every file today); a
store whose points stay on disk (an indexed campaign, issue 33) implements the same
protocol, and :class:`~rough_viewer.app.cloud.LoadedCloud` and everything above it
does not change.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from rough_viewer.app.cache import ByteBudget, ByteCache, KeyedLocks
from rough_viewer.app.settings import MapSettings, check_settings
from rough_viewer.grid import fast
from rough_viewer.grid.cells import CellIndex, CellMoments
from rough_viewer.grid.roughness import (
    GridRoughness,
    PreparedGrid,
    coarsen_prepared,
    grid_roughness,
    prepare_grid,
)
from rough_viewer.io import PointCloud
from rough_viewer.lod.octree import DEFAULT_MAX_NODE_POINTS, Octree, build_octree
from rough_viewer.scanner.trust import CellTrust, TrustSettings, cell_trust
from rough_viewer.vocabulary import ProgressFn

#: From this many points a preset coarser than the finest may be indexed on its own
#: (the coarse first map of a big cloud needs no fine grid). Below it every preset is
#: coarsened from the finest, so a grid's numbers never depend on the order grids
#: were asked for (a saved view reopened gives the same bits); above it the two ways
#: agree to round-off.
COARSE_ALONE_POINTS = 2_000_000

Key = tuple[str, tuple[float, str, int] | float]
"""A cache key: (kind, grid key or cell size)."""


class CloudStore(Protocol):
    """What is computed from all of a cloud's points, cached (see the module)."""

    @property
    def presets(self) -> tuple[float, ...]:
        """The grid presets, metres, coarsest first and nested."""
        ...

    @property
    def pool(self) -> ByteBudget:
        """The byte budget the store's cache draws from (shared with the app's)."""
        ...

    @property
    def cached_bytes(self) -> int:
        """Bytes its cache holds now."""
        ...

    def is_cached(self, settings: MapSettings) -> bool:
        """The grid result of ``settings`` is at hand."""
        ...

    def has_cells(self, settings: MapSettings) -> bool:
        """The per-cell figures of ``settings`` (:meth:`cell_result`) are at hand."""
        ...

    def mark_shown(self, settings: MapSettings, owner: object = None) -> None:
        """The grid of ``settings`` is on screen in ``owner``'s analysis (kept while
        others come and go)."""
        ...

    def forget_shown(self, owner: object) -> None:
        """``owner``'s analysis has ended: its grid is no longer kept for it."""
        ...

    def one_at_a_time(self, key: object) -> AbstractContextManager[None]:
        """Hold while computing ``key``: analyses sharing this store compute it once."""
        ...

    def result(self, settings: MapSettings, *,
               progress: ProgressFn | None = None) -> GridRoughness:
        """Grid roughness of ``settings``' (cell size, axis, min points)."""
        ...

    def cell_result(self, settings: MapSettings, *,
                    progress: ProgressFn | None = None) -> GridRoughness:
        """:meth:`result` without its point-to-cell map."""
        ...

    def prepared(self, cell_size: float, *,
                 progress: ProgressFn | None = None) -> PreparedGrid:
        """Cell membership and moments of the grid ``cell_size`` (metres)."""
        ...

    def trust(self, result: GridRoughness, settings: TrustSettings | None, *,
              progress: ProgressFn | None = None) -> CellTrust | None:
        """Scanner figures of every cell of ``result`` (None: no scanner positions)."""
        ...

    def octree(self, max_node_points: int = DEFAULT_MAX_NODE_POINTS) -> Octree:
        """The level-of-detail octree of every point, nodes of at most
        ``max_node_points`` points."""
        ...


@dataclass(frozen=True)
class _Coarsened:
    """What the cache keeps of a grid coarsened from the finest preset: its own cells,
    moments and fine-to-coarse row map, not the finest grid's per-point rows it
    shares (160 MB at 20 M points, which counted against the cache again for every
    coarser preset pushed them out, and each preset change coarsened again)."""

    index: CellIndex
    moments: CellMoments
    parent: np.ndarray

    def on(self, fine: PreparedGrid) -> PreparedGrid:
        """The coarsened grid over ``fine``'s rows (the grid it was coarsened from)."""
        return PreparedGrid(index=self.index, moments=self.moments,
                            fine_cell=fine.index.point_cell, parent=self.parent)


def _made(prepared: PreparedGrid) -> str:
    """How a grid was made: coarsened from a finer one, or indexed on its own."""
    return "coarsened" if prepared.parent is not None else "own"


def _point_rows(prepared: PreparedGrid) -> np.ndarray:
    """(N,) int64 every point's row on ``prepared``'s grid: its own index, or for a grid
    coarsened from a finer one the finer rows looked up in :attr:`PreparedGrid.parent`
    (on all threads where the kernels are loaded)."""
    if prepared.parent is None or prepared.fine_cell is None:
        return prepared.index.point_cell
    if fast.loaded():
        rows = np.empty(prepared.fine_cell.shape[0], dtype=np.int64)
        fast.relabel_into(prepared.fine_cell, prepared.parent, rows)
        return rows
    return prepared.point_cell()


def _weak_pin(store: InMemoryStore) -> Callable[[Key], bool]:
    """The store's pin rule through a weak reference: the cache it gives it to must
    not hold the store (a cycle store -> cache -> bound method -> store kept every
    loaded cloud, and its arrays, until a full garbage collection)."""
    ref = weakref.ref(store)

    def pinned(key: Key) -> bool:
        owner = ref()
        return owner is not None and owner._pinned(key)

    return pinned


class InMemoryStore:
    """A :class:`CloudStore` over a cloud held in memory.

    Parameters
    ----------
    cloud
        The points (file frame, metres).
    presets
        Grid presets, metres, coarsest first and nested (each a whole multiple of
        the finest, which the others are coarsened from).
    pool
        The byte budget the cache draws from.
    most
        Most bytes this store's cache holds of the pool.
    """

    def __init__(self, cloud: PointCloud, presets: tuple[float, ...], pool: ByteBudget,
                 *, most: int) -> None:
        self.cloud = cloud
        self._presets = tuple(presets)
        self._cache: ByteCache[Key, GridRoughness | PreparedGrid | _Coarsened | CellTrust] = ByteCache(
            pool, pinned=_weak_pin(self), most=most)
        self._octree: Octree | None = None
        self._shown: dict[object, tuple[str, tuple[float, str, int]]] = {}
        """The grid each analysis (session) shows, by owner (None: the app's one)."""
        self._computing = KeyedLocks()
        self._made_from: dict[tuple[float, str, int], str] = {}
        """How the grid of each result was made (:func:`_made`)."""
        self._cells_from: dict[tuple[float, str, int], str] = {}
        """How the grid of each cell-only result was made."""
        self._lean: set[Key] = set()
        """The presets coarsened from the finest, kept as their own cells
        (:class:`_Coarsened`: a few bytes a cell, so pinned)."""

    @property
    def presets(self) -> tuple[float, ...]:
        return self._presets

    @property
    def pool(self) -> ByteBudget:
        return self._cache.pool

    @property
    def cached_bytes(self) -> int:
        return self._cache.bytes

    def _pinned(self, key: Key) -> bool:
        """What the grid cache never evicts: the fine grid's cells (every preset is
        coarsened from them) and the presets' coarsened from them (their own cells
        only, without the per-point rows, so a preset change does not coarsen
        again), the grid on screen (the panels' preset grids must not
        push it out), and the cells of every grid with its axis and minimum points
        (the panels' trend across the presets: small, and computed again for every
        threshold if a big cloud's full grids pushed them out)."""
        if key == ("prepared", round(self.presets[-1], 9)) or key in self._lean:
            return True
        for shown in list(self._shown.values()):
            if key == shown:
                return True
            grid, mine = key[1], shown[1]
            if key[0] == "cells" and isinstance(grid, tuple) and grid[1:] == mine[1:]:
                return True
        return False

    def one_at_a_time(self, key: object) -> AbstractContextManager[None]:
        """Compute ``key`` in one thread at a time: the analyses of a classroom's tabs
        share this store, and thirty tabs asking for the same grid compute it once
        (the others wait, then find it in the cache)."""
        return self._computing.held(key)

    def trust(self, result: GridRoughness, settings: TrustSettings | None, *,
              progress: ProgressFn | None = None) -> CellTrust | None:
        """Scanner geometry and predicted bias of every cell of ``result`` (one of
        this cloud's grids), with ``settings`` (None: the bias paper's); cached per grid. None
        without scanner positions. The first call of a calibration simulates its
        bias curves (seconds)."""
        if self.cloud.scanner_positions is None or self.cloud.scan_index is None:
            return None
        key = ("trust", (round(float(result.grid.cell_size), 9), result.axis,
                         int(result.min_points)))
        hit = self._cache.get(key)
        if isinstance(hit, CellTrust) and hit.theta_m.shape[0] == result.n_cells:
            return hit
        made = cell_trust(self.cloud, result, settings, progress=progress)
        if made is not None:
            self._cache.put(key, made)
        return made

    def octree(self, max_node_points: int = DEFAULT_MAX_NODE_POINTS) -> Octree:
        """The level-of-detail octree of every point (memory checked:
        :func:`rough_viewer.lod.octree.build_octree`), nodes of at most
        ``max_node_points`` points: built at the first call and again when another
        node size is asked for (the scene asks when it shows the cloud, before any
        tab holds a node)."""
        with self.one_at_a_time("octree"):
            tree = self._octree
            if tree is None or tree.max_node_points != int(max_node_points):
                self._octree = None  # the old one goes before the new one is built
                tree = self._octree = build_octree(self.cloud, max_node_points=max_node_points)
            return tree

    def is_cached(self, settings: MapSettings) -> bool:
        return ("result", settings.grid_key) in self._cache

    def has_cells(self, settings: MapSettings) -> bool:
        """:meth:`cell_result` of ``settings`` is at hand."""
        return ("cells", settings.grid_key) in self._cache

    def mark_shown(self, settings: MapSettings, owner: object = None) -> None:
        """The grid of ``settings`` is on screen in ``owner``'s analysis (None: the
        app's one): keep its result in the cache while other grids come and go (it
        is pinned, like the finest preset's cells)."""
        self._shown[owner] = ("result", settings.grid_key)

    def forget_shown(self, owner: object) -> None:
        """``owner``'s analysis has ended (a classroom tab left): its grid is no longer
        pinned for it."""
        self._shown.pop(owner, None)

    def result(
        self,
        settings: MapSettings,
        *,
        progress: ProgressFn | None = None,
    ) -> GridRoughness:
        """Grid roughness for the settings' (cell size, axis, min points), cached."""
        key = ("result", settings.grid_key)
        hit = self._cache.get(key)
        if isinstance(hit, GridRoughness):
            return hit
        check_settings(settings)
        cells = self._cache.get(("cells", settings.grid_key))
        if isinstance(cells, GridRoughness):
            # every per-cell figure is at hand (the panels' trend keeps them): only the
            # points' rows are missing, a gather per point from the grid's cells (the
            # same rows the distance pass wrote), not the grid's passes again -- where
            # the grid is made the way the cells' was (a preset indexed on its own and
            # the same preset coarsened may differ by a point on a cell's edge)
            prep = self.prepared(settings.cell_size, progress=progress)
            if self._cells_from.get(settings.grid_key) == _made(prep):
                res = replace(cells, point_cell=_point_rows(prep))
                self._cache.put(key, res)
                return res
        prep = self.prepared(settings.cell_size, progress=progress)
        res = grid_roughness(
            self.cloud,
            settings.cell_size,
            min_points=settings.min_points,
            axis=settings.axis,
            models=("odr", "ols", "hybrid"),
            progress=progress,
            prepared=prep,
        )
        self._made_from[settings.grid_key] = _made(prep)
        self._cache.put(key, res)
        return res

    def cell_result(self, settings: MapSettings, *,
                    progress: ProgressFn | None = None) -> GridRoughness:
        """:meth:`result` without its point-to-cell map (``point_cell`` of shape (0,)):
        every per-cell figure, for whole-face statistics across grids (the Panels
        tab's trend against grid size). Cached apart and pinned while the shown grid
        has its axis and minimum points: at 20 M points a grid's point-to-cell map is
        160 MB and its cells a few MB to tens of MB, so a threshold change need not
        compute the presets again after their full results left the cache."""
        key = ("cells", settings.grid_key)
        hit = self._cache.get(key)
        if isinstance(hit, GridRoughness):
            return hit
        full = self.result(settings, progress=progress)
        self._cells_from[settings.grid_key] = self._made_from.get(settings.grid_key, "")
        light = replace(full, point_cell=np.empty(0, dtype=full.point_cell.dtype))
        self._cache.put(key, light)  # pinned while its axis and minimum points are shown
        return light

    def prepared(self, cell_size: float, *, progress: ProgressFn | None = None) -> PreparedGrid:
        """Cell membership and moments of the grid ``cell_size`` (metres), cached.

        Sizes that are integer multiples of the finest preset
        are coarsened from the fine grid, which shares their origin (the
        bounding-box minimum), instead of indexing the points again; the presets
        coarser than the finest are indexed on their own while the fine grid is not
        at hand (the coarse first map of a cloud needs no fine grid).
        ``progress(0, 1)`` is called before each pass over the points (so a
        cancelled job stops there).
        """
        key = ("prepared", round(float(cell_size), 9))
        hit = self._cache.get(key)
        if isinstance(hit, PreparedGrid):
            return hit
        if isinstance(hit, _Coarsened):
            return hit.on(self.prepared(self.presets[-1], progress=progress))
        factor = cell_size / self.presets[-1]
        fine_key = ("prepared", round(float(self.presets[-1]), 9))
        coarse_alone = self.cloud.n >= COARSE_ALONE_POINTS \
            and key[1] in {round(float(g), 9) for g in self.presets} \
            and fine_key not in self._cache
        if abs(factor - round(factor)) < 1e-9 and round(factor) > 1 and not coarse_alone:
            fine = self.prepared(self.presets[-1], progress=progress)
            prep = coarsen_prepared(fine, int(round(factor)), defer_rows=True)
            if prep.parent is not None and prep.fine_cell is fine.index.point_cell:
                self._lean.add(key)
                if not self._cache.put(key, _Coarsened(prep.index, prep.moments, prep.parent)):
                    self._lean.discard(key)
                return prep
        else:
            if progress is not None:
                progress(0, 1)
            prep = prepare_grid(self.cloud, cell_size)
        self._cache.put(key, prep)
        if key == fine_key:
            self._lean_presets(prep)
        return prep

    def _lean_presets(self, fine: PreparedGrid) -> None:
        """Once the finest grid is indexed: each coarser preset indexed on its own
        before it (a big cloud's coarse first map) is coarsened from it, and where
        every point falls in the same cell both ways (so far always), the coarsened
        grid's own cells take its place (160 MB less at 20 M points, pinned) and the
        results made from the old grid count as made from the new for their rows
        (:meth:`result` from their cells)."""
        for g in self.presets[:-1]:
            key = ("prepared", round(float(g), 9))
            own = self._cache.get(key)
            if not isinstance(own, PreparedGrid) or own.parent is not None:
                continue
            factor = int(round(g / self.presets[-1]))
            lean = coarsen_prepared(fine, factor, defer_rows=True)
            if lean.parent is None or lean.fine_cell is not fine.index.point_cell:
                continue
            same = (lean.index.ijk.shape == own.index.ijk.shape
                    and np.array_equal(lean.index.ijk, own.index.ijk)
                    and np.array_equal(_point_rows(lean), own.index.point_cell))
            if not same:
                continue
            self._lean.add(key)
            if self._cache.put(key, _Coarsened(lean.index, lean.moments, lean.parent)):
                for made_by in (self._cells_from, self._made_from):
                    for grid_key, made in list(made_by.items()):
                        if made == "own" and round(grid_key[0], 9) == key[1]:
                            made_by[grid_key] = "coarsened"
            else:
                self._lean.discard(key)
