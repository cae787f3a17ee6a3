"""A bounded, thread-safe least-recently-used memo (the forest's per-obstacle and per-pair
results, the online world's navigation functions)."""

from __future__ import annotations

import threading
from collections import OrderedDict

__all__ = ["Memo"]

_MISSING = object()


class Memo:
    """Bounded, thread-safe LRU mapping: :meth:`get` returns ``None`` for a missing key and
    marks a found one as recently used; :meth:`put` evicts the least recently used entries
    beyond ``maxsize``. ``hits`` and ``misses`` count lookups."""

    def __init__(self, maxsize: int):
        self.maxsize = maxsize
        self._data: OrderedDict = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def get(self, key):
        with self._lock:
            try:
                value = self._data[key]
            except KeyError:
                self.misses += 1
                return None
            self._data.move_to_end(key)
            self.hits += 1
            return value

    def get_many(self, keys) -> list:
        """:meth:`get` of every key (one lock for the batch)."""
        out = []
        data = self._data
        with self._lock:
            for key in keys:
                value = data.get(key, _MISSING)
                if value is _MISSING:
                    self.misses += 1
                    out.append(None)
                else:
                    data.move_to_end(key)
                    self.hits += 1
                    out.append(value)
        return out

    def put_many(self, items) -> None:
        """:meth:`put` of every ``(key, value)`` pair (one lock for the batch)."""
        data = self._data
        with self._lock:
            for key, value in items:
                data[key] = value
                data.move_to_end(key)
            while len(data) > self.maxsize:
                data.popitem(last=False)

    def put(self, key, value) -> None:
        with self._lock:
            self._data[key] = value
            self._data.move_to_end(key)
            while len(self._data) > self.maxsize:
                self._data.popitem(last=False)

    def clear(self) -> None:
        with self._lock:
            self._data.clear()
            self.hits = self.misses = 0
