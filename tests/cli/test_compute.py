"""`rough-viewer compute`: the output contract and the bad-input errors."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.cli.compute import CSV_COLUMNS
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.summary import summarise
from rough_viewer.io import PointCloud, write_las
from tests.helpers import rough_surface


@pytest.fixture
def cloud_file(tmp_path):
    xyz = rough_surface(4000, seed=12, size=2.0)[:, [0, 2, 1]] + [500_000.0, 20.0, 4_000_000.0]
    path = tmp_path / "face.npy"
    np.save(path, xyz)
    return path, xyz


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_csv_and_json_contract(tmp_path, cloud_file, capsys):
    path, xyz = cloud_file
    out, js = tmp_path / "cells.csv", tmp_path / "summary.json"
    assert main(["compute", str(path), "--grid", "0.5", "--out", str(out),
                 "--summary-json", str(js), "--quiet"]) == 0
    header, rows = read_csv(out)
    assert tuple(header) == CSV_COLUMNS
    ref = grid_roughness(xyz, 0.5)
    keep = ref.n_points >= 3
    assert len(rows) == keep.sum()
    by_key = {tuple(r[:3]): r for r in rows}
    for i in np.flatnonzero(keep):
        r = by_key[tuple(str(v) for v in ref.ijk[i])]
        assert int(r[6]) == ref.n_points[i]
        for col, val in (("cx", ref.centre[i, 0]), ("theta_odr", ref.theta_odr[i]),
                         ("theta_ols", ref.theta_ols[i]), ("theta_hybrid", ref.theta_hybrid[i]),
                         ("e_ols", ref.e_ols[i]), ("normal_z", ref.normal[i, 2])):
            text = r[CSV_COLUMNS.index(col)]
            if np.isnan(val):
                assert text == ""
            else:
                assert float(text) == val  # full precision: exact round trip
    data = json.loads(js.read_text())
    assert data["axis"] == "y" and data["axis_requested"] == "auto"
    assert data["grid_size"] == 0.5 and data["points"] == len(xyz)
    np.testing.assert_allclose(data["origin"], xyz.min(axis=0))
    for name in ("odr", "ols", "hybrid", "e_ols"):
        s = summarise(ref, name)
        assert set(data[name]) == {"cells", "mean_points", "min", "max", "mean", "variance", "std",
                                   "outliers"}
        assert data[name]["cells"] == s.cells
        assert data[name]["std"] == pytest.approx(s.std, rel=1e-12)
    text = capsys.readouterr().out
    assert "ODR" in text and "OLS" in text and "hybrid" in text and "dependent axis y (auto)" in text


def test_several_grids_one_method_and_signed(tmp_path, cloud_file):
    path, xyz = cloud_file
    out = tmp_path / "cells.csv"
    assert main(["compute", str(path), "--grid", "1", "--grid", "0.25", "--method", "ols",
                 "--axis", "z", "--signed", "--origin", "499999,19,3999999",
                 "--out", str(out), "--summary-json", str(tmp_path / "s.json"), "--quiet"]) == 0
    for g in ("1", "0.25"):
        header, rows = read_csv(tmp_path / f"cells_g{g}.csv")
        assert all(r[CSV_COLUMNS.index("theta_odr")] == "" for r in rows)
        assert any(r[CSV_COLUMNS.index("theta_ols")] != "" for r in rows)
        data = json.loads((tmp_path / f"s_g{g}.json").read_text())
        ref = grid_roughness(xyz, float(g), origin=[499999, 19, 3999999], axis="z",
                             models=("ols",), residual="signed")
        assert data["ols"]["mean"] == pytest.approx(summarise(ref, "ols").mean, rel=1e-12)
        assert data["odr"]["cells"] == 0 and data["odr"]["mean"] is None
    assert not out.exists()


def test_las_input_with_nan_rows_reports_dropped(tmp_path, capsys):
    xyz = rough_surface(500, seed=2)
    xyz[5] = np.nan
    np.save(tmp_path / "n.npy", xyz)
    assert main(["compute", str(tmp_path / "n.npy"), "--grid", "1", "--out",
                 str(tmp_path / "o.csv"), "--quiet"]) == 0
    assert "dropped 1 points" in capsys.readouterr().err
    write_las(tmp_path / "c.laz", PointCloud.from_xyz(rough_surface(500, seed=3)))
    assert main(["compute", str(tmp_path / "c.laz"), "--grid", "1", "--out",
                 str(tmp_path / "l.csv"), "--quiet"]) == 0


def bad_cases(tmp_path, good):
    (tmp_path / "exists.csv").write_text("keep me\n")
    (tmp_path / "empty.xyz").write_text("")
    (tmp_path / "two.xyz").write_text("0 0 0\n1 1 1\n")
    return {
        "missing file": (["compute", str(tmp_path / "nope.laz"), "--grid", "1"], "file not found"),
        "unknown extension": (["compute", str(tmp_path / "exists.csv.bak"), "--grid", "1"], "unknown file type"),
        "empty cloud": (["compute", str(tmp_path / "empty.xyz"), "--grid", "1"], "no points"),
        "two points": (["compute", str(tmp_path / "two.xyz"), "--grid", "1"], "at least 3"),
        "grid zero": (["compute", str(good), "--grid", "0"], "positive"),
        "grid negative": (["compute", str(good), "--grid", "-1"], "positive"),
        "grid tiny": (["compute", str(good), "--grid", "1e-300"], "cells"),
        "missing folder": (["compute", str(good), "--grid", "1", "--out", str(tmp_path / "no" / "c.csv")], "folder does not exist"),
        "existing output": (["compute", str(good), "--grid", "1", "--out", str(tmp_path / "exists.csv")], "exists"),
        "bad origin": (["compute", str(good), "--grid", "1", "--origin", "1,2"], "--origin"),
        "min points": (["compute", str(good), "--grid", "1", "--min-points", "2"], "at least 3"),
    }


@pytest.mark.parametrize("case", ["missing file", "unknown extension", "empty cloud", "two points",
                                  "grid zero", "grid negative", "grid tiny", "missing folder",
                                  "existing output", "bad origin", "min points"])
def test_bad_input_one_line_exit_2_no_output(tmp_path, cloud_file, capsys, case):
    good, _ = cloud_file
    argv, message = bad_cases(tmp_path, good)[case]
    if "--out" not in argv:
        argv = [*argv, "--out", str(tmp_path / "out.csv")]
    before = sorted(os.listdir(tmp_path))
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err
    assert sorted(os.listdir(tmp_path)) == before  # nothing written
    assert (tmp_path / "exists.csv").read_text() == "keep me\n"


def test_console_script_exit_status_and_no_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "rough_viewer", "compute", str(tmp_path / "x.las"),
                           "--grid", "1", "--out", str(tmp_path / "o.csv")],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"rough-viewer: error: file not found: {tmp_path / 'x.las'}"


def test_parquet_cell_table_equals_csv(tmp_path, cloud_file):
    pq = pytest.importorskip("pyarrow.parquet")
    path, _ = cloud_file
    csv_out, pq_out = tmp_path / "cells.csv", tmp_path / "cells.parquet"
    assert main(["compute", str(path), "--grid", "0.5", "--out", str(csv_out), "--quiet"]) == 0
    assert main(["compute", str(path), "--grid", "0.5", "--out", str(pq_out), "--quiet"]) == 0
    header, rows = read_csv(csv_out)
    table = pq.read_table(pq_out)
    assert table.column_names == header and table.num_rows == len(rows)
    for k, name in enumerate(header):
        col = table.column(name).to_pylist()
        for text, value in zip((r[k] for r in rows), col, strict=True):
            assert (text == "" and value is None) or float(text) == value


# ----------------------------------------------------------------------------- units


def test_units_mm_give_the_same_cells_in_millimetres(tmp_path, cloud_file, capsys):
    path, xyz = cloud_file
    mm_path = tmp_path / "face_mm.npy"
    np.save(mm_path, xyz * 1000.0)
    a, b = tmp_path / "m.csv", tmp_path / "mm.csv"
    ja, jb = tmp_path / "m.json", tmp_path / "mm.json"
    assert main(["compute", str(path), "--grid", "0.5", "--out", str(a), "--summary-json",
                 str(ja), "--quiet"]) == 0
    assert main(["compute", str(mm_path), "--units", "mm", "--grid", "500", "--out", str(b),
                 "--summary-json", str(jb), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "grid 500 mm" in out and "std (mm)" in out
    head, rows_m = read_csv(a)
    _, rows_mm = read_csv(b)
    assert len(rows_m) == len(rows_mm)
    m = np.array([[float(v) if v else np.nan for v in r] for r in rows_m])
    mm = np.array([[float(v) if v else np.nan for v in r] for r in rows_mm])
    lengths = [head.index(c) for c in ("cx", "cy", "cz", "theta_odr", "theta_ols",
                                       "theta_hybrid", "e_ols")]
    np.testing.assert_allclose(mm[:, lengths], 1000.0 * m[:, lengths], rtol=1e-9, atol=1e-9)
    sm, smm = json.loads(ja.read_text()), json.loads(jb.read_text())
    assert smm["unit"] == "mm" and smm["grid_size"] == 500.0
    assert smm["odr"]["mean"] == pytest.approx(1000.0 * sm["odr"]["mean"], rel=1e-9)
    assert smm["odr"]["variance"] == pytest.approx(1e6 * sm["odr"]["variance"], rel=1e-9)


def _las_in_feet(path, xyz_ft, *, unit_code: int):
    import laspy

    words = [1, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 2227, 3076, 0, 1, unit_code]
    hdr = laspy.LasHeader(point_format=3, version="1.2")
    hdr.scales = np.array([1e-3] * 3)
    hdr.offsets = np.floor(xyz_ft.min(axis=0))
    hdr.vlrs.append(laspy.VLR("LASF_Projection", 34735, "", np.array(words, "<u2").tobytes()))
    las = laspy.LasData(hdr)
    las.x, las.y, las.z = xyz_ft.T
    las.write(str(path))


def test_las_crs_in_us_feet_sets_the_unit_and_a_contradiction_warns(tmp_path, cloud_file,
                                                                     capsys):
    path, xyz = cloud_file
    per = 1200.0 / 3937.0
    las = tmp_path / "feet.las"
    _las_in_feet(las, np.round(xyz / per, 3), unit_code=9003)
    js = tmp_path / "s.json"
    assert main(["compute", str(las), "--grid", str(0.5 / per), "--out",
                 str(tmp_path / "c.csv"), "--summary-json", str(js), "--quiet"]) == 0
    s = json.loads(js.read_text())
    assert s["unit"] == "us-ft" and s["warnings"] == []
    ref = grid_roughness(np.round(xyz / per, 3) * per, 0.5)
    assert s["odr"]["mean"] * per == pytest.approx(summarise(ref, "odr").mean, rel=1e-6)
    capsys.readouterr()
    assert main(["compute", str(las), "--units", "m", "--grid", "0.5", "--out",
                 str(tmp_path / "c2.csv"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "contradicts the CRS" in err and "feet.las" in err


def test_grid_messages_name_the_unit(tmp_path, cloud_file, capsys):
    good, _ = cloud_file
    base = ["compute", str(good), "--units", "mm", "--out", str(tmp_path / "o.csv"), "--quiet"]
    assert main([*base, "--grid", "0"]) == 2
    assert capsys.readouterr().err.strip() == (
        "rough-viewer: error: --grid must be a positive length in mm, got 0")
    assert main([*base, "--grid", "1e-12"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rough-viewer: error: --grid 1e-12 mm: grid size 1e-15 m would take")
    assert main(["compute", str(good), "--grid", "-1", "--out", str(tmp_path / "o.csv")]) == 2
    assert capsys.readouterr().err.strip().endswith("positive length in m, got -1")
    assert not (tmp_path / "o.csv").exists()


def test_failed_second_grid_leaves_no_output(tmp_path, cloud_file, capsys):
    good, _ = cloud_file
    out = tmp_path / "out"
    out.mkdir()
    assert main(["compute", str(good), "--grid", "1", "--grid", "1e-300", "--out",
                 str(out / "c.csv"), "--summary-json", str(out / "s.json"), "--quiet"]) == 2
    assert "would take" in capsys.readouterr().err
    assert os.listdir(out) == []  # not c_g1.csv, not s_g1.json


def test_folder_input_says_folder(tmp_path, capsys):
    (tmp_path / "scans.laz").mkdir()
    for folder in (tmp_path, tmp_path / "scans.laz"):
        assert main(["compute", str(folder), "--grid", "1", "--out",
                     str(tmp_path / "o.csv")]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"rough-viewer: error: {folder} is a folder, not a point file")


def test_cells_of_repeated_points_are_explained(tmp_path, capsys):
    """A cloud that repeats its points (as the airborne LAZ does: 49,954 of 574,092)
    has cells of roughness 0; the summary says how many and why."""
    from tests.helpers import repeated_points_cloud

    path = tmp_path / "dup.npy"
    np.save(path, repeated_points_cloud())
    assert main(["compute", str(path), "--grid", "1", "--out", str(tmp_path / "c.csv"),
                 "--origin", "0,0,0", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "note: 3 of 6 cells with a value fit their plane exactly" in out
    assert "repeats points" in out


def test_hybrid_larger_than_the_cell_is_an_outlier(tmp_path, capsys):
    """A vertical face read with z as the dependent axis: hybrid (the distance along
    z to the ODR plane) exceeds the cell where the cell's plane is nearly vertical.
    Those cells are named, marked in the CSV's outlier column (bit 2) with their value
    kept, and left out of Table 1 unless --keep-outliers."""
    rng = np.random.default_rng(4)
    n = 4000
    x, z = rng.uniform(0, 2, n), rng.uniform(0, 2, n)
    lean = np.where(x >= 1.0, 0.5 * z, 0.0)  # the wall's right half leans back 27 degrees
    xyz = np.column_stack([x, lean + 0.003 * rng.standard_normal(n), z])
    path = tmp_path / "wall.npy"
    np.save(path, xyz)
    out, js = tmp_path / "c.csv", tmp_path / "s.json"
    assert main(["compute", str(path), "--grid", "0.5", "--axis", "z", "--out", str(out),
                 "--summary-json", str(js), "--quiet"]) == 0
    text = capsys.readouterr().out
    table = np.genfromtxt(out, delimiter=",", names=True)
    hybrid = table["theta_hybrid"]
    steep = hybrid > 0.5
    assert 0 < steep.sum() < np.isfinite(hybrid).sum()
    assert f"note: {steep.sum():,} of {np.isfinite(hybrid).sum():,} cells with a hybrid value " \
        "have a hybrid roughness larger than the cell" in text
    np.testing.assert_array_equal(table["outlier"], np.where(steep, 2, 0))  # OLS <= g / 2
    data = json.loads(js.read_text())
    kept = hybrid[np.isfinite(hybrid) & ~steep]
    assert data["hybrid"]["cells"] == kept.size and data["hybrid"]["outliers"] == steep.sum()
    assert data["hybrid"]["max"] == pytest.approx(kept.max(), rel=1e-12)
    assert data["keep_outliers"] is False
    assert main(["compute", str(path), "--grid", "0.5", "--axis", "z", "--summary-json",
                 str(js), "--keep-outliers", "--force", "--quiet"]) == 0
    data = json.loads(js.read_text())
    assert data["hybrid"]["max"] == pytest.approx(np.nanmax(hybrid), rel=1e-12)
    assert data["hybrid"]["outliers"] == 0 and data["keep_outliers"] is True
    assert "kept in every statistic, as asked" in capsys.readouterr().out


def test_a_grid_with_no_valued_cell_says_so_and_writes_nothing(tmp_path, capsys):
    """An airborne-like spacing (0.2 m) at a 1 cm grid: every cell holds one point. One
    line with the smallest grid at which the typical cell has enough points (against
    the spacing module), exit 2, no empty CSV."""
    from rough_viewer.grid.spacing import default_cell_size

    rng = np.random.default_rng(3)
    xyz = np.column_stack([rng.uniform(0, 10, 2500), rng.uniform(0, 10, 2500),
                           0.05 * rng.standard_normal(2500)])
    path = tmp_path / "sparse.npy"
    np.save(path, xyz)
    out = tmp_path / "c.csv"
    assert main(["compute", str(path), "--grid", "0.01", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    smallest = default_cell_size(xyz, target=4)
    assert "\n" not in err and err.startswith("rough-viewer: error: --grid 0.01 m: no cell has a "
                                              "value: the 2,500 points fall into 2,500 occupied")
    assert f"the smallest grid at which the typical cell holds 4 points is about {smallest:g} m" \
        in err
    assert not out.exists()
    assert main(["compute", str(path), "--grid", f"{smallest:g}", "--out", str(out),
                 "--quiet"]) == 0


def test_a_four_point_e57_says_why_no_cell_has_a_value(tmp_path, capsys):
    """Issue 31: a 4-point E57 with --grid 0.1 said "need more than 4 points to estimate
    the point spacing" (the hint's figure), though the grid was given; --grid 5 computes."""
    pye57 = pytest.importorskip("pye57")
    path = tmp_path / "four.e57"
    e57 = pye57.E57(str(path), mode="w")
    e57.write_scan_raw({"cartesianX": np.array([0.0, 1.0, 0.0, 1.0]),
                        "cartesianY": np.array([0.0, 0.0, 1.0, 1.0]),
                        "cartesianZ": np.array([0.0, 0.01, 0.02, 0.0])})
    e57.close()
    out = tmp_path / "c.csv"
    assert main(["compute", str(path), "--grid", "0.1", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "no cell has a value: the 4 points fall into 4 occupied cells" in err
    assert "use a larger --grid" in err and "point spacing" not in err and not out.exists()
    assert main(["compute", str(path), "--grid", "5", "--out", str(out), "--quiet"]) == 0


def test_compute_without_grid_takes_the_point_spacings_as_report_and_serve(tmp_path, capsys):
    """Issue 31: compute needed --grid where report and serve choose one. Left out, the
    grid is default_cell_size's (said on stderr): the same cells as --grid of that size."""
    from rough_viewer.grid.spacing import default_cell_size
    from tests.helpers import rough_surface

    xyz = rough_surface(20_000, seed=3, size=4.0)
    src = tmp_path / "face.npy"
    np.save(src, xyz)
    g = default_cell_size(xyz)
    auto, given = tmp_path / "auto.csv", tmp_path / "given.csv"
    assert main(["compute", str(src), "--out", str(auto)]) == 0
    assert f"rough-viewer: grid {g:g} m from the point spacing" in capsys.readouterr().err
    assert main(["compute", str(src), "--grid", f"{g:g}", "--out", str(given), "--quiet"]) == 0
    assert auto.read_text() == given.read_text()
    assert main(["compute", str(src), "--memory", "1GB", "--out", str(tmp_path / "x.csv")]) == 2
    assert "give --grid with --memory or --scheduler" in capsys.readouterr().err


@pytest.mark.parametrize("chunked", [False, True], ids=["in memory", "chunked"])
def test_max_points_reaches_every_read(tmp_path, capsys, chunked):
    """Issue 32 item 5: --max-points is passed down with the reads (no module global):
    the bomb guard refuses a small LAZ declaring 3 M points by default and lets it
    through with --max-points, in memory and chunk by chunk."""
    from tests.io.crafted import laz_declaring

    bomb = laz_declaring(tmp_path / "bomb.laz", 3_000_000)
    extra = ["--memory", "256MB"] if chunked else []
    argv = ["compute", str(bomb), "--grid", "0.5", "--out", str(tmp_path / "c.csv"), *extra]
    assert main(argv) == 2
    assert "decompression bomb" in capsys.readouterr().err
    main([*argv, "--max-points", "5000000"])
    assert "decompression bomb" not in capsys.readouterr().err
