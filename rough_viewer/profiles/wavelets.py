"""Wavelet de-noising of roughness profiles (Khoshelham & Altundag).

Conventions (docs/science.md section 2), so results are reproducible to the last digit:

- PyWavelets boundary mode ``symmetric``.
- Noise sigma: median of the absolute level-1 DWT detail coefficients divided by
  0.6745 (for wavelet packets too).
- ``d`` = the number of those level-1 detail coefficients.
- Fixed-form threshold: ``sigma sqrt(2 ln d)`` (DWT) and
  ``sigma sqrt(2 ln(d ln d / ln 2))`` (wavelet packets).
- Penalized (Birge-Massart) threshold: the detail coefficients that will be thresholded
  (all DWT details of levels 1..L, or every level-L packet except the pure
  approximation node, natural order) are sorted by decreasing magnitude ``w_1 >= w_2
  >= ... >= w_n``; ``t* = argmin_{t=1..n} [ -sum_{k<=t} w_k^2 + 2 t sigma^2 (alpha +
  ln(n / t)) ]`` (first minimum on ties); threshold ``|w_t*|``; alpha = 1.5 / 2 / 5 for
  low / medium / high.
- ONE global threshold per profile, applied hard (keep ``|w| >= t``) or soft (shrink
  by ``t``) to those detail coefficients; approximation coefficients are kept; the
  reconstruction is cut to the input length.

NaN gaps. A profile may contain NaN samples (gaps reported by profile extraction).
Each contiguous run of finite samples is decomposed on its own; sigma, ``d`` and the
penalized criterion are computed on the level-1 details / thresholded coefficients of
all runs pooled together, so the profile still gets ONE sigma and ONE threshold (for a
profile without NaN this is exactly the convention above). NaN samples stay NaN. A run
too short for the requested level cannot be decomposed without
PyWavelets' boundary warning (fewer than ``(filter length - 1) * 2**level`` samples,
40 for db3 at level 3): its samples become NaN in the de-noised output and the run is listed in
:attr:`Denoised.skipped_runs`; nothing is filled in silently. A profile with no run long
enough raises ``ValueError``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pywt

from rough_viewer.vocabulary import (
    DECOMPOSITIONS,
    MODES,
    THRESHOLD_RULES,
    Decomposition,
    InputError,
    Mode,
    ThresholdRule,
)

#: Sparsity parameter alpha of the Birge-Massart penalty, per penalized rule.
PENALTY_ALPHA: dict[str, float] = {
    "penalized-low": 1.5,
    "penalized-medium": 2.0,
    "penalized-high": 5.0,
}

#: Consistency constant of the MAD noise estimate (Donoho & Johnstone 1995).
MAD_CONSTANT = 0.6745

_BOUNDARY = "symmetric"


@dataclass(frozen=True)
class Denoised:
    """A de-noised profile and the numbers that produced it."""

    heights: np.ndarray
    """(K,) de-noised heights, metres (same length as the input; NaN where the input
    is NaN or in a skipped run)."""
    sigma: float
    """Noise standard deviation estimated by MAD of the level-1 DWT details, metres."""
    threshold: float
    """The one global threshold applied to the detail coefficients, metres."""
    wavelet: str
    level: int
    decomposition: Decomposition
    threshold_rule: ThresholdRule
    mode: Mode
    d: int
    """Number of level-1 DWT detail coefficients (pooled over runs)."""
    n_coefficients: int
    """Number of thresholded detail coefficients (the ``n`` of the penalized rule)."""
    n_kept: int
    """Number of thresholded detail coefficients that survive (non-zero after)."""
    runs: tuple[tuple[int, int], ...]
    """Index ranges ``[start, stop)`` of the finite runs that were de-noised."""
    skipped_runs: tuple[tuple[int, int], ...]
    """Index ranges ``[start, stop)`` of finite runs too short for ``level`` (set NaN)."""


# ----------------------------------------------------------------------------- helpers


def _wavelet(wavelet: str | pywt.Wavelet) -> pywt.Wavelet:
    try:
        return wavelet if isinstance(wavelet, pywt.Wavelet) else pywt.Wavelet(wavelet)
    except ValueError as exc:
        raise InputError(f"unknown discrete wavelet {wavelet!r} (see pywt.wavelist(kind='discrete'))") from exc


def finite_runs(heights: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges ``[start, stop)`` of the contiguous runs of finite values."""
    ok = np.isfinite(np.asarray(heights, dtype=float))
    edges = np.diff(np.concatenate(([0], ok.astype(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)
    return list(zip(starts.tolist(), stops.tolist(), strict=True))


def _as_profile(heights: np.ndarray) -> np.ndarray:
    h = np.asarray(heights, dtype=float)
    if h.ndim != 1:
        raise InputError(f"a profile must be one-dimensional, got shape {h.shape}")
    return h


#: Deepest decomposition: a level-30 one already needs a run of 2**30 samples or more
#: (``--level 1e12`` computed 2**1e12, 3.1 GB, then MemoryError).
MAX_LEVEL = 30


def min_run_length(wavelet: str | pywt.Wavelet, level: int) -> int:
    """Fewest samples a run needs for a ``level``-deep decomposition with ``wavelet``:
    ``(filter length - 1) * 2**level`` (PyWavelets' ``dwt_max_level`` limit).

    Raises InputError for a level outside 1 .. :data:`MAX_LEVEL`."""
    if not 1 <= int(level) <= MAX_LEVEL:
        raise InputError(f"the decomposition level must be from 1 to {MAX_LEVEL} (a level-L "
                         f"decomposition needs runs of 2**L samples or more), got {level}")
    return (_wavelet(wavelet).dec_len - 1) * 2**int(level)


def _usable_runs(
    h: np.ndarray, level: int, w: pywt.Wavelet
) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    min_len = min_run_length(w, level)
    runs = finite_runs(h)
    used = [(a, b) for a, b in runs if b - a >= min_len]
    skipped = [(a, b) for a, b in runs if b - a < min_len]
    if not used:
        raise InputError(
            f"profile has no run of at least {min_len} finite samples "
            f"(needed for a level-{level} decomposition)"
        )
    return used, skipped


def _level1_details(h: np.ndarray, runs: list[tuple[int, int]], w: pywt.Wavelet) -> np.ndarray:
    return np.concatenate([pywt.dwt(h[a:b], w, mode=_BOUNDARY)[1] for a, b in runs])


def _decompose(x: np.ndarray, w: pywt.Wavelet, level: int, decomposition: Decomposition):
    """Return (container, list of detail arrays to threshold)."""
    if decomposition == "dwt":
        coeffs = pywt.wavedec(x, w, mode=_BOUNDARY, level=level)
        return coeffs, coeffs[1:]
    if decomposition == "wp":
        wp = pywt.WaveletPacket(data=x, wavelet=w, mode=_BOUNDARY, maxlevel=level)
        nodes = wp.get_level(level, order="natural")
        return nodes, [n.data for n in nodes if n.path != "a" * level]
    raise InputError(f"decomposition must be 'dwt' or 'wp', got {decomposition!r}")


def _reconstruct(container, new_details, w, level, decomposition, n) -> np.ndarray:
    if decomposition == "dwt":
        out = pywt.waverec([container[0], *new_details], w, mode=_BOUNDARY)
    else:
        wp = pywt.WaveletPacket(data=None, wavelet=w, mode=_BOUNDARY, maxlevel=level)
        it = iter(new_details)
        for node in container:
            wp[node.path] = node.data if node.path == "a" * level else next(it)
        out = wp.reconstruct(update=False)
    return np.asarray(out[:n], dtype=float)


# ----------------------------------------------------------------------------- public


def mad_sigma(coefficients: np.ndarray) -> float:
    """Noise sigma from detail coefficients: ``median(|w|) / 0.6745`` (same unit as w)."""
    c = np.asarray(coefficients, dtype=float)
    if c.size == 0:
        raise InputError("no detail coefficients to estimate the noise from")
    return float(np.median(np.abs(c)) / MAD_CONSTANT)


def noise_sigma(heights: np.ndarray, *, wavelet: str = "db3") -> float:
    """Noise standard deviation of a profile by the MAD of its level-1 DWT details.

    Parameters
    ----------
    heights
        (K,) profile heights, metres; NaN samples split the profile into runs whose
        level-1 details are pooled (runs shorter than 2 samples are ignored).
    wavelet
        Any discrete PyWavelets wavelet name (default Daubechies 3).

    Returns
    -------
    float
        ``median(|d1|) / 0.6745``, metres.

    Examples
    --------
    >>> import numpy as np
    >>> smooth = np.sin(np.linspace(0, 6, 4096)) * 0.01
    >>> noisy = smooth + np.random.default_rng(0).normal(0, 0.0005, 4096)
    >>> round(noise_sigma(noisy) * 1e3, 2)  # true noise 0.5 mm
    0.49
    """
    h = _as_profile(heights)
    w = _wavelet(wavelet)
    runs, _ = _usable_runs(h, 1, w)
    return mad_sigma(_level1_details(h, runs, w))


def fixed_threshold(sigma: float, d: int, *, decomposition: Decomposition = "dwt") -> float:
    """Fixed-form (universal) threshold of Donoho & Johnstone.

    ``sigma sqrt(2 ln d)`` for DWT, ``sigma sqrt(2 ln(d ln d / ln 2))`` for wavelet
    packets; ``d`` is the number of level-1 detail coefficients. Same unit as sigma.
    """
    if d < 2:
        raise InputError(f"need at least 2 level-1 detail coefficients, got {d}")
    if decomposition == "dwt":
        return float(sigma * math.sqrt(2.0 * math.log(d)))
    if decomposition == "wp":
        return float(sigma * math.sqrt(2.0 * math.log(d * math.log(d) / math.log(2.0))))
    raise InputError(f"decomposition must be 'dwt' or 'wp', got {decomposition!r}")


def birge_massart_threshold(coefficients: np.ndarray, sigma: float, *, alpha: float) -> float:
    """Penalized (Birge-Massart) threshold over a set of detail coefficients.

    With ``w_1 >= ... >= w_n`` the magnitudes sorted in decreasing order,
    ``t* = argmin_{t=1..n} [ -sum_{k<=t} w_k^2 + 2 t sigma^2 (alpha + ln(n/t)) ]``
    (the first minimum on ties) and the threshold is ``w_t*``. Same unit as sigma.
    """
    mag = np.sort(np.abs(np.asarray(coefficients, dtype=float).ravel()))[::-1]
    n = mag.size
    if n == 0:
        raise InputError("no detail coefficients to threshold")
    t = np.arange(1, n + 1, dtype=float)
    crit = -np.cumsum(mag**2) + 2.0 * t * sigma**2 * (alpha + np.log(n / t))
    return float(mag[int(np.argmin(crit))])


def _threshold_from(
    rule: ThresholdRule, sigma: float, d: int, details: np.ndarray, decomposition: Decomposition
) -> float:
    if rule == "fixed":
        return fixed_threshold(sigma, d, decomposition=decomposition)
    if rule in PENALTY_ALPHA:
        return birge_massart_threshold(details, sigma, alpha=PENALTY_ALPHA[rule])
    raise InputError(f"threshold must be one of {', '.join(THRESHOLD_RULES)}; got {rule!r}")


def _prepare(h, wavelet, level, decomposition):
    w = _wavelet(wavelet)
    if decomposition not in DECOMPOSITIONS:
        raise InputError(f"decomposition must be 'dwt' or 'wp', got {decomposition!r}")
    if not isinstance(level, (int, np.integer)) or isinstance(level, bool) or level < 1:
        raise InputError(f"level must be a positive integer, got {level!r}")
    runs, skipped = _usable_runs(h, level, w)
    parts = []
    for a, b in runs:
        container, details = _decompose(h[a:b], w, level, decomposition)
        parts.append((a, b, container, details))
    d1 = _level1_details(h, runs, w)
    sigma = mad_sigma(d1)
    pooled = np.concatenate([np.concatenate(p[3]) for p in parts])
    return w, runs, skipped, parts, sigma, d1.size, pooled


def threshold_value(
    heights: np.ndarray,
    *,
    wavelet: str = "db3",
    level: int = 3,
    decomposition: Decomposition = "dwt",
    threshold: ThresholdRule = "fixed",
) -> float:
    """The global threshold (metres) that :func:`denoise` would apply to this profile."""
    h = _as_profile(heights)
    _, _, _, _, sigma, d, pooled = _prepare(h, wavelet, level, decomposition)
    return _threshold_from(threshold, sigma, d, pooled, decomposition)


def denoise_result(
    heights: np.ndarray,
    *,
    wavelet: str = "db3",
    level: int = 3,
    decomposition: Decomposition = "dwt",
    threshold: ThresholdRule = "fixed",
    mode: Mode = "hard",
) -> Denoised:
    """De-noise a profile by thresholding its wavelet detail coefficients.

    Parameters
    ----------
    heights
        (K,) residual heights at a regular spacing, metres; NaN marks gaps (see the
        module docstring).
    wavelet
        Any discrete PyWavelets wavelet (default ``db3``, as in the paper).
    level
        Decomposition depth (default 3, as in the paper).
    decomposition
        ``"dwt"`` (discrete wavelet transform) or ``"wp"`` (wavelet packets).
    threshold
        ``"fixed"`` or ``"penalized-low"`` / ``"-medium"`` / ``"-high"`` (Birge-Massart).
    mode
        ``"hard"`` (keep coefficients with ``|w| >= t``, zero the rest) or ``"soft"``
        (also shrink the kept ones by ``t``).

    Returns
    -------
    Denoised
        The de-noised heights (same length) with sigma and the threshold used.
    """
    h = _as_profile(heights)
    if mode not in MODES:
        raise InputError(f"mode must be 'hard' or 'soft', got {mode!r}")
    w, runs, skipped, parts, sigma, d, pooled = _prepare(h, wavelet, level, decomposition)
    t = _threshold_from(threshold, sigma, d, pooled, decomposition)
    out = np.full(h.shape, np.nan)
    n_kept = 0
    for a, b, container, details in parts:
        new = [pywt.threshold(c, t, mode=mode) for c in details]
        n_kept += int(sum(np.count_nonzero(c) for c in new))
        out[a:b] = _reconstruct(container, new, w, level, decomposition, b - a)
    return Denoised(
        heights=out,
        sigma=sigma,
        threshold=t,
        wavelet=w.name,
        level=int(level),
        decomposition=decomposition,
        threshold_rule=threshold,
        mode=mode,
        d=int(d),
        n_coefficients=int(pooled.size),
        n_kept=n_kept,
        runs=tuple(runs),
        skipped_runs=tuple(skipped),
    )


def denoise(
    heights: np.ndarray,
    *,
    wavelet: str = "db3",
    level: int = 3,
    decomposition: Decomposition = "dwt",
    threshold: ThresholdRule = "fixed",
    mode: Mode = "hard",
) -> np.ndarray:
    """De-noised heights (metres, same length); see :func:`denoise_result`."""
    return denoise_result(
        heights,
        wavelet=wavelet,
        level=level,
        decomposition=decomposition,
        threshold=threshold,
        mode=mode,
    ).heights
