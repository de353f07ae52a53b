"""``rough-viewer zones``: fracture and rubble zones of a cloud, headless.

Contract (other tools script against it)::

    rough-viewer zones INPUT [INPUT ...] --grid G [--grid G2 ...] [--method odr|ols|hybrid]
        [--axis auto|x|y|z] [--threshold T] [--min-cells K] [--connectivity face|edge|vertex]
        [--min-points K] --out ZONES.csv [--cells-out CELLS.csv] [--units m|mm|ft|us-ft]
        [--keep-outliers]
        [--crop XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX [--crop-mode keep|remove] | --crop-file VIEW.json]
        [--memory SIZE] [--scheduler threads|processes|tcp://HOST:PORT] [--workers N]
        [--force] [--quiet]

ZONES.csv: one row per zone, ids 1..Z by cell count (largest first), columns
:data:`rough_viewer.structure.zones.ZONE_COLUMNS`, always in metres whatever ``--units``
(``area_m2``, ``length_m``, ``width_m``, ``mean_theta``, ``max_theta``, ``cx, cy, cz``;
angles in degrees; numbers at full precision as ``compute`` writes them). CELLS.csv:
``compute``'s columns (all three models; :func:`rough_viewer.grid.table.cell_columns`)
plus ``zone`` (0 = in no zone), lengths in ``--units`` exactly as ``compute --units``
writes its cell table. Both go through :func:`rough_viewer.io.table.write_table`
(a ``.parquet`` name writes Parquet, as ``compute``). Several inputs (files or
quoted globs) are one merged cloud.

``--units`` (default: the unit of a LAS file's CRS, else m) is the unit of the
input's coordinates, of ``--grid`` and of the summary printed (which names the
metres ZONES.csv holds beside it). The summary also says what share of the cells
the threshold flags and gives the data's own threshold
(:func:`rough_viewer.grid.threshold.threshold_advice`: Otsu's method on log
roughness), with a warning when the threshold flags most of the face. Cells whose
roughness is larger than the cell (outliers of the definition) take no part unless
``--keep-outliers``. With several
``--grid`` values every output name gets ``_g<G>`` before its extension, as in
``compute`` (``zones.csv`` -> ``zones_g0.5.csv``). The outputs appear only when the
whole run succeeds (:func:`rough_viewer.io.output.all_or_nothing`).

``--memory`` and ``--scheduler`` stream the points as ``compute`` does
(docs/scale.md): the zones need only the cells. A COPC file is read by its tiles, each
point decoded once (docs/campaign.md). A crop needs every point and is refused with
them.
"""

from __future__ import annotations

import argparse
import math
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
    per_unit,
    positive_int,
)
from rough_viewer.cli._scale import add_scale_options
from rough_viewer.io.output import all_or_nothing, check_outputs
from rough_viewer.vocabulary import (
    CONNECTIVITIES,
    DEFAULT_MIN_CELLS,
    DEFAULT_THRESHOLD,
    MAP_LABELS,
    UNIT_LABELS,
    InputError,
    MapName,
)

if TYPE_CHECKING:
    from collections.abc import Iterator
    from pathlib import Path

    from rough_viewer.grid.roughness import GridRoughness
    from rough_viewer.structure.zones import Zones

#: Zones listed on the terminal (all of them go to ZONES.csv).
SHOWN = 10


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "zones",
        help="fracture and rubble zones (connected rough cells) to CSV",
        description="Find zones: connected groups of cells whose normalised roughness is "
        "at or above a threshold (the 2011 paper's binary transform, Fig. 2), and write "
        "one CSV row per zone (size, area, extent, trace, orientation, roughness).",
    )
    add_inputs(p)
    p.add_argument("--grid", type=float, action="append", required=True, metavar="G",
                   help="grid cell size in --units (default metres; repeat for several "
                   "sizes: each output name then gets _g<G>, as in compute)")
    p.add_argument("--method", choices=("odr", "ols", "hybrid"), default="odr",
                   help="roughness map whose normalised values are thresholded (default odr)")
    add_axis(p)
    p.add_argument("--threshold", type=float, default=None, metavar="T",
                   help="cells with normalised roughness >= T are rough, T in [0, 1] "
                   f"(default {DEFAULT_THRESHOLD:g}, the 2011 paper's, unless it flags more "
                   "than half of the cells: then the data's own threshold, Otsu's split; "
                   f"give --threshold {DEFAULT_THRESHOLD:g} to keep the paper's)")
    p.add_argument("--min-cells", type=positive_int, default=DEFAULT_MIN_CELLS, metavar="K",
                   help=f"drop zones of fewer cells (default {DEFAULT_MIN_CELLS})")
    p.add_argument("--connectivity", choices=CONNECTIVITIES, default="vertex",
                   help="cells touch by a face (6 neighbours), an edge (18) or a vertex "
                   "(26, default)")
    p.add_argument("--min-points", type=int, default=None, metavar="K",
                   help="cells with fewer points get no value (default: as compute)")
    p.add_argument("--out", required=True, metavar="ZONES.csv",
                   help="per-zone CSV output, always in metres (area_m2, length_m, width_m, "
                   "theta, centroid), whatever --units")
    p.add_argument("--cells-out", metavar="CELLS.csv",
                   help="per-cell CSV output: compute's columns plus zone, lengths in --units "
                   "as compute writes them")
    add_keep_outliers(p)
    add_crop_options(p)
    add_scale_options(p)
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_units(p)
    p.set_defaults(func=run)


