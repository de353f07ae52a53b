"""The classroom's sharing of work: compute slots (first come, first served, a
cancelled waiter leaves) and one computation per grid however many analyses ask."""

from __future__ import annotations

import threading
import time

import pytest

from rough_viewer.app.cache import ByteBudget, ComputeSlots
from rough_viewer.app.cloud import LoadedCloud
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.worker import Cancelled
from tests.app.browser import wait_until


def test_slots_serve_in_turn_and_bound_how_many_run_at_once():
    slots = ComputeSlots(2)
    order: list[int] = []
    running = [0]
    most = [0]
    gate = threading.Event()
    lock = threading.Lock()

    def work(k: int) -> None:
        with slots.held():
            with lock:
                order.append(k)
                running[0] += 1
                most[0] = max(most[0], running[0])
            gate.wait(5)
            with lock:
                running[0] -= 1

    threads = []
    for k in range(6):
        t = threading.Thread(target=work, args=(k,))
        t.start()
        threads.append(t)
        wait_until(lambda k=k: slots.waiting + slots.busy == k + 1, 5, "the request queued")
    assert slots.busy == 2 and slots.waiting == 4
    assert order == [0, 1]
    gate.set()
    for t in threads:
        t.join(10)
    assert order == [0, 1, 2, 3, 4, 5]  # first come, first served
    assert most[0] == 2 and slots.busy == 0 and slots.served == 6


def test_a_cancelled_waiter_leaves_the_queue():
    slots = ComputeSlots(1)
    release = threading.Event()
    cancelled = threading.Event()
    outcome: list[str] = []

    def holder() -> None:
        with slots.held():
            release.wait(10)

    def check() -> None:
        if cancelled.is_set():
            raise Cancelled

    def waiter() -> None:
        try:
            with slots.held(check, poll_s=0.02):
                outcome.append("ran")
        except Cancelled:
            outcome.append("cancelled")

    h = threading.Thread(target=holder)
    h.start()
    wait_until(lambda: slots.busy == 1, 5, "the slot held")
    w = threading.Thread(target=waiter)
    w.start()
    wait_until(lambda: slots.waiting == 1, 5, "the waiter queued")
    cancelled.set()
    w.join(5)
    assert outcome == ["cancelled"] and slots.waiting == 0
    release.set()
    h.join(5)
    with slots.held():  # the queue is not stuck behind the one that left
        assert slots.busy == 1


def test_many_analyses_asking_for_one_grid_compute_it_once(cloud, monkeypatch):
    """Eight threads (eight tabs' workers) ask the shared cloud for the same grid at
    once: it is computed once, each gets the same result, and with two compute slots
    never more than two computations run together."""
    from rough_viewer.app import store

    pool = ByteBudget(1 << 30, slots=ComputeSlots(2))
    loaded = LoadedCloud(cloud, cache_bytes=1 << 30, cache_pool=pool)
    calls: list[float] = []
    real = store.grid_roughness

    def counted(*args, **kwargs):
        calls.append(time.perf_counter())
        time.sleep(0.2)  # long enough for every thread to be waiting
        return real(*args, **kwargs)

    monkeypatch.setattr(store, "grid_roughness", counted)
    s = MapSettings(cell_size=loaded.default_cell_size)
    results: list[object] = []
    threads = [threading.Thread(target=lambda: results.append(loaded.result(s)))
               for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert len(calls) == 1
    assert len(results) == 8 and all(r is results[0] for r in results)
    # different grids at once: each computed once, at most two at a time
    sizes = [loaded.presets[k] for k in range(len(loaded.presets))]
    calls.clear()
    threads = [threading.Thread(target=loaded.result, args=(s.with_(cell_size=g, axis="z"),))
               for g in sizes for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert len(calls) == len(sizes)
    assert pool.slots is not None and pool.slots.busy == 0


def test_each_analysis_pins_its_own_grid(cloud):
    loaded = LoadedCloud(cloud, cache_bytes=1 << 30)
    a, b = object(), object()
    fine = MapSettings(cell_size=loaded.presets[-1])
    coarse = MapSettings(cell_size=loaded.presets[0])
    loaded.mark_shown(fine, a)
    loaded.mark_shown(coarse, b)
    pinned = loaded.store._pinned  # type: ignore[attr-defined]
    assert pinned(("result", fine.grid_key)) and pinned(("result", coarse.grid_key))
    loaded.forget_shown(b)
    assert pinned(("result", fine.grid_key)) and not pinned(("result", coarse.grid_key))


def test_slots_refuse_nonsense():
    with pytest.raises(ValueError):
        ComputeSlots(0)
