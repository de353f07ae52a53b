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


def test_the_compiled_voxel_pass_gives_the_numpy_sample(monkeypatch):
    """The compiled voxel pass (keys, buckets, priorities, each bucket's smallest)
    gives the NumPy chunks' sample to the index, on a scan-like face in UTM-sized
    coordinates, a lattice (points on the voxels' faces) and a cloud of coincident
    points, several seeds and sizes."""
    from rough_viewer.app import sampling
    from rough_viewer.grid import fast

    monkeypatch.setattr(sampling, "CHUNK", 7_001)  # several NumPy chunks
    rng = np.random.default_rng(8)
    face = rng.uniform(0.0, 1.0, (60_000, 3)) * [40.0, 0.0, 12.0]
    face[:, 1] = 0.3 * np.sin(face[:, 0]) + rng.normal(0.0, 0.002, face.shape[0])
    face += [512_000.0, 4_170_000.0, 100.0]
    i, j = np.meshgrid(np.arange(250), np.arange(160))
    lattice = np.column_stack([0.05 * i.ravel(), np.zeros(i.size), 0.05 * j.ravel()])
    spots = np.repeat(rng.uniform(0.0, 5.0, (400, 3)), 50, axis=0)
    for xyz in (face, lattice, spots):
        for seed, most in ((0, 5_000), (3, 1_234)):
            monkeypatch.setenv(fast.ENGINE_ENV, "numpy")
            want = display_subset(xyz, most, seed=seed)
            monkeypatch.setenv(fast.ENGINE_ENV, "numba")
            x, y, z = (np.ascontiguousarray(xyz[:, a]) for a in range(3))
            assert sampling._taken_compiled(x, y, z, xyz.min(axis=0), 0.1, np.array([9, 9, 9]),
                                            seed, np.full(11, np.inf, dtype=np.float32)) \
                is not None
            got = display_subset(xyz, most, seed=seed)
            assert np.array_equal(got, want) and got.dtype == want.dtype
