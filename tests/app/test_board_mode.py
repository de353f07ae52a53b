import numpy as np
import pytest

from rough_viewer.app.features.board import BoardFeature, board_lesson
from rough_viewer.synthetic.board import PAPER_THEORETICAL_ROUGHNESS_M


def test_unrotated_board_matches_the_paper_and_ols_grows_with_rotation():
    flat = board_lesson(0.0, 0.0)
    t = PAPER_THEORETICAL_ROUGHNESS_M
    assert flat.scan.theoretical_roughness == pytest.approx(t, rel=1e-3)
    for m in ("odr", "ols", "hybrid"):
        assert flat.theta[m] == pytest.approx(t, rel=0.1)
    turned = board_lesson(40.0, 0.0)
    assert turned.theta["ols"] > flat.theta["ols"] * 1.1
    assert abs(turned.theta["odr"] / t - 1) < abs(turned.theta["ols"] / t - 1)
    assert turned.n_points == pytest.approx(turned.n_points_facing, rel=0.1)
    steep = board_lesson(70.0, 0.0)
    assert steep.axis == flat.axis  # the axis stays the one facing the unrotated board
    assert steep.theta["ols"] > turned.theta["ols"]


def test_scan_button_opens_the_board_in_the_app(app):
    board = app.feature(BoardFeature)
    board.alpha.value = 30.0
    board.scan.value = True  # queues a load of the board scan on the worker
    assert app.wait_idle(60)
    lesson = board.lesson
    assert lesson is not None and app.session.shown.loaded.cloud is lesson.scan.cloud
    assert "Board α 30°" in board.note.content and "true roughness" in board.note.content
    status = app.host.status.content.replace("\\", "")
    assert "board lesson (α 30°, β 0°, synthetic)" in status and "in-memory" not in status
    assert np.isfinite(lesson.theta["odr"])
    kinds = [r.kind for r in app.worker.records]
    assert kinds[-2:] == ["LoadJob", "PanelsJob"]  # the board scan is a load
