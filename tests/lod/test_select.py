"""Node selection against brute force on random cameras: the view by linear
programming and scipy's rotations, the projected size by trigonometry, Potree's
traversal by a plain loop; and the budget."""

from __future__ import annotations

import heapq
import math

import numpy as np
import pytest
from scipy.optimize import linprog
from scipy.spatial.transform import Rotation

from rough_viewer.lod.camera import ViewCamera, in_view
from rough_viewer.lod.octree import build_octree
from rough_viewer.lod.select import boxes_in_view, select_nodes
from tests.lod.helpers import outcrop, random_camera


@pytest.fixture(scope="module")
def cloud():
    return outcrop(60_000, seed=11)


@pytest.fixture(scope="module")
def tree(cloud):
    return build_octree(cloud, root_grid=8, max_node_points=400)


# ----------------------------------------------------------------------------- the reference


def reference_frustum(cam: ViewCamera) -> tuple[np.ndarray, np.ndarray]:
    """Half-spaces A p <= b of the view pyramid, from scipy's rotation of viser's
    wxyz (scipy wants x, y, z, w) and the pinhole model: |c_x| <= c_z tan(hfov/2),
    |c_y| <= c_z tan(fov/2) for c = R^T (p - t)."""
    w, x, y, z = cam.wxyz
    r = Rotation.from_quat([x, y, z, w]).as_matrix()
    ty = math.tan(cam.fov_rad / 2)
    tx = ty * cam.aspect
    local = np.array([[1, 0, -tx], [-1, 0, -tx], [0, 1, -ty], [0, -1, -ty]], dtype=float)
    a = local @ r.T  # rows: n_world with n_world . (p - t) = n_local . c
    return a, a @ cam.position


def reference_in_view(a, b, lo, hi, scale) -> bool | None:
    """Does the box meet the pyramid? max s with A p + s <= b, lo <= p <= hi.
    None when the answer is within round-off of touching."""
    res = linprog(c=[0, 0, 0, -1], A_ub=np.column_stack([a, np.ones(4)]), b_ub=b,
                  bounds=[*zip(lo, hi, strict=True), (None, scale)], method="highs")
    assert res.status == 0
    slack = -res.fun
    if abs(slack) < 1e-7 * scale:
        return None
    return slack > 0


def reference_radius_px(cam: ViewCamera, centre, r) -> float:
    """Screen radius of a sphere seen head-on: f tan(asin(r / d))."""
    d = float(np.linalg.norm(centre - cam.position))
    if d <= r:
        return math.inf
    f = (cam.height_px / 2) / math.tan(cam.fov_rad / 2)
    return f * math.tan(math.asin(r / d))


def reference_select(tree, cam, budget, min_spacing_px):
    """Potree's traversal as a plain loop; None if any decision was a near tie."""
    a, b = reference_frustum(cam)
    kids: dict[int, list[int]] = {}
    for k, p in enumerate(tree.parent.tolist()):
        kids.setdefault(p, []).append(k)
    size = tree.side / 2.0 ** tree.level.astype(float)
    scale = tree.side

    def entry(k):
        vis = reference_in_view(a, b, tree.box_lo[k], tree.box_hi[k], scale)
        centre = tree.cube_lo[k] + size[k] / 2
        radius = reference_radius_px(cam, centre, size[k] * math.sqrt(3) / 2)
        return vis, radius

    vis, rad = entry(0)
    if vis is None:
        return None
    heap = [(-rad, 0)] if vis else []
    taken, total = [], 0
    while heap:
        if len(heap) > 1:
            first, second = heapq.nsmallest(2, heap)
            if first[0] != second[0] and math.isclose(first[0], second[0], rel_tol=1e-9):
                return None
        _, k = heapq.heappop(heap)
        if total + int(tree.counts[k]) > budget:
            break
        taken.append(k)
        total += int(tree.counts[k])
        for c in kids.get(k, []):
            vis, rad = entry(c)
            if vis is None:
                return None
            g = min(tree.root_grid, math.sqrt(max(int(tree.counts[c]), 1)))
            spacing = rad / (g * math.sqrt(3) / 2)
            if math.isclose(spacing, min_spacing_px, rel_tol=1e-9):
                return None
            if vis and spacing >= min_spacing_px:
                heapq.heappush(heap, (-rad, c))
    return taken, total


# ----------------------------------------------------------------------------- the tests