def format_zones(zones, result, *, source: str, unit: str = "m", advice=None,
                 keep_outliers: bool = False) -> str:
    """Readable summary of the zones (the first :data:`SHOWN`) for the terminal,
    lengths in ``unit`` (areas in its square; the metres of ZONES.csv named beside
    them), with the threshold ``advice``
    (:class:`rough_viewer.grid.threshold.ThresholdAdvice`) where given."""
    from rough_viewer.grid.orientation import dip_and_direction
    from rough_viewer.grid.outliers import analysed_values, outlier_text

    per, u = per_unit(unit), UNIT_LABELS[unit]
    dip, dd = dip_and_direction(result.whole_plane.normal[None])
    valued = int(np.count_nonzero(np.isfinite(
        analysed_values(result, zones.map_name, keep_outliers=keep_outliers))))
    in_zones = int(zones.cells.sum())
    area_m2 = float(zones.area_m2.sum())
    in_csv = ""
    lines = [
        f"{source}: {result.n_points_total:,} points, grid {zones.cell_size / per:g} {u}, "
        f"{MAP_LABELS[zones.map_name]} roughness, threshold {zones.threshold:g}, "
        f"{zones.connectivity} connectivity, zones of >= {zones.min_cells} cells",
        f"face (whole-cloud ODR plane): dip {dip[0]:.1f}, dip direction {dd[0]:.1f} deg",
        f"{zones.n_zones:,} zone{'s' if zones.n_zones != 1 else ''}, {in_zones:,} cells "
        f"({100.0 * in_zones / max(valued, 1):.1f} % of {valued:,} cells with a value), "
        f"{area_m2 / per**2:.4g} {u}2 of face{in_csv}",
    ]
    if advice is not None:
        lines.insert(2, ("warning: " if advice.most else "") + advice.text(unit))
    text = outlier_text(result, zones.map_name, unit=unit, kept=keep_outliers)
    if text:
        lines.insert(2, f"note: {text}")
    if zones.n_zones:
        lines.append("")
        lines.append(f"{'zone':>5} {'cells':>7} {'points':>9} {'area ' + u + '2':>9} "
                     f"{'length ' + u:>9} {'width ' + u:>8} {'trace':>9} {'dip/dir':>9} "
                     f"{'mean theta ' + u:>13}")
        for k in range(min(SHOWN, zones.n_zones)):
            lines.append(
                f"{k + 1:5d} {zones.cells[k]:7,} {zones.points[k]:9,} "
                f"{zones.area_m2[k] / per**2:9.4g} "
                f"{zones.length_m[k] / per:9.3g} {zones.width_m[k] / per:8.3g} "
                f"{zones.trace_azimuth_deg[k]:4.0f}/{zones.trace_plunge_deg[k]:<4.0f} "
                f"{zones.dip_deg[k]:3.0f}/{zones.dip_direction_deg[k]:<5.0f} "
                f"{zones.mean_theta[k] / per:13.4e}")
        if zones.n_zones > SHOWN:
            lines.append(f"  ... {zones.n_zones - SHOWN:,} more in the CSV")
        if unit != "m":
            lines.append(f"  (ZONES.csv: lengths in {u}, its unit_m column; area_m2, length_m "
                         f"and width_m in metres as named, area, length and width in {u})")
    return "\n".join(lines)


def zones_threshold(result: GridRoughness, method: MapName, given: float | None, *,
                    keep_outliers: bool = False) -> tuple[float, str]:
    """The threshold the zones use and, when it is not the one given, why
    (:func:`rough_viewer.grid.threshold.zone_threshold`, the app's rule too). A
    threshold given is used as it is."""
    from rough_viewer.grid.threshold import zone_threshold

    if given is not None:
        return float(given), ""
    chosen = zone_threshold(result, method, keep_outliers=keep_outliers)
    reason = chosen.reason()
    if reason:
        reason += f"; give --threshold {DEFAULT_THRESHOLD:g} to use it"
    return chosen.value, reason


