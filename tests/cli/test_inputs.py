"""Several inputs as one cloud on the command line: lists, quoted globs, CRS and unit
checks, the same numbers streamed (--memory) as in memory."""

from __future__ import annotations

import csv

import laspy
import numpy as np
import pytest

from rough_viewer.cli import main
from rough_viewer.cli._inputs import expand_inputs
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.vocabulary import InputError
from tests.scale.helpers_scale import split_files

WKT_UTM10 = ('PROJCS["WGS 84 / UTM zone 10N",GEOGCS["WGS 84",UNIT["degree",0.0174532925199433]],'
             'UNIT["metre",1],AUTHORITY["EPSG","32610"]]')
WKT_UTM11 = WKT_UTM10.replace("10N", "11N").replace("32610", "32611")
WKT_FT = ('PROJCS["NAD83 / California zone 3 (ftUS)",GEOGCS["NAD83",UNIT["degree",0.0174532925199433]],'
          'UNIT["US survey foot",0.304800609601219],AUTHORITY["EPSG","2227"]]')


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return split_files(tmp_path_factory.mktemp("inputs"), n=12_000)


def rows(path):
    with open(path, newline="") as fh:
        return list(csv.reader(fh))


def test_glob_and_list_are_one_merged_cloud(files, tmp_path, capsys):
    paths, xyz = files
    folder = paths[0].parent
    out_g, out_l, out_m = tmp_path / "g.csv", tmp_path / "l.csv", tmp_path / "m.csv"
    assert main(["compute", str(folder / "part*.laz"), "--grid", "0.5", "--out", str(out_g),
                 "--quiet"]) == 0
    assert "3 files" in capsys.readouterr().out
    assert main(["compute", *map(str, paths), "--grid", "0.5", "--out", str(out_l),
                 "--quiet"]) == 0
    assert out_g.read_text() == out_l.read_text()
    ref = grid_roughness(xyz, 0.5)
    body = rows(out_g)[1:]
    assert len(body) == np.count_nonzero(ref.n_points >= 3)
    assert sum(int(r[6]) for r in body) == ref.n_points[ref.n_points >= 3].sum()
    by_key = {tuple(int(v) for v in r[:3]): r for r in body}
    for i in np.flatnonzero(np.isfinite(ref.theta_odr))[:50]:
        assert float(by_key[tuple(ref.ijk[i])][7]) == ref.theta_odr[i]
    # streamed under a budget: the same cells, the same numbers to 1e-9
    assert main(["compute", *map(str, paths), "--grid", "0.5", "--memory", "300MB",
                 "--out", str(out_m), "--quiet"]) == 0
    a, b = rows(out_l)[1:], rows(out_m)[1:]
    assert [r[:7] for r in a] == [r[:7] for r in b]
    for ra, rb in zip(a, b, strict=True):
        for va, vb in zip(ra[7:10], rb[7:10], strict=True):
            assert (va == vb == "") or abs(float(va) - float(vb)) <= 1e-9 * abs(float(va)) + 1e-15


def test_report_takes_several_inputs(files, tmp_path):
    paths, _ = files
    out = tmp_path / "r.json"
    assert main(["report", *map(str, paths), "--grid", "0.5", "--format", "json",
                 "--out", str(out), "--quiet"]) == 0
    assert out.stat().st_size > 100


def test_expand_inputs_sorts_and_refuses_empty_globs(tmp_path):
    for name in ("b.xyz", "a.xyz", "c.txt"):
        (tmp_path / name).write_text("0 0 0\n")
    assert [p.name for p in expand_inputs([str(tmp_path / "*.xyz")])] == ["a.xyz", "b.xyz"]
    with pytest.raises(InputError, match="no files match"):
        expand_inputs([str(tmp_path / "*.laz")])


def _las(path, wkt, offset=0.0):
    hdr = laspy.LasHeader(point_format=1, version="1.2")
    hdr.scales = np.array([0.001, 0.001, 0.001])
    hdr.vlrs.append(laspy.VLR("LASF_Projection", 2112, "", wkt.encode() + b"\0"))
    las = laspy.LasData(hdr)
    rng = np.random.default_rng(len(str(path)))
    las.x, las.y, las.z = (rng.uniform(0, 10, 500) + offset for _ in range(3))
    las.write(str(path))
    return path


