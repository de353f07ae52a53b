"""Roughness of each joint set: its cells' ODR roughness, and the directional
roughness of its joints along their dip and along their strike (issue 30 item 4).

Two scales, two kinds of number (``docs/sets.md``, "Roughness of each set"):

- **Cell scale** (``odr_mean``, ``odr_median``, ``odr_std``): the mean, median and
  population standard deviation of the ODR roughness
  (:mod:`rough_viewer.grid.roughness`: the standard deviation of the absolute
  point-to-plane distances of a cell) of the cells whose poles made the set (the
  set's ``cells``; not the edge cells of fewer points its planes took in, whose
  few points see only a sliver of the surface). These are planar cells, so every
  value is at most the set's ``max_roughness`` (default 2 % of the cell): the
  numbers say how rough the set's planar parts are at the cell scale, never more
  than that threshold.
- **Joint scale, by direction**: every measured joint's points are turned into the
  joint's own frame: ``x`` down its dip (:func:`~rough_viewer.grid.orientation.
  dip_strike_axes`), ``y`` along its strike (right-hand rule, dip direction minus
  90 degrees), ``z`` along its upward normal (toward the viewer for a vertical
  joint), from its centroid. On that plane:

  * **profiles** (:func:`rough_viewer.profiles.profile_sets.profile_sets`, as
    ``rough-viewer directions`` lays them): parallel profiles along ``x`` (dip) and
    along ``y`` (strike), at most :data:`MAX_PROFILES_PER_JOINT` per joint and
    direction (spacing = the joint's larger in-plane extent / that number),
    band half-width and sample spacing the point spacing, each detrended by its
    own line; per profile ``Z2`` and its JRC estimate (Tse and Cruden 1979,
    ``32.2 + 32.47 log10 Z2``). ``jrc_estimate_dip`` / ``jrc_estimate_strike``
    are the means over every used profile of the set's measured joints: an
    **estimate**, calibrated for profiles sampled at 0.5-1 mm (a warning says when
    they are not; Z2 grows as the interval shrinks);
  * **triangles** (:func:`rough_viewer.tin.surface.triangulate_cloud` in the
    joint's plane, edges up to 5 point spacings): every facet's apparent dip along
    the shear direction ``t``, ``theta* = atan2(-(m . t), m . n)``, positive where
    the facet rises along ``t`` (faces the shear); the facets of all the set's
    measured joints, each in its own joint's frame, pooled into one distribution
    (:func:`rough_viewer.tin.directional.facet_roughness`): Grasselli's
    ``theta*max / (C + 1)`` (``theta_max_c1_dip``, ``theta_max_c1_strike``,
    degrees; Tatone and Grasselli 2009) and ``Delta-T`` (``delta_t_dip``,
    ``delta_t_strike``, degrees; Babanouri and Karami Nasab 2017). "Dip" is shear
    **down the dip** (``t = +x``: the rock on the open side of the scanned surface
    sliding down-dip across it), "strike" shear along the strike (``t = +y``).

  Corrugations whose crests run along the strike make the dip profiles rough and
  the strike profiles smooth: the set would shear more easily along its strike.

Work is bounded: per set the :data:`MAX_JOINTS_PER_SET` largest joints (by points)
within :data:`MAX_SET_POINTS` points in all, shared out equally among them (a joint
smaller than its share leaves the rest to the others, :func:`point_shares`); a
joint with more points than its share is measured on the disc of its points nearest
its centroid in its plane (its point spacing kept: thinning would change the
roughness). A loop over measured joints (at
most ``MAX_JOINTS_PER_SET`` per set), vectorised over points and facets; a joint
that cannot be measured (too few points, a line of points) is counted, not fatal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rough_viewer.grid.orientation import dip_strike_axes
from rough_viewer.memory import require
from rough_viewer.structure.joints import Joints
from rough_viewer.vocabulary import InputError

#: Joints measured per set at most (the largest by points).
MAX_JOINTS_PER_SET = 30
#: Points measured per set at most (profiles and triangles), over its joints.
MAX_SET_POINTS = 150_000
#: Profile lines per joint and direction at most.
MAX_PROFILES_PER_JOINT = 20
#: Fewest samples with data a profile needs (the wavelet de-noising's shortest run
#: of :func:`~rough_viewer.profiles.profile_sets.profile_sets`, db3 at level 3).
PROFILE_MIN_SAMPLES = 40
#: Least points of a joint to be measured at all.
MIN_JOINT_POINTS = 100
#: The shear directions in the joint's frame, degrees from its dip axis towards its
#: strike: down the dip, along the strike.
AZIMUTHS_DEG = (0.0, 90.0)
#: Bytes per measured point (local coordinates, the profiles' projection and
#: bands, the Delaunay triangulation's working memory and the facets).
BYTES_PER_POINT = 1_000.0


@dataclass(frozen=True)
class SetRoughness:
    """Roughness of every set (row ``k`` is set ``k + 1``; module docstring)."""

    odr_mean: np.ndarray
    """(S,) mean ODR roughness of the set's cells, metres."""
    odr_median: np.ndarray
    """(S,) median, metres."""
    odr_std: np.ndarray
    """(S,) population standard deviation, metres."""
    odr_cells: np.ndarray
    """(S,) int64 cells with an ODR value the three are of."""
    jrc_estimate_dip: np.ndarray
    """(S,) mean JRC estimate of the profiles along the joints' dip (dimensionless)."""
    jrc_estimate_strike: np.ndarray
    """(S,) mean JRC estimate of the profiles along the joints' strike."""
    z2_dip: np.ndarray
    """(S,) mean Z2 of the dip profiles (dimensionless)."""
    z2_strike: np.ndarray
    """(S,) mean Z2 of the strike profiles."""
    rms_dip: np.ndarray
    """(S,) mean RMS height of the dip profiles about their line, metres."""
    rms_strike: np.ndarray
    """(S,) mean RMS height of the strike profiles, metres."""
    profiles_dip: np.ndarray
    """(S,) int64 dip profiles used."""
    profiles_strike: np.ndarray
    """(S,) int64 strike profiles used."""
    theta_max_c1_dip: np.ndarray
    """(S,) ``theta*max/(C+1)`` of the pooled facets, shear down the dip, degrees."""
    theta_max_c1_strike: np.ndarray
    """(S,) the same along the strike, degrees."""
    delta_t_dip: np.ndarray
    """(S,) ``Delta-T``, shear down the dip, degrees."""
    delta_t_strike: np.ndarray
    """(S,) ``Delta-T`` along the strike, degrees."""
    joints_measured: np.ndarray
    """(S,) int64 joints measured (profiles or triangles)."""
    points_measured: np.ndarray
    """(S,) int64 points measured."""
    triangles: np.ndarray
    """(S,) int64 facets pooled."""
    sample_spacing: np.ndarray
    """(S,) median sample spacing of the measured joints' profiles, metres."""
    warnings: tuple[str, ...] = ()
    """What the reader should know: the JRC estimate's sampling, joints left out."""

    @property
    def n_sets(self) -> int:
        """Number of sets."""
        return int(self.odr_mean.shape[0])


