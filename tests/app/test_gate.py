"""Who may connect: the Origin check and the access token on viser's WebSocket.

Protocol-level tests open real WebSocket handshakes against a real server; the
browser tests open the URL ``rough-viewer serve`` prints, and an attack page served
from another origin on loopback, in headless Chromium.
"""

from __future__ import annotations

import http.server
import os
import threading
import time
import urllib.error
import urllib.request

import numpy as np
import pytest
from websockets.exceptions import InvalidStatus

from rough_viewer.app.gate import normalise_origin, open_server, own_origins
from rough_viewer.app.server import build_app
from rough_viewer.vocabulary import InputError
from tests.app import browser as b
from tests.app.protocol import ProtocolClient
from tests.app.serve_process import ServeProcess
from tests.helpers import face_cloud

TOKEN = "test-token-0123456789abcdef"


@pytest.fixture
def guarded():
    server, gate = open_server("127.0.0.1", 0, token=TOKEN, allow_origins=["http://lab.example:9000"],
                               log=False)
    app = build_app(server, face_cloud(5_000), prefetch=False)
    assert app.wait_idle(60)
    yield server, gate, app
    app.stop()
    server.stop()


def refused(port: int, path: str, origin: str | None) -> bool:
    try:
        c = ProtocolClient(port, path, origin=origin)
    except InvalidStatus as exc:
        assert exc.response.status_code == 403
        return True
    c.close()
    return False


def test_foreign_origins_and_missing_tokens_are_refused(guarded):
    server, gate, app = guarded
    port = server.get_port()
    own = f"http://127.0.0.1:{port}"
    good = f"/t/{TOKEN}"
    assert not refused(port, good, own)
    assert not refused(port, good, f"http://localhost:{port}")
    assert not refused(port, good, "http://LAB.example:9000/")  # --allow-origin, any case
    assert not refused(port, good, None)  # a program, not a page: the token decides
    assert refused(port, good, "http://127.0.0.1:9999")  # another port is another origin
    assert refused(port, good, "http://evil.example")
    assert refused(port, good, "null")  # sandboxed frames, file:// pages
    assert refused(port, "/", own)
    assert refused(port, "/t/wrong-token", own)
    assert refused(port, f"/t/{TOKEN}x", None)
    reasons = [r.reason for r in gate.refused]
    assert reasons.count("origin not allowed") == 3
    assert reasons.count("missing or wrong token") == 3
    assert all(TOKEN not in r.path for r in gate.refused)  # the log never shows the token


def test_a_refused_page_gets_no_data(guarded):
    server, _gate, _app = guarded
    before = len(server.get_clients())
    assert refused(server.get_port(), f"/t/{TOKEN}", "http://evil.example")
    time.sleep(0.3)
    assert len(server.get_clients()) == before


def test_admitted_client_receives_the_app(guarded):
    server, _gate, _app = guarded
    port = server.get_port()
    c = ProtocolClient(port, f"/t/{TOKEN}", origin=f"http://127.0.0.1:{port}")
    try:
        assert c.uuid("Grid size (m)")
        c.wait_for(lambda m: m.get("type") == "PointCloudMessage", what="the cloud")
    finally:
        c.close()


def get(url: str) -> tuple[int, bytes, str]:
    class NoRedirect(urllib.request.HTTPRedirectHandler):
        def redirect_request(self, *args, **kwargs):
            return None

    opener = urllib.request.build_opener(NoRedirect)
    try:
        with opener.open(url, timeout=10) as r:
            return r.status, r.read(), r.headers.get("Location", "")
    except urllib.error.HTTPError as e:
        return e.code, e.read(), e.headers.get("Location", "")


def test_http_pages(guarded):
    server, gate, _app = guarded
    base = f"http://127.0.0.1:{server.get_port()}"
    status, body, _ = get(base + "/")
    assert status == 403 and b"printed when it started" in body
    status, body, _ = get(base + "/index.html")
    assert status == 403
    status, body, _ = get(base + gate.path)
    assert status == 200 and b"<html" in body.lower() and len(body) > 100_000  # viser's client
    status, _, location = get(base + gate.path.rstrip("/"))
    assert status == 302 and location == gate.path
    status, _, _ = get(base + gate.path + "../../index.html")
    assert status in (403, 404)
    assert gate.url("127.0.0.1", 8080) == f"http://127.0.0.1:8080/t/{TOKEN}/"
    assert gate.url("0.0.0.0", 8080) == f"http://127.0.0.1:8080/t/{TOKEN}/"


def test_without_token_the_origin_check_stays():
    server, gate = open_server("127.0.0.1", 0, token=None, log=False)
    try:
        port = server.get_port()
        assert gate.path == "/" and gate.url("127.0.0.1", port).endswith(f":{port}/")
        assert not refused(port, "/", f"http://127.0.0.1:{port}")
        assert refused(port, "/", "http://127.0.0.1:1")
        assert get(f"http://127.0.0.1:{port}/")[0] == 200
    finally:
        server.stop()


