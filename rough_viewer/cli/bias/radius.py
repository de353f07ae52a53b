"""``rough-viewer bias radius``: beam effective radius from scans of a thin wire, and its piecewise-linear growth with range."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from rough_viewer.cli._options import (
    naming,
    non_negative,
    parse_xyz,
    positive,
    warn,
)
from rough_viewer.cli.bias._shared import (
    add_json_option,
    emit,
    load,
    mm,
)
from rough_viewer.vocabulary import InputError


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``bias radius`` to the ``bias`` subparsers."""
    q = sub.add_parser("radius", help="beam effective radius from scans of a thin wire",
                       description="Line fit per wire scan, residuals across the wire and the "
                       "view, mean of the top fraction of magnitudes. With 4 or more scans, a "
                       "piecewise-linear fit of radius against range.")
    q.add_argument("inputs", nargs="+", metavar="WIRE_SCAN", help="point cloud(s) of the wire")
    q.add_argument("--scanner", default="0,0,0", metavar="X,Y,Z",
                   help="scanner position in the scans' frame (default 0,0,0)")
    q.add_argument("--top-fraction", type=positive, default=0.02, metavar="F",
                   help="fraction of largest residuals averaged (default 0.02)")
    q.add_argument("--wire-radius", type=non_negative, default=0.0, metavar="M",
                   help="wire radius subtracted, metres (default 0, as the paper)")
    q.add_argument("--break-range", type=positive, metavar="M",
                   help="break point of the piecewise fit, metres (default: least squares)")
    add_json_option(q)
    q.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import effective_radius, fit_piecewise_linear

    scanner = np.array(parse_xyz(args.scanner, option="--scanner"))
    if not args.top_fraction <= 1.0:
        raise InputError(f"--top-fraction must be in (0, 1], got {args.top_fraction:g}")
    if args.break_range is not None and len(args.inputs) < 4:
        raise InputError("--break-range needs at least 4 wire scans (a piecewise fit)")
    scans: list[dict[str, Any]] = []
    for path in args.inputs:
        cloud = load(path)
        with naming(path):
            e = effective_radius(cloud.xyz(), scanner=scanner, top_fraction=args.top_fraction,
                                 wire_radius=args.wire_radius)
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
                                     break_range=args.break_range)
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
    lines = [f"{'range m':>9} {'ER mm':>8} {'points':>8}  file"]
    lines += [f"{s['range']:9.3f} {s['effective_radius'] * 1e3:8.3f} {s['n_points']:8d}  "
              f"{s['file']}" for s in scans]
    if fit:
        lines.append(
            f"piecewise fit: break at {fit['break_range']:.2f} m"
            f"{' (given)' if fit['break_given'] else ' (least squares)'}; slope "
            f"{fit['slope_near'] * 1e3:.4f} mm/m below, {fit['slope_far'] * 1e3:.4f} mm/m "
            f"above; rmse {mm(fit['rmse'])}")
    elif len(scans) > 1:
        lines.append("(a piecewise-linear fit needs at least 4 scans)")
    emit(args, data, "\n".join(lines))
    return 0
