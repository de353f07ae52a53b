"""--crop and --crop-file on compute, zones and report: the same cells and zones as
the command run on a cloud cropped by brute force; LAS copies of the kept points;
one-line errors."""

from __future__ import annotations

import csv
import json

import laspy
import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.io.crop import CropBox
from rough_viewer.report.view import View, input_ref, save_view
from tests.helpers import UTM, rough_surface

BOX_M = (UTM + [0.4, -1.0, 0.3], UTM + [2.6, 1.0, 1.7])  # x, y (out of the face), z


@pytest.fixture
def face(tmp_path):
    """A 3 m x 2 m face facing -y at UTM coordinates, metres, as .npy."""
    xyz = rough_surface(12_000, seed=5, size=3.0)[:, [0, 2, 1]] * [1.0, 1.0, 2 / 3] + UTM
    path = tmp_path / "face.npy"
    np.save(path, xyz)
    return path, xyz


def brute_force_crop(xyz, lo, hi, keep=True):
    inside = np.array([all(lo[a] <= p[a] <= hi[a] for a in range(3)) for p in xyz.tolist()])
    return xyz[inside if keep else ~inside]


def rows_of(path):
    with open(path, newline="") as fh:
        return [r for r in csv.reader(fh) if r and not r[0].startswith("#")]


def crop_text(lo, hi, per=1.0):
    return ",".join(f"{v / per:.17g}" for v in [*lo, *hi])


@pytest.mark.parametrize("mode", ["keep", "remove"])
def test_compute_crop_gives_the_cells_of_the_cropped_cloud(tmp_path, face, mode):
    path, xyz = face
    ref = tmp_path / "ref.npy"
    np.save(ref, brute_force_crop(xyz, *BOX_M, keep=mode == "keep"))
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["compute", str(path), "--grid", "0.25", "--crop", crop_text(*BOX_M),
                 "--crop-mode", mode, "--out", str(a), "--quiet"]) == 0
    assert main(["compute", str(ref), "--grid", "0.25", "--out", str(b), "--quiet"]) == 0
    assert rows_of(a) == rows_of(b) and len(rows_of(a)) > 20


def test_crop_is_in_the_input_unit(tmp_path, face):
    path, xyz = face
    mm = tmp_path / "face_mm.npy"
    np.save(mm, xyz * 1000.0)
    ref = tmp_path / "ref.npy"
    np.save(ref, brute_force_crop(xyz, *BOX_M) * 1000.0)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["compute", str(mm), "--units", "mm", "--grid", "250", "--crop",
                 crop_text(*BOX_M, per=0.001), "--out", str(a), "--quiet"]) == 0
    assert main(["compute", str(ref), "--units", "mm", "--grid", "250", "--out", str(b),
                 "--quiet"]) == 0
    assert rows_of(a) == rows_of(b)


def test_crop_file_takes_a_saved_views_crop(tmp_path, face, capsys):
    path, xyz = face
    view = View(input=input_ref(path), cell_size_m=0.25, min_points=4,
                crop=CropBox(tuple(BOX_M[0]), tuple(BOX_M[1])))
    vfile = save_view(tmp_path / "view.json", view)
    a, b, js = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "s.json"
    assert main(["compute", str(path), "--grid", "0.25", "--crop-file", str(vfile),
                 "--out", str(a), "--summary-json", str(js), "--quiet"]) == 0
    assert main(["compute", str(path), "--grid", "0.25", "--crop", crop_text(*BOX_M),
                 "--out", str(b), "--quiet"]) == 0
    assert rows_of(a) == rows_of(b)
    kept = brute_force_crop(xyz, *BOX_M).shape[0]
    summary = json.loads(js.read_text())
    assert summary["points"] == kept
    assert any(f"{kept:,} of {len(xyz):,} points kept" in w for w in summary["warnings"])
    assert f"{kept:,} of {len(xyz):,} points kept" in capsys.readouterr().err


def test_zones_crop_gives_the_zones_of_the_cropped_cloud(tmp_path, face):
    path, xyz = face
    ref = tmp_path / "ref.npy"
    np.save(ref, brute_force_crop(xyz, *BOX_M))
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    ca, cb = tmp_path / "ca.csv", tmp_path / "cb.csv"
    assert main(["zones", str(path), "--grid", "0.2", "--threshold", "0.3", "--crop",
                 crop_text(*BOX_M), "--out", str(a), "--cells-out", str(ca), "--quiet"]) == 0
    assert main(["zones", str(ref), "--grid", "0.2", "--threshold", "0.3", "--out", str(b),
                 "--cells-out", str(cb), "--quiet"]) == 0
    assert rows_of(a) == rows_of(b) and len(rows_of(a)) > 1
    assert rows_of(ca) == rows_of(cb)


