"""Plotly figures of joint sets: the stereonet with the pole density, the sets' peaks,
mean poles and cones, and the tables of the sets and of their planes; and the
colours of the points by set or by plane for the scene.

Pure functions: a :class:`rough_viewer.structure.sets.JointSets` in, a figure out; the
report uses them and the app's Sets view can. Set ``k`` is drawn in
:func:`rough_viewer.visual.colormaps.zone_colour` ``(k)`` (the zone palette), in
every figure and in the scene. The stereonet is
:func:`rough_viewer.visual.zones.stereonet_figure` with the sets drawn on top.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import plotly.graph_objects as go

from rough_viewer.grid.orientation import schmidt, trend_and_plunge
from rough_viewer.structure.sets import JointSets
from rough_viewer.visual import colormaps
from rough_viewer.visual.grid import describe
from rough_viewer.visual.zones import MAX_POLES_DRAWN, azimuth_text, stereonet_figure
from rough_viewer.vocabulary import InputError, unit_scale

#: What one coloured pole of the Sets stereonet stands for.
PolesOf = Literal["cell", "patch", "joint"]
#: Font size, header height and row height of the tables, px: the headers break at
#: ``<br>`` so that every line fits its column in the app's panel (about 540 px at a
#: 1600 x 1000 window; issue 31 item 4).
TABLE_FONT = 11
TABLE_HEADER_HEIGHT = 40
TABLE_ROW_HEIGHT = 24
#: What plotly draws of a row of ``height`` px: 4 px more (its borders).
TABLE_ROW_EXTRA = 4
#: Height of each further line of a cell's text, px.
TABLE_LINE_HEIGHT = 16
#: Longest centroid text (characters) that fits one line of its column.
CENTROID_ONE_LINE = 24


def set_colour(set_id: int) -> str:
    """``"#rrggbb"`` of set ``set_id`` (1..S; grey for 0, in no set)."""
    return colormaps.zone_colour(set_id)


ColourBy = Literal["set", "joint", "plane"]


def cell_labels(sets: JointSets, by: ColourBy = "set") -> np.ndarray:
    """``(M,)`` label of every cell to colour by: its set, its joint or its plane
    (patch), 0 for none."""
    if by not in ("set", "joint", "plane"):
        raise InputError(f"colour by set, joint or plane, not {by!r}")
    return {"set": sets.cell_set, "joint": sets.cell_joint, "plane": sets.cell_plane}[by]


def point_colours(sets: JointSets, point_cell: np.ndarray, *,
                  by: ColourBy = "set") -> np.ndarray:
    """``(N, 3)`` uint8 colours of points by the set (or the joint, or the plane) of
    their cell: the scene's colours for a Sets view (grey in none)."""
    return colormaps.zone_colours(cell_labels(sets, by)[np.asarray(point_cell)])


def _title(what: str, sets: JointSets, *, axis: str, n_points: int, unit: str) -> dict:
    sub = describe(grid_size=sets.cell_size, axis=axis, n_points=n_points, models=("odr",),
                   unit=unit)
    return {"text": f"{what}<br><sup>{sub}</sup>", "x": 0.01, "xanchor": "left"}


def _settings(sets: JointSets, unit: str) -> str:
    f, u = unit_scale(unit)
    o = sets.options
    return (f"planar: ODR θ ≤ {sets.max_roughness / f:.3g} {u}, ≥ {o.min_planar_points} points; "
            f"peaks ≥ {o.min_density:g} MUD, ≥ {o.min_angle_deg:g}° apart; "
            f"cone {o.cone_deg:g}°")


