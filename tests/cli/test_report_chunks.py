"""``report --memory`` / ``--scheduler``: the report of a cloud streamed in chunks, or of
a COPC file by its tiles, has the numbers of the report in memory (every figure but
the joint sets, which need every point, and says so)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

pytest.importorskip("lazrs")

from rough_viewer.cli import main  # noqa: E402
from rough_viewer.io import PointCloud, write_las  # noqa: E402
from rough_viewer.report.build import NO_SETS_OUT_OF_CORE  # noqa: E402
from tests.helpers import UTM, random_rotation, rough_surface  # noqa: E402

GRIDS = ("--grid", "0.6", "--grid", "0.3")


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    """A rough face at UTM coordinates in 3 overlapping LAZ scans and their COPC index."""
    folder = tmp_path_factory.mktemp("survey")
    n = 120_000
    xyz = rough_surface(n, seed=5, size=8.0) @ random_rotation(5).T * [1, 1, 0.4] + UTM
    xyz = xyz[np.random.default_rng(5).permutation(n)]
    paths = []
    for i, piece in enumerate(np.array_split(xyz, 3)):
        p = folder / f"scan{i}.laz"
        write_las(p, PointCloud.from_xyz(piece))
        paths.append(str(p))
    copc = folder / "survey.copc.laz"
    assert main(["index", *paths, "--out", str(copc), "--memory", "8MB", "--quiet"]) == 0
    return folder, paths, str(copc)


def _report(folder, name, inputs, *extra):
    out = folder / f"{name}.json"
    assert main(["report", *inputs, *GRIDS, "--format", "json", "--out", str(out), "--quiet",
                 "--force", *extra]) == 0
    return json.loads(out.read_text())


def _same(a, b, where="", rtol=1e-9):
    """Every number of ``a`` equals ``b``'s to ``rtol`` (JSON trees)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), (where, set(a) ^ set(b))
        for k in a:
            _same(a[k], b[k], f"{where}.{k}", rtol)
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), (where, len(a), len(b))
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{where}[{i}]", rtol)
    elif isinstance(a, float) and isinstance(b, (int, float)):
        assert math.isclose(a, b, rel_tol=rtol, abs_tol=1e-12), (where, a, b)
    else:
        assert a == b, (where, a, b)


def _without_sets(rep):
    """The report's numbers less what only differs by design: the time made, the
    joint sets (and their figure error) and the input's name and path."""
    rep = json.loads(json.dumps(rep))
    rep.pop("created")
    rep["input"].pop("name")
    rep["input"].pop("path")
    for g in rep["grids"]:
        g.pop("sets", None)
        g.get("figure_errors", {}).pop("sets", None)
    return rep


@pytest.mark.parametrize("how", [("--memory", "20MB"), ("--scheduler", "threads",
                                                         "--workers", "2")])
def test_the_copc_by_tiles_reports_the_numbers_in_memory(survey, how):
    folder, paths, copc = survey
    ref = _report(folder, "memory", [copc])
    got = _report(folder, "tiles", [copc], *how)
    _same(_without_sets(got), _without_sets(ref))
    assert ref["grids"][0]["cells"]["with_value"] > 150
    assert got["input"]["points"] == 120_000
    for g in got["grids"]:
        assert "sets" not in g
        assert g["figure_errors"]["sets"] == NO_SETS_OUT_OF_CORE
        assert g["models"]["odr"]["semivariogram"]["n_cells"] > 100


def test_the_scans_streamed_report_the_numbers_in_memory(survey):
    folder, paths, _ = survey
    ref = _report(folder, "scans", paths)
    got = _report(folder, "scans-streamed", paths, "--memory", "256MB")
    _same(_without_sets(got), _without_sets(ref))


def test_the_html_report_by_tiles_says_why_it_has_no_sets(survey):
    folder, _, copc = survey
    out = folder / "tiles.html"
    assert main(["report", copc, *GRIDS, "--out", str(out), "--quiet", "--force",
                 "--memory", "20MB"]) == 0
    page = out.read_text()
    assert "rough-viewer sets" in page and "Table 1" in page


@pytest.mark.parametrize("extra, says", [
    ((), "give --grid"),
    (("--grid", "0.5", "--directions", "30"), "--directions"),
    (("--grid", "0.5", "--scanner", "0,0,0"), "scanner"),
    (("--grid", "0.5", "--crop", "0,0,0,1,1,1"), "--crop"),
])
def test_what_needs_every_point_is_refused_in_one_line(survey, capsys, extra, says):
    folder, _, copc = survey
    out = folder / "refused.json"
    assert main(["report", copc, "--memory", "20MB", "--out", str(out), "--quiet",
                 *extra]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0] and "Traceback" not in err[0]
    assert not out.exists()
