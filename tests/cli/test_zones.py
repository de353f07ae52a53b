"""`rough-viewer zones`: the output contract, the options and the bad-input errors."""

from __future__ import annotations

import csv
import os
import subprocess
import sys

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.cli.compute import CSV_COLUMNS
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud, write_las
from rough_viewer.structure.zones import ZONE_COLUMNS, ZONE_FILE_COLUMNS, ZoneLabeller
from tests.helpers import banded_face

BANDS = [(-1.3, -1.6, 5.0, 0.6, 0.0), (2.3, 1.0, 3.4, 0.6, 60.0)]

HEADER = ("zone,cells,points,area_m2,length_m,width_m,trace_azimuth_deg,trace_plunge_deg,"
          "dip_deg,dip_direction_deg,mean_theta,max_theta,cx,cy,cz,area,length,width,unit_m")


@pytest.fixture(scope="module")
def face(tmp_path_factory):
    pts, _ = banded_face(40.0, 150.0, BANDS, rough=0.01, n=80_000)
    path = tmp_path_factory.mktemp("zones") / "face.laz"
    write_las(path, PointCloud.from_xyz(pts))  # a real LAZ file, read back through laspy
    return path


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_zones_csv_and_cells_csv_contract(tmp_path, face, capsys):
    out, cells = tmp_path / "zones.csv", tmp_path / "cells.csv"
    assert main(["zones", str(face), "--grid", "0.2", "--threshold", "0.2", "--out", str(out),
                 "--cells-out", str(cells), "--quiet"]) == 0
    header, rows = read_csv(out)
    assert ",".join(header) == HEADER
    assert tuple(header) == (*ZONE_COLUMNS, *ZONE_FILE_COLUMNS, "unit_m")
    # the same numbers as the library, at full precision (exact round trip)
    from rough_viewer.io import load_points

    ref = grid_roughness(load_points(face), 0.2)
    zones = ZoneLabeller.build(ref).zones(0.2)
    assert len(rows) == zones.n_zones == 2
    for k, row in enumerate(rows):
        assert float(row[-1]) == 1.0  # the file says its unit: metres
        for name, text in zip(header[:-1], row[:-1], strict=True):
            expected = zones.file_table()[name][k]
            if name in ("zone", "cells", "points"):
                assert int(text) == expected
            else:
                assert float(text) == expected
    assert [int(r[0]) for r in rows] == [1, 2]
    assert int(rows[0][1]) >= int(rows[1][1])
    # cells: compute's columns plus zone, for cells with at least min_points points
    header, crow = read_csv(cells)
    assert tuple(header) == (*CSV_COLUMNS[:-1], "zone", "unit_m")
    keep = ref.n_points >= ref.min_points
    assert len(crow) == int(keep.sum())
    by_key = {tuple(int(v) for v in r[:3]): r for r in crow}
    for i in np.flatnonzero(keep):
        r = by_key[tuple(int(v) for v in ref.ijk[i])]
        assert int(r[-2]) == zones.labels[i] and float(r[-1]) == 1.0
        assert float(r[CSV_COLUMNS.index("theta_odr")]) == ref.theta_odr[i]
        assert r[CSV_COLUMNS.index("theta_ols")] != ""  # all three models, as compute
    assert sum(int(r[-2]) > 0 for r in crow) == zones.cells.sum()
    text = capsys.readouterr().out
    assert "2 zones" in text and "dip 40.0, dip direction 150.0" in text


def test_options_reach_the_labelling(tmp_path, face):
    from rough_viewer.io import load_points

    ref = grid_roughness(load_points(face), 0.25, min_points=10, axis="z")
    for method, connectivity, min_cells in (("ols", "face", 5), ("hybrid", "edge", 1)):
        out = tmp_path / f"{method}.csv"
        assert main(["zones", str(face), "--grid", "0.25", "--method", method, "--axis", "z",
                     "--threshold", "0.3", "--min-cells", str(min_cells), "--connectivity",
                     connectivity, "--min-points", "10", "--out", str(out), "--quiet"]) == 0
        _, rows = read_csv(out)
        expected = ZoneLabeller.build(ref, method).zones(0.3, connectivity=connectivity,
                                                         min_cells=min_cells)
        assert [int(r[1]) for r in rows] == expected.cells.tolist()
    # no zone at all: a header and no rows
    out = tmp_path / "none.csv"
    assert main(["zones", str(face), "--grid", "0.25", "--threshold", "1", "--min-cells", "2",
                 "--out", str(out), "--quiet"]) == 0
    assert out.read_text() == HEADER + "\n"


