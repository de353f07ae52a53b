"""Saved views: a small JSON file that reopens the same picture next week.

A view records the input (path, size and SHA-256 of its content), the grid (cell
size, minimum points, dependent axis), the map shown, the units of the input, the
binary threshold, the colour settings, the open panels, the picked profiles, the
zone settings and the camera. :func:`save_view` writes one atomically;
:func:`load_view` reads one back, validating every field (a view file is untrusted
input: types, ranges and choices are checked by typed msgspec structures, unknown keys
refused, size bounded),
and says whether the input is still there and the same (:class:`InputCheck`):
unchanged, changed (its content hash differs), moved (found beside the view file
with the same content) or missing.

It lives in ``report`` because it is a saved result state that sits on top of the
figures' vocabulary (it checks colour-map names against
:mod:`rough_viewer.visual.colormaps`, which ``io`` may not import) and below the app
and the command line, which both use it. It holds no science.

File layout (``"format": "rough_viewer.view"``, ``"version": 1``)::

    {"format": "rough_viewer.view", "version": 1, "software": "rough_viewer 0.1.0",
     "saved_utc": "2025-01-01T00:00:00+00:00",
     "input": {"path": "/data/scan.laz", "relative_path": "../data/scan.laz",
               "sha256": "<64 hex digits>", "size_bytes": 2876728},
     "units": "m",
     "grid": {"cell_size_m": 0.25, "min_points": 4, "axis": "auto"},
     "model": "odr", "threshold": 0.05,
     "colour": {"colormap": "viridis", "mode": "continuous", "stretch": "percentile",
                "range": [2.0, 98.0], "log": true, "layer": "roughness"},
     "panels": ["table", "histogram"],
     "profiles": [{"start": [x, y, z], "end": [x, y, z], "band_half_width_m": null,
                   "wavelet": "db3", "level": 3, "decomposition": "dwt",
                   "threshold_rule": "fixed", "mode": "hard", "detrend": null}],
     "zones": {"map": "odr", "connectivity": "vertex", "min_cells": 3, "selected": null,
               "threshold_rule": "auto"},
     "camera": {"position": [x, y, z], "look_at": [x, y, z], "up": [0, 0, 1],
                "fov_deg": 50.0},
     "crop": {"min": [x, y, z], "max": [x, y, z], "mode": "keep"},
     "measures": [{"start": [x, y, z], "end": [x, y, z], "number": 1}],
     "sets": {"shown": true, "colour_by": "joint", "poles": "joint", "roughness_pct": 2.0,
              "cone_deg": 20.0, "min_angle_deg": 30.0, "max_sets": 6, "selected_set": 2,
              "selected_joint": 5}}

``zones``, ``camera`` and ``crop`` may be ``null``; ``sets`` (the Sets tab), ``crop``,
``directions``, ``selection`` and ``measures`` may be absent (views saved before them
read as the app's defaults: uncropped, no sets shown); coordinates are metres in the file's
frame. ``crop`` is an axis-aligned box whose points every analysis keeps (``mode``
``keep``) or drops (``remove``): :class:`rough_viewer.io.crop.CropBox`, also read by
``compute``, ``report`` and ``zones --crop-file``.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import re
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Annotated, Any, Literal, get_args, get_origin, get_type_hints

import msgspec
import msgspec.inspect as mi
from msgspec import Meta

from rough_viewer._version import __version__
from rough_viewer.io.crop import CropBox, CropMode
from rough_viewer.io.output import check_output_path, write_atomic
from rough_viewer.structure.sets import (
    DEFAULT_CONE_DEG,
    DEFAULT_MAX_SETS,
    DEFAULT_MIN_ANGLE_DEG,
    DEFAULT_PLANAR_SHARE,
)
from rough_viewer.visual.colormaps import ROUGHNESS_STRETCH, ColormapName, Stretch, StretchMode
from rough_viewer.vocabulary import (
    AxisChoice,
    ColourLayerName,
    Decomposition,
    InputError,
    MapName,
    Mode,
    ProgressFn,
    ThresholdRule,
    Unit,
    error_line,
)

VIEW_FORMAT = "rough_viewer.view"
VIEW_VERSION = 1

#: Largest view file read (bytes): a view is a few kilobytes.
MAX_VIEW_BYTES = 1 << 20
MAX_PROFILES = 100
MAX_MEASURES = 100
MAX_PANELS = 32
MAX_PATH_CHARS = 4096
#: Largest |coordinate| accepted, metres (beyond any projected coordinate system).
MAX_COORDINATE = 1e9
#: Bytes read at a time when hashing an input.
HASH_BLOCK = 1 << 20

ColourMode = Literal["continuous", "binary"]
COLOUR_MODES: tuple[ColourMode, ...] = ("continuous", "binary")
ZoneThresholdRule = Literal["auto", "slider"]
ZONE_THRESHOLD_RULES: tuple[ZoneThresholdRule, ...] = ("auto", "slider")
Connectivity = Literal["face", "edge", "vertex"]
CONNECTIVITIES: tuple[Connectivity, ...] = ("face", "edge", "vertex")
InputStatus = Literal["unchanged", "moved", "changed", "missing", "not_checked"]


Vec3 = tuple[float, float, float]


# ----------------------------------------------------------------------------- the view


@dataclass(frozen=True)
class InputRef:
    """The input a view was made from."""

    path: str
    """Absolute path when the view was saved on the machine of its input (the command
    line, a view saved beside its input); a view downloaded from the app names its
    input relative to the server's data folder instead (no absolute path of the
    server leaves it), found again in the data folder it is opened with."""
    sha256: str
    """SHA-256 of the file's content, 64 lower-case hex digits."""
    size_bytes: int
    """File size, bytes."""


