"""``rough-viewer profile``: a roughness profile, its wavelet de-noising and fractal dimension.

Contract::

    rough-viewer profile INPUT --from X,Y,Z --to X,Y,Z [--band M] [--spacing M]
        [--max-gap M] [--windows W1,W2,...|default|paper] [--wavelet db3] [--level 3]
        [--json] [--csv OUT.csv] [--force]
    rough-viewer profile PROFILE.txt [--profile-file] [--profile-units m|mm] ...

INPUT is a point cloud (any format ``load_points`` reads) and the profile is
extracted between the two points; or a two-column text file (distance, height), used
as it is (``--profile-file``, or detected when a text file has exactly two columns).

``--windows`` sets the roughness-length windows: lengths in the input's unit, or
``default`` (8 evenly in log from 3 % to 30 % of the profile) or ``paper`` (the
paper's 8 from 3 % to 10 %); docs/profiles.md says why the default is wider.

Prints the profile's Z2 (RMS slope) and its JRC estimate (Tse and Cruden 1979), the
noise sigma, the thresholds and the fractal dimension D of the raw profile and of
every decomposition x threshold x mode (the layout of Khoshelham & Altundag's
Tables 1 and 2 side by side); ``--json`` prints the same numbers as JSON (metres);
``--csv`` writes the samples: distance, raw and one column per de-noised variant.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from rough_viewer.cli._options import add_units, add_windows, naming, parse_xyz, per_unit, warn
from rough_viewer.io.jsonable import to_jsonable
from rough_viewer.io.output import check_output_path, write_atomic
from rough_viewer.vocabulary import InputError

_PROFILE_SUFFIXES = (".txt", ".csv", ".dat", ".xyz", ".prof", ".tsv")
_RULE_LABEL = {
    "fixed": ("Fixed-form", ""),
    "penalized-low": ("Penalized", "Low"),
    "penalized-medium": ("Penalized", "Med."),
    "penalized-high": ("Penalized", "High"),
}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "profile",
        help="profile along a line: wavelet de-noising and fractal dimension",
        description="Extract a roughness profile between two points of a cloud (or read "
        "a distance,height profile file), de-noise it with wavelets (DWT and wavelet "
        "packets; fixed and penalized thresholds; hard and soft) and report the fractal "
        "dimension of each version by the roughness-length method (docs/science.md, "
        "profiles).",
    )
    p.add_argument("input", help="point cloud (.las .laz .xyz .txt .csv .pts .npy .ply .stl) "
                   "or a two-column profile file (distance height)")
    p.add_argument("--from", dest="start", metavar="X,Y,Z", help="line start (cloud input); write --from=-1,2,3 when X is negative")
    p.add_argument("--to", dest="end", metavar="X,Y,Z", help="line end (cloud input); --to=-1,2,3 when X is negative")
    p.add_argument("--band", type=float, metavar="M",
                   help="band half-width around the line, in --units (default: local point "
                   "spacing)")
    p.add_argument("--spacing", type=float, metavar="M",
                   help="sample spacing, in --units (default: local point spacing; for a "
                   "profile file: its median step)")
    p.add_argument("--max-gap", type=float, metavar="M",
                   help="longest stretch without points interpolated across, in --units "
                   "(default: 3 spacings); longer gaps are NaN and reported")
    p.add_argument("--detrend", type=int, metavar="DEGREE",
                   help="remove a least-squares polynomial trend of this degree from the "
                   "profile first (2 removes a curvature that makes D < 1)")
    add_windows(p)
    p.add_argument("--wavelet", default="db3", help="PyWavelets discrete wavelet (default db3)")
    p.add_argument("--level", type=int, default=3, help="decomposition levels (default 3)")
    p.add_argument("--profile-file", action="store_true",
                   help="INPUT is a two-column text profile (distance, height)")
    p.add_argument("--profile-units", choices=("m", "mm"), default=None,
                   help="units of a profile file's columns (default: --units, else m)")
    add_units(p)
    p.add_argument("--json", action="store_true", help="print the numbers as JSON (metres, "
                   "keys ending in _m; 'unit' names the input's unit)")
    p.add_argument("--csv", metavar="OUT.csv", help="write the samples, raw and de-noised")
    p.add_argument("--force", action="store_true", help="overwrite an existing --csv file")
    p.set_defaults(func=run)


# ----------------------------------------------------------------------------- input


def _two_column_text(path: Path) -> bool:
    """True when ``path`` is a text file whose first data line has exactly 2 numbers."""
    if path.suffix.lower() not in _PROFILE_SUFFIXES:
        return False
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for line in fh:
                text = line.split("#", 1)[0].strip()
                if not text:
                    continue
                fields = [f for f in text.replace(",", " ").replace(";", " ").split() if f]
                try:
                    [float(f) for f in fields]
                except ValueError:
                    continue  # a header line
                return len(fields) == 2
    except OSError:
        return False
    return False


def read_profile_file(path: Path, *, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Read ``distance height`` rows (whitespace, comma or semicolon separated; ``#``
    comments and header lines skipped), times ``scale``, as metres."""
    if not path.is_file():
        raise InputError(f"no such file: {path}")
    rows: list[list[float]] = []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, line in enumerate(fh, 1):
            text = line.split("#", 1)[0].strip()
            if not text:
                continue
            fields = [f for f in text.replace(",", " ").replace(";", " ").split() if f]
            try:
                values = [float(f) for f in fields]
            except ValueError:
                if rows:
                    raise InputError(f"line {number} of {path} is not two numbers: {text!r}") from None
                continue  # header
            if len(values) != 2:
                raise InputError(
                    f"line {number} of {path} has {len(values)} columns; a profile file has 2 "
                    "(distance height)"
                )
            rows.append(values)
    if len(rows) < 2:
        raise InputError(f"no profile samples (distance height) in {path}")
    data = np.asarray(rows, dtype=float) * scale
    return data[:, 0], data[:, 1]


