"""Figures used only by the browser app: the colour bar of the point colours.

The analysis figures (histogram, semivariogram, summary table) live in
:mod:`rough_viewer.visual.grid` and are shared with the report.
"""

from __future__ import annotations

import numpy as np
import plotly.graph_objects as go

from rough_viewer.visual import colormaps


def colour_bar_figure(
    *,
    colormap: str,
    theta_min_m: float,
    theta_max_m: float,
    mode: str = "binary",
    threshold: float = 0.05,
    title: str = "",
    no_value_cells: int = 0,
    unit: str = "mm",
    scale: float = 1e3,
) -> go.Figure:
    """Horizontal colour bar of min-max normalised roughness: the binary display
    (the 2011 paper's transform: two colours split at ``threshold``), or, with
    ``mode="continuous"``, the plain min-max map. Roughness is labelled in ``unit``.

    The continuous map of the app is drawn by :func:`colour_scale_figure` (any
    :class:`~rough_viewer.visual.colormaps.Stretch`).

    Parameters
    ----------
    colormap
        Colour map name (:mod:`rough_viewer.visual.colormaps`).
    theta_min_m, theta_max_m
        Roughness of the smoothest and roughest cell (metres): normalised 0 and 1.
    mode
        ``binary`` (default) or ``continuous``.
    threshold
        Binary threshold on normalised roughness.
    title
        Figure title (model, grid size, axis, point count).
    no_value_cells
        Cells drawn in the neutral colour, stated under the bar.
    unit, scale
        Roughness is shown as metres times ``scale`` in ``unit`` (default mm).
    """
    span = theta_max_m - theta_min_m if np.isfinite(theta_max_m - theta_min_m) else 0.0
    t = np.linspace(0.0, 1.0, 256)
    shown = scale * (theta_min_m + t * span) if span > 0 else scale * np.full_like(t, theta_min_m)
    if mode == "binary":
        rgb = colormaps.apply_binary(t >= threshold, np.ones_like(t, bool), colormap)
    else:
        rgb = colormaps.apply(t, colormap)
    css = [[i / 255.0, colormaps.rgb_css(c)] for i, c in enumerate(rgb)]
    fig = go.Figure(
        go.Heatmap(
            z=[t],
            x=shown,
            colorscale=css,
            zmin=0.0,
            zmax=1.0,
            showscale=False,
            hovertemplate=f"θ %{{x:.4g}} {unit}<extra></extra>",
        )
    )
    note = f"grey: no value ({no_value_cells:,} cells)" if no_value_cells else ""
    if mode == "binary":
        cut = scale * (theta_min_m + threshold * span)
        note = (f"rough: normalised ≥ {threshold:.2f} (θ ≥ {cut:.3g} {unit})"
                + (" · " + note if note else ""))
    fig.update_layout(
        title={"text": title, "font": {"size": 12}, "x": 0.01, "xanchor": "left"},
        margin={"l": 12, "r": 12, "t": 30, "b": 52},
        height=130,
        xaxis={"title": {"text": f"θ ({unit})<br><sup>{note}</sup>", "font": {"size": 12},
                         "standoff": 4}, "showgrid": False},
        yaxis={"visible": False},
        plot_bgcolor="white",
    )
    return fig


