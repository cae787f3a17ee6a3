"""Lasso planning (paper 001 section 4.1.1), re-planning (4.2.4), run-time mission changes (5.2)
and the errors of bad missions: optimality against independent references, validity of the
plans' words, re-planning == planning from scratch, progress kept across mission changes."""

from __future__ import annotations

import doctest
import heapq
import math
import random

import numpy as np

import pytest

import tamp
import tamp.planner
from tamp import MissionPlanner
from tamp.errors import (InvalidRequestError, LtlSyntaxError, NoPlanError, TampError,
                         UnknownRegionError, UnsatisfiableError)
from tamp.ltl import Bdd, Buchi, Edge, parse, to_buchi
from tamp.ltl.semantics import evaluate
from tamp.navmap import START, Node
from tamp._product_kernel import settle
from tamp.planner import MissionMode, Plan

FORMULAS = ["F a", "G F a & G F b", "F(a & F(b & F c))", "G(a -> F b) & G F a & G !d",
            "G F b & F G !a", "(!b U a) & F b", "G F(a | c) & G F b"]


def random_regions(rng: random.Random, n: int = 4) -> dict:
    names = "abcdefgh"[:n]
    return {r: (rng.uniform(0, 5), rng.uniform(0, 5)) for r in names}


# ---- references ------------------------------------------------------------------------------
def reference_cost(planner: MissionPlanner, sources) -> float:
    """min over accepting a of  P(a) + alpha * C(a), with networkx Dijkstra on the explicit
    product (every state; C(a) = min over a -> t of c + dist(t, a))."""
    nx = pytest.importorskip("networkx")
    m, b = planner.navmap, planner.automaton
    g = nx.DiGraph()
    for n in m.nodes:
        for q in range(b.num_states):
            for n2 in m.nodes:
                c = m.cost(n, n2) if n != n2 and n2.region != START else math.inf
                if c == math.inf:
                    continue
                for q2 in b.successors(q, b.mask([n2.region])):
                    g.add_edge((n, q), (n2, q2), weight=c)
    g.add_node("src")
    for s in sources:
        g.add_edge("src", s, weight=0.0)
    pre = nx.single_source_dijkstra_path_length(g, "src")
    best = math.inf
    for a, p in pre.items():
        if a == "src" or a[1] not in b.accepting:
            continue
        back = nx.single_source_dijkstra_path_length(g.reverse(copy=False), a)
        cyc = min((d["weight"] + back[t] for _, t, d in g.out_edges(a, data=True) if t in back),
                  default=math.inf)
        best = min(best, p + planner.alpha * cyc)
    return best


def floyd_cost(planner: MissionPlanner, sources) -> float:
    """Same optimum by Floyd-Warshall over all product states (tiny maps only)."""
    m, b = planner.navmap, planner.automaton
    states = [(n, q) for n in m.nodes for q in range(b.num_states)]
    idx = {s: i for i, s in enumerate(states)}
    k = len(states)
    d = [[math.inf] * k for _ in range(k)]
    for (n, q) in states:
        for n2 in m.nodes:
            if n2 == n or n2.region == START:
                continue
            for q2 in b.successors(q, b.mask([n2.region])):
                i, j = idx[(n, q)], idx[(n2, q2)]
                d[i][j] = min(d[i][j], m.cost(n, n2))
    for mid in range(k):
        dm = d[mid]
        for i in range(k):
            dim = d[i][mid]
            if dim == math.inf:
                continue
            di = d[i]
            for j in range(k):
                if dim + dm[j] < di[j]:
                    di[j] = dim + dm[j]
    best = math.inf
    for a in states:
        if a[1] not in b.accepting:
            continue
        ia = idx[a]
        p = min(0.0 if s == a else d[idx[s]][ia] for s in sources)
        best = min(best, p + planner.alpha * d[ia][ia])
    return best


