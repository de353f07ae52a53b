"""Issue 13 and the app parts of issue 11 on a real viser server, without a browser:
colour stretch controls, colour layers, units, notices, the board lesson beside
the scan, camera presets, the profile plot's height range, and a semivariogram
that stops inside a map when a newer view arrives."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rough_viewer.app import scene
from rough_viewer.app.features.board import BACK_LABEL, BoardFeature
from rough_viewer.app.features.file import FileFeature
from rough_viewer.app.features.map.render import RenderJob
from rough_viewer.app.features.panels import PanelsFeature
from rough_viewer.app.features.profile import ProfileFeature
from rough_viewer.app.server import build_app
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.visual import colormaps
from tests.app.protocol import pick, shown_colours
from tests.helpers import face_cloud, write_las_with_colours

# ----------------------------------------------------------------------------- colours


def test_percentiles_log_absolute_and_typed_limits_in_mm(app):
    g = app.map
    rng = app.session.shown.stats.colour_range
    lo_mm, hi_mm = g.range_lo.value, g.range_hi.value
    assert (lo_mm, hi_mm) == (float(f"{rng.lo * 1e3:.3g}"), float(f"{rng.hi * 1e3:.3g}"))
    # switching to absolute pins the range shown (in mm, stored in metres)
    g.stretch.value = "absolute"
    assert app.wait_idle(60)
    st = app.session.shown.settings.stretch
    assert st.mode == "absolute" and st.log
    assert (st.lo, st.hi) == pytest.approx((lo_mm * 1e-3, hi_mm * 1e-3))
    assert "absolute" in g.colour_bar.figure.layout.xaxis.title.text
    # typing a limit in mm keeps the absolute stretch; colours follow it
    g.range_hi.value = 3.0
    g.log.value = False
    assert app.wait_idle(60)
    st = app.session.shown.settings.stretch
    assert (st.mode, st.log) == ("absolute", False) and st.hi == pytest.approx(0.003)
    res = app.session.shown.result
    theta = res.theta_odr[res.point_cell[app.session.shown.loaded.display_index]]
    t = np.clip((theta - st.lo) / (st.hi - st.lo), 0, 1)
    want = colormaps.lut("viridis")[np.round(np.nan_to_num(t) * 255).astype(int)]
    want[~np.isfinite(theta)] = colormaps.NEUTRAL_RGB
    assert np.array_equal(shown_colours(app), want)
    assert f"absolute {lo_mm:g}–3 mm, linear" in g.colour_bar.figure.layout.xaxis.title.text
    # the pinned range stays on another grid size: one colour, one roughness
    g.grid.value = "0.32"
    assert app.wait_idle(60)
    assert app.session.shown.stats.colour_range.hi == pytest.approx(0.003)
    # a log scale needs a lowest limit above 0: refused, the view stays
    g.range_lo.value = 0.0
    g.log.value = True
    assert app.wait_idle(60)
    assert "above 0" in app.host.errors[-1] and app.session.shown.settings.stretch.hi == pytest.approx(0.003)
    # moving the percentiles goes back to a percentile stretch
    g.percentiles.value = (5.0, 95.0)
    assert app.wait_idle(60)
    st = app.session.shown.settings.stretch
    assert (st.mode, st.lo, st.hi) == ("percentile", 5.0, 95.0)
    assert g.stretch.value == "percentile"


def test_no_colour_covers_half_the_points_at_the_default_stretch(app):
    colours = shown_colours(app)
    _, counts = np.unique(colours, axis=0, return_counts=True)
    assert counts.max() / len(colours) < 0.5
    res = app.session.shown.result
    v = res.theta_odr[res.point_cell[app.session.shown.loaded.display_index]]
    robust = app.session.shown.stats.colour_range
    assert colormaps.largest_colour_share(colormaps.positions(v, robust), band=8) < 0.5


# ----------------------------------------------------------------------------- layers


def test_rgb_intensity_and_distance_layers(server, tmp_path):
    cloud = face_cloud(20_000, seed=4)
    rgb8, intensity = write_las_with_colours(tmp_path / "colours.las", cloud)
    app = build_app(server, face_cloud(5_000), prefetch=False, data_dir=tmp_path)
    assert app.wait_idle(60)
    assert app.map.layer.options == ("roughness map", "distance to face plane")
    app.load(path="colours.las")
    assert app.wait_idle(60) and list(app.host.errors) == []
    g = app.map
    assert g.layer.options == ("roughness map", "scan colours (RGB)", "intensity",
                               "distance to face plane")
    idx = app.session.shown.loaded.display_index
    g.layer.value = "scan colours (RGB)"
    assert app.wait_idle(60)
    assert app.session.shown.settings.layer == "rgb"
    assert np.array_equal(shown_colours(app), rgb8[idx])  # 16-bit back to 8-bit exactly
    assert "no colour scale" in g.colour_bar.figure.layout.title.text
    g.layer.value = "intensity"
    assert app.wait_idle(60)
    grey = shown_colours(app).astype(int)
    assert np.all(grey[:, 0] == grey[:, 1])  # grey levels, brighter with intensity
    order = np.argsort(intensity[idx])
    assert grey[order[-50:], 0].mean() > grey[order[:50], 0].mean() + 150
    g.layer.value = "distance to face plane"
    assert app.wait_idle(60)
    # independent: the whole-cloud plane by SVD, signed distance of the shown points
    xyz = cloud.xyz()
    centre = xyz.mean(axis=0)
    normal = np.linalg.svd(xyz - centre, full_matrices=False)[2][-1]
    d = (xyz[idx] - centre) @ normal
    c = shown_colours(app).astype(int)
    warm = c[:, 0] > c[:, 2]
    far = np.abs(d) > np.percentile(np.abs(d), 60)
    agree = np.mean((warm == (d * np.sign(normal[np.argmax(np.abs(normal))]) > 0))[far])
    assert agree > 0.95
    assert "distance (mm)" in g.colour_bar.figure.layout.xaxis.title.text
    # roughness again; a cloud without colours drops the RGB layer
    g.layer.value = "roughness map"
    assert app.wait_idle(60) and app.session.shown.settings.layer == "roughness"
    app.stop()


def test_a_layer_the_cloud_lacks_is_refused(app):
    app.submit(RenderJob(app.map, app.session.shown.settings.with_(layer="rgb")))
    assert app.wait_idle(60)
    assert "has no RGB colours" in app.host.errors[-1] and app.session.shown.settings.layer == "roughness"


# ----------------------------------------------------------------------------- units


def test_a_cloud_in_millimetres_is_shown_in_millimetres(server, tmp_path):
    cloud = face_cloud(20_000, seed=2)
    np.save(tmp_path / "joint.npy", cloud.xyz() * 1000.0)  # the same face, in mm
    app = build_app(server, face_cloud(5_000), prefetch=False, data_dir=tmp_path)
    assert app.wait_idle(60)
    g = app.map
    app.feature(FileFeature).units.value = "mm"
    app.load(path="joint.npy")
    assert app.wait_idle(60) and list(app.host.errors) == []
    loaded = app.session.shown.loaded
    assert loaded.cloud.source_unit == "mm"
    metres = loaded.presets
    assert g.grid.label == "Grid size (mm)" and g.grid_free.label == "Free grid size (mm)"
    assert g.grid.options == (*(f"{1000 * m:g}" for m in metres), "free")
    assert g.grid.value == f"{1000 * metres[-1]:g}"
    assert f"grid {1000 * metres[-1]:g} mm" in app.host.status.content
    assert "θ (mm)" in g.colour_bar.figure.layout.xaxis.title.text
    assert g.range_lo.label == "Lowest θ (mm)"
    g.grid_free.value = 150.0  # typed in mm
    assert app.wait_idle(60)
    assert app.session.shown.settings.cell_size == pytest.approx(0.15)
    assert "grid 150 mm" in app.host.status.content
    info = pick(app, loaded.display_points[10].astype(float) + [0, -5, 0], (0, 1, 0))
    assert info is not None and "(150 mm)" in g.pick.content
    p = np.asarray(info.point) * 1000
    assert f"point ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) mm" in g.pick.content
    xs = list(app.map.scales.figure.data[0].x)
    assert xs == pytest.approx(sorted(1000 * m for m in metres))
    assert app.map.scales.figure.layout.xaxis.title.text == "grid size (mm)"
    app.stop()


def test_a_click_gives_every_roughness_to_three_significant_digits(server):
    """Issue 31 item 16: on a millimetre face e_ols was "0.0005048 mm" beside the
    others' 3 decimals; every roughness of a click's report now has 3 significant
    digits, in µm under 0.01 mm."""
    from dataclasses import replace as with_unit

    from rough_viewer.io import PointCloud

    rng = np.random.default_rng(4)  # a lab joint: 200 x 100 mm, 20 µm noise, tilted
    x, z = rng.uniform(0, 200, 20_000), rng.uniform(0, 100, 20_000)
    mm = np.c_[x, 0.2 * x + 0.02 * rng.standard_normal(x.size), z]
    cloud = with_unit(PointCloud.from_xyz(mm / 1000.0, source="joint"), source_unit="mm")
    app = build_app(server, cloud, prefetch=False)
    try:
        assert app.wait_idle(60)
        loaded = app.session.shown.loaded
        info = pick(app, loaded.display_points[10].astype(float) + [0, -5, 0], (0, 1, 0))
        assert info is not None
        said = app.map.pick.content
        for name, label in (("odr", "θ ODR "), ("hybrid", "θ hybrid "), ("e_ols", "e_ols ")):
            v_mm = info.theta[name] * 1000.0
            assert np.isfinite(v_mm) and v_mm > 0
            text = (f"{v_mm * 1000:.3g} µm" if v_mm < 0.01 else f"{v_mm:.3g} mm")
            assert label + text in said, (name, said)
        assert info.theta["e_ols"] * 1000.0 < 0.01  # this face's e_ols is in µm
    finally:
        app.stop()


def test_a_cloud_in_feet_shows_roughness_in_feet(server):
    cloud = replace(face_cloud(8_000), source_unit="ft")
    app = build_app(server, cloud, prefetch=False)
    assert app.wait_idle(60)
    g = app.map
    assert g.grid.label == "Grid size (ft)" and g.range_hi.label == "Highest θ (ft)"
    assert "θ (ft)" in g.colour_bar.figure.layout.xaxis.title.text
    shown = [float(o) for o in g.grid.options[:-1]]
    assert shown == pytest.approx([m / 0.3048 for m in app.session.shown.loaded.presets])
    assert f"grid {shown[-1]:g} ft" in app.host.status.content
    app.stop()


# ----------------------------------------------------------------------------- notices


def test_a_grid_where_most_cells_have_no_value_gets_a_notice(server):
    app = build_app(server, face_cloud(3_000), prefetch=False)
    assert app.wait_idle(60)
    assert not app.host.notice.visible
    app.map.grid_free.value = 0.03
    assert app.wait_idle(60)
    rep = app.session.shown.result.cell_report("odr")
    assert rep["with_value"] / rep["occupied"] < 0.5
    text = app.host.notice.content
    assert app.host.notice.visible and "Most cells have no value" in text
    assert f"only {rep['with_value']:,} of {rep['occupied']:,}" in text
    assert f"try grid {app.map.grid.options[-2]} m" in text  # the finest preset above 0.03
    app.map.grid.value = app.map.grid.options[0]
    assert app.wait_idle(60) and not app.host.notice.visible
    app.stop()


def test_reader_warnings_are_notices_escaped(server):
    hostile = "the header of <img src=x onerror=alert(1)>.las declares 10 points [a](javascript:x)"
    cloud = replace(face_cloud(3_000), warnings=(hostile,))
    app = build_app(server, cloud, prefetch=False)
    assert app.wait_idle(60)
    text = app.host.notice.content
    assert app.host.notice.visible and "**Warning:**" in text
    assert "<img" not in text and "&lt;img" in text and "\\[a\\]\\(javascript" in text
    app.stop()


# ----------------------------------------------------------------------------- board


def test_the_board_lesson_keeps_the_scan_and_has_its_own_colour_range(app):
    scan = app.session.shown.loaded
    g = app.map
    g.model.value = "OLS"
    g.range_lo.value = 0.5  # typed limits pin the colours (absolute, log)
    g.range_hi.value = 2.0
    assert app.wait_idle(60)
    pinned = colormaps.Stretch.absolute_mm(0.5, 2.0, log=True)
    assert app.session.shown.settings.stretch == pinned
    board = app.feature(BoardFeature)
    assert not board.back.visible
    board.scan.value = True
    assert app.wait_idle(120)
    assert app.session.shown.loaded.cloud is board.lesson.scan.cloud
    # its own colour range: the default stretch on its own cells, its own grid
    assert app.session.shown.settings.stretch == colormaps.ROUGHNESS_STRETCH
    assert app.session.shown.settings.model == "ols"
    assert app.session.shown.settings.cell_size == app.session.shown.loaded.default_cell_size
    assert app.session.stashed is not None and app.session.stashed.loaded is scan
    assert board.back.visible and board.back.label.startswith(BACK_LABEL)
    board.alpha.value = 40.0
    board.scan.value = True  # another board: the scan stays put aside
    assert app.wait_idle(120) and app.session.stashed.loaded is scan
    board.back.value = True
    assert app.wait_idle(60)
    assert app.session.shown.loaded is scan and app.session.stashed is None and not board.back.visible
    assert app.session.shown.settings.stretch == pinned and app.session.shown.settings.model == "ols"
    assert app.map.timings[-1]["cached"]  # its grids were kept
    assert app.map.stretch.value == "absolute" and app.map.range_hi.value == 2.0
    assert app.map.grid.options[:-1] == tuple(f"{g:g}" for g in scan.presets)


# ----------------------------------------------------------------------------- camera


def _ndc(pose, pts, window, fov):
    """Normalised device coordinates (x, y in [-1, 1] on screen) of ``pts`` seen from
    ``pose`` with a perspective camera of vertical ``fov`` in a ``window``."""
    view = pose.eye - pose.target
    back = view / np.linalg.norm(view)
    right = np.cross(-back, pose.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, -back)
    rel = pts - pose.eye
    depth = rel @ -back
    t = np.tan(0.5 * fov)
    aspect = window[0] / window[1]
    return (rel @ right) / (depth * t * aspect), (rel @ up) / (depth * t), depth


def test_camera_presets_look_along_the_face_normal_down_and_along_the_face(app):
    loaded = app.session.shown.loaded  # a face looking along -y, 4 m along x
    for preset, axis in (("face-on", 1), ("top", 2), ("side", 0)):
        pose = scene.camera_pose(loaded, preset)
        view = (pose.eye - pose.target) / np.linalg.norm(pose.eye - pose.target)
        assert abs(view[axis]) > 0.98, (preset, view)
        assert abs(np.dot(view, pose.up)) < 0.2  # the up vector is across the view
    app.map.camera.value = "top"
    assert app.wait_idle(30)
    assert [r.kind for r in app.worker.records][-1] == "CameraJob"


@pytest.mark.parametrize("scale", [0.005, 1.0, 2500.0])  # a 20 mm joint .. a 10 km tile
@pytest.mark.parametrize("preset", ["face-on", "top", "side"])
def test_every_preset_frames_the_cloud_in_the_free_part_of_the_window(scale, preset):
    """Every point lies in front of the camera, inside its clipping planes, left of
    the control panel and inside the window; the cloud fills the free part (its
    extent across the view spans FILL of the free width or height)."""
    from dataclasses import replace

    from rough_viewer.app.cloud import LoadedCloud
    from tests.helpers import face_cloud

    base = face_cloud(20_000, seed=3)
    cloud = replace(base, x=base.x * scale, y=base.y * scale, z=base.z * scale)
    loaded = LoadedCloud(cloud, presets=(scale,))
    pts = loaded.display_points.astype(float)
    for window in ((1600, 1000), (1280, 800), (1000, 1400)):
        pose = scene.camera_pose(loaded, preset, window=window)
        x, y, depth = _ndc(pose, pts, window, scene.DEFAULT_FOV)
        assert np.all(depth > pose.near) and np.all(depth < pose.far), (window, preset)
        edge = 1.0 - 2.0 * scene.PANEL_PX / window[0]  # the panel's left edge, in NDC
        assert x.min() >= -1.0 and x.max() <= edge + 1e-9 and np.abs(y).max() <= 1.0 + 1e-9
        fill = max((x.max() - x.min()) / (edge + 1.0), (y.max() - y.min()) / 2.0)
        # where the panel covers the window's centre (a narrow window) a deep cloud
        # must stand back further: perspective draws its far points towards the centre
        assert fill > (0.75 if edge > 0 else 0.6), (window, preset, fill)
        assert pose.far / pose.near < 1e8  # depth precision stays usable


# ----------------------------------------------------------------------------- profiles


def test_profile_plot_fits_the_relief_by_default_and_takes_an_exaggeration(app):
    m = app.feature(ProfileFeature)
    assert m.exaggeration.value == "auto"
    m.on.value = True
    pts = app.session.shown.loaded.display_points
    i = int(np.argmin(np.abs(pts[:, 0] - (-1.2)) + np.abs(pts[:, 2])))
    j = int(np.argmin(np.abs(pts[:, 0] - 1.2) + np.abs(pts[:, 2])))
    for k in (i, j):
        pick(app, pts[k].astype(float) + [0.0, -5.0, 0.0], (0.0, 1.0, 0.0))
    assert len(m.items) == 1
    a = m.items[0]
    fig = m.plot.figure
    lo, hi = fig.layout.yaxis.range
    heights = np.asarray(a.profile.heights) * 1e3
    span = np.nanmax(heights) - np.nanmin(heights)
    assert lo <= np.nanmin(heights) and hi >= np.nanmax(heights)
    assert hi - lo < 1.5 * span  # fitted to the millimetre relief, not ±metres
    # markers: labels (on top); the line follows the surface, drawn on both sides
    kinds = [type(n).__name__ for n in m.nodes[0]]
    assert kinds.count("LabelHandle") == 2 and kinds.count("LineSegmentsHandle") == 2
    m.exaggeration.value = "10×"  # 1 mm of height drawn as long as 10 mm along the line
    assert app.wait_idle(60)
    y = m.plot.figure.layout.yaxis
    assert y.scaleanchor == "x" and y.scaleratio == pytest.approx(10 * 1e-3)
    assert "×10" in y.title.text
    m.on.value = False


# ----------------------------------------------------------------------------- cancel


def test_a_newer_view_stops_the_semivariogram_inside_a_map(server, monkeypatch):
    import rough_viewer.app.features.panels as panels
    import rough_viewer.grid.variogram as variogram

    app = build_app(server, face_cloud(20_000, seed=6), prefetch=False)
    assert app.wait_idle(60)
    real = panels.semivariograms
    runs: list[list[tuple[int, int]]] = []

    def spy(ijk, values, g, *, progress=None, **kw):
        calls: list[tuple[int, int]] = []
        runs.append(calls)

        def watched(done: int, total: int) -> None:
            calls.append((done, total))
            if len(runs) == 1 and len(calls) == 2:  # a newer view arrives mid-map
                app.map.model.value = "OLS"
            assert progress is not None
            progress(done, total)  # the job's: raises once the job is cancelled

        # direct pairs in small chunks: many progress calls inside one map
        return real(ijk, values, g, progress=watched, method="pairs", **kw)

    monkeypatch.setattr(panels, "semivariograms", spy)
    monkeypatch.setattr(variogram, "PAIR_CHUNK_BYTES", 1 << 20)
    app.map.grid.value = app.map.grid.options[-3]  # the second finest preset
    assert app.wait_idle(120)
    records = [r for r in app.worker.records if r.kind == "PanelsJob"]
    assert records[-2].outcome == "cancelled"
    first = runs[0]
    assert len(first) == 2 and first[-1][0] < first[-1][1]  # stopped inside the first map
    assert records[-1].outcome == "done" and app.session.shown.settings.model == "ols"
    assert all(c[-1][0] == c[-1][1] for c in runs[1:])  # the newer panels ran in full
    app.stop()


def test_the_bias_tab_defaults_to_the_papers_residual(app):
    from rough_viewer.app.features.bias import BiasPanel
    from rough_viewer.vocabulary import BIAS_RESIDUAL

    assert app.feature(BiasPanel).residual.value == BIAS_RESIDUAL == "signed"


def test_click_timings_and_values_on_a_free_grid(app, cloud):
    app.map.grid_free.value = 0.1
    assert app.wait_idle(60)
    loaded = app.session.shown.loaded
    info = pick(app, loaded.display_points[5].astype(float) + [0, -5, 0], (0, 1, 0))
    assert info is not None
    # the cell report is of the grid shown; the plot still has one value per preset
    assert info.theta["odr"] == pytest.approx(grid_roughness(cloud, 0.1).theta_odr[info.cell])
    assert list(app.session.pick_scales.cell_sizes) == sorted(loaded.presets)


def test_a_threshold_change_redraws_only_the_face_trend(app):
    before = app.feature(PanelsFeature).variogram.figure
    app.map.threshold.value = 0.2
    assert app.wait_idle(60)
    last = [r for r in app.worker.records if r.kind == "PanelsJob"][-1]
    names = [n for n, _ in last.stages]
    assert "grid sizes" in names and "variogram" not in names and "distribution" not in names
    assert "binary cells ≥ 0.2" in app.feature(PanelsFeature).face_scales.figure.layout.yaxis2.title.text
    assert app.feature(PanelsFeature).variogram.figure is before


# ----------------------------------------------------------------------------- issue 22's minor items


def test_the_dependent_axis_line_lies_under_the_rock(app):
    """Seen from the face-on camera, the line is below every point of the rock (never
    over it) and inside the framed view."""
    loaded = app.session.shown.loaded
    pts = loaded.display_points.astype(float)
    extent = float(np.ptp(pts, axis=0).max())
    pose = scene.camera_pose(loaded, "face-on")
    _, y_rock, _ = _ndc(pose, pts, scene.FRAME_WINDOW, scene.DEFAULT_FOV)
    for k, axis in enumerate("xyz"):
        seg, label = scene.axis_segment(loaded, axis)
        x, y, depth = _ndc(pose, seg, scene.FRAME_WINDOW, scene.DEFAULT_FOV)
        assert y.max() < y_rock.min(), axis
        assert abs(x[0]) < 1 and abs(y[0]) < 1 and np.all(depth > pose.near)  # its label
        assert abs(abs((seg[1] - seg[0])[k]) - 0.08 * extent) < 1e-9
        np.testing.assert_allclose(label, seg[0])


def test_typed_percentiles_move_the_slider_and_the_colours(app):
    m = app.map
    assert (m.pct_lo.value, m.pct_hi.value) == (2.0, 98.0)
    m.pct_lo.value = 5.0
    m.pct_hi.value = 90.0
    assert app.wait_idle(60)
    st = app.session.shown.settings.stretch
    assert (st.mode, st.lo, st.hi) == ("percentile", 5.0, 90.0)
    assert tuple(m.percentiles.value) == (5.0, 90.0)
    m.percentiles.value = (10.0, 80.0)  # dragged: the typed fields follow
    assert app.wait_idle(60)
    assert (m.pct_lo.value, m.pct_hi.value) == (10.0, 80.0)
    assert app.session.shown.settings.stretch.lo == 10.0


def test_a_band_change_extracts_kept_profiles_again_and_the_table_shows_it(app, cloud):
    from rough_viewer.profiles.extraction import extract_profile

    m = app.feature(ProfileFeature)
    m.on.value = True
    pts = app.session.shown.loaded.display_points
    i = int(np.argmin(np.abs(pts[:, 0] - (-1.2)) + np.abs(pts[:, 2])))
    j = int(np.argmin(np.abs(pts[:, 0] - 1.2) + np.abs(pts[:, 2])))
    for k in (i, j):
        pick(app, pts[k].astype(float) + [0.0, -5.0, 0.0], (0.0, 1.0, 0.0))
    before = m.items[0]
    m.band.value = 0.05  # metres (the cloud's unit)
    assert app.wait_idle(60)
    a = m.items[0]
    ref = extract_profile(cloud.xyz(), before.source.start, before.source.end,
                          band_half_width=0.05)
    assert a.source.band_half_width == 0.05 != before.source.band_half_width
    assert a.source.n_points == ref.n_points > before.source.n_points
    np.testing.assert_allclose(a.profile.heights, ref.heights, equal_nan=True)
    assert "band ± (mm)" in m.note.content and "| 50 |" in m.note.content
    m.on.value = False


def test_the_profile_csv_is_saved_at_once(cloud):
    from rough_viewer.app.gate import open_server
    from tests.app.protocol import ProtocolClient

    server, _ = open_server("127.0.0.1", 0, token=None, log=False)
    app = build_app(server, cloud, prefetch=False)
    client = ProtocolClient(server.get_port())
    try:
        assert app.wait_idle(60)
        client.press("Download CSV")
        name, _data = client.wait_download("profiles.csv")
        start = [msg for msg in client.of_type("FileTransferStartDownload")
                 if msg["filename"] == name][-1]
        assert start["save_immediately"] is True  # no second click in the browser
    finally:
        client.close()
        app.stop()
        server.stop()
