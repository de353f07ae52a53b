"""Node-local float16 coordinates within 1e-3 of the node's size, and colours."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.lod.encode import (
    ERROR_SHARE,
    encode_node,
    node_colours,
    node_scale,
)
from rough_viewer.lod.octree import build_octree
from tests.lod.helpers import outcrop


@pytest.mark.parametrize("scale, offset", [
    (1.0, (512_000.0, 4_170_000.0, 100.0)),   # UTM metres: float16 of raw coordinates is useless
    (1e-3, (0.0, 0.0, 0.0)),                  # a millimetre-sized sample, in metres
    (1e-6, (3.0, -2.0, 1.0)),                 # micrometres: below the unit-scale range
    (3e4, (1e6, 1e6, 0.0)),                   # 900 km: nodes beyond float16's range in metres
])
def test_float16_error_is_within_1e_3_of_the_node_size(scale, offset):
    xyz = (outcrop(40_000, seed=5) - outcrop(1, seed=5)[0]) * scale + offset
    tree = build_octree(xyz, root_grid=16, max_node_points=1_000)
    worst = 0.0
    for k in range(tree.n_nodes):
        node = tree.node(k)
        enc = encode_node(xyz, node)
        assert enc.points.dtype == np.float16 and enc.points.shape == (node.n, 3)
        assert np.all(np.isfinite(enc.points))
        err = np.max(np.abs(enc.decode() - xyz[node.rows])) / node.size
        worst = max(worst, float(err))
        # what the browser does: float16 times scale plus the node's position
        placed = enc.points.astype(np.float32).astype(np.float64) * enc.scale + enc.centre
        assert np.max(np.abs(placed - xyz[node.rows])) <= 1e-3 * node.size
    assert worst <= 1e-3
    assert worst <= ERROR_SHARE * (1 + 1e-6)  # the bound proved in rough_viewer/lod/encode.py
    assert worst > ERROR_SHARE / 8  # and it is float16's, not something finer


def test_scale_is_one_for_metre_sized_nodes_and_a_power_of_two_otherwise():
    assert node_scale(0.01) == node_scale(1000.0) == 1.0
    for size in (1e-6, 3e-5, 7e4, 1e9):
        s = node_scale(size)
        assert np.log2(s) == round(np.log2(s)) and 0.5 <= size / s <= 2.0


def test_node_colours_are_the_points_colours():
    xyz = outcrop(20_000, seed=6)
    tree = build_octree(xyz, root_grid=16, max_node_points=800)
    colours = np.random.default_rng(0).integers(0, 256, (xyz.shape[0], 3), dtype=np.uint8)
    ids = list(range(0, tree.n_nodes, 3))
    from rough_viewer.app.scene import nodes_colours_of

    many = nodes_colours_of(tree, ids, lambda rows: colours[rows])
    for k, got in zip(ids, many, strict=True):
        node = tree.node(k)
        one = node_colours(colours, node)
        assert np.array_equal(one, colours[tree.order[tree.start[k]:tree.start[k + 1]]])
        assert np.array_equal(got, one)
    assert nodes_colours_of(tree, [], lambda rows: colours[rows]) == []


def test_a_node_of_another_cloud_is_refused():
    xyz = outcrop(5_000, seed=7)
    tree = build_octree(xyz, root_grid=8, max_node_points=500)
    with pytest.raises(ValueError, match="not the cloud the octree was built from"):
        encode_node(xyz[:10], tree.node(0))
