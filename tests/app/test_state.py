"""App state without viser: caching, colours and cell reports against the core."""

import numpy as np
import pytest

from rough_viewer.app import cloud as state_mod
from rough_viewer.app import store as store_mod
from rough_viewer.app.cache import ByteCache, nbytes
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import cell_info, map_stats, point_colours
from rough_viewer.app.settings import MapSettings, check_settings
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.summary import binary, normalise
from rough_viewer.visual import colormaps
from rough_viewer.vocabulary import InputError


@pytest.fixture(scope="module")
def loaded(cloud):
    return LoadedCloud(cloud, max_display=15_000)


def test_local_origin_keeps_float32_precise(loaded, cloud):
    assert loaded.n_display == 15_000 and loaded.n_total == cloud.n
    assert loaded.display_points.dtype == np.float32
    back = loaded.to_file_frame(loaded.display_points)
    err = np.abs(back - cloud.xyz()[loaded.display_index]).max()
    assert err < 1e-6  # metres; float32 of UTM eastings directly would be ~0.03 m off
    assert np.all(loaded.origin == np.round(loaded.origin))


def test_results_cached_per_grid_key(loaded, monkeypatch):
    calls = []
    real = store_mod.grid_roughness

    def counting(*a, **k):
        calls.append((a[1], k["axis"], k["min_points"]))
        return real(*a, **k)

    monkeypatch.setattr(store_mod, "grid_roughness", counting)
    s = MapSettings(cell_size=0.5)
    r1 = loaded.result(s)
    # colouring changes share the grid result
    r2 = loaded.result(s.with_(model="ols", threshold=0.3, display="binary", colormap="magma",
                               stretch=colormaps.Stretch.absolute_mm(1, 2), layer="distance"))
    assert r1 is r2 and len(calls) == 1
    loaded.result(s.with_(axis="z"))
    loaded.result(s.with_(min_points=10))
    assert calls == [(0.5, "auto", 4), (0.5, "z", 4), (0.5, "auto", 10)]
    assert loaded.is_cached(s.with_(min_points=10))



def test_cell_results_stay_cached_when_full_results_cannot(cloud, monkeypatch):
    """The Panels tab's trend across the presets uses cell-only results: the same
    per-cell numbers as the full ones, and small enough to stay cached where the
    full results (with the point-to-cell map) are evicted, so a threshold change
    computes no grid again."""
    calls = []
    real = store_mod.grid_roughness

    def counting(*a, **k):
        calls.append(a[1])
        return real(*a, **k)

    small = LoadedCloud(cloud, max_display=15_000, presets=(1.0, 0.5))
    full = {g: grid_roughness(cloud, g, models=("odr", "ols", "hybrid")) for g in (1.0, 0.5)}
    per_point = nbytes(full[0.5].point_cell)
    # room for the fine grid's prepared cells (pinned) and the cell-only results,
    # not for one more point-to-cell map
    budget = nbytes(small.prepared(0.5)) + sum(nbytes(r) - nbytes(r.point_cell)
                                               for r in full.values()) + per_point // 2
    small = LoadedCloud(cloud, max_display=15_000, presets=(1.0, 0.5), cache_bytes=budget)
    monkeypatch.setattr(store_mod, "grid_roughness", counting)
    s = MapSettings(cell_size=0.5)
    small.mark_shown(s)
    first = [small.cell_result(s.with_(cell_size=g)) for g in (1.0, 0.5)]
    assert calls == [1.0, 0.5]
    for g, light in zip((1.0, 0.5), first, strict=True):
        assert light.point_cell.shape == (0,) and light.n_points_total == cloud.n
        for name in ("odr", "ols", "hybrid", "e_ols"):
            # the coarser preset is coarsened from the fine grid's moments: round-off
            np.testing.assert_allclose(light.values(name), full[g].values(name), rtol=1e-9, atol=1e-15)
        np.testing.assert_array_equal(light.n_points, full[g].n_points)
    assert not small.is_cached(s.with_(cell_size=1.0))  # the full result was evicted
    again = [small.cell_result(s.with_(cell_size=g, threshold=0.3)) for g in (1.0, 0.5)]
    assert calls == [1.0, 0.5] and all(a is b for a, b in zip(again, first, strict=True))
    # only the cells of the shown grid's axis and minimum are held (others may go)
    cells = ("cells", s.with_(cell_size=1.0).grid_key)
    assert small.store._pinned(cells)
    small.mark_shown(s.with_(axis="z"))
    assert not small.store._pinned(cells)
    assert small.store._pinned(("cells", s.with_(axis="z", cell_size=2.0).grid_key))
    roomy = LoadedCloud(cloud, max_display=15_000, presets=(1.0, 0.5))  # 1 GiB cache
    roomy.cell_result(s.with_(cell_size=1.0))
    assert roomy.is_cached(s.with_(cell_size=1.0))  # small: kept whole (a preset recolours)

