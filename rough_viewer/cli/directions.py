"""``rough-viewer directions``: roughness by direction of a surface, headless.

Contract (other tools script against it)::

    rough-viewer directions INPUT --step 15 [--spacing S] [--half-width W]
        [--windows W1,W2,...|default|paper] [--units m|mm|ft|us-ft] --out DIRECTIONS.csv
        [--windows-out WINDOWS.csv [--window-radius R] [--window-step S]]
        [--sample-spacing S] [--min-samples K] [--force] [--quiet]

DIRECTIONS.csv: one row per azimuth (0, step, ... below 360 degrees, counter-clockwise
from the face's u axis towards v), columns ``azimuth_deg, profiles, h_mean, h_std,
d_mean, d_std, rms_mean, z2_mean, jrc_mean, theta_max_c1`` and ``delta_t`` where the
input is a mesh (STL, PLY with faces) or could be triangulated in its best-fit
plane, then ``h_denoised_mean, h_denoised_std, d_denoised_mean, d_denoised_std,
rms_std, z2_std, jrc_std, theta_max, c, a0``
(:data:`rough_viewer.directions.table.TABLE_COLUMNS`, ``EXTRA_COLUMNS``). ``rms``
is in ``--units``; angles in degrees; H, D, Z2, C, A0 and the JRC estimates
dimensionless. WINDOWS.csv: one row per window and azimuth, ``cx, cy, cz, area,
azimuth_deg, delta_t, theta_max_c1`` (centre and area in ``--units`` and its
square). Lengths given (``--spacing`` between profiles, ``--half-width`` of each
profile's band, ``--windows``, ``--window-radius``, ``--window-step``,
``--sample-spacing``) are in ``--units`` (default: a LAS file's CRS unit, else m).
Both files are written only when the whole run succeeds.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rough_viewer.cli._options import (
    add_units,
    add_windows,
    naming,
    per_unit,
    positive,
    warn,
    window_lengths,
)
from rough_viewer.io.output import all_or_nothing, check_outputs
from rough_viewer.vocabulary import InputError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "directions",
        help="roughness by direction: profile sets, theta*max/(C+1), Delta-T, JRC",
        description="Measure a surface in every direction at a step of azimuths: parallel "
        "profiles across the face (Hurst exponent and fractal dimension, raw and "
        "de-noised, RMS, Z2 and JRC estimates) and the TIN parameters theta*max/(C+1) "
        "(Grasselli) and Delta-T of its mesh or of the cloud triangulated in its plane; "
        "optionally as a map of circular windows.",
    )
    p.add_argument("input", metavar="INPUT", help="point cloud or mesh (.las .laz .e57 .xyz "
                   ".txt .csv .pts .npy .ply .stl; an STL or a PLY with faces is measured "
                   "on its own triangles)")
    p.add_argument("--step", type=positive, required=True, metavar="DEG",
                   help="azimuth step in degrees (e.g. 15: 24 directions)")
    p.add_argument("--spacing", type=positive, metavar="S",
                   help="distance between parallel profiles, in --units (default: the larger "
                   "of two band half-widths and 1/100 of the face's larger extent)")
    p.add_argument("--half-width", type=positive, metavar="W",
                   help="half-width of each profile's band of points, in --units (default: "
                   "the point spacing)")
    add_windows(p)
    p.add_argument("--sample-spacing", type=positive, metavar="S",
                   help="sample spacing along the profiles, in --units (default: the point "
                   "spacing; the JRC estimates hold for 0.5-1 mm)")
    p.add_argument("--min-samples", type=int, default=None, metavar="K",
                   help="fewest samples with data a profile needs (default 64; at least 40, "
                   "the wavelet de-noising's shortest run)")
    add_units(p)
    p.add_argument("--out", required=True, metavar="DIRECTIONS.csv",
                   help="one row per azimuth (.csv, or .parquet)")
    p.add_argument("--windows-out", metavar="WINDOWS.csv",
                   help="map of circular windows: one row per window and azimuth")
    p.add_argument("--window-radius", type=positive, metavar="R",
                   help="window radius, in --units (default: 1/10 of the face's shorter "
                   "extent)")
    p.add_argument("--window-step", type=positive, metavar="S",
                   help="spacing of the window centres, in --units (default: the radius)")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def no_profile_reasons(sets) -> str:
    """Why no profile was measured, over every direction, most common first.

    >>> from types import SimpleNamespace as S
    >>> no_profile_reasons([S(skipped=(("too few samples", 3),), n_profiles=3),
    ...                     S(skipped=(("too few samples", 2), ("no points", 1)), n_profiles=3)])
    '6 profile lines; too few samples: 5, no points: 1'
    >>> no_profile_reasons([S(skipped=(), n_profiles=0)])
    'no profile line crosses the face'
    """
    counts: dict[str, int] = {}
    for ps in sets:
        for reason, n in ps.skipped:
            reason = reason.split(" (")[0]  # without the per-profile figures
            counts[reason] = counts.get(reason, 0) + int(n)
    lines = sum(int(ps.n_profiles) for ps in sets)
    if not lines:
        return "no profile line crosses the face"
    why = ", ".join(f"{r}: {n:,}"
                    for r, n in sorted(counts.items(), key=lambda kv: -kv[1])[:3])
    return f"{lines:,} profile lines" + (f"; {why}" if why else "")


def run(args: argparse.Namespace) -> int:
    from rough_viewer.cli._inputs import report_cloud
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.directions.analysis import DirectionSettings, analyse_directions
    from rough_viewer.directions.table import directions_table
    from rough_viewer.io.formats.mesh import load_mesh
    from rough_viewer.io.load import load_points
    from rough_viewer.io.table import check_table_output, write_table
    from rough_viewer.profiles.profile_sets import DEFAULT_MIN_SAMPLES
    from rough_viewer.profiles.wavelets import min_run_length
    from rough_viewer.report.directions import format_directions

    shortest = min_run_length("db3", 3)
    if args.min_samples is not None and args.min_samples < shortest:
        raise InputError(f"--min-samples must be at least {shortest} (the de-noising's "
                         f"shortest run), got {args.min_samples}")
    from rough_viewer.tin.directional import MIN_AZIMUTH_STEP_DEG

    if not MIN_AZIMUTH_STEP_DEG <= args.step <= 360:
        raise InputError(f"--step must be from {MIN_AZIMUTH_STEP_DEG:g} to at most 360 degrees "
                         f"(each direction is a set of profiles), got {args.step:g}")
    path = Path(args.input)
    outs = [Path(args.out)] + ([Path(args.windows_out)] if args.windows_out else [])
    for out in outs:
        check_table_output(out)
    check_outputs(outs, force=args.force, inputs=[path])
    if (args.window_radius or args.window_step) and not args.windows_out:
        raise InputError("--window-radius and --window-step are for the window map: give "
                         "--windows-out WINDOWS.csv too")

    cloud = load_points(path, units=args.units)
    report_cloud(cloud, str(path))
    unit = cloud.source_unit
    per = per_unit(unit)
    mesh = load_mesh(path, units=args.units or "m")  # STL, PLY: no CRS, --units or m

    def metres(value: float | None) -> float | None:
        return None if value is None else value * per

    settings = DirectionSettings(
        step_deg=args.step, spacing=metres(args.spacing), half_width=metres(args.half_width),
        sample_spacing=metres(args.sample_spacing), windows=window_lengths(args.windows, unit),
        window_radius=metres(args.window_radius), window_step=metres(args.window_step),
        window_map=bool(args.windows_out),
        min_samples=args.min_samples if args.min_samples is not None else DEFAULT_MIN_SAMPLES)
    with naming(path):
        result = analyse_directions(cloud, settings, mesh=mesh, source=str(path),
                                    progress=None if args.quiet else ProgressBar("directions"))
    if not any(bool(np.any(ps.used)) for ps in result.sets):
        text = (f"no profile of {path} could be measured in any direction: "
                f"{no_profile_reasons(result.sets)} (see --half-width, --sample-spacing, "
                "--min-samples and --windows)")
        if result.tin is None:  # nothing measured at all: no table of empty directions
            raise InputError(text)
        warn([text + "; the table holds the triangles' columns only"])
    if args.windows_out and result.windows is None:
        raise InputError(f"no window map for {path}: {result.window_error}")
    warn(result.warnings)
    print(format_directions(result, unit=unit))
    with all_or_nothing():
        write_table(outs[0], directions_table(result, unit=unit), unit=unit)
        if result.windows is not None and args.windows_out:
            write_table(outs[1], result.windows.table(per), unit=unit)
    print("wrote " + " and ".join(str(o) for o in outs))
    return 0
