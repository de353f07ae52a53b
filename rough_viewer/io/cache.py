"""The decode cache: decoded LAZ coordinates kept as ``.npy`` columns, so a second
open of the same file is near-instant; a store that cannot lie.

- **Key**: an entry belongs to the file's resolved path, size, modification time,
  a checksum of its first and last 64 KiB (the LAS header, the VLRs, the chunk
  table and the EVLRs: an in-place header edit that kept the time misses) and the
  format version :data:`CACHE_VERSION`.
- **Validated on read**: ``meta.json`` must parse and describe every column (type,
  shape, the file's exact size), the columns must have one length, and each block
  of :data:`BLOCK_ROWS` rows must match its CRC-32. A damaged entry (a power loss
  left a column of 0 bytes, a disk flipped a bit, someone edited it) is dropped and
  the file decoded again, with a one-line notice on the cloud
  (:func:`cache_lookup`).
- **Written safely**: every file is fsynced, then its folder, before the entry is
  renamed into place (and the cache folder fsynced); an entry is only written when
  the disk keeps :func:`disk_reserve` free beyond it; a write that fails (a full
  disk) or is interrupted leaves nothing behind, and temporary ``.part-<pid>-``
  folders of processes that died are swept.
- **Bounded**: at most ``ROUGH_VIEWER_CACHE_MB`` megabytes (default
  :data:`DEFAULT_CACHE_MB`); the least recently used entries go first.

A cache that cannot be written is no error. Version 3 (checksums) never serves an
entry of version 2 or 1.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
import time
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from rough_viewer.io.cloud import PointCloud


def cache_dir() -> Path:
    """Folder of the LAZ decode cache: ``$ROUGH_VIEWER_CACHE`` or
    ``$XDG_CACHE_HOME/rough_viewer`` (default ``~/.cache/rough_viewer``)."""
    env = os.environ.get("ROUGH_VIEWER_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "rough_viewer"


#: Changed whenever what a decode produces or an entry holds changes, so old
#: entries are never served.
CACHE_VERSION = "v3-checked"
#: Size cap of the cache unless ``ROUGH_VIEWER_CACHE_MB`` says otherwise, megabytes.
DEFAULT_CACHE_MB = 4096
#: Rows per checksummed block of a column.
BLOCK_ROWS = 1 << 20
#: Bytes of the file's start and end in its key.
KEY_BYTES = 64 << 10
#: A ``.part-`` folder older than this is swept even if its process lives, seconds.
STALE_PART_S = 86_400.0

#: Columns an entry may hold: name -> (dtype, values per row).
COLUMNS: dict[str, tuple[str, int]] = {
    "x": ("<f8", 1), "y": ("<f8", 1), "z": ("<f8", 1),
    "intensity": ("<u2", 1), "rgb": ("<u2", 3),
}


def cache_limit_bytes() -> int:
    """The cache's size cap: ``ROUGH_VIEWER_CACHE_MB`` megabytes (0 turns the cache
    off), default :data:`DEFAULT_CACHE_MB`."""
    env = os.environ.get("ROUGH_VIEWER_CACHE_MB", "").strip()
    try:
        mb = float(env) if env else float(DEFAULT_CACHE_MB)
    except ValueError:
        mb = float(DEFAULT_CACHE_MB)
    return max(0, int(mb * 1e6))


def disk_reserve(total_bytes: int) -> int:
    """Bytes the cache leaves free on its disk beyond an entry: 10 % of the disk,
    at least 64 MiB, at most 1 GiB.

    >>> disk_reserve(100 << 30) == 1 << 30, disk_reserve(100 << 20) == 64 << 20
    (True, True)
    """
    return int(min(1 << 30, max(64 << 20, 0.1 * total_bytes)))


def _file_digest(p: Path, size: int) -> str:
    h = hashlib.sha1()
    with open(p, "rb") as fh:
        h.update(fh.read(KEY_BYTES))
        if size > KEY_BYTES:
            fh.seek(max(KEY_BYTES, size - KEY_BYTES))
            h.update(fh.read(KEY_BYTES))
    return h.hexdigest()


def cache_key(p: Path) -> str:
    """Folder name of ``p``'s entry: a hash of its resolved path, size, modification
    time, its first and last :data:`KEY_BYTES` and :data:`CACHE_VERSION`."""
    st = p.stat()
    ident = (f"{p.resolve()}|{st.st_size}|{st.st_mtime_ns}|{_file_digest(p, st.st_size)}"
             f"|{CACHE_VERSION}")
    return hashlib.sha1(ident.encode()).hexdigest()[:20]


# ----------------------------------------------------------------------------- checking


def read_npy_header(fh: BinaryIO) -> tuple[tuple[int, ...], bool, np.dtype]:
    """``(shape, fortran_order, dtype)`` of the ``.npy`` file open at its start in
    ``fh``, which is left at the data.

    Raises ValueError (or EOFError) for a file that is not one."""
    from numpy.lib import format as npf

    version = npf.read_magic(fh)
    if version == (1, 0):
        shape, fortran, dtype = npf.read_array_header_1_0(fh)
    else:
        shape, fortran, dtype = npf.read_array_header_2_0(fh)
    return tuple(shape), bool(fortran), dtype


class Damaged(Exception):
    """A cache entry that does not hold what its ``meta.json`` says (the reason)."""


def _crc(data: np.ndarray) -> int:
    return zlib.crc32(np.ascontiguousarray(data).data.cast("B"))


def block_crcs(col: np.ndarray) -> list[int]:
    """CRC-32 of each block of :data:`BLOCK_ROWS` rows of ``col``."""
    return [_crc(col[i:i + BLOCK_ROWS]) for i in range(0, col.shape[0], BLOCK_ROWS)]


@dataclass(frozen=True)
class _Entry:
    folder: Path
    n: int
    meta: dict[str, Any]
    offsets: dict[str, int]
    """Byte where each column's data start in its ``.npy`` file."""