def _log_stretch_colours(values, lo, hi, cmap):
    """Independent reference: log positions between lo and hi, clipped, on the LUT."""
    lut = colormaps.lut(cmap)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (np.log10(np.maximum(values, lo)) - np.log10(lo)) / (np.log10(hi) - np.log10(lo))
    t = np.clip(t, 0, 1)
    out = lut[np.round(np.nan_to_num(t) * 255).astype(int)]
    out[~np.isfinite(values)] = colormaps.NEUTRAL_RGB
    return out


def test_continuous_colours_follow_the_default_log_percentile_stretch(loaded, cloud):
    s = MapSettings(cell_size=0.25, model="ols", colormap="cividis")
    assert s.stretch == colormaps.ROUGHNESS_STRETCH
    got = point_colours(loaded.result(s), s, loaded.display_index)
    core = grid_roughness(cloud, 0.25)  # independent call to the core
    v = core.theta_ols
    ok = np.isfinite(v) & (v > 0)
    top = np.percentile(v[ok], 98)
    lo, hi = np.percentile(v[ok & (v >= top / 1e4)], [2, 98])
    want = _log_stretch_colours(v[core.point_cell[loaded.display_index]], lo, hi, "cividis")
    assert np.array_equal(got, want)
    # left half is smooth, right half rough: colour brightness follows
    x = cloud.x[loaded.display_index] - cloud.x.min()
    luma = got.astype(float) @ [0.2126, 0.7152, 0.0722]
    assert luma[x > 2.5].mean() > luma[x < 1.5].mean() + 50
    # no single colour covers half of the points (min-max did on skewed maps)
    stats = map_stats(loaded.result(s), s)
    t = colormaps.positions(v[core.point_cell[loaded.display_index]], stats.colour_range)
    assert colormaps.largest_colour_share(t) < 0.1


def test_an_absolute_stretch_gives_one_colour_one_roughness_on_every_grid(loaded):
    pinned = colormaps.Stretch.absolute_mm(0.5, 8.0, log=True)
    for g in (0.25, 0.5):
        s = MapSettings(cell_size=g, stretch=pinned)
        res = loaded.result(s)
        stats = map_stats(res, s)
        assert (stats.colour_range.lo, stats.colour_range.hi) == (0.0005, 0.008)
        got = point_colours(res, s, loaded.display_index)
        theta = res.theta_odr[res.point_cell[loaded.display_index]]
        # the colour is one function of θ on both grids (same limits, same map)
        assert np.array_equal(got, _log_stretch_colours(theta, 0.0005, 0.008, "viridis"))
    # the default (percentile) stretch resolves on each grid's own cells instead
    r1 = map_stats(loaded.result(MapSettings(cell_size=0.25)), MapSettings(cell_size=0.25))
    r2 = map_stats(loaded.result(MapSettings(cell_size=0.5)), MapSettings(cell_size=0.5))
    assert r1.colour_range.hi != r2.colour_range.hi


def test_binary_colours_and_threshold(loaded, cloud):
    s = MapSettings(cell_size=0.25, display="binary", threshold=0.3)
    got = point_colours(loaded.result(s), s, loaded.display_index)
    core = grid_roughness(cloud, 0.25)
    rough = binary(normalise(core.theta_odr), 0.3)[core.point_cell[loaded.display_index]]
    lut = colormaps.lut("viridis")
    assert np.array_equal(got[rough], np.broadcast_to(lut[-1], got[rough].shape))
    assert np.array_equal(got[~rough], np.broadcast_to(lut[0], got[~rough].shape))
    stats = map_stats(loaded.result(s), s)
    assert stats.rough_share == pytest.approx(np.mean(binary(normalise(core.theta_odr), 0.3)))


