"""Colour maps: the one place that turns numbers into colours.

Each map is a small look-up table (LUT, ``(256, 3)`` uint8). viridis, magma,
cividis and coolwarm are matplotlib's own tables, read from the ``cmap`` package
(pure Python, numpy only, no matplotlib) and rounded to 8 bits: the published
256-entry tables of viridis, magma and cividis entry for entry, matplotlib's
segmented coolwarm sampled at 256 points as matplotlib samples it. ``gray`` is this
package's own ramp from dark to light grey (not black to white, so points stay
visible on either background), linear between its two ends.

Used by the app (point colours, colour bar) and by any figure that needs the same
colours, so a value has the same colour everywhere.

Colour stretch: how values (roughness in metres) are spread over a map. A
:class:`Stretch` says *how* (robust percentiles of the values, or absolute limits
pinned in metres; linear or logarithmic); :func:`resolve` turns it into a
:class:`ColourRange` (the limits, in metres) for one set of values;
:func:`positions` gives every value its place in [0, 1] on the map and
:func:`colour_ticks` the round numbers (in mm) a colour bar shows.

The default for every roughness map (:data:`ROUGHNESS_STRETCH`) is the 2nd to 98th
percentile of the cells with a value, on a log scale. Roughness is a positive scale
quantity that spans two to three decades on one face (sub-millimetre scanner noise on
smooth rock, tens of millimetres at fractures and edges), and its distribution is
skewed: on the demo outcrop at 0.25 m the median ODR cell is 1.3 mm and the 98th
percentile 23 mm. A linear stretch, even a robust one, puts half of the face into
3 % of the map (one colour); the log stretch spreads equal ratios over equal colour
steps, so the smooth face and the rough spots both show their variation. The
2nd/98th percentiles (the "2 % linear stretch" of image processing) ignore the few
cells whose values are artefacts (the hybrid model reaches metres where a cell's
plane contains the dependent axis) without hiding real structure.

>>> rng = resolve(np.array([0.001, 0.002, 0.004, 0.008, 0.016]),
...               Stretch("percentile", 0.0, 100.0, log=True))
>>> positions(np.array([0.001, 0.004, 0.016, 0.0, np.nan]), rng)
array([0. , 0.5, 1. , 0. , nan])
>>> colour_ticks(rng).labels
('1', '2', '5', '10')
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from cmap import Colormap

from rough_viewer.vocabulary import InputError, hex_to_rgb

#: Colour of points whose cell has no value (too few points, degenerate plane).
NEUTRAL_RGB: tuple[int, int, int] = (190, 190, 190)
#: Colour of points whose cell is an outlier of the definition (roughness larger than
#: the cell, :mod:`rough_viewer.grid.outliers`): a bright cyan that none of the maps
#: (viridis, cividis, magma, coolwarm, gray) reaches, so such a cell never reads as
#: the roughest rock.
OUTLIER_RGB: tuple[int, int, int] = (0, 229, 255)

#: Plotly colour scale of the 2011 paper's binary maps (Fig. 2): grey below the
#: threshold, black at or above it.
PAPER_BINARY_COLORSCALE: list[list[float | str]] = [
    [0.0, "#bdbdbd"], [0.5, "#bdbdbd"], [0.5, "#000000"], [1.0, "#000000"],
]

#: Number of entries of every LUT.
LUT_SIZE = 256

#: Source of each map, default first: a ``cmap`` catalogue name (the fully
#: namespaced one, so an alias never changes meaning) or, for the grey ramp, its two
#: ends. viridis: perceptually uniform, colour-blind safe (default for roughness);
#: cividis: perceptual and readable with red-green colour blindness; magma;
#: coolwarm: diverging, blue - light grey - red, for differences such as e_ols.
ColormapName = Literal["viridis", "cividis", "magma", "coolwarm", "gray"]
_SOURCES: dict[ColormapName, str | tuple[str, str]] = {
    "viridis": "bids:viridis",
    "cividis": "cividis:cividis",
    "magma": "bids:magma",
    "coolwarm": "matplotlib:coolwarm",
    "gray": ("#1a1a1a", "#f0f0f0"),
}

#: Names offered to the user, default first.
COLORMAP_NAMES: tuple[ColormapName, ...] = get_args(ColormapName)

#: Maps whose middle is neutral (for signed or centred quantities).
DIVERGING: frozenset[str] = frozenset({"coolwarm"})

#: The colour map of each thing the points can be coloured by, in one place: the
#: roughness maps (``odr``, ``ols``, ``hybrid`` and ``e_ols``, all never negative,
#: so sequential maps; e_ols gets magma so that it is not mistaken for a roughness)
#: and the colour layers of :mod:`rough_viewer.visual.layers` (``intensity`` grey,
#: ``distance`` to the face plane diverging about 0).
DEFAULT_COLORMAPS: dict[str, str] = {
    "odr": "viridis",
    "ols": "viridis",
    "hybrid": "viridis",
    "e_ols": "magma",
    "intensity": "gray",
    "distance": "coolwarm",
    # the per-cell scanner figures (rough_viewer.scanner.trust, docs/scanner.md):
    # quantities that only grow sequential, ratios about 1 and biases about 0 diverging
    "scans": "viridis",
    "range": "viridis",
    "incidence_deg": "magma",
    "density_ratio": "coolwarm",
    "occlusion": "magma",
    "noise_pred": "magma",
    "smoothing_pred": "coolwarm",
    "bias_pred": "coolwarm",
    "trusted": "cividis",
}


def _build_lut(source: str | tuple[str, str], size: int = LUT_SIZE) -> np.ndarray:
    """``(size, 3)`` uint8 table of one :data:`_SOURCES` entry: the ``cmap`` table
    (float RGB in [0, 1]) times 255, rounded; or the linear ramp between two ends."""
    if isinstance(source, str):
        table = Colormap(source).lut(size)[:, :3] * 255.0
    else:
        rgb = np.array([hex_to_rgb(c) for c in source], dtype=np.float64)
        t = np.linspace(0.0, 1.0, size)[:, None]
        table = rgb[0] + t * (rgb[1] - rgb[0])
    return np.round(table).astype(np.uint8)


_LUTS: dict[str, np.ndarray] = {name: _build_lut(src) for name, src in _SOURCES.items()}
for _table in _LUTS.values():
    _table.setflags(write=False)


def lut(name: str) -> np.ndarray:
    """The ``(256, 3)`` uint8 look-up table of colour map ``name`` (read-only).

    Raises
    ------
    ValueError
        If ``name`` is not one of :data:`COLORMAP_NAMES`.
    """
    try:
        return _LUTS[name]
    except KeyError:
        raise InputError(
            f"unknown colour map {name!r}; choose one of {', '.join(COLORMAP_NAMES)}"
        ) from None


def default_colormap(name: str) -> str:
    """The colour map shown for map or layer ``name`` (see :data:`DEFAULT_COLORMAPS`).

    >>> default_colormap("e_ols"), default_colormap("odr")
    ('magma', 'viridis')
    """
    try:
        return DEFAULT_COLORMAPS[name]
    except KeyError:
        raise InputError(
            f"no colour map for {name!r}; known: {', '.join(DEFAULT_COLORMAPS)}"
        ) from None


def to_unit(values: np.ndarray, vmin: float, vmax: float) -> np.ndarray:
    """Scale ``values`` linearly so ``vmin`` -> 0 and ``vmax`` -> 1, clipped to [0, 1].

    NaN stays NaN. If ``vmax <= vmin`` every finite value maps to 0 where it is
    below ``vmax`` and 1 otherwise (a step at the clip value).
    """
    v = np.asarray(values, dtype=np.float64)
    if vmax > vmin:
        t = (v - vmin) / (vmax - vmin)
    else:
        with np.errstate(invalid="ignore"):
            t = np.where(v < vmax, 0.0, 1.0)
        t = np.where(np.isfinite(v), t, np.nan)
    return np.clip(t, 0.0, 1.0)


def apply(
    values: np.ndarray,
    name: str = "viridis",
    *,
    vmin: float = 0.0,
    vmax: float = 1.0,
    nan_rgb: tuple[int, int, int] = NEUTRAL_RGB,
) -> np.ndarray:
    """Colours of ``values`` as an ``(N, 3)`` uint8 array.

    Parameters
    ----------
    values
        Any real numbers, shape ``(N,)``; NaN means "no value".
    name
        Colour map name.
    vmin, vmax
        Values mapped to the first and last LUT entry; values outside are clipped
        to the end colours.
    nan_rgb
        Colour of NaN values.
    """
    table = lut(name)
    t = to_unit(values, vmin, vmax)
    finite = np.isfinite(t)
    idx = np.zeros(t.shape, dtype=np.intp)
    idx[finite] = np.round(t[finite] * (len(table) - 1)).astype(np.intp)
    out = table[idx]
    out[~finite] = np.asarray(nan_rgb, dtype=np.uint8)
    return out


def apply_binary(
    flags: np.ndarray,
    valid: np.ndarray,
    name: str = "viridis",
    *,
    nan_rgb: tuple[int, int, int] = NEUTRAL_RGB,
    outliers: np.ndarray | None = None,
) -> np.ndarray:
    """Two-colour map: ``flags`` True -> the map's last colour, False -> its first;
    entries where ``valid`` is False get ``nan_rgb``, those where ``outliers`` is True
    :data:`OUTLIER_RGB`. Returns ``(N, 3)`` uint8."""
    table = lut(name)
    out = np.where(np.asarray(flags, bool)[:, None], table[-1], table[0]).astype(np.uint8)
    out[~np.asarray(valid, bool)] = np.asarray(nan_rgb, dtype=np.uint8)
    return mark_outliers(out, outliers)


def mark_outliers(rgb: np.ndarray, outliers: np.ndarray | None) -> np.ndarray:
    """``rgb`` ((N, 3) uint8, changed in place and returned) with the entries where
    ``outliers`` ((N,) bool, or None for none) is True in :data:`OUTLIER_RGB`.

    >>> mark_outliers(np.zeros((3, 3), np.uint8), np.array([False, True, False]))[1].tolist()
    [0, 229, 255]
    """
    if outliers is not None:
        rgb[np.asarray(outliers, bool)] = np.asarray(OUTLIER_RGB, dtype=np.uint8)
    return rgb


def plotly_colorscale(name: str, steps: int = 11) -> list[list[float | str]]:
    """The map as a plotly ``colorscale``: ``[[position, "rgb(r,g,b)"], ...]``."""
    table = lut(name)
    pos = np.linspace(0.0, 1.0, steps)
    idx = np.round(pos * (len(table) - 1)).astype(int)
    return [[float(p), "rgb({},{},{})".format(*table[i])] for p, i in zip(pos, idx, strict=True)]


def rgb_css(rgb: tuple[int, int, int] | np.ndarray) -> str:
    """``"rgb(r,g,b)"`` for plotly and HTML."""
    r, g, b = (int(v) for v in rgb)
    return f"rgb({r},{g},{b})"


# ----------------------------------------------------------------------------- stretch

StretchMode = Literal["percentile", "absolute"]
STRETCH_MODES: tuple[StretchMode, ...] = ("percentile", "absolute")
"""``percentile``: limits from the values' percentiles; ``absolute``: fixed limits."""

