"""The app on a real viser server (port 0), driven by setting GUI handle values.

Setting ``handle.value`` runs the callbacks as a browser edit would; the work then
runs on the app's worker thread, so each test waits with ``app.wait_idle()``.
"""

import numpy as np
import pytest

from rough_viewer.app import store as store_mod
from rough_viewer.app.features.panels import PanelsFeature
from rough_viewer.app.files import UploadedFile
from rough_viewer.app.server import build_app
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.summary import histogram, normalise
from rough_viewer.io import PointCloud
from rough_viewer.visual import colormaps
from tests.app.protocol import pick, shown_colours


def expected_colours(app, cloud, cell, name, cmap="viridis"):
    """The default stretch (log, percentiles 2-98 of the cells) of an independent
    core run, through the colour map's LUT."""
    core = grid_roughness(cloud, cell)
    v = core.values(name)
    ok = np.isfinite(v) & (v > 0)
    top = np.percentile(v[ok], 98)
    lo, hi = np.percentile(v[ok & (v >= top / 1e4)], [2, 98])
    idx = app.session.shown.loaded.display_index
    per_point = v[core.point_cell[idx]]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.log10(np.maximum(per_point, lo)) - np.log10(lo)) / (np.log10(hi) - np.log10(lo))
    out = colormaps.lut(cmap)[np.round(np.clip(np.nan_to_num(t), 0, 1) * 255).astype(int)]
    out[~np.isfinite(per_point)] = colormaps.NEUTRAL_RGB
    return out


def test_first_view_is_odr_at_the_default_grid(app, cloud):
    assert list(app.host.errors) == []
    loaded = app.session.shown.loaded
    # presets from the point spacing; the first map is the finest
    assert loaded.presets == (0.64, 0.32, 0.16, 0.08)
    assert app.map.grid.options == ("0.64", "0.32", "0.16", "0.08", "free")
    assert app.map.grid.value == "0.08" and app.session.shown.settings.cell_size == 0.08
    assert np.array_equal(shown_colours(app), expected_colours(app, cloud, 0.08, "odr"))
    assert "40,000 points, each tab draws up to 3,000,000" in app.host.status.content
    assert "auto chose **y**" in app.map.axis_note.content
    fig = app.map.colour_bar.figure
    title = fig.layout.title.text
    assert "ODR" in title and "0.08 m" in title and "axis y" in title
    # the colour bar says which stretch, in mm, and the range fields show it (3 digits)
    assert "θ (mm)" in fig.layout.xaxis.title.text
    assert "percentiles 2–98, log" in fig.layout.xaxis.title.text
    rng = app.session.shown.stats.colour_range
    assert app.map.range_lo.value == float(f"{rng.lo * 1e3:.3g}")
    assert app.map.range_hi.value == float(f"{rng.hi * 1e3:.3g}")
    assert app.map.stretch.value == "percentile" and app.map.log.value
    assert not app.host.notice.visible  # every cell of this face has a value


def test_grid_and_model_change_colours_and_panels(app, cloud):
    before = shown_colours(app).copy()
    app.map.grid.value = "0.16"
    assert app.wait_idle(60)
    assert app.map.grid_free.value == 0.16
    assert app.session.shown.result.grid.cell_size == 0.16
    now = shown_colours(app)
    assert not np.array_equal(before, now)
    assert np.array_equal(now, expected_colours(app, cloud, 0.16, "odr"))
    # histogram panel: ODR and OLS fractions equal the core's 0.05-bin histogram
    core = grid_roughness(cloud, 0.16)
    fig = app.feature(PanelsFeature).histogram.figure
    names = [t.name for t in fig.data]
    assert names[0].startswith("ODR") and names[1].startswith("OLS")
    for trace, m in zip(fig.data, ("odr", "ols"), strict=False):
        want = histogram(normalise(core.values(m)), 0.05).fractions * 100
        assert np.allclose(trace.y, want)
    assert "grid 0.16 m" in fig.layout.title.text

    app.map.model.value = "OLS"
    assert app.wait_idle(60)
    assert np.array_equal(shown_colours(app), expected_colours(app, cloud, 0.16, "ols"))
    assert [t.name for t in app.feature(PanelsFeature).variogram.figure.data] == ["OLS", "ODR", "e_OLS"]
    table = app.feature(PanelsFeature).summary.figure.data[0]
    assert list(table.cells.values[0]) == ["ODR", "OLS", "hybrid", "e_OLS"]


