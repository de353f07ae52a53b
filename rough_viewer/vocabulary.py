"""The words every part of rough_viewer shares: models, maps, axes, residual
conventions, wavelet options, display labels and colours, the progress callback and
the one error type for bad input.

Everything here is a constant or a type; nothing imports from the rest of the
package, so every layer (science, figures, app, command line) can use it.

>>> MAPS
('odr', 'ols', 'hybrid', 'e_ols')
>>> MAP_LABELS["e_ols"]
'e_OLS'
>>> issubclass(InputError, ValueError)
True
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import Literal

# ----------------------------------------------------------------------------- errors


class InputError(ValueError):
    """Bad input the user can fix: a file, an option or a value that cannot be used.

    Raised by the science layer (reading, grid, profiles, bias) and by the app and
    command line alike. The command line prints it as one line and exits with
    status 2; the app shows it as a notice. The message names the problem and,
    where there is one, the file.
    """


def error_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type's name when it has none):
    what a one-line error quotes of a library's error.

    >>> error_line(ValueError("bad header\\nat byte 7")), error_line(KeyError())
    ('bad header', 'KeyError')
    """
    line = next((s.strip() for s in str(exc).splitlines() if s.strip()), "")
    return line or type(exc).__name__


#: What reading a file raises that is the file's fault rather than a bug: the OS (a
#: missing or unreadable file), malformed content, a truncated stream.
FILE_ERRORS: tuple[type[Exception], ...] = (OSError, ValueError, EOFError, KeyError, IndexError)


@contextlib.contextmanager
def foreign_errors(what: str, *, libraries: tuple[str, ...] | None = None) -> Iterator[None]:
    """Turn an error raised in the block by reading a file into one :class:`InputError`
    line, ``"<what>: <its first line>"``; an :class:`InputError` passes as it is and a
    :class:`MemoryError` becomes ``"<what>: not enough memory"``. The one converter of
    library errors: every reader uses it.

    Parameters
    ----------
    what : str
        What was being done, naming the file (``"cannot read a.las"``).
    libraries : tuple of str, optional
        None (default): every exception is taken for the library's (pye57 and the
        libraries behind it raise types of their own, with no common base). Else only
        :data:`FILE_ERRORS` and the exceptions of these libraries' modules (by top-level
        name: ``("laspy", "lazrs")``) convert; any other (a ``TypeError`` of ours)
        passes, for a bug is not the file's fault.

    >>> with foreign_errors("cannot read a.las"):
    ...     raise OSError("unexpected end of file")
    Traceback (most recent call last):
    rough_viewer.vocabulary.InputError: cannot read a.las: unexpected end of file
    >>> with foreign_errors("cannot read a.las", libraries=("laspy",)):
    ...     raise TypeError("a bug")
    Traceback (most recent call last):
    TypeError: a bug
    """
    try:
        yield
    except InputError:
        raise
    except MemoryError:
        raise InputError(f"{what}: not enough memory") from None
    except Exception as exc:
        if (libraries is not None and not isinstance(exc, FILE_ERRORS)
                and type(exc).__module__.split(".")[0] not in libraries):
            raise
        raise InputError(f"{what}: {error_line(exc)}") from None


#: ``progress(done, total)``: how the science reports progress without printing.
ProgressFn = Callable[[int, int], None]

# ----------------------------------------------------------------------------- grid roughness

Axis = Literal["x", "y", "z"]
"""A coordinate axis."""
AxisChoice = Literal["auto", "x", "y", "z"]
"""Dependent-axis option: ``auto`` = the axis closest to the whole cloud's ODR normal."""
Model = Literal["odr", "ols", "hybrid"]
"""A roughness model (docs/science.md section 1)."""
MapName = Literal["odr", "ols", "hybrid", "e_ols"]
"""A per-cell map: the three models and the OLS error ``e_ols = |theta_ols - theta_odr|``."""
Residual = Literal["absolute", "signed"]
#: Engine of the grid's point passes: ``numba`` (compiled, optional), ``numpy`` (the
#: reference), ``auto`` (numba when installed).
Engine = Literal["auto", "numpy", "numba"]
"""``absolute``: std of absolute distances (docs/science.md default); ``signed``: RMS of
signed distances."""

