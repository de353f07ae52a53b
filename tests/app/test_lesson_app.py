"""The Lesson tab in a real app, driven by a websocket browser: every step of the
bundled lessons sets its scene up, a right answer is accepted and a wrong one
refused against the number the grid code computes on its own, the handout arrives
with the answers, and the tab reports its lesson (issue 34, items 3 and 4)."""

from __future__ import annotations

import html
import math

import numpy as np
import pytest

from rough_viewer.app.features import lesson as lm
from rough_viewer.app.features.lesson import LessonFeature
from rough_viewer.app.host import LessonAnswer, LessonReporter, LessonStatus
from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.lessons import find_lesson, load_lesson
from rough_viewer.lessons.clouds import scene_cloud
from rough_viewer.synthetic.demos import load_demo
from tests.app.protocol import join, pick, settle


@pytest.fixture
def tab(app, server):
    client = join(server)
    client.uuid(lm.L_CHECK)  # the Lesson tab reached the browser
    yield app, client, app.feature(LessonFeature)
    client.close()


def _open(app, client, f, name: str) -> None:
    client.set_value(lm.L_LESSON, name)
    settle(app, lambda: f.lesson is not None and f.lesson.name == name and f.waiting is None,
           f"the lesson {name}", timeout=120)


def _go(app, client, f, label: str, step: int) -> None:
    client.press(label)
    settle(app, lambda: f.step == step and f.waiting is None, f"step {step + 1}", timeout=120)


def _answer(app, client, f, value: float) -> bool:
    """Type ``value``, press Check; True when the tab accepted it."""
    before = f.answers.get(f.step)
    client.set_value(lm.L_ANSWER, float(value))
    client.press(lm.L_CHECK)
    settle(app, lambda: f.answers.get(f.step) is not before, "the check")
    return f.answers[f.step].correct


def _right_and_wrong(app, client, f, reference: float) -> None:
    """The tool's number equals ``reference`` (the grid code's, computed here); 2 %
    off is accepted, 20 % off refused, and the verdict says so."""
    assert not _answer(app, client, f, 1.2 * reference)
    assert "Not quite" in f.verdict.content and "too high" in f.verdict.content
    assert _answer(app, client, f, 1.02 * reference)
    assert f.answers[f.step].expected.value == pytest.approx(reference, rel=1e-9)
    assert "**Correct.**" in f.verdict.content


def _mean(result, model: str) -> float:
    v = result.values(model)
    return float(np.mean(v[np.isfinite(v)]))


def _ratio(result) -> float:
    ok = np.isfinite(result.theta_ols) & np.isfinite(result.theta_odr)
    return float(np.median(result.theta_ols[ok] / result.theta_odr[ok]))


def test_the_tilted_board_lesson_runs_end_to_end(tab):
    app, client, f = tab
    _open(app, client, f, "tilted-board")
    expect = [  # (alpha, beta, what the step asks of the whole-board cell)
        (0, 0, lambda r: 1e3 * _mean(r, "ols")), (45, 0, lambda r: 1e3 * _mean(r, "ols")),
        (45, 0, lambda r: 1e3 * _mean(r, "odr")), (45, 0, _ratio), (45, 45, _ratio)]
    for k, (alpha, beta, of) in enumerate(expect):
        if k:
            _go(app, client, f, lm.L_NEXT, k)
        shown = app.session.shown
        assert shown.settings.cell_size == 2.0 and shown.result.axis == "y"
        assert f"α {alpha}°, β {beta}°" in app.host.status.content.replace("\\", "")
        reference = grid_roughness(load_demo("board", alpha_deg=alpha, beta_deg=beta), 2.0,
                                   axis="y")
        assert reference.n_cells == 1  # the whole board in one cell
        _right_and_wrong(app, client, f, of(reference))
    assert f.answers[3].expected.value == pytest.approx(1 / math.cos(math.radians(45)), rel=0.01)
    assert f.answers[4].expected.value == pytest.approx(2.0, rel=0.02)
    status = f.lesson_status()
    assert isinstance(f, LessonReporter) and isinstance(status, LessonStatus)
    assert (status.lesson, status.title, status.step, status.steps) == \
        ("tilted-board", "The tilted board", 4, 5)
    assert [a.step for a in status.answers] == [0, 1, 2, 3, 4]
    first = status.answers[0]
    assert isinstance(first, LessonAnswer) and first.correct
    assert first.question == f.lesson.steps[0].question.text
    assert first.given == pytest.approx(1.02 * first.expected)
    _go(app, client, f, lm.L_PREVIOUS, 3)  # back: the board at (45°, 0°), as step 3 left it
    shown = app.session.shown
    assert (shown.settings.cell_size, shown.settings.model, shown.settings.axis) == (2.0, "odr", "y")
    assert "α 45°, β 0°" in app.host.status.content.replace("\\", "")


