"""The one worker: lanes, merging a view into a pending load, cancellation between
stages, bounded queue and records, idle work (no viser here)."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import ClassVar

import pytest

from rough_viewer.app.worker import Cancelled, Job, QueueFull, Run, Worker
from tests.app.browser import wait_until


@dataclass
class Log:
    done: list[str] = field(default_factory=list)
    released: list[str] = field(default_factory=list)
    gate: threading.Event = field(default_factory=threading.Event)
    entered: threading.Event = field(default_factory=threading.Event)


@dataclass(frozen=True)
class Block(Job[Log]):
    """Holds the worker until the log's gate opens."""

    lane: ClassVar[str] = "block"

    def stages(self, ctx: Log, run: Run) -> Iterator[str]:
        ctx.entered.set()
        assert ctx.gate.wait(10)
        ctx.done.append("block")
        yield "blocked"


@dataclass(frozen=True)
class View(Job[Log]):
    value: int
    lane: ClassVar[str] = "view"

    def stages(self, ctx: Log, run: Run) -> Iterator[str]:
        ctx.done.append(f"view {self.value}")
        yield "view"


@dataclass(frozen=True)
class Load(Job[Log]):
    name: str
    view: int = 0
    lane: ClassVar[str] = "load"
    cancels: ClassVar[frozenset[str]] = frozenset({"view"})

    def absorb(self, newer: Job[Log]) -> Job[Log] | None:
        return replace(self, view=newer.value) if isinstance(newer, View) else None

    def release(self) -> None:
        pass

    def stages(self, ctx: Log, run: Run) -> Iterator[str]:
        ctx.done.append(f"load {self.name} with view {self.view}")
        yield "load"


@dataclass(frozen=True)
class Click(Job[Log]):
    n: int
    lane: ClassVar[str] = "click"
    keep_all: ClassVar[bool] = True

    def stages(self, ctx: Log, run: Run) -> Iterator[str]:
        ctx.done.append(f"click {self.n}")
        yield "click"


@dataclass(frozen=True)
class Upload(Job[Log]):
    name: str
    lane: ClassVar[str] = "load"

    def release(self) -> None:
        self._log.released.append(self.name)

    _log: Log = field(default_factory=Log, compare=False)

    def stages(self, ctx: Log, run: Run) -> Iterator[str]:
        ctx.done.append(f"upload {self.name}")
        yield "upload"


@dataclass(frozen=True)
class Stages(Job[Log]):
    """Three stages; the second waits on the gate so the test can cancel it."""

    lane: ClassVar[str] = "view"

    def stages(self, ctx: Log, run: Run) -> Iterator[str]:
        try:
            ctx.done.append("stage 1")
            yield "one"
            ctx.entered.set()
            assert ctx.gate.wait(10)
            ctx.done.append("stage 2")
            yield "two"
            ctx.done.append("stage 3")
            yield "three"
        finally:
            ctx.done.append("cleaned up")


@pytest.fixture
def log():
    return Log()


@pytest.fixture
def worker(log):
    w: Worker[Log] = Worker(log, on_error=lambda job, exc: log.done.append(f"error {exc}"))
    yield w
    log.gate.set()
    w.stop()


def hold(worker, log):
    worker.submit(Block())
    assert log.entered.wait(5)
    log.entered.clear()


def test_newest_view_wins_and_a_pending_load_absorbs_views(worker, log):
    hold(worker, log)
    for i in range(20):  # a slider drag while busy
        worker.submit(View(i))
    assert worker.pending_kinds() == ["View"]
    worker.submit(Load("a.las"))  # replaces the pending view (the load shows the newest)
    worker.submit(View(42))  # merged into the pending load, not queued after it
    worker.submit(View(43))
    assert worker.pending_kinds() == ["Load"]
    log.gate.set()
    assert worker.wait_idle(5)
    assert log.done == ["block", "load a.las with view 43"]


def test_keep_all_lane_runs_every_job_in_order(worker, log):
    hold(worker, log)
    for i in range(3):
        worker.submit(Click(i))
    worker.submit(View(1))
    log.gate.set()
    assert worker.wait_idle(5)
    assert log.done == ["block", "click 0", "click 1", "click 2", "view 1"]


def test_a_newer_job_cancels_the_running_one_between_stages(worker, log):
    worker.submit(Stages())
    assert log.entered.wait(5)
    worker.submit(View(7))  # same lane: the running job stops after its stage
    log.gate.set()
    assert worker.wait_idle(5)
    assert log.done == ["stage 1", "stage 2", "cleaned up", "view 7"]
    rec = [r for r in worker.records if r.kind == "Stages"][0]
    assert rec.outcome == "cancelled" and [s for s, _ in rec.stages] == ["one", "two"]


def test_run_check_stops_a_long_stage(log):
    started = threading.Event()
    steps: list[int] = []

    @dataclass(frozen=True)
    class Long(Job[Log]):
        lane: ClassVar[str] = "view"

        def stages(self, ctx: Log, run: Run) -> Iterator[str]:
            progress = run.progress()
            started.set()
            for i in range(1000):
                progress(i, 1000)  # raises Cancelled once cancelled
                steps.append(i)
                time.sleep(0.005)
            ctx.done.append("finished")
            yield "long"

    w: Worker[Log] = Worker(log)
    w.submit(Long())
    assert started.wait(5)
    w.submit(View(1))
    assert w.wait_idle(30)
    # stopped inside its stage: well short of its 1,000 steps (5 s), not after them
    assert len(steps) < 500, len(steps)
    assert log.done == ["view 1"] and w.records[0].outcome == "cancelled"
    w.stop()


