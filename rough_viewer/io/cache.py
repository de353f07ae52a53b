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


