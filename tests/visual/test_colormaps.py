import numpy as np
import pytest

from rough_viewer.visual import colormaps

# Exact values of matplotlib's maps, written out from the published tables (the
# 256-entry lists of viridis, magma and cividis in matplotlib's _cm_listed.py, and the
# ends of coolwarm's segment data), not computed by the code under test.
_PUBLISHED = {
    "viridis": {0: (0.267004, 0.004874, 0.329415), 128: (0.127568, 0.566949, 0.550556),
                255: (0.993248, 0.906157, 0.143936)},
    "magma": {0: (0.001462, 0.000466, 0.013866), 255: (0.987053, 0.991438, 0.749504)},
    "cividis": {0: (0.000000, 0.135112, 0.304751), 255: (0.995737, 0.909344, 0.217772)},
    "coolwarm": {0: (0.2298057, 0.298717966, 0.753683153),
                 255: (0.705673158, 0.01555616, 0.150232812)},
}
# matplotlib's five-colour palettes, ``to_hex(cmap(np.linspace(0, 1, 5)))``: entries
# 0, 64, 128, 192 and 255 of the 256-entry tables
_PALETTES = {
    "viridis": ("#440154", "#3b528b", "#21918c", "#5ec962", "#fde725"),
    "magma": ("#000004", "#51127c", "#b73779", "#fc8961", "#fcfdbf"),
}


@pytest.mark.parametrize("name", sorted(_PUBLISHED))
def test_luts_are_the_published_tables_rounded_to_8_bits(name):
    table = colormaps.lut(name)
    assert table.shape == (256, 3) and table.dtype == np.uint8
    for index, rgb in _PUBLISHED[name].items():
        assert tuple(table[index]) == tuple(round(255 * v) for v in rgb), index


@pytest.mark.parametrize("name", sorted(_PALETTES))
def test_luts_match_matplotlibs_five_colour_palettes(name):
    table = colormaps.lut(name)
    got = tuple("#{:02x}{:02x}{:02x}".format(*table[i]) for i in (0, 64, 128, 192, 255))
    assert got == _PALETTES[name]


def test_gray_is_a_linear_ramp_between_its_ends():
    c = colormaps.lut("gray").astype(int)
    assert tuple(c[0]) == (0x1A,) * 3 and tuple(c[-1]) == (0xF0,) * 3
    k = np.arange(256)
    np.testing.assert_array_equal(c[:, 0], np.round(0x1A + (0xF0 - 0x1A) * k / 255))
    assert (c[:, 0] == c[:, 1]).all() and (c[:, 1] == c[:, 2]).all()


def test_outlier_colour_is_reached_by_no_map():
    for name in colormaps.COLORMAP_NAMES:
        dist = np.abs(colormaps.lut(name).astype(int) - colormaps.OUTLIER_RGB).sum(axis=1)
        assert dist.min() > 100, name


def test_viridis_lightness_increases():
    v = colormaps.lut("viridis").astype(float)
    luma = v @ [0.2126, 0.7152, 0.0722]
    assert np.all(np.diff(luma[::16]) > 0)


def test_apply_maps_range_clips_and_marks_nan():
    vals = np.array([0.0, 0.5, 1.0, -3.0, 7.0, np.nan])
    rgb = colormaps.apply(vals, "viridis", vmin=0.0, vmax=1.0)
    lut = colormaps.lut("viridis")
    assert np.array_equal(rgb[0], lut[0]) and np.array_equal(rgb[2], lut[255])
    assert np.array_equal(rgb[1], lut[128])  # round(0.5 * 255) = 128
    assert np.array_equal(rgb[3], lut[0]) and np.array_equal(rgb[4], lut[255])
    assert tuple(rgb[5]) == colormaps.NEUTRAL_RGB


def test_apply_with_clip_range():
    lut = colormaps.lut("cividis")
    rgb = colormaps.apply(np.array([0.2, 0.3, 0.6]), "cividis", vmin=0.2, vmax=0.6)
    assert np.array_equal(rgb[0], lut[0]) and np.array_equal(rgb[2], lut[255])
    assert np.array_equal(rgb[1], lut[round(0.25 * 255)])