BIAS_RESIDUAL: Residual = "signed"
"""Default roughness of the bias toolkit: the bias paper's own definition, the
standard deviation of the SIGNED orthogonal residuals (so its published numbers come
out without a flag). Grid roughness keeps docs/science.md's absolute distances."""
RESIDUAL_NAMES: dict[str, str] = {
    "signed": "std of signed orthogonal distances (the bias paper's definition)",
    "absolute": "std of absolute orthogonal distances (the grid-roughness convention, "
                "docs/science.md section 1)",
}
"""How each residual convention is named in output (text and JSON)."""
#: Trials a scanner-bias prediction averages unless told (``bias predict --trials``
#: and the app's Bias tab).
BIAS_TRIALS = 3

AXES: tuple[Axis, Axis, Axis] = ("x", "y", "z")
AXIS_CHOICES: tuple[AxisChoice, ...] = ("auto", "x", "y", "z")
MODELS: tuple[Model, ...] = ("odr", "ols", "hybrid")
MAPS: tuple[MapName, ...] = ("odr", "ols", "hybrid", "e_ols")
RESIDUALS: tuple[Residual, ...] = ("absolute", "signed")

MAP_LABELS: dict[str, str] = {"odr": "ODR", "ols": "OLS", "hybrid": "hybrid", "e_ols": "e_OLS"}
"""Short display name of each map (tables, legends, axis titles)."""
MAP_TITLES: dict[str, str] = {
    "odr": "ODR",
    "ols": "OLS",
    "hybrid": "hybrid",
    "e_ols": "OLS error e_ols",
}
"""Longer name of each map where there is room (the app's model menu)."""
MAP_COLOURS: dict[str, str] = {
    "odr": "#1f77b4",
    "ols": "#d62728",
    "hybrid": "#2ca02c",
    "e_ols": "#9467bd",
}
"""One line colour per map, shared by every figure."""
MAP_MARKERS: dict[str, str] = {
    "odr": "circle-open",
    "ols": "triangle-up-open",
    "hybrid": "square-open",
    "e_ols": "cross-thin-open",
}
"""Marker symbols of the 2011 paper's Fig. 4: ODR circles, OLS triangles, e_OLS plus."""

DEFAULT_MIN_POINTS = 4
"""Cells with fewer points get no value. Three points fix a plane exactly (roughness
0 by construction, no information), so the default is 4; 3 stays accepted."""
MIN_POINTS_FLOOR = 3
"""The smallest ``min_points`` accepted: a plane needs 3 points."""
DEFAULT_THRESHOLD = 0.05
"""Binary transform threshold on normalised roughness (2011 paper)."""
HISTOGRAM_BIN = 0.05
"""Bin width of normalised-roughness histograms (2011 paper, Fig. 3)."""
PAPER_GRIDS: tuple[float, ...] = (1.0, 0.5, 0.25, 0.125)
"""The 2011 paper's grid sizes, metres."""

# ----------------------------------------------------------------------------- zones

Connectivity = Literal["face", "edge", "vertex"]
"""Which grid cells touch: ``face`` (6 neighbours), ``edge`` (18) or ``vertex`` (26)."""
CONNECTIVITIES: tuple[Connectivity, ...] = ("vertex", "edge", "face")
"""Connectivity options, default first."""
DEFAULT_MIN_CELLS = 3
"""Zones with fewer cells are dropped."""

# ----------------------------------------------------------------------------- scanner trust

TRUST_FIELDS: tuple[str, ...] = (
    "scans", "range", "incidence_deg", "density_ratio", "occlusion",
    "noise_pred", "smoothing_pred", "bias_pred", "trusted",
)
"""Per-cell scanner figures (docs/scanner.md), in the order of the cell table's
columns and of the LAS/PLY fields."""
TRUST_LABELS: dict[str, str] = {
    "scans": "scans seeing the cell",
    "range": "range to the scanner",
    "incidence_deg": "incidence angle (degrees)",
    "density_ratio": "point density / expected",
    "occlusion": "occlusion (points missing)",
    "noise_pred": "predicted noise inflation",
    "smoothing_pred": "predicted beam smoothing",
    "bias_pred": "net predicted bias",
    "trusted": "trusted (papers' limits)",
}
"""Display name of each per-cell scanner figure (colour layers, legends)."""

# ----------------------------------------------------------------------------- colour layers

ColourLayerName = Literal["roughness", "rgb", "intensity", "distance", "scans", "range",
                          "incidence_deg", "density_ratio", "occlusion", "noise_pred",
                          "smoothing_pred", "bias_pred", "trusted"]
"""What colours the points: the roughness map, a layer that shows the rock itself,
or one of the scanner figures of the cells (:data:`TRUST_FIELDS`)."""
COLOUR_LAYERS: tuple[ColourLayerName, ...] = (
    "roughness", "rgb", "intensity", "distance", "scans", "range", "incidence_deg",
    "density_ratio", "occlusion", "noise_pred", "smoothing_pred", "bias_pred", "trusted")
