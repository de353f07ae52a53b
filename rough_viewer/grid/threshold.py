"""Is the binary threshold sensible for this face? The share it flags, and the data's
own suggestion beside the 2011 paper's 0.05.

The binary transform (2011 paper, Fig. 2) flags cells whose min-max normalised
roughness is at least a threshold, 0.05 in the paper. Normalised roughness is
relative to the map's own range, so what 0.05 means depends on the face: on the
airborne hillslope it flags 92 % of the cells at every grid size, where the paper's
basalt face gave a minority of fracture and rubble cells. A threshold that flags
most of the face is not telling rough from smooth.

Suggestion: **Otsu's method on the logarithm of the roughness** (Otsu 1979, IEEE
Trans. Systems, Man and Cybernetics 9(1), 62-66): the split of the cells into two
classes that maximises the between-class variance ``w0 w1 (mu0 - mu1)^2`` of
``log10 theta``, taken exactly over the sorted values (every distinct value a
level, no histogram bins to choose), the values first clipped to their 2nd and 98th
percentiles (the colour stretch's robust range) so that a few cells of near
round-off roughness, decades below the rest in log, cannot make a class of their own
(a lab mesh's flat facets did: a suggestion of 5e-6 mm). Why this rule:

- roughness is a positive scale quantity spread over two to three decades and
  skewed (the colour maps use a log stretch for the same reason), so a split in
  ``log theta`` weighs a 1 mm / 2 mm difference like a 10 mm / 20 mm one;
- it needs no parameter, is deterministic, and for a face of smooth rock with
  fracture and rubble zones (two populations) it finds the valley between them;
- its separability ``eta = sigma_B^2 / sigma_T^2`` (Otsu's own measure) says how
  well two classes describe the values: 1 for two distinct values, ``2 / pi = 0.64``
  for a single normal population, 0.75 for a uniform one, 0.74 and 0.85 for a
  mixture of 80 % and 20 % normal populations 4 and 6 standard deviations apart.
  Below :data:`CLEAR_SEPARATION` the values show no clear gap and the suggestion
  only divides their spread; the text says so.

A knee of the histogram was the other candidate; it depends on the bin width and
on the histogram's tail, which is exactly where the outliers were.

Cells of roughness 0 to round-off (exact fits,
:data:`rough_viewer.grid.roughness.EXACT_FIT`; 1e-17 m has a logarithm, and would
be split off as a population of its own) take no part in the split; they are below
any threshold.
The suggestion is returned both as a roughness (metres) and on the normalised
scale of the same map (its min-max over the cells given), so it can be used as the
``threshold`` of the binary transform and of the zones.

>>> import numpy as np
>>> values = np.r_[np.full(80, 0.001), np.full(20, 0.02)]     # smooth rock + a zone
>>> advice = threshold_advice(values, 0.05)
>>> round(advice.share, 2), round(advice.suggested, 3), round(advice.suggested_share, 2)
(0.2, 0.183, 0.2)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rough_viewer.vocabulary import DEFAULT_THRESHOLD, InputError, MapName, roughness_scale

if TYPE_CHECKING:
    from rough_viewer.grid.roughness import GridRoughness

#: A threshold flagging more than this share of the cells flags "most of the face".
MOST_SHARE = 0.5
#: Otsu separability at or above which the two classes are called distinct (a single
#: normal population gives 2 / pi = 0.64 at its best split, a uniform one 0.75).
CLEAR_SEPARATION = 0.8
#: Percentiles of log10 theta the split's values are clipped to (robust to tails).
CLIP_PERCENTILES = (2.0, 98.0)
#: Name of the rule, as the text and the JSON give it.
RULE = "Otsu's method on log10 roughness"


@dataclass(frozen=True)
class OtsuSplit:
    """The best two-class split of a set of values by Otsu's method."""

    threshold: float
    """Split value in the values' own scale: midway (in the scale the split was
    made in) between the largest value of the lower class and the smallest of the
    upper one."""
    separability: float
    """``sigma_B^2 / sigma_T^2`` at the split, in [0, 1]."""
    lower: int
    """Values below the split."""
    upper: int
    """Values above it."""


