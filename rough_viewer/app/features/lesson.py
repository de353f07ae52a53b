"""The Lesson tab: guided steps through the app (lessons as data:
:mod:`rough_viewer.lessons`, docs/lessons.md).

Choose a lesson; each step sets its scene up through the host (a cloud with
:meth:`Host.load`, the map's settings with :meth:`Host.request`, a camera preset) and
asks a question whose answer the tab checks on the worker against the number it
computes from the map shown (:func:`rough_viewer.lessons.measures.expected_value`),
then shows the explanation. "Download handout" sends the lesson's page with this
tab's answers and their figures (:func:`rough_viewer.lessons.handout.handout_html`).

The feature talks only to its host, so in a classroom (a host per browser tab)
every tab has its own lesson, step and answers; :meth:`LessonFeature.lesson_status`
reports them (:class:`~rough_viewer.app.host.LessonReporter`).

Every string that comes from a lesson file is the user's: it goes through
:func:`~rough_viewer.app.markup.md` before it reaches a browser.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import partial
from typing import ClassVar

import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.detail import CameraJob
from rough_viewer.app.host import Host, LessonAnswer, LessonStatus
from rough_viewer.app.markup import md
from rough_viewer.app.settings import MODEL_LABELS, MapSettings, grid_options
from rough_viewer.app.worker import Job, Run
from rough_viewer.io import PointCloud
from rough_viewer.lessons import Lesson, Question, Scene, bundled_names, find_lesson
from rough_viewer.lessons.handout import HandoutAnswer, handout_html, step_figure
from rough_viewer.lessons.measures import accepted, expected_value
from rough_viewer.vocabulary import InputError

#: The dropdown's entry before a lesson is chosen.
NO_LESSON = "(choose a lesson)"
L_LESSON = "Lesson"
L_ANSWER = "Your answer"
L_CHECK = "Check"
L_NEXT = "Next step"
L_PREVIOUS = "Previous step"
L_AGAIN = "Set the scene again"
L_HANDOUT = "Download handout"
#: What the tab says before a lesson is chosen.
CHOOSE = ("Choose a lesson: each step sets the scene up and asks a question you answer "
          "from the tool's numbers.")
#: Largest answer the number field takes (in either sign).
MAX_ANSWER = 1e9


def paragraphs(text: str) -> str:
    """A lesson's plain text as Markdown paragraphs, every character escaped."""
    return "\n\n".join(md(" ".join(b.split())) for b in text.split("\n\n") if b.strip())


def effective_scene(lesson: Lesson, k: int) -> Scene:
    """Step ``k``'s scene with what earlier steps set and it leaves alone (a step
    that keeps the cloud keeps the latest one an earlier step named), so every step
    can be set up on its own (Previous step, Set the scene again)."""
    merged = Scene()
    for step in lesson.steps[: k + 1]:
        s = step.scene
        cloud = s if s.cloud_key is not None else merged
        merged = Scene(cloud=cloud.cloud, part=cloud.part, alpha=cloud.alpha, beta=cloud.beta,
                       model=s.model or merged.model, grid=s.grid if s.grid is not None
                       else merged.grid, axis=s.axis or merged.axis,
                       threshold=s.threshold if s.threshold is not None else merged.threshold,
                       min_points=s.min_points or merged.min_points,
                       camera=s.camera or merged.camera)
    return merged


def with_scene(settings: MapSettings, scene: Scene) -> MapSettings:
    """``settings`` with the scene's model, axis, threshold and minimum points (a
    load's own grid is set once the cloud is shown)."""
    changes: dict[str, object] = {}
    if scene.model is not None:
        changes["model"] = scene.model
    if scene.axis is not None:
        changes["axis"] = scene.axis
    if scene.threshold is not None:
        changes["threshold"] = float(scene.threshold)
    if scene.min_points is not None:
        changes["min_points"] = int(scene.min_points)
    return settings.with_(**changes)


