"""Level of detail straight from a campaign's COPC nodes (issue 33 item 3): the tree
of the file's hierarchy serves the one node selection; the nodes below the overview
are decoded on demand in the reader sandbox into a byte-bounded cache; a tab that
looks closely at a patch receives every point of it within its budget, each decoded
point in its cell's colour of the map shown; a damaged node is one error line."""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("lazrs")

import laspy  # noqa: E402
import viser  # noqa: E402

from rough_viewer.app.campaign import (  # noqa: E402
    campaign_cloud,
    campaign_presets,
    open_campaign,
    read_overview,
)
from rough_viewer.app.campaign_nodes import (  # noqa: E402
    BYTES_PER_POINT,
    CopcNodes,
    campaign_nodes,
    overview_starts,
)
from rough_viewer.app.colouring import by_cell, cell_colours  # noqa: E402
from rough_viewer.app.server import app_options, mount_app  # noqa: E402
from rough_viewer.app.settings import MapSettings  # noqa: E402
from rough_viewer.io.copc.reader import decode_nodes, open_copc  # noqa: E402
from rough_viewer.io.sandbox import isolate  # noqa: E402
from rough_viewer.lod.camera import ViewCamera  # noqa: E402
from rough_viewer.lod.copc import copc_tree  # noqa: E402
from rough_viewer.lod.select import boxes_in_view, select_nodes  # noqa: E402
from tests.app.browser import wait_until  # noqa: E402
from tests.app.protocol import ProtocolClient, join, on_worker  # noqa: E402
from tests.app.serve_process import ServeProcess  # noqa: E402
from tests.app.test_lod_app import _received_points  # noqa: E402
from tests.scale.test_tiles import _survey  # noqa: E402

N = 60_000
#: The overview: the hierarchy's root level only (12,951 of the 60,000 points).
CAP = 20_000
#: A tab's budget: half the file.
BUDGET = 30_000

sandboxed = pytest.mark.skipif(not isolate.available(), reason="the reader sandbox needs Linux")


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    return _survey(tmp_path_factory.mktemp("campaign-lod"), N, seed=11)


def _file_points(path) -> np.ndarray:
    """Every point of the COPC file, read by laspy (metres: the file's unit)."""
    las = laspy.read(str(path))
    return np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])


