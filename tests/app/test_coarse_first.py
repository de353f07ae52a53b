"""Issue 35 item 3, coarse first: a big cloud's first map is coloured from its
coarsest preset while the chosen grid is computed, then the chosen grid's colours
replace it; a slow grid change keeps the old colours until the new are ready, and
the status line says what is shown and how far the new grid has come. "Big" is
:data:`rough_viewer.app.features.map.render.PREVIEW_POINTS`, lowered here so a
small cloud counts; the colours are compared against the store's own results."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from rough_viewer.app.colouring import by_cell, cell_colours, map_stats
from rough_viewer.app.features.map import render
from rough_viewer.app.scene import Scene
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.shell import Shell
from rough_viewer.app.store import InMemoryStore
from tests.app.browser import wait_until
from tests.app.protocol import join, shown_colours

PRESETS = (0.4, 0.2, 0.1)


def expected(loaded, settings: MapSettings, idx: np.ndarray) -> np.ndarray:
    """The roughness colours of points ``idx`` for ``settings``, from the store's result
    (computed there once and cached: the app's own object)."""
    result = loaded.store.result(settings)
    stats = map_stats(result, settings)
    return by_cell(cell_colours(result, settings, colours_range=stats.colour_range),
                   result.point_cell)(idx)


@pytest.fixture
def recorded(monkeypatch):
    """Every colouring the scene is given and every status line, in order."""
    colourings: list[object] = []
    said: list[str] = []
    colour_by, say = Scene.colour_by, Shell.say

    def record_colours(self, colouring):
        colourings.append(colouring)
        colour_by(self, colouring)

    def record_status(self, status):
        said.append(status)
        say(self, status)

    monkeypatch.setattr(Scene, "colour_by", record_colours)
    monkeypatch.setattr(Shell, "say", record_status)
    monkeypatch.setattr(render, "PREVIEW_POINTS", 1)
    return colourings, said


@pytest.fixture
def big(recorded, cloud):
    """An app whose cloud counts as big, a websocket tab open while it loads."""
    from rough_viewer.app.gate import open_server
    from rough_viewer.app.server import build_app

    server, _ = open_server("127.0.0.1", 0, token=None, log=False)
    client = join(server)
    app = build_app(server, cloud, prefetch=False, variogram=False, presets=PRESETS)
    assert app.wait_idle(60)
    yield app, client, recorded
    client.close()
    app.stop()
    server.stop()


def test_first_map_is_the_coarsest_preset_then_the_chosen_grid(big):
    app, client, (colourings, said) = big
    loaded = app.session.shown.loaded
    chosen = app.session.shown.settings
    assert chosen.cell_size == 0.1 and loaded.presets == PRESETS
    idx = loaded.display_index
    colour_calls = [c for c in colourings if not np.all(np.asarray(c(idx[:5])) == 190)]
    assert len(colour_calls) == 2  # the coarse map, then the chosen grid
    coarse = chosen.with_(cell_size=0.4)
    first = np.asarray(colour_calls[0](idx))
    np.testing.assert_array_equal(first, expected(loaded, coarse, idx))
    last = np.asarray(colour_calls[1](idx))
    np.testing.assert_array_equal(last, expected(loaded, chosen, idx))
    np.testing.assert_array_equal(shown_colours(app), last)
    assert not np.array_equal(first, last)  # the two grids colour differently
    # the status said the coarse map was up while the chosen grid was computed, with
    # its progress, then names the chosen grid as ever
    pending = [s for s in said if "coarse preview, grid 0.4 m; computing grid 0.1 m…" in s]
    assert pending and pending[0].endswith("0 %") and pending[-1].endswith("100 %")
    assert "ODR, grid 0.1 m, axis y" in said[-1] and "coarse" not in said[-1]
    assert app.map.previews[-1]["cell_size"] == 0.4 and app.map.previews[-1]["for"] == 0.1
    # the coarse grid was kept in the cache: going there recolours only
    assert loaded.is_cached(coarse)
    # the first load's job: the coarse map is a stage of its own
    stages = dict(next(r for r in app.worker.records if r.kind == "ShowJob").stages)
    assert {"show", "preview", "grid", "colours"} <= set(stages)
    # what the first frame did not wait for still ran: the chosen grid, then the panels
    kinds = [r.kind for r in app.worker.records]
    assert "PanelsJob" in kinds[kinds.index("ShowJob"):]


def test_a_slow_grid_change_keeps_the_old_colours_until_the_new_are_ready(big, monkeypatch):
    app, _client, (colourings, said) = big
    loaded = app.session.shown.loaded
    before = shown_colours(app).copy()
    old = app.session.shown.settings
    gate, entered = threading.Event(), threading.Event()
    result = InMemoryStore.result

    def slow(self, settings, *, progress=None):
        if settings.cell_size == 0.3 and not self.is_cached(settings):
            entered.set()
            assert gate.wait(30)
        return result(self, settings, progress=progress)

    monkeypatch.setattr(InMemoryStore, "result", slow)
    n_colours = len(colourings)
    app.map.grid_free.value = 0.3  # a free size: the panels computed every preset
    wait_until(entered.is_set, 30, "the 0.3 m grid to start")
    try:
        # computing: the 0.1 m colours stay, the status says so
        assert len(colourings) == n_colours
        np.testing.assert_array_equal(shown_colours(app), before)
        assert app.session.shown.settings == old
        assert said[-1].endswith("ODR, grid 0.1 m shown; computing grid 0.3 m… 0 %")
    finally:
        gate.set()
    assert app.wait_idle(60)
    new = old.with_(cell_size=0.3)
    assert app.session.shown.settings.grid_key == new.grid_key
    np.testing.assert_array_equal(shown_colours(app),
                                  expected(loaded, new, loaded.display_index))
    assert len(colourings) == n_colours + 1  # no coarse map in between
    assert "ODR, grid 0.3 m, axis y" in said[-1]


def test_a_small_cloud_shows_its_grid_at_once(app, cloud):
    assert cloud.n < render.PREVIEW_POINTS
    assert not app.map.previews
    stages = dict(next(r for r in app.worker.records if r.kind == "ShowJob").stages)
    assert "preview" not in stages and "grid" in stages
    assert "computing grid" not in app.host.status.content


def test_a_big_clouds_plane_comes_from_its_coarse_first_grid(monkeypatch, cloud):
    """From PLANE_FROM_GRID_POINTS the whole-cloud plane is combined from the coarsest
    preset's cell moments (prepared once, for the plane and the coarse first map):
    the plane of a pass over the points, up to rounding."""
    from rough_viewer.app import cloud as cloud_mod
    from rough_viewer.app.cloud import LoadedCloud
    from rough_viewer.grid.planes import whole_cloud_plane

    want = whole_cloud_plane(cloud)
    from rough_viewer.app import store as store_mod

    monkeypatch.setattr(cloud_mod, "PLANE_FROM_GRID_POINTS", 1)
    monkeypatch.setattr(store_mod, "COARSE_ALONE_POINTS", 1)
    loaded = LoadedCloud(cloud, max_display=1000, presets=PRESETS)
    assert ("prepared", 0.4) in loaded.store._cache and ("prepared", 0.1) not in loaded.store._cache
    np.testing.assert_allclose(loaded.plane.normal, want.normal, atol=1e-12)
    np.testing.assert_allclose(loaded.plane.centroid, want.centroid, rtol=1e-12)
    assert loaded.auto_axis == "y"
    # the finest preset is then indexed on its own; the coarse grid indexed alone holds
    # the cells and points that coarsening the fine one gives
    from rough_viewer.grid.roughness import coarsen_prepared

    alone = loaded.prepared(0.4)
    fine = loaded.prepared(0.1)
    made = coarsen_prepared(fine, 4)
    assert alone is not made and alone.parent is None
    np.testing.assert_array_equal(alone.index.ijk, made.index.ijk)
    np.testing.assert_array_equal(alone.index.point_cell, made.index.point_cell)
    np.testing.assert_allclose(alone.moments.s2, made.moments.s2, rtol=1e-7)  # round-off
    # so once the finest grid is there, the store keeps the coarse preset coarsened
    # from it (its own cells only: no second copy of every point's row)
    lean = loaded.prepared(0.4)
    assert lean.parent is not None and lean.fine_cell is fine.index.point_cell
    np.testing.assert_array_equal(lean.point_cell(), alone.index.point_cell)


def test_a_failed_chosen_grid_leaves_the_coarse_map_shown(recorded, cloud, monkeypatch):
    """The chosen grid runs out of memory after the coarse map is up: the coarse map
    stays the map shown, with the error, and the status line names it."""
    from rough_viewer.app.gate import open_server
    from rough_viewer.app.server import build_app

    colourings, said = recorded
    result = InMemoryStore.result

    def no_fine(self, settings, *, progress=None):
        if settings.cell_size == 0.1:
            raise MemoryError
        return result(self, settings, progress=progress)

    monkeypatch.setattr(InMemoryStore, "result", no_fine)
    server, _ = open_server("127.0.0.1", 0, token=None, log=False)
    client = join(server)
    app = build_app(server, cloud, prefetch=False, variogram=False, presets=PRESETS)
    try:
        assert app.wait_idle(60)
        shown = app.session.shown
        assert shown.settings.cell_size == 0.4 and shown.result is not None
        assert app.map.grid.value == "0.4"  # the controls show what the points show
        assert "not enough memory" in app.host.errors[-1]
        assert "ODR, grid 0.4 m, axis y" in said[-1] and "computing" not in said[-1]
        np.testing.assert_array_equal(
            shown_colours(app), expected(shown.loaded, shown.settings, shown.loaded.display_index))
    finally:
        client.close()
        app.stop()
        server.stop()
