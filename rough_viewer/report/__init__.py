"""The grid-roughness report: the 2011 paper's Table 1 and Figs. 2-4 for one cloud.

:func:`build_report` computes everything (roughness maps at each grid size, Table-1
summaries, histograms, semivariograms, face-plane maps, zones, the stereonet of
cell poles and the joint sets); :func:`report_json` turns it
into plain numbers; :func:`report_html` into one self-contained HTML page (plotly.js
inlined, works offline); :func:`report_figures` gives the plotly figures, e.g. for
PNG export.

Modules: :mod:`.build` (the numbers), :mod:`.numbers` (JSON), :mod:`.html`
(the page and its figures).
"""

from rough_viewer.report.build import (
    FACE_MAP_ORDER,
    MIN_CELLS,
    VARIOGRAM_FIGURE_MAPS,
    GridSection,
    Report,
    build_report,
)
from rough_viewer.report.html import (
    FIGURE_NAMES,
    check_png_export,
    png_figures,
    png_name,
    report_figures,
    report_html,
)
from rough_viewer.report.numbers import report_json, sets_dict, variogram_dict, zones_dict
from rough_viewer.vocabulary import HISTOGRAM_BIN, PAPER_GRIDS

__all__ = [
    "FACE_MAP_ORDER",
    "FIGURE_NAMES",
    "HISTOGRAM_BIN",
    "MIN_CELLS",
    "PAPER_GRIDS",
    "VARIOGRAM_FIGURE_MAPS",
    "GridSection",
    "Report",
    "build_report",
    "check_png_export",
    "png_figures",
    "png_name",
    "report_figures",
    "report_html",
    "report_json",
    "sets_dict",
    "variogram_dict",
    "zones_dict",
]
