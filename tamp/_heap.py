"""Compiled (numba) binary min-heap over parallel arrays, for the searches of
:mod:`tamp._astar_kernel` and :mod:`tamp._product_kernel`.

Entries ``(key, val)`` are ordered by ``key``, then ``val``: the order ``heapq`` gives
``(key, val)`` tuples, so a search that pops them settles nodes as the same search over
``heapq`` would. The caller owns the arrays (capacity: every push it can make) and the size.
"""

from __future__ import annotations

import numba

__all__ = ["push", "pop"]

_JIT = dict(cache=True, nogil=True)


@numba.njit(inline="always", **_JIT)
def _less(ka, va, kb, vb):
    return ka < kb or (ka == kb and va < vb)


@numba.njit(inline="always", **_JIT)
def push(keys, vals, n, key, val):
    """Insert ``(key, val)`` into the heap of size ``n``; returns the new size."""
    i = n
    while i > 0:
        p = (i - 1) >> 1
        if not _less(key, val, keys[p], vals[p]):
            break
        keys[i] = keys[p]
        vals[i] = vals[p]
        i = p
    keys[i] = key
    vals[i] = val
    return n + 1


@numba.njit(inline="always", **_JIT)
def pop(keys, vals, n):
    """Remove the root (``keys[0], vals[0]``, read before) of the heap of size ``n``; returns
    the new size."""
    n -= 1
    key, val = keys[n], vals[n]
    i = 0
    while True:
        c = 2 * i + 1
        if c >= n:
            break
        if c + 1 < n and _less(keys[c + 1], vals[c + 1], keys[c], vals[c]):
            c += 1
        if not _less(keys[c], vals[c], key, val):
            break
        keys[i] = keys[c]
        vals[i] = vals[c]
        i = c
    if n > 0:
        keys[i] = key
        vals[i] = val
    return n
