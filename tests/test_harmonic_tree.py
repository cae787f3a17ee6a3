"""Harmonic trees (paper 001 eq. 7-8, 26, section 4.2.3): safety of every path, eq. 26 costs,
A* optimality against a brute-force Dijkstra, revision equal to a rebuild, the least-squares
weight update, and clear reports of infeasible pairs."""

from __future__ import annotations

import functools
import itertools
import math

import networkx as nx
import numpy as np
import pytest

from navigation import Squircle
from navigation.errors import TampError
import tamp.harmonic_tree as ht
from tamp.harmonic_tree import (NoTreePathError, RotationWeights, TreeFailure, edge_cost, plan_tree,
                                revise_trees, rotation_terms, tree_graph)
from tamp.roadmap import Roadmap, RoadmapConfig, descent_candidates, segments_clear
from navigation.geometry import pack

from .conftest import shared_world
from .worldgen import random_forest_world

ROBOT_GAP = 0.3  # random worlds with room for the robot (gap > 2 r), as benchmarks/control.py

SHARED = ("simple", "office", "cluttered20")
SPACING = 0.01  # dense-check sample spacing (m); clearance along a segment >= sampled - SPACING / 2


@functools.lru_cache(maxsize=None)
def random_world(seed: int):
    return random_forest_world(seed, gap=ROBOT_GAP)


def _poses(world, rng):
    """Region centres with random headings."""
    return {name: (*reg.center, float(rng.uniform(-math.pi, math.pi))) for name, reg in world.regions.items()}


def _clearance(world_obstacles, workspace, pts, wall_allowance=0.0):
    """Exact distance from ``pts`` to the nearest obstacle or the workspace boundary (less
    ``wall_allowance``: how much less room the boundary is owed than an obstacle)."""
    d = -np.atleast_1d(workspace.distance(pts)) + wall_allowance
    for o in world_obstacles:
        near = np.linalg.norm(pts - o.c, axis=1) < o.bounding_radius + 1.0
        if near.any():
            d[near] = np.minimum(d[near], np.atleast_1d(o.distance(pts[near])))
    return d


def _dense(a, b):
    n = max(2, int(math.ceil(np.linalg.norm(np.subtract(b, a)) / SPACING)) + 1)
    t = np.linspace(0.0, 1.0, n)[:, None]
    return np.asarray(a)[None, :] + t * (np.asarray(b) - np.asarray(a))[None, :]


