"""Thread-safe least-recently-used caches bounded by the bytes of their values, alone
or several sharing one budget (:class:`ByteBudget`)."""

from __future__ import annotations

import itertools
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable
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

    def __init__(self, total: int) -> None:
        self.total = int(total)
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

