"""A small client that speaks viser 1.1's WebSocket protocol, for tests that act
as a (possibly hostile) browser without Chromium.

Server -> client frames: ``[u64 msgpack length][u64 zstd length][zstd(msgpack
{"messages": [...], ...})][binary buffers]``; client -> server: one msgpack map
per message with its ``type``. Only what the tests need is decoded (messages,
not their binary buffers).
"""

from __future__ import annotations

import threading
import time
import uuid as uuidlib
from dataclasses import dataclass, field
from typing import Any, ClassVar

import msgspec
import viser
import zstandard
from websockets.sync.client import connect

from rough_viewer.app.worker import Job
from tests.app.browser import wait_until

SUBPROTOCOL = "viser-v" + viser.__version__


class ProtocolClient:
    """Connect to a viser server at ``ws://127.0.0.1:PORT{path}`` and record what it sends.

    Parameters
    ----------
    port, path
        Where to connect (``path`` carries the token, e.g. ``/t/abc``).
    origin
        ``Origin`` header to send (None: none, as a non-browser program).
    """

    def __init__(self, port: int, path: str = "/", *, origin: str | None = None,
                 timeout: float = 10.0) -> None:
        headers = {"Origin": origin} if origin is not None else {}
        self.ws = connect(f"ws://127.0.0.1:{port}{path}", subprotocols=[SUBPROTOCOL],
                          additional_headers=headers, open_timeout=timeout,
                          max_size=None)
        self.messages: list[dict[str, Any]] = []
        self.client_id: int | None = None
        self._lock = threading.Lock()
        self._zstd = zstandard.ZstdDecompressor()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()
        self.look_from((0.0, -3.0, 1.0), (0.0, 0.0, 0.0))

    def look_from(self, position: Any, look_at: Any, *, fov: float = 1.0,
                  width: int = 1280, height: int = 800) -> None:
        """Send this tab's camera: at ``position`` looking at ``look_at`` (the scene's
        frame), z up, as a browser reports it (viser's camera frame: x right, y down,
        z forward)."""
        from rough_viewer.lod.camera import ViewCamera

        cam = ViewCamera.looking_at(position, look_at, fov_rad=fov, aspect=width / height,
                                    height_px=height)
        self.send({"type": "ViewerCameraMessage", "wxyz": [float(v) for v in cam.wxyz],
                   "position": [float(v) for v in position], "fov": fov, "near": 0.01,
                   "far": 1e6, "image_height": height, "image_width": width,
                   "look_at": [float(v) for v in look_at], "up_direction": [0.0, 0.0, 1.0]})

    def _read(self) -> None:
        try:
            for frame in self.ws:
                if not isinstance(frame, bytes) or len(frame) < 16:
                    continue
                n_raw = int.from_bytes(frame[:8], "little")
                n_zip = int.from_bytes(frame[8:16], "little")
                inner = self._zstd.decompress(frame[16:16 + n_zip], max_output_size=n_raw)
                payload = msgspec.msgpack.decode(inner)
                buffers, offset = [], 16 + n_zip
                for length in payload.get("binaryBufferLengths", ()):
                    offset += (8 - offset % 8) % 8  # each buffer 8-byte aligned
                    buffers.append(frame[offset:offset + length])
                    offset += length
                messages = [_arrays(m, buffers) for m in payload["messages"]]
                with self._lock:
                    self.messages.extend(messages)
        except Exception:  # noqa: BLE001 - the connection ended
            pass

    def send(self, message: dict[str, Any]) -> None:
        self.ws.send(msgspec.msgpack.encode(message))

    def close(self) -> None:
        self.ws.close()
        self._thread.join(5)

    # ------------------------------------------------------------------ reading
    def of_type(self, kind: str) -> list[dict[str, Any]]:
        with self._lock:
            return [m for m in self.messages if m.get("type") == kind]

    def wait_for(self, predicate, timeout: float = 20.0, what: str = "a message", *,
                 since: int = 0) -> Any:
        """The last message matching ``predicate`` among those from index ``since``
        on (``len(client.messages)`` taken before acting: an older message that
        matches does not count)."""
        end = time.time() + timeout
        while time.time() < end:
            with self._lock:
                found = [m for m in self.messages[since:] if predicate(m)]
            if found:
                return found[-1]
            time.sleep(0.05)
        raise TimeoutError(f"timed out waiting for {what}")

    def uuid(self, label: str) -> str:
        """The id of the control labelled ``label`` (from its creation message)."""
        msg = self.wait_for(lambda m: m.get("type", "").startswith("Gui")
                            and isinstance(m.get("props"), dict)
                            and m["props"].get("label") == label, what=f"control {label!r}")
        return str(msg["uuid"])

    def downloads(self, since: int = 0) -> dict[str, bytes]:
        """Files the server sent for download, by name, once all their parts arrived
        (a name sent twice: the last complete one); only those started at message
        index ``since`` or later."""
        with self._lock:
            starts = [m for m in self.messages[since:]
                      if m.get("type") == "FileTransferStartDownload"]
            parts: dict[str, dict[int, bytes]] = {}
            for m in self.messages:
                if m.get("type") == "FileTransferPart":
                    parts.setdefault(m["transfer_uuid"], {})[m["part_index"]] = m["content"]
        out = {}
        for start in starts:
            got = parts.get(start["transfer_uuid"], {})
            if len(got) == start["part_count"]:
                data = b"".join(got[i] for i in range(start["part_count"]))
                if len(data) == start["size_bytes"]:
                    out[start["filename"]] = data
        return out

    def wait_download(self, name_part: str, timeout: float = 60.0, *,
                      since: int = 0) -> tuple[str, bytes]:
        """The first complete download whose name contains ``name_part`` (started at
        message index ``since`` or later)."""
        end = time.time() + timeout
        while time.time() < end:
            for name, data in self.downloads(since).items():
                if name_part in name:
                    return name, data
            time.sleep(0.05)
        raise TimeoutError(f"no download named *{name_part}*")

    # ------------------------------------------------------------------ acting
    def press(self, label: str) -> None:
        """Click the button labelled ``label``."""
        self.set_value(label, True)

    def set_value(self, label: str, value: Any) -> None:
        self.send({"type": "GuiUpdateMessage", "uuid": self.uuid(label), "updates": {"value": value}})

    def upload(self, label: str, name: str, data: bytes, *, declared: int | None = None,
               chunk: int = 512 * 1024) -> str:
        """Send ``data`` as viser's upload button does; returns the transfer id."""
        source = self.uuid(label)
        transfer = str(uuidlib.uuid4())
        parts = max(1, -(-len(data) // chunk)) if data else 0
        self.send({"type": "FileTransferStartUpload", "source_component_uuid": source,
                   "transfer_uuid": transfer, "filename": name, "mime_type": "",
                   "size_bytes": len(data) if declared is None else declared,
                   "part_count": parts})
        for i in range(parts):
            self.send({"type": "FileTransferPart", "source_component_uuid": source,
                       "transfer_uuid": transfer, "part_index": i,
                       "content": data[i * chunk:(i + 1) * chunk]})
        return transfer

    def click(self, origin, direction) -> None:
        self.send({"type": "ScenePointerMessage", "event_type": "click",
                   "ray_origin": [float(v) for v in origin],
                   "ray_direction": [float(v) for v in direction],
                   "screen_pos": [[0.5, 0.5]], "modifier": None})


    def rect_select(self, corner_a, corner_b, *, modifier: str | None = "shift") -> None:
        """A rectangle dragged over the scene (viser's rectangle selection: corners
        in normalised window coordinates, (0, 0) top left), Shift held."""
        self.send({"type": "ScenePointerMessage", "event_type": "rect-select",
                   "ray_origin": None, "ray_direction": None,
                   "screen_pos": [[float(v) for v in corner_a], [float(v) for v in corner_b]],
                   "modifier": modifier})


def _arrays(obj: Any, buffers: list[bytes]) -> Any:
    """``obj`` with viser's binary placeholders (``{"__binary_index": i, "dtype":
    "<f2"}``) replaced by the flat numpy arrays they stand for."""
    import numpy as np

    if isinstance(obj, dict):
        if "__binary_index" in obj and "dtype" in obj:
            return np.frombuffer(buffers[obj["__binary_index"]], dtype=np.dtype(obj["dtype"]))
        return {k: _arrays(v, buffers) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_arrays(v, buffers) for v in obj]
    return obj


def join(server, path: str = "/", *, origin: str | None = None) -> ProtocolClient:
    """A :class:`ProtocolClient` on the viser ``server``, once the server lists it
    among its clients (its id: ``client.client_id``; None when the server refused
    it)."""
    before = set(server.get_clients())
    client = ProtocolClient(server.get_port(), path, origin=origin)
    try:
        new = wait_until(lambda: set(server.get_clients()) - before, 10,
                         "the server to list the client")
        client.client_id = max(new)
    except TimeoutError:
        if not server.get_clients():
            raise
        client.client_id = None
    return client


def settle(app, until, what: str, timeout: float = 30.0) -> None:
    """Wait until ``until()`` holds with the worker idle: viser checks a message on its
    event loop and runs the control's callback later on a thread pool, so neither a
    fixed sleep nor ``wait_idle`` alone says the message was handled."""
    wait_until(lambda: until() and not app.worker.busy, timeout, what)
    assert app.wait_idle(60)


def pick(app: Any, origin: Any, direction: Any, timeout: float = 60.0) -> Any:
    """A scene click (as a browser's ray) run as the app's pick job; returns the cell
    report it made (None: no point under it, or a tab took the click)."""
    from rough_viewer.app.features.map.pick import PickJob

    before = len(app.map.pick_timings)
    o = [float(v) for v in origin]
    d = [float(v) for v in direction]
    app.submit(PickJob(app.map, (o[0], o[1], o[2]), (d[0], d[1], d[2])))
    assert app.wait_idle(timeout)
    return app.session.last_pick if len(app.map.pick_timings) > before else None


def shown_colours(app: Any) -> Any:
    """The colours the points of the overview sample show now (what every tab's nodes
    are coloured by, read at those points)."""
    return app.host.scene.colours(app.session.shown.loaded.display_index)



@dataclass(frozen=True)
class Calls(Job[Any]):
    """Calls ``fn()`` on the worker (a test's write of the app's handles or state)."""

    fn: Any = field(compare=False)
    lane: ClassVar[str] = "test"

    def stages(self, ctx: Any, run: Any) -> Any:
        self.fn()
        yield "called"


def on_worker(app: Any, work: Any, timeout: float = 30.0) -> None:
    """Run ``work()`` as a job on ``app``'s worker, where the app's handles and state
    are written, and wait for it."""
    app.submit(Calls(work))
    assert app.wait_idle(timeout)
