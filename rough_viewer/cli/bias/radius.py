"""``rough-viewer bias radius``: beam effective radius from scans of a thin wire, and its piecewise-linear growth with range."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from rough_viewer.cli._inputs import add_max_points
from rough_viewer.cli._options import (
    add_units,
    naming,
    non_negative,
    parse_xyz,
    positive,
    warn,
)
from rough_viewer.cli.bias._shared import (
    MAX_RANGE_M,
    add_json_option,
    check_length,
    emit,
    load,
    small,
    small_unit,
)
from rough_viewer.io.load import resolve_units
from rough_viewer.vocabulary import UNIT_LABELS, UNIT_METRES, InputError


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``bias radius`` to the ``bias`` subparsers."""
    q = sub.add_parser("radius", help="beam effective radius from scans of a thin wire",
                       description="Line fit per wire scan, residuals across the wire and the "
                       "view, mean of the top fraction of magnitudes. With 4 or more scans, a "
                       "piecewise-linear fit of radius against range.")
    q.add_argument("inputs", nargs="+", metavar="WIRE_SCAN", help="point cloud(s) of the wire")
    q.add_argument("--scanner", default="0,0,0", metavar="X,Y,Z",
                   help="scanner position in the scans' frame, in --units (default 0,0,0)")
    q.add_argument("--top-fraction", type=positive, default=0.02, metavar="F",
                   help="fraction of largest residuals averaged (default 0.02)")
    q.add_argument("--wire-radius", type=non_negative, default=0.0, metavar="M",
                   help="wire radius subtracted, in --units (default 0, as the paper; below 1 m)")
    q.add_argument("--break-range", type=positive, metavar="M",
                   help="break point of the piecewise fit, in --units (default: least "
                   "squares; below 10 km)")
    add_units(q)
    add_max_points(q)
    add_json_option(q)
    q.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import effective_radius, fit_piecewise_linear

    # every length given and shown is in the scans' unit (--units, else the CRS's)
    units = {str(p): resolve_units(p, args.units)[0] for p in args.inputs}
    if len(set(units.values())) > 1:
        raise InputError("the wire scans are in different units ("
                         + ", ".join(f"{p}: {u}" for p, u in units.items())
                         + "); give --units")
    unit = units[str(args.inputs[0])]
    per = UNIT_METRES[unit]
    scanner = np.array(parse_xyz(args.scanner, option="--scanner")) * per
    if not args.top_fraction <= 1.0:
        raise InputError(f"--top-fraction must be in (0, 1], got {args.top_fraction:g}")
    wire_radius = check_length(args.wire_radius, "--wire-radius", unit=unit)
    break_range = None
    if args.break_range is not None:
        break_range = check_length(args.break_range, "--break-range", unit=unit,
                                   allow_zero=False, maximum_m=MAX_RANGE_M)
        if len(args.inputs) < 4:
            raise InputError("--break-range needs at least 4 wire scans (a piecewise fit)")
    scans: list[dict[str, Any]] = []
    for path in args.inputs:
        cloud = load(path, unit, max_points=args.file_max_points)
        with naming(path):
            e = effective_radius(cloud.xyz(), scanner=scanner, top_fraction=args.top_fraction,
                                 wire_radius=wire_radius)
        warn([f"{path}: {w}" for w in e.warnings])
        scans.append({"file": str(path), "effective_radius": e.effective_radius,
                      "range": e.range, "n_points": e.n_points, "n_top": e.n_top,
                      "top_fraction": e.top_fraction, "residual_std": e.residual_std,
                      "wire_radius": e.wire_radius, "direction": e.direction,
                      "warnings": list(e.warnings)})
    fit = None
    if len(scans) >= 4:
        with naming("piecewise fit of effective radius against range"):
            f = fit_piecewise_linear(np.array([s["range"] for s in scans]),
                                     np.array([s["effective_radius"] for s in scans]),
                                     break_range=break_range)
        fit = {"break_range": f.break_range, "intercept": f.intercept,
               "slope_near": f.slope_near, "slope_far": f.slope_far, "rmse": f.rmse,
               "break_given": f.break_given, "n": f.n}
    data: dict = {}
    if len(scans) == 1:
        data.update({k: scans[0][k] for k in ("effective_radius", "range", "n_points", "n_top",
                                              "top_fraction", "residual_std", "wire_radius",
                                              "file", "warnings")})
    data["scans"] = scans
    data["fit"] = fit
    data["unit"] = unit
    su = small_unit(unit)
    bl, sl = UNIT_LABELS[unit], UNIT_LABELS[su]
    slope = per / UNIT_METRES[su]  # small units per unit of range, per (m / m)
    lines = [f"{'range ' + bl:>9} {'ER ' + sl:>8} {'points':>8}  file"]
    lines += [f"{s['range'] / per:9.3f} {small(s['effective_radius'], unit, label=False):>8} "
              f"{s['n_points']:8d}  {s['file']}" for s in scans]
    if fit:
        lines.append(
            f"piecewise fit: break at {fit['break_range'] / per:.2f} {bl}"
            f"{' (given)' if fit['break_given'] else ' (least squares)'}; slope "
            f"{fit['slope_near'] * slope:.4f} {sl}/{bl} below, "
            f"{fit['slope_far'] * slope:.4f} {sl}/{bl} above; rmse {small(fit['rmse'], unit)}")
    elif len(scans) > 1:
        lines.append("(a piecewise-linear fit needs at least 4 scans)")
    emit(args, data, "\n".join(lines))
    return 0
