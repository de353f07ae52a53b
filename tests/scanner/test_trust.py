"""Per-cell predicted bias and trust: the bias paper's figures through the path of
``bias predict``, the flags, calibration files."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from rough_viewer.bias.calibration import (
    PAPER_NOISE_M,
    PAPER_SPAN_M,
    calibration,
    paper_calibration,
    read_calibration,
)
from rough_viewer.bias.measurement import normalise_population
from rough_viewer.bias.simulation import paper_target, simulate_target
from rough_viewer.cli import main
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud
from rough_viewer.scanner.positions import with_scanner
from rough_viewer.scanner.trust import (
    FLAG_INCIDENCE,
    FLAG_NOISE,
    FLAG_RANGE,
    INCIDENCE_LIMIT_DEG,
    TrustSettings,
    bias_model,
    cell_trust,
    ratio_samples,
)
from rough_viewer.vocabulary import TRUST_FIELDS, InputError
from tests.helpers import board_points, ray_grid, scan_plane, wire_points


def _predict_json(capsys, *extra: str) -> dict:
    assert main(["bias", "predict", "--noise", "0.0016", "--target", "A", "--trials", "1",
                 "--quiet", "--json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_noise_inflation_is_the_papers_target_a_figure_through_bias_predict(capsys):
    """The per-cell noise model is the prediction of ``bias predict`` itself: target A,
    1.6 mm of noise, no smoothing: 5.07 -> 5.31 mm (+4.7 %) in the paper."""
    model = bias_model(PAPER_NOISE_M, (0.0,), residual="signed", trials=1)
    cli = _predict_json(capsys, "--er", "0")
    assert model.noise.expected_m == cli["expected_m"]
    assert model.noise.noise_only_m == cli["noise_only_m"]
    assert model.noise.expected_m == pytest.approx(5.07e-3, abs=2e-5)
    assert model.noise.noise_only_m == pytest.approx(5.31e-3, abs=2e-5)
    assert model.noise.noise_effect_pct == pytest.approx(4.7, abs=0.3)
    # the signed residuals add the noise's variance: gain 1
    assert model.noise_gain == pytest.approx(1.0, abs=0.02)
    # the grid's absolute residuals: the same path, the convention's own gain
    absolute = bias_model(PAPER_NOISE_M, (0.0,), residual="absolute", trials=1)
    cli_abs = _predict_json(capsys, "--er", "0", "--residual", "absolute")
    assert absolute.noise.noise_only_m == cli_abs["noise_only_m"]
    assert 1 - 2 / np.pi < absolute.noise_gain < 1.0
    # smoothing at ER / r = 0.5: the same number as 'bias predict --er 0.0095'
    smooth = bias_model(PAPER_NOISE_M, (0.5,), residual="signed", trials=1)
    assert smooth.smoothing_fraction(np.array([0.5]))[0] * 100 == pytest.approx(
        _predict_json(capsys, "--er", "0.0095")["smoothing_effect_pct"], rel=1e-12)


def _target_cloud(noise: float) -> np.ndarray:
    """Target A population-normalised to 5 : 1 with its known classes (the paper's
    roughness), heights along z, seen from 10 m straight above."""
    layout = paper_target("A")
    sim = simulate_target(layout, noise_sigma_m=noise, seed=3)
    clean = sim.xyz(true=True)
    keep = normalise_population(clean, sim.labels(), ratio=5.0, seed=0).keep
    return sim.xyz()[keep]


def test_a_cell_of_target_a_gets_its_true_roughness_back():
    """One cell holding the normalised noisy target A: its roughness less the predicted
    noise inflation is the roughness of the noise-free target (5.07 mm)."""
    noisy, clean = _target_cloud(PAPER_NOISE_M), _target_cloud(0.0)
    scanner = (0.3, 0.62, 10.0)
    settings = TrustSettings(calibration=calibration(effective_radius_m=0.0), trials=1)
    theta = {}
    for name, xyz in (("noisy", noisy), ("clean", clean)):
        cloud = with_scanner(PointCloud.from_xyz(xyz), scanner)
        res = grid_roughness(cloud, 2.0, models=("odr",), residual="signed")
        assert res.n_cells == 1
        theta[name] = res.theta_odr[0]
        if name == "noisy":
            trust = cell_trust(cloud, res, settings)
    assert theta["clean"] == pytest.approx(5.07e-3, abs=3e-5)
    assert theta["noisy"] == pytest.approx(5.31e-3, abs=3e-5)
    true = theta["noisy"] - trust.bias_pred_m[0]
    assert true == pytest.approx(theta["clean"], rel=0.005)
    assert trust.smoothing_pred_m[0] == 0.0  # no beam
    assert 100 * trust.noise_pred_m[0] / true == pytest.approx(4.7, abs=0.5)
    assert trust.geometry.incidence_deg[0] < 3.0


TILT = np.radians(25.0)
NORMAL = np.array([np.sin(TILT), -np.cos(TILT), 0.0])


@pytest.fixture(scope="module")
def wall():
    """A wall turned 25 degrees, 14 m from the scanner, with 3 mm of range noise:
    incidences from about 15 to 35 degrees across it."""
    scanner = np.array([0.0, 0.0, 0.0])
    centre = np.array([0.0, 14.0, 0.0])
    rays = ray_grid(scanner, centre, 0.15, step=1.5e-3)
    pts = scan_plane(scanner, centre, NORMAL, rays, extent=2.0, noise=0.003, seed=4)
    cloud = with_scanner(PointCloud.from_xyz(pts), scanner)
    return cloud, grid_roughness(cloud, 0.5, models=("odr",))


def test_flags_follow_the_papers_limits(wall):
    cloud, res = wall
    trust = cell_trust(cloud, res, TrustSettings(trials=1))
    k = trust.known
    assert k.sum() > 20
    inc = trust.geometry.incidence_deg
    assert np.any(inc[k] > INCIDENCE_LIMIT_DEG) and np.any(inc[k] < INCIDENCE_LIMIT_DEG)
    np.testing.assert_array_equal((trust.flags[k] & FLAG_INCIDENCE) > 0,
                                  inc[k] > INCIDENCE_LIMIT_DEG)
    # 14 m lies in the paper's 3-38 m; the roughness here is the 3 mm of noise itself
    assert not np.any(trust.flags & FLAG_RANGE)
    share = trust.noise_pred_m[k] / trust.theta_m[k]
    np.testing.assert_array_equal((trust.flags[k] & FLAG_NOISE) > 0, share > 0.3)
    np.testing.assert_array_equal(trust.trusted[k] == 1.0, trust.flags[k] == 0)
    assert np.all(np.isnan(trust.trusted[~k]))
    # a calibration over 3 to 9 m: every cell at 14 m is out of range
    near = replace(calibration(noise_sigma_m=0.0), span_m=(3.0, 9.0))
    out = cell_trust(cloud, res, TrustSettings(calibration=near, trials=1))
    assert np.all(out.flags[k] & FLAG_RANGE)
    assert not np.any(out.flags & FLAG_NOISE)  # no noise: nothing to inflate
    np.testing.assert_array_equal(out.noise_pred_m[k], 0.0)


def test_noise_across_the_cell_falls_with_cos_incidence(wall):
    """Range noise acts along the beam: across a cell seen at incidence i it is
    s = sigma cos(i), and it adds s^2 to the cell's mean squared distance m2."""
    cloud, res = wall
    trust = cell_trust(cloud, res, TrustSettings(calibration=calibration(
        noise_sigma_m=0.003, effective_radius_m=0.0), trials=1))
    k = trust.known
    s = 0.003 * np.cos(np.radians(trust.geometry.incidence_deg[k]))
    th = trust.theta_m[k]
    m2 = trust.geometry.plane_variance[k]
    want = th - th * np.sqrt(np.clip(1 - s**2 / m2, 0, None))
    np.testing.assert_allclose(trust.noise_pred_m[k], want, rtol=1e-12)
    np.testing.assert_allclose(trust.bias_pred_m[k], trust.noise_pred_m[k], rtol=1e-12)
    # this wall is flat: its roughness is its 3 mm of noise, nearly all predicted as
    # noise (what is left is the sampling spread of a cell's own noise)
    assert np.median(trust.noise_pred_m[k] / th) > 0.6