def _patches(xyz: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centre, face normal) of three patches of the face, off the root cube's middle
    (where eight cubes meet), each centred on a point of the file."""
    c = xyz.mean(axis=0)
    _, _, vt = np.linalg.svd(xyz[::10] - c, full_matrices=False)
    out = []
    for a, b in ((1.3, 0.9), (-1.1, 0.7), (0.8, -1.2)):
        p = c + a * vt[0] + b * vt[1]
        out.append((xyz[np.argmin(np.linalg.norm(xyz - p, axis=1))], vt[2]))
    return out


def _patch(xyz: np.ndarray, centre: np.ndarray, normal: np.ndarray,
           radius: float = 0.2) -> np.ndarray:
    """Brute force: the points within ``radius`` of ``centre`` along the face (and
    0.5 m across it)."""
    rel = xyz - centre
    across = rel @ normal
    along = rel - np.outer(across, normal)
    return (np.linalg.norm(along, axis=1) < radius) & (np.abs(across) < 0.5)


# ----------------------------------------------------------------------------- the tree


def test_the_tree_is_the_hierarchy_and_its_selection_the_brute_force_one(survey):
    """Every node of the file is one row of the tree with its count, its cube where
    its key puts it in the root cube (and every point it decodes to inside it), its
    parent the key halved; children contiguous. For cameras far and near, with a
    budget that holds the file and no spacing limit, the selection is every node
    whose box meets the view and whose ancestors' do (brute force over all nodes);
    with a smaller budget it holds at most the budget and is closed under parents."""
    _, out, _ = survey
    copc = open_copc(out)
    tree = copc_tree(copc)
    real = np.flatnonzero(tree.file_row >= 0)
    assert real.size == copc.nodes.shape[0] and tree.n_points == N
    e = copc.nodes[tree.file_row[real]]
    np.testing.assert_array_equal(tree.counts[real], e["count"])
    np.testing.assert_array_equal(tree.level[real], e["depth"])
    edge = 2 * copc.halfsize / 2.0 ** e["depth"]
    key = np.column_stack([e["x"], e["y"], e["z"]]).astype(np.float64)
    np.testing.assert_allclose(tree.cube_lo[real], copc.cube_min + key * edge[:, None],
                               rtol=0, atol=1e-9)
    x, y, z = decode_nodes(copc, tree.file_row[real])
    at = np.concatenate([[0], np.cumsum(e["count"])])
    for i, k in enumerate(real):
        pts = np.column_stack([x[at[i]:at[i + 1]], y[at[i]:at[i + 1]], z[at[i]:at[i + 1]]])
        assert np.all(pts >= tree.box_lo[k] - 1e-9) and np.all(pts <= tree.box_hi[k] + 1e-9)
    keys = np.rint((tree.cube_lo - tree.origin) / tree.size[:, None]).astype(np.int64)
    for k in range(1, tree.n_nodes):
        p = tree.parent[k]
        assert tree.level[p] == tree.level[k] - 1
        assert tree.child_start[p] <= k < tree.child_stop[p]
        np.testing.assert_array_equal(keys[k] // 2, keys[p])
    xyz = _file_points(out)
    centre, normal = _patches(xyz)[0]
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    for eye in (centre + 1.5 * normal, 0.5 * (lo + hi) + 12.0 * normal):
        cam = ViewCamera.looking_at(eye, centre, fov_rad=0.5)
        inside = boxes_in_view(cam, tree.box_lo, tree.box_hi)
        want = set()
        for k in range(tree.n_nodes):
            a, ok = k, True
            while a >= 0:
                ok &= bool(inside[a])
                a = int(tree.parent[a])
            if ok:
                want.add(k)
        got = select_nodes(tree, cam, 10 * N, min_spacing_px=0.0)
        assert set(got.nodes.tolist()) == want and got.complete
        small = select_nodes(tree, cam, BUDGET)
        assert small.points <= BUDGET
        chosen = set(small.nodes.tolist())
        assert all(int(tree.parent[k]) in chosen for k in chosen if k)


def test_a_hierarchy_without_inner_nodes_gets_empty_ones(survey):
    """COPC allows nodes without points: the file's deepest nodes alone (the upper
    levels dropped from the hierarchy) still make a tree, their ancestors empty."""
    import dataclasses

    _, out, _ = survey
    copc = open_copc(out)
    deep = copc.nodes[copc.nodes["depth"] == copc.nodes["depth"].max()]
    tree = copc_tree(dataclasses.replace(copc, nodes=deep))
    assert tree.counts[0] == 0 and tree.file_row[0] == -1
    assert int(tree.counts.sum()) == int(deep["count"].sum())
    assert set(tree.file_row[tree.file_row >= 0].tolist()) == set(range(deep.shape[0]))


# ----------------------------------------------------------------------------- the cache


def _wait_idle(nodes: CopcNodes, timeout: float = 120.0) -> None:
    wait_until(lambda: nodes.idle, timeout, "the nodes decoded")


@sandboxed
def test_decoded_nodes_are_the_files_and_the_cache_keeps_its_bound(survey):
    """Nodes wished for are decoded in the reader's child process, bit for bit the
    points laspy reads of them (metres); with a bound of three average nodes the
    cache never holds more bytes than it (peak counted), the least recently used go
    first, and a node larger than the bound is refused in one line, never decoded.
    The overview's nodes are rows of the overview, never decoded."""
    _, out, _ = survey
    campaign = open_campaign(out)
    overview = read_overview(campaign, CAP)
    copc = campaign.copc
    full = campaign_nodes(copc, campaign.source, overview.n)
    tree = full.tree
    starts = overview_starts(copc, tree, overview.n)
    top = np.flatnonzero(starts >= 0)
    assert top.size and int(tree.counts[top].sum()) == overview.n
    ov = np.column_stack([overview.x, overview.y, overview.z])
    for k in top:  # the overview's rows are the node's points (decoded in file order)
        x, y, z = decode_nodes(copc, [int(tree.file_row[k])])
        np.testing.assert_array_equal(ov[full.rows(k)], np.column_stack([x, y, z]))
    deep = [k for k in range(tree.n_nodes) if starts[k] < 0 and tree.counts[k] > 0]
    mean = int(tree.counts[deep].mean())
    bound = 3 * mean * BYTES_PER_POINT
    big = [k for k in deep if tree.counts[k] * BYTES_PER_POINT > bound]
    said: list[str] = []
    came: list[frozenset[int]] = []
    nodes = CopcNodes(copc, campaign.source, tree, starts, cache_bytes=bound, batch_points=2 * mean)
    nodes.listen(came.append, said.append)
    try:
        nodes.want(7, deep)
        _wait_idle(nodes)
        assert nodes.cache.peak_bytes <= bound and nodes.cache.nbytes <= bound
        assert nodes.decoded_nodes == len(deep) - len(big) and nodes.cache.evicted > 0
        assert len(said) == len(big) and all("not drawn" in s and str(out) in s for s in said)
        assert came and all(c == frozenset({7}) for c in came)
        assert nodes.requests > 1  # batches of at most twice a node
        for k in nodes.cache.keys():
            pts = nodes.points(k)
            x, y, z = decode_nodes(copc, [int(tree.file_row[k])])
            np.testing.assert_array_equal(pts.x, x)
            np.testing.assert_array_equal(pts.z, z)
        for k in top:
            assert k not in nodes.cache and nodes.has(k)
    finally:
        nodes.close()
        full.close()


