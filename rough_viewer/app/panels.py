"""Data for the analysis panels, built with the shared figure builders.

The histogram, semivariogram and summary table shown in the app are the report's
figures (:mod:`rough_viewer.visual.grid`) fed with core results
(:func:`rough_viewer.grid.summary.histogram`, :func:`summarise`,
:func:`rough_viewer.grid.variogram.semivariogram`); nothing is recomputed here. The
whole-face trend against grid size is :func:`rough_viewer.grid.scales.face_scales`
drawn by :func:`rough_viewer.visual.scales.face_scales_figure`.
The panels job (:class:`rough_viewer.app.jobs.PanelsJob`) builds them in two
stages: :func:`distribution_figures` (fast), then :func:`variogram_figure_of`
(can take seconds, or be refused for memory, on fine grids).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import plotly.graph_objects as go

from rough_viewer.app.state import ViewSettings
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.scales import face_scales
from rough_viewer.grid.summary import histogram, normalise, summarise
from rough_viewer.grid.variogram import Semivariogram, semivariogram
from rough_viewer.visual.grid import histogram_figure, summary_table_figure, variogram_figure
from rough_viewer.visual.scales import face_scales_figure
from rough_viewer.vocabulary import HISTOGRAM_BIN, MAPS, MapName, ProgressFn


@dataclass(frozen=True)
class Distribution:
    """The histogram and Table 1 summary figures of one grid result and model."""

    histogram: go.Figure
    summary: go.Figure


def histogram_maps(model: MapName) -> tuple[MapName, ...]:
    """Maps in the histogram: ODR and OLS (2011 Fig. 3), plus the current one."""
    base: tuple[MapName, ...] = ("odr", "ols")
    return base + (() if model in base else (model,))


def variogram_maps(model: MapName) -> tuple[MapName, ...]:
    """Maps in the semivariogram: the current one, ODR, OLS and e_ols (2011 Fig. 4)."""
    others: tuple[MapName, ...] = ("odr", "ols", "e_ols")
    return (model,) + tuple(m for m in others if m != model)


def _figure_kw(result: GridRoughness, unit: str = "m") -> dict[str, Any]:
    return dict(grid_size=result.grid.cell_size, axis=result.axis,
                n_points=result.n_points_total, unit=unit)


def distribution_figures(result: GridRoughness, settings: ViewSettings, *,
                         unit: str = "m") -> Distribution:
    """Histogram of normalised roughness (0.05 bins) and the summary table (Table 1),
    lengths in ``unit`` (the cloud's), roughness in its roughness unit."""
    kw = _figure_kw(result, unit)
    hist = histogram_figure({m: histogram(normalise(result.values(m)), HISTOGRAM_BIN)
                             for m in histogram_maps(settings.model)}, **kw)
    summary = summary_table_figure({m: summarise(result, m) for m in MAPS}, **kw)
    return Distribution(hist, summary)


def variograms(
    result: GridRoughness,
    maps: tuple[MapName, ...],
    *,
    is_stale: Callable[[], bool] = lambda: False,
    progress: ProgressFn | None = None,
) -> dict[str, Semivariogram] | None:
    """Semivariogram of each map of ``result`` (3-D cell lags, bin width = cell size),
    or None if ``is_stale()`` turned True between maps (fine grids take seconds).
    ``progress`` is passed to each :func:`~rough_viewer.grid.variogram.semivariogram`
    (called between its blocks; an exception from it stops the computation inside a
    map). Raises InputError when a semivariogram cannot fit in memory."""
    g = result.grid.cell_size
    out: dict[str, Semivariogram] = {}
    for m in maps:
        if is_stale():
            return None
        out[m] = semivariogram(result.ijk, result.values(m), g, progress=progress)
    return out


def variogram_figure_of(
    result: GridRoughness,
    settings: ViewSettings,
    *,
    is_stale: Callable[[], bool] = lambda: False,
    progress: ProgressFn | None = None,
    unit: str = "m",
) -> go.Figure | None:
    """The semivariogram panel, or None if ``is_stale()`` turned True on the way."""
    vgs = variograms(result, variogram_maps(settings.model), is_stale=is_stale,
                     progress=progress)
    return None if vgs is None else variogram_figure(vgs, **_figure_kw(result, unit))


def face_scales_figure_of(results: Sequence[GridRoughness], *, threshold: float,
                          unit: str = "m") -> go.Figure:
    """The whole face against grid size (2011 Table 1 as a picture): mean roughness
    and the share of binary cells of ODR, OLS and hybrid on each grid of ``results``
    (the presets: nested, one axis and minimum points)."""
    return face_scales_figure(face_scales(results, threshold=threshold), unit=unit)
