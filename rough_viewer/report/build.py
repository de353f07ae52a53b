"""Every number of the report: roughness maps at each grid size, Table-1 summaries,
histograms, semivariograms and face-plane maps (2011 paper, Table 1 and Figs. 2-4),
the zones at the binary threshold with the stereonet of the cell poles, and the
joint sets (:mod:`rough_viewer.structure.sets`, default settings)."""

from __future__ import annotations

import datetime as _dt
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import numpy as np

from rough_viewer._version import __version__
from rough_viewer.directions.analysis import DirectionsResult
from rough_viewer.grid.maps import FaceMaps, FaceRaster, face_maps, face_raster
from rough_viewer.grid.orientation import Stereonet, cell_stereonet
from rough_viewer.grid.outliers import analysed_values, outlier_text
from rough_viewer.grid.planes import PlaneFit, dominant_axis, whole_cloud_plane
from rough_viewer.grid.roughness import EXACT_FIT, GridRoughness, exact_fit_text, grid_roughness
from rough_viewer.grid.spacing import preset_cell_sizes
from rough_viewer.grid.summary import Histogram, Summary, histogram, normalise, summarise
from rough_viewer.grid.threshold import ThresholdAdvice, threshold_advice
from rough_viewer.grid.variogram import Semivariogram, semivariograms
from rough_viewer.io.cloud import PointCloud
from rough_viewer.scanner.positions import NO_POSITIONS, cloud_scanners
from rough_viewer.scanner.trust import CellTrust, TrustSettings, cell_trust
from rough_viewer.structure.sets import JointSets, joint_sets
from rough_viewer.structure.zones import ZoneLabeller, Zones
from rough_viewer.vocabulary import (
    CONNECTIVITIES,
    DEFAULT_MIN_CELLS,
    DEFAULT_MIN_POINTS,
    HISTOGRAM_BIN,
    MAP_LABELS,
    MAPS,
    UNIT_LABELS,
    UNIT_METRES,
    Connectivity,
    InputError,
    MapName,
    ProgressFn,
)

_T = TypeVar("_T")

MIN_CELLS = 10
"""A grid size leaving fewer cells with an ODR value than this is reported, not drawn."""
VARIOGRAM_FIGURE_MAPS = ("odr", "ols", "e_ols")
"""Maps overlaid in the semivariogram figure (2011 Fig. 4); the numbers cover all maps."""
FACE_MAP_ORDER = ("ols", "odr", "hybrid", "e_ols")
"""Panel order of the face-map figures (2011 Fig. 2: A = OLS, B = ODR)."""
ROUGHNESS_STAGES = 4
"""Progress stages reported by ``grid_roughness``."""
STEPS_PER_GRID = ROUGHNESS_STAGES + len(MAPS) + 2
VARIOGRAM_BUDGET = 10.0
"""Cost-model seconds the semivariograms of one grid size may take (all maps):
exact where that fits, else estimated from a sample of pairs sized to it
(:func:`rough_viewer.grid.variogram.semivariograms`), so a fine grid's report does
not take minutes."""
ZONES_MAP: MapName = "odr"
"""The map whose normalised roughness makes the report's zones."""


@dataclass(frozen=True)
class GridSection:
    """Everything the report shows for one grid size."""

    grid_size: float
    """Cell edge, metres."""
    error: str | None = None
    """Why this grid size has no results (e.g. too few cells), else None."""
    result: GridRoughness | None = None
    summaries: dict[str, Summary] = field(default_factory=dict)
    histograms: dict[str, Histogram] = field(default_factory=dict)
    variograms: dict[str, Semivariogram] = field(default_factory=dict)
    maps: dict[str, FaceMaps] = field(default_factory=dict)
    zones: Zones | None = None
    """Zones of the ODR map at the report's threshold."""
    advice: dict[str, ThresholdAdvice] = field(default_factory=dict)
    """Per map: the share of cells the report's threshold flags and the data's own
    threshold (:func:`rough_viewer.grid.threshold.threshold_advice`)."""
    stereonet: Stereonet | None = None
    """Poles of every cell's ODR plane."""
    trust: CellTrust | None = None
    """Scanner geometry and predicted bias of every cell (docs/scanner.md); None
    without scanner positions (:attr:`Report.scanner_note` says so)."""
    sets: JointSets | None = None
    """Joint sets of the planar cells (default settings)."""
    figure_errors: dict[str, str] = field(default_factory=dict)
    """Figures that could not be made (``"variogram"``, ``"maps"``, ``"zones"``,
    ``"stereonet"``, ``"sets"``), each with why; the rest of the section (Table 1, histograms,
    other figures) stands."""