def test_binary_two_colours_and_neutral():
    rgb = colormaps.apply_binary(np.array([True, False, True]), np.array([True, True, False]))
    lut = colormaps.lut("viridis")
    assert np.array_equal(rgb[0], lut[-1]) and np.array_equal(rgb[1], lut[0])
    assert tuple(rgb[2]) == colormaps.NEUTRAL_RGB


def test_unknown_name_and_plotly_scale():
    with pytest.raises(ValueError, match="unknown colour map"):
        colormaps.lut("jet")
    scale = colormaps.plotly_colorscale("magma", 3)
    assert scale[0] == [0.0, "rgb(0,0,4)"] and scale[-1][1] == "rgb(252,253,191)"


# ----------------------------------------------------------------------------- stretch

import doctest  # noqa: E402

from rough_viewer.grid.roughness import grid_roughness  # noqa: E402
from rough_viewer.synthetic.demos import load_demo  # noqa: E402
from rough_viewer.vocabulary import MAPS  # noqa: E402


def test_module_examples_run():
    assert doctest.testmod(colormaps).failed == 0


def test_percentile_stretch_takes_the_percentiles_of_the_finite_values():
    rng_ = np.random.default_rng(3)
    v = np.r_[rng_.uniform(0.0, 0.01, 1000), np.nan, np.nan]
    r = colormaps.resolve(v, colormaps.Stretch("percentile", 2.0, 98.0))
    finite = np.sort(v[np.isfinite(v)])
    # numpy's default (linear) percentile, written out: rank p/100 * (n - 1)
    for got, p in ((r.lo, 2.0), (r.hi, 98.0)):
        rank = p / 100 * (finite.size - 1)
        k = int(np.floor(rank))
        assert got == pytest.approx(finite[k] + (rank - k) * (finite[k + 1] - finite[k]))
    assert r.n_values == 1000 and not r.log
    t = colormaps.positions(v, r)
    np.testing.assert_allclose(t[:1000], np.clip((v[:1000] - r.lo) / (r.hi - r.lo), 0, 1))
    assert np.isnan(t[1000:]).all()
    assert r.below == pytest.approx(np.mean(finite < r.lo))
    assert r.above == pytest.approx(np.mean(finite > r.hi))


def test_log_positions_are_linear_in_log10_and_send_zero_to_the_first_colour():
    r = colormaps.resolve(np.array([1e-4, 1e-2]), colormaps.Stretch("absolute", 1e-4, 1e-2,
                                                                     log=True))
    t = colormaps.positions(np.array([1e-4, 1e-3, 1e-2, 0.0, -1.0, 5.0, np.nan]), r)
    np.testing.assert_allclose(t[:6], [0.0, 0.5, 1.0, 0.0, 0.0, 1.0])
    assert np.isnan(t[6])
    assert colormaps.positions(np.array([10 ** -3.5]), r)[0] == pytest.approx(0.25)


def test_log_percentiles_ignore_zeros_and_round_off():
    # 3-point cells fit their plane exactly: theta 0 or ~1e-16 m, not the smoothest rock
    real = np.geomspace(1e-4, 1e-2, 500)
    v = np.r_[real, np.zeros(30), np.full(30, 1e-16)]
    r = colormaps.resolve(v, colormaps.Stretch("percentile", 2.0, 98.0, log=True))
    assert r.hi == pytest.approx(np.percentile(real, 98))
    assert r.lo == pytest.approx(np.percentile(real, 2))
    assert r.below == pytest.approx((60 + np.sum(real < r.lo)) / v.size)
    # never more than MAX_LOG_DECADES decades, whatever the values
    wide = colormaps.resolve(np.geomspace(1e-12, 1.0, 1000),
                             colormaps.Stretch("percentile", 0.0, 100.0, log=True))
    assert wide.hi / wide.lo == pytest.approx(10**colormaps.MAX_LOG_DECADES)


def test_absolute_stretch_is_the_same_for_any_values():
    s = colormaps.Stretch.absolute_mm(0.5, 20.0)
    assert (s.lo, s.hi) == (0.0005, 0.02)
    a = colormaps.resolve(np.array([0.001, 0.003]), s)
    b = colormaps.resolve(np.linspace(0, 1, 50), s)
    assert (a.lo, a.hi) == (b.lo, b.hi) == (0.0005, 0.02)
    x = np.array([0.0005, 0.01025, 0.02])
    np.testing.assert_allclose(colormaps.positions(x, a), [0.0, 0.5, 1.0])
    assert colormaps.positions(x, a).tolist() == colormaps.positions(x, b).tolist()


