"""Issue 27 in the app: a cloud with scanner positions gets the per-cell scanner
figures as colour layers and in the cell report; a cloud without them lists none."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.bias.trust import TrustSettings, cell_trust
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud
from rough_viewer.visual.layers import trust_layer
from rough_viewer.vocabulary import COLOUR_LAYER_LABELS, COLOUR_LAYERS, TRUST_FIELDS
from tests.app.protocol import pick, shown_colours
from tests.helpers import ray_grid, scan_plane

SCANNER = np.array([0.0, -8.0, 1.5])


@pytest.fixture
def scanned(server):
    """A wall in the x-z plane at y = 0, ray-cast from a scanner 8 m in front of it."""
    rays = ray_grid(SCANNER, np.array([0.0, 0.0, 1.0]), 0.2, step=1.2e-3)
    xyz = scan_plane(SCANNER, np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]), rays,
                     extent=1.2, noise=0.002, seed=3)
    cloud = _with_positions(xyz)
    settings = TrustSettings()
    app = build_app(server, cloud, prefetch=False, presets=(0.4,),
                    settings=MapSettings(cell_size=0.4), trust=settings)
    assert app.wait_idle(120)
    yield app, cloud, settings
    app.stop()


def _with_positions(xyz: np.ndarray) -> PointCloud:
    from dataclasses import replace

    return replace(PointCloud.from_xyz(xyz, source="wall"),
                   scan_index=np.zeros(len(xyz), dtype=np.int64),
                   scanner_positions=SCANNER[None, :].astype(np.float64))


def test_the_layers_are_the_scanner_fields():
    assert COLOUR_LAYERS[4:] == TRUST_FIELDS  # one list of scanner figures
    assert all(COLOUR_LAYER_LABELS[n].startswith("scanner: ") for n in TRUST_FIELDS)


def test_scanner_layers_colour_the_points_and_the_cell_report_says_them(scanned):
    app, cloud, settings = scanned
    loaded = app.session.shown.loaded
    labels = tuple(app.map.layer.options)
    assert all(COLOUR_LAYER_LABELS[n] in labels for n in TRUST_FIELDS)
    ref = grid_roughness(cloud, 0.4)
    trust = cell_trust(cloud, ref, settings)
    app.map.layer.value = COLOUR_LAYER_LABELS["incidence_deg"]
    assert app.wait_idle(120) and list(app.host.errors) == []
    want = trust_layer("incidence_deg",
                       trust.layer("incidence_deg")[ref.point_cell[loaded.display_index]])
    np.testing.assert_array_equal(shown_colours(app), want.colours)
    assert "Scanner: incidence angle" in app.map.colour_bar.figure.layout.title.text
    app.map.layer.value = COLOUR_LAYER_LABELS["range"]
    assert app.wait_idle(120)
    assert "range (m)" in app.map.colour_bar.figure.layout.xaxis.title.text
    # a click reports the cell's scanner figures (range and incidence of the geometry)
    i = int(np.argmin(np.abs(loaded.display_points[:, 0]) + np.abs(loaded.display_points[:, 2])))
    target = loaded.display_points[i].astype(float)
    info = pick(app, target + [0.0, -5.0, 0.0], (0.0, 1.0, 0.0))
    assert info is not None
    r = trust.geometry.range_m[info.cell]
    assert f"range {r:.2f} m" in app.map.pick.content
    assert "scanner: seen by 1 scan" in app.map.pick.content


def test_a_cloud_without_positions_has_no_scanner_layers(app):
    labels = tuple(app.map.layer.options)
    assert not any(label.startswith("scanner: ") for label in labels)
    assert "scanner" not in app.map.pick.content


def test_the_exports_carry_the_scanner_columns_compute_writes(server, tmp_path):
    """Issue 31 item 3: Download cell table fills ``scans ... trusted`` as ``compute
    --scanner`` does for the same cloud and grid, and Download points (LAZ) carries
    the nine scanner fields, each point its cell's."""
    import csv
    import io

    import laspy

    from rough_viewer.app.features import export as em
    from rough_viewer.cli import main
    from rough_viewer.io import load_points
    from rough_viewer.io.scanners import with_scanner
    from tests.app.protocol import ProtocolClient

    rays = ray_grid(SCANNER, np.array([0.0, 0.0, 1.0]), 0.2, step=2e-3)
    xyz = scan_plane(SCANNER, np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]), rays,
                     extent=1.2, noise=0.002, seed=3)
    path = tmp_path / "wall.npy"
    np.save(path, xyz)
    cloud = with_scanner(load_points(path), tuple(float(v) for v in SCANNER))
    app = build_app(server, cloud, prefetch=False, presets=(0.4,), data_dir=tmp_path,
                    settings=MapSettings(cell_size=0.4), trust=TrustSettings())
    client = ProtocolClient(server.get_port())
    try:
        assert app.wait_idle(120)
        client.wait_for(lambda m: m.get("type") == "GuiButtonMessage"
                        and m["props"].get("label") == em.L_TABLE, what="the Export folder")
        got = {}
        for label, part in ((em.L_TABLE, "_cells.csv"), (em.L_POINTS, "_points.laz")):
            mark = len(client.messages)
            client.press(label)
            got[part] = client.wait_download(part, since=mark)[1]
            assert app.wait_idle(120)
    finally:
        client.close()
        app.stop()
    cli_csv, cli_laz = tmp_path / "cli.csv", tmp_path / "cli.laz"
    assert main(["compute", str(path), "--grid", "0.4", "--scanner", ",".join(map(str, SCANNER)),
                 "--out", str(cli_csv), "--las-out", str(cli_laz), "--quiet"]) == 0
    mine = list(csv.DictReader(io.StringIO(got["_cells.csv"].decode())))
    theirs = list(csv.DictReader(r for r in cli_csv.read_text().splitlines()
                                 if not r.startswith("#")))
    assert len(mine) == len(theirs) > 10
    for name in TRUST_FIELDS:
        assert [r[name] for r in mine] == [r[name] for r in theirs], name
    assert any(r["trusted"] in ("0", "1") for r in mine)  # judged, not empty
    assert all(r["scans"] == "1" for r in mine if r["n_points"] and int(r["n_points"]) >= 3)
    # the LAZ: the same nine fields as compute --las-out writes, point for point
    a, b = laspy.read(io.BytesIO(got["_points.laz"])), laspy.read(cli_laz)
    for name in TRUST_FIELDS:
        np.testing.assert_array_equal(np.asarray(a[name]), np.asarray(b[name]), err_msg=name)
    ref = grid_roughness(cloud, 0.4)
    inc = cell_trust(cloud, ref, TrustSettings()).layer("incidence_deg")[ref.point_cell]
    np.testing.assert_allclose(np.asarray(a["incidence_deg"], dtype=np.float64), inc,
                               rtol=1e-6, equal_nan=True)