@dataclass(frozen=True)
class Report:
    """A whole report: the input, the options and one section per grid size."""

    name: str
    """File name of the input (or "in-memory cloud")."""
    source: str
    """Path of the input as given."""
    n_points: int
    dropped_nonfinite: int
    bounds_min: np.ndarray
    """(3,) metres."""
    bounds_max: np.ndarray
    axis: str
    """Dependent axis used by OLS and hybrid."""
    axis_requested: str
    threshold: float
    """Binary-transform threshold on normalised roughness."""
    min_points: int
    plane: PlaneFit
    """The whole-cloud ODR plane (centroid = mean point), the frame of the face maps."""
    sections: tuple[GridSection, ...]
    version: str = __version__
    created: str = ""
    """UTC time the report was made (ISO 8601)."""
    min_cells: int = DEFAULT_MIN_CELLS
    """Zones of fewer cells are dropped."""
    connectivity: Connectivity = "vertex"
    """Which cells of a zone touch."""
    unit: str = "m"
    """Unit every length and roughness is shown in (the numbers here are metres)."""
    grids_chosen: str = "given"
    """``"given"`` or ``"default"``: sizes from the point spacing
    (:func:`rough_viewer.grid.spacing.preset_cell_sizes`)."""
    warnings: tuple[str, ...] = ()
    """What the reader and the report noticed (one line each)."""
    scanner_note: str | None = None
    """Why the report has no scanner section (no positions), else None."""
    keep_outliers: bool = False
    """Cells larger than the cell (:mod:`rough_viewer.grid.outliers`) were kept in
    every statistic and figure (default: left out and counted)."""
    directions: tuple[DirectionsResult, ...] = ()
    """Roughness by direction, one section per input file (``report --directions``)."""


def _section(
    cloud: PointCloud,
    g: float,
    *,
    axis: str,
    threshold: float,
    min_points: int,
    plane: PlaneFit,
    min_cells: int,
    connectivity: Connectivity,
    keep_outliers: bool,
    tick: Callable[[], None],
    stage: ProgressFn,
    trust: TrustSettings | None = None,
) -> GridSection:
    try:
        result = grid_roughness(cloud, g, min_points=min_points, axis=axis,  # type: ignore[arg-type]
                                progress=stage)
    except InputError as exc:
        return GridSection(grid_size=g, error=str(exc))
    return section_of(
        result, threshold=threshold, plane=plane, min_cells=min_cells,
        connectivity=connectivity, keep_outliers=keep_outliers, tick=tick,
        sets=lambda: joint_sets(result, cloud),
        trust=None if trust is None else (lambda: cell_trust(cloud, result, trust)))


