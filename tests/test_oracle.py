"""Guarantee: the evaluation's oracle (issue 8) is a lower bound on the travel distance of any
run that enters the regions in order: exact in an empty world against the continuous optimum,
never above the executive benchmark's centre-to-centre tour, and below every completed run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.executive import _world, full_knowledge_tour
from benchmarks.methods import oracle_tour
from tests.worldgen import empty_world


def test_oracle_is_the_continuous_optimum_in_an_empty_world():
    """``simple`` without obstacles: to one disc the straight line minus its radius; through two
    discs the best touch point on the first, found by brute force over 20000 points of its
    circle; every order tried with ``visit_all``; a start inside a disc visits it at no cost."""
    w = empty_world("simple", (1.0, 2.0))
    s = np.array([1.0, 2.0])
    a, b, c = (w.regions[n] for n in ("a", "b", "c"))
    d, order = oracle_tour(w, ["b"])
    assert order == ["b"] and d == pytest.approx(np.linalg.norm(s - b.center) - b.radius, abs=1e-3)
    t = 2 * np.pi * np.arange(20000) / 20000
    p = np.asarray(b.center) + b.radius * np.stack([np.cos(t), np.sin(t)], axis=1)
    best = np.min(np.linalg.norm(p - s, axis=1) + np.linalg.norm(p - c.center, axis=1)) - c.radius
    d, _ = oracle_tour(w, ["b", "c"])
    assert d == pytest.approx(best, abs=2e-3)
    assert d < full_knowledge_tour(w, ["b", "c"]) - 0.1  # the centre-to-centre tour is longer
    d_all, order = oracle_tour(w, ["b", "a", "c"], visit_all=True)
    assert sorted(order) == ["a", "b", "c"]
    assert d_all <= oracle_tour(w, ["b", "a", "c"])[0] + 1e-12
    assert d_all == pytest.approx(min(oracle_tour(w, list(o))[0] for o in
                                      (("a", "b", "c"), ("a", "c", "b"), ("b", "a", "c"), ("b", "c", "a"),
                                       ("c", "a", "b"), ("c", "b", "a"))), abs=1e-12)
    inside = empty_world("simple", tuple(np.asarray(a.center) + [0.05, 0.0]))
    assert oracle_tour(inside, ["a"])[0] == 0.0
    assert oracle_tour(inside, ["a", "c"])[0] == pytest.approx(oracle_tour(inside, ["c"])[0], abs=1e-9)


@pytest.mark.parametrize("name", ["office", "cluttered20", "random0", "random5"])
def test_oracle_is_below_the_centre_to_centre_tour(name):
    """With obstacles: never above :func:`benchmarks.executive.full_knowledge_tour` of the same
    order (which goes through the centres, 5 cm off the grown obstacles), and finite."""
    w, task = _world(name)
    seq = ["p2", "d3", "d1", "d2"] if name == "office" else list(w.regions)
    d, order = oracle_tour(w, seq)
    assert order == seq and math.isfinite(d) and d > 0
    assert d <= full_knowledge_tour(w, seq) + 1e-9


def test_tour_keeping_a_clearance():
    """``buffer``: the tour of a robot keeping that clearance. In the empty world a leg far from
    the walls is the straight line at any buffer; a start closer than the buffer to the wall has
    no such tour (``ValueError``); with obstacles the tour never shortens as the buffer grows,
    and at HT's 0.15 m ``cluttered20``'s is more than 1.2 x the lower bound (the share of issue 8's
    1.25 x that the paper's buffer alone takes: docs/evaluation.md)."""
    w = empty_world("simple", (1.0, 2.0))
    assert oracle_tour(w, ["b"], buffer=0.15)[0] == pytest.approx(oracle_tour(w, ["b"])[0], abs=1e-9)
    with pytest.raises(ValueError, match="at buffer 0.15"):
        oracle_tour(empty_world("simple", (0.2, 2.0)), ["b"], buffer=0.15)
    for name in ("office", "cluttered20", "random0"):
        wn, _ = _world(name)
        seq = ["p2", "d3", "d1", "d2"] if name == "office" else list(wn.regions)
        tours = [oracle_tour(wn, seq, visit_all=name != "office", buffer=b)[0] for b in (0.0, 0.05, 0.15)]
        assert all(math.isfinite(t) for t in tours)
        assert tours[0] <= tours[1] + 0.01 and tours[1] <= tours[2] + 0.01, (name, tours)  # roadmap error: mm
        if name == "cluttered20":
            assert tours[2] > 1.2 * tours[0]
