"""A bad file never takes the server down, and browsers cost what they may (issue 21):
a real ``serve`` survives readers that crash through "Load file" and an upload and
answers the next request; a client that stops reading is closed; connections are
capped."""

from __future__ import annotations

import base64
import json
import os
import socket

import numpy as np
import pytest
from websockets.exceptions import InvalidStatus

from rough_viewer.app.gate import open_server
from rough_viewer.io.sandbox import isolate
from tests.app.browser import wait_until
from tests.app.protocol import SUBPROTOCOL, ProtocolClient
from tests.app.serve_process import ServeProcess
from tests.helpers import face_cloud
from tests.io import crafted

pytestmark = pytest.mark.skipif(not isolate.available(), reason="isolation needs Linux")


def _said(client: ProtocolClient, text: str, since: int, timeout: float = 60.0) -> None:
    client.wait_for(lambda m: text in json.dumps(m, default=str), timeout=timeout,
                    what=repr(text), since=since)


def test_serve_survives_crashing_readers_and_answers_the_next_request(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    np.save(data / "face.npy", face_cloud(4000).xyz())
    crafted.laz_ff_chunk(data / "pump.laz")          # SIGSEGV in lazrs
    crafted.laz_huge_chunk_table(data / "table.laz")  # 64 GiB asked, then abort
    good = face_cloud(3210, seed=4).xyz()
    np.savetxt(data / "good.xyz", good, fmt="%.4f")
    proc = ServeProcess(str(data / "face.npy"), "--no-token")
    try:
        client = ProtocolClient(proc.port, proc.path)
        client.uuid("Load file")
        for name, said in (("pump.laz", "the LAZ reader crashed (signal 11, SIGSEGV) on pump.laz"),
                           ("table.laz", "the LAZ reader went past its memory limit")):
            since = len(client.messages)
            client.set_value("File path", name)
            client.press("Load file")
            _said(client, said, since)
            assert proc.alive()
        since = len(client.messages)
        client.upload("Upload file", "upload.laz", (data / "pump.laz").read_bytes())
        _said(client, "the LAZ reader crashed (signal 11, SIGSEGV) on upload.laz", since)
        assert proc.alive()
        since = len(client.messages)
        client.set_value("File path", "good.xyz")
        client.press("Load file")
        _said(client, "3,210 points, each tab", since)  # the next request is answered
        other = ProtocolClient(proc.port, proc.path)  # and a new browser is served
        other.uuid("Load file")
        other.close()
        client.close()
        assert proc.alive()
        assert str(data) not in "".join(proc.stderr)
    finally:
        proc.stop()


@pytest.fixture
def big_scene():
    """A server with about 24 MB of scene for each browser."""
    server, gate = open_server("127.0.0.1", 0, token=None, log=False, max_connections=3)
    rng = np.random.default_rng(0)
    n = 1_600_000
    server.scene.add_point_cloud("/cloud", points=rng.random((n, 3), dtype=np.float32),
                                 colors=rng.integers(0, 255, (n, 3), dtype=np.uint8),
                                 point_size=0.01)
    yield server, gate
    server.stop()


def _silent_client(port: int) -> socket.socket:
    """A WebSocket client that completes the handshake, then never reads a byte."""
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                  f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                  f"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n"
                  ).encode())
    head = b""
    while b"\r\n\r\n" not in head:
        head += sock.recv(1)
    assert head.startswith(b"HTTP/1.1 101"), head
    return sock


def test_a_client_that_stops_reading_is_closed(big_scene):
    server, gate = big_scene
    gate.stall_seconds = 1.0
    reader = ProtocolClient(server.get_port(), "/")  # a browser that reads
    sock = _silent_client(server.get_port())
    wait_until(lambda: gate.shed, 60, "the silent client to be closed")
    assert "the client stopped reading" in gate.shed[0]
    reader.wait_for(lambda m: "/cloud" in str(m.get("name", "")), timeout=60, what="the scene")
    wait_until(lambda: len(server.get_clients()) == 1, 20, "the reading client kept")
    assert len(gate.shed) == 1  # the reading client kept its connection
    sock.close()
    reader.close()


def test_an_unsent_backlog_beyond_the_bound_is_closed_at_once(big_scene):
    server, gate = big_scene
    gate.max_unsent = 4 << 20
    gate.stall_seconds = 3600.0
    sock = _silent_client(server.get_port())
    wait_until(lambda: gate.shed, 60, "the client to be closed")
    assert "more than the 4.0 MiB a connection may hold" in gate.shed[0]
    sock.close()


def test_connections_beyond_the_cap_are_refused(big_scene):
    server, gate = big_scene
    clients = [ProtocolClient(server.get_port(), "/") for _ in range(3)]
    wait_until(lambda: len(server.get_clients()) == 3, 20, "three clients")
    with pytest.raises(InvalidStatus) as exc:
        ProtocolClient(server.get_port(), "/")
    assert exc.value.response.status_code == 503
    assert "too many connections (this server allows 3" in gate.refused[-1].reason
    clients[0].close()
    wait_until(lambda: len(server.get_clients()) == 2, 20, "a place free")
    clients.append(ProtocolClient(server.get_port(), "/"))  # admitted again
    for c in clients[1:]:
        c.close()


def test_the_backlog_rule_counts_only_stalled_bytes():
    """Pure rule: bytes that move are never shed; bytes that stand still are."""
    from rough_viewer.app.gate import Gate

    gate = Gate(token=None, origins=frozenset(), stall_bytes=100, stall_seconds=10.0,
                max_unsent=10_000)
    class Connection:
        pass

    conn = Connection()
    assert gate.backlog_check(conn, 50, now=0.0) is None  # type: ignore[arg-type]
    assert gate.backlog_check(conn, 500, now=1.0) is None  # type: ignore[arg-type]
    assert gate.backlog_check(conn, 400, now=9.0) is None  # type: ignore[arg-type]
    assert gate.backlog_check(conn, 400, now=18.0) is None  # type: ignore[arg-type]
    assert "stopped reading" in str(gate.backlog_check(conn, 400, now=19.5))  # type: ignore[arg-type]
    assert "more than" in str(gate.backlog_check(conn, 20_000, now=20.0))  # type: ignore[arg-type]