# ----------------------------------------------------------------------------- the app


def _app(out, budget=BUDGET, cap=CAP):
    campaign = open_campaign(out)
    overview = read_overview(campaign, cap)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    options = app_options(overview, prefetch=False, variogram=False, point_budget=budget)
    presets = campaign_presets(overview, N)
    loaded = campaign_cloud(campaign, overview, presets=presets,
                            max_display=options.max_display, cache_bytes=options.cache_bytes,
                            cache_pool=options.cache_pool)
    app = mount_app(server, loaded, MapSettings(cell_size=presets[-1]), options)
    return server, app, loaded


def _decoded_shown(app, cid) -> list[int]:
    scene = app.host.scene
    tab = scene.tabs[cid]
    return [k for k in tab.residency.shown if not scene.nodes.in_overview(k)]


def _check_colours(app, cid, copc, rgb=None, res=None) -> int:
    """Every decoded node the tab shows is coloured point by point with its cell's
    colour ``rgb`` of ``res`` (default: the map shown) (independent: floor((p - o) /
    g) looked up among the result's cell indices). Returns the points checked."""
    scene = app.host.scene
    shown = app.session.shown
    if rgb is None:
        rgb = cell_colours(shown.result, shown.settings,
                           colours_range=shown.stats.colour_range)
    res = shown.result if res is None else res
    index = {tuple(v): i for i, v in enumerate(res.ijk.tolist())}
    checked = 0
    for k in _decoded_shown(app, cid):
        x, y, z = decode_nodes(copc, [int(scene.nodes.tree.file_row[k])])
        ijk = np.floor((np.column_stack([x, y, z]) - res.grid.origin)
                       / res.grid.cell_size).astype(np.int64)
        want = rgb[[index[tuple(v)] for v in ijk.tolist()]]
        np.testing.assert_array_equal(np.asarray(scene.tabs[cid].handles[k].colors), want)
        checked += x.shape[0]
    return checked


