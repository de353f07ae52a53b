"""What every tab's widgets share: the panel's width, plotly's options, and how a
number field shows a colour limit.

Labels and controls of each tab are in its feature's module
(:mod:`rough_viewer.app.features`); the browser tests find controls by those labels.
"""

from __future__ import annotations

import math

import plotly.graph_objects as go
import viser

from rough_viewer.visual.app import CONTROL_WIDTH, panel_aspect

__all__ = ["CONTROL_WIDTH", "PLOTLY_CONFIG", "limit_step", "placeholder", "set_figure"]
#: Plotly options of every panel: no mode bar (it covered the plots' titles at the top
#: right; dragging still zooms, a double click resets, and the Export folder saves
#: figures), no plotly logo.
PLOTLY_CONFIG: dict[str, object] = {"displayModeBar": False, "displaylogo": False}


def placeholder(title: str, note: str = "") -> go.Figure:
    """A panel before it has anything to show: its title (and a note), no axes (empty
    plotly axes draw overlapping ticks)."""
    fig = go.Figure()
    text = title if not note else f"{title}<br><sup>{note}</sup>"
    fig.update_layout(title={"text": text, "font": {"size": 12}, "x": 0.01, "xanchor": "left"},
                      height=60 if not note else 70,
                      margin={"l": 10, "r": 10, "t": 44 if not note else 54, "b": 4},
                      xaxis={"visible": False}, yaxis={"visible": False}, plot_bgcolor="white")
    return fig


def set_figure(handle: viser.GuiPlotlyHandle, fig: go.Figure) -> None:
    """Show ``fig`` at the height its builder laid it out for (at the panel width)."""
    if fig.layout.height is not None:
        handle.aspect = panel_aspect(fig)
    handle.figure = fig


def limit_step(value: float) -> float:
    """The step of a colour-limit field holding ``value``: its third significant
    digit (the field shows as many decimals as its step has), at most 0.001.

    >>> limit_step(6.22), limit_step(0.00131), limit_step(0.0)
    (0.001, 1e-05, 0.001)
    """
    v = abs(float(value))
    if not v or v != v:
        return 0.001
    return min(0.001, 10.0 ** (math.floor(math.log10(v)) - 2))