def test_selection_matches_brute_force_on_random_cameras():
    cloud = outcrop(10_000, seed=12)
    tree = build_octree(cloud, root_grid=8, max_node_points=200)  # ~700 nodes, 8 levels
    rng = np.random.default_rng(20)
    compared = 0
    for i in range(14):
        cam = random_camera(rng, cloud)
        budget = int(rng.choice([500, 2_000, 5_000, 10**9]))
        spacing = float(rng.choice([0.0, 1.0, 3.0]))
        ref = reference_select(tree, cam, budget, spacing)
        if ref is None:
            continue
        got = select_nodes(tree, cam, budget, min_spacing_px=spacing)
        assert got.nodes.tolist() == ref[0], i
        assert got.points == ref[1] <= budget
        compared += 1
    assert compared >= 12


def test_box_visibility_is_exact(cloud):
    """boxes_in_view against the linear program, on random boxes and cameras."""
    rng = np.random.default_rng(21)
    lo0, hi0 = cloud.min(axis=0), cloud.max(axis=0)
    extent = float(np.max(hi0 - lo0))
    checked = seen = 0
    for _ in range(6):
        cam = random_camera(rng, cloud)
        a, b = reference_frustum(cam)
        corner = rng.uniform(lo0, hi0, (40, 3))
        lo = corner
        hi = corner + rng.uniform(0.001, 0.2, (40, 3)) * extent
        got = boxes_in_view(cam, lo, hi)
        for j in range(40):
            ref = reference_in_view(a, b, lo[j], hi[j], extent)
            if ref is None:
                continue
            assert bool(got[j]) == ref
            checked += 1
            seen += ref
    assert checked > 200 and 0 < seen < checked


def test_every_point_in_view_is_selected_without_a_budget(cloud, tree):
    """Brute-force projection of every point: all that fall in the window are in
    the selected nodes when the budget and the spacing limit do not bind."""
    rng = np.random.default_rng(22)
    for _ in range(8):
        cam = random_camera(rng, cloud)
        sel = select_nodes(tree, cam, 10**9, min_spacing_px=0.0)
        w, x, y, z = cam.wxyz
        r = Rotation.from_quat([x, y, z, w]).as_matrix()
        c = (cloud - cam.position) @ r
        f = (cam.height_px / 2) / math.tan(cam.fov_rad / 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = f * c[:, 0] / c[:, 2] + cam.aspect * cam.height_px / 2
            v = f * c[:, 1] / c[:, 2] + cam.height_px / 2
        seen = (c[:, 2] > 0) & (u >= 0) & (u <= cam.aspect * cam.height_px) & (v >= 0) & (
            v <= cam.height_px)
        assert np.array_equal(seen, in_view(cam, cloud))
        shown = np.zeros(cloud.shape[0], dtype=bool)
        for k in sel.nodes:
            shown[tree.rows(int(k))] = True
        assert np.all(shown[seen]) and sel.complete


def test_the_budget_holds_and_the_selection_is_closed_under_parents(cloud, tree):
    rng = np.random.default_rng(23)
    for _ in range(30):
        cam = random_camera(rng, cloud)
        budget = int(rng.integers(0, 30_000))
        sel = select_nodes(tree, cam, budget, min_spacing_px=float(rng.choice([0.0, 1.0])))
        assert sel.points == int(tree.counts[sel.nodes].sum()) <= budget
        chosen = set(sel.nodes.tolist())
        assert len(chosen) == sel.nodes.shape[0]
        assert all(int(tree.parent[k]) in chosen for k in chosen if k != 0)
        if not sel.complete:  # stopped by the budget: the next node did not fit
            assert sel.points + min(int(tree.counts[k]) for k in range(tree.n_nodes)) > 0
            nxt = [c for k in chosen for c in tree.children(k) if c not in chosen] or [0]
            assert any(sel.points + int(tree.counts[c]) > budget for c in nxt)


def test_closer_cameras_see_finer_nodes_of_the_same_patch(cloud, tree):
    patch = cloud[np.argmin(np.linalg.norm(cloud - cloud.mean(axis=0), axis=1))]
    far = select_nodes(tree, ViewCamera.looking_at(patch + [0, -40, 0], patch), 20_000)
    near = select_nodes(tree, ViewCamera.looking_at(patch + [0, -1, 0], patch), 20_000)
    assert tree.level[near.nodes].max() > tree.level[far.nodes].max()
    assert near.nearest_m < far.nearest_m