@dataclass(frozen=True)
class ColourSettings:
    """How the map is coloured."""

    colormap: str = "viridis"
    """One of :data:`rough_viewer.visual.colormaps.COLORMAP_NAMES`."""
    mode: ColourMode = "continuous"
    """Continuous colours, or the binary transform at the view's threshold."""
    stretch: Stretch = ROUGHNESS_STRETCH
    """How values spread over the map (:class:`rough_viewer.visual.colormaps.Stretch`:
    percentiles of the cells or absolute limits in metres, linear or log). In the
    file: ``"stretch"`` (its mode), ``"range"`` (its limits) and ``"log"``."""
    layer: ColourLayerName = "roughness"
    """What colours the points (:data:`rough_viewer.vocabulary.COLOUR_LAYERS`): the
    roughness map, the scan's RGB, its intensity or the distance to the face plane."""


@dataclass(frozen=True)
class ProfilePick:
    """A picked profile line and how it is analysed."""

    start: Vec3
    """Line start, metres, file frame."""
    end: Vec3
    """Line end, metres, file frame."""
    band_half_width_m: float | None = None
    """Half-width of the band of points used, metres; None = the local point spacing."""
    wavelet: str = "db3"
    level: int = 3
    decomposition: Decomposition = "dwt"
    threshold_rule: ThresholdRule = "fixed"
    mode: Mode = "hard"
    detrend: int | None = None
    """Degree of the trend removed before de-noising and fitting; None = none."""


@dataclass(frozen=True)
class ZoneSettings:
    """How fracture zones are formed and which one is selected."""

    map: MapName = "odr"
    connectivity: Connectivity = "vertex"
    min_cells: int = 3
    selected: int | None = None
    """Zone id (1 = the largest), or None."""
    threshold_rule: ZoneThresholdRule = "auto"
    """``auto``: with the view's threshold at the paper's 0.05, the data's own when
    0.05 flags more than half of the cells (:func:`rough_viewer.grid.threshold.
    zone_threshold`); ``slider``: the view's threshold as it is. A view saved before
    the rule existed reads as ``slider`` (its zones were at its threshold)."""


@dataclass(frozen=True)
class DirectionsView:
    """The Directions folder's settings, and whether the directions were measured."""

    step_deg: float = 15.0
    """Azimuth step, degrees, (0, 90]."""
    spacing_m: float | None = None
    """Distance between parallel profile lines, metres; None = the default."""
    tin: bool = False
    """The triangle parameters too."""
    lines: bool = True
    """The profile lines shown on the rock."""
    measured: bool = False
    """Measured when saved: a restored view measures them again."""


#: What "Colour sets by" colours the rock by (the Sets tab's choices).
SetColourBy = Literal["set", "joint", "patch"]
SET_COLOUR_BY: tuple[SetColourBy, ...] = ("set", "joint", "patch")
#: What one stereonet pole stands for (the Sets tab's "Stereonet poles").
SetPoles = Literal["cell", "patch", "joint"]
SET_POLES: tuple[SetPoles, ...] = ("cell", "patch", "joint")
#: Bounds of the Sets tab's controls (the app's own: a view outside them is refused).
SET_ROUGHNESS_PCT_RANGE = (0.1, 50.0)
SET_CONE_DEG_RANGE = (1.0, 90.0)
SET_MIN_ANGLE_DEG_RANGE = (0.0, 90.0)
SET_MAX_SETS_RANGE = (1, 20)
#: Largest joint id a view may select (a bound, not a count any scan reaches).
MAX_JOINT_ID = 10**7


@dataclass(frozen=True)
class SetsView:
    """The Sets tab's settings, whether the sets were shown, and the selection.

    Defaults are the tab's: :mod:`rough_viewer.structure.sets`' defaults."""

    shown: bool = False
    """"Show sets" was ticked: a restored view finds and shows them again."""
    colour_by: SetColourBy = "set"
    """What colours the rock while the sets are shown."""
    poles: SetPoles = "cell"
    """One stereonet pole per planar cell, patch or joint."""
    roughness_pct: float = 100.0 * DEFAULT_PLANAR_SHARE
    """Largest ODR roughness of a planar cell, percent of the cell edge,
    :data:`SET_ROUGHNESS_PCT_RANGE`."""
    cone_deg: float = DEFAULT_CONE_DEG
    """A planar cell joins the nearest set's peak within this angle, degrees."""
    min_angle_deg: float = DEFAULT_MIN_ANGLE_DEG
    """Least angle between two sets, degrees."""
    max_sets: int = DEFAULT_MAX_SETS
    """Most sets."""
    selected_set: int | None = None
    """Selected set id (1..), or None."""
    selected_joint: int | None = None
    """Selected joint id (1..), or None."""


