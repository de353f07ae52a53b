"""What the ``bias`` subcommands share: output (text or JSON), loading, units, the
scanner option, LAS outputs, the simulation options and the ranges every numeric
option must lie in."""

from __future__ import annotations

import argparse
import math
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from rough_viewer.cli._options import non_negative_int, parse_xyz, positive, warn
from rough_viewer.io import PointCloud, load_points, write_las
from rough_viewer.io.jsonable import dumps
from rough_viewer.io.output import check_output_path, write_path_atomic
from rough_viewer.vocabulary import (
    BIAS_RESIDUAL,
    RESIDUAL_NAMES,
    ROUGHNESS_UNIT,
    UNIT_LABELS,
    UNIT_METRES,
    InputError,
    ProgressFn,
    Unit,
)

if TYPE_CHECKING:  # the simulation (and scipy) load when a bias command runs, not on start
    from rough_viewer.bias.simulation import BiasPrediction, TargetLayout

#: Largest length a bias option takes, metres (exclusive): range noise, beam effective
#: radii, asperity and wire radii and raster spacings of real scanners and targets are
#: millimetres to centimetres; a metre is beyond any of them.
MAX_LENGTH_M = 1.0
#: Largest scanner range (``--break-range``), metres: beyond any terrestrial scanner.
MAX_RANGE_M = 10_000.0
#: Most draws ``--trials`` averages: a trial takes about 0.1 s on the paper's target at
#: the default 1 mm spacing, so the limit is a few minutes (a progress bar shows it).
MAX_TRIALS = 1000
#: Largest background : asperity ratio (``--ratio``); the paper used 5, and a ratio
#: above a target's native one keeps every background point anyway.
MAX_RATIO = 1000.0


def check_length(value: float, option: str, *, unit: str = "m", allow_zero: bool = True,
                 maximum_m: float = MAX_LENGTH_M) -> float:
    """``value`` (given in ``unit``) in metres, or InputError naming ``option``.

    The value must be finite, >= 0 (> 0 without ``allow_zero``) and below
    ``maximum_m`` metres.
    """
    per = UNIT_METRES[unit]
    v = float(value) * per
    if not (math.isfinite(v) and (v >= 0 if allow_zero else v > 0) and v < maximum_m):
        low = ">= 0" if allow_zero else "> 0"
        raise InputError(f"{option} must be a length {low} and below {maximum_m / per:g} "
                         f"{UNIT_LABELS[unit]}, got {value:g}")
    return v


def check_count(value: float, option: str, *, maximum: float, low: float = 0.0) -> None:
    """InputError naming ``option`` unless ``low < value <= maximum`` (finite)."""
    if not (math.isfinite(value) and low < value <= maximum):
        raise InputError(f"{option} must be above {low:g} and at most {maximum:g}, "
                         f"got {value:g}")


def check_simulation(args: argparse.Namespace, *, noise: Iterable[float] = (),
                     ers: Iterable[float] = (), radii: Iterable[float] = (),
                     er_option: str = "--er") -> None:
    """The ranges of the simulation options (one-line InputError naming the option):
    lengths finite and below :data:`MAX_LENGTH_M`, ``--ratio`` up to
    :data:`MAX_RATIO`, ``--trials`` up to :data:`MAX_TRIALS`, a raster spacing below
    every asperity radius and effective radii at least half the spacing."""
    ers = list(ers)
    check_length(args.spacing, "--spacing", allow_zero=False)
    check_count(args.ratio, "--ratio", maximum=MAX_RATIO)
    if getattr(args, "trials", None) is not None:
        check_count(args.trials, "--trials", maximum=MAX_TRIALS)
    for v in noise:
        check_length(v, "--noise")
    for v in ers:
        check_length(v, er_option)
    for r in radii:
        r_m = check_length(r, "--asperity-radius", allow_zero=False)
        if not args.spacing < r_m:
            raise InputError(f"--spacing {args.spacing:g} m is not below the asperity radius "
                             f"{r_m:g} m: the raster cannot resolve the hemispheres")
    check_er(args, ers)


