"""The product of the map and an automaton (paper 001 section 4.1.1), and the automaton
operations the planner uses (intersection, restart from a state set, trimming, emptiness)."""

from __future__ import annotations

import math
import random

import pytest

from tamp.ltl import Bdd, Buchi, Edge, parse, to_buchi
from tamp.ltl import ops
from tamp.ltl.semantics import accepts, evaluate
from tamp.navmap import START, NavigationMap, Node
from tamp.product import Product

A, B = Bdd.var(0), Bdd.var(1)


def buchi_f_a() -> Buchi:
    """Hand-built ``F a`` over ``(a,)``."""
    return Buchi(("a",), 0, ((Edge(~A, 0), Edge(A, 1)), (Edge(Bdd.true, 1),)), frozenset({1}), "F a")


def buchi_gf_a_gf_b() -> Buchi:
    """Hand-built ``G F a & G F b`` over ``(a, b)``: 0 waits for a, 1 waits for b, 2 accepting."""
    return Buchi(("a", "b"), 0,
                 ((Edge(~A, 0), Edge(A, 1)),
                  (Edge(~B, 1), Edge(B, 2)),
                  (Edge(~A, 0), Edge(A, 1))),
                 frozenset({2}), "G F a & G F b")


def test_entering_convention_and_rows():
    m = NavigationMap({"a": (0, 0), "b": (1, 0), "c": (2, 0)}, n_orient=2, start=(5, 5))
    prod = Product(m, buchi_f_a())
    s0 = prod.encode(Node(START, 0), 0)
    succ = dict(prod.successors(s0))
    # entering an "a" node reads {a}: 0 -> 1; entering b or c keeps 0
    assert {prod.decode(t) for t in succ} == {(Node("a", 0), 1), (Node("a", 1), 1), (Node("b", 0), 0),
                                              (Node("b", 1), 0), (Node("c", 0), 0), (Node("c", 1), 0)}
    for t, c in succ.items():
        assert c == pytest.approx(m.cost(Node(START, 0), prod.decode(t)[0]))
    # self-loops and edges into START never appear
    sa = prod.encode(Node("a", 0), 1)
    assert all(prod.decode(t)[0] not in (Node("a", 0), Node(START, 0)) for t, _ in prod.successors(sa))
    assert prod.is_accepting(sa) and not prod.is_accepting(s0)
    assert prod.initial_states(Node("a", 1), [0], read=True) == [prod.encode(Node("a", 1), 1)]
    assert prod.initial_states(Node("b", 1), [0], read=True) == [prod.encode(Node("b", 1), 0)]
    assert prod.word([Node(START, 0), Node("a", 0), Node("b", 1)]) == [1, 0]


