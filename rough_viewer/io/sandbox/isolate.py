"""Untrusted decoding in a child process, so that a bad file never takes the
process that reads it down (issue 21).

The decoders of LAS/LAZ (lazrs), E57 (libE57Format), PLY, STL and text clouds run
native code on bytes anyone can craft: a LAZ chunk of 0xFF bytes sends lazrs into
endless recursion (SIGSEGV), a chunk table that claims 0xFFFFFFFF chunks makes it
allocate 64 GiB and abort, an E57 whose XML nests 160,000 levels deep keeps
libE57Format busy for a minute, then crashes. In a server every browser would lose
it. So each read runs in a child process of our own module
(``python -m rough_viewer.io.sandbox._child``, started with :mod:`subprocess`: a fresh
interpreter, safe however many threads the parent runs, no pickled functions):

- **memory**: the child sets ``RLIMIT_AS`` to its own size after start-up plus the
  read's budget (:class:`Limits`, from the reader's measured estimate with margin,
  :mod:`rough_viewer.io.estimates`) and a fixed allowance for thread stacks, malloc
  arenas and late imports (:data:`CHILD_ALLOWANCE`), so a decoder that asks for
  more fails inside the child;
- **time**: a wall-clock limit (:func:`time_limit`, ``ROUGH_VIEWER_READ_SECONDS``);
- **cancellation**: the parent calls the caller's ``progress(done, total)`` while
  it waits (the app's jobs pass one that raises when the job is cancelled) and
  kills the child when it raises; Ctrl-C and SIGTERM kill it too, and the child
  dies with its parent process (``PR_SET_PDEATHSIG``, every child started from one
  thread that lives as long as the process: :func:`spawn`);
- **results**: the points come back through shared memory (a ``memfd`` the child
  fills and passes over a Unix socket, mapped by the parent without a copy), never
  a pickle; the parent checks every array's type, shape and place before use;
- **failures**: a crash, an abort, a limit or any error in the child is one
  :class:`~rough_viewer.vocabulary.InputError` line naming the file and what
  happened ("the E57 reader crashed (signal 11, SIGSEGV) on pump.e57; the file is
  damaged or not E57").

A child is started ahead of need (:func:`warm`) so that its interpreter and
imports (about 0.15 s) overlap the parent's own start-up; a server keeps one spare.
Where the platform lacks what this needs (Linux's ``memfd``, ``SOCK_SEQPACKET``,
``RLIMIT_AS``), or ``ROUGH_VIEWER_ISOLATE=0``, readers run in-process as before.
"""

from __future__ import annotations

import atexit
import dataclasses
import json
import mmap
import os
import queue
import selectors
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Generator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from rough_viewer.io.cloud import PointCloud
from rough_viewer.memory import format_bytes
from rough_viewer.vocabulary import InputError, ProgressFn

#: The child's module (``python -m``).
CHILD_MODULE = "rough_viewer.io.sandbox._child"
#: Address space a child may use beyond its size after start-up and the read's own
#: budget: thread stacks (8 MiB each), malloc arenas (at most
#: :data:`MALLOC_ARENAS`, 64 MiB of address space each) and modules imported late
#: (pye57, plyfile).
CHILD_ALLOWANCE = 384 << 20
#: Address space per CPU on top (a decoder's worker threads: stack and buffers).
CHILD_ALLOWANCE_PER_CPU = 24 << 20
#: malloc arenas of a child (``MALLOC_ARENA_MAX``), bounding its reserved address space.
MALLOC_ARENAS = 4
#: Wall-clock limit of a read: this many seconds ...
TIME_BASE_S = 60.0
#: ... plus this many per MB of file (1 MB/s is far slower than any reader).
TIME_PER_MB_S = 1.0
#: Largest message between parent and child (JSON, without the points), bytes.
MAX_MESSAGE = 1 << 20
#: Arrays in shared memory start at multiples of this, bytes.
ALIGN = 64
#: How often the parent wakes while it waits (cancellation, limits), seconds.
POLL_S = 0.1
#: How often the caller's progress callback is called while nothing changes, seconds.
PROGRESS_EVERY_S = 0.5