def test_dropped_and_finished_jobs_are_released(worker, log):
    hold(worker, log)
    a, b = Upload("a", _log=log), Upload("b", _log=log)
    worker.submit(a)
    worker.submit(b)  # replaces a, which never runs
    assert log.released == ["a"]
    log.gate.set()
    assert worker.wait_idle(5)
    assert log.done == ["block", "upload b"] and log.released == ["a", "b"]


def test_errors_are_reported_and_the_worker_goes_on(worker, log):
    @dataclass(frozen=True)
    class Boom(Job[Log]):
        def stages(self, ctx: Log, run: Run) -> Iterator[str]:
            raise ValueError("boom")
            yield "never"

    worker.submit(Boom())
    worker.submit(Click(1))
    assert worker.wait_idle(5)
    assert log.done == ["error boom", "click 1"]
    assert [r.outcome for r in worker.records] == ["failed", "done"]


def test_queue_and_records_are_bounded(log):
    w: Worker[Log] = Worker(log, max_pending=4, max_records=3)
    hold(w, log)
    for i in range(4):
        w.submit(Click(i))
    with pytest.raises(QueueFull):
        w.submit(Click(99))
    # a refused upload is let go at once (its temporary file deleted), the queue kept
    with pytest.raises(QueueFull):
        w.submit(Upload("refused", _log=log))
    assert log.released == ["refused"] and w.pending_kinds() == ["Click"] * 4
    log.gate.set()
    assert w.wait_idle(5)
    assert log.done == ["block", "click 0", "click 1", "click 2", "click 3"]
    assert len(w.records) == 3 and [r.kind for r in w.records] == ["Click"] * 3
    w.stop()


def test_idle_work_runs_when_nothing_waits_and_yields_to_jobs(log):
    calls: list[bool] = []
    release = threading.Event()

    def idle(run: Run) -> bool:
        if len(calls) >= 3:
            return False
        calls.append(run.cancelled)
        if len(calls) == 2:
            release.wait(5)
            run.check()  # a job came in: stop here
        return True

    w: Worker[Log] = Worker(log, idle=idle)
    w.submit(View(1))
    wait_until(lambda: len(calls) >= 2, 5, "the second idle call")
    w.submit(View(2))  # cancels the idle work, runs, then idle work resumes
    release.set()
    wait_until(lambda: len(calls) >= 3, 5, "the idle work resumed")
    assert log.done == ["view 1", "view 2"] and len(calls) == 3
    w.stop()


def test_stop_drops_waiting_jobs_and_cancelled_is_an_exception():
    log = Log()
    w: Worker[Log] = Worker(log)
    hold(w, log)
    w.submit(Upload("x", _log=log))
    w.stop(timeout=0.1)
    assert log.released == ["x"]
    assert w.submit(View(1)) == 0
    log.gate.set()
    assert issubclass(Cancelled, Exception)


@dataclass(frozen=True)
class Measure(Job[Log]):
    """A long measurement checking its run between azimuths; gives way to a load."""

    lane: ClassVar[str] = "measure"
    yields_to: ClassVar[frozenset[str]] = frozenset({"load"})

    def stages(self, ctx: Log, run: Run) -> Iterator[str]:
        ctx.entered.set()
        for k in range(1000):
            run.check()  # between azimuths
            time.sleep(0.01)
            ctx.done.append(f"azimuth {k}")
        yield "measure"


def test_a_load_cancels_a_running_measurement_and_drops_a_waiting_one(worker, log):
    """Issue 36 item 17: a 1-degree Directions run held another tab's load 43 s. A job
    that yields to the load lane is cancelled between its azimuths by a load (it
    would take 10 s), and a waiting one is dropped."""
    worker.submit(Measure())
    assert log.entered.wait(5)
    t0 = time.perf_counter()
    worker.submit(Load("b"))
    assert worker.wait_idle(5)
    assert time.perf_counter() - t0 < 2.0
    assert log.done[-1] == "load b with view 0"
    assert sum(d.startswith("azimuth") for d in log.done) < 200
    assert [r.outcome for r in worker.records] == ["cancelled", "done"]
    log.entered.clear()
    hold(worker, log)
    worker.submit(Measure())
    worker.submit(Load("c"))
    assert worker.pending_kinds() == ["Load"]
    log.gate.set()
    assert worker.wait_idle(5) and log.done[-1] == "load c with view 0"
    # a job of another lane neither drops nor cancels it
    log.gate.clear()
    log.entered.clear()
    worker.submit(Measure())
    assert log.entered.wait(5)
    worker.submit(View(7))
    time.sleep(0.1)
    assert worker.records[-1].kind == "Load"  # the measurement still runs
    worker.cancel()
    assert worker.wait_idle(5)


def test_one_owner_cannot_fill_the_queue(log):
    """Issue 36 item 17: one tab could fill the shared queue (64) so every other tab
    got 'Busy'. At most max_per_owner jobs of one owner wait; another owner, and the
    app itself (no owner), are still served; a job that ran frees its place."""
    w: Worker[Log] = Worker(log, max_pending=64, max_per_owner=16)
    hold(w, log)
    for i in range(16):
        w.submit(Click(i), owner=1)
    with pytest.raises(QueueFull, match="16 jobs of this owner"):
        w.submit(Click(99), owner=1)
    for i in range(16):
        w.submit(Click(100 + i), owner=2)
    w.submit(Click(200))
    assert len(w.pending_kinds()) == 33
    log.gate.set()
    assert w.wait_idle(5)
    assert log.done[1:] == [f"click {i}" for i in (*range(16), *range(100, 116), 200)]
    for i in range(16):  # their jobs ran: owner 1 has its places back
        w.submit(Click(300 + i), owner=1)
    assert w.wait_idle(5)
    w.stop()
