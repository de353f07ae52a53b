"""Thread-safe least-recently-used caches bounded by the bytes of their values, alone
or several sharing one budget (:class:`ByteBudget`), and the slots that bound how
many computations fill them at once (:class:`ComputeSlots`)."""

from __future__ import annotations

import itertools
import os
import threading
import weakref
from collections import OrderedDict, deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import fields, is_dataclass
from typing import Any, Generic, TypeVar

import numpy as np


def nbytes(obj: object) -> int:
    """Bytes held by the numpy arrays inside ``obj`` (dataclasses, tuples, lists and
    dicts are walked; an array and its views count once, at their base's size)."""
    seen: set[int] = set()
    total = 0
    stack: list[object] = [obj]
    while stack:
        o = stack.pop()
        if isinstance(o, np.ndarray):
            base = o
            while isinstance(base.base, np.ndarray):
                base = base.base
            if id(base) not in seen:
                seen.add(id(base))
                total += int(base.nbytes)
        elif is_dataclass(o) and not isinstance(o, type):
            stack.extend(getattr(o, f.name) for f in fields(o))
        elif isinstance(o, (tuple, list)):
            stack.extend(o)
        elif isinstance(o, dict):
            stack.extend(o.values())
    return total


K = TypeVar("K")
V = TypeVar("V")


def default_slots() -> int:
    """Computations at once by default: the cores, at least 2 (so one long grid never
    holds every slot) and at most 4 (each holds the memory of a grid computation)."""
    return max(2, min(4, os.cpu_count() or 2))


class ComputeSlots:
    """At most :attr:`n` heavy computations at once, served first come, first served.

    The analyses of ``serve --classroom`` (one per browser tab, each on its own worker
    thread) share one set: thirty tabs asking for thirty grids at once compute at
    most ``n`` of them together, so memory stays within ``n`` grid computations, and
    a tab that asked first is served first, so one tab's fine grid takes one slot and
    never starves the others. A waiting computation whose job is cancelled (its tab
    moved on) leaves the queue at once.

    Parameters
    ----------
    n
        Slots (default :func:`default_slots`).

    Examples
    --------
    >>> slots = ComputeSlots(2)
    >>> with slots.held():
    ...     slots.busy
    1
    >>> slots.busy
    0
    """

    def __init__(self, n: int | None = None) -> None:
        self.n = int(n) if n is not None else default_slots()
        if self.n < 1:
            raise ValueError(f"compute slots must be at least 1, got {self.n}")
        self._cond = threading.Condition()
        self._queue: deque[object] = deque()
        self.busy = 0
        """Slots held now."""
        self.served = 0
        """Computations that held a slot so far."""

    @property
    def waiting(self) -> int:
        with self._cond:
            return len(self._queue)

    @contextmanager
    def held(self, check: Callable[[], object] | None = None,
             poll_s: float = 0.1) -> Iterator[None]:
        """Hold a slot for the block (waiting in turn); ``check()`` is called while
        waiting (it raises to give up: a cancelled job's progress callback)."""
        ticket = object()
        with self._cond:
            self._queue.append(ticket)
            try:
                while self._queue[0] is not ticket or self.busy >= self.n:
                    if check is not None:
                        self._cond.release()
                        try:
                            check()
                        finally:
                            self._cond.acquire()
                    self._cond.wait(poll_s)
            except BaseException:
                self._queue.remove(ticket)
                self._cond.notify_all()
                raise
            self._queue.popleft()
            self.busy += 1
            self.served += 1
            self._cond.notify_all()
        try:
            yield
        finally:
            with self._cond:
                self.busy -= 1
                self._cond.notify_all()


class ByteBudget:
    """One memory budget several :class:`ByteCache` draw from: together they hold at
    most :attr:`total` bytes. A cache that needs room drops its own least recently
    used values first, then the least recently used values of the others (pinned
    values are never dropped). One lock guards every cache of the budget.

    Parameters
    ----------
    total
        Most bytes (by :func:`nbytes`) of all the caches together.
    """

    def __init__(self, total: int, *, slots: ComputeSlots | None = None) -> None:
        self.total = int(total)
        self.slots = slots
        """The computations that fill the caches of this budget wait for one of these
        (None: no limit, the one analysis of an app computes one thing at a time)."""
        self.lock = threading.RLock()
        self._members: weakref.WeakSet[ByteCache[Any, Any]] = weakref.WeakSet()
        self._clock = itertools.count()

    def join(self, cache: ByteCache[Any, Any]) -> None:
        with self.lock:
            self._members.add(cache)

    def tick(self) -> int:
        """A number larger than every earlier one (when a value was last used)."""
        return next(self._clock)

    @property
    def used(self) -> int:
        """Bytes held by all the caches now."""
        with self.lock:
            return sum(c.bytes for c in list(self._members))

    def members(self) -> list[ByteCache[Any, Any]]:
        with self.lock:
            return list(self._members)


