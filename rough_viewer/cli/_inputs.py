"""Several input files as one cloud, for every command that reads a cloud
(``compute``, ``report``, ``zones``, ``serve``).

``INPUT [INPUT ...]``: files and quoted glob patterns (``"scans/*.laz"``, ``**``
for sub-folders), expanded here in sorted order so the result does not depend on
the shell. Files whose CRS or units differ are refused
(:func:`rough_viewer.scale.sources.check_compatible`).

A command registers the argument with :func:`add_inputs`, then calls
:func:`input_paths` for the list of files and :func:`load_inputs` for the merged
cloud in memory (with per-file and overall progress bars).
"""

from __future__ import annotations

import argparse
import fnmatch
import glob
import os
import sys
from collections.abc import Callable
from pathlib import Path

from rough_viewer.io.cloud import PointCloud
from rough_viewer.vocabulary import InputError

FORMATS = ".las .laz .e57 .xyz .txt .csv .pts .npy .ply .stl, DEMs .asc .tif"
_GLOB_CHARS = "*?["


def add_inputs(parser: argparse.ArgumentParser, *, optional: bool = False,
               what: str = "point cloud") -> None:
    """Add the ``inputs`` positional argument (one or more files or quoted globs;
    none allowed when ``optional``) and ``--max-points N`` (``args.file_max_points``):
    the decompression-bomb guard's limit (:mod:`rough_viewer.io.estimates`), and only
    that in every command, which passes it to every read (:func:`load_inputs`'
    ``max_points``)."""
    parser.add_argument(
        "inputs", nargs="*" if optional else "+", metavar="INPUT",
        help=f"{what}: {FORMATS}; several files and quoted globs (\"scans/*.laz\") "
        "are merged into one cloud (same CRS and units)")
    add_max_points(parser)


def add_max_points(parser: argparse.ArgumentParser) -> None:
    """Add ``--max-points N`` (``args.file_max_points``), the decompression-bomb
    guard's limit and only that, in every command that reads a cloud."""
    from rough_viewer.cli._options import positive_int
    from rough_viewer.io.estimates import DEFAULT_MAX_POINTS

    parser.add_argument(
        "--max-points", dest="file_max_points", type=positive_int, metavar="N",
        help=f"read a compressed file (LAZ, E57) that declares more points than its "
        f"size can hold (a decompression bomb, refused) if they are at most N "
        f"(default {DEFAULT_MAX_POINTS:,})")


def expand_inputs(patterns: list[str]) -> list[Path]:
    """Files named by ``patterns``: plain paths as given, glob patterns expanded
    (sorted; :func:`glob_files`). A pattern that matches nothing is an InputError; a
    plain path is checked when it is read."""
    out: list[Path] = []
    for pattern in patterns:
        if any(c in pattern for c in _GLOB_CHARS) and not Path(pattern).exists():
            found = glob_files(pattern)
            if not found:
                raise InputError(f"no files match {pattern!r}")
            out.extend(Path(p) for p in found)
        else:
            out.append(Path(pattern))
    return out


def glob_files(pattern: str) -> list[str]:
    """The files ``pattern`` matches, sorted: ``*``, ``?`` and ``[...]`` within one name
    (not matching a leading dot), ``**`` for any depth of folders, as bash's
    ``globstar`` and ``find`` do: ``**`` does not descend into folders reached through
    symbolic links (Python's ``glob`` does: one link back up counted a file 41 times,
    two never finished), while a link to a file, or a folder named without ``**``,
    is followed."""
    parts = pattern.split(os.sep)
    if parts[0] == "":  # an absolute pattern
        base, parts = os.sep, parts[1:]
    else:
        base = ""
    found: set[str] = set()
    _expand(base, [q for q in parts if q not in ("", ".")] or [""], found)
    return sorted(f for f in found if os.path.isfile(f))


def _expand(base: str, parts: list[str], found: set[str]) -> None:
    if not parts:
        if base:
            found.add(base)
        return
    head, rest = parts[0], parts[1:]
    here = base or os.curdir
    if head == "**":
        _expand(base, rest, found)  # zero folders
        for name in _names(here, "*"):
            sub = os.path.join(base, name)
            if os.path.isdir(sub) and not os.path.islink(sub):
                _expand(sub, parts, found)
            elif not rest:  # a trailing ``**`` matches the files too
                found.add(sub)
        return
    if glob.has_magic(head):
        for name in _names(here, head):
            _expand(os.path.join(base, name), rest, found)
        return
    target = os.path.join(base, head)
    if os.path.lexists(target):
        _expand(target, rest, found)