def run(args: argparse.Namespace) -> int:
    from rough_viewer.cli._crop import adopt_view_units, crop_from_args
    from rough_viewer.cli._inputs import describe, input_paths
    from rough_viewer.grid.threshold import map_threshold_advice
    from rough_viewer.io.load import resolve_units
    from rough_viewer.io.table import check_table_output
    from rough_viewer.structure.zones import ZoneLabeller

    if args.threshold is not None and not (math.isfinite(args.threshold)
                                           and 0.0 <= args.threshold <= 1.0):
        raise InputError(f"--threshold must lie in [0, 1], got {args.threshold:g}")
    if args.min_points is not None and args.min_points < 3:
        raise InputError(f"--min-points must be at least 3, got {args.min_points}")
    inputs = input_paths(args)
    source = describe(inputs)
    # every length given and shown is in the inputs' unit (--units, else the CRS's)
    adopt_view_units(args)
    unit, _ = resolve_units(inputs[0], args.units)
    grids = grid_sizes(args.grid, unit)
    several = len(grids) > 1
    wanted = [("out", args.out), *([("cells_out", args.cells_out)] if args.cells_out else [])]
    outputs = {opt: {g: output_name(path, g, several, unit) for g in grids} for opt, path in wanted}
    paths = [p for by_grid in outputs.values() for p in by_grid.values()]
    for path in paths:
        check_table_output(path)
    check_outputs(paths, force=args.force, inputs=inputs)
    box = crop_from_args(args, unit)
    results = _results(args, inputs, grids, unit, box)
    written: list[str] = []
    with all_or_nothing():  # a failed grid or write leaves none of the run's outputs
        for i, g in enumerate(grids):
            with at_grid(g, unit):
                result = next(results)
            labeller = ZoneLabeller.build(result, args.method,
                                          keep_outliers=args.keep_outliers)
            threshold, chose = zones_threshold(result, args.method, args.threshold,
                                               keep_outliers=args.keep_outliers)
            zones = labeller.zones(
                threshold, connectivity=args.connectivity, min_cells=args.min_cells)
            advice = map_threshold_advice(result, args.method, threshold,
                                          keep_outliers=args.keep_outliers)
            names = _write_tables(outputs, g, zones, result, source=source, unit=unit)
            if i:
                print()
            if chose:  # said beside the summary, not as a warning on stderr
                print(chose[0].upper() + chose[1:])
            print(format_zones(zones, result, source=source, unit=unit, advice=advice,
                               keep_outliers=args.keep_outliers))
            written.append("wrote " + " and ".join(names))
    for line in written:
        print(line)
    return 0


def _results(args: argparse.Namespace, inputs: list[Path], grids: list[float], unit: str,
             box) -> Iterator[GridRoughness]:
    """The grid roughness of each grid size (in ``unit``), in order: from the cloud in
    memory (cropped), or from one streamed run for every grid with ``--memory`` or
    ``--scheduler`` (a COPC file by its tiles)."""
    from rough_viewer.cli._crop import apply_crop, refuse_with_chunks
    from rough_viewer.cli._inputs import load_inputs
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.cli._scale import chunked_results, wants_chunks
    from rough_viewer.grid.roughness import grid_roughness
    from rough_viewer.vocabulary import DEFAULT_MIN_POINTS, MODELS

    per, u = per_unit(unit), UNIT_LABELS[unit]
    if wants_chunks(args):
        refuse_with_chunks(args)
        if args.min_points is None:
            args.min_points = DEFAULT_MIN_POINTS
        streamed, _ = chunked_results(args, inputs, [g * per for g in grids], origin=None,
                                      models=MODELS, residual="absolute")
        yield from streamed
        return
    cloud, _ = apply_crop(load_inputs(inputs, units=args.units, quiet=args.quiet,
                                       max_points=args.file_max_points), box, unit)
    options = {} if args.min_points is None else {"min_points": args.min_points}
    for g in grids:
        yield grid_roughness(cloud, g * per, axis=args.axis,
                             progress=None if args.quiet else ProgressBar(f"grid {g:g} {u}"),
                             **options)


def _write_tables(outputs: dict[str, dict[float, Path]], g: float, zones: Zones,
                  result: GridRoughness, *, source: str, unit: str) -> list[str]:
    """Write the zone table of grid ``g`` (in ``unit``) and, with ``--cells-out``, every
    cell's row with its zone; lengths in ``unit``. Returns the files written."""
    from rough_viewer.grid.table import cell_columns, table_metadata
    from rough_viewer.io.table import write_table

    out = outputs["out"][g]
    write_table(out, zones.file_table(per_unit(unit)), unit=unit)  # in --units, said in it
    names = [str(out)]
    if "cells_out" in outputs:
        cells_out = outputs["cells_out"][g]
        keep = result.n_points >= result.min_points  # the rows of cell_columns
        write_table(cells_out,
                    {**cell_columns(result, unit=unit), "zone": zones.labels[keep]},
                    metadata=table_metadata(result, source, unit=unit), unit=unit)
        names.append(str(cells_out))
    return names
