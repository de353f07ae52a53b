"""Table-1 statistics, normalisation, binary transform and histograms against plain numpy."""

from __future__ import annotations

import numpy as np

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.summary import binary, histogram, normalise, summaries, summarise
from rough_viewer.io import PointCloud
from tests.helpers import rough_surface


def test_summary_normalise_binary_histogram_against_plain_numpy():
    res = grid_roughness(PointCloud.from_xyz(rough_surface(20_000, seed=9)), 0.25)
    for name in ("odr", "ols", "hybrid", "e_ols"):
        v = res.values(name)
        ok = np.isfinite(v)
        s = summarise(res, name)
        assert s.cells == ok.sum()
        np.testing.assert_allclose(s.mean_points, res.n_points[ok].mean())
        np.testing.assert_allclose([s.min, s.max, s.mean], [v[ok].min(), v[ok].max(), v[ok].mean()])
        np.testing.assert_allclose(s.variance, np.var(v[ok]))
        np.testing.assert_allclose(s.std, np.std(v[ok]))
    v = res.theta_odr
    nv = normalise(v)
    ok = np.isfinite(v)
    np.testing.assert_allclose(nv[ok], (v[ok] - v[ok].min()) / (v[ok].max() - v[ok].min()))
    assert np.nanmin(nv) == 0 and np.nanmax(nv) == 1
    b = binary(nv, 0.3)
    assert b.sum() == np.count_nonzero(nv[ok] >= 0.3)
    h = histogram(nv)
    assert len(h.counts) == 20 and h.counts.sum() == ok.sum()
    np.testing.assert_allclose(h.fractions.sum(), 1.0)
    # independent count: bin k holds 0.05 k <= v < 0.05 (k + 1), the last bin closes at 1
    vals = nv[ok]
    for k in range(20):
        lo, hi = h.edges[k], h.edges[k + 1]
        expected = np.count_nonzero((vals >= lo) & ((vals < hi) if k < 19 else (vals <= hi)))
        assert h.counts[k] == expected


def test_summaries_cover_every_map_and_empty_maps_are_nan():
    res = grid_roughness(PointCloud.from_xyz(rough_surface(5_000, seed=2)), 0.5, models=("odr",))
    s = summaries(res)
    assert list(s) == ["odr", "ols", "hybrid", "e_ols"]
    assert s["odr"].cells > 0
    assert s["ols"].cells == 0 and np.isnan(s["ols"].mean)
