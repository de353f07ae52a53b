"""``rough-viewer bias curve``: roughness error against ER / asperity radius (the paper's Fig. 4)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from rough_viewer.cli._options import (
    list_of,
    non_negative,
    positive,
)
from rough_viewer.cli.bias._shared import (
    add_json_option,
    add_quiet_option,
    add_simulation_options,
    check_simulation,
    emit,
    layout,
    mm,
    progress_bar,
    residual_fields,
    residual_line,
)


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``bias curve`` to the ``bias`` subparsers."""
    q = sub.add_parser("curve", help="roughness error against ER / asperity radius (Fig. 4)",
                       description="For each asperity radius, the roughness error at each "
                       "ratio of effective radius to asperity radius.")
    add_simulation_options(q, target_default=None)
    q.add_argument("--noise", type=non_negative, default=0.0016, metavar="M",
                   help="range noise sigma, metres (default 0.0016)")
    q.add_argument("--asperity-radius", type=list_of(positive), default=[0.019, 0.0325],
                   metavar="M[,M...]", help="hemisphere radii, metres (default 0.019,0.0325)")
    q.add_argument("--er-ratio", type=list_of(non_negative),
                   default=[0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5], metavar="R[,R...]",
                   help="effective radius / asperity radius values (default 0..0.5); "
                   "every effective radius below 1 m")
    add_quiet_option(q)
    add_json_option(q)
    q.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.bias.simulation import smoothing_curve

    curves: list[dict[str, Any]] = []
    ratios = np.asarray(args.er_ratio, dtype=np.float64)
    check_simulation(args, noise=[args.noise], radii=args.asperity_radius,
                     ers=[float(e) for r in args.asperity_radius for e in ratios * r],
                     er_option="--er-ratio x --asperity-radius")
    for r in args.asperity_radius:
        c = smoothing_curve(ratios * r, layout=layout(args, r), noise_sigma_m=args.noise,
                            spacing_m=args.spacing, ratio=args.ratio, seed=args.seed,
                            residual=args.residual,
                            progress=progress_bar(args, f"asperity radius {r * 1e3:g} mm",
                                                  "ER"))
        curves.append({"asperity_radius_m": c.asperity_radius_m, "er_ratio": c.er_ratio,
                       "effective_radius_m": c.effective_radius_m, "expected_m": c.expected_m,
                       "noise_only_m": c.noise_only_m, "measured_m": c.measured_m,
                       "error_pct": c.error_pct, "vs_noisy_pct": c.vs_noisy_pct})
    data = {"noise_sigma_m": args.noise, "ratio": args.ratio,
            **residual_fields(args.residual), "curves": curves}
    lines = [f"roughness error against ER / asperity radius (noise {mm(args.noise)}); "
             "percent of the noise-free / noisy expected value", residual_line(args.residual)]
    for row in curves:
        lines.append(f"asperity radius {mm(row['asperity_radius_m'])}: expected "
                     f"{mm(row['expected_m'])}, with noise {mm(row['noise_only_m'])}")
        lines.append(f"  {'ER/r':>6} {'ER mm':>8} {'measured mm':>12} {'vs true %':>10} "
                     f"{'vs noisy %':>11}")
        for k in range(len(row["er_ratio"])):
            lines.append(f"  {row['er_ratio'][k]:6.3f} {row['effective_radius_m'][k] * 1e3:8.3f} "
                         f"{row['measured_m'][k] * 1e3:12.3f} {row['error_pct'][k]:10.2f} "
                         f"{row['vs_noisy_pct'][k]:11.2f}")
    emit(args, data, "\n".join(lines))
    return 0
