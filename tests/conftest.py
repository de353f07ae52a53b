"""Shared fixtures: small synthetic clouds made here (the suite never reads ../shared)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers import rough_surface


def pytest_configure(config):
    config.addinivalue_line("markers", "browser: needs headless Chromium (slow)")


@pytest.fixture
def surface_xyz() -> np.ndarray:
    return rough_surface(20_000, seed=1)


@pytest.fixture(scope="module")
def chromium():
    """Headless Chromium (Playwright) for a module's browser tests (one per module)."""
    import os

    from tests.app import browser as b

    if not os.path.exists(b.CHROMIUM):
        pytest.skip("chromium not installed (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=b.CHROMIUM, headless=True, args=b.ARGS)
        yield browser
        browser.close()
