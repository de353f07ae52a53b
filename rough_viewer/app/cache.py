"""A thread-safe least-recently-used cache bounded by the bytes of its values."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import fields, is_dataclass
from typing import Generic, TypeVar

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


class ByteCache(Generic[K, V]):
    """A thread-safe least-recently-used cache bounded by the bytes of its values.

    Parameters
    ----------
    budget
        Most bytes (by :func:`nbytes`) the cache holds. A value larger than the
        whole budget is not kept.
    pinned
        Keys never evicted to make room (they still count against the budget).
    """

    def __init__(self, budget: int, *, pinned: Callable[[K], bool] = lambda _k: False) -> None:
        self.budget = int(budget)
        self._pinned = pinned
        self._items: OrderedDict[K, tuple[V, int]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    def get(self, key: K) -> V | None:
        with self._lock:
            item = self._items.get(key)
            if item is None:
                return None
            self._items.move_to_end(key)
            return item[0]

    def __contains__(self, key: object) -> bool:
        with self._lock:
            return key in self._items

    def put(self, key: K, value: V) -> bool:
        """Keep ``value`` (evicting least recently used values to make room);
        returns False, evicting nothing, when it cannot fit beside the pinned values."""
        size = nbytes(value)
        with self._lock:
            old = self._items.pop(key, None)
            if old is not None:
                self._bytes -= old[1]
            movable = [k for k in self._items if not self._pinned(k)]
            if self._bytes - sum(self._items[k][1] for k in movable) + size > self.budget:
                return False  # it cannot fit: keep what is there rather than flush it
            for k in movable:
                if self._bytes + size <= self.budget:
                    break
                self._bytes -= self._items.pop(k)[1]
            if self._bytes + size > self.budget:
                return False
            self._items[key] = (value, size)
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

