"""Memory is part of correctness: estimate an allocation before making it, and refuse
with a clear message what cannot fit.

Linux overcommits memory, so a ``MemoryError`` often never comes: the kernel kills
the process instead. Every allocation that grows with the input or with a user's
setting (grid size, spacing, lag, upload) is estimated first and checked here.

>>> format_bytes(3 * 2**30)
'3.0 GiB'
>>> require(1024, "a tiny array")   # fits: returns quietly
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

from rough_viewer.vocabulary import InputError

#: Share of the available memory one request may take: the rest is left for the
#: interpreter, the other arrays alive at the time and the rest of the machine.
USABLE_SHARE = 0.8


def available_bytes() -> float | None:
    """Memory available to this process now, in bytes, or None when unknown.

    The smaller of the machine's available memory (``MemAvailable`` in
    ``/proc/meminfo``) and the room left under a cgroup memory limit.
    """
    candidates: list[float] = []
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    candidates.append(float(line.split()[1]) * 1024.0)
                    break
    except OSError:
        pass
    for limit_file, usage_file in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"),
    ):
        try:
            with open(limit_file) as fh:
                limit_text = fh.read().strip()
            with open(usage_file) as fh:
                usage = float(fh.read().strip())
        except (OSError, ValueError):
            continue
        if limit_text != "max" and float(limit_text) < 2**60:
            candidates.append(max(0.0, float(limit_text) - usage))
        break
    if not candidates:
        try:
            candidates.append(float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")))
        except (ValueError, OSError, AttributeError):
            return None
    return min(candidates)


def format_bytes(n: float) -> str:
    """``n`` bytes as text in the largest fitting binary unit."""
    for unit, size in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{n:.0f} B"


def require(n_bytes: float, what: str, *, hint: str = "") -> None:
    """Raise InputError unless ``n_bytes`` fit in the usable share of the available
    memory.

    Parameters
    ----------
    n_bytes : float
        Estimated size of the allocation (all its arrays at their peak), bytes.
    what : str
        What needs it, for the message (e.g. ``"the semivariogram of grid 0.02 m"``).
    hint : str, optional
        What the user can do about it (e.g. ``"choose a larger grid size"``).
    """
    avail = available_bytes()
    if avail is None:
        return
    if n_bytes > USABLE_SHARE * avail:
        tail = f"; {hint}" if hint else ""
        raise InputError(
            f"{what} needs about {format_bytes(n_bytes)}, more than the "
            f"{format_bytes(avail)} of memory available{tail}"
        )


_LIBC: ctypes.CDLL | None | bool = False  # False: not looked up yet


def give_back() -> bool:
    """Return the heap's free memory to the system (glibc's ``malloc_trim(0)``);
    False where there is no glibc.

    Freed memory stays in the process's heap until the allocator trims it: a browser
    tab that connects and leaves frees its scene messages (megabytes) in pieces that
    glibc keeps, so a server's RSS crept ~0.8 MB a tab (100 tabs: +70 MB) with no
    Python object left behind; one trim gave it all back. Call it after freeing much
    (a tab gone, a cloud replaced); it takes milliseconds.
    """
    global _LIBC
    if _LIBC is False:
        name = ctypes.util.find_library("c")
        try:
            libc = ctypes.CDLL(name) if name else None
            _LIBC = libc if libc is not None and hasattr(libc, "malloc_trim") else None
        except OSError:
            _LIBC = None
    if not isinstance(_LIBC, ctypes.CDLL):
        return False
    _LIBC.malloc_trim(0)
    return True