@dataclass(frozen=True)
class SelectionView:
    """A Select-tab selection: the points a screen rectangle held, through the whole
    depth, seen by the camera of the tab that dragged it (metres, file frame)."""

    position: Vec3
    """Camera centre."""
    wxyz: tuple[float, float, float, float]
    """Camera-to-world rotation (OpenCV axes: x right, y down, z forward)."""
    fov_rad: float
    """Vertical field of view, radians."""
    aspect: float
    """Window width / height."""
    height_px: int
    """Window height, pixels."""
    corner_a: tuple[float, float]
    """One corner of the rectangle (normalised window coordinates)."""
    corner_b: tuple[float, float]
    """The opposite corner."""


@dataclass(frozen=True)
class MeasurePick:
    """A distance measured between two points of the rock (the Measure tab)."""

    start: Vec3
    """First point, metres, file frame."""
    end: Vec3
    """Second point, metres, file frame."""
    number: int = 1
    """Its number as listed (D1, D2, ...)."""


@dataclass(frozen=True)
class Camera:
    """Where the 3-D view looks from, metres, file frame."""

    position: Vec3
    look_at: Vec3
    up: Vec3 = (0.0, 0.0, 1.0)
    fov_deg: float = 50.0
    """Vertical field of view, degrees."""


@dataclass(frozen=True)
class View:
    """Everything needed to reopen the same picture."""

    input: InputRef
    cell_size_m: float
    """Grid cell edge, metres."""
    min_points: int
    """Cells with fewer points get no value (at least 3)."""
    axis: AxisChoice = "auto"
    """Dependent axis of OLS and hybrid."""
    model: MapName = "odr"
    """The map shown."""
    units: Unit = "m"
    """Unit of the input's coordinates."""
    threshold: float = 0.05
    """Binary-transform threshold on normalised roughness, [0, 1]."""
    colour: ColourSettings = field(default_factory=ColourSettings)
    panels: tuple[str, ...] = ()
    """Names of the open analysis panels (the app's own names)."""
    profiles: tuple[ProfilePick, ...] = ()
    zones: ZoneSettings | None = None
    camera: Camera | None = None
    crop: CropBox | None = None
    """The crop every analysis runs on, or None (all points)."""
    measures: tuple[MeasurePick, ...] = ()
    """The measured distances, oldest first (absent from views saved before them)."""
    directions: DirectionsView | None = None
    """The Directions folder's settings (None: absent, the app's defaults)."""
    selection: SelectionView | None = None
    """The Select tab's selection (None: none)."""
    sets: SetsView | None = None
    """The Sets tab's settings and selection (None: absent, the tab's defaults; views
    saved before it read so)."""

    def with_(self, **changes: Any) -> View:
        """A copy with some fields changed (validated like a loaded view)."""
        return check_view(replace(self, **changes))


def _plain(value: Any) -> Any:
    """A numpy scalar as the Python number it holds (for ``json.dumps``)."""
    item = getattr(value, "item", None)
    if item is None:
        raise TypeError(f"{type(value).__name__} is not a value a view holds")
    return item()


def check_view(view: View) -> View:
    """The view, validated like one read from a file (InputError names the field)."""
    # through JSON text, as a file would be: numpy scalars the app holds become the
    # plain numbers the typed reader takes, and NaN reaches it to be refused
    doc = json.loads(json.dumps({"format": VIEW_FORMAT, "version": VIEW_VERSION,
                                 **view_to_dict(view)}, default=_plain))
    parsed = view_from_dict(doc)
    return parsed["view"]


@dataclass(frozen=True)
class InputCheck:
    """Whether a view's input is still where it was and the same."""

    status: InputStatus
    """``unchanged``; ``moved`` (not at its path, found beside the view file with the
    same content); ``changed`` (its content hash differs); ``missing``;
    ``not_checked``."""
    path: Path | None
    """Where the input is now (the file to open), or None when missing."""
    message: str
    """One line for the user."""


@dataclass(frozen=True)
class LoadedView:
    """A view read from a file."""

    view: View
    input_check: InputCheck
    software: str
    """What saved it (e.g. ``rough_viewer 0.1.0``)."""
    saved_utc: str
    """When it was saved (ISO 8601, UTC)."""


# ----------------------------------------------------------------------------- hashing


def file_sha256(path: str | os.PathLike[str], *, progress: ProgressFn | None = None) -> str:
    """SHA-256 of a file's content, read in blocks of :data:`HASH_BLOCK` bytes (never
    whole: memory stays constant for any size). ``progress(done, total)`` in bytes."""
    p = Path(path)
    digest = hashlib.sha256()
    try:
        total = p.stat().st_size
        done = 0
        buf = bytearray(HASH_BLOCK)
        view = memoryview(buf)
        with open(p, "rb", buffering=0) as fh:
            while True:
                n = fh.readinto(buf)
                if not n:
                    break
                digest.update(view[:n])
                done += n
                if progress:
                    progress(done, total)
    except OSError as exc:
        raise InputError(f"cannot read {p}: {exc.strerror or exc}") from None
    return digest.hexdigest()


