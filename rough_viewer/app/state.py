"""What the app shows, as plain data: settings, the loaded cloud, cached grid
results and the colours they give. No viser here, so all of it is testable.

Data flow: a :class:`MapSettings` snapshot names a grid (cell size, dependent
axis, minimum points) and a way to colour it. :meth:`LoadedCloud.result` computes
that grid with the core (:func:`rough_viewer.grid.roughness.grid_roughness`, the
same call as ``rough-viewer compute``) once and caches it; :func:`point_colours`
turns a result plus the colouring settings into one RGB triple per displayed
point without touching the planes again.
"""

from __future__ import annotations

import math
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field, fields, is_dataclass, replace
from typing import Generic, Literal, TypeVar

import numpy as np

from rough_viewer.app.limits import CACHE_BYTES
from rough_viewer.app.sampling import display_subset
from rough_viewer.bias.trust import CellTrust, TrustSettings, cell_trust
from rough_viewer.grid.orientation import dip_and_direction
from rough_viewer.grid.outliers import analysed_values, outlier_mask
from rough_viewer.grid.planes import PlaneFit, dominant_axis, whole_cloud_plane
from rough_viewer.grid.roughness import (
    EXACT_FIT,
    GridRoughness,
    PreparedGrid,
    coarsen_prepared,
    grid_roughness,
    prepare_grid,
)
from rough_viewer.grid.spacing import cell_sizes_from, default_cell_size
from rough_viewer.grid.summary import normalise
from rough_viewer.grid.threshold import ThresholdAdvice, threshold_advice
from rough_viewer.io import PointCloud
from rough_viewer.io.crop import CropBox, crop_cloud
from rough_viewer.lod.octree import DEFAULT_MAX_NODE_POINTS, Octree, build_octree
from rough_viewer.report.build import SPARSE_SHARE
from rough_viewer.visual import colormaps
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
    MAP_TITLES,
    MAPS,
    ROUGHNESS_UNIT,
    TRUST_FIELDS,
    UNIT_LABELS,
    UNIT_METRES,
    AxisChoice,
    ColourLayerName,
    InputError,
    MapName,
    ProgressFn,
)

DisplayMode = Literal["continuous", "binary"]

#: Maps in the order the GUI lists them; names shown to the user.
MODEL_LABELS: dict[MapName, str] = {name: MAP_TITLES[name] for name in MAPS}

#: Default display budget (points drawn in the browser).
DEFAULT_MAX_DISPLAY = 2_000_000

#: Smallest cell size the app accepts (metres): 0.1 mm, for lab scans of joints (a
#: 20 mm joint scanned densely has presets below 1 mm); the grid code checks memory.
MIN_CELL_SIZE = 1e-4

#: Largest cell size the app accepts (metres).
MAX_CELL_SIZE = 10_000.0


@dataclass(frozen=True)
class MapSettings:
    """Everything the user chose that changes the picture (one immutable snapshot)."""

    cell_size: float = 0.25
    """Grid cell edge in metres."""
    model: MapName = "odr"
    """Which roughness map colours the points."""
    axis: AxisChoice = "auto"
    """Dependent axis for OLS and hybrid; ``auto`` = closest to the whole-cloud normal."""
    min_points: int = 4
    """Cells with fewer points get no value."""
    display: DisplayMode = "continuous"
    """Continuous roughness colours, or the binary transform at ``threshold``."""
    threshold: float = 0.05
    """Binary threshold on normalised roughness (0-1)."""
    colormap: str = "viridis"
    """Colour map name (see :mod:`rough_viewer.visual.colormaps`)."""
    stretch: colormaps.Stretch = colormaps.ROUGHNESS_STRETCH
    """How roughness spreads over the colour map (percentiles of the cells or absolute
    limits in metres, linear or log): :class:`rough_viewer.visual.colormaps.Stretch`."""
    layer: ColourLayerName = "roughness"
    """What colours the points: the roughness map, the scan's RGB, its intensity, or
    the distance to the whole-cloud face plane."""
    keep_outliers: bool = False
    """Keep cells whose roughness is larger than the cell (outliers of the hybrid or
    OLS definition, :mod:`rough_viewer.grid.outliers`) in the colour stretch, the
    binary transform, the panels and the zones; by default they are left out and
    drawn in :data:`rough_viewer.visual.colormaps.OUTLIER_RGB`."""

    @property
    def grid_key(self) -> tuple[float, str, int]:
        """Cache key of the grid computation: (cell size, axis, min points)."""
        return (round(float(self.cell_size), 9), self.axis, int(self.min_points))

    def with_(self, **changes: object) -> MapSettings:
        """A copy with some fields changed."""
        return replace(self, **changes)  # type: ignore[arg-type]