def check_lasso(planner: MissionPlanner, plan: Plan, formula: str | None = None, history=()):
    """The plan walks the product, its cycle holds an accepting state, and (with ``formula``)
    the word ``history . route . suffix^omega`` satisfies the formula."""
    b, m = planner.automaton, planner.navmap
    states = list(plan.prefix_states) + list(plan.suffix_states)
    for (n, q), (n2, q2) in zip(states, states[1:]):
        assert n2 != n and m.cost(n, n2) < math.inf
        assert q2 in b.successors(q, b.mask([n2.region]))
    assert plan.suffix_states[-1] == plan.prefix_states[-1]
    assert any(q in b.accepting for _, q in plan.suffix_states)
    cost = sum(m.cost(u, v) for u, v in zip(plan.prefix, plan.prefix[1:]))
    assert cost == pytest.approx(plan.prefix_cost)
    cyc = (plan.prefix[-1],) + plan.suffix
    assert sum(m.cost(u, v) for u, v in zip(cyc, cyc[1:])) == pytest.approx(plan.suffix_cost)
    if formula is not None:
        word = [{r} for r in history] + [{n.region} for n in plan.route]
        assert evaluate(formula, word, [{n.region} for n in plan.suffix])


def test_doctests_and_public_name():
    assert tamp.MissionPlanner is MissionPlanner
    assert doctest.testmod(tamp.planner).failed == 0


# ---- optimality ------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_plan_is_optimal_against_networkx(seed):
    rng = random.Random(seed)
    regions = random_regions(rng, 4)
    formula = FORMULAS[seed % len(FORMULAS)]
    alpha = [1.0, 0.5, 3.0][seed % 3]
    start = (rng.uniform(0, 5), rng.uniform(0, 5), rng.uniform(-3, 3))
    p = MissionPlanner(regions, formula, n_orient=3, w=0.3, alpha=alpha, start=start)
    for _ in range(5):  # a few random blockages and re-costings
        u, v = rng.sample(sorted(regions), 2)
        if rng.random() < 0.5:
            p.set_cost(u, v, rng.uniform(0.1, 8.0))
        else:
            p.remove_edge(Node(u, rng.randrange(3)), Node(v, rng.randrange(3)))
    plan = p.plan()
    sources = [(p.node, q) for q in sorted(p._states)]
    assert plan.cost == pytest.approx(reference_cost(p, sources))
    check_lasso(p, plan, formula)


def _heapq_settle(prod, costs, sources):
    """The nested Dijkstra's outer search in pure Python (``heapq`` on ``(cost, state)``), run to
    the end: costs, predecessors and the accepting states in the order they are settled."""
    Q, N = prod.Q, prod.N
    dist, pred, heap, order = [math.inf] * (N * Q), [-1] * (N * Q), [], []
    for s in sources:
        dist[s] = 0.0
        heap.append((0.0, s))
    heapq.heapify(heap)
    while heap:
        d, s = heapq.heappop(heap)
        if d > dist[s]:
            continue
        n, q = divmod(s, Q)
        if q in prod.buchi.accepting:
            order.append(s)
        for t, n2 in prod.row(q):
            nd = d + costs[n * N + n2]
            if nd < dist[t]:
                dist[t], pred[t] = nd, s
                heapq.heappush(heap, (nd, t))
    return dist, pred, order


@pytest.mark.parametrize("seed", range(6))
def test_compiled_product_search_settles_states_as_heapq_does(seed):
    """``tamp._product_kernel.settle`` (compiled) against ``heapq`` with edge costs 0 to 3 (and
    some removed edges), so that many paths tie: the same costs, predecessors and order of accepting
    states, which is what keeps the planner's lassos and cycle statistics unchanged."""
    rng = random.Random(seed)
    regions = random_regions(rng, 4)
    p = MissionPlanner(regions, FORMULAS[seed % len(FORMULAS)], n_orient=2,
                       start=(rng.uniform(0, 5), rng.uniform(0, 5), 0.0))
    prod = p.product
    costs = [float(rng.randint(0, 3)) if rng.random() < 0.9 else math.inf for _ in range(prod.N * prod.N)]
    sources = [rng.randrange(prod.N * prod.Q) for _ in range(3)] + [prod.encode(p.node, q) for q in sorted(p._states)]
    ptr, row_t, row_n, accepting = prod.row_arrays()
    dist, pred, order = settle(ptr, row_t, row_n, np.asarray(costs), prod.Q, prod.N,
                               np.asarray(sources, dtype=np.int64), accepting)
    ref_dist, ref_pred, ref_order = _heapq_settle(prod, costs, sources)
    assert dist.tolist() == ref_dist and pred.tolist() == ref_pred and order.tolist() == ref_order
    assert len(ref_order) > 1 and len(set(ref_dist)) < len(ref_dist) / 2  # ties were there


