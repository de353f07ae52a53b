"""Every de-noising variant of one profile with its fractal dimension (paper Tables 1-2).

For a profile this computes the roughness-length fit of the raw heights and of the
2 decompositions x 4 thresholds x 2 modes de-noised profiles, with the one noise
sigma and the thresholds used. The command line and the app both show this.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rough_viewer.memory import require
from rough_viewer.profiles.fractal import RoughnessLength, Windows, roughness_length
from rough_viewer.profiles.wavelets import (
    DECOMPOSITIONS,
    MODES,
    THRESHOLD_RULES,
    Decomposition,
    Denoised,
    Mode,
    ThresholdRule,
    denoise_result,
    noise_sigma,
)

#: Bytes per profile sample at the peak of comparing all 16 variants: the raw and
#: de-noised heights kept, the wavelet coefficients and the roughness-length
#: windows' temporaries (measured with tracemalloc: 479-503 on 200,000 samples).
COMPARISON_BYTES_PER_SAMPLE = 64 * 8


def require_comparison(n_samples: int, spacing: str) -> None:
    """Raise InputError unless comparing a profile of ``n_samples`` samples fits in
    memory (:data:`COMPARISON_BYTES_PER_SAMPLE`); ``spacing`` is the sample spacing
    as text with its unit, for the message."""
    require(n_samples * COMPARISON_BYTES_PER_SAMPLE,
            f"de-noising a profile of {n_samples:,} samples at {spacing}",
            hint="choose a larger spacing or a shorter line")


@dataclass(frozen=True)
class Variant:
    """One de-noised version of the profile."""

    decomposition: Decomposition
    threshold_rule: ThresholdRule
    mode: Mode
    denoised: Denoised
    fractal: RoughnessLength | None
    """Roughness-length fit of the de-noised heights; None where it cannot be fitted
    (e.g. every window's s(w) is zero)."""
    rms_change: float
    """RMS of (raw - de-noised) over finite samples, metres."""

    @property
    def key(self) -> str:
        """``"<decomposition>_<threshold>_<mode>"``, e.g. ``"dwt_penalized-low_hard"``."""
        return f"{self.decomposition}_{self.threshold_rule}_{self.mode}"


@dataclass(frozen=True)
class Comparison:
    """Raw and de-noised fractal dimensions of one profile."""

    spacing: float
    """Sample spacing, metres."""
    wavelet: str
    level: int
    sigma: float
    """Noise sigma (MAD of level-1 DWT details) the thresholds used, metres."""
    raw: RoughnessLength
    variants: tuple[Variant, ...]
    """In the order decomposition (dwt, wp) x mode (soft, hard) x threshold rule
    (fixed, penalized low/medium/high) — the row order of the paper's tables."""

    @property
    def warnings(self) -> tuple[str, ...]:
        """At most two lines: the raw profile's plausibility warning
        (``"raw profile: D = ... is below 1: ..."``, :func:`~rough_viewer.profiles.
        fractal.plausibility`), and one line counting the de-noised versions whose
        D is outside ``[1, 2]`` (their D is in the table). Variants that could not be
        fitted have no dimension and count for nothing."""
        out = [f"raw profile: {w}" for w in self.raw.warnings]
        dims = [v.fractal.dimension for v in self.variants if v.fractal is not None]
        low = sum(d < 1.0 for d in dims)
        high = sum(d > 2.0 for d in dims)
        if low or high:
            parts = ([f"{low} below 1 (de-noising smooths the profile further)"] if low else []) \
                + ([f"{high} above 2"] if high else [])
            out.append(f"de-noised: D of {' and '.join(parts)} of the {len(dims)} versions; "
                       "try larger windows")
        return tuple(out)

    def thresholds(self) -> dict[str, dict[str, float]]:
        """``{decomposition: {threshold rule: threshold in metres}}``."""
        out: dict[str, dict[str, float]] = {}
        for v in self.variants:
            out.setdefault(v.decomposition, {})[v.threshold_rule] = v.denoised.threshold
        return out

    def variant(self, decomposition: str, threshold_rule: str, mode: str) -> Variant:
        """The variant with these settings (KeyError if absent)."""
        for v in self.variants:
            if (v.decomposition, v.threshold_rule, v.mode) == (decomposition, threshold_rule, mode):
                return v
        raise KeyError(f"{decomposition}/{threshold_rule}/{mode}")


def compare_denoising(
    heights: np.ndarray,
    spacing: float,
    *,
    wavelet: str = "db3",
    level: int = 3,
    windows: Windows = None,
    decompositions: Sequence[Decomposition] = DECOMPOSITIONS,
    threshold_rules: Sequence[ThresholdRule] = THRESHOLD_RULES,
    modes: Sequence[Mode] = MODES,
) -> Comparison:
    """De-noise a profile every way and fit the roughness length to each result.

    Parameters
    ----------
    heights
        (K,) profile heights at a regular spacing, metres (NaN in gaps).
    spacing
        Sample spacing, metres.
    wavelet, level
        Passed to :func:`rough_viewer.profiles.wavelets.denoise_result`.
    windows
        Roughness-length window lengths, metres, or a rule (``"default"``: 8 evenly in
        log from 3 % to 30 % of the length; ``"paper"``: 3 % to 10 %);
        :func:`~rough_viewer.profiles.fractal.roughness_length`.
    decompositions, threshold_rules, modes
        Subsets of the settings to run (default all: 16 variants).

    Returns
    -------
    Comparison
    """
    h = np.asarray(heights, dtype=float)
    require_comparison(h.size, f"{spacing:.4g} m")
    raw = roughness_length(h, spacing, windows=windows)
    variants = []
    for dec in decompositions:
        for mode in modes:
            for rule in threshold_rules:
                res = denoise_result(
                    h, wavelet=wavelet, level=level, decomposition=dec, threshold=rule, mode=mode
                )
                try:
                    fit = roughness_length(res.heights, spacing, windows=windows)
                except ValueError:
                    fit = None
                diff = h - res.heights
                diff = diff[np.isfinite(diff)]
                rms = float(np.sqrt(np.mean(diff**2))) if diff.size else float("nan")
                variants.append(Variant(dec, rule, mode, res, fit, rms))
    # the sigma the thresholds used (pooled over the runs that were decomposed; equal
    # to noise_sigma(heights) for a profile without NaN gaps)
    sigma = variants[0].denoised.sigma if variants else noise_sigma(h, wavelet=wavelet)
    return Comparison(
        spacing=float(spacing),
        wavelet=variants[0].denoised.wavelet if variants else wavelet,
        level=int(level),
        sigma=sigma,
        raw=raw,
        variants=tuple(variants),
    )
