"""``serve CAMPAIGN.copc.laz`` (issue 33 item 3): a COPC file too big for the server is
served as a campaign: the top levels of its hierarchy are the app's cloud, and every
map comes from every point of the file (by tiles), cached on disk for the next open;
a damaged file is one line."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("lazrs")

import viser  # noqa: E402

from rough_viewer.app.campaign import (  # noqa: E402
    CampaignCloud,
    campaign_cloud,
    campaign_presets,
    cells_path,
    expected_cells,
    load_cells,
    load_no_fit,
    open_campaign,
    overview_rows,
    read_overview,
    save_no_fit,
)
from rough_viewer.app.server import app_options, mount_app  # noqa: E402
from rough_viewer.app.settings import MapSettings  # noqa: E402
from rough_viewer.grid.roughness import grid_roughness  # noqa: E402
from rough_viewer.grid.spacing import median_cell_count  # noqa: E402
from rough_viewer.io import PointCloud  # noqa: E402
from rough_viewer.io.copc.reader import decode_nodes, open_copc  # noqa: E402
from rough_viewer.io.crop import CropBox  # noqa: E402
from rough_viewer.io.sandbox import isolate  # noqa: E402
from rough_viewer.vocabulary import InputError  # noqa: E402
from tests.app.protocol import ProtocolClient  # noqa: E402
from tests.app.serve_process import ServeProcess  # noqa: E402
from tests.app.test_lod_app import _received_points  # noqa: E402
from tests.scale.helpers_scale import assert_same_cells  # noqa: E402
from tests.scale.test_tiles import _damaged, _survey  # noqa: E402

N = 60_000
#: Under the points of the hierarchy's first two levels of the survey (asserted).
CAP = 20_000


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    return _survey(tmp_path_factory.mktemp("campaign"), N, seed=11)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(folder))
    return folder


def _level_points(path):
    copc = open_copc(path)
    d = copc.nodes["depth"]
    return copc, [int(copc.nodes["count"][d == lv].sum()) for lv in np.unique(d)]


def _app(campaign, overview, settings):
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    options = app_options(overview, prefetch=False, variogram=False)
    loaded = campaign_cloud(campaign, overview, presets=campaign_presets(overview, N),
                            max_display=options.max_display, cache_bytes=options.cache_bytes,
                            cache_pool=options.cache_pool)
    app = mount_app(server, loaded, settings, options)
    return server, app, loaded


def test_the_overview_is_whole_top_levels_decoded_from_the_file(survey):
    """Whole levels, shallowest first, while under the cap: here the root level only
    (its points, bit for bit those the reader decodes of those nodes), in metres."""
    _, out, _ = survey
    copc, levels = _level_points(out)
    assert levels[0] <= CAP < levels[0] + levels[1]
    rows = overview_rows(copc, CAP)
    assert np.array_equal(rows, np.flatnonzero(copc.nodes["depth"] == 0))
    assert overview_rows(copc, levels[0] + levels[1]).size == int(
        np.count_nonzero(copc.nodes["depth"] <= 1))
    overview = read_overview(open_campaign(out), CAP)
    assert overview.n == levels[0] < N
    x, y, z = decode_nodes(copc, rows)  # file units: metres here
    np.testing.assert_array_equal(np.sort(overview.x), np.sort(x))
    np.testing.assert_array_equal(np.sort(overview.z), np.sort(z))
    assert overview.source == str(out)


def test_the_map_is_every_point_of_the_file_and_the_next_open_reads_the_cache(survey, cache):
    """The app's map (all four presets, one pass) equals grid_roughness of all
    60,000 points to 1e-12, not of the overview's; the cloud held is the overview's
    12,951 points, each given the row of its own cell; a second open computes
    nothing (its cells come from the disk), a damaged cache file is computed again
    and rewritten."""
    _, out, xyz = survey
    campaign = open_campaign(out)
    overview = read_overview(campaign, CAP)
    presets = campaign_presets(overview, N)
    # the default grid is of the file's density: a typical cell of ~16 of its points
    assert median_cell_count(xyz, presets[-1]) >= 16 > median_cell_count(xyz, presets[-1] / 2)
    settings = MapSettings(cell_size=presets[-1])
    server, app, loaded = _app(campaign, overview, settings)
    try:
        assert app.wait_idle(300)
        assert not app.host.errors, app.host.errors
        res = app.session.shown.result
        assert isinstance(loaded, CampaignCloud)
        assert loaded.cloud.n == overview.n < N and loaded.n_total == N
        assert_same_cells(res, grid_roughness(xyz, presets[-1], engine="numpy"), rtol=1e-12)
        assert res.n_points.sum() == N
        # every overview point in its own cell (brute force: floor((p - o) / g))
        ov = np.column_stack([overview.x, overview.y, overview.z])
        ijk = np.floor((ov - res.grid.origin) / res.grid.cell_size).astype(np.int64)
        np.testing.assert_array_equal(res.ijk[res.point_cell], ijk)
        store = loaded.store
        assert sorted(store.computed) == sorted(presets) and store.from_disk == []
        for g in presets:  # the panels' trend across the presets: cells of every point
            cells = loaded.cell_result(settings.with_(cell_size=g))
            assert_same_cells(cells, grid_roughness(xyz, g, engine="numpy"), rtol=1e-12)
        assert sorted(store.computed) == sorted(presets)  # all four from the one pass
        with pytest.raises(InputError, match="a crop keeps the points inside a box"):
            loaded.cropped(CropBox((0, 0, 0), (1, 1, 1), mode="remove"))
    finally:
        app.stop()
        server.stop()
    # the next open: the cells from the disk, nothing decoded beyond the overview
    again = campaign_cloud(campaign, overview, presets=presets, max_display=10_000,
                           cache_bytes=1 << 28, cache_pool=None)
    res2 = again.result(settings)
    assert again.store.computed == [] and again.store.from_disk == [presets[-1]]
    for name in ("theta_odr", "theta_ols", "theta_hybrid", "normal", "n_points", "ijk"):
        np.testing.assert_array_equal(getattr(res2, name), getattr(res, name), err_msg=name)
    np.testing.assert_array_equal(res2.point_cell, res.point_cell)
    # a damaged entry is ignored, computed again and rewritten
    where = cells_path(out, settings)
    data = where.read_bytes()
    where.write_bytes(data[: len(data) // 2])
    third = campaign_cloud(campaign, overview, presets=presets, max_display=10_000,
                           cache_bytes=1 << 28, cache_pool=None)
    res3 = third.result(settings)
    assert third.store.computed == [presets[-1]]  # the others' cells: from the disk
    assert sorted(third.store.from_disk) == sorted(presets[:-1])
    np.testing.assert_array_equal(res3.theta_odr, res.theta_odr)
    assert load_cells(where, settings, N) is not None  # rewritten whole


def test_a_grid_off_the_presets_and_another_axis(survey, cache):
    """A grid that is no preset is computed alone; axis y and 5 minimum points are
    their own grid, equal to grid_roughness of every point."""
    _, out, xyz = survey
    campaign = open_campaign(out)
    overview = read_overview(campaign, CAP)
    loaded = campaign_cloud(campaign, overview, presets=campaign_presets(overview, N),
                            max_display=10_000, cache_bytes=1 << 28, cache_pool=None)
    s = MapSettings(cell_size=0.37, axis="y", min_points=5)
    res = loaded.result(s)
    assert loaded.store.computed == [0.37]
    assert_same_cells(res, grid_roughness(xyz, 0.37, axis="y", min_points=5, engine="numpy"),
                      rtol=1e-12)


def _said(client, text, timeout=120.0):
    client.wait_for(lambda m: text in json.dumps(m, default=str), timeout=timeout,
                    what=repr(text))


@pytest.mark.skipif(not isolate.available(), reason="the reader sandbox needs Linux")
def test_a_real_serve_on_the_copc_and_a_tab_that_receives_the_overview(survey, tmp_path):
    """``serve survey.copc.laz --overview-points 20000`` as a process: stderr says the
    overview, stdout the file's 60,000 points; a websocket tab gets the app, its
    status naming the campaign, and more than the overview's points (its budget
    holds the whole file): the overview's nodes from memory, deeper ones decoded on
    demand (tests/app/test_campaign_lod.py follows a tab's patch point by point)."""
    _, out, _ = survey
    _, levels = _level_points(out)
    proc = ServeProcess(str(out), "--overview-points", str(CAP), "--no-token",
                        "--point-budget", "1000000", timeout=300)
    try:
        client = ProtocolClient(proc.port, proc.path)
        _said(client, f"campaign: {levels[0]:,} of its points drawn")
        _said(client, f"{N:,} points, each tab draws")
        client.wait_for(lambda m: m.get("type") == "PointCloudMessage"
                        and m.get("name", "").startswith("/lod/"), 60, "the nodes")
        from tests.app.browser import wait_until

        wait_until(lambda: _received_points(client).shape[0] > levels[0], 120, "deeper nodes")
        assert _received_points(client).shape[0] <= N
        client.close()
        assert proc.alive()
    finally:
        proc.stop()
    err = "".join(proc.stderr)
    assert f"overview of {levels[0]:,} of its {N:,} points" in err, err
    assert "Traceback" not in err


@pytest.mark.parametrize("how,says", [("past the end", "past the end"), ("loop", "a loop")])
def test_a_damaged_copc_is_one_line_from_serve(survey, tmp_path, how, says):
    """A node offset past the end of the file, a hierarchy page that points at itself:
    ``serve`` exits 2 with one line naming the file, before it listens; no traceback,
    no hang."""
    p = _damaged(survey, tmp_path, how)
    done = subprocess.run(
        [sys.executable, "-m", "rough_viewer", "serve", str(p), "--overview-points", str(CAP),
         "--port", "0", "--no-block"], capture_output=True, text=True, timeout=120)
    err = done.stderr.strip()
    assert done.returncode == 2, err
    assert len(err.splitlines()) == 1 and str(p) in err and says in err, err
    assert "Traceback" not in err and "listening" not in err


@pytest.mark.skipif(not isolate.available(), reason="the reader sandbox needs Linux")
def test_a_damaged_node_is_one_error_line_from_the_reader_sandbox(survey, tmp_path):
    """A node whose compressed bytes are garbage fails in the reader's child process
    while the overview is read (after the address was said): one error line, exit 2,
    no traceback."""
    p = _damaged(survey, tmp_path, "bad chunk")
    done = subprocess.run(
        [sys.executable, "-m", "rough_viewer", "serve", str(p), "--overview-points", str(CAP),
         "--port", "0", "--no-block"], capture_output=True, text=True, timeout=180)
    err = done.stderr.strip()
    assert done.returncode == 2, err
    errors = [line for line in err.splitlines() if "error" in line]
    assert len(errors) == 1 and p.name in errors[0], err
    assert "Traceback" not in err


def test_the_cells_expected_from_an_overview(survey):
    """The occupied cells of the whole survey, estimated from an even thinning of it
    (a 5 % random subset, as the hierarchy's levels thin the points): within 15 % of
    the cells counted on every point (brute force: the distinct floor((p - lo) / g)),
    never more than the points."""
    _, _, xyz = survey
    sub = xyz[np.random.default_rng(1).random(xyz.shape[0]) < 0.05]
    lo = xyz.min(axis=0)
    for g in (0.8, 0.4, 0.2, 0.1):
        truth = np.unique(np.floor((xyz - lo) / g).astype(np.int64), axis=0).shape[0]
        seen = np.unique(np.floor((sub - sub.min(axis=0)) / g).astype(np.int64), axis=0).shape[0]
        est = expected_cells(PointCloud.from_xyz(sub), g, N)
        assert abs(est - truth) <= 0.15 * truth, (g, est, truth, seen)
        assert est <= N
        if g <= 0.1:
            assert seen < 0.7 * truth  # the thinning's own count is far off


def test_a_grid_whose_cells_cannot_fit_the_pass_is_refused_before_it(survey, cache):
    """With 16 MB for the map's pass (8 MB for its cells, at 400 bytes a cell), a
    2 cm grid (tens of thousands of cells expected from the overview) is one line
    at once, no pass run; a grid that fits still comes from every point."""
    import dataclasses

    _, out, xyz = survey
    campaign = dataclasses.replace(open_campaign(out), memory_bytes=16 << 20)
    overview = read_overview(campaign, CAP)
    loaded = campaign_cloud(campaign, overview, presets=campaign_presets(overview, N),
                            max_display=10_000, cache_bytes=1 << 28, cache_pool=None)
    assert expected_cells(overview, 0.02, N) > 0.5 * (16 << 20) / 400
    with pytest.raises(InputError, match="give more memory or a larger grid"):
        loaded.result(MapSettings(cell_size=0.02))
    assert loaded.store.computed == []
    res = loaded.result(MapSettings(cell_size=0.5))
    assert_same_cells(res, grid_roughness(xyz, 0.5, engine="numpy"), rtol=1e-12)


def test_a_pass_that_ran_out_of_memory_is_not_run_again_with_no_more(survey, cache):
    """What a pass said when its cells did not fit is kept beside the grid's cells
    file: the next open with no more memory says it at once (no pass); with more
    memory the grid is computed; a damaged marker is ignored and removed."""
    import dataclasses

    _, out, xyz = survey
    base = open_campaign(out)
    overview = read_overview(base, CAP)
    s = MapSettings(cell_size=0.5)
    where = cells_path(out, s)
    said = "the cells and the points held on tile seams need about 9 MiB, more memory"
    save_no_fit(where, 64 << 20, said)
    assert load_no_fit(where, 64 << 20) == said and load_no_fit(where, 65 << 20) is None

    def opened(memory):
        return campaign_cloud(dataclasses.replace(base, memory_bytes=memory), overview,
                              presets=campaign_presets(overview, N), max_display=10_000,
                              cache_bytes=1 << 28, cache_pool=None)

    small = opened(32 << 20)
    with pytest.raises(InputError, match="need about 9 MiB"):
        small.result(s)
    assert small.store.computed == []
    big = opened(128 << 20)
    assert_same_cells(big.result(s), grid_roughness(xyz, 0.5, engine="numpy"), rtol=1e-12)
    assert 0.5 in big.store.computed  # (with the other presets: they fit together)
    where.with_suffix(".nofit").write_text("{not json")
    assert load_no_fit(where, 1) is None and not where.with_suffix(".nofit").exists()
