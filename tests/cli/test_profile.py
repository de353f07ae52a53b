"""``rough-viewer profile``: JSON numbers, CSV samples, profile files, one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.profiles.comparison import compare_denoising
from rough_viewer.profiles.extraction import extract_profile
from rough_viewer.profiles.fractal import roughness_length
from rough_viewer.profiles.wavelets import noise_sigma
from rough_viewer.synthetic.fbm import fbm_profile

N = 400


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> dict:
    """A tilted 1 mm grid (0.4 m x 41 mm) carrying fBm ridges (H 0.7) plus 1 mm noise."""
    folder = tmp_path_factory.mktemp("profile_cli")
    rng = np.random.default_rng(0)
    g = fbm_profile(N, 0.7, spacing=1e-3, sigma=0.02, rng=1)
    a, c = np.meshgrid(np.arange(N) * 1e-3, np.arange(-20, 21) * 1e-3)
    z = np.interp(a, np.arange(N) * 1e-3, g) + rng.normal(0, 0.001, a.shape)
    th = np.radians(70)
    rot = np.array([[1, 0, 0], [0, np.cos(th), -np.sin(th)], [0, np.sin(th), np.cos(th)]])
    shift = np.array([100.0, 200.0, 50.0])
    xyz = np.column_stack([a.ravel(), c.ravel(), z.ravel()]) @ rot.T + shift
    cloud = folder / "cloud.npy"
    np.save(cloud, xyz)
    start = np.array([0.01, 0.0, g[10]]) @ rot.T + shift
    end = np.array([0.38, 0.0, g[380]]) @ rot.T + shift
    hand = folder / "hand.txt"
    np.savetxt(hand, np.column_stack([np.arange(N) * 1.0, g * 1e3]), header="distance_mm height_mm")
    return {
        "folder": folder, "cloud": cloud, "xyz": xyz, "start": start, "end": end,
        "hand": hand, "g": g,
    }


def xyz_arg(p: np.ndarray) -> str:
    return ",".join(repr(float(v)) for v in p)


def line_args(scene) -> list[str]:
    return ["--from", xyz_arg(scene["start"]), "--to", xyz_arg(scene["end"])]


def test_json_numbers_match_the_core(scene, capsys) -> None:
    code = main(["profile", str(scene["cloud"]), *line_args(scene), "--json"])
    out = capsys.readouterr().out
    assert code == 0
    data = json.loads(out)
    prof = extract_profile(scene["xyz"], scene["start"], scene["end"])
    assert data["samples"] == prof.distance.size
    assert data["spacing_m"] == prof.spacing and data["points"] == prof.n_points
    assert data["sigma_m"] == noise_sigma(prof.heights)
    ref = compare_denoising(prof.heights, prof.spacing)
    assert data["raw"]["dimension"] == ref.raw.dimension
    assert len(data["variants"]) == 16
    for row, v in zip(data["variants"], ref.variants, strict=True):
        assert (row["decomposition"], row["threshold"], row["mode"]) == (
            v.decomposition, v.threshold_rule, v.mode)
        assert row["threshold_m"] == v.denoised.threshold
        assert row["dimension"] == v.fractal.dimension
    assert data["thresholds_m"]["wp"]["fixed"] > data["thresholds_m"]["dwt"]["fixed"]
    # the paper's pattern on noisy data: de-noising lowers D, soft below hard
    raw_d = data["raw"]["dimension"]
    by = {(r["decomposition"], r["threshold"], r["mode"]): r["dimension"] for r in data["variants"]}
    assert all(d < raw_d for d in by.values())
    assert all(by[(dec, t, "soft")] <= by[(dec, t, "hard")] for dec, t, _ in by)


def test_text_table_and_csv(scene, capsys, tmp_path: Path) -> None:
    out_csv = tmp_path / "samples.csv"
    code = main(["profile", str(scene["cloud"]), *line_args(scene), "--csv", str(out_csv)])
    text = capsys.readouterr().out
    assert code == 0
    for label in ("Original profile", "Soft thresh.", "Hard thresh.", "Fixed-form", "Med.",
                  "noise sigma", "DWT", "Wavelet packets"):
        assert label in text
    header = out_csv.read_text().splitlines()[0].split(",")
    assert header[:3] == ["distance_m", "raw_m", "dwt_fixed_soft_m"] and len(header) == 18
    data = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    prof = extract_profile(scene["xyz"], scene["start"], scene["end"])
    np.testing.assert_array_equal(data[:, 0], prof.distance)
    np.testing.assert_array_equal(data[:, 1], prof.heights)
    ref = compare_denoising(prof.heights, prof.spacing)
    np.testing.assert_array_equal(data[:, 2], ref.variant("dwt", "fixed", "soft").denoised.heights)


def test_refuses_existing_output_without_force(scene, capsys, tmp_path: Path) -> None:
    out_csv = tmp_path / "exists.csv"
    out_csv.write_text("keep me\n")
    code = main(["profile", str(scene["cloud"]), *line_args(scene), "--csv", str(out_csv)])
    err = capsys.readouterr().err
    assert code == 2 and "exists" in err and out_csv.read_text() == "keep me\n"
    code = main(["profile", str(scene["cloud"]), *line_args(scene), "--csv", str(out_csv),
                 "--force", "--json"])
    assert code == 0 and out_csv.read_text().startswith("distance_m,")


def test_profile_file_in_millimetres(scene, capsys) -> None:
    code = main(["profile", str(scene["hand"]), "--profile-units", "mm", "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["source"] == "profile-file"
    assert data["samples"] == N and data["spacing_m"] == pytest.approx(1e-3)
    g = np.loadtxt(scene["hand"])[:, 1] * 1e-3
    assert data["sigma_m"] == noise_sigma(g)
    assert data["raw"]["dimension"] == pytest.approx(compare_denoising(g, 1e-3).raw.dimension, rel=1e-12)


@pytest.mark.parametrize(
    "make_args,needle",
    [
        (lambda s: ["profile", str(s["folder"] / "missing.npy"), *line_args(s)], "no such file"),
        (lambda s: ["profile", str(s["cloud"]), "--from", "1,2", "--to", "1,2,3"], "--from"),
        (lambda s: ["profile", str(s["cloud"])], "--from X,Y,Z"),
        (lambda s: ["profile", str(s["cloud"]), *line_args(s), "--wavelet", "db99x"], "--wavelet"),
        # issue 36: 2**1e12 took 68 s and 3.1 GB, then MemoryError
        (lambda s: ["profile", str(s["cloud"]), *line_args(s), "--level", "1000000000000"],
         "--level must be from 1 to 30"),
        (lambda s: ["profile", str(s["cloud"]), *line_args(s), "--spacing", "-1"], "--spacing"),
        (lambda s: ["profile", str(s["cloud"]), "--from", "0,0,0", "--to", "1,1,1"], "points within"),
        (lambda s: ["profile", str(s["bad"])], "line 3"),
        (lambda s: ["profile", str(s["short"])], "samples"),
    ],
)
def test_bad_input_exits_2_with_one_line(scene, capsys, make_args, needle) -> None:
    bad = scene["folder"] / "bad.txt"
    bad.write_text("# d h\n0 1\n1 x\n2 3\n")
    short = scene["folder"] / "short.txt"
    short.write_text("".join(f"{i} {np.sin(i)}\n" for i in range(20)))
    s = {**scene, "bad": bad, "short": short}
    code = main(make_args(s))
    cap = capsys.readouterr()
    assert code == 2
    assert cap.out == ""
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("rough-viewer: error:") and needle in lines[0]


def test_text_clouds_and_two_column_detection(scene, capsys, tmp_path: Path) -> None:
    cloud_txt = tmp_path / "cloud.xyz"
    np.savetxt(cloud_txt, scene["xyz"], fmt="%.6f")
    assert main(["profile", str(cloud_txt), *line_args(scene), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["source"] == "cloud" and data["points"] > 1000
    two = tmp_path / "two.csv"
    two.write_text("distance,height\n" + "".join(f"{i * 0.001},{np.sin(i / 7) * 1e-3}\n"
                                                 for i in range(300)))
    assert main(["profile", str(two), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["source"] == "profile-file" and data["samples"] == 300
    code = main(["profile", str(two), *line_args(scene)])
    assert code == 2 and "profile file" in capsys.readouterr().err


def test_units_mm_give_the_same_profile(scene, capsys, tmp_path: Path) -> None:
    mm_cloud = tmp_path / "cloud_mm.npy"
    np.save(mm_cloud, scene["xyz"] * 1000.0)
    assert main(["profile", str(scene["cloud"]), *line_args(scene), "--json"]) == 0
    ref = json.loads(capsys.readouterr().out)
    assert main(["profile", str(mm_cloud), "--units", "mm", "--from",
                 xyz_arg(scene["start"] * 1000), "--to", xyz_arg(scene["end"] * 1000),
                 "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["unit"] == "mm" and got["samples"] == ref["samples"]
    assert got["spacing_m"] == pytest.approx(ref["spacing_m"], rel=1e-9)
    assert got["raw"]["dimension"] == pytest.approx(ref["raw"]["dimension"], rel=1e-6)
    assert main(["profile", str(mm_cloud), "--units", "mm", "--from",
                 xyz_arg(scene["start"] * 1000), "--to", xyz_arg(scene["end"] * 1000)]) == 0
    assert "length 370" in capsys.readouterr().out  # 0.37 m shown as 370 mm


def _fold(tmp_path: Path) -> Path:
    """A parabola (a fold) with a little roughness: D < 1 until the trend is removed."""
    x = np.arange(2000) * 1e-3
    h = 0.5 * x**2 + fbm_profile(2000, 0.7, spacing=1e-3, sigma=1e-4, rng=3)
    path = tmp_path / "fold.txt"
    np.savetxt(path, np.column_stack([x, h]))
    return path


def test_curved_profile_warns_and_detrend_fixes_it(tmp_path: Path, capsys) -> None:
    path = _fold(tmp_path)
    assert main(["profile", str(path), "--json"]) == 0
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert data["raw"]["dimension"] < 1.0
    assert "below 1" in data["warnings"][0] and "remove the trend" in data["warnings"][0]
    assert "warning" in captured.err and "fold.txt" in captured.err
    assert main(["profile", str(path), "--detrend", "2", "--json"]) == 0
    fixed = json.loads(capsys.readouterr().out)
    assert 1.0 <= fixed["raw"]["dimension"] <= 2.0 and fixed["warnings"] == []
    assert fixed["detrend"] == 2


def _variant_warnings(tmp_path: Path, capsys, noise: float) -> tuple[dict, str]:
    # a smooth wave plus white noise: the raw profile's D lies in [1, 2] on the paper's
    # windows; with little noise the de-noised variants are the bare wave, smoother
    # than the windows (D < 1)
    x = np.arange(900) * 1e-3
    h = 0.01 * np.sin(20 * x) + np.random.default_rng(1).normal(0.0, noise, x.size)
    path = tmp_path / f"wave_{noise:g}.txt"
    np.savetxt(path, np.column_stack([x, h]))
    assert main(["profile", str(path), "--windows", "paper", "--json"]) == 0
    captured = capsys.readouterr()
    return json.loads(captured.out), captured.err


def test_denoised_variants_outside_1_2_are_one_counted_line(tmp_path: Path, capsys) -> None:
    data, err = _variant_warnings(tmp_path, capsys, 0.0005)
    assert 1.0 <= data["raw"]["dimension"] <= 2.0
    dims = [v["dimension"] for v in data["variants"] if v["dimension"] is not None]
    low = sum(d < 1.0 for d in dims)
    assert low == len(dims) == 16  # every variant here: D = 0.52-0.55
    (line,) = data["warnings"]
    assert line.endswith(f"wave_0.0005.txt: de-noised: D of {low} below 1 (de-noising smooths "
                         "the profile further) of the 16 versions; try larger windows")
    assert sum("de-noised:" in line for line in err.splitlines()) == 1
    assert all(len(line.split()) <= 40 for line in err.splitlines())  # one short line each
    assert "profiles.fractal" not in err and "detrend" not in err  # no Python names
    # the same wave with more noise: every variant in [1, 2], no warning at all
    data, err = _variant_warnings(tmp_path, capsys, 0.002)
    assert all(1.0 <= v["dimension"] <= 2.0 for v in data["variants"])
    assert data["warnings"] == [] and "warning" not in err


def test_raw_warning_names_the_raw_profile(tmp_path: Path, capsys) -> None:
    path = _fold(tmp_path)
    assert main(["profile", str(path), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    raw = [w for w in data["warnings"] if "raw profile:" in w]
    assert len(raw) == 1 and f"D = {data['raw']['dimension']:.2f}" in raw[0]


def test_windows_option_in_the_input_unit(tmp_path: Path, capsys) -> None:
    """--windows in the input's unit reaches the fit; 'paper' gives the paper's 3-10 %;
    a malformed value is one line before any reading."""
    x = np.arange(2000) * 1e-3
    path = tmp_path / "p.txt"
    np.savetxt(path, np.column_stack([x * 1e3, fbm_profile(2000, 0.6, spacing=1e-3, rng=2) * 1e3]))
    assert main(["profile", str(path), "--profile-units", "mm", "--windows", "20,40,80,160",
                 "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(data["windows_m"], [0.02, 0.04, 0.08, 0.16])
    ref = roughness_length(fbm_profile(2000, 0.6, spacing=1e-3, rng=2), 1e-3,
                           windows=[0.02, 0.04, 0.08, 0.16])
    assert data["raw"]["dimension"] == pytest.approx(ref.dimension, rel=1e-9)
    assert main(["profile", str(path), "--profile-units", "mm", "--windows", "paper",
                 "--json"]) == 0
    np.testing.assert_allclose(json.loads(capsys.readouterr().out)["windows_m"],
                               np.arange(0.03, 0.1001, 0.01) * 1.999, rtol=0.02)
    assert main(["profile", str(tmp_path / "missing.txt"), "--windows", "5"]) == 2
    err = capsys.readouterr().err
    assert "windows '5': give two or more positive lengths" in err and "missing" not in err


def test_z2_and_jrc_estimate_beside_the_profile(scene, capsys) -> None:
    """The profile's Z2 (RMS slope of its samples) and the Tse and Cruden JRC estimate
    are in the JSON and the text; the 1 mm sampling is inside the estimate's range,
    a 0.25 mm profile file is not and says so."""
    from rough_viewer.profiles.jrc import jrc_from_z2, z2

    code = main(["profile", str(scene["cloud"]), *line_args(scene), "--json"])
    data = json.loads(capsys.readouterr().out)
    prof = extract_profile(scene["xyz"], scene["start"], scene["end"])
    assert code == 0 and data["z2"] == z2(prof.heights, prof.spacing)
    assert data["jrc_estimate"] == pytest.approx(32.2 + 32.47 * np.log10(data["z2"]))
    assert not any("JRC" in w for w in data["warnings"])
    code = main(["profile", str(scene["hand"]), "--profile-units", "mm"])
    out = capsys.readouterr()
    g = np.loadtxt(scene["hand"])[:, 1] * 1e-3
    assert f"Z2 (RMS slope) {z2(g, 1e-3):.4f}" in out.out
    assert f"JRC estimate {jrc_from_z2(z2(g, 1e-3)):.1f}" in out.out
    quarter = scene["folder"] / "quarter.txt"
    np.savetxt(quarter, np.column_stack([np.arange(N) * 0.25, g[:N] * 1e3]))
    main(["profile", str(quarter), "--profile-units", "mm"])
    assert "0.5-1 mm" in capsys.readouterr().err


def test_fine_spacing_is_refused_with_the_figure_before_the_read(scene, capsys, monkeypatch):
    """Issue 36 item 6: the check assumed 80 bytes a sample where comparing the
    de-noising variants takes about 500, so --spacing 1e-7 was accepted and ended in
    a MemoryError. A million samples with 512 MiB available is refused in one line
    naming the samples and the memory; the default spacing still runs."""
    from rough_viewer import memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 512.0 * 2**20)
    length = float(np.linalg.norm(scene["end"] - scene["start"]))
    code = main(["profile", str(scene["cloud"]), *line_args(scene), "--json",
                 "--spacing", repr(length / 1e6)])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "1,000,001 samples" in err and "needs about 488.3 MiB" in err
    assert main(["profile", str(scene["cloud"]), *line_args(scene), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["samples"] > 300
