"""Level of detail, beside the scene (:mod:`rough_viewer.app.scene`): each browser
tab chooses the nodes it draws for its camera.

:class:`CameraWatch` debounces the cameras (viser's threads) into a
:class:`RefineJob`; a tab that leaves is a :class:`DropTabJob`, a new point budget a
:class:`BudgetJob`, a preset view a :class:`CameraJob` (the Map tab's camera
control, a lesson's step). The features submit them; the jobs only call the scene.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import ClassVar

from rough_viewer.app.host import Host
from rough_viewer.app.worker import Job, Run

#: Seconds a camera rests before its tab chooses its nodes again (and, while it
#: moves, the longest wait between two choices).
CAMERA_REST_S = 0.15
CAMERA_MOVING_S = 0.5


@dataclass(frozen=True)
class CameraJob(Job[Host]):
    """Move every browser's camera (of this app) to a preset view of the cloud shown."""

    preset: str
    """``"face-on"``, ``"top"`` or ``"side"`` (:func:`rough_viewer.app.scene.camera_pose`)."""
    lane: ClassVar[str] = "camera"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        ctx.scene.move_cameras(ctx.session.shown.loaded, self.preset)
        yield "camera"


@dataclass(frozen=True)
class RefineJob(Job[Host]):
    """Browser tabs choose their nodes for their cameras (level of detail); with
    ``force``, whether their cameras moved or not (a campaign's nodes they waited for
    were decoded)."""

    clients: frozenset[int]
    force: bool = False
    lane: ClassVar[str] = "lod"

    @property
    def title(self) -> str:
        return "level of detail"

    def absorb(self, newer: Job[Host]) -> Job[Host] | None:
        if isinstance(newer, RefineJob):
            return RefineJob(self.clients | newer.clients, self.force or newer.force)
        return None

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        for cid in sorted(self.clients):
            ctx.scene.refine(cid, force=self.force)
        yield "refine"


@dataclass(frozen=True)
class NodeErrorJob(Job[Host]):
    """A campaign's node could not be decoded or held: one line in the app's error
    line (the other nodes are drawn)."""

    message: str
    lane: ClassVar[str] = "lod-error"
    keep_all: ClassVar[bool] = True

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        ctx.show_error(self.message, kept="The other nodes are drawn.")
        yield "error"


#: Seconds after a tab left when the heap is trimmed a second time (its connection's
#: buffers are freed after the tab is dropped).
GIVE_BACK_AFTER_S = 2.0


@dataclass(frozen=True)
class DropTabJob(Job[Host]):
    """A browser tab left: its nodes are forgotten."""

    client_id: int
    lane: ClassVar[str] = "lod-drop"
    keep_all: ClassVar[bool] = True

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        from rough_viewer.memory import give_back

        ctx.scene.drop_tab(self.client_id)
        yield "drop"
        # its messages' memory, freed in pieces the heap keeps (issue 36 item 19): now,
        # and once its connection's last buffers are gone too
        give_back()
        later = threading.Timer(GIVE_BACK_AFTER_S, give_back)
        later.daemon = True
        later.start()
        yield "give back"


@dataclass(frozen=True)
class BudgetJob(Job[Host]):
    """Every tab's point budget."""

    budget: int
    lane: ClassVar[str] = "budget"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        ctx.scene.set_budget(self.budget)
        yield "budget"


class CameraWatch:
    """Debounces the cameras of the browser tabs: a tab chooses its nodes again once
    its camera has rested :data:`CAMERA_REST_S` (and every :data:`CAMERA_MOVING_S`
    while it moves), as a :class:`RefineJob` on the worker. A campaign's tabs also
    refine when nodes they wait for were decoded, and a node that cannot be is a
    :class:`NodeErrorJob` (:meth:`rough_viewer.app.scene.Scene.on_nodes`)."""

    def __init__(self, host: Host) -> None:
        self._host = host
        self._lock = threading.Lock()
        self._timers: dict[int, threading.Timer] = {}
        self._last: dict[int, float] = {}
        self._errors: set[str] = set()
        host.scene.on_nodes(self.arrived, self.failed)

    def arrived(self, client_ids: frozenset[int]) -> None:
        """Nodes those tabs waited for were decoded (a campaign's decoding thread)."""
        self._host.submit(RefineJob(frozenset(client_ids), force=True))

    def failed(self, message: str) -> None:
        """A node cannot be drawn: said once (a campaign's decoding thread)."""
        with self._lock:
            if message in self._errors:
                return
            self._errors.add(message)
        self._host.submit(NodeErrorJob(message))

    def moved(self, client_id: int) -> None:
        """A tab's camera changed (viser's thread pool)."""
        now = time.monotonic()
        with self._lock:
            timer = self._timers.pop(client_id, None)
            if timer is not None:
                timer.cancel()
            due = now - self._last.get(client_id, 0.0) >= CAMERA_MOVING_S
            if due:
                self._last[client_id] = now
            timer = threading.Timer(CAMERA_REST_S, self._rested, args=(client_id,))
            timer.daemon = True
            self._timers[client_id] = timer
            timer.start()
        if due:
            self._host.submit(RefineJob(frozenset({client_id})))

    def _rested(self, client_id: int) -> None:
        with self._lock:
            self._timers.pop(client_id, None)
            self._last[client_id] = time.monotonic()
        self._host.submit(RefineJob(frozenset({client_id})))

    def left(self, client_id: int) -> None:
        with self._lock:
            timer = self._timers.pop(client_id, None)
            self._last.pop(client_id, None)
        if timer is not None:
            timer.cancel()
        self._host.submit(DropTabJob(client_id))


