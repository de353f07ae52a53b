"""Profile figure: heights in mm or the cloud's unit, range fitted to the data, exaggeration."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rough_viewer.profiles.extraction import extract_profile
from rough_viewer.profiles.fractal import roughness_length
from rough_viewer.profiles.wavelets import denoise_result
from rough_viewer.visual.profiles import HEIGHT_MARGIN, height_range_mm, profile_figure


@pytest.fixture(scope="module")
def analyses():
    """Two profiles 1.8 m long across millimetre relief (2 mm waves, 0.5 mm noise)."""
    rng = np.random.default_rng(0)
    xy = rng.uniform(0, 2, (150_000, 2))
    z = 0.002 * np.sin(9 * xy[:, 0]) + 0.0005 * rng.standard_normal(len(xy))
    pts = np.column_stack([xy, z])
    out = []
    for y0, y1 in ((0.5, 0.5), (1.2, 1.4)):
        p = extract_profile(pts, np.array([0.1, y0, 0.0]), np.array([1.9, y1, 0.0]))
        d = denoise_result(p.heights)
        out.append(SimpleNamespace(profile=p, denoised=d,
                                   raw_fit=roughness_length(p.heights, p.spacing),
                                   denoised_fit=roughness_length(d.heights, p.spacing)))
    return out


def test_heights_are_in_mm_and_the_range_fits_the_data(analyses):
    fig = profile_figure(analyses)
    np.testing.assert_allclose(fig.data[0].y, analyses[0].profile.heights * 1e3)
    np.testing.assert_allclose(fig.data[1].y, analyses[0].denoised.heights * 1e3)
    heights = np.concatenate([np.r_[a.profile.heights, a.denoised.heights] for a in analyses])
    lo, hi = np.nanmin(heights) * 1e3, np.nanmax(heights) * 1e3
    span = hi - lo
    assert 3.0 < span < 8.0  # millimetre relief ...
    assert tuple(fig.layout.yaxis.range) == pytest.approx(
        (lo - HEIGHT_MARGIN * span, hi + HEIGHT_MARGIN * span))  # ... shown as such
    assert fig.layout.yaxis.scaleanchor is None
    assert "height (mm)" in fig.layout.yaxis.title.text
    assert fig.layout.yaxis2.title.text == "s(w) (mm)" and fig.layout.xaxis2.type == "log"


def test_exaggeration_fixes_the_ratio_of_the_axes(analyses):
    fig = profile_figure(analyses, exaggeration=20)
    assert fig.layout.yaxis.scaleanchor == "x"
    assert fig.layout.yaxis.scaleratio == pytest.approx(0.02)  # 1 mm drawn as 20 mm of x (m)
    assert fig.layout.yaxis.constrain == "domain"
    assert tuple(fig.layout.yaxis.range) == height_range_mm(analyses)
    assert "×20" in fig.layout.yaxis.title.text
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="exaggeration"):
            profile_figure(analyses, exaggeration=bad)


def test_empty_and_flat_profiles():
    assert height_range_mm([]) == (-1.0, 1.0)
    assert not profile_figure([]).layout.showlegend
    flat = SimpleNamespace(profile=SimpleNamespace(heights=np.full(5, 0.001)),
                           denoised=SimpleNamespace(heights=np.full(5, 0.001)))
    lo, hi = height_range_mm([flat])
    assert lo < 1.0 < hi and hi - lo == pytest.approx(0.2 * (1 + 2 * HEIGHT_MARGIN))


def test_units_follow_the_cloud(analyses):
    """A cloud in feet: distances and heights in feet, the exaggeration still a ratio
    of like lengths; a cloud in millimetres: distances in mm."""
    ft = 0.3048
    fig = profile_figure(analyses, length_unit=("ft", ft), height_unit=("ft", ft),
                         exaggeration=20)
    np.testing.assert_allclose(fig.data[0].x, analyses[0].profile.distance / ft)
    np.testing.assert_allclose(fig.data[0].y, analyses[0].profile.heights / ft)
    np.testing.assert_allclose(fig.data[2].y, analyses[0].raw_fit.s[np.isfinite(
        analyses[0].raw_fit.s)] / ft)
    assert fig.layout.xaxis.title.text == "distance along the line (ft)"
    assert fig.layout.yaxis.title.text == "height (ft), ×20"
    assert fig.layout.yaxis.scaleratio == pytest.approx(20.0)
    assert fig.layout.xaxis2.title.text == "window w (ft)"
    assert fig.layout.yaxis2.title.text == "s(w) (ft)"
    lo, hi = fig.layout.yaxis.range
    mm_lo, mm_hi = height_range_mm(analyses)
    assert (lo, hi) == pytest.approx((mm_lo * 1e-3 / ft, mm_hi * 1e-3 / ft))
    mm = profile_figure(analyses, length_unit=("mm", 1e-3), height_unit=("mm", 1e-3),
                        exaggeration=2)
    np.testing.assert_allclose(mm.data[0].x, analyses[0].profile.distance * 1e3)
    assert mm.layout.yaxis.scaleratio == pytest.approx(2.0)
    assert mm.layout.xaxis.title.text == "distance along the line (mm)"


def test_metres_of_relief_are_drawn_in_metres():
    """A 195 m airborne profile with 25 m of relief: heights in m, not -15k..10k mm;
    the s(w) plot follows."""
    x = np.linspace(0, 195, 600)
    h = 12.5 * np.sin(x / 30.0) - 2.5
    fit = roughness_length(h + 0.01 * np.random.default_rng(1).standard_normal(600),
                           x[1] - x[0])
    a = SimpleNamespace(profile=SimpleNamespace(distance=x, heights=h),
                        denoised=SimpleNamespace(heights=h), raw_fit=fit, denoised_fit=fit)
    fig = profile_figure([a])
    np.testing.assert_allclose(fig.data[0].y, h)
    assert fig.layout.yaxis.title.text.startswith("height (m)")
    lo, hi = fig.layout.yaxis.range
    assert -17 < lo < -15 and 10 < hi < 12
    assert fig.layout.yaxis2.title.text == "s(w) (m)"
