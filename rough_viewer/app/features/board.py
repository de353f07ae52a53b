"""The Board tab (2012 paper): scan the hemisphere board rotated by (alpha, beta),
open the scan in the app, and compare each model's roughness of the whole board with
the closed-form value. OLS and hybrid grow with the rotation away from the dependent
axis; ODR stays near the true value.

"Scan board" queues a load of a :class:`BoardSource` (it replaces a pending
load and takes newer map settings). The scan that was shown is put aside, not
dropped (:attr:`rough_viewer.app.session.Session.stashed`, with its cached grids and
settings): "Back to the scan" (a :class:`BackToScanJob`) shows it again as it was. The board opens with its own colour range (the default
stretch, at its own default grid), whatever range the scan was pinned to.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np
import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.host import Host
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.roughness import grid_roughness, whole_cloud_axis
from rough_viewer.io import PointCloud
from rough_viewer.synthetic.board import BoardScan, board_scan
from rough_viewer.visual.colormaps import ROUGHNESS_STRETCH
from rough_viewer.vocabulary import Axis

#: Cell edge that holds the whole 1 m board in one cell, metres.
WHOLE_BOARD_CELL = 2.0
#: The button that shows the scan put aside again (its name follows in brackets).
BACK_LABEL = "Back to the scan"


@dataclass(frozen=True)
class BoardLesson:
    """One rotated scan and the whole-board roughness of each model (metres)."""

    scan: BoardScan
    theta: dict[str, float]
    axis: str
    n_points: int
    n_points_facing: int
    """Points of the unrotated scan times cos(alpha) cos(beta) (2012 paper)."""


def board_lesson(alpha_deg: float, beta_deg: float, *, axis: Axis | None = None) -> BoardLesson:
    """Scan the board at (alpha, beta) degrees and compute the whole-board roughness.

    ``axis``: dependent axis of OLS/hybrid; default the axis facing the unrotated
    board (as in the 2012 experiment), so the rotation moves the face away from it.
    """
    scan = board_scan(alpha_deg, beta_deg)
    flat = board_scan(0.0, 0.0)
    n0 = flat.cloud.n
    used: Axis = axis or whole_cloud_axis(flat.cloud)
    lo = scan.cloud.xyz().min(axis=0)
    res = grid_roughness(scan.cloud, WHOLE_BOARD_CELL, origin=lo - 0.25, axis=used)
    cell = int(np.argmax(res.n_points))
    theta = {m: float(res.values(m)[cell]) for m in ("odr", "ols", "hybrid", "e_ols")}
    facing = int(round(n0 * np.cos(np.radians(alpha_deg)) * np.cos(np.radians(beta_deg))))
    return BoardLesson(scan, theta, res.axis, scan.cloud.n, facing)


def lesson_markdown(lesson: BoardLesson) -> str:
    """The lesson as Markdown (numbers only)."""
    t = lesson.scan.theoretical_roughness
    rows = [f"**Board α {lesson.scan.alpha_deg:g}°, β {lesson.scan.beta_deg:g}°**: "
            f"{lesson.n_points:,} points (N₀ cos α cos β = {lesson.n_points_facing:,})  ",
            f"true roughness {1e3 * t:.3f} mm; OLS/hybrid along **{lesson.axis}**", "",
            "| model | θ (mm) | vs true |", "|---|---|---|"]
    for m, label in (("odr", "ODR"), ("ols", "OLS"), ("hybrid", "hybrid")):
        v = lesson.theta[m]
        rows.append(f"| {label} | {1e3 * v:.3f} | {100 * (v / t - 1):+.1f} % |")
    return "\n".join(rows)


@dataclass(eq=False)
class BoardFeature:
    """Handles and state of the Board tab."""

    host: Host
    alpha: viser.GuiSliderHandle[float]
    beta: viser.GuiSliderHandle[float]
    scan: viser.GuiButtonHandle
    back: viser.GuiButtonHandle
    """Shows the scan put aside when the board opened (visible while there is one)."""
    note: viser.GuiMarkdownHandle
    binding: Binding = field(default_factory=Binding)
    lesson: BoardLesson | None = None
    """The last scan's lesson."""

    def update_back(self) -> None:
        """Show the "Back to ..." button while a scan is put aside (a button label is
        plain text, never Markdown)."""
        stashed = self.host.session.stashed
        if stashed is None:
            self.binding.write(self.back, visible=False)
            return
        source = stashed.loaded.cloud.source
        name = Path(source).name if source else "the scan"
        self.binding.write(self.back, label=f"{BACK_LABEL} ({name[:60]})", visible=True)


@dataclass(frozen=True)
class BoardSource:
    """The board scanned at (alpha, beta) degrees: a load's source (the lesson is
    computed, and shown in the tab, when the load reads it)."""

    b: BoardFeature = field(compare=False)
    alpha_deg: float
    beta_deg: float

    @property
    def title(self) -> str:
        return "the board scan"

    def read(self, host: Host, run: Run) -> PointCloud:
        lesson = board_lesson(self.alpha_deg, self.beta_deg)
        self.b.lesson = lesson
        self.b.binding.write(self.b.note, content=lesson_markdown(lesson))
        return lesson.scan.cloud

    def release(self) -> None:
        pass


def own_colours(settings: MapSettings) -> MapSettings:
    """The board opens with its own colour range: the default stretch on its cells."""
    return settings.with_(stretch=ROUGHNESS_STRETCH, layer="roughness")


def scan_board(host: Host, b: BoardFeature) -> int:
    """Queue the board scan as a load (the scan shown now is put aside)."""
    alpha, beta = float(b.alpha.value), float(b.beta.value)
    return host.load(BoardSource(b, alpha, beta), stash=True, adjust=own_colours,
                     label=f"board lesson (α {alpha:g}°, β {beta:g}°, synthetic)")


@dataclass(frozen=True)
class BackToScanJob(Job[Host]):
    """Show the scan put aside when the board opened, with its settings and cached
    grids (a load: it cancels maps, panels and picks of the board)."""

    b: BoardFeature = field(compare=False)
    lane: ClassVar[str] = "load"  # a load's: it replaces a pending load
    cancels: ClassVar[frozenset[str]] = frozenset({"render", "panels", "pick"})

    @property
    def title(self) -> str:
        return "back to the scan"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        stashed = ctx.session.stashed
        if stashed is None:
            self.b.update_back()
            return
        ctx.session.stashed = None
        ctx.show_cloud(stashed.loaded, stashed.settings)
        yield "show"
        yield from ctx.render(run, stashed.settings)


def mount(host: Host) -> BoardFeature:
    """Add the Board tab: rotation sliders and a button that opens the scan in the app."""
    gui = host.gui
    with host.tab("Board"):
        b = BoardFeature(
            host=host,
            alpha=gui.add_slider("Board α (°)", min=0.0, max=80.0, step=5.0, initial_value=0.0),
            beta=gui.add_slider("Board β (°)", min=0.0, max=80.0, step=5.0, initial_value=0.0),
            scan=gui.add_button("Scan board",
                                hint="Opens the scan; the cloud shown now is kept aside."),
            back=gui.add_button(BACK_LABEL, visible=False,
                                hint="Show the scan that was open before the board again."),
            note=gui.add_markdown("Scan the 2012 paper's hemisphere board at a rotation and "
                                  "compare the models with the true roughness."),
        )
    host.allow(b.alpha, b.beta, b.scan, b.back)
    b.binding.on_change([b.scan], lambda _h: scan_board(host, b))
    b.binding.on_change([b.back], lambda _h: host.submit(BackToScanJob(b)))
    host.on_cloud(b.update_back)
    return b
