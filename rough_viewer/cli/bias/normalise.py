"""``rough-viewer bias normalise``: point-population normalisation of a rough-target scan."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rough_viewer.cli._inputs import add_max_points
from rough_viewer.cli._options import (
    add_units,
    naming,
    non_negative,
    non_negative_int,
    positive,
)
from rough_viewer.cli.bias._shared import (
    MAX_RATIO,
    add_json_option,
    add_residual_option,
    check_count,
    check_las_out,
    check_length,
    emit,
    load,
    residual_fields,
    residual_line,
    scanner_position,
    small,
    write_las_atomic,
)
from rough_viewer.io.load import resolve_units
from rough_viewer.vocabulary import InputError


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``bias normalise`` to the ``bias`` subparsers."""
    q = sub.add_parser("normalise", aliases=["normalize"],
                       help="point-population normalisation of a rough-target scan",
                       description="Classify asperity and background points (K-means on plane "
                       "residuals + 3 sigma, or known classes), thin the background to a fixed "
                       "ratio, refit and report the roughness (and X/Y scores with known classes).")
    q.add_argument("input", metavar="SCAN", help="point cloud of the target, cropped")
    q.add_argument("--classes", choices=("kmeans-3sigma", "kmeans", "truth"),
                   default="kmeans-3sigma", help="how points are classified (default "
                   "kmeans-3sigma; truth = the --truth-dim dimension)")
    q.add_argument("--noise", type=non_negative, metavar="M",
                   help="range noise sigma for the 3-sigma step, in --units (default: "
                   "estimated from the background; below 1 m)")
    q.add_argument("--truth-dim", metavar="NAME",
                   help="LAS extra dimension with known classes (nonzero = asperity); gives "
                   "X and Y scores")
    q.add_argument("--ratio", type=positive, default=5.0,
                   help=f"background : asperity points kept (default 5, at most {MAX_RATIO:g})")
    q.add_argument("--scanner", metavar="X,Y,Z",
                   help="scanner position in --units (default: the side asperities stand "
                   "out on)")
    q.add_argument("--seed", type=non_negative_int, default=0,
                   help="seed of the thinning (default 0)")
    add_residual_option(q)
    q.add_argument("--out", metavar="OUT.las", help="write the kept points (.las/.laz)")
    q.add_argument("--force", action="store_true", help="overwrite --out")
    add_units(q)
    add_max_points(q)
    add_json_option(q)
    q.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import (
        classification_scores,
        classify_population,
        normalise_population,
    )
    from rough_viewer.io import read_las_extra

    out = check_las_out(args)
    # every length given and shown is in the input's unit (--units, else the CRS's)
    unit = resolve_units(args.input, args.units)[0]
    scanner = scanner_position(args, unit)
    noise = None if args.noise is None else check_length(args.noise, "--noise", unit=unit)
    check_count(args.ratio, "--ratio", maximum=MAX_RATIO)
    if args.classes == "truth" and not args.truth_dim:
        raise InputError("--classes truth needs --truth-dim NAME")
    cloud = load(args.input, unit, max_points=args.file_max_points)
    truth = None
    if args.truth_dim:
        if Path(args.input).suffix.lower() not in (".las", ".laz"):
            raise InputError(f"--truth-dim needs a LAS/LAZ file, got {args.input}")
        if cloud.dropped_nonfinite:
            raise InputError(f"{args.input} has non-finite points; cannot align --truth-dim")
        truth = read_las_extra(args.input, args.truth_dim) != 0
    xyz = cloud.xyz()
    residual = args.residual
    with naming(args.input):
        if args.classes == "truth":
            assert truth is not None  # --classes truth needs --truth-dim (checked above)
            asperity = truth
            cls = None
        else:
            cls = classify_population(xyz, noise_sigma=noise, method=args.classes,
                                      scanner=scanner)
            asperity = cls.asperity
        pop = normalise_population(xyz, asperity, ratio=args.ratio, seed=args.seed,
                                   residual=residual)
    data: dict = {"roughness": pop.roughness, "roughness_before": pop.roughness_before,
                  "n_points": int(xyz.shape[0]), "n_asperity": pop.n_asperity,
                  "n_background": pop.n_background, "native_ratio": pop.native_ratio,
                  "ratio": pop.ratio, "classes": args.classes, **residual_fields(residual),
                  "file": str(args.input), "unit": unit, "out": str(out) if out else None}
    if cls is not None:
        data.update({"kmeans_threshold": cls.threshold, "n_reclassified": cls.n_reclassified,
                     "noise_sigma": cls.noise_sigma})
    scores = None
    if truth is not None:
        scores = classification_scores(truth, asperity)
        data.update({"x_score": scores.x_score, "y_score": scores.y_score})
        known = normalise_population(xyz, truth, ratio=args.ratio, seed=args.seed,
                                     residual=residual)
        data["roughness_known_classes"] = known.roughness
    if out:
        write_las_atomic(out, xyz[pop.keep], {"asperity": asperity[pop.keep].astype(np.uint8)})
    lines = [
        f"population normalisation of {args.input} ({args.classes})",
        residual_line(residual),
        f"  {xyz.shape[0]:,} points: {pop.n_asperity:,} asperity, native ratio "
        f"{pop.native_ratio:.2f} : 1 -> {pop.ratio:.2f} : 1",
        f"  roughness before {small(pop.roughness_before, unit)}, after "
        f"{small(pop.roughness, unit)}",
    ]
    if cls is not None:
        lines.append(f"  K-means split {small(cls.threshold, unit)}; {cls.n_reclassified:,} "
                     f"points moved by the 3-sigma step (sigma {small(cls.noise_sigma, unit)})"
                     if args.classes == "kmeans-3sigma" else
                     f"  K-means split {small(cls.threshold, unit)}")
    if scores is not None:
        lines.append(f"  X score {scores.x_score:.2f} %, Y score {scores.y_score:.2f} %; "
                     f"roughness with known classes "
                     f"{small(data['roughness_known_classes'], unit)}")
    if out:
        lines.append(f"wrote {out}")
    emit(args, data, "\n".join(lines))
    return 0
