"""A synthetic terrestrial laser scan of a vertical basalt exposure (Box Canyon-like).

Pollyea and Fairley (2011) mapped fractures and a rubbly flow margin on a ~90 m x
10 m vertical basalt exposure at Box Canyon, Idaho, scanned so that the face was
roughly parallel to the xz plane. This module builds a smaller piece of such a face
and "scans" it from one stated scanner position:

Geology (face-local coordinates: ``s`` along the face, ``z`` up, ``h`` out of the
rock towards the scanner; metres)

- two basalt flows with a rubbly flow margin between them (an undulating band about
  1 m thick near 4.3 m height): blocky cobbles with voids, recessed into the face;
- columnar jointing in both flows: column-bounding fractures (near-vertical, wider
  columns in the lower flow) and column-normal cross joints (near-horizontal, one set
  per column), apertures from 1 cm to 15 cm, each a groove with steep walls;
  columns stand a few centimetres proud of or behind their neighbours;
- smooth rock elsewhere: a gentle metre-scale undulation plus millimetre-scale
  roughness;
- a bend: after the main straight face the wall curves round (a circular arc) and
  continues as a straight wall turned ``bend_deg`` towards the scanner, like an
  amphitheatre wall. There the face is oblique to the xz plane, so OLS along y
  overestimates roughness while ODR does not.

Scanner effects

- one scanner position (``spec.scanner``); rays on a regular angular grid of step
  ``spec.angular_step_rad``, so point density falls with range squared and with the
  cosine of the incidence angle;
- occlusion: the face is sampled far more densely than the rays, every sample is
  binned into the ray (pixel) that sees it, and only the nearest sample per pixel is
  kept (a z-buffer). Protruding columns, cobbles and fracture walls shadow what lies
  behind them;
- Gaussian range noise (``spec.range_noise_m``) along each ray, and an intensity
  that falls with range and incidence.

Ground truth: every point carries a class (:data:`TRUTH_ROCK`, :data:`TRUTH_BOUNDING`,
:data:`TRUTH_CROSS`, :data:`TRUTH_RUBBLE`) and a face part (:data:`FACE_MAIN`,
:data:`FACE_CURVE`, :data:`FACE_BEND`).

Everything is drawn from ``spec.seed``; the same spec always gives the same points.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rough_viewer.io.cloud import PointCloud
from rough_viewer.synthetic._noise import FractalNoise2D, ValueNoise1D, ValueNoise2D
from rough_viewer.synthetic._scan import angles_of, intensity_of, nearest_per_pixel

#: Truth class: smooth rock of a flow interior.
TRUTH_ROCK = 0
#: Truth class: a column-bounding (near-vertical) fracture, including its spalled edges.
TRUTH_BOUNDING = 1
#: Truth class: a column-normal (near-horizontal) cross joint, including its spalled edges.
TRUTH_CROSS = 2
#: Truth class: the rubbly flow margin between the two flows.
TRUTH_RUBBLE = 3
#: Names of the truth classes, by value.
TRUTH_NAMES = ("rock", "column-bounding fracture", "column-normal fracture", "rubble")

#: Face part: the main straight face, parallel to the xz plane.
FACE_MAIN = 0
#: Face part: the curved stretch where the face turns.
FACE_CURVE = 1
#: Face part: the straight wall turned ``bend_deg`` from the main face.
FACE_BEND = 2
#: Names of the face parts, by value.
FACE_NAMES = ("main face", "curve", "turned wall")


@dataclass(frozen=True)
class OutcropSpec:
    """Everything that defines a synthetic outcrop scan (metres, degrees, radians)."""

    main_length_m: float = 26.0
    """Length of the main straight face along x (m)."""
    curve_length_m: float = 4.0
    """Arc length of the curved stretch where the face turns (m)."""
    bend_length_m: float = 10.0
    """Length of the turned wall (m)."""
    bend_deg: float = 35.0
    """Angle between the turned wall and the main face (degrees, towards the scanner)."""
    height_m: float = 10.0
    """Height of the exposure (m); its foot is at z = 0."""
    margin_base_m: float = 4.3
    """Mean height of the base of the rubbly flow margin (m)."""
    margin_thickness_m: float = 1.0
    """Mean thickness of the rubbly flow margin (m)."""
    lower_column_width_m: tuple[float, float] = (1.2, 2.6)
    """Range of column widths in the lower flow (m)."""
    upper_column_width_m: tuple[float, float] = (0.8, 1.8)
    """Range of column widths in the upper flow (m)."""
    cross_joint_spacing_m: tuple[float, float] = (0.7, 2.0)
    """Range of spacings of the column-normal cross joints (m)."""
    bounding_apertures_m: tuple[float, ...] = (0.01, 0.02, 0.04, 0.08, 0.15)
    """Apertures of the column-bounding fractures (m), drawn with ``bounding_weights``."""
    bounding_weights: tuple[float, ...] = (0.25, 0.3, 0.2, 0.15, 0.1)
    """Relative frequencies of ``bounding_apertures_m``."""
    cross_apertures_m: tuple[float, ...] = (0.01, 0.02, 0.03, 0.05)
    """Apertures of the cross joints (m), drawn with ``cross_weights``."""
    cross_weights: tuple[float, ...] = (0.35, 0.35, 0.2, 0.1)
    """Relative frequencies of ``cross_apertures_m``."""
    buttresses: tuple[tuple[float, float, float, float], ...] = (
        (6.5, 1.6, 0.7, 7.6),
        (19.0, 1.2, 0.5, 9.2),
    )
    """Protruding buttresses of rock, each ``(s_centre, width, proud, top)`` in metres:
    blocks with steep sides whose normals are far from y (there OLS along y fails
    badly) and which shadow the face beside them."""
    scanner: tuple[float, float, float] = (14.0, -20.0, 1.6)
    """Scanner position (m); the face foot runs along y = 0 from x = 0."""
    angular_step_rad: float = 6.0e-4
    """Angular step of the scanner's ray grid (radians); 6e-4 rad is 1.2 cm at 20 m."""
    range_noise_m: float = 0.002
    """Standard deviation of the Gaussian range noise (m)."""
    oversampling: float = 0.7
    """Surface sample spacing as a fraction of the smallest ray spacing on the face."""
    seed: int = 2011
    """Seed of every random choice."""

    @property
    def length_m(self) -> float:
        """Total length of the face along its trace (m)."""
        return self.main_length_m + self.curve_length_m + self.bend_length_m


