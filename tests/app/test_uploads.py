"""Uploads arrive through viser's protocol and go straight to disk, within limits."""

from __future__ import annotations

import time

import numpy as np
import pytest

from rough_viewer.app.gate import open_server
from rough_viewer.app.server import build_app
from rough_viewer.app.uploads import clean_name
from tests.app.browser import wait_until
from tests.app.protocol import ProtocolClient, join, settle
from tests.helpers import face_cloud

LIMIT_MB = 1


@pytest.fixture
def live():
    server, _gate = open_server("127.0.0.1", 0, token=None, log=False)
    cloud = face_cloud(8_000)
    app = build_app(server, cloud, prefetch=False, max_upload_mb=LIMIT_MB)
    assert app.wait_idle(60)
    client = join(server)
    yield app, client, cloud
    client.close()
    app.stop()
    server.stop()


def xyz_text(n: int, seed: int = 1) -> bytes:
    xyz = face_cloud(n, seed=seed).xyz()
    return "\n".join(f"{a:.4f} {b:.4f} {c:.4f}" for a, b, c in xyz).encode()


def test_an_upload_is_loaded_and_its_file_removed(live):
    app, client, _ = live
    data = xyz_text(3000)
    client.upload("Upload file", "my scan.xyz", data, chunk=64 * 1024)  # 4+ parts
    settle(app, lambda: app.session.shown.loaded.n_total == 3000, "the uploaded cloud")
    assert app.session.shown.loaded.n_total == 3000 and app.session.shown.loaded.cloud.source == "my scan.xyz"
    assert "my scan.xyz" in app.host.status.content
    assert list(app.host.uploads.folder.iterdir()) == []  # deleted once read
    # the acks go on the uploader's own stream, not ordered with the load
    last = client.wait_for(lambda m: m.get("type") == "FileTransferPartAck"
                           and m["transferred_bytes"] == len(data), what="the last ack")
    assert last["total_bytes"] == len(data)


@pytest.mark.parametrize("name, declared, message", [
    ("big.xyz", 5 << 20, "more than the upload limit of 1.0 MiB"),
    ("tool.exe", None, "not a point-cloud file"),
    ("noext", None, "not a point-cloud file"),
])
def test_refused_at_the_start(live, name, declared, message):
    app, client, cloud = live
    data = b"0 0 0\n" * 1000
    transfer = client.upload("Upload file", name, data, declared=declared)
    settle(app, lambda: len(app.host.uploads.refused) > 0, "the refusal")
    assert message in app.host.uploads.refused[-1]
    assert app.session.shown.loaded.cloud is cloud and list(app.host.uploads.folder.iterdir()) == []
    body = client.wait_for(lambda m: m.get("type") == "NotificationShowMessage"
                           and m["props"]["title"] == "Upload refused")["props"]["body"]
    assert message in body
    # the browser's progress bar is ended, so its button works again
    client.wait_for(lambda m: m.get("type") == "FileTransferPartAck"
                    and m["transfer_uuid"] == transfer
                    and m["transferred_bytes"] == m["total_bytes"])


def test_a_client_sending_more_than_it_announced_is_cut_off(live):
    app, client, cloud = live
    data = xyz_text(60_000)  # about 1.9 MB, above the 1 MiB limit
    assert len(data) > (LIMIT_MB << 20)
    client.upload("Upload file", "liar.xyz", data, declared=100_000)
    settle(app, lambda: len(app.host.uploads.refused) > 0 and app.host.uploads.active == 0, "the cut-off")
    assert "larger than announced" in app.host.uploads.refused[-1]
    assert app.host.uploads.active == 0 and list(app.host.uploads.folder.iterdir()) == []
    assert app.session.shown.loaded.cloud is cloud