def test_report_crop_reports_the_kept_points(tmp_path, face):
    path, xyz = face
    out = tmp_path / "r.json"
    assert main(["report", str(path), "--grid", "0.5", "--crop", crop_text(*BOX_M),
                 "--format", "json", "--out", str(out), "--quiet"]) == 0
    doc = json.loads(out.read_text())
    kept = brute_force_crop(xyz, *BOX_M).shape[0]
    assert doc["input"]["points"] == kept
    assert any("crop: kept the points inside" in w for w in doc["warnings"])


def test_las_out_of_a_crop_holds_the_kept_points(tmp_path, face, capsys):
    _, xyz = face
    src = tmp_path / "face.laz"
    header = laspy.LasHeader(version="1.4", point_format=7)
    header.scales, header.offsets = np.array([1e-4] * 3), UTM
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.gps_time = np.arange(len(xyz), dtype=float)
    las.red = np.arange(len(xyz)) % 65535
    las.write(str(src))
    out = tmp_path / "crop.laz"
    assert main(["compute", str(src), "--grid", "0.25", "--crop", crop_text(*BOX_M),
                 "--las-out", str(out)]) == 0
    got = laspy.read(str(out))
    inside = np.all((xyz >= BOX_M[0]) & (xyz <= BOX_M[1]), axis=1)
    # the summary says the points written, not the source's (issue 31 item 6)
    said = capsys.readouterr().out
    assert f"{int(inside.sum()):,} points (the crop's, of {len(xyz):,})" in said
    original = laspy.read(str(src))
    assert len(got.points) == int(inside.sum())
    for dim in ("X", "Y", "Z", "gps_time", "red", "green"):
        assert np.array_equal(np.asarray(got[dim]), np.asarray(original[dim])[inside]), dim
    assert np.isfinite(np.asarray(got["theta_odr"])).any()


@pytest.mark.parametrize("extra, message", [
    (["--crop", "1,2,3,4,5"], "--crop expects six finite numbers"),
    (["--crop", "0,0,0,1,1,nan"], "--crop expects six finite numbers"),
    (["--crop", "5,0,0,1,1,1"], "--crop: crop box: x minimum 5 is above its maximum 1"),
    (["--crop-mode", "remove"], "--crop-mode goes with --crop"),
    (["--crop", "0,0,0,1,1,1", "--crop-file", "v.json"], "give --crop or --crop-file, not both"),
    (["--crop", "0,0,0,1,1,1"], "the crop keeps 0 of the 12,000 points"),
    (["--crop", "0,0,0,1,1,1", "--memory", "1GB"], "--crop and --crop-file need the points"),
    (["--crop-file", "missing.json"], "view file not found"),
])
def test_bad_crops_stop_with_one_line_and_no_output(tmp_path, face, capsys, extra, message):
    path, _ = face
    out = tmp_path / "cells.csv"
    assert main(["compute", str(path), "--grid", "0.25", *extra, "--out", str(out),
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_a_view_without_a_crop_is_refused_for_crop_file(tmp_path, face, capsys):
    path, _ = face
    vfile = save_view(tmp_path / "v.json", View(input=input_ref(path), cell_size_m=0.25,
                                                min_points=4))
    assert main(["zones", str(path), "--grid", "0.25", "--crop-file", str(vfile), "--out",
                 str(tmp_path / "z.csv"), "--quiet"]) == 2
    assert f"view file {vfile} holds no crop" in capsys.readouterr().err


def test_crop_file_reads_the_input_in_the_views_unit(tmp_path, face, capsys):
    """Issue 31: a view saved from an input read with --units mm kept 0 points under
    --crop-file without --units mm (its crop is in metres of the cloud as the app read
    it). The view's unit is taken; a contradicting --units is one line."""
    _, xyz = face
    mm = tmp_path / "face_mm.npy"
    np.save(mm, (xyz - UTM) * 1e3)  # the same face in millimetres, local coordinates
    box_m = (tuple(BOX_M[0] - UTM), tuple(BOX_M[1] - UTM))
    view = View(input=input_ref(mm), cell_size_m=0.25, min_points=4, units="mm",
                crop=CropBox(*box_m))
    vfile = save_view(tmp_path / "view.json", view)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["compute", str(mm), "--grid", "250", "--crop-file", str(vfile),
                 "--out", str(a), "--quiet"]) == 0
    assert main(["compute", str(mm), "--units", "mm", "--grid", "250", "--crop",
                 crop_text(*box_m, per=1e-3), "--out", str(b), "--quiet"]) == 0
    kept = brute_force_crop(xyz - UTM, *box_m).shape[0]
    assert kept > 1000 and f"{kept:,} of {len(xyz):,} points kept" in capsys.readouterr().err
    assert rows_of(a) == rows_of(b)
    assert main(["compute", str(mm), "--units", "m", "--grid", "0.25", "--crop-file", str(vfile),
                 "--out", str(tmp_path / "c.csv"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "was saved with the input in mm, but --units m was given" in err
    assert len(err.strip().splitlines()) == 1
