"""Which nodes one browser tab holds, and what to do when its selection changes.

One :class:`Residency` per tab. Each new selection gives a :class:`ResidencyPlan`:
nodes to **send** (never sent, or evicted since), nodes to **show** again (sent
before, hidden now: a tiny ``visible`` message, no resend), nodes to **hide** (shown,
no longer selected), and nodes to **evict** (remove from the tab) once the points the
tab holds pass ``keep_factor`` (default 2) times the budget, least recently selected
first. Colours: after a change that recolours the points (model, grid, threshold,
stretch, layer), :meth:`Residency.colours_changed` lists the shown nodes to recolour
at once; hidden nodes are marked stale and come back in a later plan's
``recolour`` when shown again.

Pure bookkeeping (no viser, no arrays of points): the app applies each plan in
order and entirely (or calls :meth:`Residency.discard` for nodes it could not send).

>>> import numpy as np
>>> tab = Residency(np.array([10, 20, 30, 40]), budget=60)
>>> tab.plan([0, 1, 2]).send
(0, 1, 2)
>>> p = tab.plan([0, 3])
>>> p.send, p.hide, p.show
((3,), (1, 2), ())
>>> p = tab.plan([0, 1])
>>> p.send, p.show, p.hide, p.evict   # 100 points held > 2 x 60 would be 120: none evicted
((), (1,), (3,), ())
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from rough_viewer.vocabulary import InputError

#: Points a tab may hold, shown or hidden, as a multiple of its budget.
DEFAULT_KEEP_FACTOR = 2.0


@dataclass(frozen=True)
class ResidencyPlan:
    """What the app does to one tab's scene for a new selection (node rows)."""

    send: tuple[int, ...]
    """Nodes to encode and add, visible, in the selection's order (largest first)."""
    show: tuple[int, ...]
    """Nodes held but hidden: make visible."""
    hide: tuple[int, ...]
    """Nodes shown but no longer selected: make invisible (kept for later)."""
    evict: tuple[int, ...]
    """Hidden nodes to remove from the tab (least recently selected first); never
    also in ``hide`` (a node hidden by this plan and evicted by it is only removed)."""
    recolour: tuple[int, ...]
    """Nodes in ``show`` whose colours changed while they were hidden: send their
    colours too."""

    @property
    def empty(self) -> bool:
        """Nothing to do."""
        return not (self.send or self.show or self.hide or self.evict or self.recolour)


class Residency:
    """The nodes one tab holds.

    Parameters
    ----------
    counts : (M,) array_like of int
        Points of every node (:attr:`rough_viewer.lod.octree.Octree.counts`).
    budget : int
        The tab's point budget (a selection holds at most this many).
    keep_factor : float
        Hidden nodes are evicted once the tab holds more than ``keep_factor *
        budget`` points (default 2).
    """

    def __init__(self, counts: Sequence[int] | np.ndarray, budget: int, *,
                 keep_factor: float = DEFAULT_KEEP_FACTOR) -> None:
        self._counts = np.asarray(counts, dtype=np.int64)
        if not keep_factor >= 1.0:
            raise InputError(f"keep factor must be at least 1, got {keep_factor}")
        self.keep_factor = float(keep_factor)
        self.budget = self._check_budget(budget)
        self._visible: dict[int, bool] = {}  # held node -> shown
        self._used: dict[int, int] = {}  # held node -> last selection it was in
        self._stale: set[int] = set()  # held, hidden, colours out of date
        self._clock = 0
        self._held_points = 0

    @staticmethod
    def _check_budget(budget: int) -> int:
        b = int(budget)
        if b != budget or b < 1:
            raise InputError(f"point budget must be a whole number >= 1, got {budget}")
        return b

    # ------------------------------------------------------------------ state

    @property
    def held(self) -> tuple[int, ...]:
        """Nodes the tab holds (shown or hidden)."""
        return tuple(self._visible)

    @property
    def shown(self) -> tuple[int, ...]:
        """Nodes the tab shows."""
        return tuple(k for k, v in self._visible.items() if v)

    @property
    def held_points(self) -> int:
        """Points the tab holds, shown or hidden."""
        return self._held_points

    @property
    def shown_points(self) -> int:
        """Points the tab shows."""
        return int(sum(int(self._counts[k]) for k in self.shown))

    # ------------------------------------------------------------------ changes

    def set_budget(self, budget: int) -> None:
        """A new budget (takes effect with the next :meth:`plan`)."""
        self.budget = self._check_budget(budget)

    def plan(self, selected: Iterable[int]) -> ResidencyPlan:
        """The changes for a new selection, recorded as done.

        Parameters
        ----------
        selected : iterable of int
            Node rows, in the selection's order (:attr:`Selection.nodes`).
        """
        order = list(dict.fromkeys(int(k) for k in selected))
        m = self._counts.shape[0]
        bad = [k for k in order if not 0 <= k < m]
        if bad:
            raise IndexError(f"no node {bad[0]}: the octree has {m} nodes")
        self._clock += 1
        wanted = set(order)
        send = [k for k in order if k not in self._visible]
        show = [k for k in order if self._visible.get(k) is False]
        hide = [k for k, v in self._visible.items() if v and k not in wanted]
        recolour = [k for k in show if k in self._stale]
        for k in hide:
            self._visible[k] = False
        for k in show:
            self._visible[k] = True
            self._stale.discard(k)
        for k in send:
            self._visible[k] = True
            self._held_points += int(self._counts[k])
        for k in order:
            self._used[k] = self._clock
        evict = self._evict()
        gone = set(evict)  # a node hidden and evicted in one plan is only removed
        hide = [k for k in hide if k not in gone]
        return ResidencyPlan(send=tuple(send), show=tuple(show), hide=tuple(hide),
                             evict=tuple(evict), recolour=tuple(recolour))

    def _evict(self) -> list[int]:
        limit = self.keep_factor * self.budget
        if self._held_points <= limit:
            return []
        hidden = sorted((k for k, v in self._visible.items() if not v),
                        key=lambda k: (self._used[k], -k))  # oldest first, finer first
        out = []
        for k in hidden:
            if self._held_points <= limit:
                break
            self._forget(k)
            out.append(k)
        return out

    def _forget(self, k: int) -> None:
        del self._visible[k]
        del self._used[k]
        self._stale.discard(k)
        self._held_points -= int(self._counts[k])

    def colours_changed(self) -> tuple[int, ...]:
        """The colours of the points changed: the shown nodes to recolour now; hidden
        ones are recoloured when shown again (:attr:`ResidencyPlan.recolour`)."""
        self._stale = {k for k, v in self._visible.items() if not v}
        return self.shown

    def discard(self, nodes: Iterable[int]) -> None:
        """Forget nodes the app could not send or has removed itself."""
        for k in nodes:
            if int(k) in self._visible:
                self._forget(int(k))

    def clear(self) -> tuple[int, ...]:
        """Forget every node (a new cloud, a crop): the nodes to remove."""
        held = self.held
        self.discard(held)
        return held
