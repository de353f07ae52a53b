"""Figures of roughness across scales (:mod:`rough_viewer.grid.scales`).

- :func:`point_scales_figure`: the small per-point plot the app shows on a click:
  ODR, OLS and hybrid roughness of the cells holding the point, one value per grid
  size.
- :func:`face_scales_figure`: the whole-face trend (the 2011 paper's Table 1 as a
  picture): mean roughness and the share of binary (rough) cells against grid size.

Grid size runs along a log axis ticked at the grid sizes themselves; roughness is
in millimetres. Model names, colours and markers come from
:mod:`rough_viewer.vocabulary`, so they match every other figure.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from rough_viewer.grid.scales import FaceScales, PointScales
from rough_viewer.visual.grid import label, title_block, title_height
from rough_viewer.vocabulary import (
    MAP_COLOURS,
    MAP_MARKERS,
    MODELS,
    InputError,
    MapName,
    roughness_scale,
    unit_scale,
)


def _grid_axis(sizes: np.ndarray, per: float = 1.0, label_: str = "m") -> dict[str, object]:
    """A log x axis ticked at the grid sizes (metres, shown divided by ``per``),
    padded by a quarter step either side."""
    sizes = np.asarray(sizes, dtype=np.float64) / per
    lo, hi = np.log10(sizes.min()), np.log10(sizes.max())
    pad = 0.15 * max(hi - lo, 0.3)
    return {"type": "log", "tickvals": list(sizes),
            "ticktext": [f"{float(f'{g:.9g}'):g}" for g in sizes],
            "range": [lo - pad, hi + pad], "title": {"text": f"grid size ({label_})"}}


def _span(sizes: np.ndarray, per: float = 1.0, label_: str = "m") -> str:
    sizes = np.asarray(sizes, dtype=np.float64) / per
    if sizes.size == 1:
        return f"grid {sizes[0]:.4g} {label_}"
    return f"grids {sizes.min():.4g}–{sizes.max():.4g} {label_}"


def point_scales_figure(
    scales: PointScales,
    *,
    maps: Sequence[MapName] = MODELS,
    point_xyz: Sequence[float] | None = None,
    n_points: int | None = None,
    unit: str = "m",
) -> go.Figure:
    """Roughness of the cells holding one point against grid size.

    Parameters
    ----------
    scales : PointScales
        From :func:`rough_viewer.grid.scales.point_scales`.
    maps : sequence of map names
        Series drawn, default ODR, OLS and hybrid.
    point_xyz : (3,) optional
        The point's coordinates (file frame, metres), for the caption.
    n_points : int, optional
        Points in the cloud, for the caption.
    unit : {"m", "mm", "ft", "us-ft"}
        Unit of the cloud's coordinates: grid sizes and the point are shown in it,
        roughness in :data:`rough_viewer.vocabulary.ROUGHNESS_UNIT` of it (mm for
        metric input). Inputs stay in metres.

    Returns
    -------
    go.Figure
        One trace per map with one value per grid (``x`` = grid size in ``unit``,
        ``y`` = roughness in the roughness unit, NaN where the cell has no value);
        ``customdata`` holds the cell's point count.
    """
    if scales.cell_sizes.size == 0:
        raise InputError("no grid to plot")
    (per, u), (rper, ru) = unit_scale(unit), roughness_scale(unit)
    fig = go.Figure()
    missing = []
    for name in maps:
        y = scales.values(name) / rper
        fig.add_trace(go.Scatter(
            x=scales.cell_sizes / per, y=y, mode="lines+markers", name=label(name),
            line={"color": MAP_COLOURS.get(name), "width": 2},
            marker={"symbol": MAP_MARKERS.get(name, "circle-open"), "size": 9,
                    "color": MAP_COLOURS.get(name)},
            customdata=scales.n_points,
            hovertemplate=(label(name) + f": grid %{{x:g}} {u}, θ %{{y:.4g}} {ru}, "
                           "%{customdata:,} points in the cell<extra></extra>"),
        ))
    for g, n, ok in zip(scales.cell_sizes, scales.n_points,
                        np.isfinite(scales.theta_odr), strict=True):
        if not ok:
            missing.append(f"{g / per:.4g} {u} ({n} points)")
    parts = [f"point #{scales.point:,}"]
    if point_xyz is not None:
        parts.append("at (" + ", ".join(f"{float(c) / per:.2f}" for c in point_xyz) + f") {u}")
    parts += [_span(scales.cell_sizes, per, u), f"dependent axis {scales.axis}"]
    if n_points is not None:
        parts.append(f"{int(n_points):,} points")
    if missing:
        parts.append("no value at " + ", ".join(missing))
    title = title_block("Roughness of this point's cells across grid sizes", " · ".join(parts))
    top = title_height(title)
    fig.update_layout(
        title=title, xaxis=_grid_axis(scales.cell_sizes, per, u),
        yaxis={"title": {"text": f"roughness θ ({ru})"}, "rangemode": "tozero"},
        height=top + 324, margin={"l": 60, "r": 10, "t": top + 24, "b": 50},
        legend={"orientation": "h", "x": 0.0, "y": 1.0, "yanchor": "bottom"},
    )
    return fig


def face_scales_figure(
    scales: FaceScales, *, maps: Sequence[MapName] = MODELS, unit: str = "m"
) -> go.Figure:
    """Whole-face roughness against grid size: mean θ (top) and the share of binary
    rough cells, normalised ``>= threshold`` (bottom), one line per model.

    Parameters
    ----------
    scales : FaceScales
        From :func:`rough_viewer.grid.scales.face_scales`.
    maps : sequence of map names
        Series drawn, default ODR, OLS and hybrid.
    unit : {"m", "mm", "ft", "us-ft"}
        As for :func:`point_scales_figure`.

    Returns
    -------
    go.Figure
        Traces ``2 * len(maps)``: first the means (roughness unit, mm for metric
        input), then the shares (%), in the order of ``maps``; ``x`` = grid sizes
        (``unit``).
    """
    if scales.cell_sizes.size == 0:
        raise InputError("no grid to plot")
    (per, u), (rper, ru) = unit_scale(unit), roughness_scale(unit)
    fig = make_subplots(rows=2, cols=1, shared_xaxes=True, vertical_spacing=0.1)
    for row, what in ((1, "mean"), (2, "share")):
        for name in maps:
            if what == "mean":
                y = scales.statistic(name, "mean") / rper
                hover = label(name) + f": grid %{{x:g}} {u}, mean θ %{{y:.4g}} {ru}<extra></extra>"
            else:
                y = scales.rough_share[name] * 100.0
                hover = label(name) + f": grid %{{x:g}} {u}, %{{y:.1f}} % rough cells<extra></extra>"
            fig.add_trace(go.Scatter(
                x=scales.cell_sizes / per, y=y, mode="lines+markers", name=label(name),
                legendgroup=name, showlegend=row == 1,
                line={"color": MAP_COLOURS.get(name), "width": 2},
                marker={"symbol": MAP_MARKERS.get(name, "circle-open"), "size": 8,
                        "color": MAP_COLOURS.get(name)},
                hovertemplate=hover,
            ), row=row, col=1)
    caption = " · ".join([_span(scales.cell_sizes, per, u),
                          "models " + ", ".join(label(m) for m in maps),
                          f"dependent axis {scales.axis}", f"{scales.n_points:,} points"])
    title = title_block("Roughness against grid size (Table 1 trend)", caption)
    top = title_height(title)
    axis = _grid_axis(scales.cell_sizes, per, u)
    fig.update_xaxes(**{k: v for k, v in axis.items() if k != "title"}, row=1, col=1)
    fig.update_xaxes(**axis, row=2, col=1)
    fig.update_yaxes(title_text=f"mean θ ({ru})", rangemode="tozero", row=1, col=1)
    fig.update_yaxes(title_text=f"binary cells ≥ {scales.threshold:g} (%)", range=[0, 100],
                     row=2, col=1)
    fig.update_layout(
        title=title, height=top + 494, margin={"l": 60, "r": 10, "t": top + 24, "b": 50},
        legend={"orientation": "h", "x": 0.0, "y": 1.0, "yanchor": "bottom"},
    )
    return fig
