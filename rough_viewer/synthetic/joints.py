"""A synthetic scan of a rock face cut by planted joint sets, with its ground truth.

The face is a weathered, broken rock wall (rough at every scale of a grid cell) from
which joint-bounded blocks stand out; each block shows one planar joint face towards
the scanner. Every joint face is a piece of one planted discontinuity plane:

- **sets**: each :class:`JointSetSpec` has a mean orientation (dip, dip direction,
  the conventions of :mod:`rough_viewer.grid.orientation`), a Fisher concentration
  ``kappa`` of its planes' normals, a mean normal spacing and a number of planes;
- **planes**: the normals are drawn from a Fisher distribution about the set's mean
  and then rotated, and their angles from the mean scaled, so that the planted
  planes have **exactly** the set's mean normal and ``kappa`` (as the large-sample
  estimate ``1 / (1 - R)``, ``R`` the mean resultant length, every plane of a set
  the same size): the numbers a method should find are the planted ones, not
  those of a random draw. Consecutive planes of a set lie ``spacing * (1 + u)``
  apart along the set's mean normal (``u`` uniform in ``+-spacing_jitter``, scaled
  so the mean spacing is exact), measured at the planes' centres;
- **exposures**: each plane is exposed as a rectangle of ``dip_length_m`` along its
  own dip and ``strike_length_m`` along its strike, centred on the design face
  ``y = 0``. The rectangles of one set are laid out along the direction of the
  face in which the set's offset grows (so every centre lies on the face), zigzag
  across it so they do not overlap; the sets sit side by side along ``x``;
- **the wall** behind them lies ``recess_m`` behind the deepest exposure, with a
  fractal relief of a few centimetres (rough, never planar at the cell scale).

Scanning follows :mod:`rough_viewer.synthetic.outcrop`: one scanner on the ``-y``
side, rays on a regular angular grid, the surfaces sampled more densely than the
rays and only the nearest sample per ray kept (a z-buffer), so the blocks shadow
the wall behind them and no point lies on a block's far side; Gaussian range noise
along each ray.

Truth per point: the plane (``-1`` for the wall) and its set (``0`` for the wall);
per plane: set, normal, centre, dimensions and offset (:class:`PlantedPlanes`).

>>> scan = generate_joint_block(JointBlockSpec(angular_step_rad=4e-3))
>>> scan.planes.n_planes, int(np.unique(scan.set_id[scan.plane >= 0]).size)
(18, 3)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rough_viewer.grid.orientation import dip_strike_axes, plane_normals
from rough_viewer.io.cloud import PointCloud
from rough_viewer.synthetic._noise import FractalNoise2D
from rough_viewer.synthetic._scan import angles_of, nearest_per_pixel
from rough_viewer.vocabulary import InputError


@dataclass(frozen=True)
class JointSetSpec:
    """One planted joint set (metres, degrees)."""

    dip_deg: float
    """Dip of the set's mean plane, degrees below horizontal."""
    dip_direction_deg: float
    """Dip direction of the set's mean plane, degrees clockwise from +y."""
    kappa: float
    """Fisher concentration of the planes' normals (exact, see the module)."""
    spacing_m: float
    """Mean normal spacing of consecutive planes (m)."""
    planes: int
    """Number of planes."""
    dip_length_m: float
    """Size of every exposure along its dip (m)."""
    strike_length_m: float
    """Size of every exposure along its strike (m)."""
    spacing_jitter: float = 0.2
    """Consecutive spacings vary by up to this share of ``spacing_m``."""


#: The default sets: a set dipping towards the scanner, and two steep sets facing
#: it obliquely from either side (43 to 78 degrees apart).
DEFAULT_SETS: tuple[JointSetSpec, ...] = (
    JointSetSpec(dip_deg=50.0, dip_direction_deg=180.0, kappa=150.0, spacing_m=1.0, planes=6,
                 dip_length_m=2.0, strike_length_m=2.6),
    JointSetSpec(dip_deg=75.0, dip_direction_deg=140.0, kappa=100.0, spacing_m=1.5, planes=6,
                 dip_length_m=2.4, strike_length_m=1.8),
    JointSetSpec(dip_deg=78.0, dip_direction_deg=221.0, kappa=200.0, spacing_m=1.2, planes=6,
                 dip_length_m=2.2, strike_length_m=2.0),
)