@pytest.mark.parametrize("formula", FORMULAS)
def test_plan_is_optimal_against_floyd_on_tiny_maps(formula):
    rng = random.Random(len(formula))
    regions = random_regions(rng, 4)
    p = MissionPlanner(regions, formula, n_orient=2, w=0.5, alpha=2.0, start="a")
    plan = p.plan()
    assert plan.cost == pytest.approx(floyd_cost(p, [(p.node, q) for q in sorted(p._states)]))
    check_lasso(p, plan, formula, history=["a"])


def test_hand_built_automaton_until_translator_free():
    """A Büchi object can be the mission (e.g. read from HOA); plans use it as is."""
    a, b = Bdd.var(0), Bdd.var(1)
    gfab = Buchi(("a", "b"), 0, ((Edge(~a, 0), Edge(a, 1)), (Edge(~b, 1), Edge(b, 2)),
                                 (Edge(~a, 0), Edge(a, 1))), frozenset({2}), "G F a & G F b")
    p = MissionPlanner({"a": (0, 0), "b": (2, 0), "c": (1, 0)}, gfab, n_orient=1, start="c")
    plan = p.plan()
    assert plan.prefix_regions == ("a", "b") and plan.suffix_regions == ("a", "b")
    assert plan.cost == pytest.approx(1 + 2 + 4)
    check_lasso(p, plan, "G F a & G F b", history=["c"])


def test_office_mission_plan():
    p = MissionPlanner("office")
    plan = p.plan()
    assert p.node == Node(START, 0)
    assert set(plan.prefix_regions) >= {"d1", "d2", "d3"} and plan.prefix_regions[0] in ("p1", "p2")
    check_lasso(p, plan, p.mission)
    # the cycle after a co-safe mission is the cheapest rotation in place
    assert plan.suffix_cost == pytest.approx(2 * 0.1 * 2 * math.pi / 8)


# ---- re-planning -----------------------------------------------------------------------------
@pytest.mark.parametrize("log_limit", [None, 40])
@pytest.mark.parametrize("seed", range(4))
def test_replan_equals_planning_from_scratch(seed, log_limit):
    """Also with a map whose change log keeps only 40 entries (a long run's bounded log): a
    version older than the log answers ``None`` and the planner drops its caches."""
    rng = random.Random(100 + seed)
    regions = random_regions(rng, 5)
    formula = ["G F a & G F b & G F c", "F(a & F b) & G F e", "G(a -> F b) & G F a & G !d",
               "G F(a | c) & G F b"][seed]
    kw = dict(n_orient=4, w=0.2, alpha=1.5, start=(2.5, 2.5, 0.0))
    live = MissionPlanner(regions, formula, **kw)
    if log_limit is not None:
        live.navmap.log_limit = log_limit
    reused = 0
    for step in range(25):
        ops = []
        for _ in range(rng.randint(1, 3)):
            u, v = rng.sample(sorted(regions), 2)
            k1, k2 = rng.randrange(4), rng.randrange(4)
            r = rng.random()
            if r < 0.4:
                ops.append(("set_cost", (Node(u, k1), Node(v, k2), rng.uniform(0.0, 9.0))))
            elif r < 0.6:
                ops.append(("set_cost", (u, v, rng.uniform(0.0, 6.0))))
            elif r < 0.85:
                ops.append(("remove_edge", (Node(u, k1), Node(v, k2))))
            else:
                ops.append(("restore_edge", (u, v)))
        for name, args in ops:
            getattr(live, name)(*args)
        if step % 7 == 3:  # progress too: the cycle cache is independent of the current state
            nxt = live.plan().route
            if nxt:
                live.advance(nxt[0])
        fresh = MissionPlanner(regions, None, **kw)  # same map state, no caches
        fresh.navmap._cost[:] = live.navmap.costs
        fresh.navmap._removed.update(live.navmap.removed)
        fresh.request(formula)
        fresh._node, fresh._states = live._node, live._states
        a, b = live.replan(), fresh.plan()
        reused += live.last_stats["cycles_reused"]
        assert a.cost == pytest.approx(b.cost)
        if step % 5 == 0:
            assert a.cost == pytest.approx(reference_cost(live, live.current))
        check_lasso(live, a)
    assert reused > 0  # the caches were actually used
    if log_limit is not None:
        assert live.navmap.log_floor > 0 and len(live.navmap._log) <= log_limit + 32  # + one edit's entries


