"""Statistics of per-cell maps: the 2011 paper's Table 1, min-max normalisation,
the binary transform and histograms of normalised roughness.

>>> import numpy as np
>>> normalise(np.array([1.0, 2.0, 3.0, np.nan]))
array([0. , 0.5, 1. , nan])
>>> binary(np.array([0.0, 0.05, 0.5, np.nan]), 0.05)
array([False,  True,  True, False])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.vocabulary import DEFAULT_THRESHOLD, HISTOGRAM_BIN, MAPS, InputError, MapName


@dataclass(frozen=True)
class Summary:
    """The 2011 paper's Table 1 for one map: population statistics over its cells."""

    cells: int
    """Number of cells with a value."""
    mean_points: float
    """Mean number of points per such cell."""
    min: float
    """Smallest value, metres."""
    max: float
    """Largest value, metres."""
    mean: float
    """Mean, metres."""
    variance: float
    """Population variance (divide by the number of cells), square metres."""
    std: float
    """Population standard deviation, metres."""
    outliers: int = 0
    """Cells with a value left out as outliers of the definition (larger than the
    cell, :mod:`rough_viewer.grid.outliers`); 0 when they were kept."""

    def as_dict(self) -> dict[str, float | int]:
        """Plain dict, for JSON."""
        return {
            "cells": self.cells,
            "mean_points": self.mean_points,
            "min": self.min,
            "max": self.max,
            "mean": self.mean,
            "variance": self.variance,
            "std": self.std,
            "outliers": self.outliers,
        }


def summarise(result: GridRoughness, name: MapName, *, keep_outliers: bool = False) -> Summary:
    """Table-1 summary of one map of ``result`` (NaN statistics when no cell has a
    value); cells larger than the cell are left out unless ``keep_outliers``
    (:func:`rough_viewer.grid.outliers.analysed_values`) and counted in
    ``Summary.outliers``."""
    v = analysed_values(result, name, keep_outliers=keep_outliers)
    ok = np.isfinite(v)
    left_out = int(np.count_nonzero(np.isfinite(result.values(name)))) - int(ok.sum())
    vals = v[ok]
    if vals.size == 0:
        return Summary(0, float("nan"), *(float("nan"),) * 5, outliers=left_out)
    mean = float(vals.mean())
    var = float(np.mean((vals - mean) ** 2))
    return Summary(
        cells=int(vals.size),
        mean_points=float(result.n_points[ok].mean()),
        min=float(vals.min()),
        max=float(vals.max()),
        mean=mean,
        variance=var,
        std=float(np.sqrt(var)),
        outliers=left_out,
    )


def normalise(values: np.ndarray) -> np.ndarray:
    """Min-max normalisation over the finite values: ``(v - min) / (max - min)``.

    NaN stays NaN; if all finite values are equal they map to 0.
    """
    v = np.asarray(values, dtype=np.float64)
    ok = np.isfinite(v)
    out = np.full(v.shape, np.nan)
    if not ok.any():
        return out
    lo = v[ok].min()
    span = v[ok].max() - lo
    out[ok] = (v[ok] - lo) / span if span > 0 else 0.0
    return out


def binary(normalised: np.ndarray, threshold: float = DEFAULT_THRESHOLD) -> np.ndarray:
    """Binary transform: ``normalised >= threshold`` (NaN -> False)."""
    v = np.asarray(normalised, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return np.isfinite(v) & (v >= threshold)


@dataclass(frozen=True)
class Histogram:
    """Histogram of normalised roughness on [0, 1]."""

    edges: np.ndarray
    """(K + 1,) bin edges (the last bin includes 1)."""
    counts: np.ndarray
    """(K,) cells per bin."""
    fractions: np.ndarray
    """(K,) share of cells per bin (sums to 1 when any cell has a value)."""


def histogram(normalised: np.ndarray, bin_width: float = HISTOGRAM_BIN) -> Histogram:
    """Histogram of normalised values in bins of ``bin_width`` on [0, 1].

    Examples
    --------
    >>> import numpy as np
    >>> h = histogram(np.array([0.0, 0.01, 0.2, 1.0, np.nan]))
    >>> h.counts[:5], float(h.fractions[0])
    (array([2, 0, 0, 0, 1]), 0.5)
    """
    k = int(round(1.0 / bin_width))
    if k < 1 or abs(k * bin_width - 1.0) > 1e-9:
        raise InputError(f"bin width must divide 1, got {bin_width}")
    v = np.asarray(normalised, dtype=np.float64)
    v = v[np.isfinite(v)]
    edges = np.linspace(0.0, 1.0, k + 1)
    # Bin membership is decided against the edges (last bin closed), as np.histogram does.
    counts, _ = np.histogram(v, bins=edges)
    total = counts.sum()
    fractions = counts / total if total else np.zeros(k)
    return Histogram(edges=edges, counts=counts, fractions=fractions)


def summaries(result: GridRoughness, *, keep_outliers: bool = False) -> dict[MapName, Summary]:
    """Table-1 summary of every map (odr, ols, hybrid, e_ols) of a result (outliers
    left out unless ``keep_outliers``, as :func:`summarise`)."""
    return {name: summarise(result, name, keep_outliers=keep_outliers) for name in MAPS}
