"""Where the app may read files from, and reading them safely.

"Load file" takes a path typed in the browser, so it is restricted to one
folder, the data folder (``--data-dir``; default the folder of the file given to
``serve``, or the current folder): the path is resolved (symbolic links
followed) and refused unless it lies inside. Reading goes through
:func:`rough_viewer.io.load.load_points`, which checks the file's header and its
measured memory estimate first (:mod:`rough_viewer.io.estimates`: a file that
cannot fit, or a decompression bomb beyond ``max_points`` (``serve --max-points``,
:attr:`rough_viewer.app.host.AppOptions.max_points`), is
refused before decoding) and decodes it in a child process
(:mod:`rough_viewer.io.sandbox.isolate`): a damaged or crafted file that crashes its
reader, or runs past its memory or time limit, is one notice, and the server
keeps serving every browser. Error messages name the file as the user gave it and
never carry server paths or text read from the file
(:func:`rough_viewer.app.markup.public_message`).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

from rough_viewer.app.limits import (
    APP_BYTES_PER_POINT,
    APP_CACHE_BYTES_PER_POINT,
    APP_FIXED_BYTES,
    CACHE_BYTES,
)
from rough_viewer.app.markup import public_message
from rough_viewer.io import PointCloud, load_points
from rough_viewer.io.formats.las import check_las_layout
from rough_viewer.io.formats.mesh import TriangleMesh, load_mesh
from rough_viewer.io.load import SUPPORTED_SUFFIXES, reader_for
from rough_viewer.memory import USABLE_SHARE, available_bytes, format_bytes
from rough_viewer.vocabulary import InputError, ProgressFn, Unit


@dataclass(frozen=True)
class DataFolder:
    """The folder "Load file" may read from."""

    root: Path
    """Absolute, resolved."""

    @classmethod
    def of(cls, folder: str | os.PathLike[str]) -> DataFolder:
        root = Path(folder).expanduser().resolve()
        if not root.is_dir():
            raise InputError(f"data folder is not a folder: {folder}")
        return cls(root)

    def resolve(self, typed: str) -> Path:
        """The file a typed path names: relative paths start at :attr:`root`.

        Raises InputError (naming the path as typed) if it is empty, lies
        outside the data folder, or is not a readable point-cloud file.
        """
        text = typed.strip()
        if not text:
            raise InputError("no file path given")
        if "\x00" in text:
            raise InputError("the path contains a NUL character")
        p = Path(text).expanduser()
        full = (p if p.is_absolute() else self.root / p).resolve()
        if not full.is_relative_to(self.root):
            raise InputError(f"{text} is outside the data folder; the server only reads "
                             "files under --data-dir")
        if full.suffix.lower() not in SUPPORTED_SUFFIXES:
            raise InputError(f"{text}: unknown file type; supported: "
                             f"{' '.join(SUPPORTED_SUFFIXES)}")
        if not full.is_file():
            raise InputError(f"file not found: {text}")
        return full

    def shown(self, path: Path) -> str:
        """How a path inside the folder is shown to clients (relative to it)."""
        try:
            return str(path.relative_to(self.root))
        except ValueError:
            return path.name


@dataclass(frozen=True)
class UploadedFile:
    """A finished upload on the server's disk (deleted by :meth:`delete`)."""

    path: Path
    """Where it is (a generated name in the app's upload folder)."""
    name: str
    """The file name the browser gave (display only; escape before showing)."""
    size: int
    """Bytes."""

    def delete(self) -> None:
        self.path.unlink(missing_ok=True)


def read_estimate(path: Path, max_points: int | None = None) -> float:
    """Bytes of memory reading ``path`` is expected to need at its peak (the reader's
    measured figures, :mod:`rough_viewer.io.estimates`; 0 for an unknown type);
    ``max_points``: the decompression-bomb guard's limit (None: the default)."""
    reader = reader_for(path)
    if reader is None:
        return 0.0
    return reader.estimate(path, max_points).typical


@dataclass(frozen=True)
class ServeNeed:
    """What showing some files in the app is expected to need, from their headers."""

    points: int
    """Points the headers declare (or expected from the sizes)."""
    read_peak: float
    """Peak bytes of the largest file's read (:mod:`rough_viewer.io.estimates`)."""

    @property
    def app_bytes(self) -> float:
        """Bytes the prepared app holds: :data:`APP_FIXED_BYTES`, plus
        :data:`APP_BYTES_PER_POINT` a point, plus its grid cache
        (:data:`APP_CACHE_BYTES_PER_POINT` a point, at most :data:`CACHE_BYTES`)."""
        return (APP_FIXED_BYTES + APP_BYTES_PER_POINT * self.points
                + min(float(CACHE_BYTES), APP_CACHE_BYTES_PER_POINT * self.points))

    @property
    def total(self) -> float:
        """The server's peak, bytes: the read's peak on top of what the app holds
        (an upper bound: the two do not peak at the same time)."""
        return self.read_peak + self.app_bytes


