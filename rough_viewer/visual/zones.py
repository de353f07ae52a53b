"""Plotly figures of fracture zones: the zone table, the zones on the face plane and
the lower-hemisphere equal-area stereonet of cell poles.

Pure functions: core results in (:class:`rough_viewer.structure.zones.Zones`,
:class:`rough_viewer.grid.orientation.Stereonet`), a figure out; the report uses them
and the app can. Zone colours come from
:func:`rough_viewer.visual.colormaps.zone_colour`, the same in every figure and in
the scene. Every title says the grid size, the map, the dependent axis and the
point count.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import plotly.graph_objects as go

from rough_viewer.grid.maps import FaceRaster, Plane, face_image, face_raster
from rough_viewer.grid.orientation import Stereonet, schmidt_inverse, trend_and_plunge
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.structure.zones import Zones
from rough_viewer.visual import colormaps
from rough_viewer.visual.grid import describe
from rough_viewer.vocabulary import MAP_LABELS, InputError, roughness_scale, unit_scale

#: Poles drawn at most per trace (evenly spaced subset); the density uses them all.
MAX_POLES_DRAWN = 20_000


def _title(what: str, *, grid_size: float, axis: str, n_points: int, map_name: str,
           unit: str = "m") -> dict:
    sub = describe(grid_size=grid_size, axis=axis, n_points=n_points, models=(map_name,),
                   unit=unit)
    return {"text": f"{what}<br><sup>{sub}</sup>", "x": 0.01, "xanchor": "left"}


def _count(n: int, noun: str) -> str:
    """``1 zone``, ``2 zones``."""
    return f"1 {noun}" if n == 1 else f"{n:,} {noun}s"


def _zone_settings(zones: Zones) -> str:
    return (f"{MAP_LABELS[zones.map_name]} normalised ≥ {zones.threshold:g}, "
            f"{zones.connectivity} connectivity, ≥ {zones.min_cells} cells")


def azimuth_text(deg: float) -> str:
    """An azimuth as three whole degrees in [000, 359] (359.7 is ``000``, not ``360``)."""
    return f"{int(round(float(deg))) % 360:03d}"


def _table_columns(zones: Zones, n: int, unit: str = "m"
                   ) -> dict[str, tuple[str, int, list[str]]]:
    """Every table column of the ``n`` largest zones: key -> (header, width, cells);
    lengths in ``unit``, roughness in its roughness unit."""
    (f, u), (rf, ru) = unit_scale(unit), roughness_scale(unit)
    return {
        "zone": ("zone", 40, [f"<b>{i}</b>" for i in range(1, n + 1)]),
        "cells": ("cells", 55, [f"{c:,}" for c in zones.cells[:n]]),
        "points": ("points", 70, [f"{p:,}" for p in zones.points[:n]]),
        "area": (f"area ({u}²)", 60, [f"{a / f**2:.3g}" for a in zones.area_m2[:n]]),
        "length": (f"length ({u})", 60, [f"{v / f:.3g}" for v in zones.length_m[:n]]),
        "width": (f"width ({u})", 60, [f"{v / f:.3g}" for v in zones.width_m[:n]]),
        "size": (f"length × width ({u})", 100,
                 [f"{a / f:.3g} × {b / f:.3g}"
                  for a, b in zip(zones.length_m[:n], zones.width_m[:n], strict=True)]),
        "trace": ("trace (az/plunge °)", 90,
                  [f"{azimuth_text(t)} / {p:02.0f}" for t, p in zip(zones.trace_azimuth_deg[:n],
                                                          zones.trace_plunge_deg[:n], strict=True)]),
        "dip": ("dip / direction (°)", 95,
                [f"{d:02.0f} / {azimuth_text(a)}" for d, a in zip(zones.dip_deg[:n],
                                                        zones.dip_direction_deg[:n], strict=True)]),
        "mean_theta": (f"mean θ ({ru})", 65, [f"{v / rf:.3g}" for v in zones.mean_theta[:n]]),
        "max_theta": (f"max θ ({ru})", 65, [f"{v / rf:.3g}" for v in zones.max_theta[:n]]),
        "centroid": (f"centroid x, y, z ({u})", 170,
                     [", ".join(f"{c / f:.2f}" for c in row) for row in zones.centroid[:n]]),
    }


#: Type size of the zone table, px: the compact table's seven columns share a panel
#: about 380 px wide in a 1280 x 800 window (12 px type clipped the "zone" header).
TABLE_FONT = 11

#: Columns of the full zone table (the report).
TABLE_COLUMNS: tuple[str, ...] = ("zone", "cells", "points", "area", "length", "width", "trace",
                                  "dip", "mean_theta", "max_theta", "centroid")
#: Columns of the compact table (a narrow panel, e.g. the app's Zones tab).
COMPACT_COLUMNS: tuple[str, ...] = ("zone", "cells", "area", "size", "trace", "dip",
                                    "mean_theta")


def zones_table_figure(
    zones: Zones,
    *,
    grid_size: float,
    axis: str,
    n_points: int,
    selected: int | None = None,
    max_rows: int = 50,
    columns: Sequence[str] = TABLE_COLUMNS,
    unit: str = "m",
) -> go.Figure:
    """The zone table, largest zone first (ids 1..Z), each id in its zone colour.

    Parameters
    ----------
    zones : Zones
        From :meth:`rough_viewer.structure.zones.ZoneLabeller.zones`.
    selected : int, optional
        A zone id whose row is highlighted.
    max_rows : int
        Rows shown (the largest zones); the title says how many there are.
    columns : sequence of str
        Which columns, in order (:data:`TABLE_COLUMNS`, the default, or
        :data:`COMPACT_COLUMNS`; also ``size``: length x width); ``zone`` first.
    unit : {"m", "mm", "ft", "us-ft"}
        Unit lengths are shown in (the input's); roughness in mm for metric input,
        else in ``unit``. The numbers in ``zones`` stay metres.
    """
    n = min(zones.n_zones, int(max_rows))
    ids = np.arange(1, n + 1)
    every = _table_columns(zones, n, unit)
    unknown = [c for c in columns if c not in every]
    if unknown or not columns or columns[0] != "zone":
        raise InputError(f"table columns must start with 'zone' and be among {', '.join(every)}")
    header = [every[c][0] for c in columns]
    cells = [every[c][2] for c in columns]
    row_fill = ["#fff3b0" if selected == i else "white" for i in ids]
    fill = [[colormaps.zone_colour(int(i)) for i in ids]] + [row_fill] * (len(header) - 1)
    font = [["white"] * n] + [["#222"] * n] * (len(header) - 1)
    fig = go.Figure(go.Table(
        columnwidth=[every[c][1] for c in columns],
        header={"values": header, "align": "left", "fill_color": "#e8e8e8",
                "font": {"size": TABLE_FONT}},
        cells={"values": cells, "align": "left", "fill_color": fill,
               "font": {"color": font, "size": TABLE_FONT}},
    ))
    more = f" (the {n} largest shown)" if n < zones.n_zones else ""
    fig.update_layout(
        title=_title(f"{_count(zones.n_zones, 'zone')}{more}: {_zone_settings(zones)}",
                     grid_size=grid_size, axis=axis, n_points=n_points, map_name=zones.map_name,
                     unit=unit),
        # rows are about 31 px; beyond 1000 px the table scrolls
        height=int(min(1000, 170 + 31 * max(n, 1))), margin={"l": 10, "r": 10, "t": 80, "b": 10},
    )
    return fig


def zones_map_figure(
    zones: Zones,
    result: GridRoughness,
    *,
    plane: Plane | None = None,
    raster: FaceRaster | None = None,
    unit: str = "m",
) -> go.Figure:
    """The zones on the face plane (the frame of the face maps): each zone in its
    colour, other cells with a value light grey, white where no cell has a value.

    Parameters
    ----------
    zones : Zones
        Zones of ``result``.
    result : GridRoughness
        The grid result (cell centres, the map, the caption's numbers).
    plane : Plane, optional
        The face plane; default the whole-cloud ODR plane ``result.whole_plane``.
    raster : FaceRaster, optional
        :func:`rough_viewer.grid.maps.face_raster` of the cell centres, if at hand.
    unit : {"m", "mm", "ft", "us-ft"}
        Unit of the face axes and the caption's grid size.
    """
    f, u = unit_scale(unit)
    g = result.grid.cell_size
    face = plane if plane is not None else result.whole_plane
    r = raster if raster is not None else face_raster(result.centre, face, g)
    if r.pixel.shape[0] != zones.labels.shape[0]:
        raise InputError("the raster and the zones are of different grids")
    ids = np.where(np.isfinite(result.values(zones.map_name)), zones.labels, np.nan)
    # a pixel shows the zone of its cells (the largest id where several meet)
    img = face_image(r, ids, reduce="max")
    image = img.image
    palette = colormaps.ZONE_PALETTE
    k = len(palette)
    with np.errstate(invalid="ignore"):
        slot = np.where(image > 0, (image - 1) % k + 1, image)  # 0 = no zone
    scale: list[list[float | str]] = []
    for i, colour in enumerate(["#e3e3e3", *palette]):
        scale += [[i / (k + 1), colour], [(i + 1) / (k + 1), colour]]
    rows, cols = image.shape
    aspect = rows / cols if cols else 0.3
    fig = go.Figure(go.Heatmap(
        z=slot, x=np.asarray(img.u) / f, y=np.asarray(img.v) / f, zmin=-0.5, zmax=k + 0.5,
        colorscale=scale, showscale=False, customdata=image,
        hovertemplate=f"u %{{x:.2f}} {u}, v %{{y:.2f}} {u}, zone %{{customdata}}<extra></extra>",
    ))
    fig.update_yaxes(scaleanchor="x", scaleratio=1, title_text=f"v, up the face ({u})")
    fig.update_xaxes(title_text=f"u, along the face ({u})")
    fig.update_layout(
        title=_title(f"Zones on the face plane: {_zone_settings(zones)}", grid_size=g,
                     axis=result.axis, n_points=result.n_points_total, map_name=zones.map_name,
                     unit=unit),
        height=int(110 + float(np.clip(900 * aspect, 160, 600)) + 70), width=1000,
        margin={"l": 60, "r": 10, "t": 90, "b": 40}, plot_bgcolor="white",
    )
    return fig


def _subset(n: int, limit: int) -> np.ndarray:
    """Evenly spaced indices of at most ``limit`` of ``n`` items."""
    if n <= limit:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, limit).round().astype(np.int64))


def _pole_hover(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(K, 2) dip and dip direction of the planes whose poles are at ``(x, y)``."""
    trend, plunge = trend_and_plunge(schmidt_inverse(x, y).reshape(-1, 3))
    return np.column_stack([90.0 - plunge, (trend + 180.0) % 360.0])


def stereonet_figure(
    net: Stereonet,
    *,
    grid_size: float,
    axis: str,
    n_points: int,
    highlight: Mapping[str, np.ndarray] | None = None,
    colours: Mapping[str, str] | None = None,
    what: str = "cell poles",
    max_poles: int = MAX_POLES_DRAWN,
    unit: str = "m",
) -> go.Figure:
    """Lower-hemisphere equal-area (Schmidt) stereonet: density contours of the poles
    at 1, 2, 4, 8 ... multiples of a uniform distribution (MUD), the poles, and
    highlighted subsets.

    Parameters
    ----------
    net : Stereonet
        From :func:`rough_viewer.grid.orientation.cell_stereonet` (or ``stereonet``).
    highlight : dict name -> array, optional
        Subsets of the poles drawn on top in their own colour: each a boolean mask or
        an index array over the cell rows (``net.rows`` refer to cells), e.g.
        ``{"zone 3": zones.labels == 3}``.
    colours : dict name -> colour, optional
        Colour of each highlighted subset (default: the zone palette in order).
    what : str
        What the poles are, for the title.
    max_poles : int
        Poles drawn per trace at most (an evenly spaced subset); the contours use all.
    unit : {"m", "mm", "ft", "us-ft"}
        Unit of the caption's grid size.
    """
    fig = go.Figure()
    if np.isfinite(net.density).any():
        # contours at 1, 2, 4, 8 ... MUD: log2 of the density, filled from 1 MUD up
        with np.errstate(divide="ignore", invalid="ignore"):
            level = np.log2(np.maximum(net.density, 2.0**-8))
        top = max(1, int(np.ceil(np.nanmax(level))))
        scale = colormaps.plotly_colorscale("magma")[::-1]
        scale = [[1.0 - float(pos), colour] for pos, colour in scale]
        scale[0] = [0.0, "rgb(255,255,255)"]
        fig.add_trace(go.Contour(
            x=net.nodes, y=net.nodes, z=level, colorscale=scale, opacity=0.7,
            zmin=0.0, zmax=float(top), connectgaps=False,
            contours={"coloring": "fill", "showlines": True, "start": 0.0, "end": float(top),
                      "size": 1.0},
            line={"width": 0.6, "color": "#666"},
            colorbar={"title": {"text": "MUD"}, "len": 0.6, "x": 1.02,
                      "tickvals": list(range(top + 1)),
                      "ticktext": [f"{2**k:g}" for k in range(top + 1)]},
            hoverinfo="skip", name="density",
        ))
    shown = _subset(net.n_poles, max_poles)
    fig.add_trace(go.Scatter(
        x=net.x[shown], y=net.y[shown], mode="markers", name=f"{what} ({net.n_poles:,})",
        marker={"size": 3, "color": "rgba(40,40,40,0.45)"},
        customdata=_pole_hover(net.x[shown], net.y[shown]),
        hovertemplate="plane dip %{customdata[0]:.0f}° / %{customdata[1]:03.0f}°<extra></extra>",
    ))
    for i, (name, subset) in enumerate((highlight or {}).items()):
        sel = np.asarray(subset)
        rows = np.flatnonzero(sel) if sel.dtype == bool else sel.astype(np.int64)
        on = np.flatnonzero(np.isin(net.rows, rows))
        count = on.shape[0]  # the legend counts every pole, not only those drawn
        on = on[_subset(count, max_poles)]
        colour = (colours or {}).get(name, colormaps.ZONE_PALETTE[i % len(colormaps.ZONE_PALETTE)])
        fig.add_trace(go.Scatter(
            x=net.x[on], y=net.y[on], mode="markers", name=f"{name} ({count:,})",
            marker={"size": 5, "color": colour, "line": {"width": 0.5, "color": "white"}},
            customdata=_pole_hover(net.x[on], net.y[on]),
            hovertemplate=(name + ": plane dip %{customdata[0]:.0f}° / "
                           "%{customdata[1]:03.0f}°<extra></extra>"),
        ))
    t = np.linspace(0.0, 2.0 * np.pi, 361)
    fig.add_trace(go.Scatter(x=np.sin(t), y=np.cos(t), mode="lines", hoverinfo="skip",
                             line={"color": "#222", "width": 1.5}, showlegend=False))
    fig.add_trace(go.Scatter(x=[-0.04, 0.04, None, 0.0, 0.0], y=[0.0, 0.0, None, -0.04, 0.04],
                             mode="lines", hoverinfo="skip", line={"color": "#222", "width": 1},
                             showlegend=False))
    for text, (x, y) in {"N": (0, 1.08), "E": (1.08, 0), "S": (0, -1.08), "W": (-1.08, 0)}.items():
        fig.add_annotation(x=x, y=y, text=text, showarrow=False, font={"size": 13})
    axis_style = {"range": [-1.15, 1.15], "visible": False}
    fig.update_xaxes(**axis_style)
    fig.update_yaxes(scaleanchor="x", scaleratio=1, **axis_style)
    fig.update_layout(
        title=_title(f"Stereonet of {what}: lower hemisphere, equal area; density "
                     f"σ {net.smoothing_deg:g}°", grid_size=grid_size, axis=axis,
                     n_points=n_points, map_name="odr", unit=unit),
        height=620, width=720, plot_bgcolor="white",
        margin={"l": 10, "r": 10, "t": 80, "b": 10},
        legend={"x": 0.0, "y": -0.02, "yanchor": "top", "orientation": "h"},
    )
    return fig