@dataclass(frozen=True)
class JointBlockSpec:
    """Everything that defines a synthetic joint-block scan (metres, radians)."""

    sets: tuple[JointSetSpec, ...] = DEFAULT_SETS
    """The planted sets."""
    gap_m: float = 0.6
    """Least gap between two exposures on the face, and between the sets' areas (m)."""
    recess_m: float = 0.6
    """How far the wall lies behind the deepest point of any exposure (m)."""
    wall_relief_m: tuple[float, ...] = (0.1, 0.08, 0.05, 0.03)
    """Amplitudes of the wall's relief octaves (m) ..."""
    wall_scales_m: tuple[float, ...] = (0.4, 0.2, 0.1, 0.05)
    """... at these pitches (m): rough at every cell size from 5 cm to 1 m."""
    margin_m: float = 1.0
    """Wall beyond the exposures on every side (m)."""
    scanner_distance_m: float = 30.0
    """Distance of the scanner in front of the face (m, on the -y side)."""
    scanner_height_m: float = 5.0
    """Height of the scanner above the face's foot (m)."""
    angular_step_rad: float = 1.5e-3
    """Angular step of the scanner's rays (rad); 1.5e-3 rad is 4.5 cm at 30 m."""
    range_noise_m: float = 0.002
    """Standard deviation of the Gaussian range noise (m)."""
    oversampling: float = 0.6
    """Surface sample spacing as a share of the ray spacing at the nearest point."""
    seed: int = 26
    """Seed of every random choice."""


#: The default joint block (about 200 k points).
JOINT_BLOCK = JointBlockSpec()


@dataclass(frozen=True, eq=False)
class PlantedPlanes:
    """The planted discontinuity planes, one row per plane (0..P-1)."""

    set_id: np.ndarray
    """(P,) int64 set of every plane, 1..S (the order of ``spec.sets``)."""
    normal: np.ndarray
    """(P, 3) unit normal, upward."""
    centre: np.ndarray
    """(P, 3) centre of the exposure (m)."""
    dip_axis: np.ndarray
    """(P, 3) unit down-dip direction in the plane."""
    strike_axis: np.ndarray
    """(P, 3) unit strike direction in the plane (horizontal)."""
    dip_length_m: np.ndarray
    """(P,) size along dip (m)."""
    strike_length_m: np.ndarray
    """(P,) size along strike (m)."""
    offset_m: np.ndarray
    """(P,) position of the centre along its set's mean normal (m)."""

    @property
    def n_planes(self) -> int:
        """Number of planes."""
        return int(self.set_id.shape[0])


@dataclass(frozen=True, eq=False)
class JointBlockScan:
    """A synthetic joint-block scan with its ground truth."""

    cloud: PointCloud
    """Points (m), in scan order."""
    plane: np.ndarray
    """(N,) int32 planted plane of every point (row of :attr:`planes`), -1 on the wall."""
    set_id: np.ndarray
    """(N,) uint8 set of every point, 1..S; 0 on the wall."""
    planes: PlantedPlanes
    """The planted planes."""
    set_normal: np.ndarray
    """(S, 3) planted mean normal of every set, upward."""
    spec: JointBlockSpec = field(repr=False)
    """The spec the scan was made from."""

    def spacings(self, set_id: int) -> np.ndarray:
        """The planted normal spacings of set ``set_id`` (1..S), consecutive planes (m)."""
        off = np.sort(self.planes.offset_m[self.planes.set_id == set_id])
        return np.diff(off)