def _check_tree(tree, rm, start, goal):
    """Anchored at the poses, eq. 26 costs, every segment safe."""
    assert tree.waypoints[0] == pytest.approx(start)
    assert tree.waypoints[-1][:2] == pytest.approx(goal[:2])
    assert math.remainder(tree.waypoints[-1][2] - goal[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
    costs = [edge_cost(u[:2], u[2], v[:2], v[2], tree.weights) for u, v in zip(tree.waypoints, tree.waypoints[1:])]
    assert tree.edge_costs == pytest.approx(costs, rel=1e-12)
    assert tree.cost == pytest.approx(sum(costs), rel=1e-12)
    need = rm.radius + rm.config.buffer
    terminal_ok = rm.safe_points(np.array([start[:2], goal[:2]]))
    for n, (u, v) in enumerate(zip(tree.waypoints, tree.waypoints[1:])):
        pts = _dense(u[:2], v[:2])
        # the boundary is owed r + b_W (RoadmapConfig.boundary_buffer), the obstacles r + b
        clear = _clearance(rm.obstacles, rm.workspace, pts, rm.config.buffer - rm.config.wall_buffer)
        at_start, at_goal = n == 0, n == len(tree.waypoints) - 2
        relaxed = (at_start and not terminal_ok[0]) or (at_goal and not terminal_ok[1])
        # a terminal inside the buffer zone: its edges are only guaranteed collision-free
        floor = rm.radius if relaxed else need
        assert clear.min() >= floor - SPACING / 2 - 1e-9, (n, u, v, clear.min())


# ---------------------------------------------------------------------- geometry
def test_segment_test_matches_dense_sampling():
    rng = np.random.default_rng(7)
    sqs = [Squircle(tuple(rng.uniform(-1, 1, 2)), *rng.uniform(0.2, 1.2, 2), rng.uniform(0, np.pi),
                    rng.choice([0.0, 0.5, 0.99])) for _ in range(16)]
    P = pack(sqs)
    a = rng.uniform(-2, 2, (400, 2))
    b = rng.uniform(-2, 2, (400, 2))
    t = np.linspace(0.0, 1.0, 4001)
    from navigation.geometry import beta_rows

    hit_any = margin_ok = 0
    for k in range(len(sqs)):
        pts = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
        beta = beta_rows(P[k], pts[..., 0], pts[..., 1]).min(axis=1)
        got = segments_clear(P[k:k + 1], a, b)
        assert not np.any(got & (beta <= 0)), "a segment through a squircle was certified clear"
        clear = beta > 1e-6
        assert np.all(got[clear]), "a clear segment was rejected"
        hit_any += int((beta <= 0).sum())
        margin_ok += int(clear.sum())
    assert hit_any > 100 and margin_ok > 100


# ---------------------------------------------------------------------- trees on worlds
def _all_pairs(world, rm, seed, allow_blocked=False):
    poses = _poses(world, np.random.default_rng(seed))
    trees = {}
    for a, b in itertools.permutations(poses, 2):
        try:
            tree = plan_tree(rm, poses[a], poses[b])
        except NoTreePathError as err:
            # the buffer closes passages narrower than 2 (r + b): an honest, named verdict
            if not allow_blocked or err.reason is not TreeFailure.DISCONNECTED:
                raise
            continue
        _check_tree(tree, rm, poses[a], poses[b])
        trees[a, b] = tree
    return trees


@pytest.mark.parametrize("name", SHARED)
def test_shared_world_paths_are_safe_and_costed(name):
    world = shared_world(name)
    rm = Roadmap.from_world(world)
    trees = _all_pairs(world, rm, seed=1)
    assert len(trees) == len(world.regions) * (len(world.regions) - 1)


@pytest.mark.parametrize("seed", [0, 2, 3])
def test_random_world_paths_are_safe_and_costed(seed):
    world = random_world(seed)
    rm = Roadmap.from_world(world)
    _all_pairs(world, rm, seed, allow_blocked=True)


def test_roadmap_graph_is_its_visible_pairs_with_their_lengths():
    """:meth:`Roadmap.graph`: exactly the visible pairs, both directions, weighted by the
    distance between their vertices (the evaluation's oracle runs Dijkstra on it)."""
    rm = Roadmap.from_world(shared_world("office"))
    g = rm.graph().tocoo()
    assert g.shape == (len(rm.points), len(rm.points)) and g.nnz == 2 * len(rm.pairs)
    assert set(zip(g.row.tolist(), g.col.tolist())) == {(int(i), int(j)) for a, b in rm.pairs for i, j in ((a, b), (b, a))}
    np.testing.assert_allclose(g.data, np.linalg.norm(rm.points[g.row] - rm.points[g.col], axis=1), rtol=0, atol=1e-12)


def _dijkstra(rm, start, goal, weights, H):
    G = tree_graph(rm, start, goal, weights, H)
    return nx.dijkstra_path_length(G, "start", "goal")


def test_astar_equals_brute_force_dijkstra_simple():
    world = shared_world("simple")
    rm = Roadmap.from_world(world)
    poses = _poses(world, np.random.default_rng(3))
    w = RotationWeights(0.3, 0.2)
    for a, b in itertools.permutations(poses, 2):
        tree = plan_tree(rm, poses[a], poses[b], w, 8)
        assert tree.cost == pytest.approx(_dijkstra(rm, poses[a], poses[b], w, 8), rel=1e-12)


def test_astar_equals_brute_force_dijkstra_random():
    world = random_world(4)
    rm = Roadmap.from_world(world)
    rng = np.random.default_rng(4)
    poses = _poses(world, rng)
    compared = 0
    for a, b in list(itertools.permutations(poses, 2))[:4]:
        w = RotationWeights(*rng.uniform(0.05, 1.0, 2))
        try:
            cost = plan_tree(rm, poses[a], poses[b], w, 4).cost
        except NoTreePathError:
            with pytest.raises(nx.NetworkXNoPath):
                _dijkstra(rm, poses[a], poses[b], w, 4)
            continue
        assert cost == pytest.approx(_dijkstra(rm, poses[a], poses[b], w, 4), rel=1e-12)
        compared += 1
    assert compared >= 2


def test_astar_stops_at_the_goal_with_dijkstras_cost():
    """The compiled A* settles the goal before the (vertex, heading) nodes farther away: on the
    office roadmap a short tree reaches few of the nodes reachable from its start, and the
    cost is the brute-force Dijkstra's to rounding (the two shortest pairs and the longest)."""
    world = shared_world("office")
    rm = Roadmap.from_world(world)
    poses = _poses(world, np.random.default_rng(7))
    w = RotationWeights(0.2, 0.1)
    pairs = sorted(itertools.permutations(poses, 2), key=lambda p: math.dist(poses[p[0]][:2], poses[p[1]][:2]))
    fractions = []
    for a, b in pairs[:2] + pairs[-1:]:
        tree = plan_tree(rm, poses[a], poses[b], w, 4)
        G = tree_graph(rm, poses[a], poses[b], w, 4)
        assert tree.cost == pytest.approx(nx.dijkstra_path_length(G, "start", "goal"), rel=1e-12)
        reachable = sum(1 for v in nx.descendants(G, "start") if isinstance(v, tuple))
        assert 0 < tree.expanded <= reachable
        fractions.append(tree.expanded / reachable)
    assert min(fractions) < 0.5


def test_trees_share_their_terminals_per_roadmap_and_equal_fresh_ones():
    """A roadmap keeps each position's terminal and visible vertices (``_wired``): trees with a
    common start reuse them, and every tree equals the tree on a fresh copy of the roadmap; the
    roadmap keeps at most ``_WIRED_KEPT`` positions."""
    world = shared_world("office")
    rm = Roadmap.from_world(world)
    poses = _poses(world, np.random.default_rng(11))
    names = sorted(poses)
    for b in names[1:]:
        tree = plan_tree(rm, poses[names[0]], poses[b])
        fresh = plan_tree(Roadmap.from_world(world), poses[names[0]], poses[b])
        assert tree.waypoints == fresh.waypoints and tree.cost == fresh.cost
    start = ("wired", np.asarray(poses[names[0]][:2], dtype=float).tobytes())
    assert start in rm._memo
    rng = np.random.default_rng(12)
    for _ in range(2 * ht._WIRED_KEPT):
        q = np.asarray(poses[names[0]][:2]) + rng.uniform(-1e-3, 1e-3, 2)
        plan_tree(rm, (*q, 0.0), poses[names[1]])
    assert sum(1 for k in rm._memo if k[0] == "wired") == ht._WIRED_KEPT


def test_vicinity_limits_edge_length():
    world = shared_world("office")
    rm = Roadmap.from_world(world, RoadmapConfig(vicinity=1.0))
    lengths = np.linalg.norm(rm.points[rm.pairs[:, 0]] - rm.points[rm.pairs[:, 1]], axis=1)
    assert lengths.max() <= 1.0
    poses = _poses(world, np.random.default_rng(5))
    tree = plan_tree(rm, poses["p1"], poses["d1"])
    _check_tree(tree, rm, poses["p1"], poses["d1"])
    assert np.all(tree.translations <= 1.0 + 1e-12)


# ---------------------------------------------------------------------- revision (4.2.3)
@pytest.mark.parametrize("seed", [0, 5])
def test_revision_equals_rebuild(seed):
    world = random_world(seed)
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(world.obstacles))
    known = [world.obstacles[i] for i in sorted(order[: len(order) // 3])]
    rest = [world.obstacles[i] for i in sorted(order[len(order) // 3:])]
    batches = [rest[: len(rest) // 2], rest[len(rest) // 2:]]
    rm = Roadmap.build(world.workspace, known, world.robot.radius)
    poses = _poses(world, rng)
    trees = {(a, b): plan_tree(rm, poses[a], poses[b]) for a, b in itertools.permutations(poses, 2)}
    seen = list(known)
    for batch in batches:
        rev = revise_trees(rm, trees, batch)
        seen += batch
        scratch = Roadmap.build(world.workspace, seen, world.robot.radius)
        np.testing.assert_array_equal(rev.roadmap.points, scratch.points)
        np.testing.assert_array_equal(rev.roadmap.pairs, scratch.pairs)
        for key, tree in rev.trees.items():
            ref = plan_tree(scratch, poses[key[0]], poses[key[1]])
            assert tree.cost == pytest.approx(ref.cost, rel=1e-12)
            _check_tree(tree, rev.roadmap, poses[key[0]], poses[key[1]])
        for key, err in rev.blocked.items():
            with pytest.raises(NoTreePathError):
                plan_tree(scratch, poses[key[0]], poses[key[1]])
        assert set(rev.trees) | set(rev.blocked) == set(trees)
        rm, trees = rev.roadmap, {**rev.trees}


def _vertex_edge_sets(rm):
    """Vertices and undirected edges as sets of coordinates (independent of vertex order)."""
    V = {tuple(np.round(p, 9)) for p in rm.points}
    E = {frozenset((tuple(np.round(rm.points[a], 9)), tuple(np.round(rm.points[b], 9)))) for a, b in rm.pairs}
    return V, E


@pytest.mark.parametrize("name", ["office", "cluttered20", "random0", "random3"])
def test_removal_equals_rebuild(name):
    world = random_world(int(name[6:])) if name.startswith("random") else shared_world(name)
    obstacles = list(world.obstacles)
    full = Roadmap.build(world.workspace, obstacles, world.robot.radius)
    rng = np.random.default_rng(len(obstacles))
    for size in (1, 3):
        gone = sorted(rng.choice(len(obstacles), size=size, replace=False).tolist())
        removed = full.without_obstacles(gone)
        rest = [o for k, o in enumerate(obstacles) if k not in gone]
        scratch = Roadmap.build(world.workspace, rest, world.robot.radius)
        assert removed.obstacles == tuple(rest)
        assert _vertex_edge_sets(removed) == _vertex_edge_sets(scratch)
        # and back: adding them again gives the full roadmap's vertices and edges
        again = removed.with_obstacles([obstacles[k] for k in gone])
        assert _vertex_edge_sets(again) == _vertex_edge_sets(full)


def test_biased_regeneration_is_safe_and_no_worse():
    """Extra candidates along the potential's descent only add vertices: never a dearer path."""
    import navigation

    world = shared_world("simple")
    rm0 = Roadmap.build(world.workspace, world.obstacles[:2], world.robot.radius)
    poses = _poses(world, np.random.default_rng(6))
    a, b = list(poses)[:2]
    tree = plan_tree(rm0, poses[a], poses[b])
    nf = navigation.NavigationFunction(world, goal=poses[b][:2], inflation=world.robot.radius)
    extra = descent_candidates(nf, poses[a][:2], spacing=0.3)
    assert len(extra) > 0
    rev = revise_trees(rm0, {"ab": tree}, world.obstacles[2:], extra=extra)
    plain = Roadmap.build(world.workspace, world.obstacles, world.robot.radius)
    assert (rev.roadmap.owner == -1).any()
    assert len(rev.roadmap.points) > len(plain.points)
    ref = plan_tree(plain, poses[a], poses[b])
    assert rev.trees["ab"].cost <= ref.cost + 1e-12
    _check_tree(rev.trees["ab"], rev.roadmap, poses[a], poses[b])


def test_new_obstacle_on_the_path_forces_a_detour():
    world = shared_world("simple")
    rm = Roadmap.from_world(world)
    poses = _poses(world, np.random.default_rng(8))
    (a, pa), (b, pb) = list(poses.items())[:2]
    tree = plan_tree(rm, pa, pb)
    mid = tree.positions[len(tree.positions) // 2 - 1: len(tree.positions) // 2 + 1].mean(axis=0)
    blocker = Squircle(tuple(mid), 0.3, 0.3, 0.0, 0.5)
    rev = revise_trees(rm, {"ab": tree}, [blocker])
    assert "ab" in rev.changed
    new = rev.trees["ab"]
    _check_tree(new, rev.roadmap, pa, pb)
    assert new.cost > tree.cost


# ---------------------------------------------------------------------- weights (4.2.3 III)
def test_weight_fit_recovers_known_weights():
    rng = np.random.default_rng(9)
    for _ in range(20):
        true = RotationWeights(*rng.uniform(0.01, 2.0, 2))
        H = int(rng.integers(2, 40))
        d = rng.uniform(0.1, 3.0, H)
        Q = rng.uniform(0.0, math.pi, (H, 2))
        fit = RotationWeights.fit(d, Q, d + Q @ true.as_array())
        assert fit.as_array() == pytest.approx(true.as_array(), rel=1e-10)


def test_weight_fit_from_traversed_edges_reprices_every_tree():
    world = shared_world("office")
    rm = Roadmap.from_world(world)
    poses = _poses(world, np.random.default_rng(10))
    trees = {k: plan_tree(rm, poses[k[0]], poses[k[1]]) for k in [("p1", "d1"), ("d2", "u1"), ("d3", "p2")]}
    true = RotationWeights(0.17, 0.23)  # the paper's fitted value (Fig. 9)
    d = np.concatenate([t.translations for t in trees.values()])
    Q = np.concatenate([t.rotations for t in trees.values()])
    w = RotationWeights.fit(d, Q, d + Q @ true.as_array())
    assert w.as_array() == pytest.approx(true.as_array(), rel=1e-9)
    rev = revise_trees(rm, trees, weights=w)
    for k, t in rev.trees.items():
        assert t.weights == w
        assert t.cost <= trees[k].recost(w) + 1e-12  # the old path is still available
        assert t.cost == pytest.approx(plan_tree(rm, poses[k[0]], poses[k[1]], w).cost, rel=1e-12)


def test_weight_fit_rejects_degenerate_samples():
    with pytest.raises(TampError, match="singular"):
        RotationWeights.fit([1.0], [[0.1, 0.2]], [1.2])
    with pytest.raises(TampError, match="singular"):
        RotationWeights.fit([1.0, 2.0], [[0.1, 0.2], [0.2, 0.4]], [1.2, 2.3])
    with pytest.raises(TampError, match="shape"):
        RotationWeights.fit([1.0, 2.0], [0.1, 0.2], [1.2, 2.3])
    with pytest.raises(TampError, match="> 0"):
        RotationWeights(0.0, 0.1)
    # contradicting data: the paper needs w > 0, so the fit is floored
    w = RotationWeights.fit([1.0, 1.0], [[1.0, 0.0], [0.0, 1.0]], [0.5, 1.5])
    assert w.w1 == pytest.approx(1e-6) and w.w2 == pytest.approx(0.5)


def test_rotation_terms_follow_eq_26():
    Q = rotation_terms([0.0, 0.0], 0.5, [1.0, 1.0], -3.0)
    assert Q == pytest.approx([math.pi / 4 - 0.5, abs(math.remainder(math.pi / 4 + 3.0, 2 * math.pi))])
    assert rotation_terms([0.0, 0.0], 0.0, [0.0, 0.0], 3.0) == pytest.approx([3.0, 0.0])  # in place
    assert rotation_terms([0, 0], 0.0, [1, 0], 0.0, theta_gamma=math.pi)[0] == pytest.approx(math.pi)
    assert edge_cost([0, 0], 0.0, [3, 4], math.atan2(4, 3), RotationWeights(1.0, 1.0)) == pytest.approx(
        5.0 + math.atan2(4, 3))


# ---------------------------------------------------------------------- infeasible pairs
def _walled_world():
    ws = Squircle((2.0, 1.5), 4.0, 3.0, 0.0, 0.99)
    walls = [Squircle((3.0, 2.0), 1.2, 0.2, 0.0, 0.99), Squircle((3.0, 1.0), 1.2, 0.2, 0.0, 0.99),
             Squircle((2.5, 1.5), 0.2, 1.2, 0.0, 0.99), Squircle((3.5, 1.5), 0.2, 1.2, 0.0, 0.99)]
    return ws, walls


def test_boundary_buffer_opens_a_passage_along_the_known_boundary():
    """``boundary_buffer``: a gap between an obstacle and the workspace boundary narrower than
    ``2 (r + b)`` but wider than ``2 r + b + b_W`` is closed at the paper's buffer and open when
    the boundary (known exactly) is owed only ``b_W``; every segment keeps ``r + b`` from the
    obstacle and ``r + b_W`` from the boundary."""
    ws = Squircle((2.0, 1.5), 4.0, 3.0, 0.0, 0.99)
    r, b, bw = 0.1, 0.15, 0.03
    gap = 2 * r + b + bw + 0.08  # 0.56 m between the wall's top and the boundary (y = 3)
    wall = Squircle((2.0, (3.0 - gap) / 2), 0.2, 3.0 - gap, 0.0, 0.99)  # from y = 0 up
    start, goal = (0.6, 2.7, 0.0), (3.4, 2.7, 0.0)
    closed = Roadmap.build(ws, [wall], r)
    with pytest.raises(NoTreePathError) as info:
        plan_tree(closed, start, goal)
    assert info.value.reason is TreeFailure.DISCONNECTED
    rm = Roadmap.build(ws, [wall], r, RoadmapConfig(buffer=b, boundary_buffer=bw))
    assert rm.config.wall_buffer == bw and closed.config.wall_buffer == b
    tree = plan_tree(rm, start, goal)
    _check_tree(tree, rm, start, goal)
    assert tree.translations.sum() < 3.2  # over the wall's top, not round anything
    # the obstacles still get the whole buffer: a gap 2 cm short of 2 r + b + b_W is closed
    h = 3.0 - (2 * r + b + bw - 0.02)
    taller = Squircle((2.0, h / 2), 0.2, h, 0.0, 0.99)
    with pytest.raises(NoTreePathError):
        plan_tree(Roadmap.build(ws, [taller], r, RoadmapConfig(buffer=b, boundary_buffer=bw)), start, goal)
    for bad in (-0.01, float("nan"), float("inf"), True, "0.03"):
        with pytest.raises(TampError, match="boundary_buffer"):
            RoadmapConfig(boundary_buffer=bad)


def _slit(case: str, slit: float):
    """A 4 x 3 m room split by a wall at x = 2 with one passage ``slit`` wide: between the
    wall's top and the boundary (``boundary``), or between two walls at mid-height
    (``obstacles``); start and goal on either side, not in line with the passage."""
    ws = Squircle((2.0, 1.5), 4.0, 3.0, 0.0, 0.99)
    if case == "boundary":
        h = 3.0 - slit
        return ws, [Squircle((2.0, h / 2), 0.2, h, 0.0, 0.99)], (0.6, 2.4, 0.0), (3.4, 2.0, 0.0)
    h = 1.5 - slit / 2
    walls = [Squircle((2.0, h / 2), 0.2, h, 0.0, 0.99), Squircle((2.0, 3.0 - h / 2), 0.2, h, 0.0, 0.99)]
    return ws, walls, (0.6, 0.5, 0.0), (3.4, 2.5, 0.0)


@pytest.mark.parametrize("case, slit", [("boundary", 0.29), ("boundary", 0.3), ("obstacles", 0.29), ("obstacles", 0.3)])
def test_gap_candidates_open_a_passage_the_boundary_vertices_do_not_see_through(case, slit):
    """A passage a few centimetres wide at the buffer (``2 (r + b)`` = 0.26 m of the slit
    taken; from 0.31 m the vertices at the walls' snugly grown ends see through it): no
    boundary vertex sees through it, so the roadmap reports the goal walled off;
    with :meth:`Roadmap.gap_candidates` added, the tree goes through, every segment safe."""
    ws, walls, start, goal = _slit(case, slit)
    rm = Roadmap.build(ws, walls, 0.1, RoadmapConfig(buffer=0.03))
    with pytest.raises(NoTreePathError) as info:
        plan_tree(rm, start, goal)
    assert info.value.reason is TreeFailure.DISCONNECTED
    cand = rm.gap_candidates()
    assert cand.shape[1] == 2 and np.isfinite(cand).all()
    opened = rm.with_obstacles((), extra=cand)
    tree = plan_tree(opened, start, goal)
    _check_tree(tree, opened, start, goal)
    assert tree.translations.sum() < 4.5  # through the passage (no other way exists)


def test_a_passage_under_a_corner_is_open_at_the_buffer_with_the_snug_inflation(monkeypatch):
    """A wall's flat top 0.56 m below the lower corner of a square turned 45 degrees: 0.06 m to
    spare at the buffer (``2 (r + b)`` = 0.5 m). The plain inflation (same ``s``) reaches about
    0.1 m beyond the neighbourhood at that corner and closes the passage; the roadmaps' snug
    one (:meth:`navigation.Squircle.grow_snug`) leaves it open, and the tree through it keeps
    ``r + b`` from every obstacle (exact distances along every segment)."""
    import tamp.roadmap

    ws = Squircle((2.0, 1.5), 4.0, 3.0, 0.0, 0.99)
    d = 0.6 / math.sqrt(2)
    walls = [Squircle((2.0, 0.6), 0.3, 1.2, 0.0, 0.99), Squircle((2.0, 1.76 + d), 0.6, 0.6, math.pi / 4, 0.99),
             Squircle((2.0, 2.6), 0.3, 0.8, 0.0, 0.99)]
    start, goal = (0.6, 0.5, 0.0), (3.4, 0.5, 0.0)
    rm = Roadmap.build(ws, walls, 0.1, RoadmapConfig(buffer=0.15))
    tree = plan_tree(rm, start, goal)
    _check_tree(tree, rm, start, goal)
    assert tree.translations.sum() < 3.6  # under the corner: the only way
    with monkeypatch.context() as m:
        m.setattr(tamp.roadmap, "grown", lambda sq, a: sq.grow(a))
        with pytest.raises(NoTreePathError):
            plan_tree(Roadmap.build(ws, walls, 0.1, RoadmapConfig(buffer=0.15)), start, goal)


@pytest.mark.parametrize("case", ["boundary", "obstacles"])
def test_gap_candidates_do_not_open_a_passage_closed_at_the_buffer(case):
    ws, walls, start, goal = _slit(case, 0.25)  # 1 cm short of 2 (r + b)
    rm = Roadmap.build(ws, walls, 0.1, RoadmapConfig(buffer=0.03))
    opened = rm.with_obstacles((), extra=rm.gap_candidates())
    assert opened.safe_points(opened.points).all()
    with pytest.raises(NoTreePathError) as info:
        plan_tree(opened, start, goal)
    assert info.value.reason is TreeFailure.DISCONNECTED
    assert Roadmap.build(ws, [], 0.1).gap_candidates().shape == (0, 2)
    for bad in ({"max_gap": 0.0}, {"spacing": -1.0}, {"samples": 2}):
        with pytest.raises(TampError, match="gap_candidates"):
            rm.gap_candidates(**bad)


def test_walled_off_goal_is_reported():
    ws, walls = _walled_world()
    rm = Roadmap.build(ws, walls, 0.05, RoadmapConfig(buffer=0.05))
    with pytest.raises(NoTreePathError, match="walled off") as info:
        plan_tree(rm, (0.5, 0.5, 0.0), (3.0, 1.5, 0.0))
    assert info.value.reason is TreeFailure.DISCONNECTED
    assert info.value.goal == (3.0, 1.5, 0.0)
    # the same goal with one wall missing (discovered later, revision) is reachable, and the
    # revision adding the wall reports it blocked
    open_rm = Roadmap.build(ws, walls[:3], 0.05, RoadmapConfig(buffer=0.05))
    tree = plan_tree(open_rm, (0.5, 0.5, 0.0), (3.0, 1.5, 0.0))
    rev = revise_trees(open_rm, {"g": tree}, walls[3:])
    assert rev.blocked["g"].reason is TreeFailure.DISCONNECTED and not rev.trees


def test_blocked_terminals_are_reported():
    ws, walls = _walled_world()
    rm = Roadmap.build(ws, walls, 0.05)
    with pytest.raises(NoTreePathError, match="goal position is not in free space") as info:
        plan_tree(rm, (0.5, 0.5, 0.0), (3.0, 2.0, 0.0))
    assert info.value.reason is TreeFailure.GOAL_BLOCKED
    with pytest.raises(NoTreePathError, match="start position") as info:
        plan_tree(rm, (9.0, 0.5, 0.0), (0.5, 2.5, 0.0))
    assert info.value.reason is TreeFailure.START_BLOCKED
    with pytest.raises(TampError, match="start must be a finite pose"):
        plan_tree(rm, (0.5, float("nan"), 0.0), (0.5, 2.5, 0.0))
    with pytest.raises(TampError, match="goal must be a"):
        plan_tree(rm, (0.5, 0.5, 0.0), (0.5, 2.5))
    with pytest.raises(TampError, match="vertices_per_obstacle"):
        RoadmapConfig(vertices_per_obstacle=6)


def test_terminal_inside_buffer_still_connects():
    """A start closer to a wall than the buffer (the robot after a discovery) leaves it."""
    ws, walls = _walled_world()
    rm = Roadmap.build(ws, walls[:1], 0.1)
    start = (3.0, 2.0 - 0.1 - 0.1 - 0.04, -math.pi / 2)  # 4 cm from the inflated wall
    assert not rm.safe_points(np.array([start[:2]]))[0]
    tree = plan_tree(rm, start, (0.5, 0.5, 0.0))
    _check_tree(tree, rm, start, (0.5, 0.5, 0.0))


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(10, 30))
def test_random_worlds_slow(seed):
    world = random_world(seed)
    rm = Roadmap.from_world(world)
    _all_pairs(world, rm, seed, allow_blocked=True)


def test_benchmark_quick_run_renders(tmp_path):
    from benchmarks.harmonic_tree import main

    assert main(["--quick", "--out", str(tmp_path)]) == 0
    table = (tmp_path / "harmonic_tree.md").read_text()
    assert "| simple (known) |" in table and "| simple | 4 |" in table


def test_large_rounded_obstacles_get_enough_vertices_to_go_around():
    # an ellipse of about 1 m semi-axes: with 8 vertices 0.05 m off it, the chords between
    # neighbouring vertices cut through it (sagitta 0.076 m); the roadmap must still go around
    world = random_world(0)
    big = Squircle((2.5, 2.5), 1.6, 2.0, 0.3, 0.0)
    rm = Roadmap.build(world.workspace, [big], world.robot.radius)
    own = rm.points[rm.owner == 0]
    assert len(own) > 8 and len(own) % 8 == 0
    G = pack([rm.buffered[0]])
    assert segments_clear(G, own, np.roll(own, -1, axis=0)).all()
    start, goal = (2.5, 0.8, 0.0), (2.5, 4.2, 0.0)  # opposite sides: no direct segment
    assert not rm.visible(np.array([start[:2]]), np.array([goal[:2]]))[0]
    tree = plan_tree(rm, start, goal)
    _check_tree(tree, rm, start, goal)


@pytest.mark.parametrize("s", [0.0, 0.5, 0.99])
def test_segment_test_near_the_bounding_rectangle(s):
    """Segments grazing a face of the squircle's bounding rectangle (which the squircle touches
    at the face's midpoint): 1e-7 m outside are clear, 1e-7 m inside are blocked, whatever the
    rectangle pre-filter of the segment test decides for other pairs."""
    theta = 0.7
    sq = Squircle((0.3, -0.2), 1.6, 0.4, theta, s)
    P = pack([sq])
    ex = np.array([math.cos(theta), math.sin(theta)])
    ey = np.array([-math.sin(theta), math.cos(theta)])
    centre = np.array(sq.center)
    out, inn = [], []
    for off in (1e-7, -1e-7):
        for side in (1.0, -1.0):
            for half in (0.3, 2.0):  # a short segment across the midpoint, a long one past the ends
                for mid, along in ((centre + side * (0.2 + off) * ey, ex), (centre + side * (0.8 + off) * ex, ey)):
                    (out if off > 0 else inn).append((mid - half * along, mid + half * along))
    a, b = (np.array(v) for v in zip(*out))
    assert segments_clear(P, a, b).all()
    a, b = (np.array(v) for v in zip(*inn))
    assert not segments_clear(P, a, b).any()
