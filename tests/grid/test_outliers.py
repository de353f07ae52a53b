"""Outlier cells: roughness larger than the cell, against brute force and the bounds
of each model."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid.outliers import (
    analysed_values,
    exceeds_cell,
    outlier_flags,
    outlier_mask,
    outlier_text,
)
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.scales import face_scales
from rough_viewer.grid.summary import histogram, normalise, summarise
from rough_viewer.structure.zones import ZoneLabeller


def leaning_wall(n: int = 8000, seed: int = 4) -> np.ndarray:
    """A wall in the x-z plane whose right half leans back 27 degrees, 3 mm of noise:
    read along z, the vertical half's hybrid values blow up, the leaning half's do not."""
    rng = np.random.default_rng(seed)
    x, z = rng.uniform(0, 2, n), rng.uniform(0, 2, n)
    lean = np.where(x >= 1.0, 0.5 * z, 0.0)
    return np.column_stack([x, lean + 0.003 * rng.standard_normal(n), z])


def test_only_hybrid_can_exceed_the_cell():
    """Random points in cells, any shape: ODR stays below sqrt(3)/2 g and OLS below
    g / 2 (the bounds in the module docstring), so neither is ever an outlier; hybrid
    is an outlier exactly where its value exceeds g."""
    rng = np.random.default_rng(0)
    pts = np.vstack([rng.uniform(0, 1, (20_000, 3)),
                     np.column_stack([rng.uniform(0, 1, (5000, 2)), np.zeros(5000)])])
    for axis in ("x", "y", "z"):
        res = grid_roughness(pts, 0.25, axis=axis, min_points=3)
        g = res.grid.cell_size
        assert np.nanmax(res.theta_odr) <= np.sqrt(3) / 2 * g
        assert np.nanmax(res.theta_ols) <= g / 2
        assert not outlier_mask(res, "odr").any() and not outlier_mask(res, "ols").any()
        np.testing.assert_array_equal(outlier_mask(res, "hybrid"), res.theta_hybrid > g)


def test_marks_flags_and_counts():
    res = grid_roughness(leaning_wall(), 0.5, axis="z")
    steep = np.nan_to_num(res.theta_hybrid, nan=0.0) > 0.5
    assert 0 < steep.sum() < np.isfinite(res.theta_hybrid).sum()
    np.testing.assert_array_equal(outlier_mask(res, "hybrid"), steep)
    np.testing.assert_array_equal(outlier_flags(res), np.where(steep, 2, 0))
    assert not outlier_mask(res, "odr").any()
    kept = analysed_values(res, "hybrid")
    assert np.all(np.isnan(kept[steep]))
    np.testing.assert_array_equal(kept[~steep], res.theta_hybrid[~steep])
    assert analysed_values(res, "hybrid", keep_outliers=True) is res.theta_hybrid
    text = outlier_text(res, "hybrid")
    assert text is not None and text.startswith(f"{steep.sum()} of ")
    assert f"up to {np.nanmax(res.theta_hybrid):.4g} m in 0.5 m cells" in text
    assert outlier_text(res, "odr") is None


def test_table_one_and_histogram_leave_outliers_out():
    """Table 1 over the cells that are not outliers (brute force); the histogram of the
    normalised map no longer puts every cell into its first bin."""
    res = grid_roughness(leaning_wall(), 0.5, axis="z")
    v = res.theta_hybrid
    ok = np.isfinite(v) & (v <= 0.5)
    s = summarise(res, "hybrid")
    assert s.cells == ok.sum() and s.outliers == np.isfinite(v).sum() - ok.sum()
    assert s.max == v[ok].max() and s.mean == pytest.approx(v[ok].mean(), rel=1e-12)
    assert s.std == pytest.approx(v[ok].std(), rel=1e-12)
    raw = summarise(res, "hybrid", keep_outliers=True)
    assert raw.max == np.nanmax(v) and raw.outliers == 0
    first_raw = histogram(normalise(v)).fractions[0]
    first = histogram(normalise(analysed_values(res, "hybrid"))).fractions[0]
    assert first_raw >= 0.5 and first < 0.5 * first_raw
    fs = face_scales([res], threshold=0.05)
    assert fs.summaries[0]["hybrid"].max == s.max
    assert face_scales([res], keep_outliers=True).summaries[0]["hybrid"].max == raw.max


def test_zones_leave_outliers_out():
    """Outlier cells take no part in zones (label 0) and do not set the normalisation's
    maximum; kept, they are the only rough cells."""
    res = grid_roughness(leaning_wall(), 0.25, axis="z")
    steep = outlier_mask(res, "hybrid")
    labeller = ZoneLabeller.build(res, "hybrid")
    assert np.all(np.isnan(labeller.normalised[steep]))
    assert np.nanmax(labeller.normalised) == 1.0
    zones = labeller.zones(0.0, min_cells=1)
    assert np.all(zones.labels[steep] == 0) and np.all(zones.labels[~steep & np.isfinite(
        res.theta_hybrid)] > 0)
    kept = ZoneLabeller.build(res, "hybrid", keep_outliers=True).zones(0.5, min_cells=1)
    rough = kept.labels > 0
    assert rough.any() and np.all(steep[rough])


def test_the_rule():
    np.testing.assert_array_equal(exceeds_cell(np.array([0.5, 0.50001, np.nan, -1.0]), 0.5),
                                  [False, True, False, False])