# ----------------------------------------------------------------------------- units


@dataclass(frozen=True)
class Units:
    """How lengths are shown: grid sizes and coordinates in the cloud's unit,
    roughness in :data:`rough_viewer.vocabulary.ROUGHNESS_UNIT` of it (mm for metric
    input). The app computes in metres; only what is shown or typed is converted.

    >>> u = Units("ft")
    >>> u.length(0.3048), u.label, u.rough_label
    (1.0, 'ft', 'ft')
    >>> Units("m").rough(0.002), Units("m").rough_label
    (2.0, 'mm')
    """

    unit: str = "m"
    """Unit of the cloud's coordinates (``PointCloud.source_unit``)."""

    @property
    def per(self) -> float:
        """Metres per length unit."""
        return UNIT_METRES[self.unit]

    @property
    def label(self) -> str:
        return UNIT_LABELS[self.unit]

    @property
    def rough_unit(self) -> str:
        return ROUGHNESS_UNIT[self.unit] if self.unit in ROUGHNESS_UNIT else self.unit

    @property
    def rough_per(self) -> float:
        """Metres per roughness unit."""
        return UNIT_METRES[self.rough_unit]

    @property
    def rough_label(self) -> str:
        return UNIT_LABELS[self.rough_unit]

    def length(self, metres: float) -> float:
        """A length in metres, in the cloud's unit (rounded to 9 significant digits)."""
        return float(f"{metres / self.per:.9g}")

    def rough(self, metres: float) -> float:
        """A roughness in metres, in the roughness unit."""
        return float(metres) / self.rough_per

    def rough_text(self, metres: float) -> str:
        """A roughness as shown beside others: 3 significant digits in the roughness
        unit, a metric one under 0.01 mm in µm (e_ols of a lab mesh is
        ``"0.505 µm"``, not ``"0.0005048 mm"``); a dash when it is not finite.

        >>> Units("mm").rough_text(5.048e-7), Units("m").rough_text(0.0012345)
        ('0.505 µm', '1.23 mm')
        """
        if not math.isfinite(metres):
            return "—"
        v = self.rough(metres)
        if self.rough_unit == "mm" and v != 0.0 and abs(v) < 0.01:
            return f"{1000.0 * v:.3g} µm"
        return f"{v:.3g} {self.rough_label}"

    def size_text(self, metres: float) -> str:
        """``"0.25 m"``, ``"12.5 mm"``: a grid size as shown."""
        return f"{self.length(metres):g} {self.label}"


def grid_presets(cloud: PointCloud) -> tuple[float, ...]:
    """The app's grid presets for ``cloud``, metres, coarsest first: the default
    grid from the point spacing (:func:`rough_viewer.grid.spacing.default_cell_size`,
    a readable size in the cloud's own unit; at least :data:`MIN_CELL_SIZE`) times 8,
    4, 2, 1. Nested, so every
    coarser preset is the finest coarsened by a whole factor."""
    # readable in the cloud's unit (default_cell_size's rule, as report and compute)
    return cell_sizes_from(max(default_cell_size(cloud), MIN_CELL_SIZE))


def check_settings(settings: MapSettings) -> None:
    """Raise InputError for settings the core cannot use (message for the GUI)."""
    if not np.isfinite(settings.cell_size) or settings.cell_size < MIN_CELL_SIZE:
        raise InputError(
            f"grid size {settings.cell_size:g} m is too small (minimum {MIN_CELL_SIZE:g} m)"
        )
    if settings.min_points < 3:
        raise InputError(f"minimum points per cell must be at least 3, got {settings.min_points}")
    if settings.model not in MODEL_LABELS:
        raise InputError(f"unknown model {settings.model!r}")
    if settings.axis not in ("auto", "x", "y", "z"):
        raise InputError(f"unknown dependent axis {settings.axis!r}")
    if settings.cell_size > MAX_CELL_SIZE:
        raise InputError(f"grid size {settings.cell_size:g} m is too large "
                         f"(maximum {MAX_CELL_SIZE:g} m)")
    if settings.layer not in COLOUR_LAYERS:
        raise InputError(f"unknown colour layer {settings.layer!r}")
    if not isinstance(settings.stretch, colormaps.Stretch):
        raise InputError("the colour stretch must be a Stretch")
    colormaps.lut(settings.colormap)


