"""``rough-viewer serve --view VIEW.json`` as a real process: it prints the URL, and a
client on that URL gets the view's settings, colours, profile, camera and notice."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from rough_viewer.io import load_points
from rough_viewer.report.view import Camera, ColourSettings, ProfilePick, View, input_ref, save_view
from tests.app.browser import wait_until
from tests.app.protocol import ProtocolClient
from tests.app.serve_process import ServeProcess
from tests.io.test_las_out import make_pf3


def _shows(client: ProtocolClient, label: str, value) -> bool:
    """The control labelled ``label`` holds ``value`` (its creation, then its updates)."""
    uuid = client.uuid(label)
    last = None
    with client._lock:
        for m in client.messages:
            if m.get("uuid") != uuid:
                continue
            if "value" in m:  # the creation message
                last = m["value"]
            if isinstance(m.get("updates"), dict) and "value" in m["updates"]:
                last = m["updates"]["value"]
    return last == value


def _comes_to(client: ProtocolClient, label: str, value) -> None:
    """Wait until the control labelled ``label`` holds ``value``: the server set every
    control before it printed the URL, but a new client receives the replay in several
    windows, so a control set late may arrive after the message the test waited for."""
    wait_until(lambda: _shows(client, label, value), 10, f"{label} to show {value!r}")


def _text(m) -> str:
    return str(m.get("updates", m.get("props", ""))).replace("\\\\", "").replace("\\", "")


@pytest.mark.slow
def test_serve_view_reopens_the_view(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    scan = site / "scan.las"
    make_pf3(scan, n=8000)
    cloud = load_points(scan)
    lo, hi = cloud.bounds()
    mid = 0.5 * (lo + hi)
    start, end = mid - [1.0, 1.0, 0.0], mid + [1.0, 1.0, 0.0]
    camera = Camera(position=tuple(mid + [0.0, -6.0, 4.0]), look_at=tuple(mid))
    view = View(input=input_ref(scan), cell_size_m=0.5, min_points=4, model="ols",
                threshold=0.3, colour=ColourSettings("cividis", "binary"),
                profiles=(ProfilePick(tuple(start), tuple(end), wavelet="db4"),), camera=camera)
    save_view(site / "scan.view.json", view)
    moved = tmp_path / "moved"
    shutil.move(site, moved)  # the folder was moved since: the view says so and finds the scan

    proc = ServeProcess("--view", str(moved / "scan.view.json"))
    try:
        assert proc.path.startswith("/t/")
        wait_until(lambda: any("note: input moved" in line for line in proc.stderr), 10,
                   "the note on stderr")
        client = ProtocolClient(proc.port, proc.path)
        try:
            client.wait_for(lambda m: "grid 0.5 m" in _text(m) and "OLS" in _text(m),
                            what="the status line of the view's grid and model")
            for label, value in (("Colour map", "cividis"), ("Display", "binary"),
                                 ("Threshold", 0.3)):
                _comes_to(client, label, value)
            note = client.wait_for(lambda m: "input moved" in _text(m), what="the notice")
            assert str(tmp_path) not in _text(note)  # file names, not the server's folders
            assert any(str(tmp_path) in line for line in proc.stderr)  # the terminal has them
            client.wait_for(lambda m: "| 1 |" in _text(m), what="the profile's table row")
            _comes_to(client, "Wavelet", "db4")
            # the view's camera is the initial camera, in the app's local frame
            origin = np.round(mid)
            want = np.asarray(camera.position) - origin
            client.wait_for(lambda m: m.get("type") == "SetCameraPositionMessage"
                            and m.get("initial") and np.allclose(m["position"], want, atol=1e-6),
                            what="the view's camera as the initial camera")
        finally:
            client.close()
        assert proc.alive()
    finally:
        proc.stop()
