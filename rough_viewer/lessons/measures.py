"""The numbers a lesson's questions ask for, computed from the tool's own results
(the grid result of the map shown and the clicked point's roughness across the
preset grids), and the check of a student's answer against them.

Pure functions on the science's results: no app, no viser.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.scales import PointScales
from rough_viewer.grid.variogram import semivariogram
from rough_viewer.lessons import Question
from rough_viewer.vocabulary import InputError


@dataclass(frozen=True)
class Expected:
    """The number a question's answer is checked against."""

    value: float
    """In :attr:`unit` (the cloud's roughness unit for a roughness; 1 for a ratio)."""
    unit: str
    """``mm`` (or the cloud's roughness unit), or "" for a ratio or a count."""


def _finite(v: np.ndarray, what: str) -> np.ndarray:
    out = v[np.isfinite(v)]
    if out.size == 0:
        raise InputError(f"no cell of the map shown has {what}")
    return out


def raw_value(question: Question, result: GridRoughness, *, keep_outliers: bool = False,
              scales: PointScales | None = None) -> float:
    """The number ``question`` asks for, in metres for a roughness (else plain).

    Parameters
    ----------
    result
        The grid result of the map shown.
    keep_outliers
        The map's setting: cells larger than the cell take part (Table 1's rule,
        :func:`rough_viewer.grid.outliers.analysed_values`).
    scales
        The clicked point's roughness across the presets (``point``; None: no click).

    Raises
    ------
    InputError
        When the map shown cannot answer (no click yet, no cell with a value).
    """
    q, m = question, question.model
    if q.measure == "points":
        return float(result.n_points_total)
    if q.measure in ("mean", "median"):
        v = _finite(analysed_values(result, m, keep_outliers=keep_outliers), f"a {m} value")
        return float(np.mean(v) if q.measure == "mean" else np.median(v))
    if q.measure == "ratio":
        a = analysed_values(result, q.of[0], keep_outliers=keep_outliers)
        b = analysed_values(result, q.of[1], keep_outliers=keep_outliers)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(b > 0, a / b, np.nan)
        return float(np.median(_finite(r, f"both {q.of[0]} and {q.of[1]}")))
    if q.measure == "point":
        if scales is None:
            raise InputError("click a point on the cloud first: the question is about its cell")
        series = scales.values(m)
        value = float(series[-1] if q.grid == "coarsest" else series[0])
        if not np.isfinite(value):
            raise InputError(f"the clicked point's cell has no {m} value on the {q.grid} grid")
        return value
    return first_lag(result, m, keep_outliers=keep_outliers)


def first_lag(result: GridRoughness, model: str, *, keep_outliers: bool = False) -> float:
    """The normalised semivariance (gamma / variance) of ``model``'s map at the first
    lag, one cell size (the Panels tab's semivariogram, 3-D cell lags)."""
    values = analysed_values(result, model, keep_outliers=keep_outliers)  # type: ignore[arg-type]
    g = result.grid.cell_size
    vg = semivariogram(result.ijk, values, g, max_lag=g)
    if vg.gamma_normalised.size == 0 or not np.isfinite(vg.gamma_normalised[0]):
        raise InputError("the map shown has no pair of neighbouring cells with a value")
    return float(vg.gamma_normalised[0])


def expected_value(question: Question, result: GridRoughness, *, rough_per: float = 1e-3,
                   rough_unit: str = "mm", keep_outliers: bool = False,
                   scales: PointScales | None = None) -> Expected:
    """:func:`raw_value` in the unit the student reads: a roughness in the cloud's
    roughness unit (``rough_per`` metres each, mm for metric clouds)."""
    raw = raw_value(question, result, keep_outliers=keep_outliers, scales=scales)
    if question.dimensionless:
        return Expected(raw, "")
    return Expected(raw / rough_per, rough_unit)


def accepted(given: float, expected: float, question: Question) -> bool:
    """True when ``given`` is within the question's tolerance of ``expected``: the
    larger of ``tolerance`` times ``|expected|`` and ``absolute``.

    >>> q = Question("?", "mean", tolerance=0.05)
    >>> accepted(3.7, 3.6, q), accepted(4.0, 3.6, q)
    (True, False)
    """
    if not (np.isfinite(given) and np.isfinite(expected)):
        return False
    return abs(given - expected) <= max(question.tolerance * abs(expected), question.absolute)
