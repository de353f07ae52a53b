"""The Zones tab on a real viser server: zones of a face with planted rough bands,
the sorted table, selection (list and scene clicks), live re-labelling at the Map
tab's threshold, connectivity and minimum size, refused values, saved-view settings."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.app import hooks
from rough_viewer.app.colouring import point_colours
from rough_viewer.app.features.zones import (
    HIGHLIGHT_RGB,
    NO_ZONE,
    NO_ZONE_RGB,
    ZonesFeature,
    zone_option,
)
from rough_viewer.app.gate import open_server
from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.io import PointCloud
from rough_viewer.report.view import ZoneSettings
from rough_viewer.structure.zones import ZoneLabeller
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import InputError, hex_to_rgb
from tests.app.protocol import join, pick, settle, shown_colours
from tests.helpers import PAPER_PRESETS, banded_face

#: Three rough bands (1 cm noise on a 1 mm face): along strike, at 60 and -30 degrees.
BANDS = [(-1.3, -1.6, 5.0, 0.6, 0.0), (2.3, 1.0, 3.4, 0.6, 60.0), (-2.2, 1.6, 2.8, 0.4, -30.0)]


@pytest.fixture(scope="module")
def banded():
    """A vertical face in the xz plane (facing -y) with the three bands, and the band of
    every point."""
    pts, band = banded_face(90.0, 180.0, BANDS, rough=0.01, n=120_000, seed=3)
    return PointCloud.from_xyz(pts, source="banded-face"), band


@pytest.fixture
def zapp(server, banded):
    app = build_app(server, banded[0], prefetch=False, presets=PAPER_PRESETS,
                    settings=MapSettings(cell_size=0.25))
    assert app.wait_idle(60)
    app.map.threshold.value = 0.2
    m = app.feature(ZonesFeature)
    m.on.value = True
    assert app.wait_idle(60)
    yield app, m
    app.stop()


def core_labels(app, threshold, connectivity="vertex", min_cells=3, map_name="odr"):
    """Zone ids of every cell straight from the core, on the shown grid result."""
    return ZoneLabeller.build(app.session.shown.result, map_name).label(
        threshold, connectivity=connectivity, min_cells=min_cells)


def shown_point_labels(app, labels):
    loaded = app.session.shown.loaded
    return labels[app.session.shown.result.point_cell[loaded.display_index]]


def click(app, display_row):
    """A scene click on displayed point ``display_row`` (the face looks along -y)."""
    target = app.session.shown.loaded.display_points[display_row].astype(float)
    return pick(app, target + [0.0, -5.0, 0.0], (0.0, 1.0, 0.0))


def test_planted_bands_become_three_zones_in_their_colours(zapp, banded):
    app, m = zapp
    _, band = banded
    lab = m.labelling
    assert lab is not None and lab.params.threshold == 0.2 and lab.params.map_name == "odr"
    want = core_labels(app, 0.2)
    assert np.array_equal(lab.labels, want) and lab.n_zones == 3
    # each zone holds (mostly) the points of one planted band, the longest first
    point_zone = want[app.session.shown.result.point_cell]
    held = [int(np.bincount(band[point_zone == k] + 1).argmax()) - 1 for k in (1, 2, 3)]
    assert sorted(held) == [0, 1, 2] and held[0] == 0
    # the scene: the points show their zone's colour instead of the map's, light grey in
    # no zone (every cell of this face has a value)
    assert app.map.overlay is m
    assert not app.map.colour_bar.visible  # the points show zones: no roughness colour bar
    per_point = shown_point_labels(app, want)
    palette = np.array([hex_to_rgb(c) for c in colormaps.ZONE_PALETTE])
    expect = np.where(per_point[:, None] > 0, palette[np.maximum(per_point, 1) - 1],
                      np.asarray(NO_ZONE_RGB))
    assert np.array_equal(shown_colours(app), expect)
    every = np.arange(app.session.shown.loaded.n_total)  # at full resolution too
    full = want[app.session.shown.result.point_cell]
    assert np.array_equal(app.host.scene.colours(every),
                          np.where(full[:, None] > 0, palette[np.maximum(full, 1) - 1],
                                   np.asarray(NO_ZONE_RGB)))
    assert "**3 zones**" in m.status.content and list(app.host.errors) == []
    m.on.value = False  # back to the map
    assert app.wait_idle(60)
    assert app.map.overlay is None and app.map.colour_bar.visible
    assert np.array_equal(shown_colours(app), point_colours(
        app.session.shown.result, app.session.shown.settings,
        app.session.shown.loaded.display_index))  # the map's colours are back


def test_table_and_list_are_sorted_largest_first(zapp):
    app, m = zapp
    zones = m.zones
    assert zones is not None and zones.labels is m.labelling.labels
    cells = np.bincount(m.labelling.labels)[1:]
    assert np.array_equal(zones.cells, cells) and np.all(np.diff(zones.cells) <= 0)
    table = m.table.figure.data[0]
    shown_cells = [int(c.replace(",", "")) for c in table.cells.values[1]]
    assert shown_cells == [int(c) for c in cells]
    assert [c.replace("<b>", "").replace("</b>", "") for c in table.cells.values[0]] == \
        ["1", "2", "3"]
    assert m.selected.options == (NO_ZONE, *(zone_option(k, int(cells[k - 1])) for k in (1, 2, 3)))
    # the stereonet shows every cell's pole, the zones' on top
    names = [t.name or "" for t in m.stereonet.figure.data]
    n_poles = int(np.all(np.isfinite(app.session.shown.result.normal), axis=1).sum())
    assert any(f"({n_poles:,})" in n for n in names)
    assert sum(n.startswith("zone ") for n in names) == 3


def test_selecting_a_zone_highlights_exactly_its_points(zapp):
    app, m = zapp
    labels = m.labelling.labels
    m.selected.value = m.selected.options[2]  # zone 2
    assert app.wait_idle(60)
    per_point = shown_point_labels(app, labels)
    want = app.session.shown.loaded.display_points[per_point == 2]
    node = m.selected_nodes[0]
    assert want.shape[0] > 100 and np.array_equal(node.points, want)
    assert np.all(node.colors == np.asarray(HIGHLIGHT_RGB))
    assert m.labelling.zone_at(m.anchor) == 2 and m.settings().selected == 2
    # its numbers, its table row and its poles
    z = m.zones
    assert "**Zone 2** of 3" in m.numbers.content
    assert f"{int(z.cells[1]):,} / {int(z.points[1]):,}" in m.numbers.content
    fills = m.table.figure.data[0].cells.fill.color[1]
    assert [f == "#fff3b0" for f in fills] == [False, True, False]
    cells2 = np.flatnonzero(labels == 2)
    poles2 = int(np.all(np.isfinite(app.session.shown.result.normal[cells2]), axis=1).sum())
    names = [t.name or "" for t in m.stereonet.figure.data]
    assert f"zone 2 ({poles2:,})" in names and not any(n.startswith("zone 1") for n in names)
    # "none" clears it
    m.selected.value = NO_ZONE
    assert app.wait_idle(60)
    assert m.selected_nodes == [] and m.settings().selected is None
    assert "No zone selected" in m.numbers.content


def test_a_click_on_the_rock_selects_the_zone_under_it(zapp):
    app, m = zapp
    per_point = shown_point_labels(app, m.labelling.labels)
    row = int(np.flatnonzero(per_point == 3)[0])
    assert click(app, row) is None  # taken by the zones: no cell report
    assert app.wait_idle(60)
    assert m.labelling.zone_at(m.anchor) == 3
    assert m.selected.value == m.selected.options[3]
    assert np.array_equal(m.selected_nodes[0].points,
                          app.session.shown.loaded.display_points[per_point == 3])
    assert any((t.name or "").startswith("zone 3") for t in m.stereonet.figure.data)
    # a point in no zone: no selection
    click(app, int(np.flatnonzero(per_point == 0)[0]))
    assert app.wait_idle(60)
    assert m.anchor is None and m.selected.value == NO_ZONE and m.selected_nodes == []
    # zones hidden: clicks report cells again
    m.on.value = False
    assert app.wait_idle(60)
    assert click(app, row) is not None


def test_threshold_changes_relabel_and_keep_the_selection(zapp):
    app, m = zapp
    m.selected.value = m.selected.options[1]  # zone 1: the band along strike
    assert app.wait_idle(60)
    anchor_zone_cells = np.flatnonzero(m.labelling.labels == 1)
    n_before = len(m.timings)
    app.map.threshold.value = 0.5  # the Map tab's slider
    assert app.wait_idle(60)
    lab = m.labelling
    assert lab.params.threshold == 0.5 and m.threshold.value == 0.5
    assert np.array_equal(lab.labels, core_labels(app, 0.5))
    assert len(m.timings) == n_before + 1 and m.timings[-1]["basis_s"] == 0.0  # labeller kept
    assert "labeller cached" in m.status.content
    # the selection follows the zone under its point
    k = lab.zone_at(m.anchor)
    assert k > 0 and np.isin(np.flatnonzero(lab.labels == k), anchor_zone_cells).all()
    # the tab's twin slider moves the Map tab's
    m.threshold.value = 0.3
    assert app.wait_idle(60)
    assert app.map.threshold.value == 0.3 and app.session.shown.settings.threshold == 0.3
    assert np.array_equal(m.labelling.labels, core_labels(app, 0.3))
    # the model and the grid are followed too
    app.map.model.value = "OLS"
    app.map.grid.value = "0.5"
    assert app.wait_idle(60)
    lab = m.labelling
    assert lab.params.map_name == "ols" and lab.result.grid.cell_size == 0.5
    assert np.array_equal(lab.labels, core_labels(app, 0.3, map_name="ols"))
    assert m.cache.bytes <= m.cache.budget == app.options.cache_bytes // 2


def patches_cloud(g=0.25):
    """Small rough squares centred in grid cells (the grid starts at the cloud's
    minimum): five on a diagonal (cells meeting at corners in the face, i.e. by a
    cube edge) and three side by side (sharing faces)."""
    chain = [(-4 + (4 + j + 0.5) * g, 3 - (4 + j + 0.5) * g, 0.15, 0.15, 0.0) for j in range(5)]
    row = [(-4 + (20 + j + 0.5) * g, 3 - 10.5 * g, 0.15, 0.15, 0.0) for j in range(3)]
    pts, _ = banded_face(90.0, 180.0, chain + row, rough=0.01, n=120_000, seed=4)
    return PointCloud.from_xyz(pts, source="patches")


def test_connectivity_and_minimum_size(zapp):
    app, m = zapp
    app.load(cloud=patches_cloud())
    assert app.wait_idle(60)
    app.map.grid_free.value = 0.25  # the grid the patches were laid out on (a new cloud
    assert app.wait_idle(60)        # opens at its own default grid)
    counts = {}
    for label, conn in (("face (6)", "face"), ("edge (18)", "edge"), ("vertex (26)", "vertex")):
        for min_cells in (1, 3, 4):
            m.connectivity.value = label
            m.min_cells.value = min_cells
            assert app.wait_idle(60)
            lab = m.labelling
            assert (lab.params.connectivity, lab.params.min_cells) == (conn, min_cells)
            assert np.array_equal(lab.labels, core_labels(app, 0.2, conn, min_cells))
            assert np.all(m.zones.cells >= min_cells)
            counts[conn, min_cells] = lab.n_zones
    # the diagonal joins by edges and corners only; the row by faces
    assert counts["vertex", 1] == counts["edge", 1] == 2 and counts["face", 1] == 6
    assert counts["face", 3] == 1 and counts["vertex", 4] == 1 and counts["vertex", 3] == 2
    assert m.settings() == ZoneSettings(map="odr", connectivity="vertex", min_cells=4,
                                        selected=None)


def test_saved_view_settings_round_trip(zapp):
    app, m = zapp
    m.apply(ZoneSettings(map="hybrid", connectivity="edge", min_cells=4, selected=2))
    assert app.wait_idle(60)
    assert app.session.shown.settings.model == "hybrid" and app.map.model.value == "hybrid"
    lab = m.labelling
    assert lab.params.map_name == "hybrid" and lab.params.connectivity == "edge"
    assert np.array_equal(lab.labels, core_labels(app, 0.2, "edge", 4, "hybrid"))
    assert lab.zone_at(m.anchor) == 2 and m.selected.value.startswith("Zone 2 ")
    assert m.settings() == ZoneSettings(map="hybrid", connectivity="edge", min_cells=4,
                                        selected=2)
    m.apply(None)
    assert app.wait_idle(60)
    assert not m.active and app.map.overlay is None
    with pytest.raises(InputError):
        m.apply(ZoneSettings(min_cells=0))


def test_another_cloud_gets_its_own_zone_cloud(zapp, banded):
    app, m = zapp
    first = m.colouring
    pts, _ = banded_face(90.0, 180.0, BANDS[:1], rough=0.01, n=40_000, seed=9)
    app.load(cloud=PointCloud.from_xyz(pts, source="one band"))
    assert app.wait_idle(60)
    assert m.colouring is not first and m.labelling.loaded is app.session.shown.loaded
    assert m.labelling.n_zones == 1 and app.map.overlay is m


@pytest.fixture
def hostile(banded):
    server, _gate = open_server("127.0.0.1", 0, token="tok", log=False)
    app = build_app(server, banded[0], prefetch=False, presets=PAPER_PRESETS,
                    settings=MapSettings(cell_size=0.25))
    assert app.wait_idle(60)
    m = app.feature(ZonesFeature)
    app.map.threshold.value = 0.2
    m.on.value = True
    assert app.wait_idle(60)
    client = join(server, "/t/tok", origin=f"http://127.0.0.1:{server.get_port()}")
    yield app, m, client
    client.close()
    app.stop()
    server.stop()


BAD = [
    ("Min zone cells", 0, "at least 1"),
    ("Min zone cells", 2.5, "whole number"),
    ("Min zone cells", "3", "a number"),
    ("Connectivity", "diagonal", "one of its options"),
    ("Selected zone", "Zone 99 — 1 cells", "one of its options"),
    ("Selected zone", "<img src=x onerror=alert(1)>", "one of its options"),
    ("Zone threshold", 1.5, "at most 1"),
    ("Zone threshold", float("nan"), "finite"),
    ("Show zones", "yes", "true or false"),
]


def test_values_from_a_browser_are_checked(hostile):
    app, m, client = hostile
    before = (m.labelling.labels.copy(), m.min_cells.value, m.connectivity.value,
              m.selected.value, m.threshold.value, app.session.shown.settings)
    for label, value, _ in BAD:
        client.set_value(label, value)
    settle(app, lambda: len(app.host.controls.rejected) >= len(BAD), "every refusal")
    after = (m.min_cells.value, m.connectivity.value, m.selected.value, m.threshold.value,
             app.session.shown.settings)
    assert after == before[1:] and np.array_equal(m.labelling.labels, before[0])
    got = [(r.label, r.reason) for r in app.host.controls.rejected]
    for label, _, reason in BAD:
        assert any(lab == label and reason in why for lab, why in got), (label, reason)
    handles = hooks.input_handles(app.server)
    assert all(app.host.controls.allowed(h) for h in (m.on, m.threshold, m.connectivity,
                                                 m.min_cells, m.selected))
    assert len(handles) > 30
    # good values from the browser work: the twin threshold, a zone from the list, a click
    client.set_value("Zone threshold", 0.3)
    settle(app, lambda: app.session.shown.settings.threshold == 0.3
           and m.labelling.params.threshold == 0.3, "the twin threshold")
    client.set_value("Selected zone", m.selected.options[1])
    settle(app, lambda: m.anchor is not None and m.labelling.zone_at(m.anchor) == 1,
           "zone 1 selected")
    per_point = shown_point_labels(app, m.labelling.labels)
    target = app.session.shown.loaded.display_points[int(np.flatnonzero(per_point == 2)[0])]
    client.click(target.astype(float) + [0.0, -5.0, 0.0], (0.0, 1.0, 0.0))
    settle(app, lambda: m.labelling.zone_at(m.anchor) == 2, "zone 2 clicked")


def test_labellers_are_cached_within_a_byte_budget(server, banded):
    from rough_viewer.app.cache import ByteBudget, ByteCache, nbytes
    from rough_viewer.app.features.zones import zone_basis
    from rough_viewer.grid.roughness import grid_roughness

    cloud = banded[0]
    one = nbytes(zone_basis(grid_roughness(cloud, 0.25), "odr", np.arange(cloud.n)))
    # room for one basis and a stereonet, not for two bases
    app = build_app(server, cloud, prefetch=False, cache_bytes=int(2 * 1.5 * one),
                    presets=PAPER_PRESETS, settings=MapSettings(cell_size=0.25))
    try:
        assert app.wait_idle(60)
        m = app.feature(ZonesFeature)
        assert m.cache.budget == int(1.5 * one)
        # the zones' cache on a pool of its own: in a pool this small the grids' pinned
        # values (the shown grid, its cells and prepared grid) leave no room for a basis
        m.cloud_for = app.session.shown.loaded
        m.cache = ByteCache(ByteBudget(int(1.5 * one)), most=int(1.5 * one))
        m.on.value = True
        assert app.wait_idle(60)
        assert m.timings[-1]["basis_s"] > 0  # built
        app.map.threshold.value = 0.3
        assert app.wait_idle(60)
        assert m.timings[-1]["basis_s"] == 0.0  # kept: a threshold change only re-labels
        app.map.grid.value = "0.5"
        assert app.wait_idle(60)
        app.map.grid.value = "0.25"
        assert app.wait_idle(60)
        assert m.timings[-1]["basis_s"] > 0  # the 0.25 m basis made room for the 0.5 m one
        assert m.cache.bytes <= m.cache.budget
        assert np.array_equal(m.labelling.labels, core_labels(app, 0.3))
    finally:
        app.stop()


def test_the_cell_table_download_carries_the_zones_shown(server, banded, tmp_path):
    """Issue 31 item 3: while zones are shown, Download cell table has a ``zone``
    column, each row its cell's zone, as ``zones --cells-out`` writes it for the same
    file, grid and zone settings, and Download points (LAZ) each point's; without
    zones neither has it."""
    import csv
    import io

    import laspy

    from rough_viewer.app.features import export as em
    from rough_viewer.cli import main
    from rough_viewer.io import load_points
    from tests.app.protocol import ProtocolClient

    path = tmp_path / "banded.npy"
    np.save(path, banded[0].xyz())
    app = build_app(server, load_points(path), prefetch=False, presets=PAPER_PRESETS,
                    settings=MapSettings(cell_size=0.25), data_dir=tmp_path)
    client = ProtocolClient(server.get_port())

    def table() -> list[dict[str, str]]:
        mark = len(client.messages)
        client.press(em.L_TABLE)
        data = client.wait_download("_cells.csv", since=mark)[1]
        assert app.wait_idle(60)
        return list(csv.DictReader(r for r in io.StringIO(data.decode()) if not r.startswith("#")))

    try:
        assert app.wait_idle(60)
        client.wait_for(lambda m: m.get("type") == "GuiButtonMessage"
                        and m["props"].get("label") == em.L_TABLE, what="the Export folder")
        assert "zone" not in table()[0]
        mark = len(client.messages)
        client.press(em.L_POINTS)
        plain = laspy.read(io.BytesIO(client.wait_download("_points.laz", since=mark)[1]))
        assert app.wait_idle(60) and "zone" not in plain.point_format.extra_dimension_names
        app.map.threshold.value = 0.2
        z = app.feature(ZonesFeature)
        z.on.value = True
        assert app.wait_idle(60) and z.labelling is not None and z.labelling.n_zones >= 3
        mine = table()
        mark = len(client.messages)
        client.press(em.L_POINTS)
        laz = laspy.read(io.BytesIO(client.wait_download("_points.laz", since=mark)[1]))
        res = app.session.shown.result
        np.testing.assert_array_equal(np.asarray(laz["zone"]), z.labelling.labels[res.point_cell])
        np.testing.assert_array_equal(z.labelling.labels, core_labels(app, 0.2))
    finally:
        client.close()
        app.stop()
    cells = tmp_path / "cells.csv"
    assert main(["zones", str(path), "--grid", "0.25", "--threshold", "0.2",
                 "--connectivity", "vertex", "--min-cells", "3", "--out",
                 str(tmp_path / "zones.csv"), "--cells-out", str(cells)]) == 0
    theirs = list(csv.DictReader(r for r in cells.read_text().splitlines()
                                 if not r.startswith("#")))
    assert len(mine) == len(theirs) > 100
    assert [(r["ix"], r["iy"], r["iz"], r["zone"]) for r in mine] == \
        [(r["ix"], r["iy"], r["iz"], r["zone"]) for r in theirs]
    assert len({r["zone"] for r in mine}) >= 4  # three zones and none


def graded_face(n=120_000, seed=5):
    """A vertical face (facing -y) of three roughness levels side by side along x: 1 mm
    noise on the first 30 %, 4 mm on the next 45 %, 12 mm on the rest. At the paper's
    0.05 the 4 mm and 12 mm cells are all rough (about 70 % of the face)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-4.0, 4.0, n)
    z = rng.uniform(-3.0, 3.0, n)
    sigma = np.select([x < -1.6, x < 2.0], [0.001, 0.004], 0.012)
    y = rng.standard_normal(n) * sigma
    return PointCloud.from_xyz(np.c_[x, y, z] + [500_000.0, 4_000_000.0, 100.0],
                               source="graded-face")


