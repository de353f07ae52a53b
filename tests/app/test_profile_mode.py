"""Profile mode on a real viser server: two clicks -> profile, de-noising, D."""

import numpy as np
import pytest

from rough_viewer.app.profile_mode import ProfileMode, ProfileSettings, analyse, profiles_csv
from rough_viewer.app.server import on_scene_click
from rough_viewer.profiles.extraction import extract_profile
from rough_viewer.profiles.fractal import roughness_length
from rough_viewer.profiles.wavelets import denoise


def click_on(app, i):
    target = app.shown.loaded.display_points[i].astype(float)
    return on_scene_click(app, target + [0.0, -5.0, 0.0], (0.0, 1.0, 0.0))


def test_two_clicks_make_a_profile_matching_the_core(app, cloud):
    m = app.mode(ProfileMode)
    m.on.value = True
    pts = app.shown.loaded.display_points
    i = int(np.argmin(np.abs(pts[:, 0] - (-1.2)) + np.abs(pts[:, 2])))
    j = int(np.argmin(np.abs(pts[:, 0] - 1.2) + np.abs(pts[:, 2])))
    assert click_on(app, i) is None and m.start is not None
    click_on(app, j)
    assert list(app.errors) == [] and len(m.items) == 1
    a = m.items[0]
    start = app.shown.loaded.to_file_frame(pts[i])
    end = app.shown.loaded.to_file_frame(pts[j])
    ref = extract_profile(cloud.xyz(), start, end)
    assert np.allclose(a.profile.heights, ref.heights, equal_nan=True)
    assert a.raw_fit.dimension == pytest.approx(roughness_length(ref.heights, ref.spacing).dimension)
    assert "D raw" in m.note.content
    assert any("D=" in (t.name or "") for t in m.plot.figure.data)

    m.wavelet.value = "sym4"  # de-noising runs as a job on the worker
    m.mode.value = "soft"
    assert app.wait_idle(60)
    b = m.items[0]
    want = denoise(ref.heights, wavelet="sym4", mode="soft")
    assert np.allclose(b.denoised.heights, want, equal_nan=True)
    assert b.settings.wavelet == "sym4"

    text = profiles_csv(m.items)
    assert len(text.strip().splitlines()) == 1 + len(ref.distance)
    m.clear.value = True
    assert app.wait_idle(60)
    assert m.items == [] and m.nodes == []
    m.on.value = False
    assert click_on(app, i) is not None  # cell picking again


def test_analyse_is_independent_of_the_app(cloud):
    xyz = cloud.xyz()
    a = analyse(xyz, xyz[0], xyz[0] + [2.0, 0.0, 0.0], ProfileSettings(level=2))
    assert a.denoised.level == 2 and np.isfinite(a.raw_fit.dimension)
    assert 1.0 <= a.raw_fit.dimension <= 2.2
