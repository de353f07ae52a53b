"""The scanner options of ``compute``, ``report`` and ``serve`` (docs/scanner.md).

::

    [--scanner X,Y,Z | --scanners FILE] [--noise M] [--beam-radius M]
    [--calibration FILE ...] [--asperity-radius M] [--angular-step DEG]

Positions: E57 files give theirs by their poses; LAS/LAZ and text take ``--scanner``
(one scanner for every point) or ``--scanners`` (a CSV of ``point_source_id, x, y,
z``, joined on every point's LAS point source id). Lengths are in ``--units`` (the
input's unit), as every length on these commands; ``--angular-step`` in degrees.
Calibration: the bias paper's by default, then ``--calibration`` files (the JSON of
``bias noise --json`` or ``bias radius --json``), then ``--noise`` and
``--beam-radius``.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rough_viewer.cli._options import naming, parse_xyz
from rough_viewer.io.cloud import PointCloud
from rough_viewer.vocabulary import UNIT_METRES, InputError

if TYPE_CHECKING:
    from rough_viewer.scanner.trust import TrustSettings

def add_scanner_options(p: argparse.ArgumentParser) -> None:
    """Add the scanner position and calibration options to a command."""
    g = p.add_argument_group(
        "scanner (per-cell range, incidence, density, predicted bias; docs/scanner.md)")
    where = g.add_mutually_exclusive_group()
    where.add_argument("--scanner", metavar="X,Y,Z",
                       help="position of the one scanner of every point, in --units (LAS/LAZ, "
                       "text; E57 files give their scans' poses)")
    where.add_argument("--scanners", metavar="FILE",
                       help="CSV of point_source_id,x,y,z (in --units): each point's scanner by "
                       "its LAS point source id")
    g.add_argument("--noise", type=float, metavar="M",
                   help="range noise sigma in --units (default: --calibration, else the bias "
                   "paper's 1.6 mm)")
    g.add_argument("--beam-radius", type=float, metavar="M",
                   help="beam effective radius in --units at every range (default: "
                   "--calibration, else 4 mm)")
    g.add_argument("--calibration", action="append", default=[], metavar="FILE",
                   help="JSON of 'bias noise --json' or 'bias radius --json' (repeatable)")
    g.add_argument("--asperity-radius", type=float, metavar="M",
                   help="radius of the features of interest in --units, for the beam "
                   "smoothing (default 0.019 m, the bias paper's target A; at most half the "
                   "grid size)")
    g.add_argument("--angular-step", type=float, metavar="DEG",
                   help="the scanner's angular step in degrees, for the expected point density "
                   "(default: fitted to the cells)")


def apply_scanner_options(cloud: PointCloud, paths: Sequence[Path], args: argparse.Namespace,
                          unit: str) -> PointCloud:
    """The cloud with the positions of ``--scanner`` or ``--scanners`` (in ``unit``),
    which replace any an E57 file gave; else the cloud as it is."""
    from rough_viewer.scanner.positions import (
        assign_scanners,
        point_source_ids,
        read_scanner_table,
        with_scanner,
    )

    per = UNIT_METRES[unit]
    if getattr(args, "scanner", None):
        x, y, z = parse_xyz(args.scanner, option="--scanner")
        return with_scanner(cloud, (x * per, y * per, z * per))
    if getattr(args, "scanners", None):
        table = read_scanner_table(args.scanners, unit=unit)
        parts = []
        for p in paths:
            with naming(p):
                parts.append(point_source_ids(p))
        ids = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
        return assign_scanners(cloud, ids, table)
    return cloud


def _length(value: float | None, option: str, unit: str, *, allow_zero: bool = True
            ) -> float | None:
    if value is None:
        return None
    from rough_viewer.cli.bias._shared import check_length  # the bias commands' parsers

    return check_length(value, option, unit=unit, allow_zero=allow_zero)


def trust_settings(args: argparse.Namespace, unit: str) -> TrustSettings:
    """The checked trust settings of the options (lengths given in ``unit``)."""
    from rough_viewer.bias.calibration import calibration
    from rough_viewer.scanner.trust import (
        DEFAULT_ASPERITY_RADIUS_M,
        MIN_ANGULAR_STEP_DEG,
        TrustSettings,
    )

    noise = _length(getattr(args, "noise", None), "--noise", unit)
    radius = _length(getattr(args, "beam_radius", None), "--beam-radius", unit)
    asperity = _length(getattr(args, "asperity_radius", None), "--asperity-radius", unit,
                       allow_zero=False)
    step = getattr(args, "angular_step", None)
    if step is not None and not (math.isfinite(step) and MIN_ANGULAR_STEP_DEG <= step < 10.0):
        raise InputError(f"--angular-step must be above 0 and below 10 degrees (at least "
                         f"{MIN_ANGULAR_STEP_DEG:g}: no scanner steps finer), got {step:g}")
    cal = calibration(noise_sigma_m=noise, effective_radius_m=radius,
                      files=getattr(args, "calibration", None) or ())
    settings = TrustSettings(
        calibration=cal,
        asperity_radius_m=DEFAULT_ASPERITY_RADIUS_M if asperity is None else asperity,
        angular_step_rad=None if step is None else math.radians(step))
    settings.check()
    return settings
