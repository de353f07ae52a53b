"""Profile figures: heights along the line and the roughness-length plot."""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from rough_viewer.vocabulary import PROFILE_COLOURS


def profile_figure(analyses, *, exaggeration: float = 1.0) -> go.Figure:
    """Profiles (raw and de-noised heights along the line, mm) above the log-log
    roughness-length plot s(w) with fitted lines and D, one colour per profile.

    ``analyses``: :class:`rough_viewer.app.profile_mode.ProfileAnalysis` items.
    ``exaggeration`` stretches the height axis against the distance axis.
    """
    fig = make_subplots(rows=2, cols=1, vertical_spacing=0.16,
                        subplot_titles=("profile (raw, de-noised)", "roughness length s(w)"))
    for k, a in enumerate(analyses):
        c = PROFILE_COLOURS[k % len(PROFILE_COLOURS)]
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
