"""The benchmarks' one timing helper: the median wall-clock seconds of several runs."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any


def median_seconds(fn: Callable[[], Any], repeat: int, *,
                   warm_up: bool = False) -> tuple[float, Any]:
    """Median wall-clock seconds of ``repeat`` calls of ``fn`` (after one untimed call
    with ``warm_up``: plans, caches, compiled kernels), and what its last call returned.

    >>> seconds, out = median_seconds(lambda: 6 * 7, 3)
    >>> out, seconds >= 0.0
    (42, True)
    """
    if warm_up:
        fn()
    times, out = [], None
    for _ in range(max(1, int(repeat))):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out
