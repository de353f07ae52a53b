"""Lessons as data: guided steps through the app, one TOML file each (docs/lessons.md).

A lesson has a title, an introduction and steps; each step a text, a scene (which
cloud: a demo, the 2012 board at a rotation, or the one shown; the map's model,
grid, axis, threshold and minimum points; a camera preset) and a question whose
answer is computed from the tool's own numbers (:mod:`rough_viewer.lessons.measures`),
with a tolerance and an explanation shown after the check.

The bundled lessons are files of this package (``tilted-board.toml``,
``turned-wall.toml``, ``scale.toml``); teachers write their own in the same format
and open them with ``rough-viewer serve --lesson FILE.toml``.

:func:`load_lesson` reads and checks a file: every problem is one
:class:`~rough_viewer.vocabulary.InputError` line naming the file and the field
(``lesson my.toml: steps[2].question.measure: unknown measure 'avg'; ...``).

>>> [n for n in bundled_names()]
['scale', 'tilted-board', 'turned-wall']
>>> lesson = find_lesson("tilted-board")
>>> lesson.title, len(lesson.steps) >= 4
('The tilted board', True)
"""

from __future__ import annotations

import importlib.resources
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, cast

from rough_viewer.vocabulary import AXIS_CHOICES, MAPS, AxisChoice, InputError, MapName

#: What a question may ask (:func:`rough_viewer.lessons.measures.expected_value`).
MEASURES: dict[str, str] = {
    "mean": "the mean roughness of `model` over the map's cells with a value (Table 1)",
    "median": "the median roughness of `model` over the map's cells with a value",
    "ratio": "the median over the cells of the ratio of the two models of `of`",
    "point": "the roughness of `model` in the clicked point's cell on the `grid` "
             "preset (finest or coarsest) of the across-scales plot",
    "variogram": "the normalised semivariance of `model` at the first lag (one cell)",
    "points": "the number of points of the cloud shown",
}
Measure = Literal["mean", "median", "ratio", "point", "variogram", "points"]

#: Camera presets a scene may ask for (the Map tab's).
CAMERAS = ("face-on", "top", "side")
#: Grid words a scene may use instead of a size in metres.
GRID_WORDS = ("default", "finest", "coarsest")
#: Face parts of the outcrop demos a scene may cut out (their truth's names).
PARTS = ("main face", "curve", "turned wall")
#: The cloud a scene leaves as it is.
KEEP = "keep"
#: Longest text of a lesson field, characters (a lesson is text for people).
MAX_TEXT = 20_000
#: Most steps of a lesson.
MAX_STEPS = 50


@dataclass(frozen=True)
class Scene:
    """What a step puts on screen; None fields leave the map's setting as it is."""

    cloud: str = KEEP
    """A demo name (``outcrop``, ``outcrop-small``, ``board``) or ``keep``."""
    part: str = ""
    """A face part of an outcrop demo to cut out (:data:`PARTS`; "" the whole)."""
    alpha: float = 0.0
    """Board rotation about the vertical, degrees."""
    beta: float = 0.0
    """Board rotation about its horizontal axis, degrees."""
    model: MapName | None = None
    grid: float | str | None = None
    """Cell edge in metres, or one of :data:`GRID_WORDS` (the cloud's presets)."""
    axis: AxisChoice | None = None
    threshold: float | None = None
    min_points: int | None = None
    camera: str | None = None

    @property
    def cloud_key(self) -> tuple[object, ...] | None:
        """What identifies the cloud (None: keep the one shown)."""
        if self.cloud == KEEP:
            return None
        if self.cloud == "board":
            return ("board", float(self.alpha), float(self.beta))
        return (self.cloud, self.part)

    @property
    def label(self) -> str:
        """How the status line names the cloud."""
        if self.cloud == "board":
            return f"board lesson (α {self.alpha:g}°, β {self.beta:g}°, synthetic)"
        return f"{self.cloud} demo" + (f", {self.part}" if self.part else "")


