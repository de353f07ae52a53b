"""``rough-viewer bias noise``: range noise from the scan of a flat board (equal segments, a plane each)."""

from __future__ import annotations

import argparse

from rough_viewer.cli._inputs import add_max_points
from rough_viewer.cli._options import (
    add_units,
    naming,
    non_negative_int,
    positive_int,
    segments,
    warn,
)
from rough_viewer.cli.bias._shared import (
    add_json_option,
    emit,
    load,
    scanner_position,
    small,
    small_unit,
)
from rough_viewer.vocabulary import UNIT_LABELS


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``bias noise`` to the ``bias`` subparsers."""
    q = sub.add_parser("noise", help="range noise from the scan of a flat board",
                       description="Split the board into equal segments, fit a plane to each, "
                       "report the standard deviation of all residuals and per-segment values.")
    q.add_argument("input", metavar="BOARD_SCAN", help="point cloud of the board, cropped")
    q.add_argument("--segments", type=segments, default=8, metavar="N|RxC",
                   help="number of equal segments, or rows x cols along the long x short "
                   "axis (default 8)")
    q.add_argument("--scanner", metavar="X,Y,Z",
                   help="scanner position in --units (orients offsets)")
    q.add_argument("--sample-points", type=positive_int, metavar="N",
                   help="random subsample of N points (the paper: 180000)")
    add_max_points(q)
    q.add_argument("--seed", type=non_negative_int, default=0,
                   help="seed of the subsample (default 0)")
    add_units(q)
    add_json_option(q)
    q.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import range_noise

    cloud = load(args.input, args.units, max_points=args.file_max_points)
    unit = cloud.source_unit
    scanner = scanner_position(args, unit)
    with naming(args.input):
        r = range_noise(cloud.xyz(), segments=args.segments, scanner=scanner,
                        max_points=args.sample_points, seed=args.seed)
    segs = [
        {"row": s.row, "col": s.col, "n_points": s.n_points, "sigma": s.sigma,
         "offset": s.offset, "tilt_deg": s.tilt_deg, "centre": s.centre}
        for s in r.segments
    ]
    warn([f"{args.input}: {w}" for w in r.warnings])
    data = {"sigma": r.sigma, "sigma_single_plane": r.sigma_single_plane,
            "n_points": r.n_points, "shape": list(r.shape), "segments": segs,
            "normal": r.normal, "file": str(args.input), "unit": unit,
            "warnings": list(r.warnings)}
    su = UNIT_LABELS[small_unit(unit)]
    lines = [
        f"range noise of {args.input}: sigma = {small(r.sigma, unit)} "
        f"({r.n_points:,} points, {r.shape[0]} x {r.shape[1]} segments)",
        f"one plane over the whole board: {small(r.sigma_single_plane, unit)}"
        + ("  (board looks curved)" if r.sigma_single_plane > 1.05 * r.sigma else ""),
        f"row col   points {'sigma ' + su:>10} {'offset ' + su:>10}  tilt deg",
    ]
    lines += [f"{s.row:3d} {s.col:3d} {s.n_points:8d} {small(s.sigma, unit, label=False):>10} "
              f"{small(s.offset, unit, label=False):>10} {s.tilt_deg:9.3f}" for s in r.segments]
    emit(args, data, "\n".join(lines))
    return 0
