"""`rough-viewer bias ...`: JSON contracts, agreement with the core, bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rough_viewer.bias.measurement import effective_radius, range_noise
from rough_viewer.cli import main
from rough_viewer.io import load_points, read_las_extra
from tests.helpers import board_points, wire_points

NOISE = 0.0016
ROOT = Path(__file__).resolve().parents[1]


def _json(capsys, argv: list[str]) -> dict:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture
def board_file(tmp_path):
    xyz, _ = board_points(n=12_000, noise=NOISE, sag=0.004, seed=21)
    path = tmp_path / "board.npy"
    np.save(path, xyz)
    return path, xyz


def test_noise_json(capsys, board_file):
    path, xyz = board_file
    data = _json(capsys, ["bias", "noise", str(path), "--json"])
    assert abs(data["sigma"] / NOISE - 1.0) < 0.05
    assert data["sigma"] == pytest.approx(range_noise(xyz).sigma, rel=1e-12)
    assert data["sigma_single_plane"] > 1.2 * NOISE
    assert data["shape"] == [4, 2] and len(data["segments"]) == 8
    seg = data["segments"][0]
    assert set(seg) >= {"row", "col", "n_points", "sigma", "offset", "tilt_deg", "centre"}
    assert sum(s["n_points"] for s in data["segments"]) == 12_000
    # Text output names the curvature.
    assert main(["bias", "noise", str(path), "--segments", "2x1"]) == 0
    out = capsys.readouterr().out
    assert "2 x 1 segments" in out and "curved" in out


def test_noise_through_the_console_entry(board_file):
    path, _ = board_file
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-m", "rough_viewer", "bias", "noise", str(path),
                           "--json"], capture_output=True, text=True, env=env, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    assert abs(json.loads(proc.stdout)["sigma"] / NOISE - 1.0) < 0.05


def test_radius_json_single_scan(capsys, tmp_path):
    xyz = wire_points(er=0.003, wire_r=0.0003, range_m=10.0, n=10_000, seed=22)
    path = tmp_path / "wire.xyz"
    np.savetxt(path, xyz, fmt="%.6f")
    data = _json(capsys, ["bias", "radius", str(path), "--scanner", "0,0,0", "--json"])
    ref = effective_radius(load_points(path).xyz(), scanner=(0, 0, 0))
    assert data["effective_radius"] == pytest.approx(ref.effective_radius, rel=1e-12)
    # Raw ER (the paper's) = 0.99 x (beam + wire radius) for a uniform footprint.
    assert data["effective_radius"] == pytest.approx(0.99 * 0.0033, rel=0.03)
    assert data["range"] == pytest.approx(10.0, rel=1e-3)
    assert data["fit"] is None and len(data["scans"]) == 1


def test_radius_piecewise_fit_over_ranges(capsys, tmp_path):
    ranges = [3.0, 6.0, 9.0, 12.0, 18.0, 24.0, 30.0, 36.0]

    def beam(r: float) -> float:  # break at 12 m
        return 0.0012 + 0.00005 * r + 0.00015 * max(r - 12.0, 0.0)

    paths = []
    for i, r in enumerate(ranges):
        p = tmp_path / f"wire_{i}.npy"
        np.save(p, wire_points(er=beam(r), wire_r=0.0, range_m=r, n=6_000, seed=30 + i))
        paths.append(str(p))
    data = _json(capsys, ["bias", "radius", *paths, "--json"])
    assert len(data["scans"]) == 8 and "effective_radius" not in data
    for s, r in zip(data["scans"], ranges, strict=True):
        assert s["effective_radius"] == pytest.approx(0.99 * beam(r), rel=0.03)
    fit = data["fit"]
    assert abs(fit["break_range"] - 12.0) < 1.5 and not fit["break_given"]
    assert fit["slope_far"] == pytest.approx(0.99 * 0.0002, rel=0.1)
    given = _json(capsys, ["bias", "radius", *paths, "--break-range", "12", "--json"])["fit"]
    assert given["break_given"] and given["break_range"] == 12.0


def test_simulate_then_normalise(capsys, tmp_path):
    out = tmp_path / "target.laz"
    sim = _json(capsys, ["bias", "simulate", "--target", "A", "--spacing", "0.002",
                         "--noise", "0.0016", "--er", "0.004", "--out", str(out), "--json"])
    assert out.exists()
    assert sim["n_points"] == 304 * 622 and sim["asperity_radius_m"] == 0.019
    assert sim["noise_effect_pct"] > 0 > sim["smoothing_effect_pct"]
    assert sim["er_ratio"] == pytest.approx(0.004 / 0.019)
    truth = read_las_extra(out, "truth")
    assert truth.sum() == sim["n_asperity"]
    norm = tmp_path / "norm.las"
    data = _json(capsys, ["bias", "normalise", str(out), "--truth-dim", "truth",
                          "--noise", "0.0016", "--out", str(norm), "--json"])
    assert data["ratio"] == pytest.approx(5.0, rel=1e-3)
    assert data["x_score"] > 85.0 and data["y_score"] < 6.0
    assert data["roughness"] == pytest.approx(data["roughness_known_classes"], rel=0.03)
    assert load_points(norm).n == data["n_asperity"] + data["n_background"]
    known = _json(capsys, ["bias", "normalise", str(out), "--classes", "truth",
                           "--truth-dim", "truth", "--json"])
    assert known["x_score"] == 100.0 and known["y_score"] == 0.0
    assert known["roughness"] == pytest.approx(data["roughness_known_classes"])


def test_predict_and_curve(capsys):
    p = _json(capsys, ["bias", "predict", "--noise", "0.0016", "--er", "0.006",
                       "--asperity-radius", "0.019", "--spacing", "0.002", "--trials", "1",
                       "--json"])
    assert p["noise_effect_pct"] > 0 > p["smoothing_effect_pct"]
    assert p["measured_m"] == pytest.approx(p["expected_m"] * (1 + p["total_effect_pct"] / 100))
    c = _json(capsys, ["bias", "curve", "--asperity-radius", "0.019,0.0325",
                       "--er-ratio", "0,0.25,0.5", "--spacing", "0.002", "--json"])
    assert [cv["asperity_radius_m"] for cv in c["curves"]] == [0.019, 0.0325]
    for cv in c["curves"]:
        assert cv["er_ratio"] == pytest.approx([0.0, 0.25, 0.5])
        assert cv["vs_noisy_pct"][0] == pytest.approx(0.0, abs=1e-9)
        assert cv["vs_noisy_pct"][2] < cv["vs_noisy_pct"][1] < 0


@pytest.mark.parametrize("argv, message", [
    (["bias", "noise", "missing.npy"], "file not found"),
    (["bias", "radius", "{board}", "--scanner", "1,2"], "--scanner expects"),
    (["bias", "radius", "{board}", "--break-range", "12"], "at least 4 wire scans"),
    (["bias", "noise", "{board}", "--segments", "5000"], "a plane needs at least 3"),
    (["bias", "simulate", "--out", "{tmp}/x.npy"], "--out must end in .las or .laz"),
    (["bias", "simulate", "--out", "{tmp}/exists.las"], "output file exists"),
    (["bias", "normalise", "{board}", "--classes", "truth"], "needs --truth-dim"),
    (["bias", "normalise", "{board}", "--truth-dim", "truth"], "needs a LAS/LAZ file"),
    (["bias", "predict", "--noise", "0.0016", "--er", "0.0002"], "too small to smooth"),
    (["bias", "radius", "{tmp}/line.npy"], "scanner lies on the wire"),
])
def test_bad_input_exits_2_with_one_line(capsys, tmp_path, board_file, argv, message):
    path, _ = board_file
    (tmp_path / "exists.las").write_text("keep me")
    t = np.linspace(1.0, 2.0, 20)
    np.save(tmp_path / "line.npy", np.column_stack((t, t, t)))
    argv = [a.format(board=path, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and message in captured.err
    assert (tmp_path / "exists.las").read_text() == "keep me"


def test_usage_errors_exit_2():
    for argv in (["bias", "noise", "x.npy", "--segments", "3y"],
                 ["bias", "predict", "--er", "0.001"],
                 ["bias", "curve", "--er-ratio", "a,b"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2


def test_predict_reproduces_the_papers_numbers_without_a_flag(capsys):
    # the bias paper's target A: 5.07 mm noise-free, 5.31 mm with 1.6 mm range noise
    p = _json(capsys, ["bias", "predict", "--noise", "0.0016", "--er", "0", "--target", "A",
                       "--trials", "2", "--json"])
    assert p["expected_m"] * 1e3 == pytest.approx(5.07, rel=0.01)
    assert p["noise_only_m"] * 1e3 == pytest.approx(5.31, rel=0.01)
    assert p["residual"] == "signed" and "bias paper" in p["residual_definition"]
    assert p["other_residual"].startswith("absolute")
    grid = _json(capsys, ["bias", "predict", "--noise", "0.0016", "--er", "0", "--target", "A",
                          "--trials", "2", "--residual", "absolute", "--json"])
    assert grid["expected_m"] * 1e3 == pytest.approx(3.64, rel=0.01)
    assert grid["residual"] == "absolute" and "docs/science.md" in grid["residual_definition"]
    assert main(["bias", "predict", "--noise", "0.0016", "--er", "0", "--target", "A",
                 "--trials", "1"]) == 0
    text = capsys.readouterr().out
    assert "signed orthogonal distances (the bias paper's definition)" in text
    assert "--residual absolute" in text


def test_noise_on_a_rough_surface_and_radius_on_a_board_warn(capsys, tmp_path, board_file):
    board_path, _ = board_file
    rng = np.random.default_rng(3)
    xy = rng.uniform(0.0, 2.0, (20_000, 2))
    z = 0.05 * np.sin(4 * xy[:, 0]) * np.cos(3 * xy[:, 1]) + 0.01 * rng.normal(size=20_000)
    rough = tmp_path / "rough.npy"
    np.save(rough, np.column_stack([xy, z]))
    data = _json(capsys, ["bias", "noise", str(rough), "--json"])
    assert data["warnings"] and "flat board" in data["warnings"][0]
    capsys.readouterr()
    assert main(["bias", "noise", str(rough)]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "rough.npy" in err
    # a board is no wire, a wire is
    data = _json(capsys, ["bias", "radius", str(board_path), "--json"])
    assert data["warnings"] and "not a thin line" in data["warnings"][0]
    wire = tmp_path / "wire.npy"
    np.save(wire, wire_points(er=0.004, wire_r=0.001, range_m=10.0, n=4000, seed=1))
    assert _json(capsys, ["bias", "radius", str(wire), "--json"])["warnings"] == []
    flat = _json(capsys, ["bias", "noise", str(board_path), "--json"])
    assert flat["warnings"] == []


def test_noise_subsample_is_sample_points_and_max_points_the_bomb_guard(capsys, board_file,
                                                                        tmp_path):
    """Issue 32 item 5: in ``bias noise`` as in every command ``--max-points`` is the
    decompression-bomb guard only; the paper's random subsample is ``--sample-points``
    (equal to range_noise's own subsample of the same seed)."""
    from tests.io.crafted import laz_declaring

    path, xyz = board_file
    data = _json(capsys, ["bias", "noise", str(path), "--sample-points", "5000", "--json"])
    assert data["n_points"] == 5000
    assert data["sigma"] == pytest.approx(range_noise(xyz, max_points=5000, seed=0).sigma,
                                          rel=1e-12)
    bomb = laz_declaring(tmp_path / "bomb.laz", 3_000_000)
    for command in ("noise", "normalise", "radius"):
        assert main(["bias", command, str(bomb)]) == 2
        assert "decompression bomb" in capsys.readouterr().err, command
    main(["bias", "noise", str(bomb), "--max-points", "5000000"])
    assert "decompression bomb" not in capsys.readouterr().err
