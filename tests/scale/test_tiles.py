"""A COPC file by its index (scale/tiles.py): cells by spatial tiles equal to the
in-memory path, every point decoded once, the same bits on Dask, damaged files one
line."""

from __future__ import annotations

import struct

import numpy as np
import pytest

pytest.importorskip("lazrs")

from rough_viewer.cli import main  # noqa: E402
from rough_viewer.grid.roughness import grid_roughness  # noqa: E402
from rough_viewer.io import PointCloud, load_points, write_las  # noqa: E402
from rough_viewer.io.copc import reader  # noqa: E402
from rough_viewer.io.copc.reader import is_copc, open_copc  # noqa: E402
from rough_viewer.scale import chunked_roughness, open_sources  # noqa: E402
from rough_viewer.scale.tiles import copc_roughness, plan_tiles  # noqa: E402
from rough_viewer.vocabulary import InputError  # noqa: E402
from tests.helpers import UTM, random_rotation, rough_surface  # noqa: E402
from tests.scale.helpers_scale import assert_same_cells  # noqa: E402

GRIDS = (0.4, 0.15)
TILE = 6_000  # points a tile: many tiles, many seams


def _survey(folder, n, *, seed, turn=None, parts=4):
    """A rough face at UTM coordinates in ``parts`` overlapping LAZ scans (the
    same scale and offset), indexed into one COPC file; the points as read back."""
    xyz = rough_surface(n, seed=seed, size=6.0) @ random_rotation(seed).T * [1, 1, 0.3]
    if turn is not None:
        xyz = xyz @ turn.T
    xyz = xyz + UTM
    xyz = xyz[np.random.default_rng(seed).permutation(n)]
    paths = []
    for i, piece in enumerate(np.array_split(xyz, parts)):
        p = folder / f"scan{i}.laz"
        write_las(p, PointCloud.from_xyz(piece))
        paths.append(p)
    out = folder / "survey.copc.laz"
    assert main(["index", *map(str, paths), "--out", str(out), "--memory", "8MB",
                 "--quiet"]) == 0
    read = [load_points(p, cache=False) for p in paths]
    return paths, out, np.concatenate([np.column_stack([c.x, c.y, c.z]) for c in read])


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    return _survey(tmp_path_factory.mktemp("copc"), 60_000, seed=11)


def _run(path, grids=GRIDS, **kw):
    return copc_roughness(open_copc(path), open_sources([path])[0], grids, **kw)


def test_plan_cuts_the_tree_into_tiles_holding_every_node_once(survey):
    _, out, xyz = survey
    copc = open_copc(out)
    plan = plan_tiles(copc, TILE)
    rows = np.concatenate([plan.top, *plan.tiles])
    assert np.array_equal(np.sort(rows), np.arange(copc.nodes.shape[0]))
    assert plan.n_tiles > 8
    leaf_max = copc.nodes["count"].max()
    assert plan.points.max() <= max(TILE, leaf_max)
    assert plan.points.sum() + copc.nodes["count"][plan.top].sum() == xyz.shape[0]


def test_cells_equal_the_in_memory_path(survey):
    _, out, xyz = survey
    res = _run(out, tile_points=TILE)
    for g, r in zip(GRIDS, res, strict=True):
        ref = grid_roughness(xyz, g, engine="numpy")
        assert r.point_cell.size == 0
        assert_same_cells(r, ref, rtol=1e-12)


def test_cells_equal_the_streamed_inputs(survey):
    paths, out, _ = survey
    res = _run(out, tile_points=TILE, memory_bytes=None)
    ref = chunked_roughness(open_sources(paths), GRIDS, chunk_points=7_000)
    for r, s in zip(res, ref, strict=True):
        assert_same_cells(r, s, rtol=1e-12)


def test_each_point_decoded_once(survey, monkeypatch):
    _, out, xyz = survey
    monkeypatch.setenv("ROUGH_VIEWER_ISOLATE", "0")  # decode in this process, to count
    seen: list[np.ndarray] = []
    real = reader.decode_integers

    def counting(copc, rows):
        seen.append(np.asarray(rows))
        return real(copc, rows)

    monkeypatch.setattr(reader, "decode_integers", counting)
    progress = []
    _run(out, tile_points=TILE, progress=lambda d, t: progress.append((d, t)))
    rows = np.concatenate(seen)
    copc = open_copc(out)
    assert np.array_equal(np.sort(rows), np.arange(copc.nodes.shape[0]))  # once each
    assert copc.nodes["count"][rows].sum() == xyz.shape[0]
    assert progress[-1] == (xyz.shape[0], xyz.shape[0])
    assert len(seen) > 8