#: The bundled demo outcrop (about 1.9 M points).
OUTCROP = OutcropSpec()

#: A small piece for quick loading (browser tests): about 150 k points.
OUTCROP_SMALL = OutcropSpec(
    main_length_m=8.0,
    curve_length_m=2.0,
    bend_length_m=4.0,
    height_m=7.0,
    scanner=(5.0, -10.0, 1.6),
    angular_step_rad=2.3e-3,
    buttresses=((3.5, 1.0, 0.5, 5.5),),
    seed=2012,
)


@dataclass(frozen=True)
class OutcropScan:
    """A synthetic outcrop scan with its ground truth."""

    cloud: PointCloud
    """Points (m) in scan order, with intensity (uint16)."""
    truth: np.ndarray
    """(N,) uint8 truth class of each point (TRUTH_*)."""
    face: np.ndarray
    """(N,) uint8 face part of each point (FACE_*)."""
    spec: OutcropSpec = field(repr=False)
    """The spec the scan was generated from."""


# --- face geometry -------------------------------------------------------------------


def face_trace(spec: OutcropSpec, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Plan-view trace of the face at along-face distance ``s`` (m).

    Returns ``(x, y, nx, ny)``: the point of the face foot line and the horizontal
    unit normal pointing out of the rock (towards the scanner side, -y on the main
    face).
    """
    s = np.asarray(s, dtype=np.float64)
    s1 = spec.main_length_m
    s2 = s1 + spec.curve_length_m
    psi_b = np.radians(spec.bend_deg)
    radius = spec.curve_length_m / psi_b if psi_b > 0 else np.inf
    psi = np.clip((s - s1) / radius, 0.0, psi_b) if psi_b > 0 else np.zeros_like(s)
    x2 = s1 + radius * np.sin(psi_b) if psi_b > 0 else s2
    y2 = -radius * (1 - np.cos(psi_b)) if psi_b > 0 else 0.0
    x = np.where(
        s < s1,
        s,
        np.where(s < s2, s1 + radius * np.sin(psi), x2 + (s - s2) * np.cos(psi_b)),
    )
    y = np.where(
        s < s1,
        0.0,
        np.where(s < s2, -radius * (1 - np.cos(psi)), y2 - (s - s2) * np.sin(psi_b)),
    )
    return x, y, -np.sin(psi), -np.cos(psi)


def face_part(spec: OutcropSpec, s: np.ndarray) -> np.ndarray:
    """FACE_MAIN, FACE_CURVE or FACE_BEND for along-face distance ``s`` (m)."""
    s1 = spec.main_length_m
    s2 = s1 + spec.curve_length_m
    return np.where(s < s1, FACE_MAIN, np.where(s < s2, FACE_CURVE, FACE_BEND)).astype(np.uint8)


# --- geology ---------------------------------------------------------------------------


def _groove(d: np.ndarray, aperture: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Depth profile (m, <= 0) of a fracture groove at distance ``d`` from its centre
    line, and whether the point is inside the fracture's damaged zone."""
    half = aperture / 2
    bevel = 0.3 * aperture + 0.01
    depth = np.minimum(0.06 + 2.5 * aperture, 0.4)
    t = np.clip((d - half) / bevel, 0.0, 1.0)
    return -depth * (1 - t) ** 2, d < half + bevel


class _Flow:
    """Columns and cross joints of one flow (drawn once from ``rng``)."""

    def __init__(
        self,
        rng: np.random.Generator,
        spec: OutcropSpec,
        widths: tuple[float, float],
        z_range: tuple[float, float],
    ) -> None:
        lo, hi = widths
        n = int(np.ceil((spec.length_m + 2 * hi) / lo)) + 2
        w = rng.uniform(lo, hi, n)
        self.bounds = -rng.uniform(0, hi) + np.concatenate([[0.0], np.cumsum(w)])
        self.apertures = rng.choice(
            np.asarray(spec.bounding_apertures_m),
            size=self.bounds.shape[0],
            p=np.asarray(spec.bounding_weights) / np.sum(spec.bounding_weights),
        )
        n_col = self.bounds.shape[0] - 1
        self.offset = np.clip(rng.normal(0.0, 0.035, n_col), -0.1, 0.1)
        self.slope = rng.uniform(-0.15, 0.15, n_col)
        self.mid = 0.5 * (self.bounds[:-1] + self.bounds[1:])
        # Cross joints: per column, heights from z_range[0] up, some left out.
        self.z0 = z_range[0] - 1.0
        span = z_range[1] + 1.0 - self.z0
        sp_lo, sp_hi = spec.cross_joint_spacing_m
        m = int(np.ceil(span / sp_lo)) + 1
        steps = rng.uniform(sp_lo, sp_hi, (n_col, m))
        zj = rng.uniform(0, sp_hi, (n_col, 1)) + np.cumsum(steps, axis=1) - steps[:, :1]
        keep = (zj < span) & (rng.uniform(size=zj.shape) < 0.8)
        col = np.broadcast_to(np.arange(n_col)[:, None], zj.shape)
        self.joint_col = col[keep]
        self.joint_z = zj[keep]
        self.joint_key = self.joint_col * 1000.0 + self.joint_z
        self.joint_aperture = rng.choice(
            np.asarray(spec.cross_apertures_m),
            size=self.joint_z.shape[0],
            p=np.asarray(spec.cross_weights) / np.sum(spec.cross_weights),
        )

    def relief(self, sw: np.ndarray, zw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Relief (m) and truth class of points at warped coordinates (sw, zw)."""
        c = np.clip(np.searchsorted(self.bounds, sw, side="right") - 1, 0, self.offset.shape[0] - 1)
        d_left = sw - self.bounds[c]
        d_right = self.bounds[c + 1] - sw
        near = np.where(d_left < d_right, c, c + 1)
        gb, in_b = _groove(np.minimum(d_left, d_right), self.apertures[near])
        # Cross joints of this point's column, tilted per column.
        zc = zw - self.z0 - self.slope[c] * (sw - self.mid[c])
        key = c * 1000.0 + zc
        idx = np.searchsorted(self.joint_key, key)
        gn = np.zeros_like(sw)
        in_n = np.zeros(sw.shape, dtype=bool)
        for cand in (idx - 1, idx):
            ok = (cand >= 0) & (cand < self.joint_key.shape[0])
            cc = np.clip(cand, 0, max(self.joint_key.shape[0] - 1, 0))
            if self.joint_key.shape[0] == 0:
                break
            ok &= self.joint_col[cc] == c
            g, inside = _groove(np.abs(zc - self.joint_z[cc]), self.joint_aperture[cc])
            gn = np.where(ok, np.minimum(gn, g), gn)
            in_n |= ok & inside
        relief = self.offset[c] + np.minimum(gb, gn)
        truth = np.where(in_b, TRUTH_BOUNDING, np.where(in_n, TRUTH_CROSS, TRUTH_ROCK))
        return relief, truth.astype(np.uint8)


class _Rubble:
    """Blocky cobbles with voids between them (a Worley-like field of domes)."""

    def __init__(self, rng: np.random.Generator, spec: OutcropSpec, cell_m: float = 0.3) -> None:
        self.cell = cell_m
        ns = int(np.ceil(spec.length_m / cell_m)) + 4
        nz = int(np.ceil(spec.height_m / cell_m)) + 4
        self.centre = rng.uniform(0.0, 1.0, (ns, nz, 2))
        self.radius = rng.uniform(0.14, 0.3, (ns, nz))
        self.height = rng.uniform(0.08, 0.3, (ns, nz))

    def __call__(self, s: np.ndarray, z: np.ndarray) -> np.ndarray:
        u, v = s / self.cell + 1.0, z / self.cell + 1.0
        i0 = np.floor(u).astype(np.int64)
        j0 = np.floor(v).astype(np.int64)
        best = np.full(s.shape, -0.32)
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                i = np.clip(i0 + di, 0, self.radius.shape[0] - 1)
                j = np.clip(j0 + dj, 0, self.radius.shape[1] - 1)
                cs = (i + self.centre[i, j, 0] - u) * self.cell
                cz = (j + self.centre[i, j, 1] - v) * self.cell
                q = 1.0 - (cs * cs + cz * cz) / self.radius[i, j] ** 2
                dome = -0.25 + self.height[i, j] * np.sqrt(np.maximum(q, 0.0))
                best = np.where(q > 0, np.maximum(best, dome), best)
        return best


class _Geology:
    """All random fields of one outcrop, drawn once from the spec's seed."""

    def __init__(self, spec: OutcropSpec) -> None:
        rng = np.random.default_rng([spec.seed, 1_000_000])
        ext = (spec.length_m + 2.0, spec.height_m + 2.0)
        self.spec = spec
        self.undulation = FractalNoise2D(rng, ext, (7.0, 3.0), (0.12, 0.05))
        self.fine = FractalNoise2D(
            rng, ext, (0.5, 0.25, 0.12, 0.06, 0.03), (0.003, 0.0016, 0.0008, 0.0005, 0.0003)
        )
        self.rough = FractalNoise2D(rng, ext, (0.12, 0.06, 0.03), (0.012, 0.007, 0.004))
        self.warp_s = ValueNoise2D(rng, ext, 2.5)
        self.warp_z = ValueNoise2D(rng, ext, 2.0)
        self.margin_base = ValueNoise1D(rng, ext[0], 5.0)
        self.margin_top = ValueNoise1D(rng, ext[0], 4.0)
        top = spec.margin_base_m + spec.margin_thickness_m
        self.lower = _Flow(rng, spec, spec.lower_column_width_m, (0.0, top))
        self.upper = _Flow(rng, spec, spec.upper_column_width_m, (spec.margin_base_m, spec.height_m))
        self.rubble = _Rubble(rng, spec)

    def relief(self, s: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Relief h (m, out of the rock) and truth class at face coordinates (s, z)."""
        spec = self.spec
        z_base = spec.margin_base_m + 0.35 * self.margin_base(s)
        z_top = z_base + spec.margin_thickness_m * (1.0 + 0.3 * self.margin_top(s))
        sw = s + 0.12 * self.warp_s(s, z)
        zw = z + 0.08 * self.warp_z(s, z)
        h_lower, t_lower = self.lower.relief(sw, zw)
        h_upper, t_upper = self.upper.relief(sw, zw)
        in_upper = z >= 0.5 * (z_base + z_top)
        h = np.where(in_upper, h_upper, h_lower)
        truth = np.where(in_upper, t_upper, t_lower)
        # Rubbly margin, blended into the flows over 0.1 m at its edges.
        band = (z > z_base - 0.1) & (z < z_top + 0.1)
        if np.any(band):
            sb, zb = s[band], z[band]
            h_r = self.rubble(sb, zb) + self.rough(sb, zb)
            w = np.clip(np.minimum(zb - (z_base[band] - 0.1), (z_top[band] + 0.1) - zb) / 0.2, 0, 1)
            w = w * w * (3 - 2 * w)
            h[band] = (1 - w) * h[band] + w * h_r
        truth = np.where((z >= z_base) & (z < z_top), TRUTH_RUBBLE, truth).astype(np.uint8)
        return h + self._buttresses(s, z) + self.undulation(s, z) + self.fine(s, z), truth

    def _buttresses(self, s: np.ndarray, z: np.ndarray) -> np.ndarray:
        edge = 0.08
        out = np.zeros_like(s)
        for centre, width, proud, top in self.spec.buttresses:
            ws = np.clip((width / 2 - np.abs(s - centre)) / edge, 0.0, 1.0)
            wz = np.clip((top - z) / edge, 0.0, 1.0)
            w = ws * wz
            out += proud * w * w * (3 - 2 * w)
        return out


def outcrop_relief(spec: OutcropSpec) -> Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """The surface model of ``spec``: ``relief(s, z) -> (h, truth)`` in face coordinates.

    ``h`` (m) is the offset of the rock surface from the face trace along its outward
    normal (:func:`face_trace`); ``truth`` the class at that spot. This is the exact
    surface that :func:`generate_outcrop` samples, for checks of the scan against it.
    """
    return _Geology(spec).relief


# --- scanning --------------------------------------------------------------------------


def _sample_step(spec: OutcropSpec) -> float:
    """Surface sample spacing (m): ``oversampling`` x the closest ray spacing on the face."""
    s = np.linspace(0.0, spec.length_m, 400)
    x, y, _, _ = face_trace(spec, s)
    sc = np.asarray(spec.scanner)
    z = np.clip(sc[2], 0.0, spec.height_m)
    r_min = float(np.min(np.sqrt((x - sc[0]) ** 2 + (y - sc[1]) ** 2 + (z - sc[2]) ** 2)))
    return spec.oversampling * spec.angular_step_rad * max(r_min - 0.5, 1.0)


def generate_outcrop(spec: OutcropSpec = OUTCROP, *, chunk_m: float = 2.0) -> OutcropScan:
    """Generate and scan the synthetic outcrop described by ``spec``.

    The face is sampled on a jittered raster finer than the scanner's rays, chunk by
    chunk along the face; each chunk keeps only its nearest sample per ray (pixel),
    then the chunks' winners compete again, so memory stays bounded and the result
    does not depend on the chunk size's effect on random draws (each chunk has its
    own seeded stream, and chunk boundaries are fixed by ``chunk_m``).

    Returns
    -------
    OutcropScan with points in scan order (azimuth-major, elevation ascending).
    """
    geo = _Geology(spec)
    scanner = np.asarray(spec.scanner, dtype=np.float64)
    step = _sample_step(spec)
    n_s = int(np.ceil(spec.length_m / step))
    n_z = int(np.ceil(spec.height_m / step))
    cols_per_chunk = max(1, int(round(chunk_m / step)))
    pieces: list[tuple[np.ndarray, ...]] = []
    for chunk, c0 in enumerate(range(0, n_s, cols_per_chunk)):
        rng = np.random.default_rng([spec.seed, 1 + chunk])
        c1 = min(n_s, c0 + cols_per_chunk)
        ii, jj = np.meshgrid(np.arange(c0, c1), np.arange(n_z), indexing="ij")
        s = (ii.ravel() + rng.uniform(0.0, 1.0, ii.size)) * step
        z = (jj.ravel() + rng.uniform(0.0, 1.0, jj.size)) * step
        keep = (s < spec.length_m) & (z < spec.height_m)
        s, z = s[keep], z[keep]
        h, truth = geo.relief(s, z)
        x0, y0, nx, ny = face_trace(spec, s)
        xyz = np.column_stack([x0 + h * nx, y0 + h * ny, z])
        phi, theta, rng_m = angles_of(xyz, scanner)
        ip = np.floor(phi / spec.angular_step_rad + 0.5).astype(np.int64)
        it = np.floor(theta / spec.angular_step_rad + 0.5).astype(np.int64)
        key = ip * (1 << 24) + (it + (1 << 23))
        win = nearest_per_pixel(key, rng_m)
        cos_inc = -(nx[win] * (xyz[win, 0] - scanner[0]) + ny[win] * (xyz[win, 1] - scanner[1]))
        cos_inc = cos_inc / rng_m[win]
        pieces.append(
            (key[win], rng_m[win], xyz[win], truth[win], face_part(spec, s[win]), cos_inc)
        )
    key = np.concatenate([p[0] for p in pieces])
    rng_m = np.concatenate([p[1] for p in pieces])
    win = nearest_per_pixel(key, rng_m)
    xyz = np.concatenate([p[2] for p in pieces])[win]
    truth = np.concatenate([p[3] for p in pieces])[win]
    face = np.concatenate([p[4] for p in pieces])[win]
    cos_inc = np.concatenate([p[5] for p in pieces])[win]
    rng_m = rng_m[win]

    noise_rng = np.random.default_rng([spec.seed, 0])
    unit = (xyz - scanner) / rng_m[:, None]
    noisy = rng_m + noise_rng.normal(0.0, spec.range_noise_m, rng_m.shape[0])
    xyz = scanner + unit * noisy[:, None]
    reflectance = np.array([0.22, 0.16, 0.16, 0.3])[truth]
    intensity = intensity_of(
        noisy,
        cos_inc,
        reflectance=reflectance,
        noise=noise_rng.lognormal(0.0, 0.12, rng_m.shape[0]),
    )
    cloud = PointCloud.from_xyz(xyz, intensity=intensity, source="",
                                scan_index=np.zeros(xyz.shape[0], np.int32),
                                scanner_positions=scanner[None, :])
    return OutcropScan(cloud=cloud, truth=truth, face=face, spec=spec)
