"""Colour layers that show the rock itself, beside the roughness maps.

Three layers, each a pure function from per-point arrays to ``(N, 3)`` uint8
colours (the format of a viser point cloud's ``colors``), packed with what a colour
bar needs in a :class:`ColourLayer`:

- ``rgb``: the scan's own colours (:func:`rgb_layer`). LAS stores RGB in 16-bit
  fields (0-65535), but many writers put 8-bit values (0-255) there; the depth is
  detected from the data (:func:`rgb_bit_depth`).
- ``intensity``: return intensity stretched to grey between its 2nd and 98th
  percentiles (:func:`intensity_layer`).
- ``distance``: the signed distance of each point to the whole-cloud face plane
  (:func:`rough_viewer.grid.planes.signed_distance` of
  :func:`~rough_viewer.grid.planes.whole_cloud_plane`), on the diverging coolwarm
  map centred at 0 (:func:`plane_distance_layer`): which parts stand proud of the
  face and which are recessed.

Colour maps and stretches come from :mod:`rough_viewer.visual.colormaps`.

>>> import numpy as np
>>> eight_in_16 = np.array([[0, 128, 255], [255, 64, 0]], dtype=np.uint16)
>>> rgb_colours(eight_in_16)          # 8-bit values in 16-bit fields: kept
array([[  0, 128, 255],
       [255,  64,   0]], dtype=uint8)
>>> rgb_colours(eight_in_16 * 257)    # true 16-bit: the high byte
array([[  0, 128, 255],
       [255,  64,   0]], dtype=uint8)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.planes import PlaneFit, signed_distance, whole_cloud_plane
from rough_viewer.io.cloud import PointCloud
from rough_viewer.visual import colormaps
from rough_viewer.visual.colormaps import ColourRange, Stretch
from rough_viewer.vocabulary import COLOUR_LAYER_LABELS, TRUST_FIELDS, TRUST_LABELS, InputError

#: Grey stretch of intensity: percentiles 2-98 of the points given, linear.
INTENSITY_STRETCH = Stretch("percentile", 2.0, 98.0)
#: Distance to the face plane: symmetric about 0, out to the larger of |2nd| and
#: |98th| percentile of the signed distances, linear.
DISTANCE_STRETCH = Stretch("percentile", 2.0, 98.0, symmetric=True)
#: Stretches of the per-cell scanner figures (docs/scanner.md): biases symmetric about
#: 0, the density ratio 0 to 2 (1, as expected, in the middle), occlusion and the
#: trusted flag on their own 0..1, the others percentiles 2-98.
TRUST_STRETCHES: dict[str, Stretch] = {
    "scans": Stretch("percentile", 0.0, 100.0),
    "range": Stretch("percentile", 2.0, 98.0),
    "incidence_deg": Stretch("absolute", 0.0, 90.0),
    "density_ratio": Stretch("absolute", 0.0, 2.0),
    "occlusion": Stretch("absolute", 0.0, 1.0),
    "noise_pred": Stretch("percentile", 2.0, 98.0),
    "smoothing_pred": Stretch("percentile", 2.0, 98.0, symmetric=True),
    "bias_pred": Stretch("percentile", 2.0, 98.0, symmetric=True),
    "trusted": Stretch("absolute", 0.0, 1.0),
}


@dataclass(frozen=True)
class ColourLayer:
    """Colours of the points for one layer, and what its colour bar needs."""

    name: str
    """``"rgb"``, ``"intensity"`` or ``"distance"`` (see
    :data:`rough_viewer.vocabulary.COLOUR_LAYERS`)."""
    label: str
    """Display name."""
    colours: np.ndarray
    """(N, 3) uint8."""
    colour_range: ColourRange | None
    """Values at the ends of the map (None for RGB: no colour bar)."""
    colormap: str | None
    """Colour map name (None for RGB)."""
    categories: tuple[tuple[float, str, str], ...] | None = None
    """Value, name and colour of each class of a layer drawn by class
    (:data:`rough_viewer.visual.colormaps.CATEGORIES`: the trusted flag), whose
    legend lists the classes; None for a continuous layer."""


def _check_rgb(rgb: np.ndarray) -> np.ndarray:
    arr = np.asarray(rgb)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"RGB colours must be an (N, 3) array, got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.integer):
        raise InputError(f"RGB colours must be integers (8 or 16 bit), got {arr.dtype}")
    if arr.size and (int(arr.min()) < 0 or int(arr.max()) > 65535):
        raise InputError("RGB colours must lie in 0-65535")
    return arr


def rgb_bit_depth(rgb: np.ndarray) -> int:
    """8 or 16: the depth the RGB values were written with.

    uint8 arrays are 8-bit. Wider integers (LAS stores 16-bit fields) are 8-bit when
    no value exceeds 255 (a writer that put 0-255 values in 16-bit fields), 16-bit
    otherwise. A genuine 16-bit scan whose every channel stays below 256/65536 of
    full scale (black) would read as 8-bit; it is black either way.
    """
    arr = _check_rgb(rgb)
    if arr.dtype == np.uint8 or arr.size == 0:
        return 8
    return 8 if int(arr.max()) <= 255 else 16


def rgb_colours(rgb: np.ndarray) -> np.ndarray:
    """``(N, 3)`` uint8 display colours of scan RGB values (8-bit or 16-bit, detected
    by :func:`rgb_bit_depth`).

    16-bit values keep their high byte (``v >> 8``), which maps both common 8-to-16
    bit conventions back exactly: ``v8 * 256`` and ``v8 * 257`` both give ``v8``.
    """
    arr = _check_rgb(rgb)
    if rgb_bit_depth(arr) == 8:
        return arr.astype(np.uint8)
    return (arr.astype(np.uint32) >> 8).astype(np.uint8)


def rgb_layer(rgb: np.ndarray) -> ColourLayer:
    """The scan-colour layer of (N, 3) RGB values (see :func:`rgb_colours`)."""
    return ColourLayer("rgb", COLOUR_LAYER_LABELS["rgb"], rgb_colours(rgb), None, None)


def intensity_layer(
    intensity: np.ndarray,
    *,
    stretch: Stretch = INTENSITY_STRETCH,
    colour_range: ColourRange | None = None,
) -> ColourLayer:
    """Grey colours of per-point intensity.

    Parameters
    ----------
    intensity : (N,) array_like
        Intensity as stored in the file (any units); NaN gets the neutral colour.
    stretch : Stretch
        Default: percentiles 2-98 of the values given, linear.
    colour_range : ColourRange, optional
        A range already resolved (e.g. on every point while ``intensity`` is the
        displayed subset); ``stretch`` is then not used.
    """
    v = np.asarray(intensity, dtype=np.float64).ravel()
    rng = colour_range or colormaps.resolve(v, stretch)
    name = colormaps.default_colormap("intensity")
    return ColourLayer("intensity", COLOUR_LAYER_LABELS["intensity"],
                       colormaps.stretch_colours(v, rng, name), rng, name)


def plane_distance_layer(
    distance_m: np.ndarray,
    *,
    stretch: Stretch = DISTANCE_STRETCH,
    colour_range: ColourRange | None = None,
) -> ColourLayer:
    """Diverging colours of signed distances to the face plane (0 = the middle colour).

    Parameters
    ----------
    distance_m : (N,) array_like
        Signed distances, metres (:func:`face_plane_distance`).
    stretch : Stretch
        Default: symmetric about 0 out to the larger of the 2nd and 98th percentile
        magnitudes; must be ``symmetric`` so that 0 stays in the middle.
    colour_range : ColourRange, optional
        A range already resolved; ``stretch`` is then not used.
    """
    if colour_range is None and not stretch.symmetric:
        raise InputError("the distance layer needs a symmetric stretch (0 in the middle)")
    v = np.asarray(distance_m, dtype=np.float64).ravel()
    rng = colour_range or colormaps.resolve(v, stretch)
    name = colormaps.default_colormap("distance")
    return ColourLayer("distance", COLOUR_LAYER_LABELS["distance"],
                       colormaps.stretch_colours(v, rng, name), rng, name)


def face_plane_distance(
    cloud: PointCloud | np.ndarray, plane: PlaneFit | None = None
) -> np.ndarray:
    """(N,) signed distance of every point to the whole-cloud ODR plane, metres.

    ``plane`` may pass the plane already fitted (the app keeps it as
    ``LoadedCloud.plane``); by default it is fitted here.
    """
    return signed_distance(cloud, plane if plane is not None else whole_cloud_plane(cloud))


def trust_layer(name: str, values: np.ndarray, *,
                colour_range: ColourRange | None = None) -> ColourLayer:
    """Colours of per-point values of one per-cell scanner figure (a
    :data:`rough_viewer.vocabulary.TRUST_FIELDS` name; values from
    ``CellTrust.layer(name)[result.point_cell]``, lengths in metres, NaN = the
    neutral colour), on its colour map (:data:`colormaps.DEFAULT_COLORMAPS`) and
    stretch (:data:`TRUST_STRETCHES`).

    >>> layer = trust_layer("density_ratio", np.array([0.0, 1.0, 2.0, np.nan]))
    >>> layer.colour_range.lo, layer.colour_range.hi, layer.colours.shape
    (0.0, 2.0, (4, 3))
    """
    if name not in TRUST_FIELDS:
        raise InputError(f"unknown scanner layer {name!r}; expected one of "
                         f"{', '.join(TRUST_FIELDS)}")
    v = np.asarray(values, dtype=np.float64).ravel()
    rng = colour_range or colormaps.resolve(v, TRUST_STRETCHES[name])
    cmap = colormaps.default_colormap(name)
    classes = colormaps.CATEGORIES.get(name)
    if classes is not None:  # a flag: one colour per class, not a ramp
        return ColourLayer(name, TRUST_LABELS[name], colormaps.category_colours(v, classes),
                           rng, cmap, classes)
    return ColourLayer(name, TRUST_LABELS[name], colormaps.stretch_colours(v, rng, cmap), rng,
                       cmap)
