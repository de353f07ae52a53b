"""The threshold's share and the suggested threshold (Otsu's method on log roughness),
against brute force and closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.summary import binary, normalise
from rough_viewer.grid.threshold import otsu_split, threshold_advice
from rough_viewer.vocabulary import InputError


def brute_otsu(v: np.ndarray) -> tuple[float, float]:
    """Every split of the sorted values tried one at a time: (threshold, eta)."""
    v = np.sort(v)
    best, at = -1.0, 0
    for k in range(1, v.size):
        if v[k] == v[k - 1]:
            continue
        a, b = v[:k], v[k:]
        between = a.size * b.size / v.size**2 * (a.mean() - b.mean()) ** 2
        if between > best:
            best, at = between, k
    return 0.5 * (v[at - 1] + v[at]), best / v.var()


def test_otsu_matches_brute_force():
    rng = np.random.default_rng(3)
    for v in (rng.normal(size=300), np.round(rng.exponential(size=400), 1),
              np.r_[rng.normal(0, 1, 200), rng.normal(5, 0.5, 50)] + 1e6):
        split = otsu_split(v)
        t, eta = brute_otsu(v)
        assert split is not None
        assert split.threshold == pytest.approx(t, rel=1e-12)
        assert split.separability == pytest.approx(eta, rel=1e-9)
        assert split.lower == np.count_nonzero(v < t) and split.upper == np.count_nonzero(v > t)
    assert otsu_split(np.full(5, 2.0)) is None and otsu_split(np.array([1.0])) is None


def test_one_normal_population_separates_by_two_over_pi():
    """A normal population split at its mean: sigma_B^2 = (2 / pi) sigma^2."""
    v = np.random.default_rng(0).normal(size=200_000)
    split = otsu_split(v)
    assert split is not None
    assert split.separability == pytest.approx(2 / np.pi, abs=0.002)
    assert abs(split.threshold) < 0.02


def test_smooth_rock_and_a_rough_zone():
    """80 % of cells near 1 mm, 20 % near 20 mm (log-normal, 20 % spread): the split
    falls between them in log, flags the rough 20 %, and the two classes are clear;
    NaN is no cell and the exact fit (0) takes no part in the split."""
    rng = np.random.default_rng(1)
    smooth = 0.001 * np.exp(0.2 * rng.standard_normal(8000))
    rough = 0.02 * np.exp(0.2 * rng.standard_normal(2000))
    values = np.r_[smooth, rough, np.nan, 0.0]                    # no value, an exact fit
    advice = threshold_advice(values, 0.05)
    assert advice.cells == 10_001
    norm = normalise(values)
    assert advice.share == pytest.approx(binary(norm, 0.05).sum() / 10_001)
    assert smooth.max() < advice.suggested_theta < rough.min()
    assert advice.suggested == pytest.approx(advice.suggested_theta / np.nanmax(values))
    assert advice.suggested_share == pytest.approx(2000 / 10_001)
    assert advice.clear and advice.separability > 0.9
    text = advice.text("m")
    assert text.startswith(f"threshold 0.05 flags {100 * advice.share:.0f} % of the 10,001 cells")
    assert "Otsu's method on log10 roughness), which flags 20 %" in text
    assert "mm" in text


def test_most_of_the_face_is_said():
    rng = np.random.default_rng(2)
    values = 0.005 * np.exp(0.3 * rng.standard_normal(5000))       # one population
    advice = threshold_advice(values, 0.05)
    assert advice.share > 0.9 and advice.most
    assert ": most of the face reads as rough;" in advice.text()
    assert not advice.clear and "no clear gap" in advice.text()
    assert 0.3 < advice.suggested_share < 0.7
    assert not threshold_advice(values, 0.9).most


def test_no_values_and_bad_threshold():
    assert threshold_advice(np.full(3, np.nan)).text() == "threshold 0.05: no cell has a value"
    one = threshold_advice(np.array([0.0, 0.0, 0.002]))
    assert one.suggested is None and "no suggestion" in one.text()
    with pytest.raises(InputError, match=r"threshold must lie in \[0, 1\]"):
        threshold_advice(np.ones(3), 1.5)


def test_cells_that_fit_exactly_take_no_part_in_the_split():
    """Round-off roughness (1e-17 m: repeated points, DEM lattices) has a logarithm but
    is no rock: left in, Otsu splits those cells off as a population of their own (the
    airborne LAZ: a suggestion of 1e-5 mm flagging 99 %)."""
    from rough_viewer.grid.roughness import grid_roughness
    from rough_viewer.grid.threshold import map_threshold_advice

    rng = np.random.default_rng(4)
    smooth = 0.001 * np.exp(0.2 * rng.standard_normal(8000))
    rough = 0.02 * np.exp(0.2 * rng.standard_normal(2000))
    exact = 1e-17 * rng.uniform(1, 5, 1500)
    with_exact = threshold_advice(np.r_[smooth, rough, exact], 0.05, exact_fit=1e-9)
    assert smooth.max() < with_exact.suggested_theta < rough.min()
    naive = threshold_advice(np.r_[smooth, rough, exact], 0.05, exact_fit=0.0)
    assert naive.suggested_theta < 1e-9  # what the exact fits did to the split
    # a grid result: repeated points make exact fits; the map's advice leaves them out
    xy = rng.uniform(0, 4, (3000, 2))
    pts = np.column_stack([xy, 0.002 * rng.standard_normal(3000)])
    pts = np.vstack([pts, np.repeat(pts[:3] + [[0.1, 0.1, 0]], 3, axis=0)])
    res = grid_roughness(pts, 1.0, min_points=4)
    advice = map_threshold_advice(res, "odr", 0.05)
    assert advice.suggested_theta is None or advice.suggested_theta > 1e-6