def serve_need(paths: list[Path], max_points: int | None = None) -> ServeNeed:
    """What showing ``paths`` (one merged cloud) needs, from their headers only: no
    point is read (an uncompressed LAS counts at most the points its data can hold).
    Files of an unknown type, or that are not regular files, count
    nothing (their read says what is wrong). ``max_points``: the decompression-bomb
    guard's limit (a bomb is refused here, as its read would).

    Raises InputError for a damaged header or a decompression bomb.
    """
    points, peak = 0, 0.0
    for p in paths:
        reader = reader_for(p)
        if reader is None or not p.is_file():
            continue
        est = reader.estimate(p, max_points)
        n, typical = est.points, est.typical
        if p.suffix.lower() == ".las":  # what its data can hold: more is a truncated
            layout = check_las_layout(p)  # file, which its read refuses as such
            if not layout.compressed and layout.record_length:
                held = max(0, layout.size - layout.data_offset) // layout.record_length
                if held < n:
                    n, typical = held, typical * held / max(n, 1)
        points += n
        peak = max(peak, typical)
    return ServeNeed(points=points, read_peak=peak)


def default_memory() -> float | None:
    """``serve``'s memory budget without ``--memory``: the usable share
    (:data:`~rough_viewer.memory.USABLE_SHARE`, 80 %) of the memory available now
    (``MemAvailable``, or the room under a cgroup limit); None when unknown."""
    avail = available_bytes()
    return None if avail is None else USABLE_SHARE * avail


def check_app_room(path: Path, shown: str, memory: float | None,
                   max_points: int | None = None) -> None:
    """Refuse, before reading, a file the File tab loads or uploads whose points
    cannot fit in the server's budget ``memory`` (``serve --memory``, bytes; None:
    no budget), naming it as ``shown``."""
    if memory is None:
        return
    with _shown_errors(path, shown, shown):
        need = serve_need([path], max_points)
    if need.total > memory:
        raise InputError(
            f"{shown}: {need.points:,} points need about {format_bytes(need.total)} in the "
            f"server, more than the server's {format_bytes(memory)} allows (serve --memory): "
            "index the survey with 'rough-viewer index' and compute its map out of core "
            "with 'rough-viewer compute --memory'")


def read_cloud(path: Path, shown: str, *, cache: bool = True, units: Unit | None = None,
               progress: ProgressFn | None = None, max_points: int | None = None,
               memory: float | None = None) -> PointCloud:
    """Read ``path`` (its memory checked first, decoded in a child process); errors
    and the reader's warnings mention ``shown`` (the name the user knows), never the
    server path or the file's content.

    ``units``: the unit of the file's coordinates (None: the CRS's, else metres;
    see :func:`rough_viewer.io.load.load_points`). ``max_points``: the
    decompression-bomb guard's limit (``serve --max-points``; None: the default).
    ``memory``: the server's budget (``serve --memory``, bytes; None: none), checked
    from the header before any point is read (:func:`check_app_room`).

    Raises InputError.
    """
    check_app_room(path, shown, memory, max_points)
    with _shown_errors(path, shown, shown):
        cloud = load_points(path, units=units, cache=cache, progress=progress,
                            max_points=max_points)
    if cloud.warnings:
        paths = _variants(path, shown)
        cloud = replace(cloud, warnings=tuple(public_message(w, paths=paths, quoted=False)
                                              for w in cloud.warnings))
    return cloud


def read_mesh(path: Path, shown: str, *, units: Unit | None = None) -> TriangleMesh | None:
    """The triangles of ``path`` (an STL, or a PLY with faces; None for any other
    file, :func:`rough_viewer.io.formats.mesh.load_mesh`); errors mention ``shown``, never
    the server path. Raises InputError."""
    with _shown_errors(path, shown, f"the triangles of {shown}"):
        return load_mesh(path, units=units)


@contextmanager
def _shown_errors(path: Path, shown: str, what: str) -> Iterator[None]:
    """A reader's errors as one InputError naming ``shown`` (never the server path);
    ``what``: what "not enough memory to read ..." names."""
    try:
        yield
    except InputError as exc:
        raise InputError(public_message(str(exc), paths=_variants(path, shown),
                                        quoted=False)) from None
    except MemoryError:
        raise InputError(f"not enough memory to read {what}") from None
    except OSError:
        raise InputError(f"cannot read {shown}") from None


def _variants(path: Path, shown: str) -> dict[str, str]:
    out = {str(path): shown, str(path.resolve()): shown}
    return {k: v for k, v in out.items() if k}
