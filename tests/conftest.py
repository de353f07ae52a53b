"""Shared fixtures: small synthetic clouds made here (the suite never reads ../shared)."""

from __future__ import annotations

import numpy as np
import pytest


def pytest_configure(config):
    config.addinivalue_line("markers", "browser: needs headless Chromium (slow)")


def rough_surface(n: int, seed: int = 0, *, size: float = 4.0, noise: float = 0.003) -> np.ndarray:
    """(n, 3) points of a wavy, noisy surface z = f(x, y), metres."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0.0, size, (n, 2))
    z = (
        0.05 * np.sin(3.1 * xy[:, 0]) * np.cos(2.3 * xy[:, 1])
        + 0.02 * np.sin(11.0 * xy[:, 0] + 1.0)
        + rng.normal(0.0, noise, n)
    )
    return np.column_stack([xy, z])


def random_rotation(seed: int) -> np.ndarray:
    """A random proper rotation matrix (3x3)."""
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] *= -1
    return q


@pytest.fixture
def surface_xyz() -> np.ndarray:
    return rough_surface(20_000, seed=1)
