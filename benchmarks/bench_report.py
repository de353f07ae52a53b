"""Where the time of ``rough-viewer report`` goes: per grid size, the seconds of each
number the report computes (roughness, Table 1 and histograms, the semivariograms
of every map, face maps, zones, stereonet) and of each figure it draws and writes
into the page (plotly figure, its HTML), then the page itself; and the whole
command as a process.

    PYTHONPATH=. python benchmarks/bench_report.py /work/shared/data/santacruz_als_laz/*.laz
    PYTHONPATH=. python benchmarks/bench_report.py SCAN.laz --grid 1 --grid 0.5 --repeat 3
    ROUGH_VIEWER_ENGINE=numpy PYTHONPATH=. python benchmarks/bench_report.py SCAN.laz

Stages are timed by calling the report's own functions in the order
:func:`rough_viewer.report.build.build_report` and
:func:`rough_viewer.report.html.report_html` call them (same arguments), so the
figures printed add up to the report's work. Medians of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _timed(times: dict[str, float], key: str, make: Callable[[], Any]) -> Any:
    t = time.perf_counter()
    out = make()
    times[key] = times.get(key, 0.0) + time.perf_counter() - t
    return out


def one_run(path: str, grids: list[float] | None) -> dict[str, float]:
    """Seconds of every stage of one report of ``path`` (in this process)."""
    from rough_viewer.grid.planes import dominant_axis, whole_cloud_plane
    from rough_viewer.grid.spacing import preset_cell_sizes
    from rough_viewer.io.load import load_points
    from rough_viewer.report import build, html

    t: dict[str, float] = {}
    cloud = _timed(t, "read the input", lambda: load_points(path))
    sizes = grids or _timed(t, "default grids (point spacing)", lambda: preset_cell_sizes(cloud))
    plane = _timed(t, "whole-cloud plane", lambda: whole_cloud_plane(cloud))
    axis = dominant_axis(plane.normal)
    for g in sizes:
        _time_grid(t, cloud, g, plane, axis)
    report = build.build_report(cloud, grids or sizes, axis="auto")  # the real sections
    for s in report.sections:
        tag = f"grid {s.grid_size:g}"
        drawn: dict[str, float] = {}
        figures, _ = html.figures_and_errors(report, s, timings=drawn)
        for key, sec in drawn.items():
            t[f"{tag}: figure {key} (plotly)"] = sec
        for key, fig in figures.items():
            _timed(t, f"{tag}: figure {key} (HTML)",
                   lambda f=fig, k=key: f.to_html(full_html=False, include_plotlyjs=False,
                                                  div_id=k, config={"displaylogo": False}))
    _timed(t, "whole page (report_html)", lambda: html.report_html(report))
    return t


def _time_grid(t: dict[str, float], cloud: Any, g: float, plane: Any, axis: str) -> None:
    """The numbers of one grid section, stage by stage (as ``build._section``)."""
    from rough_viewer.grid.orientation import cell_stereonet
    from rough_viewer.grid.roughness import grid_roughness
    from rough_viewer.grid.summary import histogram, normalise, summarise
    from rough_viewer.grid.variogram import semivariogram
    from rough_viewer.report import build
    from rough_viewer.structure.zones import ZoneLabeller
    from rough_viewer.vocabulary import HISTOGRAM_BIN, MAPS

    tag = f"grid {g:g}"
    res = _timed(t, f"{tag}: roughness", lambda: grid_roughness(cloud, g, axis=axis))
    normalised = {}
    for name in MAPS:
        _timed(t, f"{tag}: Table 1 + histograms", lambda n=name: summarise(res, n))
        normalised[name] = normalise(res.values(name))
        _timed(t, f"{tag}: Table 1 + histograms",
               lambda n=name: histogram(normalised[n], HISTOGRAM_BIN))
    for name in MAPS:
        _timed(t, f"{tag}: semivariogram {name}",
               lambda n=name: semivariogram(res.ijk, res.values(n), g))
    _timed(t, f"{tag}: face maps", lambda: build._face_maps(res, plane, normalised, 0.05))
    _timed(t, f"{tag}: zones", lambda: ZoneLabeller.build(res, build.ZONES_MAP).zones(
        0.05, connectivity="vertex", min_cells=build.DEFAULT_MIN_CELLS))
    _timed(t, f"{tag}: stereonet", lambda: cell_stereonet(res))


def whole_process(path: str, grids: list[float] | None, repeat: int) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        argv = [sys.executable, "-m", "rough_viewer", "report", path,
                "--out", str(Path(tmp) / "r.html"), "--force", "--quiet"]
        for g in grids or ():
            argv += ["--grid", str(g)]
        env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
        walls = []
        for _ in range(repeat):
            t = time.perf_counter()
            subprocess.run(argv, check=True, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, env=env)
            walls.append(time.perf_counter() - t)
    return statistics.median(walls)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("input")
    ap.add_argument("--grid", type=float, action="append", help="grid sizes (default: presets)")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    runs: dict[str, list[float]] = defaultdict(list)
    for _ in range(args.repeat):
        for key, sec in one_run(args.input, args.grid).items():
            runs[key].append(sec)
    print(f"report of {args.input}; median seconds of {args.repeat} runs in one process")
    for key, secs in runs.items():
        print(f"  {key:<44} {statistics.median(secs):8.3f}")
    whole = whole_process(args.input, args.grid, args.repeat)
    print(f"whole process 'rough-viewer report' (median of {args.repeat}): {whole:.2f} s")
    print(f"load average: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