def _names(folder: str, pattern: str) -> list[str]:
    """Names in ``folder`` matching one component (a leading dot only when the
    pattern has one)."""
    try:
        names = os.listdir(folder)
    except OSError:
        return []
    hidden = pattern.startswith(".")
    return [n for n in fnmatch.filter(names, pattern) if hidden or not n.startswith(".")]


def input_paths(args: argparse.Namespace) -> list[Path]:
    """The files of ``args.inputs``, a warning on stderr for a file given twice (its
    points then count twice)."""
    paths = expand_inputs(list(args.inputs))
    seen: set[Path] = set()
    for p in paths:
        key = p.resolve()
        if key in seen:
            print(f"rough-viewer: warning: {p} is given more than once; its points count "
                  "once per mention", file=sys.stderr)
        seen.add(key)
    return paths


#: Bytes a point takes on disk, roughly, by format (compressed ones fewer); others 24.
BYTES_PER_POINT = {".laz": 4.0, ".e57": 8.0, ".las": 28.0, ".xyz": 30.0, ".txt": 30.0,
                   ".csv": 30.0, ".pts": 30.0, ".stl": 40.0}


def preload_kernels_for(paths: list[Path]) -> None:
    """Start loading the compiled kernels on a thread while the inputs are read
    (:func:`rough_viewer.grid.fast.preload`) when the files look big enough for the
    compiled engine (their sizes over :data:`BYTES_PER_POINT`, against
    :data:`~rough_viewer.grid.fast.AUTO_MIN_POINTS`): a run of millions of points
    then finds them loaded, and a small one loads nothing."""
    from rough_viewer.grid import fast

    total = 0.0
    for p in paths:
        try:
            total += p.stat().st_size / BYTES_PER_POINT.get(p.suffix.lower(), 24.0)
        except OSError:
            continue  # reading it says what is wrong
    if total >= fast.AUTO_MIN_POINTS:
        fast.preload()


def describe(paths: list[Path], *, shown: int = 4) -> str:
    """The inputs in one phrase (for tables and summaries): the file, or ``"N files: a,
    b, ..., z"`` naming at most ``shown`` of them."""
    if len(paths) == 1:
        return str(paths[0])
    names = [str(p) for p in paths]
    if len(names) > shown:
        names = [*names[:shown - 1], "...", names[-1]]
    return f"{len(paths)} files: " + ", ".join(names)


def load_inputs(paths: list[Path], *, units: str | None = None, quiet: bool = False,
                max_points: int | None = None,
                also: Callable[[int, int, int], None] | None = None) -> PointCloud:
    """Read the files as one cloud in memory, with progress bars (unless ``quiet``)
    and the usual notes on stderr (dropped rows, warnings); ``max_points`` is the
    decompression-bomb guard's limit (``--max-points``; None: the default). ``also(i,
    done, total)`` is told the progress of file ``i`` too (``serve``'s waiting page)."""
    from rough_viewer.cli._progress import FileBars, ProgressBar
    from rough_viewer.scale.sources import load_merged

    if len(paths) == 1:
        bars = None
        progress = None if quiet else [ProgressBar(f"reading {paths[0].name}", unit="pt")]
    else:
        bars = None if quiet else FileBars([p.name for p in paths], label="reading",
                                           overall_unit="file")
        progress = None if bars is None else [_with_overall(bars, i, paths)
                                              for i in range(len(paths))]
    if also is not None:
        told: list[Callable[[int, int], None]] = [
            _and_also(None if progress is None else progress[i], also, i)
            for i in range(len(paths))]
        progress = told  # type: ignore[assignment]
    try:
        cloud = load_merged(paths, units=units, progress=progress,  # type: ignore[arg-type]
                            max_points=max_points)
    finally:
        if bars is not None:
            bars.close()
    report_cloud(cloud, describe(paths))
    return cloud


def _and_also(bar: Callable[[int, int], None] | None, also: Callable[[int, int, int], None],
              i: int) -> Callable[[int, int], None]:
    def tick(done: int, total: int) -> None:
        if bar is not None:
            bar(done, total)
        also(i, done, total)

    return tick


def _with_overall(bars, i: int, paths: list[Path]):
    """Per-file callback that also moves the overall bar, counted in files."""

    def tick(done: int, total: int) -> None:
        bars.files[i](done, total)
        if total > 0 and done >= total:
            bars.overall(i + 1, len(paths))

    return tick


def report_cloud(cloud: PointCloud, what: str) -> None:
    """Print the cloud's dropped-row count and warnings on stderr."""
    if cloud.dropped_nonfinite:
        print(f"rough-viewer: dropped {cloud.dropped_nonfinite:,} points with NaN or infinite "
              f"coordinates from {what}", file=sys.stderr)
    for w in cloud.warnings:
        print(f"rough-viewer: warning: {w}", file=sys.stderr)