@pytest.mark.parametrize(("extra", "message"), [
    (["--threshold", "1.5"], "--threshold must lie in [0, 1]"),
    (["--threshold", "-0.01"], "--threshold must lie in [0, 1]"),
    (["--threshold", "nan"], "--threshold must lie in [0, 1]"),
    (["--out", "{tmp}/exists.csv"], "exists"),
    (["--cells-out", "{tmp}/exists.csv"], "exists"),
    (["--cells-out", "{tmp}/out.csv"], "same path"),
    (["--min-points", "2"], "at least 3"),
    (["--min-cells", "0"], "--min-cells"),
    (["--connectivity", "corner"], "--connectivity"),
    (["--grid", "0"], "--grid"),
])
def test_bad_input_one_line_exit_2_no_output(tmp_path, face, capsys, extra, message):
    (tmp_path / "exists.csv").write_text("keep me\n")
    argv = ["zones", str(face), "--grid", "0.2", "--out", str(tmp_path / "out.csv"), "--quiet"]
    argv += [e.format(tmp=tmp_path) for e in extra]
    before = sorted(os.listdir(tmp_path))
    assert status_of(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err
    assert sorted(os.listdir(tmp_path)) == before  # nothing written
    assert (tmp_path / "exists.csv").read_text() == "keep me\n"


def status_of(argv: list[str]) -> int:
    """Exit status of the command line (argparse's usage errors exit through SystemExit)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def test_force_overwrites(tmp_path, face):
    out = tmp_path / "z.csv"
    out.write_text("old\n")
    assert main(["zones", str(face), "--grid", "0.2", "--threshold", "0.2", "--out", str(out),
                 "--force", "--quiet"]) == 0
    assert out.read_text().startswith(HEADER)


def test_console_script_error_is_one_line(tmp_path, face):
    proc = subprocess.run([sys.executable, "-m", "rough_viewer", "zones", str(face), "--grid",
                           "0.2", "--threshold", "2", "--out", str(tmp_path / "o.csv")],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip() == "rough-viewer: error: --threshold must lie in [0, 1], got 2"
    assert not (tmp_path / "o.csv").exists()


@pytest.fixture(scope="module")
def face_mm(tmp_path_factory):
    """The same face as ``face`` with coordinates in millimetres (a LAS without a CRS)."""
    pts, _ = banded_face(40.0, 150.0, BANDS, rough=0.01, n=80_000)
    path = tmp_path_factory.mktemp("zones_mm") / "face_mm.laz"
    write_las(path, PointCloud.from_xyz(pts * 1000.0), scale=0.1)  # same integers as face
    return path


def test_units_mm_grid_summary_and_zones_csv_in_mm(tmp_path, face, face_mm, capsys):
    """Issue 31 item 9: ZONES.csv follows --units as sets --out does (it was always in
    metres): the centroid, roughness, area, length and width in mm, its unit column
    'mm'; area_m2, length_m and width_m stay in metres, as named."""
    m_out, mm_out = tmp_path / "m.csv", tmp_path / "mm.csv"
    assert main(["zones", str(face), "--grid", "0.2", "--threshold", "0.2", "--out", str(m_out),
                 "--quiet"]) == 0
    capsys.readouterr()
    assert main(["zones", str(face_mm), "--grid", "200", "--units", "mm", "--threshold", "0.2",
                 "--out", str(mm_out), "--cells-out", str(tmp_path / "cells_mm.csv"),
                 "--quiet"]) == 0
    text = capsys.readouterr().out
    header_m, rows_m = read_csv(m_out)
    header_mm, rows_mm = read_csv(mm_out)
    assert header_mm == header_m and len(rows_mm) == len(rows_m) == 2
    # exactly the library's zones in metres of the cloud read in mm at 0.2 m
    from rough_viewer.io import load_points

    ref = ZoneLabeller.build(grid_roughness(load_points(face_mm, units="mm"), 0.2)).zones(0.2)
    col = {name: i for i, name in enumerate(header_mm)}
    for k, row in enumerate(rows_mm):
        assert float(row[-1]) == 0.001 and float(rows_m[k][-1]) == 1.0
        # in mm: the centroid, roughness and the unit-less area, length, width
        for a in range(3):
            assert float(row[col[("cx", "cy", "cz")[a]]]) == ref.centroid[k, a] / 1e-3
        assert float(row[col["mean_theta"]]) == ref.mean_theta[k] / 1e-3
        assert float(row[col["max_theta"]]) == ref.max_theta[k] / 1e-3
        assert float(row[col["area"]]) == ref.area_m2[k] / 1e-6
        assert float(row[col["length"]]) == ref.length_m[k] / 1e-3
        assert float(row[col["width"]]) == ref.width_m[k] / 1e-3
        # the columns named in metres stay in metres
        assert float(row[col["area_m2"]]) == ref.area_m2[k]
        assert float(row[col["length_m"]]) == ref.length_m[k]
    # and the metres file's zones (the same points; *1000 rounding may move a point):
    # the same in metres, times 1000 (or 10^6) where the mm file is in mm
    factor = np.array([1e3 if n in ("mean_theta", "max_theta", "cx", "cy", "cz", "length",
                                    "width") else 1e6 if n == "area" else 1.0
                       for n in header_mm[:-1]])
    for a, b in zip(rows_m, rows_mm, strict=True):
        np.testing.assert_allclose(np.array(b[:-1], dtype=float),
                                   np.array(a[:-1], dtype=float) * factor, rtol=1e-3)
    area_m2 = sum(float(r[3]) for r in rows_mm)
    assert "grid 200 mm" in text
    assert f"{area_m2 * 1e6:.4g} mm2 of face" in text and "always in metres" not in text
    assert "area mm2" in text and "mean theta mm" in text
    assert "(ZONES.csv: lengths in mm, its unit_m column" in text


def test_the_threshold_is_judged_and_the_data_suggest_one(tmp_path, face, capsys):
    """The summary gives the share the threshold flags (against the library's binary
    transform) and the data's own threshold with its share; a threshold flagging most
    of the face says so."""
    from rough_viewer.grid.summary import binary, normalise
    from rough_viewer.grid.threshold import map_threshold_advice
    from rough_viewer.io import load_points

    ref = grid_roughness(load_points(face), 0.2)
    for threshold in ("0.2", "0.01"):
        assert main(["zones", str(face), "--grid", "0.2", "--threshold", threshold, "--out",
                     str(tmp_path / f"z{threshold}.csv"), "--quiet"]) == 0
        text = capsys.readouterr().out
        t = float(threshold)
        flagged = binary(normalise(ref.theta_odr), t).sum() / np.isfinite(ref.theta_odr).sum()
        advice = map_threshold_advice(ref, "odr", t)
        assert advice.share == pytest.approx(flagged)
        assert f"threshold {t:g} flags {100 * flagged:.0f} % of the" in text
        assert f"the data suggest {advice.suggested:.3g}" in text
        assert ("warning: threshold" in text) == (flagged > 0.5)
    assert flagged > 0.5  # 0.01 flags most of this face


def test_units_mm_cells_csv_is_computes_cell_table(tmp_path, face_mm):
    cells, computed = tmp_path / "cells.csv", tmp_path / "computed.csv"
    assert main(["zones", str(face_mm), "--grid", "200", "--units", "mm", "--out",
                 str(tmp_path / "z.csv"), "--cells-out", str(cells), "--quiet"]) == 0
    assert main(["compute", str(face_mm), "--grid", "200", "--units", "mm", "--out",
                 str(computed), "--quiet"]) == 0
    header, rows = read_csv(cells)
    ref_header, ref_rows = read_csv(computed)
    assert header == [*ref_header[:-1], "zone", "unit_m"] and ref_header[-1] == "unit_m"
    # the same text: lengths in mm, as compute
    assert [r[:-2] + r[-1:] for r in rows] == ref_rows and float(rows[0][-1]) == 0.001
    assert float(ref_rows[0][ref_header.index("cx")]) > 100  # millimetres, not metres


def test_several_grids_name_outputs_as_compute(tmp_path, face, capsys):
    out, cells = tmp_path / "z.csv", tmp_path / "c.csv"
    assert main(["zones", str(face), "--grid", "0.2", "--grid", "0.25", "--grid", "0.2",
                 "--out", str(out), "--cells-out", str(cells), "--quiet"]) == 0
    text = capsys.readouterr().out
    assert sorted(os.listdir(tmp_path)) == ["c_g0.2.csv", "c_g0.25.csv",
                                            "z_g0.2.csv", "z_g0.25.csv"]
    assert "grid 0.2 m" in text and "grid 0.25 m" in text
    for g in ("0.2", "0.25"):  # each file as the one-grid run writes it
        single = tmp_path / "single" / g
        single.mkdir(parents=True)
        assert main(["zones", str(face), "--grid", g, "--out", str(single / "z.csv"),
                     "--cells-out", str(single / "c.csv"), "--quiet"]) == 0
        assert (tmp_path / f"z_g{g}.csv").read_bytes() == (single / "z.csv").read_bytes()
        assert (tmp_path / f"c_g{g}.csv").read_bytes() == (single / "c.csv").read_bytes()


def test_failed_second_grid_leaves_no_output(tmp_path, face, capsys):
    argv = ["zones", str(face), "--grid", "0.2", "--grid", "1e-9", "--out",
            str(tmp_path / "z.csv"), "--cells-out", str(tmp_path / "c.csv"), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rough-viewer: error: grid size 1e-09 m would take") and "\n" not in err
    assert os.listdir(tmp_path) == []


def test_grid_errors_name_the_unit(tmp_path, face_mm, capsys):
    base = ["zones", str(face_mm), "--units", "mm", "--out", str(tmp_path / "z.csv"), "--quiet"]
    assert main([*base, "--grid", "0"]) == 2
    assert capsys.readouterr().err.strip() == (
        "rough-viewer: error: --grid must be a positive length in mm, got 0")
    assert main([*base, "--grid", "1e-9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rough-viewer: error: --grid 1e-09 mm: grid size 1e-12 m would take")
    assert os.listdir(tmp_path) == []


_FSIZE_RUN = """
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG
resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))
from rough_viewer.cli import main
sys.exit(main(sys.argv[1:]))
"""


def test_second_output_too_large_leaves_neither(tmp_path, face):
    # a real failing write: the OS refuses files over 20 kB; ZONES.csv is far smaller,
    # CELLS.csv far larger, so the first output is written and the second fails
    z, c = tmp_path / "z.csv", tmp_path / "c.csv"
    proc = subprocess.run([sys.executable, "-c", _FSIZE_RUN, "zones", str(face), "--grid", "0.2",
                           "--out", str(z), "--cells-out", str(c), "--quiet"],
                          capture_output=True, text=True)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().startswith(f"rough-viewer: error: cannot write {c}: ")
    assert os.listdir(tmp_path) == []


def test_the_default_threshold_is_the_datas_when_the_papers_flags_most(tmp_path, face, capsys):
    """Issue 31: at 0.05 every real scan was one zone over 92-98 % of its cells. Left
    out, the threshold is the data's own (Otsu's split) when 0.05 flags more than half,
    said beside the summary; --threshold 0.05 keeps the paper's."""
    from rough_viewer.grid.roughness import grid_roughness
    from rough_viewer.grid.threshold import map_threshold_advice
    from rough_viewer.io import load_points

    paper = map_threshold_advice(grid_roughness(load_points(face), 0.2), "odr", 0.05)
    assert paper.most and paper.suggested is not None  # this face: 0.05 flags most of it
    auto, given = tmp_path / "auto.csv", tmp_path / "given.csv"
    assert main(["zones", str(face), "--grid", "0.2", "--out", str(auto), "--quiet"]) == 0
    said = capsys.readouterr().out
    chosen = float(f"{paper.suggested:.3g}")
    assert f"Threshold {chosen:g}, the data's own (Otsu's split" in said
    assert "give --threshold 0.05 to use it" in said and f"threshold {chosen:g}," in said
    assert main(["zones", str(face), "--grid", "0.2", "--threshold", "0.05", "--out", str(given),
                 "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "the data's own" not in said and "threshold 0.05," in said

    def flagged(path):
        rows = [r for r in csv.DictReader(line for line in open(path) if not line.startswith("#"))]
        return sum(int(r["cells"]) for r in rows)

    assert flagged(auto) < flagged(given)
