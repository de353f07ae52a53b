"""Parsing of option values shared by the commands (one-line errors, exit 2)."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from rough_viewer.vocabulary import AXIS_CHOICES, UNIT_LABELS, UNIT_METRES, UNITS, InputError


def parse_xyz(text: str, *, option: str) -> tuple[float, float, float]:
    """Parse ``"X,Y,Z"`` into three floats, or raise InputError naming the option."""
    parts = [p.strip() for p in text.split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(v == v and abs(v) != float("inf") for v in values):
        raise InputError(f"{option} expects three finite numbers X,Y,Z, got {text!r}")
    return values[0], values[1], values[2]


@contextmanager
def naming(what: object) -> Iterator[None]:
    """Add ``what`` (a file, usually) to the message of an InputError raised inside,
    unless the message names it already, so every error says where it came from."""
    try:
        yield
    except InputError as exc:
        text = str(exc)
        if str(what) in text:
            raise
        raise InputError(f"{text} ({what})") from None


def positive(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def non_negative(text: str) -> float:
    """argparse type: a finite number >= 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return v


def _whole_number(text: str, lowest: int) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < lowest:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {lowest}, got {text!r}")
    return v


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    return _whole_number(text, 1)


def non_negative_int(text: str) -> int:
    """argparse type: a whole number >= 0 (seeds)."""
    return _whole_number(text, 0)


def list_of(kind: Callable[[str], float]) -> Callable[[str], list[float]]:
    """argparse type: comma-separated values, each parsed by ``kind``."""
    def parse(text: str) -> list[float]:
        return [kind(p.strip()) for p in text.split(",") if p.strip()] or [kind("")]
    return parse


def add_windows(p: argparse.ArgumentParser) -> None:
    """``--windows W1,W2,...|default|paper``: the roughness-length windows, lengths in
    ``--units`` or a rule (parsed by :func:`window_lengths`)."""
    p.add_argument("--windows", metavar="W1,W2,...", default=None,
                   help="roughness-length window lengths in --units, separated by commas, or "
                   "'default' (8 evenly in log from 3 %% to 30 %% of the profile) or 'paper' "
                   "(8 from 3 %% to 10 %%, as Khoshelham & Altundag)")


def window_lengths(text: str | None, unit: str) -> tuple[float, ...] | str | None:
    """``--windows`` as the profile code takes it: lengths in metres, a rule name, or
    None (:func:`rough_viewer.profiles.fractal.parse_windows`; an error names the
    option)."""
    from rough_viewer.profiles.fractal import parse_windows

    if text is None:
        return None
    try:
        got = parse_windows(text, UNIT_METRES[unit])
    except InputError as exc:
        raise InputError(f"--{exc}") from None
    return got if got is None or isinstance(got, str) else tuple(float(w) for w in got)


def segments(text: str) -> int | tuple[int, int]:
    """argparse type: a segment count (``8``) or rows x cols (``4x2``)."""
    t = text.lower().strip()
    try:
        if "x" in t:
            r, c = (int(p) for p in t.split("x"))
            if r >= 1 and c >= 1:
                return (r, c)
        else:
            n = int(t)
            if n >= 1:
                return n
    except ValueError:
        pass
    raise argparse.ArgumentTypeError(f"expected a count (8) or rows x cols (4x2), got {text!r}")


def add_axis(p: argparse.ArgumentParser, *, help: str | None = None) -> None:
    """``--axis auto|x|y|z``: the dependent axis of OLS and hybrid (default auto)."""
    p.add_argument("--axis", choices=AXIS_CHOICES, default="auto",
                   help=help or "dependent axis of OLS and hybrid (default: auto = closest to "
                   "the whole cloud's normal)")


def add_keep_outliers(p: argparse.ArgumentParser) -> None:
    """``--keep-outliers``: keep cells whose OLS or hybrid roughness is larger than the
    cell in Table 1, the normalisation, histograms, semivariograms and zones
    (:mod:`rough_viewer.grid.outliers`; left out by default)."""
    p.add_argument("--keep-outliers", action="store_true",
                   help="keep cells whose OLS or hybrid roughness is larger than the cell "
                   "(outliers of the definition: a plane nearly parallel to the dependent "
                   "axis) in Table 1, normalisation, histograms, semivariograms and zones; "
                   "by default they are left out and counted (docs/science.md)")


def add_units(p: argparse.ArgumentParser) -> None:
    """``--units m|mm|ft|us-ft``: the unit of the input's coordinates and of every
    length given or shown (grid sizes, origins, points, roughness)."""
    p.add_argument("--units", choices=UNITS, default=None,
                   help="unit of the input's coordinates and of every length on the command "
                   "line and in the output (default: the unit of a LAS file's CRS, else m)")


def warn(lines: tuple[str, ...] | list[str]) -> None:
    """Print warnings from the science (one line each) on stderr."""
    for line in lines:
        print(f"rough-viewer: warning: {line}", file=sys.stderr)


def per_unit(unit: str) -> float:
    """Metres per ``unit``."""
    return UNIT_METRES[unit]


def grid_sizes(values: list[float], unit: str) -> list[float]:
    """The distinct ``--grid`` values in the order given, in ``unit``; each must be a
    finite positive length (else one line naming the unit)."""
    grids = list(dict.fromkeys(values))
    for g in grids:
        if not (math.isfinite(g) and g > 0):
            raise InputError(f"--grid must be a positive length in {UNIT_LABELS[unit]}, "
                             f"got {g:g}")
    return grids


@contextmanager
def at_grid(g: float, unit: str) -> Iterator[None]:
    """Name ``--grid G UNIT`` (as the user gave it) in an InputError raised inside,
    unless the message shows that size already (the science speaks in metres)."""
    shown = f"{g:g} {UNIT_LABELS[unit]}"
    try:
        yield
    except InputError as exc:
        text = str(exc)
        if shown in text:
            raise
        raise InputError(f"--grid {shown}: {text}") from None


def output_name(path: str | Path, grid: float, several: bool, unit: str = "m") -> Path:
    """Output path for one grid size: ``name_g<G>.ext`` when there are several
    (``cells.csv`` -> ``cells_g0.5.csv``, ``cells_g2.5mm.csv``: G as given, in the run's
    unit, named as everywhere: :func:`rough_viewer.vocabulary.grid_tag`)."""
    from rough_viewer.vocabulary import grid_tag

    p = Path(path)
    if not several:
        return p
    return p.with_name(f"{p.stem}_{grid_tag(grid, unit)}{p.suffix}")
