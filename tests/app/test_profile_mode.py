"""Profile mode on a real viser server: two clicks -> profile, de-noising, D."""

import numpy as np
import pytest

from rough_viewer.app.features.profile import ProfileFeature, ProfileSettings, analyse, profiles_csv
from rough_viewer.profiles.extraction import extract_profile
from rough_viewer.profiles.fractal import roughness_length
from rough_viewer.profiles.wavelets import denoise
from tests.app.protocol import pick


def click_on(app, i):
    target = app.session.shown.loaded.display_points[i].astype(float)
    return pick(app, target + [0.0, -5.0, 0.0], (0.0, 1.0, 0.0))


def _one_profile(app):
    """One profile across the test face (x from -1.2 to 1.2 m); profile mode off after."""
    m = app.feature(ProfileFeature)
    m.on.value = True
    pts = app.session.shown.loaded.display_points
    i = int(np.argmin(np.abs(pts[:, 0] - (-1.2)) + np.abs(pts[:, 2])))
    j = int(np.argmin(np.abs(pts[:, 0] - 1.2) + np.abs(pts[:, 2])))
    click_on(app, i)
    click_on(app, j)
    assert len(m.items) == 1 and len(m.nodes) == 1
    m.on.value = False
    return m


def test_two_clicks_make_a_profile_matching_the_core(app, cloud):
    m = app.feature(ProfileFeature)
    m.on.value = True
    pts = app.session.shown.loaded.display_points
    i = int(np.argmin(np.abs(pts[:, 0] - (-1.2)) + np.abs(pts[:, 2])))
    j = int(np.argmin(np.abs(pts[:, 0] - 1.2) + np.abs(pts[:, 2])))
    assert click_on(app, i) is None and m.start is not None
    click_on(app, j)
    assert list(app.host.errors) == [] and len(m.items) == 1
    a = m.items[0]
    start = app.session.shown.loaded.to_file_frame(pts[i])
    end = app.session.shown.loaded.to_file_frame(pts[j])
    ref = extract_profile(cloud.xyz(), start, end)
    assert np.allclose(a.profile.heights, ref.heights, equal_nan=True)
    assert a.raw_fit.dimension == pytest.approx(roughness_length(ref.heights, ref.spacing).dimension)
    assert "D raw" in m.note.content
    assert any("D=" in (t.name or "") for t in m.plot.figure.data)

    m.wavelet.value = "sym4"  # de-noising runs as a job on the worker
    m.threshold_mode.value = "soft"
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


def test_a_cloud_in_feet_has_its_profiles_in_feet(server):
    """Band typed in feet, the table and the plot in feet (as the Map tab shows them)."""
    from dataclasses import replace

    from rough_viewer.app.server import build_app
    from tests.helpers import face_cloud

    ft = 0.3048
    app = build_app(server, replace(face_cloud(20_000), source_unit="ft"), prefetch=False)
    try:
        assert app.wait_idle(60)
        m = app.feature(ProfileFeature)
        assert m.band.label == "Band half-width (ft)"
        assert m.band.max == pytest.approx(10.0 / ft)
        m.band.value = 0.5
        assert m.binding.read().band_half_width == pytest.approx(0.5 * ft)
        _one_profile(app)
        assert list(app.host.errors) == []
        a = m.items[0]
        assert a.settings.band_half_width == pytest.approx(0.5 * ft)
        assert "| # | length (ft) | band ± (ft) | σ noise (ft) |" in m.note.content
        assert f"| 1 | {a.profile.length / ft:.4g} |" in m.note.content
        fig = m.plot.figure
        assert fig.layout.xaxis.title.text == "distance along the line (ft)"
        np.testing.assert_allclose(fig.data[0].y, a.profile.heights / ft)
    finally:
        app.stop()


