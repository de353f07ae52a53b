"""``rough-viewer sets``: joint sets of a cloud (orientation, scatter, spacing,
persistence), headless.

Contract (other tools script against it)::

    rough-viewer sets INPUT [INPUT ...] --grid G [--grid G2 ...] [--max-roughness T]
        [--min-planar-points K] [--cone 20] [--min-angle 30] [--max-sets 6]
        [--smoothing 6] [--min-density 3] [--min-set-cells 10] [--plane-tolerance D]
        [--min-plane-cells 3] [--max-plane-rms D] [--face-tolerance 10] [--face-radius D]
        [--min-points K] [--units m|mm|ft|us-ft]
        --out SETS.csv [--planes-out PLANES.csv] [--joints-out JOINTS.csv]
        [--summary-json SUMMARY.json] [--cells-out CELLS.csv]
        [--dips-out DIPS.csv] [--las-out OUT.las|OUT.laz] [--ply-out OUT.ply]
        [--force] [--quiet]

SETS.csv: one row per set (:data:`rough_viewer.structure.sets.SET_COLUMNS`; its last
columns are the set's roughness, :mod:`rough_viewer.structure.set_roughness`: ``odr_mean,
odr_median, odr_std`` of its cells in the output unit, ``theta_max_c1_dip,
theta_max_c1_strike, delta_t_dip, delta_t_strike`` of its joints in degrees and the
dimensionless ``jrc_estimate_dip, jrc_estimate_strike``), PLANES.csv one
row per plane, i.e. patch (:data:`~rough_viewer.structure.sets.PLANE_COLUMNS`, with the
``joint_id`` it is part of), JOINTS.csv one row per joint
(:data:`~rough_viewer.structure.sets.JOINT_COLUMNS`), SUMMARY.json the rock-mass figures
(:func:`summary_dict`: ``sets``, ``jv``, ...), lengths in the output
unit (``--units``, else the unit of a LAS file's CRS, else m), areas in its square,
angles in degrees. A set within ``--face-tolerance`` of the exposure face (the whole
cloud's plane or its cells' local face; :mod:`rough_viewer.structure.face`) has
``face_parallel`` 1 in SETS.csv and ``FACE_PARALLEL`` 1 on its planes in DIPS.csv, is
marked on the terminal and left out of Jv, Ib and the RQD estimate (its spacing is no
joint spacing). DIPS.csv: the planes for Rocscience Dips (Import CSV, Dip/Dip
Direction; :meth:`~rough_viewer.structure.sets.JointSets.dips_table`). CELLS.csv:
``compute``'s columns (ODR only) plus ``set_id``, ``plane_id`` and ``joint_id``.
``--las-out`` / ``--ply-out``: every point with ``set_id``, ``plane_id`` and
``joint_id`` of its cell. With several
``--grid`` values every output name gets ``_g<G>`` before its extension, as in
``compute``. The outputs appear only when the whole run succeeds
(:func:`rough_viewer.io.output.all_or_nothing`); a cloud without joint sets writes
tables with a header only and says why.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rough_viewer.cli._inputs import add_inputs
from rough_viewer.cli._options import (
    add_units,
    at_grid,
    grid_sizes,
    non_negative,
    output_name,
    per_unit,
    positive,
    positive_int,
)
from rough_viewer.io.output import all_or_nothing, check_outputs
from rough_viewer.vocabulary import UNIT_LABELS, InputError

#: Planes listed on the terminal per set (all of them go to PLANES.csv).
SHOWN_PLANES = 3


def register(sub: argparse._SubParsersAction) -> None:
    from rough_viewer.structure import sets as js
    from rough_viewer.structure.face import DEFAULT_FACE_RADIUS_CELLS, DEFAULT_FACE_TOLERANCE_DEG

    p = sub.add_parser(
        "sets",
        help="joint sets (discontinuity sets) of planar cells: orientation, Fisher scatter, "
        "spacing and persistence, to CSV",
        description="Find discontinuity sets: the poles of the planar cells (ODR roughness "
        "at most --max-roughness) weighted by their points, their density peaks on the "
        "lower hemisphere, cells within a cone of each peak; the planes of every set "
        "(touching coplanar cells), their spacing and persistence (docs/sets.md).",
    )
    add_inputs(p)
    p.add_argument("--grid", type=float, action="append", required=True, metavar="G",
                   help="grid cell size in --units (repeat for several sizes: each output "
                   "name then gets _g<G>, as in compute)")
    p.add_argument("--max-roughness", type=positive, default=None, metavar="T",
                   help="largest ODR roughness of a planar cell, in --units (default "
                   f"{js.DEFAULT_PLANAR_SHARE:g} x the grid size)")
    p.add_argument("--min-planar-points", type=positive_int, default=js.DEFAULT_MIN_PLANAR_POINTS,
                   metavar="K", help="least points of a planar cell (default "
                   f"{js.DEFAULT_MIN_PLANAR_POINTS})")
    p.add_argument("--cone", type=positive, default=js.DEFAULT_CONE_DEG, metavar="DEG",
                   help="a cell joins the nearest density peak within this angle "
                   f"(default {js.DEFAULT_CONE_DEG:g} degrees)")
    p.add_argument("--min-angle", type=non_negative, default=js.DEFAULT_MIN_ANGLE_DEG,
                   metavar="DEG", help="least angle between two sets' peaks (default "
                   f"{js.DEFAULT_MIN_ANGLE_DEG:g} degrees)")
    p.add_argument("--max-sets", type=positive_int, default=js.DEFAULT_MAX_SETS, metavar="N",
                   help=f"largest number of sets (default {js.DEFAULT_MAX_SETS})")
    p.add_argument("--smoothing", type=positive, default=js.DEFAULT_SMOOTHING_DEG, metavar="DEG",
                   help="Fisher kernel sigma of the pole density (default "
                   f"{js.DEFAULT_SMOOTHING_DEG:g} degrees)")
    p.add_argument("--min-density", type=non_negative, default=js.DEFAULT_MIN_DENSITY,
                   metavar="MUD", help="least pole density of a set's peak, multiples of a "
                   f"uniform distribution (default {js.DEFAULT_MIN_DENSITY:g})")
    p.add_argument("--min-set-cells", type=positive_int, default=js.DEFAULT_MIN_SET_CELLS,
                   metavar="K", help=f"least cells of a set (default {js.DEFAULT_MIN_SET_CELLS})")
    p.add_argument("--plane-tolerance", type=non_negative, default=None, metavar="D",
                   help="largest offset along the set's normal between touching cells of one "
                   "plane, and least spacing, in --units (default half the grid size)")
    p.add_argument("--min-plane-cells", type=positive_int, default=js.DEFAULT_MIN_PLANE_CELLS,
                   metavar="K", help="least cells of a plane (default "
                   f"{js.DEFAULT_MIN_PLANE_CELLS})")
    p.add_argument("--max-plane-rms", type=positive, default=None, metavar="D",
                   help="largest RMS of a plane's points about it, in --units: touching cells "
                   "that curve more are no plane (default a quarter of the grid size)")
    p.add_argument("--face-tolerance", type=non_negative, default=DEFAULT_FACE_TOLERANCE_DEG,
                   metavar="DEG", help="a set within this angle of the exposure face (the "
                   "whole cloud's plane, or the local face around its cells) is flagged "
                   "face_parallel: the exposure, not a joint set; its spacing is left out of "
                   f"Jv, Ib and RQD (default {DEFAULT_FACE_TOLERANCE_DEG:g} degrees)")
    p.add_argument("--face-radius", type=positive, default=None, metavar="D",
                   help="radius of the neighbourhood whose plane is a cell's local face, in "
                   f"--units (default {DEFAULT_FACE_RADIUS_CELLS:g} x the grid size; larger "
                   "than the joint faces)")
    p.add_argument("--min-points", type=int, default=None, metavar="K",
                   help="cells with fewer points get no roughness (default: as compute)")
    p.add_argument("--out", required=True, metavar="SETS.csv",
                   help="per-set table (lengths in --units)")
    p.add_argument("--planes-out", metavar="PLANES.csv",
                   help="per-plane (patch) table, with the joint_id of every patch")
    p.add_argument("--joints-out", metavar="JOINTS.csv",
                   help="per-joint table (the patches of one discontinuity)")
    p.add_argument("--summary-json", metavar="SUMMARY.json",
                   help="the sets and the rock-mass figures (Jv, block size index, RQD "
                   "estimate) as JSON")
    p.add_argument("--cells-out", metavar="CELLS.csv",
                   help="per-cell table: compute's columns (ODR) plus set_id, plane_id and "
                   "joint_id")
    p.add_argument("--dips-out", metavar="DIPS.csv",
                   help="the planes as a CSV for Rocscience Dips (Dip/Dip Direction)")
    p.add_argument("--las-out", metavar="OUT.las|OUT.laz",
                   help="every point with set_id, plane_id and joint_id as LAS extra "
                   "dimensions")
    p.add_argument("--ply-out", metavar="OUT.ply",
                   help="every point with set_id, plane_id and joint_id as PLY properties")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_units(p)
    p.set_defaults(func=run)


def _length(value: float) -> str:
    """A length for the sets table, 11 wide; "-" where there is none (a set of one
    plane has no spacing), as the app shows it.

    >>> _length(0.25), _length(float("nan"))
    ('       0.25', '          -')
    """
    return f"{value:11.4g}" if np.isfinite(value) else f"{'-':>11}"


def format_sets(sets, result, *, source: str, unit: str = "m") -> str:
    """Readable summary of the sets and their largest planes for the terminal,
    lengths in ``unit``."""
    per, u = per_unit(unit), UNIT_LABELS[unit]
    planar = int(np.count_nonzero(sets.planar))
    o = sets.options
    lines = [
        f"{source}: {result.n_points_total:,} points, grid {sets.cell_size / per:g} {u}, "
        f"{planar:,} planar cells (ODR roughness <= {sets.max_roughness / per:.4g} {u}, "
        f">= {o.min_planar_points} points), cone {o.cone_deg:g} deg, peaks >= "
        f"{o.min_density:g} MUD and >= {o.min_angle_deg:g} deg apart",
    ]
    if not sets.n_sets:
        lines.append(sets.note)
        return "\n".join(lines)
    n_j = sets.joints.n_joints
    lines.append(f"{sets.n_sets} set{'s' if sets.n_sets != 1 else ''}, "
                 f"{n_j:,} joint{'s' if n_j != 1 else ''} of "
                 f"{sets.planes.n_planes:,} plane{'s' if sets.planes.n_planes != 1 else ''} "
                 "(patches)")
    if sets.curved_groups:
        lines.append(f"{sets.curved_groups:,} group{'s' if sets.curved_groups != 1 else ''} of "
                     f"touching cells curve (RMS about their best plane over "
                     f"{sets.max_plane_rms / per:.3g} {u}): no planes")
    if sets.sliver_planes:
        n = sets.sliver_planes
        lines.append(f"{n:,} strip{'s' if n != 1 else ''} of touching cells about a cell wide "
                     f"fit{'s' if n == 1 else ''} outside {'its' if n == 1 else 'their'} set's "
                     f"cone (the points do not fix the tilt): no planes")
    lines.append("")
    face = sets.face_parallel
    lines.append(f"{'set':>4} {'dip/dir':>9} {'kappa':>8} {'a95':>6} {'cells':>7} {'planes':>6} "
                 f"{'joints':>6} {'spacing ' + u:>11} {'scanline ' + u:>11} "
                 f"{'persist. ' + u:>11} {'face deg':>9}")
    for k in range(sets.n_sets):
        angle = sets.face_angle_deg[k]

        def marked(v: float, face_k: bool = bool(face[k])) -> str:
            # * by a value of a set parallel to the exposure face (no joint spacing)
            return "*" if face_k and np.isfinite(v) else " "

        sp, sc = sets.spacing_mean[k], sets.spacing_scanline_mean[k]
        lines.append(
            f"{k + 1:4d} {sets.dip_deg[k]:3.0f}/{sets.dip_direction_deg[k]:03.0f}   "
            f"{sets.kappa[k]:8.1f} {sets.alpha95_deg[k]:6.2f} {sets.cells[k]:7,} "
            f"{sets.n_planes_per_set[k]:6,} {sets.n_joints_per_set[k]:6,} "
            f"{_length(sp / per)}{marked(sp)}{_length(sc / per)}{marked(sc)}"
            f"{_length(sets.persistence_mean[k] / per)} "
            + (f"{angle:8.1f}{marked(angle)}" if np.isfinite(angle) else f"{'-':>8} "))
    lines += face_lines(sets, unit)
    lines.append(sets.rock_mass_text(unit))
    lines += _roughness_lines(sets, unit)
    pl = sets.planes
    if pl.n_planes:
        lines.append("")
        lines.append(f"{'plane':>6} {'set':>4} {'dip/dir':>9} {'area ' + u + '2':>10} "
                     f"{'dip x strike ' + u:>17} {'rms ' + u:>10}")
        shown = 0
        for k in range(sets.n_sets):
            ids = np.flatnonzero(pl.set_id == k + 1)[:SHOWN_PLANES]
            shown += ids.shape[0]
            for i in ids:
                lines.append(
                    f"{i + 1:6d} {k + 1:4d} {pl.dip_deg[i]:3.0f}/{pl.dip_direction_deg[i]:03.0f}   "
                    f"{pl.area[i] / per**2:10.4g} "
                    f"{pl.persistence_dip[i] / per:8.3g} x {pl.persistence_strike[i] / per:<6.3g} "
                    f"{pl.rms[i] / per:10.3g}")
        if pl.n_planes > shown:
            lines.append(f"  ... {pl.n_planes - shown:,} more planes (--planes-out)")
    return "\n".join(lines)


def _angle(value: float, width: int = 7) -> str:
    """An angle or a JRC estimate, ``width`` wide, one decimal; "-" where none.

    >>> _angle(11.37), _angle(float("nan"))
    ('   11.4', '      -')
    """
    return f"{value:{width}.1f}" if np.isfinite(value) else f"{'-':>{width}}"


def _roughness_lines(sets, unit: str) -> list[str]:
    """The terminal's table of every set's roughness (docs/sets.md, "Roughness of
    each set"): its cells' ODR roughness in ``unit`` and its joints' along dip and
    strike, and the warnings that go with them."""
    from rough_viewer.vocabulary import roughness_scale

    r = sets.roughness
    rper, ru = roughness_scale(unit)
    lines = ["", f"roughness per set: ODR of its cells in {ru} (mean, median, std); its "
             "joints along dip / strike: JRC estimate (Z2 of profiles, Tse and Cruden "
             "1979), theta*max/(C+1) and Delta-T in degrees (shear down dip / along "
             "strike)",
             f"{'set':>4} {'ODR mean':>9} {'median':>8} {'std':>8}  {'JRC est. dip':>12} "
             f"{'strike':>7}  {'th*/(C+1) dip':>13} {'strike':>7}  {'dT dip':>7} "
             f"{'strike':>7}  {'joints':>6} {'profiles':>8}"]
    for k in range(sets.n_sets):
        odr = [(f"{v / rper:8.3g}" if np.isfinite(v) else f"{'-':>8}")
               for v in (r.odr_mean[k], r.odr_median[k], r.odr_std[k])]
        lines.append(
            f"{k + 1:4d} {odr[0]:>9} {odr[1]} {odr[2]}  {_angle(r.jrc_estimate_dip[k], 12)} "
            f"{_angle(r.jrc_estimate_strike[k])}  {_angle(r.theta_max_c1_dip[k], 13)} "
            f"{_angle(r.theta_max_c1_strike[k])}  {_angle(r.delta_t_dip[k])} "
            f"{_angle(r.delta_t_strike[k])}  {r.joints_measured[k]:6d} "
            f"{r.profiles_dip[k] + r.profiles_strike[k]:8d}")
    lines += [f"warning: {w}" for w in r.warnings]
    return lines
def face_lines(sets, unit: str = "m") -> list[str]:
    """One line per set parallel to the exposure face (issue 31 item 2): which face,
    the angle, and that its spacing is no joint spacing."""
    per, u = per_unit(unit), UNIT_LABELS[unit]
    fa = sets.face
    out = []
    for k in np.flatnonzero(sets.face_parallel):
        where = []
        if np.isfinite(fa.whole_deg[k]) and fa.whole_deg[k] <= fa.tolerance_deg:
            where.append(f"{fa.whole_deg[k]:.1f} deg from the whole cloud's plane")
        if fa.by_local(k):
            where.append(f"{fa.local_deg[k]:.1f} deg from its cells' local face within "
                         f"{fa.radius / per:.3g} {u}")
        out.append(f"* set {k + 1} ({sets.dip_deg[k]:.0f}/{sets.dip_direction_deg[k]:03.0f}) "
                   f"is parallel to the exposure face: its spacing is not a joint spacing "
                   f"({', '.join(where)}); its planes are the exposure, left out of Jv, Ib "
                   "and RQD (docs/sets.md, 'Joint set or exposure face?')")
    return out


def summary_dict(sets, source: str, unit: str = "m") -> dict:
    """The sets and their rock-mass figures for ``--summary-json``: lengths in
    ``unit``, ``jv`` in joints per cubic ``unit`` (``jv_per_m3`` in metres, the unit
    of the RQD estimate's formula)."""
    from rough_viewer.io.jsonable import to_jsonable
    from rough_viewer.structure.joints import RQD_FORMULA

    per = per_unit(unit)
    f = sets.figures
    table = sets.set_table(per)
    r = sets.roughness
    extra = {"profiles_dip": r.profiles_dip, "profiles_strike": r.profiles_strike,
             "roughness_joints": r.joints_measured, "roughness_points": r.points_measured,
             "roughness_triangles": r.triangles,
             "profile_sample_spacing": r.sample_spacing / per}
    return {
        "source": source, "unit": unit, "grid": sets.cell_size / per,
        "sets": [{**{name: to_jsonable(table[name][k]) for name in table},
                  **{name: to_jsonable(v[k]) for name, v in extra.items()}}
                 for k in range(sets.n_sets)],
        "joints": int(sets.joints.n_joints), "planes": int(sets.planes.n_planes),
        "jv": to_jsonable(f.jv * per), "jv_per_m3": to_jsonable(f.jv),
        "block_size_index": to_jsonable(f.block_size_index / per),
        "rqd_estimate": to_jsonable(f.rqd_estimate),
        "rqd_estimate_formula": RQD_FORMULA,
        "sets_counted_in_jv": f.sets_counted,
        "jrc_estimate_formula": "JRC = 32.2 + 32.47 log10(Z2) (Tse and Cruden 1979), mean "
                                "over the profiles of the set's joints; an estimate, for "
                                "profiles sampled at 0.5-1 mm",
        "roughness_warnings": list(r.warnings),
        "face_parallel_sets": [int(k) + 1 for k in np.flatnonzero(sets.face_parallel)],
        "face_tolerance_deg": sets.face.tolerance_deg,
        "face_radius": sets.face.radius / per,
    }


def run(args: argparse.Namespace) -> int:
    from rough_viewer.cli._inputs import describe, input_paths, load_inputs
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.grid.roughness import grid_roughness
    from rough_viewer.io.load import resolve_units
    from rough_viewer.io.table import check_table_output
    from rough_viewer.structure.sets import joint_sets

    if args.min_points is not None and args.min_points < 3:
        raise InputError(f"--min-points must be at least 3, got {args.min_points}")
    _set_options(args, 1.0)  # checked before any work (lengths in --units)
    inputs = input_paths(args)
    source = describe(inputs)
    unit, _ = resolve_units(inputs[0], args.units)
    grids = grid_sizes(args.grid, unit)
    several = len(grids) > 1
    wanted = [(opt, getattr(args, opt)) for opt in
              ("out", "planes_out", "joints_out", "summary_json", "cells_out", "dips_out",
               "las_out", "ply_out")
              if getattr(args, opt)]
    if args.las_out:
        from rough_viewer.io.formats.las_out import check_las_output

        check_las_output(args.las_out)
    if args.ply_out and Path(args.ply_out).suffix.lower() != ".ply":
        raise InputError(f"--ply-out must end in .ply, got {args.ply_out}")
    for opt, path in wanted:
        if opt in ("out", "planes_out", "joints_out", "cells_out"):
            check_table_output(path)
    outputs = {opt: {g: output_name(path, g, several, unit) for g in grids} for opt, path in wanted}
    check_outputs([p for by_grid in outputs.values() for p in by_grid.values()],
                  force=args.force, inputs=inputs)
    quiet = args.quiet
    cloud = load_inputs(inputs, units=args.units, quiet=quiet, max_points=args.file_max_points)
    per, u = per_unit(unit), UNIT_LABELS[unit]
    grid_options = {} if args.min_points is None else {"min_points": args.min_points}
    written: list[str] = []
    with all_or_nothing():  # a failed grid or write leaves none of the run's outputs
        for i, g in enumerate(grids):
            with at_grid(g, unit):
                result = grid_roughness(
                    cloud, g * per, models=("odr",),
                    progress=None if quiet else ProgressBar(f"grid {g:g} {u}", unit="step"),
                    **grid_options)
                sets = joint_sets(result, cloud, _set_options(args, per))
            if i:
                print()
            print(format_sets(sets, result, source=source, unit=unit))
            written += _write(outputs, g, sets, result, cloud, source, unit, quiet)
    for line in written:
        print(line)
    return 0


def _set_options(args: argparse.Namespace, per: float):
    """The :class:`~rough_viewer.structure.sets.SetOptions` of the command line, lengths in
    metres (``per`` metres per unit of the command line); InputError for a bad one."""
    from rough_viewer.structure.sets import SetOptions

    return SetOptions(
        max_roughness=None if args.max_roughness is None else args.max_roughness * per,
        min_planar_points=args.min_planar_points, cone_deg=args.cone,
        min_angle_deg=args.min_angle, max_sets=args.max_sets, smoothing_deg=args.smoothing,
        min_density=args.min_density, min_set_cells=args.min_set_cells,
        plane_tolerance=None if args.plane_tolerance is None else args.plane_tolerance * per,
        min_plane_cells=args.min_plane_cells,
        max_plane_rms=None if args.max_plane_rms is None else args.max_plane_rms * per,
        face_tolerance_deg=args.face_tolerance,
        face_radius=None if args.face_radius is None else args.face_radius * per)


def _write(outputs: dict[str, dict[float, Path]], g: float, sets, result, cloud, source: str,
           unit: str, quiet: bool) -> list[str]:
    """Write every output of one grid size; the lines that say so."""
    from rough_viewer.cli._progress import ProgressBar
    from rough_viewer.grid.table import cell_columns, table_metadata
    from rough_viewer.io.formats.las_out import write_las_fields
    from rough_viewer.io.formats.ply import write_ply_fields
    from rough_viewer.io.table import write_table
    from rough_viewer.structure.sets import set_point_fields

    per = per_unit(unit)
    tables = []
    write_table(outputs["out"][g], sets.set_table(per), unit=unit)
    tables.append(str(outputs["out"][g]))
    if "planes_out" in outputs:
        write_table(outputs["planes_out"][g], sets.plane_table(per), unit=unit)
        tables.append(str(outputs["planes_out"][g]))
    if "joints_out" in outputs:
        write_table(outputs["joints_out"][g], sets.joint_table(per), unit=unit)
        tables.append(str(outputs["joints_out"][g]))
    if "summary_json" in outputs:
        import json

        from rough_viewer.io.output import write_atomic

        data = summary_dict(sets, source, unit)

        def dump(fh, d: dict = data) -> None:
            json.dump(d, fh, indent=2)

        write_atomic(outputs["summary_json"][g], dump)
        tables.append(str(outputs["summary_json"][g]))
    if "dips_out" in outputs:
        write_table(outputs["dips_out"][g], sets.dips_table(per), unit=unit)
        tables.append(str(outputs["dips_out"][g]))
    if "cells_out" in outputs:
        keep = result.n_points >= result.min_points  # the rows of cell_columns
        write_table(outputs["cells_out"][g],
                    {**cell_columns(result, unit=unit), "set_id": sets.cell_set[keep],
                     "plane_id": sets.cell_plane[keep], "joint_id": sets.cell_joint[keep]},
                    metadata=table_metadata(result, source, unit=unit), unit=unit)
        tables.append(str(outputs["cells_out"][g]))
    lines = ["wrote " + " and ".join(tables)]
    if "las_out" in outputs or "ply_out" in outputs:
        fields = set_point_fields(sets, result)
        if "las_out" in outputs:
            path = outputs["las_out"][g]
            info = write_las_fields(path, cloud, fields,
                                    progress=None if quiet else ProgressBar(f"writing {path.name}"))
            lines.append(f"wrote {path}: {info}")
        if "ply_out" in outputs:
            path = outputs["ply_out"][g]
            info = write_ply_fields(path, cloud, fields, comments=[
                f"rough_viewer sets: {source}, grid {g:g} {UNIT_LABELS[unit]}, "
                f"set_id, plane_id and joint_id (0 = none), coordinates in {UNIT_LABELS[unit]}"],
                unit=unit)
            lines.append(f"wrote {path}: {info}")
    return lines
