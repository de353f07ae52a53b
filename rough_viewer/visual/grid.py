"""Plotly figures of grid-roughness results (2011 paper, Table 1 and Figs. 2-4).

Pure functions: core results in, a :class:`plotly.graph_objects.Figure` out. The
report and the browser app both use them. Every figure's title says the grid size,
the models shown, the dependent axis (of OLS and hybrid) and the point count.

Inputs are dictionaries keyed by map name (``"odr"``, ``"ols"``, ``"hybrid"``,
``"e_ols"``); figures show the maps in the order given, so pass them in the order
you want them drawn.

Inputs are in metres (the core's unit); ``unit`` (``"m"``, ``"mm"``, ``"ft"``,
``"us-ft"``, the unit of the input's coordinates) chooses how lengths are shown:
grid sizes, lags and face-map axes in that unit, roughness in
:data:`rough_viewer.vocabulary.ROUGHNESS_UNIT` of it (mm for metric input).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from rough_viewer.grid.maps import FaceMaps
from rough_viewer.grid.variogram import Semivariogram, sampling_note
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import (
    MAP_COLOURS,
    MAP_LABELS,
    MAP_MARKERS,
    InputError,
    roughness_scale,
    unit_scale,
)


def label(name: str) -> str:
    """Display name of a map (``"e_ols"`` -> ``"e_OLS"``)."""
    return MAP_LABELS.get(name, name)


def describe(*, grid_size: float, axis: str, n_points: int, models: Sequence[str] = (),
             unit: str = "m") -> str:
    """The caption every figure carries: grid size (metres in, shown in ``unit``),
    models, dependent axis, points."""
    f, u = unit_scale(unit)
    parts = [f"grid {grid_size / f:g} {u}"]
    if models:
        parts.append("models " + ", ".join(label(m) for m in models))
    parts.append(f"dependent axis {axis}")
    parts.append(f"{int(n_points):,} points")
    return " · ".join(parts)


#: Longest caption line, in characters, that fits a ~480 px wide panel at the
#: caption's font size (the title wraps at " · " to stay inside it).
CAPTION_CHARS = 62
#: Title font size, px; the caption (``<sup>``) is drawn at about 70 % of it.
TITLE_SIZE = 15


def wrap_caption(text: str, width: int = CAPTION_CHARS) -> str:
    """``text`` broken into ``<br>``-separated lines at its `` · `` separators so that
    no line is longer than ``width`` characters where a break can help.

    >>> wrap_caption("grid 0.25 m · models ODR, OLS · dependent axis y · 1,000 points", 40)
    'grid 0.25 m · models ODR, OLS<br>dependent axis y · 1,000 points'
    """
    lines: list[str] = []
    for part in text.split(" · "):
        if lines and len(lines[-1]) + 3 + len(part) <= width:
            lines[-1] += " · " + part
        else:
            lines.append(part)
    return "<br>".join(lines)


def title_block(what: str, caption: str) -> dict[str, Any]:
    """A plotly title: ``what`` (may hold ``<br>``) above the wrapped ``caption`` in
    small type, left-aligned, at :data:`TITLE_SIZE`."""
    sub = "<br>".join(f"<sup>{line}</sup>" for line in wrap_caption(caption).split("<br>"))
    return {"text": f"{what}<br>{sub}", "x": 0.01, "xanchor": "left",
            # plotly anchors a multi-line title about 14 px above the container's
            # top edge; this pad brings its first line just inside
            "yref": "container", "y": 1.0, "yanchor": "top", "pad": {"t": 18},
            "font": {"size": TITLE_SIZE}}


def title_height(title: dict[str, Any]) -> int:
    """Pixels a :func:`title_block` needs above the plot (for the top margin)."""
    lines = title["text"].split("<br>")
    sup = sum(1 for line in lines if line.startswith("<sup>"))
    return int(12 + (len(lines) - sup) * 1.2 * TITLE_SIZE + sup * 1.05 * TITLE_SIZE)


def _title(what: str, **kw: Any) -> dict[str, Any]:
    return title_block(what, describe(**kw))


def format_number(value: float) -> str:
    """A table value in at most about 8 characters, nothing cut: thousands separated
    from 100 up, 2 decimals from 1, 1 decimal from 10, 3 significant digits below 1,
    and the exponent form below 0.001 (round-off such as ``6.5e-15``).

    >>> [format_number(v) for v in (11045.97, 41.1, 4.317, 0.0523, 0.00123, 6.5e-15, 0.0)]
    ['11,046', '41.1', '4.32', '0.0523', '0.00123', '6.5e-15', '0']
    """
    value = float(value)
    if not np.isfinite(value):
        return "–"
    a = abs(value)
    if a == 0:
        return "0"
    if a >= 100:
        return f"{value:,.0f}"
    if a >= 10:
        return f"{value:.1f}"
    if a >= 1:
        return f"{value:.2f}"
    if a >= 1e-3:
        return f"{value:.3g}"
    return f"{value:.1e}".replace("e-0", "e-")


def summary_table_figure(
    summaries: Mapping[str, Any],
    *,
    grid_size: float,
    axis: str,
    n_points: int,
    unit: str = "m",
) -> go.Figure:
    """Table 1 of the 2011 paper for one grid size, roughness in millimetres (in
    ``ROUGHNESS_UNIT[unit]``: mm for metric input, the input's unit otherwise).

    One row per map, columns cells, mean points per cell, minimum, maximum, mean,
    variance (mm²) and standard deviation (mm); numbers by :func:`format_number`
    so that every value fits its column in a panel 480 px wide.

    Parameters
    ----------
    summaries : dict map name -> ``rough_viewer.grid.summary.Summary``
        Objects with ``cells``, ``mean_points``, ``min``, ``max``, ``mean``,
        ``variance`` and ``std`` (roughness in metres, variance in m^2).
    """
    names = list(summaries)
    rows = [summaries[n] for n in names]
    rf, ru = roughness_scale(unit)
    k = 1.0 / rf
    header = ["map", "cells", "points<br>per cell", f"min<br>({ru})", f"max<br>({ru})",
              f"mean<br>({ru})", f"variance<br>({ru}²)", f"std<br>({ru})"]
    cells = [
        [label(n) for n in names],
        [f"{int(s.cells):,}" for s in rows],
        [format_number(s.mean_points) for s in rows],
        [format_number(k * s.min) for s in rows],
        [format_number(k * s.max) for s in rows],
        [format_number(k * s.mean) for s in rows],
        [format_number(k * k * s.variance) for s in rows],
        [format_number(k * s.std) for s in rows],
    ]
    title = _title("Roughness summary (Table 1)", grid_size=grid_size, axis=axis,
                   n_points=n_points, models=names, unit=unit)
    fig = go.Figure(go.Table(
        columnwidth=[1.05, 1.0, 0.95, 1.0, 1.0, 1.0, 1.25, 1.0],
        header={"values": header, "align": ["left"] + ["right"] * 7, "fill_color": "#e8e8e8",
                "font": {"size": 12}, "height": 36},
        cells={"values": cells, "align": ["left"] + ["right"] * 7, "font": {"size": 12},
               "height": 24},
    ))
    top = title_height(title)
    fig.update_layout(
        title=title, height=top + 36 + 24 * len(names) + 16,
        margin={"l": 6, "r": 6, "t": top, "b": 6},
    )
    return fig


def histogram_figure(
    histograms: Mapping[str, Any],
    *,
    grid_size: float,
    axis: str,
    n_points: int,
    unit: str = "m",
    threshold: float | None = None,
    suggestions: Mapping[str, float | None] | None = None,
) -> go.Figure:
    """Histograms of normalised roughness with the first-bin shares (2011 Fig. 3),
    and the binary threshold in use and the data's own suggestion for each map as
    vertical lines.

    Parameters
    ----------
    histograms : dict map name -> ``rough_viewer.grid.roughness.Histogram``
        Objects with ``edges`` (K+1,) and ``fractions`` (K,) over normalised values.
    threshold : float, optional
        The binary threshold in use (normalised roughness): a black dashed line.
    suggestions : dict map name -> float or None, optional
        The suggested threshold of each map
        (:attr:`rough_viewer.grid.threshold.ThresholdAdvice.suggested`): a dotted
        line in the map's colour.
    """
    names = list(histograms)
    fig = go.Figure()
    shares = []
    for name in names:
        h = histograms[name]
        edges = np.asarray(h.edges, dtype=float)
        fractions = np.asarray(h.fractions, dtype=float)
        first = float(fractions[0]) if fractions.size else float("nan")
        shares.append(f"{label(name)} {first * 100:.0f} %")
        fig.add_trace(go.Bar(
            x=0.5 * (edges[:-1] + edges[1:]), y=fractions * 100.0,
            name=label(name),
            marker_color=MAP_COLOURS.get(name),
            hovertemplate=(label(name) + ": %{y:.2f} % of cells"
                           f" (first bin {first * 100:.1f} %)<extra></extra>"),
        ))
    first_edge = f"{histograms[names[0]].edges[1]:g}" if names else ""
    title = _title(
        "Normalised roughness histogram<br>"
        + wrap_caption(f"first bin (0–{first_edge}): " + " · ".join(shares), 56),
        grid_size=grid_size, axis=axis, n_points=n_points, models=names, unit=unit)
    top = title_height(title)
    fig.update_layout(
        title=title,
        barmode="group", bargap=0.15, bargroupgap=0.0,
        xaxis_title="normalised roughness", yaxis_title="cells (%)",
        height=top + 330, margin={"l": 60, "r": 10, "t": top, "b": 50},
        legend={"x": 0.99, "xanchor": "right", "y": 0.99, "bgcolor": "rgba(255,255,255,0.7)"},
    )
    fig.update_xaxes(range=[0, 1], ticks="outside", ticklen=5, tickcolor="rgba(0,0,0,0)")
    _threshold_lines(fig, threshold, {n: v for n, v in (suggestions or {}).items()
                                      if n in histograms})
    return fig


def _threshold_lines(fig: go.Figure, threshold: float | None,
                     suggestions: Mapping[str, float | None]) -> None:
    """The threshold in use (black, dashed) and each map's suggested threshold
    (its colour, dotted) as vertical lines over a histogram, named in the legend."""
    lines = [(threshold, "threshold", "#000000", "dash")] if threshold is not None else []
    lines += [(v, f"{label(n)} suggested", MAP_COLOURS.get(n, "#555555"), "dot")
              for n, v in suggestions.items() if v is not None and np.isfinite(v)]
    for value, name, colour, dash in lines:
        fig.add_trace(go.Scatter(
            x=[value, value], y=[0, 1], yaxis="y2", mode="lines", name=f"{name} {value:.3g}",
            line={"color": colour, "dash": dash, "width": 1.5},
            hovertemplate=f"{name}: %{{x:.3g}}<extra></extra>"))
    if lines:
        fig.update_layout(yaxis2={"overlaying": "y", "range": [0, 1], "visible": False})


def variogram_figure(
    variograms: Mapping[str, Semivariogram],
    *,
    grid_size: float,
    axis: str,
    n_points: int,
    normalised: bool = True,
    unit: str = "m",
) -> go.Figure:
    """Experimental semivariograms overlaid (2011 Fig. 4, one panel per grid size).

    Parameters
    ----------
    variograms : dict map name -> Semivariogram
        Usually ``odr``, ``ols`` and ``e_ols``.
    normalised : bool
        Plot ``gamma / variance`` (sill near 1; default) or ``gamma`` (m^2).
    """
    names = list(variograms)
    fig = go.Figure()
    space = "3-D"
    f, u = unit_scale(unit)
    for name in names:
        vg = variograms[name]
        space = "in the face plane" if vg.space == "plane" else "3-D"
        y = vg.gamma_normalised if normalised else vg.gamma / f**2
        se = vg.gamma_normalised_se if normalised else (
            None if vg.gamma_se is None else vg.gamma_se / f**2)
        fig.add_trace(go.Scatter(
            x=vg.lag / f, y=y, mode="markers", name=label(name),
            marker={"symbol": MAP_MARKERS.get(name, "circle-open"), "color": MAP_COLOURS.get(name),
                    "size": 7},
            error_y=(None if se is None else {"type": "data", "array": se, "visible": True,
                                              "thickness": 1, "width": 0}),
            customdata=(vg.pairs if se is None or vg.sampled is None
                        else np.column_stack([vg.pairs, vg.sampled, se])),
            hovertemplate=(label(name) + f": lag %{{x:.3f}} {u}, γ %{{y:.4g}}, "
                           + ("%{customdata:,} pairs" if se is None else
                              "± %{customdata[2]:.2g} (1 SE), %{customdata[1]:,} of "
                              "≈%{customdata[0]:,} pairs sampled") + "<extra></extra>"),
        ))
    limited = sorted({vg.max_lag / f for vg in variograms.values() if vg.lag_limited})
    note = (f" · lags up to {limited[0]:g} {u} (memory)" if limited else "")
    note += sampling_note(variograms.values(), prefix=" · ")
    title = _title(f"{'Normalised s' if normalised else 'S'}emivariograms ({space} lags)",
                   grid_size=grid_size, axis=axis, n_points=n_points, models=names,
                   unit=unit)
    if note:
        title["text"] += f"<br><sup>{note[3:]}</sup>"
    top = title_height(title)
    fig.update_layout(
        title=title,
        xaxis_title=f"lag ({u})",
        yaxis_title="γ / variance" if normalised else f"γ ({u}²)",
        height=top + 330, margin={"l": 60, "r": 10, "t": top, "b": 50},
        legend={"x": 0.99, "xanchor": "right", "y": 0.01, "yanchor": "bottom",
                "bgcolor": "rgba(255,255,255,0.7)"},
    )
    if normalised:
        fig.add_hline(y=1.0, line={"dash": "dot", "color": "#888", "width": 1})
    return fig


#: Most pixels one face-map panel draws; larger images are shown by the max of
#: k x k pixel blocks (the binary map by its max too: a block is black when any of
#: its pixels is), so a report at a fine grid stays a few MB, not hundreds.
MAX_PANEL_PIXELS = 500_000


def _display_image(image: np.ndarray, u: np.ndarray, v: np.ndarray,
                   max_pixels: int = MAX_PANEL_PIXELS
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The image reduced by the max of k x k blocks so that it has at most
    ``max_pixels`` pixels, its pixel centres, and k (1 = unchanged)."""
    rows, cols = image.shape
    k = 1
    while (rows // k + 1) * (cols // k + 1) > max_pixels and k < max(rows, cols):
        k *= 2
    if k == 1:
        return image, u, v, 1
    r2, c2 = -(-rows // k), -(-cols // k)
    padded = np.full((r2 * k, c2 * k), np.nan)
    padded[:rows, :cols] = image
    blocks = padded.reshape(r2, k, c2, k)
    with np.errstate(all="ignore"):
        finite = np.isfinite(blocks).any(axis=(1, 3))
        reduced = np.where(finite, np.nanmax(np.where(np.isfinite(blocks), blocks, -np.inf),
                                             axis=(1, 3)), np.nan)
    du = float(u[1] - u[0]) if u.size > 1 else 1.0
    dv = float(v[1] - v[0]) if v.size > 1 else 1.0
    u2 = u[0] + (np.arange(c2) * k + 0.5 * (k - 1)) * du
    v2 = v[0] + (np.arange(r2) * k + 0.5 * (k - 1)) * dv
    return reduced, u2, v2, k


def _block_note(k: int) -> str:
    """Subtitle note for a panel whose pixels each hold k x k grid cells (their max)."""
    return f" (each pixel the max of {k} x {k} cells)" if k > 1 else ""


def face_map_figure(
    maps: Mapping[str, FaceMaps],
    *,
    kind: Literal["normalised", "binary"],
    grid_size: float,
    axis: str,
    n_points: int,
    unit: str = "m",
) -> go.Figure:
    """Face-plane maps, one panel per model stacked (2011 Fig. 2: OLS beside ODR).

    Parameters
    ----------
    maps : dict map name -> FaceMaps
        From :func:`rough_viewer.grid.maps.face_maps`.
    kind : {"normalised", "binary"}
        The continuous normalised roughness, or the binary transform at the threshold
        (grey below, black at or above, white where no cell).
    """
    names = list(maps)
    if kind not in ("normalised", "binary"):
        raise InputError(f"kind must be 'normalised' or 'binary', got {kind!r}")
    threshold = next(iter(maps.values())).threshold if names else 0.05
    images = [maps[n].normalised if kind == "normalised" else maps[n].binary for n in names]
    shown = [_display_image(img.image, img.u, img.v) for img in images]
    subtitles = [
        f"{label(n)}: " + ("normalised roughness" if kind == "normalised"
                           else f"normalised ≥ {threshold:g} in black")
        + _block_note(d[3] * max(1, round(img.cell_size / grid_size)))
        for n, d, img in zip(names, shown, images, strict=True)
    ]
    fig = make_subplots(rows=max(1, len(names)), cols=1, subplot_titles=subtitles,
                        vertical_spacing=0.08 if len(names) > 1 else 0.0)
    aspect = 0.3
    f, u = unit_scale(unit)
    for row, name in enumerate(names, start=1):
        img = images[row - 1]
        if img.u.size and img.v.size:
            aspect = (img.v[-1] - img.v[0] + img.cell_size) / (img.u[-1] - img.u[0] + img.cell_size)
        z_img, u_img, v_img, _ = shown[row - 1]
        heat = {
            "z": z_img, "x": u_img / f, "y": v_img / f, "zmin": 0.0, "zmax": 1.0,
            "hovertemplate": label(name) + f": u %{{x:.2f}} {u}, v %{{y:.2f}} {u}, "
                             "%{z:.3f}<extra></extra>",
        }
        if kind == "binary":
            heat.update(colorscale=colormaps.PAPER_BINARY_COLORSCALE, showscale=False)
        else:
            heat.update(colorscale=colormaps.plotly_colorscale("viridis"), showscale=row == 1,
                        colorbar={"title": {"text": "normalised"}, "len": 0.5, "y": 1.0,
                                  "yanchor": "top"})
        fig.add_trace(go.Heatmap(**heat), row=row, col=1)
        xref = "x" if row == 1 else f"x{row}"
        fig.update_yaxes(scaleanchor=xref, scaleratio=1, title_text=f"v, up the face ({u})",
                         row=row, col=1)
        fig.update_xaxes(title_text=f"u, along the face ({u})", row=row, col=1)
    panel = float(np.clip(900 * aspect, 160, 600))
    what = "Normalised roughness" if kind == "normalised" else f"Binary transform at {threshold:g}"
    fig.update_layout(
        title=_title(f"{what} on the face plane (whole-cloud ODR plane)", grid_size=grid_size,
                     axis=axis, n_points=n_points, models=names, unit=unit),
        height=int(110 + len(names) * (panel + 70)), width=1000,
        margin={"l": 60, "r": 10, "t": 90, "b": 40}, plot_bgcolor="white",
    )
    return fig