def test_parts_out_of_order_and_a_vanished_browser_leave_nothing(live):
    app, client, cloud = live
    source = client.uuid("Upload file")
    client.send({"type": "FileTransferStartUpload", "source_component_uuid": source,
                 "transfer_uuid": "t1", "filename": "a.xyz", "mime_type": "",
                 "size_bytes": 20, "part_count": 2})
    client.send({"type": "FileTransferPart", "source_component_uuid": source,
                 "transfer_uuid": "t1", "part_index": 1, "content": b"0 0 0\n"})
    settle(app, lambda: len(app.host.uploads.refused) > 0, "the refusal")
    assert "out of order" in app.host.uploads.refused[-1]
    client.send({"type": "FileTransferStartUpload", "source_component_uuid": source,
                 "transfer_uuid": "t2", "filename": "b.xyz", "mime_type": "",
                 "size_bytes": 20, "part_count": 2})
    client.send({"type": "FileTransferPart", "source_component_uuid": source,
                 "transfer_uuid": "t2", "part_index": 0, "content": b"0 0 0\n"})
    settle(app, lambda: app.host.uploads.active == 1 and len(list(app.host.uploads.folder.iterdir())) == 1,
           "the first part on disk")
    time.sleep(0.2)  # nothing more comes of it
    assert app.host.uploads.active == 1 and len(list(app.host.uploads.folder.iterdir())) == 1
    client.close()
    wait_until(lambda: not app.host.uploads.active and not list(app.host.uploads.folder.iterdir()), 10,
               "the part removed")
    assert app.host.uploads.active == 0 and list(app.host.uploads.folder.iterdir()) == []
    assert app.session.shown.loaded.cloud is cloud


def test_a_hostile_file_name_is_shown_as_text(live):
    app, client, _ = live
    name = '<img src=x onerror="alert(1)">/../../etc/x **b** [a](javascript:1).xyz'
    client.upload("Upload file", name, xyz_text(2000))
    settle(app, lambda: app.session.shown.loaded.n_total == 2000, "the uploaded cloud")
    status = app.host.status.content
    assert "<img" not in status and "&lt;img" in status
    assert "\\*\\*b\\*\\*" in status and "\\[a\\]\\(javascript:1\\)" in status
    assert "/" not in clean_name(name) and app.session.shown.loaded.cloud.source == clean_name(name)


def test_file_content_never_reaches_the_browser(live):
    app, client, cloud = live
    secret = b"x y z\n1 2 hunter2-password\n3 4 5\n"
    client.upload("Upload file", "secret.xyz", secret)
    settle(app, lambda: any("secret.xyz" in e for e in app.host.errors), "the error")
    assert app.session.shown.loaded.cloud is cloud
    assert "secret.xyz" in app.host.errors[-1]
    assert "hunter2" not in app.host.errors[-1] and str(app.host.uploads.folder) not in app.host.errors[-1]
    client.wait_for(lambda m: m.get("type") == "NotificationShowMessage"
                    and "secret.xyz" in m["props"]["body"], what="the notice")
    notes = [m["props"]["body"] for m in client.of_type("NotificationShowMessage")]
    assert not any("hunter2" in n or "rough-viewer-uploads" in n for n in notes)


def test_names_are_cleaned():
    assert clean_name("a/b\\c.las") == "a_b_c.las"
    assert clean_name("x\ny\x00.laz") == "x y .laz"
    assert clean_name("") == "upload"
    assert len(clean_name("n" * 1000)) == 200


def test_upload_messages_go_to_the_uploader_only(live):
    """Acks and refusals went through viser's persistent broadcast: every part of
    every upload stayed in the server for good and was replayed to each browser
    that connected later (20,000 refusals: 20,000 messages to the next page)."""
    app, client, _ = live
    for k in range(20):
        client.upload("Upload file", f"tool{k}.exe", b"0 0 0\n")
    client.upload("Upload file", "scan.xyz", xyz_text(2000), chunk=16 * 1024)
    settle(app, lambda: app.session.shown.loaded.n_total == 2000, "the uploaded cloud")
    # the uploader gets them (they may trail the server's idle)
    wait_until(lambda: len(client.of_type("FileTransferPartAck")) >= 21, 20, "the acks")
    assert len(client.of_type("FileTransferPartAck")) >= 21
    later = ProtocolClient(app.server.get_port(), "/")
    try:
        later.wait_for(lambda m: m.get("type") == "GuiMarkdownMessage", what="the page")
        time.sleep(0.5)
        assert later.of_type("FileTransferPartAck") == []
    finally:
        later.close()