def _rotation_to(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking unit vector ``a`` onto unit vector ``b``."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if np.linalg.norm(v) < 1e-15:
        return np.eye(3) if c > 0 else -np.eye(3)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def exact_fisher_normals(rng: np.random.Generator, axis: np.ndarray, kappa: float,
                         n: int) -> np.ndarray:
    """``n`` unit vectors drawn from a Fisher distribution about ``axis`` and adjusted
    so that their mean is ``axis`` and their mean resultant length is ``1 - 1/kappa``
    exactly (a sample with the planted statistics).

    >>> v = exact_fisher_normals(np.random.default_rng(1), np.array([0.0, 0, 1]), 50.0, 8)
    >>> m = v.mean(axis=0)
    >>> bool(np.allclose(m / np.linalg.norm(m), [0, 0, 1]))
    True
    >>> round(float(1 / (1 - np.linalg.norm(m))), 6)
    50.0
    """
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    if n < 2:
        return axis[None].copy()
    u = rng.uniform(0.0, 1.0, n)
    cos_t = 1.0 + np.log(u + (1.0 - u) * np.exp(-2.0 * kappa)) / kappa
    theta = np.arccos(np.clip(cos_t, -1.0, 1.0))
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    target = 1.0 - 1.0 / kappa
    z = np.array([0.0, 0.0, 1.0])
    local = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    for _ in range(50):
        m = local.mean(axis=0)
        local = local @ _rotation_to(m / np.linalg.norm(m), z).T
        theta = np.arccos(np.clip(local[:, 2], -1.0, 1.0))
        phi = np.arctan2(local[:, 1], local[:, 0])
        lo, hi = 0.0, np.pi / max(float(theta.max()), 1e-12)
        for _ in range(80):  # scale the angles so that mean(cos) is the target
            c = 0.5 * (lo + hi)
            if np.mean(np.cos(c * theta)) > target:
                lo = c
            else:
                hi = c
        theta = 0.5 * (lo + hi) * theta
        local = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                                 np.cos(theta)])
        m = local.mean(axis=0)
        if np.hypot(m[0], m[1]) < 1e-13 * np.linalg.norm(m):
            break
    return local @ _rotation_to(z, axis).T


def _footprint(dip: np.ndarray, strike: np.ndarray, s: JointSetSpec) -> np.ndarray:
    """(4, 3) corners of an exposure about the origin."""
    a, b = 0.5 * s.dip_length_m, 0.5 * s.strike_length_m
    return np.array([i * a * dip + j * b * strike for i in (-1, 1) for j in (-1, 1)])


