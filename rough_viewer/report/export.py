"""The report of ``rough-viewer report`` for a cloud and a set of settings, as the
command line and the app's Export folder make it: one call from settings to the
finished HTML page (or JSON numbers), and to a file written atomically.

>>> ReportSettings(min_points=4, grid_sizes=(0.5,)).check()   # fine: returns quietly
>>> ReportSettings(min_points=4, threshold=2.0).check()
Traceback (most recent call last):
...
rough_viewer.vocabulary.InputError: threshold must lie in [0, 1], got 2
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from rough_viewer.io.cloud import PointCloud
from rough_viewer.io.output import write_atomic
from rough_viewer.report.build import Report, build_report
from rough_viewer.report.html import report_html
from rough_viewer.report.numbers import report_json
from rough_viewer.scanner.trust import TrustSettings
from rough_viewer.vocabulary import (
    AXIS_CHOICES,
    DEFAULT_THRESHOLD,
    UNITS,
    AxisChoice,
    InputError,
    ProgressFn,
    Unit,
)

ReportFormat = Literal["html", "json"]


@dataclass(frozen=True)
class ReportSettings:
    """What a report is computed with (the options of ``rough-viewer report``)."""

    min_points: int
    """Cells with fewer points get no value."""
    grid_sizes: tuple[float, ...] | None = None
    """Cell edges, metres, one report section each; None (default): from the point
    spacing (:func:`rough_viewer.grid.spacing.preset_cell_sizes`: the size at which
    the typical occupied cell holds 16 points, times 8, 4, 2 and 1). The 2011 paper's
    are :data:`rough_viewer.vocabulary.PAPER_GRIDS`."""
    axis: AxisChoice = "auto"
    """Dependent axis of OLS and hybrid; ``auto`` = closest to the whole-cloud normal."""
    threshold: float = DEFAULT_THRESHOLD
    """Binary-transform threshold on normalised roughness, in [0, 1]."""
    unit: Unit | None = None
    """Unit lengths are shown in (default: the unit the file was in,
    ``PointCloud.source_unit``); the numbers stay metres."""
    trust: TrustSettings | None = None
    """Calibration and options of the scanner section, made when the cloud has scanner
    positions (default: the bias paper's, :class:`rough_viewer.scanner.trust.TrustSettings`)."""
    keep_outliers: bool = False
    """Keep cells whose OLS or hybrid roughness is larger than the cell in every
    statistic and figure (``--keep-outliers``; default: left out and counted,
    :mod:`rough_viewer.grid.outliers`)."""

    def check(self) -> None:
        """Raise InputError (one line, named as the command-line option) for a setting
        the report cannot use."""
        if self.grid_sizes is not None and not self.grid_sizes:
            raise InputError("a report needs at least one grid size")
        for g in self.grid_sizes or ():
            if not (isinstance(g, int | float) and math.isfinite(g) and g > 0):
                raise InputError(f"grid size must be a positive number of metres, got {g!r}")
        if self.unit is not None and self.unit not in UNITS:
            raise InputError(f"unknown unit {self.unit!r}; expected one of {', '.join(UNITS)}")
        if self.axis not in AXIS_CHOICES:
            raise InputError(f"unknown dependent axis {self.axis!r}; expected one of "
                             f"{', '.join(AXIS_CHOICES)}")
        if not (math.isfinite(self.threshold) and 0.0 <= self.threshold <= 1.0):
            raise InputError(f"threshold must lie in [0, 1], got {self.threshold:g}")
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int) \
                or self.min_points < 3:
            raise InputError(f"min points must be a whole number of at least 3, got "
                             f"{self.min_points!r}")
        if self.trust is not None:
            self.trust.check()


def compute_report(cloud: PointCloud, settings: ReportSettings, *,
                   progress: ProgressFn | None = None) -> Report:
    """Every number of the report of ``cloud`` with ``settings`` (checked first)."""
    settings.check()
    grids = (None if settings.grid_sizes is None
             else list(dict.fromkeys(float(g) for g in settings.grid_sizes)))
    return build_report(cloud, grids, axis=settings.axis, threshold=settings.threshold,
                        min_points=settings.min_points, unit=settings.unit,
                        keep_outliers=settings.keep_outliers, progress=progress,
                        trust=settings.trust)


def report_page(cloud: PointCloud, settings: ReportSettings, *,
                progress: ProgressFn | None = None) -> str:
    """The HTML report of ``rough-viewer report`` for ``cloud`` and ``settings``: one
    self-contained page (plotly.js inlined, opens offline)."""
    return report_html(compute_report(cloud, settings, progress=progress))


def report_text(report: Report, fmt: ReportFormat = "html") -> str:
    """A computed report as the text of its file: the HTML page or the JSON numbers."""
    if fmt == "json":
        return json.dumps(report_json(report), indent=1, allow_nan=False)
    if fmt == "html":
        return report_html(report)
    raise InputError(f"unknown report format {fmt!r}; expected html or json")


def write_report(path: str | os.PathLike[str], report: Report, fmt: ReportFormat = "html") -> Path:
    """Write a computed report atomically (check ``path`` first with
    :func:`rough_viewer.io.output.check_output_path`)."""
    text = report_text(report, fmt)
    write_atomic(path, lambda fh: fh.write(text))
    return Path(path)
