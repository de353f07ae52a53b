"""``rough-viewer bias predict``: predict the roughness over- or under-estimate of a scanner."""

from __future__ import annotations

import argparse

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
    check_simulation,
    emit,
    prediction_dict,
    prediction_text,
    progress_bar,
    target_radius,
)
from rough_viewer.vocabulary import BIAS_TRIALS


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``bias predict`` to the ``bias`` subparsers."""
    q = sub.add_parser("predict", help="predict the roughness over/under-estimate",
                       description="Simulate the target true, with noise, with beam smoothing "
                       "and with both; report each roughness and the percentage biases.")
    add_simulation_options(q, target_default=None)
    q.add_argument("--noise", type=non_negative, required=True, metavar="M",
                   help="range noise sigma, metres (below 1)")
    q.add_argument("--er", type=non_negative, required=True, metavar="M",
                   help="beam effective radius, metres (below 1)")
    q.add_argument("--asperity-radius", type=positive, metavar="M",
                   help="hemisphere radius on the paper's layout, metres (default: target A)")
    q.add_argument("--trials", type=positive_int, default=BIAS_TRIALS,
                   help=f"draws averaged (default 3, at most {MAX_TRIALS}; about 0.1 s each "
                   "at 1 mm spacing)")
    add_quiet_option(q)
    add_json_option(q)
    q.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.bias.simulation import predict_paper_target

    check_simulation(args, noise=[args.noise], ers=[args.er], radii=[target_radius(args)])
    # the one path of every prediction on the paper's targets (per-cell ones too)
    p = predict_paper_target(noise_sigma_m=args.noise, effective_radius_m=args.er,
                             target=args.target or "A", asperity_radius_m=args.asperity_radius,
                             spacing_m=args.spacing, ratio=args.ratio, trials=args.trials,
                             seed=args.seed, residual=args.residual,
                             progress=progress_bar(args, "bias trials", "trial"))
    emit(args, prediction_dict(p), prediction_text(p, "predicted roughness bias"))
    return 0