def add_quiet_option(q: argparse.ArgumentParser) -> None:
    """``--quiet``: no progress bar."""
    q.add_argument("--quiet", action="store_true", help="no progress bar")


def progress_bar(args: argparse.Namespace, label: str, unit: str) -> ProgressFn | None:
    """A progress bar on stderr (drawn on a terminal only), or None with ``--quiet``."""
    if getattr(args, "quiet", False):
        return None
    from rough_viewer.cli._progress import ProgressBar

    return ProgressBar(label, unit=unit)


def add_json_option(q: argparse.ArgumentParser) -> None:
    """``--json``: print JSON (metres) instead of text."""
    q.add_argument("--json", action="store_true", help="print JSON (metres) instead of text")


def add_simulation_options(q: argparse.ArgumentParser, *, target_default: str | None) -> None:
    """Options of the simulated target: layout, raster spacing, ratio, seed, residual."""
    q.add_argument("--target", choices=("A", "B"), default=target_default,
                   help="the paper's layout: 0.609 x 1.244 m board, 36 hemispheres, "
                   "A r=19 mm, B r=32.5 mm")
    q.add_argument("--spacing", type=positive, default=1e-3, metavar="M",
                   help="raster spacing, metres (default 0.001)")
    q.add_argument("--ratio", type=positive, default=5.0,
                   help="background : asperity points after normalisation (default 5)")
    q.add_argument("--seed", type=non_negative_int, default=0, help="seed (default 0)")
    add_residual_option(q)


def add_residual_option(q: argparse.ArgumentParser) -> None:
    """``--residual signed|absolute``: the roughness convention (default signed, the
    bias paper's own definition); ``--signed`` is kept as an alias of the default."""
    q.add_argument("--residual", choices=("signed", "absolute"), default=BIAS_RESIDUAL,
                   help="signed (default): std of the signed orthogonal distances, the bias "
                   "paper's definition; absolute: std of the absolute distances, the "
                   "grid-roughness convention (docs/science.md section 1)")
    q.add_argument("--signed", dest="residual", action="store_const", const="signed",
                   help=argparse.SUPPRESS)


def residual_fields(residual: str) -> dict[str, str]:
    """JSON fields naming the convention used and the other one."""
    other = "absolute" if residual == "signed" else "signed"
    return {"residual": residual, "residual_definition": RESIDUAL_NAMES[residual],
            "other_residual": f"{other}: {RESIDUAL_NAMES[other]} (--residual {other})"}


def residual_line(residual: str) -> str:
    """One text line naming the convention used and how to get the other."""
    other = "absolute" if residual == "signed" else "signed"
    return (f"  roughness = {RESIDUAL_NAMES[residual]}; --residual {other}: "
            f"{RESIDUAL_NAMES[other]}")


def emit(args: argparse.Namespace, data: dict[str, Any], text: str) -> None:
    """Print ``data`` as JSON with ``--json``, else ``text``."""
    if args.json:
        print(dumps(data, indent=2))
    else:
        print(text)


def mm(v: float) -> str:
    """A length in metres as text in millimetres."""
    return f"{v * 1e3:.3f} mm"


def small_unit(unit: str) -> str:
    """The unit small lengths (noise, radii, offsets) are shown in for input in ``unit``:
    millimetres for metric input, the input's own unit otherwise
    (:data:`rough_viewer.vocabulary.ROUGHNESS_UNIT`, as compute, report and profile)."""
    return ROUGHNESS_UNIT[unit]


def small(v: float, unit: str = "m", *, label: bool = True) -> str:
    """A small length in metres as text in :func:`small_unit` of ``unit``."""
    su = small_unit(unit)
    text = f"{v / UNIT_METRES[su]:.{3 if su == 'mm' else 5}f}"
    return f"{text} {UNIT_LABELS[su]}" if label else text