def nbytes(obj: object) -> int:
    """Bytes held by the numpy arrays inside ``obj`` (dataclasses, tuples, lists and
    dicts are walked; an array and its views count once, at their base's size)."""
    seen: set[int] = set()
    total = 0
    stack: list[object] = [obj]
    while stack:
        o = stack.pop()
        if isinstance(o, np.ndarray):
            base = o
            while isinstance(base.base, np.ndarray):
                base = base.base
            if id(base) not in seen:
                seen.add(id(base))
                total += int(base.nbytes)
        elif is_dataclass(o) and not isinstance(o, type):
            stack.extend(getattr(o, f.name) for f in fields(o))
        elif isinstance(o, (tuple, list)):
            stack.extend(o)
        elif isinstance(o, dict):
            stack.extend(o.values())
    return total


K = TypeVar("K")
V = TypeVar("V")


class ByteCache(Generic[K, V]):
    """A thread-safe least-recently-used cache bounded by the bytes of its values.

    Parameters
    ----------
    budget
        Most bytes (by :func:`nbytes`) the cache holds. A value larger than the
        whole budget is not kept.
    pinned
        Keys never evicted to make room (they still count against the budget).
    """

    def __init__(self, budget: int, *, pinned: Callable[[K], bool] = lambda _k: False) -> None:
        self.budget = int(budget)
        self._pinned = pinned
        self._items: OrderedDict[K, tuple[V, int]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    def get(self, key: K) -> V | None:
        with self._lock:
            item = self._items.get(key)
            if item is None:
                return None
            self._items.move_to_end(key)
            return item[0]

    def __contains__(self, key: object) -> bool:
        with self._lock:
            return key in self._items

    def put(self, key: K, value: V) -> bool:
        """Keep ``value`` (evicting least recently used values to make room);
        returns False, evicting nothing, when it cannot fit beside the pinned values."""
        size = nbytes(value)
        with self._lock:
            old = self._items.pop(key, None)
            if old is not None:
                self._bytes -= old[1]
            movable = [k for k in self._items if not self._pinned(k)]
            if self._bytes - sum(self._items[k][1] for k in movable) + size > self.budget:
                return False  # it cannot fit: keep what is there rather than flush it
            for k in movable:
                if self._bytes + size <= self.budget:
                    break
                self._bytes -= self._items.pop(k)[1]
            if self._bytes + size > self.budget:
                return False
            self._items[key] = (value, size)
            self._bytes += size
            return True

    @property
    def bytes(self) -> int:
        """Bytes held now."""
        with self._lock:
            return self._bytes

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)


