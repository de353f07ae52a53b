"""Crop: keep (or remove) the points inside an axis-aligned box.

The box is closed (a point on a face is inside), in metres in the cloud's frame.
``keep`` keeps the points inside, ``remove`` keeps those outside. A cropped cloud
keeps every per-point field (:meth:`rough_viewer.io.cloud.PointCloud.subset`), and
its mask over the original points says which rows a LAS/LAZ copy keeps
(:func:`rough_viewer.io.formats.las_out.write_las_fields` ``keep=``).

>>> import numpy as np
>>> from rough_viewer.io.cloud import PointCloud
>>> cloud = PointCloud.from_xyz(np.array([[0.0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3], [4, 4, 4]]))
>>> box = CropBox((0.5, 0.5, 0.5), (2.0, 2.0, 2.0))
>>> crop_mask(cloud, box).tolist()
[False, True, True, False, False]
>>> cropped = crop_cloud(cloud, CropBox(box.lo, box.hi, "remove"))
>>> cropped.cloud.x.tolist(), cropped.kept, cropped.total
([0.0, 3.0, 4.0], 3, 5)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rough_viewer.io.cloud import PointCloud, as_columns
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError

CropMode = Literal["keep", "remove"]
CROP_MODES: tuple[CropMode, ...] = ("keep", "remove")

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class CropBox:
    """An axis-aligned box and what to do with the points inside it."""

    lo: Vec3
    """Minimum corner, metres, the cloud's frame."""
    hi: Vec3
    """Maximum corner, metres (each at least ``lo``'s)."""
    mode: CropMode = "keep"
    """``keep`` the points inside, or ``remove`` them."""

    def __post_init__(self) -> None:
        lo = tuple(float(v) for v in self.lo)
        hi = tuple(float(v) for v in self.hi)
        if len(lo) != 3 or len(hi) != 3:
            raise InputError("a crop box needs three minimum and three maximum coordinates")
        if not all(math.isfinite(v) for v in lo + hi):
            raise InputError(f"crop box coordinates must be finite, got {lo} to {hi}")
        for axis, a, b in zip("xyz", lo, hi, strict=True):
            if a > b:
                raise InputError(f"crop box: {axis} minimum {a:g} is above its maximum {b:g}")
        if self.mode not in CROP_MODES:
            raise InputError(f"crop mode must be keep or remove, got {self.mode!r}")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)

    @classmethod
    def around(cls, points: PointCloud | np.ndarray, mask: np.ndarray | None = None, *,
               mode: CropMode = "keep") -> CropBox:
        """The bounding box of a cloud's points (those of ``mask``), e.g. of a
        rectangle selection in the view."""
        x, y, z = as_columns(points)
        if mask is not None:
            x, y, z = x[mask], y[mask], z[mask]
        if x.shape[0] == 0:
            raise InputError("no points selected for a crop box")
        return cls((float(x.min()), float(y.min()), float(z.min())),
                   (float(x.max()), float(y.max()), float(z.max())), mode)

    def scaled(self, metres_per_unit: float) -> CropBox:
        """The box given in another unit, in metres."""
        f = float(metres_per_unit)
        (a, b, c), (d, e, g) = self.lo, self.hi
        return CropBox((a * f, b * f, c * f), (d * f, e * f, g * f), self.mode)

    def describe(self, metres_per_unit: float = 1.0, unit: str = "m") -> str:
        """One line for the user, lengths in ``unit``."""
        def num(v: float) -> str:  # UTM-sized coordinates in full, to the millimetre
            return f"{v / metres_per_unit:.3f}".rstrip("0").rstrip(".")

        lo = ", ".join(num(v) for v in self.lo)
        hi = ", ".join(num(v) for v in self.hi)
        what = "kept the points inside" if self.mode == "keep" else "removed the points inside"
        return f"crop: {what} the box ({lo}) to ({hi}) {unit}"


def parse_box(text: str, *, option: str = "--crop") -> tuple[Vec3, Vec3]:
    """``"xmin,ymin,zmin,xmax,ymax,zmax"`` (``--crop``'s form, also typed in the app)
    as two corners, or InputError naming ``option``.

    >>> parse_box("0, 1, 2, 3.5, 4, 5")
    ((0.0, 1.0, 2.0), (3.5, 4.0, 5.0))
    """
    parts = [p.strip() for p in str(text).split(",")]
    try:
        v = [float(p) for p in parts]
    except ValueError:
        v = []
    if len(v) != 6 or not all(math.isfinite(a) for a in v):
        raise InputError(f"{option} expects six finite numbers xmin,ymin,zmin,xmax,ymax,zmax, "
                         f"got {text!r}"[:300])
    return (v[0], v[1], v[2]), (v[3], v[4], v[5])


@dataclass(frozen=True)
class Cropped:
    """A cloud after a crop."""

    cloud: PointCloud
    """The points kept, with every per-point field."""
    mask: np.ndarray
    """(N,) bool over the original cloud's points: which were kept."""

    @property
    def kept(self) -> int:
        """Points kept."""
        return self.cloud.n

    @property
    def total(self) -> int:
        """Points before the crop."""
        return int(self.mask.shape[0])


#: Points compared at a time (bounds the comparisons' temporaries).
_CHUNK = 1 << 22


def crop_mask(points: PointCloud | np.ndarray, box: CropBox) -> np.ndarray:
    """(N,) bool: the points a crop keeps (inside the closed box for ``keep``,
    outside it for ``remove``)."""
    x, y, z = as_columns(points)
    n = int(x.shape[0])
    require(n + 4.0 * min(n, _CHUNK), f"the crop mask of {n:,} points")
    out = np.empty(n, dtype=bool)
    lo, hi = box.lo, box.hi
    for s in range(0, n, _CHUNK):
        e = min(n, s + _CHUNK)
        o = out[s:e]
        np.greater_equal(x[s:e], lo[0], out=o)
        o &= x[s:e] <= hi[0]
        o &= y[s:e] >= lo[1]
        o &= y[s:e] <= hi[1]
        o &= z[s:e] >= lo[2]
        o &= z[s:e] <= hi[2]
        if box.mode == "remove":
            np.logical_not(o, out=o)
    return out


def crop_cloud(cloud: PointCloud, box: CropBox, *, min_points: int = 3) -> Cropped:
    """The cloud cropped to ``box``.

    Raises
    ------
    InputError
        When fewer than ``min_points`` points are kept (naming the cloud).
    """
    mask = crop_mask(cloud, box)
    kept = int(np.count_nonzero(mask))
    if kept < min_points:
        where = f" of {cloud.source}" if cloud.source else ""
        raise InputError(f"the crop keeps {kept} of the {cloud.n:,} points{where}; at least "
                         f"{min_points} are needed (is the box in the cloud's unit and frame?)")
    return Cropped(cloud=cloud.subset(mask), mask=mask)