def colour_scale_figure(
    colour_range: colormaps.ColourRange,
    *,
    colormap: str,
    title: str = "",
    quantity: str = "θ",
    unit: str = "mm",
    scale: float = 1e3,
    no_value: int = 0,
    no_value_what: str = "cells",
    max_ticks: int = 6,
    exact_fit: int = 0,
    outliers: int = 0,
) -> go.Figure:
    """Horizontal colour bar of a resolved colour stretch, ticked at round numbers.

    The successor of :func:`colour_bar_figure` for the continuous display: the bar
    shows exactly what the points show (any :class:`~rough_viewer.visual.colormaps.Stretch`:
    percentile or absolute, linear or log, symmetric), with the tick values of
    :func:`~rough_viewer.visual.colormaps.colour_ticks` and the shares of values
    clipped at either end.

    Parameters
    ----------
    colour_range : ColourRange
        From :func:`rough_viewer.visual.colormaps.resolve`.
    colormap : str
        Colour map name.
    title : str
        Figure title (model, grid size, axis, point count).
    quantity, unit, scale
        Axis label ``f"{quantity} ({unit})"``; tick values are range values times
        ``scale`` (1e3: metres shown in mm; 1 and ``unit=""`` for intensity).
    no_value, no_value_what
        Count of grey (no value) cells or points, stated under the bar.
    max_ticks : int
        Most tick labels.
    exact_fit : int
        Cells of roughness 0 to round-off among the range's values
        (``GridRoughness.cell_report(...)["exact_fit"]``): they sit below any log
        stretch, so the caption names them instead of counting them as "below".
    outliers : int
        Cells drawn in :data:`~rough_viewer.visual.colormaps.OUTLIER_RGB` (roughness
        larger than the cell), stated under the bar.
    """
    t = np.linspace(0.0, 1.0, 256)
    rgb = colormaps.apply(t, colormap)
    scale_css = [[i / 255.0, colormaps.rgb_css(c)] for i, c in enumerate(rgb)]
    ticks = colormaps.colour_ticks(colour_range, scale=scale, max_ticks=max_ticks)
    lo, hi = colour_range.lo * scale, colour_range.hi * scale
    if colour_range.log and np.isfinite(lo) and np.isfinite(hi) and lo > 0 and hi > lo:
        values = lo * (hi / lo) ** t
    else:
        values = lo + t * (hi - lo)
    fig = go.Figure(go.Heatmap(
        z=[t], x=t, colorscale=scale_css, zmin=0.0, zmax=1.0, showscale=False,
        customdata=[values], hovertemplate=f"{quantity} %{{customdata:.4g}} {unit}<extra></extra>",
    ))
    stretch = colour_range.stretch.describe(scale=scale, unit=unit)
    notes = [stretch]
    n = max(colour_range.n_values, 1)
    exact = min(int(exact_fit), int(round(colour_range.below * n)))
    below = colour_range.below - exact / n
    if below * 100 >= 0.5:
        notes.append(f"{below * 100:.0f} % below")
    if exact:
        notes.append(f"{exact:,} exact-fit cells (θ = 0)")
    if colour_range.above:
        notes.append(f"{colour_range.above * 100:.0f} % above")
    if no_value:
        notes.append(f"grey: no value ({no_value:,} {no_value_what})")
    if outliers:
        notes.append(f"cyan: {outliers:,} outlier cells (larger than the cell)")
    axis_title = f"{quantity} ({unit})" if unit else quantity
    fig.update_layout(
        title={"text": title, "font": {"size": 12}, "x": 0.01, "xanchor": "left"},
        margin={"l": 12, "r": 12, "t": 30, "b": 52},
        height=130,
        xaxis={"range": [-0.5 / 255, 1 + 0.5 / 255], "tickvals": list(ticks.positions),
               "ticktext": list(ticks.labels), "tickfont": {"size": 12}, "ticks": "outside",
               "showgrid": False, "zeroline": False,
               "title": {"text": f"{axis_title}<br><sup>{' · '.join(notes)}</sup>",
                         "font": {"size": 12}, "standoff": 4}},
        yaxis={"visible": False},
        plot_bgcolor="white",
    )
    return fig


#: Width of an analysis panel the figures are laid out for, px (issue 13: at least
#: ~480 px at a 1600 x 1000 window).
PANEL_WIDTH = 480
#: Width of the app's control panel, px: its plots are about PANEL_WIDTH + 60 px wide
#: less the panel's padding (issue 13: at least ~480 px at a 1600 x 1000 window).
CONTROL_WIDTH = PANEL_WIDTH + 80


def category_legend_figure(
    classes: tuple[tuple[float, str, str], ...],
    *,
    title: str = "",
    counts: tuple[int, ...] | None = None,
    no_value: int = 0,
) -> go.Figure:
    """Legend of a layer drawn by class (:data:`rough_viewer.visual.colormaps.
    CATEGORIES`, e.g. the trusted flag): one swatch per class in its colour with its
    name (and its count of cells), instead of a continuous colour bar.

    Parameters
    ----------
    classes
        Value, name and ``"#rrggbb"`` colour of each class.
    title
        Figure title.
    counts
        Cells of each class, shown with their share; None: names only.
    no_value
        Cells in the neutral grey (not judged), stated under the swatches.
    """
    names = [name for _v, name, _c in classes]
    total = sum(counts) if counts else 0
    if counts is not None:
        names = [f"{n}: {c:,} cells ({100.0 * c / total:.0f} %)" if total else f"{n}: 0 cells"
                 for n, c in zip(names, counts, strict=True)]
    k = len(classes)
    fig = go.Figure(go.Heatmap(
        z=[list(range(k))], x=names, zmin=-0.5, zmax=k - 0.5, showscale=False,
        colorscale=_steps(classes), xgap=6, hovertemplate="%{x}<extra></extra>"))
    note = f"grey: not judged ({no_value:,} cells)" if no_value else ""
    fig.update_layout(
        title={"text": title, "font": {"size": 12}, "x": 0.01, "xanchor": "left"},
        margin={"l": 12, "r": 12, "t": 30, "b": 52}, height=130,
        xaxis={"type": "category", "showgrid": False, "tickfont": {"size": 11},
               "title": {"text": f"<sup>{note}</sup>" if note else "", "standoff": 4}},
        yaxis={"visible": False}, plot_bgcolor="white", meta={"categories": names})
    return fig


def _steps(classes: tuple[tuple[float, str, str], ...]) -> list[list[float | str]]:
    """A plotly colour scale of one flat step per class (z = 0 .. k-1)."""
    k = len(classes)
    out: list[list[float | str]] = []
    for i, (_v, _n, colour) in enumerate(classes):
        out += [[i / k, colour], [(i + 1) / k, colour]]
    return out


def panel_aspect(fig: go.Figure, width: int = PANEL_WIDTH) -> float:
    """The ``aspect`` to give ``viser``'s ``add_plotly`` (which draws a figure
    ``aspect`` times as high as the panel is wide) so that ``fig`` gets the height
    its builder laid it out for (``fig.layout.height``) at ``width`` px."""
    height = fig.layout.height
    if height is None:
        raise ValueError("the figure has no layout height")
    return float(height) / float(width)