#: Signal names for messages.
_SIGNALS = {int(s): s.name for s in signal.Signals}


@dataclass(frozen=True)
class Limits:
    """What one isolated read may use."""

    memory: float
    """Bytes of address space the read may add to the child (its budget)."""
    seconds: float
    """Wall-clock limit, seconds."""
    capped: bool = False
    """True when :attr:`memory` was cut to the memory available (the message then
    says the machine lacked memory rather than that the file is crafted)."""


#: Share of a read's memory estimate added as margin to its budget ...
MARGIN = 1.5
#: ... and the least budget of any read, bytes.
BUDGET_FLOOR = 256 << 20


def limits_for(need: float, size_bytes: float) -> Limits:
    """The limits of a read expected to need ``need`` bytes at its peak, of a file of
    ``size_bytes``: the estimate with :data:`MARGIN`, at least :data:`BUDGET_FLOOR`
    beyond it, and :func:`time_limit`."""
    return Limits(memory=max(MARGIN * need, need + BUDGET_FLOOR), seconds=time_limit(size_bytes))


def time_limit(size_bytes: float) -> float:
    """Seconds a read of a file of ``size_bytes`` may take: ``ROUGH_VIEWER_READ_SECONDS``
    when set, else :data:`TIME_BASE_S` plus :data:`TIME_PER_MB_S` per MB.

    >>> time_limit(200e6)
    260.0
    """
    env = os.environ.get("ROUGH_VIEWER_READ_SECONDS")
    if env:
        try:
            value = float(env)
        except ValueError:
            raise InputError(f"ROUGH_VIEWER_READ_SECONDS must be a number of seconds, "
                             f"got {env!r}") from None
        if value > 0:
            return value
    return TIME_BASE_S + TIME_PER_MB_S * float(size_bytes) / 1e6


def available() -> bool:
    """Whether reads can be isolated here (Linux: ``memfd``, ``SOCK_SEQPACKET``,
    ``RLIMIT_AS``), and ``ROUGH_VIEWER_ISOLATE`` is not ``0``."""
    if os.environ.get("ROUGH_VIEWER_ISOLATE", "1").strip() in ("0", "no", "false", "off"):
        return False
    try:
        import resource
    except ImportError:
        return False
    return (sys.platform.startswith("linux") and hasattr(os, "memfd_create")
            and hasattr(socket, "SOCK_SEQPACKET") and hasattr(socket, "send_fds")
            and hasattr(resource, "RLIMIT_AS"))


# ----------------------------------------------------------------------------- wire


def send(sock: socket.socket, message: Mapping[str, Any], fd: int | None = None) -> None:
    """Send one JSON message (and a file descriptor) over a SEQPACKET socket."""
    data = json.dumps(message, separators=(",", ":")).encode()
    if len(data) > MAX_MESSAGE:
        raise ValueError(f"message of {len(data):,} bytes")
    if fd is None:
        sock.sendall(data)
    else:
        socket.send_fds(sock, [data], [fd])


def receive(sock: socket.socket) -> tuple[dict[str, Any] | None, list[int]]:
    """One message and the descriptors sent with it; ``(None, [])`` at end of stream.

    Raises ValueError for a message that is not a JSON object or was cut short."""
    data, fds, flags, _ = socket.recv_fds(sock, MAX_MESSAGE, 4)
    if not data and not fds:
        return None, []
    if flags & (getattr(socket, "MSG_TRUNC", 0) | getattr(socket, "MSG_CTRUNC", 0)):
        for fd in fds:
            os.close(fd)
        raise ValueError("message cut short")
    try:
        message = json.loads(data)
    except ValueError:
        message = None
    if not isinstance(message, dict):
        for fd in fds:
            os.close(fd)
        raise ValueError("not a JSON object")
    return message, list(fds)