def test_replan_reuses_cycles_and_plan():
    p = MissionPlanner("office")
    first = p.plan()
    assert p.plan() is first  # nothing changed: cached
    rows = p.product.rows_built
    p.set_cost("p1", "d3", 50.0)  # not on the chosen cycles
    again = p.replan()
    assert p.product.rows_built >= rows and p.last_stats["cycles_reused"] >= 1
    assert again.cost == pytest.approx(first.cost) or again.cost >= first.cost


# ---- progress and mission changes ---------------------------------------------------------------
def test_advance_tracks_progress_and_violation():
    p = MissionPlanner({"a": (0, 0), "b": (3, 0), "c": (0, 3)}, "F a & F b & G !c", start="b")
    assert p.plan().prefix_regions == ("a",)
    p.advance("a")
    plan = p.plan()
    assert len(plan.prefix) == 1 and any(q in p.automaton.accepting for _, q in p.current)
    p.advance("c")
    with pytest.raises(NoPlanError, match="violated on entering region 'c'"):
        p.plan()
    p.request("G F a", "replace")  # a replacement rescues the robot
    assert p.plan().suffix_regions


def test_replace_and_refusals_keep_previous_mission():
    regions = {"a": (0, 0), "b": (3, 0), "c": (0, 3)}
    p = MissionPlanner(regions, "G F a & G F b", start="c")
    before = p.plan()
    for bad, err in [("F zz & F a", UnknownRegionError), ("F (a", LtlSyntaxError),
                     ("a & !a", UnsatisfiableError), ("F(a & b)", UnsatisfiableError)]:
        with pytest.raises(err):
            p.request(bad, "replace")
        assert p.mission == "G F a & G F b" and p.plan() == before
    with pytest.raises(InvalidRequestError, match="'replace', 'add', 'urgent'"):
        p.request("F c", "later")
    p.remove_edge("c", "b")
    p.remove_edge("a", "b")
    with pytest.raises(NoPlanError):
        p.request("F b", "replace")
    assert p.mission == "G F a & G F b"
    p.restore_edge("a", "b")
    plan = p.request("G F c", MissionMode.REPLACE)
    assert p.mission == "G F c" and plan.suffix_regions


def test_add_keeps_progress():
    regions = {"a": (0, 0), "b": (4, 0), "c": (0, 4), "d": (4, 4)}
    p = MissionPlanner(regions, "F(a & F b)", n_orient=1, start="c")
    p.advance("a")  # half of the sequence is done
    plan = p.request("F d", "add")
    # b is still owed, a is not: the cheapest route serves b and d, and never needs a again
    assert set(plan.prefix_regions) >= {"b", "d"} and "a" not in plan.prefix_regions
    check_lasso(p, plan, "F b & F d")
    with pytest.raises(UnsatisfiableError, match="contradicts"):
        p.request("G !b", "add")
    assert p.mission == "(F(a & F b)) & (F d)"
    # the added formula reads the current region: adding F a while in a is already served
    p2 = MissionPlanner(regions, "G F b", n_orient=1, start="a")
    assert "a" not in p2.request("F a", "add").prefix_regions[:1]


