"""The app's one worker thread and the typed jobs it runs.

Every piece of work the app does (load a file, recolour the map, build the
panels, extract a profile, de-noise, scan the board, predict scanner bias, pick
a point) is a :class:`Job`: a small frozen dataclass naming what to do, whose
:meth:`Job.stages` generator does it in named stages. GUI callbacks (they run on
viser's thread pool) only build a job and :meth:`Worker.submit` it; the worker
runs the jobs one at a time on its own thread, so the app's state and scene are
only ever changed from one thread.

How jobs meet in the queue (see :meth:`Worker.submit`):

- **Lanes.** Every job class names a ``lane``. A new job drops the pending jobs
  of its own lane (the newest view wins over a slider drag) and of the lanes in
  its ``cancels``; a running job of those lanes is cancelled at its next stage.
  Jobs of a ``keep_all`` lane (profile picks) all run, in order.
- **Merging.** Before that, each pending job may :meth:`Job.absorb` the newcomer:
  a pending load takes a newer view's settings instead of being replaced by it,
  so "Load file" followed at once by a control change shows the loaded file
  with the new settings.
- **Cancellation.** The worker checks between stages; long stages check
  :meth:`Run.check` (e.g. from a progress callback) and stop with
  :class:`Cancelled`. A cancelled or failed job leaves the app as it was.
- **Yielding.** A job names the lanes it ``yields_to``: a new job of one of them
  drops it while it waits and cancels it while it runs (a Directions measurement
  gives way to a load or a crop, which replace the cloud it measures).
- **Bounds.** At most ``max_pending`` jobs wait (a flood of clicks is refused,
  not queued without end), and at most ``max_per_owner`` of one owner (a browser:
  one tab cannot fill the queue the others share); the last ``max_records``
  finished jobs are kept in :attr:`Worker.records` with their stage times.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Generator, Hashable, Iterator
from dataclasses import dataclass, field
from typing import ClassVar, Generic, Literal, TypeVar

C = TypeVar("C")

Outcome = Literal["done", "cancelled", "failed"]


class Cancelled(Exception):
    """Raised inside a job (by :meth:`Run.check`) when it has been cancelled."""


class QueueFull(Exception):
    """Raised by :meth:`Worker.submit` when ``max_pending`` jobs already wait."""


class NotOnWorker(RuntimeError):
    """Raised when the app's state or scene is written from a thread other than the
    worker's (:meth:`Worker.require_worker`): the single-writer rule is broken."""


_this = threading.local()


def require_a_worker(what: str) -> None:
    """Raise :class:`NotOnWorker` unless called on the thread of a worker (of any
    app: for writers that do not know which app's worker they serve, as a GUI
    binding)."""
    if getattr(_this, "worker", None) is None:
        raise NotOnWorker(f"{what} is written on thread "
                          f"{threading.current_thread().name!r}, not on a worker")


class Run:
    """The handle a running job gets: is it cancelled, and progress checks."""

    def __init__(self) -> None:
        self._cancelled = threading.Event()

    def cancel(self) -> None:
        """Ask the job to stop at its next stage (or :meth:`check`)."""
        self._cancelled.set()

    @property
    def cancelled(self) -> bool:
        return self._cancelled.is_set()

    def check(self) -> None:
        """Raise :class:`Cancelled` if the job has been cancelled."""
        if self._cancelled.is_set():
            raise Cancelled

    def progress(self, report: Callable[[int, int], None] | None = None) -> Callable[[int, int], None]:
        """A ``progress(done, total)`` callback for the science layer that also
        stops the computation (raising :class:`Cancelled`) once the job is cancelled."""

        def progress(done: int, total: int) -> None:
            self.check()
            if report is not None:
                report(done, total)

        return progress


@dataclass(frozen=True)
class Job(Generic[C]):
    """One piece of work for the worker; subclass per kind (a frozen dataclass).

    ``C`` is the context the worker hands to :meth:`stages` (the app).
    """

    lane: ClassVar[str] = "job"
    """Jobs of one lane supersede each other (see the module docstring)."""
    cancels: ClassVar[frozenset[str]] = frozenset()
    """Other lanes whose pending jobs this job drops and whose running job it cancels."""
    keep_all: ClassVar[bool] = False
    """Every job of this lane runs, in order (user actions such as profile picks)."""
    yields_to: ClassVar[frozenset[str]] = frozenset()
    """Lanes whose new jobs drop this job while it waits and cancel it while it runs."""

    def absorb(self, newer: Job[C]) -> Job[C] | None:
        """This pending job with ``newer`` merged into it, or None (no merge)."""
        return None

    def release(self) -> None:
        """Free what the job holds (e.g. an uploaded temp file) once it has run or
        was dropped without running; must be safe to call twice. Default: nothing."""

    def stages(self, ctx: C, run: Run) -> Iterator[str]:
        """Do the work; ``yield`` the name of each finished stage (where the worker
        may stop a cancelled job)."""
        raise NotImplementedError

    @property
    def title(self) -> str:
        """What the job does, for notices (default: the class name)."""
        return type(self).__name__