@pytest.mark.parametrize("other, message", [(WKT_UTM11, "EPSG:32611"), (WKT_FT, "us-ft")])
@pytest.mark.parametrize("memory", [False, True])
def test_different_crs_or_units_refused_one_line(tmp_path, capsys, other, message, memory):
    a = _las(tmp_path / "a.las", WKT_UTM10)
    b = _las(tmp_path / "b.las", other)
    argv = ["compute", str(a), str(b), "--grid", "1", "--out", str(tmp_path / "o.csv"),
            "--quiet"] + (["--memory", "300MB"] if memory else [])
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and message in err and "b.las" in err and "a.las" in err
    assert not (tmp_path / "o.csv").exists()


def test_same_crs_merges_and_a_bare_file_needs_units(tmp_path, capsys):
    """A file without CRS or unit beside files with one: refused (its unit would be a
    guess) unless --units says it, then merged with a warning."""
    a = _las(tmp_path / "a.las", WKT_UTM10)
    b = _las(tmp_path / "b.las", WKT_UTM10, offset=5.0)
    np.savetxt(tmp_path / "c.xyz", np.random.default_rng(0).uniform(0, 10, (300, 3)))
    argv = ["compute", str(a), str(b), str(tmp_path / "c.xyz"), "--grid", "2",
            "--out", str(tmp_path / "o.csv"), "--quiet"]
    for memory in ([], ["--memory", "300MB"]):
        assert main(argv + memory) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "c.xyz declares no CRS or unit but" in err
        assert "a.las is in EPSG:32610 (m): give --units" in err
        assert not (tmp_path / "o.csv").exists()
    assert main(argv + ["--units", "m"]) == 0
    err = capsys.readouterr().err
    assert "declares no CRS" in err and "EPSG:32610" in err


def test_clouds_that_do_not_overlap_are_flagged_once(tmp_path, capsys):
    """A UTM tile and a lab scan near the origin merged with --units: one warning that
    names the groups and the merged extent, on stderr and in SUMMARY.json."""
    import json

    a = _las(tmp_path / "a.las", WKT_UTM10, offset=500_000.0)
    np.savetxt(tmp_path / "lab.xyz", np.random.default_rng(0).uniform(0, 0.03, (300, 3)))
    for memory in ([], ["--memory", "300MB"]):
        js = tmp_path / f"s{len(memory)}.json"
        assert main(["compute", str(a), str(tmp_path / "lab.xyz"), "--units", "m", "--grid",
                     "2", "--summary-json", str(js), "--quiet", *memory]) == 0
        err = capsys.readouterr().err
        lines = [line for line in err.splitlines() if "do not overlap" in line]
        assert len(lines) == 1, err
        assert "they form 2 separate groups" in lines[0] and "a.las: " in lines[0]
        assert "the merged cloud is 866 km across" in lines[0]
        assert any("do not overlap" in w for w in json.loads(js.read_text())["warnings"]) \
            or memory  # the chunked path has no cloud warnings in its JSON
    # files side by side touch: no warning
    b = _las(tmp_path / "b.las", WKT_UTM10, offset=500_010.0)
    assert main(["compute", str(a), str(b), "--grid", "2", "--summary-json",
                 str(tmp_path / "t.json"), "--quiet"]) == 0
    assert "overlap" not in capsys.readouterr().err


def test_no_match_glob_exit_2(tmp_path, capsys):
    assert main(["compute", str(tmp_path / "*.laz"), "--grid", "1", "--out",
                 str(tmp_path / "o.csv")]) == 2
    assert "no files match" in capsys.readouterr().err


def test_zones_takes_several_inputs_as_one_cloud(files, tmp_path):
    paths, xyz = files
    np.save(tmp_path / "all.npy", xyz)
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["zones", *map(str, paths), "--grid", "0.25", "--out", str(a), "--quiet"]) == 0
    assert main(["zones", str(tmp_path / "all.npy"), "--grid", "0.25", "--out", str(b),
                 "--quiet"]) == 0
    ra, rb = rows(a), rows(b)
    assert len(ra) > 1 and ra == rb