@pytest.mark.parametrize("residual", ["absolute", "signed"])
def test_gaussian_relief_gets_its_true_roughness_back(residual):
    """Gaussian relief of 4 mm under 2 mm of range noise along the beam, seen at
    20-40 degrees: each cell's roughness less its predicted noise is the roughness of
    the same relief without noise (Gaussian heights keep the ratio of the std of
    |distance| to the RMS, sqrt(1 - 2 / pi), whatever their size)."""
    rng = np.random.default_rng(11)
    n = 60_000
    scanner = np.array([0.0, 0.0, 0.0])
    xy = rng.uniform(-1.0, 1.0, (n, 2))
    u, normal = np.array([np.cos(0.5), np.sin(0.5), 0.0]), np.array([-np.sin(0.5), np.cos(0.5), 0.0])
    centre = 11.0 * (np.cos(np.radians(30)) * normal + np.sin(np.radians(30)) * u)
    base = centre + xy[:, :1] * u + xy[:, 1:] * np.array([0.0, 0.0, 1.0])
    clean = base + (0.004 * rng.standard_normal(n))[:, None] * normal
    beams = clean - scanner
    beams /= np.linalg.norm(beams, axis=1)[:, None]
    noisy = clean + (0.002 * rng.standard_normal(n))[:, None] * beams
    origin = centre - 1.25
    res_c = grid_roughness(clean, 0.5, origin=origin, models=("odr",), residual=residual)
    cloud = with_scanner(PointCloud.from_xyz(noisy), scanner)
    res_n = grid_roughness(cloud, 0.5, origin=origin, models=("odr",), residual=residual)
    trust = cell_trust(cloud, res_n, TrustSettings(calibration=calibration(
        noise_sigma_m=0.002, effective_radius_m=0.0), trials=1))
    both = np.isfinite(res_c.theta_odr) & np.isfinite(res_n.theta_odr) & (res_n.n_points > 500)
    np.testing.assert_array_equal(res_c.ijk[both], res_n.ijk[both])
    assert both.sum() >= 8
    inc = trust.geometry.incidence_deg[both]
    assert inc.min() > 15 and inc.max() < 45
    measured = res_n.theta_odr[both]
    predicted = measured - trust.bias_pred_m[both]
    assert np.all(measured > 1.04 * res_c.theta_odr[both])  # the noise shows ...
    ratio = predicted / res_c.theta_odr[both]  # ... and goes (up to each cell's sampling)
    assert np.median(ratio) == pytest.approx(1.0, abs=0.01)
    np.testing.assert_allclose(ratio, 1.0, atol=0.06)