def load(path: str, units: str | None = None, *, max_points: int | None = None) -> PointCloud:
    """The points of ``path`` read in ``units`` (default: a LAS CRS's, else metres),
    in metres, a compressed file refused beyond the bomb guard's ``max_points``
    (``--max-points``; None: the default); prints the reader's warnings."""
    cloud = load_points(path, units=cast("Unit | None", units),  # argparse checked it
                        max_points=max_points)
    warn(cloud.warnings)
    return cloud


def scanner_position(args: argparse.Namespace, unit: str = "m") -> np.ndarray | None:
    """``--scanner X,Y,Z`` (in ``unit``) as an array in metres, or None."""
    if args.scanner is None:
        return None
    return np.array(parse_xyz(args.scanner, option="--scanner")) * UNIT_METRES[unit]


def check_las_out(args: argparse.Namespace) -> Path | None:
    """The checked ``--out`` LAS/LAZ path, or None."""
    if not args.out:
        return None
    if Path(args.out).suffix.lower() not in (".las", ".laz"):
        raise InputError(f"--out must end in .las or .laz, got {args.out}")
    inputs = [args.input] if getattr(args, "input", None) else []
    return check_output_path(args.out, force=args.force, inputs=inputs)


def write_las_atomic(path: Path, xyz: np.ndarray, extra: dict) -> None:
    """Write a LAS/LAZ atomically (temporary file in the same folder, then rename)."""
    write_path_atomic(path, lambda tmp: write_las(tmp, PointCloud.from_xyz(xyz), extra=extra))


def target_radius(args: argparse.Namespace) -> float:
    """The asperity radius of the run, metres: ``--asperity-radius``, else the target's."""
    from rough_viewer.bias.simulation import PAPER_RADIUS_M

    r = getattr(args, "asperity_radius", None)
    return PAPER_RADIUS_M[args.target or "A"] if r is None else float(r)


def layout(args: argparse.Namespace, radius: float | None) -> TargetLayout:
    """The paper's target layout (``--target``) with an optional asperity radius."""
    from rough_viewer.bias.simulation import paper_target

    return paper_target(args.target or "A", asperity_radius_m=radius, seed=args.seed)


def prediction_dict(p: BiasPrediction) -> dict[str, Any]:
    """The numbers of a bias prediction (JSON output)."""
    keys = ("noise_sigma_m", "effective_radius_m", "asperity_radius_m", "er_ratio", "expected_m",
            "noise_only_m", "smoothing_only_m", "measured_m", "measured_std_m",
            "noise_effect_pct", "smoothing_effect_pct", "total_effect_pct", "vs_noisy_pct",
            "trials", "normalisation", "ratio")
    return {**{k: getattr(p, k) for k in keys}, **residual_fields(p.residual)}


def prediction_text(p: BiasPrediction, title: str) -> str:
    """A bias prediction as text."""
    return "\n".join([
        title,
        f"  noise {mm(p.noise_sigma_m)}, effective radius {mm(p.effective_radius_m)}, "
        f"asperity radius {mm(p.asperity_radius_m)} (ER/r = {p.er_ratio:.3f})",
        f"  normalised to {p.ratio:.2f} : 1, {p.trials} trial(s)",
        residual_line(p.residual),
        f"  expected (true surface)   {mm(p.expected_m)}",
        f"  with noise                {mm(p.noise_only_m)}  ({p.noise_effect_pct:+.2f} %)",
        f"  with beam smoothing       {mm(p.smoothing_only_m)}  "
        f"({p.smoothing_effect_pct:+.2f} %)",
        f"  measured (both)           {mm(p.measured_m)}  ({p.total_effect_pct:+.2f} %; "
        f"{p.vs_noisy_pct:+.2f} % against the noisy simulation)",
    ])


def check_er(args: argparse.Namespace, ers: Iterable[float]) -> None:
    """Refuse effective radii too small to smooth at the raster spacing."""
    for e in list(ers):
        if 0 < e < 0.5 * args.spacing:
            raise InputError(f"effective radius {e:g} m is below half the raster spacing "
                             f"{args.spacing:g} m, too small to smooth; use a finer --spacing")


