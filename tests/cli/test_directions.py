"""``rough-viewer directions``: the DIRECTIONS.csv and WINDOWS.csv contracts, units,
meshes and clouds, one-line errors (issue 25)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.directions.analysis import DirectionSettings, analyse_directions
from rough_viewer.directions.table import directions_table
from rough_viewer.io.load import load_points
from rough_viewer.synthetic.fbm import fbm_surface
from tests.io.test_mesh import write_binary_stl

CONTRACT = ["azimuth_deg", "profiles", "h_mean", "h_std", "d_mean", "d_std", "rms_mean",
            "z2_mean", "jrc_mean", "theta_max_c1"]


def read_csv(path: Path) -> tuple[list[str], dict[str, np.ndarray]]:
    with open(path) as fh:
        rows = list(csv.reader(fh))
    head = rows[0]
    cols = {h: np.array([float(r[i]) if r[i] else np.nan for r in rows[1:]])
            for i, h in enumerate(head)}
    return head, cols


@pytest.fixture(scope="module")
def sawtooth_stl(tmp_path_factory) -> Path:
    """A sawtooth joint in millimetres: 30-degree flanks rising and falling along x,
    teeth 1 mm high, 12 whole teeth (41.6 mm) by 30 mm, as a binary STL of its own
    triangles (whole teeth: the best-fit plane is level)."""
    rise = 1 / math.tan(math.radians(30.0))
    x = np.arange(97) * (rise / 4)
    z = np.interp(x % (2 * rise), [0, rise, 2 * rise], [0.0, 1.0, 0.0])
    y = np.arange(0.0, 30.0 + 1e-9, 0.5)
    xx, yy = np.meshgrid(x, y)
    zz = np.broadcast_to(z, xx.shape)
    i = np.arange(xx.size).reshape(xx.shape)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    path = tmp_path_factory.mktemp("directions") / "saw.stl"
    write_binary_stl(path, np.column_stack([xx.ravel(), yy.ravel(), zz.ravel()]), faces)
    return path


def test_directions_csv_contract_on_a_sawtooth_mesh(sawtooth_stl, tmp_path, capsys):
    out = tmp_path / "d.csv"
    step = str(1 / math.tan(math.radians(30.0)) / 4)  # the vertices' step along x
    code = main(["directions", str(sawtooth_stl), "--step", "15", "--units", "mm",
                 "--out", str(out), "--quiet", "--sample-spacing", step])
    text = capsys.readouterr().out
    assert code == 0 and "triangles of the file's mesh" in text
    head, cols = read_csv(out)
    assert head[:11] == CONTRACT + ["delta_t"]
    np.testing.assert_array_equal(cols["azimuth_deg"], np.arange(0, 360, 15.0))
    # Delta-T and theta*max/(C+1) of the 30-degree flanks: atan(tan 30 |cos a|), degrees
    # (the STL stores float32 corners: a little round-off)
    expected = np.degrees(np.arctan(math.tan(math.radians(30)) * np.abs(np.cos(np.radians(
        cols["azimuth_deg"])))))
    np.testing.assert_allclose(cols["delta_t"], expected, atol=2e-3)
    # theta*max/(C+1) is exact on float64 geometry (tests/tin); here the float32
    # corners scatter the dips by ~0.01 degrees about 30, so the threshold at 30
    # degrees falls just below theta*max and C moves off 0 a little
    np.testing.assert_allclose(cols["theta_max_c1"], expected, rtol=0.05, atol=2e-3)
    # profiles along x cross the teeth: their Z2 is tan(30) (the RMS slope), their RMS
    # that of a triangle wave 1 mm high sampled at quarter flanks (heights 0, 1/4, ...,
    # 1: sqrt(3/32) mm); profiles along the ridges are flat
    assert cols["profiles"][0] > 20
    assert cols["z2_mean"][0] == pytest.approx(math.tan(math.radians(30)), rel=0.03)
    assert cols["rms_mean"][0] == pytest.approx(math.sqrt(3 / 32), rel=0.02)
    assert cols["rms_mean"][6] < 1e-3 and cols["z2_mean"][6] < 1e-3
    # the numbers are those of the API, in mm where they are lengths
    cloud = load_points(sawtooth_stl, units="mm")
    from rough_viewer.io.formats.mesh import load_mesh

    settings = DirectionSettings(step_deg=15.0, sample_spacing=float(step) * 1e-3)
    api = directions_table(analyse_directions(cloud, settings,
                                              mesh=load_mesh(sawtooth_stl, units="mm")),
                           unit="mm")
    assert head[-1] == "unit_m" and np.all(cols["unit_m"] == 0.001)  # the file says: mm
    for name in head[:-1]:
        np.testing.assert_allclose(cols[name], api[name], rtol=1e-12, equal_nan=True)


def test_cloud_is_triangulated_and_windows_written(tmp_path, capsys):
    """A cloud (.npy, metres) has no triangles of its own: the command triangulates it
    in its plane; the window map has one row per window and azimuth."""
    z = fbm_surface((120, 120), 0.6, spacing=0.002, rms=0.003, rng=3)
    yy, xx = np.mgrid[0:120, 0:120] * 0.002
    path = tmp_path / "face.npy"
    np.save(path, np.column_stack([xx.ravel(), yy.ravel(), z.ravel()]))
    out, win = tmp_path / "d.csv", tmp_path / "w.csv"
    code = main(["directions", str(path), "--step", "45", "--out", str(out), "--windows-out",
                 str(win), "--window-radius", "0.04", "--window-step", "0.05", "--quiet",
                 "--windows", "0.01,0.02,0.04"])
    text = capsys.readouterr().out
    assert code == 0 and "triangulated in its plane" in text
    head, cols = read_csv(out)
    assert head[:11] == CONTRACT + ["delta_t"] and cols["azimuth_deg"].size == 8
    assert np.all(np.isfinite(cols["delta_t"])) and np.all(cols["profiles"] > 0)
    whead, wcols = read_csv(win)
    assert whead == ["cx", "cy", "cz", "area", "azimuth_deg", "delta_t", "theta_max_c1",
                     "unit_m"] and np.all(wcols["unit_m"] == 1.0)
    n_win = wcols["cx"].size // 8
    assert n_win >= 4 and wcols["cx"].size == 8 * n_win
    np.testing.assert_array_equal(wcols["azimuth_deg"][:8], np.arange(0, 360, 45.0))
    # a window of radius 4 cm covers about pi (4 cm)^2 of this gentle surface
    assert np.all(wcols["area"] > 0.5 * math.pi * 0.04**2)
    assert np.all(wcols["area"] < 1.2 * math.pi * 0.04**2)


def test_units_scale_every_length(sawtooth_stl, tmp_path, capsys):
    """The same file read in mm and in m (as if its numbers were metres): H, Z2, JRC
    and the angles do not change, the RMS is 1000 times smaller in the m run's unit
    (each read in its own unit)."""
    a, b = tmp_path / "mm.csv", tmp_path / "m.csv"
    assert main(["directions", str(sawtooth_stl), "--step", "90", "--units", "mm", "--out",
                 str(a), "--quiet", "--spacing", "2", "--half-width", "0.25"]) == 0
    assert main(["directions", str(sawtooth_stl), "--step", "90", "--units", "m", "--out",
                 str(b), "--quiet", "--spacing", "2", "--half-width", "0.25"]) == 0
    capsys.readouterr()
    _, mm = read_csv(a)
    _, m = read_csv(b)
    # (scaling by 1e-3 rounds: the numbers agree to round-off of the fits)
    for name in ("h_mean", "z2_mean", "delta_t", "theta_max_c1"):
        np.testing.assert_allclose(mm[name], m[name], rtol=1e-6, equal_nan=True)
    np.testing.assert_allclose(mm["rms_mean"], m["rms_mean"], rtol=1e-6)


@pytest.mark.parametrize("extra, needle", [
    (["--window-radius", "1"], "--windows-out"),
    (["--windows", "2"], "--windows"),
    (["--step", "400"], "at most 360"),
    (["--step", "1e-300"], "--step must be from 1 to"),  # issue 36: a traceback
    (["--step", "0.01"], "--step must be from 1 to"),  # issue 36: about an hour of work
])
def test_bad_options_are_one_line_errors(sawtooth_stl, tmp_path, capsys, extra, needle):
    out = tmp_path / "d.csv"
    args = ["directions", str(sawtooth_stl), "--step", "15", "--out", str(out), *extra]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert needle in err and len(err.strip().splitlines()) == 1 and not out.exists()


def test_existing_output_and_missing_input(sawtooth_stl, tmp_path, capsys):
    out = tmp_path / "d.csv"
    out.write_text("keep\n")
    assert main(["directions", str(sawtooth_stl), "--step", "90", "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err and out.read_text() == "keep\n"
    assert main(["directions", str(tmp_path / "nope.stl"), "--step", "90", "--out",
                 str(tmp_path / "x.csv")]) == 2
    assert "not found" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["directions", str(sawtooth_stl), "--out", str(tmp_path / "y.csv")])  # no --step


@pytest.mark.parametrize("extra", [
    ["--sample-spacing", "1e300"], ["--min-samples", "1000000000000"], ["--windows", "1e-9,1e-8"],
])
def test_settings_that_measure_no_profile_are_said_not_silent(
        sawtooth_stl, tmp_path, capsys, extra):
    """Issue 36: each of these wrote a table whose every direction had 0 profiles, exit 0,
    without a word (on the sawtooth's vertices as a point cloud: bands of points make
    the profiles). The triangles still measure every direction, so the table stays,
    with one warning line saying why no profile was measured."""
    from rough_viewer.io import load_points

    cloud = load_points(sawtooth_stl, units="mm")
    src = tmp_path / "saw.npy"
    np.save(src, cloud.xyz() * 1e3)
    out = tmp_path / "d.csv"
    assert main(["directions", str(src), "--units", "mm", "--step", "45", "--out", str(out),
                 "--quiet", *extra]) == 0
    err = capsys.readouterr().err
    assert "could be measured in any direction" in err and "profile lines;" in err
    assert "the table holds the triangles' columns only" in err
    assert len(err.strip().splitlines()) == 1 and out.exists()


def test_a_profile_too_long_for_memory_is_refused_with_the_figure(
        sawtooth_stl, tmp_path, capsys, monkeypatch):
    """Issue 36 item 6: directions --sample-spacing had no check per profile (1e-7 on
    the demo: 5.4 GB in 19 s, then a traceback). A 41.6 mm face sampled every
    1e-8 mm makes profiles of about 4e9 samples: refused in one line with the
    figure, no output; the vertices' spacing still runs with 64 MiB available."""
    from rough_viewer import memory

    out = tmp_path / "d.csv"
    args = ["directions", str(sawtooth_stl), "--step", "90", "--units", "mm",
            "--out", str(out), "--quiet"]
    assert main([*args, "--sample-spacing", "1e-8"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err and not out.exists()
    assert "a profile of 4,1" in err and "samples at 1e-11 m" in err and "needs about" in err
    monkeypatch.setattr(memory, "available_bytes", lambda: 64.0 * 2**20)
    step = str(1 / math.tan(math.radians(30.0)) / 4)
    assert main([*args, "--sample-spacing", step]) == 0 and out.exists()


@pytest.mark.parametrize("extra, windows", [
    (["--window-radius", "0.01"], "12,4"),  # the step defaults to the radius
    (["--window-radius", "5", "--window-step", "0.01"], "12,4"),
])
def test_window_map_work_is_estimated_and_refused_with_the_figure(
        sawtooth_stl, tmp_path, capsys, extra, windows):
    """Issue 36 item 10: --window-radius 0.001 ran 66 s to 3.1 GB and then failed,
    --window-step 0.001 was days of work. On the 41.6 x 30 mm sawtooth a step of
    0.01 mm lays about 4,160 x 3,000 window centres: at 24 azimuths and 91 dip
    thresholds (about 0.55 ms each window and azimuth) that is far beyond the
    limit, refused at once in one line naming windows, azimuths and minutes."""
    from rough_viewer.tin.directional import window_map_seconds

    out, win = tmp_path / "d.csv", tmp_path / "w.csv"
    code = main(["directions", str(sawtooth_stl), "--step", "15", "--units", "mm",
                 "--out", str(out), "--windows-out", str(win), "--quiet", *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists() and not win.exists()
    assert f"a window map of {windows}" in err and "at 24 azimuths" in err
    n = float(err.split("a window map of ")[1].split()[0].replace(",", ""))
    assert 4150 * 2990 < n <= 4161 * 3001
    assert window_map_seconds(n, 1.0, 24, 1.0) > 30 * 60
    assert "minutes of work, more than the 30 allowed" in err
