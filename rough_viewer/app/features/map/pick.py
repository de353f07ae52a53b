"""A click on the rock: the cell under it and its roughness across the preset
grids."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import CellInfo, cell_info
from rough_viewer.app.features.map.binding import MapTab
from rough_viewer.app.host import Host, Pick
from rough_viewer.app.markup import md
from rough_viewer.app.picking import pick_cloud_point
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.units import Units
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.scales import PointScales, point_scales_from_prepared
from rough_viewer.scanner.trust import CellTrust
from rough_viewer.visual.scales import point_scales_figure

# ----------------------------------------------------------------------------- pick


@dataclass(frozen=True)
class PickJob(Job[Host]):
    """A click in the scene: pick the point under the ray, then report its cell (or
    hand it to a feature that takes clicks, e.g. the Profile tab)."""

    m: MapTab = field(compare=False)
    origin: tuple[float, float, float]
    direction: tuple[float, float, float]
    lane: ClassVar[str] = "pick"
    keep_all: ClassVar[bool] = True

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        on_click(self.m, self.origin, self.direction)
        yield "pick"


def valid_ray(origin: object, direction: object) -> bool:
    """Both are 3 finite numbers and the direction is not zero (a client's ray)."""
    try:
        o = np.asarray(origin, dtype=np.float64)
        d = np.asarray(direction, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return (o.shape == (3,) and d.shape == (3,) and bool(np.all(np.isfinite(o)))
            and bool(np.all(np.isfinite(d))) and float(np.linalg.norm(d)) > 0)


def on_click(m: MapTab, origin: object, direction: object) -> CellInfo | None:
    """Pick the displayed point under a click ray; let a feature take it, or report
    its cell and the roughness of its cells on every preset grid (returned: the
    cell report). Worker."""
    host = m.host
    shown = host.session.shown
    if shown.result is None or not valid_ray(origin, direction):
        return None
    t0 = time.perf_counter()
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    loaded = shown.loaded
    i = pick_cloud_point(loaded.cloud, loaded.to_file_frame(o), d)  # every point, not a sample
    if i is None:  # the earlier point's report and plot go with it
        m.forget_pick("No point under the click.")
        return None
    xyz = np.array([loaded.cloud.x[i], loaded.cloud.y[i], loaded.cloud.z[i]], dtype=np.float64)
    pick = Pick(int(i), xyz, loaded.to_local(xyz))
    local = pick.local
    if host.picked(pick):
        return None
    info = cell_info(shown.result, pick.point, pick.xyz)
    g = shown.result.grid.cell_size
    u = shown.loaded.units
    host.session.last_pick = info
    m.binding.write(m.pick, content=format_cell_info(info, g, u,
                                                     trust=shown.loaded.trust(shown.result)))
    host.scene.remove(m.pick_nodes)
    m.pick_nodes = host.scene.mark_pick(shown.loaded, info, local, g)
    t_cell = time.perf_counter() - t0
    scales = across_scales(shown.loaded, shown.settings, shown.result, pick.point)
    fig = point_scales_figure(scales, point_xyz=pick.xyz.tolist(), n_points=shown.loaded.n_total,
                              unit=u.unit)
    m.binding.show_figure(m.scales, fig)
    host.session.pick_scales = scales
    m.pick_timings.append({"cell_s": t_cell, "pick_s": time.perf_counter() - t0,
                           "grids": len(scales.cell_sizes)})
    return info


def across_scales(loaded: LoadedCloud, settings: MapSettings, result: GridRoughness,
                  point: int) -> PointScales:
    """ODR, OLS, hybrid roughness and e_ols of the cells holding cloud point ``point``
    on every preset grid (with the shown axis and minimum points): only those cells
    are evaluated, on the nested grids' cell membership (the finest preset's,
    coarsened), so a click costs milliseconds."""
    assert loaded.presets is not None
    grids = [loaded.prepared(g) for g in loaded.presets]
    return point_scales_from_prepared(loaded.cloud, grids, point, axis=result.axis,
                                      min_points=settings.min_points)


def _orientation(dip: float, direction: float) -> str:
    """"dip 26.6°, dip direction 180.0°" (docs/zones.md), or a dash."""
    if not (math.isfinite(dip) and math.isfinite(direction)):
        return "dip —"
    return f"dip {dip:.1f}°, dip direction {direction:05.1f}°"


def format_cell_info(info: CellInfo, cell_size: float, units: Units | None = None, *,
                     trust: CellTrust | None = None) -> str:
    """Markdown of a picked cell (roughness in the roughness unit, mm for metric
    input; coordinates and the grid in the cloud's unit), with the scanner's figures
    of the cell where the cloud has scanner positions (``trust``)."""
    u = units or Units("m")

    rough = u.rough_text  # every model and e_ols to the same 3 significant digits

    n = info.normal
    normal = "—" if not np.all(np.isfinite(n)) else f"({n[0]:.3f}, {n[1]:.3f}, {n[2]:.3f})"
    p = [c / u.per for c in info.point]
    return "\n".join([
        f"**Cell {info.ijk}** ({u.size_text(cell_size)}), {info.n_points} points  ",
        f"point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) {u.label}  ",
        f"θ ODR {rough(info.theta['odr'])}, OLS ({info.axis}) {rough(info.theta['ols'])}  ",
        f"θ hybrid {rough(info.theta['hybrid'])}, e_ols {rough(info.theta['e_ols'])}  ",
        f"normal {normal}  ",
        f"plane {_orientation(info.dip_deg, info.dip_direction_deg)}",
        *(f"  \nscanner: {md(line)}" for line in
          (trust.lines(info.cell, u.unit) if trust is not None else ())),
    ])


