"""Joint sets: from planar cells to discontinuity sets, their planes, spacing and
persistence (after DSE, Riquelme et al. 2014, 2015, 2018, and CloudCompare's Facets,
Dewez et al. 2016).

The grid gives every cell an ODR plane and a roughness; smooth cells are pieces of
discontinuity planes. The steps (conventions of :mod:`rough_viewer.grid.orientation`):

1. **Planar cells**: cells with an ODR plane, at least ``min_planar_points``
   points (default 10: a cell of 4 or 5 points of rough rock fits a plane by
   chance, its roughness has 1 or 2 degrees of freedom) and an ODR roughness of at
   most ``max_roughness`` (default :data:`DEFAULT_PLANAR_SHARE` of the cell size).
2. **Poles**: the downward normals of the planar cells (lower hemisphere), each
   weighted by its cell's points.
3. **Density**: the axial Fisher kernel of the stereonet
   (:func:`~rough_viewer.grid.orientation.kernel_density`, ``sigma`` =
   ``smoothing_deg``), in multiples of a uniform distribution (MUD).
4. **Peaks**: the local maxima of the density on the stereonet's node grid, each
   refined by mean shift on the sphere to the exact local maximum of the kernel
   sum over every pole; peaks below ``min_density`` are dropped, and of two peaks
   closer than ``min_angle_deg`` the weaker; at most ``max_sets``, strongest first.
   These are the sets' principal orientations.
5. **Sets**: every planar cell goes to the nearest peak (axial angle) when that is
   within ``cone_deg``; a peak that gathers fewer than ``min_set_cells`` cells is
   dropped and its cells go to the next peak within the cone. Set ids 1..S by peak
   density (strongest first); 0 = in no set.
6. **Per set** (:func:`fisher_statistics`, every cell one observation of weight
   its points): the Fisher mean pole, dip and dip direction of its plane,
   ``kappa = (N - 1) / (N - R)`` and
   ``alpha95 = arccos(1 - (N - R) / R ((1 / 0.05)^(1 / (N - 1)) - 1))``, with ``N``
   the cells and ``R = N |sum w p| / sum w`` (``w`` the points; equal weights give
   the textbook resultant length). A cell outside the cone of its set's final
   mean leaves the set and the statistics are taken again, until every cell of a
   set lies within ``cone_deg`` of its mean.
7. **Planes** (single discontinuities): within a set, cells that touch (faces,
   edges or corners) and whose offsets along the set's mean normal differ by at
   most ``plane_tolerance`` (default half a cell) form one plane; planes of fewer
   than ``min_plane_cells`` cells are dropped (their cells keep their set, plane
   0). Plane ids 1..P by set, then by cells (largest first). Each plane then takes
   in the **edge cells** it touches: cells in no set with fewer than
   ``min_planar_points`` points (slivers where the plane crosses a cell's corner,
   too few points to vote with their own normal) but a roughness of at most
   ``max_roughness``, whose centroid lies within 3 x the plane's RMS of it; they
   carry the plane's set and plane ids (the set's ``cells`` count only the cells
   whose poles made it). A group whose points lie farther than ``max_plane_rms``
   (RMS, default a quarter of a cell) from their best plane is a curved surface
   chained cell by cell (a hillslope, a vault, an undulating face), not a plane: it
   is dropped and counted (:attr:`JointSets.curved_groups`); so is a group whose
   points' plane lies outside the cone of its set's mean (a strip about a cell wide
   whose points do not fix its tilt about its length;
   :attr:`JointSets.sliver_planes`): every plane lies within the cone.
8. **Per plane**, from its points: the ODR fit (dip, dip direction, centroid, RMS
   of the orthogonal distances = square root of the smallest covariance
   eigenvalue); the persistence along dip and along strike: the longest chord in
   that direction, the points binned in strips a quarter of a cell wide across it
   and a chord broken where two consecutive points lie more than one cell apart;
   the area: the summed length of the chords along dip times the strip width.
9. **Joints** (:mod:`rough_viewer.structure.joints`): the planes above are patches; the
   patches of one set that lie on one discontinuity, touching or not, are one joint
   (a plane fitted to both within ``max_plane_rms``, each centroid within
   ``plane_tolerance`` of the other's plane).
10. **Per set**: the normal spacing between consecutive joints along the set's mean
   normal, measured where they overlap, and the scanline spacing on virtual
   scanlines along that normal (ISRM 1978); mean, median and population standard
   deviation of the normal spacing; the mean persistence: the mean over the set's
   planes of the longer of their two chords; and, over the sets, ``Jv``, the block
   size index and the RQD estimate (:attr:`JointSets.figures`).
12. **Roughness per set** (:mod:`rough_viewer.structure.set_roughness`): the mean, median
   and standard deviation of its cells' ODR roughness, and the directional
   roughness of its largest joints along their dip and strike (profiles' JRC
   estimate, ``theta*max/(C+1)`` and ``Delta-T`` of their triangles, each joint in
   its own plane's frame).
11. **The exposure face** (:mod:`rough_viewer.structure.face`): a set within
   ``face_tolerance_deg`` of the whole-cloud plane or of its cells' local face is
   :attr:`JointSets.face_parallel`: the exposure, not a joint set; its spacing is
   no joint spacing and it adds nothing to the rock-mass figures.

Everything is vectorised over cells and points; loops run over sets (at most
``max_sets``) and density peaks only.

>>> import numpy as np
>>> from rough_viewer.grid.roughness import grid_roughness
>>> rng = np.random.default_rng(0)
>>> xy = rng.uniform(0, 4, (20_000, 2))
>>> z = np.where(xy[:, 0] < 2, 0.5 * xy[:, 0], 2.0 - 0.5 * xy[:, 0])  # a ridge: two planes
>>> pts = np.column_stack([xy, z + 0.001 * rng.standard_normal(20_000)])
>>> js = joint_sets(grid_roughness(pts, 0.25), pts)
>>> js.n_sets, np.round(js.dip_deg, 1).tolist(), sorted(np.round(js.dip_direction_deg).tolist())
(2, [26.6, 26.6], [90.0, 270.0])
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rough_viewer.grid.orientation import (
    DEFAULT_SMOOTHING_DEG,
    Stereonet,
    dip_and_direction,
    dip_strike_axes,
    kernel_density,
    kernel_kappa,
    orient_normals,
    schmidt_inverse,
    stereonet,
)
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.io.cloud import PointCloud, as_columns
from rough_viewer.io.formats.point_fields import CellField, PointFields
from rough_viewer.memory import require
from rough_viewer.structure.face import (
    DEFAULT_FACE_RADIUS_CELLS,
    DEFAULT_FACE_TOLERANCE_DEG,
    FaceAngles,
    face_angles,
)
from rough_viewer.structure.joints import (
    Joints,
    RockMassFigures,
    joint_table,
    merge_patches,
    rock_mass_figures,
    rock_mass_text,
    set_spacing,
)
from rough_viewer.structure.set_roughness import SetRoughness, set_roughness
from rough_viewer.structure.zones import _neighbour_pairs
from rough_viewer.vocabulary import DEFAULT_MIN_CELLS, InputError, ProgressFn

#: Default cone (degrees) around a peak within which a cell joins its set.
DEFAULT_CONE_DEG = 20.0
#: Default least angle (degrees) between two peaks (sets).
DEFAULT_MIN_ANGLE_DEG = 30.0
#: Default largest number of sets.
DEFAULT_MAX_SETS = 6
#: Default least peak density (MUD) of a set.
DEFAULT_MIN_DENSITY = 3.0
#: Default least number of cells of a set.
DEFAULT_MIN_SET_CELLS = 10
#: Default largest ODR roughness of a planar cell, as a share of the cell size.
DEFAULT_PLANAR_SHARE = 0.02
#: Default least points of a planar cell.
DEFAULT_MIN_PLANAR_POINTS = 10
#: Default offset tolerance between the cells of one plane, as a share of the cell size.
DEFAULT_PLANE_TOLERANCE_SHARE = 0.5
#: Default largest RMS of a plane's points about it, as a share of the cell size.
DEFAULT_PLANE_RMS_SHARE = 0.25
#: Default least number of cells of a plane.
DEFAULT_MIN_PLANE_CELLS = DEFAULT_MIN_CELLS
#: Confidence of alpha95.
ALPHA95_P = 0.05
#: Mean-shift iterations refining a density peak at most, and the step (radians) at
#: which they stop.
_SHIFT_ITERATIONS = 200
_SHIFT_TOLERANCE = 1e-11
#: Poles farther than this many kernel sigmas from a peak do not move it (their
#: weight is below exp(-12.5) = 4e-6 of a coinciding pole's).
_SHIFT_REACH_SIGMAS = 5.0

#: Columns of SETS.csv, in order (the ``rough-viewer sets`` contract).
SET_COLUMNS: tuple[str, ...] = (
    "set_id", "dip_deg", "dip_direction_deg", "fisher_kappa", "alpha95_deg", "cells",
    "planes", "joints", "spacing_mean", "spacing_median", "spacing_std",
    "spacing_scanline_mean", "persistence_mean", "face_parallel", "face_angle_deg",
    "odr_mean", "odr_median", "odr_std", "theta_max_c1_dip", "theta_max_c1_strike",
    "delta_t_dip", "delta_t_strike", "jrc_estimate_dip", "jrc_estimate_strike",
)
#: Columns of PLANES.csv, in order.
PLANE_COLUMNS: tuple[str, ...] = (
    "plane_id", "set_id", "joint_id", "dip_deg", "dip_direction_deg", "cx", "cy", "cz", "area",
    "persistence_dip", "persistence_strike", "rms", "cells",
)
#: Columns of JOINTS.csv, in order.
JOINT_COLUMNS: tuple[str, ...] = (
    "joint_id", "set_id", "dip_deg", "dip_direction_deg", "cx", "cy", "cz", "patches", "area",
    "trace_length", "persistence_dip", "persistence_strike", "rms",
)
#: Length columns of the tables (divided by the output unit; ``area`` by its square).
LENGTH_COLUMNS = frozenset({"spacing_mean", "spacing_median", "spacing_std",
                            "spacing_scanline_mean", "persistence_mean", "cx", "cy", "cz",
                            "persistence_dip", "persistence_strike", "rms", "trace_length",
                            "odr_mean", "odr_median", "odr_std"})


@dataclass(frozen=True)
class FisherStats:
    """Fisher statistics of unit vectors (one hemisphere), optionally weighted."""

    mean: np.ndarray
    """(3,) unit mean direction (the weighted resultant's direction)."""
    n: int
    """Number of vectors ``N``."""
    resultant: float
    """``R = N |sum w v| / sum w`` (the resultant length for equal weights)."""
    kappa: float
    """``(N - 1) / (N - R)`` (inf when every vector is the same)."""
    alpha95_deg: float
    """Cone of 95 % confidence about the mean, degrees (NaN for N < 2)."""


def fisher_statistics(vectors: np.ndarray, weights: np.ndarray | None = None,
                      *, p: float = ALPHA95_P) -> FisherStats:
    """Fisher mean, ``kappa`` and ``alpha95`` of unit vectors (Fisher 1953).

    Parameters
    ----------
    vectors : (N, 3) array
        Unit vectors, all on the side of their mean (flip axial data first).
    weights : (N,) array, optional
        Weight of every vector (default 1): the mean is the weighted resultant's
        direction and ``R = N |sum w v| / sum w``.
    p : float
        ``1 -`` confidence of the cone (default 0.05).

    Returns
    -------
    FisherStats
        ``kappa = (N - 1) / (N - R)``;
        ``alpha95 = arccos(1 - (N - R) / R ((1 / p)^(1 / (N - 1)) - 1))``.

    Examples
    --------
    >>> v = np.array([[0.0, 0.1, 1.0], [0.1, 0.0, 1.0], [0.0, -0.1, 1.0], [-0.1, 0.0, 1.0]])
    >>> st = fisher_statistics(v / np.linalg.norm(v, axis=1, keepdims=True))
    >>> st.mean.round(6) + 0.0, round(st.kappa, 2), round(st.alpha95_deg, 2)
    (array([0., 0., 1.]), 151.12, 7.5)
    """
    v = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    n = int(v.shape[0])
    if n == 0:
        return FisherStats(np.full(3, np.nan), 0, float("nan"), float("nan"), float("nan"))
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    total = float(w.sum())
    s = (w[:, None] * v).sum(axis=0)
    length = float(np.linalg.norm(s))
    mean = s / length if length > 0 else np.full(3, np.nan)
    r = n * min(length / total, 1.0) if total > 0 else float("nan")
    if n < 2:
        return FisherStats(mean, n, r, float("nan"), float("nan"))
    spread = n - r
    kappa = (n - 1) / spread if spread > 0 else float("inf")
    cos_a = 1.0 - spread / r * ((1.0 / p) ** (1.0 / (n - 1)) - 1.0)
    alpha = float(np.degrees(np.arccos(np.clip(cos_a, -1.0, 1.0))))
    return FisherStats(mean, n, float(r), float(kappa), alpha)


@dataclass(frozen=True, eq=False)
class JointPlanes:
    """Single discontinuities (planes) of the sets, one row per plane (id ``k + 1``)."""

    set_id: np.ndarray
    """(P,) int64 set of every plane, 1..S."""
    cells: np.ndarray
    """(P,) int64 cells per plane."""
    points: np.ndarray
    """(P,) int64 points per plane."""
    normal: np.ndarray
    """(P, 3) unit normal of the plane's ODR fit to its points, upward."""
    dip_deg: np.ndarray
    """(P,) dip, degrees."""
    dip_direction_deg: np.ndarray
    """(P,) dip direction, degrees clockwise from +y."""
    centroid: np.ndarray
    """(P, 3) centroid of the plane's points, metres."""
    rms: np.ndarray
    """(P,) RMS of the points' orthogonal distances to the plane, metres."""
    area: np.ndarray
    """(P,) area of the plane's cells on the plane, square metres."""
    persistence_dip: np.ndarray
    """(P,) longest chord of its points along dip, metres."""
    persistence_strike: np.ndarray
    """(P,) longest chord of its points along strike, metres."""
    offset: np.ndarray
    """(P,) centroid's position along its set's mean normal, metres (from the grid origin)."""
    scatter: np.ndarray
    """(P, 3, 3) population covariance of the plane's points, square metres."""
    joint_id: np.ndarray
    """(P,) int64 joint the plane (patch) is part of, 1..J."""

    @property
    def n_planes(self) -> int:
        """Number of planes."""
        return int(self.set_id.shape[0])

    @property
    def persistence(self) -> np.ndarray:
        """(P,) the longer of the two chords, metres."""
        return np.maximum(self.persistence_dip, self.persistence_strike)


@dataclass(frozen=True, eq=False)
class JointSets:
    """Discontinuity sets of one grid result: labels per cell, a row per set, the
    planes, and the stereonet they were found on. Per-set arrays have length
    ``n_sets``; row ``k`` is set ``k + 1``."""

    cell_set: np.ndarray
    """(M,) int32 set of every cell of the grid, 0 = in no set."""
    cell_plane: np.ndarray
    """(M,) int32 plane of every cell, 0 = in no plane."""
    planar: np.ndarray
    """(M,) bool: the planar cells (ODR roughness <= ``max_roughness``, at least
    ``min_planar_points`` points)."""
    net: Stereonet
    """Poles of the planar cells (rows = cell rows), density weighted by points."""
    peak: np.ndarray
    """(S, 3) unit downward direction of every set's density peak."""
    peak_density: np.ndarray
    """(S,) density at the peak, MUD."""
    mean_pole: np.ndarray
    """(S, 3) unit downward Fisher mean pole."""
    normal: np.ndarray
    """(S, 3) unit mean normal, upward (vertical: toward the viewer)."""
    dip_deg: np.ndarray
    """(S,) dip of the mean plane, degrees."""
    dip_direction_deg: np.ndarray
    """(S,) dip direction of the mean plane, degrees clockwise from +y."""
    kappa: np.ndarray
    """(S,) Fisher ``kappa``."""
    alpha95_deg: np.ndarray
    """(S,) Fisher ``alpha95``, degrees."""
    cells: np.ndarray
    """(S,) int64 cells per set."""
    points: np.ndarray
    """(S,) int64 points per set."""
    n_planes_per_set: np.ndarray
    """(S,) int64 planes (patches) per set."""
    n_joints_per_set: np.ndarray
    """(S,) int64 joints per set."""
    spacing_mean: np.ndarray
    """(S,) mean normal spacing of consecutive joints, metres (NaN with fewer than two
    joints; :mod:`rough_viewer.structure.joints`)."""
    spacing_median: np.ndarray
    """(S,) median normal spacing, metres."""
    spacing_std: np.ndarray
    """(S,) population standard deviation of the normal spacing, metres."""
    spacing_scanline_mean: np.ndarray
    """(S,) mean spacing on scanlines along the set's normal (ISRM), metres."""
    persistence_mean: np.ndarray
    """(S,) mean over the set's planes of the longer chord, metres."""
    planes: JointPlanes
    """The planes (patches)."""
    joints: Joints
    """The joints (patches of one discontinuity)."""
    cell_joint: np.ndarray
    """(M,) int32 joint of every cell, 0 = in no joint."""
    roughness: SetRoughness
    """Roughness of every set: its cells' ODR roughness, its joints' along dip and
    strike (:mod:`rough_viewer.structure.set_roughness`)."""
    cell_size: float
    """Grid cell edge, metres."""
    options: SetOptions
    """The settings the sets were found with."""
    max_roughness: float
    """Largest ODR roughness of a planar cell, metres (the option, or its default)."""
    plane_tolerance: float
    """Offset tolerance within a plane, metres (the option, or its default)."""
    max_plane_rms: float
    """Largest RMS of a plane's points about it, metres (the option, or its default)."""
    curved_groups: int
    """Groups of touching cells (of ``min_plane_cells`` or more) that were no plane:
    their points' RMS about their best plane exceeds ``max_plane_rms`` (a curved
    surface, chained cell by cell); their cells keep their set, plane 0."""
    note: str
    """Why there is no set (empty when there are sets)."""
    face: FaceAngles
    """Every set's angles to the exposure face (:mod:`rough_viewer.structure.face`)."""
    sliver_planes: int
    """Groups of touching cells (of ``min_plane_cells`` or more) whose points' plane
    lies outside the cone of their set's mean (a strip one cell wide: its points do
    not fix its tilt about its length): no planes; their cells keep their set."""

    @property
    def face_parallel(self) -> np.ndarray:
        """(S,) bool: the set lies within the face tolerance of the exposure face (the
        whole-cloud plane or its cells' local face): its planes are the exposure, its
        spacing no joint spacing, and it adds nothing to :attr:`figures`."""
        return self.face.parallel

    @property
    def face_angle_deg(self) -> np.ndarray:
        """(S,) angle between the set's mean pole and the exposure face's normal,
        degrees (the smaller of the whole-cloud and the local face's; NaN if neither)."""
        return self.face.angle_deg

    @property
    def face_note(self) -> str:
        """One sentence naming the sets parallel to the exposure face (empty when
        none is): the report's, the app's and the set table's warning.

        The sentence reads e.g. "Set 2 (89/033) lies parallel to the exposure face:
        its spacing is not a joint spacing (left out of Jv, Ib and RQD)."
        """
        ids = np.flatnonzero(self.face_parallel)
        if ids.shape[0] == 0:
            return ""
        named = [f"{k + 1} ({self.dip_deg[k]:.0f}/{self.dip_direction_deg[k]:03.0f})"
                 for k in ids]
        one = len(named) == 1
        listed = named[0] if one else ", ".join(named[:-1]) + " and " + named[-1]
        return (f"Set{'' if one else 's'} {listed} lie{'s' if one else ''} parallel to the "
                f"exposure face (within {self.face.tolerance_deg:g}°): "
                f"{'its' if one else 'their'} spacing is not a joint spacing (left out of "
                "Jv, Ib and RQD).")

    @property
    def n_sets(self) -> int:
        """Number of sets."""
        return int(self.cells.shape[0])

    @property
    def figures(self) -> RockMassFigures:
        """Jv, block size index and RQD estimate of the sets' normal spacings, the
        sets parallel to the exposure face left out (:attr:`face_parallel`)."""
        return rock_mass_figures(np.where(self.face_parallel, np.nan, self.spacing_mean))

    def rock_mass_text(self, unit: str = "m") -> str:
        """The rock-mass figures in the sentence the terminal and the app show
        (:func:`rough_viewer.structure.joints.rock_mass_text`), lengths in ``unit``."""
        face = np.asarray(self.face_parallel, dtype=bool)
        return rock_mass_text(self.figures, unit, face_left_out=bool(face.any()),
                              only_face_spaced=bool(np.any(face & np.isfinite(
                                  self.spacing_mean))))

    @property
    def cone_deg(self) -> float:
        """A cell joins the nearest peak within this angle, degrees."""
        return self.options.cone_deg

    def set_table(self, unit_m: float = 1.0) -> dict[str, np.ndarray]:
        """Column -> (S,) values in :data:`SET_COLUMNS` order, lengths divided by
        ``unit_m`` (metres per output unit)."""
        cols: dict[str, np.ndarray] = {
            "set_id": np.arange(1, self.n_sets + 1, dtype=np.int64),
            "dip_deg": self.dip_deg, "dip_direction_deg": self.dip_direction_deg,
            "fisher_kappa": self.kappa, "alpha95_deg": self.alpha95_deg,
            "cells": self.cells, "planes": self.n_planes_per_set,
            "joints": self.n_joints_per_set,
            "spacing_mean": self.spacing_mean, "spacing_median": self.spacing_median,
            "spacing_std": self.spacing_std, "spacing_scanline_mean": self.spacing_scanline_mean,
            "persistence_mean": self.persistence_mean,
            "face_parallel": self.face_parallel.astype(np.int64),
            "face_angle_deg": self.face_angle_deg,
        }
        r = self.roughness
        cols.update({
            "odr_mean": r.odr_mean, "odr_median": r.odr_median, "odr_std": r.odr_std,
            "theta_max_c1_dip": r.theta_max_c1_dip,
            "theta_max_c1_strike": r.theta_max_c1_strike,
            "delta_t_dip": r.delta_t_dip, "delta_t_strike": r.delta_t_strike,
            "jrc_estimate_dip": r.jrc_estimate_dip, "jrc_estimate_strike": r.jrc_estimate_strike,
        })
        return _in_unit(cols, unit_m)

    def plane_table(self, unit_m: float = 1.0) -> dict[str, np.ndarray]:
        """Column -> (P,) values in :data:`PLANE_COLUMNS` order, lengths divided by
        ``unit_m`` and the area by its square."""
        pl = self.planes
        cols: dict[str, np.ndarray] = {
            "plane_id": np.arange(1, pl.n_planes + 1, dtype=np.int64),
            "set_id": pl.set_id, "joint_id": pl.joint_id, "dip_deg": pl.dip_deg,
            "dip_direction_deg": pl.dip_direction_deg,
            "cx": pl.centroid[:, 0], "cy": pl.centroid[:, 1], "cz": pl.centroid[:, 2],
            "area": pl.area / unit_m**2,
            "persistence_dip": pl.persistence_dip, "persistence_strike": pl.persistence_strike,
            "rms": pl.rms, "cells": pl.cells,
        }
        return _in_unit(cols, unit_m)

    def joint_table(self, unit_m: float = 1.0) -> dict[str, np.ndarray]:
        """Column -> (J,) values in :data:`JOINT_COLUMNS` order, lengths divided by
        ``unit_m`` and the area by its square."""
        jt = self.joints
        cols: dict[str, np.ndarray] = {
            "joint_id": np.arange(1, jt.n_joints + 1, dtype=np.int64), "set_id": jt.set_id,
            "dip_deg": jt.dip_deg, "dip_direction_deg": jt.dip_direction_deg,
            "cx": jt.centroid[:, 0], "cy": jt.centroid[:, 1], "cz": jt.centroid[:, 2],
            "patches": jt.patches, "area": jt.area / unit_m**2,
            "trace_length": jt.trace_length, "persistence_dip": jt.persistence_dip,
            "persistence_strike": jt.persistence_strike, "rms": jt.rms,
        }
        return _in_unit(cols, unit_m)

    def dips_table(self, unit_m: float = 1.0) -> dict[str, np.ndarray]:
        """The planes as Rocscience Dips reads them (Import CSV, Dip/Dip Direction
        convention): ``Dip``, ``Dip Direction``, ``Quantity`` (1: each plane is one
        discontinuity), ``X (East)``, ``Y (North)``, ``Z (Elev.)``, ``Persistence``
        (the longer chord), then extra columns ``JOINT_SET``, ``PLANE``, ``JOINT`` (the
        joint the plane, a patch, is part of), ``AREA``, ``PERSISTENCE_DIP``,
        ``PERSISTENCE_STRIKE``, ``RMS``, ``CELLS`` and ``FACE_PARALLEL`` (1: the plane's
        set lies parallel to the exposure face, it is the exposure, not a joint;
        :attr:`face_parallel`); lengths divided by ``unit_m``."""
        pl = self.planes
        face = (np.concatenate([[False], self.face_parallel])[pl.set_id]
                if pl.n_planes else np.zeros(0, dtype=bool))
        return {
            "Dip": pl.dip_deg, "Dip Direction": pl.dip_direction_deg,
            "Quantity": np.ones(pl.n_planes, dtype=np.int64),
            "X (East)": pl.centroid[:, 0] / unit_m, "Y (North)": pl.centroid[:, 1] / unit_m,
            "Z (Elev.)": pl.centroid[:, 2] / unit_m, "Persistence": pl.persistence / unit_m,
            "JOINT_SET": pl.set_id, "PLANE": np.arange(1, pl.n_planes + 1, dtype=np.int64),
            "JOINT": pl.joint_id,
            "AREA": pl.area / unit_m**2, "PERSISTENCE_DIP": pl.persistence_dip / unit_m,
            "PERSISTENCE_STRIKE": pl.persistence_strike / unit_m, "RMS": pl.rms / unit_m,
            "CELLS": pl.cells, "FACE_PARALLEL": face.astype(np.int64),
        }


def _in_unit(cols: dict[str, np.ndarray], unit_m: float) -> dict[str, np.ndarray]:
    return {k: (v / unit_m if k in LENGTH_COLUMNS else v) for k, v in cols.items()}


def _axial_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between the axes of unit vectors ``a`` (K, 3) and ``b`` (S, 3): (K, S)."""
    return np.degrees(np.arccos(np.clip(np.abs(a @ b.T), 0.0, 1.0)))


def refine_peak(start: np.ndarray, poles: np.ndarray, weights: np.ndarray,
                smoothing_deg: float) -> np.ndarray:
    """The local maximum of the axial Fisher-kernel density of ``poles`` nearest
    ``start`` (a unit vector), by mean shift on the sphere; downward unit vector.

    Each step moves to the kernel-weighted mean of the poles (turned to the side of
    the current estimate), the fixed point of which is where the density's gradient
    vanishes.
    """
    kappa = kernel_kappa(smoothing_deg)
    reach = np.cos(min(np.radians(_SHIFT_REACH_SIGMAS * smoothing_deg), np.pi / 2))
    m = np.asarray(start, dtype=np.float64) / np.linalg.norm(start)
    near = np.abs(poles @ m) >= reach
    p, w = poles[near], weights[near]
    for _ in range(_SHIFT_ITERATIONS):
        c = p @ m
        k = w * np.exp(kappa * (np.abs(c) - 1.0)) * np.where(c < 0, -1.0, 1.0)
        s = k @ p
        size = np.linalg.norm(s)
        if size == 0:
            break
        new = s / size
        step = np.linalg.norm(new - m)
        m = new
        if step < _SHIFT_TOLERANCE:
            break
    return -m if m[2] > 0 else m


def density_peaks(
    net: Stereonet,
    poles: np.ndarray,
    weights: np.ndarray,
    *,
    min_density: float = DEFAULT_MIN_DENSITY,
    min_angle_deg: float = DEFAULT_MIN_ANGLE_DEG,
    max_peaks: int = DEFAULT_MAX_SETS,
) -> tuple[np.ndarray, np.ndarray]:
    """The principal orientations: peaks of the pole density, strongest first.

    Candidates are the local maxima (8 neighbours) of ``net.density`` on its node
    grid of at least half ``min_density``; each is refined by :func:`refine_peak`
    and its exact density computed over every pole
    (:func:`~rough_viewer.grid.orientation.kernel_density`). Peaks below
    ``min_density`` go; going down the list, a peak within ``min_angle_deg`` of a
    stronger one goes; at most ``max_peaks`` stay.

    Parameters
    ----------
    net : Stereonet
        The poles' stereonet (its node density gives the starting points).
    poles : (K, 3) array
        Unit poles (either sense).
    weights : (K,) array
        Weight of every pole.

    Returns
    -------
    peaks : (S, 3) array
        Downward unit directions.
    density : (S,) array
        Density at each, MUD.
    """
    dens = net.density
    if poles.shape[0] == 0 or not np.isfinite(dens).any():
        return np.zeros((0, 3)), np.zeros(0)
    padded = np.pad(np.where(np.isfinite(dens), dens, -np.inf), 1, constant_values=-np.inf)
    g = dens.shape[0]
    centre = padded[1:-1, 1:-1]
    is_max = np.isfinite(centre) & (centre >= 0.5 * min_density)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                is_max &= centre >= padded[1 + di:1 + di + g, 1 + dj:1 + dj + g]
    iy, ix = np.nonzero(is_max)
    order = np.argsort(-centre[iy, ix], kind="stable")
    starts = schmidt_inverse(net.nodes[ix[order]], net.nodes[iy[order]]).reshape(-1, 3)
    found = np.array([refine_peak(s, poles, weights, net.smoothing_deg) for s in starts]
                     ).reshape(-1, 3)
    exact = kernel_density(found, poles, weights, smoothing_deg=net.smoothing_deg)
    rank = np.argsort(-exact, kind="stable")
    keep: list[int] = []
    for i in rank:
        if exact[i] < min_density or len(keep) >= max_peaks:
            break
        if keep and _axial_angle(found[i:i + 1], found[keep]).min() < min_angle_deg:
            continue
        keep.append(int(i))
    return found[keep].reshape(-1, 3), exact[keep]


#: Finest density kernel, degrees: the stereonet's nodes (61 a side) lie 2.7-3.8
#: degrees apart, and a kernel much finer than that is sampled by no node
#: (``--smoothing 0.01`` found 0 sets, silently).
MIN_SMOOTHING_DEG = 1.0


@dataclass(frozen=True)
class SetOptions:
    """The settings of :func:`joint_sets` (lengths in metres, angles in degrees),
    checked when made: an option that cannot be used raises InputError (one line),
    so the command line makes them before reading the input."""

    max_roughness: float | None = None
    """Largest ODR roughness of a planar cell, metres (None: :data:`DEFAULT_PLANAR_SHARE`
    times the cell size)."""
    min_planar_points: int = DEFAULT_MIN_PLANAR_POINTS
    """Least points of a planar cell."""
    cone_deg: float = DEFAULT_CONE_DEG
    """A cell joins the nearest peak within this angle."""
    min_angle_deg: float = DEFAULT_MIN_ANGLE_DEG
    """Least angle between two sets' peaks."""
    max_sets: int = DEFAULT_MAX_SETS
    """Largest number of sets (1..255)."""
    smoothing_deg: float = DEFAULT_SMOOTHING_DEG
    """Kernel ``sigma`` of the pole density (as the stereonet's)."""
    min_density: float = DEFAULT_MIN_DENSITY
    """Least density of a peak, MUD."""
    min_set_cells: int = DEFAULT_MIN_SET_CELLS
    """Least cells of a set."""
    plane_tolerance: float | None = None
    """Largest offset difference (metres, along the set's mean normal) between
    touching cells of one plane, and the least normal spacing (None: half a cell)."""
    min_plane_cells: int = DEFAULT_MIN_PLANE_CELLS
    """Least cells of a plane."""
    max_plane_rms: float | None = None
    """Largest RMS (metres) of a plane's points about their best plane: a group of
    touching cells that curves more is no plane (None: a quarter of a cell)."""
    face_tolerance_deg: float = DEFAULT_FACE_TOLERANCE_DEG
    """A set whose mean pole lies within this angle of the exposure face's normal is
    flagged parallel to the face (:mod:`rough_viewer.structure.face`)."""
    face_radius: float | None = None
    """Radius (metres) of the neighbourhood of a cell whose plane is its local face
    (None: :data:`~rough_viewer.structure.face.DEFAULT_FACE_RADIUS_CELLS` cells)."""

    def __post_init__(self) -> None:
        t, tol = self.max_roughness, self.plane_tolerance
        rms = self.max_plane_rms
        if rms is not None and not (np.isfinite(rms) and rms > 0):
            raise InputError(f"the largest RMS of a plane must be a positive length, got {rms:g}")
        if t is not None and not (np.isfinite(t) and t > 0):
            raise InputError(f"the largest roughness of a planar cell must be a positive "
                             f"length, got {t:g}")
        if not (np.isfinite(self.cone_deg) and 0 < self.cone_deg <= 90):
            raise InputError(f"the cone must be in (0, 90] degrees, got {self.cone_deg:g}")
        if not (np.isfinite(self.min_angle_deg) and 0 <= self.min_angle_deg <= 90):
            raise InputError(f"the least angle between sets must be in [0, 90] degrees, got "
                             f"{self.min_angle_deg:g}")
        if int(self.max_sets) != self.max_sets or not 1 <= self.max_sets <= 255:
            raise InputError(f"the largest number of sets must be a whole number in 1..255, "
                             f"got {self.max_sets}")
        if not (np.isfinite(self.smoothing_deg) and MIN_SMOOTHING_DEG <= self.smoothing_deg <= 90):
            raise InputError(f"smoothing must be from {MIN_SMOOTHING_DEG:g} to 90 degrees (the "
                             "density net's nodes lie about 3 degrees apart: a finer kernel "
                             "falls between them and finds no set), got "
                             f"{self.smoothing_deg:g}")
        if not (np.isfinite(self.min_density) and self.min_density >= 0):
            raise InputError(f"the least peak density must be >= 0 MUD, got "
                             f"{self.min_density:g}")
        for name, v in (("cells of a set", self.min_set_cells),
                        ("cells of a plane", self.min_plane_cells),
                        ("points of a planar cell", self.min_planar_points)):
            if int(v) != v or v < 1:
                raise InputError(f"the least number of {name} must be a whole number >= 1, "
                                 f"got {v}")
        if tol is not None and not (np.isfinite(tol) and tol >= 0):
            raise InputError(f"the plane tolerance must be a length >= 0, got {tol:g}")
        if not (np.isfinite(self.face_tolerance_deg) and 0 <= self.face_tolerance_deg <= 90):
            raise InputError(f"the face tolerance must be in [0, 90] degrees, got "
                             f"{self.face_tolerance_deg:g}")
        r = self.face_radius
        if r is not None and not (np.isfinite(r) and r > 0):
            raise InputError(f"the face radius must be a positive length, got {r:g}")

    def face_radius_m(self, cell_size: float) -> float:
        """The local face's radius in metres on a grid of ``cell_size`` (the default
        where None)."""
        return float(DEFAULT_FACE_RADIUS_CELLS * cell_size if self.face_radius is None
                     else self.face_radius)

    def lengths(self, cell_size: float) -> tuple[float, float, float]:
        """``(max_roughness, plane_tolerance, max_plane_rms)`` in metres on a grid of
        ``cell_size`` (the defaults where None)."""
        t = DEFAULT_PLANAR_SHARE * cell_size if self.max_roughness is None else self.max_roughness
        tol = (DEFAULT_PLANE_TOLERANCE_SHARE * cell_size if self.plane_tolerance is None
               else self.plane_tolerance)
        rms = (DEFAULT_PLANE_RMS_SHARE * cell_size if self.max_plane_rms is None
               else self.max_plane_rms)
        return float(t), float(tol), float(rms)


def joint_sets(
    result: GridRoughness,
    cloud: PointCloud | np.ndarray,
    options: SetOptions | None = None,
    *,
    progress: ProgressFn | None = None,
    roughness: bool = True,
) -> JointSets:
    """Discontinuity sets, their planes, spacing and persistence (see the module).

    Parameters
    ----------
    result : GridRoughness
        The grid result (ODR normals and roughness; :attr:`~GridRoughness.point_cell`
        is needed for the planes' fits, so not an out-of-core result).
    cloud : PointCloud or (N, 3) array
        The points ``result`` was computed from, metres.
    options : SetOptions, optional
        The settings (default :class:`SetOptions()`: planar cells of at most 2 % of
        the cell in roughness and 10 points, a cone of 20 degrees, peaks of at least
        3 MUD and 30 degrees apart, at most 6 sets of 10 cells, planes of 3 cells
        within half a cell of offset).
    progress : callable, optional
        ``progress(done, total)`` over 4 stages.
    roughness : bool
        Measure every set's joints along dip and strike (step 11; default); False
        leaves those values NaN (the cells' ODR statistics stay), for a quicker
        answer.

    Returns
    -------
    JointSets
        With ``note`` saying why when there is no set.
    """
    o = options if options is not None else SetOptions()
    g = float(result.grid.cell_size)
    t, tol, max_rms = o.lengths(g)
    cone_deg, max_sets, min_density = o.cone_deg, o.max_sets, o.min_density
    min_plane_cells, min_planar_points = o.min_plane_cells, o.min_planar_points
    x, y, z = as_columns(cloud)
    if result.point_cell.shape[0] != x.shape[0]:
        raise InputError("joint sets need the points of the grid result (its point_cell "
                         f"has {result.point_cell.shape[0]:,} rows, the cloud "
                         f"{x.shape[0]:,} points); compute the grid in memory")
    tick = progress or (lambda done, total: None)
    tick(0, 4)
    m_cells = result.n_cells
    has_plane = np.all(np.isfinite(result.normal), axis=1) & np.isfinite(result.theta_odr)
    planar = has_plane & (result.theta_odr <= t) & (result.n_points >= min_planar_points)
    rows = np.flatnonzero(planar)
    # 3 vectors and a few scalars per planar cell, the (K, S) angles, the peaks' work
    require(rows.shape[0] * (200.0 + 16.0 * max_sets) + 8.0 * m_cells * 4,
            f"joint sets of {rows.shape[0]:,} planar cells", hint="choose a larger grid size")
    weights = result.n_points[rows].astype(np.float64)
    toward = result.whole_plane.normal
    net, poles, peaks, peak_density = _pole_peaks(result, rows, weights, o)
    tick(1, 4)
    labels, peaks, peak_density = _gather_sets(poles, peaks, peak_density, o.cone_deg,
                                               o.min_set_cells)
    n_sets = int(peaks.shape[0])
    note = _why_none(result, rows, has_plane, t, int(min_planar_points), min_density,
                     o.min_set_cells, cone_deg) if n_sets == 0 else ""
    # per set: Fisher statistics of its cells' poles, turned to the peak's side; a
    # cell the peak gathered that lies outside the cone of its set's final mean
    # leaves the set (issue 31 item 15), until none does
    labels, mean_pole, kappa, alpha = _set_statistics(poles, weights, labels, peaks, cone_deg)
    cell_set = np.zeros(m_cells, dtype=np.int32)
    cell_set[rows] = labels
    normal = orient_normals(mean_pole, toward) if n_sets else np.zeros((0, 3))
    dip, dd = dip_and_direction(normal, toward) if n_sets else (np.zeros(0), np.zeros(0))
    set_cells = np.bincount(labels, minlength=n_sets + 1)[1:].astype(np.int64)
    set_points = np.bincount(labels, weights=weights, minlength=n_sets + 1)[1:].astype(np.int64)
    tick(2, 4)
    cell_plane, cell_set, planes, curved, slivers = _planes(
        result, (x, y, z), cell_set, normal, tol, int(min_plane_cells), t,
        int(min_planar_points), max_rms, cone_deg)
    tick(3, 4)
    planes, cell_joint, point_joint, joints = _joints(result, (x, y, z), cell_plane, planes,
                                                      toward, tol, max_rms)
    n_planes = np.bincount(planes.set_id, minlength=n_sets + 1)[1:].astype(np.int64)
    n_joints = np.bincount(joints.set_id, minlength=n_sets + 1)[1:].astype(np.int64)
    spacing, persistence_mean = _spacing_and_persistence(
        planes, joints, normal, point_joint, (x, y, z), result.grid.origin, g, tol)
    # the cell statistics are of the cells whose poles made the set (not the edge
    # cells of fewer points its planes took in)
    set_rough = set_roughness(np.where(planar, cell_set, 0), result.theta_odr, n_sets,
                              joints, point_joint, (x, y, z), directional=roughness)
    face = face_angles(mean_pole, cell_set, result.centroid, toward,
                       result.whole_plane.eigenvalues, radius=o.face_radius_m(g),
                       tolerance_deg=o.face_tolerance_deg)
    tick(4, 4)
    return JointSets(
        cell_set=cell_set, cell_plane=cell_plane, planar=planar, net=net, peak=peaks,
        peak_density=peak_density, mean_pole=mean_pole, normal=normal, dip_deg=dip,
        dip_direction_deg=dd, kappa=kappa, alpha95_deg=alpha, cells=set_cells,
        points=set_points, n_planes_per_set=n_planes, n_joints_per_set=n_joints,
        spacing_mean=spacing[:, 0], spacing_median=spacing[:, 1], spacing_std=spacing[:, 2],
        spacing_scanline_mean=spacing[:, 3], persistence_mean=persistence_mean, planes=planes,
        joints=joints, cell_joint=cell_joint, roughness=set_rough, cell_size=g, options=o,
        max_roughness=t, plane_tolerance=tol, max_plane_rms=max_rms, curved_groups=curved,
        note=note, face=face, sliver_planes=slivers)


def _pole_peaks(result: GridRoughness, rows: np.ndarray, weights: np.ndarray,
                o: SetOptions) -> tuple[Stereonet, np.ndarray, np.ndarray, np.ndarray]:
    """The stereonet of the poles of the planar cells ``rows`` (weighted by their
    points), the poles (downward unit vectors) and the density peaks with their
    densities (MUD)."""
    net = stereonet(result.normal[rows], toward=result.whole_plane.normal,
                    smoothing_deg=o.smoothing_deg, weights=weights)
    net = Stereonet(x=net.x, y=net.y, rows=rows[net.rows], nodes=net.nodes, density=net.density,
                    smoothing_deg=net.smoothing_deg, weights=net.weights)
    poles = _downward(result.normal[rows])
    peaks, peak_density = density_peaks(net, poles, weights, min_density=o.min_density,
                                        min_angle_deg=o.min_angle_deg, max_peaks=o.max_sets)
    return net, poles, peaks, peak_density


def _gather_sets(poles: np.ndarray, peaks: np.ndarray, peak_density: np.ndarray,
                 cone_deg: float, min_set_cells: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pole to its nearest peak within the cone (label set + 1, 0 for none),
    the peaks gathering fewer than ``min_set_cells`` cells dropped until none does;
    returns the labels and the peaks kept with their densities."""
    labels = np.zeros(poles.shape[0], dtype=np.int64)  # set index + 1 per planar cell
    while peaks.shape[0]:
        labels = _assign(poles, peaks, cone_deg)
        counts = np.bincount(labels, minlength=peaks.shape[0] + 1)[1:]
        small = counts < min_set_cells
        if not small.any():
            break
        peaks, peak_density = peaks[~small], peak_density[~small]
    if not peaks.shape[0]:
        labels[:] = 0
    return labels, peaks, peak_density


def _joints(result: GridRoughness, xyz: tuple[np.ndarray, np.ndarray, np.ndarray],
            cell_plane: np.ndarray, planes: JointPlanes, toward: np.ndarray, tol: float,
            max_rms: float) -> tuple[JointPlanes, np.ndarray, np.ndarray, Joints]:
    """The joints: the patches of one discontinuity (structure/joints.py). Returns the
    planes with their joint ids, the joint of every cell (1..J, 0 for none), of every
    point (0..J-1, -1 for none) and the joint table."""
    patch_joint = merge_patches(planes.set_id, planes.points, planes.centroid, planes.scatter,
                                planes.normal, tolerance=tol, max_rms=max_rms)
    planes = replace(planes, joint_id=patch_joint + 1)
    cell_joint = np.zeros(result.n_cells, dtype=np.int32)
    on_plane = cell_plane > 0
    cell_joint[on_plane] = (patch_joint[cell_plane[on_plane] - 1] + 1).astype(np.int32)
    point_joint = cell_joint[result.point_cell].astype(np.int64) - 1
    joints = joint_table(patch_joint, planes.set_id, planes.points, planes.centroid,
                         planes.scatter, planes.area, point_joint, xyz, toward)
    return planes, cell_joint, point_joint, joints


def _spacing_and_persistence(planes: JointPlanes, joints: Joints, normal: np.ndarray,
                             point_joint: np.ndarray,
                             xyz: tuple[np.ndarray, np.ndarray, np.ndarray],
                             origin: np.ndarray, g: float, tol: float
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Per set: the normal spacing's mean, median and standard deviation and the
    scanline spacing's mean ((S, 4), metres, NaN where none), and the mean
    persistence of its planes ((S,), metres). A loop over sets."""
    n_sets = normal.shape[0]
    spacing = np.full((n_sets, 4), np.nan)
    persistence_mean = np.full(n_sets, np.nan)
    for s in range(n_sets):
        mine = planes.set_id == s + 1
        if mine.any():
            persistence_mean[s] = float(planes.persistence[mine].mean())
        sp = set_spacing(joints, s + 1, normal[s], point_joint, xyz, origin, g, tol)
        if sp.normal.size:
            spacing[s, :3] = (sp.normal.mean(), np.median(sp.normal), sp.normal.std())
        if sp.scanline.size:
            spacing[s, 3] = sp.scanline.mean()
    return spacing, persistence_mean


#: Most passes of :func:`_set_statistics` (each drops the cells outside the cone of
#: their set's mean; the first or second leaves none on every scan tried).
_MEAN_PASSES = 10


def _set_statistics(poles: np.ndarray, weights: np.ndarray, labels: np.ndarray,
                    peaks: np.ndarray, cone_deg: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fisher statistics of every set's cells (poles turned to the peak's side), the
    cells outside the cone of their set's mean dropped (label 0) and the statistics
    taken again until every cell of a set lies within the cone of its mean.

    Returns
    -------
    labels, mean_pole, kappa, alpha95
        The labels (set + 1, 0 = none) and per set: the downward unit mean pole,
        ``kappa`` and ``alpha95`` (degrees).
    """
    n_sets = peaks.shape[0]
    labels = labels.copy()
    mean_pole = np.zeros((n_sets, 3))
    kappa = np.zeros(n_sets)
    alpha = np.zeros(n_sets)
    for _ in range(_MEAN_PASSES):
        for s in range(n_sets):
            on = labels == s + 1
            p = poles[on] * np.where(poles[on] @ peaks[s] < 0, -1.0, 1.0)[:, None]
            st = fisher_statistics(p, weights[on])
            mean_pole[s] = -st.mean if st.mean[2] > 0 else st.mean
            kappa[s], alpha[s] = st.kappa, st.alpha95_deg
        on = np.flatnonzero(labels > 0)
        if not n_sets or on.shape[0] == 0:
            break
        off = _axial_angle_rows(poles[on], mean_pole[labels[on] - 1]) > cone_deg
        if not off.any():
            break
        labels[on[off]] = 0
    return labels, mean_pole, kappa, alpha


def _axial_angle_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between the axes of the rows of ``a`` and ``b`` (both (K, 3)): (K,)."""
    c = np.abs(np.einsum("ij,ij->i", a, b))
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def _downward(normals: np.ndarray) -> np.ndarray:
    """Unit normals turned downward (the poles); horizontal ones kept as given."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where((n[:, 2] > 0)[:, None], -n, n)


def _assign(poles: np.ndarray, peaks: np.ndarray, cone_deg: float) -> np.ndarray:
    """(K,) 1 + index of the nearest peak within the cone, 0 where none."""
    angle = _axial_angle(poles, peaks)
    nearest = np.argmin(angle, axis=1)
    within = angle[np.arange(poles.shape[0]), nearest] <= cone_deg
    return np.where(within, nearest + 1, 0)


def _why_none(result: GridRoughness, rows: np.ndarray, has_plane: np.ndarray, t: float,
              min_points: int, min_density: float, min_set_cells: int, cone_deg: float) -> str:
    """One sentence: why no set was found."""
    valued = int(np.count_nonzero(has_plane))
    if valued == 0:
        return "no cell has an ODR plane (too few points per cell?); no joint set"
    if rows.shape[0] == 0:
        enough = has_plane & (result.n_points >= min_points)
        if not enough.any():
            return (f"no planar cell: none of the {valued:,} cells with an ODR value has "
                    f"{min_points} points (a larger grid size gives fuller cells); no joint set")
        low = float(np.nanmin(result.theta_odr[enough]))
        return (f"no planar cell: none of the {int(enough.sum()):,} cells with an ODR value "
                f"and {min_points}+ points has a roughness of at most {t:.4g} m (the smoothest "
                f"has {low:.4g} m); no joint set")
    return (f"no joint set: the poles of the {rows.shape[0]:,} planar cells (of {valued:,}) "
            f"have no density peak of at least {min_density:g} MUD gathering "
            f"{min_set_cells} cells within {cone_deg:g} degrees (the rock has no preferred "
            "plane orientation at this grid size)")


def _planes(result: GridRoughness, xyz: tuple[np.ndarray, np.ndarray, np.ndarray],
            cell_set: np.ndarray, set_normal: np.ndarray, tol: float, min_cells: int,
            max_roughness: float, min_planar_points: int, max_rms: float, cone_deg: float
            ) -> tuple[np.ndarray, np.ndarray, JointPlanes, int, int]:
    """Planes of every set: the plane and set of every cell (with the edge cells
    the planes took in), the plane table and the numbers of curved groups and of
    slivers (a plane outside the cone of its set's mean) dropped."""
    members = np.flatnonzero(cell_set > 0)
    cell_plane = np.zeros(result.n_cells, dtype=np.int32)
    if members.shape[0] == 0:
        return cell_plane, cell_set, _no_planes(), 0, 0
    plane_of, plane_set = _cell_groups(result, members, cell_set, set_normal, tol, min_cells)
    cell_plane[members] = plane_of
    n_p = int(plane_set.shape[0])
    if n_p == 0:
        return cell_plane, cell_set, _no_planes(), 0, 0
    in_set = cell_set > 0  # before the planes take in their edge cells
    cell_set = cell_set.copy()
    first_fit = _fit_planes(result, xyz, cell_plane, n_p, measure=False)
    # a group whose points do not fit one plane (a curved surface chained cell by
    # cell) is no discontinuity plane: its cells keep their set, plane 0
    flat = first_fit.rms <= max_rms
    curved = int(np.count_nonzero(~flat))
    if curved:
        plane_set, n_p = _renumber(cell_plane, plane_set, flat)
        if n_p == 0:
            return cell_plane, cell_set, _no_planes(), curved, 0
        first_fit = _Fit(normal=first_fit.normal[flat], centroid=first_fit.centroid[flat],
                         rms=first_fit.rms[flat], points=first_fit.points[flat],
                         cov=first_fit.cov[flat])
    _take_edge_cells(result, cell_plane, cell_set, plane_set, first_fit, max_roughness,
                     min_planar_points)
    fit = _fit_planes(result, xyz, cell_plane, n_p, measure=True)  # with the edge cells
    assert fit.chord_dip is not None and fit.chord_strike is not None and fit.area is not None
    # a plane whose points' normal lies outside the cone of its set's mean is a strip
    # about one cell wide whose points do not fix its tilt about its length (demo:
    # 12 cells 1.65 x 0.09 m fitted 30 degrees off their set although every cell's
    # pole lies within 17 degrees; issue 31 item 15): no plane, its cells keep their
    # set (its edge cells go back to none)
    tilt = _axial_angle_rows(fit.normal, set_normal[plane_set - 1])
    sliver = tilt > cone_deg
    slivers = int(np.count_nonzero(sliver))
    if slivers:
        gone = np.concatenate([[False], sliver])[cell_plane]
        cell_set[gone & ~in_set] = 0
        plane_set, n_p = _renumber(cell_plane, plane_set, ~sliver)
        if n_p == 0:
            return cell_plane, cell_set, _no_planes(), curved, slivers
        keep = ~sliver
        fit = _Fit(normal=fit.normal[keep], centroid=fit.centroid[keep], rms=fit.rms[keep],
                   points=fit.points[keep], cov=fit.cov[keep], chord_dip=fit.chord_dip[keep],
                   chord_strike=fit.chord_strike[keep], area=fit.area[keep])
    return cell_plane, cell_set, _plane_table(result, fit, cell_plane, plane_set,
                                              set_normal), curved, slivers


def _cell_groups(result: GridRoughness, members: np.ndarray, cell_set: np.ndarray,
                 set_normal: np.ndarray, tol: float, min_cells: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The groups of cells of one set that touch (faces, edges, corners) and lie
    within ``tol`` (metres) of one another along the set's normal, of at least
    ``min_cells`` cells: the plane of every cell ``members`` (1..P by set, then size
    largest first, then grid order; 0 for none) and the set of every plane."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    sid = cell_set[members].astype(np.int64)
    offset = np.einsum("ij,ij->i", result.centroid[members] - result.grid.origin,
                       set_normal[sid - 1])
    a, b, _ = _neighbour_pairs(result.ijk[members])
    keep = (sid[a] == sid[b]) & (np.abs(offset[a] - offset[b]) <= tol)
    k = members.shape[0]
    graph = coo_matrix((np.ones(int(keep.sum()), dtype=np.int8), (a[keep], b[keep])), shape=(k, k))
    _, comp = connected_components(graph.tocsr(), directed=False)
    sizes = np.bincount(comp)
    comp_set = np.zeros(sizes.shape[0], dtype=np.int64)
    comp_set[comp] = sid
    first = np.full(sizes.shape[0], k, dtype=np.int64)
    np.minimum.at(first, comp, np.arange(k))  # grid order breaks ties
    big = np.flatnonzero(sizes >= min_cells)
    big = big[np.lexsort((first[big], -sizes[big], comp_set[big]))]
    new_id = np.zeros(sizes.shape[0], dtype=np.int32)
    new_id[big] = np.arange(1, big.shape[0] + 1, dtype=np.int32)
    return new_id[comp], comp_set[big]


def _renumber(cell_plane: np.ndarray, plane_set: np.ndarray, kept: np.ndarray
              ) -> tuple[np.ndarray, int]:
    """Keep the planes ``kept`` ((P,) bool), numbered 1.. in their order: the cells of
    the others go to plane 0 (``cell_plane`` in place). Returns the kept planes' sets
    and their number."""
    renumber = np.zeros(plane_set.shape[0] + 1, dtype=np.int32)
    renumber[1:][kept] = np.arange(1, int(kept.sum()) + 1, dtype=np.int32)
    cell_plane[:] = renumber[cell_plane]
    return plane_set[kept], int(kept.sum())


def _plane_table(result: GridRoughness, fit: _Fit, cell_plane: np.ndarray,
                 plane_set: np.ndarray, set_normal: np.ndarray) -> JointPlanes:
    """The table of the planes fitted (``fit``, measured) with their cells and sets."""
    assert fit.chord_dip is not None and fit.chord_strike is not None and fit.area is not None
    n_p = int(plane_set.shape[0])
    plane_cells = np.bincount(cell_plane, minlength=n_p + 1)[1:].astype(np.int64)
    toward = result.whole_plane.normal
    normal = orient_normals(fit.normal, toward)
    dip, dd = dip_and_direction(normal, toward)
    offset_p = np.einsum("ij,ij->i", fit.centroid - result.grid.origin,
                         set_normal[plane_set - 1])
    return JointPlanes(
        set_id=plane_set, cells=plane_cells, points=fit.points, normal=normal, dip_deg=dip,
        dip_direction_deg=dd, centroid=fit.centroid, rms=fit.rms, area=fit.area,
        persistence_dip=fit.chord_dip, persistence_strike=fit.chord_strike,
        offset=offset_p, scatter=fit.cov, joint_id=np.zeros(n_p, dtype=np.int64))


#: An edge cell joins a plane when its centroid lies within this many times the
#: plane's RMS of it.
EDGE_RMS_FACTOR = 3.0


def _take_edge_cells(result: GridRoughness, cell_plane: np.ndarray, cell_set: np.ndarray,
                     plane_set: np.ndarray, fit: _Fit, max_roughness: float,
                     min_planar_points: int) -> None:
    """Let every plane take in the edge cells it touches (in place): cells in no set
    with an ODR value at most ``max_roughness`` but fewer than ``min_planar_points``
    points (slivers of the plane where it crosses a cell's corner; their own normal
    is too poor to have voted), whose centroid lies within
    :data:`EDGE_RMS_FACTOR` x the plane's RMS of the plane; the nearest plane when
    several touch."""
    small = np.flatnonzero((cell_set == 0) & np.isfinite(result.theta_odr)
                           & (result.theta_odr <= max_roughness)
                           & (result.n_points < min_planar_points)
                           & np.all(np.isfinite(result.centroid), axis=1))
    inside = np.flatnonzero(cell_plane > 0)
    if small.shape[0] == 0:
        return
    rows = np.concatenate([inside, small])
    a, b, _ = _neighbour_pairs(result.ijk[rows])
    n_in = inside.shape[0]
    # pairs of one plane cell (p) and one candidate (c), in either order
    p = np.concatenate([a[(a < n_in) & (b >= n_in)], b[(b < n_in) & (a >= n_in)]])
    c = np.concatenate([b[(a < n_in) & (b >= n_in)], a[(b < n_in) & (a >= n_in)]])
    if p.shape[0] == 0:
        return
    plane = cell_plane[rows[p]].astype(np.int64) - 1
    cell = rows[c]
    dist = np.abs(np.einsum("ij,ij->i", result.centroid[cell] - fit.centroid[plane],
                            fit.normal[plane]))
    ok = dist <= EDGE_RMS_FACTOR * fit.rms[plane]
    plane, cell, dist = plane[ok], cell[ok], dist[ok]
    order = np.lexsort((dist, cell))
    cell, plane = cell[order], plane[order]
    first = np.ones(cell.shape[0], dtype=bool)
    first[1:] = cell[1:] != cell[:-1]
    cell_plane[cell[first]] = plane[first] + 1
    cell_set[cell[first]] = plane_set[plane[first]]


def _no_planes() -> JointPlanes:
    e = np.zeros(0)
    e3 = np.zeros((0, 3))
    ei = np.zeros(0, dtype=np.int64)
    return JointPlanes(set_id=ei, cells=ei, points=ei, normal=e3, dip_deg=e,
                       dip_direction_deg=e, centroid=e3, rms=e, area=e, persistence_dip=e,
                       persistence_strike=e, offset=e, scatter=np.zeros((0, 3, 3)),
                       joint_id=ei)


@dataclass(frozen=True)
class _Fit:
    """Planes fitted to their points (per-plane arrays)."""

    normal: np.ndarray
    centroid: np.ndarray
    rms: np.ndarray
    points: np.ndarray
    cov: np.ndarray
    chord_dip: np.ndarray | None = None
    chord_strike: np.ndarray | None = None
    area: np.ndarray | None = None


def _fit_planes(result: GridRoughness, xyz: tuple[np.ndarray, np.ndarray, np.ndarray],
                cell_plane: np.ndarray, n_p: int, *, measure: bool) -> _Fit:
    """ODR fit, RMS and points of every plane from its points; with ``measure`` also
    its chords along dip and strike and its area."""
    require(5.0 * result.point_cell.shape[0], "the planes of every point")
    plane_of_point = cell_plane[result.point_cell]
    sel = np.flatnonzero(plane_of_point > 0)
    k = sel.shape[0]
    # per point of a plane: its index and plane (16 bytes), three relative
    # coordinates (24), two in-plane ones (16) and the chords' strip, key, order,
    # sorted copies and the sort's own work (about 90)
    require(k * 150.0, f"plane fits of {k:,} points", hint="choose a larger grid size")
    q = (plane_of_point[sel] - 1).astype(np.int64)
    # a reference point per plane (the points-weighted mean of its cells' centroids)
    # keeps the sums small on large coordinates (UTM)
    rows = np.flatnonzero(cell_plane > 0)
    w = result.n_points[rows].astype(np.float64)
    pr = cell_plane[rows].astype(np.int64) - 1
    ref = np.column_stack([np.bincount(pr, weights=w * result.centroid[rows, a], minlength=n_p)
                           for a in range(3)]) / np.bincount(pr, weights=w, minlength=n_p)[:, None]
    rel = np.column_stack([xyz[a][sel] - ref[q, a] for a in range(3)])
    count = np.bincount(q, minlength=n_p).astype(np.float64)
    mean = np.column_stack([np.bincount(q, weights=rel[:, a], minlength=n_p)
                            for a in range(3)]) / count[:, None]
    cov = np.zeros((n_p, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            v = np.bincount(q, weights=rel[:, i] * rel[:, j], minlength=n_p) / count
            cov[:, i, j] = cov[:, j, i] = v - mean[:, i] * mean[:, j]
    evals, evecs = np.linalg.eigh(cov)
    fit = _Fit(normal=evecs[:, :, 0], centroid=ref + mean,
               rms=np.sqrt(np.maximum(evals[:, 0], 0.0)), points=count.astype(np.int64),
               cov=cov)
    if not measure:
        return fit
    dip_axis, strike_axis = dip_strike_axes(fit.normal)
    rel -= mean[q]
    u_dip = np.einsum("ij,ij->i", rel, dip_axis[q])
    u_strike = np.einsum("ij,ij->i", rel, strike_axis[q])
    del rel
    g = result.grid.cell_size
    strip = CHORD_STRIP_SHARE * g
    along_dip, covered = _chords(q, u_strike, u_dip, n_p, strip, g)
    along_strike, _ = _chords(q, u_dip, u_strike, n_p, strip, g)
    return replace(fit, chord_dip=along_dip, chord_strike=along_strike, area=covered * strip)


#: Width of the strips in which chords are measured, as a share of the cell size.
CHORD_STRIP_SHARE = 0.25


def _chords(group: np.ndarray, across: np.ndarray, along: np.ndarray, n_groups: int,
            strip: float, gap: float) -> tuple[np.ndarray, np.ndarray]:
    """Chords along ``along`` of every group's points: points in strips of width
    ``strip`` across, sorted along; a chord runs between consecutive points at most
    ``gap`` apart, from its first to its last point.

    Returns
    -------
    longest : (G,) array
        The longest chord of every group.
    total : (G,) array
        The summed length of every group's chords (times ``strip``: its area).
    """
    longest = np.zeros(n_groups)
    if group.shape[0] == 0:
        return longest, np.zeros(n_groups)
    band = np.floor(across / strip).astype(np.int64)
    band -= band.min()
    key = group * (int(band.max()) + 1) + band  # one sort key: group, then strip
    order = np.lexsort((along, key))
    gq, kq, aq = group[order], key[order], along[order]
    start = np.ones(gq.shape[0], dtype=bool)
    start[1:] = (kq[1:] != kq[:-1]) | (np.diff(aq) > gap)
    first = np.flatnonzero(start)
    last = np.append(first[1:], gq.shape[0]) - 1
    length = aq[last] - aq[first]
    np.maximum.at(longest, gq[first], length)
    return longest, np.bincount(gq[first], weights=length, minlength=n_groups)


def set_point_fields(sets: JointSets, result: GridRoughness) -> PointFields:
    """The per-point fields of LAS/LAZ and PLY exports of the sets: ``set_id``
    (uint8, 0 = in no set), ``plane_id`` (int32, 0 = in no plane) and ``joint_id``
    (int32, 0 = in no joint) of every point's cell (0 for a point in no cell)."""
    if sets.cell_set.shape[0] != result.n_cells:
        raise ValueError("the joint sets are of another grid result")
    return PointFields(fields=(
        CellField("set_id", sets.cell_set.astype(np.uint8), "joint set id (0 = none)",
                  np.uint8(0)),
        CellField("plane_id", sets.cell_plane.astype(np.int32), "joint plane id (0 = none)",
                  np.int32(0)),
        CellField("joint_id", sets.cell_joint.astype(np.int32), "joint id (0 = none)",
                  np.int32(0)),
    ), point_cell=result.point_cell)
