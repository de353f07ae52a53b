"""Face-plane maps: cells projected onto the plane of the face, as 2-D images.

The plane of the face is the whole-cloud ODR plane (centroid and unit normal). Its
2-D axes are fixed so that every map of one cloud shares one frame:

- ``v`` ("up the face") is the world ``z`` axis projected onto the plane; when the
  face is nearly horizontal (``|n_z| > 0.9``) the world ``y`` axis is used instead,
  so the map is a plan view;
- ``u`` ("along the face") is ``n x v``, flipped if needed so that its largest world
  component is positive (the map is never mirrored against the dominant world axis).

Coordinates are ``u = (p - centroid) . u_axis`` and ``v = (p - centroid) . v_axis``
(metres). Pixels are squares of the cell size ``g``: pixel ``(a, b) = floor(u / g),
floor(v / g)``, anchored at the centroid. A cell goes to the pixel of its centre.
When several cells project onto one pixel (a face that is not flat, or cells stacked
through the thickness), the pixel takes their ``max`` (default for maps: a rough
cell is never hidden behind a smooth one) or their ``mean``. Pixels with no cell are
NaN.

Binary transform (2011 paper, Fig. 2): pixel = 1 where the normalised roughness is
``>= threshold``, 0 below, NaN where no cell. It is applied to the continuous
normalised image (normalised per cell with ``rough_viewer.grid.roughness.normalise``,
then rasterised), so a pixel is 1 when its max (or mean) normalised value reaches
the threshold.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError

Reduce = Literal["max", "mean"]

#: Bytes per pixel of one face image at its peak: counts, sums or maxima, the image
#: and the binary image made from it.
BYTES_PER_PIXEL = 40


class Plane(Protocol):
    """What the face-plane tools need of a plane (e.g. ``planes.PlaneFit``): read-only,
    so frozen dataclasses match."""

    @property
    def centroid(self) -> np.ndarray: ...

    @property
    def normal(self) -> np.ndarray: ...


@dataclass(frozen=True)
class FacePlane:
    """A plane given by a point and a normal (satisfies :class:`Plane`)."""

    centroid: np.ndarray
    """(3,) a point of the plane, metres (for the whole-cloud plane: the mean point)."""
    normal: np.ndarray
    """(3,) unit normal."""


@dataclass(frozen=True)
class FaceFrame:
    """2-D frame of the face plane."""

    origin: np.ndarray
    """(3,) the plane's centroid, metres (u = v = 0)."""
    normal: np.ndarray
    """(3,) unit normal of the plane."""
    u_axis: np.ndarray
    """(3,) unit vector "along the face"."""
    v_axis: np.ndarray
    """(3,) unit vector "up the face" (or world y for a near-horizontal face)."""


@dataclass(frozen=True)
class FaceRaster:
    """Cells projected onto the face plane and assigned to pixels."""

    frame: FaceFrame
    cell_size: float
    """Pixel edge, metres (= the grid's cell size)."""
    uv: np.ndarray
    """(M, 2) plane coordinates of the cell centres, metres."""
    pixel: np.ndarray
    """(M, 2) int64 pixel index (column a along u, row b along v) of every cell,
    relative to ``offset``: all indices are >= 0."""
    offset: np.ndarray
    """(2,) int64, absolute pixel index of pixel (0, 0): its lower-left corner is at
    ``offset * cell_size`` in (u, v)."""
    shape: tuple[int, int]
    """(rows, columns) = (number along v, number along u) of the image."""


@dataclass(frozen=True)
class FaceImage:
    """A per-cell map as an image on the face plane."""

    image: np.ndarray
    """(rows, cols) float, row = v, column = u; NaN where no cell."""
    count: np.ndarray
    """(rows, cols) int64, number of cells in each pixel."""
    u: np.ndarray
    """(cols,) pixel-centre u coordinates, metres."""
    v: np.ndarray
    """(rows,) pixel-centre v coordinates, metres."""
    cell_size: float
    reduce: Reduce


@dataclass(frozen=True)
class FaceMaps:
    """One model's face-plane maps (2011 paper, Fig. 2)."""

    normalised: FaceImage
    """Min-max normalised roughness in [0, 1]."""
    binary: FaceImage
    """1.0 where normalised >= threshold, 0.0 below, NaN where no cell."""
    threshold: float


