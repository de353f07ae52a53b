"""Limits on a real ``rough-viewer serve`` process: an upload above the limit and a
LAZ bomb end in an error, and the server's memory stays where it was.

"Memory" is the process's peak resident size (``VmHWM``) read from /proc before
and after; viser's own upload path would have held a whole upload in memory, and
a LAZ bomb (a small file whose header declares 50 million points) took the server
to 6.8 GB before the header check.
"""

from __future__ import annotations

import struct
import time

import laspy
import numpy as np
import pytest

from rough_viewer.app.cloud import grid_presets
from tests.app.protocol import ProtocolClient
from tests.app.serve_process import ServeProcess
from tests.helpers import face_cloud

MiB = 1 << 20
#: Growth of the peak resident size tolerated, bytes (message buffers, allocator noise).
SLACK = 40 * MiB


def laz_bomb(path, declared: int = 50_000_000, n: int = 20_000) -> None:
    """A valid LAS 1.4 LAZ of ``n`` points whose header declares ``declared`` points."""
    xyz = face_cloud(n, seed=9).xyz()
    hdr = laspy.LasHeader(point_format=6, version="1.4")
    hdr.scales = np.array([1e-4] * 3)
    hdr.offsets = np.floor(xyz.min(axis=0))
    las = laspy.LasData(hdr)
    las.x, las.y, las.z = xyz.T
    las.write(str(path))
    data = bytearray(path.read_bytes())
    struct.pack_into("<I", data, 107, 0)  # legacy 32-bit count
    struct.pack_into("<Q", data, 247, declared)  # LAS 1.4 64-bit count
    path.write_bytes(bytes(data))


#: The grid presets of the served cloud (from its point spacing), as the dropdown shows them.
PRESETS = tuple(f"{g:g}" for g in grid_presets(face_cloud(20_000, seed=3)))


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    folder = tmp_path_factory.mktemp("data")
    np.save(folder / "face.npy", face_cloud(20_000, seed=3).xyz())
    laz_bomb(folder / "bomb.laz")
    proc = ServeProcess(str(folder / "face.npy"), "--max-upload-mb", "16", "--no-token")
    client = ProtocolClient(proc.port, "/")
    client.uuid("Upload file")
    yield proc, client, folder
    client.close()
    proc.stop()


def status(client: ProtocolClient, text: str, since: int, timeout: float = 60.0) -> None:
    """Wait for ``text`` in a message that came after index ``since``."""
    client.wait_for(lambda m: m.get("type") in ("GuiMarkdownMessage", "GuiUpdateMessage")
                    and text in str(m), timeout=timeout, what=repr(text), since=since)


def refusal(client: ProtocolClient, text: str, since: int, timeout: float = 60.0) -> str:
    msg = client.wait_for(lambda m: m.get("type") == "NotificationShowMessage"
                          and text in m["props"]["body"], timeout=timeout, what=repr(text),
                          since=since)
    return str(msg["props"]["body"])


def settled_peak(proc: ServeProcess) -> int:
    time.sleep(1.0)
    return proc.memory()["VmHWM"]


def test_an_upload_above_the_limit_leaves_memory_unchanged(served):
    proc, client, _ = served
    before = settled_peak(proc)
    blob = b"0.0 0.0 0.0\n" * (200 * MiB // 12)  # 200 MiB announced truthfully
    mark = len(client.messages)
    client.upload("Upload file", "huge.xyz", blob)
    body = refusal(client, "huge.xyz is 200.0 MiB, more than the upload limit of 16.0 MiB",
                   mark)
    liar = b"1.0 2.0 3.0\n" * (64 * MiB // 12)  # 64 MiB sent after announcing 1 MiB
    mark = len(client.messages)
    client.upload("Upload file", "liar.xyz", liar, declared=MiB)
    refusal(client, "liar.xyz: the upload is larger than announced", mark)
    # the server still answers: a grid other than the one it opened on (the finest)
    mark = len(client.messages)
    client.set_value("Grid size (m)", PRESETS[0])
    status(client, f"grid {PRESETS[0]} m", mark)
    after = settled_peak(proc)
    print(f"\npeak resident before {before / MiB:.0f} MiB, after 264 MiB of refused "
          f"uploads {after / MiB:.0f} MiB")
    assert after - before < SLACK, (before, after, body)
    assert proc.alive()


@pytest.mark.parametrize("how", ["upload", "load"])
def test_a_laz_bomb_is_an_error_and_leaves_memory_unchanged(served, how):
    proc, client, folder = served
    before = settled_peak(proc)
    bomb = folder / "bomb.laz"
    mark = len(client.messages)
    if how == "upload":
        client.upload("Upload file", "bomb.laz", bomb.read_bytes())
    else:
        client.set_value("File path", "bomb.laz")
        client.set_value("Load file", True)
    body = refusal(client, "50,000,000", mark)
    assert "bomb.laz" in body and str(folder) not in body and "rough-viewer-uploads" not in body
    # still serving: a grid other than the previous test's (the module shares a server)
    size = PRESETS[1] if how == "upload" else PRESETS[0]
    mark = len(client.messages)
    client.set_value("Grid size (m)", size)
    status(client, f"grid {size} m", mark)
    after = settled_peak(proc)
    print(f"\nLAZ bomb by {how}: peak resident before {before / MiB:.0f} MiB, "
          f"after {after / MiB:.0f} MiB")
    assert after - before < SLACK
    assert proc.alive()