@sandboxed
def test_a_tab_close_to_a_patch_gets_its_decoded_nodes_in_their_cells_colours(survey):
    """A websocket tab 1.5 m in front of a patch: the nodes it lacks are decoded off
    the worker and sent as they come; each decoded point shows its cell's colour in
    the map; a model change, a grid change, a feature's colouring by cell recolour
    the decoded nodes too (a colouring of the cloud's rows only leaves them in the
    last by cell); the tab holds at most its budget; the server's decoded nodes stay
    within the cache's bound."""
    _, out, _ = survey
    xyz = _file_points(out)
    server, app, loaded = _app(out)
    client = join(server)
    try:
        assert app.wait_idle(300)
        cid = client.client_id
        centre, normal = _patches(xyz)[0]
        o = loaded.origin
        client.look_from(centre + 1.5 * normal - o, centre - o, fov=0.5)
        wait_until(lambda: cid in app.host.scene.tabs and not app.host.scene.tabs[cid].missing
                   and app.host.scene.tabs[cid].camera is not None
                   and _decoded_shown(app, cid) and app.host.scene.nodes.idle
                   and not app.worker.busy, 120, "the decoded nodes")
        assert app.wait_idle(60)
        tab = app.host.scene.tabs[cid]
        assert tab.residency.shown_points <= BUDGET
        assert _check_colours(app, cid, loaded.campaign.copc) > 1000
        nodes = app.host.scene.nodes
        assert nodes.cache.peak_bytes <= nodes.cache.max_bytes
        before = {k: np.array(tab.handles[k].colors) for k in _decoded_shown(app, cid)}
        app.map.model.value = "OLS"
        wait_until(lambda: app.session.shown.settings.model == "ols", 60, "the OLS map")
        assert app.wait_idle(120)
        assert _check_colours(app, cid, loaded.campaign.copc) > 1000
        assert any(not np.array_equal(before[k], tab.handles[k].colors) for k in before)
        # another grid: the decoded points take their cells of that grid
        coarse = next(o for o in app.map.grid.options
                      if o != "free" and float(o) == loaded.presets[0])
        app.map.grid.value = coarse
        wait_until(lambda: app.session.shown.settings.cell_size == loaded.presets[0], 120,
                   "the coarse map")
        assert app.wait_idle(120)
        assert _check_colours(app, cid, loaded.campaign.copc) > 1000
        # a feature's colouring by cell (as the zones and the sets make theirs): every
        # cell its own colour; then one of the cloud's rows only (a crop's selection):
        # the decoded nodes keep the last colouring by cell
        res = app.session.shown.result
        labels = np.random.default_rng(3).integers(0, 255, (res.ijk.shape[0], 3)).astype(np.uint8)
        on_worker(app, lambda: app.host.scene.colour_by(by_cell(labels, res)))
        assert _check_colours(app, cid, loaded.campaign.copc, labels, res) > 1000
        on_worker(app, lambda: app.host.scene.colour_by(
            lambda idx: np.zeros((len(idx), 3), dtype=np.uint8)))
        assert _check_colours(app, cid, loaded.campaign.copc, labels, res) > 1000
        assert not app.host.errors, app.host.errors
    finally:
        client.close()
        app.stop()
        server.stop()


@sandboxed
def test_a_node_that_left_the_cache_is_decoded_again_for_its_new_colours(survey):
    """With room for the largest node in the decoded nodes' cache, the tab still gets its
    nodes (it keeps what it was sent); a model change then finds their points gone:
    they are decoded again, off the worker, and recoloured as they come, each point
    in its cell's colour; the cache never held more than its bound."""
    _, out, _ = survey
    xyz = _file_points(out)
    server, app, loaded = _app(out)
    nodes = loaded.lod_nodes()
    tree = nodes.tree
    deep = [k for k in range(tree.n_nodes) if not nodes.in_overview(k)]
    nodes.cache.max_bytes = int(tree.counts[deep].max()) * BYTES_PER_POINT  # the largest
    client = join(server)
    try:
        assert app.wait_idle(300)
        cid = client.client_id
        centre, normal = _patches(xyz)[0]
        o = loaded.origin
        client.look_from(centre + 1.5 * normal - o, centre - o, fov=0.5)

        def settled() -> bool:
            tab = app.host.scene.tabs.get(cid)
            return bool(tab is not None and tab.camera is not None and not tab.missing
                        and not tab.stale and len(_decoded_shown(app, cid)) >= 3
                        and nodes.idle and not app.worker.busy)

        wait_until(settled, 120, "the decoded nodes")
        decoded = nodes.decoded_nodes
        app.map.model.value = "OLS"
        wait_until(lambda: app.session.shown.settings.model == "ols", 60, "the OLS map")
        wait_until(settled, 120, "the nodes decoded again")
        assert app.wait_idle(60)
        assert nodes.cache.evicted > 0
        assert nodes.decoded_nodes > decoded  # those whose points had gone
        assert _check_colours(app, cid, loaded.campaign.copc) > 1000
        assert nodes.cache.peak_bytes <= nodes.cache.max_bytes
    finally:
        client.close()
        app.stop()
        server.stop()


def _damage_node(survey, tmp_path, row: int):
    """The file with node ``row``'s compressed bytes overwritten with 0xFF."""
    _, out, _ = survey
    e = open_copc(out).nodes[row]
    buf = bytearray(out.read_bytes())
    at = int(e["offset"])
    buf[at:at + min(64, int(e["size"]))] = b"\xff" * min(64, int(e["size"]))
    p = tmp_path / "damaged-node.copc.laz"
    p.write_bytes(bytes(buf))
    return p