def _weak_pin(cloud: LoadedCloud) -> Callable[[tuple[str, tuple[float, str, int] | float]], bool]:
    """The cloud's pin rule through a weak reference: the cache it gives it to must
    not hold the cloud (a cycle cloud -> cache -> bound method -> cloud kept every
    loaded cloud, and its arrays, until a full garbage collection)."""
    ref = weakref.ref(cloud)

    def pinned(key: tuple[str, tuple[float, str, int] | float]) -> bool:
        owner = ref()
        return owner is not None and owner._pinned(key)

    return pinned


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
    _cache: ByteCache[tuple[str, tuple[float, str, int] | float], GridRoughness | PreparedGrid | CellTrust] = \
        field(init=False, repr=False)
    _layers: dict[str, ColourLayer] = field(init=False, repr=False)
    _octree: Octree | None = field(init=False, repr=False, default=None)
    _shown_key: tuple[str, tuple[float, str, int]] | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.cloud.n < 3:
            raise InputError(f"{self.cloud.source or 'cloud'}: needs at least 3 points, has {self.cloud.n}")
        xyz = self.cloud.xyz()
        lo, hi = self.cloud.bounds()  # per column: 5x faster than xyz.min(axis=0)
        # Local origin: the bounding-box centre rounded to whole metres, so the
        # float32 coordinates sent to the browser stay precise for UTM scans.
        self.origin = (np.asarray(self.frame_origin, dtype=np.float64)
                       if self.frame_origin is not None else np.round(0.5 * (lo + hi)))
        self.display_index = display_subset(xyz, self.max_display, seed=self.seed)
        self.display_points = (xyz[self.display_index] - self.origin).astype(np.float32)
        self.plane = whole_cloud_plane(self.cloud)
        self.auto_axis = dominant_axis(self.plane.normal)
        if self.presets is None:
            self.presets = grid_presets(self.cloud)
        self.presets = tuple(sorted((float(g) for g in self.presets), reverse=True))
        if not self.presets or self.presets[-1] < MIN_CELL_SIZE:
            raise InputError("grid presets must be at least "
                             f"{MIN_CELL_SIZE:g} m, got {self.presets}")
        self._shown_key = None
        self._cache = ByteCache(self.cache_bytes, pinned=_weak_pin(self))
        self._layers = {}

    def _pinned(self, key: tuple[str, tuple[float, str, int] | float]) -> bool:
        """What the grid cache never evicts: the fine grid's cells (every preset is
        coarsened from them), the grid on screen (the panels' preset grids must not
        push it out), and the cells of every grid with its axis and minimum points
        (the panels' trend across the presets: small, and computed again for every
        threshold if a big cloud's full grids pushed them out)."""
        if key == ("prepared", round(self.fine_cell_size, 9)):
            return True
        shown = self._shown_key
        if shown is None:
            return False
        if key == shown:
            return True
        grid, mine = key[1], shown[1]
        return (key[0] == "cells" and isinstance(grid, tuple)
                and grid[1:] == mine[1:])

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
                           cache_bytes=whole.cache_bytes, seed=whole.seed,
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
                           cache_bytes=whole.cache_bytes, seed=whole.seed,
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

    def trust(self, result: GridRoughness, *, progress: ProgressFn | None = None
              ) -> CellTrust | None:
        """Scanner geometry and predicted bias of every cell of ``result`` (one of
        this cloud's grids), with :attr:`trust_settings`; cached per grid. None
        without scanner positions. The first call of a calibration simulates its
        bias curves (seconds)."""
        if self.cloud.scanner_positions is None or self.cloud.scan_index is None:
            return None
        key = ("trust", (round(float(result.grid.cell_size), 9), result.axis,
                         int(result.min_points)))
        hit = self._cache.get(key)
        if isinstance(hit, CellTrust) and hit.theta_m.shape[0] == result.n_cells:
            return hit
        made = cell_trust(self.cloud, result, self.trust_settings, progress=progress)
        if made is not None:
            self._cache.put(key, made)
        return made

    def octree(self, max_node_points: int = DEFAULT_MAX_NODE_POINTS) -> Octree:
        """The level-of-detail octree of every point (built once, memory checked:
        :func:`rough_viewer.lod.octree.build_octree`), nodes of at most
        ``max_node_points`` points at its first call; browser tabs get its nodes."""
        if self._octree is None:
            self._octree = build_octree(self.cloud, max_node_points=max_node_points)
        return self._octree

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
            return by_cell(trust_layer(name, cells, colour_range=rng).colours, result.point_cell)
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
    def n_display(self) -> int:
        """Points drawn."""
        return len(self.display_index)

    @property
    def cached_bytes(self) -> int:
        """Bytes held by the cached grids now (at most ``cache_bytes``)."""
        return self._cache.bytes

    def to_file_frame(self, local: np.ndarray) -> np.ndarray:
        """Local display coordinates -> the file's frame (metres, float64)."""
        return np.asarray(local, dtype=np.float64) + self.origin

    def to_local(self, xyz: np.ndarray) -> np.ndarray:
        """File-frame coordinates (metres) -> the display frame (float64)."""
        return np.asarray(xyz, dtype=np.float64) - self.origin

    def is_cached(self, settings: MapSettings) -> bool:
        return ("result", settings.grid_key) in self._cache

    def mark_shown(self, settings: MapSettings) -> None:
        """The grid of ``settings`` is on screen: keep its result in the cache while
        other grids come and go (it is pinned, like the finest preset's cells)."""
        self._shown_key = ("result", settings.grid_key)

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
        res = grid_roughness(
            self.cloud,
            settings.cell_size,
            min_points=settings.min_points,
            axis=settings.axis,
            models=("odr", "ols", "hybrid"),
            progress=progress,
            prepared=self.prepared(settings.cell_size, progress=progress),
        )
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
        light = replace(full, point_cell=np.empty(0, dtype=full.point_cell.dtype))
        self._cache.put(key, light)  # pinned while its axis and minimum points are shown
        return light

    def prepared(self, cell_size: float, *, progress: ProgressFn | None = None) -> PreparedGrid:
        """Cell membership and moments of the grid ``cell_size`` (metres), cached.

        Sizes that are integer multiples of :attr:`fine_cell_size` (the presets)
        are coarsened from the fine grid, which shares their origin (the
        bounding-box minimum), instead of indexing the points again.
        ``progress(0, 1)`` is called before each pass over the points (so a
        cancelled job stops there).
        """
        key = ("prepared", round(float(cell_size), 9))
        hit = self._cache.get(key)
        if isinstance(hit, PreparedGrid):
            return hit
        factor = cell_size / self.fine_cell_size
        if abs(factor - round(factor)) < 1e-9 and round(factor) > 1:
            fine = self.prepared(self.fine_cell_size, progress=progress)
            prep = coarsen_prepared(fine, int(round(factor)))
        else:
            if progress is not None:
                progress(0, 1)
            prep = prepare_grid(self.cloud, cell_size)
        self._cache.put(key, prep)
        return prep


