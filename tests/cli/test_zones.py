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
from rough_viewer.grid.zones import ZONE_COLUMNS, ZoneLabeller
from rough_viewer.io import PointCloud, write_las
from tests.helpers import banded_face

BANDS = [(-1.3, -1.6, 5.0, 0.6, 0.0), (2.3, 1.0, 3.4, 0.6, 60.0)]

HEADER = ("zone,cells,points,area_m2,length_m,width_m,trace_azimuth_deg,trace_plunge_deg,"
          "dip_deg,dip_direction_deg,mean_theta,max_theta,cx,cy,cz")


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
    assert tuple(header) == ZONE_COLUMNS
    # the same numbers as the library, at full precision (exact round trip)
    from rough_viewer.io import load_points

    ref = grid_roughness(load_points(face), 0.2)
    zones = ZoneLabeller.build(ref).zones(0.2)
    assert len(rows) == zones.n_zones == 2
    for k, row in enumerate(rows):
        for name, text in zip(header, row, strict=True):
            expected = zones.table()[name][k]
            if name in ("zone", "cells", "points"):
                assert int(text) == expected
            else:
                assert float(text) == expected
    assert [int(r[0]) for r in rows] == [1, 2]
    assert int(rows[0][1]) >= int(rows[1][1])
    # cells: compute's columns plus zone, for cells with at least min_points points
    header, crow = read_csv(cells)
    assert tuple(header) == (*CSV_COLUMNS, "zone")
    keep = ref.n_points >= ref.min_points
    assert len(crow) == int(keep.sum())
    by_key = {tuple(int(v) for v in r[:3]): r for r in crow}
    for i in np.flatnonzero(keep):
        r = by_key[tuple(int(v) for v in ref.ijk[i])]
        assert int(r[-1]) == zones.labels[i]
        assert float(r[CSV_COLUMNS.index("theta_odr")]) == ref.theta_odr[i]
        assert r[CSV_COLUMNS.index("theta_ols")] != ""  # all three models, as compute
    assert sum(int(r[-1]) > 0 for r in crow) == zones.cells.sum()
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