def cell_odr_statistics(cell_set: np.ndarray, theta_odr: np.ndarray, n_sets: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean, median, population standard deviation (metres) and count of the ODR
    roughness of every set's cells (NaN values left out).

    >>> m, med, sd, n = cell_odr_statistics(np.array([1, 1, 1, 2, 0]),
    ...                                     np.array([1.0, 2.0, 6.0, np.nan, 9.0]), 2)
    >>> m.tolist(), med.tolist(), sd.round(4).tolist(), n.tolist()
    ([3.0, nan], [2.0, nan], [2.1602, nan], [3, 0])
    """
    s = np.asarray(cell_set, dtype=np.int64)
    t = np.asarray(theta_odr, dtype=np.float64)
    ok = (s > 0) & (s <= n_sets) & np.isfinite(t)
    s, t = s[ok], t[ok]
    n = np.bincount(s, minlength=n_sets + 1)[1:].astype(np.int64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.bincount(s, weights=t, minlength=n_sets + 1)[1:] / n
    # the deviation from the mean of each value (no cancellation of mean(t^2) - mean^2)
    dev = t - mean[s - 1] if s.size else t
    var = np.bincount(s, weights=dev * dev, minlength=n_sets + 1)[1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        std = np.sqrt(var / n)
    order = np.lexsort((t, s))
    ss, ts = s[order], t[order]
    first = np.searchsorted(ss, np.arange(1, n_sets + 1))
    median = np.full(n_sets, np.nan)
    has = n > 0
    lo = first[has] + (n[has] - 1) // 2
    hi = first[has] + n[has] // 2
    median[has] = 0.5 * (ts[lo] + ts[hi])
    return mean, median, std, n


def point_shares(points: np.ndarray, budget: int) -> np.ndarray:
    """Points each joint is measured on: ``budget`` shared out equally, a joint
    smaller than its share taking only its own points and leaving the rest to the
    others (water filling); never more than ``budget`` in all.

    >>> point_shares(np.array([50_000, 1_000, 300_000, 200_000]), 100_000).tolist()
    [33000, 1000, 33000, 33000]
    >>> point_shares(np.array([10, 20]), 100).tolist()
    [10, 20]
    """
    p = np.asarray(points, dtype=np.int64)
    out = np.zeros_like(p)
    left = int(budget)
    for i, j in enumerate(np.argsort(p, kind="stable").tolist()):  # smallest first
        out[j] = min(int(p[j]), left // (p.size - i))
        left -= int(out[j])
    return out


def _count(counts: dict[str, int], why: str, k: int) -> None:
    if k > 0:
        counts[why] = counts.get(why, 0) + int(k)


def _no_sets() -> SetRoughness:
    e, ei = np.zeros(0), np.zeros(0, dtype=np.int64)
    return SetRoughness(*(e,) * 3, ei, *(e,) * 6, ei, ei, *(e,) * 4, ei, ei, ei, e)


#: The directional values of the profiles, by key: ``jrc0`` dip, ``jrc1`` strike, ...
_PROFILE_KEYS = ("jrc0", "jrc1", "z20", "z21", "rms0", "rms1")


class _Tally:
    """What the measured joints of every set give, gathered joint by joint (mutable,
    local to one :func:`set_roughness` call)."""

    def __init__(self, n_sets: int) -> None:
        self.values: dict[str, list[list[np.ndarray]]] = {
            k: [[] for _ in range(n_sets)] for k in _PROFILE_KEYS}
        self.steps: list[list[float]] = [[] for _ in range(n_sets)]
        self.normals: list[np.ndarray] = []
        self.areas: list[np.ndarray] = []
        self.groups: list[np.ndarray] = []
        self.measured = np.zeros(n_sets, dtype=np.int64)
        self.points = np.zeros(n_sets, dtype=np.int64)
        self.skipped: dict[str, int] = {}

    def pooled(self, key: str) -> np.ndarray:
        """(S,) mean of the finite values of ``key`` of every set, NaN where none."""
        out = np.full(len(self.steps), np.nan)
        for s, parts in enumerate(self.values[key]):
            v = np.concatenate(parts) if parts else np.zeros(0)
            v = v[np.isfinite(v)]
            if v.size:
                out[s] = float(v.mean())
        return out

    def count(self, key: str) -> np.ndarray:
        """(S,) int64 values of ``key`` of every set (the profiles used)."""
        return np.array([sum(int(v.size) for v in parts) for parts in self.values[key]],
                        dtype=np.int64)


def _measured_joints(joints: Joints, s: int, max_joints: int, max_points: int,
                     skipped: dict[str, int]) -> tuple[list[int], list[int]]:
    """The joints of set ``s + 1`` to measure (largest first, at most ``max_joints``)
    and the points each may give (:func:`point_shares`); the rest counted in
    ``skipped``."""
    ids = np.flatnonzero(joints.set_id == s + 1)  # largest first (joint ids' order)
    big = ids[joints.points[ids] >= MIN_JOINT_POINTS]
    _count(skipped, f"fewer than {MIN_JOINT_POINTS} points", ids.size - big.size)
    _count(skipped, f"beyond the {max_joints} largest of a set", big.size - max_joints)
    big = big[:max_joints]
    caps = point_shares(joints.points[big], int(max_points))
    _count(skipped, f"its share of the {max_points:,} points measured per set under "
           f"{MIN_JOINT_POINTS}", int(np.count_nonzero(caps < MIN_JOINT_POINTS)))
    return big.tolist(), caps.tolist()


def _joint_frame(rows: np.ndarray, rot: np.ndarray, centroid: np.ndarray,
                 xyz: tuple[np.ndarray, np.ndarray, np.ndarray], cap: int,
                 skipped: dict[str, int]) -> np.ndarray:
    """(n, 3) points ``rows`` of a joint in its own frame (rows of ``rot``: dip,
    strike, normal; from its centroid), metres; at most ``cap`` of them, the disc of
    those nearest the centroid (its spacing kept)."""
    require(rows.shape[0] * 32.0, f"the points of a joint of {rows.shape[0]:,} points")
    loc = np.column_stack([xyz[a][rows] - centroid[a] for a in range(3)]) @ rot.T
    if loc.shape[0] > cap:  # the disc about its centroid: its spacing kept
        _count(skipped, "measured on the disc of its points nearest its centroid, "
               "partly", 1)
        r2 = loc[:, 0] ** 2 + loc[:, 1] ** 2
        loc = loc[np.argpartition(r2, cap - 1)[:cap]]
    return loc


def _measure_joint(loc: np.ndarray, s: int, tally: _Tally, max_profiles: int) -> bool:
    """Measure one joint of set ``s + 1`` (its points ``loc`` in its own frame,
    metres) into ``tally``: its spacing, its profiles' values along dip and strike and
    its facets. True where profiles or triangles gave something."""
    from rough_viewer.grid.maps import FacePlane
    from rough_viewer.grid.spacing import neighbour_distance
    from rough_viewer.profiles.profile_sets import profile_sets
    from rough_viewer.tin.surface import MAX_EDGE_SPACINGS, facets, triangulate_cloud

    skipped = tally.skipped
    local_plane = FacePlane(centroid=np.zeros(3), normal=np.array([0.0, 0.0, 1.0]))
    extent = float(np.max(loc[:, :2].max(axis=0) - loc[:, :2].min(axis=0)))
    try:  # the point spacing, as profiles and triangles take it
        spacing = neighbour_distance(loc[:, :2], k=4)
    except InputError:
        _count(skipped, "its points coincide", 1)
        return False
    tally.steps[s].append(spacing)
    took = False
    try:
        sets = profile_sets(loc, AZIMUTHS_DEG, plane=local_plane,
                            spacing=extent / max_profiles, band_half_width=spacing,
                            sample_spacing=spacing, min_samples=PROFILE_MIN_SAMPLES)
    except InputError:
        sets = ()
        _count(skipped, "no profiles", 1)
    for d, ps in enumerate(sets):
        used = ps.used
        if used.any():
            took = True
            for name in ("jrc", "z2", "rms"):
                tally.values[f"{name}{d}"][s].append(ps.values[name][used])
    try:
        mesh = triangulate_cloud(loc, plane=local_plane, max_edge=MAX_EDGE_SPACINGS * spacing)
        f = facets(mesh, toward=np.array([0.0, 0.0, 1.0]))
    except InputError:
        _count(skipped, "no triangles", 1)
    else:
        if f.areas.size:
            took = True
            tally.normals.append(f.normals)
            tally.areas.append(f.areas)
            tally.groups.append(np.full(f.areas.size, s, dtype=np.int64))
    return took


def _facet_statistics(tally: _Tally, n_sets: int
                      ) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """``theta_max_c1`` and ``delta_t`` ((S, 2): dip, strike; degrees, NaN where no
    facet) of the pooled facets of every set, and the facets pooled ((S,) int64)."""
    from rough_viewer.tin.directional import facet_roughness

    tin = {k: np.full((n_sets, 2), np.nan) for k in ("theta_max_c1", "delta_t")}
    tri = np.zeros(n_sets, dtype=np.int64)
    if tally.normals:
        g = np.concatenate(tally.groups)
        res = facet_roughness(np.concatenate(tally.normals), np.concatenate(tally.areas), g,
                              n_sets, AZIMUTHS_DEG)
        tin = {k: res[k] for k in ("theta_max_c1", "delta_t")}
        tri = np.bincount(g, minlength=n_sets).astype(np.int64)
    return tin, tri


def _warnings(step: np.ndarray, profiles: np.ndarray, skipped: dict[str, int]) -> list[str]:
    """What the reader should know: the JRC estimate's sampling (``step``, (S,) median
    sample spacing, metres), the sets without profiles, the joints left out."""
    from rough_viewer.profiles.jrc import jrc_warnings

    warnings: list[str] = []
    if profiles.any():
        warnings += list(jrc_warnings(float(np.nanmedian(step[profiles > 0]))))
    for s in np.flatnonzero((profiles == 0) & np.isfinite(step)).tolist():
        warnings.append(f"set {s + 1}: no JRC estimate: no profile on its joints has the "
                        f"{PROFILE_MIN_SAMPLES} samples with data a profile needs (sampled "
                        f"every {step[s] * 1e3:.3g} mm, the point spacing)")
    for why, k in skipped.items():
        if why.startswith("measured"):
            warnings.append(f"set roughness: {k:,} joint{'s' if k != 1 else ''} {why}")
        else:
            warnings.append(f"set roughness: {k:,} joint{'s' if k != 1 else ''} not "
                            f"measured ({why})")
    return warnings


def set_roughness(
    cell_set: np.ndarray,
    theta_odr: np.ndarray,
    n_sets: int,
    joints: Joints,
    point_joint: np.ndarray,
    xyz: tuple[np.ndarray, np.ndarray, np.ndarray],
    *,
    max_joints: int = MAX_JOINTS_PER_SET,
    max_points: int = MAX_SET_POINTS,
    max_profiles: int = MAX_PROFILES_PER_JOINT,
    directional: bool = True,
) -> SetRoughness:
    """The roughness of every set (module docstring).

    Parameters
    ----------
    cell_set : (M,) int array
        Set of every cell whose roughness counts, 1..S, 0 for none.
    theta_odr : (M,) array
        ODR roughness of every cell, metres (NaN where none).
    n_sets : int
        ``S``.
    joints : Joints
        The sets' joints (:mod:`rough_viewer.structure.joints`).
    point_joint : (N,) int array
        Joint index 0..J-1 of every point, -1 for none.
    xyz : three (N,) arrays
        The points, metres.
    max_joints, max_points, max_profiles : int
        The bounds of the work (module docstring).
    directional : bool
        Measure the joints along dip and strike (default); False gives the cell
        statistics only (the directional values NaN, in a fraction of the time).

    Returns
    -------
    SetRoughness
    """
    if n_sets == 0:
        return _no_sets()
    if max_joints < 1 or max_points < MIN_JOINT_POINTS or max_profiles < 1:
        raise InputError("set roughness needs at least one joint, one profile and "
                         f"{MIN_JOINT_POINTS} points per set")
    odr = cell_odr_statistics(cell_set, theta_odr, n_sets)
    pj = np.asarray(point_joint, dtype=np.int64)
    sel = np.flatnonzero(pj >= 0)
    order = sel[np.argsort(pj[sel], kind="stable")]
    starts = np.searchsorted(pj[order], np.arange(joints.n_joints + 1))
    dip_axis, strike_axis = dip_strike_axes(joints.normal) if joints.n_joints else (
        np.zeros((0, 3)), np.zeros((0, 3)))
    tally = _Tally(n_sets)
    for s in range(n_sets if directional else 0):
        for j, cap in zip(*_measured_joints(joints, s, max_joints, max_points, tally.skipped),
                          strict=True):
            if cap < MIN_JOINT_POINTS:
                continue
            rot = np.stack([dip_axis[j], strike_axis[j], joints.normal[j]])
            loc = _joint_frame(order[starts[j]:starts[j + 1]], rot, joints.centroid[j], xyz,
                               cap, tally.skipped)
            n = loc.shape[0]
            require(n * BYTES_PER_POINT, f"the roughness of a joint of {n:,} points",
                    hint="choose a larger grid size")
            if _measure_joint(loc, s, tally, max_profiles):
                tally.measured[s] += 1
                tally.points[s] += n
    tin, tri = _facet_statistics(tally, n_sets)
    step = np.array([float(np.median(v)) if v else np.nan for v in tally.steps])
    profiles = tally.count("jrc0") + tally.count("jrc1")
    return SetRoughness(
        odr_mean=odr[0], odr_median=odr[1], odr_std=odr[2], odr_cells=odr[3],
        jrc_estimate_dip=tally.pooled("jrc0"), jrc_estimate_strike=tally.pooled("jrc1"),
        z2_dip=tally.pooled("z20"), z2_strike=tally.pooled("z21"),
        rms_dip=tally.pooled("rms0"), rms_strike=tally.pooled("rms1"),
        profiles_dip=tally.count("jrc0"), profiles_strike=tally.count("jrc1"),
        theta_max_c1_dip=tin["theta_max_c1"][:, 0],
        theta_max_c1_strike=tin["theta_max_c1"][:, 1],
        delta_t_dip=tin["delta_t"][:, 0], delta_t_strike=tin["delta_t"][:, 1],
        joints_measured=tally.measured, points_measured=tally.points, triangles=tri,
        sample_spacing=step,
        warnings=tuple(dict.fromkeys(_warnings(step, profiles, tally.skipped))))