def test_the_whole_face_trend_against_the_preset_grids(app, cloud):
    from rough_viewer.grid.summary import binary

    fig = app.feature(PanelsFeature).face_scales.figure
    assert "Table 1 trend" in fig.layout.title.text
    means = [t for t in fig.data if t.showlegend is not False][:3]
    shares = list(fig.data)[3:6]
    sizes = app.session.shown.loaded.presets
    for trace, share, m in zip(means, shares, ("odr", "ols", "hybrid"), strict=True):
        assert list(trace.x) == sorted(sizes)
        for x, y, z in zip(trace.x, trace.y, share.y, strict=True):
            core = grid_roughness(cloud, x).values(m)  # independent, per grid
            ok = np.isfinite(core)
            assert y == pytest.approx(np.mean(core[ok]) * 1e3, rel=1e-9)
            rough = binary(normalise(core), 0.05)
            assert z == pytest.approx(100 * rough.sum() / ok.sum(), rel=1e-9)
    # the waves of the face count as roughness on larger cells
    assert means[0].y[-1] > means[0].y[0]


def test_threshold_and_colormap_recolour_without_recomputing(app, monkeypatch):
    calls = []
    real = store_mod.grid_roughness
    monkeypatch.setattr(store_mod, "grid_roughness", lambda *a, **k: calls.append(a) or real(*a, **k))
    app.map.display.value = "binary"
    app.map.threshold.value = 0.3
    assert app.wait_idle(60)
    colours = shown_colours(app)
    lut = colormaps.lut("viridis")
    distinct = {tuple(c) for c in np.unique(colours, axis=0)}
    assert distinct <= {tuple(lut[0]), tuple(lut[-1]), colormaps.NEUTRAL_RGB}
    rough = np.all(colours == lut[-1], axis=1).mean()
    app.map.threshold.value = 0.8
    assert app.wait_idle(60)
    assert np.all(shown_colours(app) == lut[-1], axis=1).mean() < rough
    app.map.colormap.value = "magma"
    assert app.wait_idle(60)
    assert {tuple(c) for c in np.unique(shown_colours(app), axis=0)} <= {
        tuple(colormaps.lut("magma")[0]), tuple(colormaps.lut("magma")[-1]),
        colormaps.NEUTRAL_RGB}
    assert calls == []  # every change above reused the cached planes
    assert all(t["cached"] for t in list(app.map.timings)[-3:])


def test_e_ols_gets_a_sequential_map_and_toggle_button(app, cloud):
    app.map.model.value = "OLS error e_ols"
    assert app.wait_idle(60)
    assert app.session.shown.settings.colormap == "magma"  # e_ols >= 0: sequential, not diverging
    assert np.array_equal(shown_colours(app),
                          expected_colours(app, cloud, 0.08, "e_ols", "magma"))
    app.map.model.value = "ODR"
    app.map.toggle.value = True  # fires on_click like a browser press
    assert app.wait_idle(60)  # the worker flips the model
    assert app.map.model.value == "OLS"
    app.map.toggle.value = True
    assert app.wait_idle(60)
    assert app.map.model.value == "ODR"


def test_axis_choice_and_free_grid(app):
    app.map.axis.value = "z"
    app.map.grid_free.value = 0.3
    assert app.wait_idle(60)
    assert app.map.grid.value == "free"
    res = app.session.shown.result
    assert res.axis == "z" and res.grid.cell_size == 0.3
    assert "using **z**" in app.map.axis_note.content


def test_bad_grid_keeps_previous_view(app):
    before = shown_colours(app).copy()
    app.map.grid_free.value = 0.00001
    assert app.wait_idle(60)
    assert app.host.errors and "too small" in app.host.errors[-1]
    assert app.host.error.visible and "previous view" in app.host.error.content
    assert np.array_equal(shown_colours(app), before)
    assert app.map.grid.value == "0.08" and app.session.shown.settings.cell_size == 0.08
    app.map.grid.value = "0.32"  # a good change clears the message
    assert app.wait_idle(60)
    assert not app.host.error.visible


