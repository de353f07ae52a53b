"""Figures used only by the browser app: the colour bar of the point colours.

The analysis figures (histogram, semivariogram, summary table) live in
:mod:`rough_viewer.visual.grid` and are shared with the report.
"""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

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


_PROFILE_COLOURS = ("#e63c28", "#1e78e6", "#faa000", "#963cc8", "#14aa5a")


def profile_figure(analyses, *, exaggeration: float = 1.0) -> go.Figure:
    """Profiles (raw and de-noised heights along the line, mm) above the log-log
    roughness-length plot s(w) with fitted lines and D, one colour per profile.

    ``analyses``: :class:`rough_viewer.app.profile_mode.ProfileAnalysis` items.
    ``exaggeration`` stretches the height axis against the distance axis.
    """
    fig = make_subplots(rows=2, cols=1, vertical_spacing=0.16,
                        subplot_titles=("profile (raw, de-noised)", "roughness length s(w)"))
    for k, a in enumerate(analyses):
        c = _PROFILE_COLOURS[k % len(_PROFILE_COLOURS)]
        p = a.profile
        fig.add_trace(go.Scatter(x=p.distance, y=p.heights, mode="lines", name=f"P{k + 1} raw",
                                 line=dict(color=c, width=1), opacity=0.45), row=1, col=1)
        fig.add_trace(go.Scatter(x=p.distance, y=a.denoised.heights, mode="lines",
                                 name=f"P{k + 1} de-noised", line=dict(color=c, width=2)),
                      row=1, col=1)
        for fit, dash, what in ((a.raw_fit, "dot", "raw"), (a.denoised_fit, "solid", "de-noised")):
            ok = np.isfinite(fit.s)
            fig.add_trace(go.Scatter(x=fit.windows[ok], y=fit.s[ok], mode="markers",
                                     marker=dict(color=c, symbol="circle-open" if what == "raw"
                                                 else "circle"),
                                     name=f"P{k + 1} {what} D={fit.dimension:.3f}"), row=2, col=1)
            if np.isfinite(fit.amplitude) and ok.any():
                w = fit.windows[ok]
                fig.add_trace(go.Scatter(x=w, y=fit.amplitude * w ** fit.hurst, mode="lines",
                                         line=dict(color=c, dash=dash, width=1),
                                         showlegend=False, hoverinfo="skip"), row=2, col=1)
    fig.update_xaxes(title_text="distance along the line (m)", row=1, col=1)
    fig.update_yaxes(title_text=f"height (m), ×{exaggeration:g}", row=1, col=1,
                     scaleanchor="x", scaleratio=float(exaggeration))
    fig.update_xaxes(title_text="window w (m)", type="log", row=2, col=1)
    fig.update_yaxes(title_text="s(w) (m)", type="log", row=2, col=1)
    fig.update_layout(margin=dict(l=50, r=10, t=30, b=40), legend=dict(font=dict(size=9)),
                      showlegend=bool(analyses))
    return fig
