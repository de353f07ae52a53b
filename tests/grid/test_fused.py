"""The fused pass of the compiled engine (keys, counts and moments in one pass over a
dense grid, the keys turned into rows by the distance pass), the bounds noted per
cloud, and coarsened presets whose rows the distance pass makes: against the NumPy
reference, to the last bit where the arithmetic is the same."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.grid import cells, fast
from rough_viewer.grid.roughness import coarsen_prepared, grid_roughness, prepare_grid
from rough_viewer.io.cloud import PointCloud, known_bounds, note_bounds
from rough_viewer.vocabulary import InputError
from tests.helpers import UTM, random_rotation, rough_surface

pytestmark = pytest.mark.skipif(not fast.available(), reason="numba is not installed")

FIELDS = ("ijk", "n_points", "point_cell", "centroid", "normal", "theta_odr", "theta_ols",
          "theta_hybrid", "e_ols")


def assert_bits(got, ref):
    assert got.axis == ref.axis
    for name in FIELDS:
        a, b = getattr(got, name), getattr(ref, name)
        assert a.shape == b.shape, name
        np.testing.assert_array_equal(a, b, err_msg=name)  # NaN where NaN, else equal


@pytest.fixture
def spy(monkeypatch):
    """Counts the fused passes and the bounds passes."""
    calls = {"fused": 0, "bounds": 0}
    fused, bounds_at = fast.fused_index_and_moments, fast.bounds_at

    def counted_fused(*a, **k):
        calls["fused"] += 1
        return fused(*a, **k)

    def counted_bounds(*a, **k):
        calls["bounds"] += 1
        return bounds_at(*a, **k)

    monkeypatch.setattr(fast, "fused_index_and_moments", counted_fused)
    monkeypatch.setattr(fast, "bounds_at", counted_bounds)
    return calls


def scan_face(n: int, seed: int) -> PointCloud:
    """A tilted rough face at UTM coordinates, stored in scan columns (long runs of
    one cell), with a sparse fringe: a few scattered points far from the face make
    cells of 1-3 points and leave most of the bounding grid empty."""
    rng = np.random.default_rng(seed)
    face = rough_surface(n, seed=seed, size=6.0) @ random_rotation(seed).T
    order = np.lexsort((face[:, 2], np.floor(face[:, 0] / 0.05)))
    fringe = rng.uniform(face.min(axis=0) - 1.0, face.max(axis=0) + 1.0, (40, 3))
    xyz = np.vstack([face[order], fringe]) + UTM
    return PointCloud.from_xyz(xyz)


@pytest.mark.parametrize("g", [0.15, 0.25, 0.6, 1.5])
def test_fused_pass_gives_the_reference_bits_on_a_tilted_face(g, spy):
    cloud = scan_face(60_000, seed=3)
    ref = grid_roughness(cloud, g, engine="numpy")
    got = grid_roughness(cloud, g, engine="numba")
    assert spy["fused"] == 1
    assert_bits(got, ref)
    assert (ref.n_points <= 3).sum() > 5 and np.isfinite(ref.theta_odr).sum() > 10


def test_several_blocks_shuffled_and_on_one_thread_give_the_reference_bits(spy):
    """More points than one chunk (2**21): the blocks' sums added in block order on one
    thread or two; a shuffled cloud (a new cell at almost every point) too."""
    n = cells._chunk_size(0) + 70_001
    xyz = rough_surface(n, seed=8, size=3.0) @ random_rotation(2).T + UTM
    for cloud in (xyz, xyz[np.random.default_rng(1).permutation(n)]):
        ref = grid_roughness(cloud, 0.3, engine="numpy")
        with fast.threads(1):
            one = grid_roughness(cloud, 0.3, engine="numba")
        two = grid_roughness(cloud, 0.3, engine="numba")
        assert_bits(one, ref)
        assert_bits(two, ref)
    assert spy["fused"] == 4


def test_prepare_grid_through_the_fused_pass_has_rows_not_keys(spy):
    cloud = scan_face(20_000, seed=5)
    prep = prepare_grid(cloud, 0.25, engine="numba")
    assert spy["fused"] == 1
    ref_index = cells.index_points(cloud.x, cloud.y, cloud.z, prep.index.grid, engine="numpy")
    ref = cells.cell_moments(cloud.x, cloud.y, cloud.z, ref_index, engine="numpy")
    np.testing.assert_array_equal(prep.index.point_cell, ref_index.point_cell)
    np.testing.assert_array_equal(prep.index.ijk, ref_index.ijk)
    np.testing.assert_array_equal(prep.moments.s1, ref.s1)
    np.testing.assert_array_equal(prep.moments.s2, ref.s2)


def test_an_origin_given_and_a_grid_too_big_for_the_fused_pass(spy):
    cloud = scan_face(20_000, seed=6)
    origin = UTM - [0.37, 0.11, 0.05]
    assert_bits(grid_roughness(cloud, 0.2, origin=origin, engine="numba"),
                grid_roughness(cloud, 0.2, origin=origin, engine="numpy"))
    assert spy["fused"] == 1
    wide = cloud.xyz()
    wide[0] += 3000.0  # one far point: 1e9 grid cells, the two-pass kernels
    assert_bits(grid_roughness(wide, 0.2, engine="numba"),
                grid_roughness(wide, 0.2, engine="numpy"))
    assert spy["fused"] == 1


def test_later_grids_skip_the_bounds_pass_and_a_changed_cloud_is_seen(spy):
    cloud = scan_face(30_000, seed=7)
    first = grid_roughness(cloud, 0.5, engine="numba")
    assert spy == {"fused": 1, "bounds": 1}
    lo, hi, at = known_bounds(cloud.x, cloud.y, cloud.z)
    np.testing.assert_array_equal(lo, cloud.xyz().min(axis=0))
    np.testing.assert_array_equal(hi, cloud.xyz().max(axis=0))
    assert cloud.x[at[0]] == lo[0] and cloud.z[at[5]] == hi[2]
    again = grid_roughness(cloud, 0.25, engine="numba")
    assert spy == {"fused": 2, "bounds": 1}  # the noted bounds, checked by the pass
    assert_bits(again, grid_roughness(cloud, 0.25, engine="numpy"))
    assert_bits(first, grid_roughness(cloud, 0.5, engine="numpy"))

    # a point moved beyond the box in place, the six face points untouched: the
    # fused pass finds it outside and the bounds are taken again
    free = next(i for i in range(cloud.n) if i not in set(at.tolist()))
    cloud.y[free] = hi[1] + 0.3
    moved = grid_roughness(cloud, 0.25, engine="numba")
    assert spy["bounds"] == 2
    assert_bits(moved, grid_roughness(cloud, 0.25, engine="numpy"))
    # a face point moved inward: the noted box is not the points' any more
    cloud.x[at[0]] += 0.2
    inward = grid_roughness(cloud, 0.25, engine="numba")
    assert spy["bounds"] == 3
    assert_bits(inward, grid_roughness(cloud, 0.25, engine="numpy"))


def test_a_wrong_box_noted_changes_nothing_and_nan_is_refused(spy):
    cloud = scan_face(20_000, seed=9)
    xyz = cloud.xyz()
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    at = np.concatenate([xyz.argmin(axis=0), xyz.argmax(axis=0)])
    note_bounds(cloud.x, cloud.y, cloud.z, lo - 1.0, hi, at)  # not on its faces
    assert_bits(grid_roughness(cloud, 0.3, engine="numba"),
                grid_roughness(cloud, 0.3, engine="numpy"))
    assert spy["bounds"] == 1
    note_bounds(cloud.x, cloud.y, cloud.z, lo, hi, at)
    cloud.z[11] = np.nan  # the noted box still has its face points
    with pytest.raises(InputError, match="too small"):
        grid_roughness(cloud, 0.3, engine="numba")
    assert spy["fused"] == 2 and spy["bounds"] == 2


@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_coarsened_presets_make_their_rows_in_the_distance_pass(engine, spy):
    cloud = scan_face(40_000, seed=4)
    fine = prepare_grid(cloud, 0.125, engine=engine)
    fine_rows = fine.index.point_cell.copy()
    two = coarsen_prepared(fine, 2, defer_rows=True)
    eight = coarsen_prepared(two, 4, defer_rows=True)  # coarsened twice: 8 times the finest
    now = coarsen_prepared(two, 4)  # the rows gathered at once
    np.testing.assert_array_equal(now.index.point_cell, eight.point_cell())
    for prep, g in ((two, 0.25), (eight, 1.0)):
        assert prep.index.point_cell.shape == (0,) and prep.fine_cell is fine.index.point_cell
        direct = grid_roughness(cloud, g, engine=engine)
        res = grid_roughness(cloud, g, prepared=prep, engine=engine)
        np.testing.assert_array_equal(res.ijk, direct.ijk)
        np.testing.assert_array_equal(res.n_points, direct.n_points)
        np.testing.assert_array_equal(res.point_cell, direct.point_cell)
        np.testing.assert_array_equal(prep.point_cell(), direct.point_cell)
        for name in ("odr", "ols", "hybrid", "e_ols"):  # regrouped sums: round-off
            np.testing.assert_allclose(res.values(name), direct.values(name), rtol=1e-9,
                                       atol=1e-12)
        np.testing.assert_allclose(res.centroid, direct.centroid, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(fine.index.point_cell, fine_rows)  # left as it was


def test_the_npy_reader_notes_the_bounds_it_saw(tmp_path):
    from rough_viewer.io import load_points

    xyz = rough_surface(300_001, seed=2) + UTM
    np.save(tmp_path / "c.npy", xyz)
    cloud = load_points(tmp_path / "c.npy")
    lo, hi, at = known_bounds(cloud.x, cloud.y, cloud.z)
    np.testing.assert_array_equal(lo, xyz.min(axis=0))
    np.testing.assert_array_equal(hi, xyz.max(axis=0))
    np.testing.assert_array_equal(at, np.concatenate([xyz.argmin(axis=0), xyz.argmax(axis=0)]))
    np.save(tmp_path / "f.npy", np.asfortranarray(xyz))
    fortran = load_points(tmp_path / "f.npy")
    np.testing.assert_array_equal(known_bounds(fortran.x, fortran.y, fortran.z)[0], lo)
    xyz[200_000, 1] = np.inf  # in the second block
    np.save(tmp_path / "inf.npy", xyz)
    dropped = load_points(tmp_path / "inf.npy")
    assert dropped.n == 300_000 and dropped.dropped_nonfinite == 1
    assert known_bounds(dropped.x, dropped.y, dropped.z) is None