@sandboxed
def test_a_damaged_node_decoded_on_demand_is_one_error_line(survey, tmp_path):
    """A deep node whose chunk is garbage: decoding it for a tab fails in the reader's
    child process, which is one line in the app's error line naming the file; the
    app keeps serving (the other nodes come, the tab is refined again). (The map's
    pass over every node fails on it first: that is its own line.)"""
    _, out, _ = survey
    xyz = _file_points(out)
    copc = open_copc(out)
    centre, normal = _patches(xyz)[0]
    tree = copc_tree(copc)
    cam = ViewCamera.looking_at(centre + 1.5 * normal, centre, fov_rad=0.5)
    sel = select_nodes(tree, cam, BUDGET)
    deep = [int(tree.file_row[k]) for k in sel.nodes if tree.level[k] >= 1]
    bad = _damage_node(survey, tmp_path, deep[-1])
    server, app, loaded = _app(bad)
    client = join(server)
    try:
        assert app.wait_idle(300)
        before = len(app.host.errors)
        cid = client.client_id
        o = loaded.origin
        client.look_from(centre + 1.5 * normal - o, centre - o, fov=0.5)
        wait_until(lambda: len(app.host.errors) > before, 120, "the error line")
        wait_until(lambda: app.host.scene.nodes.idle and not app.worker.busy, 120, "idle")
        errors = list(app.host.errors)[before:]
        assert len(errors) == 1 and bad.name in errors[0] and "\n" not in errors[0], errors
        assert _decoded_shown(app, cid)  # the others were drawn
        assert app.host.scene.nodes.failed(next(
            k for k in range(tree.n_nodes) if tree.file_row[k] == deep[-1]))
    finally:
        client.close()
        app.stop()
        server.stop()


def _matched(patch: np.ndarray, got: np.ndarray, tol: float) -> bool:
    """Every point of ``patch`` matched to its own point of ``got`` within ``tol``
    (one to one: an assignment of least total distance among the points of ``got``
    near the patch)."""
    from scipy.optimize import linear_sum_assignment
    from scipy.spatial import cKDTree

    hits = cKDTree(got).query_ball_point(patch, tol)
    near = got[np.unique(np.concatenate([np.asarray(h, dtype=np.int64) for h in hits]))]
    if near.shape[0] < patch.shape[0]:
        return False
    cost = np.linalg.norm(patch[:, None, :] - near[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    return rows.shape[0] == patch.shape[0] and bool(cost[rows, cols].max() < tol)


@sandboxed
def test_a_real_serve_sends_a_tab_every_point_of_the_patch_it_looks_at(survey):
    """``serve survey.copc.laz --overview-points 20000 --point-budget 30000`` as a
    process, a websocket tab 1.5 m in front of three patches in turn: each time it
    receives every point of the 20 cm patch (matched one to one with the file's
    points as laspy reads them, within float16's node-local error: 6 m nodes are
    sent to 1.5 mm), most of them
    from nodes below the overview, and never more than its budget shown."""
    from scipy.spatial import cKDTree

    _, out, _ = survey
    xyz = _file_points(out)
    overview = read_overview(open_campaign(out), CAP)
    lo, hi = overview.bounds()
    o = np.round(0.5 * (lo + hi))  # the app's display frame
    proc = ServeProcess(str(out), "--overview-points", str(CAP), "--no-token",
                        "--point-budget", str(BUDGET), timeout=300)
    try:
        client = ProtocolClient(proc.port, proc.path)
        wait_until(lambda: len(_received_points(client)) > 0, 120, "the first nodes")
        ov = cKDTree(np.column_stack([overview.x, overview.y, overview.z]))
        for centre, normal in _patches(xyz):
            patch = xyz[_patch(xyz, centre, normal)]
            assert patch.shape[0] > 200
            assert (ov.query(patch)[0] > 0).mean() > 0.5  # most are below the overview
            client.look_from(centre + 1.5 * normal - o, centre - o, fov=0.5)

            def complete(patch=patch) -> bool:
                got = _received_points(client) + o
                if got.shape[0] < patch.shape[0]:
                    return False
                return _matched(patch, got, 2e-3)

            t0 = time.time()
            wait_until(complete, 120, "every point of the patch")
            assert time.time() - t0 < 120
            assert _received_points(client).shape[0] <= BUDGET
        client.close()
        assert proc.alive()
    finally:
        proc.stop()
    assert "Traceback" not in "".join(proc.stderr)
