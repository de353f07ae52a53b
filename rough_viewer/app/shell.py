"""The shell: the one :class:`~rough_viewer.app.host.Host` of an app.

It holds what every feature shares and no feature owns: the viser server's GUI and
its tab group, the checks of browsers' values (:mod:`.controls`) and uploads
(:mod:`.uploads`), the worker that runs every job, the session and the scene (both
written on the worker only), the events between features, and the messages above
the tabs (status line, error line, a pinned note, notes, progress bar), which
are written on the worker only (as the session and the scene).
"""

from __future__ import annotations

import contextlib
import sys
import traceback
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

import viser

from rough_viewer.app.binding import assign
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import Colouring
from rough_viewer.app.controls import ClientValues
from rough_viewer.app.files import UploadedFile
from rough_viewer.app.host import AppOptions, ClickHandler, CloudSource, MapService, Pick, Rule
from rough_viewer.app.limits import (
    MAX_ERRORS,
    MAX_JOB_RECORDS,
    MAX_MESSAGE,
    MAX_PENDING_JOBS,
)
from rough_viewer.app.markup import md
from rough_viewer.app.scene import Scene
from rough_viewer.app.session import Session, Shown
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.stage import Stage, stage_of
from rough_viewer.app.uploads import Uploads
from rough_viewer.app.worker import Job, QueueFull, Run, Worker
from rough_viewer.io.load import SUPPORTED_SUFFIXES
from rough_viewer.vocabulary import InputError

#: Label of the folder that holds the notes that stay.
NOTICE_FOLDER = "Notice details"


def notice_summary(notes: str) -> str:
    r"""One line naming the notes (their bold labels: ``**Warning:**`` ...), for above
    the tabs; the notes themselves go in the closed :data:`NOTICE_FOLDER`.

    >>> notice_summary("**Warning:** a  \n**Warning:** b  \n**Outliers:** 3 cells")
    '⚠ **3 notices**: 2 warnings, outliers — open *Notice details*'
    """
    if not notes:
        return ""
    labels: dict[str, int] = {}
    lines = [line for line in notes.split("  \n") if line.strip()]
    for line in lines:
        label = line[2:line.index(":**")] if line.startswith("**") and ":**" in line \
            else "note"
        labels[label] = labels.get(label, 0) + 1
    named = ", ".join(f"{n} {k.lower()}s" if n > 1 else k.lower() for k, n in labels.items())
    count = "1 notice" if len(lines) == 1 else f"{len(lines)} notices"
    return f"⚠ **{count}**: {named} — open *{NOTICE_FOLDER}*"

T = TypeVar("T")