def test_the_trusted_flag_is_drawn_in_two_colours_with_a_legend(scanned):
    """Issue 31 item 16: the 0/1 'trusted' layer was drawn on a continuous ramp; it is
    two colours (green trusted, red not, grey not judged) with a legend of the two
    classes and their cells."""
    from rough_viewer.vocabulary import hex_to_rgb

    app, cloud, settings = scanned
    loaded = app.session.shown.loaded
    ref = grid_roughness(cloud, 0.4)
    flag = cell_trust(cloud, ref, settings).layer("trusted")
    app.map.layer.value = COLOUR_LAYER_LABELS["trusted"]
    assert app.wait_idle(120) and list(app.host.errors) == []
    per_point = flag[ref.point_cell[loaded.display_index]]
    want = np.where((per_point == 1)[:, None], hex_to_rgb("#2ca02c"),
                    np.where((per_point == 0)[:, None], hex_to_rgb("#d62728"), (190, 190, 190)))
    np.testing.assert_array_equal(shown_colours(app), want)
    assert len({tuple(c) for c in shown_colours(app).tolist()}) <= 3
    fig = app.map.colour_bar.figure
    assert fig.data[0].type == "heatmap" and len(fig.data[0].x) == 2
    n1, n0 = int(np.sum(flag == 1)), int(np.sum(flag == 0))
    assert n1 + n0 > 0
    names = list(fig.data[0].x)
    assert names[0].startswith(f"not trusted: {n0:,} cells")
    assert names[1].startswith(f"trusted: {n1:,} cells")
