"""``rough-viewer compute``: per-cell roughness of a cloud, headless.

Contract (other tools script against it)::

    rough-viewer compute INPUT --grid G [--grid G2 ...] [--method odr|ols|hybrid|all]
        [--axis auto|x|y|z] [--min-points K] [--origin X,Y,Z] [--signed]
        --out CELLS.csv [--summary-json SUMMARY.json] [--force] [--quiet]

With several ``--grid`` values each output name gets ``_g<G>`` before its
extension (``cells.csv`` -> ``cells_g0.5.csv``, ``cells_g0.25.csv``).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

# CSV_COLUMNS stays importable from here: the compute contract's columns
from rough_viewer.cli._cells_csv import CSV_COLUMNS as CSV_COLUMNS
from rough_viewer.cli._cells_csv import write_cells_csv
from rough_viewer.cli._options import parse_xyz
from rough_viewer.io.jsonable import to_jsonable
from rough_viewer.io.output import check_output_path, write_atomic
from rough_viewer.vocabulary import InputError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compute",
        help="per-cell roughness of a cloud to CSV (and a JSON summary)",
        description="Compute ODR, OLS and hybrid grid roughness (SCIENCE.md section 1) "
        "and write one CSV row per cell.",
    )
    p.add_argument("input", help="point cloud: .las .laz .xyz .txt .csv .pts .npy .ply .stl")
    p.add_argument("--grid", type=float, action="append", required=True, metavar="G",
                   help="grid cell size in metres (repeat for several sizes)")
    p.add_argument("--method", choices=("odr", "ols", "hybrid", "all"), default="all",
                   help="roughness model (default: all)")
    p.add_argument("--axis", choices=("auto", "x", "y", "z"), default="auto",
                   help="dependent axis of OLS and hybrid (default: auto = closest to the "
                   "whole cloud's normal)")
    p.add_argument("--min-points", type=int, default=3, metavar="K",
                   help="cells with fewer points get no value (default 3)")
    p.add_argument("--origin", metavar="X,Y,Z", help="grid origin (default: bounding-box minimum)")
    p.add_argument("--signed", action="store_true",
                   help="RMS of signed distances instead of the std of absolute distances")
    p.add_argument("--out", required=True, metavar="CELLS.csv", help="per-cell CSV output")
    p.add_argument("--summary-json", metavar="SUMMARY.json", help="Table-1 summary as JSON")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def output_name(path: str, grid: float, several: bool) -> Path:
    """Output path for one grid size: ``name_g<G>.ext`` when there are several."""
    p = Path(path)
    if not several:
        return p
    return p.with_name(f"{p.stem}_g{grid:g}{p.suffix}")


def summary_dict(result, cloud_source: str, dropped: int) -> dict:
    """The SUMMARY.json content for one grid size."""
    from rough_viewer.grid.summary import summarise
    from rough_viewer.vocabulary import MAPS

    out: dict = {}
    for name in MAPS:
        out[name] = summarise(result, name).as_dict()
    out.update(
        {
            "grid_size": result.grid.cell_size,
            "origin": [float(v) for v in result.grid.origin],
            "axis": result.axis,
            "axis_requested": result.axis_requested,
            "points": result.n_points_total,
            "dropped_nonfinite": dropped,
            "min_points": result.min_points,
            "residual": result.residual,
            "models": list(result.models),
            "cells": result.cell_report("odr"),
            "input": cloud_source,
        }
    )
    return to_jsonable(out)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.cli._table import format_table
    from rough_viewer.grid.roughness import grid_roughness
    from rough_viewer.io import load_points
    from rough_viewer.vocabulary import MODELS

    grids = list(dict.fromkeys(args.grid))
    for g in grids:
        if not (math.isfinite(g) and g > 0):
            raise InputError(f"--grid must be a positive number of metres, got {g:g}")
    if args.min_points < 3:
        raise InputError(f"--min-points must be at least 3, got {args.min_points}")
    origin = np.array(parse_xyz(args.origin, option="--origin")) if args.origin else None
    several = len(grids) > 1
    outs = {g: check_output_path(output_name(args.out, g, several), force=args.force) for g in grids}
    jsons = {}
    if args.summary_json:
        jsons = {
            g: check_output_path(output_name(args.summary_json, g, several), force=args.force)
            for g in grids
        }
    quiet = args.quiet
    cloud = load_points(args.input, progress=None if quiet else ProgressBar(f"reading {Path(args.input).name}"))
    if cloud.dropped_nonfinite:
        print(
            f"rough-viewer: dropped {cloud.dropped_nonfinite:,} points with NaN or infinite "
            f"coordinates from {args.input}",
            file=sys.stderr,
        )
    models = MODELS if args.method == "all" else (args.method,)
    for i, g in enumerate(grids):
        result = grid_roughness(
            cloud, g, origin=origin, min_points=args.min_points, axis=args.axis,
            models=models, residual="signed" if args.signed else "absolute",
            progress=None if quiet else ProgressBar(f"grid {g:g} m"),
        )
        write_cells_csv(outs[g], result)
        if g in jsons:
            data = summary_dict(result, str(args.input), cloud.dropped_nonfinite)
            write_atomic(jsons[g], lambda fh, d=data: json.dump(d, fh, indent=2))
        if i:
            print()
        print(format_table(result, source=str(args.input)))
        print(f"wrote {outs[g]}" + (f" and {jsons[g]}" if g in jsons else ""))
    return 0
