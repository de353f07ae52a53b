"""The decode cache: decoded LAZ coordinates kept as ``.npy`` columns, so a second
open of the same file is near-instant.

Entries are keyed by the file's resolved path, size and modification time, and a
format version; a cache that cannot be written is no error.
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


def cache_key(p: Path) -> str:
    st = p.stat()
    ident = f"{p.resolve()}|{st.st_size}|{st.st_mtime_ns}|v1"
    return hashlib.sha1(ident.encode()).hexdigest()[:20]


def cache_read(p: Path) -> PointCloud | None:
    folder = cache_dir() / cache_key(p)
    try:
        meta = json.loads((folder / "meta.json").read_text())
        cols = [np.load(folder / f"{c}.npy") for c in "xyz"]
        inten = np.load(folder / "intensity.npy") if meta.get("intensity") else None
    except (OSError, ValueError):
        return None
    return PointCloud(
        x=cols[0], y=cols[1], z=cols[2], intensity=inten, source=str(p),
        dropped_nonfinite=int(meta.get("dropped", 0)),
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
        meta = {"source": str(p), "intensity": cloud.intensity is not None,
                "dropped": cloud.dropped_nonfinite}
        (tmp / "meta.json").write_text(json.dumps(meta))
        try:
            os.replace(tmp, final)
        except OSError:
            shutil.rmtree(tmp, ignore_errors=True)
    except OSError:
        pass  # a cache we cannot write is no error


