"""A lesson's printable handout: one self-contained HTML page (the report's page and
figure writer, :func:`rough_viewer.report.html.html_page`) with the introduction,
every step's text and question, and, for the steps a student answered, the answer,
the tool's number, the verdict, the explanation and the figure of the map the
answer was checked on. Blank handouts (``rough-viewer lesson NAME --handout``) have
an answer line to fill in instead.
"""

from __future__ import annotations

import html
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from rough_viewer.grid.outliers import analysed_values
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.scales import PointScales
from rough_viewer.grid.summary import histogram, normalise
from rough_viewer.grid.variogram import semivariogram
from rough_viewer.lessons import Lesson, Question, Step
from rough_viewer.lessons.measures import Expected
from rough_viewer.vocabulary import HISTOGRAM_BIN, MapName

#: Lags of a handout's semivariogram figure, in cells (the figure stays quick).
FIGURE_LAGS = 20

_CSS = """
.step { page-break-inside: avoid; margin-bottom: 1.5em; }
.question { font-weight: bold; margin: 0.6em 0; }
.answer td { padding: 2px 12px 2px 0; }
.right { color: #060; font-weight: bold; } .wrong { color: #a00; font-weight: bold; }
.blank { border-bottom: 1px solid #222; display: inline-block; width: 12em; }
@media print { .figure { break-inside: avoid; } }
"""


@dataclass(frozen=True)
class HandoutAnswer:
    """A student's checked answer to one step (what the handout shows of it)."""

    step: int
    """0-based step index."""
    given: float
    expected: Expected
    correct: bool
    where: str
    """The map it was checked on ("grid 0.25 m, axis y, 43,941 points")."""
    figure: Any = None
    """The figure of that map (a plotly figure; None: none)."""


def step_figure(question: Question, result: GridRoughness, *, threshold: float = 0.05,
                keep_outliers: bool = False, scales: PointScales | None = None,
                unit: str = "m") -> Any:
    """The figure a handout shows for an answered question: the clicked point across
    the scales (``point``), the semivariogram (``variogram``, the first
    :data:`FIGURE_LAGS` lags), else the histogram of normalised roughness of ODR,
    OLS and the question's map (the Panels tab's)."""
    from rough_viewer.visual.grid import histogram_figure, variogram_figure
    from rough_viewer.visual.scales import point_scales_figure

    kw: dict[str, Any] = {"grid_size": result.grid.cell_size, "axis": result.axis,
                          "n_points": result.n_points_total, "unit": unit}
    if question.measure == "point" and scales is not None:
        return point_scales_figure(scales, n_points=result.n_points_total, unit=unit)
    maps: tuple[MapName, ...] = ("odr", "ols")
    if question.measure == "ratio":
        maps = tuple(dict.fromkeys((*maps, *question.of)))
    elif question.model not in maps:
        maps = (*maps, question.model)
    values = {m: analysed_values(result, m, keep_outliers=keep_outliers) for m in maps}
    if question.measure == "variogram":
        g = result.grid.cell_size
        m = question.model
        return variogram_figure({m: semivariogram(result.ijk, values[m], g,
                                                  max_lag=FIGURE_LAGS * g)}, **kw)
    return histogram_figure({m: histogram(normalise(v), HISTOGRAM_BIN) for m, v in values.items()},
                            threshold=threshold, **kw)


def _paragraphs(text: str) -> list[str]:
    """Plain text (a lesson's) as escaped paragraphs, split at blank lines."""
    blocks = [" ".join(b.split()) for b in text.split("\n\n")]
    return [f"<p>{html.escape(b)}</p>" for b in blocks if b]


def _number(v: float) -> str:
    return f"{v:.4g}" if np.isfinite(v) else "—"


def _answer_rows(q: Question, a: HandoutAnswer | None, unit: str) -> list[str]:
    if a is None:
        return [f'<p>Your answer: <span class="blank"></span> {html.escape(unit)}</p>']
    u = html.escape(a.expected.unit)
    verdict = ('<span class="right">correct</span>' if a.correct
               else '<span class="wrong">not within the tolerance</span>')
    rows = [("your answer", f"{_number(a.given)} {u}"),
            ("the tool's number", f"{_number(a.expected.value)} {u} ({html.escape(a.where)})"),
            ("tolerance", f"{100 * q.tolerance:g} %"
             + (f" or {q.absolute:g} {u}" if q.absolute else "")),
            ("verdict", verdict)]
    out = ['<table class="answer">'
           + "".join(f"<tr><td>{k}</td><td>{v}</td></tr>" for k, v in rows) + "</table>"]
    return out + _paragraphs(q.explanation)


def _step_html(lesson: Lesson, k: int, step: Step, answer: HandoutAnswer | None,
               unit: str) -> list[str]:
    esc = html.escape
    parts = [f'<section class="step" id="step-{k + 1}">',
             f"<h2>Step {k + 1} of {len(lesson.steps)}: {esc(step.title)}</h2>",
             *_paragraphs(step.text)]
    q = step.question
    if q is not None:
        parts.append(f'<p class="question" data-question="{k + 1}">{esc(q.text)}</p>')
        parts += _answer_rows(q, answer, "" if q.dimensionless else unit)
        if answer is not None and answer.figure is not None:
            from rough_viewer.report.html import figure_html

            parts.append(figure_html(answer.figure, f"step-{k + 1}-figure", "step"))
    return parts + ["</section>"]


def handout_html(lesson: Lesson, answers: Mapping[int, HandoutAnswer] | None = None, *,
                 unit: str = "mm", student: str = "") -> str:
    """The handout page of ``lesson``: every step and question; ``answers`` (by
    0-based step) fill in what a student answered (None: a blank handout to fill
    in by hand). ``unit``: the unit roughness answers are given in; ``student``:
    a name or id printed at the top."""
    from rough_viewer.report.html import html_page

    esc = html.escape
    got = dict(answers or {})
    right = sum(1 for a in got.values() if a.correct)
    asked = sum(1 for s in lesson.steps if s.question is not None)
    body = [f"<h1>{esc(lesson.title)}</h1>",
            f'<p class="note">Lesson {esc(lesson.name)} ({esc(lesson.source)}), '
            f"{len(lesson.steps)} steps, {asked} questions"
            + (f"; {right} of {asked} answered correctly" if answers is not None else "")
            + (f"; student {esc(student)}" if student else "")
            + ". Made by rough-viewer.</p>",
            *_paragraphs(lesson.introduction)]
    for k, step in enumerate(lesson.steps):
        body += _step_html(lesson, k, step, got.get(k), unit)
    return html_page(f"Lesson handout: {lesson.title}", body, css=_CSS)
