"""Smooth random fields (value noise) evaluated at arbitrary points, vectorised."""

from __future__ import annotations

import numpy as np


def _smooth(f: np.ndarray) -> np.ndarray:
    return f * f * (3.0 - 2.0 * f)


class ValueNoise2D:
    """Random values on a square lattice of pitch ``scale_m``, smoothly interpolated.

    Values have zero mean and unit standard deviation at the lattice nodes; the field
    varies over distances of about ``scale_m``.
    """

    def __init__(
        self, rng: np.random.Generator, extent_m: tuple[float, float], scale_m: float
    ) -> None:
        self.scale = float(scale_m)
        nx = int(np.ceil(extent_m[0] / scale_m)) + 3
        ny = int(np.ceil(extent_m[1] / scale_m)) + 3
        self.values = rng.standard_normal((nx, ny))
        self.offset = rng.uniform(0.0, 1.0, 2)

    def __call__(self, s: np.ndarray, z: np.ndarray) -> np.ndarray:
        u = s / self.scale + self.offset[0]
        v = z / self.scale + self.offset[1]
        i = np.clip(np.floor(u).astype(np.int64), 0, self.values.shape[0] - 2)
        j = np.clip(np.floor(v).astype(np.int64), 0, self.values.shape[1] - 2)
        fu = _smooth(np.clip(u - i, 0.0, 1.0))
        fv = _smooth(np.clip(v - j, 0.0, 1.0))
        a = self.values
        lo = a[i, j] + fu * (a[i + 1, j] - a[i, j])
        hi = a[i, j + 1] + fu * (a[i + 1, j + 1] - a[i, j + 1])
        return lo + fv * (hi - lo)


class ValueNoise1D:
    """One-dimensional value noise of pitch ``scale_m`` (unit standard deviation at nodes)."""

    def __init__(self, rng: np.random.Generator, extent_m: float, scale_m: float) -> None:
        self.scale = float(scale_m)
        self.values = rng.standard_normal(int(np.ceil(extent_m / scale_m)) + 3)
        self.offset = float(rng.uniform(0.0, 1.0))

    def __call__(self, s: np.ndarray) -> np.ndarray:
        u = s / self.scale + self.offset
        i = np.clip(np.floor(u).astype(np.int64), 0, self.values.shape[0] - 2)
        f = _smooth(np.clip(u - i, 0.0, 1.0))
        return self.values[i] + f * (self.values[i + 1] - self.values[i])


class FractalNoise2D:
    """Sum of value-noise octaves: octave ``k`` has pitch ``scales_m[k]`` and amplitude
    ``amplitudes_m[k]`` (metres), so the field's spectrum is set octave by octave."""

    def __init__(
        self,
        rng: np.random.Generator,
        extent_m: tuple[float, float],
        scales_m: tuple[float, ...],
        amplitudes_m: tuple[float, ...],
    ) -> None:
        self.octaves = [ValueNoise2D(rng, extent_m, s) for s in scales_m]
        self.amplitudes = tuple(float(a) for a in amplitudes_m)

    def __call__(self, s: np.ndarray, z: np.ndarray) -> np.ndarray:
        out = np.zeros(np.broadcast(s, z).shape)
        for octave, amp in zip(self.octaves, self.amplitudes, strict=True):
            out += amp * octave(s, z)
        return out