def test_urgent_is_served_first_then_main_resumes():
    regions = {"a": (0, 0), "b": (4, 0), "c": (0, 4), "u1": (4, 4)}
    p = MissionPlanner(regions, "F(a & F(b & F c))", n_orient=1, start="c")
    p.advance("a")
    plan = p.request("F u1", "urgent")
    assert plan.urgent_regions == ("u1",) and plan.prefix[0] == Node("u1", 0)
    assert plan.prefix_regions[:2] == ("b", "c")  # a is not repeated: progress kept
    assert p.pending_urgent == ("F u1",)
    check_lasso(p, plan)
    p.advance("u1")
    assert p.pending_urgent == ()
    assert p.plan().prefix_regions == ("b", "c") and not p.plan().urgent


def test_urgent_path_advances_main_mission():
    """The main automaton reads the regions of the urgent path (its trace is real)."""
    regions = {"a": (0, 0), "b": (4, 0), "u": (8, 0)}
    p = MissionPlanner(regions, "F b & F u", n_orient=1, start="a")
    plan = p.request("F(b & F u)", "urgent")
    assert plan.urgent_regions == ("b", "u")
    assert len(plan.prefix) == 1  # nothing left of the main mission after the urgent path
    # an urgent path never violates the main mission
    p2 = MissionPlanner({"a": (0, 0), "c": (1, 0), "u": (2, 0)}, "G !c & G F a", n_orient=1, start="a")
    assert "c" not in p2.request("F(c | u)", "urgent").urgent_regions


def test_urgent_errors():
    regions = {"a": (0, 0), "u1": (3, 0)}
    p = MissionPlanner(regions, "G F a", n_orient=1, start="a")
    with pytest.raises(InvalidRequestError, match="not co-safe"):
        p.request("G F u1", "urgent")
    assert p.pending_urgent == ()
    p.remove_edge("a", "u1")
    with pytest.raises(NoPlanError) as err:
        p.request("F u1", "urgent")
    assert ("a", "u1") in err.value.blocked and p.pending_urgent == ()
    assert MissionPlanner(regions, None, start="a").mission is None
    with pytest.raises(InvalidRequestError, match="active mission"):
        MissionPlanner(regions, None, start="a").request("F u1", "urgent")


# ---- errors -----------------------------------------------------------------------------------
def test_error_types_are_distinct_and_name_the_cause():
    regions = {"a": (0, 0), "b": (3, 0)}
    with pytest.raises(UnknownRegionError) as err:
        MissionPlanner(regions, "F a & G(x -> F yy)")
    assert err.value.names == ("x", "yy") and "'yy'" in str(err.value)
    with pytest.raises(LtlSyntaxError) as err:
        MissionPlanner(regions, "F a &")
    assert err.value.position == 5
    with pytest.raises(UnsatisfiableError, match="unsatisfiable"):
        MissionPlanner(regions, "G a & F !a")
    types = {UnknownRegionError, LtlSyntaxError, UnsatisfiableError, NoPlanError, InvalidRequestError}
    assert len(types) == 5 and all(issubclass(t, TampError) for t in types)
    with pytest.raises(InvalidRequestError, match="alpha"):
        MissionPlanner(regions, "F a", alpha=-1)


def test_no_plan_names_blocked_transitions():
    regions = {"a": (0, 0), "b": (3, 0), "c": (0, 3)}
    p = MissionPlanner(regions, "G F b & G F c", n_orient=2, start="a")
    p.remove_edge("b", "c")
    p.remove_edge("a", "b")
    with pytest.raises(NoPlanError) as err:
        p.plan()
    assert err.value.blocked and set(err.value.blocked) <= {("a", "b"), ("b", "a"), ("b", "c"), ("c", "b")}
    assert "blocked transitions" in str(err.value) and "G F b & G F c" in str(err.value)
    p.restore_edge("a", "b")
    check_lasso(p, p.plan(), "G F b & G F c", history=["a"])


