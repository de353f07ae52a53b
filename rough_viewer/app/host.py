"""The narrow interface every feature of the app is given: :class:`Host`.

A feature (the Map tab, the Profile tab, the Export folder, ...) is mounted with a
host and knows nothing else of the app. The host offers:

- **a place for controls**: :meth:`Host.tab` (a tab of the app's tab group) or
  :meth:`Host.folder`, the GUI to add controls with (:attr:`Host.gui`), and
  :meth:`Host.allow` / :meth:`Host.rule` to let browsers set them (every value a
  browser sends is checked; an unregistered control cannot be set);
- **the scene** (:attr:`Host.scene`, :class:`rough_viewer.app.scene.Scene`) and
  **the session** (:attr:`Host.session`): read anywhere, written only by jobs;
- **work**: :meth:`Host.submit` a :class:`~rough_viewer.app.worker.Job` (callbacks do
  nothing else), :meth:`Host.on_idle` for background work;
- **events**, each delivered on the worker: :meth:`Host.on_cloud` (another cloud is
  shown), :meth:`Host.on_render` (a map was coloured), :meth:`Host.on_click` (a point
  was picked), :meth:`Host.on_connect` (a browser connected);
- **messages**: notices, the error line, the status line, a pinned note;
- **the map** (:class:`MapService`, handed to the Map tab): :meth:`Host.request` a
  map, its :meth:`Host.settings`, colour the points instead of it
  (:meth:`Host.take_overlay`, :meth:`Host.give_back_overlay`), show a cloud
  (:meth:`Host.show_cloud`, :meth:`Host.load`, :meth:`Host.render`);
- **the other features**: :meth:`Host.feature` by type, :meth:`Host.features`
  (no feature imports another's module: what one needs of another goes through
  the host).

This module imports no feature and no viser internals: features depend on it, the
shell (:mod:`rough_viewer.app.shell`) implements it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, runtime_checkable

import numpy as np

from rough_viewer.app.cache import ByteBudget, ComputeSlots
from rough_viewer.app.files import DataFolder
from rough_viewer.app.limits import CACHE_BYTES, DEFAULT_MAX_DISPLAY, DEFAULT_MAX_UPLOAD_MB
from rough_viewer.io.estimates import DEFAULT_MAX_POINTS
from rough_viewer.lod.select import DEFAULT_BUDGET
from rough_viewer.scanner.trust import TrustSettings
from rough_viewer.vocabulary import Unit

if TYPE_CHECKING:
    import viser

    from rough_viewer.app.cloud import LoadedCloud
    from rough_viewer.app.colouring import Colouring
    from rough_viewer.app.files import UploadedFile
    from rough_viewer.app.scene import Scene
    from rough_viewer.app.session import Session
    from rough_viewer.app.settings import MapSettings
    from rough_viewer.app.worker import Job, Run
    from rough_viewer.io import PointCloud
    from rough_viewer.lessons import Lesson
    from rough_viewer.report.view import View

T = TypeVar("T")


@dataclass(frozen=True)
class AppOptions:
    """Limits and switches of one app (``serve``'s options)."""

    data: DataFolder
    """The folder "Load file" reads from (and saved views are written to)."""
    max_display: int = DEFAULT_MAX_DISPLAY
    """Points of the even overview sample (camera framing, point size, highlights);
    browser tabs draw the cloud by level of detail (``point_budget``)."""
    point_budget: int = DEFAULT_BUDGET
    """Most points a browser tab shows at once (``serve --point-budget``)."""
    max_points: int = DEFAULT_MAX_POINTS
    """Most points a compressed file the File tab reads may declare beyond what its
    size can hold: the decompression-bomb guard (``serve --max-points``)."""
    variogram: bool = True
    """Compute the semivariogram panel."""
    prefetch: bool = True
    """While idle, compute the preset grids for the current axis and minimum points."""
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD_MB << 20
    """Largest upload accepted, bytes."""
    cache_bytes: int = CACHE_BYTES
    """Memory budget of every cache of the app together, bytes: the loaded cloud's
    grids (and its crops'), the zones' and the sets' caches (:attr:`cache_pool`)."""
    units: Unit | None = None
    """Unit of the coordinates of files loaded from the File tab (``serve --units``;
    None: each file's CRS unit, else metres)."""
    save_views: bool = False
    """"Save view beside the input" may write into the data folder
    (``serve --save-views``)."""
    trust: TrustSettings | None = None
    """Calibration of the scanner colour layers and cell report (``serve --noise``,
    ``--beam-radius``, ``--calibration``, ...; None: the bias paper's)."""
    compute_slots: int | None = None
    """Grid computations at once across the app's analyses (``serve --classroom``:
    one analysis per tab, :class:`~rough_viewer.app.cache.ComputeSlots`); None: no
    limit (one analysis, one worker)."""
    lesson: Lesson | None = None
    """The lesson the Lesson tab opens on (``serve --lesson``; None: none chosen)."""
    memory: float | None = None
    """The server's memory budget, bytes (``serve --memory``; None: none): a file the
    File tab loads or uploads whose points need more is refused before it is read
    (:func:`rough_viewer.app.files.check_app_room`)."""

    @cached_property
    def cache_pool(self) -> ByteBudget:
        """The one budget of :attr:`cache_bytes` every cache of the app draws from
        (made on first use; a frozen dataclass may cache a property), with the
        compute slots of :attr:`compute_slots`."""
        slots = ComputeSlots(self.compute_slots) if self.compute_slots else None
        return ByteBudget(self.cache_bytes, slots=slots)


@dataclass(frozen=True)
class Pick:
    """A displayed point under a click: its index in the cloud and its position."""

    point: int
    """Index into the loaded cloud."""
    xyz: np.ndarray
    """(3,) file frame, metres."""
    local: np.ndarray
    """(3,) display frame (relative to the local origin), metres."""


ClickHandler = Callable[[Pick], bool]
"""A feature's click handler (on the worker): True when it took the click (then no
other feature, nor the cell report, gets it)."""

Rule = Callable[[Any], Any]
"""Extra check of a browser's value: returns the value to use or raises InputError."""


class CloudSource(Protocol):
    """Where a load (:meth:`Host.load`) gets its points."""

    @property
    def title(self) -> str:
        """How the source is named to the user (a path as typed, an upload's name)."""
        ...

    def read(self, host: Host, run: Run) -> PointCloud:
        """The points (InputError naming the file as the user knows it)."""
        ...

    def release(self) -> None:
        """Free what the source holds (an upload's file); safe to call twice."""
        ...


@runtime_checkable
class SavedViewPart(Protocol):
    """A feature's part of a saved view (:class:`rough_viewer.report.view.View`).

    :func:`rough_viewer.app.views.view_of` composes the parts of every feature that
    has one and knows no feature's fields.
    """

    def snapshot(self) -> dict[str, Any]:
        """The view's fields this feature fills (names of :class:`View`'s fields)."""
        ...

    def restore(self, view: View) -> Job[Host] | None:
        """A job that puts this feature's part of ``view`` back (None: nothing to
        do). Raises InputError when the view's values do not fit the feature."""
        ...


@runtime_checkable
class FigureSource(Protocol):
    """A feature whose panels can be exported (the Export folder's figure list)."""

    def figures(self) -> dict[str, viser.GuiPlotlyHandle]:
        """Name (a file-name part; :func:`rough_viewer.visual.export.figure_title`
        gives its title) -> the plotly panel."""
        ...


@dataclass(frozen=True)
class LessonAnswer:
    """One checked answer of a lesson's step (the last check of that step)."""

    step: int
    """0-based step index."""
    question: str
    """The question's text (the lesson file's: escape it before showing it)."""
    given: float
    """The number the student typed."""
    expected: float
    """The tool's number on the map the answer was checked on (same unit)."""
    correct: bool
    """``given`` was within the question's tolerance of ``expected``."""


@dataclass(frozen=True)
class LessonStatus:
    """Where a tab stands in its lesson (the teacher's Class tab reads it)."""

    lesson: str
    """The lesson's name (its file's stem; "" when no lesson is open)."""
    title: str
    """The lesson's title (user text: escape it)."""
    step: int
    """The current step, 0-based."""
    steps: int
    """Number of steps (0 when no lesson is open)."""
    answers: tuple[LessonAnswer, ...] = ()
    """The steps answered so far, in step order (the last check of each)."""


@runtime_checkable
class LessonReporter(Protocol):
    """A feature that reports its tab's lesson (the Lesson tab): the Class tab finds
    it among a tab's features with ``isinstance(f, LessonReporter)``."""

    def lesson_status(self) -> LessonStatus:
        """A snapshot of the lesson, its step and the answers (any thread)."""
        ...


class MapService(Protocol):
    """What the other features may ask of the map (the mounted Map tab implements
    it; the shell hands each :class:`Host` call of these names to it). Every
    method but :meth:`request`, :meth:`settings` and :meth:`load` runs on the
    worker."""

    def request(self, **changes: object) -> int:
        """Queue a map once the Map tab's controls named by ``changes`` hold these
        values, as a person sets them (``toggle=True`` flips ODR and OLS)."""
        ...

    def settings(self) -> MapSettings:
        """The settings the Map tab's controls ask for (the shown ones if a control
        is unusable)."""
        ...

    def take_overlay(self, owner: object, release: Callable[[], None],
                     colouring: Colouring) -> None:
        """``owner`` colours the points with ``colouring`` instead of the map (the
        feature that held them is told with its ``release``)."""
        ...

    def give_back_overlay(self, owner: object) -> None:
        """``owner`` no longer colours the points: the map's colours come back."""
        ...

    def holds_overlay(self, owner: object) -> bool:
        """True while ``owner``'s colours are on the points."""
        ...

    def map_colouring(self) -> Colouring | None:
        """The map's own colours of the points (None before the first map)."""
        ...

    def show_cloud(self, loaded: LoadedCloud, settings: MapSettings, *,
                   frame: bool = True) -> None:
        """Put ``loaded`` in the scene and ``settings`` in the map's controls; the
        ``on_cloud`` listeners are told. ``frame``: every camera frames it."""
        ...

    def render(self, run: Run, settings: MapSettings) -> Iterator[str]:
        """The stages of a job that colour the map with ``settings``."""
        ...

    def load(self, source: CloudSource, *, stash: bool = False, label: str = "",
             adjust: Callable[[MapSettings], MapSettings] | None = None) -> int:
        """Queue showing the cloud ``source`` reads, at its own default grid, with
        the map's settings (``adjust``-ed). ``stash``: put the scan shown now aside;
        ``label``: the status line's name of a cloud that is no file."""
        ...

    def last_render(self) -> dict[str, object]:
        """The timing record of the last map coloured (``{}`` before the first)."""
        ...

    def show_view(self, loaded: LoadedCloud, settings: MapSettings) -> int:
        """Queue showing ``loaded`` with exactly ``settings`` in the map's controls
        (a cloud already on screen is only recoloured; a classroom's teacher sends
        a view)."""
        ...


class Host(MapService, Protocol):
    """What a feature is given (see the module docstring)."""

    @property
    def options(self) -> AppOptions: ...

    @property
    def session(self) -> Session: ...

    @property
    def scene(self) -> Scene: ...

    @property
    def gui(self) -> viser.GuiApi: ...

    def tab(self, label: str) -> AbstractContextManager[object]:
        """A tab of the app's tab group (made by the first call with ``label``; later
        calls add to it, after what is there)."""
        ...

    def folder(self, label: str) -> AbstractContextManager[object]:
        """A new folder below the tabs."""
        ...

    def allow(self, *handles: Any) -> None:
        """Let browsers set these controls (each value checked against the control)."""
        ...

    def rule(self, handle: Any, check: Rule) -> None:
        """An extra check of the values browsers send to ``handle``."""
        ...

    def take_uploads(self, handle: Any, on_file: Callable[[UploadedFile], object]) -> None:
        """Files sent with the upload button ``handle`` go to ``on_file`` (streamed to
        disk with a size limit)."""
        ...

    # ------------------------------------------------------------------ work
    def submit(self, job: Job[Host]) -> int:
        """Queue a job on the worker; 0 (with a notice) when too many wait."""
        ...

    def on_idle(self, work: Callable[[Any], bool]) -> None:
        """Background work ``work(run) -> bool`` (more to do) while no job waits."""
        ...

    # ------------------------------------------------------------------ events
    def on_cloud(self, listener: Callable[[], None]) -> None:
        """Call ``listener()`` on the worker each time another cloud is shown."""
        ...

    def on_render(self, listener: Callable[[], None], *, late: bool = False) -> None:
        """Call ``listener()`` on the worker after each map is coloured (keep it
        quick: submit a job). ``late`` listeners come after the others (their jobs
        then wait behind those of the quick ones: background panels)."""
        ...

    def on_click(self, handler: ClickHandler) -> None:
        """Ask ``handler`` about each picked point, in order, before the cell report."""
        ...

    def on_connect(self, listener: Callable[[viser.ClientHandle], None]) -> None:
        """Call ``listener(client)`` when a browser connects (messages to it only)."""
        ...

    def on_disconnect(self, listener: Callable[[viser.ClientHandle], None]) -> None:
        """Call ``listener(client)`` when a browser leaves (submit a job)."""
        ...

    def cloud_shown(self) -> None:
        """Tell the ``on_cloud`` listeners (the map does, on the worker)."""
        ...

    def rendered(self) -> None:
        """Tell the ``on_render`` listeners (the map does, on the worker)."""
        ...

    def picked(self, pick: Pick) -> bool:
        """Offer ``pick`` to the click handlers; True when one took it."""
        ...

    # ------------------------------------------------------------------ messages
    def notify(self, title: str, body: str, *, color: Any = None,
               seconds: float = 6.0) -> None:
        """A notification in every browser (plain text, never Markdown)."""
        ...

    def notify_client(self, client_id: int, title: str, body: str) -> None:
        """A red notification in one browser."""
        ...

    def show_error(self, message: str, *, kept: str = "The previous view is kept.") -> None:
        """The error line (escaped) and a notice; ``kept`` says what stays."""
        ...

    def clear_error(self) -> None:
        ...

    def say(self, status: str) -> None:
        """The status line (Markdown: escape user text first)."""
        ...

    def warn(self, notes: str) -> None:
        """The notes that stay under the status line ("" hides them; Markdown)."""
        ...

    def pin(self, text: str) -> None:
        """A note above the tabs that stays and is sent to each browser that connects
        (a saved view's input moved or changed)."""
        ...

    def progress(self, percent: float | None) -> None:
        """The progress bar at ``percent`` (None hides it)."""
        ...

    def clients(self) -> dict[int, viser.ClientHandle]:
        """The connected browsers."""
        ...

    # ------------------------------------------------------------------ features
    def feature(self, kind: type[T]) -> T:
        """The mounted feature of type ``kind`` (KeyError if none)."""
        ...

    def features(self) -> Sequence[object]:
        """Every mounted feature, in mount order."""
        ...


def parts(host: Host) -> Iterator[SavedViewPart]:
    """The features of ``host`` that have a part in saved views, in mount order."""
    for f in host.features():
        if isinstance(f, SavedViewPart):
            yield f


@dataclass(frozen=True)
class Student:
    """One student's tab of a classroom, as the teacher's Class tab lists it."""

    name: str
    """A short id (``S1``, ``S2``, ...: in the order they connected)."""
    client_id: int
    cell_size: float
    """The grid on screen, metres."""
    model: str
    threshold: float
    axis: str
    following: bool
    """The tab follows the teacher's settings."""
    lesson: str = ""
    """Where the student is in the lesson (``turned-wall 2/4``; "" without one)."""
    answers: str = ""
    """The student's answers so far (``2 of 3 right``; "" without any)."""


class ClassService(Protocol):
    """What the teacher's Class tab asks of the classroom (``serve --classroom``;
    :class:`rough_viewer.app.classroom.Classroom` implements it)."""

    def students(self) -> list[Student]:
        """The students' tabs connected now, in the order they came."""
        ...

    def send_view(self, teacher: Host) -> int:
        """Show the teacher's cloud, settings and camera in every student's tab; the
        number of tabs it went to."""
        ...

    def follow(self, teacher: Host, on: bool) -> None:
        """While ``on``, every map the teacher shows is shown in the students' tabs."""
        ...

    @property
    def following(self) -> bool:
        ...

    def show_student(self, teacher: Host, name: str) -> bool:
        """Show student ``name``'s cloud, settings and camera in the teacher's tab
        (False: no such student now)."""
        ...

    def on_change(self, host: Host, listener: Callable[[], None]) -> None:
        """Call ``listener()`` (on any thread: submit a job) when a student comes,
        leaves or shows another map, while ``host``'s tab is connected."""
        ...