def pack(arrays: Mapping[str, np.ndarray]) -> tuple[int, list[dict[str, Any]]]:
    """Copy ``arrays`` into a new memfd; returns its descriptor and the layout
    (name, dtype, shape, offset of each) that :func:`unpack` reads."""
    layout: list[dict[str, Any]] = []
    offset = 0
    for name, arr in arrays.items():
        a = np.asarray(arr)
        layout.append({"name": name, "dtype": a.dtype.str, "shape": list(a.shape),
                       "offset": offset})
        offset += -(-a.nbytes // ALIGN) * ALIGN
    fd = os.memfd_create("rough-viewer-points", os.MFD_CLOEXEC)
    try:
        os.ftruncate(fd, max(offset, 1))
        with mmap.mmap(fd, max(offset, 1), flags=mmap.MAP_SHARED,
                       prot=mmap.PROT_READ | mmap.PROT_WRITE) as mm:
            for spec, arr in zip(layout, arrays.values(), strict=True):
                a = np.asarray(arr)
                if a.nbytes:
                    dest = np.frombuffer(mm, dtype=a.dtype, count=a.size,
                                         offset=spec["offset"]).reshape(a.shape)
                    dest[...] = a
                    del dest
    except BaseException:
        os.close(fd)
        raise
    return fd, layout


def unpack(fd: int, layout: object, *, names: frozenset[str] | None = None
           ) -> dict[str, np.ndarray]:
    """The arrays a child packed into ``fd`` (mapped, not copied; the descriptor is
    closed). Every entry is checked: a known name, a plain numeric dtype, a shape of
    non-negative sizes, a place inside the memory.

    Raises ValueError for a layout that does not describe the memory."""
    try:
        size = os.fstat(fd).st_size
        if not isinstance(layout, list):
            raise ValueError("no layout")
        mm = (mmap.mmap(fd, size, flags=mmap.MAP_SHARED | getattr(mmap, "MAP_POPULATE", 0),
                        prot=mmap.PROT_READ | mmap.PROT_WRITE) if size else None)
    finally:
        os.close(fd)
    out: dict[str, np.ndarray] = {}
    for spec in layout:
        if not isinstance(spec, dict):
            raise ValueError("bad layout entry")
        name, shape, offset = spec.get("name"), spec.get("shape"), spec.get("offset")
        if not isinstance(name, str) or (names is not None and name not in names) \
                or name in out:
            raise ValueError(f"unexpected array {name!r}")
        dtype = np.dtype(str(spec.get("dtype")))
        if dtype.kind not in "biuf" or dtype.hasobject or dtype.fields is not None \
                or dtype.subdtype is not None:
            raise ValueError(f"array {name} of type {dtype}")
        if not isinstance(shape, list) or not all(isinstance(s, int) and s >= 0 for s in shape) \
                or not isinstance(offset, int) or offset < 0 or offset % ALIGN:
            raise ValueError(f"array {name} misplaced")
        count = int(np.prod(shape, dtype=np.int64)) if shape else 1
        if offset + count * dtype.itemsize > size:
            raise ValueError(f"array {name} beyond the shared memory")
        if count == 0 or mm is None:
            out[name] = np.zeros(shape, dtype=dtype)
        else:
            out[name] = np.frombuffer(mm, dtype=dtype, count=count, offset=offset).reshape(shape)
    return out


#: PointCloud fields that hold arrays, and those of them with one row per point.
_ARRAY_FIELDS = frozenset(f.name for f in dataclasses.fields(PointCloud) if "ndarray" in str(f.type))
_PER_POINT = ("intensity", "rgb", "scan_index")


def cloud_message(cloud: PointCloud) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """A cloud as arrays (for :func:`pack`) and JSON fields (everything else)."""
    arrays: dict[str, np.ndarray] = {}
    other: dict[str, Any] = {}
    for f in dataclasses.fields(cloud):
        value = getattr(cloud, f.name)
        if isinstance(value, np.ndarray):
            arrays[f.name] = value
        elif isinstance(value, tuple):
            other[f.name] = [str(v)[:2000] for v in value[:200]]
        else:
            other[f.name] = value
    return arrays, other


def cloud_from_message(arrays: dict[str, np.ndarray], other: object) -> PointCloud:
    """Rebuild a cloud from :func:`cloud_message`'s parts, checking what came."""
    if not isinstance(other, dict):
        raise ValueError("no cloud fields")
    known = {f.name: f for f in dataclasses.fields(PointCloud)}
    kwargs: dict[str, Any] = {}
    for name, value in other.items():
        if name not in known or name in _ARRAY_FIELDS and value is not None:
            raise ValueError(f"unexpected cloud field {name!r}")
        if isinstance(value, list):
            if not all(isinstance(v, str) for v in value):
                raise ValueError(f"cloud field {name} is not text")
            value = tuple(value)
        elif value is not None and not isinstance(value, str | int | float | bool):
            raise ValueError(f"cloud field {name} of type {type(value).__name__}")
        kwargs[name] = value
    for name, arr in arrays.items():
        if name not in _ARRAY_FIELDS:
            raise ValueError(f"unexpected array {name!r}")
        kwargs[name] = arr
    cols = [kwargs.get(c) for c in "xyz"]
    if not all(isinstance(c, np.ndarray) and c.ndim == 1 and c.dtype == np.float64
               for c in cols):
        raise ValueError("coordinates are not three float64 columns")
    n = cols[0].shape[0]  # type: ignore[union-attr]
    if any(c.shape[0] != n for c in cols):  # type: ignore[union-attr]
        raise ValueError("coordinate columns of unequal length")
    for name in _PER_POINT:
        per_point = kwargs.get(name)
        if isinstance(per_point, np.ndarray) and per_point.shape[0] != n:
            raise ValueError(f"{name} of {per_point.shape[0]} rows for {n} points")
    return PointCloud(**kwargs)


# ----------------------------------------------------------------------------- children


def _child_env() -> dict[str, str]:
    env = dict(os.environ)
    env.update({
        "MALLOC_ARENA_MAX": str(MALLOC_ARENAS),
        # numpy's BLAS needs no threads of its own in a reader (and each reserves memory)
        "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
        "PYTHONFAULTHANDLER": "1",
        "PYTHONDONTWRITEBYTECODE": "1",
    })
    return env


class _Child:
    """One child process and the parent's end of its socket."""

    def __init__(self) -> None:
        parent, child = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self.sock = parent
        self.stderr: IO[bytes] = tempfile.TemporaryFile(prefix="rough-viewer-reader-")
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", CHILD_MODULE, str(child.fileno()), str(os.getpid())],
                pass_fds=(child.fileno(),), stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL, stderr=self.stderr, env=_child_env(),
                start_new_session=True, close_fds=True)
        except BaseException:
            parent.close()
            self.stderr.close()
            raise
        finally:
            child.close()
        self.killed = False

    def alive(self) -> bool:
        return self.proc.poll() is None

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.killed = True
            try:
                self.proc.kill()
            except OSError:
                pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:  # pragma: no cover - SIGKILL does not wait
            pass

    def close(self) -> None:
        self.kill()
        self.sock.close()
        self.stderr.close()

    def stderr_tail(self, n_bytes: int = 8192) -> str:
        try:
            self.stderr.flush()
            size = self.stderr.seek(0, os.SEEK_END)
            self.stderr.seek(max(0, size - n_bytes))
            return self.stderr.read().decode("utf-8", errors="replace")
        except (OSError, ValueError):
            return ""