def _curved_profile():
    """A 2 m profile across a face bent like a barrel (a 0.2 m bulge) with 0.5 mm
    noise: the bend makes s(w) grow faster than w (D < 1) unless it is removed."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 2, (60_000, 2))
    z = 0.2 * (xy[:, 0] - 1.0) ** 2 + 0.0005 * rng.standard_normal(len(xy))
    pts = np.column_stack([xy, z])
    return extract_profile(pts, np.array([0.05, 1.0, 0.0]), np.array([1.95, 1.0, 0.0]))


def test_a_curved_profile_warns_and_removing_its_trend_fixes_it():
    from rough_viewer.app.features.profile import redo, summary_markdown
    from rough_viewer.profiles.fractal import detrend

    prof = _curved_profile()
    bent = redo(prof, ProfileSettings())
    assert bent.denoised_fit.dimension < 1.0 and bent.warnings  # de-noised: the bend is left
    text = summary_markdown([bent])
    assert "⚠ **P1**" in text and "below 1" in text and "*Remove trend*" in text
    flat = redo(prof, ProfileSettings(detrend=2))
    assert 1.0 <= flat.raw_fit.dimension <= 2.0 and 1.0 <= flat.denoised_fit.dimension <= 2.0
    assert flat.warnings == ()
    assert "⚠" not in summary_markdown([flat])
    # the analysed heights are the extracted ones minus the trend; the source is kept
    assert flat.source is prof and flat.profile is not prof
    np.testing.assert_allclose(flat.profile.heights, detrend(prof.heights, prof.spacing),
                               equal_nan=True)
    # the de-noised line drawn on the rock is back on the rock (trend put back)
    ok = np.isfinite(prof.heights)
    assert np.nanmax(np.abs(flat.surface_heights() - prof.heights)[ok]) < 0.003
    # de-noising again starts from the extracted profile, not the detrended one
    again = redo(flat.source, ProfileSettings(detrend=None))
    np.testing.assert_allclose(again.profile.heights, prof.heights, equal_nan=True)


def test_the_remove_trend_control_redoes_the_kept_profiles(app):
    m = _one_profile(app)
    assert m.items[0].settings.detrend is None
    m.detrend.value = "degree 2"
    assert app.wait_idle(60)
    a = m.items[0]
    assert a.settings.detrend == 2 and a.extracted is not None
    from rough_viewer.profiles.fractal import detrend

    np.testing.assert_allclose(a.profile.heights, detrend(a.source.heights, a.source.spacing),
                               equal_nan=True)
    text = profiles_csv(m.items).splitlines()
    row = text[1].split(",")
    xyz = a.source.sample_xyz()[0]
    assert [float(v) for v in row[4:7]] == pytest.approx(xyz, abs=1e-9)  # on the rock



def test_profiles_belong_to_their_cloud(app):
    """Another file: the profiles go (they were drawn across the new scan). The
    board lesson: the scan's profiles go aside with it and come back with it."""
    from rough_viewer.app.features.board import BoardFeature
    from tests.helpers import face_cloud

    m = _one_profile(app)
    kept = m.items[0]
    scan = app.session.shown.loaded
    board = app.feature(BoardFeature)
    board.scan.value = True
    assert app.wait_idle(60)
    assert app.session.shown.loaded is not scan and m.items == [] and m.nodes == []
    assert "Tick" in m.note.content  # the table is empty too
    board.back.value = True
    assert app.wait_idle(60)
    assert app.session.shown.loaded is scan and m.items == [kept] and len(m.nodes) == 1
    assert "| 1 |" in m.note.content
    app.load(cloud=face_cloud(5_000))
    assert app.wait_idle(60)
    assert m.items == [] and m.nodes == [] and m.aside is None


def test_a_setting_that_fails_puts_the_controls_back_and_its_error_goes(app):
    """Level 6 needs 320 samples: a short profile cannot take it. The profiles keep
    their level-3 numbers, so the Level control goes back to 3; a later setting
    that works clears the error."""
    m = _one_profile(app)
    assert m.items[0].settings.level == 3
    assert np.count_nonzero(np.isfinite(m.items[0].profile.heights)) < 320
    before = m.items[0]
    m.level.value = 6
    assert app.wait_idle(60)
    assert app.host.error.visible and "level-6" in app.host.error.content
    assert m.level.value == 3 and m.items[0] is before
    m.level.value = 2
    assert app.wait_idle(60)
    assert m.items[0].settings.level == 2 and not app.host.error.visible
