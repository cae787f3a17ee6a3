"""Graph helpers shared by the automaton code: reachability and strongly connected components.

Nodes are any hashable values; ``successors(v)`` returns an iterable of nodes. Both functions
are iterative (no recursion limit) and explore only what is reachable from the given roots.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterable, Iterator

__all__ = ["reachable", "strongly_connected_components"]


def reachable(sources: Iterable[Hashable], successors: Callable) -> set:
    """Every node reachable from ``sources`` (sources included)."""
    seen = set(sources)
    stack = list(seen)
    while stack:
        v = stack.pop()
        for w in successors(v):
            if w not in seen:
                seen.add(w)
                stack.append(w)
    return seen


def strongly_connected_components(roots: Iterable[Hashable], successors: Callable) -> Iterator[list]:
    """Strongly connected components reachable from ``roots`` (iterative Tarjan).

    Components are yielded as lists, each one after every component it can reach (reverse
    topological order), lazily, so a caller may stop at the first interesting one.
    """
    index: dict = {}
    low: dict = {}
    on_stack: set = set()
    stack: list = []
    counter = 0
    for root in roots:
        if root in index:
            continue
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(successors(root)))]
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(successors(w))))
                    advanced = True
                    break
                if w in on_stack and index[w] < low[v]:
                    low[v] = index[w]
            if advanced:
                continue
            work.pop()
            if work:
                u = work[-1][0]
                if low[v] < low[u]:
                    low[u] = low[v]
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                yield comp