class _Launcher:
    """One thread that starts every child and lives as long as this process.

    A child asks Linux to kill it when its parent dies (``PR_SET_PDEATHSIG``), and
    Linux counts the death of the parent THREAD that started it: a spare started by a
    short-lived thread (the one that replenishes the spare, a job's worker) was
    killed as soon as that thread ended (issue 36). Children started here die with
    the process only."""

    def __init__(self) -> None:
        self.pid = os.getpid()
        self.requests: queue.SimpleQueue[tuple[Callable[[], Any], queue.SimpleQueue[Any]]] = \
            queue.SimpleQueue()
        threading.Thread(target=self._run, daemon=True, name="rough-viewer-launcher").start()

    def _run(self) -> None:
        while True:
            make, answer = self.requests.get()
            try:
                answer.put((True, make()))
            except BaseException as exc:  # noqa: BLE001 - the caller re-raises it
                answer.put((False, exc))

    def call(self, make: Callable[[], Any]) -> Any:
        answer: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self.requests.put((make, answer))
        ok, value = answer.get()
        if not ok:
            raise value
        return value


_launcher: _Launcher | None = None
_launcher_lock = threading.Lock()


def spawn() -> _Child:
    """A new child, started from :class:`_Launcher`'s thread."""
    global _launcher
    with _launcher_lock:
        if _launcher is None or _launcher.pid != os.getpid():  # none yet, or a fork
            _launcher = _Launcher()
        launcher = _launcher
    child: _Child = launcher.call(_Child)
    return child


