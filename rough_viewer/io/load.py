"""Reading point clouds from files, and writing LAS/LAZ.

Supported inputs (by file extension):

- ``.las``, ``.laz``: laspy, read in chunks; LAZ decoded with the parallel lazrs
  backend and its decoded coordinates cached (see :func:`cache_dir`), so a second
  open is near-instant. Intensity is kept.
- ``.xyz``, ``.txt``, ``.csv``, ``.pts``: whitespace- or comma-separated ``x y z``,
  extra columns ignored, an optional header line.
- ``.npy``: an (N, 3) (or wider: the first three columns) numeric array.
- ``.ply``: ASCII or binary (either endianness) vertex ``x``, ``y``, ``z``.
- ``.stl``: ASCII or binary; the mesh's vertices, each once.

Rows with NaN or infinite coordinates are dropped and counted
(:attr:`PointCloud.dropped_nonfinite`). Every problem raises
:class:`rough_viewer.vocabulary.InputError` with the file's name.
"""

from __future__ import annotations

import os
from pathlib import Path

from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.las import read_las
from rough_viewer.io.ply import read_ply
from rough_viewer.io.stl import read_stl
from rough_viewer.io.text import read_npy, read_text
from rough_viewer.vocabulary import InputError, ProgressFn

TEXT_SUFFIXES = (".xyz", ".txt", ".csv", ".pts")
SUPPORTED_SUFFIXES = (".las", ".laz", *TEXT_SUFFIXES, ".npy", ".ply", ".stl")


def load_points(
    path: str | os.PathLike[str], *, progress: ProgressFn | None = None, cache: bool = True
) -> PointCloud:
    """Read a point cloud file.

    Parameters
    ----------
    path : path-like
        A ``.las .laz .xyz .txt .csv .pts .npy .ply .stl`` file.
    progress : callable, optional
        ``progress(done, total)`` in points, for LAS/LAZ files.
    cache : bool
        Use (and fill) the decoded-coordinate cache for LAZ files.

    Returns
    -------
    PointCloud

    Raises
    ------
    InputError
        Missing or unreadable file, unknown extension, malformed content, fewer than
        3 finite points.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "face.xyz").write_text("x y z\\n0 0 0\\n1 0 0\\n0 1 0.01\\n1 1 nan\\n")
    >>> cloud = load_points(folder / "face.xyz")
    >>> cloud.n, cloud.dropped_nonfinite
    (3, 1)
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise InputError(
            f"unknown file type {p.suffix or '(none)'!r} for {p}; "
            f"supported: {' '.join(SUPPORTED_SUFFIXES)}"
        )
    if not p.exists():
        raise InputError(f"file not found: {p}")
    if not p.is_file():
        raise InputError(f"not a file: {p}")
    if not os.access(p, os.R_OK):
        raise InputError(f"cannot read {p}: permission denied")
    try:
        if suffix in (".las", ".laz"):
            return read_las(p, progress=progress, cache=cache and suffix == ".laz")
        if suffix in TEXT_SUFFIXES:
            return read_text(p)
        if suffix == ".npy":
            return read_npy(p)
        if suffix == ".ply":
            return read_ply(p)
        return read_stl(p)
    except InputError:
        raise
    except MemoryError:
        raise InputError(f"not enough memory to read {p}") from None
    except (OSError, ValueError, EOFError, KeyError, IndexError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read {p}: {msg}") from None
    except Exception as exc:  # laspy raises its own error types
        if type(exc).__module__.startswith("laspy") or "Laz" in type(exc).__name__:
            msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise InputError(f"cannot read {p}: {msg}") from None
        raise