class Shell:
    """The host of one app (see the module docstring and :class:`~.host.Host`).

    Parameters
    ----------
    server
        A running viser server (the app on its shared GUI), or a stage (one tab's
        own: :mod:`rough_viewer.app.stage`).
    options
        The app's limits and switches.
    shown
        What the app shows before its first job (the cloud it was started on).
    """

    def __init__(self, server: viser.ViserServer | Stage, options: AppOptions,
                 shown: Shown) -> None:
        self.stage = stage = stage_of(server)
        """Where the app is shown: the server's shared GUI, or one tab's own."""
        self.server = stage.server
        self._options = options
        self._features: list[object] = []
        self._map: MapService | None = None
        self._cloud: list[Callable[[], None]] = []
        self._render: list[Callable[[], None]] = []
        self._render_late: list[Callable[[], None]] = []
        self._click: list[ClickHandler] = []
        self._idle: list[Callable[[Run], bool]] = []
        self.errors: deque[str] = deque(maxlen=MAX_ERRORS)
        """Error messages shown to the user, oldest first (the last :data:`MAX_ERRORS`)."""
        self.pinned = ""
        """The pinned note (:meth:`pin`), sent to each browser that connects."""
        self.worker: Worker[Shell] = Worker(self, on_error=self._on_error,
                                            idle=self._run_idle if options.prefetch else None,
                                            max_pending=MAX_PENDING_JOBS,
                                            max_records=MAX_JOB_RECORDS)
        self._session = Session(shown, self.worker.require_worker)
        self._scene = Scene(stage, self.worker.require_worker, budget=options.point_budget)
        self.controls = ClientValues(stage, self.notify_client)
        """The checks of every value a browser sends."""
        self.uploads = Uploads(
            stage, max_bytes=options.max_upload_bytes, suffixes=SUPPORTED_SUFFIXES,
            refuse=lambda cid, msg: self.notify_client(cid, "Upload refused", msg))
        """Uploads streamed to disk."""
        gui = stage.gui
        self.status = gui.add_markdown("Loading…")
        self.error = gui.add_markdown("", visible=False)
        self.note = gui.add_markdown("", visible=False)
        """The pinned note (a saved view's input moved or changed)."""
        self.notice_line = gui.add_markdown("", visible=False)
        """One line over the tabs naming the notes that stay (the airborne LAZ's eight
        lines pushed the tabs down); the notes themselves in :attr:`notice_folder`."""
        self.notice_folder = gui.add_folder(NOTICE_FOLDER, expand_by_default=False,
                                            visible=False)
        """A folder, closed at first, holding :attr:`notice`."""
        with self.notice_folder:
            self.notice = gui.add_markdown("", visible=False)
        """Notes that stay (reader warnings, a grid where most cells have no value)."""
        self.progress_bar = gui.add_progress_bar(0.0, visible=False, animated=True)
        self._tabs: viser.GuiTabGroupHandle | None = None
        self._tab_by_label: dict[str, Any] = {}

        @stage.on_client_connect
        def _(client: viser.ClientHandle) -> None:
            if self.pinned:
                client.add_notification("Saved view", self.pinned, auto_close_seconds=15.0,
                                        color="yellow")

    # ------------------------------------------------------------------ Host: state
    @property
    def options(self) -> AppOptions:
        return self._options

    @property
    def session(self) -> Session:
        return self._session

    @property
    def scene(self) -> Scene:
        return self._scene

    @property
    def gui(self) -> viser.GuiApi:
        return self.stage.gui

    def tab(self, label: str) -> contextlib.AbstractContextManager[object]:
        if self._tabs is None:
            self._tabs = self.stage.gui.add_tab_group()
        if label not in self._tab_by_label:  # a second call adds to the same tab
            self._tab_by_label[label] = self._tabs.add_tab(label)
        return self._tab_by_label[label]

    def folder(self, label: str) -> contextlib.AbstractContextManager[object]:
        return self.stage.gui.add_folder(label)

    def allow(self, *handles: Any) -> None:
        self.controls.allow(*handles)

    def rule(self, handle: Any, check: Rule) -> None:
        self.controls.rule(handle, check)

    def take_uploads(self, handle: Any, on_file: Callable[[UploadedFile], object]) -> None:
        self.uploads.register(handle, on_file)

    # ------------------------------------------------------------------ Host: work
    def submit(self, job: Job[Any]) -> int:
        from rough_viewer.app.binding import asking

        try:
            return self.worker.submit(job, owner=asking())
        except QueueFull:
            self.notify("Busy", "Too many requests are waiting; try again in a moment.",
                        color="yellow")
            return 0

    def on_idle(self, work: Callable[[Run], bool]) -> None:
        self._idle.append(work)

    def _run_idle(self, run: Run) -> bool:
        return any(work(run) for work in self._idle)

    def _on_error(self, job: Job[Any], exc: BaseException) -> None:
        """A job failed: the person's input (InputError) or memory is named; anything
        else is a bug, logged with its traceback on the server's terminal and named as
        an internal error in the browser (never a traceback or a server path)."""
        self.progress(None)
        if isinstance(exc, InputError):
            self.show_error(str(exc))
        elif isinstance(exc, MemoryError):
            self.show_error(f"{job.title}: not enough memory")
        else:
            traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
            self.show_error(f"internal error: {job.title} failed ({type(exc).__name__}); "
                            "the server's log has the details")

    # ------------------------------------------------------------------ Host: events
    def on_cloud(self, listener: Callable[[], None]) -> None:
        self._cloud.append(listener)

    def on_render(self, listener: Callable[[], None], *, late: bool = False) -> None:
        (self._render_late if late else self._render).append(listener)

    def on_click(self, handler: ClickHandler) -> None:
        self._click.append(handler)

    def on_connect(self, listener: Callable[[viser.ClientHandle], None]) -> None:
        self.stage.on_client_connect(listener)

    def on_disconnect(self, listener: Callable[[viser.ClientHandle], None]) -> None:
        self.stage.on_client_disconnect(listener)

    def cloud_shown(self) -> None:
        self.worker.require_worker("the new-cloud event")
        for listener in self._cloud:
            listener()

    def rendered(self) -> None:
        self.worker.require_worker("the render event")
        for listener in (*self._render, *self._render_late):
            listener()

    def picked(self, pick: Pick) -> bool:
        self.worker.require_worker("the click event")
        return any(handler(pick) for handler in self._click)

    # ------------------------------------------------------------------ Host: messages
    def notify(self, title: str, body: str, *, color: Any = None, seconds: float = 6.0) -> None:
        for client in self.stage.clients().values():
            client.add_notification(title, body, auto_close_seconds=seconds, color=color)

    def notify_client(self, client_id: int, title: str, body: str) -> None:
        client = self.stage.clients().get(client_id)
        if client is not None:
            client.add_notification(title, body, auto_close_seconds=10.0, color="red")

    def show_error(self, message: str, *, kept: str = "The previous view is kept.") -> None:
        self.worker.require_worker("the error line")
        self.errors.append(message)
        self.error.content = f"**Error:** {md(message, max_chars=MAX_MESSAGE)}  \n{kept}"
        self.error.visible = True
        self.notify("Error", message[:MAX_MESSAGE], color="red", seconds=10.0)

    def clear_error(self) -> None:
        self.worker.require_worker("the error line")
        if self.error.visible:
            self.error.visible = False

    def say(self, status: str) -> None:
        self.worker.require_worker("the status line")
        self.status.content = status

    def warn(self, notes: str) -> None:
        self.worker.require_worker("the notes")
        if notes == self.notice.content and self.notice.visible == bool(notes):
            return  # the same notes: the folder stays as the user left it
        self.notice.content = notes
        self.notice.visible = bool(notes)
        self.notice_line.content = notice_summary(notes)
        self.notice_line.visible = bool(notes)
        self.notice_folder.visible = bool(notes)

    def pin(self, text: str) -> None:
        self.worker.require_worker("the pinned note")
        self.pinned = text[:400]
        self.note.content = f"**Saved view:** {md(text, max_chars=400)}"
        self.note.visible = bool(text)

    def progress(self, percent: float | None) -> None:
        self.worker.require_worker("the progress bar")
        if percent is None:
            self.progress_bar.visible = False
            return
        assign(self.progress_bar, float(min(100.0, max(0.0, percent))))
        if not self.progress_bar.visible:
            self.progress_bar.visible = True

    def clients(self) -> dict[int, viser.ClientHandle]:
        return self.stage.clients()

    # ------------------------------------------------------------------ Host: the map
    def map(self) -> MapService:
        """The mounted map (the first feature, :class:`~.host.MapService`)."""
        if self._map is None:
            raise LookupError("no map is mounted")
        return self._map

    def request(self, **changes: object) -> int:
        return self.map().request(**changes)

    def settings(self) -> MapSettings:
        return self.map().settings()

    def take_overlay(self, owner: object, release: Callable[[], None],
                     colouring: Colouring) -> None:
        self.map().take_overlay(owner, release, colouring)

    def give_back_overlay(self, owner: object) -> None:
        self.map().give_back_overlay(owner)

    def holds_overlay(self, owner: object) -> bool:
        return self.map().holds_overlay(owner)

    def map_colouring(self) -> Colouring | None:
        return self.map().map_colouring()

    def show_cloud(self, loaded: LoadedCloud, settings: MapSettings, *,
                   frame: bool = True) -> None:
        self.map().show_cloud(loaded, settings, frame=frame)

    def render(self, run: Run, settings: MapSettings) -> Iterator[str]:
        return self.map().render(run, settings)

    def load(self, source: CloudSource, *, stash: bool = False, label: str = "",
             adjust: Callable[[MapSettings], MapSettings] | None = None) -> int:
        return self.map().load(source, stash=stash, label=label, adjust=adjust)

    def last_render(self) -> dict[str, object]:
        return self.map().last_render()

    def show_view(self, loaded: LoadedCloud, settings: MapSettings) -> int:
        return self.map().show_view(loaded, settings)

    # ------------------------------------------------------------------ Host: features
    def add_feature(self, feature: object) -> None:
        """Register a mounted feature (build does, in mount order)."""
        self._features.append(feature)

    def use_map(self, feature: MapService) -> None:
        """The mounted map, which the map's host calls go to (build says which)."""
        self._map = feature

    def feature(self, kind: type[T]) -> T:
        for f in self._features:
            if isinstance(f, kind):
                return f
        raise KeyError(kind.__name__)

    def features(self) -> Sequence[object]:
        return tuple(self._features)
