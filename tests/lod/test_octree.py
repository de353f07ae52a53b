"""The additive octree: every point in exactly one node, nodes and their ancestors
are the full cloud inside each cube, one point per sample cell, nodes capped."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.io import PointCloud
from rough_viewer.lod.octree import DEPTH_BITS, build_bytes, build_octree
from rough_viewer.vocabulary import InputError
from tests.lod.helpers import outcrop


@pytest.fixture(scope="module")
def cloud():
    return outcrop(120_000)


@pytest.fixture(scope="module")
def tree(cloud):
    return build_octree(cloud, root_grid=16, max_node_points=1_500)


def ancestors(tree, k):
    out = []
    while k >= 0:
        out.append(k)
        k = int(tree.parent[k])
    return out


def test_every_point_in_exactly_one_node(cloud, tree):
    assert tree.n_points == cloud.shape[0]
    assert np.array_equal(np.bincount(tree.order, minlength=cloud.shape[0]),
                          np.ones(cloud.shape[0], dtype=np.int64))
    assert int(tree.counts.sum()) == cloud.shape[0] and tree.counts.min() >= 1
    assert all(np.all(np.diff(tree.rows(k)) > 0) for k in range(tree.n_nodes))  # file order
    assert tree.n_nodes > 100 and tree.depth >= 4


def descendants(tree, k):
    out, todo = [], [k]
    while todo:
        a = todo.pop()
        out.append(a)
        todo.extend(tree.children(a))
    return out


def union_mask(tree, n, nodes):
    mask = np.zeros(n, dtype=bool)
    mask[np.concatenate([tree.rows(a) for a in nodes])] = True
    return mask


def cube_masks(tree, cloud, k):
    """Points strictly inside node k's cube, and points clearly outside it (points
    within 1e-9 of the extent of a face are neither)."""
    eps = 1e-9 * tree.side
    lo, hi = tree.cube_lo[k], tree.cube_lo[k] + tree.size[k]
    inside = np.all((cloud > lo + eps) & (cloud < hi - eps), axis=1)
    outside = np.any((cloud < lo - eps) | (cloud > hi + eps), axis=1)
    return inside, outside


def test_a_leaf_with_its_ancestors_is_the_full_cloud_in_its_cube(cloud, tree):
    """Brute force: the union of a leaf and its ancestors, within the leaf's cube, is
    every point of the cloud there (full resolution)."""
    leaves = np.flatnonzero(tree.child_start == tree.child_stop)
    for k in np.random.default_rng(1).choice(leaves, 40, replace=False):
        inside, outside = cube_masks(tree, cloud, int(k))
        union = union_mask(tree, cloud.shape[0], ancestors(tree, int(k)))
        assert inside.any()
        assert np.array_equal(union & inside, inside)
        own = union_mask(tree, cloud.shape[0], [int(k)])
        assert not np.any(own & outside)


def test_a_subtree_with_its_ancestors_is_the_full_cloud_in_its_cube(cloud, tree):
    for k in np.random.default_rng(2).choice(tree.n_nodes, 40, replace=False):
        inside, outside = cube_masks(tree, cloud, int(k))
        below = union_mask(tree, cloud.shape[0], descendants(tree, int(k)))
        union = below | union_mask(tree, cloud.shape[0], ancestors(tree, int(k)))
        assert np.array_equal(union & inside, inside)
        assert not np.any(below & outside)


def test_a_node_with_its_ancestors_has_the_node_spacing_everywhere(cloud):
    """Every sample cell (edge = the node's spacing) of a node's cube that holds a
    point of the cloud holds a point of the node or an ancestor (no cap binding)."""
    tree = build_octree(cloud, root_grid=8, max_node_points=10**6)
    assert np.all(tree.counts <= 8**3)
    for k in np.random.default_rng(3).choice(tree.n_nodes, 40, replace=False):
        inside, _ = cube_masks(tree, cloud, int(k))
        union = union_mask(tree, cloud.shape[0], ancestors(tree, int(k)))
        spacing = tree.size[k] / 8
        cell = np.floor((cloud - tree.cube_lo[k]) / spacing).astype(np.int64)
        key = (cell[:, 0] * 8 + cell[:, 1]) * 8 + cell[:, 2]
        occupied = set(key[inside].tolist())
        covered = set(key[inside & union].tolist())
        assert occupied == covered, int(k)


def test_children_hold_the_rest_of_the_cube(tree):
    for k in range(tree.n_nodes):
        kids = tree.children(k)
        assert all(int(tree.parent[c]) == k for c in kids)
        assert all(int(tree.level[c]) == int(tree.level[k]) + 1 for c in kids)
    assert int(tree.parent[0]) == -1 and int(tree.level[0]) == 0
    assert sorted(np.flatnonzero(tree.parent >= 0)) == sorted(
        c for k in range(tree.n_nodes) for c in tree.children(k))


def test_subtree_boxes_bound_every_point_below(cloud, tree):
    lo = np.full((tree.n_nodes, 3), np.inf)
    hi = np.full((tree.n_nodes, 3), -np.inf)
    for k in range(tree.n_nodes):
        p = cloud[tree.rows(k)]
        for a in ancestors(tree, k):
            lo[a] = np.minimum(lo[a], p.min(axis=0))
            hi[a] = np.maximum(hi[a], p.max(axis=0))
    assert np.array_equal(lo, tree.box_lo) and np.array_equal(hi, tree.box_hi)


def test_one_point_per_sample_cell_and_the_cap(cloud, tree):
    """Root spacing = largest extent / root_grid, halved per level; no two points of
    a node share a sample cell; no node over the cap."""
    extent = float(np.max(cloud.max(axis=0) - cloud.min(axis=0)))
    assert tree.side == extent and tree.root_spacing == extent / 16
    assert tree.counts.max() <= 1_500
    size = tree.size
    for k in range(tree.n_nodes):
        p = cloud[tree.rows(k)]
        cell = np.floor((p - tree.cube_lo[k]) / (size[k] / 16)).astype(np.int64)
        cell = np.clip(cell, 0, 15)
        key = (cell[:, 0] * 16 + cell[:, 1]) * 16 + cell[:, 2]
        assert np.unique(key).shape[0] == key.shape[0], k


def test_default_root_spacing_is_extent_over_128():
    xyz = outcrop(30_000, seed=3)
    tree = build_octree(PointCloud.from_xyz(xyz))
    extent = float(np.max(xyz.max(axis=0) - xyz.min(axis=0)))
    assert tree.root_spacing == extent / 128 and tree.root_grid == 128
    assert tree.counts.max() <= 20_000


def test_volumetric_cloud_is_capped_and_duplicates_end_in_one_leaf():
    rng = np.random.default_rng(4)
    cube = rng.uniform(0.0, 1.0, (60_000, 3))
    dup = np.tile([0.25, 0.5, 0.75], (3_000, 1))
    tree = build_octree(np.vstack([cube, dup]), root_grid=32, max_node_points=2_000)
    capped = tree.level < DEPTH_BITS
    assert tree.counts[capped].max() <= 2_000
    assert np.array_equal(np.bincount(tree.order), np.ones(63_000, dtype=np.int64))
    leaf = np.flatnonzero(~capped)
    assert leaf.shape[0] == 1 and tree.counts[leaf[0]] > 2_000  # coincident points


def test_tiny_inputs_and_bad_settings():
    one = build_octree(np.array([[1.0, 2.0, 3.0]]))
    assert one.n_nodes == 1 and one.rows(0).tolist() == [0]
    same = build_octree(np.tile([5.0, 5.0, 5.0], (10, 1)))
    assert np.array_equal(np.sort(same.order), np.arange(10))
    with pytest.raises(InputError, match="at least one point"):
        build_octree(np.empty((0, 3)))
    with pytest.raises(InputError, match="power of two"):
        build_octree(np.zeros((4, 3)), root_grid=100)
    with pytest.raises(InputError, match="finite"):
        build_octree(np.array([[0.0, 0.0, np.nan], [1.0, 1.0, 1.0]]))
    with pytest.raises(InputError, match="max node points"):
        build_octree(np.zeros((4, 3)), max_node_points=0)


def test_memory_is_estimated_first(monkeypatch):
    import rough_viewer.memory as memory

    monkeypatch.setattr(memory, "available_bytes", lambda: 1e6)
    with pytest.raises(InputError, match="octree of 100,000 points needs about"):
        build_octree(np.random.default_rng(0).uniform(0, 1, (100_000, 3)))
    assert build_bytes(10**8) < 2.0e9  # 16 bytes a point plus the chunks' temporaries


def test_octree_keeps_an_index_not_the_points(tree):
    assert tree.order.dtype == np.int32
    assert tree.nbytes < 4 * tree.n_points + 200 * tree.n_nodes


def test_morton_codes_interleave_the_cell_indices():
    """Against a bit-by-bit interleave of the 21-bit cell indices (x lowest)."""
    from rough_viewer.lod.octree import morton_codes

    rng = np.random.default_rng(9)
    xyz = rng.uniform(0.0, 7.0, (2_000, 3))
    xyz[0], xyz[1] = 0.0, 7.0  # the cube's corners: the top is clipped into the last cell
    codes = morton_codes(xyz[:, 0], xyz[:, 1], xyz[:, 2], np.zeros(3), 7.0)
    q = np.minimum(np.floor(xyz / 7.0 * 2**21).astype(np.int64), 2**21 - 1)
    for i in range(2_000):
        want = 0
        for bit in range(DEPTH_BITS):
            for axis in range(3):
                want |= ((int(q[i, axis]) >> bit) & 1) << (3 * bit + axis)
        assert int(codes[i]) == want


def test_the_octree_does_not_depend_on_chunks_or_threads(monkeypatch, cloud):
    """Every pass works a chunk at a time (4 M and 1 M points): with chunks of about
    1 000 points and 1 to 3 threads the octree is the same."""
    import rough_viewer.lod.octree as octree

    fields = ("order", "start", "level", "key", "parent", "child_start", "child_stop",
              "cube_lo", "box_lo", "box_hi")
    ref = build_octree(cloud, root_grid=16, max_node_points=1_500, workers=1)
    monkeypatch.setattr(octree, "CHUNK_POINTS", 997)
    monkeypatch.setattr(octree, "SORT_CHUNK", 1_009)
    for workers in (1, 3):
        got = build_octree(cloud, root_grid=16, max_node_points=1_500, workers=workers)
        for f in fields:
            assert np.array_equal(getattr(got, f), getattr(ref, f)), (workers, f)


FIELDS = ("order", "start", "level", "key", "parent", "child_start", "child_stop",
          "cube_lo", "box_lo", "box_hi")


def _degenerate_clouds(cloud):
    rng = np.random.default_rng(11)
    cube = rng.uniform(0.0, 1.0, (40_000, 3))
    dup = np.tile([0.25, 0.5, 0.75], (3_000, 1))  # one spot, 3 000 times
    near = np.repeat(rng.uniform(0.0, 1.0, (500, 3)), 7, axis=0)  # equal codes in runs
    return {
        "outcrop": np.asarray(cloud),
        "cube and duplicates": rng.permutation(np.vstack([cube, dup, near])),
        "a line": np.column_stack([np.linspace(0.0, 1.0, 5_000), np.zeros(5_000),
                                   np.zeros(5_000)]),
        "one spot": np.tile([5.0, 5.0, 5.0], (50, 1)),
        "one point": np.array([[1.0, 2.0, 3.0]]),
    }


@pytest.mark.parametrize("root_grid, cap", [(16, 1_500), (128, 200)])
def test_the_compiled_build_is_the_numpy_build(monkeypatch, cloud, root_grid, cap):
    """The compiled kernels (Morton radix sort, one pass per level, nodes' rows and
    boxes by a counting sort) give the NumPy build's octree to the bit, on a scan, a
    volume with coincident points and runs of equal codes, a line, one spot."""
    import rough_viewer.lod.octree as octree
    from rough_viewer.grid import fast

    for name, xyz in _degenerate_clouds(cloud).items():
        monkeypatch.setenv(fast.ENGINE_ENV, "numpy")
        assert not octree._compiled(xyz.shape[0])
        want = build_octree(xyz, root_grid=root_grid, max_node_points=cap)
        monkeypatch.setenv(fast.ENGINE_ENV, "numba")
        assert octree._compiled(xyz.shape[0])
        for chunk in (octree.SORT_CHUNK, 1_009):
            monkeypatch.setattr(octree, "SORT_CHUNK", chunk)
            got = build_octree(xyz, root_grid=root_grid, max_node_points=cap)
            for f in FIELDS:
                a, b = getattr(got, f), getattr(want, f)
                assert a.dtype == b.dtype and np.array_equal(a, b), (name, chunk, f)


def test_the_compiled_sort_is_a_stable_argsort_of_the_codes(monkeypatch):
    """Morton codes sorted by the compiled radix sort, with each point's index: as
    ``np.argsort(codes, kind="stable")`` (equal codes keep the points' order) on
    random, clustered and coincident points, one or several chunks."""
    import rough_viewer.lod.octree as octree
    from rough_viewer.grid import fast

    monkeypatch.setenv(fast.ENGINE_ENV, "numba")
    rng = np.random.default_rng(5)
    clouds = [rng.uniform(-3.0, 4.0, (30_000, 3)),
              np.repeat(rng.normal(0.0, 1e-3, (900, 3)), 11, axis=0)[rng.permutation(9_900)],
              np.tile([1.0, 1.0, 1.0], (2_000, 1)),
              rng.integers(0, 4, (20_000, 3)).astype(np.float64)]  # 64 spots, many ties
    for xyz in clouds:
        lo, side = octree._root_cube(xyz[:, 0], xyz[:, 1], xyz[:, 2])
        want_codes = octree.morton_codes(xyz[:, 0], xyz[:, 1], xyz[:, 2], lo, side)
        want = np.argsort(want_codes, kind="stable")
        for chunk in (octree.SORT_CHUNK, 777):
            monkeypatch.setattr(octree, "SORT_CHUNK", chunk)
            codes, rest = octree._sorted_codes_compiled(xyz[:, 0], xyz[:, 1], xyz[:, 2], lo,
                                                        side, np.int32, "a test")
            assert np.array_equal(rest, want) and rest.dtype == np.int32
            assert np.array_equal(codes, want_codes[want])