_lock = threading.Lock()
_spare: _Child | None = None
_keep_warm = False


def warm(*, keep: bool = False) -> None:
    """Start a child ahead of the next read, so its start-up (interpreter and
    imports) overlaps the caller's own work; ``keep``: keep one spare after every
    read (a server). Does nothing where reads are not isolated."""
    global _spare, _keep_warm
    if not available():
        return
    with _lock:
        _keep_warm = _keep_warm or keep
        if _spare is not None and _spare.alive():
            return
        old, _spare = _spare, None
    if old is not None:
        old.close()
    child = spawn()
    with _lock:
        if _spare is None:
            _spare = child
            return
    child.close()


def _take() -> _Child:
    global _spare
    with _lock:
        child, _spare = _spare, None
        keep = _keep_warm
    if child is not None and not child.alive():
        child.close()
        child = None
    if child is None:
        child = spawn()
    if keep:
        threading.Thread(target=_replenish, daemon=True, name="rough-viewer-warm").start()
    return child


def _replenish() -> None:
    try:
        warm()
    except OSError:  # pragma: no cover - no spare is no error
        pass


@atexit.register
def _close_spare() -> None:
    global _spare
    with _lock:
        child, _spare = _spare, None
    if child is not None:
        child.close()


# ----------------------------------------------------------------------------- messages


def _signal_name(number: int) -> str:
    name = _SIGNALS.get(number)
    return f"signal {number}, {name}" if name else f"signal {number}"


def memory_message(label: str, path: object, limits: Limits) -> str:
    """The one line for a reader that went past its memory limit.

    >>> memory_message("LAZ", "a.laz", Limits(2**30, 60))
    'the LAZ reader went past its memory limit of 1.0 GiB on a.laz (a file of its size and header needs far less): the file is damaged or crafted; stopped'
    """
    if limits.capped:
        return (f"the {label} reader ran out of memory on {path}: it needed more than the "
                f"{format_bytes(limits.memory)} available")
    return (f"the {label} reader went past its memory limit of {format_bytes(limits.memory)} "
            f"on {path} (a file of its size and header needs far less): the file is damaged "
            "or crafted; stopped")


def death_message(label: str, path: object, returncode: int | None, stderr: str,
                  limits: Limits) -> str:
    """The one line for a child that ended without an answer.

    >>> death_message("E57", "pump.e57", -11, "", Limits(1e9, 60))
    'the E57 reader crashed (signal 11, SIGSEGV) on pump.e57; the file is damaged or not E57'
    """
    out_of_memory = ("memory allocation of" in stderr or "MemoryError" in stderr
                     or "bad_alloc" in stderr or "Cannot allocate memory" in stderr)
    if out_of_memory:
        return memory_message(label, path, limits)
    if returncode == -signal.SIGKILL:
        return f"the {label} reader was killed (out of memory?) on {path}"
    if returncode is not None and returncode < 0:
        return (f"the {label} reader crashed ({_signal_name(-returncode)}) on {path}; the file "
                f"is damaged or not {label}")
    return f"the {label} reader stopped unexpectedly (exit status {returncode}) on {path}"


# ----------------------------------------------------------------------------- parent


