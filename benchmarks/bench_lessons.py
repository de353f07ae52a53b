"""Benchmark of the Lesson tab, in the app's job path: how long a step takes to set
its scene up (its cloud read and shown, the map at the step's grid, the panels),
how long a Check takes and how long the handout takes to build.

On a running app (``build_app`` on a real viser server, no browser) every bundled
lesson is opened and walked through step by step, ``--repeat`` times (the first
round reads each scene's cloud; later rounds find it among the clouds kept and the
grids cached). Printed per lesson, as medians over the rounds:

- ``step k``: from "Next step" (the job submitted) until the worker is idle (the
  load, the map at the step's grid, the panels, the camera);
- ``check``: one Check (the tool's number and the step's figure);
- ``handout``: the page with every answer and figure, and its size.

    PYTHONPATH=. python benchmarks/bench_lessons.py
    PYTHONPATH=. python benchmarks/bench_lessons.py --repeat 5 --lessons tilted-board
"""

from __future__ import annotations

import argparse
import statistics
import time

import viser

from rough_viewer.app.features.lesson import CheckJob, LessonFeature, LessonJob
from rough_viewer.app.server import build_app
from rough_viewer.lessons import bundled_names
from rough_viewer.lessons.handout import handout_html
from rough_viewer.synthetic.demos import load_demo


def walk(app, f: LessonFeature, name: str) -> dict[str, float]:
    """One pass through lesson ``name``: seconds per step, per check, handout."""
    out: dict[str, float] = {}
    for k in range(len(f.lessons[name].steps)):
        t = time.perf_counter()
        app.submit(LessonJob(f, "open", name=name) if k == 0 else LessonJob(f, "go", delta=1))
        assert app.wait_idle(300)
        out[f"step {k + 1}"] = time.perf_counter() - t
        if f.lesson is not None and f.lesson.steps[k].question is not None:
            if f.lesson.steps[k].question.measure == "point":
                continue  # needs a click: the tests do it
            t = time.perf_counter()
            app.submit(CheckJob(f, 1.0))
            assert app.wait_idle(120)
            out.setdefault("check", 0.0)
            out["check"] = max(out["check"], time.perf_counter() - t)
    t = time.perf_counter()
    page = handout_html(f.lesson, dict(f.answers))  # type: ignore[arg-type]
    out["handout"] = time.perf_counter() - t
    out["handout MB"] = len(page.encode()) / 1e6
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--lessons", nargs="+", default=bundled_names())
    args = ap.parse_args()
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = build_app(server, load_demo("outcrop-small"), prefetch=False)
    assert app.wait_idle(300)
    f = app.feature(LessonFeature)
    try:
        for name in args.lessons:
            rounds = [walk(app, f, name) for _ in range(max(1, args.repeat))]
            first = rounds[0]
            print(f"{name}: medians of {len(rounds)} rounds (first round in brackets)")
            for key in first:
                med = statistics.median(r[key] for r in rounds)
                unit = "" if key.endswith("MB") else " s"
                print(f"  {key:<12} {med:8.2f}{unit}  [{first[key]:.2f}]")
    finally:
        app.stop()
        server.stop()


if __name__ == "__main__":
    main()