def face_frame(plane: Plane) -> FaceFrame:
    """The 2-D axes of a plane, as described in the module docstring."""
    n = np.asarray(plane.normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    up = np.array([0.0, 0.0, 1.0]) if abs(n[2]) <= 0.9 else np.array([0.0, 1.0, 0.0])
    v = up - np.dot(up, n) * n
    v /= np.linalg.norm(v)
    u = np.cross(n, v)
    u /= np.linalg.norm(u)
    if u[np.argmax(np.abs(u))] < 0:
        u = -u
    return FaceFrame(origin=np.asarray(plane.centroid, dtype=np.float64).copy(), normal=n,
                     u_axis=u, v_axis=v)


def face_raster(centres: np.ndarray, plane: Plane, cell_size: float) -> FaceRaster:
    """Project cell centres (M, 3), metres, onto the face plane; pixels of ``cell_size``."""
    centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    g = float(cell_size)
    if not g > 0:
        raise InputError(f"cell_size must be positive, got {cell_size}")
    frame = face_frame(plane)
    rel = centres - frame.origin
    uv = np.column_stack([rel @ frame.u_axis, rel @ frame.v_axis])
    absolute = np.floor(uv / g).astype(np.int64)
    if len(absolute):
        offset = absolute.min(axis=0)
        pixel = absolute - offset
        ncols, nrows = (int(s) for s in pixel.max(axis=0) + 1)
    else:
        offset = np.zeros(2, dtype=np.int64)
        pixel = absolute
        ncols = nrows = 0
    return FaceRaster(frame=frame, cell_size=g, uv=uv, pixel=pixel, offset=offset,
                      shape=(nrows, ncols))


def face_image(raster: FaceRaster, values: np.ndarray, *, reduce: Reduce = "max") -> FaceImage:
    """Rasterise per-cell ``values`` (M,) onto the face plane.

    NaN values count as no cell. ``reduce`` combines the cells of one pixel.
    """
    values = np.asarray(values, dtype=np.float64)
    if values.shape != (raster.pixel.shape[0],):
        raise ValueError(f"values must have shape ({raster.pixel.shape[0]},), got {values.shape}")
    if reduce not in ("max", "mean"):
        raise ValueError(f"reduce must be 'max' or 'mean', got {reduce!r}")
    rows, cols = raster.shape
    size = rows * cols
    require(size * BYTES_PER_PIXEL, f"a face-plane image of {cols:,} x {rows:,} pixels "
            f"({raster.cell_size:g} m)", hint="use a larger grid size")
    ok = np.isfinite(values)
    flat = raster.pixel[ok, 1] * cols + raster.pixel[ok, 0]
    count = np.bincount(flat, minlength=size)
    if reduce == "mean":
        total = np.bincount(flat, weights=values[ok], minlength=size)
        with np.errstate(invalid="ignore", divide="ignore"):
            image = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    else:
        image = np.full(size, -np.inf)
        np.maximum.at(image, flat, values[ok])
        image[count == 0] = np.nan
    g = raster.cell_size
    u = (raster.offset[0] + np.arange(cols) + 0.5) * g
    v = (raster.offset[1] + np.arange(rows) + 0.5) * g
    return FaceImage(image=image.reshape(rows, cols), count=count.reshape(rows, cols), u=u, v=v,
                     cell_size=g, reduce=reduce)


def face_maps(
    raster: FaceRaster,
    normalised: np.ndarray,
    *,
    threshold: float = 0.05,
    reduce: Reduce = "max",
) -> FaceMaps:
    """Continuous and binary face-plane maps of one model's normalised roughness.

    Parameters
    ----------
    raster : FaceRaster
        From :func:`face_raster` on the grid's cell centres.
    normalised : (M,) float
        Min-max normalised roughness of every cell (NaN where none), from
        ``rough_viewer.grid.roughness.normalise``.
    threshold : float
        Binary cut-off on the normalised value (paper: 0.05).
    reduce : {"max", "mean"}
        How the cells of one pixel are combined.
    """
    cont = face_image(raster, normalised, reduce=reduce)
    with np.errstate(invalid="ignore"):
        bits = np.where(np.isfinite(cont.image), (cont.image >= threshold).astype(np.float64), np.nan)
    binary = FaceImage(image=bits, count=cont.count, u=cont.u, v=cont.v, cell_size=cont.cell_size,
                       reduce=reduce)
    return FaceMaps(normalised=cont, binary=binary, threshold=float(threshold))
