"""`rough-viewer sets`: the output contract (SETS.csv, PLANES.csv, DIPS.csv, CELLS.csv,
LAS/PLY ids), units, the options and the bad-input errors."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.cli.compute import CSV_COLUMNS
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud, load_points, write_las
from rough_viewer.structure.sets import SetOptions, joint_sets
from rough_viewer.synthetic.joints import JointBlockSpec, generate_joint_block

SETS_HEADER = ("set_id,dip_deg,dip_direction_deg,fisher_kappa,alpha95_deg,cells,planes,joints,"
               "spacing_mean,spacing_median,spacing_std,spacing_scanline_mean,persistence_mean,"
               "face_parallel,face_angle_deg,odr_mean,odr_median,odr_std,theta_max_c1_dip,"
               "theta_max_c1_strike,delta_t_dip,delta_t_strike,jrc_estimate_dip,"
               "jrc_estimate_strike,unit_m")
PLANES_HEADER = ("plane_id,set_id,joint_id,dip_deg,dip_direction_deg,cx,cy,cz,area,persistence_dip,"
                 "persistence_strike,rms,cells,unit_m")
G = 0.5


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    scan = generate_joint_block(JointBlockSpec(angular_step_rad=3e-3))  # 37 k points
    folder = tmp_path_factory.mktemp("sets")
    path = folder / "block.laz"
    write_las(path, scan.cloud, scale=1e-4)
    mm = folder / "block_mm.xyz"  # the same points in millimetres, as text
    cloud = load_points(path)
    np.savetxt(mm, cloud.xyz() * 1000.0, fmt="%.2f")
    return path, mm


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def test_tables_follow_the_contract_at_full_precision(tmp_path, block, capsys):
    path, _ = block
    out = {k: tmp_path / f"{k}.csv" for k in ("sets", "planes", "cells", "dips")}
    assert main(["sets", str(path), "--grid", str(G), "--out", str(out["sets"]),
                 "--planes-out", str(out["planes"]), "--cells-out", str(out["cells"]),
                 "--dips-out", str(out["dips"]), "--quiet"]) == 0
    cloud = load_points(path)
    result = grid_roughness(cloud, G, models=("odr",))
    ref = joint_sets(result, cloud)
    header, rows = read_csv(out["sets"])
    assert ",".join(header) == SETS_HEADER and len(rows) == ref.n_sets == 3
    table = {**ref.set_table(), "unit_m": np.ones(ref.n_sets)}  # the file says: metres
    for k, row in enumerate(rows):
        for name, text in zip(header, row, strict=True):
            if text == "":  # no value (joints that no scanline crosses twice)
                assert np.isnan(table[name][k])
            else:
                assert float(text) == table[name][k]  # exact round trip
    header, rows = read_csv(out["planes"])
    assert ",".join(header) == PLANES_HEADER and len(rows) == ref.planes.n_planes
    assert [int(r[0]) for r in rows] == list(range(1, ref.planes.n_planes + 1))
    assert float(rows[0][header.index("area")]) == ref.planes.area[0]
    header, rows = read_csv(out["dips"])
    assert header[:7] == ["Dip", "Dip Direction", "Quantity", "X (East)", "Y (North)",
                          "Z (Elev.)", "Persistence"]
    assert [float(r[0]) for r in rows] == list(ref.planes.dip_deg)
    assert [float(r[1]) for r in rows] == list(ref.planes.dip_direction_deg)
    assert {r[2] for r in rows} == {"1"}
    # every plane's joint (issue 31 item 12), as PLANES.csv has it
    assert [int(r[header.index("JOINT")]) for r in rows] == list(ref.planes.joint_id)
    header, rows = read_csv(out["cells"])
    assert tuple(header) == (*CSV_COLUMNS[:-1], "set_id", "plane_id", "joint_id", "unit_m")
    keep = result.n_points >= result.min_points
    assert len(rows) == int(keep.sum())
    assert [int(r[-4]) for r in rows] == list(ref.cell_set[keep])
    assert [int(r[-3]) for r in rows] == list(ref.cell_plane[keep])
    assert [int(r[-2]) for r in rows] == list(ref.cell_joint[keep])
    assert {int(r[-2]) for r in rows} >= {0, 1}
    assert {r[-1] for r in rows} == {"1.0"}
    text = capsys.readouterr().out
    assert "3 sets" in text and "wrote" in text


def test_units_mm_give_the_same_sets_in_millimetres(tmp_path, block):
    path, mm = block
    m_out, mm_out = tmp_path / "m.csv", tmp_path / "mm.csv"
    pm, pmm = tmp_path / "pm.csv", tmp_path / "pmm.csv"
    assert main(["sets", str(path), "--grid", str(G), "--out", str(m_out), "--planes-out",
                 str(pm), "--quiet"]) == 0
    assert main(["sets", str(mm), "--units", "mm", "--grid", str(G * 1000), "--out",
                 str(mm_out), "--planes-out", str(pmm), "--quiet"]) == 0
    h, rows_m = read_csv(m_out)
    _, rows_mm = read_csv(mm_out)
    assert len(rows_m) == len(rows_mm) == 3
    lengths = {"spacing_mean", "spacing_median", "spacing_std", "spacing_scanline_mean",
               "persistence_mean", "odr_mean", "odr_median", "odr_std"}
    assert {r[-1] for r in rows_m} == {"1.0"} and {r[-1] for r in rows_mm} == {"0.001"}
    for a, b in zip(rows_m, rows_mm, strict=True):
        for name, x, y in zip(h[:-1], a[:-1], b[:-1], strict=True):
            scale = 1000.0 if name in lengths else 1.0
            if x == "" or y == "":
                assert x == y
                continue
            assert float(y) == pytest.approx(float(x) * scale, rel=1e-6, abs=1e-9)
    h, rows_m = read_csv(pm)
    _, rows_mm = read_csv(pmm)
    i = h.index("area")
    assert float(rows_mm[0][i]) == pytest.approx(float(rows_m[0][i]) * 1e6, rel=1e-6)
    i = h.index("persistence_dip")
    assert float(rows_mm[0][i]) == pytest.approx(float(rows_m[0][i]) * 1e3, rel=1e-6)


def test_options_reach_the_sets(tmp_path, block):
    path, _ = block
    cloud = load_points(path)
    ref = joint_sets(grid_roughness(cloud, G, models=("odr",)), cloud,
                     SetOptions(max_sets=2, cone_deg=10.0))
    out = tmp_path / "s.csv"
    assert main(["sets", str(path), "--grid", str(G), "--max-sets", "2", "--cone", "10",
                 "--out", str(out), "--quiet"]) == 0
    _, rows = read_csv(out)
    assert len(rows) == 2 and [int(r[5]) for r in rows] == list(ref.cells)
    out2 = tmp_path / "s2.csv"
    assert main(["sets", str(path), "--grid", str(G), "--max-roughness", "1e-5",
                 "--out", str(out2), "--quiet"]) == 0
    assert len(read_csv(out2)[1]) == 0


def test_las_and_ply_carry_the_ids(tmp_path, block):
    import laspy
    from plyfile import PlyData

    path, _ = block
    las, ply = tmp_path / "ids.laz", tmp_path / "ids.ply"
    assert main(["sets", str(path), "--grid", str(G), "--out", str(tmp_path / "s.csv"),
                 "--las-out", str(las), "--ply-out", str(ply), "--quiet"]) == 0
    cloud = load_points(path)
    result = grid_roughness(cloud, G, models=("odr",))
    ref = joint_sets(result, cloud)
    data = laspy.read(las)
    assert np.array_equal(np.asarray(data["set_id"]), ref.cell_set[result.point_cell])
    assert np.array_equal(np.asarray(data["plane_id"]), ref.cell_plane[result.point_cell])
    assert np.array_equal(np.asarray(data["joint_id"]), ref.cell_joint[result.point_cell])
    vertex = PlyData.read(str(ply))["vertex"]
    assert np.array_equal(np.asarray(vertex["plane_id"]), ref.cell_plane[result.point_cell])
    assert np.array_equal(np.asarray(vertex["joint_id"]), ref.cell_joint[result.point_cell])


def test_a_cloud_without_planes_writes_headers_and_says_so(tmp_path, capsys):
    rng = np.random.default_rng(0)
    xy = rng.uniform(0.0, 4.0, (20_000, 2))
    path = tmp_path / "rubble.laz"
    write_las(path, PointCloud.from_xyz(np.column_stack([xy, 0.05 * rng.standard_normal(20_000)])))
    out, planes = tmp_path / "s.csv", tmp_path / "p.csv"
    assert main(["sets", str(path), "--grid", "0.25", "--out", str(out), "--planes-out",
                 str(planes), "--quiet"]) == 0
    assert read_csv(out) == (SETS_HEADER.split(","), [])
    assert read_csv(planes) == (PLANES_HEADER.split(","), [])
    assert "no joint set" in capsys.readouterr().out


@pytest.mark.parametrize(("extra", "message"), [
    (["--cone", "95"], "cone"),
    (["--max-sets", "300"], "sets"),
    (["--min-angle", "100"], "angle"),
    (["--ply-out", "x.las"], "--ply-out"),
    (["--las-out", "x.ply"], "--las-out"),
    (["--min-points", "2"], "--min-points"),
    # issue 36: a kernel finer than the net's nodes found 0 sets, exit 0
    (["--smoothing", "0.01"], "smoothing must be from 1 to 90 degrees"),
    (["--face-tolerance", "95"], "face tolerance"),
])
def test_bad_input_one_line_exit_2_no_output(tmp_path, block, capsys, extra, message):
    path, _ = block
    out = tmp_path / "s.csv"
    extra = [str(tmp_path / e) if e.startswith("x.") else e for e in extra]
    assert main(["sets", str(path), "--grid", str(G), "--out", str(out), "--quiet",
                 *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert not out.exists()


def test_existing_output_is_refused_without_force(tmp_path, block, capsys):
    path, _ = block
    out = tmp_path / "s.csv"
    out.write_text("keep")
    assert main(["sets", str(path), "--grid", str(G), "--out", str(out), "--quiet"]) == 2
    assert "exists" in capsys.readouterr().err and out.read_text() == "keep"
    assert main(["sets", str(path), "--grid", str(G), "--out", str(out), "--quiet",
                 "--force"]) == 0
    assert read_csv(out)[0] == SETS_HEADER.split(",")


def test_several_grids_name_outputs_as_compute(tmp_path, block):
    path, _ = block
    out = tmp_path / "s.csv"
    assert main(["sets", str(path), "--grid", "0.5", "--grid", "0.4", "--out", str(out),
                 "--quiet"]) == 0
    assert (tmp_path / "s_g0.5.csv").exists() and (tmp_path / "s_g0.4.csv").exists()
    assert not out.exists()


def test_a_set_of_one_plane_shows_no_spacing_as_a_dash(tmp_path, capsys):
    """Issue 31: a one-plane set's spacing printed "nan" where the app shows "-"."""
    rng = np.random.default_rng(0)
    uv = rng.uniform(0, 4, (40_000, 2))
    z = 0.3 * uv[:, 0] + 0.001 * rng.standard_normal(uv.shape[0])
    src = tmp_path / "plane.xyz"
    np.savetxt(src, np.column_stack([uv, z]))
    assert main(["sets", str(src), "--grid", "0.25", "--out", str(tmp_path / "s.csv"),
                 "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "1 set, 1 joint of 1 plane (patches)\n" in said and "nan" not in said
    row = next(line for line in said.splitlines() if line.startswith("   1  17/270"))
    # set, dip/dir, kappa, a95, cells, planes, joints, spacing, scanline spacing
    assert row.split()[7] == "-" and row.split()[8] == "-"
    assert float(row.split()[9]) == pytest.approx(4.18, abs=0.02)  # persistence: the 4 m plane, dipping 17 deg


def test_joints_out_and_summary_json(tmp_path, block):
    """Issue 30: JOINTS.csv has one row per joint in the contract's columns, the
    patches of PLANES.csv name their joint, and SUMMARY.json carries the sets and
    Jv = sum of 1 / spacing_mean, in m and in mm."""
    path, mm = block
    out = {k: tmp_path / f"{k}.csv" for k in ("sets", "planes", "joints")}
    summary = tmp_path / "summary.json"
    assert main(["sets", str(path), "--grid", str(G), "--out", str(out["sets"]),
                 "--planes-out", str(out["planes"]), "--joints-out", str(out["joints"]),
                 "--summary-json", str(summary), "--quiet"]) == 0
    cloud = load_points(path)
    ref = joint_sets(grid_roughness(cloud, G, models=("odr",)), cloud)
    header, rows = read_csv(out["joints"])
    assert ",".join(header) == ("joint_id,set_id,dip_deg,dip_direction_deg,cx,cy,cz,patches,"
                                "area,trace_length,persistence_dip,persistence_strike,rms,"
                                "unit_m")
    assert len(rows) == ref.joints.n_joints > 0
    assert sum(int(r[header.index("patches")]) for r in rows) == ref.planes.n_planes
    ph, prow = read_csv(out["planes"])
    assert [int(r[ph.index("joint_id")]) for r in prow] == list(ref.planes.joint_id)
    data = json.loads(summary.read_text())
    sh, srows = read_csv(out["sets"])
    spacing = [float(r[sh.index("spacing_mean")]) for r in srows if r[sh.index("spacing_mean")]]
    assert len(data["sets"]) == ref.n_sets
    assert data["sets"][0]["joints"] == int(srows[0][sh.index("joints")])
    assert data["jv"] == pytest.approx(sum(1.0 / s for s in spacing), rel=1e-12)
    assert data["rqd_estimate"] == pytest.approx(min(100.0, max(0.0, 110 - 2.5 * data["jv"])))
    assert data["block_size_index"] == pytest.approx(np.mean(spacing))
    mm_summary = tmp_path / "mm.json"
    assert main(["sets", str(mm), "--units", "mm", "--grid", str(G * 1000), "--out",
                 str(tmp_path / "mm.csv"), "--summary-json", str(mm_summary), "--quiet"]) == 0
    data_mm = json.loads(mm_summary.read_text())
    assert data_mm["jv"] == pytest.approx(data["jv"] / 1000.0, rel=1e-6)  # per mm
    assert data_mm["jv_per_m3"] == pytest.approx(data["jv"], rel=1e-6)
    assert data_mm["rqd_estimate"] == pytest.approx(data["rqd_estimate"], rel=1e-6)


def test_set_roughness_in_sets_csv_summary_json_and_terminal(tmp_path, block, capsys):
    """Issue 30 item 4: SETS.csv ends with every set's roughness (ODR of its cells in
    the output unit, the joints' theta*max/(C+1), Delta-T and JRC estimate along dip
    and strike), SUMMARY.json carries the same per set with the profiles behind them,
    and the terminal shows them with the JRC estimate's sampling warning."""
    path, mm = block
    out, summary = tmp_path / "sets.csv", tmp_path / "summary.json"
    assert main(["sets", str(path), "--grid", str(G), "--out", str(out), "--summary-json",
                 str(summary), "--quiet"]) == 0
    said = capsys.readouterr().out
    cloud = load_points(path)
    ref = joint_sets(grid_roughness(cloud, G, models=("odr",)), cloud)
    r = ref.roughness
    header, rows = read_csv(out)
    tail = ("odr_mean", "odr_median", "odr_std", "theta_max_c1_dip", "theta_max_c1_strike",
            "delta_t_dip", "delta_t_strike", "jrc_estimate_dip", "jrc_estimate_strike")
    assert tuple(header[-len(tail) - 1:-1]) == tail and header[-1] == "unit_m"
    col = {name: np.array([float(row[header.index(name)] or "nan") for row in rows])
           for name in tail}
    for name in tail:  # exact round trip, empty where there is no value
        assert np.array_equal(col[name], ref.set_table()[name], equal_nan=True)
    # the joint block's faces are planes with 2 mm of range noise: their cells' ODR is
    # that of the noise about a plane, sigma sqrt(1 - 2/pi) = 1.2 mm, at most
    assert all(0.0 < v < 0.0015 for v in col["odr_median"])
    assert all(np.isfinite(col["delta_t_dip"])) and r.joints_measured.min() >= 1
    # the block's joint faces are 2 m across at a 9 cm point spacing: no profile has
    # the 40 samples a profile needs, so no JRC estimate, and the run says why
    assert np.isnan(col["jrc_estimate_dip"]).all() and r.profiles_dip.sum() == 0
    assert "warning: set 1: no JRC estimate: no profile on its joints has the 40 samples" in said
    data = json.loads(summary.read_text())
    for k, entry in enumerate(data["sets"]):
        for name in tail:
            if np.isnan(col[name][k]):
                assert entry[name] is None
            else:
                assert entry[name] == pytest.approx(col[name][k], rel=1e-12)
        assert entry["profiles_dip"] == r.profiles_dip[k]
        assert entry["roughness_joints"] == r.joints_measured[k]
    assert "estimate" in data["jrc_estimate_formula"]
    assert data["roughness_warnings"] == list(r.warnings)
    assert "JRC est. dip" in said and "th*/(C+1) dip" in said
    row = next(line for line in said.splitlines()
               if line.split()[:1] == ["1"] and "." in line and len(line.split()) == 12)
    assert float(row.split()[1]) == pytest.approx(r.odr_mean[0] * 1e3, rel=1e-2)  # in mm
    assert row.split()[4] == "-"
    assert float(row.split()[6]) == pytest.approx(r.theta_max_c1_dip[0], abs=0.05)
    mm_out = tmp_path / "mm.csv"
    assert main(["sets", str(mm), "--units", "mm", "--grid", str(G * 1000), "--out",
                 str(mm_out), "--quiet"]) == 0
    h, rows_mm = read_csv(mm_out)
    assert [float(r_[h.index("odr_mean")]) for r_ in rows_mm] == pytest.approx(
        col["odr_mean"] * 1000.0, rel=1e-6)
def test_the_hillside_is_flagged_in_every_output(tmp_path, capsys):
    """Issue 31 item 2: the Santa Cruz LAZ's only "set" was the hillside, silently, and
    went to the Dips CSV; a synthetic hillside (dip 22 / 187, a 2 m scarp across it)
    is flagged on the terminal, in SETS.csv, DIPS.csv and the summary."""
    from tests.structure.test_face import SCARP_M, hillside

    src = tmp_path / "hill.npy"
    np.save(src, hillside())
    out = {k: tmp_path / f"{k}.csv" for k in ("sets", "dips")}
    summary = tmp_path / "summary.json"
    assert main(["sets", str(src), "--grid", "2", "--out", str(out["sets"]), "--dips-out",
                 str(out["dips"]), "--summary-json", str(summary), "--quiet"]) == 0
    said = capsys.readouterr().out
    cloud = load_points(src)
    ref = joint_sets(grid_roughness(cloud, 2.0, models=("odr",)), cloud)
    assert ref.face_parallel.tolist() == [True]
    line = next(x for x in said.splitlines() if x.startswith("* set 1 (22/187)"))
    assert "is parallel to the exposure face: its spacing is not a joint spacing" in line
    assert f"{ref.face.whole_deg[0]:.1f} deg from the whole cloud's plane" in line
    assert "left out of Jv, Ib and RQD" in line
    row = next(x for x in said.splitlines() if x.startswith("   1  22/187"))
    spacing = SCARP_M * np.cos(np.radians(22.0))
    assert row.split()[7].endswith("*")  # the spacing, marked
    assert float(row.split()[7].rstrip("*")) == pytest.approx(spacing, rel=0.05)
    assert row.split()[-1] == f"{ref.face_angle_deg[0]:.1f}*"
    assert "no set off the exposure face has two joints apart: no Jv" in said
    header, rows = read_csv(out["sets"])
    fp, fa = header.index("face_parallel"), header.index("face_angle_deg")
    assert fa == fp + 1 and header[fp - 1] == "persistence_mean"
    assert rows[0][fp] == "1" and float(rows[0][fa]) == ref.face_angle_deg[0]
    header, rows = read_csv(out["dips"])
    assert header[-2:] == ["FACE_PARALLEL", "unit_m"] and {r[-2] for r in rows} == {"1"}
    data = json.loads(summary.read_text())
    assert data["face_parallel_sets"] == [1] and data["sets_counted_in_jv"] == 0
    assert data["jv"] is None and data["sets"][0]["face_parallel"] == 1
    # --face-tolerance 0 flags nothing
    again = tmp_path / "again.csv"
    assert main(["sets", str(src), "--grid", "2", "--out", str(again), "--face-tolerance",
                 "0", "--quiet"]) == 0
    h_again, rows_again = read_csv(again)
    assert rows_again[0][h_again.index("face_parallel")] == "0"
    assert "parallel to the exposure face" not in capsys.readouterr().out