def map_values(result: GridRoughness, settings: MapSettings) -> np.ndarray:
    """(M,) the shown map's roughness as the colours, panels and zones use it, metres:
    NaN without a value and, unless ``settings.keep_outliers``, for outlier cells
    (:func:`rough_viewer.grid.outliers.analysed_values`)."""
    return analysed_values(result, settings.model, keep_outliers=settings.keep_outliers)


def normalised_map(result: GridRoughness, settings: MapSettings) -> np.ndarray:
    """Min-max normalised roughness of every cell of the shown map (NaN: no value, or
    an outlier left out)."""
    return normalise(map_values(result, settings))


def colour_range(result: GridRoughness, settings: MapSettings) -> colormaps.ColourRange:
    """The stretch of ``settings`` resolved on the cells of the shown map (one vote
    per cell with a value, as Table 1 counts; outliers left out unless kept), metres."""
    return colormaps.resolve(map_values(result, settings), settings.stretch)


def shown_outliers(result: GridRoughness, settings: MapSettings) -> np.ndarray | None:
    """(M,) bool: the cells drawn in the outlier colour (None: none, or kept)."""
    if settings.keep_outliers:
        return None
    mask = outlier_mask(result, settings.model)
    return mask if mask.any() else None


Colouring = Callable[[np.ndarray], np.ndarray]
"""What colours the points: ``colouring(idx)`` gives the (K, 3) uint8 colours of cloud
points ``idx`` (indices into the loaded cloud), for any subset (the nodes a browser
tab shows)."""


def by_cell(cell_rgb: np.ndarray, point_cell: np.ndarray) -> Colouring:
    """The colouring that gives each point its cell's colour ((M, 3) ``cell_rgb``)."""
    def colouring(idx: np.ndarray) -> np.ndarray:
        return cell_rgb[point_cell[idx]]

    return colouring


def cell_colours(
    result: GridRoughness,
    settings: MapSettings,
    *,
    colours_range: colormaps.ColourRange | None = None,
) -> np.ndarray:
    """(M, 3) uint8 colour of every cell of the shown map (see :func:`point_colours`)."""
    out = shown_outliers(result, settings)
    if settings.display == "binary":
        norm = normalised_map(result, settings)
        with np.errstate(invalid="ignore"):
            flags = norm >= settings.threshold
        return colormaps.apply_binary(flags, np.isfinite(norm), settings.colormap, outliers=out)
    rng = colours_range if colours_range is not None else colour_range(result, settings)
    return colormaps.stretch_colours(map_values(result, settings), rng, settings.colormap,
                                     outliers=out)


def point_colours(
    result: GridRoughness,
    settings: MapSettings,
    point_index: np.ndarray,
    *,
    colours_range: colormaps.ColourRange | None = None,
) -> np.ndarray:
    """RGB colour (``(K, 3)`` uint8) of the points ``point_index`` of the cloud.

    Continuous display: each point takes the colour of its cell's roughness under
    the settings' stretch (:func:`colour_range`; robust log percentiles by default,
    or absolute limits) on ``settings.colormap``. Binary display: the 2011 paper's
    transform, min-max normalised roughness ``>= threshold`` in the map's last
    colour, the rest in its first. Points in cells without a value get
    :data:`colormaps.NEUTRAL_RGB`, points in outlier cells (left out)
    :data:`colormaps.OUTLIER_RGB`. ``colours_range`` may pass a precomputed
    :func:`colour_range`.
    """
    return cell_colours(result, settings, colours_range=colours_range)[
        result.point_cell[point_index]]