def section_of(
    result: GridRoughness,
    *,
    threshold: float,
    plane: PlaneFit,
    min_cells: int,
    connectivity: Connectivity,
    keep_outliers: bool,
    tick: Callable[[], None] = lambda: None,
    sets: Callable[[], JointSets] | str,
    trust: Callable[[], CellTrust | None] | None = None,
) -> GridSection:
    """One grid size's section from its grid result: everything but the joint sets
    and the scanner figures comes from the cells alone.

    Parameters
    ----------
    result : GridRoughness
        The grid (in memory, or out of core: :mod:`rough_viewer.scale`).
    sets : callable or str
        Makes the joint sets (they need every point); a string says why there are
        none (an out-of-core result), recorded as the ``"sets"`` figure's error.
    trust : callable, optional
        Makes the scanner figures; None: no scanner section.
    """
    g = float(result.grid.cell_size)
    n_valid = int(np.count_nonzero(np.isfinite(result.theta_odr)))
    if n_valid < MIN_CELLS:
        return GridSection(
            grid_size=g,
            error=(f"too few cells: {n_valid} cell{'s' if n_valid != 1 else ''} with a "
                   f"roughness value, at least {MIN_CELLS} needed (cells need "
                   f"{result.min_points} points); use a smaller grid size"),
            result=result,
        )
    summaries: dict[str, Summary] = {}
    histograms: dict[str, Histogram] = {}
    normalised: dict[str, np.ndarray] = {}
    analysed: dict[str, np.ndarray] = {}
    advice: dict[str, ThresholdAdvice] = {}
    for name in MAPS:
        summaries[name] = summarise(result, name, keep_outliers=keep_outliers)
        analysed[name] = analysed_values(result, name, keep_outliers=keep_outliers)
        normalised[name] = normalise(analysed[name])
        histograms[name] = histogram(normalised[name], HISTOGRAM_BIN)
        advice[name] = threshold_advice(analysed[name], threshold,
                                        exact_fit=EXACT_FIT * result.grid.cell_size)
    figure_errors: dict[str, str] = {}
    variograms = _figure(figure_errors, "variogram", g, lambda: semivariograms(
        result.ijk, {str(name): analysed[name] for name in MAPS}, g,
        time_budget=VARIOGRAM_BUDGET))
    for _ in MAPS:
        tick()
    maps = _figure(figure_errors, "maps", g,
                   lambda: _face_maps(result, plane, normalised, threshold))
    zones = _figure(figure_errors, "zones", g, lambda: ZoneLabeller.build(
        result, ZONES_MAP, keep_outliers=keep_outliers).zones(
            threshold, connectivity=connectivity, min_cells=min_cells))
    net = _figure(figure_errors, "stereonet", g, lambda: cell_stereonet(result))
    if isinstance(sets, str):
        figure_errors["sets"] = sets
        found = None
    else:
        found = _figure(figure_errors, "sets", g, sets)
    tick()
    cells = None if trust is None else _figure(figure_errors, "scanner", g, trust)
    tick()
    return GridSection(grid_size=g, result=result, summaries=summaries, histograms=histograms,
                       variograms=variograms or {}, maps=maps or {}, zones=zones,
                       advice=advice, stereonet=net, trust=cells, sets=found,
                       figure_errors=figure_errors)


#: Most pixels of one face-plane image. A face whose image at the grid size would be
#: larger (parts far apart, a long face at a fine grid) is rasterised at 2, 4, 8 ...
#: times the grid size, each pixel the max of the cells in it: the same picture the
#: figure would draw after block reduction, without the dense image in between.
FACE_IMAGE_MAX_PIXELS = 4_000_000