@dataclass(eq=False)
class LessonFeature:
    """Handles and state of the Lesson tab (state written on the worker only)."""

    host: Host
    choose: viser.GuiDropdownHandle[str]
    heading: viser.GuiMarkdownHandle
    question: viser.GuiMarkdownHandle
    answer: viser.GuiNumberHandle[float]
    check: viser.GuiButtonHandle
    verdict: viser.GuiMarkdownHandle
    previous: viser.GuiButtonHandle
    next: viser.GuiButtonHandle
    again: viser.GuiButtonHandle
    handout: viser.GuiButtonHandle
    lessons: dict[str, Lesson]
    """Dropdown entry -> lesson (the bundled ones and ``serve --lesson``'s)."""
    binding: Binding = field(default_factory=Binding)
    lesson: Lesson | None = None
    step: int = 0
    answers: dict[int, HandoutAnswer] = field(default_factory=dict)
    """The last checked answer of each step (0-based)."""
    waiting: Scene | None = None
    """The scene whose cloud is being loaded (its grid and camera follow on show)."""
    cloud_key: tuple[object, ...] | None = None
    """The scene cloud the tab loaded last, and the cloud it read (weakly)."""
    cloud_ref: weakref.ref[PointCloud] | None = None
    started: bool = False
    """The first cloud was shown (``serve --lesson``'s first step then sets up)."""

    # ------------------------------------------------------------------ reporting
    def lesson_status(self) -> LessonStatus:
        """Where this tab stands in its lesson (any thread: reads only)."""
        lesson = self.lesson
        if lesson is None:
            return LessonStatus("", "", 0, 0, ())
        answers = tuple(
            LessonAnswer(k, q.text, a.given, a.expected.value, a.correct)
            for k, a in sorted(self.answers.items())
            if (q := lesson.steps[k].question) is not None)
        return LessonStatus(lesson.name, lesson.title, self.step, len(lesson.steps), answers)

    def shows_lesson_cloud(self, key: tuple[object, ...] | None) -> bool:
        """True when the cloud shown is the one the tab loaded for ``key``."""
        if key is None:
            return True
        cloud = self.cloud_ref() if self.cloud_ref is not None else None
        return key == self.cloud_key and cloud is self.host.session.shown.loaded.cloud

    # ------------------------------------------------------------------ showing (worker)
    def show_step(self) -> None:
        """The current step's text and question in the tab."""
        lesson = self.lesson
        b = self.binding
        if lesson is None:
            b.write(self.heading, content=CHOOSE)
            b.write(self.question, content="")
            b.write(self.verdict, content="")
            return
        step = lesson.steps[self.step]
        head = [f"**{md(lesson.title)}**: step {self.step + 1} of {len(lesson.steps)}, "
                f"*{md(step.title)}*"]
        if self.step == 0 and lesson.introduction:
            head.append(paragraphs(lesson.introduction))
        head.append(paragraphs(step.text))
        b.write(self.heading, content="\n\n".join(head))
        q = step.question
        b.write(self.question, content="No question in this step." if q is None else
                f"**Question:** {md(q.text)}")
        done = self.answers.get(self.step)
        b.write(self.verdict, content="" if done is None or q is None else verdict_text(q, done))
        b.set(self.answer, float(done.given) if done is not None else 0.0)  # this step's own

    def say(self, text: str) -> None:
        self.binding.write(self.verdict, content=text)


def verdict_text(q: Question, a: HandoutAnswer) -> str:
    """The check's answer: correct or not, how far off, and the explanation."""
    u = f" {md(a.expected.unit)}" if a.expected.unit else ""
    if a.correct:
        head = (f"**Correct.** The tool's number is {a.expected.value:.4g}{u} "
                f"({md(a.where)}).")
    else:
        side = "high" if a.given > a.expected.value else "low"
        head = (f"**Not quite:** {a.given:.4g}{u} is too {side} (the tolerance is "
                f"{100 * q.tolerance:g} %). Look again and check once more.")
    return "\n\n".join([head, paragraphs(q.explanation)]) if q.explanation else head


@dataclass(frozen=True)
class LessonCloud:
    """A scene's cloud as a load's source (a demo, a face part, the board)."""

    f: LessonFeature = field(compare=False)
    scene: Scene

    @property
    def title(self) -> str:
        return self.scene.label

    def read(self, host: Host, run: Run) -> PointCloud:
        from rough_viewer.lessons.clouds import scene_cloud

        cloud = scene_cloud(self.scene)
        self.f.cloud_key, self.f.cloud_ref = self.scene.cloud_key, weakref.ref(cloud)
        return cloud

    def release(self) -> None:
        pass


def grid_changes(host: Host, scene: Scene) -> dict[str, object]:
    """The Map tab's grid controls for the scene's grid on the cloud shown (a preset
    by its entry, another size as the free size; {} when it shows it already)."""
    loaded = host.session.shown.loaded
    presets = tuple(loaded.presets or ())
    if scene.grid is None or not presets:
        return {}
    size = {"default": loaded.default_cell_size, "finest": min(presets),
            "coarsest": max(presets)}.get(str(scene.grid)) if isinstance(scene.grid, str) \
        else float(scene.grid)
    assert size is not None
    if abs(host.settings().cell_size - size) <= 1e-9 * size:
        return {}
    for text, preset in grid_options(presets, loaded.units).items():
        if abs(preset - size) <= 1e-9 * size:
            return {"grid": text}
    return {"grid_free": loaded.units.length(size)}