def test_a_turned_face_picks_its_axis_after_the_tiles(tmp_path):
    """The face turned to stand in the y-z plane: the dependent axis (from the
    whole cloud's plane, known only at the end) is x, and OLS is that axis's."""
    turn = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    _, out, xyz = _survey(tmp_path, 30_000, seed=3, turn=turn)
    for axis in ("auto", "y"):
        res = _run(out, (0.3,), tile_points=4_000, axis=axis)[0]
        ref = grid_roughness(xyz, 0.3, axis=axis, engine="numpy")
        assert res.axis == ref.axis == ("x" if axis == "auto" else "y")
        assert_same_cells(res, ref, rtol=1e-12)


@pytest.mark.parametrize("models", [("ols",), ("hybrid",), ("odr",)])
def test_model_subsets_and_signed_residual(survey, models):
    _, out, xyz = survey
    res = _run(out, (0.4,), tile_points=TILE, models=models, residual="signed")[0]
    ref = grid_roughness(xyz, 0.4, models=models, residual="signed", engine="numpy")
    assert_same_cells(res, ref, rtol=1e-12)


def test_everything_in_one_tile_when_it_fits(survey):
    _, out, xyz = survey
    res = _run(out, (0.4,))[0]
    assert plan_tiles(open_copc(out), 4_000_000).n_tiles == 1
    assert_same_cells(res, grid_roughness(xyz, 0.4, engine="numpy"), rtol=1e-12)


def test_process_pool_and_threads_same_bits(survey):
    from rough_viewer.scale.dask_runner import DaskRunner

    _, out, _ = survey
    one = _run(out, tile_points=TILE)
    for scheduler in ("processes", "threads"):
        with DaskRunner(scheduler, workers=2) as runner:
            res = _run(out, tile_points=TILE, runner=runner)
        for a, b in zip(res, one, strict=True):
            for name in ("theta_odr", "theta_ols", "theta_hybrid", "normal", "n_points"):
                np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_local_cluster_equals_one_process(survey):
    distributed = pytest.importorskip("distributed")
    from rough_viewer.scale.dask_runner import DaskRunner

    _, out, xyz = survey
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                       silence_logs=40)
    try:
        with distributed.Client(cluster) as client:
            res = _run(out, tile_points=TILE, runner=DaskRunner(client=client))
    finally:
        cluster.close()
    for g, r, s in zip(GRIDS, res, _run(out, tile_points=TILE), strict=True):
        np.testing.assert_array_equal(r.theta_odr, s.theta_odr)
        assert_same_cells(r, grid_roughness(xyz, g, engine="numpy"), rtol=1e-12)


def test_cli_compute_on_the_copc_equals_compute_on_the_scans(survey, tmp_path):
    paths, out, _ = survey
    a, b = tmp_path / "copc.csv", tmp_path / "scans.csv"
    assert is_copc(out) and not is_copc(paths[0])
    assert main(["compute", str(out), "--grid", "0.4", "--memory", "256MB", "--out", str(a),
                 "--quiet"]) == 0
    assert main(["compute", *map(str, paths), "--grid", "0.4", "--memory", "256MB",
                 "--out", str(b), "--quiet"]) == 0
    ta = np.genfromtxt(a, delimiter=",", names=True)
    tb = np.genfromtxt(b, delimiter=",", names=True)
    assert ta.dtype.names == tb.dtype.names and ta.shape == tb.shape
    for name in ta.dtype.names:
        np.testing.assert_allclose(ta[name], tb[name], rtol=1e-9, atol=1e-12, err_msg=name)


# ----------------------------------------------------------------------------- damaged


def _hierarchy_at(path):
    """(byte of the root hierarchy page, its size) from the COPC info VLR."""
    data = path.read_bytes()
    root_at, root_size = struct.unpack_from("<2Q", data, 375 + 54 + 5 * 8)
    return data, root_at, root_size


def _damaged(survey, tmp_path, how):
    _, out, _ = survey
    data, root_at, root_size = _hierarchy_at(out)
    buf = bytearray(data)
    entry = root_at + 32 * 3  # the fourth node
    if how == "past the end":
        struct.pack_into("<Q", buf, entry + 16, len(buf) + 4096)
    elif how == "loop":
        # the entry becomes a pointer to a child page: the root page itself
        struct.pack_into("<Qii", buf, entry + 16, root_at, root_size, -1)
    elif how == "bad chunk":
        first = int(open_copc(out).nodes["offset"][0])
        buf[first:first + 64] = b"\xff" * 64
    p = tmp_path / f"{how.replace(' ', '-')}.copc.laz"
    p.write_bytes(bytes(buf))
    return p


@pytest.mark.parametrize("how,says", [("past the end", "past the end"),
                                      ("loop", "a loop")])
