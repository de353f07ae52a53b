"""Isolation itself: a reader that crashes, aborts, allocates without end, hangs or
exits is one line naming the file, and this process goes on; points come back whole;
a cancelled read kills its child (issue 21)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rough_viewer.io import isolate
from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.isolate import Limits, read_isolated, stream_isolated
from rough_viewer.vocabulary import InputError
from tests.app.browser import wait_until

pytestmark = pytest.mark.skipif(not isolate.available(), reason="isolation needs Linux")

LIMITS = Limits(memory=64 << 20, seconds=60.0)


def _read(tmp_path, name: str, limits: Limits = LIMITS, **kwargs) -> PointCloud:
    path = tmp_path / "scan.bin"
    path.write_bytes(b"anything")
    return read_isolated(f"tests.io.crashers:{name}", path, label="LAZ", limits=limits, **kwargs)


@pytest.mark.parametrize("name, expected", [
    ("segfault", "the LAZ reader crashed (signal 11, SIGSEGV) on {p}; the file is damaged or "
                 "not LAZ"),
    ("abort", "the LAZ reader crashed (signal 6, SIGABRT) on {p}; the file is damaged or not LAZ"),
    ("exits", "the LAZ reader stopped unexpectedly (exit status 7) on {p}"),
    ("killed", "the LAZ reader was killed (out of memory?) on {p}"),
    ("panics", "cannot read {p}: the decoder failed (attempt to calculate the remainder with a "
               "divisor of zero)"),
    ("refuses", "no points in {p}"),
])
def test_a_failing_reader_is_one_line_naming_the_file(tmp_path, name, expected):
    with pytest.raises(InputError) as exc:
        _read(tmp_path, name)
    assert str(exc.value) == expected.format(p=tmp_path / "scan.bin")


def test_a_reader_past_its_memory_limit_is_stopped_there(tmp_path):
    """2 GiB asked of a budget of 64 MiB: the allocation fails inside the child."""
    with pytest.raises(InputError) as exc:
        _read(tmp_path, "allocate", options={"gib": 2.0})
    assert str(exc.value) == isolate.memory_message("LAZ", tmp_path / "scan.bin", LIMITS)
    assert "went past its memory limit of 64.0 MiB" in str(exc.value)


def test_a_hanging_reader_is_stopped_at_its_time_limit(tmp_path):
    with pytest.raises(InputError) as exc:
        _read(tmp_path, "hang", Limits(memory=64 << 20, seconds=1.5))
    assert str(exc.value).startswith(f"the LAZ reader took longer than 2 s on {tmp_path / 'scan.bin'}")
    pid = int((tmp_path / "scan.pid").read_text())
    wait_until(lambda: not _alive(pid), 10, "the child to be gone")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


class Cancelled(Exception):
    pass


def test_a_cancelled_read_kills_its_child(tmp_path):
    """The app's jobs pass a progress callback that raises once cancelled."""
    calls: list[tuple[int, int]] = []

    def progress(done: int, total: int) -> None:
        calls.append((done, total))
        if (tmp_path / "scan.pid").exists() and done == 1:
            raise Cancelled

    t0 = time.monotonic()
    with pytest.raises(Cancelled):
        _read(tmp_path, "hang", progress=progress, expected=10)
    assert time.monotonic() - t0 < 30
    assert calls[0] == (0, 10) and calls[-1] == (1, 10)  # the child's own progress arrived
    pid = int((tmp_path / "scan.pid").read_text())
    wait_until(lambda: not _alive(pid), 10, "the child to be gone")


def test_points_come_back_whole(tmp_path):
    seen: list[tuple[int, int]] = []
    cloud = _read(tmp_path, "reads", options={"n": 5000}, progress=lambda d, t: seen.append((d, t)))
    i = np.arange(5000, dtype=np.float64)
    np.testing.assert_array_equal(cloud.x, i)
    np.testing.assert_array_equal(cloud.y, 2 * i)
    np.testing.assert_array_equal(cloud.z, -i)
    assert cloud.intensity is not None and cloud.intensity.dtype == np.uint16
    np.testing.assert_array_equal(cloud.intensity, np.arange(5000))
    assert cloud.rgb is not None and cloud.rgb.shape == (5000, 3)
    assert cloud.scan_index is not None and int(cloud.scan_index.sum()) == 2500
    np.testing.assert_array_equal(cloud.scanner_positions, [[0, 0, 1], [5, 0, 1]])
    assert cloud.dropped_nonfinite == 3 and cloud.warnings == ("the header of x declares 5 points",)
    assert cloud.source == str(tmp_path / "scan.bin")
    assert (2500, 5000) in seen and seen[-1] == (5000, 5000)
    cloud.x[0] = 7.0  # the shared memory is the parent's own now: writable


def test_a_stream_yields_its_items_then_ends(tmp_path):
    path = tmp_path / "scan.bin"
    path.write_bytes(b"x")
    items = list(stream_isolated("tests.io.crashers:chunks", path, label="LAZ", limits=LIMITS,
                                 names=frozenset("xyz"), options={"count": 4}))
    assert [float(it["x"][0]) for it in items] == [0.0, 1.0, 2.0, 3.0]
    assert all(it["y"].tolist() == list(range(10)) for it in items)


def test_this_process_survives_many_crashes(tmp_path):
    for _ in range(3):
        with pytest.raises(InputError, match="crashed"):
            _read(tmp_path, "segfault")
    assert _read(tmp_path, "reads").n == 1000