def test_pinned_range_reproduces_the_colours_on_other_values():
    v = np.random.default_rng(0).lognormal(-6, 1, 2000)
    r = colormaps.resolve(v, colormaps.ROUGHNESS_STRETCH)
    pinned = r.pinned()
    assert pinned.mode == "absolute" and pinned.log
    again = colormaps.resolve(v[:10], pinned)
    assert (again.lo, again.hi) == (r.lo, r.hi)
    np.testing.assert_array_equal(colormaps.stretch_colours(v, again, "viridis"),
                                  colormaps.stretch_colours(v, r, "viridis"))


def test_symmetric_range_centres_zero():
    d = np.r_[np.linspace(-0.004, 0.010, 1001)]
    r = colormaps.resolve(d, colormaps.Stretch("percentile", 0.0, 100.0, symmetric=True))
    assert (r.lo, r.hi) == (-0.010, 0.010)
    np.testing.assert_allclose(colormaps.positions(np.array([-0.01, 0.0, 0.005]), r),
                               [0.0, 0.5, 0.75])


def test_degenerate_ranges():
    empty = colormaps.resolve(np.array([np.nan, np.nan]))
    assert np.isnan(empty.lo) and empty.n_values == 0
    assert np.isnan(colormaps.positions(np.array([1.0]), empty)).all()
    assert colormaps.colour_ticks(empty).labels == ()
    same = colormaps.resolve(np.full(5, 0.002), colormaps.Stretch())
    np.testing.assert_array_equal(colormaps.positions(np.array([0.002, np.nan]), same)[:1], [0.5])
    assert colormaps.colour_ticks(same).labels == ("2",)
    assert np.isnan(colormaps.resolve(np.zeros(4), colormaps.ROUGHNESS_STRETCH).lo)


@pytest.mark.parametrize("kwargs", [
    {"mode": "percentile", "lo": 5.0, "hi": 5.0},
    {"mode": "percentile", "lo": -1.0, "hi": 50.0},
    {"mode": "percentile", "lo": 2.0, "hi": 101.0},
    {"mode": "absolute", "lo": 0.0, "hi": 0.01, "log": True},
    {"mode": "absolute", "lo": float("nan"), "hi": 0.01},
    {"mode": "percentile", "lo": 2.0, "hi": 98.0, "log": True, "symmetric": True},
    {"mode": "linear"},
])
def test_bad_stretches_are_refused(kwargs):
    with pytest.raises(ValueError):
        colormaps.Stretch(**kwargs)


@pytest.mark.parametrize(("lo", "hi", "log", "want"), [
    (0.0, 0.022, False, ("0", "5", "10", "15", "20")),
    (0.0006, 0.023, True, ("1", "2", "5", "10", "20")),
    (1e-5, 0.05, True, ("0.01", "0.1", "1", "10")),
    (0.002, 0.009, True, ("2", "4", "6", "8")),
    (-0.0153, 0.0153, False, ("−10", "0", "10")),
    (0.0, 11.046, False, ("0", "2,000", "4,000", "6,000", "8,000", "10,000")),
    (0.0011, 0.0019, False, ("1.2", "1.4", "1.6", "1.8")),
])
def test_colour_ticks_are_a_few_round_millimetres(lo, hi, log, want):
    r = colormaps.ColourRange(lo, hi, log, colormaps.Stretch(), 10, 0.0, 0.0)
    ticks = colormaps.colour_ticks(r)
    assert ticks.labels == want
    assert 2 <= len(ticks.labels) <= 6
    # every tick sits where its value is drawn, inside the bar
    np.testing.assert_allclose(ticks.positions, colormaps.positions(ticks.values / 1e3, r))
    assert np.all((ticks.positions >= 0) & (ticks.positions <= 1))
    np.testing.assert_allclose([float(s.replace(",", "").replace("−", "-")) for s in want],
                               ticks.values)


