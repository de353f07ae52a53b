"""The single-writer rule: the session and the scene change on the worker only."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import pytest

from rough_viewer.app.session import Session, Shown
from rough_viewer.app.worker import Job, NotOnWorker, Run
from tests.app.protocol import shown_colours


def test_a_session_write_from_another_thread_fails(app):
    shown = app.session.shown
    with pytest.raises(NotOnWorker, match="session.shown"):
        app.session.shown = shown  # the test's thread is not the worker
    with pytest.raises(NotOnWorker, match="session.stashed"):
        app.session.put_aside()
    with pytest.raises(AttributeError):
        app.session.anything = 1
    assert app.session.shown is shown and app.session.stashed is None


def test_a_scene_write_from_another_thread_fails(app):
    before = np.asarray(shown_colours(app)).copy()
    grey = np.zeros_like(before)
    for write in (lambda: app.host.scene.colour_by(lambda idx: grey[:len(idx)]),
                  lambda: app.host.scene.set_point_size(0.5),
                  lambda: app.host.scene.set_budget(10),
                  lambda: app.host.scene.marker("/x", np.zeros(3)),
                  lambda: app.host.scene.move_cameras(app.session.shown.loaded, "top")):
        with pytest.raises(NotOnWorker, match="the scene"):
            write()
    np.testing.assert_array_equal(shown_colours(app), before)
    assert app.host.scene.point_size != 0.5 and app.host.scene.budget != 10


@dataclass(frozen=True)
class Writes(Job[Any]):
    """Writes the session and the scene from inside a job (on the worker)."""

    seen: list[str] = field(compare=False)
    lane: ClassVar[str] = "writes"

    def stages(self, ctx: Any, run: Run) -> Iterator[str]:
        ctx.session.shown = ctx.session.shown
        ctx.scene.set_point_size(ctx.scene.point_size)
        self.seen.append(threading.current_thread().name)
        yield "written"


def test_jobs_write_on_the_worker(app):
    seen: list[str] = []
    app.submit(Writes(seen))
    assert app.wait_idle(30)
    assert seen == [app.worker._thread.name] and list(app.host.errors) == []


def test_a_session_without_a_writer_check_is_refused_by_its_check():
    def never(what: str) -> None:
        raise NotOnWorker(what)

    s = Session(Shown(loaded=None, settings=None), never)  # type: ignore[arg-type]
    with pytest.raises(NotOnWorker):
        s.face_key = (1,)
    assert s.face_key is None


@dataclass(frozen=True)
class Bug(Job[Any]):
    lane: ClassVar[str] = "bug"

    @property
    def title(self) -> str:
        return "a broken job"

    def stages(self, ctx: Any, run: Run) -> Iterator[str]:
        raise KeyError("not a user's error")
        yield "never"


def test_a_bug_is_logged_and_named_as_an_internal_error(app, capfd):
    app.submit(Bug())
    assert app.wait_idle(30)
    err = capfd.readouterr().err
    assert "Traceback" in err and "KeyError" in err  # on the server's terminal
    msg = app.host.errors[-1]
    assert msg.startswith("internal error: a broken job failed (KeyError)")
    assert "Traceback" not in app.host.error.content and "not a user" not in msg


def test_messages_and_binding_writes_from_another_thread_fail(app):
    """The shell's lines above the tabs and every binding's writes are the worker's,
    as the session and the scene are (issue 32 item 4)."""
    from rough_viewer.app.binding import Binding

    host = app.host
    status = host.status.content
    for write, what in ((lambda: host.show_error("x"), "the error line"),
                        (lambda: host.clear_error(), "the error line"),
                        (lambda: host.say("x"), "the status line"),
                        (lambda: host.warn("x"), "the notes"),
                        (lambda: host.pin("x"), "the pinned note"),
                        (lambda: host.progress(50.0), "the progress bar")):
        with pytest.raises(NotOnWorker, match=what):
            write()
    b = Binding()
    for write in (lambda: b.set(app.map.threshold, 0.9),
                  lambda: b.write(app.map.pick, content="x"),
                  lambda: b.show_figure(app.map.scales, app.map.scales.figure)):
        with pytest.raises(NotOnWorker):
            write()
    assert host.status.content == status and list(host.errors) == []
    assert app.map.threshold.value != 0.9 and app.map.pick.content != "x"


def test_the_selection_is_the_sessions(app):
    """The Select tab's selection lives in the session (one analysis holds it), so a
    write from another thread fails there, and a job's selection is the session's."""
    from rough_viewer.app.features.crop import CropFeature
    from tests.app.protocol import on_worker

    f = app.host.feature(CropFeature)
    loaded = app.session.shown.loaded
    mask = np.zeros(loaded.cloud.n, dtype=bool)
    mask[:500] = True
    with pytest.raises(NotOnWorker, match="session.selection"):
        f.selection = None
    on_worker(app, lambda: f.select(mask))
    assert app.session.selection is f.selection is not None
    assert f.selection.count == 500 and f.selection.loaded is loaded
