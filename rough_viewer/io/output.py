"""Safe output files: check a path before any work, then write through a temporary
file in the same folder and rename, so an error or interrupt never leaves a
half-written file and nothing is overwritten unless asked."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from rough_viewer.vocabulary import InputError


def check_output_path(path: str | os.PathLike[str], *, force: bool) -> Path:
    """Check that ``path`` can be written: its folder exists and, unless ``force``,
    the file does not. Call before any work so nothing is computed in vain."""
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"output folder does not exist: {parent} (for {p})")
    if p.is_dir():
        raise InputError(f"output path is a folder: {p}")
    if p.exists() and not force:
        raise InputError(f"output file exists: {p} (use --force to overwrite)")
    return p


def write_path_atomic(path: str | os.PathLike[str], write_to: Callable[[Path], None]) -> None:
    """Make a file through a temporary file in the same folder, then rename it, so an
    error or interrupt never leaves a half-written output.

    ``write_to`` receives the temporary path (it ends with ``path``'s suffix, so
    writers that choose a format by suffix, such as LAS/LAZ, work) and writes the
    whole file there. The result gets the usual umask permissions.
    """
    p = Path(path)
    parent = p.parent if str(p.parent) else Path(".")
    fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=f".part{p.suffix}", dir=parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        write_to(tmp)
        # mkstemp makes the file private (0600); give it the usual umask permissions
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, p)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: str | os.PathLike[str], write: Callable[[object], None], *, mode: str = "w") -> None:
    """Write a file atomically (see :func:`write_path_atomic`); ``write`` receives the
    open file object."""
    kwargs = {"newline": ""} if "b" not in mode else {}

    def write_to(tmp: Path) -> None:
        with open(tmp, mode, **kwargs) as fh:
            write(fh)

    write_path_atomic(path, write_to)
