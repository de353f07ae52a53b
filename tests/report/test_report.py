"""Tests of the report: JSON numbers against independent references, the HTML page,
the command's input checks, and the page in headless Chromium."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import sys

import numpy as np
import pytest
from plotly.offline import get_plotlyjs

from rough_viewer import __version__
from rough_viewer.cli import main
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.summary import histogram, normalise, summarise
from rough_viewer.io import PointCloud
from rough_viewer.report import FIGURE_NAMES, build_report, report_html, report_json
from rough_viewer.report.build import FACE_IMAGE_MAX_PIXELS
from rough_viewer.vocabulary import MAPS

GOOD = (0.5, 0.25)
TOO_COARSE = 2.5  # leaves 3 cells


def rough_tilted_face(n: int = 20_000, seed: int = 0) -> np.ndarray:
    """A 6 m x 2 m rough face, turned 25 degrees about z, far from the origin (UTM-like)."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(0, 6, n)
    v = rng.uniform(0, 2, n)
    h = (0.1 * np.sin(1.7 * u) * np.cos(2.3 * v) + 0.01 * rng.normal(size=n)
         + 0.05 * (np.sin(6 * u) > 0.9) * rng.normal(size=n))
    a = np.radians(25)
    return np.column_stack([
        600_000 + u * np.cos(a) - h * np.sin(a),
        4_100_000 + u * np.sin(a) + h * np.cos(a),
        1500 + v,
    ])


@pytest.fixture(scope="module")
def cloud_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("cloud") / "face.npy"
    np.save(path, rough_tilted_face())
    return path


@pytest.fixture(scope="module")
def cloud(cloud_file):
    return PointCloud.from_xyz(np.load(cloud_file), source=str(cloud_file))


@pytest.fixture(scope="module")
def report(cloud):
    return build_report(cloud, [*GOOD, TOO_COARSE])