def test_tick_labels_for_any_range_are_short_and_distinct():
    rng_ = np.random.default_rng(5)
    for _ in range(300):  # from 0.1 µm to 100 m, up to 5 decades
        lo = 10 ** rng_.uniform(-7, 1)
        hi = min(lo * 10 ** rng_.uniform(0.05, 5), 100.0)
        for log in (False, True):
            t = colormaps.colour_ticks(colormaps.ColourRange(lo, hi, log, colormaps.Stretch(),
                                                             2, 0, 0))
            assert 2 <= len(t.labels) <= 6, (lo, hi, log, t.labels)
            assert len(set(t.labels)) == len(t.labels), (lo, hi, log, t.labels)
            assert max(len(s) for s in t.labels) <= 9, t.labels


def test_e_ols_has_a_sequential_map():
    for name in MAPS:
        cmap = colormaps.default_colormap(name)
        assert cmap not in colormaps.DIVERGING
        luma = colormaps.lut(cmap).astype(float) @ [0.2126, 0.7152, 0.0722]
        assert np.all(np.diff(luma[::16]) > 0), name  # lightness rises: an order, no middle
    assert colormaps.default_colormap("e_ols") != colormaps.default_colormap("odr")
    assert colormaps.default_colormap("distance") in colormaps.DIVERGING
    with pytest.raises(ValueError):
        colormaps.default_colormap("theta")


def test_largest_colour_share_counts_lut_entries_and_bands():
    t = np.r_[np.zeros(3), np.full(2, 3 / 255), 1.0, np.nan]
    assert colormaps.largest_colour_share(t) == pytest.approx(3 / 6)
    assert colormaps.largest_colour_share(t, band=4) == pytest.approx(5 / 6)
    assert colormaps.largest_colour_share(np.array([np.nan])) == 0.0


@pytest.fixture(scope="module")
def demo_quarter():
    cloud = load_demo("outcrop-small")
    return grid_roughness(cloud, 0.25)


@pytest.mark.parametrize("name", MAPS)
def test_default_stretch_shows_the_demo_in_many_colours(demo_quarter, name):
    """Issue 13: on the demo at 0.25 m no single colour (one LUT entry, or a band of 8,
    1/32 of the map) covers more than half of the cells or points under the default
    stretch; under min-max it did."""
    res = demo_quarter
    values = res.values(name)
    default = colormaps.positions(values, colormaps.resolve(values))
    assert colormaps.resolve(values).stretch == colormaps.ROUGHNESS_STRETCH
    minmax = colormaps.positions(values, colormaps.resolve(
        values, colormaps.Stretch("percentile", 0.0, 100.0)))
    for t in (default, default[res.point_cell]):
        assert colormaps.largest_colour_share(t) <= 0.5
        assert colormaps.largest_colour_share(t, band=8) <= 0.5
    # min-max normalisation (the old default) piles more than half of the drawn
    # points into 8 neighbouring colours, on every map
    assert colormaps.largest_colour_share(minmax[res.point_cell], band=8) > 0.5
    if name == "hybrid":  # metre-sized outliers: three quarters in the first colour
        assert colormaps.largest_colour_share(minmax) > 0.7


def test_outlier_colour_is_none_of_the_maps_and_marks_points():
    """Outlier cells take their own colour in both displays, a colour no map reaches."""
    from rough_viewer.visual.colormaps import (
        COLORMAP_NAMES,
        OUTLIER_RGB,
        apply_binary,
        lut,
        resolve,
        stretch_colours,
    )

    for name in COLORMAP_NAMES:
        nearest = np.abs(lut(name).astype(int) - np.array(OUTLIER_RGB)).sum(axis=1).min()
        assert nearest > 60, name
    values = np.array([0.001, 0.002, 0.5, np.nan])
    out = np.array([False, False, True, False])
    rng = resolve(values[:2])
    rgb = stretch_colours(values, rng, outliers=out)
    assert rgb[2].tolist() == list(OUTLIER_RGB) and rgb[0].tolist() != list(OUTLIER_RGB)
    np.testing.assert_array_equal(rgb[[0, 1, 3]], stretch_colours(values, rng)[[0, 1, 3]])
    flags = apply_binary(values > 0.0015, np.isfinite(values), outliers=out)
    assert flags[2].tolist() == list(OUTLIER_RGB) and flags[3].tolist() == [190, 190, 190]
