"""Cells whose roughness is an outlier of the definition, not a property of the rock.

Every point of a cell lies in a cube of edge ``g`` (the cell size), so a roughness
measured on that cell cannot honestly exceed ``g``:

- ODR: orthogonal distances to a plane through the points' centroid are at most the
  cube's diagonal ``sqrt(3) g``, and the standard deviation of numbers in ``[0, M]``
  is at most ``M / 2`` (Popoviciu's inequality), so ``theta_odr <= 0.87 g``;
- OLS: the least-squares residuals along the dependent axis are no larger in RMS
  than the spread of that coordinate (a constant is one of the planes OLS could
  fit), and the coordinate spans at most ``g``, so ``theta_ols <= g / 2``;
- hybrid: the ODR distances divided by ``|n_a|``, the dependent-axis component of
  the cell's ODR normal. Where the cell's plane is nearly parallel to the axis
  (a steep part of the face seen along ``a``), ``|n_a| -> 0`` and the value has no
  bound: 65 m in a 0.2 m cell on the demo outcrop, 51.8 m in a 4 m cell of the
  airborne hillslope.

The rule (one function, :func:`exceeds_cell`): a cell whose OLS or hybrid roughness
is larger than the cell size is an **outlier** of that model; ``e_ols`` inherits
OLS's (it is ``|theta_ols - theta_odr|``); ODR has none. By the bounds above only the
hybrid model meets the rule in practice; OLS is checked all the same.

docs/science.md keeps the value: the per-cell arrays, CELLS.csv and the per-point exports
hold it unchanged, and CELLS.csv marks the cell in its ``outlier`` column
(:func:`outlier_flags`). Everything that summarises or compares cells leaves outliers
out unless asked to keep them (``keep_outliers``; ``--keep-outliers`` on the command
line): Table 1 (:func:`rough_viewer.grid.summary.summarise`), the min-max
normalisation, the histograms and the binary transform built on it, the
semivariograms, the zones and the roughness-across-scales trend. Left in, one such
cell sets the maximum, so min-max normalisation puts every other cell into the first
histogram bin.

>>> import numpy as np
>>> exceeds_cell(np.array([0.01, 0.3, np.nan, 0.2]), 0.2)
array([False,  True, False, False])
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rough_viewer.vocabulary import MAP_LABELS, MAPS, InputError, MapName

if TYPE_CHECKING:
    from rough_viewer.grid.roughness import GridRoughness

#: Maps whose cells can be outliers, and the model whose value decides: ``e_ols`` is
#: derived from OLS.
OUTLIER_SOURCE: dict[str, str] = {"ols": "ols", "hybrid": "hybrid", "e_ols": "ols"}

#: Bits of the ``outlier`` column of CELLS.csv: 1 = OLS larger than the cell, 2 =
#: hybrid larger than the cell (3 = both); 0 = neither.
OUTLIER_BITS: dict[str, int] = {"ols": 1, "hybrid": 2}


def exceeds_cell(values: np.ndarray, cell_size: float) -> np.ndarray:
    """The rule: ``values > cell_size`` (roughness and cell edge in one unit, metres
    in the core); NaN is never an outlier."""
    v = np.asarray(values, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return np.isfinite(v) & (v > float(cell_size))


def outlier_mask(result: GridRoughness, name: MapName) -> np.ndarray:
    """(M,) bool: the cells of ``result`` that are outliers of map ``name`` (its
    model's roughness larger than the cell; always False for ODR)."""
    if name not in MAPS:
        raise InputError(f"unknown map {name!r}; expected one of {', '.join(MAPS)}")
    source = OUTLIER_SOURCE.get(name)
    if source is None:
        return np.zeros(result.n_cells, dtype=bool)
    return exceeds_cell(result.values(source), result.grid.cell_size)  # type: ignore[arg-type]


def outlier_flags(result: GridRoughness) -> np.ndarray:
    """(M,) uint8 per cell: the sum of :data:`OUTLIER_BITS` of the models it is an
    outlier of (0 = none): the ``outlier`` column of CELLS.csv."""
    flags = np.zeros(result.n_cells, dtype=np.uint8)
    for model, bit in OUTLIER_BITS.items():
        flags[outlier_mask(result, model)] |= np.uint8(bit)  # type: ignore[arg-type]
    return flags


def analysed_values(result: GridRoughness, name: MapName, *,
                    keep_outliers: bool = False) -> np.ndarray:
    """(M,) the map ``name`` as every summary and comparison uses it, metres: NaN
    where the cell has no value and, unless ``keep_outliers``, where it is an
    outlier (:func:`outlier_mask`). A new array when outliers are removed; the
    result's own array otherwise."""
    v = result.values(name)
    if keep_outliers:
        return v
    out = outlier_mask(result, name)
    if not out.any():
        return v
    v = v.copy()
    v[out] = np.nan
    return v


def outlier_text(result: GridRoughness, name: MapName = "hybrid", *, unit: str = "m",
                 kept: bool = False) -> str | None:
    """The one sentence saying how many cells of map ``name`` are outliers, or None
    when there are none; lengths in ``unit``. The command line, the report and the
    app show it, each adding how to keep or drop them.

    >>> import numpy as np
    >>> from rough_viewer.grid.roughness import grid_roughness
    >>> rng = np.random.default_rng(1)
    >>> xy = rng.uniform(0, 1, (4000, 2))
    >>> wall = np.column_stack([xy[:, 0], 0.5 + 1e-3 * rng.standard_normal(4000), xy[:, 1]])
    >>> res = grid_roughness(wall, 0.5, axis="z")   # a vertical wall seen along z
    >>> outlier_text(res)[:62]
    '4 of 4 cells with a hybrid value have a hybrid roughness large'
    """
    from rough_viewer.vocabulary import UNIT_LABELS, UNIT_METRES

    mask = outlier_mask(result, name)
    n = int(mask.sum())
    if not n:
        return None
    values = result.values(name)
    valued = int(np.count_nonzero(np.isfinite(values)))
    per, u = UNIT_METRES[unit], UNIT_LABELS[unit]
    g = result.grid.cell_size / per
    top = float(np.max(values[mask])) / per
    what = MAP_LABELS[name]
    return (f"{n:,} of {valued:,} cells with a {what} value {'has' if n == 1 else 'have'} a "
            f"{what} roughness larger "
            f"than the cell (up to {top:.4g} {u} in {g:g} {u} cells): "
            f"{'its' if n == 1 else 'their'} plane is nearly parallel to the dependent axis "
            f"{result.axis}, along which {what} measures, so the value says nothing about the "
            "rock; " + ("kept in every statistic, as asked" if kept else
                        "left out of Table 1, the normalisation, histograms, semivariograms "
                        "and zones"))