# ----------------------------------------------------------------------------- output


def _fit_dict(fit) -> dict:
    if fit is None:
        return {"dimension": None, "hurst": None, "amplitude": None, "r2": None}
    return {
        "dimension": to_jsonable(fit.dimension),
        "hurst": to_jsonable(fit.hurst),
        "amplitude": to_jsonable(fit.amplitude),
        "r2": to_jsonable(fit.r2),
    }


def result_dict(info: dict, comparison) -> dict:
    """The ``--json`` document (metres)."""
    return {
        **info,
        "wavelet": comparison.wavelet,
        "level": comparison.level,
        "sigma_m": comparison.sigma,
        "thresholds_m": comparison.thresholds(),
        "windows_m": [float(w) for w in comparison.raw.windows],
        "raw": _fit_dict(comparison.raw),
        "variants": [
            {
                "decomposition": v.decomposition,
                "threshold": v.threshold_rule,
                "mode": v.mode,
                "threshold_m": v.denoised.threshold,
                **_fit_dict(v.fractal),
                "rms_change_m": to_jsonable(v.rms_change),
                "coefficients_kept": v.denoised.n_kept,
                "coefficients": v.denoised.n_coefficients,
            }
            for v in comparison.variants
        ],
    }


def _d(fit) -> str:
    return "   -" if fit is None else f"{fit.dimension:5.2f}"


def display_units(unit: str) -> tuple[float, str, float, str]:
    """(per metre, label) of the unit for lengths and of the one for small values
    (thresholds, noise, band): metres and millimetres for a metric input, the
    input's unit otherwise."""
    from rough_viewer.vocabulary import roughness_scale, unit_scale

    (f, u), (rf, ru) = unit_scale(unit), roughness_scale(unit)
    return 1.0 / f, u, 1.0 / rf, ru