def test_load_files_from_the_data_folder_and_an_upload(server, cloud, tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    app = build_app(server, cloud, prefetch=False, data_dir=data)
    assert app.wait_idle(60)
    app.load(path="missing.las")
    assert app.wait_idle(60)
    assert "not found" in app.host.errors[-1] and app.session.shown.loaded.cloud is cloud
    (data / "bad.xyz").write_text("x y z\n1 2 admin\n")
    app.load(path="bad.xyz")
    assert app.wait_idle(60)
    assert len(app.host.errors) == 2 and app.session.shown.loaded.cloud is cloud
    # the message names the file as typed and never echoes its content or a server path
    assert "bad.xyz" in app.host.errors[-1] and "admin" not in app.host.errors[-1]
    assert str(data) not in app.host.errors[-1]
    # outside the data folder: refused, whatever the path's spelling
    outside = tmp_path / "outside.npy"
    np.save(outside, cloud.xyz()[:100])
    (data / "link.npy").symlink_to(outside)
    for typed in (str(outside), "../outside.npy", "link.npy"):
        app.load(path=typed)
        assert app.wait_idle(60)
        assert "outside the data folder" in app.host.errors[-1], typed
        assert app.session.shown.loaded.cloud is cloud
    xyz = cloud.xyz()[::4]
    np.save(data / "quarter.npy", xyz)
    app.load(path="quarter.npy")
    assert app.wait_idle(60)
    assert app.session.shown.loaded.n_total == len(xyz)
    assert "quarter.npy" in app.host.status.content
    assert len(shown_colours(app)) == len(xyz)
    app.load(path=str(data / "quarter.npy"))  # an absolute path inside is fine
    assert app.wait_idle(60) and app.session.shown.loaded.n_total == len(xyz)
    up = tmp_path / "upload-1.xyz"
    up.write_text("\n".join(f"{a:.4f} {b:.4f} {c:.4f}" for a, b, c in xyz[:3000]))
    app.load(upload=UploadedFile(up, "up.xyz", up.stat().st_size))
    assert app.wait_idle(60)
    assert app.session.shown.loaded.n_total == 3000 and "up.xyz" in app.host.status.content
    assert not up.exists()  # the uploaded file is deleted once read
    app.stop()


def test_click_reports_cell(app, cloud):
    loaded = app.session.shown.loaded
    i = 777
    target = loaded.display_points[i].astype(float)
    origin = target + np.array([0.0, -5.0, 0.0])  # the face looks at -y
    info = pick(app, origin, (0.0, 1.0, 0.0))
    core = grid_roughness(cloud, 0.08)
    p = int(loaded.display_index[i])
    assert info is not None and info.cell == core.point_cell[p]
    assert info.theta["odr"] == pytest.approx(core.theta_odr[info.cell])
    assert info.theta["e_ols"] == pytest.approx(core.e_ols[info.cell])
    assert f"Cell {info.ijk}" in app.map.pick.content
    assert np.allclose(info.point, cloud.xyz()[p], atol=1e-5)  # file frame
    # across scales: one value per preset grid, equal to the full maps of each grid
    ps = app.session.pick_scales
    assert list(ps.cell_sizes) == sorted(loaded.presets)
    fig = app.map.scales.figure
    assert app.map.scales.visible and [t.name for t in fig.data] == ["ODR", "OLS", "hybrid"]
    for g, odr, ols, hyb, trace_x in zip(ps.cell_sizes, ps.theta_odr, ps.theta_ols,
                                         ps.theta_hybrid, fig.data[0].x, strict=True):
        full = grid_roughness(cloud, g)  # independent: the whole map of that grid
        c = full.point_cell[p]
        assert odr == pytest.approx(full.theta_odr[c], rel=1e-9)
        assert ols == pytest.approx(full.theta_ols[c], rel=1e-9)
        assert hyb == pytest.approx(full.theta_hybrid[c], rel=1e-9)
        assert trace_x == g
    assert np.allclose(fig.data[0].y, ps.theta_odr * 1e3)
    assert app.map.pick_timings[-1]["grids"] == 4
    # the marker is a label (drawn on top, sized in pixels); the cell outline 12 edges
    assert [type(n).__name__ for n in app.map.pick_nodes] == ["LabelHandle", "LineSegmentsHandle"]
    assert pick(app, origin, (0.0, -1.0, 0.0)) is None
    # a click that hits nothing: its report does not sit beside the earlier point's
    assert app.map.pick.content == "No point under the click."
    assert app.map.pick_nodes == [] and app.session.last_pick is None
    assert [t.name for t in app.map.scales.figure.data] != ["ODR", "OLS", "hybrid"]


def test_big_cloud_has_an_even_overview_sample(server):
    rng = np.random.default_rng(2)
    xyz = np.column_stack([rng.uniform(0, 3, 30_000), rng.normal(0, 0.002, 30_000),
                           rng.uniform(0, 3, 30_000)])
    app = build_app(server, PointCloud.from_xyz(xyz), max_display=5_000)
    assert app.wait_idle(60)
    assert app.session.shown.loaded.n_display == 5_000  # framing, point size, highlights
    assert app.session.shown.result.point_cell.shape == (30_000,)
    assert "30,000 points, each tab draws up to" in app.host.status.content
    app.stop()


def test_idle_worker_prefetches_preset_grids(server, cloud):
    import time

    app = build_app(server, cloud.subset(np.arange(10_000)), prefetch=True)
    assert app.wait_idle(60)
    loaded = app.session.shown.loaded
    presets = [app.session.shown.settings.with_(cell_size=g) for g in loaded.presets]
    end = time.time() + 30
    while not all(loaded.is_cached(s) for s in presets) and time.time() < end:
        time.sleep(0.05)
    assert all(loaded.is_cached(s) for s in presets)
    app.map.grid.value = app.map.grid.options[0]
    assert app.wait_idle(60)
    assert app.map.timings[-1]["cached"] and app.session.shown.result.grid.cell_size == loaded.presets[0]
    app.stop()
