"""The session: one analysis (what the app shows, its selection, what is put aside,
the keys of what is drawn).

One :class:`Session` per app, owned by the worker (:mod:`rough_viewer.app.worker`):
every attribute is read from any thread, but written only on the worker's thread
(a write from another thread raises :class:`~rough_viewer.app.worker.NotOnWorker`).
Features read it through their host; jobs change it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.colouring import CellInfo, MapStats
from rough_viewer.app.settings import MapSettings
from rough_viewer.grid.measure import PlaneMeasure
from rough_viewer.grid.roughness import GridRoughness
from rough_viewer.grid.scales import PointScales
from rough_viewer.io import PointCloud
from rough_viewer.io.crop import CropBox
from rough_viewer.io.formats.mesh import TriangleMesh
from rough_viewer.report.view import SelectionView, View


@dataclass(frozen=True)
class Shown:
    """What the scene shows now (replaced as a whole by the worker)."""

    loaded: LoadedCloud
    settings: MapSettings
    result: GridRoughness | None = None
    stats: MapStats | None = None


@dataclass(frozen=True)
class Selection:
    """Points selected on the shown cloud."""

    loaded: LoadedCloud
    """The cloud they were selected on."""
    mask: np.ndarray
    """(N,) bool over its points."""
    box: CropBox
    """Their bounding box (metres, the file frame; mode ``keep``)."""
    plane: PlaneMeasure | None
    """Their ODR plane (None: fewer than 3 points, or on a line)."""
    plane_error: str = ""
    made_by: SelectionView | None = None
    """The camera and rectangle that selected them (what a saved view holds)."""

    @property
    def count(self) -> int:
        return int(np.count_nonzero(self.mask))


class Session:
    """One analysis's state (the app's, shared by its tabs today; a tab's own once each
    has one), written by the worker only.

    Parameters
    ----------
    shown
        What is shown first (the cloud given to the app, before its first render).
    require_writer
        ``require_writer(what)`` raises unless the calling thread may write (the
        worker's :meth:`~rough_viewer.app.worker.Worker.require_worker`).
    """

    shown: Shown
    """The cloud on screen, the map settings, its grid result and statistics."""
    stashed: Shown | None
    """The scan put aside while the board lesson is shown (None: nothing aside)."""
    panel_key: tuple[object, ...] | None
    """(grid key, model, semivariogram on) of the grid panels on screen."""
    face_key: tuple[object, ...] | None
    """(axis, minimum points, threshold) of the whole-face trend on screen."""
    last_pick: CellInfo | None
    """The cell report of the last clicked point (None: no point picked)."""
    pick_scales: PointScales | None
    """The last clicked point's roughness across the preset grids."""
    view: View | None
    """The saved view the session was opened with (None: none): saving a view keeps
    its fields that no mounted feature fills."""
    uploaded_mesh: tuple[PointCloud, TriangleMesh] | None
    """An uploaded mesh file's cloud and its triangles, read before the upload was
    deleted (the Directions folder measures on them; None: the last upload had
    none)."""

    selection: Selection | None
    """The points selected on the shown cloud (the Select tab; None: none)."""

    _require: Callable[[str], None]
    _FIELDS = ("shown", "stashed", "panel_key", "face_key", "last_pick", "pick_scales", "view",
               "uploaded_mesh", "selection")

    def __init__(self, shown: Shown, require_writer: Callable[[str], None]) -> None:
        object.__setattr__(self, "_require", require_writer)
        for name in self._FIELDS:
            object.__setattr__(self, name, None)
        object.__setattr__(self, "shown", shown)

    def __setattr__(self, name: str, value: object) -> None:
        if name not in self._FIELDS:
            raise AttributeError(f"the session has no {name!r}")
        self._require(f"session.{name}")
        object.__setattr__(self, name, value)

    def put_aside(self) -> None:
        """Keep the scan shown now aside (once: a second board scan keeps the first
        scan aside, not the first board)."""
        if self.stashed is None:
            self.stashed = self.shown

    def new_cloud(self, loaded: LoadedCloud, settings: MapSettings) -> None:
        """Another cloud is shown: nothing of the old one's grid is on screen."""
        self.shown = Shown(loaded, settings)
        self.panel_key = None
        self.face_key = None
        self.forget_pick()

    def forget_pick(self) -> None:
        self.last_pick = None
        self.pick_scales = None