def format_tables(info: dict, comparison) -> str:
    """Text report: header and the Tables 1-2 layout (DWT and WP side by side); lengths
    in the input's unit (``info["unit"]``), small values in mm for metric input."""
    big, ub, mm, uf = display_units(info.get("unit", "m"))
    lines = [f"profile: {info['input']}"]
    if info["source"] == "cloud":
        lines.append(
            f"  from {tuple(info['from_given'])} to {tuple(info['to_given'])}; local normal "
            f"({', '.join(f'{c:.3f}' for c in info['normal'])})"
        )
        lines.append(
            f"  {info['points']} points in a band of +-{info['band_half_width_m'] * mm:.3f} "
            f"{uf} (point spacing {info['point_spacing_m'] * mm:.3f} {uf})"
        )
    lines.append(
        f"  length {info['length_m'] * big:.4f} {ub}, {info['samples']} samples at "
        f"{info['spacing_m'] * mm:.3f} {uf}"
        + (", resampled" if info.get("resampled") else "")
        + (f", degree-{info['detrend']} trend removed" if info.get("detrend") is not None
           else "")
    )
    gaps = info["gaps_m"]
    if gaps:
        spans = ", ".join(f"{a * big:.4f}-{b * big:.4f}" for a, b in gaps[:5]) + (
            " ..." if len(gaps) > 5 else "")
        lines.append(
            f"  {len(gaps)} gap(s) not interpolated ({info['nan_samples']} NaN samples): "
            f"{spans} {ub}"
        )
    else:
        lines.append("  no gaps")
    if info.get("z2") is not None:
        lines.append(f"  Z2 (RMS slope) {info['z2']:.4f}; JRC estimate {info['jrc_estimate']:.1f} "
                     "(Tse and Cruden 1979, for profiles sampled at 0.5-1 mm)")
    raw = comparison.raw
    w = comparison.raw.windows
    lines.append(
        f"wavelet {comparison.wavelet}, {comparison.level} levels; noise sigma (MAD of level-1 "
        f"details) {comparison.sigma * mm:.4f} {uf}"
    )
    wf, wu = (mm, uf) if w[-1] * mm < 1000 else (big, ub)
    lines.append(
        f"roughness length: {w.size} windows {w[0] * wf:.4g}-{w[-1] * wf:.4g} {wu}; D = 2 - H"
    )
    lines.append("")
    head = f"{'':34s}{'DWT (Table 1)':>22s}{'Wavelet packets (Table 2)':>28s}"
    sub = f"{'':34s}{'thresh ' + uf:>12s}{'D':>8s}{'':>4s}{'thresh ' + uf:>14s}{'D':>8s}"
    lines += [head, sub]
    lines.append(f"{'Original profile':34s}{'':12s}{_d(raw):>8s}{'':4s}{'':14s}{_d(raw):>8s}")
    for mode, label in (("soft", "Soft thresh."), ("hard", "Hard thresh.")):
        for i, rule in enumerate(("fixed", "penalized-low", "penalized-medium", "penalized-high")):
            a, b = _RULE_LABEL[rule]
            first = label if i == 0 else ""
            name = f"{first:14s}{a if i < 2 else '':12s}{b:8s}"
            cells = []
            for dec in ("dwt", "wp"):
                try:
                    v = comparison.variant(dec, rule, mode)
                except KeyError:
                    cells.append(("", "   -"))
                    continue
                cells.append((f"{v.denoised.threshold * mm:.4f}", _d(v.fractal)))
            lines.append(
                f"{name:34s}{cells[0][0]:>12s}{cells[0][1]:>8s}{'':4s}{cells[1][0]:>14s}{cells[1][1]:>8s}"
            )
    return "\n".join(lines)


def write_samples_csv(path: Path, distance: np.ndarray, raw: np.ndarray, comparison) -> None:
    """distance_m, raw_m and one ``<dec>_<threshold>_<mode>_m`` column per variant; NaN empty."""
    cols = [distance, raw] + [v.denoised.heights for v in comparison.variants]
    names = ["distance_m", "raw_m"] + [f"{v.key}_m" for v in comparison.variants]
    text = []
    for c in cols:
        t = np.asarray(c, dtype=float).astype(str)
        t[~np.isfinite(c)] = ""
        text.append(t.tolist())

    def write(fh) -> None:
        fh.write(",".join(names) + "\n")
        for row in zip(*text, strict=True):
            fh.write(",".join(row) + "\n")

    write_atomic(path, write)


# ----------------------------------------------------------------------------- run


def _positive_option(value: float | None, option: str) -> float | None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise InputError(f"{option} must be a positive length, got {value:g}")
    return value


def _metres(args: argparse.Namespace, per: float) -> None:
    """Lengths given on the command line (in the input's unit) into metres."""
    for option in ("band", "spacing", "max_gap"):
        value = getattr(args, option)
        if value is not None:
            setattr(args, option, value * per)


def _check_options(args: argparse.Namespace) -> None:
    import pywt

    for option in ("band", "spacing", "max_gap"):
        _positive_option(getattr(args, option), "--" + option.replace("_", "-"))
    if args.wavelet not in pywt.wavelist(kind="discrete"):
        raise InputError(f"--wavelet {args.wavelet!r} is not a discrete PyWavelets wavelet (e.g. db3, sym4, haar)")
    from rough_viewer.profiles.wavelets import MAX_LEVEL

    if not 1 <= args.level <= MAX_LEVEL:
        raise InputError(f"--level must be from 1 to {MAX_LEVEL} (a level-L decomposition "
                         f"needs profiles of 2**L samples or more), got {args.level}")
    if args.windows is not None:
        from rough_viewer.profiles.fractal import parse_windows

        parse_windows(args.windows)  # the form, before any reading; the unit comes later
    if args.detrend is not None and not 0 <= args.detrend <= 5:
        raise InputError(f"--detrend must be a degree from 0 to 5, got {args.detrend}")


Samples = tuple[np.ndarray, np.ndarray, tuple[tuple[float, float], ...], float, dict[str, Any]]