def test_a_layout_that_does_not_describe_the_memory_is_refused():
    fd, layout = isolate.pack({"x": np.arange(10.0)})
    os.close(fd)
    for bad in ([{"name": "x", "dtype": "|O", "shape": [10], "offset": 0}],   # objects
                [{"name": "x", "dtype": "<f8", "shape": [17], "offset": 0}],  # beyond
                [{"name": "x", "dtype": "<f8", "shape": [-1], "offset": 0}],
                [{"name": "evil", "dtype": "<f8", "shape": [1], "offset": 0}],
                [{"name": "x", "dtype": "<f8", "shape": [1], "offset": 8}]):  # misaligned
        fd, _ = isolate.pack({"x": np.arange(10.0)})
        with pytest.raises(ValueError):
            isolate.unpack(fd, bad, names=frozenset("xyz"))
    fd, layout = isolate.pack({"x": np.arange(10.0), "y": np.ones((4, 3), dtype=np.uint16)})
    got = isolate.unpack(fd, layout, names=frozenset("xy"))
    np.testing.assert_array_equal(got["x"], np.arange(10.0))
    np.testing.assert_array_equal(got["y"], np.ones((4, 3)))


def test_time_limit_grows_with_the_file_and_can_be_set(monkeypatch):
    monkeypatch.delenv("ROUGH_VIEWER_READ_SECONDS", raising=False)
    assert isolate.time_limit(0) == isolate.TIME_BASE_S
    assert isolate.time_limit(100e6) == isolate.TIME_BASE_S + 100 * isolate.TIME_PER_MB_S
    monkeypatch.setenv("ROUGH_VIEWER_READ_SECONDS", "5")
    assert isolate.time_limit(100e6) == 5.0
    monkeypatch.setenv("ROUGH_VIEWER_READ_SECONDS", "soon")
    with pytest.raises(InputError, match="ROUGH_VIEWER_READ_SECONDS"):
        isolate.time_limit(1)


def test_a_spare_started_by_a_thread_that_ends_stays_alive():
    """Linux's kill-on-parent-death counts the parent THREAD: every child is started
    by one long-lived thread, so a spare a short-lived thread asked for survives it."""
    import threading

    isolate._close_spare()

    def start_and_wait_for_its_preload() -> None:
        isolate.warm()
        pid = isolate._spare.proc.pid  # type: ignore[union-attr]
        # the child asks for its parent's death signal before it imports numpy
        wait_until(lambda: "numpy" in Path(f"/proc/{pid}/maps").read_text(), 30,
                   "the child to import numpy")

    starter = threading.Thread(target=start_and_wait_for_its_preload)
    starter.start()
    starter.join()
    # the kernel handles the thread's death after join returns: wait till it is gone
    wait_until(lambda: not os.path.exists(f"/proc/self/task/{starter.native_id}"), 10,
               "the starting thread to end")
    spare = isolate._spare
    assert spare is not None
    with pytest.raises(subprocess.TimeoutExpired):  # a killed child ends in milliseconds
        spare.proc.wait(1.0)
    assert spare.alive()


def test_a_read_under_ulimit_v_asks_no_more_than_the_hard_limit(tmp_path):
    """A parent under ``ulimit -v`` whose child's limit would exceed it: the child
    takes the hard limit instead of failing to raise it (issue 36)."""
    path = tmp_path / "scan.bin"
    path.write_bytes(b"anything")
    script = (
        "import resource, sys\n"
        "from rough_viewer.io.isolate import Limits, read_isolated\n"
        "hard = 6 << 30\n"
        "resource.setrlimit(resource.RLIMIT_AS, (hard, hard))\n"
        "cloud = read_isolated('tests.io.crashers:reads', sys.argv[1], label='LAZ',\n"
        "                      limits=Limits(memory=64 << 30, seconds=60), options={'n': 50})\n"
        "print(cloud.n)\n")
    done = subprocess.run([sys.executable, "-c", script, str(path)], capture_output=True,
                          text=True, timeout=120, cwd=Path(__file__).parents[2],
                          env=dict(os.environ, PYTHONPATH=str(Path(__file__).parents[2])))
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["50"]


def test_the_address_limit_is_the_lower_of_the_wanted_and_the_hard_limit():
    script = ("import resource\n"
              "from rough_viewer.io._child import address_limit\n"
              "resource.setrlimit(resource.RLIMIT_AS, (5 << 30, 5 << 30))\n"
              "print(address_limit(64 << 30), address_limit(1 << 30))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=60, check=True,
                          env=dict(os.environ, PYTHONPATH=str(Path(__file__).parents[2])))
    assert done.stdout.split() == [str(5 << 30), str(1 << 30)]


def test_a_relative_path_is_read_from_the_callers_folder_not_the_spares(tmp_path, monkeypatch):
    """A spare child is forked before the caller changes folder (``cd data && serve
    face.las`` in one process after a read elsewhere): it reads the relative path from
    the caller's folder now. Before, 'cannot read face.las: No such file or directory'."""
    import laspy

    from rough_viewer.io import load_points

    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        header = laspy.LasHeader(point_format=0, version="1.2")
        header.scales = np.array([0.001, 0.001, 0.001])
        las = laspy.LasData(header)
        n = 10 if name == "a" else 20
        las.x, las.y, las.z = np.arange(n) * 0.1, np.arange(n) * 0.2, np.zeros(n)
        las.write(tmp_path / name / "face.las")
    monkeypatch.chdir(tmp_path / "a")
    assert load_points("face.las").n == 10
    isolate.warm()  # a spare started in folder a
    monkeypatch.chdir(tmp_path / "b")
    cloud = load_points("face.las")
    assert cloud.n == 20 and cloud.source == "face.las"