def test_plan_from_given_product_states_and_bad_states():
    p = MissionPlanner({"a": (0, 0), "b": (3, 0)}, to_buchi(parse("G F a & G F b")), n_orient=2, start="a")
    plan = p.plan([(Node("b", 1), q) for q in range(p.automaton.num_states)])
    assert plan.prefix[0] == Node("b", 1) and p.node == Node("a", 0)
    with pytest.raises(InvalidRequestError):
        p.plan([(Node("b", 1), 99)])
    with pytest.raises(UnknownRegionError):
        p.advance("zz")
    with pytest.raises(InvalidRequestError, match="no start node"):
        p.advance(Node(START, 0))
    with pytest.raises(InvalidRequestError, match="no start node"):
        p.set_position((1.0, 1.0))
    q = MissionPlanner({"a": (0, 0), "b": (3, 0)}, "G F a", start=(1.0, 1.0))
    with pytest.raises(InvalidRequestError, match="set_position"):
        q.advance(Node(START, 0))


def test_world_events_modes_parse():
    assert MissionMode.parse("urgent") is MissionMode.URGENT
    import navigation

    ev = navigation.load_world("office").events[0]
    assert MissionMode.parse(ev.mode) is MissionMode.URGENT
    p = MissionPlanner("office")
    plan = p.request(ev.task, ev.mode)
    assert plan.urgent_regions == ("u1",) and plan.to_dict()["urgent"] == ["u1"]
    p.set_position((4.5, 0.5, 0.0))
    assert p.node == Node(START, 0) and p.plan().urgent_regions == ("u1",)


def test_with_regions_carries_the_mission_over_and_leaves_the_planner_alone():
    """A planner over a changed region set keeps the mission, its automaton states, the urgent
    queue, the visited trace and the robot's node; the original planner is unchanged."""
    regions = {"a": (0.0, 0.0), "b": (3.0, 0.0), "c": (0.0, 3.0)}
    p = MissionPlanner(regions, "F a & F b & F c", start="a")
    p.advance("a")
    p.request("F c", MissionMode.URGENT)
    before = (p.current, p.pending_urgent, list(p.visited), p.node)
    q = p.with_regions({**regions, "d": (3.0, 3.0)}, pose=(0.0, 0.0, 0.0))
    assert (p.current, p.pending_urgent, list(p.visited), p.node) == before
    assert "d" not in p.navmap.regions and "d" in q.navmap.regions
    assert q.mission == p.mission and q.pending_urgent == p.pending_urgent
    assert {s for _, s in q.current} == {s for _, s in p.current} and q.node == p.node
    assert list(q.visited) == list(p.visited)
    assert q.plan().urgent  # the urgent request is still served first
    # a moved region: the robot's node is re-resolved from the pose
    moved = q.with_regions({**regions, "a": (0.5, 0.0), "d": (3.0, 3.0)}, pose=(0.1, 0.1, 0.0), moved={"a"})
    assert moved.node.region == START
    # the check sees the mission and the urgent request, and may refuse
    seen = []
    q.with_regions(regions, pose=(0.0, 0.0, 0.0), check=lambda *a: seen.append(a[-1]))
    assert sorted(seen) == [False, True]
    with pytest.raises(InvalidRequestError):
        q.with_regions(regions, pose=(0.0, 0.0, 0.0), check=lambda *a: (_ for _ in ()).throw(InvalidRequestError("no")))


# ---- following the plans (one run of the automaton) -----------------------------------------
RECURRENT = ["G F a & G F b & G F c", "G F a & G F b", "G(a -> F b) & G F a & G !d", "G F b & F G !a",
             "G F(a | c) & G F b", "G F a & G F b & G F c & G F d"]


