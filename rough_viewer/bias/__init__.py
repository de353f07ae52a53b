"""Scanner bias on roughness (SCIENCE.md section 3, the TLS instrument-bias paper):
measurement of range noise and beam radius from calibration scans, point-population
normalisation, and simulation of rough targets to predict the bias."""

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
