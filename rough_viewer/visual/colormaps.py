"""Colour maps: the one place that turns numbers into colours.

Each map is a small look-up table (LUT, ``(256, 3)`` uint8) built by linear
interpolation between a few anchor colours written here. Anchors for the
perceptual maps (viridis, cividis, magma) are sampled from their published
definitions at evenly spaced positions; the interpolated tables are close to,
not identical with, matplotlib's. No matplotlib dependency.

Used by the app (point colours, colour bar) and by any figure that needs the same
colours, so a value has the same colour everywhere.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from rough_viewer.vocabulary import InputError

ColormapName = Literal["viridis", "cividis", "magma", "coolwarm", "gray"]

#: Colour of points whose cell has no value (too few points, degenerate plane).
NEUTRAL_RGB: tuple[int, int, int] = (190, 190, 190)

#: Plotly colour scale of the 2011 paper's binary maps (Fig. 2): grey below the
#: threshold, black at or above it.
PAPER_BINARY_COLORSCALE: list[list[float | str]] = [
    [0.0, "#bdbdbd"], [0.5, "#bdbdbd"], [0.5, "#000000"], [1.0, "#000000"],
]

#: Number of entries of every LUT.
LUT_SIZE = 256

_ANCHORS: dict[str, tuple[str, ...]] = {
    # Perceptually uniform, colour-blind safe (default for roughness).
    "viridis": (
        "#440154", "#482878", "#3e4989", "#31688e", "#26828e",
        "#1f9e89", "#35b779", "#6ece58", "#b5de2b", "#fde725",
    ),
    # Perceptual and readable with red-green colour blindness.
    "cividis": (
        "#00224e", "#123570", "#3b496c", "#575d6d", "#707173",
        "#8a8779", "#a69d75", "#c4b56c", "#e4cf5b", "#fee838",
    ),
    "magma": (
        "#000004", "#180f3d", "#440f76", "#721f81", "#9e2f7f",
        "#cd4071", "#f1605d", "#fd9668", "#feca8d", "#fcfdbf",
    ),
    # Diverging, blue - light grey - red, for differences such as e_ols.
    "coolwarm": (
        "#3b4cc0", "#6788ee", "#9abbff", "#c9d7f0", "#edd1c2",
        "#f7a889", "#e26952", "#b40426",
    ),
    "gray": ("#1a1a1a", "#f0f0f0"),
}

#: Names offered to the user, default first.
COLORMAP_NAMES: tuple[str, ...] = tuple(_ANCHORS)

#: Maps whose middle is neutral (for signed or centred quantities).
DIVERGING: frozenset[str] = frozenset({"coolwarm"})


def _hex_to_rgb(code: str) -> tuple[int, int, int]:
    code = code.lstrip("#")
    return int(code[0:2], 16), int(code[2:4], 16), int(code[4:6], 16)


def _build_lut(anchors: tuple[str, ...], size: int = LUT_SIZE) -> np.ndarray:
    rgb = np.array([_hex_to_rgb(a) for a in anchors], dtype=np.float64)
    pos = np.linspace(0.0, 1.0, len(anchors))
    t = np.linspace(0.0, 1.0, size)
    table = np.column_stack([np.interp(t, pos, rgb[:, k]) for k in range(3)])
    return np.round(table).astype(np.uint8)


_LUTS: dict[str, np.ndarray] = {name: _build_lut(a) for name, a in _ANCHORS.items()}
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
) -> np.ndarray:
    """Two-colour map: ``flags`` True -> the map's last colour, False -> its first;
    entries where ``valid`` is False get ``nan_rgb``. Returns ``(N, 3)`` uint8."""
    table = lut(name)
    out = np.where(np.asarray(flags, bool)[:, None], table[-1], table[0]).astype(np.uint8)
    out[~np.asarray(valid, bool)] = np.asarray(nan_rgb, dtype=np.uint8)
    return out


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
    table = np.array([_hex_to_rgb(c) for c in ZONE_PALETTE], dtype=np.uint8)
    lab = np.asarray(labels).astype(np.int64)
    out = table[(np.maximum(lab, 1) - 1) % len(ZONE_PALETTE)]
    out[lab <= 0] = np.asarray(none_rgb, dtype=np.uint8)
    return out