def input_ref(path: str | os.PathLike[str], *, progress: ProgressFn | None = None) -> InputRef:
    """The :class:`InputRef` of a file: absolute path, size and content hash."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"input file not found: {p}")
    return InputRef(path=str(p.resolve()), sha256=file_sha256(p, progress=progress),
                    size_bytes=p.stat().st_size)


def _same_content(p: Path, ref: InputRef, progress: ProgressFn | None) -> bool:
    try:
        if p.stat().st_size != ref.size_bytes:
            return False  # no need to read it
    except OSError:
        return False
    return file_sha256(p, progress=progress) == ref.sha256


def check_input(ref: InputRef, *, view_folder: str | os.PathLike[str] | None = None,
                relative_path: str | None = None, data_folder: str | os.PathLike[str] | None = None,
                progress: ProgressFn | None = None) -> InputCheck:
    """Whether the input of a view is where it was and unchanged.

    Looks at the recorded path first (a relative one, a download's, in
    ``data_folder``, else beside the view file; never above either); if no file is
    there, at ``relative_path`` and at the file's name beside the view file
    (``view_folder``), for a folder that was moved or copied whole.
    """
    recorded = Path(ref.path)
    if not recorded.is_absolute():
        base = data_folder if data_folder is not None else view_folder
        if base is None or ".." in recorded.parts:
            return InputCheck("missing", None, f"input {recorded} not found (a view names "
                              "it relative to the data folder: pass --data-dir)")
        recorded = Path(base) / recorded
    if recorded.is_file():
        if _same_content(recorded, ref, progress):
            return InputCheck("unchanged", recorded, f"input {recorded} unchanged")
        return InputCheck("changed", recorded,
                          f"input {recorded} has changed since the view was saved "
                          "(its content differs); the view's numbers may not match")
    candidates: list[Path] = []
    if view_folder is not None:
        folder = Path(view_folder)
        if relative_path:
            candidates.append(folder / relative_path)
        candidates.append(folder / recorded.name)
    seen: set[Path] = set()
    found_other: Path | None = None
    for cand in candidates:
        try:
            real = cand.resolve()
        except (OSError, RuntimeError):
            continue
        if real in seen or not cand.is_file():
            continue
        seen.add(real)
        if _same_content(cand, ref, progress):
            return InputCheck("moved", cand,
                              f"input moved: {recorded} is gone, using {cand} (same content)")
        found_other = found_other or cand
    if found_other is not None:
        return InputCheck("changed", found_other,
                          f"input {recorded} is gone; {found_other} has its name but a "
                          "different content; the view's numbers may not match")
    if not Path(ref.path).is_absolute():
        return InputCheck("missing", None, f"input {recorded} not found (the view names "
                          f"{ref.path} in the data folder: pass --data-dir with the folder "
                          "that holds it)")
    return InputCheck("missing", None, f"input {recorded} not found (moved or deleted?)")


# ----------------------------------------------------------------------------- to and from JSON


def view_to_dict(view: View) -> dict[str, Any]:
    """The JSON-ready content of a view (without the file's header fields)."""
    d = asdict(view)
    d["grid"] = {"cell_size_m": d.pop("cell_size_m"), "min_points": d.pop("min_points"),
                 "axis": d.pop("axis")}
    s = view.colour.stretch
    d["colour"] = {"colormap": view.colour.colormap, "mode": view.colour.mode,
                   "stretch": s.mode, "range": [s.lo, s.hi], "log": s.log,
                   "layer": view.colour.layer}
    d["panels"] = list(d["panels"])
    d["profiles"] = [{**p, "start": list(p["start"]), "end": list(p["end"])}
                     for p in d["profiles"]]
    for key in ("directions", "selection", "sets"):  # written only when known: older versions
        if d[key] is None:                   # read the rest
            d.pop(key)
    if "selection" in d:
        d["selection"] = {k: list(v) if isinstance(v, tuple) else v
                          for k, v in d["selection"].items()}
    measures = d.pop("measures")
    if measures:  # written only when there are some: older versions read the rest
        d["measures"] = [{**m, "start": list(m["start"]), "end": list(m["end"])}
                         for m in measures]
    if d["camera"] is not None:
        d["camera"] = {k: list(v) if isinstance(v, tuple) else v for k, v in d["camera"].items()}
    crop = d.pop("crop")
    if crop is not None:
        d["crop"] = {"min": list(crop["lo"]), "max": list(crop["hi"]), "mode": crop["mode"]}
    return d


# ----------------------------------------------------------------------------- the file's types

# The file's layout as typed structures: msgspec checks every type, choice, range,
# length and pattern, refuses unknown keys and fills defaults (a key left out reads
# as its default). What a type cannot say is checked by hand in the readers below,
# each for its reason: bounds that depend on another field (a colour range's limits
# on its mode, log scales above 0), relations between fields (a range rises, a line
# or a camera is not a point, a crop box's minimum is below its maximum, a unit
# quaternion, panel names listed once), the wavelet names (PyWavelets' own list, known
# only once it is imported) and the format's name and version (a newer version gets
# its own hint). Every object refuses unknown keys (forbid_unknown_fields).

_NO_NUL = "^[^\x00]*$"
#: The message of each pattern the file's strings must match.
_PATTERN_MESSAGES = {
    _NO_NUL: "must be a string without NUL characters",
    "^[0-9a-f]{64}$": "must be 64 lower-case hex digits",
    "^[a-z][a-z0-9_-]{0,39}$": "must be a short lower-case name (a-z, 0-9, _ or -)",
}


_Text = Annotated[str, Meta(max_length=200, pattern=_NO_NUL)]
_Path = Annotated[str, Meta(min_length=1, max_length=MAX_PATH_CHARS, pattern=_NO_NUL)]
_Count = Annotated[int, Meta(ge=1, le=10**9)]
_Panel = Annotated[str, Meta(pattern="^[a-z][a-z0-9_-]{0,39}$")]
_Bound = Annotated[float, Meta(ge=0.0, le=1e6)]
_UpPart = Annotated[float, Meta(ge=-1e6, le=1e6)]
_Coord = Annotated[float, Meta(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
_Point = tuple[_Coord, _Coord, _Coord]


class _InputFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    path: _Path
    sha256: Annotated[str, Meta(pattern="^[0-9a-f]{64}$")]
    size_bytes: Annotated[int, Meta(ge=0, le=2**63 - 1)]
    relative_path: Annotated[str, Meta(max_length=MAX_PATH_CHARS, pattern=_NO_NUL)] | None = (
        None)


class _GridFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    cell_size_m: Annotated[float, Meta(gt=0.0, le=1e6)]
    min_points: Annotated[int, Meta(ge=3, le=10**9)]
    axis: AxisChoice = "auto"


class _ColourFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    colormap: ColormapName = "viridis"
    mode: ColourMode = "continuous"
    stretch: StretchMode = ROUGHNESS_STRETCH.mode
    range: tuple[_Bound, _Bound] = (ROUGHNESS_STRETCH.lo, ROUGHNESS_STRETCH.hi)
    log: bool = ROUGHNESS_STRETCH.log
    layer: ColourLayerName = "roughness"


class _ProfileFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    start: _Point
    end: _Point
    band_half_width_m: Annotated[float, Meta(gt=0.0, le=1e4)] | None = None
    wavelet: str = "db3"
    level: Annotated[int, Meta(ge=1, le=12)] = 3
    decomposition: Decomposition = "dwt"
    threshold_rule: ThresholdRule = "fixed"
    mode: Mode = "hard"
    detrend: Annotated[int, Meta(ge=0, le=5)] | None = None


class _ZonesFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    map: MapName = "odr"
    connectivity: Connectivity = "vertex"
    min_cells: _Count = 3
    selected: _Count | None = None
    threshold_rule: ZoneThresholdRule = "slider"  # views saved before the rule: "slider"


class _CameraFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    position: _Point
    look_at: _Point
    up: tuple[_UpPart, _UpPart, _UpPart] = (0.0, 0.0, 1.0)
    fov_deg: Annotated[float, Meta(gt=0.0, le=180.0)] = 50.0


class _CropFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    min: _Point
    max: _Point
    mode: CropMode = "keep"


class _MeasureFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    start: _Point
    end: _Point
    number: _Count = 1


class _DirectionsFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    step_deg: Annotated[float, Meta(ge=1.0, le=90.0)] = 15.0
    spacing_m: Annotated[float, Meta(gt=0.0, le=1e6)] | None = None
    tin: bool = False
    lines: bool = True
    measured: bool = False


_Unit = Annotated[float, Meta(ge=-1.0, le=1.0)]
_Corner = Annotated[float, Meta(ge=-1.0, le=2.0)]


class _SelectionFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    position: _Point
    wxyz: tuple[_Unit, _Unit, _Unit, _Unit]
    fov_rad: Annotated[float, Meta(gt=0.0, le=3.1)]
    aspect: Annotated[float, Meta(gt=0.0, le=100.0)]
    height_px: Annotated[int, Meta(ge=1, le=100_000)]
    corner_a: tuple[_Corner, _Corner]
    corner_b: tuple[_Corner, _Corner]


def _within(bounds: tuple[float, float]) -> Meta:
    return Meta(ge=bounds[0], le=bounds[1])


_SetPct = Annotated[float, _within(SET_ROUGHNESS_PCT_RANGE)]
_SetCone = Annotated[float, _within(SET_CONE_DEG_RANGE)]
_SetAngle = Annotated[float, _within(SET_MIN_ANGLE_DEG_RANGE)]
_SetCount = Annotated[int, _within(SET_MAX_SETS_RANGE)]


class _SetsFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    shown: bool = False
    colour_by: SetColourBy = "set"
    poles: SetPoles = "cell"
    roughness_pct: _SetPct = 100.0 * DEFAULT_PLANAR_SHARE
    cone_deg: _SetCone = DEFAULT_CONE_DEG
    min_angle_deg: _SetAngle = DEFAULT_MIN_ANGLE_DEG
    max_sets: _SetCount = DEFAULT_MAX_SETS
    selected_set: Annotated[int, Meta(ge=1, le=SET_MAX_SETS_RANGE[1])] | None = None
    selected_joint: Annotated[int, Meta(ge=1, le=MAX_JOINT_ID)] | None = None


class _ViewFile(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    format: str
    version: Annotated[int, Meta(ge=1, le=10**6)]
    input: _InputFile
    grid: _GridFile
    software: _Text = ""
    saved_utc: Annotated[str, Meta(max_length=40, pattern=_NO_NUL)] = ""
    units: Unit = "m"
    model: MapName = "odr"
    threshold: Annotated[float, Meta(ge=0.0, le=1.0)] = 0.05
    colour: _ColourFile = _ColourFile()
    panels: Annotated[list[_Panel], Meta(max_length=MAX_PANELS)] = []
    profiles: Annotated[list[_ProfileFile], Meta(max_length=MAX_PROFILES)] = []
    zones: _ZonesFile | None = None
    camera: _CameraFile | None = None
    crop: _CropFile | None = None
    measures: Annotated[list[_MeasureFile], Meta(max_length=MAX_MEASURES)] = []
    directions: _DirectionsFile | None = None
    selection: _SelectionFile | None = None
    sets: _SetsFile | None = None


# ----------------------------------------------------------------------------- errors

_COUNT_WORDS = {2: "two", 3: "three", 4: "four"}
_LIST_HINTS = {"colour.range": " [low, high]"}
_AT = re.compile(r"^(?P<what>.*?)(?: - at `\$(?P<path>[^`]*)`)?$", re.S)
_STEP = re.compile(r"\.([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]")


def _kind(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "true/false",
            type(None): "null"}.get(type(value), type(value).__name__)


def _walk(data: Any, info: Any, path: str) -> tuple[Any, Any, tuple[Any, ...]]:
    """The JSON value, the msgspec type information and the declared choices (in the
    order written; msgspec's information sorts them) at ``path`` (``.a[0].b``); the
    value is ``None`` where the document has none there."""
    value, choices = data, ()
    for name, index in _STEP.findall(path):
        info = _unwrap(info)
        if name:
            value = value.get(name) if isinstance(value, dict) else None
            field_ = next(f for f in info.fields if f.encode_name == name)
            hint = get_type_hints(info.cls)[field_.name]
            choices = next((get_args(a) for a in (hint, *get_args(hint))
                            if get_origin(a) is Literal), ())
            info = field_.type
        else:
            i = int(index)
            value = value[i] if isinstance(value, list) and i < len(value) else None
            info = info.item_types[i] if isinstance(info, mi.TupleType) else info.item_type
            choices = ()
    return value, _unwrap(info), choices


def _unwrap(info: Any) -> Any:
    """``T`` of ``T | None``."""
    if isinstance(info, mi.UnionType):
        return next(t for t in info.types if not isinstance(t, mi.NoneType))
    return info


def _bounds(info: mi.FloatType | mi.IntType) -> str:
    lo = info.gt if info.gt is not None else info.ge
    if isinstance(info, mi.IntType):
        return f"[{lo}, {info.le}]"
    return f"({lo:g}, {info.le:g}]" if info.gt is not None else f"[{lo:g}, {info.le:g}]"


def _complaint(info: Any, value: Any, choices: tuple[Any, ...], hint: str = "") -> str:
    """What is wrong with ``value`` for a field of type ``info`` (a Literal of
    ``choices``), in the file's words (``hint`` follows a list's length)."""
    number = isinstance(value, int | float) and not isinstance(value, bool)
    if isinstance(info, mi.LiteralType):
        return f"must be one of {', '.join(map(str, choices))}, got {repr(value)[:40]}"
    if isinstance(info, mi.FloatType):
        return f"must lie in {_bounds(info)}, got {value!r}" if number else \
            f"must be a number, got {_kind(value)}"
    if isinstance(info, mi.IntType):
        return f"must lie in {_bounds(info)}, got {value}" if isinstance(value, int) and \
            number else f"must be a whole number, got {_kind(value)}"
    if isinstance(info, mi.BoolType):
        return f"must be true or false, got {_kind(value)}"
    if isinstance(info, mi.StrType):
        if not isinstance(value, str):
            return f"must be a string, got {_kind(value)}"
        if info.min_length and len(value) < info.min_length:
            return "must not be empty"
        if info.max_length is not None and len(value) > info.max_length:
            return f"must be a string of at most {info.max_length} characters"
        return _PATTERN_MESSAGES.get(info.pattern or "", "is not an allowed string")
    if isinstance(info, mi.TupleType):
        return f"must be a list of {_COUNT_WORDS[len(info.item_types)]} numbers{hint}"
    if isinstance(info, mi.ListType):
        if isinstance(value, list):
            return f"has {len(value)} entries, at most {info.max_length} allowed"
        return f"must be a list, got {_kind(value)}"
    return f"must be an object, got {_kind(value)}"


def _explain(error: msgspec.ValidationError, data: Any) -> tuple[str, str]:
    """Where and what of msgspec's error, as the field's name and one clause."""
    match = _AT.match(str(error))
    assert match is not None  # the pattern matches every string
    what, path = match["what"], match["path"] or ""
    where = path.lstrip(".") or "the file"
    key = re.fullmatch(r"Object (contains unknown|missing required) field `(.*)`", what)
    if key:
        clause = "has an unknown key" if key[1] == "contains unknown" else "lacks"
        return where, f"{clause} {key[2]!r}"
    value, info, choices = _walk(data, mi.type_info(_ViewFile), path)
    return where, _complaint(info, value, choices, _LIST_HINTS.get(where, ""))


# ----------------------------------------------------------------------------- readers


class _Checks:
    """The hand-written checks (see the file's types for why each is by hand), naming
    the file and the field in errors."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, what: str) -> InputError:
        return InputError(f"view file {self.source}: {where} {what}")

    def line(self, start: Vec3, end: Vec3, where: str) -> None:
        if start == end:
            raise self.fail(where, "has the same start and end")


def view_from_dict(data: Any, *, source: str = "(in memory)") -> dict[str, Any]:
    """Validate the parsed JSON of a view file.

    Returns
    -------
    dict
        ``view`` (:class:`View`), ``relative_path`` (str or None), ``software`` and
        ``saved_utc`` (str).

    Raises
    ------
    InputError
        One line naming the file and the field: wrong type, out of range, unknown
        choice or key, another format or a newer version.
    """
    r = _Checks(source)
    try:
        f = msgspec.convert(data, _ViewFile)
    except msgspec.ValidationError as exc:
        raise r.fail(*_explain(exc, data)) from None
    if f.format != VIEW_FORMAT:
        raise r.fail("format", f"must be {VIEW_FORMAT!r} (not a rough_viewer view?)")
    if f.version > VIEW_VERSION:
        raise r.fail("version", f"is {f.version}: made by a newer rough_viewer; this one reads "
                     f"version {VIEW_VERSION}")
    if len(set(f.panels)) != len(f.panels):
        raise r.fail("panels", "lists a panel twice")
    view = View(
        input=InputRef(path=f.input.path, sha256=f.input.sha256,
                       size_bytes=f.input.size_bytes),
        cell_size_m=f.grid.cell_size_m, min_points=f.grid.min_points, axis=f.grid.axis,
        model=f.model, units=f.units, threshold=f.threshold, colour=_colour(r, f.colour),
        panels=tuple(f.panels),
        directions=None if f.directions is None else DirectionsView(
            **msgspec.structs.asdict(f.directions)),
        selection=None if f.selection is None else _selection(r, f.selection),
        sets=None if f.sets is None else SetsView(**msgspec.structs.asdict(f.sets)),
        measures=tuple(_measure(r, m, f"measures[{i}]") for i, m in enumerate(f.measures)),
        profiles=tuple(_profile(r, p, f"profiles[{i}]") for i, p in enumerate(f.profiles)),
        zones=None if f.zones is None else ZoneSettings(**msgspec.structs.asdict(f.zones)),
        camera=None if f.camera is None else _camera(r, f.camera),
        crop=None if f.crop is None else _crop(r, f.crop),
    )
    return {"view": view, "relative_path": f.input.relative_path, "software": f.software,
            "saved_utc": f.saved_utc}


def _colour(r: _Checks, c: _ColourFile) -> ColourSettings:
    lo, hi = c.range
    if c.stretch == "percentile":  # the limits' bounds depend on the mode
        for i, v in enumerate(c.range):
            if v > 100.0:
                raise r.fail(f"colour.range[{i}]", f"must lie in [0, 100], got {v:g}")
    if not lo < hi:
        raise r.fail("colour.range", f"must rise (low < high), got [{lo:g}, {hi:g}]")
    if c.log and c.stretch == "absolute" and lo <= 0.0:
        raise r.fail("colour.range", "must start above 0 for a logarithmic absolute scale")
    try:
        stretch = Stretch(c.stretch, lo, hi, log=c.log)
    except InputError as exc:
        raise r.fail("colour.range", str(exc)) from None
    return ColourSettings(colormap=c.colormap, mode=c.mode, stretch=stretch, layer=c.layer)


def _selection(r: _Checks, s: _SelectionFile) -> SelectionView:
    if not 0.5 < sum(q * q for q in s.wxyz) < 1.5:
        raise r.fail("selection.wxyz", "must be a unit quaternion")
    return SelectionView(**msgspec.structs.asdict(s))


def _measure(r: _Checks, m: _MeasureFile, where: str) -> MeasurePick:
    r.line(m.start, m.end, where)
    return MeasurePick(start=m.start, end=m.end, number=m.number)


def _profile(r: _Checks, p: _ProfileFile, where: str) -> ProfilePick:
    import pywt

    r.line(p.start, p.end, where)
    wavelets = pywt.wavelist(kind="discrete")
    if p.wavelet not in wavelets:
        raise r.fail(f"{where}.wavelet", f"must be one of {', '.join(wavelets)}, got "
                     f"{repr(p.wavelet)[:40]}")
    return ProfilePick(**msgspec.structs.asdict(p))


def _camera(r: _Checks, c: _CameraFile) -> Camera:
    if c.up == (0.0, 0.0, 0.0):
        raise r.fail("camera.up", "must not be zero")
    if c.position == c.look_at:
        raise r.fail("camera", "looks at its own position")
    return Camera(**msgspec.structs.asdict(c))


def _crop(r: _Checks, c: _CropFile) -> CropBox:
    for axis, a, b in zip("xyz", c.min, c.max, strict=True):
        if a > b:
            raise r.fail("crop", f"has its {axis} minimum {a:g} above its maximum {b:g}")
    return CropBox(c.min, c.max, c.mode)


# ----------------------------------------------------------------------------- files


def view_text(view: View, *, folder: str | os.PathLike[str] | None = None) -> str:
    """The JSON text of a view file (validated first).

    ``folder`` is where the file will be kept: the input's path relative to it is
    stored too, so a folder moved whole still finds its scan. None (a view sent to a
    browser, whose folder is unknown): no relative path.
    """
    check_view(view)
    data = view_to_dict(view)
    relative: str | None = None
    if folder is not None:
        try:
            relative = os.path.relpath(Path(view.input.path).resolve(), Path(folder).resolve())
        except ValueError:  # another drive on Windows
            relative = None
    data["input"]["relative_path"] = relative
    doc = {"format": VIEW_FORMAT, "version": VIEW_VERSION, "software": f"rough_viewer {__version__}",
           "saved_utc": _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat(), **data}
    return json.dumps(doc, indent=2, allow_nan=False) + "\n"


def save_view(path: str | os.PathLike[str], view: View, *, force: bool = False) -> Path:
    """Write a view file atomically (nothing overwritten without ``force``; never the
    input itself). The input's path is also stored relative to the view file, so a
    folder moved whole still finds its scan.

    Returns
    -------
    Path
        ``path``.
    """
    check_view(view)
    p = check_output_path(path, force=force, inputs=[view.input.path])
    text = view_text(view, folder=p.parent)
    write_atomic(p, lambda fh: fh.write(text))
    return p


def _no_constants(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


#: Digits of the longest integer a view holds (a byte count, a seed): 400 digits
#: overflowed the float conversions with a traceback.
MAX_INT_DIGITS = 20


def _bounded_int(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_INT_DIGITS:
        raise ValueError(f"an integer of {digits} digits; no field of a view has more than "
                         f"{MAX_INT_DIGITS}")
    return int(text)


def load_view(path: str | os.PathLike[str], *, check: bool = True,
              data_folder: str | os.PathLike[str] | None = None,
              progress: ProgressFn | None = None) -> LoadedView:
    """Read and validate a view file, and check its input.

    Parameters
    ----------
    path : path-like
        The ``.json`` view file (untrusted: at most :data:`MAX_VIEW_BYTES`, every field
        checked).
    check : bool
        Check the input (its size, then its content hash, read in blocks); False gives
        ``status="not_checked"``.
    data_folder : path-like, optional
        Where an input named by a relative path (a view downloaded from the app) is
        looked for; default the view file's folder.
    progress : callable, optional
        ``progress(done, total)`` in bytes while hashing the input.

    Raises
    ------
    InputError
        One line naming the file and the problem.
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        if not p.is_file():
            raise InputError(f"view file is not a regular file: {p}")
        if size > MAX_VIEW_BYTES:
            raise InputError(f"view file {p} is {size:,} bytes; a view is at most "
                             f"{MAX_VIEW_BYTES:,}")
        with open(p, "rb") as fh:
            raw = fh.read(MAX_VIEW_BYTES + 1)
    except FileNotFoundError:
        raise InputError(f"view file not found: {p}") from None
    except OSError as exc:
        raise InputError(f"cannot read view file {p}: {exc.strerror or exc}") from None
    try:
        data = json.loads(raw.decode("utf-8"), parse_constant=_no_constants,
                          parse_int=_bounded_int)
    except (UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"view file {p} is not valid JSON: {error_line(exc)}") from None
    except RecursionError:
        raise InputError(f"view file {p} is nested too deeply to be a view") from None
    parsed = view_from_dict(data, source=str(p))
    view: View = parsed["view"]
    if check:
        input_check = check_input(view.input, view_folder=p.parent,
                                  relative_path=parsed["relative_path"],
                                  data_folder=data_folder, progress=progress)
    else:
        input_check = InputCheck("not_checked", Path(view.input.path), "input not checked")
    return LoadedView(view=view, input_check=input_check, software=parsed["software"],
                      saved_utc=parsed["saved_utc"])
