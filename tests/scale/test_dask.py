"""The Dask runner (scale/dask_runner.py) on a real LocalCluster of 2 worker processes:
equal to the in-memory path, the same bits as the sequential path, and unchanged
when a worker is killed mid-run."""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.scale import chunked_roughness, open_sources
from rough_viewer.vocabulary import InputError
from tests.scale.helpers_scale import assert_same_cells, split_files

distributed = pytest.importorskip("distributed")
from rough_viewer.scale.dask_runner import DaskRunner  # noqa: E402

GRIDS = (0.4, 0.15)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return split_files(tmp_path_factory.mktemp("dask"), n=30_000)


@pytest.fixture(scope="module")
def client():
    """One LocalCluster for the module: 2 worker processes, loopback only."""
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                       silence_logs=40)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def sequential(files):
    paths, _ = files
    return chunked_roughness(open_sources(paths), GRIDS, chunk_points=2500)


def same_bits(a, b):
    for name in ("theta_odr", "theta_ols", "theta_hybrid", "normal"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_distributed_equals_in_memory_and_sequential(files, client, sequential):
    paths, xyz = files
    seen = []
    res = chunked_roughness(open_sources(paths), GRIDS, chunk_points=2500,
                            runner=DaskRunner(client=client), progress=lambda d, t: seen.append(d))
    for g, r, s in zip(GRIDS, res, sequential, strict=True):
        assert_same_cells(r, grid_roughness(xyz, g, engine="numpy"))
        same_bits(r, s)   # a fixed reduction tree: the same bits as one process
    assert seen[-1] == 2 * len(xyz) and len(seen) > 20


def test_local_threads_same_bits(files, sequential):
    paths, _ = files
    for workers in (1, 2):
        res = chunked_roughness(open_sources(paths), GRIDS, chunk_points=2500,
                                runner=DaskRunner("threads", workers=workers))
        for r, s in zip(res, sequential, strict=True):
            same_bits(r, s)


def test_local_process_pool_same_bits(files, sequential):
    paths, _ = files
    with DaskRunner("processes", workers=2) as runner:
        res = chunked_roughness(open_sources(paths), GRIDS, chunk_points=2500, runner=runner)
    for r, s in zip(res, sequential, strict=True):
        same_bits(r, s)


def test_worker_killed_mid_run_is_retried_result_unchanged(files, client):
    paths, _ = files
    pids = client.run(os.getpid)
    victim = sorted(pids.values())[0]
    killed = []

    def progress(done, total):
        # after the first chunks are in, kill a worker process that holds results
        if not killed and 0 < done < total // 4:
            os.kill(victim, signal.SIGKILL)
            killed.append(done)

    res = chunked_roughness(open_sources(paths), GRIDS, chunk_points=1000,
                            runner=DaskRunner(client=client), progress=progress)
    assert killed
    for r, s in zip(res, chunked_roughness(open_sources(paths), GRIDS, chunk_points=1000),
                    strict=True):
        same_bits(r, s)
    deadline = time.time() + 30
    while len(client.scheduler_info()["workers"]) < 2 and time.time() < deadline:
        time.sleep(0.2)  # the nanny restarts the worker
    assert victim not in client.run(os.getpid).values()


def test_cli_scheduler_address_prints_dashboard(files, client, tmp_path, capsys):
    paths, _ = files
    address = client.scheduler.address
    assert address.startswith("tcp://127.0.0.1:")
    out_d, out_s = tmp_path / "d.csv", tmp_path / "s.csv"
    assert main(["compute", *map(str, paths), "--grid", "0.4", "--scheduler", address,
                 "--out", str(out_d), "--quiet"]) == 0
    assert "dashboard" in capsys.readouterr().err
    assert main(["compute", *map(str, paths), "--grid", "0.4", "--memory", "300MB",
                 "--out", str(out_s), "--quiet"]) == 0
    assert out_d.read_text() == out_s.read_text()


def _server(answer: bytes | None):
    """A TCP server on a free port that accepts, sends ``answer`` (None: nothing, as
    an HTTP server waiting for a request) and keeps the connection open a while."""
    import socket
    import threading

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)

    def serve():
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            if answer:
                conn.sendall(answer)
            threading.Timer(5.0, conn.close).start()

    threading.Thread(target=serve, daemon=True).start()
    return srv, f"tcp://127.0.0.1:{srv.getsockname()[1]}"


@pytest.mark.parametrize("answer, message", [
    (None, "did not answer as a Dask scheduler within 1 s"),
    (b"HTTP/1.0 400 Bad Request\r\n\r\n", "answered, but not as a Dask scheduler"),
])
def test_an_address_that_is_not_a_dask_scheduler_is_one_line(answer, message, client):
    """An HTTP server made distributed.Client wait for ever; bytes that are not a
    handshake were read as an exabyte-long message. Both are refused in one line,
    and a real scheduler passes."""
    import time

    from rough_viewer.scale.dask_runner import probe_scheduler

    srv, address = _server(answer)
    try:
        t = time.time()
        with pytest.raises(InputError) as info:
            probe_scheduler(address, timeout=1.0)
        # a hang guard, not a timing: the old client waited for ever on such an address
        assert time.time() - t < 30 and message in str(info.value)
        assert address in str(info.value) and "\n" not in str(info.value)
    finally:
        srv.close()
    probe_scheduler(client.scheduler.address, timeout=5.0)  # a real one answers
    import socket

    with socket.socket() as unused:  # a port nothing listens on
        unused.bind(("127.0.0.1", 0))
        port = unused.getsockname()[1]
    with pytest.raises(InputError, match="cannot reach the Dask scheduler"):
        probe_scheduler(f"tcp://127.0.0.1:{port}", timeout=1.0)