@dataclass(frozen=True)
class Question:
    """What a step asks and how the answer is checked."""

    text: str
    measure: Measure
    model: MapName = "odr"
    of: tuple[MapName, MapName] = ("ols", "odr")
    """Numerator and denominator of a ``ratio``."""
    grid: str = "coarsest"
    """``point``: the preset of the across-scales plot (``finest`` or ``coarsest``)."""
    tolerance: float = 0.05
    """Largest relative difference accepted (0.05: 5 %)."""
    absolute: float = 0.0
    """Largest absolute difference accepted, in the answer's unit (the larger wins)."""
    explanation: str = ""

    @property
    def dimensionless(self) -> bool:
        """True when the answer has no unit (a ratio, a count)."""
        return self.measure in ("ratio", "variogram", "points")


@dataclass(frozen=True)
class Step:
    title: str
    text: str
    scene: Scene
    question: Question | None


@dataclass(frozen=True)
class Lesson:
    name: str
    """The file's stem (a bundled lesson's name)."""
    title: str
    introduction: str
    steps: tuple[Step, ...]
    source: str
    """The file as messages name it (its name, never the server's folders)."""


# ----------------------------------------------------------------------------- reading


class _Fields:
    """One table of the file being checked: typed getters that name the field."""

    def __init__(self, table: Mapping[str, Any], where: str, path: str) -> None:
        self.table, self.where, self.path = table, where, path

    def fail(self, name: str, problem: str) -> InputError:
        field = f"{self.path}.{name}" if self.path else name
        return InputError(f"lesson {self.where}: {field}: {problem}")

    def only(self, names: tuple[str, ...]) -> None:
        for key in self.table:
            if key not in names:
                raise self.fail(str(key), f"unknown field (expected one of {', '.join(names)})")

    def text(self, name: str, default: str | None = None) -> str:
        v = self.table.get(name, default)
        if v is None:
            raise self.fail(name, "missing")
        if not isinstance(v, str):
            raise self.fail(name, f"must be text, got {type(v).__name__}")
        if len(v) > MAX_TEXT:
            raise self.fail(name, f"longer than {MAX_TEXT:,} characters")
        return v.strip()

    def number(self, name: str, default: float | None = None, *,
               lo: float = -math.inf, hi: float = math.inf) -> float | None:
        v = self.table.get(name, default)
        if v is None:
            return None
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise self.fail(name, f"must be a number, got {v!r}")
        if not lo <= v <= hi:
            raise self.fail(name, f"must be between {lo:g} and {hi:g}, got {v:g}")
        return float(v)

    def choice(self, name: str, options: tuple[str, ...], default: str | None = None
               ) -> str | None:
        v = self.table.get(name, default)
        if v is None:
            return None
        if v not in options:
            raise self.fail(name, f"unknown value {v!r}; choose one of {', '.join(options)}")
        return str(v)

    def table_of(self, name: str) -> _Fields | None:
        v = self.table.get(name)
        if v is None:
            return None
        if not isinstance(v, dict):
            raise self.fail(name, "must be a table")
        return _Fields(v, self.where, f"{self.path}.{name}" if self.path else name)


def _demo_names() -> tuple[str, ...]:
    from rough_viewer.synthetic.demos import list_demos

    return tuple(d.name for d in list_demos())


def _grid(f: _Fields) -> float | str | None:
    v = f.table.get("grid")
    if isinstance(v, str):
        return f.choice("grid", GRID_WORDS)
    return f.number("grid", lo=1e-4, hi=10_000.0)


def _scene(f: _Fields | None) -> Scene:
    if f is None:
        return Scene()
    f.only(("cloud", "part", "alpha", "beta", "model", "grid", "axis", "threshold",
            "min_points", "camera"))
    cloud = f.choice("cloud", (KEEP, *_demo_names()), KEEP) or KEEP
    part = f.choice("part", ("", *PARTS), "") or ""
    if part and not cloud.startswith("outcrop"):
        raise f.fail("part", "only the outcrop demos have face parts")
    min_points = f.number("min_points", lo=3, hi=100_000)
    if min_points is not None and min_points != int(min_points):
        raise f.fail("min_points", f"must be a whole number, got {min_points:g}")
    return Scene(
        cloud=cloud, part=part,
        alpha=f.number("alpha", 0.0, lo=-80.0, hi=80.0) or 0.0,
        beta=f.number("beta", 0.0, lo=-80.0, hi=80.0) or 0.0,
        model=cast(MapName | None, f.choice("model", MAPS)),
        grid=_grid(f),
        axis=cast(AxisChoice | None, f.choice("axis", AXIS_CHOICES)),
        threshold=f.number("threshold", lo=0.0, hi=1.0),
        min_points=None if min_points is None else int(min_points),
        camera=f.choice("camera", CAMERAS))