def test_own_origins():
    import socket

    local = own_origins("127.0.0.1", 8080)
    assert {"http://127.0.0.1:8080", "http://localhost:8080", "http://[::1]:8080"} <= local
    assert len(local) == 3
    assert "http://10.1.2.3:8080" in own_origins("10.1.2.3", 8080)
    everywhere = own_origins("0.0.0.0", 80)
    assert f"http://{socket.gethostname().lower()}:80" in everywhere
    assert f"http://{socket.gethostname().lower()}" in everywhere  # port 80 may be left out


def test_origin_values_are_checked():
    assert normalise_origin("HTTP://Host.Example:8080/") == "http://host.example:8080"
    for bad in ("host:8080", "ftp://x", "http://x/path", "http://user@x", "*"):
        with pytest.raises(InputError, match="--allow-origin"):
            normalise_origin(bad)


# ----------------------------------------------------------------------------- Chromium

ATTACK_PAGE = """<!doctype html><meta charset="utf-8"><title>attack</title>
<script>
window.results = {};
function probe(name, url) {
  const ws = new WebSocket(url, ["viser-v%(version)s"]);
  ws.binaryType = "arraybuffer";
  window.results[name] = "pending";
  ws.onopen = () => { window.results[name] = "open"; };
  ws.onmessage = () => { window.results[name] = "data"; };
  ws.onclose = () => { if (window.results[name] === "pending") window.results[name] = "refused"; };
}
probe("with_token", "ws://127.0.0.1:%(port)d%(path)s");
probe("without_token", "ws://127.0.0.1:%(port)d/");
</script>"""


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    path = tmp_path_factory.mktemp("serve") / "face.npy"
    np.save(path, face_cloud(20_000, seed=3).xyz())
    proc = ServeProcess(str(path))
    yield proc
    proc.stop()


@pytest.mark.browser
def test_the_printed_url_opens_the_app(chromium, served):
    assert served.path.startswith("/t/") and len(served.path) > 30
    ctx = chromium.new_context(viewport=b.VIEWPORT)
    page = ctx.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        page.goto(served.url)  # exactly what the user is told to open
        b.wait_coloured(page, 0.05, timeout=90)
        b.hide_toasts(page)
        before = b.scene_pixels(page)
        b.choose(page, "Display", "binary")  # the app answers the page's controls
        b.wait_pixels(page, lambda im: np.abs(im.astype(int) - before).sum(axis=2).mean() > 5,
                      60, "colours to change")
        page.screenshot(path=str(served_shot_dir() / "printed-url.png"), timeout=60_000)
    finally:
        ctx.close()
    assert not errors, errors


@pytest.mark.browser
def test_a_page_from_another_origin_cannot_connect(chromium, served):
    import viser

    page_html = (ATTACK_PAGE % {"version": viser.__version__, "port": served.port,
                                "path": served.path.rstrip("/")}).encode()

    class Attack(http.server.BaseHTTPRequestHandler):
        def do_GET(self):  # noqa: N802 - http.server's name
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.end_headers()
            self.wfile.write(page_html)

        def log_message(self, *args):
            pass

    attacker = http.server.HTTPServer(("127.0.0.1", 0), Attack)
    threading.Thread(target=attacker.serve_forever, daemon=True).start()
    ctx = chromium.new_context()
    page = ctx.new_page()
    try:
        # the attack page knows even the token, and still gets nothing
        page.goto(f"http://127.0.0.1:{attacker.server_port}/")
        page.wait_for_function("() => Object.values(window.results).every(v => v !== 'pending')",
                               timeout=20_000)
        results = page.evaluate("() => window.results")
        # and the app's own page at the bare address explains what is needed
        page.goto(f"http://127.0.0.1:{served.port}/")
        assert "printed when it started" in page.content()
    finally:
        ctx.close()
        attacker.shutdown()
    assert results == {"with_token": "refused", "without_token": "refused"}
    refused = f"refused a connection from origin http://127.0.0.1:{attacker.server_port}"
    b.wait_until(lambda: refused in "".join(served.stderr), 10, "the refusal in the log")
    assert served.alive()


def served_shot_dir():
    from pathlib import Path

    out = Path(os.environ.get("ROUGH_VIEWER_SHOTS", "/tmp/rough-viewer-shots"))
    out.mkdir(parents=True, exist_ok=True)
    return out


def test_a_repeated_origin_header_is_refused_not_a_server_error(guarded):
    """Two Origin headers (one the server's own): websockets' .get() raised
    MultipleValuesError, an HTTP 500 with a traceback in the log."""
    import socket

    server, gate, _app = guarded
    port = server.get_port()
    for first, second in ((f"http://127.0.0.1:{port}", "http://evil.example"),
                          ("http://evil.example", f"http://127.0.0.1:{port}")):
        request = (f"GET /t/{TOKEN}/ HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
                   "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                   "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                   f"Origin: {first}\r\nOrigin: {second}\r\n\r\n")
        with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
            sock.sendall(request.encode())
            status = sock.recv(200).split(b"\r\n")[0]
        assert status.startswith(b"HTTP/1.1 403"), status
    assert [r.reason for r in gate.refused][-2:] == ["origin not allowed"] * 2
