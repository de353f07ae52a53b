"""Board teaching view (2012 paper): scan the hemisphere board rotated by
(alpha, beta), open the scan in the app, and compare each model's roughness of
the whole board with the closed-form value. OLS and hybrid grow with the
rotation away from the dependent axis; ODR stays near the true value."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.roughness import grid_roughness, whole_cloud_axis
from rough_viewer.synthetic.board import BoardScan, board_scan

#: Cell edge that holds the whole 1 m board in one cell, metres.
WHOLE_BOARD_CELL = 2.0


@dataclass(frozen=True)
class BoardLesson:
    """One rotated scan and the whole-board roughness of each model (metres)."""

    scan: BoardScan
    theta: dict[str, float]
    axis: str
    n_points: int
    n_points_facing: int
    """Points of the unrotated scan times cos(alpha) cos(beta) (2012 paper)."""


def board_lesson(alpha_deg: float, beta_deg: float, *, axis: str | None = None) -> BoardLesson:
    """Scan the board at (alpha, beta) degrees and compute the whole-board roughness.

    ``axis``: dependent axis of OLS/hybrid; default the axis facing the unrotated
    board (as in the 2012 experiment), so the rotation moves the face away from it.
    """
    scan = board_scan(alpha_deg, beta_deg)
    flat = board_scan(0.0, 0.0)
    n0 = flat.cloud.n
    axis = axis or whole_cloud_axis(flat.cloud)
    lo = scan.cloud.xyz().min(axis=0)
    res = grid_roughness(scan.cloud, WHOLE_BOARD_CELL, origin=lo - 0.25, axis=axis)  # type: ignore[arg-type]
    cell = int(np.argmax(res.n_points))
    theta = {m: float(res.values(m)[cell]) for m in ("odr", "ols", "hybrid", "e_ols")}
    facing = int(round(n0 * np.cos(np.radians(alpha_deg)) * np.cos(np.radians(beta_deg))))
    return BoardLesson(scan, theta, res.axis, scan.cloud.n, facing)


def lesson_markdown(lesson: BoardLesson) -> str:
    t = lesson.scan.theoretical_roughness
    rows = [f"**Board α {lesson.scan.alpha_deg:g}°, β {lesson.scan.beta_deg:g}°**: "
            f"{lesson.n_points:,} points (N₀ cos α cos β = {lesson.n_points_facing:,})  ",
            f"true roughness {1e3 * t:.3f} mm; OLS/hybrid along **{lesson.axis}**", "",
            "| model | θ (mm) | vs true |", "|---|---|---|"]
    for m, label in (("odr", "ODR"), ("ols", "OLS"), ("hybrid", "hybrid")):
        v = lesson.theta[m]
        rows.append(f"| {label} | {1e3 * v:.3f} | {100 * (v / t - 1):+.1f} % |")
    return "\n".join(rows)


def add_board_tab(app, tabs) -> None:
    """Board tab: rotation sliders and a button that opens the scan in the app."""
    gui = app.server.gui
    with tabs.add_tab("Board"):
        alpha = gui.add_slider("Board α (°)", min=0.0, max=80.0, step=5.0, initial_value=0.0)
        beta = gui.add_slider("Board β (°)", min=0.0, max=80.0, step=5.0, initial_value=0.0)
        scan = gui.add_button("Scan board")
        note = gui.add_markdown("Scan the 2012 paper's hemisphere board at a rotation and "
                                "compare the models with the true roughness.")
    app.board = {"controls": {"alpha": alpha, "beta": beta, "scan": scan, "note": note},
                 "lesson": None}

    @scan.on_click
    def _(_event) -> None:
        try:
            lesson = board_lesson(float(alpha.value), float(beta.value))
        except Exception as exc:  # noqa: BLE001 - reported to the user
            app.show_error(f"board scan: {exc}")
            return
        app.board["lesson"] = lesson
        note.content = lesson_markdown(lesson)
        app.load(cloud=lesson.scan.cloud)
