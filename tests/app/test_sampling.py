import numpy as np

from rough_viewer.app.sampling import display_subset


def test_small_cloud_is_kept_whole():
    xyz = np.random.default_rng(0).uniform(size=(100, 3))
    assert np.array_equal(display_subset(xyz, 100), np.arange(100))


def test_budget_and_even_spread():
    # a plane whose left tenth holds 90 % of the points (like a scan near the scanner)
    rng = np.random.default_rng(0)
    dense = np.column_stack([rng.uniform(0, 1, 90_000), rng.uniform(0, 10, 90_000)])
    sparse = np.column_stack([rng.uniform(1, 10, 10_000), rng.uniform(0, 10, 10_000)])
    xyz = np.column_stack([np.vstack([dense, sparse]), np.zeros(100_000)])
    idx = display_subset(xyz, 10_000, seed=3)
    assert len(idx) == 10_000 and len(np.unique(idx)) == 10_000
    assert np.all(np.diff(idx) > 0)
    share_dense = np.mean(idx < 90_000)
    # random thinning would keep 90 % in the dense tenth; even thinning far less
    assert share_dense < 0.35, share_dense
    assert np.array_equal(idx, display_subset(xyz, 10_000, seed=3))  # reproducible
