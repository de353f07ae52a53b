"""Values from a browser are checked against each control before the app sees them
(a protocol-level client plays the hostile page)."""

from __future__ import annotations

import time

import pytest

from rough_viewer.app import hooks
from rough_viewer.app.controls import check_value
from rough_viewer.app.features.bias import BiasPanel
from rough_viewer.app.features.file import FileFeature
from rough_viewer.app.gate import open_server
from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.vocabulary import InputError
from tests.app.browser import wait_until
from tests.app.protocol import join, settle
from tests.helpers import PAPER_PRESETS, face_cloud


@pytest.fixture
def live():
    server, gate = open_server("127.0.0.1", 0, token="tok", log=False)
    # fixed presets: these tests are about the checks, not the data's grid
    app = build_app(server, face_cloud(8_000), prefetch=False, presets=PAPER_PRESETS,
                    settings=MapSettings(cell_size=0.25))
    assert app.wait_idle(60)
    client = join(server, "/t/tok", origin=f"http://127.0.0.1:{server.get_port()}")
    yield app, client
    client.close()
    app.stop()
    server.stop()


def barrier(app, client) -> None:
    """Send one good change and wait for it: the event loop handles a connection's
    messages in order, so every message sent before it has been checked by then."""
    choice = "OLS" if app.map.model.value != "OLS" else "ODR"
    client.set_value("Model", choice)
    settle(app, lambda: app.map.model.value == choice, "the barrier's model change")


BAD = [
    ("Model", "<script>alert(1)</script>", "one of its options"),
    ("Model", 3, "one of its options"),
    ("Grid size (m)", "0.3", "one of its options"),
    ("Free grid size (m)", "abc", "a number"),
    ("Free grid size (m)", 1e-9, "at least 0.0001"),
    ("Free grid size (m)", 1e9, "at most 10000"),
    ("Min points per cell", 4.5, "whole number"),
    ("Min points per cell", True, "a number"),
    ("Min points per cell", 2, "at least 3"),
    ("Threshold", float("nan"), "finite"),
    ("Threshold", float("inf"), "finite"),
    ("Percentiles", [90.0, 10.0], "increasing"),
    ("Percentiles", [10.0], "2 numbers"),
    ("Percentiles", [-5.0, 50.0], "at least 0"),
    ("Colour stretch", "minmax", "one of its options"),
    ("Lowest θ (mm)", float("nan"), "finite"),
    ("Highest θ (mm)", -1.0, "at least 0"),
    ("Colour by", "scan colours (RGB)", "one of its options"),  # no RGB in this cloud
    ("View", "underneath", "one of its options"),
    ("Units", "furlong", "one of its options"),
    ("Show dependent axis", "yes", "true or false"),
    ("File path", "x" * 5000, "at most 4096"),
    ("Toggle ODR / OLS", False, "press must be true"),
    ("Range noise (mm)", -1.0, "at least 0"),
    ("Roughness", "abs", "one of its options"),
]


def test_invalid_values_are_put_back_with_a_notice(live):
    app, client = live
    before = app.session.shown.settings
    values = {label: hooks.input_handles(app.server)[client.uuid(label)].value
              for label, _, _ in BAD}
    for label, value, _reason in BAD:
        client.set_value(label, value)
    settle(app, lambda: len(app.host.controls.rejected) >= len(BAD), "every refusal")
    # nothing reached the app: same controls, same view, every later change still works
    for label, _, _ in BAD:
        assert hooks.input_handles(app.server)[client.uuid(label)].value == values[label], label
    assert app.session.shown.settings == before and list(app.host.errors) == []
    got = [(r.label, r.reason) for r in app.host.controls.rejected]
    for label, _, reason in BAD:
        assert any(lab == label and reason in why for lab, why in got), (label, reason)
    # the sender's control is put back to the good value, with a notice
    grid = client.uuid("Free grid size (m)")
    client.wait_for(lambda m: m.get("type") == "GuiUpdateMessage" and m["uuid"] == grid
                    and m["updates"] == {"value": 0.25}, what="the value put back")
    # the notices go on the sender's own stream, not ordered with the put-back above
    def bodies() -> list[str]:
        return [m["props"]["body"] for m in client.of_type("NotificationShowMessage")]

    wait_until(lambda: sum("last good value is kept" in n for n in bodies()) >= len(BAD), 20,
               "a notice for each refusal")
    notes = bodies()
    assert sum("last good value is kept" in n for n in notes) == len(BAD)
    assert all("<script>" not in n for n in notes)  # the bad value is not echoed
    client.set_value("Grid size (m)", "0.5")
    client.set_value("Model", "OLS")
    settle(app, lambda: app.session.shown.settings.cell_size == 0.5 and app.session.shown.settings.model == "ols",
           "the grid and model shown")


def test_valid_values_are_normalised(live):
    app, client = live
    client.set_value("Min points per cell", 5.0)  # a whole float for an int control
    client.set_value("Free grid size (m)", 1)  # an int for a float control
    settle(app, lambda: app.map.min_points.value == 5 and app.session.shown.settings.cell_size == 1.0
           and app.session.shown.settings.min_points == 5, "both values shown")
    assert app.map.min_points.value == 5 and isinstance(app.map.min_points.value, int)
    assert app.session.shown.settings.cell_size == 1.0 and app.map.grid.value == "free"