def report_raster(result: GridRoughness, plane: PlaneFit) -> FaceRaster:
    """The face-plane raster of a result's cells for the report's images: pixels of
    the grid size, or of 2, 4, 8 ... times it when the image would exceed
    :data:`FACE_IMAGE_MAX_PIXELS` (each pixel then shows the max of its cells)."""
    g = result.grid.cell_size
    raster = face_raster(result.centre, plane, g)
    k = 1
    while (raster.shape[0] // k + 1) * (raster.shape[1] // k + 1) > FACE_IMAGE_MAX_PIXELS:
        k *= 2
    return raster if k == 1 else face_raster(result.centre, plane, g * k)


def _face_maps(result: GridRoughness, plane: PlaneFit, normalised: dict[str, np.ndarray],
               threshold: float) -> dict[str, FaceMaps]:
    raster = report_raster(result, plane)
    return {str(name): face_maps(raster, normalised[name], threshold=threshold) for name in MAPS}


def _figure(errors: dict[str, str], key: str, g: float, make: Callable[[], _T]) -> _T | None:
    """Make one figure's numbers; a failure (memory or bad input) is recorded in
    ``errors`` and never takes the rest of the section with it."""
    try:
        return make()
    except InputError as exc:
        errors[key] = str(exc)
    except MemoryError:
        errors[key] = f"not enough memory for the {key} at grid {g:g} m; use a larger grid size"
    return None


def default_report_grids(cloud: PointCloud) -> tuple[float, ...]:
    """The report's grid sizes when none are given, metres, coarsest first: the presets
    (:func:`rough_viewer.grid.spacing.preset_cell_sizes`) at which the cloud makes at
    least :data:`MIN_CELLS` typical cells (points / median points per occupied cell),
    the finest always; a small cloud's coarse presets gave "too few cells" sections
    (2 of 4 on laspy's sample files)."""
    from rough_viewer.grid.spacing import median_cell_count

    sizes = preset_cell_sizes(cloud)
    kept = tuple(g for g in sizes[:-1]
                 if cloud.n / max(median_cell_count(cloud, g), 1.0) >= MIN_CELLS)
    return (*kept, sizes[-1])


def build_report(
    cloud: PointCloud,
    grid_sizes: Sequence[float] | None = None,
    *,
    axis: str = "auto",
    threshold: float = 0.05,
    min_points: int = DEFAULT_MIN_POINTS,
    min_cells: int = DEFAULT_MIN_CELLS,
    connectivity: Connectivity = "vertex",
    unit: str | None = None,
    keep_outliers: bool = False,
    progress: ProgressFn | None = None,
    trust: TrustSettings | None = None,
) -> Report:
    """Compute every number of the report.

    Parameters
    ----------
    cloud : PointCloud
        The points, metres.
    grid_sizes : sequence of float, optional
        Cell edges, metres; default from the point spacing
        (:func:`rough_viewer.grid.spacing.preset_cell_sizes`: the size at which the
        median occupied cell holds 16 points, times 8, 4, 2 and 1). The paper's are
        :data:`rough_viewer.vocabulary.PAPER_GRIDS`.
    axis : {"auto", "x", "y", "z"}
        Dependent axis of OLS and hybrid.
    threshold : float
        Binary transform threshold on normalised roughness (paper: 0.05).
    min_points : int
        Cells with fewer points get no value.
    min_cells : int
        Zones (connected cells at or above ``threshold``, ODR) of fewer cells are
        dropped.
    connectivity : {"vertex", "edge", "face"}
        Which cells of a zone touch.
    unit : {"m", "mm", "ft", "us-ft"}, optional
        Unit to show lengths in (default: the unit the file was in,
        ``cloud.source_unit``); the numbers stay metres.
    keep_outliers : bool
        Keep cells whose OLS or hybrid roughness is larger than the cell in Table 1,
        the normalisation, histograms, semivariograms, face maps and zones (default:
        left out; :mod:`rough_viewer.grid.outliers`).
    progress : callable, optional
        ``progress(done, total)`` over all steps of all grid sizes.
    trust : TrustSettings, optional
        Calibration and options of the scanner section (default the paper's); the
        section is made when the cloud has scanner positions.

    Returns
    -------
    Report
        One section per grid size; a grid size that fails (too few cells, too many
        cells for memory) has ``error`` set and the others go on.
    """
    if cloud.n < 3:
        raise InputError(f"need at least 3 points, got {cloud.n} ({cloud.source or 'cloud'})")
    if connectivity not in CONNECTIVITIES:
        raise InputError(f"unknown connectivity {connectivity!r}; expected vertex, edge or face")
    if int(min_cells) != min_cells or min_cells < 1:
        raise InputError(f"min cells must be a whole number >= 1, got {min_cells}")
    chosen = "given" if grid_sizes is not None else "default"
    if grid_sizes is None:
        grid_sizes = default_report_grids(cloud)
    sizes = list(dict.fromkeys(float(g) for g in grid_sizes))
    total = STEPS_PER_GRID * len(sizes)
    done = base = 0
    shown = -1

    def show(value: int) -> None:
        nonlocal shown
        value = min(value, total)
        if progress is not None and value > shown:
            shown = value
            progress(value, total)

    def tick() -> None:
        nonlocal done
        done += 1
        show(done)

    def stage(stage_done: int, stage_total: int) -> None:
        # grid_roughness's own stages, mapped onto the first steps of this grid size
        if stage_total > 0:
            show(base + round(ROUGHNESS_STAGES * min(stage_done, stage_total) / stage_total))

    show(0)
    has_scanners = cloud_scanners(cloud) is not None
    trust_used = (trust or TrustSettings()) if has_scanners else None
    if trust_used is not None:
        trust_used.check()
    plane = whole_cloud_plane(cloud)
    used_axis = dominant_axis(plane.normal) if axis == "auto" else axis
    sections = []
    for i, g in enumerate(sizes):
        base = STEPS_PER_GRID * i
        done = base + ROUGHNESS_STAGES
        sections.append(_section(cloud, g, axis=used_axis, threshold=threshold,
                                 min_points=min_points, plane=plane, min_cells=min_cells,
                                 connectivity=connectivity, keep_outliers=keep_outliers,
                                 tick=tick, stage=stage, trust=trust_used))
        done = STEPS_PER_GRID * (i + 1)
        show(done)
    lo, hi = cloud.bounds()
    return _report(
        sections, name=Path(cloud.source).name if cloud.source else "in-memory cloud",
        source=cloud.source, n_points=cloud.n, dropped_nonfinite=cloud.dropped_nonfinite,
        bounds=(lo, hi), axis=used_axis, axis_requested=axis, threshold=threshold,
        min_points=min_points, plane=plane, min_cells=min_cells, connectivity=connectivity,
        unit=unit or cloud.source_unit, grids_chosen=chosen, warnings=cloud.warnings,
        scanner_note=None if has_scanners else NO_POSITIONS, keep_outliers=keep_outliers)


def _report(sections: list[GridSection], *, name: str, source: str, n_points: int,
            dropped_nonfinite: int, bounds: tuple[np.ndarray, np.ndarray], axis: str,
            axis_requested: str, threshold: float, min_points: int, plane: PlaneFit,
            min_cells: int, connectivity: Connectivity, unit: str, grids_chosen: str,
            warnings: tuple[str, ...], scanner_note: str | None,
            keep_outliers: bool) -> Report:
    return Report(
        name=name, source=source, n_points=int(n_points),
        dropped_nonfinite=int(dropped_nonfinite), bounds_min=np.asarray(bounds[0], float),
        bounds_max=np.asarray(bounds[1], float), axis=axis, axis_requested=axis_requested,
        threshold=float(threshold), min_points=int(min_points), plane=plane,
        sections=tuple(sections),
        created=_dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(),
        min_cells=int(min_cells), connectivity=connectivity, unit=unit,
        grids_chosen=grids_chosen,
        warnings=tuple(warnings) + _coverage_warnings(sections, unit, keep_outliers),
        scanner_note=scanner_note, keep_outliers=bool(keep_outliers))


#: Why an out-of-core report has no joint sets.
NO_SETS_OUT_OF_CORE = ("the joint sets fit their planes to every point, which --memory and "
                       "--scheduler do not keep in memory; run 'rough-viewer sets' on the "
                       "input (or this report without those options) for them")


def report_from_results(
    results: Sequence[GridRoughness],
    *,
    source: str,
    bounds: tuple[np.ndarray, np.ndarray],
    dropped_nonfinite: int = 0,
    threshold: float = 0.05,
    min_cells: int = DEFAULT_MIN_CELLS,
    connectivity: Connectivity = "vertex",
    unit: str = "m",
    keep_outliers: bool = False,
    warnings: Sequence[str] = (),
    progress: ProgressFn | None = None,
) -> Report:
    """The report of grid results computed out of core (:mod:`rough_viewer.scale`:
    streamed chunks, or a COPC file's tiles): every figure of :func:`build_report`
    from the cells alone, the same numbers for the same cells; the joint sets are left
    out (:data:`NO_SETS_OUT_OF_CORE`) and so is the scanner section.

    Parameters
    ----------
    results : sequence of GridRoughness
        One per grid size, in the order to show, of one cloud (the same whole plane,
        point count and dependent axis).
    source : str
        The input as given (a path, or several joined).
    bounds : (lo, hi) of (3,) arrays
        The cloud's extent, metres (the files' headers).
    dropped_nonfinite : int
        Rows the reader dropped for NaN or infinite coordinates.
    threshold, min_cells, connectivity, unit, keep_outliers
        As :func:`build_report`.
    warnings : sequence of str
        What the reader noticed.
    progress : callable, optional
        ``progress(done, total)`` over the sections.
    """
    if not results:
        raise InputError("a report needs at least one grid size")
    if connectivity not in CONNECTIVITIES:
        raise InputError(f"unknown connectivity {connectivity!r}; expected vertex, edge or face")
    first = results[0]
    plane = first.whole_plane
    sections = []
    for i, res in enumerate(results):
        sections.append(section_of(res, threshold=threshold, plane=plane, min_cells=min_cells,
                                   connectivity=connectivity, keep_outliers=keep_outliers,
                                   sets=NO_SETS_OUT_OF_CORE))
        if progress is not None:
            progress(i + 1, len(results))
    return _report(
        sections, name=Path(source).name if source else "in-memory cloud", source=source, n_points=first.n_points_total,
        dropped_nonfinite=dropped_nonfinite, bounds=bounds, axis=first.axis,
        axis_requested=first.axis_requested, threshold=threshold,
        min_points=first.min_points, plane=plane, min_cells=min_cells,
        connectivity=connectivity, unit=unit, grids_chosen="given", warnings=tuple(warnings),
        scanner_note=NO_POSITIONS, keep_outliers=keep_outliers)


#: Share of occupied cells with an ODR value below which a grid is called sparse.
SPARSE_SHARE = 0.5


def _coverage_warnings(sections: list[GridSection], unit: str,
                       keep_outliers: bool = False) -> tuple[str, ...]:
    """A line for every grid where most occupied cells have no value, for every grid
    with cells that fit their plane exactly (``EXACT_FIT``), with outlier cells
    (:mod:`rough_viewer.grid.outliers`) and where the threshold flags most of the
    zones' map (:class:`rough_viewer.grid.threshold.ThresholdAdvice`)."""
    out = []
    for s in sections:
        if s.result is None:
            continue
        size = s.grid_size / UNIT_METRES[unit]
        for name in ("ols", "hybrid"):
            text = outlier_text(s.result, name, unit=unit, kept=keep_outliers)
            if text:
                out.append(f"grid {size:g} {UNIT_LABELS[unit]}: {text}"
                           + ("" if keep_outliers else " (--keep-outliers keeps them)"))
        advice = s.advice.get(ZONES_MAP)
        if advice is not None and advice.most:
            out.append(f"grid {size:g} {UNIT_LABELS[unit]}, {MAP_LABELS[ZONES_MAP]}: "
                       f"{advice.text(unit)}")
        rep = s.result.cell_report("odr")
        if rep["occupied"] and rep["with_value"] < SPARSE_SHARE * rep["occupied"]:
            out.append(f"grid {size:g} {UNIT_LABELS[unit]}: only {rep['with_value']:,} of "
                       f"{rep['occupied']:,} occupied cells have a value (too few points per "
                       "cell); a larger grid size gives a fuller map")
        if rep["exact_fit"]:
            out.append(f"grid {size:g} {UNIT_LABELS[unit]}: "
                       f"{exact_fit_text(rep['exact_fit'], rep['with_value'])} of Table 1 "
                       "(remove duplicate points or raise --min-points)")
    return tuple(out)