#: Most decades a log stretch spans: its lower limit is raised to ``hi / 10**4`` if
#: needed, so round-off values (1e-15 m) cannot squeeze the real range into a corner.
MAX_LOG_DECADES = 4.0


@dataclass(frozen=True)
class Stretch:
    """How values are spread over a colour map (see the module docstring).

    >>> Stretch().describe()
    'percentiles 2–98, linear'
    >>> Stretch.absolute_mm(0.5, 50, log=True).describe()
    'absolute 0.5–50 mm, log'
    """

    mode: StretchMode = "percentile"
    """``"percentile"`` or ``"absolute"``."""
    lo: float = 2.0
    """Lower limit: a percentile (0-100) of the values in ``percentile`` mode; a value
    in the values' units (metres for roughness) in ``absolute`` mode."""
    hi: float = 98.0
    """Upper limit, like ``lo``."""
    log: bool = False
    """Spread ``log10(value)`` instead of the value: equal ratios get equal colour
    steps. Zero, negative values and values below the lower limit take the first
    colour. In ``percentile`` mode the percentiles are those of the positive values
    within :data:`MAX_LOG_DECADES` decades of the positive values' upper percentile
    (smaller ones are round-off, counted as zero)."""
    symmetric: bool = False
    """Diverging use: the resolved limits are widened to ``±max(|lo|, |hi|)``, so 0
    falls on the middle colour (signed quantities such as a distance to a plane)."""

    def __post_init__(self) -> None:
        if self.mode not in ("percentile", "absolute"):
            raise InputError(f"stretch mode must be 'percentile' or 'absolute', got {self.mode!r}")
        lo, hi = float(self.lo), float(self.hi)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InputError(f"colour range needs lower < upper limit, got {lo:g} and {hi:g}")
        if self.mode == "percentile" and not (0.0 <= lo and hi <= 100.0):
            raise InputError(f"percentiles must lie in 0-100, got {lo:g} and {hi:g}")
        if self.log and self.symmetric:
            raise InputError("a symmetric (diverging) colour range cannot be logarithmic")
        if self.log and self.mode == "absolute" and lo <= 0:
            raise InputError(f"a log colour scale needs a lower limit above 0, got {lo:g}")

    @classmethod
    def absolute_mm(cls, lo_mm: float, hi_mm: float, *, log: bool = False) -> Stretch:
        """Absolute limits typed in millimetres (stored in metres)."""
        return cls("absolute", float(lo_mm) * 1e-3, float(hi_mm) * 1e-3, log=log)

    def describe(self, *, scale: float = 1e3, unit: str = "mm") -> str:
        """One line for a colour bar: ``"percentiles 2–98, log"`` or
        ``"absolute 0.5–50 mm, linear"`` (absolute limits times ``scale``, in ``unit``)."""
        how = "log" if self.log else "linear"
        if self.symmetric:
            how += ", symmetric about 0"
        if self.mode == "percentile":
            return f"percentiles {self.lo:g}–{self.hi:g}, {how}"
        return f"absolute {self.lo * scale:g}–{self.hi * scale:g} {unit}, {how}"


