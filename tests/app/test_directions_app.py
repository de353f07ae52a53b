"""Issue 25 in the app: the Profile tab's Directions folder measures the shown cloud
by direction, as the library does, and draws its profile lines on the rock."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.app.features.profile.directions import DirectionsFeature
from rough_viewer.app.server import build_app
from rough_viewer.directions.analysis import DirectionSettings, analyse_directions
from rough_viewer.io import PointCloud
from rough_viewer.synthetic.fbm import fbm_sheet


@pytest.fixture
def sheet_app(server):
    """A 2 x 2 m anisotropic surface (rougher across x than along it)."""
    z = fbm_sheet((100, 100), 0.3, 0.7, spacing=0.02, sigma=0.01, rng=1)
    y, x = np.meshgrid(np.arange(100) * 0.02, np.arange(100) * 0.02, indexing="ij")
    cloud = PointCloud.from_xyz(np.column_stack([x.ravel(), y.ravel(), z.ravel()]),
                                source="sheet")
    app = build_app(server, cloud, prefetch=False, variogram=False)
    assert app.wait_idle(60)
    yield app, cloud
    app.stop()


def test_measure_directions_gives_the_library_numbers_and_lines(sheet_app):
    app, cloud = sheet_app
    f = app.feature(DirectionsFeature)
    f.step.value = 45.0
    f.tin.value = True
    f.measure.value = True
    assert app.wait_idle(120) and list(app.host.errors) == []
    ref = analyse_directions(cloud, DirectionSettings(step_deg=45.0))
    got = f.result
    assert got is not None and list(got.azimuth_deg) == list(ref.azimuth_deg)
    for a, b in zip(got.sets, ref.sets, strict=True):
        np.testing.assert_allclose(a.values["hurst"], b.values["hurst"], equal_nan=True)
    np.testing.assert_allclose(got.tin.theta_max_c1, ref.tin.theta_max_c1)
    assert "**8 directions**" in f.status.content
    # every warning of the library's result whole, one a line (issue 31: cut with "…")
    assert ref.warnings and all(" ".join(w.split()[-3:]) in f.status.content  # their ends
                                for w in ref.warnings[:4])
    assert "…" not in f.status.content
    names = [t.name for t in f.rose.figure.data]
    assert any("θ" in (n or "") or "theta" in (n or "").lower() for n in names)
    assert len(f.table.figure.data[0].cells.values[0]) == 8
    assert len(f.nodes) == 2  # the lines on both sides of the rock
    lines = f.nodes[0]
    assert lines.visible and lines.points.shape[1:] == (2, 3) and len(lines.points) > 10
    f.lines.value = False
    assert app.wait_idle(30) and not any(n.visible for n in f.nodes)
    app.load(cloud=cloud.subset(np.arange(cloud.n // 2)))
    assert app.wait_idle(60)
    assert f.result is None and f.nodes == []


def test_directions_yield_to_loads_and_crops_between_azimuths():
    """Issue 36 item 17: a load or a crop (both in the load lane) cancels a running
    Directions job, which checks its run between azimuths and profiles: a progress
    that stops at its second call ends a 1-degree measurement (180 profile lines)
    after at most two of them."""
    from rough_viewer.app.features.crop import CropJob
    from rough_viewer.app.features.map.load import LoadJob
    from rough_viewer.app.features.profile.directions import DirectionsJob
    from rough_viewer.app.worker import Cancelled
    from rough_viewer.synthetic.fbm import fbm_surface

    assert {LoadJob.lane, CropJob.lane} <= DirectionsJob.yields_to
    z = fbm_surface((150, 150), 0.7, spacing=0.01, rms=0.01, rng=2)
    yy, xx = np.mgrid[0:150, 0:150] * 0.01
    cloud = PointCloud.from_xyz(np.column_stack([xx.ravel(), yy.ravel(), z.ravel()]))
    calls: list[tuple[int, int]] = []

    def progress(done: int, total: int) -> None:
        calls.append((done, total))
        if len(calls) >= 2:
            raise Cancelled

    with pytest.raises(Cancelled):
        analyse_directions(cloud, DirectionSettings(step_deg=1.0, tin=False),
                           progress=progress)
    assert len(calls) == 2 and calls[-1][0] < 0.02 * calls[-1][1]


def test_a_saved_view_keeps_the_directions_settings_and_measures_them_again(sheet_app,
                                                                          tmp_path):
    """Issue 31 item 11: views kept no directions; a saved view holds the step, line
    spacing, triangle parameters, lines shown and whether they were measured, and a
    fresh app given the view shows those settings and the library's numbers."""
    import viser

    from rough_viewer.app.views import apply_view, view_of
    from rough_viewer.report.view import DirectionsView, InputRef, load_view, save_view

    app, cloud = sheet_app
    f = app.feature(DirectionsFeature)
    f.step.value = 30.0
    f.spacing.value = 0.25
    f.lines.value = False
    f.measure.value = True
    assert app.wait_idle(120) and f.result is not None
    ref_in = InputRef(path=str(tmp_path / "sheet.npy"), sha256="0" * 64, size_bytes=1)
    saved = load_view(save_view(tmp_path / "v.json", view_of(app.host, ref_in, camera=None)),
                      check=False).view
    assert saved.directions == DirectionsView(step_deg=30.0, spacing_m=0.25, tin=False,
                                              lines=False, measured=True)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    other = build_app(server, cloud, prefetch=False, variogram=False)
    try:
        assert other.wait_idle(60)
        g = other.feature(DirectionsFeature)
        assert g.step.value == 15.0 and g.result is None
        apply_view(other.host, saved)
        assert other.wait_idle(120) and list(other.host.errors) == []
        assert (g.step.value, g.spacing.value, g.tin.value, g.lines.value) == \
            (30.0, 0.25, False, False)
        ref = analyse_directions(cloud, DirectionSettings(step_deg=30.0, spacing=0.25))
        assert g.result is not None and list(g.result.azimuth_deg) == list(ref.azimuth_deg)
        for a, b in zip(g.result.sets, ref.sets, strict=True):
            np.testing.assert_allclose(a.values["hurst"], b.values["hurst"], equal_nan=True)
        assert g.nodes and all(not n.visible for n in g.nodes)  # the lines hidden, as saved
    finally:
        other.stop()
        server.stop()
