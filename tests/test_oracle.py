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