COLOUR_LAYER_LABELS: dict[str, str] = {
    "roughness": "roughness map",
    "rgb": "scan colours (RGB)",
    "intensity": "intensity",
    "distance": "distance to face plane",
    **{name: f"scanner: {label}" for name, label in TRUST_LABELS.items()},
}
"""Display name of each colour layer."""

# ----------------------------------------------------------------------------- units

Unit = Literal["m", "mm", "ft", "us-ft"]
"""A length unit of input coordinates and of what the user sees (``--units``)."""
CrsUnit = Literal["m", "ft", "us-ft"]
"""A linear unit a coordinate reference system can declare."""
UNITS: tuple[Unit, ...] = ("m", "mm", "ft", "us-ft")
UNIT_METRES: dict[str, float] = {"m": 1.0, "mm": 1e-3, "ft": 0.3048, "us-ft": 1200.0 / 3937.0}
"""Metres per unit (the US survey foot is exactly 1200/3937 m)."""
UNIT_LABELS: dict[str, str] = {"m": "m", "mm": "mm", "ft": "ft", "us-ft": "US ft"}
"""How each unit is written after a number."""


def grid_tag(size: float, unit: str = "m") -> str:
    """``g<G>`` naming a grid size in every file name (the app's downloads, the
    report's PNGs, the commands' per-grid outputs): ``size`` in ``unit``, the unit
    written unless metres.

    >>> grid_tag(0.25), grid_tag(2.5, "mm"), grid_tag(1.0, "us-ft")
    ('g0.25', 'g2.5mm', 'g1us-ft')
    """
    return f"g{float(f'{size:.9g}'):g}{'' if unit == 'm' else unit}"
ROUGHNESS_UNIT: dict[str, Unit] = {"m": "mm", "mm": "mm", "ft": "ft", "us-ft": "us-ft"}
"""Unit roughness (a few mm) is shown in, for each coordinate unit: millimetres for
metric input (docs/science.md: the tools may show mm), the input's own unit otherwise."""


def unit_scale(unit: str) -> tuple[float, str]:
    """(metres per unit, label) of a display unit for lengths.

    >>> unit_scale("mm"), unit_scale("ft")
    ((0.001, 'mm'), (0.3048, 'ft'))
    """
    if unit not in UNIT_METRES:
        raise InputError(f"unknown unit {unit!r}; expected one of {', '.join(UNIT_METRES)}")
    return UNIT_METRES[unit], UNIT_LABELS[unit]


def roughness_scale(unit: str) -> tuple[float, str]:
    """(metres per unit, label) roughness is shown in for lengths in ``unit``: mm for
    metric input, the input's own unit otherwise (``ROUGHNESS_UNIT``).

    >>> roughness_scale("m"), roughness_scale("ft")
    ((0.001, 'mm'), (0.3048, 'ft'))
    """
    return unit_scale(ROUGHNESS_UNIT.get(unit, unit))


# ----------------------------------------------------------------------------- profiles

Decomposition = Literal["dwt", "wp"]
"""Wavelet decomposition: discrete wavelet transform or wavelet packets."""
ThresholdRule = Literal["fixed", "penalized-low", "penalized-medium", "penalized-high"]
"""Threshold rule: fixed form, or Birge-Massart penalized with alpha 1.5 / 2 / 5."""
Mode = Literal["hard", "soft"]
"""How a threshold is applied to the detail coefficients."""

DECOMPOSITIONS: tuple[Decomposition, ...] = ("dwt", "wp")
THRESHOLD_RULES: tuple[ThresholdRule, ...] = (
    "fixed",
    "penalized-low",
    "penalized-medium",
    "penalized-high",
)
MODES: tuple[Mode, ...] = ("soft", "hard")

PROFILE_COLOURS: tuple[str, ...] = ("#e63c28", "#1e78e6", "#faa000", "#963cc8", "#14aa5a")
"""Colours of kept profiles, in order (the scene line and its curves share one)."""


def hex_to_rgb(code: str) -> tuple[int, int, int]:
    """``"#rrggbb"`` -> ``(r, g, b)`` in 0..255.

    >>> hex_to_rgb("#e63c28")
    (230, 60, 40)
    """
    code = code.lstrip("#")
    return int(code[0:2], 16), int(code[2:4], 16), int(code[4:6], 16)