def _follow(planner: MissionPlanner, rng: random.Random, steps: int, *, perturb: bool, urgent_at=None):
    """Drive ``planner`` like the executive: go to the plan's next region, ``advance`` there;
    with ``perturb`` re-cost random transitions first (the executive re-costs as it evaluates
    trees). Returns the regions entered, and ``None`` for "stays where it is for good" (a plan
    whose lasso never leaves the region: the executive's "nothing left to visit")."""
    trace = []
    for step in range(steps):
        if perturb:
            for _ in range(rng.randint(0, 3)):
                u, v = rng.sample(sorted(planner.navmap.regions), 2)
                planner.set_cost(u, v, rng.uniform(1.0, 8.0))
        if urgent_at == step:
            planner.request("F u", "urgent")
        plan = planner.plan()
        here = planner.node.region
        target = next((n.region for n in plan.route + plan.suffix if n.region != here), None)
        if target is None:
            if urgent_at is not None and urgent_at > step:
                continue  # stays, until the urgent request comes
            return trace + [None]
        planner.advance(target)
        trace.append(target)
    return trace


@pytest.mark.parametrize("urgent", [False, True])
@pytest.mark.parametrize("seed", range(12))
def test_a_robot_that_follows_its_plans_satisfies_a_recurrent_mission(seed, urgent):
    """The guarantee behind a recurrent mission: driven plan after plan while the map's costs
    keep changing (then settle), the robot's trace ends in a cycle, and the lasso word it
    makes satisfies the formula. Planning from the whole state set at every region broke this
    (the plans took turns between runs; the robot skipped a region forever); committing to
    the plan's run (class doc, "One run of the automaton") keeps it."""
    rng = random.Random(700 + seed)
    formula = RECURRENT[seed % len(RECURRENT)]
    regions = random_regions(rng, 5)
    if urgent:
        regions["u"] = (rng.uniform(0, 5), rng.uniform(0, 5))
    planner = MissionPlanner(regions, formula, n_orient=2, w=0.2, start=(2.5, 2.5, 0.0))
    trace = _follow(planner, rng, 40, perturb=True, urgent_at=7 if urgent else None)
    # costs settled: the planner is a deterministic finite system; find the cycle
    seen = {}
    while trace[-1:] != [None]:
        key = (planner.node, planner.current, planner.plan().route, planner.plan().suffix)
        if key in seen:
            break
        seen[key] = len(trace)
        trace += _follow(planner, rng, 1, perturb=False)
        assert len(trace) < 400, "no cycle"
    if trace[-1] is None:  # the robot stays in its region for good: the word repeats its letter
        prefix, cycle = trace[:-1], [planner.node.region]
    else:
        start = seen[key]
        prefix, cycle = trace[:start], trace[start:]
    assert cycle, trace
    word = lambda names: [{r} for r in names]  # noqa: E731
    assert evaluate(formula, word(prefix), word(cycle)), (formula, prefix, cycle)
    if urgent:
        assert "u" in trace and planner.pending_urgent == ()


def test_commitment_falls_back_to_every_state_when_the_committed_run_has_no_lasso():
    """``G F b | G F c``: the plans commit to the run that loops through ``b`` (the nearer).
    When ``b`` becomes unreachable that run has no lasso, but the trace also leads to the
    ``c`` run's states: the plan comes from those (nothing is blocked that was not before)."""
    regions = {"a": (0, 0), "b": (1, 0), "c": (0, 3)}
    p = MissionPlanner(regions, "G F b | G F c", n_orient=1, start="a")
    for _ in range(6):
        plan = p.plan()
        p.advance(next(n.region for n in plan.route + plan.suffix if n.region != p.node.region))
    committed = {q for _, q in p.current}
    assert "c" not in p.plan().suffix_regions and p.reachable > committed
    for r in ("a", "c"):
        p.remove_edge(r, "b")
    plan = p.plan()
    assert "c" in plan.suffix_regions and "b" not in plan.route + plan.suffix
    assert {q for _, q in p.current} == p.reachable  # the current states are the whole set now
