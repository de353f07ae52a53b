"""Isolation itself: a reader that crashes, aborts, allocates without end, hangs or
exits is one line naming the file, and this process goes on; points come back whole;
a cancelled read kills its child (issue 21)."""

from __future__ import annotations

import os
import time

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


def test_a_child_under_ulimit_asks_no_more_than_the_hard_limit(tmp_path):
    """Issue 36: under ``ulimit -v`` the child asked ``setrlimit`` for more than the
    hard limit ("not allowed to raise maximum limit") and every read failed. It now
    takes the lower of the two, and the read succeeds within the user's limit."""
    import subprocess
    import sys

    path = tmp_path / "scan.bin"
    path.write_bytes(b"anything")
    script = (
        "import resource, sys\n"
        "from rough_viewer.io import _child\n"
        "from rough_viewer.io.isolate import Limits, read_isolated\n"
        "cap = _child._vm_size() + (1536 << 20)\n"
        "resource.setrlimit(resource.RLIMIT_AS, (cap, cap))\n"
        "c = read_isolated('tests.io.crashers:reads', sys.argv[1], label='LAZ',\n"
        "                  limits=Limits(memory=8 << 30, seconds=60.0), options={'n': 500})\n"
        "print(c.n)\n")
    done = subprocess.run([sys.executable, "-c", script, str(path)], capture_output=True,
                          text=True, timeout=120, cwd=os.getcwd())
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split()[-1] == "500"


def test_a_spare_started_by_a_thread_that_ends_lives_and_dies_with_the_process():
    """Issue 36: PR_SET_PDEATHSIG fires when the forking THREAD ends: a spare started
    by a short-lived thread was killed with it. Children are now forked by one
    long-lived thread: the spare outlives its starting thread, and still dies when
    the process is killed."""
    import signal
    import subprocess
    import sys

    script = (
        "import os, threading, time\n"
        "from rough_viewer.io import isolate\n"
        "def start():\n"
        "    isolate.warm()\n"
        "    time.sleep(2.0)  # the child is ready (prctl done) before this thread ends\n"
        "t = threading.Thread(target=start)\n"
        "t.start(); t.join()\n"
        "time.sleep(0.5)\n"
        "spare = isolate._spare\n"
        "print(spare.proc.pid, spare.alive(), flush=True)\n"
        "time.sleep(60)\n")
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True,
                              cwd=os.getcwd())
    try:
        assert parent.stdout is not None
        pid, alive = parent.stdout.readline().split()
        assert alive == "True"  # the thread that started it has ended
        parent.send_signal(signal.SIGKILL)
        parent.wait(10)

        def gone() -> bool:
            try:
                with open(f"/proc/{pid}/stat") as fh:
                    return fh.read().split(")")[-1].split()[0] == "Z"
            except OSError:
                return True

        wait_until(gone, 10)
    finally:
        if parent.poll() is None:
            parent.kill()