def test_two_changes_at_once_leave_the_map_on_both(live, monkeypatch):
    """viser runs the callbacks of two quick changes in parallel. The free-grid
    change moves the grid dropdown to "free"; a reading of the controls taken before
    that move, but shown after it, left the map on the old grid for good (found with
    0-0.2 s of jitter before the submit). Callbacks now only name their control; the
    worker moves the controls that follow and reads them, one job after another (two
    pending ones merge). A slow first reading reproduces the old race."""
    app, client = live
    read = app.map.binding.read
    calls = []

    def slow_first_reading():
        settings = read()
        calls.append(settings)
        if len(calls) == 1:
            time.sleep(0.5)  # the other callback runs meanwhile
        return settings

    monkeypatch.setattr(app.map.binding, "read", slow_first_reading)
    client.set_value("Min points per cell", 5)
    client.set_value("Free grid size (m)", 1.0)
    wait_until(lambda: calls and app.map.min_points.value == 5
               and app.map.grid_free.value == 1.0, 20, "both values")
    time.sleep(0.8)
    assert app.wait_idle(60)
    assert app.map.grid.value == "free" and app.map.min_points.value == 5
    shown = app.session.shown.settings
    assert (shown.cell_size, shown.min_points) == (1.0, 5)


def test_only_values_may_change(live):
    app, client = live
    uuid = client.uuid("Model")
    client.send({"type": "GuiUpdateMessage", "uuid": uuid,
                 "updates": {"options": ["<img src=x>"], "label": "<b>pwned</b>"}})
    client.send({"type": "GuiUpdateMessage", "uuid": client.uuid("Load file"),
                 "updates": {"disabled": True}})
    client.send({"type": "GuiUpdateMessage", "uuid": "no-such-control",
                 "updates": {"value": 1}})
    client.send({"type": "ShareUrlRequest"})
    barrier(app, client)
    time.sleep(0.3)  # a share tunnel, had it been asked, starts on another thread
    assert app.map.model.options[0] == "ODR" and app.map.model.label == "Model"
    assert not app.feature(FileFeature).load.disabled
    assert app.server._share_tunnel is None  # no public tunnel was opened


def test_every_control_of_the_app_is_registered(live):
    app, _client = live
    handles = hooks.input_handles(app.server)
    # the upload button sends files (checked by the uploads), progress bars nothing
    from viser._gui_handles import GuiProgressBarHandle

    missing = [h.label for h in handles.values() if not app.host.controls.allowed(h)
               and h is not app.feature(FileFeature).upload and not isinstance(h, GuiProgressBarHandle)]
    assert missing == [] and len(handles) > 25
    assert isinstance(app.feature(BiasPanel), BiasPanel)


def test_check_value_rules_without_a_browser(live):
    app, _ = live
    assert check_value(app.map.threshold, 1) == 1.0
    assert check_value(app.map.percentiles, [0, 100]) == (0.0, 100.0)
    with pytest.raises(InputError):
        check_value(app.map.percentiles, [50, 50.5])  # closer than the minimum range 1
    assert check_value(app.map.camera, "top") == "top"
    with pytest.raises(InputError):
        check_value(app.map.camera, 1)
    with pytest.raises(InputError):
        check_value(app.feature(FileFeature).upload, b"data")


@pytest.mark.parametrize("bad", [
    {"ray_origin": [1, 2], "ray_direction": "x", "screen_pos": []},          # IndexError in viser
    {"ray_origin": [1e308] * 3, "ray_direction": [0.0, 1.0, 0.0]},           # overflow warning
    {"ray_origin": [0.0, -5.0, float("nan")], "ray_direction": [0.0, 1.0, 0.0]},
    {"event_type": "drag"},
    {"screen_pos": [[0.5, 0.5]] * 3},
])
@pytest.mark.filterwarnings("ignore:.*does not match annotation:UserWarning")  # viser says so of bad0
def test_malformed_clicks_are_dropped_and_a_real_one_still_works(live, bad, capfd):
    app, client = live
    pts = app.session.shown.loaded.display_points
    target = pts[100].astype(float)
    message = {"type": "ScenePointerMessage", "event_type": "click",
               "ray_origin": [float(v) for v in target + [0.0, -5.0, 0.0]],
               "ray_direction": [0.0, 1.0, 0.0],
               "screen_pos": [[0.5, 0.5]], "modifier": None}
    before = app.host.controls.dropped_clicks
    client.send({**message, **bad})
    settle(app, lambda: app.host.controls.dropped_clicks >= before + 1, "the dropped click")
    assert app.session.last_pick is None and app.host.controls.dropped_clicks == before + 1
    client.send(message)  # the same connection still clicks
    wait_until(lambda: app.session.last_pick is not None, 10, "the real click")
    assert app.session.last_pick is not None
    err = capfd.readouterr().err
    assert "Traceback" not in err and "exception" not in err.lower() and "Warning" not in err