def _from_profile_file(args: argparse.Namespace, path: Path) -> Samples:
    """Heights of a two-column profile file, resampled at a regular spacing."""
    from rough_viewer.profiles.extraction import regular_samples

    if args.start or args.end:
        raise InputError(f"--from/--to are for point clouds; {path} is a profile file")
    from rough_viewer.vocabulary import UNIT_METRES

    unit = args.profile_units or args.units or "m"
    per = UNIT_METRES[unit]
    _metres(args, per)
    d_in, h_in = read_profile_file(path, scale=per)
    with naming(path):
        distance, heights, gaps = regular_samples(d_in, h_in, spacing=args.spacing,
                                                  max_gap=args.max_gap)
    step = float(np.median(np.diff(distance)))
    info: dict[str, Any] = {
        "input": str(path),
        "unit": unit,
        "source": "profile-file",
        "samples": int(distance.size),
        "spacing_m": step,
        "length_m": float(distance[-1] - distance[0]),
        "resampled": distance.size != d_in.size or not np.array_equal(distance, d_in),
    }
    return distance, heights, gaps, step, info


def _from_cloud(args: argparse.Namespace, path: Path) -> Samples:
    """The profile of a point cloud along ``--from`` .. ``--to``."""
    from rough_viewer.io import load_points
    from rough_viewer.profiles.extraction import extract_profile

    if not (args.start and args.end):
        raise InputError(f"{path} is a point cloud: give the line with --from X,Y,Z --to X,Y,Z")
    g0 = parse_xyz(args.start, option="--from")
    g1 = parse_xyz(args.end, option="--to")
    if args.spacing is not None:  # before the read: line and spacing are in one unit
        from rough_viewer.profiles.comparison import require_comparison

        length = math.dist(g0, g1)
        if math.isfinite(length):
            require_comparison(round(min(length / args.spacing, 1e18)) + 1,
                               f"--spacing {args.spacing:g}")
    cloud = load_points(path, units=args.units)
    warn(cloud.warnings)
    per = per_unit(cloud.source_unit)
    p0 = tuple(c * per for c in g0)
    p1 = tuple(c * per for c in g1)
    _metres(args, per)
    with naming(path):
        prof = extract_profile(cloud, p0, p1, band_half_width=args.band, spacing=args.spacing,
                               max_gap=args.max_gap)
    info: dict[str, Any] = {
        "input": str(path),
        "unit": cloud.source_unit,
        "source": "cloud",
        "from": list(p0),
        "to": list(p1),
        "from_given": list(g0),
        "to_given": list(g1),
        "samples": int(prof.distance.size),
        "spacing_m": prof.spacing,
        "length_m": prof.length,
        "band_half_width_m": prof.band_half_width,
        "point_spacing_m": prof.point_spacing,
        "points": prof.n_points,
        "normal": [float(c) for c in prof.frame.normal],
    }
    return prof.distance, prof.heights, prof.gaps, prof.spacing, info


def run(args: argparse.Namespace) -> int:
    from rough_viewer.profiles.comparison import compare_denoising
    from rough_viewer.profiles.fractal import parse_windows
    from rough_viewer.vocabulary import UNIT_METRES

    path = Path(args.input)
    _check_options(args)
    csv_path = (check_output_path(args.csv, force=args.force, inputs=[path])
                if args.csv else None)
    if not path.exists():
        raise InputError(f"no such file: {path}")

    read = _from_profile_file if args.profile_file or _two_column_text(path) else _from_cloud
    distance, heights, gaps, step, info = read(args, path)
    info["gaps_m"] = [[float(a), float(b)] for a, b in gaps]
    info["nan_samples"] = int(np.count_nonzero(~np.isfinite(heights)))
    info["max_gap_m"] = args.max_gap if args.max_gap is not None else 3.0 * step

    info["detrend"] = args.detrend
    if args.detrend is not None:
        from rough_viewer.profiles.fractal import detrend

        with naming(path):
            heights = detrend(heights, step, degree=args.detrend)
    windows = None if args.windows is None else parse_windows(
        args.windows, UNIT_METRES[info["unit"]])
    with naming(f"{path}: {distance.size} samples"):
        comparison = compare_denoising(heights, step, wavelet=args.wavelet, level=args.level,
                                       windows=windows)
    from rough_viewer.profiles.jrc import jrc_from_z2, jrc_warnings, z2

    info["z2"] = z2(heights, step)  # RMS slope of the raw profile, and its JRC estimate
    info["jrc_estimate"] = float(jrc_from_z2(info["z2"]))
    # every fit's dimension is checked: the raw profile's and each de-noised variant's
    info["warnings"] = [f"{path}: {w}" for w in (*comparison.warnings, *jrc_warnings(step))]
    warn(info["warnings"])

    if csv_path is not None:
        write_samples_csv(csv_path, distance, heights, comparison)
    if args.json:
        json.dump(result_dict(info, comparison), sys.stdout, indent=2)
        sys.stdout.write("\n")
        if csv_path is not None:
            print(f"wrote {csv_path}", file=sys.stderr)
    else:
        print(format_tables(info, comparison))
        if csv_path is not None:
            print(f"wrote {csv_path}")
    return 0
