"""Data for the analysis panels, built with the shared figure builders.

The histogram, semivariogram and summary table shown in the app are the report's
figures (:mod:`rough_viewer.visual.grid`) fed with core results
(:func:`rough_viewer.grid.roughness.histogram`, :func:`summarise`,
:func:`rough_viewer.grid.variogram.semivariogram`); nothing is recomputed here.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import plotly.graph_objects as go

from rough_viewer.app.state import ViewSettings
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.summary import histogram, normalise, summarise
from rough_viewer.grid.variogram import Semivariogram, semivariogram
from rough_viewer.visual.grid import histogram_figure, summary_table_figure, variogram_figure

ALL_MAPS = ("odr", "ols", "hybrid", "e_ols")


@dataclass(frozen=True)
class Panels:
    """The three panel figures for one grid result and model."""

    histogram: go.Figure
    variogram: go.Figure | None
    summary: go.Figure
    histogram_maps: tuple[str, ...]
    variogram_maps: tuple[str, ...]


def histogram_maps(model: str) -> tuple[str, ...]:
    """Maps in the histogram: ODR and OLS (2011 Fig. 3), plus the current one."""
    return ("odr", "ols") + (() if model in ("odr", "ols") else (model,))


def variogram_maps(model: str) -> tuple[str, ...]:
    """Maps in the semivariogram: the current one, ODR, OLS and e_ols (2011 Fig. 4)."""
    return (model,) + tuple(m for m in ("odr", "ols", "e_ols") if m != model)


def variograms(
    result: GridRoughness,
    maps: tuple[str, ...],
    *,
    is_stale: Callable[[], bool] = lambda: False,
) -> dict[str, Semivariogram] | None:
    """Semivariogram of each map of ``result`` (3-D cell lags, bin width = cell size),
    or None if ``is_stale()`` turned True between maps (fine grids take seconds)."""
    g = result.grid.cell_size
    out = {}
    for m in maps:
        if is_stale():
            return None
        out[m] = semivariogram(result.ijk, result.values(m), g)
    return out


def build_panels(
    result: GridRoughness,
    settings: ViewSettings,
    *,
    variogram: bool = True,
    is_stale: Callable[[], bool] = lambda: False,
) -> Panels | None:
    """Figures for the panels, or None if ``is_stale()`` turned True on the way."""
    kw = dict(grid_size=result.grid.cell_size, axis=result.axis,
              n_points=result.n_points_total)
    h_maps = histogram_maps(settings.model)
    hist = histogram_figure(
        {m: histogram(normalise(result.values(m)), 0.05) for m in h_maps}, **kw
    )
    summary = summary_table_figure({m: summarise(result, m) for m in ALL_MAPS}, **kw)
    if is_stale():
        return None
    v_maps = variogram_maps(settings.model) if variogram else ()
    vfig = None
    if variogram:
        vgs = variograms(result, v_maps, is_stale=is_stale)
        if vgs is None:
            return None
        vfig = variogram_figure(vgs, **kw)
    return Panels(hist, vfig, summary, h_maps, v_maps)
