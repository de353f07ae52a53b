import numpy as np

from rough_viewer.app.picking import pick_point, ray_distances


def test_ray_distances_against_closed_form():
    pts = np.array([[0.0, 0.0, 5.0], [1.0, 0.0, 5.0], [0.0, 2.0, -1.0]])
    perp, along = ray_distances(pts, (0, 0, 0), (0, 0, 2))
    assert np.allclose(perp, [0.0, 1.0, 2.0])
    assert np.allclose(along, [5.0, 5.0, -1.0])


def test_pick_prefers_the_visible_surface():
    # camera at z = 10 looking down: sheet z = 3 is in front, sheet z = 1 behind;
    # only the hidden sheet has a point exactly on the ray
    rng = np.random.default_rng(1)
    xy = rng.uniform(-1, 1, (20_000, 2))
    front = np.column_stack([xy, np.full(len(xy), 3.0)])
    back = np.column_stack([xy[::-1], np.full(len(xy), 1.0)])
    pts = np.vstack([back, front, [[0.2, 0.1, 1.0]]])
    i = pick_point(pts, (0.2, 0.1, 10.0), (0, 0, -1))
    assert pts[i, 2] == 3.0
    assert np.hypot(pts[i, 0] - 0.2, pts[i, 1] - 0.1) <= 0.004 * 7 + 1e-12
    # without the front sheet the exact hit is found
    assert pick_point(np.vstack([back, [[0.2, 0.1, 1.0]]]), (0.2, 0.1, 10.0), (0, 0, -1)) == len(back)


def test_pick_misses_and_behind_camera():
    pts = np.array([[0.0, 0.0, -5.0]])
    assert pick_point(pts, (0, 0, 0), (0, 0, 1)) is None  # behind
    assert pick_point(np.array([[5.0, 0.0, 1.0]]), (0, 0, 0), (0, 0, 1)) is None  # far off
    assert pick_point(np.zeros((0, 3)), (0, 0, 0), (0, 0, 1)) is None
