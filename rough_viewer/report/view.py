"""Saved views: a small JSON file that reopens the same picture next week.

A view records the input (path, size and SHA-256 of its content), the grid (cell
size, minimum points, dependent axis), the map shown, the units of the input, the
binary threshold, the colour settings, the open panels, the picked profiles, the
zone settings and the camera. :func:`save_view` writes one atomically;
:func:`load_view` reads one back, validating every field (a view file is untrusted
input: types, ranges and choices are checked, unknown keys refused, size bounded),
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
import math
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, TypeVar

from rough_viewer._version import __version__
from rough_viewer.io.crop import CROP_MODES, CropBox
from rough_viewer.io.output import check_output_path, write_atomic
from rough_viewer.structure.sets import (
    DEFAULT_CONE_DEG,
    DEFAULT_MAX_SETS,
    DEFAULT_MIN_ANGLE_DEG,
    DEFAULT_PLANAR_SHARE,
)
from rough_viewer.visual.colormaps import COLORMAP_NAMES, ROUGHNESS_STRETCH, STRETCH_MODES, Stretch
from rough_viewer.vocabulary import (
    AXIS_CHOICES,
    COLOUR_LAYERS,
    DECOMPOSITIONS,
    MAPS,
    MODES,
    THRESHOLD_RULES,
    UNITS,
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

_PANEL_NAME = re.compile(r"[a-z][a-z0-9_-]{0,39}")
_SHA256 = re.compile(r"[0-9a-f]{64}")

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


def check_view(view: View) -> View:
    """The view, validated like one read from a file (InputError names the field)."""
    parsed = view_from_dict({"format": VIEW_FORMAT, "version": VIEW_VERSION,
                             **view_to_dict(view)})
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


class _Reader:
    """Checks one untrusted JSON value after another, naming the field in errors."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, where: str, what: str) -> InputError:
        return InputError(f"view file {self.source}: {where} {what}")

    def obj(self, value: Any, where: str, required: Sequence[str],
            optional: Sequence[str] = ()) -> Mapping[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(where, f"must be an object, got {_kind(value)}")
        unknown = sorted(set(value) - set(required) - set(optional))
        if unknown:
            raise self.fail(where, f"has an unknown key {unknown[0]!r}")
        missing = [k for k in required if k not in value]
        if missing:
            raise self.fail(where, f"lacks {missing[0]!r}")
        return value

    def number(self, value: Any, where: str, lo: float, hi: float, *,
               lo_open: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(where, f"must be a number, got {_kind(value)}")
        v = float(value)
        if not math.isfinite(v) or v > hi or v < lo or (lo_open and v == lo):
            bound = f"({lo:g}, {hi:g}]" if lo_open else f"[{lo:g}, {hi:g}]"
            raise self.fail(where, f"must lie in {bound}, got {value!r}")
        return v

    def integer(self, value: Any, where: str, lo: int, hi: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(where, f"must be a whole number, got {_kind(value)}")
        if not lo <= value <= hi:
            raise self.fail(where, f"must lie in [{lo}, {hi}], got {value}")
        return int(value)

    def boolean(self, value: Any, where: str) -> bool:
        if not isinstance(value, bool):
            raise self.fail(where, f"must be true or false, got {_kind(value)}")
        return value

    def string(self, value: Any, where: str, max_chars: int = 200) -> str:
        if not isinstance(value, str):
            raise self.fail(where, f"must be a string, got {_kind(value)}")
        if len(value) > max_chars or "\x00" in value:
            raise self.fail(where, f"must be a string of at most {max_chars} characters")
        return value

    def choice(self, value: Any, where: str, choices: Sequence[str]) -> Any:
        if not isinstance(value, str) or value not in choices:
            shown = repr(value)[:40]
            raise self.fail(where, f"must be one of {', '.join(choices)}, got {shown}")
        return value

    def vec3(self, value: Any, where: str, limit: float = MAX_COORDINATE) -> Vec3:
        if not isinstance(value, list) or len(value) != 3:
            raise self.fail(where, "must be a list of three numbers")
        x, y, z = (self.number(v, f"{where}[{i}]", -limit, limit) for i, v in enumerate(value))
        return (x, y, z)

    def items(self, value: Any, where: str, max_items: int) -> list[Any]:
        if not isinstance(value, list):
            raise self.fail(where, f"must be a list, got {_kind(value)}")
        if len(value) > max_items:
            raise self.fail(where, f"has {len(value)} entries, at most {max_items} allowed")
        return value


def _kind(value: Any) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "true/false",
            type(None): "null"}.get(type(value), type(value).__name__)


T = TypeVar("T")


def _optional(value: Any, parse: Callable[[Any], T]) -> T | None:
    return None if value is None else parse(value)


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
    r = _Reader(source)
    top = r.obj(data, "the file", ["format", "version", "input", "grid"],
                ["software", "saved_utc", "units", "model", "threshold", "colour", "panels",
                 "profiles", "zones", "camera", "crop", "measures", "directions",
                 "selection", "sets"])
    if top["format"] != VIEW_FORMAT:
        raise r.fail("format", f"must be {VIEW_FORMAT!r} (not a rough_viewer view?)")
    version = r.integer(top["version"], "version", 1, 10**6)
    if version > VIEW_VERSION:
        raise r.fail("version", f"is {version}: made by a newer rough_viewer; this one reads "
                     f"version {VIEW_VERSION}")
    inp = r.obj(top["input"], "input", ["path", "sha256", "size_bytes"], ["relative_path"])
    path = r.string(inp["path"], "input.path", MAX_PATH_CHARS)
    if not path:
        raise r.fail("input.path", "must not be empty")
    sha = r.string(inp["sha256"], "input.sha256", 64)
    if not _SHA256.fullmatch(sha):
        raise r.fail("input.sha256", "must be 64 lower-case hex digits")
    ref = InputRef(path=path, sha256=sha,
                   size_bytes=r.integer(inp["size_bytes"], "input.size_bytes", 0, 2**63 - 1))
    relative = _optional(inp.get("relative_path"),
                         lambda v: r.string(v, "input.relative_path", MAX_PATH_CHARS))
    grid = r.obj(top["grid"], "grid", ["cell_size_m", "min_points"], ["axis"])
    colour = _colour(r, top.get("colour", {}))
    panels = tuple(r.string(p, f"panels[{i}]", 40)
                   for i, p in enumerate(r.items(top.get("panels", []), "panels", MAX_PANELS)))
    for i, name in enumerate(panels):
        if not _PANEL_NAME.fullmatch(name):
            raise r.fail(f"panels[{i}]", "must be a short lower-case name (a-z, 0-9, _ or -)")
    if len(set(panels)) != len(panels):
        raise r.fail("panels", "lists a panel twice")
    view = View(
        input=ref,
        cell_size_m=r.number(grid["cell_size_m"], "grid.cell_size_m", 0.0, 1e6, lo_open=True),
        min_points=r.integer(grid["min_points"], "grid.min_points", 3, 10**9),
        axis=r.choice(grid.get("axis", "auto"), "grid.axis", AXIS_CHOICES),
        model=r.choice(top.get("model", "odr"), "model", MAPS),
        units=r.choice(top.get("units", "m"), "units", UNITS),
        threshold=r.number(top.get("threshold", 0.05), "threshold", 0.0, 1.0),
        colour=colour,
        panels=panels,
        directions=_optional(top.get("directions"), lambda v: _directions(r, v)),
        selection=_optional(top.get("selection"), lambda v: _selection(r, v)),
        sets=_optional(top.get("sets"), lambda v: _sets(r, v)),
        measures=tuple(_measure(r, m, f"measures[{i}]") for i, m in
                       enumerate(r.items(top.get("measures", []), "measures", MAX_MEASURES))),
        profiles=tuple(_profile(r, p, f"profiles[{i}]") for i, p in
                       enumerate(r.items(top.get("profiles", []), "profiles", MAX_PROFILES))),
        zones=_optional(top.get("zones"), lambda v: _zones(r, v)),
        camera=_optional(top.get("camera"), lambda v: _camera(r, v)),
        crop=_optional(top.get("crop"), lambda v: _crop(r, v)),
    )
    return {
        "view": view,
        "relative_path": relative,
        "software": r.string(top.get("software", ""), "software"),
        "saved_utc": r.string(top.get("saved_utc", ""), "saved_utc", 40),
    }


def _colour(r: _Reader, value: Any) -> ColourSettings:
    c = r.obj(value, "colour", [], ["colormap", "mode", "stretch", "range", "log", "layer"])
    default = ColourSettings()
    mode = r.choice(c.get("stretch", default.stretch.mode), "colour.stretch", STRETCH_MODES)
    bounds = {"percentile": (0.0, 100.0), "absolute": (0.0, 1e6)}[mode]
    raw = c.get("range", [default.stretch.lo, default.stretch.hi])
    if not isinstance(raw, list) or len(raw) != 2:
        raise r.fail("colour.range", "must be a list of two numbers [low, high]")
    lo = r.number(raw[0], "colour.range[0]", *bounds)
    hi = r.number(raw[1], "colour.range[1]", *bounds)
    if not lo < hi:
        raise r.fail("colour.range", f"must rise (low < high), got [{lo:g}, {hi:g}]")
    log = r.boolean(c.get("log", default.stretch.log), "colour.log")
    if log and mode == "absolute" and lo <= 0.0:
        raise r.fail("colour.range", "must start above 0 for a logarithmic absolute scale")
    try:
        stretch = Stretch(mode, lo, hi, log=log)
    except InputError as exc:
        raise r.fail("colour.range", str(exc)) from None
    return ColourSettings(
        colormap=r.choice(c.get("colormap", default.colormap), "colour.colormap", COLORMAP_NAMES),
        mode=r.choice(c.get("mode", default.mode), "colour.mode", COLOUR_MODES),
        stretch=stretch,
        layer=r.choice(c.get("layer", default.layer), "colour.layer", COLOUR_LAYERS))


def _directions(r: _Reader, value: Any) -> DirectionsView:
    d = r.obj(value, "directions", [], ["step_deg", "spacing_m", "tin", "lines", "measured"])
    default = DirectionsView()
    return DirectionsView(
        step_deg=r.number(d.get("step_deg", default.step_deg), "directions.step_deg", 1.0, 90.0),
        spacing_m=_optional(d.get("spacing_m"), lambda v: r.number(
            v, "directions.spacing_m", 0.0, 1e6, lo_open=True)),
        tin=r.boolean(d.get("tin", default.tin), "directions.tin"),
        lines=r.boolean(d.get("lines", default.lines), "directions.lines"),
        measured=r.boolean(d.get("measured", default.measured), "directions.measured"))


def _sets(r: _Reader, value: Any) -> SetsView:
    keys = ["shown", "colour_by", "poles", "roughness_pct", "cone_deg", "min_angle_deg",
            "max_sets", "selected_set", "selected_joint"]
    d = r.obj(value, "sets", [], keys)
    default = SetsView()
    return SetsView(
        shown=r.boolean(d.get("shown", default.shown), "sets.shown"),
        colour_by=r.choice(d.get("colour_by", default.colour_by), "sets.colour_by",
                           SET_COLOUR_BY),
        poles=r.choice(d.get("poles", default.poles), "sets.poles", SET_POLES),
        roughness_pct=r.number(d.get("roughness_pct", default.roughness_pct),
                               "sets.roughness_pct", *SET_ROUGHNESS_PCT_RANGE),
        cone_deg=r.number(d.get("cone_deg", default.cone_deg), "sets.cone_deg",
                          *SET_CONE_DEG_RANGE),
        min_angle_deg=r.number(d.get("min_angle_deg", default.min_angle_deg),
                               "sets.min_angle_deg", *SET_MIN_ANGLE_DEG_RANGE),
        max_sets=r.integer(d.get("max_sets", default.max_sets), "sets.max_sets",
                           *SET_MAX_SETS_RANGE),
        selected_set=_optional(d.get("selected_set"), lambda v: r.integer(
            v, "sets.selected_set", 1, SET_MAX_SETS_RANGE[1])),
        selected_joint=_optional(d.get("selected_joint"), lambda v: r.integer(
            v, "sets.selected_joint", 1, MAX_JOINT_ID)))


def _selection(r: _Reader, value: Any) -> SelectionView:
    s = r.obj(value, "selection", ["position", "wxyz", "fov_rad", "aspect", "height_px",
                                   "corner_a", "corner_b"])
    q = s["wxyz"]
    if not isinstance(q, list) or len(q) != 4:
        raise r.fail("selection.wxyz", "must be a list of four numbers")
    w, x, y, z = (r.number(v, f"selection.wxyz[{i}]", -1.0, 1.0) for i, v in enumerate(q))
    if not 0.5 < w * w + x * x + y * y + z * z < 1.5:
        raise r.fail("selection.wxyz", "must be a unit quaternion")

    def corner(key: str) -> tuple[float, float]:
        c = s[key]
        if not isinstance(c, list) or len(c) != 2:
            raise r.fail(f"selection.{key}", "must be a list of two numbers")
        return (r.number(c[0], f"selection.{key}[0]", -1.0, 2.0),
                r.number(c[1], f"selection.{key}[1]", -1.0, 2.0))

    return SelectionView(
        position=r.vec3(s["position"], "selection.position"), wxyz=(w, x, y, z),
        fov_rad=r.number(s["fov_rad"], "selection.fov_rad", 0.0, 3.1, lo_open=True),
        aspect=r.number(s["aspect"], "selection.aspect", 0.0, 100.0, lo_open=True),
        height_px=r.integer(s["height_px"], "selection.height_px", 1, 100_000),
        corner_a=corner("corner_a"), corner_b=corner("corner_b"))


def _measure(r: _Reader, value: Any, where: str) -> MeasurePick:
    m = r.obj(value, where, ["start", "end"], ["number"])
    start, end = r.vec3(m["start"], f"{where}.start"), r.vec3(m["end"], f"{where}.end")
    if start == end:
        raise r.fail(where, "has the same start and end")
    return MeasurePick(start=start, end=end,
                       number=r.integer(m.get("number", 1), f"{where}.number", 1, 10**9))


def _profile(r: _Reader, value: Any, where: str) -> ProfilePick:
    import pywt

    p = r.obj(value, where, ["start", "end"], ["band_half_width_m", "wavelet", "level",
                                               "decomposition", "threshold_rule", "mode",
                                               "detrend"])
    start, end = r.vec3(p["start"], f"{where}.start"), r.vec3(p["end"], f"{where}.end")
    if start == end:
        raise r.fail(where, "has the same start and end")
    default = ProfilePick(start=start, end=end)
    return ProfilePick(
        start=start, end=end,
        band_half_width_m=_optional(p.get("band_half_width_m"), lambda v: r.number(
            v, f"{where}.band_half_width_m", 0.0, 1e4, lo_open=True)),
        wavelet=r.choice(p.get("wavelet", default.wavelet), f"{where}.wavelet",
                         pywt.wavelist(kind="discrete")),
        level=r.integer(p.get("level", default.level), f"{where}.level", 1, 12),
        decomposition=r.choice(p.get("decomposition", default.decomposition),
                               f"{where}.decomposition", DECOMPOSITIONS),
        threshold_rule=r.choice(p.get("threshold_rule", default.threshold_rule),
                                f"{where}.threshold_rule", THRESHOLD_RULES),
        mode=r.choice(p.get("mode", default.mode), f"{where}.mode", MODES),
        detrend=_optional(p.get("detrend"), lambda v: r.integer(v, f"{where}.detrend", 0, 5)),
    )


def _zones(r: _Reader, value: Any) -> ZoneSettings:
    z = r.obj(value, "zones", [], ["map", "connectivity", "min_cells", "selected",
                                   "threshold_rule"])
    default = ZoneSettings()
    return ZoneSettings(
        map=r.choice(z.get("map", default.map), "zones.map", MAPS),
        connectivity=r.choice(z.get("connectivity", default.connectivity), "zones.connectivity",
                              CONNECTIVITIES),
        min_cells=r.integer(z.get("min_cells", default.min_cells), "zones.min_cells", 1, 10**9),
        selected=_optional(z.get("selected"),
                           lambda v: r.integer(v, "zones.selected", 1, 10**9)),
        threshold_rule=r.choice(z.get("threshold_rule", "slider"), "zones.threshold_rule",
                                ZONE_THRESHOLD_RULES),
    )


def _camera(r: _Reader, value: Any) -> Camera:
    c = r.obj(value, "camera", ["position", "look_at"], ["up", "fov_deg"])
    up = r.vec3(c.get("up", [0.0, 0.0, 1.0]), "camera.up", 1e6)
    if up == (0.0, 0.0, 0.0):
        raise r.fail("camera.up", "must not be zero")
    position, look_at = r.vec3(c["position"], "camera.position"), r.vec3(c["look_at"],
                                                                          "camera.look_at")
    if position == look_at:
        raise r.fail("camera", "looks at its own position")
    return Camera(position=position, look_at=look_at, up=up,
                  fov_deg=r.number(c.get("fov_deg", 50.0), "camera.fov_deg", 0.0, 180.0,
                                   lo_open=True))


def _crop(r: _Reader, value: Any) -> CropBox:
    c = r.obj(value, "crop", ["min", "max"], ["mode"])
    lo, hi = r.vec3(c["min"], "crop.min"), r.vec3(c["max"], "crop.max")
    for axis, a, b in zip("xyz", lo, hi, strict=True):
        if a > b:
            raise r.fail("crop", f"has its {axis} minimum {a:g} above its maximum {b:g}")
    return CropBox(lo, hi, r.choice(c.get("mode", "keep"), "crop.mode", CROP_MODES))


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
