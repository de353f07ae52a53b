"""The report for a cloud and settings, as the app's Export folder will ask for it."""

from __future__ import annotations

import json

import pytest

from rough_viewer.io import PointCloud
from rough_viewer.report.export import ReportSettings, compute_report, report_page, write_report
from rough_viewer.vocabulary import InputError
from tests.helpers import rough_surface


@pytest.fixture(scope="module")
def cloud() -> PointCloud:
    return PointCloud.from_xyz(rough_surface(20_000, seed=6, size=4.0), source="face.xyz")


def test_report_page_follows_the_settings(cloud):
    settings = ReportSettings(min_points=5, grid_sizes=(0.5, 0.25), axis="z", threshold=0.2)
    page = report_page(cloud, settings)
    assert '<section id="grid-0_5"' in page and '<section id="grid-0_25"' in page
    assert "<td>binary threshold</td><td>0.2 (normalised roughness;" in page
    assert "<td>min points per cell</td><td>5</td>" in page
    assert "Binary transform at 0.2" in page


def test_report_numbers_match_the_settings(cloud, tmp_path):
    settings = ReportSettings(min_points=4, grid_sizes=(0.5,), axis="auto", threshold=0.05)
    report = compute_report(cloud, settings)
    assert report.min_points == 4 and report.sections[0].result.min_points == 4
    path = write_report(tmp_path / "r.json", report, "json")
    data = json.loads(path.read_text())
    assert data["grids"][0]["grid_size"] == 0.5
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]


@pytest.mark.parametrize("bad, message", [
    ({"grid_sizes": ()}, "at least one grid size"),
    ({"grid_sizes": (0.5, float("nan"))}, "grid size must be a positive"),
    ({"threshold": -0.1}, "threshold must lie in [0, 1]"),
    ({"min_points": 2}, "min points must be a whole number of at least 3"),
    ({"axis": "w"}, "unknown dependent axis"),
])
def test_bad_settings_are_one_line(cloud, bad, message):
    settings = ReportSettings(**{"min_points": 4, **bad})
    with pytest.raises(InputError) as info:
        report_page(cloud, settings)
    assert message in str(info.value)
