"""Values from a browser are checked against each control before the app sees them
(a protocol-level client plays the hostile page)."""

from __future__ import annotations

import time

import pytest

from rough_viewer.app import hooks
from rough_viewer.app.bias_panel import BiasPanel
from rough_viewer.app.controls import check_value
from rough_viewer.app.gate import open_server
from rough_viewer.app.server import build_app
from rough_viewer.app.state import ViewSettings
from rough_viewer.vocabulary import InputError
from tests.app.protocol import ProtocolClient
from tests.helpers import face_cloud


@pytest.fixture
def live():
    server, gate = open_server("127.0.0.1", 0, token="tok", log=False)
    # fixed presets: these tests are about the checks, not the data's grid
    app = build_app(server, face_cloud(8_000), prefetch=False, presets=(1.0, 0.5, 0.25, 0.125),
                    settings=ViewSettings(cell_size=0.25))
    assert app.wait_idle(60)
    port = server.get_port()
    client = ProtocolClient(port, "/t/tok", origin=f"http://127.0.0.1:{port}")
    end = time.time() + 10
    while not server.get_clients() and time.time() < end:
        time.sleep(0.02)
    yield app, client
    client.close()
    app.stop()
    server.stop()


def settle(app, seconds: float = 0.4) -> None:
    time.sleep(seconds)  # the server handles the message on its event loop
    assert app.wait_idle(60)


BAD = [
    ("Model", "<script>alert(1)</script>", "one of its options"),
    ("Model", 3, "one of its options"),
    ("Grid size (m)", "0.3", "one of its options"),
    ("Free grid size (m)", "abc", "a number"),
    ("Free grid size (m)", 1e-9, "at least 0.001"),
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
    before = app.shown.settings
    values = {label: hooks.input_handles(app.server)[client.uuid(label)].value
              for label, _, _ in BAD}
    for label, value, _reason in BAD:
        client.set_value(label, value)
    settle(app)
    # nothing reached the app: same controls, same view, every later change still works
    for label, _, _ in BAD:
        assert hooks.input_handles(app.server)[client.uuid(label)].value == values[label], label
    assert app.shown.settings == before and list(app.errors) == []
    got = [(r.label, r.reason) for r in app.controls.rejected]
    for label, _, reason in BAD:
        assert any(lab == label and reason in why for lab, why in got), (label, reason)
    # the sender's control is put back to the good value, with a notice
    grid = client.uuid("Free grid size (m)")
    client.wait_for(lambda m: m.get("type") == "GuiUpdateMessage" and m["uuid"] == grid
                    and m["updates"] == {"value": 0.25}, what="the value put back")
    notes = [m["props"]["body"] for m in client.of_type("NotificationShowMessage")]
    assert sum("last good value is kept" in n for n in notes) == len(BAD)
    assert all("<script>" not in n for n in notes)  # the bad value is not echoed
    client.set_value("Grid size (m)", "0.5")
    client.set_value("Model", "OLS")
    settle(app)
    assert app.shown.settings.cell_size == 0.5 and app.shown.settings.model == "ols"


def test_valid_values_are_normalised(live):
    app, client = live
    client.set_value("Min points per cell", 5.0)  # a whole float for an int control
    client.set_value("Free grid size (m)", 1)  # an int for a float control
    settle(app)
    assert app.gui.min_points.value == 5 and isinstance(app.gui.min_points.value, int)
    assert app.shown.settings.cell_size == 1.0 and app.gui.grid.value == "free"


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
    settle(app)
    assert app.gui.model.options[0] == "ODR" and app.gui.model.label == "Model"
    assert not app.gui.load.disabled
    assert app.server._share_tunnel is None  # no public tunnel was opened


def test_every_control_of_the_app_is_registered(live):
    app, _client = live
    handles = hooks.input_handles(app.server)
    # the upload button sends files (checked by the uploads), progress bars nothing
    from viser._gui_handles import GuiProgressBarHandle

    missing = [h.label for h in handles.values() if not app.controls.allowed(h)
               and h is not app.gui.upload and not isinstance(h, GuiProgressBarHandle)]
    assert missing == [] and len(handles) > 25
    assert isinstance(app.mode(BiasPanel), BiasPanel)


def test_check_value_rules_without_a_browser(live):
    app, _ = live
    assert check_value(app.gui.threshold, 1) == 1.0
    assert check_value(app.gui.percentiles, [0, 100]) == (0.0, 100.0)
    with pytest.raises(InputError):
        check_value(app.gui.percentiles, [50, 50.5])  # closer than the minimum range 1
    assert check_value(app.gui.camera, "top") == "top"
    with pytest.raises(InputError):
        check_value(app.gui.camera, 1)
    with pytest.raises(InputError):
        check_value(app.gui.upload, b"data")


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
    pts = app.shown.loaded.display_points
    target = pts[100].astype(float)
    message = {"type": "ScenePointerMessage", "event_type": "click",
               "ray_origin": [float(v) for v in target + [0.0, -5.0, 0.0]],
               "ray_direction": [0.0, 1.0, 0.0],
               "screen_pos": [[0.5, 0.5]], "modifier": None}
    before = app.controls.dropped_clicks
    client.send({**message, **bad})
    settle(app)
    assert app.last_pick is None and app.controls.dropped_clicks == before + 1
    client.send(message)  # the same connection still clicks
    end = time.time() + 10
    while app.last_pick is None and time.time() < end:
        time.sleep(0.05)
    assert app.last_pick is not None
    err = capfd.readouterr().err
    assert "Traceback" not in err and "exception" not in err.lower() and "Warning" not in err
