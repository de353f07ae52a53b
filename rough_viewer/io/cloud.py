"""The point cloud: three float64 coordinate columns in metres, in the file's frame."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rough_viewer.vocabulary import InputError


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
        cls, xyz: np.ndarray, intensity: np.ndarray | None = None, source: str = ""
    ) -> PointCloud:
        """A cloud from an (N, 3) array (copied into contiguous float64 columns)."""
        arr = np.asarray(xyz, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] < 3:
            raise InputError("xyz must be an (N, 3) array")
        return cls(
            x=np.ascontiguousarray(arr[:, 0]),
            y=np.ascontiguousarray(arr[:, 1]),
            z=np.ascontiguousarray(arr[:, 2]),
            intensity=None if intensity is None else np.asarray(intensity),
            source=source,
        )

    def subset(self, which: np.ndarray) -> PointCloud:
        """The points selected by a boolean mask or an index array."""
        return PointCloud(
            x=self.x[which],
            y=self.y[which],
            z=self.z[which],
            intensity=None if self.intensity is None else self.intensity[which],
            source=self.source,
            dropped_nonfinite=self.dropped_nonfinite,
        )


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


def finite_cloud(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, intensity: np.ndarray | None, path: Path
) -> PointCloud:
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(z)
    dropped = int(ok.size - np.count_nonzero(ok))
    if dropped:
        x, y, z = x[ok], y[ok], z[ok]
        intensity = None if intensity is None else intensity[ok]
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
    )