def _question(f: _Fields | None) -> Question | None:
    if f is None:
        return None
    f.only(("text", "measure", "model", "of", "grid", "tolerance", "absolute", "explanation"))
    of = f.table.get("of", ["ols", "odr"])
    if (not isinstance(of, list) or len(of) != 2 or any(m not in MAPS for m in of)
            or of[0] == of[1]):
        raise f.fail("of", f"must be two different maps of {', '.join(MAPS)}, got {of!r}")
    measure = f.choice("measure", tuple(MEASURES))
    if measure is None:
        raise f.fail("measure", f"missing; choose one of {', '.join(MEASURES)}")
    return Question(
        text=f.text("text"), measure=cast(Measure, measure),
        model=cast(MapName, f.choice("model", MAPS, "odr")),
        of=(cast(MapName, of[0]), cast(MapName, of[1])),
        grid=f.choice("grid", ("finest", "coarsest"), "coarsest") or "coarsest",
        tolerance=f.number("tolerance", 0.05, lo=0.0, hi=1.0) or 0.0,
        absolute=f.number("absolute", 0.0, lo=0.0) or 0.0,
        explanation=f.text("explanation", ""))


def _step(raw: object, k: int, where: str) -> Step:
    top = _Fields({}, where, "")
    if not isinstance(raw, dict):
        raise top.fail(f"steps[{k}]", "must be a table ([[steps]])")
    f = _Fields(raw, where, f"steps[{k}]")
    f.only(("title", "text", "scene", "question"))
    return Step(title=f.text("title", f"Step {k + 1}"), text=f.text("text"),
                scene=_scene(f.table_of("scene")), question=_question(f.table_of("question")))


def parse_lesson(data: Mapping[str, Any], *, name: str, where: str) -> Lesson:
    """A lesson from a parsed TOML document (``where``: the file as messages name
    it). InputError, one line naming the file and the field, for anything wrong."""
    f = _Fields(data, where, "")
    f.only(("title", "introduction", "steps"))
    steps = data.get("steps")
    if not isinstance(steps, list) or not steps:
        raise f.fail("steps", "missing: a lesson needs at least one [[steps]] table")
    if len(steps) > MAX_STEPS:
        raise f.fail("steps", f"more than {MAX_STEPS} steps")
    return Lesson(name=name, title=f.text("title"), introduction=f.text("introduction", ""),
                  steps=tuple(_step(s, k, where) for k, s in enumerate(steps)), source=where)


def load_lesson(path: str | Path, *, shown: str | None = None) -> Lesson:
    """Read and check the lesson file ``path`` (``shown``: how messages name it;
    default its file name)."""
    p = Path(path)
    where = shown or p.name
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"lesson {where}: cannot read: {exc.strerror or exc}") from None
    if len(raw) > 4 * MAX_TEXT * MAX_STEPS:
        raise InputError(f"lesson {where}: too large for a lesson ({len(raw):,} bytes)")
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise InputError(f"lesson {where}: not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"lesson {where}: not valid TOML: {exc}") from None
    return parse_lesson(data, name=p.stem, where=where)


def _bundled_dir() -> Path:
    return Path(str(importlib.resources.files(__name__)))


def bundled_names() -> list[str]:
    """Names of the bundled lessons, sorted."""
    return sorted(p.stem for p in _bundled_dir().glob("*.toml"))


def find_lesson(name_or_path: str) -> Lesson:
    """A bundled lesson by name, or a lesson file by path (``.toml``)."""
    if name_or_path in bundled_names():
        return load_lesson(_bundled_dir() / f"{name_or_path}.toml")
    p = Path(name_or_path).expanduser()
    if p.suffix.lower() == ".toml" or p.is_file():
        if not p.is_file():
            raise InputError(f"lesson file not found: {name_or_path}")
        return load_lesson(p)
    raise InputError(f"unknown lesson {name_or_path!r}; choose one of "
                     f"{', '.join(bundled_names())}, or give a .toml file")


__all__ = ["CAMERAS", "GRID_WORDS", "MEASURES", "PARTS", "Lesson", "Question", "Scene", "Step",
           "bundled_names", "find_lesson", "load_lesson", "parse_lesson"]
