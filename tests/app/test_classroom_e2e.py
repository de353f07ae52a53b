"""A classroom in headless Chromium: a teacher and two students on one server.

Each page is a real viser client in Chromium (software WebGL) on a real classroom
(the gate with its two tokens, one app per tab). Screenshots of the three pages are
written to ``$ROUGH_VIEWER_SHOTS`` when it is set (for a person to look at)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import pytest

from rough_viewer.app.classroom import Classroom
from rough_viewer.app.features.classroom import L_SEND
from rough_viewer.app.gate import new_token, open_server
from rough_viewer.app.server import app_options, shared_cloud
from rough_viewer.app.settings import MapSettings
from tests.app import browser as b
from tests.helpers import face_cloud

pytestmark = pytest.mark.browser


def _shot(page, name: str) -> None:
    folder = os.environ.get("ROUGH_VIEWER_SHOTS")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(Path(folder) / f"{name}.png"))


def _status(page) -> str:
    return page.locator("p", has_text=" grid ").first.inner_text()


def test_a_teacher_and_two_students(chromium):
    server, gate = open_server("127.0.0.1", 0, token=new_token(), teacher_token=new_token(),
                               log=False)
    cloud = face_cloud(60_000, seed=3)
    options = dataclasses.replace(app_options(cloud, prefetch=False), compute_slots=2)
    loaded = shared_cloud(cloud, options)
    room = Classroom(server, gate, loaded, MapSettings(cell_size=loaded.default_cell_size),
                     options).start()
    contexts = []
    try:
        pages = {}
        for name, path in (("teacher", gate.teacher_path), ("student-1", gate.path),
                           ("student-2", gate.path)):
            ctx = chromium.new_context(viewport=b.VIEWPORT)
            ctx.set_default_timeout(30_000)
            contexts.append(ctx)
            page = ctx.new_page()
            page.goto(f"http://127.0.0.1:{server.get_port()}{path}?fixedDpr=1&hideViserLogo")
            b.wait_coloured(page, 0.05, timeout=120)
            b.hide_toasts(page)
            pages[name] = page
        b.wait_until(lambda: len(room.rooms) == 3, 60, "three tabs, three apps")
        by_role = {r.role: r for r in room.rooms.values()}
        teacher = by_role["teacher"]
        students = sorted((r for r in room.rooms.values() if r.role == "student"),
                          key=lambda r: r.name)
        for r in room.rooms.values():
            assert r.app.wait_idle(120)
        # only the teacher's page has the Class tab
        assert pages["teacher"].get_by_role("tab", name="Class").count() == 1
        assert pages["student-1"].get_by_role("tab", name="Class").count() == 0
        assert pages["student-2"].get_by_role("tab", name="Class").count() == 0
        # each student picks a map of their own, in their own page
        s1_page = next(p for n, p in pages.items() if n == "student-1")
        s2_page = pages["student-2"]
        b.choose(s1_page, "Model", "OLS")
        coarse = students[0].app.map.grid.options[0]
        b.choose(s2_page, "Grid size (m)", coarse)
        b.wait_until(lambda: {r.app.session.shown.settings.model for r in students} == {"odr", "ols"}
                     and any(r.app.map.grid.value == coarse for r in students), 60,
                     "each student's own map")
        for r in students:
            assert r.app.wait_idle(60)
        ols = next(r for r in students if r.app.session.shown.settings.model == "ols")
        other = next(r for r in students if r is not ols)
        assert other.app.session.shown.settings.model == "odr"
        assert ols.app.map.grid.value != coarse and other.app.map.grid.value == coarse
        assert teacher.app.session.shown.settings.model == "odr"
        b.wait_until(lambda: "OLS, grid" in _status(s1_page), 30, "student 1's status line")
        b.wait_until(lambda: f"ODR, grid {coarse} m" in _status(s2_page), 30,
                     "student 2's status line")
        for name, page in pages.items():
            _shot(page, f"1-{name}-own-choice")
        # the teacher lists them and sends a view
        tp = pages["teacher"]
        b.choose(tp, "Model", "OLS")
        b.wait_until(lambda: teacher.app.session.shown.settings.model == "ols", 60,
                     "the teacher's OLS map")
        assert teacher.app.wait_idle(60)
        tp.get_by_role("tab", name="Class").click()
        tp.get_by_text("2 students").wait_for()
        _shot(tp, "2-teacher-class-tab")
        tp.get_by_role("button", name=L_SEND).click()
        mine = teacher.app.session.shown.settings
        b.wait_until(lambda: all(r.app.session.shown.settings == mine for r in students), 60,
                     "every student on the teacher's view")
        for page in (s1_page, s2_page):
            b.wait_until(lambda page=page: f"OLS, grid {teacher.app.map.grid.value} m"
                         in _status(page), 30, "the teacher's map in a student's page")
        for name, page in pages.items():
            _shot(page, f"3-{name}-after-send")
    finally:
        for ctx in contexts:
            ctx.close()
        room.stop()
        server.stop()