def test_beam_smoothing_follows_er_over_the_asperity_scale(wall):
    cloud, res = wall
    settings = TrustSettings(calibration=calibration(noise_sigma_m=0.0,
                                                     effective_radius_m=0.0095), trials=1)
    trust = cell_trust(cloud, res, settings)
    k = trust.known
    np.testing.assert_allclose(trust.er_ratio[k], 0.5)
    frac = trust.model.smoothing_fraction(np.array([0.5]))[0]
    assert -0.2 < frac < -0.08  # the paper: up to 20 % at ER / r of 0.6
    true = trust.theta_m[k] / (1 + frac)
    np.testing.assert_allclose(trust.smoothing_pred_m[k], trust.theta_m[k] - true, rtol=1e-12)
    # a grid finer than twice the asperity radius holds asperities of half its size
    fine = grid_roughness(cloud, 0.02, models=("odr",))
    t2 = cell_trust(cloud, fine, settings)
    assert t2.asperity_scale_m == pytest.approx(0.01)
    np.testing.assert_allclose(t2.er_ratio[t2.known], 0.95)


def test_columns_lines_and_layers(wall):
    cloud, res = wall
    trust = cell_trust(cloud, res, TrustSettings(trials=1))
    cols = trust.columns()
    assert tuple(cols) == TRUST_FIELDS
    assert isinstance(cols["scans"], np.ma.MaskedArray) and cols["scans"].dtype == np.int64
    np.testing.assert_array_equal(cols["range"], trust.geometry.range_m)
    row = int(np.flatnonzero(trust.known & (trust.flags & FLAG_INCIDENCE > 0))[0])
    lines = trust.lines(row, unit="m")
    assert lines[0].startswith("seen by 1 scan: range ")
    assert f"{trust.geometry.range_m[row]:.2f} m" in lines[0]
    assert "not trusted: incidence above 22.5 degrees" in lines[-1]
    assert f"{trust.theta_m[row] * 1e3:.3f} mm" in lines[2]
    ft = trust.lines(row, unit="ft")
    assert f"{trust.geometry.range_m[row] / 0.3048:.2f} ft" in ft[0]
    for name in TRUST_FIELDS:
        assert trust.layer(name).shape == (res.n_cells,)
    with pytest.raises(ValueError, match="unknown trust field") as bug:
        trust.layer("nope")
    assert type(bug.value) is ValueError  # the caller's mistake, not the user's
    summary = trust.summary()
    assert summary.cells == int(trust.known.sum())
    assert summary.trusted + summary.flagged["incidence"] >= summary.cells - summary.flagged[
        "noise"]
    assert any("trusted" in line for line in summary.lines("m"))


