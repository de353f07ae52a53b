"""Time the Panels tab's and the report's work on the finest grid of a big scan:
20 M points of a 66 m x 60 m rough face gridded at 0.07 m (about 1 M cells).

Prints, medians of several runs:

- the histogram and Table 1 (``distribution_figures``);
- the first semivariogram panel (``FIRST_BUDGET`` of the cost model) and its
  refinement (``REFINE_BUDGET``): the method the cost model chose, the sampled
  pairs and the largest relative standard error over the lags;
- the report's semivariograms of one grid (all four maps, ``VARIOGRAM_BUDGET``);
- what the exact methods would cost by the same cost model (not run: minutes).

Run: PYTHONPATH=. flock /tmp/rough_viewer_heavy.lock python benchmarks/bench_panels.py
[--points 20000000] [--grid 0.07] [--runs 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from timing import median_seconds

from rough_viewer.app.features.panels import (
    FIRST_BUDGET,
    REFINE_BUDGET,
    distribution_figures,
    variogram_figure_of,
    variogram_maps,
    variograms,
)
from rough_viewer.app.settings import MapSettings
from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.variogram import plan_semivariogram, semivariograms
from rough_viewer.report.build import VARIOGRAM_BUDGET
from rough_viewer.vocabulary import MAPS


def face_points(n: int, seed: int = 0, width: float = 66.0, height: float = 60.0) -> np.ndarray:
    """A rough face ``width`` x ``height`` m in x and z, undulating 3 m along y."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, width, n)
    z = rng.uniform(0.0, height, n)
    y = (3.0 * np.sin(x / 9.0) * np.cos(z / 13.0) + 1.2 * x / width
         + 0.02 * np.sin(x * 3.1) * np.cos(z * 2.3) + 0.004 * rng.standard_normal(n))
    return np.column_stack([x, y, z])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=20_000_000)
    parser.add_argument("--grid", type=float, default=0.07)
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    t = time.perf_counter()
    result = grid_roughness(face_points(args.points), args.grid)
    print(f"{args.points:,} points, grid {args.grid} m: {result.ijk.shape[0]:,} cells "
          f"(made in {time.perf_counter() - t:.1f} s)")
    settings = MapSettings(cell_size=args.grid)
    maps = variogram_maps(settings.model)
    odr = analysed_values(result, "odr")
    for name, fn in (("pairs", "pairs"), ("fft", "fft")):
        plan = plan_semivariogram(result.ijk, odr, args.grid, method=fn)  # type: ignore[arg-type]
        print(f"exact by {name}: cost model {plan.seconds * len(maps):,.0f} s for the panel's "
              f"{len(maps)} maps (lag {plan.max_lag:g} m{', shortened' if plan.lag_limited else ''})")
    tdist, _ = median_seconds(lambda: distribution_figures(result, settings), args.runs)
    print(f"histogram + Table 1: median {tdist:.3f} s")
    for label, budget in (("first", FIRST_BUDGET), ("refined", REFINE_BUDGET)):
        tv, _ = median_seconds(lambda b=budget: variogram_figure_of(result, settings,
                                                                     time_budget=b), args.runs)
        vgs = variograms(result, maps, time_budget=budget)
        assert vgs is not None
        vg = vgs[maps[0]]
        detail = ("exact" if vg.exact else
                  f"sample of {int(vg.sampled.sum()):,} pairs, at least {int(vg.sampled.min()):,}"
                  f" a lag, largest relative SE {np.nanmax(vg.gamma_se / vg.gamma):.1%}")
        print(f"{label} semivariogram panel (budget {budget:g} s, {len(maps)} maps): median "
              f"{tv:.3f} s; {vg.method}: {detail}")
    values = {str(m): analysed_values(result, m) for m in MAPS}
    tr, out = median_seconds(lambda: semivariograms(result.ijk, values, args.grid,
                                                    time_budget=VARIOGRAM_BUDGET), args.runs)
    vg = out["odr"]
    print(f"report semivariograms of the grid (budget {VARIOGRAM_BUDGET:g} s, {len(MAPS)} maps): "
          f"median {tr:.3f} s; {vg.method}"
          + ("" if vg.exact else f", largest relative SE {np.nanmax(vg.gamma_se / vg.gamma):.1%}"))


if __name__ == "__main__":
    main()
