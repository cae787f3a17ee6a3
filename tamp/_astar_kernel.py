"""Compiled (numba) A* of the harmonic trees (paper 001 eq. 8, :func:`tamp.harmonic_tree._astar`).

:func:`astar` searches the CSR graph of :func:`tamp.harmonic_tree._heading_graph` plus one
tree's start row for the cheapest path from the start node to the goal node, and stops when the
goal is settled: scipy's ``dijkstra`` (which it replaces) settles every node reachable from the
start, most of them farther from the goal than the path's cost.

* Heuristic ``h`` per node: the Euclidean distance from the node's position to the goal
  (a ``(vertex, heading)`` node and an edge node sit at their vertex, the edge node at its
  edge's head). Every edge of the graph costs at least the distance it moves (eq. 26: length
  plus non-negative rotation terms), so ``h`` is consistent: each node is settled once, with
  its cheapest cost, as in Dijkstra's algorithm.
* Costs are accumulated as scipy does (``g(v) = g(u) + w(u, v)``, a predecessor replaced only
  by a strictly cheaper one), so the path's cost is the same number; where two paths cost
  exactly the same, either may be returned.
* The open set is a binary heap of ``(g + h, node)`` (:mod:`tamp._heap`: ties broken by node)
  with stale entries skipped (lazy deletion); it holds at most one entry per relaxed edge.
"""

from __future__ import annotations

import numba
import numpy as np

from ._heap import pop as _pop
from ._heap import push as _push

__all__ = ["astar", "warm_up"]

_JIT = dict(cache=True, nogil=True)


@numba.njit(**_JIT)
def astar(indptr, indices, data, start_cols, start_vals, h, goal):
    """Cheapest path from the start node (``len(indptr) - 1``, whose out-edges are
    ``start_cols`` / ``start_vals``) to ``goal`` over the CSR graph ``indptr, indices, data``
    (rows ``0 .. len(indptr) - 2``), guided by the consistent heuristic ``h`` (one entry per
    node, the start's included).

    Returns ``(cost, pred, reached)``: the path's cost (``inf`` when the goal is unreachable),
    every node's predecessor (``-1``: none; the start is its own root) and ``g``'s finiteness
    per node (``reached``: a node was pushed).
    """
    n_rows = len(indptr) - 1
    S = n_rows
    N = n_rows + 1
    g = np.full(N, np.inf)
    pred = np.full(N, -1, dtype=np.int64)
    done = np.zeros(N, dtype=np.bool_)
    cap = len(indices) + len(start_cols) + 1
    keys = np.empty(cap)
    vals = np.empty(cap, dtype=np.int64)
    g[S] = 0.0
    done[S] = True
    n = 0
    for k in range(len(start_cols)):
        v = start_cols[k]
        nv = start_vals[k]
        if nv < g[v]:
            g[v] = nv
            pred[v] = S
            n = _push(keys, vals, n, nv + h[v], v)
    while n > 0:
        f, u = keys[0], vals[0]
        n = _pop(keys, vals, n)
        if done[u] or f > g[u] + h[u]:
            continue
        done[u] = True
        if u == goal:
            break
        gu = g[u]
        for j in range(indptr[u], indptr[u + 1]):
            v = indices[j]
            if done[v]:
                continue
            nv = gu + data[j]
            if nv < g[v]:
                g[v] = nv
                pred[v] = u
                n = _push(keys, vals, n, nv + h[v], v)
    return g[goal], pred, np.isfinite(g)


def warm_up() -> float:
    """Compile (or load from numba's cache) the kernel (see :mod:`navigation.kernels`); returns
    the seconds it took."""
    import time

    t0 = time.perf_counter()
    indptr = np.array([0, 1, 1], dtype=np.int32)
    astar(indptr, np.array([1], dtype=np.int32), np.array([1.0]), np.array([0], dtype=np.int32),
          np.array([0.5]), np.zeros(3), 1)
    return time.perf_counter() - t0
