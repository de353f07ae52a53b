"""The decode cache: decoded LAZ coordinates kept as ``.npy`` columns, so a second
open of the same file is near-instant.

Entries are keyed by the file's resolved path, size and modification time, and a
format version; a cache that cannot be written is no error. Version 2 (every point
format decoded with its z layer, RGB and reader warnings kept) never serves an entry
written by version 1, whose LAS 1.4 z values could be wrong.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

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


#: Changed whenever what a decode produces changes, so old entries are never served.
CACHE_VERSION = "v2-z-rgb"


def cache_key(p: Path) -> str:
    """Folder name of ``p``'s entry: a hash of its resolved path, size, modification
    time and :data:`CACHE_VERSION`."""
    st = p.stat()
    ident = f"{p.resolve()}|{st.st_size}|{st.st_mtime_ns}|{CACHE_VERSION}"
    return hashlib.sha1(ident.encode()).hexdigest()[:20]


def cache_read(p: Path) -> PointCloud | None:
    folder = cache_dir() / cache_key(p)
    try:
        meta = json.loads((folder / "meta.json").read_text())
        cols = [np.load(folder / f"{c}.npy") for c in "xyz"]
        inten = np.load(folder / "intensity.npy") if meta.get("intensity") else None
        rgb = np.load(folder / "rgb.npy") if meta.get("rgb") else None
    except (OSError, ValueError):
        return None
    return PointCloud(
        x=cols[0], y=cols[1], z=cols[2], intensity=inten, source=str(p),
        dropped_nonfinite=int(meta.get("dropped", 0)), rgb=rgb,
        warnings=tuple(str(w) for w in meta.get("warnings", ())),
    )


def cache_write(p: Path, cloud: PointCloud) -> None:
    root = cache_dir()
    final = root / cache_key(p)
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=".part-", dir=root))
        for c in "xyz":
            np.save(tmp / f"{c}.npy", getattr(cloud, c))
        if cloud.intensity is not None:
            np.save(tmp / "intensity.npy", cloud.intensity)
        if cloud.rgb is not None:
            np.save(tmp / "rgb.npy", cloud.rgb)
        meta = {"source": str(p), "intensity": cloud.intensity is not None,
                "rgb": cloud.rgb is not None, "dropped": cloud.dropped_nonfinite,
                "warnings": list(cloud.warnings), "version": CACHE_VERSION}
        (tmp / "meta.json").write_text(json.dumps(meta))
        try:
            os.replace(tmp, final)
        except OSError:
            shutil.rmtree(tmp, ignore_errors=True)
    except OSError:
        pass  # a cache we cannot write is no error




class CacheWriter:
    """Fills one file's cache entry chunk by chunk, in point order, without holding
    the file's points: each column is a ``.npy`` file whose header is written first
    and whose data are appended (the same entry :func:`cache_write` makes).

    Use :func:`cache_writer` to get one; :meth:`commit` publishes the entry (only if
    exactly ``n`` points were appended), :meth:`abort` drops it.
    """

    def __init__(self, p: Path, n: int, *, intensity: bool, rgb: bool) -> None:
        self.p, self.n, self.done = p, int(n), 0
        root = cache_dir()
        root.mkdir(parents=True, exist_ok=True)
        self._tmp = Path(tempfile.mkdtemp(prefix=".part-", dir=root))
        self._final = root / cache_key(p)
        specs: list[tuple[str, str, tuple[int, ...]]] = [(c, "<f8", (self.n,)) for c in "xyz"]
        if intensity:
            specs.append(("intensity", "<u2", (self.n,)))
        if rgb:
            specs.append(("rgb", "<u2", (self.n, 3)))
        self._files = {}
        for name, descr, shape in specs:
            fh = open(self._tmp / f"{name}.npy", "wb")  # noqa: SIM115 - closed in commit/abort
            np.lib.format.write_array_header_1_0(
                fh, {"descr": descr, "fortran_order": False, "shape": shape})
            self._files[name] = fh

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
        for name, fh in self._files.items():
            col = cols[name]
            if col is None:
                raise ValueError(f"the cache entry has a {name} column")
            dtype = "<f8" if name in "xyz" else "<u2"
            np.ascontiguousarray(col, dtype=dtype).tofile(fh)
        self.done += int(x.shape[0])

    def commit(self, *, dropped: int = 0, warnings: tuple[str, ...] = ()) -> bool:
        """Publish the entry; False (and nothing published) if it is incomplete or
        cannot be written."""
        try:
            for fh in self._files.values():
                fh.close()
            if self.done != self.n:
                raise OSError("incomplete")
            meta = {"source": str(self.p), "intensity": "intensity" in self._files,
                    "rgb": "rgb" in self._files, "dropped": int(dropped),
                    "warnings": list(warnings), "version": CACHE_VERSION}
            (self._tmp / "meta.json").write_text(json.dumps(meta))
            os.replace(self._tmp, self._final)
            return True
        except OSError:
            self.abort()
            return False

    def abort(self) -> None:
        """Drop the partial entry."""
        for fh in self._files.values():
            fh.close()
        shutil.rmtree(self._tmp, ignore_errors=True)


def cache_writer(p: Path, n: int, *, intensity: bool, rgb: bool) -> CacheWriter | None:
    """A :class:`CacheWriter` for ``p``'s entry, or None when the cache folder cannot be
    written or lacks room for it (with 1 GiB to spare)."""
    need = n * (3 * 8 + (2 if intensity else 0) + (6 if rgb else 0))
    try:
        root = cache_dir()
        root.mkdir(parents=True, exist_ok=True)
        if shutil.disk_usage(root).free < need + 2**30:
            return None
        return CacheWriter(p, n, intensity=intensity, rgb=rgb)
    except OSError:
        return None


def cached_points(p: Path) -> int | None:
    """Number of points in ``p``'s complete cache entry, or None when it has none."""
    folder = cache_dir() / cache_key(p)
    try:
        json.loads((folder / "meta.json").read_text())
        return int(np.load(folder / "x.npy", mmap_mode="r").shape[0])
    except (OSError, ValueError):
        return None


def cache_read_slice(p: Path, start: int, stop: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Coordinates ``[start, stop)`` of ``p``'s cache entry (as stored in the file), read
    without loading the rest; None when there is no entry."""
    folder = cache_dir() / cache_key(p)
    try:
        cols = []
        for c in "xyz":
            mm = np.load(folder / f"{c}.npy", mmap_mode="r")
            cols.append(np.array(mm[start:stop]))
            del mm
    except (OSError, ValueError):
        return None
    return cols[0], cols[1], cols[2]