class _Session:
    """One request to a child: send it, then wait for answers within the limits."""

    def __init__(self, request: dict[str, Any], *, label: str, path: Path, limits: Limits,
                 progress: ProgressFn | None, expected: int) -> None:
        self.label, self.path, self.limits = label, path, limits
        self.progress = progress
        self.done, self.total = 0, max(0, int(expected))
        self.child = _take()
        self.started = time.monotonic()
        self.deadline = self.started + limits.seconds
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.child.sock, selectors.EVENT_READ)
        self._last_call = 0.0
        try:  # a spare child was forked earlier: it reads relative paths from our folder
            cwd = os.getcwd()
        except OSError:
            cwd = ""
        request = dict(request, memory=int(limits.memory), sys_path=list(sys.path), cwd=cwd)
        try:
            send(self.child.sock, request)
        except OSError:
            pass  # a child that died at start-up: wait() says how
        self._report(force=True)

    def _report(self, *, force: bool = False) -> None:
        if self.progress is None:
            return
        now = time.monotonic()
        if force or now - self._last_call >= PROGRESS_EVERY_S:
            self._last_call = now
            self.progress(self.done, self.total)  # may raise: the caller cancels

    def fail(self, message: str) -> InputError:
        self.child.kill()
        return InputError(message)

    def wait(self) -> tuple[dict[str, Any], list[int]]:
        """The next answer that is not progress (progress goes to the callback)."""
        while True:
            remaining = self.deadline - time.monotonic()
            if remaining <= 0:
                raise self.fail(
                    f"the {self.label} reader took longer than {self.limits.seconds:.0f} s on "
                    f"{self.path} and was stopped; the file may be damaged (a slow disk: set "
                    "ROUGH_VIEWER_READ_SECONDS to allow more)")
            events = self.selector.select(min(POLL_S, remaining))
            if events:
                try:
                    message, fds = receive(self.child.sock)
                except (OSError, ValueError):
                    message, fds = None, []
                if message is None:
                    raise self._died()
                if message.get("t") == "progress":
                    done, total = message.get("done"), message.get("total")
                    if isinstance(done, int) and isinstance(total, int):
                        self.done, self.total = done, total
                        self._report(force=True)
                    continue
                if message.get("t") == "error":
                    for fd in fds:
                        os.close(fd)
                    if message.get("kind") == "memory":
                        raise self.fail(memory_message(self.label, self.path, self.limits))
                    raise self.fail(str(message.get("message") or "")[:2000]
                                    or f"cannot read {self.path}")
                return message, fds
            if not self.child.alive():
                raise self._died()
            self._report()

    def _died(self) -> InputError:
        try:
            self.child.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.child.kill()
        return InputError(death_message(self.label, self.path, self.child.proc.returncode,
                                        self.child.stderr_tail(), self.limits))

    def close(self) -> None:
        self.selector.close()
        self.child.close()


def read_isolated(reader: str, path: str | os.PathLike[str], *, label: str, limits: Limits,
                  progress: ProgressFn | None = None, options: Mapping[str, Any] | None = None,
                  expected: int = 0) -> PointCloud:
    """Run ``reader`` (``"module:function"``, called in the child as
    ``function(path, progress=..., **options)`` and returning a
    :class:`~rough_viewer.io.cloud.PointCloud`) on ``path`` in a child process.

    Parameters
    ----------
    reader : str
        The reading function, importable in the child.
    path : path-like
        The file (named in every message).
    label : str
        The format as messages name it (``"LAZ"``, ``"E57"``).
    limits : Limits
        Memory budget and wall-clock limit.
    progress : callable, optional
        ``progress(done, total)``, called with the child's progress and at least every
        :data:`PROGRESS_EVERY_S` while waiting; an exception it raises (a cancelled
        job) kills the child and propagates.
    options : mapping, optional
        More keyword arguments for ``reader`` (JSON values).
    expected : int
        The point count to show before the child reports one (0: unknown).

    Raises
    ------
    InputError
        The reader's own error, or one line saying that it crashed, aborted, ran out
        of its memory limit or its time, naming ``path``.
    """
    p = Path(path)
    session = _Session({"op": "read", "reader": reader, "path": os.fspath(p),
                        "options": dict(options or {})},
                       label=label, path=p, limits=limits, progress=progress,
                       expected=expected)
    try:
        message, fds = session.wait()
        if message.get("t") != "cloud" or len(fds) != 1:
            for fd in fds:
                os.close(fd)
            raise session.fail(f"the {label} reader gave no points for {p}")
        try:
            arrays = unpack(fds[0], message.get("layout"), names=_ARRAY_FIELDS)
            cloud = cloud_from_message(arrays, message.get("fields"))
        except (ValueError, TypeError) as exc:
            raise session.fail(f"the {label} reader gave damaged points for {p} ({exc})") \
                from None
    finally:
        session.close()
    if progress is not None:
        progress(cloud.n, cloud.n)
    return cloud


