"""``rough-viewer bias simulate``: simulate a rough target with range noise and beam smoothing."""

from __future__ import annotations

import argparse

import numpy as np

from rough_viewer.cli._options import (
    non_negative,
    positive,
    positive_int,
)
from rough_viewer.cli.bias._shared import (
    MAX_TRIALS,
    add_json_option,
    add_quiet_option,
    add_simulation_options,
    check_las_out,
    check_simulation,
    emit,
    layout,
    prediction_dict,
    prediction_text,
    progress_bar,
    target_radius,
    write_las_atomic,
)


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``bias simulate`` to the ``bias`` subparsers."""
    q = sub.add_parser("simulate", help="simulate a rough target: noise, beam smoothing",
                       description="Simulate the paper's target (or another asperity radius "
                       "on its layout), report expected and measured roughness, optionally "
                       "write the simulated cloud with a 'truth' dimension (1 = asperity).")
    add_simulation_options(q, target_default="A")
    q.add_argument("--asperity-radius", type=positive, metavar="M",
                   help="hemisphere radius, metres (default: the target's)")
    q.add_argument("--noise", type=non_negative, default=0.0016, metavar="M",
                   help="range noise sigma, metres (default 0.0016, below 1)")
    q.add_argument("--er", type=non_negative, default=0.0, metavar="M",
                   help="beam effective radius, metres (default 0: no smoothing; below 1)")
    q.add_argument("--trials", type=positive_int, default=1,
                   help=f"draws averaged (default 1, at most {MAX_TRIALS})")
    add_quiet_option(q)
    q.add_argument("--out", metavar="CLOUD.las", help="write the simulated cloud (.las/.laz)")
    q.add_argument("--force", action="store_true", help="overwrite --out")
    add_json_option(q)
    q.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import normalise_population
    from rough_viewer.bias.simulation import predict_bias, simulate_target

    check_simulation(args, noise=[args.noise], ers=[args.er], radii=[target_radius(args)])
    out = check_las_out(args)
    target = layout(args, args.asperity_radius)
    residual = args.residual
    p = predict_bias(noise_sigma_m=args.noise, effective_radius_m=args.er, layout=target,
                     spacing_m=args.spacing, ratio=args.ratio, trials=args.trials,
                     seed=args.seed, residual=residual,
                     progress=progress_bar(args, "bias trials", "trial"))
    sim = simulate_target(target, spacing_m=args.spacing, noise_sigma_m=args.noise,
                          effective_radius_m=args.er, seed=args.seed)
    pop = normalise_population(sim.xyz(), sim.labels(), ratio=args.ratio, seed=args.seed,
                               residual=residual)
    data = prediction_dict(p)
    data.update({"target": args.target, "spacing_m": args.spacing,
                 "n_points": int(sim.asperity.size), "n_asperity": pop.n_asperity,
                 "native_ratio": pop.native_ratio, "roughness_all_points_m": pop.roughness_before,
                 "out": str(out) if out else None})
    if out:
        write_las_atomic(out, sim.xyz(), {"truth": sim.labels().astype(np.uint8)})
    text = prediction_text(p, f"simulated target {args.target}: {sim.asperity.size:,} points, "
                               f"native ratio {pop.native_ratio:.2f} : 1")
    if out:
        text += f"\nwrote {out} (extra dimension 'truth': 1 = asperity)"
    emit(args, data, text)
    return 0