def test_damaged_hierarchy_is_one_line(survey, tmp_path, capsys, how, says):
    p = _damaged(survey, tmp_path, how)
    with pytest.raises(InputError, match=says):
        open_copc(p)
    out = tmp_path / "cells.csv"
    assert main(["compute", str(p), "--grid", "0.4", "--memory", "256MB", "--out", str(out),
                 "--quiet"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(p) in err and says in err
    assert "Traceback" not in err and not out.exists()


def test_damaged_chunk_is_one_line_from_the_child(survey, tmp_path, capsys):
    p = _damaged(survey, tmp_path, "bad chunk")
    out = tmp_path / "cells.csv"
    assert main(["compute", str(p), "--grid", "0.4", "--memory", "256MB", "--out", str(out),
                 "--quiet"]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and p.name in err and "Traceback" not in err
    assert not out.exists()


def _numbers(path):
    import csv

    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], [[float(v) if v not in ("", "nan") else np.nan for v in r]
                     if all(_is_number(v) for v in r) else r for r in rows[1:]]


def _is_number(v):
    try:
        float(v)
    except ValueError:
        return v == ""
    return True


@pytest.mark.parametrize("command", [
    ["zones", "--grid", "0.4", "--threshold", "0.02"],
    ["sets", "--grid", "0.4"],
])
def test_other_commands_read_the_copc_as_the_scans(survey, tmp_path, command):
    """Every command reads a COPC file as it reads the scans it came from (in memory:
    the same points in another order, so the same numbers to round-off)."""
    paths, out, _ = survey
    a, b = tmp_path / "copc.csv", tmp_path / "scans.csv"
    name, *opts = command
    assert main([name, str(out), *opts, "--out", str(a), "--quiet"]) == 0
    assert main([name, *map(str, paths), *opts, "--out", str(b), "--quiet"]) == 0
    ha, ra = _numbers(a)
    hb, rb = _numbers(b)
    assert ha == hb and len(ra) == len(rb) and len(ra) > 0
    # a joint's profiles are sampled from its points in file order (the shear-strength
    # columns move by a few per mille with the order); every other column is the same
    keep = [i for i, h in enumerate(ha) if not h.startswith(("theta_max", "delta_t", "jrc"))]
    for x, y in zip(ra, rb, strict=True):
        if all(isinstance(v, float) for v in x):
            np.testing.assert_allclose(np.take(x, keep), np.take(y, keep), rtol=1e-9, atol=1e-9)
        else:
            assert x == y


@pytest.mark.parametrize("field,shift", [(187, -1.0), (179, -1.0)])
def test_a_header_box_that_lies_costs_a_second_read_not_wrong_cells(survey, tmp_path, field,
                                                                     shift):
    """The header's minimum x 1 m below the points' (the grid's origin follows the
    minimum), or its maximum x 1 m inside them (points outside the grid): the first
    read finds the box off, the second gives the cells of the in-memory path."""
    _, out, xyz = survey
    data = bytearray(out.read_bytes())
    value = struct.unpack_from("<d", data, field)[0]  # LAS header: max x at 179, min x at 187
    struct.pack_into("<d", data, field, value + shift)
    bad = tmp_path / "bad-box.copc.laz"
    bad.write_bytes(bytes(data))
    seen = []
    res = _run(bad, (0.4,), tile_points=TILE, progress=lambda d, t: seen.append((d, t)))[0]
    assert_same_cells(res, grid_roughness(xyz, 0.4, engine="numpy"), rtol=1e-12)
    assert seen[-1][1] == 2 * xyz.shape[0]


def test_zones_by_tiles_equal_zones_in_memory(survey, tmp_path):
    """zones --memory on the COPC (cells by tiles) gives the zones of the scans in
    memory."""
    paths, out, _ = survey
    a, b = tmp_path / "tiles.csv", tmp_path / "memory.csv"
    ca, cb = tmp_path / "tiles-cells.csv", tmp_path / "memory-cells.csv"
    opts = ["--grid", "0.4", "--threshold", "0.02", "--quiet"]
    assert main(["zones", str(out), *opts, "--memory", "256MB", "--out", str(a),
                 "--cells-out", str(ca)]) == 0
    assert main(["zones", *map(str, paths), *opts, "--out", str(b), "--cells-out", str(cb)]) == 0
    for x, y in ((a, b), (ca, cb)):
        hx, rx = _numbers(x)
        hy, ry = _numbers(y)
        assert hx == hy and len(rx) == len(ry) > 0
        np.testing.assert_allclose(np.array(rx, dtype=float), np.array(ry, dtype=float),
                                   rtol=1e-9, atol=1e-12)
