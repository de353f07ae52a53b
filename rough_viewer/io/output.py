"""Safe output files, the one module every command and the app write through.

Rules (issue 15, "Safety"):

- check every output before any work (:func:`check_output_path`,
  :func:`check_outputs`), so nothing is computed in vain: the folder exists and is
  writable; an existing file is replaced only with ``force``; an output that is a
  symlink, a device, a pipe or a folder, or that is the input itself (same path, a
  hard link, a symlink to it), is refused; two outputs of one run never share a path;
  a name chosen inside a folder stays in it (:func:`path_in_folder`);
- write through a temporary file in the same folder, fsync it, and rename it
  (:func:`write_path_atomic`, :func:`write_atomic`), so an error, a full disk, an
  interrupt or a power loss never leaves a half-written, empty or temporary file,
  and the old file, if any, stays as it was;
- an output checked without ``force`` is created exclusively: it is published by a
  hard link, which fails if the name exists, so of two runs that both passed the
  "exists" check the second refuses instead of silently replacing the first's file;
- a run with several outputs writes them inside :func:`all_or_nothing`: each file
  is made under a temporary name and all are renamed into place only when the run
  ends without error, so a failed run leaves none of its outputs (not the first of
  two when the second meets a full disk) and every old file as it was;
- a write error (read-only folder, full disk, quota) becomes one
  :class:`~rough_viewer.vocabulary.InputError` line naming the file, never a
  traceback.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from rough_viewer.vocabulary import InputError, error_line

PathLike = str | os.PathLike[str]


@dataclass(frozen=True)
class _Pending:
    """A finished temporary file waiting to be renamed onto ``path``."""

    tmp: Path
    path: Path


#: The files written so far inside the innermost :func:`all_or_nothing`, or None.
_BATCH: ContextVar[list[_Pending] | None] = ContextVar("rough_viewer_output_batch",
                                                         default=None)

#: Outputs checked without ``force`` (absolute paths): published only if they still do
#: not exist (:func:`_publish`), so a second run that passed the same check never
#: replaces the first one's file.
_EXCLUSIVE: set[str] = set()
_EXCLUSIVE_LOCK = threading.Lock()


def _claim(p: Path, exclusive: bool) -> None:
    key = os.path.abspath(p)
    with _EXCLUSIVE_LOCK:
        if exclusive:
            _EXCLUSIVE.add(key)
        else:
            _EXCLUSIVE.discard(key)


def _fsync(path: Path, *, folder: bool = False) -> None:
    """Flush a file (or a folder's entries) to the disk."""
    fd = os.open(path, os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if folder else 0))
    try:
        os.fsync(fd)
    except OSError as exc:
        if not folder or exc.errno not in (errno.EINVAL, errno.EBADF, errno.ENOTSUP):
            raise
    finally:
        os.close(fd)


def _publish(tmp: Path, p: Path) -> None:
    """Rename the finished temporary file ``tmp`` onto ``p``: replacing it when the
    output was checked with ``force`` (or not checked), else only if ``p`` does not
    exist, atomically (a hard link fails when the name is taken; then ``tmp`` goes).

    Raises InputError naming ``p`` when another run made it meanwhile."""
    with _EXCLUSIVE_LOCK:
        exclusive = os.path.abspath(p) in _EXCLUSIVE
    if not exclusive:
        os.replace(tmp, p)
    else:
        try:
            os.link(tmp, p)
        except FileExistsError:
            tmp.unlink(missing_ok=True)
            raise InputError(f"output file exists: {p} (another run wrote it meanwhile; use "
                             "--force to overwrite)") from None
        except OSError as exc:
            if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.EXDEV, errno.EMLINK):
                raise
            # a file system without hard links: the exclusive create is the next best
            fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            os.close(fd)
            os.replace(tmp, p)
        else:
            tmp.unlink(missing_ok=True)
    _fsync(_parent(p), folder=True)


def _parent(p: Path) -> Path:
    return p.parent if str(p.parent) else Path(".")