def test_the_turned_wall_lesson_finds_one_over_cos_35(tab):
    app, client, f = tab
    _open(app, client, f, "turned-wall")
    lesson = f.lesson
    main_face = scene_cloud(lesson.steps[0].scene)
    wall = scene_cloud(lesson.steps[1].scene)
    assert app.session.shown.loaded.n_total == main_face.n
    _right_and_wrong(app, client, f, _ratio(grid_roughness(main_face, 0.25, axis="y")))
    _go(app, client, f, lm.L_NEXT, 1)
    assert app.session.shown.loaded.n_total == wall.n
    on_y = grid_roughness(wall, 0.25, axis="y")
    _right_and_wrong(app, client, f, _ratio(on_y))
    assert f.answers[1].expected.value == pytest.approx(1 / math.cos(math.radians(35)), rel=0.03)
    assert _answer(app, client, f, 1 / math.cos(math.radians(35)))  # the theory is accepted
    assert "not this step's" not in f.verdict.content
    client.set_value("Dependent axis", "x")  # the student moves away from the step's map
    settle(app, lambda: app.session.shown.settings.axis == "x", "axis x")
    assert not _answer(app, client, f, 1 / math.cos(math.radians(35)))  # checked on x
    assert "not this step's (axis x instead of y)" in f.verdict.content
    _go(app, client, f, lm.L_AGAIN, 1)  # the step's own map again
    settle(app, lambda: app.session.shown.settings.axis == "y", "axis y again")
    assert _answer(app, client, f, 1 / math.cos(math.radians(35)))
    _go(app, client, f, lm.L_NEXT, 2)
    _right_and_wrong(app, client, f, 1e3 * _mean(on_y, "odr"))
    _go(app, client, f, lm.L_NEXT, 3)
    assert app.session.shown.settings.axis == "x"
    _right_and_wrong(app, client, f, _ratio(grid_roughness(wall, 0.25, axis="x")))
    assert f.answers[3].expected.value > 1.6  # 55° from the axis: near 1 / cos 55°


def test_the_scale_lesson_with_a_click_and_the_handout(tab):
    app, client, f = tab
    _open(app, client, f, "scale")
    loaded = app.session.shown.loaded
    presets = sorted(loaded.presets)
    cloud = loaded.cloud
    assert app.session.shown.settings.cell_size == presets[0]
    _right_and_wrong(app, client, f, 1e3 * _mean(grid_roughness(cloud, presets[0]), "odr"))
    _go(app, client, f, lm.L_NEXT, 1)
    coarse = grid_roughness(cloud, presets[-1])
    assert app.session.shown.settings.cell_size == presets[-1]
    _right_and_wrong(app, client, f, 1e3 * _mean(coarse, "odr"))
    assert f.answers[1].expected.value > 3 * f.answers[0].expected.value  # scale matters
    _go(app, client, f, lm.L_NEXT, 2)
    client.set_value(lm.L_ANSWER, 1.0)
    client.press(lm.L_CHECK)  # no click yet: the tab asks for one and records nothing
    settle(app, lambda: "click a point on the cloud first" in f.verdict.content, "the ask")
    assert 2 not in f.answers
    i = int(np.argmin(np.abs(cloud.x - np.median(cloud.x)) + np.abs(cloud.z - np.median(cloud.z))))
    xyz = np.array([cloud.x[i], cloud.y[i], cloud.z[i]])
    local = loaded.to_local(xyz)
    assert pick(app, local - np.array([0.0, 30.0, 0.0]), (0.0, 1.0, 0.0)) is not None
    picked = app.session.pick_scales.point
    _right_and_wrong(app, client, f, 1e3 * coarse.theta_odr[coarse.point_cell[picked]])
    _go(app, client, f, lm.L_NEXT, 3)
    assert app.session.shown.settings.cell_size == 0.25
    from rough_viewer.lessons import Question
    from rough_viewer.lessons.measures import raw_value

    first_lag = raw_value(Question("?", "variogram"), grid_roughness(cloud, 0.25))
    _right_and_wrong(app, client, f, first_lag)
    assert 0.3 < first_lag < 1.0  # neighbours more alike than far cells

    mark = len(client.messages)
    client.press(lm.L_HANDOUT)
    name, data = client.wait_download("handout", since=mark)
    page = data.decode("utf-8")
    assert name == "scale_handout.html"
    for step in f.lesson.steps:
        assert html.escape(step.question.text) in page
    for a in f.answers.values():
        assert f"{a.given:.4g}" in page and f"{a.expected.value:.4g}" in page
    assert page.count('data-figure="step"') == 4


