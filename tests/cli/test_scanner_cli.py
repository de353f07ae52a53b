"""The scanner options of compute, report and serve: CELLS.csv's scanner columns, the
LAS/PLY fields, the report's section, and one-line errors."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from rough_viewer.cli import build_parser, main
from rough_viewer.cli.compute import CSV_COLUMNS
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.table import TRUST_COLUMNS
from rough_viewer.io import load_points, read_las_extra
from rough_viewer.scanner.positions import NO_POSITIONS, with_scanner
from rough_viewer.scanner.trust import TrustSettings, cell_trust
from tests.helpers import ray_grid, scan_plane

SCANNER = np.array([2.0, -1.0, 1.5])
STEP_DEG = 0.1


@pytest.fixture(scope="module")
def wall_las(tmp_path_factory):
    """A wall 9 m from a scanner at (2, -1, 1.5), as a LAS with point source ids 4."""
    import laspy

    centre = np.array([2.5, 8.0, 1.5])
    rays = ray_grid(SCANNER, centre, 0.12, step=np.radians(STEP_DEG))
    pts = scan_plane(SCANNER, centre, np.array([0.2, -1.0, 0.1]) / np.sqrt(1.05), rays,
                     extent=1.0, noise=0.002, seed=2)
    path = tmp_path_factory.mktemp("wall") / "wall.las"
    hdr = laspy.LasHeader(point_format=6, version="1.4")
    hdr.offsets = np.floor(pts.min(axis=0))
    hdr.scales = np.array([1e-5] * 3)
    las = laspy.LasData(hdr)
    las.x, las.y, las.z = pts.T
    las.point_source_id = np.full(len(pts), 4, np.uint16)
    las.write(str(path))
    return path


def _rows(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_compute_fills_the_scanner_columns(wall_las, tmp_path, capsys):
    out = tmp_path / "cells.csv"
    assert main(["compute", str(wall_las), "--grid", "0.25", "--out", str(out),
                 "--scanner", "2,-1,1.5", "--angular-step", str(STEP_DEG), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "scanner: " in text and "trusted" in text
    header, rows = _rows(out)
    assert tuple(header) == CSV_COLUMNS and tuple(header[-10:-1]) == TRUST_COLUMNS
    # the same numbers as the science on the same cloud
    cloud = with_scanner(load_points(wall_las), SCANNER)
    res = grid_roughness(cloud, 0.25)
    trust = cell_trust(cloud, res, TrustSettings(angular_step_rad=np.radians(STEP_DEG)))
    keep = res.n_points >= res.min_points
    assert len(rows) == keep.sum()
    col = {name: header.index(name) for name in TRUST_COLUMNS}
    rng = np.array([float(r[col["range"]]) for r in rows])
    np.testing.assert_array_equal(rng, trust.geometry.range_m[keep])
    assert {r[col["scans"]] for r in rows} == {"1"}
    assert {r[col["trusted"]] for r in rows} <= {"0", "1"}
    inc = np.array([float(r[col["incidence_deg"]]) for r in rows])
    assert 10 < np.median(inc) < 20  # the wall turned ~11 degrees, seen slightly askew
    dens = np.array([float(r[col["density_ratio"]]) for r in rows])
    assert np.median(dens) == pytest.approx(1.0, abs=0.03)


def test_compute_without_positions_leaves_them_empty(wall_las, tmp_path, capsys):
    out = tmp_path / "cells.csv"
    assert main(["compute", str(wall_las), "--grid", "0.25", "--out", str(out), "--quiet"]) == 0
    assert NO_POSITIONS in capsys.readouterr().out
    header, rows = _rows(out)
    for name in TRUST_COLUMNS:
        assert {r[header.index(name)] for r in rows} == {""}


def test_scanners_table_and_las_ply_fields(wall_las, tmp_path, capsys):
    table = tmp_path / "scanners.csv"
    table.write_text("point_source_id,x,y,z\n4,2,-1,1.5\n")
    las_out, ply_out = tmp_path / "out.laz", tmp_path / "out.ply"
    assert main(["compute", str(wall_las), "--grid", "0.25", "--scanners", str(table),
                 "--las-out", str(las_out), "--ply-out", str(ply_out), "--quiet",
                 "--noise", "0.002", "--beam-radius", "0.003"]) == 0
    capsys.readouterr()
    cloud = with_scanner(load_points(wall_las), SCANNER)
    res = grid_roughness(cloud, 0.25)
    from rough_viewer.bias.calibration import calibration

    trust = cell_trust(cloud, res, TrustSettings(calibration=calibration(
        noise_sigma_m=0.002, effective_radius_m=0.003)))
    rng = read_las_extra(las_out, "range")
    np.testing.assert_allclose(rng, trust.geometry.range_m[res.point_cell].astype(np.float32))
    noise = read_las_extra(las_out, "noise_pred")
    np.testing.assert_allclose(noise, trust.noise_pred_m[res.point_cell].astype(np.float32))
    trusted = read_las_extra(las_out, "trusted")
    want = np.where(trust.known, trust.flags == 0, -1).astype(np.int8)[res.point_cell]
    np.testing.assert_array_equal(trusted, want)
    from plyfile import PlyData

    v = PlyData.read(str(ply_out))["vertex"]
    for name in TRUST_COLUMNS:
        assert name in v.data.dtype.names
    np.testing.assert_array_equal(v["scans"], np.ones(cloud.n))


def test_report_has_a_scanner_section(wall_las, tmp_path, capsys):
    out = tmp_path / "r.html"
    assert main(["report", str(wall_las), "--grid", "0.25", "--out", str(out),
                 "--scanner", "2,-1,1.5", "--quiet"]) == 0
    page = out.read_text()
    assert "<h3>Scanner</h3>" in page and 'data-figure="scanner_map"' in page
    assert "range noise 1.6 mm (the bias paper" in page
    js = tmp_path / "r.json"
    assert main(["report", str(wall_las), "--grid", "0.25", "--out", str(js), "--format",
                 "json", "--scanner", "2,-1,1.5", "--quiet"]) == 0
    data = json.loads(js.read_text())
    scanner = data["grids"][0]["scanner"]
    assert data["scanner_note"] is None
    assert scanner["cells"] > 10 and scanner["scans"] == {"1": scanner["cells"]}
    assert scanner["range"]["median"] == pytest.approx(9.1, abs=0.3)
    # the fitted N0 recovers the scanner's angular step
    assert scanner["angular_step_deg"][0] == pytest.approx(STEP_DEG, rel=0.03)
    assert main(["report", str(wall_las), "--grid", "0.25", "--out", str(js), "--format",
                 "json", "--quiet", "--force"]) == 0
    data = json.loads(js.read_text())
    assert data["scanner_note"] == NO_POSITIONS and data["grids"][0]["scanner"] is None
    capsys.readouterr()


@pytest.mark.parametrize(("extra", "message"), [
    (["--noise", "-1"], "--noise must be a length >= 0"),
    (["--beam-radius", "2"], "--beam-radius must be a length"),
    (["--asperity-radius", "0"], "--asperity-radius must be a length > 0"),
    (["--angular-step", "0"], "--angular-step must be above 0"),
    (["--angular-step", "1e-300"], "at least 1e-06"),  # issue 36: ZeroDivisionError
    (["--calibration", "absent.json"], "calibration file not found"),
    (["--scanner", "1,2"], "--scanner expects three finite numbers"),
    (["--scanner", "1e308,0,0"], "reaches beyond 1e+09 m"),  # issue 36: was accepted
    (["--scanners", "absent.csv"], "scanner table not found"),
    (["--scanner", "1,2,3", "--memory", "1GB"], "--memory and --scheduler do not keep"),
])
def test_bad_scanner_options_exit_2_with_one_line(wall_las, tmp_path, capsys, extra, message):
    assert main(["compute", str(wall_las), "--grid", "0.25", "--out", str(tmp_path / "c.csv"),
                 "--quiet", *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "c.csv").exists()


def test_scanners_on_a_cloud_without_ids_is_one_line(tmp_path, capsys):
    np.save(tmp_path / "p.npy", np.random.default_rng(0).uniform(0, 1, (100, 3)))
    (tmp_path / "s.csv").write_text("1,0,0,0\n")
    assert main(["compute", str(tmp_path / "p.npy"), "--grid", "0.5", "--out",
                 str(tmp_path / "c.csv"), "--scanners", str(tmp_path / "s.csv"),
                 "--quiet"]) == 2
    assert "carries no point_source_id" in capsys.readouterr().err


def test_serve_puts_the_positions_into_its_cloud(wall_las):
    from rough_viewer.cli.serve import _load_cloud

    args = build_parser().parse_args(["serve", str(wall_las), "--scanner", "2,-1,1.5"])
    cloud = _load_cloud(args)
    np.testing.assert_allclose(cloud.scanner_positions, SCANNER[None, :])
    assert cloud.scan_index.shape == (cloud.n,)
    demo = _load_cloud(build_parser().parse_args(["serve", "--demo", "outcrop-small"]))
    np.testing.assert_allclose(demo.scanner_positions, [[5.0, -10.0, 1.6]])
    bad = build_parser().parse_args(["serve", "--demo", "board", "--scanners", "s.csv"])
    with pytest.raises(Exception, match="--scanners needs INPUT files"):
        _load_cloud(bad)
    assert main(["serve", str(wall_las), "--noise", "-1", "--no-block"]) == 2


def test_a_scanner_table_beyond_the_coordinate_limit_is_one_line(wall_las, tmp_path, capsys):
    """Issue 36: a position of 1e308 m was accepted (incidence 90, bias 0 printed)."""
    table = tmp_path / "s.csv"
    table.write_text("point_source_id,x,y,z\n1,0,0,1e308\n")
    assert main(["compute", str(wall_las), "--grid", "0.25", "--out", str(tmp_path / "c.csv"),
                 "--quiet", "--scanners", str(table)]) == 2
    err = capsys.readouterr().err
    assert "s.csv line 2: the position reaches beyond 1e+09 m" in err and err.count("\n") == 1
    assert not (tmp_path / "c.csv").exists()


@pytest.mark.parametrize("sid", ["inf", "nan", "-inf"])
def test_a_scanner_table_with_an_id_that_is_no_number_is_one_line(wall_las, tmp_path, capsys,
                                                                 sid):
    """Issue 36: ids inf and nan ended in OverflowError / ValueError tracebacks."""
    table = tmp_path / "s.csv"
    table.write_text(f"point_source_id,x,y,z\n{sid},0,0,1\n")
    assert main(["compute", str(wall_las), "--grid", "0.25", "--out", str(tmp_path / "c.csv"),
                 "--quiet", "--scanners", str(table)]) == 2
    err = capsys.readouterr().err
    assert "s.csv line 2: point_source_id must be a whole number from 0 to" in err
    assert err.count("\n") == 1 and "Traceback" not in err
