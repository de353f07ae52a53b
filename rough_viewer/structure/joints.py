"""Joints from patches, their spacing along the set's normal and on scanlines, and
the rock-mass figures of the sets (ISRM 1978; Palmstrom 2005).

A **patch** (a row of PLANES.csv) is a group of touching coplanar cells of one set
(:mod:`rough_viewer.structure.sets`, step 7). On a rock mass cut by several sets a single
discontinuity is broken into many patches: the cells where another joint crosses it
hold two planes and are not planar. A **joint** is every patch of one set that lies
on one discontinuity, touching or not:

1. **Candidates**: two patches of one set whose centroids each lie within
   ``plane_tolerance`` of the other's fitted plane (however far apart along it).
2. **Merging**: candidate pairs are taken in order of the RMS of one plane fitted to
   both (from their points' moment sums, exact); two groups merge when the plane
   fitted to all their points has an RMS of at most ``max_plane_rms`` and each
   group's centroid lies within ``plane_tolerance`` of the other's plane. A loop
   over candidate pairs (at most :data:`MAX_CANDIDATE_PAIRS`), never over points.
3. **Per joint**, from the moment sums: the ODR plane of all its points (centroid,
   normal, RMS), its patches, its area (the patches' areas summed) and its extent:
   ``persistence_dip`` and ``persistence_strike`` = the span of its points along the
   dip and strike of its plane, gaps between its exposures included;
   ``trace_length`` = the span along the longest in-plane principal axis of its
   points.

**Spacing** of a set (ISRM 1978), in the set's frame: in-plane axes (dip, strike)
of the set's mean plane and the height ``h`` along its mean normal ``m``; every
joint's plane gives ``h_j(u, v)`` at every in-plane location. The in-plane locations
are binned at one cell; a joint *covers* a bin where one of its points falls in it.

- **Normal spacing** (``spacing_mean``, ``spacing_median``, ``spacing_std``): the
  set's joints ordered by their height at the set's centre; for each consecutive
  pair, ``h_b - h_a`` averaged over the bins both cover (where they overlap), or, if
  they overlap nowhere, at the midpoint of their centroids' in-plane positions (never
  the difference of the centroids' offsets: a tilted joint's centroid sits off the
  other's line). Differences of at most ``plane_tolerance`` are no spacing.
- **Scanline spacing** (``spacing_scanline_mean``): virtual scanlines along ``m``,
  one through the centre of every bin covered by the set; along each, the joints it
  crosses sorted by ``h``; the mean of the distances between consecutive crossings
  (more than ``plane_tolerance``) over every scanline: the ISRM mean spacing of a
  scanline laid along the set's normal.

**Rock-mass figures** (:func:`rock_mass_figures`): the volumetric joint count
``Jv = sum over sets of 1 / spacing_mean`` (joints per cubic metre; ISRM 1978,
Palmstrom 2005; sets without a spacing, i.e. with fewer than two joints, add
nothing); the block size index ``Ib = mean of the sets' spacing_mean`` (ISRM 1978,
there for three sets); and the RQD estimate ``RQD = 110 - 2.5 Jv`` clipped to 0..100
(Palmstrom 2005, which replaced Palmstrom's 1982 ``115 - 3.3 Jv``): an estimate from a
correlation with a wide scatter, for ``Jv`` between 4 and 44 (100 below 4, 0 above
44), when no core exists; it is no measured RQD.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.orientation import dip_and_direction, dip_strike_axes, orient_normals
from rough_viewer.memory import require
from rough_viewer.vocabulary import InputError, unit_scale

#: Most candidate patch pairs merged per set (each takes a 3x3 eigen-decomposition
#: in a Python loop); beyond it the closest pairs are kept.
MAX_CANDIDATE_PAIRS = 200_000
#: Rows of the pair matrix computed at once.
_PAIR_CHUNK = 256
#: A joint covers a bin where the cloud has a point within this many times the
#: joint's RMS of its plane ...
COVER_RMS_FACTOR = 3.0
#: ... up to this many bins beyond the bins of its own points.
COVER_REACH_BINS = 8
#: RQD estimate from Jv (Palmstrom 2005): ``RQD = RQD_INTERCEPT - RQD_SLOPE * Jv``.
RQD_INTERCEPT = 110.0
RQD_SLOPE = 2.5
#: Jv for which the RQD estimate holds (Palmstrom 2005): 100 below, 0 above.
RQD_JV_RANGE = (4.0, 44.0)
#: The RQD estimate's formula and limits, as the outputs state it.
RQD_FORMULA = (f"RQD = {RQD_INTERCEPT:g} - {RQD_SLOPE:g} Jv (Jv per m3), clipped to 0..100; "
               f"Palmstrom 2005; valid for Jv {RQD_JV_RANGE[0]:g}..{RQD_JV_RANGE[1]:g}")


@dataclass(frozen=True, eq=False)
class Joints:
    """Joints (single discontinuities made of one or more patches), id ``k + 1``."""

    set_id: np.ndarray
    """(J,) int64 set of every joint, 1..S."""
    patches: np.ndarray
    """(J,) int64 patches per joint."""
    points: np.ndarray
    """(J,) int64 points per joint."""
    normal: np.ndarray
    """(J, 3) unit normal of the ODR plane of all its points, upward (vertical: toward
    the viewer)."""
    dip_deg: np.ndarray
    """(J,) dip, degrees."""
    dip_direction_deg: np.ndarray
    """(J,) dip direction, degrees clockwise from +y."""
    centroid: np.ndarray
    """(J, 3) centroid of its points, metres."""
    rms: np.ndarray
    """(J,) RMS of its points' orthogonal distances to its plane, metres."""
    area: np.ndarray
    """(J,) summed area of its patches, square metres."""
    persistence_dip: np.ndarray
    """(J,) span of its points along its plane's dip, metres (gaps included)."""
    persistence_strike: np.ndarray
    """(J,) span of its points along its plane's strike, metres (gaps included)."""
    trace_length: np.ndarray
    """(J,) span of its points along its longest in-plane principal axis, metres."""
    width: np.ndarray
    """(J,) standard deviation of its points across its longest in-plane axis (the
    square root of the middle eigenvalue of its plane's fit), metres: a joint narrower
    than a cell has a poorly known dip across its length."""

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return int(self.set_id.shape[0])


