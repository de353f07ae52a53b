"""`rough-viewer bias ...`: memory refused before allocating, option ranges, progress
bars and --units on the commands that read point clouds."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

from rough_viewer.cli import main
from tests.helpers import NOISE, board_points, wire_points


def _json(capsys, argv: list[str]) -> dict:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def _refused(capsys, argv: list[str]) -> str:
    """Exit status 2, nothing on stdout, one line on stderr (returned)."""
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1, captured.err
    return captured.err


@pytest.fixture
def board():
    xyz, _ = board_points(n=6_000, noise=NOISE, sag=0.002, seed=5)
    return xyz


def test_predict_refuses_a_beam_kernel_too_large_before_allocating(capsys, monkeypatch):
    from rough_viewer import memory

    # 200 MB free: the 609 x 1244 raster alone (73 MB) would fit, with the smoothing of
    # ER 0.9 m at 1 mm it does not: 72.7 MB raster + 3044 x 2409 x 64 B padded FFT
    # (469.3 MB) + 1801^2 x 96 B kernel building (311.4 MB) = 853.4 MB = 813.9 MiB
    monkeypatch.setattr(memory, "available_bytes", lambda: 200e6)
    err = _refused(capsys, ["bias", "predict", "--noise", "0.0016", "--er", "0.9"])
    assert "simulation and beam smoothing of a 1,244 x 609 raster" in err
    assert "needs about 813.9 MiB" in err
    assert "choose a smaller effective radius or a larger raster spacing" in err
    err = _refused(capsys, ["bias", "curve", "--asperity-radius", "0.03", "--er-ratio", "0,30"])
    assert "beam smoothing" in err and "needs about" in err


@pytest.mark.parametrize("argv, message", [
    # the audit's case: 1e300 m of noise gave "+3361.41 %" and exit 0
    (["predict", "--noise", "1e300", "--er", "0.004"], "--noise must be a length >= 0 and below 1 m"),
    (["predict", "--noise", "0.0016", "--er", "10"], "--er must be a length >= 0 and below 1 m"),
    (["predict", "--noise", "0.0016", "--er", "0.004", "--spacing", "2"], "--spacing must be"),
    (["predict", "--noise", "0.0016", "--er", "0.004", "--spacing", "0.02"],
     "--spacing 0.02 m is not below the asperity radius 0.019 m"),
    (["predict", "--noise", "0.0016", "--er", "0.004", "--asperity-radius", "5"],
     "--asperity-radius must be"),
    (["predict", "--noise", "0.0016", "--er", "0.004", "--ratio", "1e9"],
     "--ratio must be above 0 and at most 1000"),
    (["predict", "--noise", "0.0016", "--er", "0.004", "--trials", "100000"],
     "--trials must be above 0 and at most 1000"),
    (["simulate", "--noise", "3"], "--noise must be"),
    (["simulate", "--er", "1e10"], "--er must be"),
    (["curve", "--er-ratio", "0,60"], "--er-ratio x --asperity-radius must be"),
    (["curve", "--noise", "1e300"], "--noise must be"),
    (["curve", "--asperity-radius", "0.019,1e20"], "--asperity-radius must be"),
    (["normalise", "{board}", "--noise", "5"], "--noise must be a length >= 0 and below 1 m"),
    (["normalise", "{board}", "--noise", "1500", "--units", "mm"],
     "--noise must be a length >= 0 and below 1000 mm, got 1500"),
    (["normalise", "{board}", "--ratio", "1e300"], "--ratio must be"),
    (["radius", "{wire}", "--wire-radius", "2"], "--wire-radius must be"),
    (["radius", "{wire}", "{wire}", "{wire}", "{wire}", "--break-range", "1e9"],
     "--break-range must be a length > 0 and below 10000 m"),
])
def test_out_of_range_options_exit_2_naming_the_option(capsys, tmp_path, board, argv, message):
    np.save(tmp_path / "board.npy", board)
    np.save(tmp_path / "wire.npy", wire_points(er=0.003, wire_r=0.0, range_m=10.0, n=2000,
                                                seed=2))
    argv = ["bias"] + [a.format(board=tmp_path / "board.npy", wire=tmp_path / "wire.npy")
                       for a in argv]
    assert message in _refused(capsys, argv)


def test_non_numbers_and_negative_seeds_are_usage_errors(capsys):
    for argv in (["bias", "predict", "--noise", "nan", "--er", "0"],
                 ["bias", "predict", "--noise", "inf", "--er", "0"],
                 ["bias", "predict", "--noise", "0.0016", "--er", "0", "--seed", "-1"],
                 ["bias", "noise", "x.npy", "--seed", "-3"]):
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "argument --" in err


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_predict_and_curve_draw_a_progress_bar_unless_quiet(capsys, monkeypatch):
    import sys

    terminal = _Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    argv = ["bias", "predict", "--noise", "0.0016", "--er", "0.006", "--spacing", "0.004",
            "--trials", "3", "--json"]
    data = _json(capsys, argv)
    bar = terminal.getvalue()
    assert "bias trials" in bar and "3/3" in bar and "100%" in bar
    terminal.seek(0)
    terminal.truncate()
    assert _json(capsys, argv + ["--quiet"]) == data
    assert terminal.getvalue() == ""
    _json(capsys, ["bias", "curve", "--asperity-radius", "0.019", "--er-ratio", "0,0.3",
                   "--spacing", "0.004", "--json"])
    assert "asperity radius 19 mm" in terminal.getvalue() and "2/2" in terminal.getvalue()


def test_units_mm_gives_the_same_noise_radius_and_roughness_as_metres(capsys, tmp_path, board):
    metres = tmp_path / "board_m.npy"
    millimetres = tmp_path / "board_mm.npy"
    np.save(metres, board)
    np.save(millimetres, board * 1e3)
    m = _json(capsys, ["bias", "noise", str(metres), "--json"])
    mm = _json(capsys, ["bias", "noise", str(millimetres), "--units", "mm", "--json"])
    assert m["unit"] == "m" and mm["unit"] == "mm"
    assert mm["sigma"] == pytest.approx(m["sigma"], rel=1e-9)
    assert abs(m["sigma"] / NOISE - 1) < 0.05
    # read as metres (no --units), the mm file is 1000 times too rough: the audit's case
    wrong = _json(capsys, ["bias", "noise", str(millimetres), "--json"])
    assert wrong["sigma"] == pytest.approx(1e3 * m["sigma"], rel=1e-9)
    # the text labels: small lengths in mm for metric input, the input's unit otherwise
    assert main(["bias", "noise", str(millimetres), "--units", "mm"]) == 0
    text_mm = capsys.readouterr().out
    assert main(["bias", "noise", str(metres)]) == 0
    text_m = capsys.readouterr().out
    assert text_mm.replace("board_mm", "board_m") == text_m
    assert f"sigma = {m['sigma'] * 1e3:.3f} mm" in text_m
    feet = tmp_path / "board_ft.npy"
    np.save(feet, board / 0.3048)
    assert main(["bias", "noise", str(feet), "--units", "ft"]) == 0
    text_ft = capsys.readouterr().out
    assert f"sigma = {m['sigma'] / 0.3048:.5f} ft" in text_ft and "sigma ft" in text_ft
    # --noise and --scanner are lengths in --units too
    n_m = _json(capsys, ["bias", "normalise", str(metres), "--noise", "0.0016",
                         "--scanner", "0,0,0", "--json"])
    n_mm = _json(capsys, ["bias", "normalise", str(millimetres), "--noise", "1.6",
                          "--scanner", "0,0,0", "--units", "mm", "--json"])
    assert n_mm["n_asperity"] == n_m["n_asperity"]
    assert n_mm["noise_sigma"] == pytest.approx(0.0016)
    assert n_mm["roughness"] == pytest.approx(n_m["roughness"], rel=1e-9)


def test_radius_units_mm_and_scanner_in_mm(capsys, tmp_path):
    wire = wire_points(er=0.003, wire_r=0.0, range_m=10.0, n=3000, seed=8)
    np.save(tmp_path / "wire_m.npy", wire)
    np.save(tmp_path / "wire_mm.npy", wire * 1e3)
    m = _json(capsys, ["bias", "radius", str(tmp_path / "wire_m.npy"), "--json"])
    mm = _json(capsys, ["bias", "radius", str(tmp_path / "wire_mm.npy"), "--units", "mm",
                        "--wire-radius", "0.5", "--json"])
    assert mm["unit"] == "mm" and mm["range"] == pytest.approx(m["range"], rel=1e-9)
    assert mm["wire_radius"] == pytest.approx(0.0005)
    assert mm["effective_radius"] == pytest.approx(m["effective_radius"] - 0.0005, rel=1e-9)
    # the scanner 1 m off along x, given in mm, moves the range as it does in metres
    m1 = _json(capsys, ["bias", "radius", str(tmp_path / "wire_m.npy"), "--scanner", "1,0,0",
                        "--json"])
    mm1 = _json(capsys, ["bias", "radius", str(tmp_path / "wire_mm.npy"), "--units", "mm",
                         "--scanner", "1000,0,0", "--json"])
    assert mm1["range"] == pytest.approx(m1["range"], rel=1e-9) and m1["range"] != m["range"]
    assert main(["bias", "radius", str(tmp_path / "wire_mm.npy"), "--units", "mm"]) == 0
    out = capsys.readouterr().out
    assert "range mm" in out and "ER mm" in out and f"{m['range'] * 1e3:9.3f}" in out
