"""``serve --classroom``: every tab its own analysis, the teacher's Class tab.

Real viser server behind the real gate (two tokens), real WebSocket tabs
(tests/app/protocol.py), the real Classroom building one app per tab."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rough_viewer.app.classroom import Classroom
from rough_viewer.app.features.classroom import L_FOLLOW, L_SEND, L_SHOW, L_STUDENT
from rough_viewer.app.gate import new_token, open_server
from rough_viewer.app.server import app_options, shared_cloud
from rough_viewer.app.settings import MODEL_LABELS, MapSettings
from tests.app.browser import wait_until
from tests.app.protocol import ProtocolClient, shown_colours


@pytest.fixture
def classroom(cloud):
    server, gate = open_server("127.0.0.1", 0, token=new_token(), teacher_token=new_token(),
                               log=False)
    options = dataclasses.replace(app_options(cloud, prefetch=False), compute_slots=2)
    loaded = shared_cloud(cloud, options)
    room = Classroom(server, gate, loaded, MapSettings(cell_size=loaded.default_cell_size),
                     options).start()
    tabs: list[ProtocolClient] = []

    def join(teacher: bool = False) -> tuple[ProtocolClient, object]:
        before = set(room.rooms)
        tab = ProtocolClient(server.get_port(), gate.teacher_path if teacher else gate.path)
        tabs.append(tab)
        new = wait_until(lambda: set(room.rooms) - before, 60, "the tab's own app")
        r = room.rooms[max(new)]
        assert r.app.wait_idle(120)
        return tab, r

    yield room, join, gate
    for tab in tabs:
        tab.close()
    room.stop()
    server.stop()


def _quiet(tab, still_s: float = 1.5) -> int:
    """The tab's message count once nothing more came for ``still_s`` (viser sends in
    windows: what its app did before may still be on the way)."""
    import time

    count, since = len(tab.messages), time.time()
    while time.time() - since < still_s:
        time.sleep(0.1)
        if len(tab.messages) != count:
            count, since = len(tab.messages), time.time()
    return count


def _settle(room, cond, what):
    wait_until(lambda: cond() and not room.app.worker.busy, 60, what)
    assert room.app.wait_idle(60)


def test_two_tabs_keep_their_own_settings_and_colours(classroom):
    room, join, _gate = classroom
    a, ra = join()
    b, rb = join()
    assert ra.role == rb.role == "student" and ra.app.host is not rb.app.host
    assert ra.app.session.shown.loaded is rb.app.session.shown.loaded  # one shared cloud
    before_b = shown_colours(rb.app).copy()
    grids = list(ra.app.map.grid.options)
    coarse = grids[0]
    since = _quiet(b)
    a.set_value("Grid size (m)", coarse)
    a.set_value("Model", MODEL_LABELS["ols"])
    _settle(ra, lambda: ra.app.session.shown.settings.model == "ols"
            and ra.app.map.grid.value == coarse, "tab A's own map")
    sa, sb = ra.app.session.shown.settings, rb.app.session.shown.settings
    assert sa.model == "ols" and sb.model == "odr"
    assert sa.cell_size > sb.cell_size
    # B's colours are B's ODR map still; A's are its own OLS map at the coarse grid
    assert np.array_equal(shown_colours(rb.app), before_b)
    assert not np.array_equal(shown_colours(ra.app), shown_colours(rb.app))
    # and B's browser was sent nothing by A's change
    assert b.messages[since:] == []
    # B's status line still names its own model and grid
    assert "ODR, grid" in rb.app.host.status.content
    assert "OLS, grid" in ra.app.host.status.content
    # the grid both had is computed once (shared cache) and each shows its own result
    assert ra.app.session.shown.result is not rb.app.session.shown.result


def test_teacher_sends_and_follow_reaches_every_student(classroom):
    room, join, _gate = classroom
    t, rt = join(teacher=True)
    _s1, r1 = join()
    _s2, r2 = join()
    assert rt.role == "teacher" and rt.name.startswith("T")
    coarse = list(rt.app.map.grid.options)[0]
    t.set_value("Grid size (m)", coarse)
    t.set_value("Model", MODEL_LABELS["ols"])
    _settle(rt, lambda: rt.app.session.shown.settings.model == "ols"
            and rt.app.map.grid.value == coarse, "the teacher's map")
    mine = rt.app.session.shown.settings
    t.press(L_SEND)
    for r in (r1, r2):
        _settle(r, lambda r=r: r.app.session.shown.settings == mine, "the teacher's view sent")
        assert r.app.map.model.value == MODEL_LABELS["ols"]
        assert r.app.map.grid.value == coarse
    # follow: every map the teacher shows from now on goes to the students
    t.set_value(L_FOLLOW, True)
    wait_until(lambda: room.following, 30, "follow on")
    t.set_value("Model", MODEL_LABELS["hybrid"])
    _settle(rt, lambda: rt.app.session.shown.settings.model == "hybrid", "teacher's hybrid")
    for r in (r1, r2):
        _settle(r, lambda r=r: r.app.session.shown.settings.model == "hybrid",
                "students follow")
    # released: the teacher's next map stays the teacher's
    t.set_value(L_FOLLOW, False)
    wait_until(lambda: not room.following, 30, "follow off")
    t.set_value("Model", MODEL_LABELS["odr"])
    _settle(rt, lambda: rt.app.session.shown.settings.model == "odr", "teacher's odr")
    for r in (r1, r2):
        assert r.app.wait_idle(60)
        assert r.app.session.shown.settings.model == "hybrid"
    # the Class tab lists both students with what they show
    listed = {s.name: s for s in room.students()}
    assert set(listed) == {r1.name, r2.name}
    assert all(s.model == "hybrid" for s in listed.values())
    table = rt.app.feature(_class_tab()).table
    wait_until(lambda: r1.name in table.content and r2.name in table.content
               and "HYBRID" in table.content, 30, "the Class tab's table")


def test_teacher_sees_a_students_view(classroom):
    room, join, _gate = classroom
    t, rt = join(teacher=True)
    s, rs = join()
    s.set_value("Model", MODEL_LABELS["ols"])
    _settle(rs, lambda: rs.app.session.shown.settings.model == "ols", "the student's map")
    wait_until(lambda: rs.name in rt.app.feature(_class_tab()).student.options, 30,
               "the student in the Class tab")
    t.set_value(L_STUDENT, rs.name)
    t.press(L_SHOW)
    _settle(rt, lambda: rt.app.session.shown.settings.model == "ols", "the student's view")
    assert rt.app.session.shown.settings == rs.app.session.shown.settings


def _class_tab():
    from rough_viewer.app.features.classroom import ClassTab

    return ClassTab


def test_a_students_token_opens_no_class_controls(classroom):
    room, join, gate = classroom
    t, rt = join(teacher=True)
    s, rs = join()
    labels_t = {m["props"].get("label") for m in t.messages
                if isinstance(m.get("props"), dict)}
    labels_s = {m["props"].get("label") for m in s.messages
                if isinstance(m.get("props"), dict)}
    assert {L_SEND, L_FOLLOW, L_SHOW} <= labels_t
    assert not ({L_SEND, L_FOLLOW, L_SHOW, L_STUDENT} & labels_s)
    assert "Model" in labels_s and "Model" in labels_t
    with pytest.raises(KeyError):
        rs.app.feature(_class_tab())
    # a student who sends the teacher's button id gets nothing done
    send_uuid = t.uuid(L_SEND)
    s.send({"type": "GuiUpdateMessage", "uuid": send_uuid, "updates": {"value": True}})
    t.set_value("Model", MODEL_LABELS["ols"])
    _settle(rt, lambda: rt.app.session.shown.settings.model == "ols", "teacher's map")
    assert rs.app.wait_idle(30)
    assert rs.app.session.shown.settings.model == "odr"
    # the two tokens differ and a wrong one is refused
    assert gate.token != gate.teacher_token
    from websockets.exceptions import InvalidStatus

    with pytest.raises(InvalidStatus):
        ProtocolClient(rt.app.server.get_port(), "/t/not-a-token/")


def test_a_tab_that_leaves_frees_its_app(classroom):
    room, join, _gate = classroom
    a, ra = join()
    b, rb = join()
    a.close()
    wait_until(lambda: ra.client_id not in room.rooms, 30, "the tab's app to go")
    wait_until(lambda: not ra.app.worker._thread.is_alive(), 30, "its worker to end")
    assert rb.client_id in room.rooms and rb.app.wait_idle(30)
    assert [s.name for s in room.students()] == [rb.name]


def test_one_students_slow_grid_does_not_hold_up_another(classroom, monkeypatch):
    """Student A asks for a grid that takes seconds (slowed here); student B's own new
    grid is answered meanwhile (its own worker, the second compute slot)."""
    import threading

    from rough_viewer.app import store

    room, join, _gate = classroom
    a, ra = join()
    b, rb = join()
    presets = list(ra.app.session.shown.loaded.presets)  # coarsest first
    slow_size, quick_size = presets[0], presets[1]
    release = threading.Event()
    held: list[int] = []
    real = store.grid_roughness

    def grid(cloud, cell_size, **kw):
        if abs(cell_size - slow_size) < 1e-12 and kw.get("axis") == "z":
            if not release.is_set():
                held.append(1)
            release.wait(30)  # A's grid: held until B has its answer
        return real(cloud, cell_size, **kw)

    monkeypatch.setattr(store, "grid_roughness", grid)
    grids = {g: v for g, v in zip(ra.app.map.grid.options, ra.app.map.grid.options,
                                  strict=True)}
    slow = next(g for g in grids if abs(float(g) - slow_size) < 1e-9)
    quick = next(g for g in grids if abs(float(g) - quick_size) < 1e-9)
    a.set_value("Dependent axis", "z")
    a.set_value("Grid size (m)", slow)
    wait_until(lambda: ra.app.worker.busy, 30, "A's slow grid to start")
    b.set_value("Dependent axis", "z")
    b.set_value("Grid size (m)", quick)
    try:
        # B's map (its panels may wait for A's grid: the trend across grid sizes
        # needs every preset, and that grid is computed once, by A)
        wait_until(lambda: rb.app.session.shown.settings.cell_size == pytest.approx(quick_size)
                   and rb.app.session.shown.settings.axis == "z", 20,
                   "B's own grid while A waits")
        assert held == [1]  # A's grid is being computed, once (B's panels wait for it)
        assert ra.app.worker.busy
        assert ra.app.worker.busy  # A is still computing its grid
        assert ra.app.session.shown.settings.cell_size != pytest.approx(slow_size)
    finally:
        release.set()
    _settle(ra, lambda: ra.app.session.shown.settings.cell_size == pytest.approx(slow_size),
            "A's slow grid in the end")


def test_tabs_on_one_grid_share_its_panels(classroom):
    """Two tabs on the same grid: its histogram and semivariogram are made once and
    both tabs show the same figures."""
    from rough_viewer.app.features.panels import PanelsFeature

    room, join, _gate = classroom
    _a, ra = join()
    _b, rb = join()
    for r in (ra, rb):
        wait_until(lambda r=r: r.app.session.panel_key is not None, 60, "the panels")
        assert r.app.wait_idle(60)
    loaded = ra.app.session.shown.loaded
    assert loaded is rb.app.session.shown.loaded
    keys = list(loaded._derived._items)  # type: ignore[attr-defined]
    assert loaded._derived.made == len(keys)  # type: ignore[attr-defined]
    assert sum(1 for k in keys if k[0] == "variogram") >= 1
    pa, pb = ra.app.feature(PanelsFeature), rb.app.feature(PanelsFeature)
    assert pa.variogram.figure is pb.variogram.figure
    assert pa.histogram.figure is pb.histogram.figure
