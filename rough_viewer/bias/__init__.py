"""Scanner bias on roughness (docs/science.md section 3, the TLS instrument-bias paper):
measurement of range noise and beam radius from calibration scans, point-population
normalisation, and simulation of rough targets to predict the bias.

Names are loaded on first use (the command line's trust settings import the
calibration, not SciPy's signal and optimisation modules).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rough_viewer.lazy import lazy_names

#: Public name -> module that defines it (loaded on first use, PEP 562).
_API: dict[str, str] = {
    "EffectiveRadius": "rough_viewer.bias.measurement",
    "NormalisedPopulation": "rough_viewer.bias.measurement",
    "RangeNoise": "rough_viewer.bias.measurement",
    "classify_population": "rough_viewer.bias.measurement",
    "effective_radius": "rough_viewer.bias.measurement",
    "fit_piecewise_linear": "rough_viewer.bias.measurement",
    "normalise_population": "rough_viewer.bias.measurement",
    "range_noise": "rough_viewer.bias.measurement",
    "target_roughness": "rough_viewer.bias.measurement",
    "BiasPrediction": "rough_viewer.bias.simulation",
    "SmoothingCurve": "rough_viewer.bias.simulation",
    "predict_bias": "rough_viewer.bias.simulation",
    "simulate_target": "rough_viewer.bias.simulation",
    "smoothing_curve": "rough_viewer.bias.simulation",
}

__all__ = [
    "BiasPrediction",
    "EffectiveRadius",
    "NormalisedPopulation",
    "RangeNoise",
    "SmoothingCurve",
    "classify_population",
    "effective_radius",
    "fit_piecewise_linear",
    "normalise_population",
    "predict_bias",
    "range_noise",
    "simulate_target",
    "smoothing_curve",
    "target_roughness",
]

__getattr__, __dir__ = lazy_names(__name__, _API)


if TYPE_CHECKING:  # names for type checkers and IDEs; loaded lazily at run time
    from rough_viewer.bias.measurement import (
        EffectiveRadius,
        NormalisedPopulation,
        RangeNoise,
        classify_population,
        effective_radius,
        fit_piecewise_linear,
        normalise_population,
        range_noise,
        target_roughness,
    )
    from rough_viewer.bias.simulation import (
        BiasPrediction,
        SmoothingCurve,
        predict_bias,
        simulate_target,
        smoothing_curve,
    )
