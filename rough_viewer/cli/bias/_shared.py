"""What the ``bias`` subcommands share: output (text or JSON), loading, the scanner
option, LAS outputs and the simulation options."""

from __future__ import annotations

import argparse
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rough_viewer.cli._options import parse_xyz, positive
from rough_viewer.io import PointCloud, load_points, write_las
from rough_viewer.io.jsonable import dumps
from rough_viewer.io.output import check_output_path, write_path_atomic
from rough_viewer.vocabulary import BIAS_RESIDUAL, RESIDUAL_NAMES, InputError

if TYPE_CHECKING:  # the simulation (and scipy) load when a bias command runs, not on start
    from rough_viewer.bias.simulation import BiasPrediction, TargetLayout


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
    q.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    add_residual_option(q)


def add_residual_option(q: argparse.ArgumentParser) -> None:
    """``--residual signed|absolute``: the roughness convention (default signed, the
    bias paper's own definition); ``--signed`` is kept as an alias of the default."""
    q.add_argument("--residual", choices=("signed", "absolute"), default=BIAS_RESIDUAL,
                   help="signed (default): std of the signed orthogonal distances, the bias "
                   "paper's definition; absolute: std of the absolute distances, the "
                   "grid-roughness convention (SCIENCE.md section 1)")
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


def load(path: str) -> PointCloud:
    """The points of ``path``."""
    return load_points(path)


def scanner_position(args: argparse.Namespace) -> np.ndarray | None:
    """``--scanner X,Y,Z`` as an array, or None."""
    return None if args.scanner is None else np.array(parse_xyz(args.scanner, option="--scanner"))


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
    for e in ers:
        if 0 < e < 0.5 * args.spacing:
            raise InputError(f"effective radius {e:g} m is below half the raster spacing "
                             f"{args.spacing:g} m, too small to smooth; use a finer --spacing")


