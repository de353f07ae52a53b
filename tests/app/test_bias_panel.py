"""The scanner-bias panel on a real viser server (no browser), and its figures."""

from __future__ import annotations

import socket

import pytest

from rough_viewer.app.features.bias import add_bias_panel
from rough_viewer.bias.simulation import predict_bias
from rough_viewer.vocabulary import BIAS_TRIALS


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def server():
    import viser

    srv = viser.ViserServer(host="127.0.0.1", port=_free_port(), verbose=False)
    yield srv
    srv.stop()


def test_panel_predicts_from_its_values(server):
    panel = add_bias_panel(server, spacing_m=0.002)
    panel.noise_mm.value = 1.6
    panel.er_mm.value = 6.0
    panel.asperity_mm.value = 19.0
    panel.button.value = True  # a press: the panel's own worker predicts
    assert panel.worker is not None and panel.worker.wait_idle(120)
    p = panel.last
    # the panel's own "Roughness" dropdown (first entry: absolute) decides the convention
    ref = predict_bias(noise_sigma_m=0.0016, effective_radius_m=0.006, asperity_radius_m=0.019,
                       spacing_m=0.002, trials=BIAS_TRIALS, residual=str(panel.residual.value))
    assert p is not None and p.measured_m == pytest.approx(ref.measured_m)
    assert f"{ref.measured_m * 1e3:.3f} mm" in panel.result.content
    assert f"{ref.noise_effect_pct:+.2f} %" in panel.result.content
    fig = panel.plot.figure
    assert len(fig.data) == 2                      # the curve and the marked prediction
    assert fig.data[1].x[0] == pytest.approx(6.0 / 19.0)
    assert not panel.button.disabled
    # the same trials as `rough-viewer bias predict` (its numbers, the docs say)
    from rough_viewer.cli import build_parser

    args = build_parser().parse_args(["bias", "predict", "--noise", "0.0016", "--er", "0.004"])
    assert args.trials == BIAS_TRIALS


def test_panel_refuses_unrepresentable_er(server):
    panel = add_bias_panel(server.gui, spacing_m=0.002)
    panel.er_mm.value = 0.5
    panel.button.value = True
    assert panel.worker is not None and panel.worker.wait_idle(60)
    assert "Cannot predict" in panel.result.content and panel.last is None