def test_zones_use_the_datas_threshold_when_the_papers_flags_most(server):
    """Issue 31 item 8 (the app): with the slider at the paper's 0.05 and 0.05 flagging
    more than half of the cells, the Zones tab labels at the data's own threshold (the
    rule of ``rough-viewer zones``), says so, and shows it on its slider; "the
    slider's" rule keeps the paper's 0.05; a threshold moved to is used as it is."""
    from rough_viewer.app.features.zones import RULE_AUTO, RULE_SLIDER
    from rough_viewer.cli.zones import zones_threshold
    from rough_viewer.grid.outliers import analysed_values

    app = build_app(server, graded_face(), prefetch=False, presets=PAPER_PRESETS,
                    settings=MapSettings(cell_size=0.25))
    try:
        assert app.wait_idle(60) and app.map.threshold.value == 0.05
        m = app.feature(ZonesFeature)
        assert m.rule.value == RULE_AUTO
        m.on.value = True
        assert app.wait_idle(60)
        res = app.session.shown.result
        v = analysed_values(res, "odr")
        v = v[np.isfinite(v)]
        norm = (v - v.min()) / (v.max() - v.min())
        assert 0.6 < np.mean(norm >= 0.05) < 0.8  # the paper's flags most of the face
        want, _ = zones_threshold(res, "odr", None)  # the command line's choice
        lab = m.labelling
        assert want != 0.05 and lab.params.threshold == want
        assert np.array_equal(lab.labels, core_labels(app, want))
        said = m.status.content.replace("\\", "")  # markdown escapes
        assert f"Threshold {want:.3g}, the data's own" in said and RULE_SLIDER in said
        assert m.threshold.value == want and app.map.threshold.value == 0.05
        assert m.settings().threshold_rule == "auto"
        # the paper's value, as zones --threshold 0.05
        m.rule.value = RULE_SLIDER
        assert app.wait_idle(60)
        assert m.labelling.params.threshold == 0.05 and m.threshold.value == 0.05
        assert np.array_equal(m.labelling.labels, core_labels(app, 0.05))
        assert "the data's own" not in m.status.content
        assert m.settings().threshold_rule == "slider"
        # under the data's rule a threshold moved to is the user's
        m.rule.value = RULE_AUTO
        assert app.wait_idle(60) and m.labelling.params.threshold == want
        app.map.threshold.value = 0.3
        assert app.wait_idle(60)
        assert m.labelling.params.threshold == 0.3 and m.threshold.value == 0.3
        assert np.array_equal(m.labelling.labels, core_labels(app, 0.3))
        # a saved view keeps the rule
        app.map.threshold.value = 0.05
        m.apply(ZoneSettings(threshold_rule="slider"))
        assert app.wait_idle(60)
        assert m.rule.value == RULE_SLIDER and m.labelling.params.threshold == 0.05
        assert list(app.host.errors) == []
    finally:
        app.stop()
