"""Where the app may read files from, and reading them safely.

"Load file" takes a path typed in the browser, so it is restricted to one
folder, the data folder (``--data-dir``; default the folder of the file given to
``serve``, or the current folder): the path is resolved (symbolic links
followed) and refused unless it lies inside. Before a file is read its size is
checked against the memory a reader needs (:func:`read_estimate`); LAS/LAZ/E57
headers are checked by the readers themselves. Error messages name the file as
the user gave it and never carry server paths or text read from the file
(:func:`rough_viewer.app.markup.public_message`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

from rough_viewer.app.markup import public_message
from rough_viewer.io import PointCloud, load_points
from rough_viewer.io.load import SUPPORTED_SUFFIXES, TEXT_SUFFIXES
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError, ProgressFn, Unit

#: Bytes of memory per byte of file a reader may need at its peak, by format. Text
#: rows can be as short as "1 2 3\n" (6 bytes for 24 bytes of float64, parsed in
#: chunks then copied into columns); binary formats hold the file's numbers once
#: more as float64. LAS/LAZ/E57 check their header's point count themselves.
READ_FACTOR: dict[str, float] = {
    **{s: 12.0 for s in TEXT_SUFFIXES},
    ".npy": 3.0,
    ".ply": 4.0,
    ".stl": 6.0,
}


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


def read_estimate(path: Path) -> float:
    """Bytes of memory reading ``path`` may need at its peak (0 when the reader
    checks for itself), from its size and :data:`READ_FACTOR`."""
    factor = READ_FACTOR.get(path.suffix.lower(), 0.0)
    return factor * path.stat().st_size


def read_cloud(path: Path, shown: str, *, cache: bool = True, units: Unit | None = None,
               progress: ProgressFn | None = None) -> PointCloud:
    """Read ``path`` after checking that it fits in memory; errors and the reader's
    warnings mention ``shown`` (the name the user knows), never the server path or
    the file's content.

    ``units``: the unit of the file's coordinates (None: the CRS's, else metres;
    see :func:`rough_viewer.io.load.load_points`).

    Raises InputError.
    """
    try:
        require(read_estimate(path), f"reading {shown}",
                hint="the file is too large for this server's memory")
        cloud = load_points(path, units=units, cache=cache, progress=progress)
        if cloud.warnings:
            paths = _variants(path, shown)
            cloud = replace(cloud, warnings=tuple(public_message(w, paths=paths, quoted=False)
                                                  for w in cloud.warnings))
        return cloud
    except InputError as exc:
        raise InputError(public_message(str(exc), paths=_variants(path, shown),
                                        quoted=False)) from None
    except MemoryError:
        raise InputError(f"not enough memory to read {shown}") from None
    except OSError:
        raise InputError(f"cannot read {shown}") from None


def _variants(path: Path, shown: str) -> dict[str, str]:
    out = {str(path): shown, str(path.resolve()): shown}
    return {k: v for k, v in out.items() if k}
