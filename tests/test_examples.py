"""The numbered scripts in examples/ are the manual: each one runs and says what it
promises."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _run(name: str, *args: str) -> str:
    done = subprocess.run([sys.executable, str(EXAMPLES / name), *args], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_every_example_is_tested() -> None:
    names = sorted(p.name for p in EXAMPLES.glob("[0-9][0-9]_*.py"))
    tested = sorted(n for n in globals() if n.startswith("test_example_"))
    assert len(names) == len(tested), (names, tested)


def test_example_01_grid_roughness() -> None:
    out = _run("01_grid_roughness.py")
    assert "dependent axis y" in out  # the outcrop faces y
    assert all(f"{name}:" in out for name in ("odr", "ols", "hybrid", "e_ols"))


def test_example_02_ols_vs_odr() -> None:
    rows = [line.split() for line in _run("02_ols_vs_odr.py").splitlines()[1:]]
    odr = [float(r[1]) for r in rows]
    assert max(odr) - min(odr) < 0.02 * min(odr)  # ODR does not see the tilt
    for r in rows:  # OLS along z grows as 1 / cos(tilt)
        assert float(r[3]) == pytest.approx(float(r[4]), rel=0.01)


def test_example_03_semivariogram() -> None:
    assert "gamma/variance" in _run("03_semivariogram.py")


def test_example_04_profile() -> None:
    d = {line.split(":")[0].strip(): float(line.split("=")[1])
         for line in _run("04_profile.py").splitlines() if "D =" in line}
    assert abs(d["de-noised"] - d["true"]) < abs(d["noisy"] - d["true"])


def test_example_05_scanner_bias() -> None:
    out = _run("05_scanner_bias.py")
    assert "with noise" in out and "beam smoothing" in out


def test_example_06_app() -> None:
    assert "showing 153,385 of 153,385 points" in _run("06_app.py", "--check")


def test_example_07_colours_and_scales() -> None:
    out = _run("07_colours_and_scales.py")
    shares = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) > 2 and parts[1] in ("min-max", "default") and "%" in line:
            shares[parts[0], parts[1]] = float(line.split("%")[0].split()[-1])
    assert len(shares) == 8
    assert all(shares[m, "default"] <= 50 for m in ("odr", "ols", "hybrid", "e_ols"))
    assert shares["hybrid", "min-max"] > 50
    assert out.count("grid ") >= 4 and "whole face across scales" in out


def test_example_08_zones() -> None:
    import re

    out = _run("08_zones.py")
    shares = {float(m[0]): (float(m[1]), float(m[2])) for m in re.findall(
        r"threshold ([\d.]+):.*rubble points in zones ([\d.]+), rock points in zones ([\d.]+)",
        out)}
    rubble, rock = shares[0.1]
    assert rubble >= 0.65 and rock <= 0.15  # zones hold rubble, not smooth rock
    assert shares[0.05][0] > shares[0.2][0]  # a lower threshold takes in more
    assert "poles, peak density" in out


def test_example_09_joint_sets() -> None:
    import re

    out = _run("09_joint_sets.py")
    assert "3 sets, 18 planes" in out
    rows = re.findall(r"^\s+\d\s+\d+/\d+\s+(\d+)\s+([\d.]+)\s+[\d.]+\s+\d+/\d+\s+(\d+)\s+([\d.]+)$",
                      out, flags=re.M)
    assert len(rows) == 3
    for kappa, spacing, planted_kappa, planted_spacing in rows:
        assert abs(float(kappa) / float(planted_kappa) - 1) < 0.25
        assert abs(float(spacing) / float(planted_spacing) - 1) < 0.05