@dataclass(frozen=True)
class RockMassFigures:
    """Rock-mass figures of the sets' normal spacings (module docstring)."""

    jv: float
    """Volumetric joint count, joints per cubic metre (NaN without any spacing)."""
    block_size_index: float
    """ISRM block size index ``Ib``: the mean of the sets' mean spacings, metres."""
    rqd_estimate: float
    """``110 - 2.5 Jv`` clipped to 0..100, percent (Palmstrom 2005): an estimate."""
    sets_counted: int
    """Sets with a spacing (those that add to ``Jv``)."""


def rock_mass_figures(spacing_mean: np.ndarray) -> RockMassFigures:
    """``Jv``, ``Ib`` and the RQD estimate of sets of mean normal spacings (metres).

    >>> f = rock_mass_figures(np.array([0.5, 0.8, 0.6, np.nan]))
    >>> round(f.jv, 4), round(f.block_size_index, 4), round(f.rqd_estimate, 2), f.sets_counted
    (4.9167, 0.6333, 97.71, 3)
    """
    s = np.asarray(spacing_mean, dtype=np.float64)
    s = s[np.isfinite(s) & (s > 0)]
    if s.size == 0:
        return RockMassFigures(float("nan"), float("nan"), float("nan"), 0)
    jv = float(np.sum(1.0 / s))
    rqd = float(np.clip(RQD_INTERCEPT - RQD_SLOPE * jv, 0.0, 100.0))
    return RockMassFigures(jv, float(s.mean()), rqd, int(s.size))


