"""Roughness by direction in the report: a section per input file (issue 25)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.directions.analysis import DirectionSettings, analyse_directions
from rough_viewer.directions.table import EXTRA_COLUMNS, TABLE_COLUMNS, directions_table
from rough_viewer.io import PointCloud
from rough_viewer.report.directions import directions_dict
from rough_viewer.synthetic.fbm import fbm_sheet


def sheet_file(path, seed: int, scale: float = 1.0):
    z = fbm_sheet((90, 90), 0.3, 0.7, spacing=0.002, sigma=0.05, rng=seed)
    yy, xx = np.mgrid[0:90, 0:90] * 0.002
    np.save(path, np.column_stack([xx.ravel(), yy.ravel(), scale * z.ravel()]))
    return path


def test_report_has_a_directions_section_per_input(tmp_path, capsys):
    a, b = sheet_file(tmp_path / "a.npy", 1), sheet_file(tmp_path / "b.npy", 2, 3.0)
    out, js = tmp_path / "r.html", tmp_path / "r.json"
    assert main(["report", str(a), str(b), "--grid", "0.02", "--directions", "45",
                 "--out", str(out), "--quiet"]) == 0
    assert main(["report", str(a), str(b), "--grid", "0.02", "--directions", "45",
                 "--format", "json", "--out", str(js), "--quiet"]) == 0
    capsys.readouterr()
    page = out.read_text()
    assert page.count('class="directions-section"') == 2
    assert f"Roughness by direction: {a}" in page and f"Roughness by direction: {b}" in page
    assert page.count('data-figure="directions-rose"') == 2
    data = json.loads(js.read_text())["directions"]
    assert [d["source"] for d in data] == [str(a), str(b)]
    # each file measured on its own: the same numbers as the API on that file alone
    for d, path in zip(data, (a, b), strict=True):
        cloud = PointCloud.from_xyz(np.load(path))
        api = directions_table(analyse_directions(cloud, DirectionSettings(step_deg=45.0)))
        assert d["columns"] == list(api)
        got = np.array([[np.nan if v is None else v for v in row] for row in d["rows"]])
        np.testing.assert_allclose(got, np.column_stack([api[c] for c in api]),
                                   rtol=1e-12, equal_nan=True)
    # the steeper sheet (heights times 3) is rougher by the TIN parameters
    assert np.nanmean(np.array(data[1]["rows"])[:, data[1]["columns"].index("delta_t")]) > \
        np.nanmean(np.array(data[0]["rows"])[:, data[0]["columns"].index("delta_t")])


def test_report_without_directions_has_no_section(tmp_path, capsys):
    a = sheet_file(tmp_path / "a.npy", 1)
    out = tmp_path / "r.json"
    assert main(["report", str(a), "--grid", "0.02", "--format", "json", "--out", str(out),
                 "--quiet"]) == 0
    capsys.readouterr()
    assert json.loads(out.read_text())["directions"] == []
    assert main(["report", str(a), "--grid", "0.02", "--directions", "500", "--out",
                 str(tmp_path / "x.html")]) == 2
    assert "at most 360" in capsys.readouterr().err
    assert main(["report", str(a), "--grid", "0.02", "--directions", "1e-300", "--out",
                 str(tmp_path / "x.html")]) == 2  # issue 36: a traceback
    err = capsys.readouterr().err
    assert "--directions must be from 1 to" in err and len(err.strip().splitlines()) == 1


def test_table_columns_and_dict():
    z = fbm_sheet((60, 60), 0.3, 0.7, spacing=0.002, rng=4)
    yy, xx = np.mgrid[0:60, 0:60] * 0.002
    cloud = PointCloud.from_xyz(np.column_stack([xx.ravel(), yy.ravel(), z.ravel()]))
    r = analyse_directions(cloud, DirectionSettings(step_deg=90.0, min_samples=40))
    t = directions_table(r, unit="mm")
    assert tuple(t) == TABLE_COLUMNS + EXTRA_COLUMNS
    np.testing.assert_allclose(t["rms_mean"], directions_table(r)["rms_mean"] * 1e3)
    d = directions_dict(r, unit="mm")
    assert d["surface"] == "triangulated" and d["triangles"] == r.tin.n_triangles
    assert d["sample_spacing"] == pytest.approx(r.sets[0].sample_spacing * 1e3, rel=1e-12)


def test_the_tin_parameters_can_be_left_out():
    """tin=False (the app's default: triangulating a large cloud takes most of the
    time): the same profile sets, no triangles, no warning about them."""
    z = fbm_sheet((60, 60), 0.3, 0.7, spacing=0.002, rng=4)
    yy, xx = np.mgrid[0:60, 0:60] * 0.002
    cloud = PointCloud.from_xyz(np.column_stack([xx.ravel(), yy.ravel(), z.ravel()]))
    full = analyse_directions(cloud, DirectionSettings(step_deg=90.0, min_samples=40))
    bare = analyse_directions(cloud, DirectionSettings(step_deg=90.0, min_samples=40, tin=False))
    assert bare.tin is None and bare.surface == "none" and bare.n_triangles == 0
    assert not any("TIN" in w for w in bare.warnings)
    for a, b in zip(bare.sets, full.sets, strict=True):
        np.testing.assert_array_equal(a.values["hurst"], b.values["hurst"])
    assert np.all(np.isnan(directions_table(bare)["theta_max_c1"]))