def test_partial_uploads_of_a_killed_server_are_swept_by_the_next(tmp_path):
    """Issue 36: after ``kill -9`` of serve its partial uploads stayed in the upload
    folder. A real serve is killed while an upload folder holds a part; the next
    server's uploads sweep it, and leave a running server's folder alone."""
    import signal
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from rough_viewer.app import uploads

    script = ("import tempfile, time\n"
              "from pathlib import Path\n"
              "from rough_viewer.app.uploads import owned_prefix\n"
              "d = Path(tempfile.mkdtemp(prefix=owned_prefix()))\n"
              "(d / 'part-1.laz').write_bytes(b'x' * 1000)\n"
              "print(d, flush=True)\n"
              "time.sleep(60)\n")
    child = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None
    left = Path(child.stdout.readline().strip())
    mine = Path(tempfile.mkdtemp(prefix=uploads.owned_prefix()))
    try:
        assert uploads.sweep_stale_uploads(left.parent) == 0  # both owners run
        assert left.exists() and mine.exists()
        child.send_signal(signal.SIGKILL)
        child.wait(10)
        server, _gate = open_server("127.0.0.1", 0, token=None, log=False)
        try:
            made = uploads.Uploads(server, max_bytes=1 << 20, suffixes=(".laz",),
                                   refuse=lambda _c, _m: None)
            assert not left.exists()  # the killed server's partial upload went
            assert mine.exists()  # a running server's stays
            assert made.folder.name.startswith(uploads.owned_prefix())
            made.close()
            assert not made.folder.exists()
        finally:
            server.stop()
    finally:
        if child.poll() is None:
            child.kill()
        import shutil
        shutil.rmtree(mine, ignore_errors=True)
        shutil.rmtree(left, ignore_errors=True)


def test_an_uploaded_stl_keeps_its_mesh_through_a_crop(live, tmp_path):
    """Issue 31 item 5: Directions' TIN parameters of an uploaded STL use its own
    triangles, as ``serve FILE.stl`` does (the upload is deleted once read), and a
    crop uses the triangles of the vertices it keeps."""
    from rough_viewer.app.features.crop import CropFeature, CropJob
    from rough_viewer.app.features.profile.directions import DirectionsFeature
    from rough_viewer.directions.analysis import DirectionSettings, analyse_directions
    from rough_viewer.io import load_points
    from rough_viewer.io.crop import CropBox, crop_mask
    from rough_viewer.io.formats.mesh import load_mesh
    from tests.io.test_mesh import write_binary_stl

    app, client, _ = live
    n, step = 60, 0.03
    y, x = np.meshgrid(np.arange(n) * step, np.arange(n) * step, indexing="ij")
    z = 0.01 * np.sin(7.0 * x) * np.cos(3.0 * y) + 0.002 * np.random.default_rng(2).normal(size=x.shape)
    vertices = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    i = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    # each square cut along its other diagonal from the one a Delaunay of the grid picks
    faces = np.concatenate([np.column_stack([i, i + 1, i + n + 1]),
                            np.column_stack([i, i + n + 1, i + n])])
    path = tmp_path / "joint.stl"
    write_binary_stl(path, vertices, faces)
    client.upload("Upload file", "joint.stl", path.read_bytes(), chunk=128 * 1024)
    settle(app, lambda: app.session.shown.loaded.cloud.source == "joint.stl", "the upload")
    assert list(app.host.uploads.folder.iterdir()) == []
    f = app.feature(DirectionsFeature)
    f.step.value = 45.0
    f.tin.value = True
    cloud, mesh = load_points(path), load_mesh(path)
    for box in (None, CropBox((-1.0, -1.0, -1.0), (0.9, 1.2, 1.0), "keep")):
        if box is not None:
            app.host.submit(CropJob(app.host.feature(CropFeature), box))
            assert app.wait_idle(60) and app.session.shown.loaded.crop == box
        f.measure.value = True
        settle(app, lambda: f.result is not None, "the directions")
        shown = app.session.shown.loaded.cloud
        keep = np.ones(cloud.n, dtype=bool) if box is None else crop_mask(cloud, box)
        want_mesh = mesh if box is None else mesh.kept(keep)
        assert want_mesh is not None
        assert f.result.surface == "mesh" and f.result.n_triangles == want_mesh.n_faces
        assert f.result.n_triangles == (len(faces) if box is None else
                                        int(keep[faces].all(axis=1).sum()))
        np.testing.assert_array_equal(shown.xyz(), cloud.xyz()[keep])
        ref = analyse_directions(shown, DirectionSettings(step_deg=45.0), mesh=want_mesh)
        np.testing.assert_allclose(f.result.tin.theta_max_c1, ref.tin.theta_max_c1)
        f.result = None
