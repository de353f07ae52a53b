"""``rough-viewer compute``: per-cell roughness of a cloud, headless.

Contract (other tools script against it)::

    rough-viewer compute INPUT [INPUT ...] --grid G [--grid G2 ...]
        [--method odr|ols|hybrid|all] [--axis auto|x|y|z] [--min-points K]
        [--origin X,Y,Z] [--signed] [--out CELLS.csv|CELLS.parquet]
        [--summary-json SUMMARY.json] [--las-out OUT.las|OUT.laz] [--ply-out OUT.ply]
        [--memory SIZE] [--scheduler threads|processes|tcp://HOST:PORT] [--workers N]
        [--units m|mm|ft|us-ft] [--keep-outliers]
        [--scanner X,Y,Z | --scanners FILE] [--noise M] [--beam-radius M]
        [--calibration FILE ...] [--asperity-radius M] [--angular-step DEG]
        [--crop XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX [--crop-mode keep|remove] | --crop-file VIEW.json]
        [--force] [--quiet]

Several inputs (files or quoted globs) are one merged cloud. At least one output is
required. With several ``--grid`` values each output name gets ``_g<G>`` before its
extension (``cells.csv`` -> ``cells_g0.5.csv``, ``cells_g0.25.csv``). ``--las-out``
and ``--ply-out`` write every point with its cell's values as extra dimensions /
scalar properties (docs/export.md). ``--memory`` streams the points in chunks within
that budget; ``--scheduler`` runs the chunks on Dask (docs/scale.md); neither keeps
the points, so neither goes with ``--las-out``, ``--ply-out``, ``--scanner``,
``--scanners`` or a crop. With scanner positions (E57 poses, ``--scanner``,
``--scanners``) the cell table's scanner columns and the LAS/PLY scanner fields are filled
(docs/scanner.md); without, the columns are empty and one line says so.
``--crop`` and ``--crop-file`` compute on the points inside (or outside) a box
(docs/lod.md); ``--las-out`` and ``--ply-out`` then hold the kept points only.

``--units`` (default: the unit of a LAS file's CRS, else m) is the unit of the
input's coordinates and of ``--grid``, ``--origin``, the table printed, the cell
table and the summary JSON (which says ``unit``); the per-point LAS/PLY fields stay
in metres (their names and comments say so).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rough_viewer.cli._crop import add_crop_options
from rough_viewer.cli._inputs import add_inputs
from rough_viewer.cli._options import (
    add_axis,
    add_keep_outliers,
    add_units,
    at_grid,
    grid_sizes,
    output_name,
    parse_xyz,
    per_unit,
)
from rough_viewer.cli._scale import add_scale_options
from rough_viewer.cli._scanner import add_scanner_options
from rough_viewer.grid.table import CELL_COLUMNS
from rough_viewer.io.jsonable import to_jsonable
from rough_viewer.io.output import all_or_nothing, check_outputs, write_atomic
from rough_viewer.io.table import UNIT_COLUMN
from rough_viewer.vocabulary import DEFAULT_MIN_POINTS, UNIT_LABELS, InputError, Residual

if TYPE_CHECKING:
    from rough_viewer.grid.roughness import GridRoughness
    from rough_viewer.io.cloud import PointCloud
    from rough_viewer.scanner.trust import CellTrust, TrustSettings

#: The per-cell table's columns (the contract; defined in :mod:`rough_viewer.grid.table`),
#: then the unit of its lengths (:data:`rough_viewer.io.table.UNIT_COLUMN`: metres per
#: unit), as every table written states it.
CSV_COLUMNS = (*CELL_COLUMNS, UNIT_COLUMN)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compute",
        help="per-cell roughness of a cloud to CSV (and a JSON summary)",
        description="Compute ODR, OLS and hybrid grid roughness (docs/science.md section 1) "
        "and write one CSV row per cell.",
    )
    add_inputs(p)
    p.add_argument("--grid", type=float, action="append", metavar="G",
                   help="grid cell size in --units (repeat for several sizes; default: from "
                   "the point spacing, the size at which the typical occupied cell holds 16 "
                   "points, as report and serve choose)")
    p.add_argument("--method", choices=("odr", "ols", "hybrid", "all"), default="all",
                   help="roughness model (default: all)")
    add_axis(p)
    p.add_argument("--min-points", type=int, default=DEFAULT_MIN_POINTS, metavar="K",
                   help="cells with fewer points get no value (default 4: three points fix a "
                   "plane exactly, so their roughness is 0 by construction; 3 is accepted)")
    p.add_argument("--origin", metavar="X,Y,Z", help="grid origin (default: bounding-box minimum)")
    p.add_argument("--signed", action="store_true",
                   help="RMS of signed distances instead of the std of absolute distances")
    p.add_argument("--out", metavar="CELLS.csv",
                   help="per-cell table: CSV, or Parquet when the name ends in .parquet "
                   "(needs pyarrow)")
    p.add_argument("--summary-json", metavar="SUMMARY.json", help="Table-1 summary as JSON")
    p.add_argument("--las-out", metavar="OUT.las|OUT.laz",
                   help="every input point with its cell's roughness as LAS extra dimensions")
    p.add_argument("--ply-out", metavar="OUT.ply",
                   help="every point with its cell's roughness as PLY scalar properties")
    add_scale_options(p)
    add_scanner_options(p)
    add_keep_outliers(p)
    add_crop_options(p)
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_units(p)
    p.set_defaults(func=run)


def summary_dict(result, cloud_source: str, dropped: int, unit: str = "m",
                 warnings: tuple[str, ...] = (), *, keep_outliers: bool = False) -> dict:
    """The SUMMARY.json content for one grid size, lengths in ``unit``; Table 1
    without the outlier cells unless ``keep_outliers`` (each map's ``outliers`` says
    how many were left out)."""
    from rough_viewer.grid.summary import summarise
    from rough_viewer.vocabulary import MAPS, UNIT_METRES

    per = UNIT_METRES[unit]
    out: dict = {}
    for name in MAPS:
        d = summarise(result, name, keep_outliers=keep_outliers).as_dict()
        for k in ("min", "max", "mean", "std"):
            d[k] = d[k] / per
        d["variance"] = d["variance"] / per**2
        out[name] = d
    out.update(
        {
            "unit": unit,
            "warnings": list(warnings),
            "grid_size": result.grid.cell_size / per,
            "origin": [float(v) / per for v in result.grid.origin],
            "axis": result.axis,
            "axis_requested": result.axis_requested,
            "points": result.n_points_total,
            "dropped_nonfinite": dropped,
            "min_points": result.min_points,
            "residual": result.residual,
            "models": list(result.models),
            "keep_outliers": keep_outliers,
            "cells": result.cell_report("odr"),
            "input": cloud_source,
        }
    )
    return to_jsonable(out)


def run(args: argparse.Namespace) -> int:
    from rough_viewer.cli._crop import adopt_view_units, apply_crop, crop_from_args
    from rough_viewer.cli._inputs import describe, input_paths, load_inputs, preload_kernels_for
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.cli._scale import chunked_results, wants_chunks
    from rough_viewer.cli._scanner import apply_scanner_options, trust_settings
    from rough_viewer.grid.roughness import grid_roughness
    from rough_viewer.io.load import resolve_units
    from rough_viewer.vocabulary import MODELS

    if args.min_points < 3:
        raise InputError(f"--min-points must be at least 3, got {args.min_points}")
    origin = np.array(parse_xyz(args.origin, option="--origin")) if args.origin else None
    paths = input_paths(args)
    if not wants_chunks(args):
        preload_kernels_for(paths)  # on a thread, while the inputs are read
    # every length given and shown is in the inputs' unit (--units, else the CRS's)
    adopt_view_units(args)
    unit, _ = resolve_units(paths[0], args.units) if paths else ("m", ())
    chosen = not args.grid  # the grid comes from the point spacing, once the cloud is read
    if chosen and wants_chunks(args):
        raise InputError("give --grid with --memory or --scheduler: the default grid comes "
                         "from the point spacing of the whole cloud in memory")
    grids = [1.0] if chosen else grid_sizes(args.grid, unit)  # one placeholder size: one name
    several = len(grids) > 1
    outputs = _outputs(args, grids, several, paths, unit)
    box = crop_from_args(args, unit)
    quiet = args.quiet
    per = per_unit(unit)
    metres = [g * per for g in grids]
    if origin is not None:
        origin = origin * per
    source = describe(paths)
    models = MODELS if args.method == "all" else (args.method,)
    residual: Residual = "signed" if args.signed else "absolute"
    # checked before any work where an option asks for them; else the defaults, made
    # (with the bias modules' imports) only for a cloud that has scanner positions
    trust = trust_settings(args, unit) if _trust_options(args) else None
    results: Iterable[GridRoughness]
    cloud: PointCloud | None = None
    keep: np.ndarray | None = None
    if wants_chunks(args):
        _refuse_point_outputs_with_chunks(args)
        results, dropped = chunked_results(args, paths, metres, origin=origin, models=models,
                                           residual=residual)
    else:
        cloud, cropped = apply_crop(apply_scanner_options(
            load_inputs(paths, units=getattr(args, "units", None), quiet=quiet,
                        max_points=args.file_max_points), paths, args,
            unit), box, unit)
        keep = None if cropped is None else cropped.mask
        dropped = cloud.dropped_nonfinite
        if chosen:
            grids, outputs = _chosen_grid(cloud, per, unit, outputs, quiet)
        results = (grid_roughness(
            cloud, g * per, origin=origin, min_points=args.min_points, axis=args.axis,
            models=models, residual=residual,
            progress=None if quiet else ProgressBar(f"grid {g:g} {UNIT_LABELS[unit]}",
                                                    unit="step"),
        ) for g in grids)
    written: list[str] = []
    with all_or_nothing():  # a failed grid or write leaves none of the run's outputs
        results_iter = iter(results)
        for i, g in enumerate(grids):
            written += _one_grid(results_iter, first=i == 0, g=g,
                                 args=args, unit=unit, cloud=cloud, source=source,
                                 trust=trust, outputs=outputs, dropped=dropped, keep=keep)
    for line in written:
        print(line)
    return 0


def _refuse_point_outputs_with_chunks(args: argparse.Namespace) -> None:
    """Refuse with ``--memory`` or ``--scheduler`` the options that need every point."""
    from rough_viewer.cli._crop import refuse_with_chunks

    refuse_with_chunks(args)
    if args.las_out or args.ply_out:
        raise InputError("--las-out and --ply-out write every point, which --memory and "
                         "--scheduler do not keep; run without them for those outputs")
    if args.scanner or args.scanners:
        raise InputError("the per-cell scanner figures need every point, which --memory "
                         "and --scheduler do not keep; run without them for --scanner "
                         "and --scanners")


def _one_grid(results: Iterator[GridRoughness], *, first: bool, g: float,
              args: argparse.Namespace, unit: str, cloud: PointCloud | None, source: str,
              trust: TrustSettings | None, outputs: dict[str, dict[float, Path]],
              dropped: int, keep: np.ndarray | None) -> list[str]:
    """One grid size ``g`` (in ``unit``) of the run: its result (the next of
    ``results``) computed and checked, its table printed, its outputs written;
    returns what was written, to say."""
    from rough_viewer.cli._table import format_table

    with at_grid(g, unit):
        result = next(results)
        check_has_values(result, unit, cloud)
    if not first:
        print()
    print(format_table(result, source=source, unit=unit, keep_outliers=args.keep_outliers))
    cells = _trust(cloud, result, trust, args, unit)
    return _write_outputs(outputs, g, result, cloud, dropped, source, args, unit, cells,
                          keep=keep)


def _chosen_grid(cloud: PointCloud, per: float, unit: str,
                 outputs: dict[str, dict[float, Path]], quiet: bool
                 ) -> tuple[list[float], dict[str, dict[float, Path]]]:
    """The grid from the point spacing (``--grid`` left out), in the run's unit, and the
    outputs keyed by it; said on stderr unless ``quiet``."""
    from rough_viewer.grid.spacing import default_cell_size

    g = float(f"{default_cell_size(cloud) / per:.6g}")
    if not quiet:
        print(f"rough-viewer: grid {g:g} {UNIT_LABELS[unit]} from the point spacing (the "
              "typical occupied cell holds 16 points); give --grid to choose", file=sys.stderr)
    return [g], {opt: {g: next(iter(by_grid.values()))} for opt, by_grid in outputs.items()}


def check_has_values(result: GridRoughness, unit: str, cloud: PointCloud | None) -> None:
    """Refuse a grid on which no cell has a value (every cell below ``min_points``, or
    degenerate): its outputs would be empty. The message says how many points the
    cells hold and, when the points are in memory, the smallest grid at which the
    typical occupied cell has enough of them."""
    if any(np.isfinite(result.values(m)).any() for m in result.models):
        return
    from rough_viewer.grid.spacing import default_cell_size  # SciPy's KD-tree: only here
    per, u = per_unit(unit), UNIT_LABELS[unit]
    most = int(result.n_points.max()) if result.n_cells else 0
    text = (f"no cell has a value: the {result.n_points_total:,} points fall into "
            f"{result.n_cells:,} occupied cells, at most {most:,} in one, and a cell needs "
            f"{result.min_points} points with a unique plane (--min-points)")
    hint = "; use a larger --grid"
    if cloud is not None:
        try:  # the point spacing needs 5 points or more: a 4-point cloud gets no figure
            smallest = default_cell_size(cloud, target=result.min_points)
            suggested = default_cell_size(cloud)
        except InputError:
            pass
        else:
            hint = (f"; the smallest grid at which the typical cell holds {result.min_points} "
                    f"points is about {smallest / per:g} {u} (the point spacing suggests "
                    f"{suggested / per:g} {u}: 16 points per cell)")
    text += hint
    raise InputError(text)


def _outputs(args: argparse.Namespace, grids: list[float], several: bool,
             inputs: list[Path], unit: str = "m") -> dict[str, dict[float, Path]]:
    """Every output path of the run by option and grid size, all checked before any work."""
    from rough_viewer.io.formats.las_out import check_las_output
    from rough_viewer.io.table import check_table_output

    given = {opt: getattr(args, opt) for opt in ("out", "summary_json", "las_out", "ply_out")
             if getattr(args, opt)}
    if not given:
        raise InputError("no output given: use --out CELLS.csv, --las-out OUT.las|OUT.laz, "
                         "--ply-out OUT.ply or --summary-json SUMMARY.json")
    if args.las_out:
        check_las_output(args.las_out)
    if args.ply_out and Path(args.ply_out).suffix.lower() != ".ply":
        raise InputError(f"--ply-out must end in .ply, got {args.ply_out}")
    if args.out:
        check_table_output(args.out)
    outputs = {opt: {g: output_name(path, g, several, unit) for g in grids} for opt, path in given.items()}
    check_outputs([p for by_grid in outputs.values() for p in by_grid.values()],
                  force=args.force, inputs=inputs)
    return outputs


def _trust_options(args: argparse.Namespace) -> bool:
    """Whether any option of the per-cell scanner figures was given."""
    return any(getattr(args, name, None) not in (None, [], ())
               for name in ("noise", "beam_radius", "asperity_radius", "angular_step",
                            "calibration"))


def _trust(cloud: PointCloud | None, result: GridRoughness, settings: TrustSettings | None,
           args: argparse.Namespace, unit: str) -> CellTrust | None:
    """The per-cell scanner figures of one grid (printed as a few lines), or None
    when the cloud has no scanner positions (said once, in one line). ``settings``
    None: the options' (the defaults), made here."""
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.scanner.positions import NO_POSITIONS

    if cloud is None:  # streamed: no points kept
        return None
    if cloud.scanner_positions is None or np.size(cloud.scanner_positions) == 0:
        print(f"{NO_POSITIONS}; the scanner columns are empty")
        return None
    from rough_viewer.cli._scanner import trust_settings
    from rough_viewer.scanner.trust import cell_trust

    cells = cell_trust(cloud, result, settings or trust_settings(args, unit),
                       progress=None if args.quiet else ProgressBar("scanner", unit="step"))
    if cells is None:
        print(f"{NO_POSITIONS}; the scanner columns are empty")
    else:
        print("\n".join(cells.summary().lines(unit)))
    return cells


