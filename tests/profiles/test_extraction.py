"""Profile extraction on a synthetic, arbitrarily tilted rough plane of known heights.

The surface in its own frame is ``h = g(a)`` with ``a`` the coordinate along the line
(so averaging across the band is exact) and ``g`` a sum of three sinusoids (amplitudes
1-3 mm, wavelengths 40-130 mm; ``max |g''| = 64 m^-1``). It is rotated by arbitrary
Euler angles and moved to UTM-like coordinates. Extraction must return ``g`` minus the least-squares
plane of the surface over the patch, evaluated on the line. Error budget at 1 mm sampling: linear
interpolation between bin means at most ``max|g''| gap^2 / 8`` with gaps up to
``max_gap = 3 mm`` (72 um), plus the in-bin averaging ``max|g''| spacing^2 / 24``
(3 um); the PCA tilt from the roughness itself (~1e-3 rad) moves samples by
``|g| tilt`` (~3 um, times a slope < 0.4 -> ~1 um). Tolerance: 80 um maximum and
15 um rms; measured: maximum 20-40 um, rms about 5 um.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rough_viewer.profiles.extraction import extract_profile, point_spacing, regular_samples

T = np.array([500123.4, 4_200_000.7, 312.5])


def g(a: np.ndarray) -> np.ndarray:
    return (
        0.002 * np.sin(2 * np.pi * a / 0.04 + 0.3)
        + 0.003 * np.sin(2 * np.pi * a / 0.13 + 1.0)
        + 0.001 * np.cos(2 * np.pi * a / 0.07)
    )


def tilted_cloud(seed: int, angles, *, n: int = 60000, grid: bool = False):
    """Points on h = g(a) over a in [-0.05, 0.45], c in [-0.06, 0.06], rotated; and the
    3-D start/end of the line a = 0..0.4 at c = 0."""
    rng = np.random.default_rng(seed)
    if grid:
        a, c = np.meshgrid(np.arange(-0.05, 0.45, 0.002), np.arange(-0.06, 0.0601, 0.002))
        a, c = a.ravel(), c.ravel()
    else:
        a = rng.uniform(-0.05, 0.45, n)
        c = rng.uniform(-0.06, 0.06, n)
    rot = Rotation.from_euler("zyx", angles, degrees=True).as_matrix()
    xyz = np.column_stack([a, c, g(a)]) @ rot.T + T
    start = T + rot @ np.array([0.0, 0.0, g(np.array(0.0))])
    end = T + rot @ np.array([0.4, 0.0, g(np.array(0.4))])
    return xyz, start, end, a, c, rot


def detrended(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    ok = np.isfinite(y)
    return y - np.polyval(np.polyfit(x[ok], y[ok], 1), x)


@pytest.mark.parametrize("seed,angles", [(0, (37, 61, -23)), (1, (-120, 15, 80)), (2, (5, 89, 3))])
def test_tilted_rough_plane_returns_known_heights(seed, angles) -> None:
    xyz, start, end, _, _, rot = tilted_cloud(seed, angles)
    p = extract_profile(xyz, start, end, spacing=0.001, band_half_width=0.002)
    assert p.length == pytest.approx(0.4, abs=1e-4)
    np.testing.assert_allclose(p.distance, np.arange(401) * 0.001)
    assert p.gaps == () and p.n_gap_samples == 0
    # the frame's normal is the true normal (up to sign), within 3e-3 rad
    assert abs(abs(p.frame.normal @ rot[:, 2]) - 1) < 5e-6
    # reference: g minus the least-squares plane of the true surface over the patch
    # (here the whole cloud: every point is within the default radius of 0.1 m)
    _, _, _, a, c, _ = tilted_cloud(seed, angles)
    design = np.column_stack([np.ones(a.size), a, c])
    coef, *_ = np.linalg.lstsq(design, g(a), rcond=None)
    ref = g(p.distance) - (coef[0] + coef[1] * p.distance)
    sign = np.sign(p.frame.normal @ rot[:, 2])  # the frame's normal is signed by rule
    err = sign * p.heights - ref
    assert p.frame.n_points == xyz.shape[0]
    assert np.max(np.abs(err)) < 80e-6
    assert np.sqrt(np.mean(err**2)) < 15e-6
    # samples mapped back to 3-D lie on the true surface (to the same tolerance)
    back = (p.sample_xyz() - T) @ rot
    np.testing.assert_allclose(back[:, 0], p.distance, atol=2e-5)
    np.testing.assert_allclose(back[:, 1], 0.0, atol=2e-5)
    assert np.max(np.abs(back[:, 2] - g(back[:, 0]))) < 80e-6
    # the band: every point used lies within 2 mm of the line in the surface frame
    local = (xyz[p.point_index] - T) @ rot
    assert np.all(np.abs(local[:, 1]) <= 0.002 + 1e-5)
    assert p.n_points == p.point_index.size == p.counts.sum()
    # the band points are exactly those within the band, up to rounding of the frame
    expected = np.flatnonzero(
        (np.abs(((xyz - T) @ rot)[:, 1]) <= 0.002 - 2e-5)
        & (((xyz - T) @ rot)[:, 0] >= -0.0005 + 2e-5)
        & (((xyz - T) @ rot)[:, 0] <= 0.4005 - 2e-5)
    )
    assert np.isin(expected, p.point_index).all()


def test_gap_is_reported_not_interpolated() -> None:
    xyz, start, end, a, _, _ = tilted_cloud(4, (20, 40, 60))
    keep = ~((a > 0.200) & (a < 0.230))
    p = extract_profile(xyz[keep], start, end, spacing=0.001, band_half_width=0.002)
    assert len(p.gaps) == 1
    lo, hi = p.gaps[0]
    # bin means of the last/first points beside the hole: within 1.5 spacings of it
    assert 0.1985 < lo <= 0.2001 and 0.2299 <= hi < 0.2315
    nan = np.flatnonzero(np.isnan(p.heights))
    # samples 0.201 .. 0.229 are more than half a spacing from any point: all NaN
    assert nan[0] in (200, 201) and nan[-1] in (229, 230)
    assert np.array_equal(nan, np.arange(nan[0], nan[-1] + 1))
    assert p.n_gap_samples == nan.size
    # short gaps (< max_gap = 3 mm) are interpolated: a 2 mm hole gives no NaN
    keep2 = ~((a > 0.300) & (a < 0.302))
    q = extract_profile(xyz[keep2], start, end, spacing=0.001, band_half_width=0.002)
    assert q.gaps == () and q.n_gap_samples == 0
    # ends of the line beyond the data are reported as gaps too
    keep3 = a > 0.05
    r = extract_profile(xyz[keep3], start, end, spacing=0.001, band_half_width=0.002)
    assert r.gaps[0][0] == 0.0 and r.gaps[0][1] == pytest.approx(0.05, abs=0.001)
    assert np.all(np.isnan(r.heights[:49])) and np.all(np.isfinite(r.heights[51:]))


def test_defaults_follow_the_point_spacing() -> None:
    xyz, start, end, *_ = tilted_cloud(0, (10, 50, 30), grid=True)
    p = extract_profile(xyz, start, end)
    # 2 mm grid: the 4th neighbour in the plane is at 2 mm (slight tilt aside)
    assert p.point_spacing == pytest.approx(0.002, rel=0.01)
    assert p.spacing == p.point_spacing == p.band_half_width
    assert p.max_gap == pytest.approx(3 * p.spacing)
    assert p.n_gap_samples == 0
    assert point_spacing(np.column_stack([np.arange(10.0), np.zeros(10)])) == 2.0


def test_accepts_point_cloud_objects() -> None:
    xyz, start, end, *_ = tilted_cloud(5, (0, 30, 0), n=20000)

    class Cloud:
        def xyz(self):
            return xyz

    a = extract_profile(Cloud(), start, end, spacing=0.002, band_half_width=0.003)
    b = extract_profile(xyz, start, end, spacing=0.002, band_half_width=0.003)
    np.testing.assert_array_equal(a.heights, b.heights)


def test_errors() -> None:
    xyz, start, end, *_ = tilted_cloud(6, (0, 0, 0), n=5000)
    with pytest.raises(ValueError, match="same point"):
        extract_profile(xyz, start, start)
    with pytest.raises(ValueError, match="points within"):
        extract_profile(xyz, start + 10.0, end + 10.0)
    with pytest.raises(ValueError, match="perpendicular"):
        extract_profile(xyz, start, start + np.array([0.002, 0, 0.3]))
    with pytest.raises(ValueError, match="positive"):
        extract_profile(xyz, start, end, spacing=-1.0)
    with pytest.raises(ValueError, match="three"):
        extract_profile(xyz, start[:2], end)


def test_regular_samples() -> None:
    d = np.arange(100) * 1e-3 + 0.5
    h = np.sin(d * 50)
    d2, h2, gaps = regular_samples(d, h)
    assert np.array_equal(d2, d) and np.array_equal(h2, h) and gaps == ()
    # irregular: 0, 1, 2, 3, then 10, 11 (mm) -> gap 3..10 mm
    di = np.array([0, 1, 2, 3, 10, 11]) * 1e-3
    hi = np.array([0.0, 1, 2, 3, 10, 11])
    d3, h3, gaps = regular_samples(di, hi)
    np.testing.assert_allclose(d3, np.arange(12) * 1e-3)
    np.testing.assert_allclose(h3[[0, 1, 2, 3, 10, 11]], [0, 1, 2, 3, 10, 11])
    assert np.all(np.isnan(h3[4:10]))
    assert gaps == ((0.003, 0.010),)
    with pytest.raises(ValueError, match="increasing"):
        regular_samples(np.array([0.0, 2.0, 1.0]), np.zeros(3))
