"""The demo registry, the bundled outcrop's ground truth, and ``rough-viewer demo``."""

from __future__ import annotations

import laspy
import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.summary import binary, normalise
from rough_viewer.synthetic import board_scan
from rough_viewer.synthetic.demos import (
    DEMO_DIR,
    demo_path,
    demo_truth,
    list_demos,
    load_demo,
    load_demo_with_truth,
)
from rough_viewer.synthetic.outcrop import FACE_BEND, FACE_MAIN, OUTCROP
from rough_viewer.vocabulary import InputError


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def outcrop_025():
    """The bundled outcrop, its truth and its 0.25 m grid roughness (read once)."""
    cloud, truth = load_demo_with_truth("outcrop")
    return cloud, truth, grid_roughness(cloud, 0.25)


def _cell_mean(result, values):
    m = result.n_points.shape[0]
    return np.bincount(result.point_cell, values.astype(float), m) / result.n_points


# ---------------------------------------------------------------------------- registry


def test_registry_lists_the_demos_and_finds_the_bundled_files():
    demos = {d.name: d for d in list_demos()}
    assert set(demos) == {"outcrop", "outcrop-small", "board"}
    assert demos["board"].path is None and demos["board"].kind == "generated"
    for name in ("outcrop", "outcrop-small"):
        p = demo_path(name)
        assert p == demos[name].path and p.is_file() and p.parent == DEMO_DIR
        assert p.stat().st_size < 15_000_000
    assert (DEMO_DIR / "__init__.py").is_file()  # the package data rough_viewer.demo_data
    with pytest.raises(InputError, match="unknown demo"):
        demo_path("nope")
    with pytest.raises(InputError, match="on the fly"):
        demo_path("board")


def test_small_demo_loads_with_aligned_truth():
    cloud = load_demo("outcrop-small")
    truth = demo_truth("outcrop-small")
    assert 100_000 < cloud.n < 200_000
    assert truth.labels.shape == (cloud.n,) and truth.face.shape == (cloud.n,)
    assert set(np.unique(truth.labels).tolist()) == {0, 1, 2, 3}
    assert truth.names[3] == "rubble"
    assert cloud.intensity is not None


def test_board_demo_is_the_ray_cast_board():
    cloud = load_demo("board", alpha_deg=22.5, beta_deg=11.25)
    assert cloud is board_scan(22.5, 11.25).cloud
    truth = demo_truth("board", alpha_deg=22.5, beta_deg=11.25)
    assert truth.labels.shape == (cloud.n,) and truth.face is None


# ----------------------------------------------------------------- the bundled outcrop


def test_bundled_outcrop_size_and_content(outcrop_025):
    cloud, truth, _ = outcrop_025
    assert 1_500_000 < cloud.n < 3_000_000
    lo, hi = cloud.bounds()
    assert hi[0] - lo[0] > 35 and 9.5 < hi[2] - lo[2] < 10.5  # ~40 m x 10 m
    frac = np.bincount(truth.labels, minlength=4) / cloud.n
    assert np.all(frac > 0.01)  # rock, both fracture sets, rubble


def test_high_odr_roughness_finds_the_fractures_and_rubble(outcrop_025):
    # Cells with a binary (normalised >= 0.05) ODR value at 0.25 m against cells that
    # hold any fracture or rubble point. Measured: base rate 0.518, precision 0.963,
    # recall 0.805 (random flags would have precision = base rate).
    cloud, truth, r = outcrop_025
    valid = np.isfinite(r.theta_odr)
    flagged = binary(normalise(r.theta_odr))
    true = valid & (_cell_mean(r, truth.labels > 0) > 0)
    base = true.sum() / valid.sum()
    precision = (flagged & true).sum() / flagged.sum()
    recall = (flagged & true).sum() / true.sum()
    assert 0.3 < base < 0.7
    assert precision > 0.9 and precision > 1.6 * base
    assert recall > 0.75