def test_cells_without_value_are_neutral(cloud):
    small = LoadedCloud(cloud.subset(np.arange(2000)), max_display=2000)
    s = MapSettings(cell_size=0.125, min_points=5)
    res = small.result(s)
    got = point_colours(res, s, small.display_index)
    empty = ~np.isfinite(res.theta_odr[res.point_cell])
    assert empty.any() and (~empty).any()
    assert np.all(got[empty] == colormaps.NEUTRAL_RGB)


def test_cell_info_matches_brute_force(loaded, cloud):
    s = MapSettings(cell_size=0.5)
    res = loaded.result(s)
    p = 1234
    info = cell_info(res, p, cloud.xyz()[p])
    xyz = cloud.xyz()
    lo = xyz.min(axis=0)
    ijk = np.floor((xyz - lo) / 0.5).astype(int)
    same = np.all(ijk == ijk[p], axis=1)
    assert info.ijk == tuple(ijk[p]) and info.n_points == same.sum()
    pts = xyz[same] - xyz[same].mean(axis=0)
    normal = np.linalg.svd(pts, full_matrices=False)[2][-1]
    d = np.abs(pts @ normal)
    assert info.theta["odr"] == pytest.approx(d.std(), rel=1e-6)
    assert abs(abs(np.dot(info.normal, normal)) - 1) < 1e-9
    assert info.axis == "y" and info.point == tuple(xyz[p])


def test_check_settings_rejects_bad_input():
    with pytest.raises(InputError, match="too small"):
        check_settings(MapSettings(cell_size=1e-5))
    with pytest.raises(InputError, match="at least 3"):
        check_settings(MapSettings(min_points=2))
    with pytest.raises(ValueError, match="colour map"):
        check_settings(MapSettings(colormap="jet"))


def test_presets_come_from_the_point_spacing_and_are_nested(loaded, cloud):
    from rough_viewer.grid.spacing import default_cell_size

    g = default_cell_size(cloud)
    assert loaded.presets == (8 * g, 4 * g, 2 * g, g) == (0.64, 0.32, 0.16, 0.08)
    assert loaded.default_cell_size == loaded.fine_cell_size == g
    # the typical occupied cell of the default grid holds at least 16 points
    ijk = np.floor((cloud.xyz() - cloud.xyz().min(axis=0)) / g).astype(np.int64)
    _, counts = np.unique(ijk, axis=0, return_counts=True)
    assert np.median(counts) >= 16


def test_presets_in_feet_are_round_numbers_of_feet(cloud):
    from dataclasses import replace

    in_ft = replace(cloud, source_unit="ft")
    presets = state_mod.grid_presets(in_ft)
    ft = [round(p / 0.3048, 9) for p in presets]
    assert ft == [8 * ft[-1], 4 * ft[-1], 2 * ft[-1], ft[-1]]
    assert f"{ft[-1]:g}" in ("0.25", "0.3", "0.4", "0.5")  # readable in feet


def test_presets_coarsened_from_fine_grid_equal_direct_core(cloud):
    fresh = LoadedCloud(cloud, max_display=1000, presets=(1.0, 0.5, 0.25, 0.125))
    fine = fresh.prepared(0.125)
    assert fresh.prepared(1.0) is not fine and fresh.prepared(0.125) is fine
    for size in (1.0, 0.5, 0.3):
        got = fresh.result(MapSettings(cell_size=size))
        want = grid_roughness(cloud, size)
        assert np.array_equal(got.point_cell, want.point_cell)
        for m in ("odr", "ols", "hybrid", "e_ols"):
            assert np.allclose(got.values(m), want.values(m), rtol=1e-9, atol=1e-15,
                               equal_nan=True)


