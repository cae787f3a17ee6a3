"""Operations on state-based Büchi automata that the mission planner needs.

* :func:`restrict_alphabet` / letters: the planner's words use one region per letter (regions
  are pairwise disjoint, FORMATS.md), so the alphabet is the set of *singleton* letters.
* :func:`from_states`: the automaton started in a *set* of states (the planner's progress).
* :func:`intersect`: language intersection, the Büchi product with the usual two-copy flag
  (Baier and Katoen, *Principles of Model Checking*, 2008, Thm. 4.56): state ``(p, q, i)``;
  the flag moves from copy 0 to copy 1 when leaving a state with ``p`` accepting in ``A``, and
  from 1 back to 0 when leaving a state with ``q`` accepting in ``B``; accepting states are
  ``(p, q, 0)`` with ``p`` accepting in ``A``.
* :func:`synchronous_product`: the plain product (no acceptance bookkeeping), used to follow two
  automata along one path.
* :func:`trim` / :func:`is_empty`: keep the states that are reachable and from which an
  accepting cycle is reachable (emptiness = no such state).
* :func:`universal_states`: states from which *every* word over the given letters is accepted
  (a sound under-approximation, used to decide that a co-safe request has been served).

All functions take an optional ``letters`` collection of masks: when given, an edge is usable
only if its guard holds for at least one of those letters.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable

from ._graph import reachable, strongly_connected_components
from .automaton import Buchi, Edge
from .bdd import Bdd

__all__ = [
    "singleton_letters",
    "edge_usable",
    "from_states",
    "intersect",
    "synchronous_product",
    "trim",
    "is_empty",
    "live_states",
    "universal_states",
]


def singleton_letters(buchi: Buchi, names: Iterable[str]) -> frozenset[int]:
    """Masks of the letters ``{r}`` for each region ``r`` in ``names`` (in ``buchi``'s APs;
    a region that is not an AP of ``buchi`` gives the empty letter ``0``)."""
    return frozenset(buchi.mask([r]) for r in names)


def edge_usable(guard: Bdd, letters: Collection[int] | None) -> bool:
    """True when ``guard`` holds for some letter of ``letters`` (any letter when ``None``)."""
    if letters is None:
        return not guard.is_false
    return any(guard.holds(m) for m in letters)


def _succ_graph(buchi: Buchi, letters) -> list[list[int]]:
    return [[e.dst for e in out if edge_usable(e.guard, letters)] for out in buchi.edges]


def _reachable(succ: list[list[int]], sources: Iterable[int]) -> set[int]:
    return reachable(sources, succ.__getitem__)


def _sccs(succ: list[list[int]], nodes: Iterable[int]) -> list[list[int]]:
    """Strongly connected components of the subgraph induced by ``nodes``."""
    nodes = list(nodes)
    inside = set(nodes)
    return list(strongly_connected_components(nodes, lambda v: [w for w in succ[v] if w in inside]))


def live_states(buchi: Buchi, letters: Collection[int] | None = None) -> frozenset[int]:
    """States from which an accepting cycle is reachable (using only ``letters``)."""
    succ = _succ_graph(buchi, letters)
    good: set[int] = set()
    for comp in _sccs(succ, range(buchi.num_states)):
        cs = set(comp)
        cyclic = len(comp) > 1 or comp[0] in succ[comp[0]]
        if cyclic and cs & buchi.accepting:
            good |= cs
    # backward closure
    pred: list[list[int]] = [[] for _ in range(buchi.num_states)]
    for q, out in enumerate(succ):
        for r in out:
            pred[r].append(q)
    return frozenset(_reachable(pred, good))


def trim(buchi: Buchi, letters: Collection[int] | None = None) -> Buchi:
    """Equivalent automaton (over ``letters``) without useless states.

    Keeps the states that are reachable from the initial state and live (an accepting cycle is
    reachable from them); edges unusable over ``letters`` are dropped. When the language is
    empty the result has the single non-accepting initial state and no edges.
    """
    succ = _succ_graph(buchi, letters)
    keep = _reachable(succ, [buchi.initial]) & live_states(buchi, letters)
    if buchi.initial not in keep:
        return Buchi(buchi.aps, 0, ((),), frozenset(), buchi.name)
    order = sorted(keep, key=lambda q: (q != buchi.initial, q))
    new = {q: i for i, q in enumerate(order)}
    edges = tuple(
        tuple(Edge(e.guard, new[e.dst]) for e in buchi.edges[q]
              if e.dst in new and edge_usable(e.guard, letters))
        for q in order)
    return Buchi(buchi.aps, 0, edges, frozenset(new[q] for q in keep & buchi.accepting), buchi.name)


def is_empty(buchi: Buchi, letters: Collection[int] | None = None) -> bool:
    """True when no word (over ``letters``) is accepted."""
    succ = _succ_graph(buchi, letters)
    return not (_reachable(succ, [buchi.initial]) & live_states(buchi, letters))


def from_states(buchi: Buchi, states: Iterable[int], name: str | None = None) -> Buchi:
    """The automaton that accepts the union of the languages of ``buchi`` from ``states``.

    A single state becomes the initial state; several are joined by a fresh, non-accepting
    initial state whose edges are the union of theirs (it is left at the first letter, so its
    acceptance does not matter). The result is :func:`trim`-med.
    """
    states = sorted(set(states))
    if not states:
        raise ValueError("from_states needs at least one state")
    if len(states) == 1:
        b = Buchi(buchi.aps, states[0], buchi.edges, buchi.accepting, buchi.name if name is None else name)
        return trim(b)
    n = buchi.num_states
    guards: dict[int, Bdd] = {}
    for q in states:
        for e in buchi.edges[q]:
            guards[e.dst] = guards.get(e.dst, Bdd.false) | e.guard
    fresh = tuple(Edge(g, d) for d, g in sorted(guards.items()))
    b = Buchi(buchi.aps, n, buchi.edges + (fresh,), buchi.accepting,
              buchi.name if name is None else name)
    return trim(b)


def _common(a: Buchi, b: Buchi) -> tuple[Buchi, Buchi, tuple[str, ...]]:
    aps = tuple(a.aps) + tuple(x for x in b.aps if x not in a.aps)
    return (a if a.aps == aps else a.relabel(aps)), (b if b.aps == aps else b.relabel(aps)), aps


def intersect(a: Buchi, b: Buchi, name: str | None = None,
              letters: Collection[int] | None = None) -> Buchi:
    """Büchi automaton of ``L(a) & L(b)`` (two-copy flag construction), :func:`trim`-med.

    The APs are ``a.aps`` followed by the APs of ``b`` that ``a`` lacks. ``letters`` (masks
    over those APs) restricts the usable edges.
    """
    a, b, aps = _common(a, b)
    key = {(a.initial, b.initial, 0): 0}
    order = [(a.initial, b.initial, 0)]
    edges: list[tuple[Edge, ...]] = []
    i = 0
    while i < len(order):
        p, q, f = order[i]
        i += 1
        if f == 0 and p in a.accepting:
            g = 1
        elif f == 1 and q in b.accepting:
            g = 0
        else:
            g = f
        out = []
        for ea in a.edges[p]:
            for eb in b.edges[q]:
                guard = ea.guard & eb.guard
                if not edge_usable(guard, letters):
                    continue
                t = (ea.dst, eb.dst, g)
                j = key.get(t)
                if j is None:
                    j = key[t] = len(order)
                    order.append(t)
                out.append(Edge(guard, j))
        edges.append(tuple(out))
    acc = frozenset(j for (p, _q, f), j in key.items() if f == 0 and p in a.accepting)
    nm = name if name is not None else f"({a.name}) & ({b.name})"
    return trim(Buchi(aps, 0, tuple(edges), acc, nm), letters)


def synchronous_product(a: Buchi, b: Buchi,
                        letters: Collection[int] | None = None) -> tuple[Buchi, list[tuple[int, int]]]:
    """Run ``a`` and ``b`` side by side: states ``(p, q)``, guards ``ga & gb``.

    Returns the automaton (accepting set empty: callers decide what a target is) and the list
    mapping each of its states to its pair ``(p, q)``. Not trimmed.
    """
    a, b, aps = _common(a, b)
    key = {(a.initial, b.initial): 0}
    order = [(a.initial, b.initial)]
    edges: list[tuple[Edge, ...]] = []
    i = 0
    while i < len(order):
        p, q = order[i]
        i += 1
        out = []
        for ea in a.edges[p]:
            for eb in b.edges[q]:
                guard = ea.guard & eb.guard
                if not edge_usable(guard, letters):
                    continue
                t = (ea.dst, eb.dst)
                j = key.get(t)
                if j is None:
                    j = key[t] = len(order)
                    order.append(t)
                out.append(Edge(guard, j))
        edges.append(tuple(out))
    return Buchi(aps, 0, tuple(edges), frozenset(), f"({a.name}) x ({b.name})"), order


def universal_states(buchi: Buchi, letters: Collection[int]) -> frozenset[int]:
    """States from which every infinite word over ``letters`` is accepted (sound subset).

    The greatest set ``D`` of accepting states such that for every letter each state of ``D``
    has a successor in ``D``: from ``D`` every word has a run that stays in ``D``, hence visits
    accepting states forever. For the usual automata of co-safe formulas (``F u1``,
    ``F(a & F b)``) these are exactly the states reached once the request is served.
    """
    letters = list(letters)
    d = set(buchi.accepting)
    changed = True
    while changed:
        changed = False
        for q in list(d):
            for m in letters:
                if not any(r in d for r in buchi.successors(q, m)):
                    d.discard(q)
                    changed = True
                    break
    return frozenset(d)