def _layout(spec: JointBlockSpec, rng: np.random.Generator):
    """Planted planes: normals, centres (on y = 0), axes and offsets, set by set."""
    rows: list[tuple[int, np.ndarray, np.ndarray, JointSetSpec, float]] = []
    set_normals = []
    x_cursor = 0.0
    for k, s in enumerate(spec.sets, start=1):
        if s.planes < 1 or s.spacing_m <= 0 or s.kappa <= 1 or s.dip_length_m <= 0 \
                or s.strike_length_m <= 0 or not 0 <= s.spacing_jitter < 1:
            raise InputError(f"joint set {k}: planes >= 1, spacing, kappa > 1, sizes > 0 and "
                             "a jitter in [0, 1) are needed")
        mean_n = plane_normals(np.array([s.dip_deg]), np.array([s.dip_direction_deg]))[0]
        set_normals.append(mean_n)
        proj = np.array([mean_n[0], mean_n[2]])  # the offset's gradient on the face (x, z)
        size = float(np.linalg.norm(proj))
        if size < 0.2 or abs(mean_n[1]) < 0.3:
            raise InputError(f"joint set {k} is nearly parallel or perpendicular to the face "
                             "y = 0; it cannot be laid out on it")
        e = proj / size
        e_perp = np.array([-e[1], e[0]])
        steps = s.spacing_m * (1.0 + rng.uniform(-s.spacing_jitter, s.spacing_jitter,
                                                 max(s.planes - 1, 0)))
        if steps.size:
            steps *= s.spacing_m / steps.mean()
        offsets = np.concatenate([[0.0], np.cumsum(steps)])
        offsets -= offsets.mean()
        normals = exact_fisher_normals(rng, mean_n, s.kappa, s.planes)
        dip, strike = dip_strike_axes(normals)
        corners = np.stack([_footprint(dip[j], strike[j], s) for j in range(s.planes)])
        fx = corners[:, :, [0, 2]]  # corners on the face (x, z)
        along = fx @ e
        across = fx @ e_perp
        half_across = float(np.max(np.abs(across)))
        # consecutive exposures zigzag across e; every second one must clear along e
        w = half_across + 0.5 * spec.gap_m
        reach = float(np.max(np.abs(along)))
        if s.planes > 2 and float((steps[1:] + steps[:-1]).min()) / size < \
                2.0 * reach + spec.gap_m:
            raise InputError(f"joint set {k}: exposures of {s.dip_length_m:g} x "
                             f"{s.strike_length_m:g} m overlap at a spacing of {s.spacing_m:g} m")
        pos = offsets[:, None] / size * e[None] + np.where(
            np.arange(s.planes) % 2 == 0, -w, w)[:, None] * e_perp[None]
        lo = (pos[:, None, :] + fx).reshape(-1, 2).min(axis=0)
        hi = (pos[:, None, :] + fx).reshape(-1, 2).max(axis=0)
        shift = np.array([x_cursor - lo[0], -lo[1]])
        x_cursor += float(hi[0] - lo[0]) + spec.gap_m
        for j in range(s.planes):
            fxz = pos[j] + shift
            rows.append((k, normals[j], np.array([fxz[0], 0.0, fxz[1]]), s, float(offsets[j])))
    set_id = np.array([r[0] for r in rows], dtype=np.int64)
    normal = np.array([r[1] for r in rows])
    centre = np.array([r[2] for r in rows])
    dip, strike = dip_strike_axes(normal)
    # the lowest exposure starts one margin above the face's foot (z = 0)
    reach_z = np.array([np.max(np.abs(_footprint(dip[j], strike[j], r[3])[:, 2]))
                        for j, r in enumerate(rows)])
    centre[:, 2] += spec.margin_m - float(np.min(centre[:, 2] - reach_z))
    set_n = np.array(set_normals)
    offset = np.einsum("ij,ij->i", centre, set_n[set_id - 1])
    planes = PlantedPlanes(
        set_id=set_id, normal=normal, centre=centre, dip_axis=dip, strike_axis=strike,
        dip_length_m=np.array([r[3].dip_length_m for r in rows]),
        strike_length_m=np.array([r[3].strike_length_m for r in rows]),
        offset_m=offset)
    return planes, set_n


