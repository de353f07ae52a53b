"""Lessons as data: the bundled files validate, a broken file is one line naming the
file and the field, the measures equal brute-force references, and the handout
holds every question and a student's answers (issue 34, items 3 and 4)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rough_viewer.grid.roughness import grid_roughness
from rough_viewer.grid.scales import point_scales
from rough_viewer.io import PointCloud
from rough_viewer.lessons import (
    MEASURES,
    Question,
    bundled_names,
    find_lesson,
    load_lesson,
)
from rough_viewer.lessons.handout import HandoutAnswer, handout_html, step_figure
from rough_viewer.lessons.measures import Expected, accepted, expected_value, raw_value
from rough_viewer.vocabulary import InputError
from tests.helpers import rough_surface

GOOD = '''title = "My lesson"
introduction = "Intro."

[[steps]]
text = "Look."
[steps.scene]
cloud = "board"
alpha = 30
grid = 2.0
axis = "y"
[steps.question]
text = "How rough?"
measure = "mean"
model = "ols"
'''


@pytest.mark.parametrize("name", ["tilted-board", "turned-wall", "scale"])
def test_every_bundled_lesson_validates(name):
    assert name in bundled_names()
    lesson = find_lesson(name)
    assert lesson.name == name and lesson.title and lesson.introduction
    assert len(lesson.steps) >= 4
    assert lesson.steps[0].scene.cloud_key is not None  # the first step names its cloud
    for step in lesson.steps:
        q = step.question
        assert q is not None and q.text and q.explanation and q.measure in MEASURES
        assert 0 < q.tolerance <= 0.1


def test_a_lesson_file_of_ones_own_is_found_by_path(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(GOOD)
    lesson = find_lesson(str(path))
    assert lesson.name == "mine" and lesson.source == "mine.toml"
    s = lesson.steps[0]
    assert s.scene.cloud_key == ("board", 30.0, 0.0) and s.scene.grid == 2.0
    assert s.question is not None and s.question.model == "ols" and s.question.tolerance == 0.05
    assert s.title == "Step 1"


BROKEN = [
    ("title = 'x'\n[[steps]\n", "not valid TOML"),
    ("[[steps]]\ntext = 'a'\n", "title: missing"),
    ("title = 'x'\n", "steps: missing"),
    ("title = 'x'\ncolour = 1\n[[steps]]\ntext = 'a'\n", "colour: unknown field"),
    (GOOD.replace('measure = "mean"', 'measure = "avg"'),
     "steps[0].question.measure: unknown value 'avg'"),
    (GOOD.replace('grid = 2.0', 'grid = "huge"'), "steps[0].scene.grid: unknown value 'huge'"),
    (GOOD.replace('grid = 2.0', 'grid = -1'), "steps[0].scene.grid: must be between"),
    (GOOD.replace('axis = "y"', 'part = "turned wall"'),
     "steps[0].scene.part: only the outcrop demos"),
    (GOOD.replace('cloud = "board"', 'cloud = "moon"'), "steps[0].scene.cloud: unknown value"),
    (GOOD.replace('model = "ols"', 'model = "ols"\nof = ["ols", "ols"]'),
     "steps[0].question.of: must be two different maps"),
    (GOOD.replace('model = "ols"', 'tolerance = 2'), "steps[0].question.tolerance: must be "),
    (GOOD.replace('text = "How rough?"', 'text = 5'), "steps[0].question.text: must be text"),
    (GOOD.replace('alpha = 30', 'alpha = true'), "steps[0].scene.alpha: must be a number"),
    (GOOD + '[[steps]]\nquestion = 3\ntext = "b"\n', "steps[1].question: must be a table"),
]


@pytest.mark.parametrize("text,problem", BROKEN)
def test_a_broken_lesson_is_one_line_naming_the_file_and_the_field(tmp_path, text, problem):
    path = tmp_path / "broken.toml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        load_lesson(path)
    message = str(err.value)
    assert "\n" not in message and message.startswith("lesson broken.toml: "), message
    assert problem in message, message


def test_unknown_lessons_and_missing_files_are_refused():
    with pytest.raises(InputError, match="unknown lesson 'nope'; choose one of scale"):
        find_lesson("nope")
    with pytest.raises(InputError, match="lesson file not found: /no/such.toml"):
        find_lesson("/no/such.toml")


# ----------------------------------------------------------------------------- measures


@pytest.fixture(scope="module")
def results():
    cloud = PointCloud.from_xyz(rough_surface(20_000, seed=3, size=3.0))
    grids = [grid_roughness(cloud, g, axis="z") for g in (0.25, 0.5, 1.0)]
    return cloud, grids


def test_mean_median_and_ratio_are_the_cells_statistics(results):
    _cloud, (fine, *_rest) = results
    ols, odr = fine.theta_ols, fine.theta_odr
    ok = np.isfinite(ols) & np.isfinite(odr)
    assert ok.sum() > 100
    assert raw_value(Question("?", "mean", model="ols"), fine) == pytest.approx(ols[ok].mean())
    assert raw_value(Question("?", "median"), fine) == pytest.approx(np.median(odr[ok]))
    ratio = raw_value(Question("?", "ratio", of=("ols", "odr")), fine)
    assert ratio == pytest.approx(np.median(ols[ok] / odr[ok]))
    assert ratio > 1.0  # vertical distances are never shorter than perpendicular ones
    e = expected_value(Question("?", "mean", model="ols"), fine)
    assert e.unit == "mm" and e.value == pytest.approx(1e3 * ols[ok].mean())
    assert raw_value(Question("?", "points"), fine) == 20_000


def test_the_point_measure_reads_the_clicked_cell_on_the_coarsest_and_finest_grid(results):
    cloud, grids = results
    point = 1234
    scales = point_scales(grids, point)
    coarse, fine = grids[-1], grids[0]
    q = Question("?", "point", model="odr", grid="coarsest")
    assert raw_value(q, fine, scales=scales) == coarse.theta_odr[coarse.point_cell[point]]
    q = Question("?", "point", model="ols", grid="finest")
    assert raw_value(q, coarse, scales=scales) == fine.theta_ols[fine.point_cell[point]]
    with pytest.raises(InputError, match="click a point on the cloud first"):
        raw_value(q, fine, scales=None)


def test_the_first_lag_equals_a_brute_force_pair_count(results):
    _cloud, grids = results
    r = grids[1]  # 0.5 m: few cells, every pair counted here
    v = r.theta_odr
    ok = np.isfinite(v)
    ijk, z = r.ijk[ok].astype(float), v[ok]
    d = np.linalg.norm(ijk[:, None, :] - ijk[None, :, :], axis=2)
    iu = np.triu_indices(len(z), 1)
    near = (d[iu] >= 0.5) & (d[iu] < 1.5)  # the first bin: [0.5 g, 1.5 g)
    gamma = 0.5 * np.mean((z[iu[0]] - z[iu[1]])[near] ** 2)
    assert raw_value(Question("?", "variogram"), r) == pytest.approx(gamma / z.var(), rel=1e-9)


def test_an_answer_is_accepted_within_the_tolerance_only():
    q = Question("?", "mean", tolerance=0.05)
    assert accepted(1.049, 1.0, q) and accepted(0.951, 1.0, q)
    assert not accepted(1.051, 1.0, q) and not accepted(0.949, 1.0, q)
    assert not accepted(float("nan"), 1.0, q)
    assert accepted(0.3, 0.0, Question("?", "mean", tolerance=0.0, absolute=0.5))


# ----------------------------------------------------------------------------- handout


def test_a_blank_handout_holds_every_step_and_question(tmp_path):
    lesson = find_lesson("tilted-board")
    page = handout_html(lesson)
    assert page.startswith("<!DOCTYPE html>") and "Plotly" in page  # the report's page writer
    for k, step in enumerate(lesson.steps):
        assert f"Step {k + 1} of {len(lesson.steps)}" in page
        assert step.question is not None and step.question.text in page
    assert page.count('class="blank"') == len(lesson.steps)
    assert lesson.steps[0].question.explanation.split()[0] not in page.split("<h2>")[1]


def test_a_handout_with_answers_shows_them_and_escapes_the_lesson_text(tmp_path, results):
    _cloud, (fine, *_r) = results
    path = tmp_path / "x.toml"
    path.write_text(GOOD.replace('"My lesson"', '"<script>alert(1)</script>"'))
    lesson = load_lesson(path)
    q = lesson.steps[0].question
    assert q is not None
    fig = step_figure(q, fine)
    answers = {0: HandoutAnswer(0, 5.123, Expected(5.0, "mm"), True, "grid 2 m, axis y", fig)}
    page = handout_html(lesson, answers, student="s-7")
    assert "<script>alert(1)</script>" not in page and "&lt;script&gt;alert(1)" in page
    assert "5.123 mm" in page and "5 mm (grid 2 m, axis y)" in page and "correct" in page
    assert "1 of 1 answered correctly" in page and "student s-7" in page
    assert 'data-figure="step"' in page and "How rough?" in page


def test_the_command_line_writes_a_blank_handout_and_keeps_an_existing_file(tmp_path, capsys):
    from rough_viewer.cli import main

    out = tmp_path / "h.html"
    assert main(["lesson", "turned-wall", "--handout", str(out)]) == 0
    page = out.read_text()
    assert all(s.question.text in page for s in find_lesson("turned-wall").steps if s.question)
    out.write_text("mine")
    assert main(["lesson", "turned-wall", "--handout", str(out)]) == 2
    assert out.read_text() == "mine"
    err = capsys.readouterr().err.strip()
    assert "use --force" in err and "\n" not in err
    assert main(["lesson", "scale", "--handout", str(out), "--force"]) == 0
    assert "Roughness depends on scale" in out.read_text()


def test_the_command_line_checks_a_lesson_file_in_one_line(tmp_path, capsys):
    from rough_viewer.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text(GOOD.replace('axis = "y"', 'axis = "w"'))
    assert main(["lesson", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("rough-viewer: error: lesson bad.toml: steps[0].scene.axis: unknown value "
                   "'w'; choose one of auto, x, y, z")
    assert main(["lesson", "--list"]) == 0
    listed = capsys.readouterr().out
    assert "tilted-board" in listed and "The turned wall" in listed


def test_the_turned_wall_numbers_follow_one_over_cos_35():
    """The lesson's claim on the demo itself: the median OLS/ODR ratio of the turned
    wall with y as the dependent axis is near 1 / cos 35 degrees, and 1 on the main
    face."""
    from rough_viewer.lessons.clouds import scene_cloud

    lesson = find_lesson("turned-wall")
    ratio = Question("?", "ratio")
    main_face = grid_roughness(scene_cloud(lesson.steps[0].scene), 0.25, axis="y")
    wall = grid_roughness(scene_cloud(lesson.steps[1].scene), 0.25, axis="y")
    assert raw_value(ratio, main_face) == pytest.approx(1.0, abs=0.01)
    assert raw_value(ratio, wall) == pytest.approx(1 / math.cos(math.radians(35)), rel=0.03)
    assert Path(lesson.source).name == "turned-wall.toml"


def test_a_scene_cloud_is_read_once_for_every_tab():
    """Thirty tabs on one step show one cloud, not thirty copies (the clouds kept)."""
    from rough_viewer.lessons import Scene
    from rough_viewer.lessons.clouds import scene_cloud

    wall = Scene(cloud="outcrop-small", part="turned wall")
    assert scene_cloud(wall) is scene_cloud(Scene(cloud="outcrop-small", part="turned wall",
                                                  model="ols", grid=0.5))
    board = scene_cloud(Scene(cloud="board", alpha=10))
    assert board is scene_cloud(Scene(cloud="board", alpha=10.0))
    assert board is not scene_cloud(Scene(cloud="board", alpha=20))
    with pytest.raises(InputError, match="keeps the cloud shown"):
        scene_cloud(Scene())


def test_serve_opens_on_a_lesson_and_refuses_a_broken_one_before_listening(tmp_path, capsys):
    from rough_viewer.cli import main

    rng = np.random.default_rng(0)
    path = tmp_path / "pts.npy"
    np.save(path, np.column_stack([rng.uniform(0, 2, 5000), rng.uniform(0, 2, 5000),
                                   rng.normal(0, 0.003, 5000)]))
    bad = tmp_path / "bad.toml"
    bad.write_text(GOOD.replace("[[steps]]", "[[stepz]]"))
    assert main(["serve", str(path), "--port", "0", "--lesson", str(bad), "--no-block"]) == 2
    captured = capsys.readouterr()
    assert captured.err.strip() == "rough-viewer: error: lesson bad.toml: stepz: unknown field " \
        "(expected one of title, introduction, steps)"
    assert "listening" not in captured.err  # refused before the server opened
    assert main(["serve", str(path), "--port", "0", "--lesson", "scale", "--no-block"]) == 0
    assert "5,000 points, open http://127.0.0.1:" in capsys.readouterr().out
