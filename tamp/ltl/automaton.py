"""Büchi automata with BDD edge guards (the object the planner and HOA tools exchange).

A :class:`Buchi` is a *state-based* nondeterministic Büchi automaton over the alphabet
``2^aps``: states ``0 .. num_states-1``, one initial state, edges ``(guard, dst)`` per state
with :class:`~tamp.ltl.bdd.Bdd` guards over AP indices, and a set of accepting states. A run
is accepting when it visits an accepting state infinitely often (paper 001 section 4.1.1:
``B = (Q, Q0, 2^AP, delta, Q_F)``).

Letters are valuations given as ``int`` masks (bit ``i`` = ``aps[i]`` holds); build one from
region names with :meth:`Buchi.mask`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from .bdd import Bdd, valuation_mask

__all__ = ["Buchi", "Edge"]


@dataclass(frozen=True, slots=True)
class Edge:
    """One edge of a :class:`Buchi`: reading a letter that satisfies ``guard`` moves to ``dst``."""

    guard: Bdd
    dst: int


@dataclass(frozen=True)
class Buchi:
    """State-based nondeterministic Büchi automaton.

    Attributes
    ----------
    aps : tuple of str
        Atomic propositions; AP ``i`` is bit ``i`` of a letter mask and variable ``i`` of guards.
    initial : int
        The initial state.
    edges : tuple of tuple of Edge
        ``edges[q]`` are the edges leaving ``q`` (at most one per destination; guards never
        false).
    accepting : frozenset of int
        Accepting states.
    name : str
        Free text, usually the formula the automaton was built from.

    Build with :func:`tamp.ltl.to_buchi`, :meth:`from_hoa`, or directly (validated).
    """

    aps: tuple[str, ...]
    initial: int
    edges: tuple[tuple[Edge, ...], ...]
    accepting: frozenset[int]
    name: str = ""
    _succ_cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        n = len(self.edges)
        if n == 0:
            raise ValueError("a Büchi automaton needs at least one state")
        if not 0 <= self.initial < n:
            raise ValueError(f"initial state {self.initial} is not in 0..{n - 1}")
        for q, out in enumerate(self.edges):
            for e in out:
                if not 0 <= e.dst < n:
                    raise ValueError(f"edge {q} -> {e.dst}: destination not in 0..{n - 1}")
        bad = [q for q in self.accepting if not 0 <= q < n]
        if bad:
            raise ValueError(f"accepting states {bad} are not in 0..{n - 1}")
        if len(set(self.aps)) != len(self.aps):
            raise ValueError(f"duplicate atomic propositions in {self.aps}")

    @property
    def num_states(self) -> int:
        return len(self.edges)

    @property
    def num_edges(self) -> int:
        return sum(len(out) for out in self.edges)

    def mask(self, true_aps: Iterable[str]) -> int:
        """Letter in which exactly ``true_aps`` hold (names that are not APs are ignored)."""
        return valuation_mask(true_aps, self.aps)

    def successors(self, state: int, letter: int) -> tuple[int, ...]:
        """States reached from ``state`` reading ``letter`` (a mask). Cached."""
        key = (state, letter)
        hit = self._succ_cache.get(key)
        if hit is None:
            hit = tuple(e.dst for e in self.edges[state] if e.guard.holds(letter))
            self._succ_cache[key] = hit
        return hit

    def is_accepting(self, state: int) -> bool:
        return state in self.accepting

    # HOA v1 -------------------------------------------------------------------------------
    def to_hoa(self) -> str:
        """HOA v1 text (see :func:`tamp.ltl.hoa.to_hoa`)."""
        from .hoa import to_hoa

        return to_hoa(self)

    @classmethod
    def from_hoa(cls, text: str) -> "Buchi":
        """Read HOA v1 text (see :func:`tamp.ltl.hoa.from_hoa`)."""
        from .hoa import from_hoa

        return from_hoa(text)

    def __str__(self) -> str:
        return self.to_hoa()

    def relabel(self, aps: Sequence[str]) -> "Buchi":
        """The same automaton over a superset ``aps`` of its propositions (guards re-indexed)."""
        from .bdd import cube

        index = {a: i for i, a in enumerate(aps)}
        missing = [a for a in self.aps if a not in index]
        if missing:
            raise ValueError(f"relabel: propositions {missing} are not in {list(aps)}")
        edges = []
        for out in self.edges:
            new = []
            for e in out:
                g = Bdd.false
                for c in e.guard.cubes():
                    g = g | cube((index[self.aps[i]], pol) for i, pol in c)
                new.append(Edge(g, e.dst))
            edges.append(tuple(new))
        return Buchi(tuple(aps), self.initial, tuple(edges), self.accepting, self.name)
