"""The map's jobs on a real server: nothing a user asked for is lost, errors become
notices, and a grid that cannot fit leaves the server up."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from rough_viewer.app.features.bias import BiasPanel
from rough_viewer.app.features.file import FileFeature
from rough_viewer.app.features.map.render import RenderJob
from rough_viewer.app.features.panels import PanelsFeature
from rough_viewer.app.gate import open_server
from rough_viewer.app.server import App, build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.worker import Job, Run
from tests.app.protocol import join, settle, shown_colours
from tests.helpers import PAPER_PRESETS

#: Fixed presets for tests about the job pipeline, not the data's grid.
FIXED = {"presets": PAPER_PRESETS, "settings": MapSettings(cell_size=0.25)}


@dataclass(frozen=True)
class Hold(Job[App]):
    """Keeps the worker busy until released (like a long grid on a big cloud)."""

    gate: threading.Event = field(compare=False)
    entered: threading.Event = field(compare=False)
    lane: ClassVar[str] = "hold"

    def stages(self, ctx: App, run: Run) -> Iterator[str]:
        self.entered.set()
        self.gate.wait(30)
        yield "held"


def hold(app: App) -> threading.Event:
    gate, entered = threading.Event(), threading.Event()
    app.submit(Hold(gate, entered))
    assert entered.wait(10)
    return gate


def test_a_load_followed_at_once_by_a_control_change_shows_the_loaded_file(server, cloud,
                                                                           tmp_path):
    np.save(tmp_path / "other.npy", cloud.xyz()[::2])
    app = build_app(server, cloud, prefetch=False, data_dir=tmp_path, **FIXED)
    assert app.wait_idle(60)
    gate = hold(app)
    app.feature(FileFeature).path.value = "other.npy"
    app.feature(FileFeature).load.value = True  # "Load file" while the worker is busy
    app.map.model.value = "OLS"  # and a control change right after
    app.map.grid.value = "0.5"
    assert app.worker.pending_kinds() == ["LoadJob"]  # the views merged into the load
    gate.set()
    assert app.wait_idle(60)
    shown = app.session.shown
    assert shown.loaded.n_total == cloud.n // 2 and "other.npy" in app.host.status.content
    # the model change is kept; the new file opens at its own default grid, among its
    # own presets (from its point spacing: half the points, coarser grids)
    assert shown.settings.model == "ols"
    assert shown.loaded.presets == (0.8, 0.4, 0.2, 0.1)
    assert shown.settings.cell_size == 0.1 and app.map.grid.value == "0.1"
    assert app.map.grid.options == ("0.8", "0.4", "0.2", "0.1", "free")
    assert shown.result is not None and shown.result.n_points_total == cloud.n // 2
    assert list(app.host.errors) == []
    app.stop()


def test_the_same_through_the_browser_protocol(cloud, tmp_path):
    np.save(tmp_path / "third.npy", cloud.xyz()[::3])
    server, _ = open_server("127.0.0.1", 0, token=None, log=False)
    app = build_app(server, cloud, prefetch=False, data_dir=tmp_path)
    assert app.wait_idle(60)
    client = join(server)
    try:
        gate = hold(app)
        client.set_value("File path", "third.npy")
        client.set_value("Load file", True)
        client.set_value("Display", "binary")
        time.sleep(0.5)
        gate.set()
        settle(app, lambda: app.session.shown.loaded.n_total == len(cloud.xyz()[::3])
               and app.session.shown.settings.display == "binary", "the load and the display", 60)
        assert app.session.shown.loaded.n_total == len(cloud.xyz()[::3])
        assert app.session.shown.settings.display == "binary"
    finally:
        client.close()
        app.stop()
        server.stop()


def test_a_failed_load_keeps_the_control_change(server, cloud, tmp_path):
    app = build_app(server, cloud, prefetch=False, data_dir=tmp_path)
    assert app.wait_idle(60)
    gate = hold(app)
    app.load(path="missing.npy")
    app.map.model.value = "hybrid"
    gate.set()
    assert app.wait_idle(60)
    assert "not found" in app.host.errors[-1]
    assert app.session.shown.loaded.cloud is cloud and app.session.shown.settings.model == "hybrid"
    assert app.host.error.visible  # the load's error stays on screen
    app.stop()


def test_a_newer_load_replaces_a_pending_one(server, cloud, tmp_path):
    for name, step in (("a.npy", 2), ("b.npy", 4)):
        np.save(tmp_path / name, cloud.xyz()[::step])
    app = build_app(server, cloud, prefetch=False, data_dir=tmp_path)
    assert app.wait_idle(60)
    gate = hold(app)
    app.load(path="a.npy")
    app.load(path="b.npy")
    assert app.worker.pending_kinds() == ["LoadJob"]
    gate.set()
    assert app.wait_idle(60)
    assert app.session.shown.loaded.n_total == len(cloud.xyz()[::4])
    app.stop()


def test_bias_predictions_are_reached_from_the_app_and_run_on_the_worker(app):
    threads: list[str] = []
    real = app.worker._thread

    bias = app.feature(BiasPanel)
    bias.asperity_mm.value = 10.0
    bias.noise_mm.value = 1.0
    bias.er_mm.value = 3.0
    original = bias.update

    def spy():
        threads.append(threading.current_thread().name)
        return original()

    bias.update = spy  # type: ignore[method-assign]
    bias.button.value = True  # "Predict bias" in the Bias tab
    assert app.wait_idle(120)
    assert threads == [real.name] and bias.last is not None
    assert "ER / r" in bias.result.content and len(bias.plot.figure.data) == 2
    assert [r.kind for r in app.worker.records][-1] == "BiasJob"


def test_a_fine_grid_that_cannot_fit_ends_in_a_message(server, cloud, monkeypatch):
    # On a machine with 1 MB free (memory.available_bytes), a 2 mm grid on 40,000
    # points cannot fit: the grid code refuses it (memory.require) before allocating,
    # the same path as the 16.5 GB request on a 24 GB machine.
    import rough_viewer.memory as memory

    app = build_app(server, cloud, prefetch=False, **FIXED)
    assert app.wait_idle(60)
    before = shown_colours(app).copy()
    monkeypatch.setattr(memory, "available_bytes", lambda: 1e6)
    app.map.grid_free.value = 0.002
    assert app.wait_idle(60)
    msg = app.host.errors[-1]
    assert "grid 0.002 m" in msg and "needs about" in msg and "memory" in msg, msg
    assert app.host.error.visible and "previous view is kept" in app.host.error.content
    # the view and the controls are the previous ones
    assert app.session.shown.settings.cell_size == 0.25 and app.map.grid.value == "0.25"
    assert np.array_equal(shown_colours(app), before)
    monkeypatch.undo()
    app.map.grid.value = "0.5"  # the server is still up and answers
    assert app.wait_idle(60) and app.session.shown.settings.cell_size == 0.5
    assert not app.host.error.visible
    app.stop()


def test_a_semivariogram_that_cannot_fit_leaves_the_map(server, cloud, monkeypatch):
    import rough_viewer.app.features.panels as panels
    from rough_viewer.memory import require

    def too_big(ijk, maps, g, **kw):
        require(1e15, f"the semivariogram of {len(ijk):,} cells at {g:g} m")
        raise AssertionError("unreachable")

    app = build_app(server, cloud, prefetch=False, **FIXED)
    assert app.wait_idle(60)
    monkeypatch.setattr(panels, "semivariograms", too_big)
    app.map.grid.value = "0.5"
    assert app.wait_idle(60)
    msg = app.host.errors[-1]
    assert msg.startswith("semivariogram of grid 0.5 m: the semivariogram of") and \
        "needs about" in msg, msg
    assert "The map and the other panels are shown" in app.host.error.content
    assert app.session.shown.settings.cell_size == 0.5  # the map is shown
    assert "grid 0.5 m" in app.feature(PanelsFeature).histogram.figure.layout.title.text
    assert "grid 0.25 m" in app.feature(PanelsFeature).variogram.figure.layout.title.text  # the old one stays
    monkeypatch.undo()
    app.map.grid.value = "1"
    assert app.wait_idle(60) and "grid 1 m" in app.feature(PanelsFeature).variogram.figure.layout.title.text
    app.stop()


@dataclass(frozen=True)
class Errors(Job[Any]):
    """Shows ``n`` errors (the error line is written on the worker only)."""

    n: int
    lane: ClassVar[str] = "errors"

    def stages(self, ctx: Any, run: Run) -> Iterator[str]:
        for i in range(self.n):
            ctx.show_error(f"error {i}")
        yield "errors"


def test_long_lived_lists_are_bounded(app):
    app.submit(Errors(300))
    assert app.wait_idle(30)
    assert len(app.host.errors) == 100 and app.host.errors[-1] == "error 299"
    for _ in range(250):
        app.submit(RenderJob(app.map, app.session.shown.settings.with_(threshold=0.1)))
        assert app.wait_idle(30)
    assert len(app.map.timings) == 200


def test_cells_of_repeated_points_get_a_notice():
    """The app says why some cells are 0 (the same sentence as compute and report)."""
    from rough_viewer.app.cloud import LoadedCloud
    from rough_viewer.app.colouring import map_stats
    from rough_viewer.app.features.map.render import notice_text
    from rough_viewer.app.settings import MapSettings
    from rough_viewer.io import PointCloud
    from tests.helpers import repeated_points_cloud

    loaded = LoadedCloud(PointCloud.from_xyz(repeated_points_cloud()), presets=(1.0,))
    settings = MapSettings(cell_size=1.0)
    result = loaded.result(settings)
    stats = map_stats(result, settings)
    assert stats.exact_fit == 3
    text = notice_text(loaded, stats, settings).replace("\\\\", "")
    assert "**Cells of roughness 0:** 3 of 6 cells with a value fit their plane exactly" in text
    assert "Min points per cell" in text