def test_serve_lesson_opens_the_app_on_its_first_step(server, cloud):
    from rough_viewer.app.server import build_app

    app = build_app(server, cloud, prefetch=False, lesson=find_lesson("tilted-board"))
    try:
        assert app.wait_idle(120)
        f = app.feature(LessonFeature)
        settle(app, lambda: f.waiting is None and app.session.shown.settings.cell_size == 2.0,
               "the first step")
        assert f.lesson is not None and f.step == 0 and f.choose.value == "tilted-board"
        assert "board lesson" in app.host.status.content
        assert "The board facing the scanner" in f.heading.content
    finally:
        app.stop()


def test_lesson_text_is_escaped_in_the_tab(server, cloud, tmp_path):
    from rough_viewer.app.server import build_app

    path = tmp_path / "evil.toml"
    path.write_text('title = "<img src=x onerror=alert(1)>"\n[[steps]]\ntitle = "*bold*"\n'
                    'text = "[link](http://x) <b>b</b>"\n[steps.question]\n'
                    'text = "<script>q</script>"\nmeasure = "points"\n')
    app = build_app(server, cloud, prefetch=False, lesson=load_lesson(path))
    try:
        assert app.wait_idle(120)
        f = app.feature(LessonFeature)
        settle(app, lambda: f.lesson is not None and "step 1 of 1" in f.heading.content, "step")
        text = f.heading.content + f.question.content
        for raw in ("<img", "<b>", "<script>", "[link](", "*bold*"):
            assert raw not in text
        assert "&lt;img" in text and "&lt;script&gt;" in text
    finally:
        app.stop()


def test_serve_refuses_an_unknown_lesson_in_one_line():
    from rough_viewer.cli import build_parser
    from rough_viewer.cli.serve import _lesson
    from rough_viewer.vocabulary import InputError

    args = build_parser("serve").parse_args(["serve", "--lesson", "nope"])
    with pytest.raises(InputError, match="^unknown lesson 'nope'; choose one of"):
        _lesson(args)
    args = build_parser("serve").parse_args(["serve", "--lesson", "scale"])
    assert _lesson(args).title == "Roughness depends on scale"


def test_every_classroom_tab_has_its_own_lesson_and_the_teacher_sees_the_answers(cloud):
    """``serve --classroom --lesson``: each student's tab opens on the lesson, steps
    and answers are the tab's own, the lesson's cloud is one object for every tab, and
    the teacher's classroom lists each student's step and answers."""
    import dataclasses

    from rough_viewer.app.classroom import Classroom
    from rough_viewer.app.gate import new_token, open_server
    from rough_viewer.app.server import app_options, shared_cloud
    from rough_viewer.app.settings import MapSettings
    from tests.app.browser import wait_until
    from tests.app.protocol import ProtocolClient

    server, gate = open_server("127.0.0.1", 0, token=new_token(), teacher_token=new_token(),
                               log=False)
    options = dataclasses.replace(app_options(cloud, prefetch=False,
                                              lesson=find_lesson("tilted-board")),
                                  compute_slots=2)
    loaded = shared_cloud(cloud, options)
    room = Classroom(server, gate, loaded, MapSettings(cell_size=loaded.default_cell_size),
                     options).start()
    tabs = []
    try:
        rooms = []
        for _ in range(2):
            before = set(room.rooms)
            tabs.append(ProtocolClient(server.get_port(), gate.path))
            new = wait_until(lambda before=before: set(room.rooms) - before, 60, "a tab's app")
            rooms.append(room.rooms[max(new)])
        features = [r.app.feature(LessonFeature) for r in rooms]
        for r, f in zip(rooms, features, strict=True):
            settle(r.app, lambda f=f, r=r: f.lesson is not None and f.waiting is None
                   and r.app.session.shown.settings.cell_size == 2.0, "the lesson's first step",
                   timeout=120)
        a, b = tabs
        (ra, rb), (fa, fb) = rooms, features
        assert ra.app.session.shown.loaded.cloud is rb.app.session.shown.loaded.cloud
        reference = grid_roughness(load_demo("board"), 2.0, axis="y")
        since = len(b.messages)
        _answer(ra.app, a, fa, 1e3 * _mean(reference, "ols"))
        _go(ra.app, a, fa, lm.L_NEXT, 1)
        assert fa.answers[0].correct and fb.answers == {} and fb.step == 0
        assert "α 45°" in ra.app.host.status.content.replace("\\", "")
        assert "α 0°" in rb.app.host.status.content.replace("\\", "")
        assert not any("Correct" in str(m) for m in b.messages[since:])  # nothing of A's
        lines = {s.client_id: (s.lesson, s.answers) for s in room.students()}
        given = fa.lesson_status().answers[0].given
        assert lines[ra.client_id] == ("tilted-board 2/5",
                                       f"step 1: {given:.3g} ✓ (1 of 1 right)")
        assert lines[rb.client_id] == ("tilted-board 1/5", "")
        assert isinstance(fb, LessonReporter) and fb.lesson_status().answers == ()
    finally:
        for tab in tabs:
            tab.close()
        room.stop()
        server.stop()