def map_changes(host: Host, scene: Scene) -> dict[str, object]:
    """The Map tab's controls a scene changes on the cloud shown."""
    changes = grid_changes(host, scene)
    if scene.model is not None:
        changes["model"] = MODEL_LABELS[scene.model]
    if scene.axis is not None:
        changes["axis"] = scene.axis
    if scene.threshold is not None:
        changes["threshold"] = float(scene.threshold)
    if scene.min_points is not None:
        changes["min_points"] = int(scene.min_points)
    return changes


def off_scene(f: LessonFeature, scene: Scene) -> list[str]:
    """How the map shown differs from ``scene`` (what its number depends on: the
    cloud, grid, axis and minimum points); [] when it is the scene's."""
    shown = f.host.session.shown.settings
    out = []
    if not f.shows_lesson_cloud(scene.cloud_key):
        out.append("another cloud")
    elif grid_changes(f.host, scene):
        out.append("another grid")
    if scene.axis is not None and shown.axis != scene.axis:
        out.append(f"axis {shown.axis} instead of {scene.axis}")
    if scene.min_points is not None and shown.min_points != scene.min_points:
        out.append("other minimum points")
    return out


def set_scene(f: LessonFeature, scene: Scene) -> None:
    """Queue what puts ``scene`` on screen (worker): a load of its cloud (the grid
    and camera follow once it is shown: :func:`cloud_shown`), or the map's changes
    and the camera on the cloud shown."""
    host = f.host
    if not f.shows_lesson_cloud(scene.cloud_key):
        f.waiting = scene
        host.load(LessonCloud(f, scene), adjust=partial(with_scene, scene=scene),
                  label=scene.label)
        return
    f.waiting = None
    changes = map_changes(host, scene)
    if changes:
        host.request(**changes)
    if scene.camera is not None:
        host.submit(CameraJob(scene.camera))


def cloud_shown(f: LessonFeature) -> None:
    """Another cloud is shown (worker): the lesson's, whose grid and camera follow;
    or, the first time, the cloud ``serve --lesson`` opens on."""
    if not f.started:
        f.started = True
        if f.lesson is not None:
            f.host.submit(LessonJob(f, "go", step=0))
        return
    scene = f.waiting
    if scene is None or not f.shows_lesson_cloud(scene.cloud_key):
        return
    f.waiting = None
    changes = grid_changes(f.host, scene)
    if changes:
        f.host.request(**changes)
    if scene.camera is not None:
        f.host.submit(CameraJob(scene.camera))


# ----------------------------------------------------------------------------- jobs


@dataclass(frozen=True)
class LessonJob(Job[Host]):
    """Open a lesson (``action="open"``, by its dropdown entry) or go to a step
    (``"go"``: ``step``, or ``delta`` from the current one), and set its scene up."""

    f: LessonFeature = field(compare=False)
    action: str
    name: str = ""
    step: int | None = None
    delta: int = 0
    lane: ClassVar[str] = "lesson"
    keep_all: ClassVar[bool] = True  # two presses of Next are two steps

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f = self.f
        if self.action == "open":
            f.lesson = f.lessons.get(self.name)
            f.step, f.answers = 0, {}
        lesson = f.lesson
        if lesson is not None:
            k = self.step if self.step is not None else f.step + self.delta
            f.step = max(0, min(len(lesson.steps) - 1, k))
        f.show_step()
        yield "step"
        if lesson is not None:
            set_scene(f, effective_scene(lesson, f.step))
            yield "scene"


@dataclass(frozen=True)
class CheckJob(Job[Host]):
    """Check the typed answer against the number computed from the map shown."""

    f: LessonFeature = field(compare=False)
    given: float
    lane: ClassVar[str] = "lesson-check"
    keep_all: ClassVar[bool] = True

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f = self.f
        lesson = f.lesson
        q = lesson.steps[f.step].question if lesson is not None else None
        shown = ctx.session.shown
        if lesson is None or q is None:
            f.say("Nothing to check: " + ("choose a lesson." if lesson is None
                                           else "this step asks no question."))
            return
        if shown.result is None:
            f.say("The map is still being computed: check again in a moment.")
            return
        u = shown.loaded.units
        try:
            expected = expected_value(q, shown.result, rough_per=u.rough_per,
                                      rough_unit=u.rough_unit,
                                      keep_outliers=shown.settings.keep_outliers,
                                      scales=ctx.session.pick_scales)
        except InputError as exc:
            f.say(md(str(exc)))
            return
        yield "expected"
        s = shown.settings
        where = (f"grid {u.size_text(s.cell_size)}, axis {shown.result.axis}, "
                 f"{shown.result.n_points_total:,} points")
        figure = step_figure(q, shown.result, threshold=s.threshold,
                             keep_outliers=s.keep_outliers, scales=ctx.session.pick_scales,
                             unit=u.unit)
        answer = HandoutAnswer(f.step, self.given, expected,
                               accepted(self.given, expected.value, q), where, figure)
        f.answers = {**f.answers, f.step: answer}
        off = off_scene(f, effective_scene(lesson, f.step))
        f.say(verdict_text(q, answer) + ("" if not off else
              f"\n\n*Checked on the map shown, not this step's ({', '.join(off)}): "
              f"**{L_AGAIN}** puts the step's map back.*"))
        yield "checked"


