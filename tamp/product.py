"""The product of the navigation map and a Büchi automaton (paper 001 section 4.1.1).

Paper 001 defines ``A^ = G x A_phi`` with ``((g, s), (g', s')) in delta^`` when ``(g, g') in E``
and ``s' in delta(s, {g})``, weighted by ``d(g, g')``: the automaton reads the label of the
node being *left*. Here a product state ``(n, q)`` carries the automaton state *after* reading
the label of ``n`` — the paper's state of the successor — so the transition relation is

.. math::

    ((n, q), (n', q')) \\in \\hat\\delta \\iff (n, n') \\in E \\;\\wedge\\; q' \\in \\delta(q, L(n')),
    \\qquad \\hat d = d(n, n'),

i.e. the letter of the node being *entered* is read. The two products have the same runs up to
this one-step shift of the automaton component, the same costs and the same accepting lassos
(an accepting cycle visits the same automaton states), but with this convention the product
state changes the moment the robot reaches a region, which is what progress tracking and
co-safe (urgent) requests need: reaching ``u1`` *is* serving ``F u1``. Labels are singletons,
``L((g, theta)) = {g}``; the virtual start node has no incoming edge, so its label is never
read.

Product state ``(n, q)`` is the integer ``n * Q + q`` (``n`` the map node index, ``Q`` the
number of automaton states).

Structure versus weights
------------------------
The successor structure depends only on the automaton and the map's *node set*: the map is
fully connected and a removed edge has cost ``inf``. So :class:`Product` never stores weights:
it builds, lazily and once per automaton state ``q``, the row of pairs ``(n' * Q + q', n')``
(every map node ``n'`` and every ``q' in delta(q, L(n'))``); the successors of ``(n, q)`` are
that row, and the weight of a pair is looked up in the map's cost vector at ``n * N + n'``
(``inf`` = removed or self-loop). A cost change or a removal therefore touches no product data
at all; only the searches that read the changed weights are affected (see
:mod:`tamp.planner` for what they reuse).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from .ltl.automaton import Buchi
from .navmap import NavigationMap, Node

__all__ = ["Product", "ProductState"]

ProductState = tuple[Node, int]  #: a product state as (map node, automaton state)


class Product:
    """Lazy product ``NavigationMap x Buchi`` (entering convention, see the module docstring).

    Parameters
    ----------
    navmap : NavigationMap
    buchi : Buchi
        Its APs must be region names of ``navmap`` (checked by the planner, not here; a region
        that is not an AP reads as the empty letter).

    Attributes
    ----------
    Q, N : int
        Automaton states and map nodes; product states are ``0 .. N * Q - 1``.
    """

    def __init__(self, navmap: NavigationMap, buchi: Buchi):
        self.navmap = navmap
        self.buchi = buchi
        self.Q = buchi.num_states
        self.N = navmap.num_nodes
        # letter of each region (singleton) in the automaton's AP order
        region_letter = [buchi.mask([r]) for r in navmap.regions]
        self._node_letter = tuple(region_letter[r] if r >= 0 else None for r in navmap.node_region)
        self._rows: list[tuple[tuple[int, int], ...] | None] = [None] * self.Q
        self._accepting = buchi.accepting
        self.rows_built = 0
        self._row_arrays = None

    # ---- encoding -----------------------------------------------------------------------
    def encode(self, node, q: int) -> int:
        return self.navmap.index[self.navmap.node(node)] * self.Q + int(q)

    def decode(self, s: int) -> ProductState:
        n, q = divmod(s, self.Q)
        return self.navmap.nodes[n], q

    def is_accepting(self, s: int) -> bool:
        return s % self.Q in self._accepting

    def letter(self, node) -> int | None:
        """The automaton letter read on entering ``node`` (``None`` for the start node)."""
        return self._node_letter[self.navmap.index[self.navmap.node(node)]]

    # ---- structure ----------------------------------------------------------------------
    def row(self, q: int) -> tuple[tuple[int, int], ...]:
        """Pairs ``(n' * Q + q', n')`` for every map node ``n'`` and ``q' in delta(q, L(n'))``."""
        r = self._rows[q]
        if r is None:
            Q = self.Q
            b = self.buchi
            out = []
            by_letter: dict[int, tuple[int, ...]] = {}
            for n2, m in enumerate(self._node_letter):
                if m is None:
                    continue
                succ = by_letter.get(m)
                if succ is None:
                    succ = by_letter[m] = b.successors(q, m)
                for q2 in succ:
                    out.append((n2 * Q + q2, n2))
            r = self._rows[q] = tuple(out)
            self.rows_built += 1
        return r

    def row_arrays(self):
        """Every row of :meth:`row` as CSR arrays ``(ptr, t, n')`` (``int64``; row ``q`` is
        ``ptr[q] .. ptr[q + 1]``) and the accepting mask over automaton states, built once (for
        the compiled search, :mod:`tamp._product_kernel`)."""
        arrs = self._row_arrays
        if arrs is None:
            rows = [self.row(q) for q in range(self.Q)]
            ptr = np.zeros(self.Q + 1, dtype=np.int64)
            ptr[1:] = np.cumsum([len(r) for r in rows])
            flat = np.array([pair for r in rows for pair in r], dtype=np.int64).reshape(-1, 2)
            acc = np.zeros(self.Q, dtype=np.bool_)
            acc[list(self._accepting)] = True
            arrs = self._row_arrays = (ptr, np.ascontiguousarray(flat[:, 0]), np.ascontiguousarray(flat[:, 1]), acc)
        return arrs

    def successors(self, s: int, costs=None) -> list[tuple[int, float]]:
        """Successors of product state ``s`` with their current weights (``inf`` skipped)."""
        n, q = divmod(s, self.Q)
        costs = self.navmap.costs if costs is None else costs
        base = n * self.N
        return [(t, costs[base + n2]) for t, n2 in self.row(q) if costs[base + n2] != float("inf")]

    def initial_states(self, node, states: Iterable[int], *, read: bool) -> list[int]:
        """Product states at ``node`` for automaton ``states``; with ``read`` the label of
        ``node`` is read first (the robot *is* in that region), otherwise the states are taken
        as they are (already read, or the start node)."""
        n = self.navmap.index[self.navmap.node(node)]
        m = self._node_letter[n]
        out: set[int] = set()
        for q in states:
            if read and m is not None:
                out.update(self.buchi.successors(q, m))
            else:
                out.add(q)
        return sorted(n * self.Q + q for q in out)

    def reachable(self, sources: Iterable[int]) -> tuple[int, int]:
        """``(states, edges)`` of the part reachable from ``sources`` over finite-cost edges
        (builds every row it meets; a size report for benchmarks and tests)."""
        costs = self.navmap.costs
        inf = float("inf")
        seen = set(sources)
        stack = list(seen)
        n_edges = 0
        N, Q = self.N, self.Q
        while stack:
            s = stack.pop()
            n, q = divmod(s, Q)
            base = n * N
            for t, n2 in self.row(q):
                if costs[base + n2] == inf:
                    continue
                n_edges += 1
                if t not in seen:
                    seen.add(t)
                    stack.append(t)
        return len(seen), n_edges

    def word(self, nodes: Iterable[Node]) -> list[int]:
        """Letters read along ``nodes`` (the start node reads nothing)."""
        out = []
        for node in nodes:
            m = self.letter(node)
            if m is not None:
                out.append(m)
        return out

    def __repr__(self) -> str:
        return (f"Product({self.N} map nodes x {self.Q} automaton states, "
                f"{self.rows_built} rows built, start={'yes' if self.navmap.has_start else 'no'})")

