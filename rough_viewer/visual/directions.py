"""Figures of roughness by direction: the rose, the per-direction table, the map of
circular windows, and the profile lines to draw on the rock.

Pure functions: the ``DIRECTIONS.csv`` table
(:func:`rough_viewer.directions.table.directions_table`, a dict of columns),
:class:`rough_viewer.tin.directional.WindowRoughness` or the profile sets in, a
plotly figure or plain arrays out. Azimuths are drawn as they are defined:
counter-clockwise from the face's ``u`` axis (0 degrees, to the right) towards its
``v`` axis (90 degrees, up).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import plotly.graph_objects as go

from rough_viewer.profiles.profile_sets import ProfileSet
from rough_viewer.tin.directional import WindowRoughness
from rough_viewer.visual import colormaps
from rough_viewer.visual.grid import format_number, title_block
from rough_viewer.vocabulary import PROFILE_COLOURS, InputError, roughness_scale, unit_scale

#: Values a rose can show: column of the table -> (label, its spread column or None,
#: a trace colour).
ROSE_VALUES: dict[str, tuple[str, str | None, str]] = {
    "h_mean": ("Hurst exponent H", "h_std", PROFILE_COLOURS[0]),
    "h_denoised_mean": ("H, de-noised", "h_denoised_std", PROFILE_COLOURS[1]),
    "d_mean": ("fractal dimension D", "d_std", PROFILE_COLOURS[0]),
    "jrc_mean": ("JRC estimate (Tse and Cruden 1979)", "jrc_std", PROFILE_COLOURS[2]),
    "z2_mean": ("Z2", "z2_std", PROFILE_COLOURS[2]),
    "rms_mean": ("profile RMS", "rms_std", PROFILE_COLOURS[3]),
    "theta_max_c1": ("θ*max/(C+1), degrees", None, PROFILE_COLOURS[3]),
    "delta_t": ("ΔT, degrees", None, PROFILE_COLOURS[4]),
}


def _closed(values: np.ndarray) -> np.ndarray:
    return np.concatenate([values, values[:1]])


def rose_figure(
    table: Mapping[str, np.ndarray],
    *,
    values: Sequence[str] = ("h_mean", "h_denoised_mean"),
    unit: str = "m",
    caption: str = "",
) -> go.Figure:
    """A rose: each value against azimuth on polar axes, mean +- one standard
    deviation of the profiles as a shaded band where the table has it.

    Parameters
    ----------
    table : dict of arrays
        ``directions_table`` (``azimuth_deg`` and the named columns).
    values : sequence of str
        Columns to draw (keys of :data:`ROSE_VALUES`); the TIN parameters
        (``theta_max_c1``, ``delta_t``) are directed, the profile values repeat
        every 180 degrees.
    unit : str
        Unit of the table's ``rms`` columns (shown in the roughness unit of it).
    caption : str
        Second title line (e.g. the input and point count).
    """
    az = np.asarray(table["azimuth_deg"], dtype=np.float64)
    fig = go.Figure()
    rf, ru = roughness_scale(unit)
    uf, _ = unit_scale(unit)
    for name in values:
        if name not in ROSE_VALUES:
            raise InputError(f"unknown rose value {name!r}; choose from {', '.join(ROSE_VALUES)}")
        if name not in table:
            continue
        label, spread, colour = ROSE_VALUES[name]
        scale = uf / rf if name.startswith("rms") else 1.0
        r = np.asarray(table[name], dtype=np.float64) * scale
        if name.startswith("rms"):
            label = f"{label}, {ru}"
        if spread is not None and spread in table:
            sd = np.nan_to_num(np.asarray(table[spread], dtype=np.float64) * scale)
            theta = np.concatenate([_closed(az), _closed(az)[::-1]])
            band = np.concatenate([_closed(r + sd), _closed(np.maximum(r - sd, 0))[::-1]])
            fig.add_trace(go.Scatterpolar(r=band, theta=theta, fill="toself", mode="lines",
                                          line={"width": 0}, fillcolor=colour, opacity=0.18,
                                          hoverinfo="skip", showlegend=False))
        fig.add_trace(go.Scatterpolar(r=_closed(r), theta=_closed(az), mode="lines+markers",
                                      name=label, line={"color": colour, "width": 2},
                                      hovertemplate="azimuth %{theta:.0f}°: %{r:.3g}"
                                      "<extra>" + label + "</extra>"))
    title = title_block("Roughness by direction", caption or "azimuth from the face's u axis "
                        "towards v; bands: ± one standard deviation over the profiles")
    fig.update_layout(title=title, margin={"t": 90, "l": 40, "r": 40, "b": 40},
                      height=ROSE_HEIGHT,  # a polar plot wants its width: no strip
                      polar={"angularaxis": {"rotation": 0, "direction": "counterclockwise",
                                             "dtick": 30},
                             "radialaxis": {"rangemode": "tozero"}},
                      legend={"orientation": "h", "y": -0.12})
    return fig


#: Columns of :func:`directions_table_figure` and their headers.
#: Headers break at ``<br>`` so that no line is wider than its column: eleven columns
#: share the 480 px panel (the app showed "zimuth", "rofiles", "RC stimate").
TABLE_FIGURE_COLUMNS = (
    ("azimuth_deg", "azi-<br>muth °"), ("profiles", "pro-<br>files"), ("h_mean", "H"),
    ("h_std", "± H"), ("d_mean", "D"), ("h_denoised_mean", "H de-<br>noised"),
    ("rms_mean", "RMS"), ("z2_mean", "Z2"), ("jrc_mean", "JRC<br>est."),
    ("theta_max_c1", "θ*max<br>/(C+1) °"), ("delta_t", "ΔT °"),
)
#: Height of the rose, px (at the app's 480 px panel: title, polar axes, legend).
ROSE_HEIGHT = 520
#: Font size and height of the table's header, px (two lines of header text).
TABLE_HEADER_FONT = 11
TABLE_HEADER_HEIGHT = 40


def directions_table_figure(table: Mapping[str, np.ndarray], *, unit: str = "m",
                            caption: str = "") -> go.Figure:
    """The per-direction table as a plotly table (RMS in the roughness unit)."""
    rf, ru = roughness_scale(unit)
    uf, _ = unit_scale(unit)
    heads, cells = [], []
    for key, head in TABLE_FIGURE_COLUMNS:
        if key not in table:
            continue
        v = np.asarray(table[key], dtype=np.float64)
        if key == "rms_mean":
            v = v * uf / rf
            head = f"RMS<br>{ru}"
        heads.append(f"<b>{head}</b>")
        cells.append([f"{x:g}" if key in ("azimuth_deg", "profiles") else format_number(x)
                      for x in v])
    fig = go.Figure(go.Table(header={"values": heads, "align": "right",
                                     "height": TABLE_HEADER_HEIGHT,
                                     "font": {"size": TABLE_HEADER_FONT}},
                             cells={"values": cells, "align": "right",
                                    "font": {"size": TABLE_HEADER_FONT}}))
    n = len(cells[0]) if cells else 0
    fig.update_layout(title=title_block("Roughness by direction: table", caption or
                                        "JRC estimates from each profile's Z2 (Tse and "
                                        "Cruden 1979); θ*max/(C+1), ΔT facing the direction"),
                      margin={"t": 80, "l": 10, "r": 10, "b": 10}, height=154 + 26 * n)
    return fig


def window_map_figure(windows: WindowRoughness, *, azimuth_deg: float | None = None,
                      value: str = "delta_t", unit: str = "m", colormap: str = "viridis",
                      caption: str = "") -> go.Figure:
    """The window map on the face plane: a disc per window, coloured by ``value``
    (``"delta_t"`` or ``"theta_max_c1"``) in one direction, or by its largest value
    over all directions (``azimuth_deg=None``), with a tick towards that direction."""
    if value not in ("delta_t", "theta_max_c1"):
        raise InputError(f"a window map shows delta_t or theta_max_c1, not {value!r}")
    data = getattr(windows, value)
    uf, u = unit_scale(unit)
    uv = windows.centre_uv / uf
    if azimuth_deg is None:
        filled = np.where(np.isfinite(data), data, -np.inf)
        k = np.argmax(filled, axis=1)
        shown = data[np.arange(data.shape[0]), k]
        direction = windows.azimuth_deg[k]
        what = f"largest {ROSE_VALUES[value][0]} over all directions"
    else:
        j = int(np.argmin(np.abs(((windows.azimuth_deg - azimuth_deg) + 180) % 360 - 180)))
        shown = data[:, j]
        direction = np.full(shown.shape, windows.azimuth_deg[j])
        what = f"{ROSE_VALUES[value][0]} at azimuth {windows.azimuth_deg[j]:g}"
    fig = go.Figure()
    fig.add_trace(go.Scatter(
        x=uv[:, 0], y=uv[:, 1], mode="markers", name=value,
        marker={"color": shown, "colorscale": colormaps.plotly_colorscale(colormap),
                "size": 10, "colorbar": {"title": "degrees"}},
        customdata=np.column_stack([direction, windows.area / uf**2]),
        hovertemplate="u %{x:.4g}, v %{y:.4g}: %{marker.color:.3g}° (azimuth "
                      "%{customdata[0]:.0f}°, area %{customdata[1]:.3g})<extra></extra>"))
    # a tick from each centre towards its direction, one radius long
    rad = np.radians(direction)
    r = windows.radius / uf
    tick = np.full((uv.shape[0] * 3, 2), np.nan)
    tick[0::3] = uv
    tick[1::3] = uv + r * np.column_stack([np.cos(rad), np.sin(rad)])
    fig.add_trace(go.Scatter(x=tick[:, 0], y=tick[:, 1], mode="lines", hoverinfo="skip",
                             line={"color": "#444", "width": 1}, showlegend=False))
    fig.update_layout(title=title_block("Directional roughness in windows", caption or
                                        f"{what}; {windows.n_windows:,} windows of radius "
                                        f"{windows.radius / uf:.3g} {u}"),
                      xaxis={"title": f"u ({u})", "scaleanchor": "y"},
                      yaxis={"title": f"v ({u})"}, margin={"t": 90}, showlegend=False)
    return fig


def profile_segments(sets: Sequence[ProfileSet], *, used_only: bool = True
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The profile lines to draw on the rock: ``(segments, azimuth)``, ``segments``
    (M, 2, 3) float32 start and end of each profile (file frame, metres: on the
    profile's fitted line, so on the rock on average) and ``azimuth`` (M,) the
    degrees of its set. Sets of one line direction (``a`` and ``a + 180``) are drawn
    once."""
    seen: set[float] = set()
    segs, az = [], []
    for s in sets:
        key = round(s.azimuth_deg % 180.0, 9)
        if key in seen:
            continue
        seen.add(key)
        keep = s.used if used_only else np.ones(s.n_profiles, dtype=bool)
        segs.append(np.stack([s.starts[keep], s.ends[keep]], axis=1))
        az.append(np.full(int(np.count_nonzero(keep)), s.azimuth_deg))
    if not segs:
        return np.empty((0, 2, 3), dtype=np.float32), np.empty(0)
    return np.concatenate(segs).astype(np.float32), np.concatenate(az)


def segment_colours(azimuth: np.ndarray, *, colormap: str = "viridis") -> np.ndarray:
    """(M, 2, 3) uint8 colours of :func:`profile_segments`, one per line direction
    (the colour map over 0-180 degrees), both ends alike."""
    a = np.mod(np.asarray(azimuth, dtype=np.float64), 180.0)
    rgb = colormaps.apply(a, colormap, vmin=0.0, vmax=180.0)
    return np.repeat(rgb[:, None, :], 2, axis=1)

