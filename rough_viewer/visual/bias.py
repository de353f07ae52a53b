"""Plotly figures of scanner-bias results (instrument-bias paper, Figs. 2B, 3A and 4).

Pure functions: core results from :mod:`rough_viewer.bias.measurement` and
:mod:`rough_viewer.bias.simulation` in, a :class:`plotly.graph_objects.Figure` out.
Lengths are shown in millimetres.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import plotly.graph_objects as go

from rough_viewer.bias.measurement import EffectiveRadius, PiecewiseLinearFit, RangeNoise
from rough_viewer.bias.simulation import SmoothingCurve
from rough_viewer.visual import colormaps

__all__ = ["board_segments_figure", "radius_range_figure", "smoothing_curve_figure"]


def smoothing_curve_figure(
    curves: Sequence[SmoothingCurve],
    *,
    reference: Literal["noisy", "true"] = "noisy",
    mark: tuple[float, float] | None = None,
) -> go.Figure:
    """Roughness error against ER / asperity radius, one line per asperity radius.

    Parameters
    ----------
    curves : sequence of SmoothingCurve
        From :func:`rough_viewer.bias.simulation.smoothing_curve`.
    reference : {"noisy", "true"}
        Error against the noisy unsmoothed simulation (the paper's Fig. 4) or
        against the true surface.
    mark : (er_ratio, error_pct), optional
        A point to highlight (e.g. the current prediction).
    """
    fig = go.Figure()
    for c in curves:
        y = c.vs_noisy_pct if reference == "noisy" else c.error_pct
        fig.add_trace(go.Scatter(
            x=c.er_ratio, y=y, mode="lines+markers",
            name=f"r = {c.asperity_radius_m * 1e3:g} mm",
            hovertemplate="ER/r %{x:.3f}<br>error %{y:+.2f} %<extra></extra>",
        ))
    if mark is not None:
        fig.add_trace(go.Scatter(x=[mark[0]], y=[mark[1]], mode="markers", name="prediction",
                                 marker={"size": 12, "symbol": "star", "color": "black"}))
    fig.add_hline(y=0.0, line={"color": "#999", "width": 1})
    noise = curves[0].noise_sigma_m * 1e3 if curves else 0.0
    against = "noisy simulation" if reference == "noisy" else "true surface"
    fig.update_layout(
        title={"text": f"Beam smoothing: roughness error vs ER / asperity radius"
                       f"<br><sup>range noise {noise:g} mm · against the {against} · "
                       f"population-normalised</sup>", "x": 0.01, "xanchor": "left"},
        xaxis_title="effective radius / asperity radius",
        yaxis_title="roughness error (%)",
        margin={"l": 60, "r": 20, "t": 70, "b": 50},
    )
    return fig


def board_segments_figure(noise: RangeNoise, *, value: Literal["offset", "sigma"] = "offset"
                          ) -> go.Figure:
    """Per-segment values of a board scan as a rows x cols heat map.

    ``"offset"`` (mean distance to the whole-board plane) shows a bowed board;
    ``"sigma"`` the per-segment noise.
    """
    rows, cols = noise.shape
    z = np.full((rows, cols), np.nan)
    for s in noise.segments:
        z[s.row, s.col] = (s.offset if value == "offset" else s.sigma) * 1e3
    scale = colormaps.plotly_colorscale("coolwarm" if value == "offset" else "viridis")
    extra = {"zmid": 0.0} if value == "offset" else {}
    fig = go.Figure(go.Heatmap(
        z=z, x=[f"col {c}" for c in range(cols)], y=[f"row {r}" for r in range(rows)],
        colorscale=scale, colorbar={"title": "mm"}, texttemplate="%{z:.3f}", **extra))
    what = "offset from one plane" if value == "offset" else "noise sigma"
    fig.update_layout(
        title={"text": f"Board segments: {what}<br><sup>noise {noise.sigma * 1e3:.3f} mm "
                       f"(one plane: {noise.sigma_single_plane * 1e3:.3f} mm) · "
                       f"{noise.n_points:,} points</sup>", "x": 0.01, "xanchor": "left"},
        yaxis={"autorange": "reversed"}, margin={"l": 60, "r": 20, "t": 70, "b": 40},
    )
    return fig


def radius_range_figure(scans: Sequence[EffectiveRadius],
                        fit: PiecewiseLinearFit | None = None) -> go.Figure:
    """Effective radius against range, with the piecewise-linear fit (paper Fig. 3A)."""
    x = np.array([s.range for s in scans])
    y = np.array([s.effective_radius for s in scans]) * 1e3
    fig = go.Figure(go.Scatter(x=x, y=y, mode="markers", name="wire scans"))
    sub = ""
    if fit is not None and x.size:
        xs = np.linspace(min(x.min(), fit.break_range), max(x.max(), fit.break_range), 200)
        fig.add_trace(go.Scatter(x=xs, y=fit.predict(xs) * 1e3, mode="lines",
                                 name="piecewise fit"))
        fig.add_vline(x=fit.break_range, line={"dash": "dot", "color": "#999"})
        sub = f"break {fit.break_range:.2f} m · rmse {fit.rmse * 1e3:.3f} mm"
    fig.update_layout(
        title={"text": f"Beam effective radius vs range<br><sup>{len(scans)} scans"
                       f"{' · ' + sub if sub else ''}</sup>", "x": 0.01, "xanchor": "left"},
        xaxis_title="range (m)", yaxis_title="effective radius (mm)",
        margin={"l": 60, "r": 20, "t": 70, "b": 50},
    )
    return fig
