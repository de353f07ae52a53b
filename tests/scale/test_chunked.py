"""Out-of-core grid roughness (scale/chunked.py) equals the in-memory path."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.io import PointCloud, write_las
from rough_viewer.scale import chunk_plan, chunked_roughness, open_sources, parse_bytes, read_chunk
from rough_viewer.scale.partials import Partial, TreeReducer, merge, reduce_partials
from rough_viewer.vocabulary import InputError
from tests.helpers import UTM
from tests.scale.helpers_scale import assert_same_cells, split_files


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return split_files(tmp_path_factory.mktemp("split"))


@pytest.mark.parametrize("engine", ["numpy", "numba"])
@pytest.mark.parametrize("chunk_points", [997, 5000])
def test_chunks_across_files_equal_in_memory(files, engine, chunk_points):
    paths, xyz = files
    sources = open_sources(paths)
    assert len(chunk_plan(sources, chunk_points)) > len(paths)  # chunks inside every file
    grids = (0.4, 0.25, 0.1)
    results = chunked_roughness(sources, grids, chunk_points=chunk_points, engine=engine)
    for g, res in zip(grids, results, strict=True):
        ref = grid_roughness(xyz, g, engine="numpy")
        assert_same_cells(res, ref)
        assert res.point_cell.shape == (0,)
        # most cells really are made of points from several files
        file_of_point = np.repeat(np.arange(3), [s.n_points for s in sources])
        pairs = np.unique(np.column_stack([ref.point_cell, file_of_point]), axis=0)
        straddling = np.count_nonzero(np.bincount(pairs[:, 0]) > 1)
        assert straddling > 0.5 * ref.n_cells


def test_options_carry_over(files):
    paths, xyz = files
    origin = UTM - 0.05
    kw = dict(origin=origin, min_points=5, axis="z", models=("ols", "hybrid"),
              residual="signed")
    res = chunked_roughness(open_sources(paths), [0.3], chunk_points=3000, **kw)[0]
    assert_same_cells(res, grid_roughness(xyz, 0.3, **kw))
    assert np.isnan(res.theta_odr).all() and res.min_points == 5


def test_same_file_twice_doubles_counts_not_roughness(files):
    paths, _ = files
    one = chunked_roughness(open_sources(paths[:1]), [0.5], chunk_points=2000)[0]
    two = chunked_roughness(open_sources([paths[0], paths[0]]), [0.5], chunk_points=2000)[0]
    np.testing.assert_array_equal(two.n_points, 2 * one.n_points)
    ok = np.isfinite(one.theta_odr) & np.isfinite(two.theta_odr)
    np.testing.assert_allclose(two.theta_odr[ok], one.theta_odr[ok], rtol=1e-9)


def _patch_header(path, field_offset, value):
    with open(path, "r+b") as fh:
        fh.seek(field_offset)
        fh.write(struct.pack("<d", value))


@pytest.mark.parametrize("where", ["min_x_too_small", "max_x_too_small"])
def test_wrong_header_bounds_are_measured_and_pass_repeated(tmp_path, files, where):
    """A header whose box is wrong (stale or rounded) must not shift or drop cells."""
    paths, xyz = files
    pts = xyz[:5000]
    p = tmp_path / "bad.las"
    write_las(p, PointCloud.from_xyz(pts))
    # LAS 1.2 header: max x at byte 179, min x at 187
    if where == "min_x_too_small":
        _patch_header(p, 187, float(pts[:, 0].min()) - 0.123)
    else:
        _patch_header(p, 179, float(pts[:, 0].max()) - 0.5)
    src = open_sources([p])
    seen = []
    res = chunked_roughness(src, [0.25], chunk_points=1000,
                            progress=lambda d, t: seen.append((d, t)))[0]
    ref = grid_roughness(np.column_stack(read_chunk(src[0], chunk_plan(src, 10**9)[0])), 0.25)
    assert_same_cells(res, ref)
    assert seen[-1] == (3 * 5000, 3 * 5000)  # three passes over the points


def test_memory_budget_sizes_chunks_and_refuses_too_little(files, monkeypatch):
    paths, _ = files
    sources = open_sources(paths)
    assert parse_bytes("2GB") == 2_000_000_000 and parse_bytes("1.5GiB") == 1.5 * 2**30
    with pytest.raises(InputError, match="too small"):
        chunked_roughness(sources, [0.5], memory_bytes=parse_bytes("20MB"))
    with pytest.raises(InputError, match="--memory"):
        parse_bytes("lots")
    res = chunked_roughness(sources, [0.5], memory_bytes=parse_bytes("300MB"))[0]
    assert res.n_cells > 0
    # cells whose tables cannot fit the budget's share are refused, not allocated
    # (bytes per cell inflated: a test cloud small enough to run has too few cells)
    from rough_viewer.scale import chunked

    monkeypatch.setattr(chunked, "BYTES_PER_CELL", 10**5)
    with pytest.raises(InputError, match="cell tables"):
        chunked_roughness(sources, [0.05], memory_bytes=parse_bytes("300MB"))


def test_partials_merge_adds_rows_by_key():
    a = Partial(np.array([1, 4, 9]), np.array([[1.0], [2.0], [3.0]]), 3)
    b = Partial(np.array([0, 4, 10]), np.array([[10.0], [20.0], [30.0]]), 4)
    m = merge(a, b)
    np.testing.assert_array_equal(m.keys, [0, 1, 4, 9, 10])
    np.testing.assert_array_equal(m.values[:, 0], [10, 1, 22, 3, 30])
    assert m.n_points == 7
    parts = [Partial(np.array([k % 3]), np.array([[0.1 * k]]), 1) for k in range(11)]
    red = TreeReducer()
    for p in parts:
        red.add(p)
    tree = reduce_partials(parts)
    np.testing.assert_array_equal(red.result().values, tree.values)  # the same tree, bit for bit
    np.testing.assert_allclose(tree.values[:, 0], [0.1 * sum(range(0, 11, 3)),
                                                   0.1 * sum(range(1, 11, 3)),
                                                   0.1 * sum(range(2, 11, 3))])


def test_text_files_join_las_files(tmp_path, files):
    paths, xyz = files
    n0 = open_sources(paths[:1])[0].n_points
    np.savetxt(tmp_path / "rest.xyz", xyz[n0:], fmt="%.4f")
    sources = open_sources([paths[0], tmp_path / "rest.xyz"])
    assert [s.streamed for s in sources] == [True, False]
    res = chunked_roughness(sources, [0.5], chunk_points=4000)[0]
    ref = grid_roughness(np.vstack([xyz[:n0], np.loadtxt(tmp_path / "rest.xyz")]), 0.5)
    assert_same_cells(res, ref)


def test_bad_inputs_name_the_file(tmp_path, files):
    paths, _ = files
    with pytest.raises(InputError, match="file not found"):
        open_sources([paths[0], tmp_path / "nope.laz"])
    (tmp_path / "junk.laz").write_bytes(b"not a las file at all")
    with pytest.raises(InputError, match="junk.laz"):
        open_sources([tmp_path / "junk.laz"])


def test_decode_cache_filled_by_pass_one_serves_pass_two_and_load_points(files, tmp_path,
                                                                          monkeypatch):
    from rough_viewer.io import load_points
    from rough_viewer.io.cache import cached_points

    monkeypatch.setenv("ROUGH_VIEWER_CACHE", str(tmp_path / "cache"))
    paths, xyz = files
    sources = open_sources(paths)
    assert all(cached_points(p) is None for p in paths)
    first = chunked_roughness(sources, [0.3], chunk_points=3000)[0]
    assert [cached_points(p) for p in paths] == [s.n_points for s in sources]
    again = chunked_roughness(sources, [0.3], chunk_points=3000)[0]   # all from the cache
    np.testing.assert_array_equal(again.theta_odr, first.theta_odr)
    assert_same_cells(first, grid_roughness(xyz, 0.3))
    for p in paths:  # the entry is the one load_points writes and reads
        cached, decoded = load_points(p), load_points(p, cache=False)
        np.testing.assert_array_equal(cached.x, decoded.x)
        np.testing.assert_array_equal(cached.z, decoded.z)
        np.testing.assert_array_equal(cached.intensity, decoded.intensity)
