"""Per-tab residency: a simulated tab applies every plan; what it holds always
matches, shown = selected, held points stay within twice the budget, eviction is
least recently used, colours follow every change."""

from __future__ import annotations

import numpy as np
import pytest

from rough_viewer.lod.octree import build_octree
from rough_viewer.lod.residency import Residency
from rough_viewer.lod.select import select_nodes
from rough_viewer.vocabulary import InputError
from tests.lod.helpers import outcrop, random_camera


class Tab:
    """What a browser tab holds: node -> shown, and each node's colour version."""

    def __init__(self) -> None:
        self.nodes: dict[int, bool] = {}
        self.colour: dict[int, int] = {}
        self.sent = 0

    def apply(self, plan, counts, version: int) -> None:
        for k in plan.evict:
            assert self.nodes.pop(k) is False  # only hidden nodes are evicted
            del self.colour[k]
        for k in plan.hide:
            assert self.nodes[k] is True
            self.nodes[k] = False
        for k in plan.show:
            assert self.nodes[k] is False
            self.nodes[k] = True
        for k in plan.recolour:
            assert k in plan.show
            self.colour[k] = version
        for k in plan.send:
            assert k not in self.nodes  # never sent twice while held
            self.nodes[k] = True
            self.colour[k] = version
            self.sent += int(counts[k])


def test_a_tab_follows_random_cameras_within_twice_its_budget():
    cloud = outcrop(80_000, seed=31)
    tree = build_octree(cloud, root_grid=16, max_node_points=1_000)
    budget = 12_000
    res = Residency(tree.counts, budget)
    tab = Tab()
    rng = np.random.default_rng(32)
    version = 0
    last_used: dict[int, int] = {}
    for step in range(60):
        if step % 7 == 3:  # a model change: every shown node recoloured now
            version += 1
            for k in res.colours_changed():
                assert tab.nodes[k] is True
                tab.colour[k] = version
        sel = select_nodes(tree, random_camera(rng, cloud), budget)
        hidden_before = {k for k, v in tab.nodes.items() if not v}
        plan = res.plan(sel.nodes)
        tab.apply(plan, tree.counts, version)
        for k in sel.nodes.tolist():
            last_used[k] = step
        shown = {k for k, v in tab.nodes.items() if v}
        assert shown == set(sel.nodes.tolist()) == set(res.shown)
        assert set(tab.nodes) == set(res.held)
        held = int(tree.counts[list(tab.nodes)].sum())
        assert held == res.held_points <= 2 * budget
        assert all(tab.colour[k] == version for k in shown)  # colours follow every change
        if plan.evict:  # least recently used first: none kept was older than one evicted
            kept_hidden = hidden_before - set(plan.evict) - set(plan.show)
            oldest_kept = min((last_used[k] for k in kept_hidden), default=step)
            assert max(last_used[k] for k in plan.evict) <= oldest_kept
    assert tab.sent > 2 * budget  # the cameras did move the tab around


def test_hidden_nodes_come_back_without_resending():
    res = Residency([100, 100, 100, 100], budget=250)
    assert res.plan([0, 1]).send == (0, 1)
    p = res.plan([0, 2])
    assert p.send == (2,) and p.hide == (1,)
    p = res.plan([0, 1])
    assert p.send == () and p.show == (1,) and p.hide == (2,)
    assert res.held_points == 300 and res.shown_points == 200


def test_eviction_beyond_twice_the_budget_oldest_first():
    res = Residency([10] * 10, budget=20)
    for k in range(0, 10, 2):
        res.plan([k, k + 1])
    # held 100 > 40: the three oldest pairs went, oldest first
    assert set(res.held) == {6, 7, 8, 9}
    assert res.held_points == 40


def test_stale_colours_arrive_when_a_node_is_shown_again():
    res = Residency([5, 5, 5], budget=100)
    res.plan([0, 1])
    res.plan([0])  # 1 hidden
    assert res.colours_changed() == (0,)
    p = res.plan([0, 1])
    assert p.show == (1,) and p.recolour == (1,)
    assert res.plan([0, 1]).empty  # nothing more to do


def test_clear_discard_budget_and_bad_input():
    res = Residency([5, 5, 5], budget=10)
    res.plan([0, 1])
    res.discard([1])
    assert res.held == (0,)
    assert res.plan([0, 1]).send == (1,)
    assert set(res.clear()) == {0, 1} and res.held == () and res.held_points == 0
    res.set_budget(3)
    assert res.budget == 3
    with pytest.raises(IndexError, match="no node 7"):
        res.plan([7])
    with pytest.raises(InputError, match="point budget"):
        Residency([1], budget=0)
    with pytest.raises(InputError, match="keep factor"):
        Residency([1], budget=5, keep_factor=0.5)


def test_a_lowered_budget_evicts_nodes_it_does_not_also_hide():
    """Issue 36: lowering the budget below half of what a tab holds made one plan hide
    and evict the same nodes; the app removed them and then hid them (KeyError in the
    budget job). Every node is in at most one of a plan's lists, and applying the
    plans in order to a plain set of handles never touches a removed node."""
    counts = np.full(40, 1_000)
    tab = Residency(counts, budget=30_000)
    handles: dict[int, bool] = {}

    def apply(p):
        lists = [set(p.send), set(p.show), set(p.hide), set(p.evict)]
        assert sum(len(x) for x in lists) == len(set().union(*lists))
        for k in p.evict:
            del handles[k]
        for k in p.hide:
            handles[k] = False  # a KeyError here is the app's bug
            assert k in tab.held
        for k in p.show:
            assert k in handles
            handles[k] = True
        for k in p.send:
            handles[k] = True

    apply(tab.plan(range(30)))
    tab.set_budget(3_000)  # the tab holds 30 k points, ten times the new budget
    apply(tab.plan([35, 36, 37]))
    assert tab.held_points <= 2 * 3_000
    assert sorted(k for k, v in handles.items() if v) == [35, 36, 37]
    assert set(handles) == set(tab.held)
