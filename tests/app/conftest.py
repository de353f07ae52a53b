"""Fixtures for the app tests: a small synthetic rock face and a running app."""

from __future__ import annotations

import pytest

from rough_viewer.io import PointCloud  # noqa: E402
from tests.helpers import face_cloud


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