def _same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name one file (same path after resolving links, or the
    same inode: hard links)."""
    try:
        if a.resolve() == b.resolve():
            return True
    except (OSError, RuntimeError):
        pass
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_output_path(
    path: PathLike,
    *,
    force: bool,
    inputs: Iterable[PathLike] = (),
    folder: PathLike | None = None,
) -> Path:
    """Check that ``path`` can be written; call before any work.

    Parameters
    ----------
    path : path-like
        The output file.
    force : bool
        Whether an existing regular file may be replaced (``--force``).
    inputs : iterable of path-like
        Files the run reads; the output may be none of them.
    folder : path-like, optional
        The folder the user chose for outputs; ``path`` must lie in it.

    Returns
    -------
    Path
        ``path`` as a Path.

    Raises
    ------
    InputError
        One line naming the file: missing or unwritable folder, a folder, symlink,
        device or pipe as output, the input as output, an existing file without
        ``force``, a path outside ``folder``.
    """
    p = Path(path)
    if "\x00" in str(p):
        raise InputError(f"output path contains a NUL character: {p!r}")
    if folder is not None:
        _check_within(folder, p, shown=p)
    parent = _parent(p)
    if not parent.is_dir():
        raise InputError(f"output folder does not exist: {parent} (for {p})")
    if p.is_symlink():
        raise InputError(f"output path is a symbolic link, refused: {p}")
    for source in inputs:
        if _same_file(p, Path(source)):
            raise InputError(f"output path is the input file: {p}")
    if p.exists():
        mode = p.stat().st_mode
        if stat.S_ISDIR(mode):
            raise InputError(f"output path is a folder: {p}")
        if not stat.S_ISREG(mode):
            raise InputError(f"output path is not a regular file (a device or pipe?), refused: {p}")
        if not force:
            raise InputError(f"output file exists: {p} (use --force to overwrite)")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"output folder is not writable: {parent} (for {p})")
    _claim(p, not force)
    return p


def check_outputs(
    paths: Iterable[PathLike],
    *,
    force: bool,
    inputs: Iterable[PathLike] = (),
    folder: PathLike | None = None,
) -> list[Path]:
    """:func:`check_output_path` for every output of one run, and no two the same file.

    Returns the paths in the order given.
    """
    sources = [Path(s) for s in inputs]
    checked: list[Path] = []
    for path in paths:
        p = check_output_path(path, force=force, inputs=sources, folder=folder)
        for other in checked:
            if _same_file(p, other) or os.path.abspath(p) == os.path.abspath(other):
                raise InputError(f"two outputs have the same path: {p}")
        checked.append(p)
    return checked


def path_in_folder(folder: PathLike, name: PathLike) -> Path:
    """``folder / name``, refused unless it lies inside ``folder``.

    For names that come from users or browsers: a name that climbs out (``..``), an
    absolute path elsewhere, or a link inside the folder that points elsewhere is
    refused with one line.
    """
    target = Path(folder) / Path(name)
    _check_within(folder, target, shown=name)
    return target


def _check_within(folder: PathLike, target: Path, *, shown: PathLike) -> None:
    base = Path(folder)
    try:
        base_real = base.resolve()
        target_real = target.parent.resolve() / target.name
    except (OSError, RuntimeError) as exc:
        raise InputError(f"cannot resolve output path {target}: {exc}") from None
    if target.name in ("", ".", "..") or not target_real.is_relative_to(base_real) \
            or target_real == base_real:
        raise InputError(f"output path lies outside the chosen folder {base}: {shown}")


def _reason(exc: OSError) -> str:
    if exc.errno == errno.ENOSPC:
        return "no space left on device"
    if exc.errno == errno.EDQUOT:
        return "disk quota exceeded"
    if exc.errno in (errno.EROFS,):
        return "read-only file system"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    return exc.strerror or str(exc) or type(exc).__name__


def write_path_atomic(path: PathLike, write_to: Callable[[Path], None]) -> None:
    """Make a file through a temporary file in the same folder, then rename it.

    ``write_to`` receives the temporary path (it ends with ``path``'s suffix, so
    writers that choose a format by suffix, such as LAS/LAZ, work) and writes the
    whole file there. On success the file gets the usual umask permissions and
    replaces ``path`` in one step; on any error or interrupt the temporary file is
    removed and ``path`` is left as it was.

    Raises
    ------
    InputError
        One line when the file system refuses (read-only folder, full disk, quota,
        permissions); other errors propagate unchanged (after the clean-up).
    """
    p = Path(path)
    parent = _parent(p)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=f".part{p.suffix}",
                                        dir=parent)
    except OSError as exc:
        raise InputError(f"cannot write {p}: {_reason(exc)}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        try:
            write_to(tmp)
        except Exception as exc:  # a writer that wraps the disk's error in its own type
            cause = _os_error(exc, folder=parent)
            if cause is None:
                raise
            raise cause from None
        # mkstemp makes the file private (0600); give it the usual umask permissions
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        _fsync(tmp)  # the data on the disk before the name: no empty file after a power loss
        batch = _BATCH.get()
        if batch is None:
            _publish(tmp, p)
        else:  # renamed when the batch ends without error
            batch.append(_Pending(tmp, p))
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise InputError(f"cannot write {p}: {_reason(exc)}") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


#: Free bytes under which a folder counts as full when a writer's own error does not
#: say why it failed.
FULL_DISK_BYTES = 1 << 20


def _os_error(exc: BaseException, *, folder: Path | None = None) -> OSError | None:
    """The OSError behind a library's own error (laspy and lazrs wrap a full disk in
    theirs: ``LazrsError: IoError: No space left on device``, or only ``IoError:
    Failed to call write``, when the folder then has less than
    :data:`FULL_DISK_BYTES` free), else None."""
    seen: set[int] = set()
    cur: BaseException | None = exc
    while cur is not None and id(cur) not in seen:
        if isinstance(cur, OSError):
            return cur
        seen.add(id(cur))
        cur = cur.__cause__ or cur.__context__
    text = str(exc)
    for code, phrase in ((errno.ENOSPC, "No space left on device"),
                         (errno.EDQUOT, "Disk quota exceeded"),
                         (errno.EROFS, "Read-only file system")):
        if phrase in text:
            return OSError(code, phrase)
    if "IoError" in text or "Failed to call write" in text:  # lazrs, without the cause
        try:
            full = folder is not None and shutil.disk_usage(folder).free < FULL_DISK_BYTES
        except OSError:
            full = False
        if full:
            return OSError(errno.ENOSPC, "No space left on device")
        return OSError(errno.EIO, f"the writer failed ({error_line(exc)})")
    return None


def write_atomic(path: PathLike, write: Callable[[IO[Any]], object], *, mode: str = "w") -> None:
    """Write a file atomically (see :func:`write_path_atomic`); ``write`` receives the
    open file object (text with ``mode="w"``, bytes with ``mode="wb"``)."""

    def write_to(tmp: Path) -> None:
        fh: IO[Any]
        with (open(tmp, mode) if "b" in mode else open(tmp, mode, newline="")) as fh:
            write(fh)

    write_path_atomic(path, write_to)


@contextmanager
def all_or_nothing() -> Iterator[None]:
    """Make every file written inside the block (through :func:`write_path_atomic` or
    :func:`write_atomic`) appear only if the whole block succeeds.

    Each file is written to a temporary file in its folder as usual, but the renames
    wait for the end of the block: on success all are renamed into place (in the order
    written); on any error or interrupt all temporary files are removed, so a failed
    run leaves none of its outputs and every file it would have replaced unchanged.
    Nested blocks join the outermost one.

    Raises
    ------
    InputError
        One line naming the file when a rename fails (then the outputs already
        renamed by this block are removed too, unless they replaced older files).
    """
    if _BATCH.get() is not None:
        yield
        return
    pending: list[_Pending] = []
    token = _BATCH.set(pending)
    try:
        yield
    except BaseException:
        for item in pending:
            item.tmp.unlink(missing_ok=True)
        raise
    finally:
        _BATCH.reset(token)
    _commit(pending)


def _commit(pending: list[_Pending]) -> None:
    """Rename the temporary files of a batch into place; on a failure remove the
    remaining temporary files and the new files this batch already made."""
    made: list[Path] = []
    for i, item in enumerate(pending):
        existed = item.path.exists()
        try:
            _publish(item.tmp, item.path)
        except (OSError, InputError) as exc:
            for rest in pending[i:]:
                rest.tmp.unlink(missing_ok=True)
            for path in made:
                path.unlink(missing_ok=True)
            if isinstance(exc, InputError):
                raise
            raise InputError(f"cannot write {item.path}: {_reason(exc)}") from None
        if not existed:
            made.append(item.path)