def stream_isolated(reader: str, path: str | os.PathLike[str], *, label: str,
                    limits: Limits, names: frozenset[str],
                    options: Mapping[str, Any] | None = None, ahead: bool = False
                    ) -> Generator[dict[str, np.ndarray], None, None]:
    """Run the generator ``reader`` (``"module:function"``, called in the child as
    ``function(path, progress=..., **options)`` and yielding mappings of arrays) in a
    child process and yield its items, one at a time: the child makes the next item
    only when the caller asks for it, so one item is held at a time; with ``ahead``
    the child makes the next while the caller works on this one (two at a time, the
    child's decoding beside the caller's work).

    ``limits.seconds`` bounds the wait for each item; ``names`` are the array names
    an item may hold. Closing the iterator early stops the child.

    Raises
    ------
    InputError
        As :func:`read_isolated`.
    """
    p = Path(path)
    session = _Session({"op": "stream", "reader": reader, "path": os.fspath(p),
                        "options": dict(options or {})},
                       label=label, path=p, limits=limits, progress=None, expected=0)
    try:
        while True:
            message, fds = session.wait()
            kind = message.get("t")
            if kind == "end":
                return
            if kind != "item" or len(fds) != 1:
                for fd in fds:
                    os.close(fd)
                raise session.fail(f"the {label} reader gave no points for {p}")
            try:
                item = unpack(fds[0], message.get("layout"), names=names)
            except (ValueError, TypeError) as exc:
                raise session.fail(f"the {label} reader gave damaged points for {p} ({exc})") \
                    from None
            if ahead:
                _ask_next(session, limits)
            yield item
            del item
            if not ahead:
                _ask_next(session, limits)
    finally:
        session.close()


def _ask_next(session: _Session, limits: Limits) -> None:
    session.deadline = time.monotonic() + limits.seconds
    try:
        send(session.child.sock, {"t": "next"})
    except OSError:
        pass  # it died: the next wait says how


def call_isolated(function: str, path: str | os.PathLike[str], *, label: str,
                  limits: Limits, options: Mapping[str, Any] | None = None) -> object:
    """Run ``function`` (``"module:function"``, called in the child as
    ``function(path, **options)``) on ``path`` in a child process and return what it
    returns: a JSON value of at most :data:`MAX_MESSAGE` bytes, which the caller
    must check (what a file's header says, parsed where the file cannot hurt).

    Raises
    ------
    InputError
        As :func:`read_isolated`.
    """
    p = Path(path)
    session = _Session({"op": "call", "reader": function, "path": os.fspath(p),
                        "options": dict(options or {})},
                       label=label, path=p, limits=limits, progress=None, expected=0)
    try:
        message, fds = session.wait()
        for fd in fds:
            os.close(fd)
        if message.get("t") != "value" or fds:
            raise session.fail(f"the {label} reader gave no answer for {p}")
        return message.get("value")
    finally:
        session.close()


def run_reader(reader: str, call: Callable[[], PointCloud], path: str | os.PathLike[str], *,
               isolate: bool, label: str, limits: Limits, progress: ProgressFn | None,
               options: Mapping[str, Any] | None = None, expected: int = 0) -> PointCloud:
    """:func:`read_isolated` when ``isolate`` and :func:`available`, else ``call()`` in
    this process."""
    if isolate and available():
        return read_isolated(reader, path, label=label, limits=limits, progress=progress,
                             options=options, expected=expected)
    return call()