def otsu_split(values: np.ndarray) -> OtsuSplit | None:
    """Otsu's two-class split of ``values`` (finite values only; NaN ignored), exact
    over the sorted values; None when fewer than two distinct values remain.

    >>> s = otsu_split(np.array([1.0, 1.1, 0.9, 5.0, 5.2, 4.8]))
    >>> s.threshold, s.lower, s.upper
    (2.95, 3, 3)
    """
    v = np.sort(np.asarray(values, dtype=np.float64).ravel())
    v = v[np.isfinite(v)]
    n = v.size
    if n < 2 or v[0] == v[-1]:
        return None
    # centred first: cumulative sums of large values lose nothing
    c = v - v.mean()
    k = np.arange(1, n, dtype=np.float64)          # size of the lower class
    s0 = np.cumsum(c)[:-1]                         # its sum
    total = float(c.sum())
    mu0 = s0 / k
    mu1 = (total - s0) / (n - k)
    between = (k / n) * (1.0 - k / n) * (mu0 - mu1) ** 2
    between[v[1:] <= v[:-1]] = -1.0                # a split between equal values is none
    best = int(np.argmax(between))
    var = float(np.mean(c * c))
    return OtsuSplit(threshold=0.5 * (float(v[best]) + float(v[best + 1])),
                     separability=float(between[best]) / var if var > 0 else 0.0,
                     lower=best + 1, upper=n - best - 1)


@dataclass(frozen=True)
class ThresholdAdvice:
    """What a binary threshold does on one map, and the data's own threshold."""

    threshold: float
    """The threshold in use, normalised roughness in [0, 1]."""
    cells: int
    """Cells with a value (the ones the transform classifies)."""
    share: float
    """Share of them at or above ``threshold`` (NaN when no cell has a value)."""
    suggested: float | None
    """The suggestion on the normalised scale of the same map, in [0, 1]; None when
    the values do not split (fewer than two distinct positive values)."""
    suggested_theta: float | None
    """The suggestion as a roughness, metres."""
    suggested_share: float | None
    """Share of the cells at or above the suggestion."""
    separability: float | None
    """Otsu's ``sigma_B^2 / sigma_T^2`` of ``log10 theta`` at the suggestion."""
    rule: str = RULE
    """How the suggestion was found."""

    @property
    def most(self) -> bool:
        """The threshold flags more than :data:`MOST_SHARE` of the cells."""
        return self.cells > 0 and self.share > MOST_SHARE

    @property
    def clear(self) -> bool:
        """The values fall in two distinct classes (separability at least
        :data:`CLEAR_SEPARATION`)."""
        return self.separability is not None and self.separability >= CLEAR_SEPARATION

    def text(self, unit: str = "m") -> str:
        """One line for the terminal, the report and the app: the share flagged,
        whether that is most of the face, and the suggestion with its share;
        roughness in the roughness unit of ``unit`` (mm for metric input)."""
        if not self.cells:
            return f"threshold {self.threshold:g}: no cell has a value"
        line = (f"threshold {self.threshold:g} flags {100 * self.share:.0f} % of the "
                f"{self.cells:,} cells with a value")
        if self.most:
            line += ": most of the face reads as rough"
        if self.suggested is None or self.suggested_theta is None \
                or self.suggested_share is None:
            return line + "; the values do not split into two classes, no suggestion"
        per, u = roughness_scale(unit)
        line += (f"; the data suggest {self.suggested:.3g} (θ ≥ {self.suggested_theta / per:.3g}"
                 f" {u}, {self.rule}), which flags {100 * self.suggested_share:.0f} %")
        if not self.clear:
            line += " (no clear gap between smooth and rough: the suggestion splits the spread)"
        return line

    def as_dict(self) -> dict[str, object]:
        """Plain numbers for JSON (metres)."""
        return {"threshold": self.threshold, "cells": self.cells, "share": self.share,
                "most": self.most, "suggested": self.suggested,
                "suggested_theta_m": self.suggested_theta,
                "suggested_share": self.suggested_share,
                "separability": self.separability, "rule": self.rule}


def map_threshold_advice(result: GridRoughness, name: MapName,
                         threshold: float = DEFAULT_THRESHOLD, *,
                         keep_outliers: bool = False) -> ThresholdAdvice:
    """:func:`threshold_advice` of one map of a grid result, as the binary transform
    and the zones see it: outliers left out unless ``keep_outliers``
    (:func:`rough_viewer.grid.outliers.analysed_values`), exact fits
    (:data:`~rough_viewer.grid.roughness.EXACT_FIT` times the cell size) out of the
    split. What the command line, the report and the app's map and zones panels call."""
    from rough_viewer.grid.outliers import analysed_values
    from rough_viewer.grid.roughness import EXACT_FIT

    return threshold_advice(analysed_values(result, name, keep_outliers=keep_outliers),
                            threshold, exact_fit=EXACT_FIT * result.grid.cell_size)


