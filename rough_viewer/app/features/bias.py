"""The Bias tab: predict the roughness bias of a scanner (noise, beam smoothing).

:func:`add_bias_panel` adds a folder to a viser GUI: range noise, effective radius,
asperity radius (millimetres), roughness convention and a "Predict" button. The
prediction (:func:`rough_viewer.bias.simulation.predict_bias` on the paper's target
layout) is shown as a small table, with the smoothing curve against ER / asperity
radius for the chosen asperity radius (:func:`rough_viewer.visual.bias.
smoothing_curve_figure`). The panel is self-contained: it needs no loaded cloud.

In the app, :func:`mount` puts the panel in a "Bias" tab and its button queues a
:class:`BiasJob` on the app's worker; on its own (:func:`add_bias_panel`, on any
viser GUI) the panel has a worker of its own that runs it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.host import Host
from rough_viewer.app.layout import PLOTLY_CONFIG
from rough_viewer.app.worker import Job, Run, Worker
from rough_viewer.bias.simulation import BiasPrediction, predict_bias, smoothing_curve
from rough_viewer.vocabulary import BIAS_RESIDUAL, BIAS_TRIALS, RESIDUALS, Residual

#: ER / asperity radius values of the panel's curve.
CURVE_RATIOS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6)

#: Largest values the panel accepts (mm, and the ratio): the simulation raster
#: grows with the asperity radius and the ratio.
MAX_NOISE_MM = 50.0
MAX_ER_MM = 100.0
MAX_ASPERITY_MM = 100.0
MAX_RATIO = 20.0


@dataclass
class BiasPanel:
    """Handles of the bias panel; :meth:`update` recomputes from their values."""

    noise_mm: viser.GuiNumberHandle[float]
    """Range noise sigma, mm."""
    er_mm: viser.GuiNumberHandle[float]
    """Beam effective radius, mm."""
    asperity_mm: viser.GuiNumberHandle[float]
    """Asperity (hemisphere) radius, mm."""
    ratio: viser.GuiNumberHandle[float]
    """Background : asperity ratio of the normalisation."""
    residual: viser.GuiDropdownHandle[Residual]
    """"absolute" (docs/science.md) or "signed" (the paper's numbers)."""
    button: viser.GuiButtonHandle
    """Runs :meth:`update`."""
    result: viser.GuiMarkdownHandle
    """The prediction table."""
    plot: viser.GuiPlotlyHandle
    """The smoothing curve."""
    spacing_m: float = 1e-3
    """Raster spacing of the simulation, metres."""
    last: BiasPrediction | None = None
    """The latest prediction."""
    binding: Binding = field(default_factory=Binding)
    worker: Worker[BiasPanel] | None = None
    """The panel's own worker, on a GUI of its own (:func:`add_bias_panel` without
    ``submit``; None in the app, whose worker runs its :class:`BiasJob`)."""

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        return {"bias": self.plot}

    def update(self) -> BiasPrediction | None:
        """Recompute the prediction and the curve from the handles' values (a job's
        work: on a worker, which runs one at a time).

        Returns the prediction, or None (with a message in the table) for values that
        cannot be simulated.
        """
        from rough_viewer.visual.bias import smoothing_curve_figure

        noise = float(self.noise_mm.value) * 1e-3
        er = float(self.er_mm.value) * 1e-3
        radius = float(self.asperity_mm.value) * 1e-3
        ratio = float(self.ratio.value)
        residual = _residual(self.residual.value)
        b = self.binding
        if residual is None or not (noise >= 0 and er >= 0 and radius > 0 and ratio > 0):
            b.write(self.result, content="**Cannot predict:** values must be positive.")
            return None
        if 0 < er < 0.5 * self.spacing_m:
            b.write(self.result, content=f"**Cannot predict:** ER below "
                    f"{self.spacing_m * 500:g} mm is finer than the simulation raster.")
            return None
        b.write(self.button, disabled=True)
        b.write(self.result, content="_computing..._")
        try:
            p = predict_bias(noise_sigma_m=noise, effective_radius_m=er,
                             asperity_radius_m=radius, spacing_m=self.spacing_m,
                             ratio=ratio, trials=BIAS_TRIALS, residual=residual)
            ratios = np.asarray(CURVE_RATIOS)
            ratios = ratios[(ratios == 0) | (ratios * radius >= 0.5 * self.spacing_m)]
            curve = smoothing_curve(ratios * radius, asperity_radius_m=radius,
                                    noise_sigma_m=noise, spacing_m=self.spacing_m,
                                    ratio=ratio, residual=residual)
        except ValueError as exc:
            b.write(self.result, content=f"**Cannot predict:** {exc}")
            return None
        finally:
            b.write(self.button, disabled=False)
        b.write(self.result, content=prediction_markdown(p))
        b.write(self.plot, figure=smoothing_curve_figure([curve], mark=(p.er_ratio,
                                                                       p.vs_noisy_pct)))
        self.last = p
        return p


def _residual(value: str) -> Residual | None:
    for r in RESIDUALS:
        if r == value:
            return r
    return None


def prediction_markdown(p: BiasPrediction) -> str:
    """The prediction as a markdown table (millimetres and percent)."""
    return "\n".join([
        f"ER / r = **{p.er_ratio:.3f}**, {p.residual} distances, "
        f"normalised {p.ratio:.1f} : 1",
        "",
        "| surface | roughness | bias |",
        "|---|---|---|",
        f"| true | {p.expected_m * 1e3:.3f} mm | |",
        f"| + noise | {p.noise_only_m * 1e3:.3f} mm | {p.noise_effect_pct:+.2f} % |",
        f"| + beam smoothing | {p.smoothing_only_m * 1e3:.3f} mm | "
        f"{p.smoothing_effect_pct:+.2f} % |",
        f"| measured (both) | {p.measured_m * 1e3:.3f} mm | {p.total_effect_pct:+.2f} % |",
    ])


def add_bias_panel(gui: Any, *, order: float | None = None, spacing_m: float = 1e-3,
                   expand: bool = False,
                   submit: Callable[[BiasJob], object] | None = None) -> BiasPanel:
    """Add the scanner-bias panel to a viser GUI.

    Parameters
    ----------
    gui : viser.ViserServer or its ``.gui`` (GuiApi)
        Where to add the folder.
    order : float, optional
        Position of the folder among the GUI's elements.
    spacing_m : float
        Raster spacing of the simulation, metres.
    expand : bool
        Open the folder at start.
    submit : callable, optional
        Queues the :class:`BiasJob` "Predict bias" makes (the app's worker's
        ``submit``); default: the panel's own worker (:attr:`BiasPanel.worker`).

    Returns
    -------
    BiasPanel
        Its handles; the button queues :meth:`BiasPanel.update` as a job.
    """
    import plotly.graph_objects as go

    api: viser.GuiApi = getattr(gui, "gui", gui)
    with api.add_folder("Scanner bias", order=order, expand_by_default=expand):
        noise = api.add_number("Range noise (mm)", 1.6, min=0.0, max=MAX_NOISE_MM, step=0.1,
                               hint="rangefinder noise sigma (bias noise BOARD_SCAN)")
        er = api.add_number("Effective radius (mm)", 4.0, min=0.0, max=MAX_ER_MM, step=0.1,
                            hint="beam effective radius at the scan range (bias radius)")
        radius = api.add_number("Asperity radius (mm)", 19.0, min=1.0, max=MAX_ASPERITY_MM,
                                step=0.5, hint="hemisphere radius of the features of interest")
        ratio = api.add_number("Background : asperity", 5.0, min=0.5, max=MAX_RATIO, step=0.5,
                               hint="point-population normalisation ratio")
        residual = api.add_dropdown("Roughness", RESIDUALS,
                                    initial_value=BIAS_RESIDUAL,
                                    hint="signed distances (the bias paper's definition "
                                    "and published numbers; default) or absolute (the "
                                    "grid maps' convention, docs/science.md)")
        button = api.add_button("Predict bias")
        result = api.add_markdown("Set the scanner values and press **Predict bias**.")
        plot = api.add_plotly(go.Figure(), config=PLOTLY_CONFIG, aspect=1.2)
    panel = BiasPanel(noise_mm=noise, er_mm=er, asperity_mm=radius, ratio=ratio,
                      residual=residual, button=button, result=result, plot=plot,
                      spacing_m=spacing_m)
    if submit is None:
        panel.worker = Worker(panel, name="rough-viewer-bias")
        submit = panel.worker.submit
    panel.binding.on_change([button], lambda _h: submit(BiasJob(panel)))
    return panel


@dataclass(frozen=True)
class BiasJob(Job[Any]):
    """Predict the bias from the panel's values (on the app's worker)."""

    panel: BiasPanel = field(compare=False)
    lane: ClassVar[str] = "bias"

    @property
    def title(self) -> str:
        return "bias prediction"

    def stages(self, ctx: Any, run: Run) -> Iterator[str]:
        self.panel.update()
        yield "predict"


def mount(host: Host) -> BiasPanel:
    """Add the "Bias" tab with the scanner-bias panel (predictions run as jobs)."""
    with host.tab("Bias"):
        panel = add_bias_panel(host.gui, expand=True,
                               submit=host.submit)
    host.allow(panel.noise_mm, panel.er_mm, panel.asperity_mm, panel.ratio,
               panel.residual, panel.button)
    return panel
