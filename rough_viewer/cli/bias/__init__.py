"""``rough-viewer bias``: scanner bias on roughness (range noise, beam radius, simulation).

Subcommands (each prints a short text report, or JSON with ``--json``; lengths in
metres in JSON, millimetres in text; the commands reading a scan take lengths in
``--units`` and show them in mm for metric input, in the input's unit otherwise)::

    rough-viewer bias noise BOARD_SCAN [--segments 8|RxC] [--scanner X,Y,Z]
        [--sample-points N] [--seed S] [--max-points N] [--units m|mm|ft|us-ft] [--json]
    rough-viewer bias radius WIRE_SCAN [WIRE_SCAN ...] [--scanner X,Y,Z]
        [--top-fraction 0.02] [--wire-radius M] [--break-range M]
        [--units m|mm|ft|us-ft] [--json]
    rough-viewer bias simulate [--target A|B] [--asperity-radius M] [--noise M] [--er M]
        [--spacing M] [--ratio 5] [--trials N] [--seed S] [--residual signed|absolute]
        [--out CLOUD.las|.laz] [--force] [--quiet] [--json]
    rough-viewer bias normalise SCAN [--classes kmeans-3sigma|kmeans|truth] [--noise M]
        [--truth-dim truth] [--ratio 5] [--scanner X,Y,Z] [--seed S]
        [--residual signed|absolute] [--units m|mm|ft|us-ft]
        [--out NORMALISED.las|.laz] [--force] [--json]
    rough-viewer bias predict --noise M --er M [--asperity-radius M | --target A|B]
        [--ratio 5] [--trials N] [--spacing M] [--seed S] [--residual signed|absolute]
        [--quiet] [--json]
    rough-viewer bias curve --noise M --asperity-radius M[,M...] --er-ratio R[,R...]
        [--ratio 5] [--spacing M] [--seed S] [--residual signed|absolute] [--quiet]
        [--json]

Every numeric option is range-checked before any work (one line naming the option,
exit 2; the limits are in ``_shared`` and docs/bias.md).

Each subcommand is one module of this package. See docs/bias.md.
"""

from __future__ import annotations

import argparse

from rough_viewer.cli.bias import curve, noise, normalise, predict, radius, simulate

#: Subcommand modules, in the order ``rough-viewer bias --help`` lists them.
SUBCOMMANDS = (noise, radius, simulate, normalise, predict, curve)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bias",
        help="scanner bias: range noise, beam effective radius, rough-target simulation",
        description="Measure a scanner's range noise (flat board) and beam effective radius "
        "(thin wire), simulate rough targets and predict how noise and beam smoothing bias "
        "roughness (docs/science.md section 3, docs/bias.md).",
    )
    s = p.add_subparsers(dest="bias_command", metavar="SUBCOMMAND", parser_class=type(p))
    p.set_defaults(func=lambda a: (p.print_help(), 2)[1])
    for module in SUBCOMMANDS:
        module.register(s)
