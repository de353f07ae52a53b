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