def threshold_advice(values: np.ndarray, threshold: float = DEFAULT_THRESHOLD, *,
                     exact_fit: float | None = None) -> ThresholdAdvice:
    """The share of cells ``threshold`` flags on a map and the suggested threshold.

    Parameters
    ----------
    values : (M,) array
        The map's roughness per cell, metres, NaN where none; pass the values the
        binary transform normalises (outliers already left out:
        :func:`rough_viewer.grid.outliers.analysed_values`).
    threshold : float
        Threshold on min-max normalised roughness, in [0, 1].
    exact_fit : float, optional
        Values at or below it (cells that fit their plane exactly, roughness 0 to
        round-off: 1e-17 m has a logarithm, but not one of rock) take no part in the
        split; default 1e-9 times the largest value.

    Returns
    -------
    ThresholdAdvice
    """
    if not (math.isfinite(threshold) and 0.0 <= threshold <= 1.0):
        raise InputError(f"threshold must lie in [0, 1], got {threshold:g}")
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return ThresholdAdvice(float(threshold), 0, float("nan"), None, None, None, None)
    lo, hi = float(v.min()), float(v.max())
    span = hi - lo
    norm = (v - lo) / span if span > 0 else np.zeros_like(v)
    share = float(np.mean(norm >= threshold))
    floor = 1e-9 * hi if exact_fit is None else float(exact_fit)
    positive = v[v > max(floor, 0.0)]
    split = None
    if positive.size:
        logs = np.log10(positive)
        # the tails clipped to the 2nd and 98th percentiles (the colour stretch's robust
        # range): a few cells of near-round-off roughness (mesh facets, repeated points)
        # are decades away in log and would otherwise make a class of their own
        low, high = np.percentile(logs, CLIP_PERCENTILES)
        split = otsu_split(np.clip(logs, low, high))
    if split is None or span <= 0:
        return ThresholdAdvice(float(threshold), int(v.size), share, None, None, None, None)
    theta = 10.0 ** split.threshold
    suggested = float(np.clip((theta - lo) / span, 0.0, 1.0))
    return ThresholdAdvice(
        threshold=float(threshold), cells=int(v.size), share=share, suggested=suggested,
        suggested_theta=float(theta), suggested_share=float(np.mean(norm >= suggested)),
        separability=split.separability)


@dataclass(frozen=True)
class ZoneThreshold:
    """The threshold zones use when none is chosen, and why (:func:`zone_threshold`)."""

    value: float
    """Threshold on normalised roughness, in [0, 1]."""
    paper: ThresholdAdvice
    """What the paper's :data:`~rough_viewer.vocabulary.DEFAULT_THRESHOLD` does on
    the map (its share, the data's own threshold)."""

    @property
    def own(self) -> bool:
        """The data's own threshold is used: the paper's flags most of the face."""
        return self.value != self.paper.threshold

    def reason(self) -> str:
        """Why the data's own threshold is used (empty when it is not)."""
        p = self.paper
        if not self.own or p.suggested_share is None:
            return ""
        return (f"threshold {self.value:.3g}, the data's own (Otsu's split, flags "
                f"{100 * p.suggested_share:.0f} % of the cells): the paper's "
                f"{p.threshold:g} flags {100 * p.share:.0f} %, most of the face")


def zone_threshold(result: GridRoughness, name: MapName, *,
                   keep_outliers: bool = False) -> ZoneThreshold:
    """The threshold the zones of a map use when none is chosen: the paper's
    :data:`~rough_viewer.vocabulary.DEFAULT_THRESHOLD` unless it flags more than
    :data:`MOST_SHARE` of the cells (one zone over the whole face on every real scan),
    then the data's own (:func:`map_threshold_advice`'s suggestion, 3 significant
    digits). The one rule of ``rough-viewer zones`` and the app's Zones tab."""
    advice = map_threshold_advice(result, name, DEFAULT_THRESHOLD, keep_outliers=keep_outliers)
    if not advice.most or advice.suggested is None or advice.suggested_share is None:
        return ZoneThreshold(DEFAULT_THRESHOLD, advice)
    own = float(f"{advice.suggested:.3g}")
    return ZoneThreshold(DEFAULT_THRESHOLD if own == DEFAULT_THRESHOLD else own, advice)
