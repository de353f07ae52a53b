"""``rough-viewer index``: one COPC file (an octree-indexed LAZ 1.4) of every point of
the inputs, built out of core.

Contract::

    rough-viewer index INPUT [INPUT ...] --out CAMPAIGN.copc.laz
        [--memory SIZE] [--workers N] [--max-points N] [--force] [--quiet]

Several inputs (LAS/LAZ files or quoted globs) are one cloud (same CRS and units, as
every command). Every point is kept, in point format 6, 7 or 8 (0-5 converted,
extra bytes kept); the integer coordinates are copied as stored when the inputs share
scale and offset; the first input's CRS VLRs are kept (docs/campaign.md).
"""

from __future__ import annotations

import argparse
import os

from rough_viewer.cli._inputs import add_max_points, input_paths
from rough_viewer.cli._options import positive_int
from rough_viewer.vocabulary import InputError

DEFAULT_MEMORY = "2GB"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "index",
        help="index LAS/LAZ files into one COPC file (octree LAZ), out of core",
        description="Write one COPC 1.0 file (a LAZ 1.4 file whose chunks are octree "
        "nodes, read by QGIS, PDAL, Potree and laspy) of every point of the inputs. Two "
        "passes: the inputs are streamed in chunks into bucket files beside --out "
        "(one uncompressed copy of the points on disk, ~30-40 bytes a point), then each "
        "bucket's octree is built in memory and compressed. Peak memory at most about --memory "
        "plus the interpreter (~150 MB a process).")
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="LAS/LAZ files and quoted globs (\"scans/*.laz\"), one cloud "
                   "(same CRS and units)")
    p.add_argument("--out", required=True, metavar="CAMPAIGN.copc.laz", help="the COPC file")
    p.add_argument("--memory", metavar="SIZE", default=DEFAULT_MEMORY,
                   help="memory for the points (e.g. 2GB, 512MB; default 2GB): pass 1 holds a "
                   "chunk of about 40%% of it, pass 2 one bucket per worker within 80%% of it")
    p.add_argument("--workers", type=positive_int, metavar="N", default=1,
                   help="processes compressing the buckets of pass 2 (default 1; each holds "
                   "a bucket, so the bucket size is divided by N)")
    add_max_points(p)
    p.add_argument("--force", action="store_true", help="overwrite an existing --out")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.io.copc.index import build_copc, check_disk, plan_index
    from rough_viewer.io.output import check_output_path, write_path_atomic
    from rough_viewer.scale.chunked import parse_bytes
    from rough_viewer.scale.sources import check_compatible

    paths = input_paths(args)
    memory = parse_bytes(args.memory)
    out = check_output_path(args.out, force=args.force, inputs=paths)
    if not out.name.lower().endswith(".laz"):
        raise InputError(f"--out must end in .copc.laz (or .laz): {out}")
    from rough_viewer.io.estimates import estimate_las

    for p in paths:
        if not Path(p).is_file():
            raise InputError(f"no such file: {p}")
        estimate_las(Path(p), getattr(args, "file_max_points", None))  # the bomb guard
    for w in check_compatible(paths):
        print(f"rough-viewer: warning: {w}", file=__import__("sys").stderr)
    plan = plan_index(paths, memory_bytes=memory, workers=args.workers)
    folder = out.parent if str(out.parent) else Path(os.curdir)
    check_disk(plan, folder)
    bar = None if args.quiet else ProgressBar("indexing", unit="pt")
    got = []
    try:
        write_path_atomic(out, lambda tmp: got.append(
            build_copc(plan, tmp, work_dir=folder, progress=bar)))
    finally:
        if bar is not None:
            bar.close()
    s = got[0]
    print(f"wrote {s.count:,} points in point format {plan.point_format} to {out}")
    return 0
