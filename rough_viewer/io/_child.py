"""The child process of :mod:`rough_viewer.io.isolate`:
``python -m rough_viewer.io._child FD PARENT_PID``.

It imports the common readers' libraries first (so a spare child is ready), then
waits on its socket (descriptor ``FD``) for one request, limits its own address
space, runs the reader and sends the points back in shared memory, or one error
line. It dies with its parent, and exits when the parent's end of the socket closes.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import sys
import time
from pathlib import Path
from typing import Any

#: Imported before the request arrives (the common case: LAS/LAZ, and the readers).
PRELOAD = ("numpy", "laspy", "lazrs", "rough_viewer.io.load")
#: Least time between two progress messages, seconds.
PROGRESS_INTERVAL_S = 0.1


def _die_with_parent(parent_pid: int) -> None:
    """Ask Linux to kill this process when its parent dies (``PR_SET_PDEATHSIG``).

    Linux sends that signal when the parent THREAD that started the child ends, not
    the parent process; so the parent starts every child from one thread that lives
    as long as it does (:func:`rough_viewer.io.isolate.spawn`)."""
    try:
        import ctypes
        import signal

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        pass
    if os.getppid() != parent_pid:  # the parent died before prctl
        os._exit(1)


def _vm_size() -> int:
    """This process's address space now, bytes (``VmSize``)."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    return 0


def _limit_memory(budget: int) -> None:
    import resource

    from rough_viewer.io.isolate import CHILD_ALLOWANCE, CHILD_ALLOWANCE_PER_CPU

    limit = _vm_size() + max(0, budget) + CHILD_ALLOWANCE \
        + CHILD_ALLOWANCE_PER_CPU * (os.cpu_count() or 1)
    resource.setrlimit(resource.RLIMIT_AS, (address_limit(limit), address_limit(limit)))


def address_limit(wanted: int) -> int:
    """``wanted`` bytes of address space, or less: the hard ``RLIMIT_AS`` this
    process inherited (``ulimit -v``) when that is lower, since no process may raise
    its hard limit."""
    import resource

    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    return wanted if hard == resource.RLIM_INFINITY else min(wanted, hard)


def _resolve(ref: str) -> Any:
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


def _error_text(exc: BaseException, path: str) -> tuple[str, str]:
    """(kind, one line) for an exception a reader raised."""
    from rough_viewer.vocabulary import InputError, error_line

    if isinstance(exc, InputError):
        return "input", str(exc)
    if isinstance(exc, MemoryError):
        return "memory", f"not enough memory to read {path}"
    kind = type(exc).__name__
    if kind == "PanicException":  # pyo3 (lazrs) turns a Rust panic into a BaseException
        return "panic", f"cannot read {path}: the decoder failed ({error_line(exc)})"
    return "error", f"cannot read {path}: {error_line(exc)}"


def _serve(sock: Any) -> None:
    from rough_viewer.io import isolate

    request, _ = isolate.receive(sock)
    if request is None:
        return
    for entry in request.get("sys_path", ()):
        if isinstance(entry, str) and entry not in sys.path:
            sys.path.append(entry)
    path = str(request.get("path", ""))
    cwd = request.get("cwd")
    if isinstance(cwd, str) and cwd:
        try:
            os.chdir(cwd)  # the parent's folder now, not the one this child started in
        except OSError:
            pass  # an absolute path still reads; a relative one fails naming the file
    last = [0.0]

    def progress(done: int, total: int) -> None:
        now = time.monotonic()
        if now - last[0] >= PROGRESS_INTERVAL_S or (total > 0 and done >= total):
            last[0] = now
            isolate.send(sock, {"t": "progress", "done": int(done), "total": int(total)})

    try:
        reader = _resolve(str(request["reader"]))
        _limit_memory(int(request.get("memory", 0)))
        options = dict(request.get("options") or {})
        if request.get("op") == "call":  # a small JSON answer (a header's facts)
            isolate.send(sock, {"t": "value", "value": reader(Path(path), **options)})
            return
        if request.get("op") == "stream":
            for item in reader(Path(path), progress=progress, **options):
                fd, layout = isolate.pack(item)
                try:
                    isolate.send(sock, {"t": "item", "layout": layout}, fd)
                finally:
                    os.close(fd)
                del item
                answer, _ = isolate.receive(sock)
                if answer is None or answer.get("t") != "next":
                    return
            isolate.send(sock, {"t": "end"})
            return
        cloud = reader(Path(path), progress=progress, **options)
        arrays, fields = isolate.cloud_message(cloud)
        del cloud
        fd, layout = isolate.pack(arrays)
        del arrays
        try:
            isolate.send(sock, {"t": "cloud", "layout": layout, "fields": fields}, fd)
        finally:
            os.close(fd)
    except BaseException as exc:  # noqa: BLE001 - every failure becomes one line
        kind, text = _error_text(exc, path)
        with contextlib.suppress(OSError):
            isolate.send(sock, {"t": "error", "kind": kind, "message": text[:4000]})


def main(argv: list[str]) -> int:
    import socket

    fd, parent = int(argv[1]), int(argv[2])
    _die_with_parent(parent)
    for name in PRELOAD:
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
    sock = socket.socket(fileno=fd)
    try:
        _serve(sock)
    finally:
        with contextlib.suppress(OSError):
            sock.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