def generate_joint_block(spec: JointBlockSpec = JOINT_BLOCK) -> JointBlockScan:
    """Build and scan the joint block of ``spec`` (see the module docstring).

    Returns
    -------
    JointBlockScan
        Points in scan order, with the planted plane and set of every point.
    """
    if not spec.sets:
        raise InputError("a joint block needs at least one set")
    rng = np.random.default_rng([spec.seed, 26])
    planes, set_n = _layout(spec, rng)
    corners = np.concatenate([
        planes.centre[p] + np.array([i * 0.5 * planes.dip_length_m[p] * planes.dip_axis[p]
                                     + j * 0.5 * planes.strike_length_m[p] * planes.strike_axis[p]
                                     for i in (-1, 1) for j in (-1, 1)])
        for p in range(planes.n_planes)])
    lo = corners.min(axis=0) - spec.margin_m
    hi = corners.max(axis=0) + spec.margin_m
    lo[2] = max(lo[2], 0.0)
    wall_y = float(corners[:, 1].max()) + spec.recess_m
    scanner = np.array([0.5 * (lo[0] + hi[0]), -spec.scanner_distance_m, spec.scanner_height_m])
    nearest = float(np.min(np.linalg.norm(corners - scanner, axis=1)))
    step = spec.oversampling * spec.angular_step_rad * max(nearest - 1.0, 1.0)
    require_samples = (hi[0] - lo[0]) * (hi[2] - lo[2]) / step**2
    if require_samples > 5e7:
        raise InputError(f"the joint block would need {require_samples:,.0f} surface samples; "
                         "choose a coarser angular step")
    # the wall: a jittered raster on the face, rough relief along -y
    relief = FractalNoise2D(np.random.default_rng([spec.seed, 1]),
                            (float(hi[0] - lo[0]) + 2.0, float(hi[2] - lo[2]) + 2.0),
                            spec.wall_scales_m, spec.wall_relief_m)
    srng = np.random.default_rng([spec.seed, 2])
    nx, nz = int(np.ceil((hi[0] - lo[0]) / step)), int(np.ceil((hi[2] - lo[2]) / step))
    ii, jj = np.meshgrid(np.arange(nx), np.arange(nz), indexing="ij")
    wx = lo[0] + (ii.ravel() + srng.uniform(0, 1, ii.size)) * step
    wz = lo[2] + (jj.ravel() + srng.uniform(0, 1, jj.size)) * step
    wy = wall_y + relief(wx - lo[0], wz - lo[2])
    samples = [np.column_stack([wx, wy, wz])]
    labels = [np.full(wx.shape[0], -1, dtype=np.int32)]
    for p in range(planes.n_planes):
        na = max(1, int(np.ceil(planes.dip_length_m[p] / step)))
        nb = max(1, int(np.ceil(planes.strike_length_m[p] / step)))
        ia, ib = np.meshgrid(np.arange(na), np.arange(nb), indexing="ij")
        a = ((ia.ravel() + srng.uniform(0, 1, ia.size)) / na - 0.5) * planes.dip_length_m[p]
        b = ((ib.ravel() + srng.uniform(0, 1, ib.size)) / nb - 0.5) * planes.strike_length_m[p]
        samples.append(planes.centre[p] + a[:, None] * planes.dip_axis[p]
                       + b[:, None] * planes.strike_axis[p])
        labels.append(np.full(a.shape[0], p, dtype=np.int32))
    xyz = np.concatenate(samples)
    label = np.concatenate(labels)
    phi, theta, rng_m = angles_of(xyz, scanner)
    ip = np.floor(phi / spec.angular_step_rad + 0.5).astype(np.int64)
    it = np.floor(theta / spec.angular_step_rad + 0.5).astype(np.int64)
    win = nearest_per_pixel(ip * (1 << 24) + (it + (1 << 23)), rng_m)
    xyz, label, rng_m = xyz[win], label[win], rng_m[win]
    noisy = rng_m + np.random.default_rng([spec.seed, 3]).normal(0.0, spec.range_noise_m,
                                                                 rng_m.shape[0])
    xyz = scanner + (xyz - scanner) * (noisy / rng_m)[:, None]
    set_id = np.where(label >= 0, planes.set_id[np.maximum(label, 0)], 0).astype(np.uint8)
    return JointBlockScan(cloud=PointCloud.from_xyz(xyz), plane=label, set_id=set_id,
                          planes=planes, set_normal=set_n, spec=spec)


# --- a rock mass cut by persistent joints -------------------------------------------


@dataclass(frozen=True)
class RockMassSetSpec:
    """One planted set of persistent joints through a rock mass (metres, degrees)."""

    dip_deg: float
    """Dip of the set's mean plane, degrees below horizontal."""
    dip_direction_deg: float
    """Dip direction of the set's mean plane, degrees clockwise from +y."""
    joints: int
    """Number of joints."""
    spacing_m: float
    """Mean normal spacing of consecutive joints, along the set's mean normal through
    the block's centre (m)."""
    kappa: float = 400.0
    """Fisher concentration of the joints' normals (exact, as
    :func:`exact_fisher_normals` plants it)."""
    spacing_jitter: float = 0.1
    """Consecutive spacings vary by up to this share of ``spacing_m``."""
    corrugation_m: float = 0.0
    """Amplitude of the corrugations of every joint of the set (m; 0: planar): each
    joint is displaced along its own normal by ``corrugation_m * sin(2 pi a /
    corrugation_wavelength_m + phase)``, ``a`` the distance along its own dip, the
    phase random per joint; the crests run along the strike."""
    corrugation_wavelength_m: float = 0.1
    """Wavelength of the corrugations, along the joint's dip (m)."""


