"""``rough-viewer report``: the 2011 paper's Table 1 and Figs. 2-4 for one cloud.

Contract::

    rough-viewer report INPUT [INPUT ...] [--grid G ...] [--axis auto|x|y|z] [--threshold T]
        [--min-points K] --out REPORT.html [--format html|json] [--png DIR]
        [--directions DEG] [--units m|mm|ft|us-ft] [--keep-outliers]
        [--scanner X,Y,Z | --scanners FILE] [--noise M] [--beam-radius M]
        [--calibration FILE ...] [--asperity-radius M] [--angular-step DEG]
        [--crop XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX [--crop-mode keep|remove] | --crop-file VIEW.json]
        [--memory SIZE] [--scheduler threads|processes|tcp://HOST:PORT] [--workers N]
        [--force] [--quiet]

With scanner positions (E57 poses, ``--scanner``, ``--scanners``) every grid size
gets a scanner section (docs/scanner.md); without, one line says so. Default grid sizes: from the point spacing, the size at which the typical occupied
cell holds 16 points, times 8, 4, 2 and 1 (``rough_viewer.grid.spacing``); the
paper's are ``--grid 1 --grid 0.5 --grid 0.25 --grid 0.125``. ``--units`` is the unit
of the input's coordinates and of every length given and shown. ``--format json`` writes
the numbers alone. ``--png DIR`` also writes every figure as ``DIR/g<G>_<figure>.png``
(needs the optional package kaleido; the HTML does not). Several inputs (files or
quoted globs) are one merged cloud. ``--directions DEG`` adds a section per input
file: its roughness by direction (``rough-viewer directions`` with its defaults).
``--crop`` / ``--crop-file`` report on the points inside (or outside) a box; the
report's warnings say so (docs/lod.md). ``--memory`` / ``--scheduler`` compute the
cells out of core (streamed chunks, Dask, or a COPC file's tiles, each point decoded
once) and make every figure from them, the joint sets excepted (they need every point;
the page says so); they need ``--grid`` and refuse ``--directions``, the scanner
options and a crop.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from rough_viewer.cli._crop import add_crop_options
from rough_viewer.cli._inputs import add_inputs
from rough_viewer.cli._options import (
    add_axis,
    add_keep_outliers,
    add_units,
    grid_sizes,
    per_unit,
    positive,
    warn,
)
from rough_viewer.cli._scale import add_scale_options
from rough_viewer.cli._scanner import add_scanner_options
from rough_viewer.io.output import all_or_nothing, check_output_path, path_in_folder
from rough_viewer.vocabulary import DEFAULT_MIN_POINTS, UNIT_LABELS, InputError

if TYPE_CHECKING:
    from rough_viewer.report.build import Report
    from rough_viewer.report.export import ReportFormat, ReportSettings


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report",
        help="HTML (or JSON) report: Table 1, face maps, histograms, semivariograms",
        description="Grid roughness report of a cloud at several grid sizes (2011 paper "
        "Table 1 and Figs. 2-4): one self-contained HTML file that works offline.",
    )
    add_inputs(p)
    p.add_argument("--grid", type=float, action="append", metavar="G",
                   help="grid cell size in --units, repeatable (default: from the point "
                   "spacing: the size at which the typical occupied cell holds 16 points, "
                   "times 8, 4, 2 and 1)")
    add_axis(p)
    p.add_argument("--threshold", type=float, default=0.05, metavar="T",
                   help="binary transform threshold on normalised roughness (default 0.05)")
    p.add_argument("--min-points", type=int, default=DEFAULT_MIN_POINTS, metavar="K",
                   help="cells with fewer points get no value (default 4: three points fix a "
                   "plane exactly, so their roughness is 0 by construction; 3 is accepted)")
    p.add_argument("--directions", type=positive, metavar="DEG",
                   help="add roughness by direction at this azimuth step (degrees), one "
                   "section per input file, with rough-viewer directions' defaults")
    p.add_argument("--out", required=True, metavar="REPORT.html", help="output file")
    p.add_argument("--format", choices=("html", "json"), default="html",
                   help="html: the full report (default); json: the numbers alone")
    p.add_argument("--png", metavar="DIR",
                   help="also write every figure as PNG into DIR (needs kaleido)")
    add_keep_outliers(p)
    add_crop_options(p)
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_units(p)
    add_scanner_options(p)
    add_scale_options(p)
    p.set_defaults(func=run)


def _png_targets(directory: str, grids: list[float], *, force: bool, unit: str = "m"
                 ) -> tuple[Path, list[Path]]:
    from rough_viewer.report import FIGURE_NAMES, check_png_export, png_name
    from rough_viewer.report.html import SCANNER_FIGURE

    check_png_export()
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise InputError(f"--png expects a folder, got a file: {d}")
    if not d.parent.is_dir():
        raise InputError(f"output folder does not exist: {d.parent} (for --png {d})")
    targets = [d / png_name(g, f, unit) for g in grids for f in (*FIGURE_NAMES, SCANNER_FIGURE)]
    if d.is_symlink():
        raise InputError(f"--png folder is a symbolic link, refused: {d}")
    if d.is_dir():
        for t in targets:
            check_output_path(t, force=force, folder=d)
    return d, targets


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from rough_viewer.cli._crop import adopt_view_units, apply_crop, crop_from_args
    from rough_viewer.cli._inputs import input_paths, load_inputs
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.cli._scale import wants_chunks
    from rough_viewer.cli._scanner import apply_scanner_options
    from rough_viewer.io.load import resolve_units
    from rough_viewer.report import check_png_export
    from rough_viewer.report.export import compute_report

    paths = input_paths(args)
    from rough_viewer.grid import fast

    fast.preload()  # a report is seconds of work: the kernels load while the input is read
    adopt_view_units(args)
    unit_in = resolve_units(paths[0], args.units)[0]
    given, settings = _report_settings(args, unit_in)
    out = check_output_path(args.out, force=args.force, inputs=paths)
    if args.png:
        check_png_export()
    box = crop_from_args(args, resolve_units(paths[0], args.units)[0])

    quiet = args.quiet
    if wants_chunks(args):
        report, png_dir = _report_by_chunks(args, paths, given, settings, unit_in)
        per, u = per_unit(unit_in), UNIT_LABELS[unit_in]
    else:
        cloud = apply_scanner_options(load_inputs(paths, units=args.units, quiet=quiet,
                                                  max_points=args.file_max_points), paths,
                                      args, unit_in)  # prints its warnings
        cloud, _ = apply_crop(cloud, box, cloud.source_unit)
        per = per_unit(cloud.source_unit)
        u = UNIT_LABELS[cloud.source_unit]
        if given is not None:  # lengths given in the input's unit
            settings = replace(settings, grid_sizes=tuple(g * per for g in given))
        png_dir = None
        if args.png and given is not None:
            png_dir, _ = _png_targets(args.png, list(settings.grid_sizes or ()),
                                      force=args.force, unit=cloud.source_unit)
        report = compute_report(cloud, settings,
                                progress=None if quiet else ProgressBar("report"))
        warn(report.warnings[len(cloud.warnings):])
    if args.directions is not None:
        report = _with_directions(report, paths, args)
    if given is None:
        print("grid sizes from the point spacing: "
              + ", ".join(f"{s.grid_size / per:g}" for s in report.sections) + f" {u}")
        if args.png:
            png_dir, _ = _png_targets(args.png, [s.grid_size for s in report.sections],
                                      force=args.force)
    _say_section_errors(report, per, u)
    n_figures = _write_outputs(out, report, args.format, png_dir, quiet=quiet)
    print(f"wrote {out}")
    if png_dir is not None:
        print(f"wrote {n_figures} PNG figures to {png_dir}")
    return 0


def _report_by_chunks(args: argparse.Namespace, paths: list[Path],
                      given: tuple[float, ...] | None, settings: ReportSettings, unit: str
                      ) -> tuple[Report, Path | None]:
    """The report of the inputs streamed in chunks (``--memory``), on Dask
    (``--scheduler``) or, for one COPC file, by its tiles: every figure from the
    cells (:func:`rough_viewer.report.build.report_from_results`), the same numbers
    as in memory, without the joint sets; the PNG folder checked."""
    from rough_viewer.cli._crop import refuse_with_chunks
    from rough_viewer.cli._inputs import describe
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.cli._scale import chunked_run
    from rough_viewer.report.build import report_from_results
    from rough_viewer.vocabulary import MODELS

    refuse_with_chunks(args)
    if given is None:
        raise InputError("give --grid with --memory or --scheduler: the default grid sizes "
                         "come from the point spacing of the whole cloud in memory")
    if args.scanner or args.scanners:
        raise InputError("the scanner section needs every point, which --memory and "
                         "--scheduler do not keep; run without them for --scanner and "
                         "--scanners")
    if args.directions is not None:
        raise InputError("--directions measures profiles of every point, which --memory and "
                         "--scheduler do not keep; run 'rough-viewer directions' on the "
                         "input, or the report without those options")
    per = per_unit(unit)
    sizes = list(dict.fromkeys(g * per for g in given))
    png_dir = None
    if args.png:
        png_dir, _ = _png_targets(args.png, sizes, force=args.force, unit=unit)
    run = chunked_run(args, paths, sizes, origin=None, models=MODELS, residual="absolute")
    report = report_from_results(
        run.results, source=describe(paths), bounds=run.bounds, dropped_nonfinite=run.dropped,
        threshold=settings.threshold, unit=unit, keep_outliers=settings.keep_outliers,
        warnings=run.warnings, progress=None if args.quiet else ProgressBar("report"))
    warn([w for w in report.warnings if w not in run.warnings])
    return report, png_dir


def _report_settings(args: argparse.Namespace, unit_in: str
                     ) -> tuple[tuple[float, ...] | None, ReportSettings]:
    """The grid sizes given (in the inputs' unit ``unit_in``, None for those from the
    point spacing) and the report's settings, checked (an error names the option as
    the user typed it); ``--directions`` checked too."""
    from rough_viewer.cli._scanner import trust_settings
    from rough_viewer.report.export import ReportSettings

    # grid sizes are given in the inputs' unit (--units, else the CRS's): say so
    given = tuple(grid_sizes(args.grid, unit_in)) if args.grid else None
    settings = ReportSettings(min_points=args.min_points, grid_sizes=given,
                              axis=args.axis, threshold=args.threshold,
                              trust=trust_settings(args, unit_in),
                              keep_outliers=args.keep_outliers)
    try:
        settings.check()
    except InputError as exc:  # name the option as the user typed it
        text = str(exc)
        for word, option in (("grid size", "--grid"), ("threshold", "--threshold"),
                             ("min points", "--min-points")):
            text = text.replace(word, option, 1) if text.startswith(word) else text
        raise InputError(text) from None
    if args.directions is not None:
        from rough_viewer.tin.directional import MIN_AZIMUTH_STEP_DEG

        if not MIN_AZIMUTH_STEP_DEG <= args.directions <= 360:
            raise InputError(f"--directions must be from {MIN_AZIMUTH_STEP_DEG:g} to at most "
                             f"360 degrees (each direction is a set of profiles), got "
                             f"{args.directions:g}")
    return given, settings


def _with_directions(report: Report, paths: list[Path], args: argparse.Namespace) -> Report:
    """The report with the directional roughness of every input (``--directions``
    degrees apart), its warnings said."""
    from dataclasses import replace

    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.directions.analysis import DirectionSettings, analyse_paths

    found = analyse_paths(paths, DirectionSettings(step_deg=args.directions),
                          units=args.units,
                          progress=None if args.quiet else ProgressBar("directions"))
    for d in found:
        warn([f"{d.source}: {w}" for w in d.warnings])
    return replace(report, directions=tuple(found))


def _say_section_errors(report: Report, per: float, u: str) -> None:
    """Refuse a report whose every grid size failed (nothing written); else say on
    stderr each grid size and figure that failed (``per`` input units a metre, ``u``
    their label)."""
    failed = [s for s in report.sections if s.error is not None]
    if failed and len(failed) == len(report.sections):  # nothing to report: refuse, write nothing
        raise InputError("no grid size could be computed: " + "; ".join(
            f"grid {s.grid_size / per:g} {u}: {s.error}" for s in failed))
    for s in report.sections:
        if s.error is not None:
            print(f"rough-viewer: grid {s.grid_size / per:g} {u}: {s.error}", file=sys.stderr)
        for key, why in s.figure_errors.items():
            print(f"rough-viewer: grid {s.grid_size / per:g} {u}: no {key} figure: {why}",
                  file=sys.stderr)


def _write_outputs(out: Path, report: Report, fmt: ReportFormat, png_dir: Path | None, *,
                   quiet: bool) -> int:
    """Write the report and, into ``png_dir`` where given, its PNG figures: all or
    nothing (a PNG that fails takes the page with it, and a folder made for them goes
    again). Returns the number of PNG figures written."""
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.report import png_figures
    from rough_viewer.report.export import write_report
    from rough_viewer.visual.export import image_session, write_figure

    figures = []
    made_dir = png_dir is not None and not png_dir.exists()
    try:
        with all_or_nothing():  # a PNG that fails takes the page with it: nothing half done
            write_report(out, report, fmt)
            if png_dir is not None:
                figures = png_figures(report)
                bar = None if quiet else ProgressBar("PNG figures")
                png_dir.mkdir(exist_ok=True)
                with image_session("png"):
                    for i, (name, fig) in enumerate(figures):
                        write_figure(fig, path_in_folder(png_dir, name), fmt="png")
                        if bar is not None:
                            bar(i + 1, len(figures))
    except BaseException:
        if made_dir and png_dir is not None and png_dir.is_dir() and not any(png_dir.iterdir()):
            png_dir.rmdir()
        raise
    return len(figures)