def brute_force_variogram(centres, values, g):
    """Contract binning by a plain loop over pairs: bin k holds d in [(k-.5)g, (k+.5)g)."""
    ok = np.isfinite(values)
    c, z = centres[ok], values[ok]
    extent = (c.max(axis=0) - c.min(axis=0)) + g
    n_bins = int(np.floor(0.5 * extent.max() / g + 1e-9))
    pairs = np.zeros(n_bins, dtype=np.int64)
    total = np.zeros(n_bins)
    for i in range(len(z) - 1):
        d = np.sqrt(((c[i + 1:] - c[i]) ** 2).sum(axis=1))
        k = np.floor(d / g + 0.5).astype(int)
        sel = (k >= 1) & (k <= n_bins)
        np.add.at(pairs, k[sel] - 1, 1)
        np.add.at(total, k[sel] - 1, (z[i + 1:][sel] - z[i]) ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        gamma = np.where(pairs > 0, total / (2 * pairs), np.nan)
    return np.arange(1, n_bins + 1) * g, pairs, gamma


def test_json_numbers_match_independent_references(cloud, report):
    data = json.loads(json.dumps(report_json(report), allow_nan=False))
    assert data["software"] == {"name": "rough_viewer", "version": __version__}
    assert data["input"]["points"] == cloud.n == 20_000
    np.testing.assert_allclose(data["input"]["bounds_min"], cloud.bounds()[0])
    assert data["axis"] == "y"  # face turned 25 degrees from xz: normal closest to y
    assert [gr["grid_size"] for gr in data["grids"]] == [*GOOD, TOO_COARSE]
    for gr in data["grids"][:2]:
        g = gr["grid_size"]
        assert gr["error"] is None
        result = grid_roughness(cloud, g)
        assert set(gr["models"]) == set(MAPS) == {"odr", "ols", "hybrid", "e_ols"}
        for name in MAPS:
            entry = gr["models"][name]
            values = result.values(name)
            ref = summarise(result, name).as_dict()
            assert entry["summary"] == pytest.approx(ref, rel=1e-12)
            hist = histogram(normalise(values), 0.05)
            np.testing.assert_allclose(entry["histogram"]["edges"], np.linspace(0, 1, 21))
            np.testing.assert_allclose(entry["histogram"]["fractions"], hist.fractions)
            assert sum(entry["histogram"]["fractions"]) == pytest.approx(1.0)
            lag, pairs, gamma = brute_force_variogram(result.centre, values, g)
            vg = entry["semivariogram"]
            np.testing.assert_allclose(vg["lag"], lag)
            assert vg["pairs"] == pairs.tolist()
            np.testing.assert_allclose(vg["gamma"], gamma, rtol=1e-8)
            var = np.var(values[np.isfinite(values)])
            np.testing.assert_allclose(vg["gamma_normalised"], gamma / var, rtol=1e-8)
    coarse = data["grids"][2]
    assert "too few cells" in coarse["error"] and "models" not in coarse


def test_html_holds_every_figure_and_the_input_facts(report):
    page = report_html(report)
    assert "face.npy" in page and "20,000" in page and f"rough_viewer {__version__}" in page
    assert "dependent axis (OLS, hybrid)</td><td>y" in page
    # plotly.js inlined once; apart from it, nothing refers to the network
    plotly_js = get_plotlyjs()
    assert page.count(plotly_js) == 1
    rest = page.replace(plotly_js, "")
    assert "<script src=" not in rest and "http" not in rest
    for g in GOOD:
        sid = f"grid-{g:g}".replace(".", "_")
        section = page.split(f'<section id="{sid}"')[1].split("</section>")[0]
        assert re.findall(r'data-figure="(\w+)"', section) == list(FIGURE_NAMES)
        assert f"grid {g:g} m" in section
    bad = page.split('<section id="grid-2_5"')[1].split("</section>")[0]
    assert "too few cells" in bad and "data-figure" not in bad


def test_every_grid_too_coarse_still_reports(cloud):
    rep = build_report(cloud, [TOO_COARSE, 50.0])
    assert [s.error is not None for s in rep.sections] == [True, True]
    assert rep.axis == "y" and rep.n_points == 20_000
    data = report_json(rep)
    assert all("too few cells" in g["error"] for g in data["grids"])
    assert report_html(rep).count("too few cells") == 2


def test_progress_reaches_the_end(cloud):
    calls = []
    build_report(cloud, [0.5, TOO_COARSE], progress=lambda d, t: calls.append((d, t)))
    assert calls[-1][0] == calls[-1][1] and calls[0][0] == 0
    assert all(b[0] >= a[0] for a, b in zip(calls, calls[1:], strict=False))


def test_command_writes_json_and_html(cloud_file, tmp_path, capsys):
    out = tmp_path / "r.json"
    rc = main(["report", str(cloud_file), "--grid", "0.5", "--grid", str(TOO_COARSE),
               "--format", "json", "--out", str(out), "--quiet"])
    assert rc == 0
    data = json.loads(out.read_text())
    assert data["grids"][0]["models"]["odr"]["summary"]["cells"] > 10
    err = capsys.readouterr().err
    assert "grid 2.5 m: too few cells" in err
    html_out = tmp_path / "r.html"
    assert main(["report", str(cloud_file), "--grid", "0.5", "--out", str(html_out),
                 "--quiet", "--threshold", "0.1"]) == 0
    assert "Binary transform at 0.1" in html_out.read_text()


def test_command_refuses_bad_input(cloud_file, tmp_path, capsys):
    out = tmp_path / "r.html"
    out.write_text("keep me")
    assert main(["report", str(cloud_file), "--grid", "0.5", "--out", str(out), "--quiet"]) == 2
    assert "output file exists" in capsys.readouterr().err
    assert out.read_text() == "keep me"
    missing = tmp_path / "nope" / "r.html"
    assert main(["report", str(cloud_file), "--out", str(missing), "--quiet"]) == 2
    assert "output folder does not exist" in capsys.readouterr().err
    for opts in (["--grid", "0"], ["--grid", "nan"], ["--threshold", "1.5"], ["--min-points", "2"]):
        assert main(["report", str(cloud_file), *opts, "--out", str(tmp_path / "x.html")]) == 2
        err = capsys.readouterr().err
        assert err.startswith("rough-viewer: error:") and err.count("\n") == 1
    assert not (tmp_path / "x.html").exists()
    assert main(["report", str(tmp_path / "absent.npy"), "--out", str(tmp_path / "x.html")]) == 2
    assert "absent.npy" in capsys.readouterr().err


def test_png_without_kaleido_is_a_one_line_error(cloud_file, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "kaleido", None)  # as if not installed
    out = tmp_path / "r.html"
    rc = main(["report", str(cloud_file), "--grid", "0.5", "--out", str(out),
               "--png", str(tmp_path / "png"), "--quiet"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "kaleido" in err and err.count("\n") == 1
    assert not out.exists()  # checked before any work


def test_a_png_that_fails_leaves_nothing(cloud_file, tmp_path, monkeypatch, capsys):
    """The fourth figure's renderer fails: one line, exit 2, and neither the page nor
    the first three PNGs nor the new folder stay."""
    import plotly.graph_objects as go

    import rough_viewer.visual.export as export_module

    calls = []

    def flaky_to_image(fig, format="png", scale=1):
        calls.append(1)
        if len(calls) >= 4:  # the fourth figure, and its second try
            raise RuntimeError("the browser went away")
        return b"\x89PNG fake"

    monkeypatch.setattr(export_module, "check_figure_export", lambda fmt: None)
    monkeypatch.setattr(go.Figure, "to_image", flaky_to_image)
    png, out = tmp_path / "png", tmp_path / "r.html"
    assert main(["report", str(cloud_file), "--grid", "0.5", "--out", str(out),
                 "--png", str(png), "--quiet"]) == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if "error:" in line]
    assert errors == ["rough-viewer: error: PNG export failed: the browser went away"]
    assert not out.exists() and not png.exists() and len(calls) == 4 + 1  # one retry
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_png_export_writes_every_figure(cloud_file, tmp_path, monkeypatch):
    """The export logic, with kaleido's renderer replaced by a stub."""
    import plotly.graph_objects as go

    import rough_viewer.visual.export as export_module

    rendered = []

    def fake_to_image(fig, format="png", scale=1):
        rendered.append(fig.layout.title.text)
        return b"\x89PNG fake"

    monkeypatch.setattr(export_module, "check_figure_export", lambda fmt: None)
    monkeypatch.setattr(go.Figure, "to_image", fake_to_image)
    png = tmp_path / "png"
    rc = main(["report", str(cloud_file), "--grid", "0.5", "--grid", str(TOO_COARSE),
               "--out", str(tmp_path / "r.html"), "--png", str(png), "--quiet"])
    assert rc == 0
    assert sorted(p.name for p in png.iterdir()) == sorted(f"g0.5_{f}.png" for f in FIGURE_NAMES)
    assert (png / "g0.5_histogram.png").read_bytes() == b"\x89PNG fake"
    assert all("grid 0.5 m" in t for t in rendered)
    # existing PNGs are refused before any work, unless --force
    (tmp_path / "r.html").unlink()
    assert main(["report", str(cloud_file), "--grid", "0.5", "--out", str(tmp_path / "r.html"),
                 "--png", str(png), "--quiet"]) == 2
    assert not (tmp_path / "r.html").exists()


@pytest.mark.skipif(importlib.util.find_spec("kaleido") is None,
                    reason="kaleido not installed (rough_viewer[images])")
def test_png_export_draws_real_images(cloud_file, tmp_path):
    """kaleido and Chromium draw every figure: real PNGs of the figure's size."""
    from PIL import Image

    png = tmp_path / "png"
    rc = main(["report", str(cloud_file), "--grid", "0.5", "--out", str(tmp_path / "r.html"),
               "--png", str(png), "--quiet"])
    assert rc == 0
    assert sorted(p.name for p in png.iterdir()) == sorted(f"g0.5_{f}.png" for f in FIGURE_NAMES)
    for name in ("histogram", "summary"):
        image = Image.open(png / f"g0.5_{name}.png")
        assert image.format == "PNG" and min(image.size) > 300
        assert len(np.unique(np.asarray(image.convert("RGB")).reshape(-1, 3), axis=0)) > 20


@pytest.mark.browser
def test_report_opens_in_chromium_with_every_figure(report, tmp_path, chromium):
    path = tmp_path / "report.html"
    path.write_text(report_html(report), encoding="utf-8")
    ctx = chromium.new_context(viewport={"width": 1200, "height": 900}, offline=True)
    page = ctx.new_page()
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.goto(path.as_uri())
    expected = len(GOOD) * len(FIGURE_NAMES)
    page.wait_for_function(
        f"document.querySelectorAll('.js-plotly-plot .main-svg').length >= {expected}",
        timeout=60_000)
    for g in GOOD:
        sid = f"grid-{g:g}".replace(".", "_")
        for name in FIGURE_NAMES:
            fig = page.locator(f'#{sid} [data-figure="{name}"] .js-plotly-plot')
            assert fig.count() == 1, (g, name)
            title = fig.locator(".gtitle").first.text_content()
            assert f"grid {g:g} m" in title and "dependent axis y" in title, title
            assert "20,000 points" in title
    traces = page.evaluate(
        "Array.from(document.querySelectorAll('.js-plotly-plot')).map(d => d.data.length)")
    assert len(traces) == expected and min(traces) >= 1
    assert page.get_by_text("too few cells").count() == 1
    ctx.close()
    assert not errors, errors


def test_far_apart_parts_get_coarser_face_pixels_not_a_dense_box():
    # two rough patches 50 km apart diagonally: at 0.5 m the face image between them
    # would be 100,000 x 100,000 pixels; it is drawn at 64 x 64 cells per pixel
    a = rough_tilted_face(4000, seed=1)
    b = rough_tilted_face(4000, seed=2) + np.array([35_000.0, 35_000.0, 0.0])
    report = build_report(PointCloud.from_xyz(np.vstack([a, b])), (0.5,))
    s = report.sections[0]
    assert s.error is None and s.figure_errors == {}
    img = s.maps["odr"].normalised
    assert img.image.size <= FACE_IMAGE_MAX_PIXELS and img.cell_size == 0.5 * 64
    # the figure may reduce further for display (at most 500,000 pixels a panel)
    html = report_html(report)
    found = re.search(r"each pixel the max of (\d+) x \1 cells", html)
    assert found and int(found.group(1)) >= 64
    assert "no zones_map figure" not in html  # the zone map uses the same coarse raster


def test_a_figure_that_cannot_fit_never_takes_table1_or_histograms_with_it(monkeypatch):
    import rough_viewer.memory as memory

    # a machine with 60 MB free once the cloud is read: the face-plane images (up to
    # 160 MB) cannot be made; Table 1, histograms and semivariograms (lag shortened)
    # still are
    a = rough_tilted_face(4000, seed=1)
    b = rough_tilted_face(4000, seed=2) + np.array([3_000.0, 3_000.0, 0.0])
    cloud = PointCloud.from_xyz(np.vstack([a, b]))
    monkeypatch.setattr(memory, "available_bytes", lambda: 60e6)
    report = build_report(cloud, (0.5,))
    s = report.sections[0]
    assert s.error is None
    assert "maps" in s.figure_errors and "face-plane image" in s.figure_errors["maps"]
    ref = grid_roughness(cloud, 0.5)
    assert s.summaries["odr"].cells == int(np.isfinite(ref.theta_odr).sum())
    assert set(s.histograms) == set(MAPS) and set(s.variograms) == set(MAPS)
    assert all(vg.pairs.sum() > 0 for vg in s.variograms.values())
    html = report_html(report)
    assert "no maps figure" in html and 'data-figure="summary"' in html
    assert 'data-figure="maps_normalised"' not in html
    assert json.loads(json.dumps(report_json(report)))["grids"][0]["figure_errors"]["maps"]


def test_command_without_grid_uses_the_grids_from_the_point_spacing(cloud_file, cloud, tmp_path,
                                                                    capsys):
    from rough_viewer.grid.spacing import TARGET_POINTS, median_cell_count, preset_cell_sizes

    out = tmp_path / "d.json"
    assert main(["report", str(cloud_file), "--format", "json", "--out", str(out),
                 "--quiet"]) == 0
    data = json.loads(out.read_text())
    sizes = [g["grid_size"] for g in data["grids"]]
    assert sizes == pytest.approx(list(preset_cell_sizes(cloud)))
    assert data["grids_chosen"] == "default"
    assert sizes == pytest.approx([8 * sizes[-1], 4 * sizes[-1], 2 * sizes[-1], sizes[-1]])
    assert median_cell_count(cloud, sizes[-1]) >= TARGET_POINTS
    assert "grid sizes from the point spacing" in capsys.readouterr().out


def test_command_units_mm_scale_every_length(cloud_file, cloud, tmp_path):
    mm_file = tmp_path / "face_mm.npy"
    np.save(mm_file, np.load(cloud_file) * 1000.0)
    a, b = tmp_path / "m.json", tmp_path / "mm.json"
    assert main(["report", str(cloud_file), "--grid", "0.5", "--format", "json", "--out", str(a),
                 "--quiet"]) == 0
    assert main(["report", str(mm_file), "--units", "mm", "--grid", "500", "--format", "json",
                 "--out", str(b), "--quiet"]) == 0
    m, mm = json.loads(a.read_text()), json.loads(b.read_text())
    assert mm["unit"] == "mm" and mm["grids"][0]["grid_size"] == 500.0
    sm, smm = m["grids"][0]["models"]["odr"], mm["grids"][0]["models"]["odr"]
    assert smm["summary"]["mean"] == pytest.approx(1000 * sm["summary"]["mean"], rel=1e-9)
    assert smm["semivariogram"]["lag"] == pytest.approx([1000 * v for v in sm["semivariogram"]["lag"]])
    html_out = tmp_path / "mm.html"
    assert main(["report", str(mm_file), "--units", "mm", "--grid", "500", "--out",
                 str(html_out), "--quiet"]) == 0
    text = html_out.read_text()
    assert "Grid 500 mm" in text and "lag (mm)" in text
    assert "std\\u003cbr\\u003e(mm)" in text  # Table 1 header, as plotly escapes it


def test_zones_section_in_json_matches_the_labeller(cloud, report):
    from rough_viewer.grid.orientation import cell_stereonet
    from rough_viewer.structure.zones import ZONE_COLUMNS, ZoneLabeller

    data = json.loads(json.dumps(report_json(report), allow_nan=False))
    assert data["min_cells"] == 3 and data["connectivity"] == "vertex"
    for entry, g in zip(data["grids"], GOOD, strict=False):
        ref = grid_roughness(cloud, g, axis=report.axis)
        zones = ZoneLabeller.build(ref).zones(report.threshold)
        z = entry["zones"]
        assert z["map"] == "odr" and z["threshold"] == report.threshold
        assert z["columns"] == list(ZONE_COLUMNS)
        assert z["count"] == zones.n_zones == len(z["rows"])
        assert z["cells_in_zones"] == int(zones.cells.sum())
        table = zones.table()
        for k, row in enumerate(z["rows"]):
            for name, value in zip(ZONE_COLUMNS, row, strict=True):
                assert value == pytest.approx(float(table[name][k]), rel=1e-12, abs=1e-12)
        net = cell_stereonet(ref)
        assert z["stereonet"]["poles"] == net.n_poles
        dens = np.array([[np.nan if v is None else v for v in r]
                         for r in z["stereonet"]["density_mud"]])
        np.testing.assert_allclose(dens, net.density, rtol=1e-12, equal_nan=True)
    assert "zones" not in data["grids"][2]  # the grid size with too few cells


def test_report_zone_options_and_their_checks(cloud):
    rep = build_report(cloud, [0.25], threshold=0.3, min_cells=5, connectivity="face")
    zones = rep.sections[0].zones
    assert zones is not None and zones.connectivity == "face" and zones.min_cells == 5
    assert np.all(zones.cells >= 5)
    from rough_viewer.vocabulary import InputError

    with pytest.raises(InputError, match="connectivity"):
        build_report(cloud, [0.25], connectivity="corner")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="min cells"):
        build_report(cloud, [0.25], min_cells=0)


@pytest.mark.parametrize("grids, shown", [
    (["1e-9"], ["grid 1e-09 m: grid size 1e-09 m would take"]),
    (["1e-9", str(TOO_COARSE)], ["grid 1e-09 m: grid size 1e-09 m would take",
                                 "grid 2.5 m: too few cells"]),
])
def test_no_grid_computed_exits_2_and_writes_nothing(cloud_file, tmp_path, capsys, grids, shown):
    argv = ["report", str(cloud_file), "--out", str(tmp_path / "r.html"), "--quiet"]
    for g in grids:
        argv += ["--grid", g]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("rough-viewer: error: no grid size could be computed: ")
    assert err.count("\n") == 1 and all(s in err for s in shown)
    assert os.listdir(tmp_path) == []


def test_grid_message_names_the_unit(cloud_file, tmp_path, capsys):
    assert main(["report", str(cloud_file), "--grid", "0", "--units", "mm", "--out",
                 str(tmp_path / "r.html")]) == 2
    assert capsys.readouterr().err == (
        "rough-viewer: error: --grid must be a positive length in mm, got 0\n")
    assert os.listdir(tmp_path) == []


def test_cells_of_repeated_points_are_a_report_warning():
    from tests.helpers import repeated_points_cloud

    rep = build_report(PointCloud.from_xyz(repeated_points_cloud()), grid_sizes=[1.0])
    assert any(w.startswith("grid 1 m: 3 of 6 cells with a value fit their plane exactly")
               and "--min-points" in w for w in rep.warnings)


def test_each_grid_section_holds_its_joint_sets(report, cloud):
    """The JSON's sets are the library's on the same grid (the report's display
    unit), and the page says how many sets and planes each grid has."""
    from rough_viewer.structure.sets import PLANE_COLUMNS, SET_COLUMNS, joint_sets

    data = report_json(report)
    page = report_html(report)
    for g, entry in zip(GOOD, data["grids"], strict=False):
        ref = joint_sets(grid_roughness(cloud, g, axis="y"), cloud)
        sets = entry["sets"]
        assert sets["columns"] == list(SET_COLUMNS) and sets["count"] == ref.n_sets
        assert sets["plane_columns"] == list(PLANE_COLUMNS)
        assert len(sets["plane_rows"]) == ref.planes.n_planes
        table = ref.set_table()
        for k, row in enumerate(sets["rows"]):
            for name, value in zip(SET_COLUMNS, row, strict=True):
                expected = table[name][k]
                assert value == (None if not np.isfinite(expected) else pytest.approx(expected))
        assert sets["note"] == ref.note and sets["max_roughness"] == pytest.approx(0.02 * g)
        sid = f"grid-{g:g}".replace(".", "_")
        section = page.split(f'<section id="{sid}"')[1].split("</section>")[0]
        assert "<h3>Joint sets</h3>" in section
        if ref.n_sets:
            assert f"{ref.planes.n_planes:,} planes" in section
        else:
            assert "no joint set" in section


def test_outliers_are_left_out_and_the_threshold_judged():
    """A wall read along z whose vertical half gives hybrid values larger than the
    cell: the report's hybrid Table 1, histogram and semivariogram leave those cells
    out (or keep them when asked), the warnings name them, and every map carries the
    share its threshold flags with the data's own threshold."""
    from rough_viewer.grid.outliers import analysed_values, outlier_mask
    from rough_viewer.grid.threshold import threshold_advice
    from tests.grid.test_outliers import leaning_wall

    cloud = PointCloud.from_xyz(leaning_wall(20_000), source="wall.xyz")
    ref = grid_roughness(cloud, 0.25, axis="z")
    steep = outlier_mask(ref, "hybrid")
    assert steep.any()
    for keep in (False, True):
        rep = build_report(cloud, [0.25], axis="z", keep_outliers=keep)
        data = json.loads(json.dumps(report_json(rep), allow_nan=False))
        assert data["keep_outliers"] is keep
        entry = data["grids"][0]["models"]["hybrid"]
        values = analysed_values(ref, "hybrid", keep_outliers=keep)
        assert entry["summary"] == pytest.approx(
            summarise(ref, "hybrid", keep_outliers=keep).as_dict(), rel=1e-12)
        assert entry["summary"]["max"] == pytest.approx(np.nanmax(values), rel=1e-12)
        np.testing.assert_allclose(entry["histogram"]["fractions"],
                                   histogram(normalise(values)).fractions)
        assert entry["semivariogram"]["n_cells"] == np.isfinite(values).sum()
        advice = data["grids"][0]["threshold_advice"]
        for name in MAPS:
            expected = threshold_advice(analysed_values(ref, name, keep_outliers=keep), 0.05,
                                        exact_fit=1e-9 * 0.25)
            assert advice[name]["share"] == pytest.approx(expected.share)
            assert advice[name]["suggested"] == pytest.approx(expected.suggested)
        named = [w for w in rep.warnings if "larger than the cell" in w]
        assert len(named) == 1 and named[0].startswith(f"grid 0.25 m: {steep.sum()} of ")
        assert ("--keep-outliers keeps them" in named[0]) is not keep
    page = report_html(rep)
    assert "hybrid outliers (larger than the cell), kept" in page
    assert "threshold 0.05 flags" in page


def test_default_grids_of_a_small_cloud_leave_out_the_too_coarse():
    """Issue 31: the default report grids gave "too few cells" on 2 of 4 grids of
    laspy's small sample files. A 1,000-point 10 m face keeps the presets that make at
    least MIN_CELLS cells: every section of its report has results."""
    from rough_viewer.grid.spacing import preset_cell_sizes
    from rough_viewer.report.build import MIN_CELLS, default_report_grids

    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(0, 10, (1000, 2)), 0.01 * rng.standard_normal(1000)])
    cloud = PointCloud.from_xyz(pts)
    presets = preset_cell_sizes(cloud)
    grids = default_report_grids(cloud)
    assert grids == presets[2:]  # 12 m and 6 m cells: 1 and 4 cells on a 10 m face
    for g in presets:  # brute force: occupied cells of each preset
        cells = np.unique(np.floor((pts - pts.min(axis=0)) / g), axis=0).shape[0]
        assert (cells >= MIN_CELLS) == (g in grids)
    report = build_report(cloud)
    assert [s.grid_size for s in report.sections] == list(grids)
    assert all(s.error is None for s in report.sections)


