"""Issue 30 items 3 and 5 and issue 31 item 12 in the app, without a browser: on a
small rock mass cut by three planted sets the Sets tab colours the rock by joint,
a click selects the joint under it and shows its row, the stereonet shows one pole
per joint, the rock-mass figures are the command line's, and the Export folder
downloads the Dips CSV (the bytes ``sets --dips-out`` writes) and carries
``joint_id`` in the cell table and the points."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from rough_viewer.app.features import export as em
from rough_viewer.app.features.sets import (
    DOWNLOAD_TABLES,
    L_COLOUR,
    L_POLES,
    SetsFeature,
)
from rough_viewer.app.markup import md
from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.cli.sets import format_sets
from rough_viewer.structure.joints import rock_mass_text
from rough_viewer.structure.sets import joint_sets
from rough_viewer.synthetic.joints import RockMassSetSpec, RockMassSpec, generate_rock_mass
from rough_viewer.visual.sets import point_colours
from tests.app.protocol import ProtocolClient, pick, settle, shown_colours

G = 0.25
#: A 3 m block of the issue's three sets, fewer joints (44 k points, about 1 s).
SMALL_ROCK_MASS = RockMassSpec(size_m=3.0, sets=(
    RockMassSetSpec(60.0, 30.0, joints=5, spacing_m=0.5),
    RockMassSetSpec(45.0, 150.0, joints=3, spacing_m=0.8),
    RockMassSetSpec(80.0, 270.0, joints=4, spacing_m=0.6)))
PLANTED_JOINTS = sum(s.joints for s in SMALL_ROCK_MASS.sets)
DIPS = next(t for t, n in DOWNLOAD_TABLES.items() if n == "dips")


@pytest.fixture(scope="module")
def rock():
    return generate_rock_mass(SMALL_ROCK_MASS)


@pytest.fixture
def japp(server, rock):
    app = build_app(server, rock.cloud, prefetch=False, variogram=False, presets=(G,),
                    settings=MapSettings(cell_size=G), max_display=60_000)
    assert app.wait_idle(120)
    f = app.feature(SetsFeature)
    f.on.value = True
    assert app.wait_idle(120)
    yield app, f, joint_sets(app.session.shown.result, rock.cloud)
    app.stop()


def test_the_rock_is_coloured_by_joint_and_the_table_counts_the_planted_joints(japp, rock):
    app, f, ref = japp
    res, loaded = app.session.shown.result, app.session.shown.loaded
    f.colour_by.value = "joint"
    assert app.wait_idle(60)
    np.testing.assert_array_equal(
        shown_colours(app), point_colours(ref, res.point_cell[loaded.display_index], by="joint"))
    # each set's joints in the table: the planted number, set by set (by orientation)
    table = f.table.figure.data[0]
    assert table.header.values[5] == "joints"
    counts = [int(c) for c in table.cells.values[5]]
    assert sum(counts) == ref.joints.n_joints == PLANTED_JOINTS
    assert f"{PLANTED_JOINTS} joints of {ref.planes.n_planes} patches" in f.status.content
    for k, n in enumerate(ref.normal):
        planted = int(np.argmax(np.abs(rock.set_normal @ n)))
        assert counts[k] == SMALL_ROCK_MASS.sets[planted].joints
    # the joints are the planted ones: nearly every point of a joint is of one planted joint
    point_joint = ref.cell_joint[res.point_cell].astype(np.int64)
    on = point_joint > 0
    pairs, n_pairs = np.unique(point_joint[on] * 1000 + rock.joint[on], return_counts=True)
    purest = np.zeros(ref.joints.n_joints + 1)
    np.maximum.at(purest, pairs // 1000, n_pairs)
    assert np.min(purest[1:] / ref.joints.points) > 0.95


def test_the_rock_mass_figures_are_the_command_lines(japp, rock):
    app, f, ref = japp
    res = app.session.shown.result
    text = rock_mass_text(ref.figures, "m")
    assert f.rock_mass.content == f"**Rock mass** (from the joint spacing): {md(text)}"
    # the very line `rough-viewer sets` prints
    assert text in format_sets(ref, res, source="rock", unit="m").splitlines()
    assert "RQD estimate" in text and "110 - 2.5 Jv" in text and "an estimate" in text
    planted = sum(1.0 / rock.spacings(k).mean() for k in (1, 2, 3))
    assert ref.figures.jv == pytest.approx(planted, rel=0.10)
    assert f"Jv {ref.figures.jv:.4g} joints per m3" in f.rock_mass.content


def test_a_click_selects_the_joint_under_it_and_shows_its_row(japp, rock):
    app, f, ref = japp
    res, loaded = app.session.shown.result, app.session.shown.loaded
    jt = ref.joints
    # a point of the largest joint of set 2, clicked from 2 cm off its plane
    want = int(np.flatnonzero(jt.set_id == 2)[0]) + 1
    rows = np.flatnonzero(ref.cell_joint[res.point_cell[loaded.display_index]] == want)
    target = loaded.display_points[rows[len(rows) // 2]].astype(float)
    normal = jt.normal[want - 1]
    assert pick(app, target + 0.02 * normal, -normal) is None  # the tab took it
    assert f.selected_joint == want and f.selected_set == 2
    k = want - 1
    info = f.joint_info.content
    assert info.startswith(md(f"Joint {want} (set 2): {jt.dip_deg[k]:02.0f}/"
                              f"{jt.dip_direction_deg[k]:03.0f}, {int(jt.patches[k]):,} patch"))
    for number in (f"area {jt.area[k]:.3g} m2", f"trace length {jt.trace_length[k]:.3g} m",
                   f"persistence {jt.persistence_dip[k]:.3g} m along dip",
                   f"{jt.persistence_strike[k]:.3g} m along strike"):
        assert number in info  # mid-sentence: nothing to escape
    # its planted joint: the one most of its points were planted on
    planted = np.bincount(rock.joint[ref.cell_joint[res.point_cell] == want]).argmax()
    assert rock.joint_set[planted] == int(np.argmax(np.abs(rock.set_normal @ ref.normal[1]))) + 1
    # the joint table lists set 2's joints, the selected one first and highlighted
    joints = f.joints.figure.data[0]
    assert joints.cells.values[0][0] == f"<b>{want}</b>"
    assert joints.cells.fill.color[1][0] == "#fff3b0"
    assert f"{int(np.count_nonzero(jt.set_id == 2))} joints of set 2" in \
        f.joints.figure.layout.title.text
    # the stereonet, one pole per joint: the selected one drawn larger
    f.poles.value = "per joint"
    assert app.wait_idle(60)
    traces = [t for t in f.stereonet.figure.data if t.name and "joint" in str(t.name)]
    assert sum(len(t.x) for t in traces) == jt.n_joints
    assert np.count_nonzero(np.concatenate([np.asarray(t.marker.size) for t in traces]) == 16) == 1
    # a click on a cell in no joint: its set, no joint
    none = np.flatnonzero((ref.cell_joint == 0) & (ref.cell_set > 0))
    assert none.size > 0  # cells of a set in no patch (too few touching cells)
    f.select_cell(int(none[0]))
    f.show_figures()
    assert f.selected_joint == 0 and f.selected_set == int(ref.cell_set[none[0]])
    assert "in no joint" in f.joint_info.content


def test_the_export_folder_downloads_the_dips_csv_and_the_joint_ids(japp, tmp_path):
    """The Dips CSV is byte for byte the file ``sets --dips-out`` writes (one writer);
    the cell table and the LAZ carry ``joint_id`` beside ``set_id`` and ``plane_id``."""
    import laspy

    from rough_viewer.io.table import write_table

    app, f, ref = japp
    res = app.session.shown.result
    write_table(tmp_path / "dips.csv", ref.dips_table(1.0))
    write_table(tmp_path / "joints.csv", ref.joint_table(1.0))
    client = ProtocolClient(app.server.get_port())
    try:
        client.wait_for(lambda m: m.get("type") == "GuiButtonMessage"
                        and m["props"].get("label") == em.L_TAB_TABLE, what="the Export folder")
        mark = len(client.messages)
        client.set_value(em.L_TAB_TABLE_CHOICE, DIPS)
        settle(app, lambda: app.feature(em.ExportFeature).tab_table.value == DIPS, "the choice")
        client.press(em.L_TAB_TABLE)
        name, dips = client.wait_download("_dips.csv", since=mark)
        assert app.wait_idle(60)
        mark = len(client.messages)
        client.set_value(em.L_TAB_TABLE_CHOICE, "Joint sets: JOINTS.csv")
        settle(app, lambda: "JOINTS" in app.feature(em.ExportFeature).tab_table.value,
               "the choice")
        client.press(em.L_TAB_TABLE)
        joints = client.wait_download("_joints.csv", since=mark)[1]
        assert app.wait_idle(60)
        mark = len(client.messages)
        client.press(em.L_TABLE)
        cells = client.wait_download("_cells.csv", since=mark)[1]
        assert app.wait_idle(60)
        mark = len(client.messages)
        client.press(em.L_POINTS)
        laz = laspy.read(io.BytesIO(client.wait_download("_points.laz", since=mark)[1]))
        assert app.wait_idle(60)
        # a title no feature offers is refused (the value never reaches the dropdown)
        client.set_value(em.L_TAB_TABLE_CHOICE, "../../etc/passwd")
        assert app.wait_idle(30)
        assert app.feature(em.ExportFeature).tab_table.value == "Joint sets: JOINTS.csv"
        # with the sets off: nothing sent, the reason said
        f.on.value = False
        assert app.wait_idle(60)
        mark = len(client.messages)
        client.press(em.L_TAB_TABLE)
        settle(app, lambda: "Export failed" in app.feature(em.ExportFeature).status.content,
               "the refusal")
        assert "tick Show sets" in app.feature(em.ExportFeature).status.content
        assert not client.downloads(since=mark)
    finally:
        client.close()
    assert name.endswith("_g0.25_dips.csv")
    assert dips == (tmp_path / "dips.csv").read_bytes()
    assert joints == (tmp_path / "joints.csv").read_bytes()
    header = dips.decode().splitlines()[0].split(",")
    assert header[:7] == ["Dip", "Dip Direction", "Quantity", "X (East)", "Y (North)",
                          "Z (Elev.)", "Persistence"] and "JOINT" in header
    assert len(dips.decode().splitlines()) == ref.planes.n_planes + 1
    np.testing.assert_array_equal(np.asarray(laz["joint_id"]), ref.cell_joint[res.point_cell])
    np.testing.assert_array_equal(np.asarray(laz["set_id"]), ref.cell_set[res.point_cell])
    keep = res.n_points >= res.min_points
    rows = list(csv.DictReader(r for r in io.StringIO(cells.decode()) if not r.startswith("#")))
    np.testing.assert_array_equal([int(r["joint_id"]) for r in rows], ref.cell_joint[keep])
    assert {int(r["joint_id"]) for r in rows} == set(range(PLANTED_JOINTS + 1))


def test_the_new_controls_take_only_their_options(japp):
    app, f, _ = japp
    client = ProtocolClient(app.server.get_port())
    try:
        client.set_value(L_COLOUR, "zone; drop table")
        client.set_value(L_POLES, "<script>")
        client.set_value(L_COLOUR, "patch")  # after the others: once it is in, they were seen
        settle(app, lambda: f.colour_by.value == "patch", "the messages")
    finally:
        client.close()
    assert f.poles.value == "per cell" and f.on.value