#: Default stretch of every roughness map (odr, ols, hybrid, e_ols): see the module
#: docstring for why percentiles 2-98 on a log scale.
ROUGHNESS_STRETCH = Stretch("percentile", 2.0, 98.0, log=True)


@dataclass(frozen=True)
class ColourRange:
    """A stretch resolved on one set of values: what position 0 and 1 of the map mean."""

    lo: float
    """Value at the first colour (values' units, metres for roughness); NaN when no
    value was finite."""
    hi: float
    """Value at the last colour; equal to ``lo`` when all values are equal (they
    then take the middle colour)."""
    log: bool
    """Positions are linear in ``log10(value)``."""
    stretch: Stretch
    """The stretch this range came from."""
    n_values: int
    """Finite values the range was resolved on."""
    below: float
    """Share of those values below ``lo`` (drawn in the first colour)."""
    above: float
    """Share of those values above ``hi`` (drawn in the last colour)."""

    def pinned(self) -> Stretch:
        """This range as an absolute stretch, so the same values get the same colours
        on another grid size or file (CloudCompare's absolute scale)."""
        return Stretch("absolute", self.lo, self.hi, log=self.log,
                       symmetric=self.stretch.symmetric)


def resolve(values: np.ndarray, stretch: Stretch = ROUGHNESS_STRETCH) -> ColourRange:
    """The limits of ``stretch`` on ``values``.

    Parameters
    ----------
    values : array_like
        The values to colour, any shape (for roughness: one per cell with a value,
        metres; NaN = no value and is ignored).
    stretch : Stretch
        Default :data:`ROUGHNESS_STRETCH`.

    Returns
    -------
    ColourRange
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if stretch.mode == "absolute":
        lo, hi = float(stretch.lo), float(stretch.hi)
    elif stretch.log:
        positive = v[v > 0]
        if positive.size == 0:
            return ColourRange(float("nan"), float("nan"), True, stretch, int(v.size), 0.0, 0.0)
        top = float(np.percentile(positive, stretch.hi))
        # values more than MAX_LOG_DECADES below the top count as zero (round-off,
        # e.g. the exactly-fitted planes of 3-point cells), not as the low end
        basis = positive[positive >= top / 10.0**MAX_LOG_DECADES]
        lo, hi = (float(q) for q in np.percentile(basis, [stretch.lo, stretch.hi]))
    else:
        if v.size == 0:
            return ColourRange(float("nan"), float("nan"), False, stretch, 0, 0.0, 0.0)
        lo, hi = (float(q) for q in np.percentile(v, [stretch.lo, stretch.hi]))
    if stretch.symmetric:
        half = max(abs(lo), abs(hi))
        lo, hi = -half, half
    if stretch.log and hi > 0:
        lo = max(lo, hi / 10.0**MAX_LOG_DECADES)
    n = int(v.size)
    below = float(np.count_nonzero(v < lo)) / n if n else 0.0
    above = float(np.count_nonzero(v > hi)) / n if n else 0.0
    return ColourRange(lo, hi, stretch.log, stretch, n, below, above)


def positions(values: np.ndarray, colour_range: ColourRange) -> np.ndarray:
    """Place of every value on the colour map, in [0, 1] (float64, same shape).

    Values outside the range are clipped to its ends; on a log range zero and
    negative values go to 0. NaN stays NaN (the neutral colour); so does every value
    when the range has no finite limits. When ``lo == hi`` finite values go to 0.5.
    """
    v = np.asarray(values, dtype=np.float64)
    lo, hi = colour_range.lo, colour_range.hi
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return np.full(v.shape, np.nan)
    if hi <= lo:
        return np.where(np.isfinite(v), 0.5, np.nan)
    if colour_range.log:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (np.log10(np.maximum(v, lo)) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
    else:
        t = (v - lo) / (hi - lo)
    return np.clip(t, 0.0, 1.0)


def stretch_colours(
    values: np.ndarray,
    colour_range: ColourRange,
    name: str = "viridis",
    *,
    nan_rgb: tuple[int, int, int] = NEUTRAL_RGB,
    outliers: np.ndarray | None = None,
) -> np.ndarray:
    """``(N, 3)`` uint8 colours of ``values`` under ``colour_range`` on map ``name``;
    entries where ``outliers`` is True in :data:`OUTLIER_RGB` (pass the per-point
    :func:`rough_viewer.grid.outliers.outlier_mask` of each point's cell)."""
    return mark_outliers(apply(positions(values, colour_range), name, nan_rgb=nan_rgb),
                         outliers)


def largest_colour_share(positions_: np.ndarray, *, band: int = 1) -> float:
    """The largest share of the finite ``positions_`` that fall on one LUT entry
    (``band=1``) or on any ``band`` consecutive entries: how much of a picture one
    colour (or one barely distinguishable band of colours) covers. NaN (neutral grey)
    is left out; 0 when nothing is finite.

    >>> largest_colour_share(np.array([0.0, 0.0, 0.5, 1.0, np.nan]))
    0.5
    """
    t = np.asarray(positions_, dtype=np.float64).ravel()
    t = t[np.isfinite(t)]
    if t.size == 0:
        return 0.0
    idx = np.round(np.clip(t, 0.0, 1.0) * (LUT_SIZE - 1)).astype(np.intp)
    counts = np.bincount(idx, minlength=LUT_SIZE)
    width = max(1, min(int(band), LUT_SIZE))
    runs = np.convolve(counts, np.ones(width, dtype=np.int64), mode="valid")
    return float(runs.max()) / t.size


# ----------------------------------------------------------------------------- colour-bar ticks


@dataclass(frozen=True)
class ColourTicks:
    """Round numbers to label a colour bar with."""

    values: np.ndarray
    """(K,) tick values in display units (mm for roughness)."""
    positions: np.ndarray
    """(K,) their places on the map, in [0, 1]."""
    labels: tuple[str, ...]
    """(K,) their labels, without the unit."""


def format_tick(value: float, step: float | None = None) -> str:
    """A tick label: as many decimals as ``step`` (or the value itself, when no step)
    needs, thousands separated, a true minus sign.

    >>> format_tick(0.05), format_tick(2.0), format_tick(12500.0), format_tick(-1.5, 0.5)
    ('0.05', '2', '12,500', '−1.5')
    """
    ref = abs(step) if step else abs(value)
    decimals = 0 if ref == 0 or ref >= 1 else int(math.ceil(-math.log10(ref) - 1e-9))
    if step is None and ref:
        # keep significant digits of values like 0.25 or 1.5 that decimals would cut
        while decimals < 12 and abs(round(value, decimals) - value) > 1e-9 * abs(value):
            decimals += 1
    text = f"{abs(value):,.{decimals}f}"
    return ("−" if value < 0 and float(text.replace(",", "")) != 0 else "") + text


def _linear_ticks(lo: float, hi: float, max_ticks: int) -> tuple[list[float], float]:
    """The most multiples of a 1-2-5 step (at most ``max_ticks``) inside [lo, hi]."""
    top = math.floor(math.log10(hi - lo)) + 1
    best: tuple[list[float], float] = ([], 10.0**top)
    for e in range(top, top - 4, -1):
        for m in (5.0, 2.0, 1.0):
            step = m * 10.0**e
            first = math.ceil(lo / step - 1e-9)
            last = math.floor(hi / step + 1e-9)
            if last - first + 1 > max_ticks:
                return best
            best = ([k * step for k in range(first, last + 1)], step)
    return best


def colour_ticks(
    colour_range: ColourRange, *, scale: float = 1e3, max_ticks: int = 6
) -> ColourTicks:
    """Tick values and labels for a colour bar of ``colour_range``.

    Parameters
    ----------
    colour_range : ColourRange
        From :func:`resolve` (values in metres for roughness).
    scale : float
        Display units per value unit: 1e3 labels metres in millimetres.
    max_ticks : int
        Most ticks (at least 2).

    Returns
    -------
    ColourTicks
        Linear ranges get multiples of 1, 2 or 5 x 10^k; log ranges get the decades
        inside the range, or 1-2-5 steps when it spans less than about two decades,
        or linear steps when even those give fewer than three ticks.
        A range with ``lo == hi`` gets one tick, an empty range none.
    """
    max_ticks = max(2, int(max_ticks))
    lo, hi = colour_range.lo * scale, colour_range.hi * scale
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return ColourTicks(np.empty(0), np.empty(0), ())
    if hi <= lo:
        return ColourTicks(np.array([lo]), np.array([0.5]), (format_tick(lo),))
    step: float | None = None
    if colour_range.log and lo > 0:
        k0, k1 = math.ceil(math.log10(lo) - 1e-9), math.floor(math.log10(hi) + 1e-9)
        decades = [10.0**k for k in range(k0, k1 + 1)]
        if len(decades) >= 3:
            every = math.ceil(len(decades) / max_ticks)
            ticks = decades[::every]
        else:
            ticks = [m * 10.0**k for k in range(k0 - 1, k1 + 1) for m in (1.0, 2.0, 5.0)
                     if lo * (1 - 1e-9) <= m * 10.0**k <= hi * (1 + 1e-9)]
            if len(ticks) > max_ticks:
                ticks = [t for t in ticks  # keep 1 and 5 x 10^k
                         if round(t / 10.0 ** math.floor(math.log10(t) + 1e-9)) in (1, 5)]
            if len(ticks) < 3:
                ticks, step = _linear_ticks(lo, hi, max_ticks)
    else:
        ticks, step = _linear_ticks(lo, hi, max_ticks)
    values = np.array(ticks, dtype=np.float64)
    return ColourTicks(
        values=values,
        positions=positions(values / scale, colour_range),
        labels=tuple(format_tick(t, step) for t in ticks),
    )


# ----------------------------------------------------------------------------- zones

#: Distinct colours of zones (qualitative, after Tableau 10 without its grey), cycled
#: by zone id: zone ``k`` (1..Z) takes ``ZONE_PALETTE[(k - 1) % len(ZONE_PALETTE)]``.
ZONE_PALETTE: tuple[str, ...] = (
    "#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948",
    "#b07aa1", "#ff9da7", "#9c755f", "#17becf", "#8c6d31", "#393b79",
)


def zone_colour(zone: int) -> str:
    """``"#rrggbb"`` of zone ``zone`` (1..Z); the neutral grey for 0 (in no zone).

    >>> zone_colour(1), zone_colour(13), zone_colour(0)
    ('#4e79a7', '#4e79a7', '#bebebe')
    """
    if zone <= 0:
        return "#{:02x}{:02x}{:02x}".format(*NEUTRAL_RGB)
    return ZONE_PALETTE[(int(zone) - 1) % len(ZONE_PALETTE)]


def zone_colours(labels: np.ndarray, *, none_rgb: tuple[int, int, int] = NEUTRAL_RGB) -> np.ndarray:
    """``(N, 3)`` uint8 colours of zone ids (0 = in no zone -> ``none_rgb``)."""
    table = np.array([hex_to_rgb(c) for c in ZONE_PALETTE], dtype=np.uint8)
    lab = np.asarray(labels).astype(np.int64)
    out = table[(np.maximum(lab, 1) - 1) % len(ZONE_PALETTE)]
    out[lab <= 0] = np.asarray(none_rgb, dtype=np.uint8)
    return out


#: Layers of a few classes drawn in one colour per class with a legend, not on a
#: continuous ramp: value, name and colour of each class. ``trusted`` (the scanner's
#: 0/1 flag, docs/scanner.md) takes the trust map's green for trusted
#: (:data:`rough_viewer.visual.trust.TRUST_CLASSES`) and a red for not trusted.
CATEGORIES: dict[str, tuple[tuple[float, str, str], ...]] = {
    "trusted": ((0.0, "not trusted", "#d62728"), (1.0, "trusted", "#2ca02c")),
}


def category_colours(values: np.ndarray, classes: tuple[tuple[float, str, str], ...]
                     ) -> np.ndarray:
    """``(N, 3)`` uint8 colours of class values: each class's colour where a value
    equals its value, the neutral grey elsewhere (NaN: not judged).

    >>> category_colours(np.array([0.0, 1.0, np.nan]), CATEGORIES["trusted"]).tolist()
    [[214, 39, 40], [44, 160, 44], [190, 190, 190]]
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    out = np.empty((v.shape[0], 3), dtype=np.uint8)
    out[:] = np.asarray(NEUTRAL_RGB, dtype=np.uint8)
    for value, _name, colour in classes:
        out[v == value] = np.asarray(hex_to_rgb(colour), dtype=np.uint8)
    return out