#: The rock mass of issue 30: three sets cutting each other in a 6 m block.
ROCK_MASS_SETS: tuple[RockMassSetSpec, ...] = (
    RockMassSetSpec(dip_deg=60.0, dip_direction_deg=30.0, joints=15, spacing_m=0.5),
    RockMassSetSpec(dip_deg=45.0, dip_direction_deg=150.0, joints=9, spacing_m=0.8),
    RockMassSetSpec(dip_deg=80.0, dip_direction_deg=270.0, joints=11, spacing_m=0.6),
)


@dataclass(frozen=True)
class RockMassSpec:
    """A cube of rock cut by persistent planar joints, every joint sampled where it
    lies inside the cube (a see-through rock mass: each joint is crossed by the
    joints of the other sets, which break it into patches on a grid)."""

    sets: tuple[RockMassSetSpec, ...] = ROCK_MASS_SETS
    """The planted sets."""
    size_m: float = 6.0
    """Edge of the cube (m), from the origin."""
    point_spacing_m: float = 0.05
    """Spacing of the jittered sample raster on every joint (m)."""
    noise_m: float = 0.002
    """Standard deviation of the Gaussian noise of every coordinate (m)."""
    min_gap_share: float = 0.4
    """A joint ends where it would come closer to the set's previous joint than this
    share of the set's spacing (tilted joints of one set would cross in the block)."""
    seed: int = 30


@dataclass(frozen=True, eq=False)
class RockMassScan:
    """Points of a planted rock mass with the truth of every point and joint."""

    cloud: PointCloud
    """Points (m)."""
    joint: np.ndarray
    """(N,) int32 planted joint of every point (row of the joint arrays)."""
    set_id: np.ndarray
    """(N,) uint8 set of every point, 1..S."""
    joint_set: np.ndarray
    """(J,) int64 set of every joint, 1..S."""
    joint_normal: np.ndarray
    """(J, 3) unit normal of every joint, upward."""
    joint_offset: np.ndarray
    """(J,) where the joint crosses the line through the block's centre along its
    set's mean normal, from the centre (m): the joint passes through
    ``centre + offset * set_normal``."""
    set_normal: np.ndarray
    """(S, 3) planted mean normal of every set, upward."""
    spec: RockMassSpec = field(repr=False)

    def spacings(self, set_id: int) -> np.ndarray:
        """The planted normal spacings of set ``set_id`` (1..S), consecutive joints (m)."""
        return np.diff(np.sort(self.joint_offset[self.joint_set == set_id]))


