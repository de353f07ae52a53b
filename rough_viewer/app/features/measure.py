"""The Measure tab: the distance between two clicked points of the rock.

With *Measure mode* on, the first click marks a point and the second gives the
straight-line distance between the two, its horizontal and vertical parts and the
line's trend and plunge (:func:`rough_viewer.grid.measure.point_distance`; azimuths
clockwise from +y, docs/zones.md), drawn as a line with a label. The straight line
between two points of a hillside often runs under the ground (or among the points'
splats), so it is also drawn as dots that show through the rock, like its label.
Points are picked at full resolution, on every point of the cloud; the same point
twice is no measure, and leaving measure mode forgets a first point. The last
:data:`MAX_MEASURES` are listed and drawn; "Clear" drops them and numbering starts
again at D1. The plane of a region is measured in the Select
tab, a cell's dip and dip direction are in the Map tab's cell report.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.host import Host, Pick
from rough_viewer.app.units import Units
from rough_viewer.app.worker import Job, Run
from rough_viewer.grid.measure import Distance, point_distance
from rough_viewer.report.view import MeasurePick, View

L_ON = "Measure mode"
L_CLEAR = "Clear measures"
#: Measures kept (listed and drawn).
MAX_MEASURES = 8
#: Colour of a measure's line.
LINE_COLOUR = (255, 140, 0)
PROMPT = "Tick **Measure mode** and click two points on the rock."
#: Dots along a measure's line, drawn on top of the rock (its two ends included).
LINE_DOTS = 11
#: Text of one dot.
DOT = "•"


def dot_positions(a: np.ndarray, b: np.ndarray, n: int = LINE_DOTS) -> np.ndarray:
    """``(n, 3)`` points evenly spaced along the segment from ``a`` to ``b``, both ends
    included (display frame, metres; ``n >= 2``): where a measure's line is dotted."""
    t = (np.arange(n, dtype=np.float64) / (n - 1))[:, None]
    return np.asarray(a, dtype=np.float64) + t * (np.asarray(b, dtype=np.float64)
                                                   - np.asarray(a, dtype=np.float64))


def distance_text(k: int, d: Distance, units: Units) -> str:
    """One line of the list: distance, horizontal, vertical, trend/plunge (Markdown)."""
    def length(v: float) -> str:
        return f"{v / units.per:.4g} {units.label}"

    line = (f"**D{k}**: {length(d.distance_m)} (horizontal {length(d.horizontal_m)}, "
            f"vertical {length(d.vertical_m)}")
    if np.isfinite(d.trend_deg):
        line += f", trend {d.trend_deg:05.1f}°, plunge {d.plunge_deg:.1f}°"
    return line + ")"


