"""A small text progress bar for the command line (stderr), with no dependency.

Core functions take ``progress: Callable[[int, int], None] | None`` and call it
with (done, total); this module turns such calls into a bar.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class ProgressBar:
    """Callable progress bar: ``bar(done, total)`` redraws at most 10 times a second.

    Draws only on a terminal; when the stream is redirected to a file or pipe the bar
    stays silent, so logs hold no carriage-return clutter.
    """

    def __init__(self, label: str, *, stream: TextIO | None = None, width: int = 30) -> None:
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self._last = 0.0
        self._start = time.perf_counter()
        self._done = False
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = bool(isatty and isatty())

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        finished = total > 0 and done >= total
        if not finished and now - self._last < 0.1:
            return
        self._last = now
        frac = 0.0 if total <= 0 else min(1.0, done / total)
        filled = int(round(frac * self.width))
        bar = "#" * filled + "-" * (self.width - filled)
        elapsed = now - self._start
        self.stream.write(f"\r{self.label} [{bar}] {frac * 100:5.1f}% {elapsed:6.1f} s")
        if finished and not self._done:
            self._done = True
            self.stream.write("\n")
        self.stream.flush()


def null_progress(done: int, total: int) -> None:
    """A progress callback that does nothing."""