def _planted_joints(spec: RockMassSpec
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The joints of every set of ``spec``, checked: set (1..S) of every joint, its unit
    normal (Fisher about its set's), its offset along its set's mean normal from the
    block's centre (metres), and the sets' mean normals (S, 3)."""
    rng = np.random.default_rng([spec.seed, 30])
    set_n, joint_set, normals, offsets = [], [], [], []
    for k, s in enumerate(spec.sets, start=1):
        if s.joints < 1 or not s.spacing_m > 0 or not s.kappa > 1 \
                or not 0 <= s.spacing_jitter < 1 or not s.corrugation_m >= 0 \
                or not s.corrugation_wavelength_m > 0:
            raise InputError(f"rock mass set {k}: joints >= 1, a spacing > 0, kappa > 1, "
                             "a jitter in [0, 1), a corrugation >= 0 and a wavelength > 0 "
                             "are needed")
        m = plane_normals(np.array([s.dip_deg]), np.array([s.dip_direction_deg]))[0]
        steps = s.spacing_m * (1.0 + rng.uniform(-s.spacing_jitter, s.spacing_jitter,
                                                 s.joints - 1))
        if steps.size:
            steps *= s.spacing_m / steps.mean()
        off = np.concatenate([[0.0], np.cumsum(steps)])
        set_n.append(m)
        joint_set.append(np.full(s.joints, k, dtype=np.int64))
        normals.append(exact_fisher_normals(rng, m, s.kappa, s.joints))
        offsets.append(off - 0.5 * off[-1])
    jset = np.concatenate(joint_set)
    jn = np.concatenate(normals)
    joff = np.concatenate(offsets)
    sn = np.array(set_n)
    return jset, jn, joff, sn


def generate_rock_mass(spec: RockMassSpec = RockMassSpec()) -> RockMassScan:
    """Sample the persistent joints of ``spec`` inside its cube.

    Joint ``j`` of a set passes through ``centre + o_j m`` (``m`` the set's mean
    normal, ``o_j`` its offset: consecutive offsets ``spacing * (1 + u)``, ``u``
    uniform in ``+-spacing_jitter`` scaled so the mean is exact, centred on the
    block) with a normal drawn by :func:`exact_fisher_normals`; it is sampled on a
    jittered raster of ``point_spacing_m`` over the part of its plane inside the cube
    (and ending against the set's previous joint where it would come closer than
    ``min_gap_share`` of the spacing to it), displaced along its normal by the set's
    corrugations (if any), plus isotropic Gaussian noise.

    >>> rm = generate_rock_mass(RockMassSpec(size_m=2.0, point_spacing_m=0.1, sets=(
    ...     RockMassSetSpec(30.0, 90.0, joints=3, spacing_m=0.5, spacing_jitter=0.0),)))
    >>> rm.joint_set.tolist(), np.round(rm.spacings(1), 6).tolist()
    ([1, 1, 1], [0.5, 0.5])
    """
    if not spec.sets:
        raise InputError("a rock mass needs at least one set")
    if not (spec.size_m > 0 and spec.point_spacing_m > 0 and spec.noise_m >= 0):
        raise InputError("a rock mass needs a positive size and point spacing")
    half = 0.5 * spec.size_m
    reach = half * np.sqrt(3.0)
    n_side = int(np.ceil(2 * reach / spec.point_spacing_m))
    if n_side * n_side * sum(s.joints for s in spec.sets) > 5e7:
        raise InputError("the rock mass would need over 5e7 samples; choose a coarser spacing")
    centre = np.full(3, half)
    jset, jn, joff, sn = _planted_joints(spec)
    dip, strike = dip_strike_axes(jn)
    srng = np.random.default_rng([spec.seed, 2])
    ia, ib = np.meshgrid(np.arange(n_side), np.arange(n_side), indexing="ij")
    pts, lab = [], []
    for j in range(jn.shape[0]):
        a = -reach + (ia.ravel() + srng.uniform(0, 1, ia.size)) * spec.point_spacing_m
        b = -reach + (ib.ravel() + srng.uniform(0, 1, ib.size)) * spec.point_spacing_m
        on = centre + joff[j] * sn[jset[j] - 1]
        p = on + a[:, None] * dip[j] + b[:, None] * strike[j]
        inside = np.all((p >= 0) & (p <= spec.size_m), axis=1)
        prev = j - 1
        if prev >= 0 and jset[prev] == jset[j]:
            # a joint ends where it would come closer than min_gap_share of the
            # spacing to the set's previous one (it abuts it: joints of one set cross
            # nowhere)
            m = sn[jset[j] - 1]
            s_m = spec.sets[int(jset[j]) - 1].spacing_m
            d = p - centre
            flat = d - (d @ m)[:, None] * m  # the in-plane position along m's line
            h_prev = ((centre + joff[prev] * m - centre - flat) @ jn[prev]) / (m @ jn[prev])
            inside &= (d @ m) - h_prev >= spec.min_gap_share * s_m
        amp = spec.sets[int(jset[j]) - 1].corrugation_m
        if amp > 0:
            wave = spec.sets[int(jset[j]) - 1].corrugation_wavelength_m
            phase = np.random.default_rng([spec.seed, 4, j]).uniform(0.0, 2.0 * np.pi)
            p = p + (amp * np.sin(2.0 * np.pi * a / wave + phase))[:, None] * jn[j]
        pts.append(p[inside])
        lab.append(np.full(int(inside.sum()), j, dtype=np.int32))
    xyz = np.concatenate(pts)
    joint = np.concatenate(lab)
    xyz += np.random.default_rng([spec.seed, 3]).normal(0.0, spec.noise_m, xyz.shape)
    return RockMassScan(cloud=PointCloud.from_xyz(xyz), joint=joint,
                        set_id=jset[joint].astype(np.uint8), joint_set=jset, joint_normal=jn,
                        joint_offset=joff, set_normal=sn, spec=spec)
