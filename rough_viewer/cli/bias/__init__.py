"""``rough-viewer bias``: scanner bias on roughness (range noise, beam radius, simulation).

Subcommands (each prints a short text report, or JSON with ``--json``; lengths in
metres in JSON, millimetres in text)::

    rough-viewer bias noise BOARD_SCAN [--segments 8|RxC] [--scanner X,Y,Z]
        [--max-points N] [--seed S] [--json]
    rough-viewer bias radius WIRE_SCAN [WIRE_SCAN ...] [--scanner X,Y,Z]
        [--top-fraction 0.02] [--wire-radius M] [--break-range M] [--json]
    rough-viewer bias simulate [--target A|B] [--asperity-radius M] [--noise M] [--er M]
        [--spacing M] [--ratio 5] [--trials N] [--seed S] [--signed]
        [--out CLOUD.las|.laz] [--force] [--json]
    rough-viewer bias normalise SCAN [--classes kmeans-3sigma|kmeans|truth] [--noise M]
        [--truth-dim truth] [--ratio 5] [--scanner X,Y,Z] [--seed S] [--signed]
        [--out NORMALISED.las|.laz] [--force] [--json]
    rough-viewer bias predict --noise M --er M [--asperity-radius M | --target A|B]
        [--ratio 5] [--trials N] [--spacing M] [--seed S] [--signed] [--json]
    rough-viewer bias curve --noise M --asperity-radius M[,M...] --er-ratio R[,R...]
        [--ratio 5] [--spacing M] [--seed S] [--signed] [--json]

See docs/bias.md.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from rough_viewer.cli._options import parse_xyz
from rough_viewer.io.jsonable import dumps
from rough_viewer.io.output import check_output_path, write_path_atomic
from rough_viewer.vocabulary import InputError


def _positive(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def _non_negative(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return v


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return v


def _list_of(kind):
    def parse(text: str) -> list[float]:
        return [kind(p.strip()) for p in text.split(",") if p.strip()] or [kind("")]
    return parse


def _segments(text: str) -> int | tuple[int, int]:
    t = text.lower().strip()
    try:
        if "x" in t:
            r, c = (int(p) for p in t.split("x"))
            if r >= 1 and c >= 1:
                return (r, c)
        else:
            n = int(t)
            if n >= 1:
                return n
    except ValueError:
        pass
    raise argparse.ArgumentTypeError(f"expected a count (8) or rows x cols (4x2), got {text!r}")


def _emit(args: argparse.Namespace, data: dict, text: str) -> None:
    if args.json:
        print(dumps(data, indent=2))
    else:
        print(text)


def _mm(v: float) -> str:
    return f"{v * 1e3:.3f} mm"


def _load(path: str):
    from rough_viewer.io import load_points

    return load_points(path)


def _scanner(args: argparse.Namespace):
    return None if args.scanner is None else np.array(parse_xyz(args.scanner, option="--scanner"))


def _check_las_out(args: argparse.Namespace) -> Path | None:
    if not args.out:
        return None
    if Path(args.out).suffix.lower() not in (".las", ".laz"):
        raise InputError(f"--out must end in .las or .laz, got {args.out}")
    return check_output_path(args.out, force=args.force)


def _write_las_atomic(path: Path, xyz: np.ndarray, extra: dict) -> None:
    """Write a LAS/LAZ atomically (temporary file in the same folder, then rename)."""
    from rough_viewer.io import PointCloud, write_las

    write_path_atomic(path, lambda tmp: write_las(tmp, PointCloud.from_xyz(xyz), extra=extra))


# ------------------------------------------------------------------------------ register


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bias",
        help="scanner bias: range noise, beam effective radius, rough-target simulation",
        description="Measure a scanner's range noise (flat board) and beam effective radius "
        "(thin wire), simulate rough targets and predict how noise and beam smoothing bias "
        "roughness (SCIENCE.md section 3, docs/bias.md).",
    )
    s = p.add_subparsers(dest="bias_command", metavar="SUBCOMMAND", parser_class=type(p))
    p.set_defaults(func=lambda a: (p.print_help(), 2)[1])

    def common(q: argparse.ArgumentParser) -> None:
        q.add_argument("--json", action="store_true", help="print JSON (metres) instead of text")

    q = s.add_parser("noise", help="range noise from the scan of a flat board",
                     description="Split the board into equal segments, fit a plane to each, "
                     "report the standard deviation of all residuals and per-segment values.")
    q.add_argument("input", metavar="BOARD_SCAN", help="point cloud of the board, cropped")
    q.add_argument("--segments", type=_segments, default=8, metavar="N|RxC",
                   help="number of equal segments, or rows x cols along the long x short "
                   "axis (default 8)")
    q.add_argument("--scanner", metavar="X,Y,Z", help="scanner position (orients offsets)")
    q.add_argument("--max-points", type=_positive_int, metavar="N",
                   help="random subsample of N points (the paper: 180000)")
    q.add_argument("--seed", type=int, default=0, help="seed of the subsample (default 0)")
    common(q)
    q.set_defaults(func=run_noise)

    q = s.add_parser("radius", help="beam effective radius from scans of a thin wire",
                     description="Line fit per wire scan, residuals across the wire and the "
                     "view, mean of the top fraction of magnitudes. With 4 or more scans, a "
                     "piecewise-linear fit of radius against range.")
    q.add_argument("inputs", nargs="+", metavar="WIRE_SCAN", help="point cloud(s) of the wire")
    q.add_argument("--scanner", default="0,0,0", metavar="X,Y,Z",
                   help="scanner position in the scans' frame (default 0,0,0)")
    q.add_argument("--top-fraction", type=_positive, default=0.02, metavar="F",
                   help="fraction of largest residuals averaged (default 0.02)")
    q.add_argument("--wire-radius", type=_non_negative, default=0.0, metavar="M",
                   help="wire radius subtracted, metres (default 0, as the paper)")
    q.add_argument("--break-range", type=_positive, metavar="M",
                   help="break point of the piecewise fit, metres (default: least squares)")
    common(q)
    q.set_defaults(func=run_radius)

    def sim_options(q: argparse.ArgumentParser, *, target_default: str | None) -> None:
        q.add_argument("--target", choices=("A", "B"), default=target_default,
                       help="the paper's layout: 0.609 x 1.244 m board, 36 hemispheres, "
                       "A r=19 mm, B r=32.5 mm")
        q.add_argument("--spacing", type=_positive, default=1e-3, metavar="M",
                       help="raster spacing, metres (default 0.001)")
        q.add_argument("--ratio", type=_positive, default=5.0,
                       help="background : asperity points after normalisation (default 5)")
        q.add_argument("--seed", type=int, default=0, help="seed (default 0)")
        q.add_argument("--signed", action="store_true",
                       help="roughness as the std of signed distances (the paper's "
                       "published numbers) instead of absolute ones")

    q = s.add_parser("simulate", help="simulate a rough target: noise, beam smoothing",
                     description="Simulate the paper's target (or another asperity radius "
                     "on its layout), report expected and measured roughness, optionally "
                     "write the simulated cloud with a 'truth' dimension (1 = asperity).")
    sim_options(q, target_default="A")
    q.add_argument("--asperity-radius", type=_positive, metavar="M",
                   help="hemisphere radius, metres (default: the target's)")
    q.add_argument("--noise", type=_non_negative, default=0.0016, metavar="M",
                   help="range noise sigma, metres (default 0.0016)")
    q.add_argument("--er", type=_non_negative, default=0.0, metavar="M",
                   help="beam effective radius, metres (default 0: no smoothing)")
    q.add_argument("--trials", type=_positive_int, default=1, help="draws averaged (default 1)")
    q.add_argument("--out", metavar="CLOUD.las", help="write the simulated cloud (.las/.laz)")
    q.add_argument("--force", action="store_true", help="overwrite --out")
    common(q)
    q.set_defaults(func=run_simulate)

    q = s.add_parser("normalise", aliases=["normalize"],
                     help="point-population normalisation of a rough-target scan",
                     description="Classify asperity and background points (K-means on plane "
                     "residuals + 3 sigma, or known classes), thin the background to a fixed "
                     "ratio, refit and report the roughness (and X/Y scores with known classes).")
    q.add_argument("input", metavar="SCAN", help="point cloud of the target, cropped")
    q.add_argument("--classes", choices=("kmeans-3sigma", "kmeans", "truth"),
                   default="kmeans-3sigma", help="how points are classified (default "
                   "kmeans-3sigma; truth = the --truth-dim dimension)")
    q.add_argument("--noise", type=_non_negative, metavar="M",
                   help="range noise sigma for the 3-sigma step, metres (default: estimated "
                   "from the background)")
    q.add_argument("--truth-dim", metavar="NAME",
                   help="LAS extra dimension with known classes (nonzero = asperity); gives "
                   "X and Y scores")
    q.add_argument("--ratio", type=_positive, default=5.0,
                   help="background : asperity points kept (default 5)")
    q.add_argument("--scanner", metavar="X,Y,Z",
                   help="scanner position (default: the side asperities stand out on)")
    q.add_argument("--seed", type=int, default=0, help="seed of the thinning (default 0)")
    q.add_argument("--signed", action="store_true", help="std of signed distances")
    q.add_argument("--out", metavar="OUT.las", help="write the kept points (.las/.laz)")
    q.add_argument("--force", action="store_true", help="overwrite --out")
    common(q)
    q.set_defaults(func=run_normalise)

    q = s.add_parser("predict", help="predict the roughness over/under-estimate",
                     description="Simulate the target true, with noise, with beam smoothing "
                     "and with both; report each roughness and the percentage biases.")
    sim_options(q, target_default=None)
    q.add_argument("--noise", type=_non_negative, required=True, metavar="M",
                   help="range noise sigma, metres")
    q.add_argument("--er", type=_non_negative, required=True, metavar="M",
                   help="beam effective radius, metres")
    q.add_argument("--asperity-radius", type=_positive, metavar="M",
                   help="hemisphere radius on the paper's layout, metres (default: target A)")
    q.add_argument("--trials", type=_positive_int, default=3, help="draws averaged (default 3)")
    common(q)
    q.set_defaults(func=run_predict)

    q = s.add_parser("curve", help="roughness error against ER / asperity radius (Fig. 4)",
                     description="For each asperity radius, the roughness error at each "
                     "ratio of effective radius to asperity radius.")
    sim_options(q, target_default=None)
    q.add_argument("--noise", type=_non_negative, default=0.0016, metavar="M",
                   help="range noise sigma, metres (default 0.0016)")
    q.add_argument("--asperity-radius", type=_list_of(_positive), default=[0.019, 0.0325],
                   metavar="M[,M...]", help="hemisphere radii, metres (default 0.019,0.0325)")
    q.add_argument("--er-ratio", type=_list_of(_non_negative),
                   default=[0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5], metavar="R[,R...]",
                   help="effective radius / asperity radius values (default 0..0.5)")
    common(q)
    q.set_defaults(func=run_curve)


# ------------------------------------------------------------------------------ run


def run_noise(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import range_noise

    scanner = _scanner(args)
    cloud = _load(args.input)
    try:
        r = range_noise(cloud.xyz(), segments=args.segments, scanner=scanner,
                        max_points=args.max_points, seed=args.seed)
    except ValueError as exc:
        raise InputError(f"{exc} ({args.input})") from None
    segs = [
        {"row": s.row, "col": s.col, "n_points": s.n_points, "sigma": s.sigma,
         "offset": s.offset, "tilt_deg": s.tilt_deg, "centre": s.centre}
        for s in r.segments
    ]
    data = {"sigma": r.sigma, "sigma_single_plane": r.sigma_single_plane,
            "n_points": r.n_points, "shape": list(r.shape), "segments": segs,
            "normal": r.normal, "file": str(args.input)}
    lines = [
        f"range noise of {args.input}: sigma = {_mm(r.sigma)} "
        f"({r.n_points:,} points, {r.shape[0]} x {r.shape[1]} segments)",
        f"one plane over the whole board: {_mm(r.sigma_single_plane)}"
        + ("  (board looks curved)" if r.sigma_single_plane > 1.05 * r.sigma else ""),
        "row col   points   sigma mm  offset mm  tilt deg",
    ]
    lines += [f"{s.row:3d} {s.col:3d} {s.n_points:8d} {s.sigma * 1e3:10.3f} "
              f"{s.offset * 1e3:10.3f} {s.tilt_deg:9.3f}" for s in r.segments]
    _emit(args, data, "\n".join(lines))
    return 0


def run_radius(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import effective_radius, fit_piecewise_linear

    scanner = np.array(parse_xyz(args.scanner, option="--scanner"))
    if not args.top_fraction <= 1.0:
        raise InputError(f"--top-fraction must be in (0, 1], got {args.top_fraction:g}")
    if args.break_range is not None and len(args.inputs) < 4:
        raise InputError("--break-range needs at least 4 wire scans (a piecewise fit)")
    scans = []
    for path in args.inputs:
        cloud = _load(path)
        try:
            e = effective_radius(cloud.xyz(), scanner=scanner, top_fraction=args.top_fraction,
                                 wire_radius=args.wire_radius)
        except ValueError as exc:
            raise InputError(f"{exc} ({path})") from None
        scans.append({"file": str(path), "effective_radius": e.effective_radius,
                      "range": e.range, "n_points": e.n_points, "n_top": e.n_top,
                      "top_fraction": e.top_fraction, "residual_std": e.residual_std,
                      "wire_radius": e.wire_radius, "direction": e.direction})
    fit = None
    if len(scans) >= 4:
        try:
            f = fit_piecewise_linear([s["range"] for s in scans],
                                     [s["effective_radius"] for s in scans],
                                     break_range=args.break_range)
        except ValueError as exc:
            raise InputError(f"piecewise fit: {exc}") from None
        fit = {"break_range": f.break_range, "intercept": f.intercept,
               "slope_near": f.slope_near, "slope_far": f.slope_far, "rmse": f.rmse,
               "break_given": f.break_given, "n": f.n}
    data: dict = {}
    if len(scans) == 1:
        data.update({k: scans[0][k] for k in ("effective_radius", "range", "n_points", "n_top",
                                              "top_fraction", "residual_std", "wire_radius",
                                              "file")})
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
            f"above; rmse {_mm(fit['rmse'])}")
    elif len(scans) > 1:
        lines.append("(a piecewise-linear fit needs at least 4 scans)")
    _emit(args, data, "\n".join(lines))
    return 0


def _layout(args: argparse.Namespace, radius: float | None):
    from rough_viewer.bias.simulation import paper_target

    return paper_target(args.target or "A", asperity_radius_m=radius, seed=args.seed)


def _prediction_dict(p) -> dict:
    keys = ("noise_sigma_m", "effective_radius_m", "asperity_radius_m", "er_ratio", "expected_m",
            "noise_only_m", "smoothing_only_m", "measured_m", "measured_std_m",
            "noise_effect_pct", "smoothing_effect_pct", "total_effect_pct", "vs_noisy_pct",
            "trials", "normalisation", "ratio", "residual")
    return {k: getattr(p, k) for k in keys}


def _prediction_text(p, title: str) -> str:
    return "\n".join([
        title,
        f"  noise {_mm(p.noise_sigma_m)}, effective radius {_mm(p.effective_radius_m)}, "
        f"asperity radius {_mm(p.asperity_radius_m)} (ER/r = {p.er_ratio:.3f})",
        f"  normalised to {p.ratio:.2f} : 1, {p.trials} trial(s), {p.residual} distances",
        f"  expected (true surface)   {_mm(p.expected_m)}",
        f"  with noise                {_mm(p.noise_only_m)}  ({p.noise_effect_pct:+.2f} %)",
        f"  with beam smoothing       {_mm(p.smoothing_only_m)}  "
        f"({p.smoothing_effect_pct:+.2f} %)",
        f"  measured (both)           {_mm(p.measured_m)}  ({p.total_effect_pct:+.2f} %; "
        f"{p.vs_noisy_pct:+.2f} % against the noisy simulation)",
    ])


def _check_er(args: argparse.Namespace, ers) -> None:
    for e in ers:
        if 0 < e < 0.5 * args.spacing:
            raise InputError(f"effective radius {e:g} m is below half the raster spacing "
                             f"{args.spacing:g} m, too small to smooth; use a finer --spacing")


def run_predict(args: argparse.Namespace) -> int:
    from rough_viewer.bias.simulation import predict_bias

    _check_er(args, [args.er])
    try:
        p = predict_bias(noise_sigma_m=args.noise, effective_radius_m=args.er,
                         layout=_layout(args, args.asperity_radius), spacing_m=args.spacing,
                         ratio=args.ratio, trials=args.trials, seed=args.seed,
                         residual="signed" if args.signed else "absolute")
    except ValueError as exc:
        raise InputError(str(exc)) from None
    _emit(args, _prediction_dict(p), _prediction_text(p, "predicted roughness bias"))
    return 0


def run_simulate(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import normalise_population
    from rough_viewer.bias.simulation import predict_bias, simulate_target

    out = _check_las_out(args)
    _check_er(args, [args.er])
    layout = _layout(args, args.asperity_radius)
    residual = "signed" if args.signed else "absolute"
    try:
        p = predict_bias(noise_sigma_m=args.noise, effective_radius_m=args.er, layout=layout,
                         spacing_m=args.spacing, ratio=args.ratio, trials=args.trials,
                         seed=args.seed, residual=residual)
        sim = simulate_target(layout, spacing_m=args.spacing, noise_sigma_m=args.noise,
                              effective_radius_m=args.er, seed=args.seed)
        pop = normalise_population(sim.xyz(), sim.labels(), ratio=args.ratio, seed=args.seed,
                                   residual=residual)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    data = _prediction_dict(p)
    data.update({"target": args.target, "spacing_m": args.spacing,
                 "n_points": int(sim.asperity.size), "n_asperity": pop.n_asperity,
                 "native_ratio": pop.native_ratio, "roughness_all_points_m": pop.roughness_before,
                 "out": str(out) if out else None})
    if out:
        _write_las_atomic(out, sim.xyz(), {"truth": sim.labels().astype(np.uint8)})
    text = _prediction_text(p, f"simulated target {args.target}: {sim.asperity.size:,} points, "
                               f"native ratio {pop.native_ratio:.2f} : 1")
    if out:
        text += f"\nwrote {out} (extra dimension 'truth': 1 = asperity)"
    _emit(args, data, text)
    return 0


def run_normalise(args: argparse.Namespace) -> int:
    from rough_viewer.bias.measurement import (
        classification_scores,
        classify_population,
        normalise_population,
    )
    from rough_viewer.io import read_las_extra

    out = _check_las_out(args)
    scanner = _scanner(args)
    if args.classes == "truth" and not args.truth_dim:
        raise InputError("--classes truth needs --truth-dim NAME")
    cloud = _load(args.input)
    truth = None
    if args.truth_dim:
        if Path(args.input).suffix.lower() not in (".las", ".laz"):
            raise InputError(f"--truth-dim needs a LAS/LAZ file, got {args.input}")
        if cloud.dropped_nonfinite:
            raise InputError(f"{args.input} has non-finite points; cannot align --truth-dim")
        truth = read_las_extra(args.input, args.truth_dim) != 0
    xyz = cloud.xyz()
    residual = "signed" if args.signed else "absolute"
    try:
        if args.classes == "truth":
            asperity = truth
            cls = None
        else:
            cls = classify_population(xyz, noise_sigma=args.noise, method=args.classes,
                                      scanner=scanner)
            asperity = cls.asperity
        pop = normalise_population(xyz, asperity, ratio=args.ratio, seed=args.seed,
                                   residual=residual)
    except ValueError as exc:
        raise InputError(f"{exc} ({args.input})") from None
    data: dict = {"roughness": pop.roughness, "roughness_before": pop.roughness_before,
                  "n_points": int(xyz.shape[0]), "n_asperity": pop.n_asperity,
                  "n_background": pop.n_background, "native_ratio": pop.native_ratio,
                  "ratio": pop.ratio, "classes": args.classes, "residual": residual,
                  "file": str(args.input), "out": str(out) if out else None}
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
        _write_las_atomic(out, xyz[pop.keep], {"asperity": asperity[pop.keep].astype(np.uint8)})
    lines = [
        f"population normalisation of {args.input} ({args.classes}, {residual} distances)",
        f"  {xyz.shape[0]:,} points: {pop.n_asperity:,} asperity, native ratio "
        f"{pop.native_ratio:.2f} : 1 -> {pop.ratio:.2f} : 1",
        f"  roughness before {_mm(pop.roughness_before)}, after {_mm(pop.roughness)}",
    ]
    if cls is not None:
        lines.append(f"  K-means split {_mm(cls.threshold)}; {cls.n_reclassified:,} points moved "
                     f"by the 3-sigma step (sigma {_mm(cls.noise_sigma)})"
                     if args.classes == "kmeans-3sigma" else
                     f"  K-means split {_mm(cls.threshold)}")
    if scores is not None:
        lines.append(f"  X score {scores.x_score:.2f} %, Y score {scores.y_score:.2f} %; "
                     f"roughness with known classes {_mm(data['roughness_known_classes'])}")
    if out:
        lines.append(f"wrote {out}")
    _emit(args, data, "\n".join(lines))
    return 0


def run_curve(args: argparse.Namespace) -> int:
    from rough_viewer.bias.simulation import smoothing_curve

    curves = []
    ratios = np.asarray(args.er_ratio, dtype=np.float64)
    for r in args.asperity_radius:
        _check_er(args, ratios * r)
        try:
            c = smoothing_curve(ratios * r, layout=_layout(args, r), noise_sigma_m=args.noise,
                                spacing_m=args.spacing, ratio=args.ratio, seed=args.seed,
                                residual="signed" if args.signed else "absolute")
        except ValueError as exc:
            raise InputError(str(exc)) from None
        curves.append({"asperity_radius_m": c.asperity_radius_m, "er_ratio": c.er_ratio,
                       "effective_radius_m": c.effective_radius_m, "expected_m": c.expected_m,
                       "noise_only_m": c.noise_only_m, "measured_m": c.measured_m,
                       "error_pct": c.error_pct, "vs_noisy_pct": c.vs_noisy_pct})
    data = {"noise_sigma_m": args.noise, "ratio": args.ratio,
            "residual": "signed" if args.signed else "absolute", "curves": curves}
    lines = [f"roughness error against ER / asperity radius (noise {_mm(args.noise)}); "
             "percent of the noise-free / noisy expected value"]
    for c in curves:
        lines.append(f"asperity radius {_mm(c['asperity_radius_m'])}: expected "
                     f"{_mm(c['expected_m'])}, with noise {_mm(c['noise_only_m'])}")
        lines.append(f"  {'ER/r':>6} {'ER mm':>8} {'measured mm':>12} {'vs true %':>10} "
                     f"{'vs noisy %':>11}")
        for k in range(len(c["er_ratio"])):
            lines.append(f"  {c['er_ratio'][k]:6.3f} {c['effective_radius_m'][k] * 1e3:8.3f} "
                         f"{c['measured_m'][k] * 1e3:12.3f} {c['error_pct'][k]:10.2f} "
                         f"{c['vs_noisy_pct'][k]:11.2f}")
    _emit(args, data, "\n".join(lines))
    return 0