def test_ols_exceeds_odr_on_the_bend_and_agrees_on_the_main_face(outcrop_025):
    # Rock-only cells: on the wall turned by 35 degrees, OLS along y measures distances
    # 1 / cos(35) = 1.22 times the orthogonal ones; on the main face OLS equals ODR.
    cloud, truth, r = outcrop_025
    assert r.axis == "y"  # auto: the face is roughly parallel to xz, as at Box Canyon
    rock = (_cell_mean(r, truth.labels > 0) == 0) & (r.n_points >= 20)
    face = _cell_mean(r, truth.face)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = r.theta_ols / r.theta_odr
    bend = rock & (face == FACE_BEND) & np.isfinite(ratio)
    main_face = rock & (face == FACE_MAIN) & np.isfinite(ratio)
    assert bend.sum() > 500 and main_face.sum() > 1000
    assert np.median(ratio[bend]) == pytest.approx(1 / np.cos(np.radians(OUTCROP.bend_deg)), rel=0.02)
    assert np.mean(ratio[bend] > 1.1) > 0.95
    assert np.median(ratio[main_face]) == pytest.approx(1.0, abs=0.005)
    assert np.percentile(ratio[main_face], 90) < 1.01


def test_buttress_casts_a_shadow(outcrop_025):
    # Buttress 1 (s = 6.5 m, 1.6 m wide, 0.7 m proud) seen from the scanner at x = 14 m,
    # 20 m out: its left edge (x = 5.7-5.78) hides the face for about 0.25 m to its left
    # (measured: ~10 points in the strip against ~2600 in the same strip in the open).
    cloud, truth, _ = outcrop_025
    x, z = cloud.x, cloud.z
    rows = (z > 0.5) & (z < 3.5)
    shadow = rows & (x > 5.52) & (x < 5.68)
    lit = rows & (x > 7.32) & (x < 7.48)  # the same strip width beside the right edge
    assert lit.sum() > 2_000
    assert shadow.sum() < 0.02 * lit.sum()


# ------------------------------------------------------------------------------ command


def test_demo_list(capsys):
    assert main(["demo", "--list"]) == 0
    out = capsys.readouterr().out
    for name in ("outcrop", "outcrop-small", "board"):
        assert name in out


def test_demo_generate_rewrites_the_bundled_file_byte_for_byte(tmp_path, capsys):
    out = tmp_path / "small.laz"
    assert main(["demo", "generate", "outcrop-small", "--out", str(out)]) == 0
    assert out.read_bytes() == demo_path("outcrop-small").read_bytes()
    # no overwrite without --force, and then nothing is touched
    before = out.stat().st_mtime_ns
    assert main(["demo", "generate", "outcrop-small", "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err
    assert out.stat().st_mtime_ns == before
    assert main(["demo", "generate", "outcrop-small", "--out", str(out), "--force"]) == 0


def test_demo_generate_board_writes_points_and_truth(tmp_path):
    out = tmp_path / "board.las"
    assert main(["demo", "generate", "board", "--alpha", "45", "--beta", "22.5",
                 "--out", str(out)]) == 0
    scan = board_scan(45, 22.5)
    las = laspy.read(out)
    assert len(las.points) == scan.cloud.n
    np.testing.assert_allclose(np.asarray(las.x), scan.cloud.x, atol=1e-4)
    assert np.array_equal(np.asarray(las["truth"]), scan.on_sphere.astype(np.uint8))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["demo", "generate", "nope", "--out", "X.laz"], "unknown demo"),
        (["demo", "generate", "board", "--out", "X.xyz"], ".las or .laz"),
        (["demo", "generate", "board", "--alpha", "95", "--out", "X.laz"], "--alpha"),
        (["demo", "generate", "board", "--out", "missing/X.laz"], "folder does not exist"),
    ],
)
def test_demo_generate_bad_input_exits_2_without_output(tmp_path, capsys, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("rough-viewer: error:") and message in err
    assert list(tmp_path.iterdir()) == []
