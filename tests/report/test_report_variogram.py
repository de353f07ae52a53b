"""The report's semivariograms within a time budget: exact where the cost model
says it is cheap, else a sampled estimate whose method and errors the report states."""

from __future__ import annotations

import numpy as np

from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.variogram import semivariogram
from rough_viewer.io import PointCloud
from rough_viewer.report import build_report, report_html, report_json
from tests.report.test_report import rough_tilted_face


def test_a_grid_too_dear_for_exact_is_sampled_and_the_report_says_so(monkeypatch):
    import rough_viewer.grid.variogram as variogram

    cloud = PointCloud.from_xyz(rough_tilted_face(12_000, seed=3), source="face")
    exact = build_report(cloud, [0.25])
    assert all(vg.method in ("fft", "pairs") for vg in exact.sections[0].variograms.values())
    assert "exact over every pair" in report_html(exact)
    # the cost model of a fine grid of a big scan: neither exact method fits
    monkeypatch.setattr(variogram, "FRAME_SECONDS", 1.0)
    monkeypatch.setattr(variogram, "PAIR_SECONDS", 1.0)
    monkeypatch.setattr(variogram, "PAIR_SECONDS_COMPILED", 1.0)
    report = build_report(cloud, [0.25])
    data = report_json(report)
    result = grid_roughness(cloud, 0.25)
    odr = data["grids"][0]["models"]["odr"]["semivariogram"]
    assert odr["method"] == "sample"
    se = np.array(odr["gamma_normalised_se"], dtype=float)
    gamma = np.array(odr["gamma_normalised"], dtype=float)
    assert np.all(se > 0) and len(se) == len(gamma) == len(odr["sampled_pairs"])
    assert len(odr["gamma_se"]) == len(gamma)
    # the estimate is near the exact semivariogram of the same map, within its errors
    ref = semivariogram(result.ijk, analysed_values(result, "odr"), 0.25, method="pairs")
    assert ref.lag.shape == gamma.shape
    z = (gamma - ref.gamma_normalised) / se
    assert np.sqrt(np.mean(z * z)) < 2.0
    page = report_html(report)
    assert "random sample" in page and "standard error" in page
    for entry in data["grids"][0]["models"].values():
        assert entry["semivariogram"]["method"] == "sample"
