"""One cache budget for the whole app (issue 32 item 5): the grid cache of the loaded
cloud and of its crops, the zones' and the sets' caches draw from one
:class:`ByteBudget` of ``cache_bytes`` and hold at most that much together (they held
up to 1.75x it, each crop another 1x)."""

import numpy as np

from rough_viewer.app.cache import ByteBudget, ByteCache
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.settings import MapSettings
from rough_viewer.io.crop import CropBox


def test_caches_sharing_a_budget_hold_at_most_it_together():
    pool = ByteBudget(1000)
    grids: ByteCache[str, np.ndarray] = ByteCache(pool)
    zones: ByteCache[str, np.ndarray] = ByteCache(pool, most=500)
    sets: ByteCache[str, np.ndarray] = ByteCache(pool, most=250)
    assert (grids.budget, zones.budget, sets.budget) == (1000, 500, 250)
    assert grids.put("g1", np.zeros(50)) and grids.put("g2", np.zeros(25))  # 600 bytes
    assert zones.put("z1", np.zeros(40))  # 320: 920 in all
    assert pool.used == 920
    # the sets need 200: the pool's least recently used value (g1) makes room
    assert sets.put("s1", np.zeros(25))
    assert "g1" not in grids and "g2" in grids and pool.used == 200 + 320 + 200
    # a cache's own share: zones may not pass 500 however much the pool has free
    assert zones.put("z2", np.zeros(30))  # 320 + 240 > 500: its own z1 goes, not a grid
    assert "z1" not in zones and zones.bytes == 240 and "g2" in grids
    assert pool.used <= pool.total
    # recently used values stay: g2 read now, then room needed again
    assert grids.get("g2") is not None
    assert grids.put("g3", np.zeros(60))
    assert pool.used <= 1000 and "g3" in grids


def test_pinned_values_of_other_caches_are_never_dropped():
    pool = ByteBudget(800)
    a: ByteCache[str, np.ndarray] = ByteCache(pool, pinned=lambda k: k == "keep")
    b: ByteCache[str, np.ndarray] = ByteCache(pool)
    assert a.put("keep", np.zeros(60))  # 480 pinned
    assert not b.put("big", np.zeros(50))  # 400 cannot fit beside it
    assert "keep" in a and pool.used == 480
    assert b.put("small", np.zeros(40)) and pool.used == 800


def test_a_crop_shares_its_whole_clouds_budget(cloud):
    whole = LoadedCloud(cloud, max_display=1000, cache_bytes=3_000_000)
    lo, hi = cloud.bounds()
    mid = 0.5 * (lo + hi)
    crop = whole.cropped(CropBox((float(lo[0]), float(lo[1]), float(lo[2]) - 1),
                                 (float(mid[0]), float(hi[1]), float(hi[2]) + 1)))
    assert crop.store.pool is whole.store.pool
    for g in (0.3, 0.4, 0.5, 0.6, 0.7):
        whole.result(MapSettings(cell_size=g))
        crop.result(MapSettings(cell_size=g))
        assert whole.cached_bytes + crop.cached_bytes <= 3_000_000
    assert whole.cached_bytes > 0 and crop.cached_bytes > 0


def test_the_app_has_one_budget_for_all_its_caches(server, cloud):
    from rough_viewer.app.features.sets import SetsFeature
    from rough_viewer.app.features.zones import ZonesFeature
    from rough_viewer.app.server import build_app

    app = build_app(server, cloud, prefetch=False, variogram=False,
                    cache_bytes=50_000_000, settings=MapSettings(cell_size=0.5))
    try:
        assert app.wait_idle(60)
        pool = app.options.cache_pool
        assert pool.total == app.options.cache_bytes == 50_000_000
        assert app.session.shown.loaded.store.pool is pool
        assert app.feature(ZonesFeature).cache.pool is pool
        assert app.feature(SetsFeature).cache.pool is pool
        assert pool.used <= pool.total
    finally:
        app.stop()