def rock_mass_text(f: RockMassFigures, unit: str = "m", *, face_left_out: bool = False,
                   only_face_spaced: bool = False) -> str:
    """The rock-mass figures in one sentence, as the terminal and the app's Sets tab
    show them: ``Jv`` in joints per ``unit`` cubed (and per cubic metre), ``Ib`` in
    ``unit``, the RQD estimate with its formula, named an estimate. ``face_left_out``:
    some sets parallel to the exposure face were left out; ``only_face_spaced``: only
    such sets had a spacing.

    >>> print(rock_mass_text(rock_mass_figures(np.array([0.5, 0.8, 0.6]))))
    Jv 4.917 joints per m3 (4.92 per m3, 3 sets with a spacing), block size index Ib \
0.6333 m, RQD estimate 98 % (110 - 2.5 Jv, Palmstrom 2005; an estimate, not a measured RQD)
    >>> rock_mass_text(rock_mass_figures(np.array([np.nan])))
    'no set has two joints apart: no Jv, block size index or RQD estimate'
    """
    per, u = unit_scale(unit)
    if not f.sets_counted:
        if only_face_spaced:
            return ("no set off the exposure face has two joints apart: no Jv, block size "
                    "index or RQD estimate")
        return "no set has two joints apart: no Jv, block size index or RQD estimate"
    return (f"Jv {f.jv * per:.4g} joints per {u}3 ({f.jv:.3g} per m3, {f.sets_counted} "
            f"set{'s' if f.sets_counted != 1 else ''} with a spacing"
            + (", the sets parallel to the exposure face left out" if face_left_out else "")
            + f"), block size index Ib {f.block_size_index / per:.4g} {u}, RQD estimate "
            f"{f.rqd_estimate:.0f} % (110 - 2.5 Jv, Palmstrom 2005; an estimate, not a "
            "measured RQD)")


