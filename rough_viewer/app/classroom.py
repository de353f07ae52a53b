"""A classroom on one server: every browser tab its own analysis (``serve --classroom``).

Without ``--classroom`` the app is one analysis its tabs share (:func:`build_app` on
the server's own GUI). With it, every tab that connects gets an app of its own
(:func:`~rough_viewer.app.server.mount_app` on the tab's stage,
:class:`~rough_viewer.app.stage.TabStage`): its controls, settings, colours,
panels, crop, selections, profiles, zones, sets, directions and measures, its own
worker thread (so one tab's fine grid never holds up another's answer) and its own
messages; what no tab changes is shared: the loaded cloud with its octree and
every computed grid (one cache under one budget, one computation per grid however
many tabs ask: :meth:`~rough_viewer.app.store.InMemoryStore.one_at_a_time`), the
reader sandbox, and the compute slots that bound how many grids are computed at
once (:class:`~rough_viewer.app.cache.ComputeSlots`).

A tab's role comes from the token in its address (:class:`~rough_viewer.app.gate.Gate`):
the students' address opens a student's tab, the teacher's address a teacher's tab,
which has the Class tab as well (:mod:`rough_viewer.app.features.classroom`). A
student's token never opens the teacher's tab: the role is the token's, and the two
tokens are independent random strings.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import ClassVar, Literal

import viser

from rough_viewer.app import hooks
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.features import classroom as class_tab
from rough_viewer.app.gate import Gate
from rough_viewer.app.host import AppOptions, Host, LessonReporter, Student
from rough_viewer.app.server import App, Mount, mount_app
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.stage import TabStage
from rough_viewer.app.views import camera_of
from rough_viewer.app.worker import Job, Run
from rough_viewer.report.view import Camera

Role = Literal["teacher", "student"]


@dataclass(frozen=True)
class PlaceCameraJob(Job[Host]):
    """Put this tab's camera where another tab's is (a teacher's view sent)."""

    camera: Camera
    """File frame, metres (:func:`rough_viewer.app.views.camera_of`)."""
    lane: ClassVar[str] = "class-camera"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        ctx.scene.place_camera(ctx.session.shown.loaded, self.camera)
        yield "camera"


@dataclass(eq=False)
class Room:
    """One tab of the classroom: its role, short name, stage and app."""

    name: str
    role: Role
    stage: TabStage
    app: App

    @property
    def client_id(self) -> int:
        return self.stage.client_id


@dataclass(eq=False)
class Classroom:
    """Every tab of ``server`` its own analysis of ``loaded`` (see the module).

    Parameters
    ----------
    server
        The running viser server (behind ``gate``).
    gate
        Its gate: which token each tab came with (None: every tab a student's).
    loaded
        The cloud every tab opens on (shared: its grids are computed once).
    settings
        The map every tab opens with (until the teacher sends another).
    options
        The apps' options (one cache budget and one set of compute slots for all).
    extra
        More features for every tab (after :data:`~rough_viewer.app.server.FEATURES`).
    """

    server: viser.ViserServer
    gate: Gate | None
    loaded: LoadedCloud
    settings: MapSettings
    options: AppOptions
    extra: Sequence[Mount] = ()
    prepare: Callable[[App, Role], None] | None = None
    """Called with each tab's app once it is built (a saved view restored, ...)."""
    rooms: dict[int, Room] = field(default_factory=dict)
    _building: set[int] = field(default_factory=set)
    _listeners: list[tuple[Host, Callable[[], None]]] = field(default_factory=list)
    _following: Room | None = None
    _lock: threading.RLock = field(default_factory=threading.RLock)
    _students: Iterator[int] = field(default_factory=lambda: itertools.count(1))
    _teachers: Iterator[int] = field(default_factory=lambda: itertools.count(1))
    _closed: bool = False

    def start(self) -> Classroom:
        """Give every tab connected now, and each one that comes, its own app."""
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._leave)
        for client in list(self.server.get_clients().values()):
            self._connect(client)
        return self

    def stop(self) -> None:
        """Stop every tab's app."""
        with self._lock:
            self._closed = True
            rooms = list(self.rooms.values())
            self.rooms.clear()
        for room in rooms:
            self._close(room)

    # ------------------------------------------------------------------ tabs
    def role_of(self, client: viser.ClientHandle) -> Role:
        """The tab's role, from the token its WebSocket came with."""
        if self.gate is None:
            return "student"
        connection = hooks.connection_of(self.server, client.client_id)
        return "teacher" if self.gate.is_teacher(connection) else "student"

    def _connect(self, client: viser.ClientHandle) -> None:
        cid = int(client.client_id)
        role = self.role_of(client)
        with self._lock:
            if self._closed or cid in self.rooms or cid in self._building:
                return
            self._building.add(cid)
            number = next(self._teachers if role == "teacher" else self._students)
        name = f"{'T' if role == 'teacher' else 'S'}{number}"
        try:
            room = self._build(client, role, name)
        finally:
            with self._lock:
                self._building.discard(cid)
        with self._lock:
            if self._closed or cid not in self.server.get_clients():
                gone = True
            else:
                gone = False
                self.rooms[cid] = room
        if gone:
            self._close(room)
            return
        room.stage.start()
        leader = self._following
        if role == "student" and leader is not None:
            self._send(leader, [room])
        self._changed()

    def _build(self, client: viser.ClientHandle, role: Role, name: str) -> Room:
        stage = TabStage(self.server, client)
        extra: tuple[Mount, ...] = tuple(self.extra)
        if role == "teacher":
            extra += (partial(class_tab.mount, service=self),)
        app = mount_app(stage, self.loaded, self.settings, self.options, extra=extra)
        room = Room(name, role, stage, app)
        app.host.on_render(partial(self._rendered, room), late=True)
        if self.prepare is not None:
            self.prepare(app, role)
        return room

    def _leave(self, client: viser.ClientHandle) -> None:
        with self._lock:
            room = self.rooms.pop(int(client.client_id), None)
            if room is not None and self._following is room:
                self._following = None
        if room is not None:
            self._close(room)
            self._changed()

    def _close(self, room: Room) -> None:
        with self._lock:
            self._listeners = [(h, f) for h, f in self._listeners if h is not room.app.host]
        room.stage.left()
        session = room.app.session
        room.app.stop()
        for loaded in {id(x): x for x in (self.loaded, session.shown.loaded)}.values():
            loaded.forget_shown(session)

    def _rendered(self, room: Room) -> None:
        """A tab showed a map (on its worker): the teacher's, while followed, goes to
        every student; the Class tab lists what each shows."""
        if self._following is room:
            self._send(room, self._student_rooms())
        self._changed()

    # ------------------------------------------------------------------ the class
    def _student_rooms(self) -> list[Room]:
        with self._lock:
            return [r for r in self.rooms.values() if r.role == "student"]

    def _room_of(self, host: Host) -> Room | None:
        with self._lock:
            return next((r for r in self.rooms.values() if r.app.host is host), None)

    def students(self) -> list[Student]:
        out = []
        following = self._following is not None
        for room in self._student_rooms():
            s = room.app.session.shown.settings
            lesson, answers = lesson_line(room.app)
            out.append(Student(room.name, room.client_id, float(s.cell_size), s.model,
                               float(s.threshold), s.axis, following, lesson, answers))
        return out

    def send_view(self, teacher: Host) -> int:
        room = self._room_of(teacher)
        if room is None:
            return 0
        students = self._student_rooms()
        self._send(room, students)
        return len(students)

    def _send(self, source: Room, targets: Sequence[Room]) -> None:
        """``source``'s cloud, settings and camera to each of ``targets``."""
        shown = source.app.session.shown
        camera = camera_of(source.app.host, source.stage.client)
        for room in targets:
            room.app.host.show_view(shown.loaded, shown.settings)
            if camera is not None:
                room.app.submit(PlaceCameraJob(camera))

    def follow(self, teacher: Host, on: bool) -> None:
        room = self._room_of(teacher)
        with self._lock:
            self._following = room if on else None
        if on and room is not None:
            self._send(room, self._student_rooms())
        self._changed()

    @property
    def following(self) -> bool:
        return self._following is not None

    def show_student(self, teacher: Host, name: str) -> bool:
        mine = self._room_of(teacher)
        with self._lock:
            theirs = next((r for r in self.rooms.values() if r.name == name), None)
        if mine is None or theirs is None:
            return False
        self._send(theirs, [mine])
        return True

    def on_change(self, host: Host, listener: Callable[[], None]) -> None:
        with self._lock:
            self._listeners.append((host, listener))

    def _changed(self) -> None:
        with self._lock:
            live = {id(r.app.host) for r in self.rooms.values()}
            listeners = [f for h, f in self._listeners if id(h) in live]
        for listener in listeners:
            listener()


def lesson_line(app: App) -> tuple[str, str]:
    """(where the tab is in its lesson, how its answers went), "" each without one.

    The Lesson tab reports both (:class:`~rough_viewer.app.host.LessonReporter`)."""
    for feature in app.features:
        if not isinstance(feature, LessonReporter):
            continue
        st = feature.lesson_status()
        if not st.lesson or not st.steps:
            return "", ""
        right = sum(1 for a in st.answers if a.correct)
        told = ""
        if st.answers:  # each answer (its step, the number given, right or not), then the count
            each = ", ".join(f"step {a.step + 1}: {a.given:.3g} {'✓' if a.correct else '✗'}"
                             for a in st.answers)
            told = f"{each} ({right} of {len(st.answers)} right)"
        return f"{st.lesson} {st.step + 1}/{st.steps}", told
    return "", ""
