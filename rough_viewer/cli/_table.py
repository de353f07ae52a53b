"""The one text format of the Table-1 summary (2011 paper, Table 1), used by the
command line; the report and the app show the same numbers from the same
:class:`rough_viewer.grid.summary.Summary`."""

from __future__ import annotations

import math

from rough_viewer.grid.outliers import outlier_text
from rough_viewer.grid.roughness import GridRoughness, exact_fit_text
from rough_viewer.grid.summary import summaries
from rough_viewer.vocabulary import MAP_LABELS, UNIT_LABELS, UNIT_METRES


def _num(v: float, fmt: str) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, fmt)


def format_table(result: GridRoughness, *, source: str = "", unit: str = "m",
                 keep_outliers: bool = False) -> str:
    """Readable Table-1 style summary of all maps of one grid size, lengths in ``unit``;
    cells larger than the cell left out unless ``keep_outliers`` (and said so)."""
    per, u = UNIT_METRES[unit], UNIT_LABELS[unit]
    g = result.grid.cell_size / per
    axis = result.axis + (" (auto)" if result.axis_requested == "auto" else "")
    head = (
        f"{source or 'cloud'}: {result.n_points_total:,} points, grid {g:g} {u}, "
        f"dependent axis {axis}, min points {result.min_points}"
        + (", signed residuals" if result.residual == "signed" else "")
    )
    rep = result.cell_report("odr")
    cells_line = (
        f"cells: {rep['occupied']:,} occupied, {rep['below_min_points']:,} below min points"
    )
    lines = [head, cells_line]
    if rep["exact_fit"]:
        lines.append(f"note: {exact_fit_text(rep['exact_fit'], rep['with_value'])}. "
                     "Remove duplicate points or raise --min-points")
    for name in ("ols", "hybrid"):
        text = outlier_text(result, name, unit=unit, kept=keep_outliers) \
            if name in result.models else None
        if text:
            lines.append(f"note: {text}" + ("" if keep_outliers else
                         " (--keep-outliers keeps them; CELLS.csv marks them in 'outlier')"))
    lines.append("")
    cols = ("model", "cells", "mean pts", f"min ({u})", f"max ({u})", f"mean ({u})",
            f"variance ({u}2)", f"std ({u})")
    widths = (7, 9, 9, 11, 11, 11, 13, 11)
    lines.append("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(cols, widths, strict=True))))
    for name, s in summaries(result, keep_outliers=keep_outliers).items():
        if name != "e_ols" and name not in result.models:
            continue
        if name == "e_ols" and not ("odr" in result.models and "ols" in result.models):
            continue
        row = (
            MAP_LABELS[name].ljust(widths[0]),
            f"{s.cells:,}".rjust(widths[1]),
            _num(s.mean_points, ".1f").rjust(widths[2]),
            _num(s.min / per, ".4e").rjust(widths[3]),
            _num(s.max / per, ".4e").rjust(widths[4]),
            _num(s.mean / per, ".4e").rjust(widths[5]),
            _num(s.variance / per**2, ".4e").rjust(widths[6]),
            _num(s.std / per, ".4e").rjust(widths[7]),
        )
        lines.append("  ".join(row))
        deg = result.cell_report(name)["degenerate"] if name != "e_ols" else 0
        if deg:
            lines.append(f"{'':9}({deg:,} cells with enough points but no unique {MAP_LABELS[name]} plane)")
    return "\n".join(lines)