@dataclass(frozen=True)
class HandoutJob(Job[Host]):
    """Send the lesson's handout, with this tab's answers, to the browser that asked."""

    f: LessonFeature = field(compare=False)
    client_id: int | None
    lane: ClassVar[str] = "lesson-handout"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f = self.f
        lesson = f.lesson
        if lesson is None:
            f.say("Choose a lesson first.")
            return
        unit = ctx.session.shown.loaded.units.rough_label
        data = handout_html(lesson, dict(f.answers), unit=unit).encode("utf-8")
        yield "write"
        clients = ctx.clients()
        targets = [clients[self.client_id]] if self.client_id in clients else \
            (list(clients.values()) if self.client_id is None else [])
        for client in targets:
            client.send_file_download(f"{lesson.name}_handout.html", data,
                                      save_immediately=True)
        f.say(f"Sent the handout ({len(data) / 1e6:.1f} MB)." if targets
              else "The browser that asked has left; nothing sent.")
        yield "send"


# ----------------------------------------------------------------------------- mount


def lesson_entries(host: Host) -> dict[str, Lesson]:
    """The dropdown's lessons: the bundled ones, and ``serve --lesson``'s first when
    it is a file of its own."""
    entries: dict[str, Lesson] = {}
    given = host.options.lesson
    if given is not None:
        entries[given.name] = given
    for name in bundled_names():
        if name not in entries:
            try:
                entries[name] = find_lesson(name)
            except InputError:  # a broken bundled file: the tests say so, the tab goes on
                continue
    return entries


def mount(host: Host) -> LessonFeature:
    """Add the Lesson tab."""
    gui = host.gui
    lessons = lesson_entries(host)
    given = host.options.lesson
    with host.tab("Lesson"):
        f = LessonFeature(
            host=host,
            choose=gui.add_dropdown(L_LESSON, (NO_LESSON, *lessons),
                                    initial_value=given.name if given is not None else NO_LESSON),
            heading=gui.add_markdown(CHOOSE if given is None else
                                     f"Opening the lesson **{md(given.title)}**…"),
            question=gui.add_markdown(""),
            answer=gui.add_number(L_ANSWER, initial_value=0.0, min=-MAX_ANSWER, max=MAX_ANSWER,
                                  step=0.0001),
            check=gui.add_button(L_CHECK, hint="Checks your answer against the tool's number "
                                 "on the map shown."),
            verdict=gui.add_markdown(""),
            previous=gui.add_button(L_PREVIOUS),
            next=gui.add_button(L_NEXT),
            again=gui.add_button(L_AGAIN, hint="Puts this step's cloud, map and camera back."),
            handout=gui.add_button(L_HANDOUT, hint="A printable page: the steps, questions, "
                                   "your answers and the figures they were checked on."),
            lessons=lessons, lesson=given)
    host.allow(f.choose, f.answer, f.check, f.previous, f.next, f.again, f.handout)
    b = f.binding
    b.on_change([f.choose], lambda _h: host.submit(LessonJob(f, "open", name=str(f.choose.value))))
    b.on_change([f.check], lambda _h: host.submit(CheckJob(f, float(f.answer.value))))
    b.on_change([f.next], lambda _h: host.submit(LessonJob(f, "go", delta=1)))
    b.on_change([f.previous], lambda _h: host.submit(LessonJob(f, "go", delta=-1)))
    b.on_change([f.again], lambda _h: host.submit(LessonJob(f, "go", delta=0)))

    @f.handout.on_click
    def _(event: viser.GuiEvent[viser.GuiButtonHandle]) -> None:
        host.submit(HandoutJob(f, event.client_id))  # to the browser that asked

    host.on_cloud(lambda: cloud_shown(f))
    return f
