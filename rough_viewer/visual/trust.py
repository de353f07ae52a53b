"""Figures of the per-cell scanner trust (:mod:`rough_viewer.scanner.trust`,
docs/scanner.md): which cells are trusted and why not, and the predicted bias, on
the face plane."""

from __future__ import annotations

from typing import Any

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from rough_viewer.grid.maps import FaceRaster, face_image
from rough_viewer.scanner.trust import FLAG_INCIDENCE, FLAG_NOISE, FLAG_RANGE, CellTrust
from rough_viewer.visual import colormaps
from rough_viewer.visual.grid import _display_image, _title
from rough_viewer.vocabulary import unit_scale

#: Trust classes of the map, by code: name and colour.
TRUST_CLASSES: tuple[tuple[str, str], ...] = (
    ("trusted", "#2ca02c"),
    ("incidence > 22.5°", "#ff7f0e"),
    ("range outside calibration", "#9467bd"),
    ("noise > 30 % of roughness", "#d62728"),
    ("several", "#3c3c3c"),
)


def trust_codes(trust: CellTrust) -> np.ndarray:
    """(M,) class code of every cell (:data:`TRUST_CLASSES`), NaN where not judged."""
    f = trust.flags.astype(np.int64)
    code = np.select([f == 0, f == FLAG_INCIDENCE, f == FLAG_RANGE, f == FLAG_NOISE],
                     [0, 1, 2, 3], default=4).astype(np.float64)
    return np.where(trust.known, code, np.nan)


def _discrete(colours: list[str]) -> list[list[float | str]]:
    n = len(colours)
    out: list[list[float | str]] = []
    for k, c in enumerate(colours):
        out += [[k / n, c], [(k + 1) / n, c]]
    return out


def trust_map_figure(trust: CellTrust, raster: FaceRaster, *, grid_size: float, axis: str,
                     n_points: int, unit: str = "m") -> go.Figure:
    """Two face-plane panels: every cell's trust class (trusted, or the flag that
    failed it) and its net predicted bias in percent of its ODR roughness.

    Parameters
    ----------
    trust : CellTrust
        The per-cell trust of a grid result.
    raster : FaceRaster
        The result's cells on the face plane (:func:`rough_viewer.grid.maps.face_raster`);
        its pixels may be coarser than the grid (then each shows the worst class of
        its cells and their mean bias).
    """
    codes = face_image(raster, trust_codes(trust), reduce="max")
    with np.errstate(invalid="ignore", divide="ignore"):
        pct = np.where(trust.known & (trust.theta_m > 0),
                       100.0 * trust.bias_pred_m / trust.theta_m, np.nan)
    bias = face_image(raster, pct, reduce="mean")
    finite = pct[np.isfinite(pct)]
    span = float(np.percentile(np.abs(finite), 98)) if finite.size else 1.0
    span = max(span, 1.0)
    f, u = unit_scale(unit)
    fig = make_subplots(rows=2, cols=1, vertical_spacing=0.1, subplot_titles=(
        "trust: " + ", ".join(f"{name} ({c})" for name, c in
                              (("green", "trusted"), ("orange", "incidence"),
                               ("purple", "range"), ("red", "noise"), ("dark", "several"))),
        "net predicted bias, % of ODR roughness (noise + beam smoothing)"))
    colours = [c for _, c in TRUST_CLASSES]
    z1, u1, v1, _ = _display_image(codes.image, codes.u, codes.v)
    names = np.array([n for n, _ in TRUST_CLASSES] + [""])
    text = np.where(np.isfinite(z1), names[np.nan_to_num(z1, nan=len(TRUST_CLASSES)).astype(int)],
                    "")
    fig.add_trace(go.Heatmap(z=z1, x=u1 / f, y=v1 / f, zmin=-0.5, zmax=len(colours) - 0.5,
                             colorscale=_discrete(colours), showscale=False, text=text,
                             hovertemplate=f"u %{{x:.2f}} {u}, v %{{y:.2f}} {u}: %{{text}}"
                             "<extra></extra>"), row=1, col=1)
    z2, u2, v2, _ = _display_image(bias.image, bias.u, bias.v)
    heat: dict[str, Any] = {
        "z": z2, "x": u2 / f, "y": v2 / f, "zmin": -span, "zmax": span,
        "colorscale": colormaps.plotly_colorscale("coolwarm"),
        "colorbar": {"title": {"text": "%"}, "len": 0.45, "y": 0.0, "yanchor": "bottom"},
        "hovertemplate": f"u %{{x:.2f}} {u}, v %{{y:.2f}} {u}: %{{z:+.1f}} %<extra></extra>",
    }
    fig.add_trace(go.Heatmap(**heat), row=2, col=1)
    aspect = 0.3
    if codes.u.size and codes.v.size:
        aspect = (codes.v[-1] - codes.v[0] + codes.cell_size) / (codes.u[-1] - codes.u[0]
                                                               + codes.cell_size)
    for row, xref in ((1, "x"), (2, "x2")):
        fig.update_yaxes(scaleanchor=xref, scaleratio=1, title_text=f"v, up the face ({u})",
                         row=row, col=1)
        fig.update_xaxes(title_text=f"u, along the face ({u})", row=row, col=1)
    panel = float(np.clip(900 * aspect, 160, 600))
    fig.update_layout(
        title=_title("Scanner trust on the face plane", grid_size=grid_size, axis=axis,
                     n_points=n_points, models=["odr"], unit=unit),
        height=int(110 + 2 * (panel + 70)), width=1000,
        margin={"l": 60, "r": 10, "t": 90, "b": 40}, plot_bgcolor="white",
    )
    return fig