def test_map_changes_touch_no_product_structure():
    m = NavigationMap({"a": (0, 0), "b": (1, 0)}, n_orient=4)
    prod = Product(m, buchi_gf_a_gf_b())
    before = prod.reachable([prod.encode(Node("a", 0), 1)])
    built = prod.rows_built
    m.set_cost("a", "b", 3.0)
    m.remove_edge(Node("a", 0), Node("b", 0))
    after = prod.reachable([prod.encode(Node("a", 0), 1)])
    assert prod.rows_built == built  # rows are per automaton state, never rebuilt
    # the two removed map edges carry at most Q product edges each
    assert after[0] == before[0] and 0 < before[1] - after[1] <= 2 * prod.Q
    n0 = m.index[Node("a", 0)]
    s = n0 * prod.Q + 1
    assert all(c == pytest.approx(m.costs[n0 * prod.N + t // prod.Q]) for t, c in prod.successors(s))


def test_reachable_size_matches_explicit_construction():
    nx = pytest.importorskip("networkx")
    m = NavigationMap({"a": (0, 0), "b": (1, 2), "c": (3, 1)}, n_orient=3, start=(0, 1))
    buchi = to_buchi(parse("G(a -> F b) & G !c & G F a"))
    prod = Product(m, buchi)
    g = nx.DiGraph()
    src = (Node(START, 0), buchi.initial)
    stack, seen = [src], {src}
    while stack:  # paper definition, entering form, built explicitly
        n, q = stack.pop()
        for n2 in m.nodes:
            if n2 == n or n2.region == START:
                continue
            for q2 in buchi.successors(q, buchi.mask([n2.region])):
                g.add_edge((n, q), (n2, q2))
                if (n2, q2) not in seen:
                    seen.add((n2, q2))
                    stack.append((n2, q2))
    assert prod.reachable([prod.encode(*src)]) == (len(seen), g.number_of_edges())


# ---- automaton operations ----------------------------------------------------------------
def random_word(rng: random.Random, names, n_max=4):
    letter = lambda: {rng.choice(names)} if rng.random() < 0.8 else set()  # noqa: E731
    return ([letter() for _ in range(rng.randint(0, n_max))],
            [letter() for _ in range(rng.randint(1, n_max))])


@pytest.mark.parametrize("f,g", [("G F a", "G F b"), ("F(a & F b)", "G !c"), ("a U b", "G F c"),
                                 ("G(a -> F b)", "F G !b"), ("F a", "G !a")])
def test_intersection_is_conjunction(f, g):
    rng = random.Random(7)
    inter = ops.intersect(to_buchi(parse(f)), to_buchi(parse(g)))
    conj = parse(f"({f}) & ({g})")
    for _ in range(150):
        u, v = random_word(rng, ["a", "b", "c"])
        assert accepts(inter, u, v) == evaluate(conj, u, v), (u, v)


def test_intersection_of_hand_built_automata():
    inter = ops.intersect(buchi_f_a(), buchi_gf_a_gf_b())
    assert accepts(inter, [], [{"a"}, {"b"}])
    assert not accepts(inter, [{"a"}], [{"b"}])
    assert ops.is_empty(ops.intersect(buchi_f_a(), to_buchi(parse("G !a"))))


def test_from_states_keeps_progress():
    b = buchi_gf_a_gf_b()
    rest = ops.from_states(b, [1])  # a already seen: b next
    assert accepts(rest, [{"b"}], [{"a"}, {"b"}])
    both = ops.from_states(b, [0, 1])  # union of the two futures
    assert accepts(both, [], [{"a"}, {"b"}]) and accepts(both, [{"b"}], [{"a"}, {"b"}])
    with pytest.raises(ValueError):
        ops.from_states(b, [])


def test_trim_is_empty_and_letters():
    f_ab = to_buchi(parse("F(a & b)"))
    assert not ops.is_empty(f_ab)
    single = ops.singleton_letters(f_ab, ["a", "b", "c"])
    assert ops.is_empty(f_ab, single)  # disjoint regions: a & b never holds
    t = ops.trim(f_ab, single)
    assert t.num_states == 1 and not t.accepting
    dead = Buchi(("a",), 0, ((Edge(A, 1), Edge(~A, 2)), (Edge(Bdd.true, 1),), ((Edge(A, 2)),)),
                 frozenset({1}))
    assert ops.trim(dead).num_states == 2 and ops.live_states(dead) == frozenset({0, 1})
    # over the empty letter only, state 1 still has its cycle but cannot be reached
    assert ops.live_states(dead, [0]) == frozenset({1}) and ops.is_empty(dead, [0])


def test_universal_states_mark_served_requests():
    fu = to_buchi(parse("F u1"))
    letters = ops.singleton_letters(fu, ["u1", "a"])
    d = ops.universal_states(fu, letters)
    assert len(d) == 1 and all(fu.successors(q, fu.mask(["a"])) for q in d)
    assert ops.universal_states(to_buchi(parse("G F a")), ops.singleton_letters(
        to_buchi(parse("G F a")), ["a", "b"])) == frozenset()


def test_synchronous_product_tracks_both():
    sp, pairs = ops.synchronous_product(buchi_f_a(), buchi_gf_a_gf_b())
    assert pairs[0] == (0, 0) and not sp.accepting
    q = sp.successors(0, sp.mask(["a"]))
    assert [pairs[i] for i in q] == [(1, 1)]
    assert math.isfinite(len(pairs))
