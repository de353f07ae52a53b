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


@pytest.fixture(scope="module")
def chromium():
    """Headless Chromium (Playwright) for the module's browser tests."""
    import os

    from tests.app import browser as b

    if not os.path.exists(b.CHROMIUM):
        pytest.skip("chromium not installed (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=b.CHROMIUM, headless=True, args=b.ARGS)
        yield browser
        browser.close()