def test_the_grid_cache_is_bounded_by_bytes(cloud):
    loaded = LoadedCloud(cloud, max_display=1000, cache_bytes=2_000_000)
    sizes = []
    for g in (0.3, 0.35, 0.4, 0.45, 0.55, 0.6, 0.65, 0.7):
        loaded.result(MapSettings(cell_size=g))
        sizes.append(loaded.cached_bytes)
    assert max(sizes) <= 2_000_000 and loaded.cached_bytes > 0
    assert loaded.is_cached(MapSettings(cell_size=0.7))
    assert not loaded.is_cached(MapSettings(cell_size=0.3))  # least recently used went
    one = nbytes(loaded.result(MapSettings(cell_size=0.7)))
    assert one > 8 * cloud.n  # the per-point cell index alone is 8 bytes a point
    cache: ByteCache[str, np.ndarray] = ByteCache(100)
    assert cache.put("a", np.zeros(10)) and not cache.put("big", np.zeros(20))
    assert "a" in cache and cache.bytes == 80  # a value that cannot fit flushes nothing
    pinned: ByteCache[str, np.ndarray] = ByteCache(200, pinned=lambda k: k == "p")
    assert pinned.put("p", np.zeros(15)) and pinned.put("a", np.zeros(5))
    assert not pinned.put("b", np.zeros(11)) and "a" in pinned  # 120 + 88 > 200
    assert pinned.put("c", np.zeros(10)) and "a" not in pinned and pinned.bytes == 200
    a = np.zeros(5)
    assert nbytes((a, a[1:], {"x": a})) == a.nbytes  # views count once


def test_the_grid_on_screen_stays_cached_while_others_come_and_go(cloud):
    loaded = LoadedCloud(cloud, max_display=1000, cache_bytes=2_000_000)
    shown = MapSettings(cell_size=0.3)
    first = loaded.result(shown)
    loaded.mark_shown(shown)
    for g in (0.35, 0.4, 0.45, 0.55, 0.6, 0.65, 0.7):
        loaded.result(MapSettings(cell_size=g))
    assert loaded.cached_bytes <= 2_000_000
    assert loaded.is_cached(shown) and loaded.result(shown) is first
    assert not loaded.is_cached(MapSettings(cell_size=0.35))  # the others were evicted


def test_a_dropped_cloud_is_freed_without_a_garbage_collection(cloud):
    """Issue 36: the grid cache's pin rule held the cloud (cloud -> cache -> bound
    method -> cloud), so every loaded cloud and its arrays stayed until a full
    collection. With the collector off, dropping the last reference frees it."""
    import gc
    import weakref

    gc.collect()
    gc.disable()
    try:
        loaded = LoadedCloud(cloud, max_display=2_000)
        settings = MapSettings(cell_size=0.5)
        loaded.mark_shown(settings)
        loaded.result(settings)
        loaded.result(settings.with_(cell_size=1.0))  # the pin rule runs on every put
        assert loaded.store._cache._pinned(("result", settings.grid_key))
        ref, store = weakref.ref(loaded), weakref.ref(loaded.store)
        del loaded
        assert ref() is None and store() is None
    finally:
        gc.enable()


def test_clouds_compare_by_identity(cloud):
    a = LoadedCloud(cloud, max_display=2_000)
    b = LoadedCloud(cloud, max_display=2_000)
    assert a == a and a != b  # no element-wise array comparison (eq=False)


def test_the_octree_has_the_node_size_asked_for(cloud):
    """The octree was built at its first call's node size and kept whatever a later
    call asked (a budget changed between two showings of the cloud). Now the same size
    gives the same tree, another size a tree whose nodes hold at most that many."""
    from rough_viewer.lod.octree import build_octree

    loaded = LoadedCloud(cloud, max_display=2_000)
    big = loaded.octree(5_000)
    assert loaded.octree(5_000) is big
    small = loaded.octree(1_000)
    assert small is not big and small.max_node_points == 1_000
    assert int(small.counts.max()) <= 1_000 < int(big.counts.max())
    want = build_octree(cloud, max_node_points=1_000)  # the reference: built directly
    np.testing.assert_array_equal(small.counts, want.counts)


