"""Issue 26 in the app: the Sets tab finds the joint sets of the shown grid (the
library's, with the tab's settings), colours the rock by set or plane, takes clicks,
and shares the points with the zones (one colours them at a time)."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.app.features.sets import NO_SET, SetsFeature, set_option
from rough_viewer.app.features.zones import ZonesFeature
from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.structure.sets import SetOptions, joint_sets
from rough_viewer.synthetic.joints import JOINT_BLOCK, generate_joint_block
from rough_viewer.visual.sets import point_colours
from tests.app.protocol import pick, shown_colours

G = 0.25


@pytest.fixture(scope="module")
def block():
    return generate_joint_block(JOINT_BLOCK)


@pytest.fixture
def sapp(server, block):
    app = build_app(server, block.cloud, prefetch=False, variogram=False, presets=(G,),
                    settings=MapSettings(cell_size=G), max_display=60_000)
    assert app.wait_idle(120)
    f = app.feature(SetsFeature)
    f.on.value = True
    assert app.wait_idle(120)
    yield app, f
    app.stop()


def test_the_planted_sets_are_found_and_the_rock_coloured_by_them(sapp, block):
    app, f = sapp
    res = app.session.shown.result
    ref = joint_sets(res, block.cloud, SetOptions(max_roughness=0.02 * G))
    assert f.sets is not None and f.sets.n_sets == ref.n_sets == 3
    np.testing.assert_array_equal(f.sets.cell_set, ref.cell_set)
    loaded = app.session.shown.loaded
    np.testing.assert_array_equal(shown_colours(app),
                                  point_colours(ref, res.point_cell[loaded.display_index]))
    assert app.map.overlay is f
    assert not app.map.colour_bar.visible
    assert "**3 sets**" in f.status.content
    assert f.selected.options == (NO_SET, *(set_option(ref, k) for k in (1, 2, 3)))
    assert "3 joint sets" in f.table.figure.layout.title.text
    f.colour_by.value = "patch"  # the same sets, coloured by patch (plane)
    assert app.wait_idle(60)
    np.testing.assert_array_equal(
        shown_colours(app), point_colours(ref, res.point_cell[loaded.display_index], by="plane"))
    f.on.value = False
    assert app.wait_idle(60)
    assert app.map.overlay is None


def test_a_click_selects_the_set_under_it_and_its_planes_are_listed(sapp):
    app, f = sapp
    res = app.session.shown.result
    loaded = app.session.shown.loaded
    per_point = f.sets.cell_set[res.point_cell[loaded.display_index]]
    row = int(np.flatnonzero(per_point == 2)[0])
    target = loaded.display_points[row].astype(float)
    normal = f.sets.normal[1]
    assert pick(app, target + 3.0 * normal, -normal) is None  # the tab took it
    assert f.selected_set == 2 and f.selected.value == f.selected.options[2]
    assert "set 2" in f.planes.figure.layout.title.text.lower()
    f.selected.value = NO_SET
    assert app.wait_idle(60)
    assert f.selected_set == 0


def test_zones_and_sets_take_turns_on_the_points(sapp):
    app, f = sapp
    z = app.feature(ZonesFeature)
    z.on.value = True  # the zones take the points: the sets let go
    assert app.wait_idle(60)
    assert not f.on.value and app.map.overlay is z
    f.on.value = True  # and back
    assert app.wait_idle(60)
    assert not z.on.value and app.map.overlay is f


def test_the_tab_settings_reach_the_sets(sapp, block):
    """A narrower cone and a stricter planar share give the library's sets with those
    settings (fewer cells in sets)."""
    app, f = sapp
    before = int(f.sets.cells.sum())
    f.cone.value = 8.0
    f.roughness.value = 1.0  # % of the cell
    assert app.wait_idle(60)
    res = app.session.shown.result
    ref = joint_sets(res, block.cloud, SetOptions(max_roughness=0.01 * G, cone_deg=8.0))
    np.testing.assert_array_equal(f.sets.cell_set, ref.cell_set)
    assert int(f.sets.cells.sum()) < before


def test_the_cell_table_download_carries_the_sets_shown(sapp, block):
    """Issue 31 item 3: while sets are shown, Download cell table has ``set_id`` and
    ``plane_id`` (0 = none), each row its cell's, as ``sets --cells-out`` writes them,
    and Download points (LAZ) each point's, as ``sets --las-out``."""
    import csv
    import io

    import laspy

    from rough_viewer.app.features import export as em
    from tests.app.protocol import ProtocolClient

    app, f = sapp
    res = app.session.shown.result
    ref = joint_sets(res, block.cloud, SetOptions(max_roughness=0.02 * G))
    keep = res.n_points >= res.min_points
    client = ProtocolClient(app.server.get_port())
    try:
        client.wait_for(lambda m: m.get("type") == "GuiButtonMessage"
                        and m["props"].get("label") == em.L_TABLE, what="the Export folder")
        mark = len(client.messages)
        client.press(em.L_TABLE)
        data = client.wait_download("_cells.csv", since=mark)[1]
        assert app.wait_idle(60)
        mark = len(client.messages)
        client.press(em.L_POINTS)
        laz = laspy.read(io.BytesIO(client.wait_download("_points.laz", since=mark)[1]))
    finally:
        client.close()
    np.testing.assert_array_equal(np.asarray(laz["set_id"]), ref.cell_set[res.point_cell])
    np.testing.assert_array_equal(np.asarray(laz["plane_id"]), ref.cell_plane[res.point_cell])
    rows = list(csv.DictReader(r for r in io.StringIO(data.decode()) if not r.startswith("#")))
    assert len(rows) == int(keep.sum())
    np.testing.assert_array_equal([int(r["set_id"]) for r in rows], ref.cell_set[keep])
    np.testing.assert_array_equal([int(r["plane_id"]) for r in rows], ref.cell_plane[keep])
    assert {int(r["set_id"]) for r in rows} == {0, 1, 2, 3}


def test_a_set_parallel_to_the_exposure_face_is_flagged_in_the_tab():
    """Issue 31 item 2: the status carries the warning line and the set's dropdown
    entry and table row their marker; a real set gets neither."""
    from rough_viewer.app.features.sets import set_of_option, status_markdown
    from rough_viewer.grid.roughness import grid_roughness
    from rough_viewer.visual.sets import sets_table_figure
    from tests.structure.test_face import hillside

    pts = hillside(size=40.0, step=0.5)
    res = grid_roughness(pts, 2.0, models=("odr",))
    sets = joint_sets(res, pts)
    assert sets.face_parallel.tolist() == [True]
    status = status_markdown(sets, "2 m")
    assert status.startswith("**1 set** at grid 2 m")
    warning = status.split("\n\n")[1]
    assert warning.startswith("**⚠ Set 1 \\(22/187\\) lies parallel to the exposure face")
    assert "its spacing is not a joint spacing" in warning
    entry = set_option(sets, 1)
    assert entry.endswith("cells ⚠ exposure face") and set_of_option(entry) == 1
    fig = sets_table_figure(sets, axis="z", n_points=pts.shape[0])
    cells = fig.data[0].cells.values
    assert cells[0] == ["<b>1</b> ⚠"] and cells[6][0].endswith(" ⚠")  # spacing, marked
    assert cells[-1] == [f"{sets.face_angle_deg[0]:.1f} ⚠ face"]
    assert fig.layout.title.text.startswith("1 joint set (⚠ 1: exposure face)<br>")
    real = joint_sets(res, pts, SetOptions(face_tolerance_deg=0.0))
    assert "\n" not in status_markdown(real, "2 m") and "⚠" not in set_option(real, 1)