def test_a_set_parallel_to_the_exposure_face_is_flagged_in_the_report():
    """Issue 31 item 2: the hillside's slope "set" is flagged on the page, in the
    set table figure and in the JSON (``face_parallel``, ``face_angle_deg``)."""
    from rough_viewer.report import report_figures
    from rough_viewer.structure.sets import SET_COLUMNS, joint_sets
    from tests.structure.test_face import hillside

    pts = hillside(size=40.0, step=0.5)
    rep = build_report(PointCloud.from_xyz(pts), grid_sizes=[2.0])
    ref = joint_sets(grid_roughness(pts, 2.0, models=("odr",)), pts)
    assert ref.face_parallel.tolist() == [True]
    page = report_html(rep)
    assert ("⚠ Set 1 (22/187) lies parallel to the exposure face (within 10°): its spacing "
            "is not a joint spacing (left out of Jv, Ib and RQD).") in page
    sets = report_json(rep)["grids"][0]["sets"]
    row = dict(zip(SET_COLUMNS, sets["rows"][0], strict=True))
    assert row["face_parallel"] == 1
    assert row["face_angle_deg"] == pytest.approx(ref.face_angle_deg[0])
    table = report_figures(rep, rep.sections[0])["sets_table"]
    cells = table.data[0].cells.values
    assert cells[0] == ["<b>1</b> ⚠"] and cells[-1][0].endswith("⚠ face")
    assert table.layout.title.text.startswith("1 joint set (⚠ 1: exposure face)<br>")