def _write_outputs(outputs: dict[str, dict[float, Path]], g: float, result,
                   cloud: PointCloud | None, dropped: int, source: str,
                   args: argparse.Namespace, unit: str = "m",
                   trust: CellTrust | None = None, *,
                   keep: np.ndarray | None = None) -> list[str]:
    """Write every output of one grid size; return the lines that say so (printed
    once the run's outputs are all in place). ``keep``: the crop's mask over the
    points read, for LAS copies of the kept points."""
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.grid.table import (
        POINT_LENGTH_FIELDS,
        cell_columns,
        point_fields,
        table_metadata,
    )
    from rough_viewer.io.formats.las_out import write_las_fields
    from rough_viewer.io.formats.ply import write_ply_fields
    from rough_viewer.io.table import write_table

    written = []
    if "out" in outputs:
        write_table(outputs["out"][g], cell_columns(
            result, unit=unit, trust=None if trust is None else trust.columns()),
            metadata=table_metadata(result, source, unit=unit), unit=unit)
        written.append(str(outputs["out"][g]))
    if "summary_json" in outputs:
        data = summary_dict(result, source, dropped, unit,
                            cloud.warnings if cloud is not None else (),
                            keep_outliers=args.keep_outliers)

        def dump(fh, d: dict = data) -> None:
            json.dump(d, fh, indent=2)

        write_atomic(outputs["summary_json"][g], dump)
        written.append(str(outputs["summary_json"][g]))
    lines = ["wrote " + " and ".join(written)] if written else []
    wants_points = "las_out" in outputs or "ply_out" in outputs
    fields = (point_fields(result, None if trust is None else trust.columns())
              if wants_points and cloud is not None else None)
    if "las_out" in outputs and fields is not None and cloud is not None:
        path = outputs["las_out"][g]
        info = write_las_fields(path, cloud, fields, keep=keep,
                                progress=None if args.quiet else ProgressBar(f"writing {path.name}"))
        lines.append(f"wrote {path}: {info}")
    if "ply_out" in outputs and fields is not None and cloud is not None:
        path = outputs["ply_out"][g]
        info = write_ply_fields(path, cloud, fields, comments=[
            f"rough_viewer: {Path(source).name if len(args.inputs) == 1 else source}, "
            f"grid {g:g} {UNIT_LABELS[unit]}, axis {result.axis}, "
            f"coordinates and roughness in {UNIT_LABELS[unit]}"],
            unit=unit, lengths=POINT_LENGTH_FIELDS)
        lines.append(f"wrote {path}: {info}")
    return lines
