"""Compiled (numba) outer search of the nested Dijkstra (paper 001 section 4.1.1,
:func:`tamp.planner._nested_dijkstra`).

:func:`settle` runs Dijkstra's algorithm over the product automaton from ``sources`` to the end
(every reachable product state settled) and lists the accepting states in the order it settles
them. The planner then walks that list with its cycle searches and stops where the pure-Python
search stopped (``P(a) >= best``), so the result is the same: a state's cost and predecessor do
not change after it is settled (costs are ``>= 0``; a predecessor is replaced only by a strictly
cheaper one), and ties are broken as ``heapq`` breaks them on ``(cost, state)`` tuples: the
binary heap (:mod:`tamp._heap`) orders its entries by cost, then state, so the states are
settled in the same order.

The product's edges are the CSR arrays of :meth:`tamp.product.Product.row_arrays`: row ``q``
holds the pairs ``(t, n')`` of :meth:`~tamp.product.Product.row`; the edge from product state
``n * Q + q`` to ``t`` costs ``costs[n * N + n']``.
"""

from __future__ import annotations

import numba
import numpy as np

from ._heap import pop as _pop
from ._heap import push as _push

__all__ = ["settle", "warm_up"]

_JIT = dict(cache=True, nogil=True)


@numba.njit(**_JIT)
def settle(row_ptr, row_t, row_n, costs, Q, N, sources, accepting):
    """Dijkstra over the product from ``sources`` (cost 0 each, duplicates kept as ``heapq``
    would keep them). Returns ``(dist, pred, order)``: every state's cost (``inf``: not
    reached) and predecessor (``-1``: a source or not reached), and the accepting states
    (``accepting[q]``) in the order they were settled (a duplicated source twice)."""
    size = N * Q
    dist = np.full(size, np.inf)
    pred = np.full(size, -1, dtype=np.int64)
    longest = 0
    for q in range(Q):
        longest = max(longest, row_ptr[q + 1] - row_ptr[q])
    cap = len(sources) + size * longest + 1
    keys = np.empty(cap)
    vals = np.empty(cap, dtype=np.int64)
    order = np.empty(cap, dtype=np.int64)
    n_order = 0
    n = 0
    for s in sources:
        dist[s] = 0.0
        n = _push(keys, vals, n, 0.0, s)
    while n > 0:
        d, s = keys[0], vals[0]
        n = _pop(keys, vals, n)
        if d > dist[s]:
            continue
        node = s // Q
        q = s - node * Q
        if accepting[q]:
            order[n_order] = s
            n_order += 1
        base = node * N
        for j in range(row_ptr[q], row_ptr[q + 1]):
            t = row_t[j]
            nd = d + costs[base + row_n[j]]
            if nd < dist[t]:
                dist[t] = nd
                pred[t] = s
                n = _push(keys, vals, n, nd, t)
    return dist, pred, order[:n_order].copy()


def warm_up() -> float:
    """Compile (or load from numba's cache) the kernel (see :mod:`navigation.kernels`); returns
    the seconds it took."""
    import time

    t0 = time.perf_counter()
    settle(np.array([0, 1], dtype=np.int64), np.array([1], dtype=np.int64), np.array([1], dtype=np.int64),
           np.array([0.0, 1.0, 1.0, 0.0]), 1, 2, np.array([0], dtype=np.int64), np.array([True]))
    return time.perf_counter() - t0