def cone_outline(axis: np.ndarray, angle_deg: float, n: int = 181) -> tuple[np.ndarray, np.ndarray]:
    """The small circle of ``angle_deg`` about a (unit) axis on the lower-hemisphere
    Schmidt net: ``(x, y)`` with NaN where it crosses the primitive circle (the part
    above the horizon shows through the antipode, on the net's other side)."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    t = np.linspace(0.0, 2.0 * np.pi, n)
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    d = c * a + s * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)
    trend, plunge = trend_and_plunge(d)  # downward senses: the lower hemisphere
    x, y = schmidt(trend, plunge)
    jump = np.flatnonzero(np.hypot(np.diff(x), np.diff(y)) > 0.5)
    x, y = np.insert(x, jump + 1, np.nan), np.insert(y, jump + 1, np.nan)
    return x, y


def sets_stereonet_figure(
    sets: JointSets,
    *,
    axis: str,
    n_points: int,
    selected: int | None = None,
    max_poles: int = MAX_POLES_DRAWN,
    unit: str = "m",
    poles: PolesOf = "cell",
    selected_joint: int | None = None,
) -> go.Figure:
    """The stereonet of the planar cells' poles (density weighted by points, contours
    in MUD) with every set's poles in its colour, its density peak (star), its Fisher
    mean pole (circle) and its cone.

    Parameters
    ----------
    sets : JointSets
        From :func:`rough_viewer.structure.sets.joint_sets`.
    axis, n_points : str, int
        The caption's dependent axis and point count.
    selected : int, optional
        A set id drawn with a thicker cone (the others stay).
    max_poles : int
        Poles drawn per trace at most; the density uses every pole.
    unit : {"m", "mm", "ft", "us-ft"}
        Unit of the caption's lengths.
    poles : {"cell", "patch", "joint"}
        The coloured poles: every planar cell's (the density's), or one per plane
        (patch) or one per joint (its plane fitted to all its points), in its set's
        colour; the density stays that of the cells.
    selected_joint : int, optional
        A joint id whose pole is drawn larger (with ``poles="joint"``).
    """
    if poles not in ("cell", "patch", "joint"):
        raise InputError(f"poles per cell, patch or joint, not {poles!r}")
    names = {k: f"set {k}" for k in range(1, sets.n_sets + 1)}
    fig = stereonet_figure(
        sets.net, grid_size=sets.cell_size, axis=axis, n_points=n_points,
        highlight={names[k]: sets.cell_set == k for k in names} if poles == "cell" else {},
        colours={names[k]: set_colour(k) for k in names}, what="planar-cell poles",
        max_poles=max_poles, unit=unit)
    if poles != "cell":
        _one_pole_each(fig, sets, poles, selected_joint)
    for k in names:
        colour = set_colour(k)
        cx, cy = cone_outline(sets.peak[k - 1], sets.cone_deg)
        fig.add_trace(go.Scatter(
            x=cx, y=cy, mode="lines", hoverinfo="skip", showlegend=False,
            line={"color": colour, "width": 3.0 if selected == k else 1.5,
                  "dash": "solid" if selected in (None, k) else "dot"}))
        pt, pp = trend_and_plunge(sets.peak[k - 1:k])
        px, py = schmidt(pt, pp)
        mt, mp = trend_and_plunge(sets.mean_pole[k - 1:k])
        mx, my = schmidt(mt, mp)
        fig.add_trace(go.Scatter(
            x=[px[0], mx[0]], y=[py[0], my[0]], mode="markers", showlegend=False,
            marker={"symbol": ["star", "circle-open"], "size": [15, 12], "color": colour,
                    "line": {"width": [1, 2.5], "color": ["black", colour]}},
            hovertext=[f"set {k}: density peak {sets.peak_density[k - 1]:.1f} MUD",
                       f"set {k}: mean plane {sets.dip_deg[k - 1]:02.0f} / "
                       f"{azimuth_text(sets.dip_direction_deg[k - 1])}, κ "
                       f"{sets.kappa[k - 1]:.0f}"],
            hoverinfo="text"))
    what = (f"{sets.n_sets} joint set{'s' if sets.n_sets != 1 else ''}" if sets.n_sets
            else "No joint set")
    fig.update_layout(title=_title(
        f"{what}: planar-cell poles, lower hemisphere, equal area; density σ "
        f"{sets.net.smoothing_deg:g}°, weighted by points<br><sup>{_settings(sets, unit)}</sup>",
        sets, axis=axis, n_points=n_points, unit=unit), margin={"l": 10, "r": 10, "t": 110, "b": 10})
    return fig


def _one_pole_each(fig: go.Figure, sets: JointSets, poles: PolesOf,
                   selected_joint: int | None) -> None:
    """One pole per plane (patch) or per joint, a trace per set in its colour."""
    if poles == "joint":
        jt = sets.joints
        set_id, normal, dip, dd, what = (jt.set_id, jt.normal, jt.dip_deg,
                                         jt.dip_direction_deg, "joint")
        extra = [f"{p:,} patch{'es' if p != 1 else ''}" for p in jt.patches]
    else:
        pl = sets.planes
        set_id, normal, dip, dd, what = (pl.set_id, pl.normal, pl.dip_deg,
                                         pl.dip_direction_deg, "plane")
        extra = [f"joint {j}" for j in pl.joint_id]
    if set_id.shape[0] == 0:
        return
    # the pole: the downward normal (lower hemisphere)
    down = np.where((normal[:, 2] > 0)[:, None], -normal, normal)
    trend, plunge = trend_and_plunge(down)
    x, y = schmidt(trend, plunge)
    ids = np.arange(1, set_id.shape[0] + 1)
    for k in range(1, sets.n_sets + 1):
        on = np.flatnonzero(set_id == k)
        big = (ids[on] == selected_joint) if poles == "joint" else np.zeros(on.shape[0], bool)
        fig.add_trace(go.Scatter(
            x=x[on], y=y[on], mode="markers", name=f"set {k}: {on.shape[0]:,} {what}"
            f"{'s' if on.shape[0] != 1 else ''}",
            marker={"size": np.where(big, 16, 8).tolist(), "color": set_colour(k),
                    "symbol": "diamond" if poles == "joint" else "circle",
                    "line": {"width": np.where(big, 2.5, 0.8).tolist(), "color": "black"}},
            hovertext=[f"{what} {ids[i]} (set {k}): {dip[i]:02.0f} / "
                       f"{azimuth_text(dd[i])}, {extra[i]}" for i in on],
            hoverinfo="text"))


def _coloured_table(ids: np.ndarray, header: Sequence[str], cells: Sequence[list[str]],
                    widths: Sequence[int], id_colour: np.ndarray, selected: np.ndarray,
                    row_height: int = TABLE_ROW_HEIGHT) -> go.Table:
    """A table whose first column is the ids in their colours, selected rows yellow."""
    n = ids.shape[0]
    row_fill = ["#fff3b0" if s else "white" for s in selected]
    fill = [[set_colour(int(c)) for c in id_colour]] + [row_fill] * (len(header) - 1)
    font = [["white"] * n] + [["#222"] * n] * (len(header) - 1)
    return go.Table(columnwidth=list(widths),
                    header={"values": list(header), "align": "left", "fill_color": "#e8e8e8",
                            "height": TABLE_HEADER_HEIGHT, "font": {"size": TABLE_FONT}},
                    cells={"values": list(cells), "align": "left", "fill_color": fill,
                           "height": row_height,
                           "font": {"color": font, "size": TABLE_FONT}})


def _dip(dip: np.ndarray, dd: np.ndarray) -> list[str]:
    """``60/030``: dip / dip direction as the terminal prints them (no space to break
    the cell's line at in a narrow column)."""
    return [f"{d:02.0f}/{azimuth_text(a)}" for d, a in zip(dip, dd, strict=True)]


def _num(values: np.ndarray, scale: float = 1.0, fmt: str = ".3g") -> list[str]:
    return ["–" if not np.isfinite(v) else format(v / scale, fmt) for v in values]


def sets_table_figure(
    sets: JointSets,
    *,
    axis: str,
    n_points: int,
    selected: int | None = None,
    unit: str = "m",
) -> go.Figure:
    """The set table: one row per set in its colour: mean plane dip / dip direction,
    Fisher kappa and alpha95, planes (patches), joints, joint spacing (normal mean and
    median, scanline mean), mean persistence in ``unit`` (the numbers in ``sets`` stay
    metres) and the angle to the exposure face (⚠ on a set parallel to it)."""
    f, u = unit_scale(unit)
    n = sets.n_sets
    ids = np.arange(1, n + 1)
    # the lengths' unit once, under the title: eleven columns share a 460 px panel (the
    # cells and the spacing's std are in SETS.csv)
    header = ["set", "dip / dir.<br>(°)", "κ", "α95<br>(°)", "pat-<br>ches", "joints",
              "spacing<br>mean", "me-<br>dian", "scan-<br>line", "persist-<br>ence",
              "face<br>(°)"]
    face = sets.face_parallel
    # a set parallel to the exposure face: ⚠ by its id, its angle and its spacings
    # (no joint spacing; issue 31 item 2)
    warn = np.where(face, " ⚠", "")
    cells = [[f"<b>{i}</b>{w}" for i, w in zip(ids, warn, strict=True)],
             _dip(sets.dip_deg, sets.dip_direction_deg),
             _num(sets.kappa, fmt=".0f"), _num(sets.alpha95_deg, fmt=".2f"),
             [f"{c:,}" for c in sets.n_planes_per_set],
             [f"{c:,}" for c in sets.n_joints_per_set],
             *([v + w for v, w in zip(_num(col, f), warn, strict=True)]
               for col in (sets.spacing_mean, sets.spacing_median,
                           sets.spacing_scanline_mean)),
             _num(sets.persistence_mean, f),
             [v + (" ⚠ face" if w else "") for v, w in
              zip(_num(sets.face_angle_deg, fmt=".1f"), warn, strict=True)]]
    # "1.0 ⚠ face" takes two lines of its column
    row_height = TABLE_ROW_HEIGHT + (TABLE_LINE_HEIGHT if face.any() else 0)
    table = _coloured_table(ids, header, cells,
                            [30, 49, 28, 31, 34, 37, 50, 46, 46, 48, 52],
                            ids, ids == selected, row_height)
    fig = go.Figure(table)
    what = f"{n} joint set{'s' if n != 1 else ''}" if n else sets.note[:1].upper() + sets.note[1:]
    if face.any():
        listed = ", ".join(str(i) for i in ids[face])
        what += f" (⚠ {listed}: exposure face)"
    fig.update_layout(title=_title(f"{what}<br><sup>lengths in {u}; {_settings(sets, unit)}"
                                   "</sup>", sets,
                                   axis=axis, n_points=n_points, unit=unit),
                      height=int(min(600, 170 + (row_height + TABLE_ROW_EXTRA) * max(n, 1))),
                      margin={"l": 10, "r": 10, "t": 100, "b": 10})
    return fig


def planes_table_figure(
    sets: JointSets,
    *,
    axis: str,
    n_points: int,
    set_id: int | None = None,
    selected: int | None = None,
    max_rows: int = 50,
    unit: str = "m",
) -> go.Figure:
    """The plane table: one row per plane (of every set, or of ``set_id``), the id in
    its set's colour: set, dip / dip direction, centroid, area, persistence along
    dip x strike, RMS and cells; lengths in ``unit``. ``selected`` is a plane id
    whose row is highlighted; at most ``max_rows`` rows (the title says how many
    there are)."""
    f, u = unit_scale(unit)
    pl = sets.planes
    if set_id is not None and not 1 <= set_id <= max(sets.n_sets, 1):
        raise InputError(f"no set {set_id}: there are {sets.n_sets}")
    rows = np.arange(pl.n_planes) if set_id is None else np.flatnonzero(pl.set_id == set_id)
    total = rows.shape[0]
    rows = rows[:max(int(max_rows), 0)]
    ids = rows + 1
    header = ["plane", "set", "dip / dir.<br>(°)", f"centroid x, y, z<br>({u})",
              f"area<br>({u}²)", f"dip × strike<br>({u})", f"rms<br>({u})", "cells"]
    centroid = [", ".join(f"{c / f:.2f}" for c in row) for row in pl.centroid[rows]]
    # a centroid of map coordinates (UTM: 239163.87, 3765268.97, ...) takes two lines
    lines = 2 if max((len(t) for t in centroid), default=0) > CENTROID_ONE_LINE else 1
    row_height = TABLE_ROW_HEIGHT + (lines - 1) * TABLE_LINE_HEIGHT
    cells = [[f"<b>{i}</b>" for i in ids], [str(s) for s in pl.set_id[rows]],
             _dip(pl.dip_deg[rows], pl.dip_direction_deg[rows]), centroid,
             _num(pl.area[rows], f * f),
             [f"{a / f:.3g}\u00a0×\u00a0{b / f:.3g}" for a, b in
              zip(pl.persistence_dip[rows], pl.persistence_strike[rows], strict=True)],
             _num(pl.rms[rows], f), [f"{c:,}" for c in pl.cells[rows]]]
    table = _coloured_table(ids, header, cells, [38, 26, 48, 126, 44, 84, 50, 38],
                            pl.set_id[rows], ids == selected, row_height)
    return _listing(table, "plane", total, rows.shape[0], set_id, row_height, sets,
                    axis=axis, n_points=n_points, unit=unit)


def joints_table_figure(
    sets: JointSets,
    *,
    axis: str,
    n_points: int,
    set_id: int | None = None,
    selected: int | None = None,
    max_rows: int = 50,
    unit: str = "m",
) -> go.Figure:
    """The joint table: one row per joint (of every set, or of ``set_id``), the id in
    its set's colour: set, dip / dip direction, patches, area, trace length,
    persistence along dip x strike and RMS; lengths in ``unit``. ``selected`` is a
    joint id whose row is highlighted and listed first; at most ``max_rows`` rows
    (the title says how many there are)."""
    f, u = unit_scale(unit)
    jt = sets.joints
    if set_id is not None and not 1 <= set_id <= max(sets.n_sets, 1):
        raise InputError(f"no set {set_id}: there are {sets.n_sets}")
    rows = np.arange(jt.n_joints) if set_id is None else np.flatnonzero(jt.set_id == set_id)
    total = rows.shape[0]
    if selected is not None and selected - 1 in rows:
        rows = np.concatenate([[selected - 1], rows[rows != selected - 1]])
    rows = rows[:max(int(max_rows), 0)]
    ids = rows + 1
    header = ["joint", "set", "dip / dir.<br>(°)", "pat-<br>ches", f"area<br>({u}²)",
              f"trace<br>length ({u})", f"persistence<br>dip × strike ({u})", f"rms<br>({u})"]
    cells = [[f"<b>{i}</b>" for i in ids], [str(s) for s in jt.set_id[rows]],
             _dip(jt.dip_deg[rows], jt.dip_direction_deg[rows]),
             [f"{c:,}" for c in jt.patches[rows]], _num(jt.area[rows], f * f),
             _num(jt.trace_length[rows], f),
             [f"{a / f:.3g}\u00a0×\u00a0{b / f:.3g}" for a, b in
              zip(jt.persistence_dip[rows], jt.persistence_strike[rows], strict=True)],
             _num(jt.rms[rows], f)]
    table = _coloured_table(ids, header, cells, [40, 30, 60, 40, 50, 60, 100, 56],
                            jt.set_id[rows], ids == selected)
    return _listing(table, "joint", total, rows.shape[0], set_id, TABLE_ROW_HEIGHT, sets,
                    axis=axis, n_points=n_points, unit=unit)


def _listing(table: go.Table, noun: str, total: int, shown: int, set_id: int | None,
             row_height: int, sets: JointSets, *, axis: str, n_points: int,
             unit: str) -> go.Figure:
    """The figure of a plane or joint table: its title says how many ``noun`` there
    are (of set ``set_id``) and how many are shown; as high as its rows, at most
    1,000 px."""
    fig = go.Figure(table)
    scope = "" if set_id is None else f" of set {set_id}"
    more = f" (the first {shown} shown)" if shown < total else ""
    fig.update_layout(title=_title(f"{total:,} {noun}{'s' if total != 1 else ''}{scope}{more}",
                                   sets, axis=axis, n_points=n_points, unit=unit),
                      height=int(min(1000, 140 + (row_height + TABLE_ROW_EXTRA)
                                     * max(shown, 1))),
                      margin={"l": 10, "r": 10, "t": 80, "b": 10})
    return fig
