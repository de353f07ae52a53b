"""``--memory``, ``--scheduler`` and ``--workers``: the streamed (out-of-core) and Dask
runs of a command, shared by every command that computes grid roughness.

The machinery is :mod:`rough_viewer.scale`; this module parses the options, picks
the runner, prints the Dask dashboard link and draws per-file and overall bars.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rough_viewer.cli._options import positive_int
from rough_viewer.vocabulary import InputError, Model, Residual

if TYPE_CHECKING:
    from rough_viewer.grid.roughness import GridRoughness


def add_scale_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--memory``, ``--scheduler`` and ``--workers``."""
    parser.add_argument(
        "--memory", metavar="SIZE",
        help="stream the points in chunks and hold at most SIZE (e.g. 2GB, 512MB) besides "
        "the interpreter; per worker process with --scheduler")
    parser.add_argument(
        "--scheduler", metavar="threads|processes|tcp://HOST:PORT",
        help="run the chunks on Dask: local threads or processes, or an existing "
        "dask.distributed scheduler (needs rough_viewer[dask])")
    parser.add_argument("--workers", type=positive_int, metavar="N",
                        help="threads or processes of a local --scheduler (default: CPU count)")


def wants_chunks(args: argparse.Namespace) -> bool:
    """Whether the command streams its points (``--memory`` or ``--scheduler`` given)."""
    if getattr(args, "workers", None) and not getattr(args, "scheduler", None):
        raise InputError("--workers needs --scheduler threads or processes")
    return bool(getattr(args, "memory", None) or getattr(args, "scheduler", None))


@dataclass(frozen=True)
class ChunkedRun:
    """What a streamed (or tiled, or Dask) run of several grid sizes gives."""

    results: list[GridRoughness]
    """One per grid size, in the order asked."""
    dropped: int
    """Rows dropped for NaN or infinite coordinates."""
    bounds: tuple[np.ndarray, np.ndarray]
    """The inputs' extent from their headers (or their first pass), metres."""
    warnings: tuple[str, ...]
    """What the readers noticed."""


def chunked_results(args: argparse.Namespace, paths: Sequence[Path], grids: Sequence[float], *,
                    origin: np.ndarray | None, models: Sequence[Model], residual: Residual
                    ) -> tuple[list[GridRoughness], int]:
    """Grid roughness of the merged files at every grid size, streamed; and the number
    of rows dropped for NaN or infinite coordinates."""
    run = chunked_run(args, paths, grids, origin=origin, models=models, residual=residual)
    return run.results, run.dropped


def chunked_run(args: argparse.Namespace, paths: Sequence[Path], grids: Sequence[float], *,
                origin: np.ndarray | None, models: Sequence[Model], residual: Residual
                ) -> ChunkedRun:
    """:func:`chunked_results` with the inputs' extent and readers' warnings."""
    from rough_viewer.cli._inputs import report_cloud
    from rough_viewer.cli._progress import FileBars, ProgressBar
    from rough_viewer.io.cloud import PointCloud
    from rough_viewer.io.copc.reader import is_copc
    from rough_viewer.scale.chunked import SequentialRunner, chunked_roughness, parse_bytes
    from rough_viewer.scale.sources import open_sources

    memory = parse_bytes(args.memory) if args.memory else None
    sources = open_sources(paths, units=getattr(args, "units", None),
                           max_points=getattr(args, "file_max_points", None))
    dropped = sum(s.dropped_nonfinite for s in sources)
    notes = tuple(w for s in sources for w in s.warnings)
    report_cloud(PointCloud(x=np.empty(0), y=np.empty(0), z=np.empty(0),
                            dropped_nonfinite=dropped, warnings=notes), "the inputs")
    bounds = (np.min([s.bounds_min for s in sources], axis=0),
              np.max([s.bounds_max for s in sources], axis=0))

    def done(results: list[GridRoughness]) -> ChunkedRun:
        return ChunkedRun(results=results, dropped=dropped, bounds=bounds, warnings=notes)

    runner = SequentialRunner() if not args.scheduler else _dask_runner(args)
    quiet = args.quiet
    try:
        if len(sources) == 1 and sources[0].streamed and is_copc(sources[0].path):
            return done(_copc_results(args, sources[0], grids, origin=origin, models=models,
                                      residual=residual, memory=memory, runner=runner))
        bars: FileBars | None = None
        overall: ProgressBar | None = None
        per_file: list[ProgressBar] | None = None
        if len(paths) > 1 and not quiet:
            bars = FileBars([p.name for p in paths], label="all files")
            overall, per_file = bars.overall, bars.files
        elif not quiet:
            overall = ProgressBar("streaming", unit="pt")
        try:
            results = chunked_roughness(
                sources, grids, origin=origin, min_points=args.min_points, axis=args.axis,
                models=models, residual=residual, memory_bytes=memory, runner=runner,
                progress=overall, file_progress=per_file)
        finally:
            if bars is not None:
                bars.close()
    finally:
        close = getattr(runner, "close", None)
        if close is not None:
            close()
    return done(results)


def _copc_results(args: argparse.Namespace, source, grids: Sequence[float], *,
                  origin: np.ndarray | None, models: Sequence[Model], residual: Residual,
                  memory: int | None, runner) -> list[GridRoughness]:
    """A COPC file by its index: spatial tiles, each point decoded once
    (:func:`rough_viewer.scale.tiles.copc_roughness`)."""
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.io.copc.reader import open_copc
    from rough_viewer.scale.tiles import copc_roughness

    copc = open_copc(source.path)
    bar = None if args.quiet else ProgressBar("tiles", unit="pt")
    try:
        return copc_roughness(
            copc, source, grids, origin=origin, min_points=args.min_points, axis=args.axis,
            models=models, residual=residual, memory_bytes=memory,
            runner=runner if args.scheduler else None, progress=bar)
    finally:
        if bar is not None:
            bar.close()


def _dask_runner(args: argparse.Namespace):
    from rough_viewer.scale.dask_runner import DaskRunner

    runner = DaskRunner(args.scheduler, workers=args.workers)
    if args.workers and args.scheduler not in ("threads", "processes"):
        runner.close()
        raise InputError("--workers is for --scheduler threads or processes; a distributed "
                         "scheduler has the workers it has")
    link = runner.dashboard_link
    if link:
        print(f"rough-viewer: Dask dashboard at {link}", file=sys.stderr, flush=True)
    return runner
