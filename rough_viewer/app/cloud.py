"""The loaded cloud: a cloud prepared for display (its overview sample, presets,
colour layers, crop lineage) and, behind its :attr:`LoadedCloud.store`
(:mod:`rough_viewer.app.store`), what is computed from all of its points (grid
results, the octree, the scanner figures), cached.

Data flow: a :class:`~rough_viewer.app.settings.MapSettings` snapshot names a grid
(cell size, dependent axis, minimum points) and a way to colour it.
:meth:`LoadedCloud.result` computes that grid with the core
(:func:`rough_viewer.grid.roughness.grid_roughness`, the same call as
``rough-viewer compute``) once and caches it; :mod:`rough_viewer.app.colouring` turns a
result plus the colouring settings into colours without touching the planes again.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

from rough_viewer.app.cache import ByteBudget, Memo
from rough_viewer.app.colouring import Colouring, by_cell
from rough_viewer.app.limits import CACHE_BYTES, DEFAULT_MAX_DISPLAY
from rough_viewer.app.sampling import display_subset
from rough_viewer.app.settings import MIN_CELL_SIZE, MapSettings
from rough_viewer.app.store import CloudStore, InMemoryStore
from rough_viewer.app.units import Units
from rough_viewer.grid.planes import PlaneFit, dominant_axis, whole_cloud_plane
from rough_viewer.grid.roughness import (
    GridRoughness,
    PreparedGrid,
)
from rough_viewer.grid.spacing import cell_sizes_from, default_cell_size
from rough_viewer.io import PointCloud
from rough_viewer.io.crop import CropBox, crop_cloud
from rough_viewer.lod.octree import DEFAULT_MAX_NODE_POINTS, Octree
from rough_viewer.scanner.trust import CellTrust, TrustSettings
from rough_viewer.visual.layers import (
    ColourLayer,
    face_plane_distance,
    intensity_layer,
    plane_distance_layer,
    rgb_layer,
    trust_layer,
)
from rough_viewer.vocabulary import (
    COLOUR_LAYERS,
    TRUST_FIELDS,
    ColourLayerName,
    InputError,
    ProgressFn,
)

#: From this many points the whole-cloud plane is combined from the cell moments of
#: the coarsest preset (the coarse first map's grid, prepared anyway) instead of a
#: pass of its own over the points.
PLANE_FROM_GRID_POINTS = 2_000_000

#: Values derived from a cloud's grids (panel figures) a cloud keeps for the analyses
#: that show it (:meth:`LoadedCloud.derived`).
DERIVED_KEPT = 48

T = TypeVar("T")


def grid_presets(cloud: PointCloud) -> tuple[float, ...]:
    """The app's grid presets for ``cloud``, metres, coarsest first: the default
    grid from the point spacing (:func:`rough_viewer.grid.spacing.default_cell_size`,
    a readable size in the cloud's own unit; at least :data:`MIN_CELL_SIZE`) times 8,
    4, 2, 1. Nested, so every
    coarser preset is the finest coarsened by a whole factor."""
    # readable in the cloud's unit (default_cell_size's rule, as report and compute)
    return cell_sizes_from(max(default_cell_size(cloud), MIN_CELL_SIZE))


@dataclass(eq=False)
class LoadedCloud:
    """A cloud prepared for display, with its grid results cached.

    Parameters
    ----------
    cloud
        The points (file frame, metres).
    max_display
        Most points drawn; roughness is always computed on all ``cloud.n``.
    cache_bytes
        Memory budget of the cached grids (results and cell membership together),
        bytes; least recently used ones are dropped first (default
        :data:`CACHE_BYTES`).
    cache_pool
        The budget the grid cache draws from, shared with the app's other caches
        (:attr:`rough_viewer.app.host.AppOptions.cache_pool`) and with the clouds
        cropped from this one; default its own of ``cache_bytes``.
    """

    cloud: PointCloud
    max_display: int = DEFAULT_MAX_DISPLAY
    cache_bytes: int = CACHE_BYTES
    seed: int = 0
    presets: tuple[float, ...] | None = None
    """Grid presets, metres, coarsest first and nested (each a whole multiple of the
    finest); default :func:`grid_presets` of the cloud."""
    label: str = ""
    """What the status line calls a cloud that is no file (e.g. the board lesson);
    default: its file's name."""
    trust_settings: TrustSettings | None = None
    """Calibration of the scanner figures (default: the bias paper's)."""
    cache_pool: ByteBudget | None = field(default=None, repr=False)
    crop: CropBox | None = None
    """The crop that made ``cloud`` from :attr:`uncropped`'s (None: not cropped)."""
    crop_mask: np.ndarray | None = field(default=None, repr=False)
    """(M,) bool over the uncropped cloud's points: the ones kept (LAS copies of the
    file keep these rows)."""
    uncropped: LoadedCloud | None = field(default=None, repr=False)
    """The whole cloud this one was cropped from (with its cached grids)."""
    crop_exact: bool = False
    """The crop kept exactly the points of a selection (:meth:`cropped_exact`), not
    every point of :attr:`crop` (then their bounding box)."""
    frame_origin: tuple[float, float, float] | None = None
    """The local origin of the display frame (None: the bounding-box centre, rounded;
    a crop keeps its whole cloud's, so the scene does not move)."""
    origin: np.ndarray = field(init=False)
    display_index: np.ndarray = field(init=False)
    display_points: np.ndarray = field(init=False)
    plane: PlaneFit = field(init=False)
    auto_axis: str = field(init=False)
    store: CloudStore = field(init=False, repr=False)
    """What is computed from every point, cached (:mod:`rough_viewer.app.store`: the
    points in memory today; a store on disk implements the same protocol)."""
    _layers: dict[str, ColourLayer] = field(init=False, repr=False)
    _derived: Memo[object, object] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.cloud.n < 3:
            raise InputError(f"{self.cloud.source or 'cloud'}: needs at least 3 points, has {self.cloud.n}")
        c = self.cloud
        lo, hi = self.cloud.bounds()  # per column: 5x faster than xyz.min(axis=0)
        # Local origin: the bounding-box centre rounded to whole metres, so the
        # float32 coordinates sent to the browser stay precise for UTM scans.
        self.origin = (np.asarray(self.frame_origin, dtype=np.float64)
                       if self.frame_origin is not None else np.round(0.5 * (lo + hi)))
        idx = self.display_index = display_subset(c, self.max_display, seed=self.seed)
        self.display_points = (np.column_stack([c.x[idx], c.y[idx], c.z[idx]])
                               - self.origin).astype(np.float32)
        if self.presets is None:
            self.presets = grid_presets(self.cloud)
        self.presets = tuple(sorted((float(g) for g in self.presets), reverse=True))
        if not self.presets or self.presets[-1] < MIN_CELL_SIZE:
            raise InputError("grid presets must be at least "
                             f"{MIN_CELL_SIZE:g} m, got {self.presets}")
        self.store = self._make_store()
        self._layers = {}
        self._derived = Memo(DERIVED_KEPT)
        if self.cloud.n >= PLANE_FROM_GRID_POINTS:
            # the coarsest preset's moments give the plane (equal up to rounding), and
            # its cells are the big cloud's first map: one pass over the points for both
            self.plane = self.store.prepared(self.presets[0]).whole_plane()
        else:
            self.plane = whole_cloud_plane(self.cloud)
        self.auto_axis = dominant_axis(self.plane.normal)

    def _make_store(self) -> CloudStore:
        """The store of what is computed from every point (the points in memory; a
        campaign's overview: :class:`rough_viewer.app.campaign.CampaignCloud`)."""
        assert self.presets is not None
        return InMemoryStore(self.cloud, self.presets,
                             self.cache_pool or ByteBudget(self.cache_bytes),
                             most=self.cache_bytes)

    def cropped(self, box: CropBox) -> LoadedCloud:
        """The whole cloud (:attr:`uncropped`, else this one) cropped by ``box``
        (metres, the file frame): one crop at a time, as a saved view and ``--crop``
        hold one box. Its grid presets are the whole cloud's, so the grid sizes stay.

        Raises InputError when the crop keeps fewer than 3 points."""
        whole = self.uncropped or self
        made = crop_cloud(whole.cloud, box)
        if made.kept < 3:
            raise InputError(f"{box.describe(whole.units.per, whole.units.label)} keeps "
                             f"{made.kept} of {made.total:,} points; a map needs at least 3")
        return LoadedCloud(made.cloud, max_display=whole.max_display,
                           cache_bytes=whole.cache_bytes, cache_pool=whole.store.pool,
                           seed=whole.seed,
                           presets=whole.presets, label=whole.label,
                           trust_settings=whole.trust_settings, crop=box,
                           crop_mask=made.mask, uncropped=whole,
                           frame_origin=(float(whole.origin[0]), float(whole.origin[1]),
                                         float(whole.origin[2])))

    def cropped_exact(self, mask: np.ndarray) -> LoadedCloud:
        """The whole cloud cropped to exactly the points ``mask`` selects of this
        cloud (a selection of 226,861 points keeps those, not the 239,125 of their
        bounding box); :attr:`crop` is their bounding box, :attr:`crop_exact` True.
        One crop at a time, as :meth:`cropped`.

        Raises InputError when the mask is not one per point or keeps fewer than 3."""
        keep = np.asarray(mask)
        if keep.dtype != np.bool_ or keep.shape != (self.cloud.n,):
            raise InputError(f"a selection of this cloud has one flag per point "
                             f"({self.cloud.n:,}), got {keep.shape}")
        whole = self.uncropped or self
        if self.uncropped is not None and self.crop_mask is not None:
            rows = np.flatnonzero(self.crop_mask)[keep]
            keep = np.zeros(whole.cloud.n, dtype=bool)
            keep[rows] = True
        kept = int(np.count_nonzero(keep))
        if kept < 3:
            raise InputError(f"the selection keeps {kept} points; a map needs at least 3")
        return LoadedCloud(whole.cloud.subset(keep), max_display=whole.max_display,
                           cache_bytes=whole.cache_bytes, cache_pool=whole.store.pool,
                           seed=whole.seed,
                           presets=whole.presets, label=whole.label,
                           trust_settings=whole.trust_settings,
                           crop=CropBox.around(whole.cloud, keep), crop_mask=keep,
                           uncropped=whole, crop_exact=True,
                           frame_origin=(float(whole.origin[0]), float(whole.origin[1]),
                                         float(whole.origin[2])))

    @property
    def fine_cell_size(self) -> float:
        """The finest preset (metres): the others are coarsened from it."""
        assert self.presets is not None
        return self.presets[-1]

    @property
    def default_cell_size(self) -> float:
        """The grid shown first (metres): the finest preset, the size at which the
        typical occupied cell holds 16 points."""
        return self.fine_cell_size

    @property
    def units(self) -> Units:
        """How this cloud's lengths are shown (its file's unit)."""
        return Units(self.cloud.source_unit)

    @property
    def layers(self) -> tuple[ColourLayerName, ...]:
        """The colour layers this cloud has: always the roughness map and the
        distance to the face plane; the scan's RGB and intensity where the file has
        them; the scanner figures of the cells (:data:`rough_viewer.vocabulary.
        TRUST_FIELDS`) where it has scanner positions."""
        out: list[ColourLayerName] = ["roughness"]
        if self.cloud.rgb is not None:
            out.append("rgb")
        if self.cloud.intensity is not None:
            out.append("intensity")
        out.append("distance")
        if self.cloud.scanner_positions is not None and self.cloud.scan_index is not None:
            out += [name for name in COLOUR_LAYERS if name in TRUST_FIELDS]
        return tuple(out)

    def layer_colouring(self, name: ColourLayerName, result: GridRoughness) -> Colouring:
        """The colouring of colour layer ``name`` (not ``roughness``) for any points:
        the layer's colour range is resolved once, on the displayed points
        (:meth:`layer`); a scanner figure is per cell of ``result``."""
        if name in TRUST_FIELDS:
            trust = self.trust(result)
            if trust is None:
                self.cell_layer(name, result)  # InputError: no positions
            assert trust is not None
            cells = trust.layer(name)
            rng = self.cell_layer(name, result).colour_range
            return by_cell(trust_layer(name, cells, colour_range=rng).colours, result)
        shown = self.layer(name)  # InputError when the cloud lacks it
        cloud = self.cloud
        if name == "rgb":
            assert cloud.rgb is not None
            rgb = np.asarray(cloud.rgb)
            return lambda idx: rgb_layer(rgb[idx]).colours
        if name == "intensity":
            assert cloud.intensity is not None
            values = np.asarray(cloud.intensity)
            return lambda idx: intensity_layer(values[idx], colour_range=shown.colour_range).colours
        plane = self.plane

        def distance(idx: np.ndarray) -> np.ndarray:
            xyz = np.column_stack([cloud.x[idx], cloud.y[idx], cloud.z[idx]])
            return plane_distance_layer(face_plane_distance(xyz, plane),
                                        colour_range=shown.colour_range).colours

        return distance

    def cell_layer(self, name: ColourLayerName, result: GridRoughness) -> ColourLayer:
        """The colours of the displayed points for a per-cell scanner figure of
        ``result`` (InputError without scanner positions)."""
        trust = self.trust(result)
        if trust is None:
            raise InputError(f"{self.cloud.source or 'this cloud'} has no scanner positions "
                             "(serve --scanner X,Y,Z or --scanners FILE; E57 scans carry "
                             "theirs)")
        return trust_layer(name, trust.layer(name)[result.point_cell[self.display_index]])

    def layer(self, name: ColourLayerName) -> ColourLayer:
        """The colours of the displayed points for colour layer ``name`` (not
        ``roughness``), computed once per cloud. InputError when the cloud lacks it."""
        if name not in self.layers or name == "roughness" or name in TRUST_FIELDS:
            what = {"rgb": "RGB colours", "intensity": "intensities"}.get(name, repr(name))
            raise InputError(f"{self.cloud.source or 'this cloud'} has no {what}")
        hit = self._layers.get(name)
        if hit is not None:
            return hit
        idx = self.display_index
        if name == "rgb":
            assert self.cloud.rgb is not None
            made = rgb_layer(np.asarray(self.cloud.rgb)[idx])
        elif name == "intensity":
            assert self.cloud.intensity is not None
            made = intensity_layer(np.asarray(self.cloud.intensity)[idx])
        else:
            local = self.display_points.astype(np.float64) + self.origin
            made = plane_distance_layer(face_plane_distance(local, self.plane))
        self._layers[name] = made
        return made

    @property
    def n_total(self) -> int:
        """Points used for roughness (all of them)."""
        return self.cloud.n

    @property
    def file_rows(self) -> bool:
        """Whether :attr:`cloud` is the rows of its file (or, cropped, those of
        :attr:`crop_mask` of the uncropped cloud's): a LAS export can then copy the
        file's records with every dimension. A campaign's overview and crops are not."""
        return self.n_total == self.cloud.n

    @property
    def n_display(self) -> int:
        """Points drawn."""
        return len(self.display_index)

    @property
    def cached_bytes(self) -> int:
        """Bytes held by the cached grids now (at most ``cache_bytes``)."""
        return self.store.cached_bytes

    def to_file_frame(self, local: np.ndarray) -> np.ndarray:
        """Local display coordinates -> the file's frame (metres, float64)."""
        return np.asarray(local, dtype=np.float64) + self.origin

    def to_local(self, xyz: np.ndarray) -> np.ndarray:
        """File-frame coordinates (metres) -> the display frame (float64)."""
        return np.asarray(xyz, dtype=np.float64) - self.origin

    def derived(self, key: object, make: Callable[[], T | None]) -> T | None:
        """What ``make()`` derives from this cloud's grids under ``key`` (a panel's
        figure), kept for the last :data:`DERIVED_KEPT` keys and made once however
        many analyses ask at once (the tabs of a classroom: thirty students on one
        grid get its semivariogram computed once). None (a cancelled making) is
        not kept."""
        return self._derived.get_or_make(key, make)  # type: ignore[return-value]

    # ------------------------------------------------------------------ the store's
    @contextmanager
    def _computing(self, key: object, progress: ProgressFn | None) -> Iterator[None]:
        """Around a computation of the store: one thread at a time computes ``key``
        (analyses sharing this cloud compute it once), and, where the cache budget
        has compute slots (a classroom), it waits for one of them (``progress(0, 1)``
        is called while it waits, so a cancelled job stops waiting)."""
        with self.store.one_at_a_time(key):
            slots = self.store.pool.slots
            if slots is None:
                yield
                return
            with slots.held(None if progress is None else (lambda: progress(0, 1))):
                yield

    def is_cached(self, settings: MapSettings) -> bool:
        """The grid result of ``settings`` is at hand (no computing)."""
        return self.store.is_cached(settings)

    def mark_shown(self, settings: MapSettings, owner: object = None) -> None:
        """The grid of ``settings`` is on screen (in ``owner``'s analysis; None: the
        app's one): keep its result in the cache while other grids come and go (it
        is pinned, like the finest preset's cells)."""
        self.store.mark_shown(settings, owner)

    def forget_shown(self, owner: object) -> None:
        """``owner``'s analysis has ended: its grid is no longer pinned for it."""
        self.store.forget_shown(owner)

    def result(self, settings: MapSettings, *,
               progress: ProgressFn | None = None) -> GridRoughness:
        """Grid roughness for the settings' (cell size, axis, min points), cached
        (:meth:`rough_viewer.app.store.CloudStore.result`)."""
        with self._computing(("result", settings.grid_key), progress):
            return self.store.result(settings, progress=progress)

    def cell_result(self, settings: MapSettings, *,
                    progress: ProgressFn | None = None) -> GridRoughness:
        """:meth:`result` without its point-to-cell map, cached apart
        (:meth:`rough_viewer.app.store.InMemoryStore.cell_result`)."""
        with self.store.one_at_a_time(("cells", settings.grid_key)):
            if self.store.has_cells(settings):
                return self.store.cell_result(settings, progress=progress)
            # made from the full result: under its flight, so that a map and a panel
            # asking for the same grid at once compute it once
            with self._computing(("result", settings.grid_key), progress):
                return self.store.cell_result(settings, progress=progress)

    def prepared(self, cell_size: float, *, progress: ProgressFn | None = None) -> PreparedGrid:
        """Cell membership and moments of the grid ``cell_size`` (metres), cached;
        presets coarsened from the finest."""
        with self._computing(("prepared", round(float(cell_size), 9)), progress):
            return self.store.prepared(cell_size, progress=progress)

    def trust(self, result: GridRoughness, *, progress: ProgressFn | None = None
              ) -> CellTrust | None:
        """Scanner geometry and predicted bias of every cell of ``result`` (one of
        this cloud's grids), with :attr:`trust_settings`; cached per grid. None
        without scanner positions. The first call of a calibration simulates its
        bias curves (seconds)."""
        with self._computing(("trust", result.grid.cell_size, result.axis), progress):
            return self.store.trust(result, self.trust_settings, progress=progress)

    def points_covering(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """(K, 3) metres, file frame: every point of the cloud inside the box
        ``[lo, hi]`` (metres), in the cloud's order (a campaign:
        :meth:`rough_viewer.app.campaign.CampaignCloud.points_covering`, every point
        of its file there). A profile's patch is cut so, not copied whole (an
        (N, 3) copy of 20 M points is 480 MB)."""
        c = self.cloud
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        inside = (c.x >= lo[0]) & (c.x <= hi[0])
        inside &= (c.y >= lo[1]) & (c.y <= hi[1])
        inside &= (c.z >= lo[2]) & (c.z <= hi[2])
        return np.column_stack([c.x[inside], c.y[inside], c.z[inside]])

    def octree(self, max_node_points: int = DEFAULT_MAX_NODE_POINTS) -> Octree:
        """The level-of-detail octree of every point, nodes of at most
        ``max_node_points`` points (built again when another node size is asked
        for); browser tabs get its nodes."""
        return self.store.octree(max_node_points)
