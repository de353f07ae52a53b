"""Tests of rough_viewer.visual.sets: the figures carry the sets' numbers, peaks and
cones in the sets' colours."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.orientation import schmidt_inverse
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.structure.sets import joint_sets
from rough_viewer.synthetic.joints import JointBlockSpec, generate_joint_block
from rough_viewer.visual import colormaps
from rough_viewer.visual.sets import (
    cone_outline,
    joints_table_figure,
    planes_table_figure,
    point_colours,
    set_colour,
    sets_stereonet_figure,
    sets_table_figure,
)
from rough_viewer.vocabulary import InputError


@pytest.fixture(scope="module")
def found():
    scan = generate_joint_block(JointBlockSpec(angular_step_rad=3e-3))
    res = grid_roughness(scan.cloud, 0.5, models=("odr",))
    return res, joint_sets(res, scan.cloud)


def kw(res):
    return {"axis": res.axis, "n_points": res.n_points_total}


def test_cone_outline_is_the_small_circle_on_the_lower_hemisphere():
    axis = np.array([0.3, -0.8, -0.52])
    axis /= np.linalg.norm(axis)
    x, y = cone_outline(axis, 20.0)
    ok = np.isfinite(x)
    d = schmidt_inverse(x[ok], y[ok]).reshape(-1, 3)
    angle = np.degrees(np.arccos(np.clip(np.abs(d @ axis), 0, 1)))
    assert angle == pytest.approx(20.0, abs=1e-6)
    assert np.all(np.hypot(x[ok], y[ok]) <= 1.0 + 1e-12)
    # a cone that crosses the horizon breaks where it leaves the net and comes back
    flat = np.array([1.0, 0.0, -0.05])
    fx, _ = cone_outline(flat / np.linalg.norm(flat), 20.0)
    assert np.isnan(fx).sum() >= 1


def test_stereonet_draws_every_set_its_peak_mean_and_cone(found):
    res, sets = found
    fig = sets_stereonet_figure(sets, selected=2, **kw(res))
    names = [t.name for t in fig.data]
    for k in range(1, sets.n_sets + 1):
        assert f"set {k} ({sets.cells[k - 1]:,})" in names  # the poles that made it
    scatter = [t for t in fig.data if t.type == "scatter"]
    markers = [t for t in scatter if t.mode == "markers" and t.hovertext is not None]
    assert len(markers) == sets.n_sets
    for k, t in enumerate(markers, start=1):
        assert t.marker.color == set_colour(k)
        assert f"{sets.peak_density[k - 1]:.1f} MUD" in t.hovertext[0]
        assert f"{sets.dip_deg[k - 1]:02.0f} / " in t.hovertext[1]
    lines = [t for t in scatter if t.mode == "lines" and t.line.color in
             {set_colour(k) for k in range(1, sets.n_sets + 1)}]
    assert len(lines) == sets.n_sets
    assert [t.line.width for t in lines] == [3.0 if k == 2 else 1.5 for k in range(1, 4)]
    text = fig.layout.title.text
    assert "3 joint sets" in text and "cone 20°" in text and "grid 0.5 m" in text


def test_tables_hold_the_numbers_in_the_display_unit(found):
    res, sets = found
    fig = sets_table_figure(sets, selected=1, unit="mm", **kw(res))
    cols = fig.data[0].cells.values
    assert list(cols[0]) == ["<b>1</b>", "<b>2</b>", "<b>3</b>"]
    assert cols[1][0] == f"{sets.dip_deg[0]:02.0f}/{int(round(sets.dip_direction_deg[0])) % 360:03d}"
    assert list(cols[5]) == [f"{c:,}" for c in sets.n_joints_per_set]
    assert cols[6][1] == f"{sets.spacing_mean[1] * 1000:.3g}"
    assert cols[8][1] == f"{sets.spacing_scanline_mean[1] * 1000:.3g}"
    assert list(fig.data[0].cells.fill.color[0]) == [set_colour(k) for k in (1, 2, 3)]
    assert fig.data[0].cells.fill.color[1][0] != fig.data[0].cells.fill.color[1][1]
    planes = planes_table_figure(sets, set_id=2, **kw(res))
    pc = planes.data[0].cells.values
    mine = np.flatnonzero(sets.planes.set_id == 2)
    assert list(pc[0]) == [f"<b>{i + 1}</b>" for i in mine]
    assert set(pc[1]) == {"2"}
    assert pc[4][0] == f"{sets.planes.area[mine[0]]:.3g}"
    assert f"{len(mine)} planes of set 2" in planes.layout.title.text
    short = planes_table_figure(sets, max_rows=2, **kw(res))
    assert len(short.data[0].cells.values[0]) == 2 and "first 2 shown" in short.layout.title.text
    with pytest.raises(InputError):
        planes_table_figure(sets, set_id=9, **kw(res))


def test_no_set_says_why(found):
    res, _ = found
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(0, 4, (30_000, 2)), 0.05 * rng.standard_normal(30_000)])
    r = grid_roughness(pts, 0.25, models=("odr",))
    none = joint_sets(r, pts)
    assert "No joint set" in sets_stereonet_figure(none, **kw(r)).layout.title.text
    assert "no joint set" in sets_table_figure(none, **kw(r)).layout.title.text.lower()
    assert len(planes_table_figure(none, **kw(r)).data[0].cells.values[0]) == 0


def test_point_colours_by_set_and_by_plane(found):
    res, sets = found
    by_set = point_colours(sets, res.point_cell)
    assert np.array_equal(by_set, colormaps.zone_colours(sets.cell_set[res.point_cell]))
    by_plane = point_colours(sets, res.point_cell, by="plane")
    assert np.array_equal(by_plane, colormaps.zone_colours(sets.cell_plane[res.point_cell]))


def test_point_colours_by_joint(found):
    res, sets = found
    by_joint = point_colours(sets, res.point_cell, by="joint")
    assert np.array_equal(by_joint, colormaps.zone_colours(sets.cell_joint[res.point_cell]))
    with pytest.raises(InputError):
        point_colours(sets, res.point_cell, by="zone")  # type: ignore[arg-type]


def test_the_joint_table_lists_a_sets_joints_selected_first(found):
    res, sets = found
    jt = sets.joints
    mine = np.flatnonzero(jt.set_id == 2)
    assert mine.size >= 2
    pick = int(mine[-1]) + 1
    fig = joints_table_figure(sets, set_id=2, selected=pick, unit="mm", **kw(res))
    c = fig.data[0].cells.values
    assert list(c[0]) == [f"<b>{pick}</b>"] + [f"<b>{i + 1}</b>" for i in mine[:-1]]
    assert set(c[1]) == {"2"}
    k = pick - 1
    assert c[2][0] == f"{jt.dip_deg[k]:02.0f}/{int(round(jt.dip_direction_deg[k])) % 360:03d}"
    assert c[3][0] == f"{jt.patches[k]:,}"
    assert c[4][0] == f"{jt.area[k] * 1e6:.3g}"
    assert c[5][0] == f"{jt.trace_length[k] * 1000:.3g}"
    assert fig.data[0].cells.fill.color[1][0] == "#fff3b0"  # the selected row
    assert f"{mine.size} joints of set 2" in fig.layout.title.text
    with pytest.raises(InputError):
        joints_table_figure(sets, set_id=9, **kw(res))


def test_the_stereonet_shows_one_pole_per_joint_where_its_plane_points(found):
    """Each joint's pole sits at the Schmidt point of the pole of its dip / dip
    direction (trend = dip direction + 180, plunge = 90 - dip)."""
    res, sets = found
    jt = sets.joints
    fig = sets_stereonet_figure(sets, poles="joint", selected_joint=1, **kw(res))
    traces = [t for t in fig.data if t.type == "scatter" and t.name and "joint" in t.name]
    assert len(traces) == sets.n_sets
    assert sum(len(t.x) for t in traces) == jt.n_joints
    for k, t in enumerate(traces, start=1):
        assert t.marker.color == set_colour(k)
        mine = np.flatnonzero(jt.set_id == k)
        down = schmidt_inverse(np.asarray(t.x), np.asarray(t.y))
        trend = np.radians(jt.dip_direction_deg[mine] + 180.0)
        plunge = np.radians(90.0 - jt.dip_deg[mine])
        want = np.column_stack([np.sin(trend) * np.cos(plunge), np.cos(trend) * np.cos(plunge),
                                -np.sin(plunge)])
        np.testing.assert_allclose(np.abs(np.sum(down * want, axis=1)), 1.0, atol=1e-9)
    # the selected joint is drawn larger; with per-cell poles no per-joint trace
    sizes = np.concatenate([np.asarray(t.marker.size) for t in traces])
    assert sorted(sizes)[-1] == 16 and np.count_nonzero(sizes == 16) == 1
    cells = sets_stereonet_figure(sets, **kw(res))
    assert not [t for t in cells.data if t.name and "joint" in str(t.name)]
    patches = sets_stereonet_figure(sets, poles="patch", **kw(res))
    assert sum(len(t.x) for t in patches.data
               if t.name and "plane" in str(t.name)) == sets.planes.n_planes
    with pytest.raises(InputError):
        sets_stereonet_figure(sets, poles="zone", **kw(res))  # type: ignore[arg-type]
