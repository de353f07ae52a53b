"""Fixtures for the app tests: a small synthetic rock face and a running app."""

from __future__ import annotations

import numpy as np
import pytest

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


@pytest.fixture(scope="session")
def cloud() -> PointCloud:
    return face_cloud()


@pytest.fixture
def server():
    import viser

    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()


@pytest.fixture
def app(server, cloud):
    from rough_viewer.app.server import build_app

    a = build_app(server, cloud, prefetch=False)  # prefetching is tested on its own
    assert a.wait_idle(60)
    yield a
    a.stop()