@dataclass(frozen=True)
class JobRecord:
    """A finished job: what it was, how it ended, and the seconds of each stage."""

    number: int
    kind: str
    outcome: Outcome
    stages: tuple[tuple[str, float], ...]
    seconds: float


ErrorHandler = Callable[[Job[C], BaseException], None]
IdleHandler = Callable[[Run], bool]


@dataclass
class _State(Generic[C]):
    pending: list[tuple[int, Job[C]]] = field(default_factory=list)
    owners: dict[int, Hashable] = field(default_factory=dict)
    """The owner (a browser) of each waiting job that has one, by job number."""
    running: tuple[int, Job[C], Run] | None = None
    submitted: int = 0
    stop: bool = False
    idle_done: bool = True


class Worker(Generic[C]):
    """Run :class:`Job` s for the context ``ctx`` on one thread.

    Parameters
    ----------
    ctx
        Passed to every job's :meth:`Job.stages` (the app).
    on_error
        Called on the worker thread with the job and the exception when a job
        fails (default: print the traceback). The worker always survives.
    idle
        Optional background work, ``idle(run) -> bool``, run whenever no job
        waits (e.g. precomputing likely next grids); it returns True while it
        has more to do. A submitted job cancels it.
    max_pending
        Most jobs waiting at once; :meth:`submit` raises :class:`QueueFull` beyond.
    max_per_owner
        Most jobs of one owner waiting at once (:meth:`submit`'s ``owner``).
    max_records
        Finished jobs kept in :attr:`records`.
    """

    def __init__(
        self,
        ctx: C,
        *,
        on_error: ErrorHandler[C] | None = None,
        idle: IdleHandler | None = None,
        max_pending: int = 64,
        max_per_owner: int = 16,
        max_records: int = 500,
        name: str = "rough-viewer-worker",
    ) -> None:
        self._ctx = ctx
        self._on_error = on_error
        self._idle = idle
        self._max_pending = max_pending
        self._max_per_owner = max_per_owner
        self._cond = threading.Condition()
        self._state: _State[C] = _State()
        self._idle_run: Run | None = None
        self.records: deque[JobRecord] = deque(maxlen=max_records)
        """The last finished jobs, oldest first."""
        self._thread = threading.Thread(target=self._loop, name=name, daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ thread
    def require_worker(self, what: str) -> None:
        """Raise :class:`NotOnWorker` unless called on the worker's thread: every
        write of the app's state and scene goes through here."""
        if threading.current_thread() is not self._thread:
            raise NotOnWorker(f"{what} is written on thread "
                              f"{threading.current_thread().name!r}, not on the worker")

    # ------------------------------------------------------------------ queue
    def submit(self, job: Job[C], *, owner: Hashable | None = None) -> int:
        """Queue ``job`` (merging and superseding as the module docstring says) for
        ``owner`` (a browser; None: the app itself).

        Returns the job's number (the number of the job it merged into, if any),
        or 0 once the worker is stopping. Raises :class:`QueueFull` when
        ``max_pending`` jobs already wait, or ``max_per_owner`` of ``owner``'s
        (``job`` is then released; the waiting jobs stay).
        """
        dropped: list[Job[C]] = []
        try:
            with self._cond:
                st = self._state
                if st.stop:
                    dropped.append(job)
                    return 0
                if self._idle_run is not None:
                    self._idle_run.cancel()
                st.idle_done = False
                for i in range(len(st.pending) - 1, -1, -1):
                    number, waiting = st.pending[i]
                    merged = waiting.absorb(job)
                    if merged is not None:
                        st.pending[i] = (number, merged)
                        self._cond.notify_all()
                        return number
                lanes = set(job.cancels)
                if not job.keep_all:
                    lanes.add(job.lane)
                keep = []
                for number, waiting in st.pending:
                    if waiting.lane in lanes or job.lane in waiting.yields_to:
                        dropped.append(waiting)
                    else:
                        keep.append((number, waiting))
                mine = 0 if owner is None else sum(
                    1 for number, _ in keep if st.owners.get(number) == owner)
                if len(keep) >= self._max_pending or mine >= self._max_per_owner:
                    # refused: the waiting jobs stay as they were, the new one is let go
                    dropped = [job]
                    raise QueueFull(f"{mine} jobs of this owner are waiting already"
                                    if len(keep) < self._max_pending
                                    else f"{len(keep)} jobs are waiting already")
                st.pending = keep
                kept = {number for number, _ in keep}
                st.owners = {n: o for n, o in st.owners.items() if n in kept}
                if st.running is not None and (st.running[1].lane in lanes
                                               or job.lane in st.running[1].yields_to):
                    st.running[2].cancel()
                st.submitted += 1
                st.pending.append((st.submitted, job))
                if owner is not None:
                    st.owners[st.submitted] = owner
                self._cond.notify_all()
                return st.submitted
        finally:
            for waiting in dropped:
                _release(waiting)

    def cancel(self) -> None:
        """Drop the waiting jobs and cancel the running one."""
        with self._cond:
            st = self._state
            dropped = [waiting for _, waiting in st.pending]
            st.pending = []
            st.owners = {}
            if st.running is not None:
                st.running[2].cancel()
            self._cond.notify_all()
        for waiting in dropped:
            _release(waiting)

    @property
    def busy(self) -> bool:
        """A job runs or waits."""
        with self._cond:
            return self._state.running is not None or bool(self._state.pending)

    def pending_kinds(self) -> list[str]:
        """Class names of the waiting jobs, in order (tests, diagnostics)."""
        with self._cond:
            return [type(job).__name__ for _, job in self._state.pending]

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until no job runs or waits (idle work aside); False on timeout."""
        with self._cond:
            return self._cond.wait_for(
                lambda: self._state.running is None and not self._state.pending,
                timeout=timeout,
            )

    def stop(self, timeout: float | None = 5.0) -> None:
        """Drop the waiting jobs, cancel the running one and end the thread."""
        self.cancel()
        with self._cond:
            self._state.stop = True
            if self._idle_run is not None:
                self._idle_run.cancel()
            self._cond.notify_all()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    # ------------------------------------------------------------------ loop
    def _has_work(self) -> bool:
        st = self._state
        return bool(st.pending) or st.stop or (self._idle is not None and not st.idle_done)

    def _loop(self) -> None:
        _this.worker = self
        st = self._state
        while True:
            with self._cond:
                self._cond.wait_for(self._has_work)
                if st.stop:
                    return
                if st.pending:
                    number, job = st.pending.pop(0)
                    st.owners.pop(number, None)
                    run = Run()
                    st.running = (number, job, run)
                    idle = False
                else:
                    self._idle_run = run = Run()
                    idle = True
            if idle:
                self._run_idle(run)
                continue
            self._run_job(number, job, run)

    def _run_idle(self, run: Run) -> None:
        assert self._idle is not None
        try:
            more = bool(self._idle(run))
        except Cancelled:
            more = True
        except Exception:  # noqa: BLE001 - background work is optional
            traceback.print_exc()
            more = False
        with self._cond:
            self._idle_run = None
            if not more and not run.cancelled:
                self._state.idle_done = True

    def _run_job(self, number: int, job: Job[C], run: Run) -> None:
        t0 = time.perf_counter()
        t = t0
        stages: list[tuple[str, float]] = []
        outcome: Outcome = "done"
        try:
            gen = job.stages(self._ctx, run)
            try:
                for name in gen:
                    now = time.perf_counter()
                    stages.append((str(name), now - t))
                    t = now
                    if run.cancelled:
                        outcome = "cancelled"
                        break
            finally:
                if isinstance(gen, Generator):
                    gen.close()  # runs the job's own finally blocks now
        except Cancelled:
            outcome = "cancelled"
        except BaseException as exc:  # noqa: BLE001 - the worker must survive
            outcome = "failed"
            if self._on_error is not None:
                try:
                    self._on_error(job, exc)
                except Exception:  # noqa: BLE001
                    traceback.print_exc()
            else:
                traceback.print_exc()
        finally:
            _release(job)
            self.records.append(JobRecord(number, type(job).__name__, outcome, tuple(stages),
                                          time.perf_counter() - t0))
            with self._cond:
                self._state.running = None
                self._cond.notify_all()


def _release(job: Job[C]) -> None:
    try:
        job.release()
    except Exception:  # noqa: BLE001 - cleanup must not break the queue
        traceback.print_exc()