def _moments_of_pairs(n: np.ndarray, c: np.ndarray, cov: np.ndarray, i: np.ndarray,
                      j: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count, centroid and covariance of the union of groups ``i`` and ``j`` (arrays
    of group indices) from each group's count, centroid and population covariance."""
    ni, nj = n[i][:, None], n[j][:, None]
    tot = ni + nj
    mid = (ni * c[i] + nj * c[j]) / tot
    di, dj = c[i] - mid, c[j] - mid
    merged = (ni[:, :, None] * (cov[i] + di[:, :, None] * di[:, None, :])
              + nj[:, :, None] * (cov[j] + dj[:, :, None] * dj[:, None, :])) / tot[:, :, None]
    return tot[:, 0], mid, merged


def _smallest_rms(cov: np.ndarray) -> np.ndarray:
    """RMS about the best plane: the square root of the smallest eigenvalue."""
    return np.sqrt(np.maximum(np.linalg.eigvalsh(cov)[..., 0], 0.0))


def merge_patches(patch_set: np.ndarray, points: np.ndarray, centroid: np.ndarray,
                  cov: np.ndarray, normal: np.ndarray, *, tolerance: float,
                  max_rms: float) -> np.ndarray:
    """Joint of every patch (module docstring, steps 1 and 2).

    Parameters
    ----------
    patch_set : (P,) int array
        Set of every patch, 1..S.
    points : (P,) array
        Points per patch.
    centroid : (P, 3) array
        Centroid of every patch's points, metres.
    cov : (P, 3, 3) array
        Population covariance of every patch's points, square metres.
    normal : (P, 3) array
        Unit normal of every patch's ODR plane.
    tolerance : float
        Largest distance of a patch's centroid to the other's plane, metres.
    max_rms : float
        Largest RMS of a joint's points about its plane, metres.

    Returns
    -------
    (P,) int64 array
        Joint index 0..J-1 of every patch, by set, then by points (largest first).
    """
    p_n = int(patch_set.shape[0])
    parent = np.arange(p_n)
    n = points.astype(np.float64)
    # group moments, updated as groups merge (index = root patch)
    gn, gc, gcov = n.copy(), centroid.astype(np.float64).copy(), cov.astype(np.float64).copy()

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = int(parent[a])
        return a

    for s in np.unique(patch_set):
        mine = np.flatnonzero(patch_set == s)
        k = mine.shape[0]
        if k < 2:
            continue
        i, j = _near_pairs(mine, centroid, normal, tolerance)
        if i.size == 0:
            continue
        _, _, pair_cov = _moments_of_pairs(n, centroid, cov, i, j)
        score = _smallest_rms(pair_cov)
        keep = score <= max_rms
        i, j, score = i[keep], j[keep], score[keep]
        order = np.argsort(score, kind="stable")[:MAX_CANDIDATE_PAIRS]
        for a, b in zip(i[order].tolist(), j[order].tolist(), strict=True):
            ra, rb = find(a), find(b)
            if ra == rb:
                continue
            ia, ib = np.array([ra]), np.array([rb])
            tot, mid, mcov = _moments_of_pairs(gn, gc, gcov, ia, ib)
            if _smallest_rms(mcov)[0] > max_rms:
                continue
            # each group's centroid near the other's plane
            w_a, v_a = np.linalg.eigh(gcov[ra])
            w_b, v_b = np.linalg.eigh(gcov[rb])
            gap = gc[rb] - gc[ra]
            if abs(gap @ v_a[:, 0]) > tolerance or abs(gap @ v_b[:, 0]) > tolerance:
                continue
            parent[rb] = ra
            gn[ra], gc[ra], gcov[ra] = tot[0], mid[0], mcov[0]
    roots = np.array([find(a) for a in range(p_n)], dtype=np.int64)
    return _joint_ids(roots, patch_set, n)


def _near_pairs(mine: np.ndarray, centroid: np.ndarray, normal: np.ndarray, tolerance: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``(i, j)`` (``i`` before ``j`` in ``mine``) of the patches ``mine`` of
    one set each of whose centroids lies within ``tolerance`` (metres) of the other's
    plane; a loop over chunks of :data:`_PAIR_CHUNK` rows."""
    k = mine.shape[0]
    require(8.0 * 6 * min(k, _PAIR_CHUNK) * k, f"patch pairs of a set of {k:,} patches")
    ci, cj = [], []
    for start in range(0, k, _PAIR_CHUNK):
        rows = mine[start:start + _PAIR_CHUNK]
        d = centroid[mine][None, :, :] - centroid[rows][:, None, :]  # (r, k, 3)
        d_ij = np.abs(np.einsum("rkx,rx->rk", d, normal[rows]))
        d_ji = np.abs(np.einsum("rkx,kx->rk", d, normal[mine]))
        ok = np.maximum(d_ij, d_ji) <= tolerance
        ok &= np.arange(k)[None, :] > (start + np.arange(rows.shape[0]))[:, None]
        r, c = np.nonzero(ok)
        ci.append(rows[r])
        cj.append(mine[c])
    return np.concatenate(ci), np.concatenate(cj)


def _joint_ids(roots: np.ndarray, patch_set: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Joint index 0..J-1 of every patch from its group's root patch: by set, then by
    points ``n`` (largest first), then first patch."""
    p_n = int(roots.shape[0])
    uniq, inverse = np.unique(roots, return_inverse=True)
    j_points = np.bincount(inverse, weights=n, minlength=uniq.shape[0])
    j_set = np.zeros(uniq.shape[0], dtype=np.int64)
    j_set[inverse] = patch_set
    first = np.full(uniq.shape[0], p_n, dtype=np.int64)
    np.minimum.at(first, inverse, np.arange(p_n))
    rank = np.lexsort((first, -j_points, j_set))
    new = np.empty(uniq.shape[0], dtype=np.int64)
    new[rank] = np.arange(uniq.shape[0])
    return new[inverse]


def joint_table(patch_joint: np.ndarray, patch_set: np.ndarray, points: np.ndarray,
                centroid: np.ndarray, cov: np.ndarray, area: np.ndarray,
                point_joint: np.ndarray, xyz: tuple[np.ndarray, np.ndarray, np.ndarray],
                toward: np.ndarray) -> Joints:
    """The joints of :func:`merge_patches` measured (module docstring, step 3).

    ``point_joint`` is the joint index (0..J-1, -1 for none) of every point of
    ``xyz`` (metres); ``toward`` the viewer's side for vertical planes (the
    whole-cloud normal).
    """
    j_n = int(patch_joint.max()) + 1 if patch_joint.size else 0
    if j_n == 0:
        return _no_joints()
    cnt = np.bincount(patch_joint, weights=points.astype(np.float64), minlength=j_n)
    # the plane: every patch's points weighted by the inverse of its own variance
    # about its plane, so that a patch that straddles two joints (where they come
    # within a cell of each other) does not tilt the plane of the joint
    patch_var = np.maximum(np.linalg.eigvalsh(cov)[:, 0], 1e-12 * np.trace(cov, axis1=1,
                                                                            axis2=2) + 1e-30)
    weight = points / patch_var
    c, jcov = _pooled(patch_joint, weight, centroid, cov, j_n)
    raw_c, raw_cov = _pooled(patch_joint, points.astype(np.float64), centroid, cov, j_n)
    w, v = np.linalg.eigh(jcov)
    normal = orient_normals(v[:, :, 0], toward)
    off = np.einsum("ij,ij->i", raw_c - c, normal)
    rms = np.sqrt(np.maximum(np.einsum("ij,ijk,ik->i", normal, raw_cov, normal) + off**2, 0.0))
    dip, dd = dip_and_direction(normal, toward)
    major = v[:, :, 2]
    jset = np.zeros(j_n, dtype=np.int64)
    jset[patch_joint] = patch_set
    dip_axis, strike_axis = dip_strike_axes(normal)
    sel = np.flatnonzero(point_joint >= 0)
    require(sel.shape[0] * 80.0, f"the extents of joints of {sel.shape[0]:,} points")
    q = point_joint[sel]
    spans = []
    for axis in (dip_axis, strike_axis, major):
        t = sum((xyz[a][sel] - c[q, a]) * axis[q, a] for a in range(3))
        hi = np.full(j_n, -np.inf)
        lo = np.full(j_n, np.inf)
        np.maximum.at(hi, q, t)
        np.minimum.at(lo, q, t)
        spans.append(np.where(hi >= lo, hi - lo, 0.0))
    return Joints(set_id=jset, patches=np.bincount(patch_joint, minlength=j_n).astype(np.int64),
                  points=cnt.astype(np.int64), normal=normal, dip_deg=dip,
                  dip_direction_deg=dd, centroid=c,
                  rms=rms,
                  area=np.bincount(patch_joint, weights=area, minlength=j_n),
                  persistence_dip=spans[0], persistence_strike=spans[1], trace_length=spans[2],
                  width=np.sqrt(np.maximum(w[:, 1], 0.0)))


def _pooled(group: np.ndarray, weight: np.ndarray, centroid: np.ndarray, cov: np.ndarray,
            n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """Weighted centroid and covariance of the union of every group's patches."""
    tot = np.bincount(group, weights=weight, minlength=n_groups)
    c = np.column_stack([np.bincount(group, weights=weight * centroid[:, a], minlength=n_groups)
                         for a in range(3)]) / tot[:, None]
    d = centroid - c[group]
    out = np.zeros((n_groups, 3, 3))
    np.add.at(out, group, weight[:, None, None] * (cov + d[:, :, None] * d[:, None, :]))
    return c, out / tot[:, None, None]


def _no_joints() -> Joints:
    e, e3, ei = np.zeros(0), np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    return Joints(set_id=ei, patches=ei, points=ei, normal=e3, dip_deg=e, dip_direction_deg=e,
                  centroid=e3, rms=e, area=e,
                  persistence_dip=e, persistence_strike=e, trace_length=e, width=e)


@dataclass(frozen=True)
class SetSpacing:
    """Spacing of one set's joints (metres; NaN without two joints apart)."""

    normal: np.ndarray
    """The normal spacings, one per consecutive pair of joints (more than the
    tolerance apart)."""
    scanline: np.ndarray
    """Every distance between consecutive crossings on the set's scanlines."""


@dataclass(frozen=True)
class _SetFrame:
    """A set's frame and its joints' planes in it: ``m`` the set's unit normal, ``e1``
    and ``e2`` its dip and strike axes; per joint (local index ``k``) the plane
    ``n . (p - origin) = base`` written as a height along ``m``."""

    m: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    base: np.ndarray
    a1: np.ndarray
    a2: np.ndarray
    nm: np.ndarray

    def height(self, k: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Height along ``m`` of joint ``k`` (local index) at in-plane ``(u, v)``, metres."""
        return (self.base[k] - u * self.a1[k] - v * self.a2[k]) / self.nm[k]


def _set_frame(joints: Joints, ids: np.ndarray, set_normal: np.ndarray, origin: np.ndarray,
               bin_size: float) -> _SetFrame:
    """The frame of the set of joints ``ids`` (:class:`_SetFrame`)."""
    m = np.asarray(set_normal, dtype=np.float64)
    m = m / np.linalg.norm(m)
    e1, e2 = (a[0] for a in dip_strike_axes(m[None]))
    # a joint narrower than a bin (a strip) has a poorly known tilt across it: its
    # plane is taken at the set's mean orientation through its centroid
    nj = np.where((joints.width[ids] >= bin_size)[:, None], joints.normal[ids], m[None])
    nm = nj @ m
    nm = np.where(np.abs(nm) < 1e-9, 1e-9, nm)
    base = np.einsum("ij,ij->i", nj, joints.centroid[ids] - origin)
    return _SetFrame(m=m, e1=e1, e2=e2, base=base, a1=nj @ e1, a2=nj @ e2, nm=nm)


@dataclass(frozen=True)
class _Bins:
    """Every point in a set's frame: in-plane ``u``, ``v`` and height ``hp`` (metres),
    its bin ``cell`` (row-major, ``width`` bins a row, from bin ``(u_lo, v_lo)``) and
    the points sorted by bin (``by_cell``, ``sorted_cell``)."""

    u: np.ndarray
    v: np.ndarray
    hp: np.ndarray
    cell: np.ndarray
    width: int
    u_lo: int
    v_lo: int
    by_cell: np.ndarray
    sorted_cell: np.ndarray


def _bin_points(frame: _SetFrame, xyz: tuple[np.ndarray, np.ndarray, np.ndarray],
                origin: np.ndarray, bin_size: float) -> _Bins:
    """Every point's bin and height in the set's frame (:class:`_Bins`)."""
    e1, e2, m = frame.e1, frame.e2, frame.m
    n_all = int(xyz[0].shape[0])
    require(n_all * 72.0, f"the scanlines of a set over {n_all:,} points")
    rel = [xyz[a] - origin[a] for a in range(3)]
    u = rel[0] * e1[0] + rel[1] * e1[1] + rel[2] * e1[2]
    v = rel[0] * e2[0] + rel[1] * e2[1] + rel[2] * e2[2]
    hp = rel[0] * m[0] + rel[1] * m[1] + rel[2] * m[2]
    del rel
    bu = np.floor(u / bin_size).astype(np.int64)
    bv = np.floor(v / bin_size).astype(np.int64)
    u_lo, v_lo = int(bu.min()), int(bv.min())
    bu -= u_lo
    bv -= v_lo
    width = int(bv.max()) + 1
    cell = bu * width + bv
    del bu, bv
    by_cell = np.argsort(cell, kind="stable")
    return _Bins(u=u, v=v, hp=hp, cell=cell, width=width, u_lo=u_lo, v_lo=v_lo,
                 by_cell=by_cell, sorted_cell=cell[by_cell])


def _covered_pairs(frame: _SetFrame, bins: _Bins, own: np.ndarray, band: np.ndarray,
                   point_joint: np.ndarray, k_n: int) -> np.ndarray:
    """``bin * k_n + joint`` of every bin a joint covers: those with its own points
    (``own``) and those within :data:`COVER_REACH_BINS` of them holding a point of
    no joint within ``band`` (metres) of its plane. A loop over joints, vectorised
    over points."""
    width, cell = bins.width, bins.cell
    own_cell, own_joint = own // k_n, own % k_n
    found = [own]
    for k in range(k_n):
        mine = own_cell[own_joint == k]
        if mine.size == 0:
            continue
        iu, iv = mine // width, mine % width
        lo_u, hi_u = int(iu.min()) - COVER_REACH_BINS, int(iu.max()) + COVER_REACH_BINS
        lo_v = max(int(iv.min()) - COVER_REACH_BINS, 0)
        hi_v = min(int(iv.max()) + COVER_REACH_BINS, width - 1)
        rows = np.arange(max(lo_u, 0), hi_u + 1)
        first = np.searchsorted(bins.sorted_cell, rows * width + lo_v)
        last = np.searchsorted(bins.sorted_cell, rows * width + hi_v, side="right")
        runs = last - first
        if int(runs.sum()) == 0:
            continue
        pick = bins.by_cell[np.repeat(first - np.cumsum(runs) + runs, runs)
                            + np.arange(int(runs.sum()))]
        pick = pick[point_joint[pick] < 0]  # points of no joint: never another's
        kk = np.full(pick.shape[0], k)
        near = np.abs(bins.hp[pick] - frame.height(kk, bins.u[pick], bins.v[pick])) <= band[k]
        found.append(cell[pick[near]] * k_n + k)
    return np.unique(np.concatenate(found))


def _bin_centres(c: np.ndarray, width: int, u_lo: int, v_lo: int, bin_size: float
                 ) -> tuple[np.ndarray, np.ndarray]:
    """In-plane coordinates of the centres of bins ``c`` (:class:`_Bins`), metres."""
    return (c // width + u_lo + 0.5) * bin_size, (c % width + v_lo + 0.5) * bin_size


def _normal_gaps(frame: _SetFrame, offset: np.ndarray, cells_of: list[np.ndarray],
                 centre: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Signed distances along the set's normal between consecutive joints (by their
    centroids' ``offset``), the mean over the bins both cover (``cells_of``), else
    between the centroids; metres. A loop over joints."""
    rank = np.argsort(offset, kind="stable")
    normal_gaps = []
    for a, b in zip(rank[:-1].tolist(), rank[1:].tolist(), strict=True):
        shared = np.intersect1d(cells_of[a], cells_of[b], assume_unique=True)
        if shared.size:
            su, sv = centre(shared)
            ka, kb = np.full(su.shape[0], a), np.full(su.shape[0], b)
            normal_gaps.append(float(np.mean(frame.height(kb, su, sv)
                                             - frame.height(ka, su, sv))))
        else:
            normal_gaps.append(float(offset[b] - offset[a]))
    return np.array(normal_gaps)


def set_spacing(joints: Joints, set_id: int, set_normal: np.ndarray,
                point_joint: np.ndarray, xyz: tuple[np.ndarray, np.ndarray, np.ndarray],
                origin: np.ndarray, bin_size: float, tolerance: float) -> SetSpacing:
    """Normal and scanline spacings of set ``set_id`` (module docstring).

    Parameters
    ----------
    joints : Joints
        The joints of every set.
    set_normal : (3,) array
        The set's unit mean normal.
    point_joint : (N,) int array
        Joint index 0..J-1 of every point, -1 for none.
    xyz : three (N,) arrays
        The points, metres.
    origin : (3,) array
        Reference point near the cloud (the grid origin), metres.
    bin_size : float
        Width of the in-plane bins (one cell), metres.
    tolerance : float
        Distances of at most this are no spacing, metres.
    """
    if not bin_size > 0:
        raise InputError(f"the bin size must be positive, got {bin_size:g}")
    ids = np.flatnonzero(joints.set_id == set_id)
    empty = SetSpacing(np.zeros(0), np.zeros(0))
    if ids.shape[0] < 2:
        return empty
    frame = _set_frame(joints, ids, set_normal, origin, bin_size)
    local = np.full(joints.n_joints, -1, dtype=np.int64)
    local[ids] = np.arange(ids.shape[0])
    # every point's bin and height in the set's frame: a joint covers the bins where
    # the cloud has points on its plane, through the strips where other joints cross
    # it (no planar cell there) and up to its edges
    bins = _bin_points(frame, xyz, origin, bin_size)
    width, k_n = bins.width, ids.shape[0]
    sel = np.flatnonzero(point_joint >= 0)
    sel = sel[local[point_joint[sel]] >= 0]
    q = local[point_joint[sel]]
    own = np.unique(bins.cell[sel] * k_n + q)  # (bin, joint) with the joint's own points
    own_cell, own_joint = own // k_n, own % k_n
    band = np.maximum(COVER_RMS_FACTOR * joints.rms[ids], 1e-9)
    pair = _covered_pairs(frame, bins, own, band, point_joint, k_n)
    b_cell, b_joint = _fill(pair // k_n // width, pair // k_n % width, pair % k_n, width, k_n)
    u_lo, v_lo = bins.u_lo, bins.v_lo
    del bins
    o_cell, o_joint = _fill(own_cell // width, own_cell % width, own_joint, width, k_n)

    def centre(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _bin_centres(c, width, u_lo, v_lo, bin_size)

    h = frame.height(b_joint, *centre(b_cell))
    # scanlines: per bin, crossings sorted by height
    order = np.lexsort((h, b_cell))
    hs, cs = h[order], b_cell[order]
    same = cs[1:] == cs[:-1]
    gaps = np.diff(hs)[same]
    scan = gaps[gaps > tolerance]
    # normal spacing: consecutive joints by their centroids' offsets along m,
    # measured where they overlap (else between the centroids)
    offset = (joints.centroid[ids] - origin) @ frame.m
    by_joint = np.argsort(o_joint, kind="stable")
    starts = np.searchsorted(o_joint[by_joint], np.arange(k_n + 1))
    cells_of = [o_cell[by_joint[starts[k]:starts[k + 1]]] for k in range(k_n)]
    g = np.abs(_normal_gaps(frame, offset, cells_of, centre))
    return SetSpacing(normal=g[g > tolerance], scanline=scan)


def _fill(bu: np.ndarray, bv: np.ndarray, joint: np.ndarray, width: int, k_n: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """The bins a joint covers: every bin whose centre lies in the convex hull of
    the bins with its points (the joint runs on through the strips where other
    joints cross it and leave no planar cell). A loop over joints, vectorised over
    bins. Returns the (bin, joint) rows, sorted by bin then joint, unique."""
    from scipy.spatial import ConvexHull, QhullError

    out_bin, out_joint = [], []
    order = np.argsort(joint, kind="stable")
    starts = np.searchsorted(joint[order], np.arange(k_n + 1))
    for k in range(k_n):
        rows = order[starts[k]:starts[k + 1]]
        u, v = bu[rows], bv[rows]
        if rows.shape[0] == 0:
            continue
        require(8.0 * 6 * float(u.max() - u.min() + 1) * float(v.max() - v.min() + 1),
                "the bins of a joint's scanlines", hint="choose a larger grid size")
        mu, mv = np.meshgrid(np.arange(u.min(), u.max() + 1), np.arange(v.min(), v.max() + 1),
                             indexing="ij")
        gu, gv = mu.ravel(), mv.ravel()
        inside: np.ndarray = np.zeros(gu.shape[0], dtype=bool)
        try:
            # the corners of the bins, so that a row of bins has an area
            corners = (np.column_stack([u, v])[:, None, :]
                       + np.array([[0, 0], [1, 0], [0, 1], [1, 1]])[None]).reshape(-1, 2)
            hull = ConvexHull(np.unique(corners, axis=0))
            eq = hull.equations
            centre = np.column_stack([gu + 0.5, gv + 0.5])
            inside = np.all(centre @ eq[:, :2].T + eq[:, 2] <= 1e-9, axis=1)
        except QhullError:
            pass
        inside[(u - u.min()) * (int(v.max() - v.min()) + 1) + (v - v.min())] = True
        out_bin.append(gu[inside] * width + gv[inside])
        out_joint.append(np.full(int(inside.sum()), k, dtype=np.int64))
    pair = np.unique(np.concatenate(out_bin) * k_n + np.concatenate(out_joint))
    return pair // k_n, pair % k_n
