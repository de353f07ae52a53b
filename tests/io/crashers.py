"""Readers that fail on purpose, for testing the isolation itself (tests/io/test_isolate.py):
the child process imports them by name (``tests.io.crashers:segfault``), the test-only
hook of :func:`rough_viewer.io.sandbox.isolate.read_isolated`. Never imported by the package.
"""

from __future__ import annotations

import ctypes
import os
import signal
import time
from pathlib import Path

import numpy as np

from rough_viewer.io.cloud import PointCloud, finite_cloud
from rough_viewer.vocabulary import InputError, ProgressFn


def segfault(p: Path, *, progress: ProgressFn | None = None) -> PointCloud:
    """Reads address 0: SIGSEGV, as lazrs does on a chunk of 0xFF."""
    ctypes.string_at(0)
    raise AssertionError("unreachable")


def abort(p: Path, *, progress: ProgressFn | None = None) -> PointCloud:
    """SIGABRT, as a failed allocation in Rust does."""
    os.abort()


def allocate(p: Path, *, progress: ProgressFn | None = None, gib: float = 64.0) -> PointCloud:
    """Touches ``gib`` GiB, as lazrs does for a chunk table of 0xFFFFFFFF chunks."""
    block = np.ones(int(gib * 2**30) // 8)
    return finite_cloud(block[:3], block[:3], block[:3], None, p)


def hang(p: Path, *, progress: ProgressFn | None = None) -> PointCloud:
    """Never returns, as libE57Format on XML nested 160,000 levels deep (it reports
    progress once first, and writes its pid next to the file)."""
    p.with_suffix(".pid").write_text(str(os.getpid()))
    if progress is not None:
        progress(1, 10)
    while True:
        time.sleep(1)


def exits(p: Path, *, progress: ProgressFn | None = None) -> PointCloud:
    """Leaves without a word."""
    os._exit(7)


def killed(p: Path, *, progress: ProgressFn | None = None) -> PointCloud:
    """Killed by SIGKILL from outside (what the kernel's OOM killer does)."""
    os.kill(os.getpid(), signal.SIGKILL)
    raise AssertionError("unreachable")


class PanicException(BaseException):
    """What pyo3 raises for a Rust panic (lazrs): a BaseException, not an Exception."""


def panics(p: Path, *, progress: ProgressFn | None = None) -> PointCloud:
    raise PanicException("attempt to calculate the remainder with a divisor of zero")


def refuses(p: Path, *, progress: ProgressFn | None = None) -> PointCloud:
    raise InputError(f"no points in {p}")


def reads(p: Path, *, progress: ProgressFn | None = None, n: int = 1000) -> PointCloud:
    """A good reader: ``n`` points of a known pattern, with every kind of attribute."""
    i = np.arange(n, dtype=np.float64)
    if progress is not None:
        progress(n // 2, n)
    return PointCloud(x=i, y=2 * i, z=-i, intensity=np.arange(n, dtype=np.uint16),
                      source=str(p), dropped_nonfinite=3,
                      rgb=np.stack([np.arange(n, dtype=np.uint16)] * 3, axis=1),
                      scan_index=(np.arange(n) % 2).astype(np.int32),
                      scanner_positions=np.array([[0.0, 0.0, 1.0], [5.0, 0.0, 1.0]]),
                      warnings=("the header of x declares 5 points",))


def chunks(p: Path, *, progress: ProgressFn | None = None, count: int = 3):
    """A stream of ``count`` items of 10 rows each, then the end."""
    for k in range(count):
        yield {"x": np.full(10, float(k)), "y": np.arange(10.0), "z": np.zeros(10)}
