"""Issue 22 in the app: outlier cells named, left out and drawn in their own colour
(or kept), the binary threshold judged against the data's own, settable fractal-fit
windows, and one plotly.js for a ZIP of figures."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from rough_viewer.app.features.panels import PanelsFeature
from rough_viewer.app.features.profile import ProfileFeature
from rough_viewer.app.features.zones import ZonesFeature
from rough_viewer.app.server import build_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.grid.outliers import analysed_values, outlier_mask
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.summary import histogram, normalise
from rough_viewer.grid.threshold import map_threshold_advice
from rough_viewer.io import PointCloud
from rough_viewer.structure.zones import ZoneLabeller
from rough_viewer.visual import colormaps
from tests.app.protocol import pick, shown_colours
from tests.grid.test_outliers import leaning_wall


@pytest.fixture
def wall(server):
    """A wall read along z whose vertical half has hybrid values larger than the cell."""
    cloud = PointCloud.from_xyz(leaning_wall(20_000), source="wall.xyz")
    app = build_app(server, cloud, prefetch=False, presets=(0.25,),
                    settings=MapSettings(cell_size=0.25, model="hybrid", axis="z"))
    assert app.wait_idle(60)
    yield app, cloud
    app.stop()


def test_outlier_cells_are_left_out_in_their_own_colour_or_kept(wall):
    app, cloud = wall
    ref = grid_roughness(cloud, 0.25, axis="z")
    out = outlier_mask(ref, "hybrid")
    assert out.any() and not out.all()
    shown = app.session.shown
    idx = shown.loaded.display_index
    colours = np.asarray(shown_colours(app))
    in_outlier = out[ref.point_cell[idx]]
    assert np.all(colours[in_outlier] == colormaps.OUTLIER_RGB)
    assert not np.any(np.all(colours[~in_outlier] == colormaps.OUTLIER_RGB, axis=1))
    # the stretch, the histogram and the notice leave them out, and say so
    kept_out = analysed_values(ref, "hybrid")
    assert shown.stats.theta_max == pytest.approx(np.nanmax(kept_out), rel=1e-12)
    assert shown.stats.theta_max <= 0.25 and shown.stats.outliers == int(out.sum())
    hist = app.feature(PanelsFeature).histogram.figure
    hybrid = next(t for t in hist.data if (t.name or "").startswith("hybrid"))
    np.testing.assert_allclose(hybrid.y, 100 * histogram(normalise(kept_out), 0.05).fractions)
    assert "**Outliers:**" in app.host.notice.content
    assert f"{int(out.sum()):,} of" in app.host.notice.content
    assert "outlier" in app.map.colour_bar.figure.to_json().lower()
    # kept: coloured by their value like every cell, the stretch reaches them
    app.map.keep_outliers.value = True
    assert app.wait_idle(60)
    colours = np.asarray(shown_colours(app))
    assert not np.any(np.all(colours == colormaps.OUTLIER_RGB, axis=1))
    assert app.session.shown.stats.theta_max == pytest.approx(np.nanmax(ref.theta_hybrid))
    assert "they take part" in app.host.notice.content


def test_zones_leave_outliers_out_and_judge_the_threshold(wall):
    app, _cloud = wall
    z = app.feature(ZonesFeature)
    app.map.threshold.value = 0.2
    z.on.value = True
    assert app.wait_idle(60)
    res = app.session.shown.result
    want = ZoneLabeller.build(res, "hybrid").label(0.2, connectivity="vertex", min_cells=3)
    np.testing.assert_array_equal(z.labelling.labels, want)
    assert np.all(z.labelling.labels[outlier_mask(res, "hybrid")] == 0)
    advice = map_threshold_advice(res, "hybrid", 0.2)
    assert f"flags {100 * advice.share:.0f} %" in z.status.content
    # the binary display says the same under the status line
    app.map.display.value = "binary"
    assert app.wait_idle(60)
    assert "**Threshold:**" in app.host.notice.content and "the data suggest" in \
        app.host.notice.content


def test_the_fit_windows_can_be_typed(app, cloud):
    from rough_viewer.profiles.fractal import roughness_length

    m = app.feature(ProfileFeature)
    m.on.value = True
    pts = app.session.shown.loaded.display_points
    i = int(np.argmin(np.abs(pts[:, 0] - (-1.2)) + np.abs(pts[:, 2])))
    j = int(np.argmin(np.abs(pts[:, 0] - 1.2) + np.abs(pts[:, 2])))
    for k in (i, j):
        pick(app, pts[k].astype(float) + [0.0, -5.0, 0.0], (0.0, 1.0, 0.0))
    a = m.items[0]
    m.windows.value = "0.1, 0.2, 0.4, 0.8"  # metres, the cloud's unit
    assert app.wait_idle(60)
    b = m.items[0]
    ref = roughness_length(b.profile.heights, b.profile.spacing, windows=(0.1, 0.2, 0.4, 0.8))
    assert b.raw_fit.dimension == pytest.approx(ref.dimension, rel=1e-12)
    assert b.raw_fit.dimension != a.raw_fit.dimension
    m.windows.value = "0.1"  # one window cannot fit a slope: named, the profile kept
    assert app.wait_idle(60)
    assert "windows" in app.host.errors[-1] and m.items[0] is b
    assert m.windows.label == "Fit windows (m)"
    m.on.value = False


def test_a_zip_of_html_figures_holds_one_plotly_js(server):
    from rough_viewer.app.features import export as em
    from tests.app.protocol import ProtocolClient
    from tests.helpers import face_cloud

    app = build_app(server, face_cloud(5_000), prefetch=False, presets=(0.5, 0.25))
    client = ProtocolClient(server.get_port())
    try:
        assert app.wait_idle(60)
        client.set_value(em.L_FIGURE, em.ALL_FIGURES)
        client.press(em.L_FIGURE_BUTTON)
        _name, data = client.wait_download("_figures_html.zip")
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            names = zf.namelist()
            pages = [n for n in names if n.endswith(".html")]
            assert names.count("plotly.min.js") == 1 and len(pages) >= 4
            assert all(zf.getinfo(n).file_size < 500_000 for n in pages)
            assert all('src="plotly.min.js"' in zf.read(n).decode() for n in pages)
    finally:
        client.close()
        app.stop()