def _check(folder: Path) -> _Entry:
    """The entry in ``folder`` after checking its structure (not yet its checksums).

    Raises FileNotFoundError when there is no entry, Damaged when it is broken."""
    try:
        text = (folder / "meta.json").read_text()
    except FileNotFoundError:
        if folder.is_dir():
            raise Damaged("its meta.json is missing") from None
        raise
    except (OSError, UnicodeDecodeError) as exc:
        raise Damaged(f"its meta.json cannot be read ({exc})") from None
    try:
        meta = json.loads(text)
    except ValueError:
        raise Damaged("its meta.json is not valid JSON") from None
    if not isinstance(meta, dict) or meta.get("version") != CACHE_VERSION:
        raise Damaged("its meta.json is not of this version")
    n, columns = meta.get("n"), meta.get("columns")
    if not isinstance(n, int) or n < 0 or not isinstance(columns, dict) \
            or not {"x", "y", "z"} <= set(columns) or not set(columns) <= set(COLUMNS):
        raise Damaged("its meta.json does not describe the columns")
    if not isinstance(meta.get("dropped", 0), int) or not isinstance(meta.get("warnings", []), list):
        raise Damaged("its meta.json is malformed")
    offsets: dict[str, int] = {}
    blocks = -(-n // BLOCK_ROWS)
    for name, crcs in columns.items():
        dtype, width = COLUMNS[name]
        if not isinstance(crcs, list) or len(crcs) != blocks \
                or not all(isinstance(c, int) for c in crcs):
            raise Damaged(f"its meta.json lacks the checksums of {name}")
        path = folder / f"{name}.npy"
        try:
            size = path.stat().st_size
            with open(path, "rb") as fh:
                shape, fortran, dt = read_npy_header(fh)
                offset = fh.tell()
        except FileNotFoundError:
            raise Damaged(f"{name}.npy is missing") from None
        except (OSError, ValueError, EOFError, SyntaxError) as exc:
            raise Damaged(f"{name}.npy is not a NumPy file ({str(exc)[:80] or 'empty'})") \
                from None
        want = (n,) if width == 1 else (n, width)
        if dt != np.dtype(dtype) or tuple(shape) != want or fortran:
            raise Damaged(f"{name}.npy holds {dt} {tuple(shape)}, not {np.dtype(dtype)} {want}")
        if size != offset + n * width * np.dtype(dtype).itemsize:
            raise Damaged(f"{name}.npy is {size:,} bytes, not the "
                          f"{offset + n * width * np.dtype(dtype).itemsize:,} its header needs")
        offsets[name] = offset
    return _Entry(folder=folder, n=n, meta=meta, offsets=offsets)


def _load(entry: _Entry, name: str, start: int = 0, stop: int | None = None) -> np.ndarray:
    """Rows ``[start, stop)`` of one column, their blocks checked against their CRCs
    (whole blocks are read and checked, then cut)."""
    dtype, width = COLUMNS[name]
    stop = entry.n if stop is None else min(stop, entry.n)
    first, last = start // BLOCK_ROWS, max(start, stop - 1) // BLOCK_ROWS
    lo, hi = first * BLOCK_ROWS, min(entry.n, (last + 1) * BLOCK_ROWS)
    row_bytes = np.dtype(dtype).itemsize * width
    shape: tuple[int, ...] = (hi - lo,) if width == 1 else (hi - lo, width)
    with open(entry.folder / f"{name}.npy", "rb") as fh:
        fh.seek(entry.offsets[name] + lo * row_bytes)
        data = np.fromfile(fh, dtype=dtype, count=(hi - lo) * width).reshape(shape)
    if data.shape[0] != hi - lo:
        raise Damaged(f"{name}.npy ended early")
    expected = entry.meta["columns"][name][first:last + 1]
    if block_crcs(data) != expected:
        raise Damaged(f"{name}.npy does not match its checksum")
    if lo == start and hi == stop:
        return data
    return np.ascontiguousarray(data[start - lo:stop - lo])


def _drop(folder: Path) -> None:
    shutil.rmtree(folder, ignore_errors=True)
    with contextlib.suppress(OSError):
        folder.unlink()


def _touch(folder: Path) -> None:
    """Mark an entry used now (least-recently-used eviction reads this time)."""
    with contextlib.suppress(OSError):
        os.utime(folder / "meta.json")


# ----------------------------------------------------------------------------- reading


@dataclass(frozen=True)
class CacheLookup:
    """What the cache had for a file."""

    cloud: PointCloud | None
    """The cached points (coordinates as stored in the file), or None."""
    notice: str | None = None
    """One line when a damaged entry was found and dropped (the file must be decoded
    again), else None."""


def cache_lookup(p: Path) -> CacheLookup:
    """``p``'s entry, checked; a damaged one is dropped with a notice."""
    try:
        folder = cache_dir() / cache_key(p)
    except OSError:
        return CacheLookup(None)
    try:
        entry = _check(folder)
        cols = {name: _load(entry, name) for name in entry.meta["columns"]}
    except FileNotFoundError:
        return CacheLookup(None)
    except Damaged as why:
        _drop(folder)
        return CacheLookup(None, f"the decode cache entry of {p} was damaged ({why}); it was "
                                 "dropped and the file decoded again")
    except OSError:
        return CacheLookup(None)
    _touch(folder)
    meta = entry.meta
    cloud = PointCloud(
        x=cols["x"], y=cols["y"], z=cols["z"], intensity=cols.get("intensity"),
        source=str(p), dropped_nonfinite=int(meta.get("dropped", 0)), rgb=cols.get("rgb"),
        warnings=tuple(str(w) for w in meta.get("warnings", ())),
    )
    return CacheLookup(cloud)


def cache_read(p: Path) -> PointCloud | None:
    """``p``'s cached points, or None (no entry, or a damaged one, dropped)."""
    return cache_lookup(p).cloud


def cached_points(p: Path) -> int | None:
    """Number of points in ``p``'s complete entry (its structure checked), or None
    when it has none (a damaged one is dropped)."""
    try:
        folder = cache_dir() / cache_key(p)
        return _check(folder).n
    except Damaged:
        _drop(folder)
        return None
    except OSError:
        return None


def cache_read_slice(p: Path, start: int, stop: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Coordinates ``[start, stop)`` of ``p``'s entry (as stored in the file), read
    without loading the rest (the blocks they lie in are checked); None when there is
    no entry or it is damaged (then dropped)."""
    try:
        folder = cache_dir() / cache_key(p)
        entry = _check(folder)
        cols = [_load(entry, c, start, stop) for c in "xyz"]
    except Damaged:
        _drop(folder)
        return None
    except OSError:
        return None
    _touch(folder)
    return cols[0], cols[1], cols[2]


# ----------------------------------------------------------------------------- writing


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def sweep_parts(root: Path) -> None:
    """Remove ``.part-`` folders left by processes that died (or older than
    :data:`STALE_PART_S`)."""
    try:
        entries = list(os.scandir(root))
    except OSError:
        return
    now = time.time()
    for e in entries:
        if not e.name.startswith(".part-"):
            continue
        pid_text = e.name.split("-")[1] if e.name.count("-") >= 2 else ""
        try:
            age = now - e.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue
        if age > STALE_PART_S or not (pid_text.isdigit() and _pid_alive(int(pid_text))):
            _drop(Path(e.path))


def _entries(root: Path) -> Iterator[tuple[float, int, Path]]:
    """(last use, bytes, folder) of every entry."""
    try:
        found = list(os.scandir(root))
    except OSError:
        return
    for e in found:
        if e.name.startswith(".") or not e.is_dir(follow_symlinks=False):
            continue
        size = 0
        try:
            for f in os.scandir(e.path):
                size += f.stat(follow_symlinks=False).st_size
            used = os.stat(os.path.join(e.path, "meta.json")).st_mtime
        except OSError:
            used = 0.0  # no meta.json: damaged, first to go
        yield used, size, Path(e.path)


def make_room(root: Path, need: int, *, keep: Path | None = None) -> bool:
    """Evict least recently used entries until ``need`` more bytes fit under the cap
    (:func:`cache_limit_bytes`) and the disk keeps :func:`disk_reserve` free; False
    (nothing evicted) when they cannot."""
    cap = cache_limit_bytes()
    if need > cap:
        return False
    try:
        usage = shutil.disk_usage(root)
    except OSError:
        return False
    entries = sorted((e for e in _entries(root) if e[2] != keep), key=lambda e: e[0])
    total = sum(e[1] for e in entries)
    reserve = disk_reserve(usage.total)
    # bytes that eviction can give back count towards free space
    if usage.free + total < need + reserve:
        return False
    free = usage.free
    for _used, size, folder in entries:
        if total + need <= cap and free - need >= reserve:
            break
        _drop(folder)
        total -= size
        free += size
    return total + need <= cap and free - need >= reserve


def _entry_bytes(n: int, columns: dict[str, Any]) -> int:
    return sum(n * COLUMNS[c][1] * np.dtype(COLUMNS[c][0]).itemsize + 128 for c in columns) + 4096


class _Column:
    """One ``.npy`` column file written row by row, with its block checksums."""

    def __init__(self, path: Path, name: str, n: int) -> None:
        dtype, width = COLUMNS[name]
        self.dtype, self.width = np.dtype(dtype), width
        self.fh: BinaryIO = open(path, "wb")  # noqa: SIM115 - closed by close()
        np.lib.format.write_array_header_1_0(
            self.fh, {"descr": dtype, "fortran_order": False,
                      "shape": (n,) if width == 1 else (n, width)})
        self.crcs: list[int] = []
        self._crc, self._rows = 0, 0

    def append(self, values: np.ndarray) -> None:
        data = np.ascontiguousarray(values, dtype=self.dtype)
        data = data.reshape(-1) if self.width == 1 else data.reshape(-1, self.width)
        at = 0
        while at < data.shape[0]:
            take = min(BLOCK_ROWS - self._rows, data.shape[0] - at)
            piece = data[at:at + take]
            self._crc = zlib.crc32(np.ascontiguousarray(piece).data.cast("B"), self._crc)
            self._rows += take
            at += take
            if self._rows == BLOCK_ROWS:
                self.crcs.append(self._crc)
                self._crc, self._rows = 0, 0
        data.tofile(self.fh)

    def finish(self) -> None:
        if self._rows:
            self.crcs.append(self._crc)
            self._crc, self._rows = 0, 0
        self.fh.flush()
        os.fsync(self.fh.fileno())
        self.fh.close()

    def close(self) -> None:
        self.fh.close()


class CacheWriter:
    """Fills one file's cache entry chunk by chunk, in point order, without holding
    the file's points: each column is a ``.npy`` file whose header is written first
    and whose data are appended (the same entry :func:`cache_write` makes).

    Use :func:`cache_writer` to get one; :meth:`commit` publishes the entry (only if
    exactly ``n`` points were appended), :meth:`abort` drops it.
    """

    def __init__(self, p: Path, n: int, *, intensity: bool, rgb: bool) -> None:
        self.p, self.n, self.done = p, int(n), 0
        self._root = cache_dir()
        self._root.mkdir(parents=True, exist_ok=True)
        self._final = self._root / cache_key(p)
        self._tmp = Path(tempfile.mkdtemp(prefix=f".part-{os.getpid()}-", dir=self._root))
        names = ["x", "y", "z"] + (["intensity"] if intensity else []) + (["rgb"] if rgb else [])
        self._files: dict[str, _Column] = {}
        try:
            for name in names:
                self._files[name] = _Column(self._tmp / f"{name}.npy", name, self.n)
        except BaseException:
            self.abort()
            raise

    @property
    def columns(self) -> tuple[str, ...]:
        """Columns of the entry (``x``, ``y``, ``z``, then ``intensity``, ``rgb`` where
        the file has them)."""
        return tuple(self._files)

    def append(self, x: np.ndarray, y: np.ndarray, z: np.ndarray,
               intensity: np.ndarray | None = None, rgb: np.ndarray | None = None) -> None:
        """Append the next points (coordinates as stored in the file, before any unit
        conversion)."""
        cols = {"x": x, "y": y, "z": z, "intensity": intensity, "rgb": rgb}
        for name in self._files:
            if cols[name] is None:
                raise ValueError(f"the cache entry has a {name} column")
        if self.done + int(x.shape[0]) > self.n:
            raise ValueError("more points than the entry holds")
        try:
            for name, col in self._files.items():
                col.append(np.asarray(cols[name]))
        except OSError:  # a full disk: no entry
            self.abort()
            raise
        self.done += int(x.shape[0])

    def commit(self, *, dropped: int = 0, warnings: tuple[str, ...] = ()) -> bool:
        """Publish the entry (its files and folder fsynced first); False (and nothing
        published) if it is incomplete or cannot be written."""
        try:
            if self.done != self.n:
                raise OSError("incomplete")
            for col in self._files.values():
                col.finish()
            meta = {"version": CACHE_VERSION, "source": str(self.p), "n": self.n,
                    "columns": {k: c.crcs for k, c in self._files.items()},
                    "dropped": int(dropped), "warnings": [str(w) for w in warnings]}
            with open(self._tmp / "meta.json", "w") as fh:
                json.dump(meta, fh)
                fh.flush()
                os.fsync(fh.fileno())
            _fsync_dir(self._tmp)
            if self._final.exists():  # another process published it meanwhile
                raise OSError("exists")
            os.rename(self._tmp, self._final)
            _fsync_dir(self._root)
            return True
        except OSError:
            self.abort()
            return False
        except BaseException:
            self.abort()
            raise

    def abort(self) -> None:
        """Drop the partial entry."""
        for col in self._files.values():
            col.close()
        _drop(self._tmp)


def cache_writer(p: Path, n: int, *, intensity: bool, rgb: bool) -> CacheWriter | None:
    """A :class:`CacheWriter` for ``p``'s entry, or None when the cache folder cannot be
    written or lacks room for it (under the size cap, keeping :func:`disk_reserve`
    free; least recently used entries are evicted to make room)."""
    columns = {c: None for c in ["x", "y", "z"] + (["intensity"] if intensity else [])
               + (["rgb"] if rgb else [])}
    try:
        root = cache_dir()
        root.mkdir(parents=True, exist_ok=True)
        sweep_parts(root)
        if not make_room(root, _entry_bytes(n, columns)):
            return None
        return CacheWriter(p, n, intensity=intensity, rgb=rgb)
    except OSError:
        return None


def cache_write(p: Path, cloud: PointCloud) -> None:
    """Keep ``cloud`` (coordinates as stored in the file) as ``p``'s entry, if there
    is room; a cache that cannot be written is no error."""
    writer = cache_writer(p, cloud.n, intensity=cloud.intensity is not None,
                          rgb=cloud.rgb is not None)
    if writer is None:
        return
    try:
        writer.append(cloud.x, cloud.y, cloud.z, intensity=cloud.intensity, rgb=cloud.rgb)
    except (OSError, ValueError):
        writer.abort()
        return
    writer.commit(dropped=cloud.dropped_nonfinite, warnings=tuple(cloud.warnings))