@dataclass(frozen=True)
class MapStats:
    """Numbers the colour bar and status line show for the current map."""

    theta_min: float
    """Smallest roughness of a valid cell (metres)."""
    theta_max: float
    """Largest roughness of a valid cell (metres)."""
    cells: int
    """Occupied cells."""
    valid_cells: int
    """Cells with a value for this model."""
    rough_share: float
    """Share of valid cells at or above the binary threshold."""
    colour_range: colormaps.ColourRange
    """The stretch resolved on this map (what the colours' ends mean)."""
    exact_fit: int = 0
    """Cells with a value of 0 to round-off (points exactly on a plane, e.g. repeated
    points; :data:`rough_viewer.grid.roughness.EXACT_FIT`)."""
    outliers: int = 0
    """Cells whose roughness is larger than the cell (left out unless kept)."""
    advice: ThresholdAdvice | None = None
    """What the binary threshold flags, and the data's own threshold."""

    @property
    def sparse(self) -> bool:
        """Most occupied cells have no value (fewer than ``SPARSE_SHARE`` of them):
        the grid is too fine for the point density."""
        return self.cells > 0 and self.valid_cells < SPARSE_SHARE * self.cells


def map_stats(result: GridRoughness, settings: MapSettings) -> MapStats:
    """Range and counts of the current map (see :class:`MapStats`); outliers left out
    unless kept."""
    values = map_values(result, settings)
    finite = np.isfinite(values)
    norm = normalise(values)
    valid = int(finite.sum())
    if valid:
        lo, hi = float(values[finite].min()), float(values[finite].max())
        rough = float(np.mean(norm[finite] >= settings.threshold))
    else:
        lo = hi = rough = float("nan")
    return MapStats(lo, hi, len(values), valid, rough,
                    colormaps.resolve(values, settings.stretch),
                    exact_fit=result.cell_report(settings.model)["exact_fit"],
                    outliers=int(outlier_mask(result, settings.model).sum()),
                    advice=threshold_advice(values, settings.threshold,
                                            exact_fit=EXACT_FIT * result.grid.cell_size))


@dataclass(frozen=True)
class CellInfo:
    """What a click on a point reports about its cell (file frame, metres)."""

    cell: int
    """Index into the result's cell arrays."""
    ijk: tuple[int, int, int]
    """Grid index of the cell."""
    centre: tuple[float, float, float]
    n_points: int
    theta: dict[str, float]
    """Roughness per model (``odr``, ``ols``, ``hybrid``, ``e_ols``), metres, NaN if none."""
    normal: tuple[float, float, float]
    """ODR unit normal of the cell (NaN if no plane)."""
    point: tuple[float, float, float]
    """The clicked point, file frame."""
    axis: str
    """Dependent axis used for OLS/hybrid."""
    dip_deg: float = math.nan
    """Dip of the cell's ODR plane, degrees [0, 90] (docs/zones.md; NaN if none)."""
    dip_direction_deg: float = math.nan
    """Azimuth of its down-dip direction, degrees clockwise from +y, [0, 360); a
    vertical plane takes the side of the whole-cloud normal."""


def cell_info(result: GridRoughness, point: int, point_xyz: np.ndarray) -> CellInfo:
    """Describe the cell holding cloud point number ``point`` (see :class:`CellInfo`)."""
    c = int(result.point_cell[point])

    def three(a: np.ndarray) -> tuple[float, float, float]:
        return float(a[0]), float(a[1]), float(a[2])

    i, j, k = (int(v) for v in result.ijk[c])
    dip, dd = dip_and_direction(result.normal[c:c + 1], result.whole_plane.normal)
    return CellInfo(
        cell=c,
        ijk=(i, j, k),
        centre=three(result.centre[c]),
        n_points=int(result.n_points[c]),
        theta={m: float(result.values(m)[c]) for m in MODEL_LABELS},
        normal=three(result.normal[c]),
        point=three(np.asarray(point_xyz, dtype=np.float64)),
        axis=result.axis,
        dip_deg=float(dip[0]),
        dip_direction_deg=float(dd[0]),
    )