@dataclass(eq=False)
class MeasureFeature:
    """The Measure tab's controls and its measures."""

    host: Host
    on: viser.GuiCheckboxHandle
    clear: viser.GuiButtonHandle
    note: viser.GuiMarkdownHandle
    binding: Binding = field(default_factory=Binding)
    start: Pick | None = None
    """The first point of a measure being picked."""
    items: list[tuple[int, Distance, list[viser.SceneNodeHandle]]] = field(default_factory=list)
    """(number, distance, its scene nodes), oldest first."""
    ends: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    """The two points (file frame, metres) of each listed measure, by number."""
    count: int = 0
    """Measures made (numbers them)."""
    pending: list[viser.SceneNodeHandle] = field(default_factory=list)

    def on_pick(self, pick: Pick) -> bool:
        """A click while measure mode is on: the first, then the second point (worker).
        False when measure mode is off."""
        if not self.on.value:
            return False
        scene = self.host.scene
        if self.start is None:
            self.start = pick
            self.pending = [scene.marker("/measures/start", pick.local, "● start")]
            self.note.content = "First point picked; click the second."
            return True
        d = point_distance(self.start.xyz, pick.xyz)
        if pick.point == self.start.point or not d.distance_m > 0.0:
            self.note.content = ("That is the first point again; click a second, "
                                 "different point.")
            return True
        a, self.start = self.start, None
        scene.remove(self.pending)
        self.pending = []
        self.count += 1
        self.add(self.count, a.xyz, pick.xyz)
        self.refresh()
        return True

    def add(self, k: int, a_xyz: np.ndarray, b_xyz: np.ndarray) -> None:
        """Draw and list measure ``k`` between two points (file frame, metres;
        worker)."""
        scene, loaded = self.host.scene, self.host.session.shown.loaded
        a_xyz, b_xyz = np.asarray(a_xyz, dtype=np.float64), np.asarray(b_xyz, dtype=np.float64)
        d = point_distance(a_xyz, b_xyz)
        a, b = loaded.to_local(a_xyz[None])[0], loaded.to_local(b_xyz[None])[0]
        u = loaded.units
        seg = np.stack([a, b])[None].astype(np.float64)
        nodes: list[viser.SceneNodeHandle] = [
            scene.lines(f"/measures/{k}/line", seg, LINE_COLOUR),
            *(scene.marker(f"/measures/{k}/dot{i}", p, DOT)
              for i, p in enumerate(dot_positions(a, b))),
            scene.add_label(f"/measures/{k}/label", f"D{k} {d.distance_m / u.per:.4g} {u.label}",
                            0.5 * (a + b)),
        ]
        self.items.append((k, d, nodes))
        self.ends[k] = (a_xyz, b_xyz)
        while len(self.items) > MAX_MEASURES:
            old = self.items.pop(0)
            scene.remove(old[2])
            self.ends.pop(old[0], None)

    # ------------------------------------------------------------------ saved views
    def snapshot(self) -> dict[str, Any]:
        """The measures listed, oldest first (points in the file frame, metres)."""
        return {"measures": tuple(
            MeasurePick(start=_vec(self.ends[k][0]), end=_vec(self.ends[k][1]), number=k)
            for k, _d, _n in self.items)}

    def restore(self, view: View) -> Job[Host] | None:
        return RestoreMeasuresJob(self, view.measures)

    def refresh(self) -> None:
        u = self.host.session.shown.loaded.units
        lines = [distance_text(k, d, u) for k, d, _n in reversed(self.items)]
        self.note.content = "  \n".join(lines) if lines else PROMPT

    def forget_start(self) -> None:
        """Drop a first point still waiting for its second (worker)."""
        self.host.scene.remove(self.pending)
        self.pending, self.start = [], None

    def drop(self) -> None:
        """No measures; the next is D1 again (worker)."""
        self.forget_start()
        for _k, _d, nodes in self.items:
            self.host.scene.remove(nodes)
        self.items, self.count, self.ends = [], 0, {}
        self.note.content = PROMPT


@dataclass(frozen=True)
class ClearMeasuresJob(Job[Host]):
    """Drop every measure."""

    f: MeasureFeature = field(compare=False)
    lane: ClassVar[str] = "measure"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        self.f.drop()
        yield "clear"


@dataclass(frozen=True)
class RestoreMeasuresJob(Job[Host]):
    """A saved view's measures in place of the listed ones, with their numbers (the
    next measure is numbered after the last)."""

    f: MeasureFeature = field(compare=False)
    measures: tuple[MeasurePick, ...]
    lane: ClassVar[str] = "measure-restore"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        f = self.f
        f.drop()
        for m in self.measures[-MAX_MEASURES:]:
            f.add(m.number, np.asarray(m.start), np.asarray(m.end))
        f.count = max((m.number for m in self.measures), default=0)
        f.refresh()
        yield "measures"


def _vec(v: np.ndarray) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


@dataclass(frozen=True)
class LeaveMeasureJob(Job[Host]):
    """Measure mode was turned off: a first point waiting for its second is dropped."""

    f: MeasureFeature = field(compare=False)
    lane: ClassVar[str] = "measure-mode"  # a pending Clear still runs

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        if not self.f.on.value and self.f.start is not None:
            self.f.forget_start()
            self.f.refresh()
        yield "leave"


def mount(host: Host) -> MeasureFeature:
    """Add the Measure tab; clicks come here in measure mode."""
    gui = host.gui
    with host.tab("Measure"):
        f = MeasureFeature(
            host=host,
            on=gui.add_checkbox(L_ON, False, hint="Clicks measure: two points give their "
                                "distance (the Map tab's cell report waits)."),
            clear=gui.add_button(L_CLEAR),
            note=gui.add_markdown(PROMPT),
        )
    host.allow(f.on, f.clear)
    f.binding.on_change([f.clear], lambda _h: host.submit(ClearMeasuresJob(f)))
    f.binding.on_change([f.on], lambda _h: None if f.on.value else host.submit(LeaveMeasureJob(f)))
    host.on_click(f.on_pick)
    # a measure's points are of the cloud shown: another cloud (or a crop) drops them
    host.on_cloud(f.drop)
    return f
