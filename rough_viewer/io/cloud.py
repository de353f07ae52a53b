"""The point cloud: three float64 coordinate columns in metres, in the file's frame,
with the optional per-point attributes a file may carry (intensity, colour, scan
index) and what a reader noticed on the way (warnings)."""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rough_viewer.vocabulary import InputError

#: Largest coordinate magnitude a cloud may have, metres: far beyond any survey
#: (geocentric coordinates reach 6.4e6 m) and still resolving a micrometre; larger
#: ones (a damaged file, or the wrong unit) overflow the planes' sums of squares.
MAX_COORDINATE_M = 1e9


@dataclass(frozen=True)
class PointCloud:
    """Points as three float64 columns (structure of arrays), metres, the file's frame."""

    x: np.ndarray
    """(N,) float64 x, metres."""
    y: np.ndarray
    """(N,) float64 y, metres."""
    z: np.ndarray
    """(N,) float64 z, metres."""
    intensity: np.ndarray | None = None
    """(N,) intensity as stored in the file, or None."""
    source: str = ""
    """Path of the file read, or ``""`` for an in-memory cloud."""
    dropped_nonfinite: int = 0
    """Rows dropped because a coordinate was NaN or infinite."""
    rgb: np.ndarray | None = None
    """(N, 3) colour as stored in the file (uint16 for LAS/E57, uint8 elsewhere), or None."""
    scan_index: np.ndarray | None = None
    """(N,) int32: which scan of a multi-scan file (E57) each point came from, or None."""
    scanner_positions: np.ndarray | None = None
    """(S, 3) float64 position of each scan's scanner in the cloud's frame, metres
    (row ``scan_index[i]`` belongs to point i), or None. Not subset with the points."""
    source_unit: str = "m"
    """Unit the file's coordinates were in (``rough_viewer.vocabulary.UNITS``); the
    cloud itself is always metres. Tools show lengths in this unit by default."""
    warnings: tuple[str, ...] = ()
    """What the reader noticed that the user should know (a header point count that
    disagrees with the data, units that contradict the file's CRS), one line each."""

    @property
    def n(self) -> int:
        """Number of points."""
        return int(self.x.shape[0])

    def xyz(self) -> np.ndarray:
        """(N, 3) float64 array of the coordinates (a new array)."""
        return np.column_stack([self.x, self.y, self.z])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounding box ``(min, max)``, each (3,), metres."""
        lo = np.array([self.x.min(), self.y.min(), self.z.min()])
        hi = np.array([self.x.max(), self.y.max(), self.z.max()])
        return lo, hi

    @classmethod
    def from_xyz(
        cls,
        xyz: np.ndarray,
        intensity: np.ndarray | None = None,
        source: str = "",
        *,
        rgb: np.ndarray | None = None,
        scan_index: np.ndarray | None = None,
        scanner_positions: np.ndarray | None = None,
    ) -> PointCloud:
        """A cloud from an (N, 3) array in metres (copied into contiguous float64
        columns) and optional per-point attributes."""
        arr = np.asarray(xyz, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] < 3:
            raise InputError("xyz must be an (N, 3) array")
        return cls(
            x=np.ascontiguousarray(arr[:, 0]),
            y=np.ascontiguousarray(arr[:, 1]),
            z=np.ascontiguousarray(arr[:, 2]),
            intensity=None if intensity is None else np.asarray(intensity),
            source=source,
            rgb=None if rgb is None else np.asarray(rgb),
            scan_index=None if scan_index is None else np.asarray(scan_index),
            scanner_positions=None if scanner_positions is None
            else np.asarray(scanner_positions, dtype=np.float64),
        )

    def subset(self, which: np.ndarray) -> PointCloud:
        """The points selected by a boolean mask or an index array (every per-point
        attribute with them; scanner positions, source and warnings kept)."""
        return replace(
            self,
            x=self.x[which],
            y=self.y[which],
            z=self.z[which],
            intensity=None if self.intensity is None else self.intensity[which],
            rgb=None if self.rgb is None else self.rgb[which],
            scan_index=None if self.scan_index is None else self.scan_index[which],
        )

    def scaled(self, metres_per_unit: float, unit: str, *,
               z_metres_per_unit: float | None = None) -> PointCloud:
        """The cloud with coordinates multiplied by ``metres_per_unit`` (a file in
        ``unit`` read into metres), z by ``z_metres_per_unit`` where the file's
        vertical unit differs (default the same); scanner positions likewise."""
        fz = metres_per_unit if z_metres_per_unit is None else z_metres_per_unit
        if metres_per_unit == 1.0 and fz == 1.0:
            return replace(self, source_unit=unit)
        factors = np.array([metres_per_unit, metres_per_unit, fz])
        return replace(
            self,
            x=self.x * metres_per_unit if metres_per_unit != 1.0 else self.x,
            y=self.y * metres_per_unit if metres_per_unit != 1.0 else self.y,
            z=self.z * fz if fz != 1.0 else self.z,
            scanner_positions=None if self.scanner_positions is None
            else self.scanner_positions * factors,
            source_unit=unit,
        )

    def with_warnings(self, *lines: str) -> PointCloud:
        """The same cloud with more warnings."""
        return replace(self, warnings=self.warnings + tuple(lines))


#: Bounding boxes of coordinate columns noted by whoever computed them (a reader
#: while the file's blocks were in the cache, a grid pass), keyed by the x column's
#: id and held through weak references to the three columns: see :func:`note_bounds`.
_BOUNDS: dict[int, tuple[Any, Any, Any, np.ndarray, np.ndarray, np.ndarray]] = {}
#: Most boxes kept (the oldest go first).
BOUNDS_KEPT = 32
_BOUNDS_LOCK = threading.Lock()


def note_bounds(x: np.ndarray, y: np.ndarray, z: np.ndarray, lo: np.ndarray,
                hi: np.ndarray, at: np.ndarray) -> None:
    """Remember the bounding box ``(lo, hi)``, each (3,) metres, of the columns ``x,
    y, z`` (these very arrays), and ``at`` (6,) the index of a point on each face
    (min x, y, z, max x, y, z), so that a later pass over them can start from it.

    A hint, not a fact: the arrays may be changed in place afterwards. Whoever uses
    :func:`known_bounds` checks the box against the points it passes over (the
    grid's fused pass: every point inside, and the six points still on the faces)
    or knows the columns are unchanged since (a reader's own checks, right after the
    read)."""
    import weakref

    key = id(x)

    def forget(_ref: Any, key: int = key) -> None:
        entry = _BOUNDS.get(key)
        if entry is not None and entry[0]() is None:
            _BOUNDS.pop(key, None)

    try:
        refs = (weakref.ref(x, forget), weakref.ref(y), weakref.ref(z))
    except TypeError:  # not weak-referenceable
        return
    entry = (*refs, np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64),
             np.array(at, dtype=np.int64))
    with _BOUNDS_LOCK:  # the app's analyses compute on several threads
        _BOUNDS.pop(key, None)
        while len(_BOUNDS) >= BOUNDS_KEPT:
            _BOUNDS.pop(next(iter(_BOUNDS)), None)
        _BOUNDS[key] = entry


def known_bounds(x: np.ndarray, y: np.ndarray, z: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(lo, hi, at)`` as :func:`note_bounds` noted them for these three columns, or
    None (copies; see there for what they may be trusted with)."""
    entry = _BOUNDS.get(id(x))
    if entry is None or entry[0]() is not x or entry[1]() is not y or entry[2]() is not z:
        return None
    return entry[3].copy(), entry[4].copy(), entry[5].copy()


def on_faces(x: np.ndarray, y: np.ndarray, z: np.ndarray, lo: np.ndarray, hi: np.ndarray,
             at: np.ndarray) -> bool:
    """Whether the points ``at`` (indices, as :func:`note_bounds` takes them) still
    lie on the six faces of the box ``lo, hi``."""
    n = int(x.shape[0])
    if at.shape != (6,) or not ((at >= 0) & (at < n)).all():
        return False
    cols = (x, y, z, x, y, z)
    values = np.concatenate([lo, hi])
    return all(bool(cols[f][at[f]] == values[f]) for f in range(6))


def as_columns(points: PointCloud | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Three contiguous float64 columns (metres) of a PointCloud or an (N, 3) array."""
    if isinstance(points, PointCloud):
        return points.x, points.y, points.z
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError("points must be a PointCloud or an (N, 3) array")
    return (
        np.ascontiguousarray(arr[:, 0]),
        np.ascontiguousarray(arr[:, 1]),
        np.ascontiguousarray(arr[:, 2]),
    )


def as_xyz(points: Any) -> np.ndarray:
    """An (N, 3) float64 array of a PointCloud, of anything with an ``xyz()`` method,
    or of an (N, 3) array (metres); InputError for any other shape."""
    if hasattr(points, "xyz") and callable(points.xyz):
        points = points.xyz()
    xyz = np.asarray(points, dtype=np.float64)
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise InputError(f"points must be an (N, 3) array, got shape {xyz.shape}")
    return xyz


def finite_cloud(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    intensity: np.ndarray | None,
    path: Path,
    *,
    rgb: np.ndarray | None = None,
    scan_index: np.ndarray | None = None,
    scanner_positions: np.ndarray | None = None,
) -> PointCloud:
    """A cloud of the rows whose three coordinates are finite (the others counted in
    ``dropped_nonfinite``); InputError naming ``path`` when fewer than 3 remain."""
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    dropped = int(ok.size - np.count_nonzero(ok))
    if dropped:
        x, y, z = x[ok], y[ok], z[ok]
        intensity = None if intensity is None else intensity[ok]
        rgb = None if rgb is None else rgb[ok]
        scan_index = None if scan_index is None else scan_index[ok]
    n = int(x.shape[0])
    if n == 0:
        extra = f" ({dropped} rows with NaN or infinite coordinates dropped)" if dropped else ""
        raise InputError(f"no points in {path}{extra}")
    if n < 3:
        raise InputError(f"only {n} point(s) in {path}; at least 3 are needed")
    return PointCloud(
        x=np.ascontiguousarray(x, dtype=np.float64),
        y=np.ascontiguousarray(y, dtype=np.float64),
        z=np.ascontiguousarray(z, dtype=np.float64),
        intensity=intensity,
        source=str(path),
        dropped_nonfinite=dropped,
        rgb=rgb,
        scan_index=scan_index,
        scanner_positions=scanner_positions,
    )




def check_input_file(path: Path) -> None:
    """Refuse an input that is not a regular file, with one line that says what it is.

    Raises
    ------
    InputError
        ``file not found: P``, ``P is a folder, not a point file`` or ``not a
        regular file (a device or pipe?): P``.
    """
    p = Path(path)
    if p.is_file():
        return
    if p.is_dir():
        raise InputError(f"{p} is a folder, not a point file; name the files in it "
                         f"(a quoted glob such as \"{p / '*.laz'}\")")
    if not p.exists():
        raise InputError(f"file not found: {p}")
    raise InputError(f"not a regular file (a device or pipe?): {p}")