def test_a_result_whose_cells_are_cached_is_the_same_without_the_grid_passes(cloud, monkeypatch):
    """A preset whose full result left the cache but whose cells stayed (the panels'
    trend) comes back from its cells and every point's row, with no grid pass: the
    same bits in every field as the result the passes made."""
    presets = (1.0, 0.5, 0.25)
    roomy = LoadedCloud(cloud, max_display=15_000, presets=presets)
    s = MapSettings(cell_size=0.25)
    want = {g: roomy.result(s.with_(cell_size=g)) for g in presets}
    per_point = nbytes(want[0.25].point_cell)
    small = LoadedCloud(cloud, max_display=15_000, presets=presets)
    budget = nbytes(small.prepared(0.25)) + sum(nbytes(r) - nbytes(r.point_cell)
                                                for r in want.values()) + per_point // 2
    small = LoadedCloud(cloud, max_display=15_000, presets=presets, cache_bytes=budget)
    small.mark_shown(s)
    for g in presets:
        small.cell_result(s.with_(cell_size=g))
    assert not any(small.is_cached(s.with_(cell_size=g)) for g in presets)
    calls = []
    monkeypatch.setattr(store_mod, "grid_roughness", lambda *a, **k: calls.append(a[1]))
    for g in presets:
        got = small.result(s.with_(cell_size=g))
        ref = want[g]
        assert got.point_cell.shape == (cloud.n,)
        assert _same_bits(got, ref)
        # each point's row is the cell holding it, checked from the coordinates
        ijk = np.floor((cloud.xyz() - got.grid.origin) / got.grid.cell_size).astype(np.int64)
        assert np.array_equal(got.ijk[got.point_cell], ijk)
    assert calls == []
    # the coarsened presets stay cached as their own cells (no per-point rows), so a
    # preset change does not coarsen again
    for g in (1.0, 0.5):
        assert ("prepared", g) in small.store._cache
        assert small.prepared(g).fine_cell is small.prepared(0.25).index.point_cell


def _same_bits(a, b) -> bool:
    """Whether two results (dataclasses of arrays and plain values) hold the same bits."""
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.tobytes() == b.tobytes() and a.shape == b.shape
    if hasattr(a, "__dataclass_fields__"):
        return type(a) is type(b) and all(_same_bits(getattr(a, f), getattr(b, f))
                                          for f in a.__dataclass_fields__)
    return bool(a == b)


def test_cells_of_a_preset_indexed_alone_are_not_mixed_with_its_coarsened_rows(cloud,
                                                                              monkeypatch):
    """A big cloud's coarsest preset is indexed on its own first (coarse first); once
    that grid left the cache, the same preset comes coarsened from the finest, which
    may put a point on a cell's edge in the other cell: its full result is then
    computed again, never its old cells with the new rows."""
    monkeypatch.setattr(store_mod, "COARSE_ALONE_POINTS", 0)
    presets = (1.0, 0.5, 0.25)
    probe = LoadedCloud(cloud, max_display=15_000, presets=presets)
    s = MapSettings(cell_size=0.25)
    sizes = {g: probe.result(s.with_(cell_size=g)) for g in presets}
    per_point = nbytes(sizes[0.25].point_cell)
    budget = nbytes(probe.prepared(0.25)) + sum(nbytes(r) - nbytes(r.point_cell)
                                                for r in sizes.values()) + per_point // 2
    small = LoadedCloud(cloud, max_display=15_000, presets=presets, cache_bytes=budget)
    assert small.prepared(1.0).parent is None  # indexed on its own (no finest grid yet)
    small.mark_shown(s)
    small.cell_result(s.with_(cell_size=1.0))
    small.cell_result(s)  # the finest grid: the presets are coarsened from it now
    assert ("prepared", 1.0) not in small.store._cache
    assert small.prepared(1.0).parent is not None
    calls = []
    real = store_mod.grid_roughness

    def counting(*a, **k):
        calls.append(a[1])
        return real(*a, **k)

    monkeypatch.setattr(store_mod, "grid_roughness", counting)
    got = small.result(s.with_(cell_size=1.0))
    assert calls == [1.0]
    assert np.array_equal(np.bincount(got.point_cell, minlength=got.n_cells), got.n_points)
