"""Profile figures: heights along the line and the roughness-length plot."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from rough_viewer.vocabulary import PROFILE_COLOURS, InputError

#: Height-axis margin above and below the data, as a share of the data's span.
HEIGHT_MARGIN = 0.08
#: Smallest height span shown, mm (a perfectly flat profile still gets an axis).
MIN_HEIGHT_SPAN_MM = 0.2
#: Units of the figure unless told: distances in metres, heights in millimetres,
#: as (label, metres per unit).
METRES = ("m", 1.0)
MILLIMETRES = ("mm", 1e-3)


def height_range_mm(analyses: Sequence[Any], *, per: float = 1e-3) -> tuple[float, float]:
    """The height-axis range of :func:`profile_figure`, mm (or units of ``per``
    metres): the lowest and highest raw or de-noised height of every profile,
    widened by :data:`HEIGHT_MARGIN` of their span on each side (at least
    :data:`MIN_HEIGHT_SPAN_MM` in all); (-1, 1) when there is no height.

    >>> from types import SimpleNamespace as NS
    >>> a = NS(profile=NS(heights=[0.0, 0.010]), denoised=NS(heights=[0.0, 0.010]))
    >>> [round(v, 3) for v in height_range_mm([a])]
    [-0.8, 10.8]
    >>> [round(v, 5) for v in height_range_mm([a], per=0.3048)]
    [-0.00262, 0.03543]
    """
    parts = [np.asarray(h, dtype=np.float64) / per for a in analyses
             for h in (a.profile.heights, a.denoised.heights)]
    values = np.concatenate(parts) if parts else np.empty(0)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return (-1.0, 1.0)
    lo, hi = float(values.min()), float(values.max())
    span = max(hi - lo, MIN_HEIGHT_SPAN_MM * 1e-3 / per)
    mid = 0.5 * (lo + hi)
    half = 0.5 * span * (1 + 2 * HEIGHT_MARGIN)
    return (mid - half, mid + half)


#: Height span, in the small height unit, from which heights are shown in the length
#: unit instead (1,000 mm: a 195 m airborne profile's 25 m of relief reads in m, not
#: as -15k..10k mm).
HEIGHT_UNIT_SWITCH = 1000.0


def height_unit_for(analyses: Sequence[Any], length_unit: tuple[str, float],
                    height_unit: tuple[str, float]) -> tuple[str, float]:
    """The unit heights are drawn in: ``height_unit`` (mm for metric input) unless
    the heights span :data:`HEIGHT_UNIT_SWITCH` of it or more and ``length_unit`` is
    larger, then ``length_unit``.

    >>> from types import SimpleNamespace as NS
    >>> a = NS(profile=NS(heights=[-15.0, 10.0]), denoised=NS(heights=[-14.0, 9.0]))
    >>> height_unit_for([a], METRES, MILLIMETRES), height_unit_for([], METRES, MILLIMETRES)
    (('m', 1.0), ('mm', 0.001))
    """
    if length_unit[1] <= height_unit[1]:
        return height_unit
    lo, hi = height_range_mm(analyses, per=height_unit[1])
    return length_unit if hi - lo >= HEIGHT_UNIT_SWITCH else height_unit


def profile_figure(analyses: Sequence[Any], *, exaggeration: float | None = None,
                   length_unit: tuple[str, float] = METRES,
                   height_unit: tuple[str, float] = MILLIMETRES) -> go.Figure:
    """Profiles (raw and de-noised heights along the line, mm) above the log-log
    roughness-length plot s(w) with fitted lines and D, one colour per profile.

    Parameters
    ----------
    analyses : sequence of ProfileAnalysis
        Objects with ``profile`` (``distance`` and ``heights``, metres),
        ``denoised.heights`` (metres), ``raw_fit`` and ``denoised_fit``
        (:class:`~rough_viewer.profiles.fractal.RoughnessLength`), e.g.
        ``rough_viewer.app.features.profile.ProfileAnalysis``.
    exaggeration : float, optional
        None (default): the height axis spans the data (:func:`height_range_mm`), so
        millimetre relief fills the panel; its title says the plot is not to scale.
        A number ``E > 0``: one millimetre of height is drawn ``E`` times as long as
        one millimetre along the line (``E = 1`` is true scale); the height range
        stays fitted to the data and the plot box takes the shape that ratio gives
        (a thin strip for small ``E``).
    length_unit, height_unit : (str, float)
        Label and metres per unit of distances (along the line, windows) and of
        heights (profiles, s(w)): metres and millimetres by default; a cloud in feet
        gives ``("ft", 0.3048)`` for both. Heights spanning a metre or more are drawn
        in the length unit (:func:`height_unit_for`).
    """
    lu, lper = length_unit
    hu, hper = height_unit_for(analyses, length_unit, height_unit)
    if exaggeration is not None and not (np.isfinite(exaggeration) and exaggeration > 0):
        raise InputError(f"vertical exaggeration must be a positive number, got {exaggeration}")
    fig = make_subplots(rows=2, cols=1, vertical_spacing=0.2,
                        subplot_titles=("profile (raw, de-noised)", "roughness length s(w)"))
    hover = f"%{{x:.4g}} {lu}, %{{y:.4g}} {hu}<extra></extra>"
    for k, a in enumerate(analyses):
        c = PROFILE_COLOURS[k % len(PROFILE_COLOURS)]
        p = a.profile
        fig.add_trace(go.Scatter(x=np.asarray(p.distance) / lper,
                                 y=np.asarray(p.heights) / hper, mode="lines",
                                 name=f"P{k + 1} raw", legendgroup=f"P{k + 1}",
                                 line={"color": c, "width": 1, "dash": "dot"}, opacity=0.6,
                                 hovertemplate=hover),
                      row=1, col=1)
        fig.add_trace(go.Scatter(x=np.asarray(p.distance) / lper,
                                 y=np.asarray(a.denoised.heights) / hper,
                                 mode="lines", name=f"P{k + 1} de-noised",
                                 legendgroup=f"P{k + 1}", line={"color": c, "width": 2},
                                 hovertemplate=hover),
                      row=1, col=1)
        for fit, dash, what in ((a.raw_fit, "dot", "raw"), (a.denoised_fit, "solid", "de-noised")):
            ok = np.isfinite(fit.s)
            fig.add_trace(go.Scatter(x=fit.windows[ok] / lper, y=fit.s[ok] / hper,
                                     mode="markers",
                                     marker={"color": c, "symbol": "circle-open" if what == "raw"
                                             else "circle"},
                                     legendgroup=f"P{k + 1}",
                                     name=f"P{k + 1} {what} D={fit.dimension:.3f}"), row=2, col=1)
            if np.isfinite(fit.amplitude) and ok.any():
                w = fit.windows[ok]
                fig.add_trace(go.Scatter(x=w / lper, y=fit.amplitude * w ** fit.hurst / hper,
                                         mode="lines", line={"color": c, "dash": dash, "width": 1},
                                         legendgroup=f"P{k + 1}", showlegend=False,
                                         hoverinfo="skip"), row=2, col=1)
    lo, hi = height_range_mm(analyses, per=hper)
    fig.update_xaxes(title_text=f"distance along the line ({lu})", row=1, col=1)
    if exaggeration is None:
        fig.update_yaxes(title_text=f"height ({hu}), fitted", range=[lo, hi], row=1, col=1)
    else:
        # one height unit is E * hper / lper distance units on the screen
        fig.update_yaxes(title_text=f"height ({hu}), ×{exaggeration:g}", range=[lo, hi],
                         scaleanchor="x", scaleratio=float(exaggeration) * hper / lper,
                         constrain="domain", row=1, col=1)
        fig.update_xaxes(constrain="domain", row=1, col=1)
    fig.update_xaxes(title_text=f"window w ({lu})", type="log", row=2, col=1)
    fig.update_yaxes(title_text=f"s(w) ({hu})", type="log", row=2, col=1)
    fig.update_layout(height=620, margin={"l": 60, "r": 10, "t": 30, "b": 40},
                      legend={"orientation": "h", "x": 0.0, "y": -0.13, "yanchor": "top",
                              "font": {"size": 10}},
                      showlegend=bool(analyses))
    return fig