def test_no_positions_says_so():
    cloud = PointCloud.from_xyz(np.random.default_rng(0).uniform(0, 1, (500, 3)))
    res = grid_roughness(cloud, 0.5, models=("odr",))
    assert cell_trust(cloud, res) is None


def test_calibration_from_bias_noise_and_bias_radius_json(capsys, tmp_path):
    xyz, _ = board_points(n=8000, noise=0.002, sag=0.0, seed=5)
    np.save(tmp_path / "board.npy", xyz)
    assert main(["bias", "noise", str(tmp_path / "board.npy"), "--json"]) == 0
    (tmp_path / "noise.json").write_text(capsys.readouterr().out)
    ranges = [4.0, 8.0, 12.0, 20.0, 28.0]

    def beam(r: float) -> float:
        return 0.001 + 0.0001 * r + 0.0002 * max(r - 12.0, 0.0)

    paths = []
    for i, r in enumerate(ranges):
        p = tmp_path / f"wire{i}.npy"
        np.save(p, wire_points(er=beam(r), wire_r=0.0, range_m=r, n=6000, seed=40 + i))
        paths.append(str(p))
    assert main(["bias", "radius", *paths, "--json"]) == 0
    (tmp_path / "radius.json").write_text(capsys.readouterr().out)
    cal = calibration(files=[tmp_path / "noise.json", tmp_path / "radius.json"])
    assert cal.noise_sigma_m == pytest.approx(0.002, rel=0.05)
    assert cal.span_m == pytest.approx((4.0, 28.0), rel=1e-3)
    assert cal.fit is not None
    for r in (6.0, 16.0, 25.0):
        assert float(cal.effective_radius(r)) == pytest.approx(0.99 * beam(r), rel=0.06)
    # a number given replaces the file's, and a typed radius has no span
    typed = calibration(noise_sigma_m=0.001, effective_radius_m=0.003,
                        files=[tmp_path / "noise.json"])
    assert typed.noise_sigma_m == 0.001 and typed.span_m is None
    paper = paper_calibration()
    assert paper.span_m == PAPER_SPAN_M and paper.noise_sigma_m == 0.0016
    (tmp_path / "other.json").write_text('{"cells": 3}')
    with pytest.raises(InputError, match="neither 'bias noise --json'"):
        read_calibration(tmp_path / "other.json")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(InputError, match="broken.json"):
        read_calibration(tmp_path / "broken.json")
    with pytest.raises(InputError, match="not found"):
        read_calibration(tmp_path / "absent.json")


def test_ratio_samples():
    assert ratio_samples(np.array([0.3, 0.3, np.nan])) == (0.3,)
    assert ratio_samples(np.array([0.02, 0.33])) == (0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35)
    coarse = ratio_samples(np.array([0.0, 1.0]))
    assert len(coarse) <= 8 and coarse[0] == 0.0 and coarse[-1] >= 1.0
    assert ratio_samples(np.array([np.nan])) == (0.0,)
    assert ratio_samples(np.array([5.0, 9.0])) == (3.0,)


def test_an_angular_step_finer_than_any_scanner_is_refused_by_the_settings():
    """The bound the command line had alone (1e-300 deg ended in ZeroDivisionError)."""
    import math

    with pytest.raises(InputError, match="no scanner steps finer"):
        TrustSettings(angular_step_rad=math.radians(1e-300)).check()
    TrustSettings(angular_step_rad=math.radians(2e-6)).check()
