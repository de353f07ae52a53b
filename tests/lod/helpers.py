"""Synthetic clouds and cameras shared by the level-of-detail tests."""

from __future__ import annotations

import math

import numpy as np

from rough_viewer.lod.camera import ViewCamera
from tests.helpers import UTM


def outcrop(n: int, seed: int = 0) -> np.ndarray:
    """A wavy vertical face with a ledge and a few stray points (vegetation), at
    UTM-sized coordinates."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 30.0, n)
    z = rng.uniform(0.0, 8.0, n)
    y = 0.4 * np.sin(0.5 * x) * np.cos(0.8 * z) + 0.003 * rng.standard_normal(n)
    ledge = z < 1.0
    y[ledge] -= rng.uniform(0.0, 2.0, int(ledge.sum()))
    stray = rng.random(n) < 0.01
    y[stray] -= rng.uniform(0.5, 3.0, int(stray.sum()))
    return np.column_stack([x, y, z]) + UTM


def random_camera(rng, cloud) -> ViewCamera:
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    centre, extent = 0.5 * (lo + hi), float(np.max(hi - lo))
    target = cloud[rng.integers(cloud.shape[0])] + rng.normal(0, 0.05 * extent, 3)
    if rng.random() < 0.3:  # inside the cloud's box, close to the rock
        position = target + rng.normal(0, 0.05 * extent, 3)
    else:
        direction = rng.normal(size=3)
        position = centre + direction / np.linalg.norm(direction) * extent * rng.uniform(0.3, 2)
    up = np.array([0.0, 0.0, 1.0]) + rng.normal(0, 0.3, 3)
    return ViewCamera.looking_at(position, target, up=up, fov_rad=math.radians(rng.uniform(25, 90)),
                                 aspect=rng.uniform(0.5, 2.5), height_px=int(rng.integers(300, 1500)))
