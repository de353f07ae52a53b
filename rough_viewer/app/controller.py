"""One background worker that runs the latest request only.

GUI callbacks (slider drags arrive about every 50 ms) call :meth:`LatestWorker.submit`
and return at once; the worker thread runs the handler on the newest request,
dropping any that were replaced while it was busy. A long handler can call
``is_stale()`` between steps and stop early when a newer request is waiting.
"""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")

Handler = Callable[[T, Callable[[], bool]], None]


class LatestWorker(Generic[T]):
    """Run ``handler(request, is_stale)`` on one thread, newest request wins.

    Parameters
    ----------
    handler
        Called on the worker thread. ``is_stale()`` is True once a newer request
        has been submitted. Exceptions are passed to ``on_error`` (default: print
        the traceback) and never stop the worker.
    on_error
        Called on the worker thread with the exception.
    idle
        Optional background job, ``idle(is_stale) -> bool``, run on the worker
        thread whenever no request waits (e.g. precomputing likely next grids);
        it returns True if it did some work and wants to be called again.
    """

    def __init__(
        self,
        handler: Handler,
        *,
        on_error: Callable[[BaseException], None] | None = None,
        name: str = "rough-viewer-worker",
        idle: Callable[[Callable[[], bool]], bool] | None = None,
    ) -> None:
        self._handler = handler
        self._idle = idle
        self._idle_done = True
        self._on_error = on_error
        self._cond = threading.Condition()
        self._pending: T | None = None
        self._has_pending = False
        self._busy = False
        self._submitted = 0
        self._finished = 0
        self._stop = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def submit(self, request: T) -> int:
        """Queue ``request``, replacing any request not yet started; returns its number."""
        with self._cond:
            self._submitted += 1
            self._pending = request
            self._has_pending = True
            self._idle_done = False
            self._cond.notify_all()
            return self._submitted

    def is_stale(self) -> bool:
        """True while a newer request waits (for handlers to stop early)."""
        with self._cond:
            return self._has_pending

    @property
    def busy(self) -> bool:
        with self._cond:
            return self._busy or self._has_pending

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until every submitted request has been handled or dropped.
        Returns False on timeout."""
        with self._cond:
            return self._cond.wait_for(
                lambda: not self._has_pending and not self._busy, timeout=timeout
            )

    def stop(self, timeout: float | None = 5.0) -> None:
        """Stop the worker after the current request."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def _run(self) -> None:
        while True:
            with self._cond:
                idle_work = (self._idle is not None and not self._idle_done
                             and not self._has_pending and not self._stop)
            if idle_work:
                try:
                    more = bool(self._idle(self.is_stale))
                except Exception:  # noqa: BLE001 - background work is optional
                    traceback.print_exc()
                    more = False
                if not more:
                    with self._cond:
                        self._idle_done = True
                continue
            with self._cond:
                self._cond.wait_for(lambda: self._has_pending or self._stop)
                if self._stop:
                    return
                request = self._pending
                self._pending = None
                self._has_pending = False
                self._busy = True
            try:
                self._handler(request, self.is_stale)
            except BaseException as exc:  # noqa: BLE001 - the worker must survive
                if self._on_error is not None:
                    try:
                        self._on_error(exc)
                    except Exception:  # noqa: BLE001
                        traceback.print_exc()
                else:
                    traceback.print_exc()
            finally:
                with self._cond:
                    self._busy = False
                    self._finished += 1
                    self._cond.notify_all()