class ByteCache(Generic[K, V]):
    """A thread-safe least-recently-used cache bounded by the bytes of its values.

    Parameters
    ----------
    budget
        Most bytes (by :func:`nbytes`) the cache holds, or a :class:`ByteBudget` it
        shares with other caches (it then holds at most ``most`` bytes of it). A
        value larger than the whole budget is not kept.
    pinned
        Keys never evicted to make room (they still count against the budget).
    most
        With a shared budget: the most this cache may hold of it (default all).
    """

    def __init__(self, budget: int | ByteBudget, *,
                 pinned: Callable[[K], bool] = lambda _k: False, most: int | None = None
                 ) -> None:
        self.pool = budget if isinstance(budget, ByteBudget) else ByteBudget(budget)
        self.budget = min(self.pool.total, self.pool.total if most is None else int(most))
        """Most bytes this cache holds (its share of :attr:`pool`)."""
        self._pinned = pinned
        self._items: OrderedDict[K, tuple[V, int, int]] = OrderedDict()
        self._bytes = 0
        self._lock = self.pool.lock
        self.pool.join(self)

    def get(self, key: K) -> V | None:
        with self._lock:
            item = self._items.get(key)
            if item is None:
                return None
            self._items[key] = (item[0], item[1], self.pool.tick())
            self._items.move_to_end(key)
            return item[0]

    def __contains__(self, key: object) -> bool:
        with self._lock:
            return key in self._items

    def put(self, key: K, value: V) -> bool:
        """Keep ``value`` (evicting least recently used values, this cache's first,
        to make room); returns False, evicting nothing, when it cannot fit beside the
        pinned values."""
        size = nbytes(value)
        with self._lock:
            old = self._items.pop(key, None)
            if old is not None:
                self._bytes -= old[1]
            own = [(t, k, self) for k, (_v, _n, t) in self._items.items() if not self._pinned(k)]
            others = sorted((t, k, c) for c in self.pool.members() if c is not self
                            for k, (_v, _n, t) in c._items.items() if not c._pinned(k))
            own_free = sum(self._items[k][1] for _t, k, _c in own)
            other_free = sum(c._items[k][1] for _t, k, c in others)
            if (self._bytes - own_free + size > self.budget
                    or self.pool.used - own_free - other_free + size > self.pool.total):
                return False  # it cannot fit: keep what is there rather than flush it
            for _t, k, c in [*own, *others]:  # own first (oldest first), then the pool's
                if self._bytes + size <= self.budget and \
                        self.pool.used + size <= self.pool.total:
                    break
                if c is not self and self._bytes + size > self.budget:
                    break  # only own values free this cache's share
                c._bytes -= c._items.pop(k)[1]
            if self._bytes + size > self.budget or self.pool.used + size > self.pool.total:
                return False
            self._items[key] = (value, size, self.pool.tick())
            self._bytes += size
            return True

    @property
    def bytes(self) -> int:
        """Bytes held now."""
        with self._lock:
            return self._bytes

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)



class KeyedLocks:
    """One lock per key, held by one thread at a time: what makes a value once however
    many threads ask for it together (the others wait, then find it made). A key's
    lock is dropped once no thread holds or waits for it.

    >>> locks = KeyedLocks()
    >>> with locks.held("grid 0.25"):
    ...     len(locks)
    1
    >>> len(locks)
    0
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._locks: dict[object, tuple[threading.Lock, int]] = {}

    def __len__(self) -> int:
        with self._lock:
            return len(self._locks)

    @contextmanager
    def held(self, key: object) -> Iterator[None]:
        with self._lock:
            lock, users = self._locks.get(key, (threading.Lock(), 0))
            self._locks[key] = (lock, users + 1)
        try:
            with lock:
                yield
        finally:
            with self._lock:
                lock, users = self._locks[key]
                if users > 1:
                    self._locks[key] = (lock, users - 1)
                else:
                    del self._locks[key]


class Memo(Generic[K, V]):
    """The last :attr:`most` values made by key, each made once however many threads
    ask for it at once (the others wait for it): what the analyses of a classroom's
    tabs derive alike from a shared grid (its panels' figures).

    A ``make`` that raises (a cancelled job) or returns None leaves nothing behind:
    the next caller makes it again.

    >>> memo: Memo[str, int] = Memo(2)
    >>> memo.get_or_make("a", lambda: 1), memo.get_or_make("a", lambda: 2)
    (1, 1)
    """

    def __init__(self, most: int = 64) -> None:
        self.most = int(most)
        self._items: OrderedDict[K, V] = OrderedDict()
        self._lock = threading.Lock()
        self._making = KeyedLocks()
        self.made = 0
        """Values made so far (a test counts them)."""

    def get_or_make(self, key: K, make: Callable[[], V | None]) -> V | None:
        with self._lock:
            if key in self._items:
                self._items.move_to_end(key)
                return self._items[key]
        with self._making.held(key):
            with self._lock:
                if key in self._items:
                    return self._items[key]
            value = make()
            with self._lock:
                if value is not None:
                    self.made += 1
                    self._items[key] = value
                    while len(self._items) > self.most:
                        self._items.popitem(last=False)
            return value
