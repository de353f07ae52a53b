"""Figures used only by the browser app: the colour bar of the point colours.

The analysis figures (histogram, semivariogram, summary table) live in
:mod:`rough_viewer.visual.grid` and are shared with the report.
"""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go

from rough_viewer.visual import colormaps

_MARGIN = dict(l=12, r=12, t=34, b=30)


def colour_bar_figure(
    *,
    colormap: str,
    theta_min_m: float,
    theta_max_m: float,
    clip: tuple[float, float] = (0.0, 1.0),
    mode: str = "continuous",
    threshold: float = 0.05,
    title: str = "",
    no_value_cells: int = 0,
) -> go.Figure:
    """Horizontal colour bar for normalised roughness, labelled in millimetres.

    Parameters
    ----------
    colormap
        Colour map name (:mod:`rough_viewer.visual.colormaps`).
    theta_min_m, theta_max_m
        Roughness of the smoothest and roughest cell (metres): normalised 0 and 1.
    clip
        Normalised range spread over the colour map (values outside take the end
        colours).
    mode
        ``continuous`` or ``binary`` (two colours split at ``threshold``).
    threshold
        Binary threshold on normalised roughness.
    title
        Figure title (model, grid size, axis, point count).
    no_value_cells
        Cells drawn in the neutral colour, stated under the bar.
    """
    span = theta_max_m - theta_min_m if np.isfinite(theta_max_m - theta_min_m) else 0.0
    t = np.linspace(0.0, 1.0, 256)
    mm = 1e3 * (theta_min_m + t * span) if span > 0 else 1e3 * np.full_like(t, theta_min_m)
    if mode == "binary":
        rgb = colormaps.apply_binary(t >= threshold, np.ones_like(t, bool), colormap)
    else:
        rgb = colormaps.apply(t, colormap, vmin=clip[0], vmax=clip[1])
    scale = [[i / 255.0, colormaps.rgb_css(c)] for i, c in enumerate(rgb)]
    fig = go.Figure(
        go.Heatmap(
            z=[t],
            x=mm,
            colorscale=scale,
            zmin=0.0,
            zmax=1.0,
            showscale=False,
            hovertemplate="θ %{x:.3f} mm<extra></extra>",
        )
    )
    note = f"grey: no value ({no_value_cells} cells)" if no_value_cells else ""
    if mode == "binary":
        cut = 1e3 * (theta_min_m + threshold * span)
        note = f"rough: normalised ≥ {threshold:.2f} (θ ≥ {cut:.2f} mm)  " + note
    fig.update_layout(
        title=dict(text=title, font=dict(size=12)),
        margin=_MARGIN,
        xaxis=dict(title=dict(text=f"θ (mm)   {note}", font=dict(size=11)), showgrid=False),
        yaxis=dict(visible=False),
        plot_bgcolor="white",
    )
    return fig
