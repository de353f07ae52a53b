"""Synthetic clouds shared by the app tests (imported by conftest and test_e2e)."""

from __future__ import annotations

import numpy as np

from rough_viewer.core.io import PointCloud

UTM = np.array([512_000.0, 4_170_000.0, 100.0])


def face_cloud(n: int = 40_000, *, seed: int = 0) -> PointCloud:
    """A vertical face 4 m x 2 m facing -y at UTM-like coordinates, gently waved,
    whose noise grows from 0.5 mm at the left edge to 10.5 mm at the right."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 4.0, n)
    z = rng.uniform(0.0, 2.0, n)
    sigma = 0.0005 + 0.0025 * x
    y = 0.02 * np.sin(1.5 * x) + sigma * rng.standard_normal(n)
    return PointCloud.from_xyz(np.column_stack([x, y, z]) + UTM, source="synthetic-face")


