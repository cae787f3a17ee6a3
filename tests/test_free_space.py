"""Guarantee: the navigation function is defined everywhere and keeps its contract.

* In free space: finite values, gradients (and Hessians) on a dense grid and at points down to
  rounding distance from every boundary; values in ``[0, mu]``; value and gradient 0 at the goal.
* Outside free space (inside obstacles, on boundaries, outside the workspace): ``value == mu``,
  a unit gradient pointing away from free space, zero Hessian, ``free False``, potential
  ``+inf``, no NaN.
* Shapes: ``(2,)`` in gives ``()``, ``(2,)``, ``(2, 2)``; ``(N, 2)`` gives ``(N,)``, ``(N, 2)``,
  ``(N, 2, 2)``; ``evaluate`` always has a leading ``N`` axis.
* Errors: ``PointsError`` (bad shapes, non-finite input), ``OutsideFreeSpaceError`` (goal not
  free), ``NavigationError`` (parameters that break a guarantee).
* Parameters: recorded on ``nf.params``, overridable, and reproducible through ``params=``.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import navigation
from navigation import (
    NavigationError,
    NavigationFunction,
    NavParams,
    OutsideFreeSpaceError,
    PointsError,
    Squircle,
    build_forest,
)

from .conftest import random_world, shared_world
from .worldgen import random_forest_world, random_free_points

SHARED_WORLDS = ("simple", "office", "cluttered20")
RANDOM_SEEDS = tuple(range(10))
SLOW_RANDOM_SEEDS = tuple(range(50))
GRID = 150


@functools.lru_cache(maxsize=None)
def shared_nf(name: str, goal_index: int = 0) -> NavigationFunction:
    w = shared_world(name)
    return NavigationFunction(w, list(w.regions.values())[goal_index].center)


def _world(kind: str, key):
    return shared_world(key) if kind == "shared" else random_world(key)


WORLD_CASES = [("shared", n) for n in SHARED_WORLDS] + [("random", s) for s in RANDOM_SEEDS]
WORLD_IDS = [f"{k}-{v}" for k, v in WORLD_CASES]


def bounding_box(sq: Squircle, pad: float = 0.0):
    b = sq.boundary_points(512)
    return b.min(axis=0) - pad, b.max(axis=0) + pad


def grid_over(sq: Squircle, n: int = GRID, pad: float = 0.0) -> np.ndarray:
    lo, hi = bounding_box(sq, pad)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n), indexing="ij")
    return np.stack((gx.ravel(), gy.ravel()), axis=1)


def free_by_definition(forest, q: np.ndarray) -> np.ndarray:
    """Strictly inside the workspace and outside every obstacle (Squircle.beta)."""
    free = forest.workspace.beta(q) < 0
    for o in forest.obstacles:
        free &= o.beta(q) > 0
    return free


def violations(forest, q: np.ndarray) -> np.ndarray:
    """``(N, 1 + M)``: how much each constraint is violated (> 0 violated, 0 on the boundary):
    column 0 the workspace (``beta_ws``), then every obstacle (``-beta_i``)."""
    cols = [forest.workspace.beta(q)] + [-o.beta(q) for o in forest.obstacles]
    return np.stack(cols, axis=1)


def assert_outside_contract(nf: NavigationFunction, q: np.ndarray, label: str) -> None:
    """``q (N, 2)`` are all non-free: the documented answer outside free space."""
    ev = nf.evaluate(q, 2)
    mu = nf.params.mu
    bad = np.nonzero(ev.free)[0]
    assert len(bad) == 0, f"{label}: {len(bad)} non-free points reported free, e.g. {q[bad[:3]].tolist()}"
    assert np.all(ev.value == mu), f"{label}: value != mu at {q[ev.value != mu][:3].tolist()}"
    assert np.all(np.isfinite(ev.gradient)), f"{label}: non-finite gradient"
    norm = np.linalg.norm(ev.gradient, axis=1)
    np.testing.assert_allclose(norm, 1.0, rtol=1e-12, err_msg=f"{label}: gradient not unit length")
    assert np.all(ev.hessian == 0.0), f"{label}: non-zero Hessian"
    assert np.all(ev.potential == np.inf), f"{label}: potential is not +inf"
    assert not np.any(nf.is_free(q))
    np.testing.assert_array_equal(nf.value(q), mu)
    np.testing.assert_array_equal(nf.gradient(q), ev.gradient)
    np.testing.assert_array_equal(nf.hessian(q), 0.0)


def assert_points_away(nf: NavigationFunction, q: np.ndarray, label: str) -> None:
    """At non-free points that violate exactly one constraint, ``-gradient`` leads back to
    free space across that constraint: a small step along ``-gradient`` reduces the violation."""
    f = nf.forest
    viol = violations(f, q)
    single = np.sum(viol >= 0, axis=1) == 1
    q, viol = q[single], viol[single]
    if len(q) == 0:
        return
    k = np.argmax(viol, axis=1)
    g = nf.gradient(q)
    sqs = [f.workspace] + list(f.obstacles)
    for j in np.unique(k):
        sel = k == j
        n = sqs[j].gradient(q[sel])  # grad beta: outward normal of squircle j
        n = n if j == 0 else -n  # direction in which violation grows
        nn = np.linalg.norm(n, axis=1)
        ok = nn > 1e-9 * max(1.0, np.abs(q).max())  # the direction is defined
        dot = np.sum(g[sel] * n, axis=1)[ok] / nn[ok]
        assert np.all(dot > 0), (f"{label}: gradient does not point away from free space across "
                                 f"{'the workspace boundary' if j == 0 else f'obstacle {j - 1}'} at "
                                 f"{q[sel][ok][dot <= 0][:3].tolist()}")


# ---------------------------------------------------------------------- free space
def check_grid(world, goal) -> None:
    nf = NavigationFunction(world, goal)
    q = grid_over(nf.forest.workspace)
    ev = nf.evaluate(q, 2)
    mu = nf.params.mu
    np.testing.assert_array_equal(ev.free, free_by_definition(nf.forest, q))
    np.testing.assert_array_equal(nf.is_free(q), ev.free)
    fr = ev.free
    assert fr.mean() > 0.3
    for name, arr in (("value", ev.value), ("gradient", ev.gradient), ("hessian", ev.hessian)):
        finite = np.isfinite(arr.reshape(len(q), -1)).all(axis=1)
        assert finite.all(), f"{world.name}: non-finite {name} at {q[~finite][:5].tolist()} (free={fr[~finite][:5]})"
    assert np.all((ev.value >= 0.0) & (ev.value <= mu)), f"{world.name}: value outside [0, mu]"
    assert np.all(ev.value[~fr] == mu)
    assert np.all(ev.potential[fr] < np.inf) and np.all(ev.potential[~fr] == np.inf)
    # order 1 (the renderer's call) gives the same values and gradients
    ev1 = nf.evaluate(q, 1)
    assert ev1.hessian is None
    np.testing.assert_array_equal(ev1.value, ev.value)
    np.testing.assert_allclose(ev1.gradient, ev.gradient, rtol=1e-12, atol=0)
    assert_outside_contract(nf, q[~fr], f"{world.name} grid (non-free points)")


@pytest.mark.parametrize(("kind", "key"), WORLD_CASES, ids=WORLD_IDS)
def test_grid_finite_and_bounded(kind, key):
    world = _world(kind, key)
    check_grid(world, list(world.regions.values())[0].center)


@pytest.mark.slow
@pytest.mark.parametrize("seed", SLOW_RANDOM_SEEDS)
def test_grid_finite_and_bounded_many(seed):
    world = random_forest_world(seed)
    for region in list(world.regions.values())[:2]:
        check_grid(world, region.center)


def near_boundary(forest, offsets, per_boundary: int = 128) -> np.ndarray:
    """Points at the given distances (along the normal) on the free side of every boundary."""
    out = []
    for sq, sign in [(forest.workspace, -1.0)] + [(o, 1.0) for o in forest.obstacles]:
        b = sq.boundary_points(per_boundary)
        n = sq.gradient(b)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        out.extend(b + sign * d * n for d in offsets)
    return np.concatenate(out)


@pytest.mark.parametrize(("kind", "key"), WORLD_CASES, ids=WORLD_IDS)
def test_finite_next_to_boundaries(kind, key):
    """Points from rounding distance to 1 mm outside every boundary (and the boundary samples
    themselves, free or not by rounding) get finite values, gradients and Hessians."""
    world = _world(kind, key)
    nf = NavigationFunction(world, list(world.regions.values())[0].center)
    q = near_boundary(nf.forest, (0.0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-3))
    with np.errstate(all="ignore"):  # a failure must show as non-finite output, not a warning
        ev = nf.evaluate(q, 2)
    mu = nf.params.mu
    for name, arr in (("value", ev.value), ("gradient", ev.gradient), ("hessian", ev.hessian)):
        finite = np.isfinite(arr.reshape(len(q), -1)).all(axis=1)
        assert finite.all(), (f"{world.name}: non-finite {name} at {np.count_nonzero(~finite)} of {len(q)} "
                              f"points next to boundaries ({np.count_nonzero(~finite & ev.free)} of them free), "
                              f"e.g. {q[~finite][:4].tolist()}")
    assert np.all((ev.value >= 0.0) & (ev.value <= mu))
    assert_outside_contract(nf, q[~ev.free], f"{world.name} boundary samples (non-free)")



def test_finite_at_the_workspace_centre():
    """The point-world map ``psi`` has a removable 0/0 at the workspace centre (it is C1 there,
    its second derivatives depend on the direction of approach): value, gradient and Hessian
    are finite there, equal their limits along +x, and the centre works as a goal and for the
    oriented field."""
    from navigation.oriented import OrientedField

    checked = 0
    # cluttered20 grown by the robot radius is not a forest (tests/test_forest.py)
    for world in [shared_world(n) for n in ("simple", "office")] + [random_forest_world(s, gap=0.3) for s in range(6)]:
        c = np.asarray(world.workspace.center, dtype=float)
        goal = list(world.regions.values())[0].center
        nf = NavigationFunction(world, goal, inflation=world.robot.radius)
        if not nf.is_free(c[None])[0]:
            continue
        at, near = nf.evaluate(c, 2), nf.evaluate(c + [1e-9, 0.0], 2)
        for name in ("value", "gradient", "hessian"):
            a, b = getattr(at, name), getattr(near, name)
            assert np.isfinite(a).all(), f"{world.name}: non-finite {name} at the workspace centre"
            np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-9)
        assert np.isfinite(OrientedField(nf, 0.3).evaluate(c).angle)
        centred = NavigationFunction(world, c, inflation=world.robot.radius)
        q = random_free_points(world, 50, np.random.default_rng(1), margin=world.robot.radius + 0.01)
        assert np.isfinite(centred.evaluate(q, 2).hessian).all() and centred.value(c) == 0.0
        checked += 1
    assert checked >= 4

@pytest.mark.parametrize(("kind", "key"), WORLD_CASES, ids=WORLD_IDS)
def test_zero_at_the_goal(kind, key):
    world = _world(kind, key)
    for region in list(world.regions.values())[:3]:
        nf = NavigationFunction(world, region.center)
        ev = nf.evaluate(region.center, 2)
        assert ev.free[0]
        assert ev.value[0] == 0.0
        np.testing.assert_array_equal(ev.gradient[0], 0.0)
        assert ev.potential[0] == -np.inf
        np.testing.assert_array_equal(nf.goal, region.center)
        # and nowhere else in free space (sampled) is the value 0
        rng = np.random.default_rng(3)
        q = random_free_points(world, 500, rng)
        assert np.all(nf.value(q)[np.any(q != nf.goal, axis=1)] > 0.0)


# ---------------------------------------------------------------------- outside free space
@pytest.mark.parametrize(("kind", "key"), WORLD_CASES, ids=WORLD_IDS)
def test_outside_free_space_contract(kind, key):
    world = _world(kind, key)
    nf = NavigationFunction(world, list(world.regions.values())[0].center)
    f = nf.forest
    rng = np.random.default_rng(11)
    # inside obstacles: centres, and random points of each obstacle's box kept when inside it
    inside = [np.array([o.center for o in f.obstacles])]
    for o in f.obstacles:
        p = o.center + rng.uniform(-1, 1, size=(200, 2)) * max(o.width, o.height) / 2
        inside.append(p[o.beta(p) < 0])
    inside = np.concatenate(inside)
    assert_outside_contract(nf, inside, f"{world.name} inside obstacles")
    assert_points_away(nf, inside, f"{world.name} inside obstacles")
    # on and just across the boundaries (non-free side), and far outside the workspace
    across = near_boundary(f, (-1e-12, -1e-9, -1e-6, -1e-3, -0.1))
    across = across[~free_by_definition(f, across)]
    assert_outside_contract(nf, across, f"{world.name} just inside the boundaries")
    assert_points_away(nf, across, f"{world.name} just inside the boundaries")
    lo, hi = bounding_box(f.workspace)
    ring = grid_over(f.workspace, 60, pad=1.0)
    far = np.concatenate([ring[~(np.all(ring > lo, axis=1) & np.all(ring < hi, axis=1))],
                          [[1e3, 1e3], [-1e6, 2.0], [0.5 * (lo[0] + hi[0]), 1e12], [-1e150, -1e150]]])
    assert_outside_contract(nf, far, f"{world.name} outside the workspace")
    assert_points_away(nf, far[np.abs(far).max(axis=1) < 1e6], f"{world.name} outside the workspace")


def test_exactly_on_a_boundary_is_not_free():
    """``beta == 0`` exactly (an axis-aligned squircle's extreme points) is not free space."""
    ws = Squircle((2.0, 2.0), 4.0, 4.0)
    ob = Squircle((1.0, 1.0), 1.0, 1.0)
    forest = build_forest(ws, [ob])
    nf = NavigationFunction(forest, (3.0, 3.0))
    on = np.array([[1.5, 1.0], [0.5, 1.0], [1.0, 1.5], [1.0, 0.5], [4.0, 2.0], [2.0, 0.0]])
    assert np.all(np.concatenate((ob.beta(on[:4]), ws.beta(on[4:]))) == 0.0)
    assert_outside_contract(nf, on, "exact boundary points")
    g = nf.gradient(on)
    np.testing.assert_allclose(g, [[-1, 0], [1, 0], [0, -1], [0, 1], [1, 0], [0, -1]], atol=1e-12)


# ---------------------------------------------------------------------- shapes
def test_shapes_single_and_batch():
    nf = shared_nf("office")
    rng = np.random.default_rng(2)
    q = np.concatenate((random_free_points(shared_world("office"), 4, rng), [[-5.0, -5.0]]))
    assert nf.value(q).shape == (5,)
    assert nf.gradient(q).shape == (5, 2)
    assert nf.hessian(q).shape == (5, 2, 2)
    assert nf.is_free(q).shape == (5,) and nf.is_free(q).dtype == np.bool_
    for i, p in enumerate(q):
        assert nf.value(p).shape == ()
        assert nf.gradient(p).shape == (2,)
        assert nf.hessian(p).shape == (2, 2)
        assert nf.is_free(p).shape == ()
        assert nf.value(p) == nf.value(q)[i]
        np.testing.assert_array_equal(nf.gradient(p), nf.gradient(q)[i])
        np.testing.assert_array_equal(nf.hessian(p), nf.hessian(q)[i])
        assert nf.is_free(p) == nf.is_free(q)[i]
        # lists and tuples are points too
        assert nf.value(tuple(p)) == nf.value(p) and nf.value(list(p)) == nf.value(p)
    for order in (0, 1, 2):
        for pts, n in ((q, 5), (q[0], 1), (q[:1], 1)):
            ev = nf.evaluate(pts, order)
            assert ev.value.shape == (n,) and ev.potential.shape == (n,) and ev.free.shape == (n,)
            assert (ev.gradient is None) == (order < 1) and (ev.hessian is None) == (order < 2)
            if order >= 1:
                assert ev.gradient.shape == (n, 2)
            if order >= 2:
                assert ev.hessian.shape == (n, 2, 2)
    x, J, H = nf.transform(q[:4], 2)
    assert x.shape == (4, 2) and J.shape == (4, 2, 2) and H.shape == (4, 2, 2, 2)
    x1, J1, _ = nf.transform(q[0], 1)
    assert x1.shape == (1, 2) and J1.shape == (1, 2, 2)


def test_empty_batch():
    nf = shared_nf("simple")
    q = np.zeros((0, 2))
    assert nf.value(q).shape == (0,)
    assert nf.gradient(q).shape == (0, 2)
    assert nf.hessian(q).shape == (0, 2, 2)
    assert nf.is_free(q).shape == (0,)


BAD_SHAPES = [np.zeros(3), np.zeros((2, 3)), np.zeros((1, 2, 2)), np.zeros(()), np.zeros((0,)), [[1.0], [2.0]],
              "ab", [1.0, "x"], None]
BAD_VALUES = [[np.nan, 1.0], [1.0, np.inf], [[1.0, 1.0], [-np.inf, 0.0]], [[np.nan, np.nan]]]
METHODS = ("value", "gradient", "hessian", "is_free", "evaluate", "transform")


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("bad", BAD_SHAPES + BAD_VALUES,
                         ids=[f"shape{i}" for i in range(len(BAD_SHAPES))] + [f"nonfinite{i}" for i in range(len(BAD_VALUES))])
def test_points_error(method, bad):
    nf = shared_nf("simple")
    with pytest.raises(PointsError, match="`q`") as info:
        getattr(nf, method)(bad)
    assert isinstance(info.value, ValueError) and isinstance(info.value, NavigationError)


def test_evaluate_rejects_bad_order():
    nf = shared_nf("simple")
    for order in (-1, 3, 1.5, "2"):
        with pytest.raises(NavigationError):
            nf.evaluate([1.0, 1.0], order)


def test_transform_rejects_non_free_points():
    nf = shared_nf("simple")
    f = nf.forest
    for q in ([f.obstacles[0].center], [[-10.0, -10.0]], [nf.goal, f.obstacles[1].center]):
        with pytest.raises(OutsideFreeSpaceError):
            nf.transform(q)


# ---------------------------------------------------------------------- goal errors
@pytest.mark.parametrize("name", SHARED_WORLDS)
def test_goal_not_in_free_space(name):
    world = shared_world(name)
    f = world.forest(0.0)
    lo, hi = bounding_box(f.workspace)
    for i, o in enumerate(f.obstacles):
        with pytest.raises(OutsideFreeSpaceError):
            NavigationFunction(world, o.center)
        b = o.boundary_points(16)
        inward = b - 1e-6 * o.gradient(b) / np.linalg.norm(o.gradient(b), axis=1, keepdims=True)
        for p in inward[o.beta(inward) < 0][:2]:
            with pytest.raises(OutsideFreeSpaceError):
                NavigationFunction(world, p)
    for p in ([lo[0] - 1.0, lo[1] - 1.0], [hi[0] + 0.5, 0.5 * (lo[1] + hi[1])], [1e9, 1e9]):
        with pytest.raises(OutsideFreeSpaceError):
            NavigationFunction(world, p)
    for p in ([np.nan, 1.0], [1.0, np.inf]):
        with pytest.raises(PointsError):
            NavigationFunction(world, p)
    for p in ([[1.0, 1.0], [2.0, 2.0]], [1.0, 2.0, 3.0]):
        with pytest.raises((OutsideFreeSpaceError, PointsError)):
            NavigationFunction(world, p)


def test_goal_on_a_boundary():
    ws = Squircle((2.0, 2.0), 4.0, 4.0)
    ob = Squircle((1.0, 1.0), 1.0, 1.0)
    forest = build_forest(ws, [ob])
    for goal in ((1.5, 1.0), (1.0, 0.5), (4.0, 2.0), (2.0, 0.0)):
        with pytest.raises(OutsideFreeSpaceError):
            NavigationFunction(forest, goal)
    NavigationFunction(forest, (1.5 + 1e-9, 1.0))  # just outside the obstacle: free


def test_goal_inside_an_inflated_obstacle():
    world = shared_world("simple")
    f = world.forest(0.0)
    o = f.obstacles[0]
    b = o.boundary_points(8)
    outward = b + 0.05 * o.gradient(b) / np.linalg.norm(o.gradient(b), axis=1, keepdims=True)
    p = outward[free_by_definition(f, outward)][0]
    NavigationFunction(world, p)  # free without inflation
    with pytest.raises(OutsideFreeSpaceError):
        NavigationFunction(world, p, inflation=0.1)


# ---------------------------------------------------------------------- parameters
def test_params_recorded():
    for name in SHARED_WORLDS:
        nf = shared_nf(name)
        p, f = nf.params, nf.forest
        assert isinstance(p, NavParams)
        n_trees = len(f.roots)
        assert p.K > n_trees
        assert p.mu == 1.0
        assert 0 < p.width_fraction < 0.5
        assert len(p.purge_width) == len(f.obstacles)
        assert len(p.root_width) == len(p.rho) == len(p.delta) == n_trees
        for i, w in enumerate(p.purge_width):
            if f.parent[i] == navigation.forest.NO_PARENT:
                assert math.isnan(w)
            else:
                assert 0 < w <= p.width_cap
        assert all(0 < r < f.obstacles[j].inscribed_radius for r, j in zip(p.rho, f.roots))
        assert all(w > 0 for w in p.root_width) and all(d > 0 for d in p.delta)
        assert p.workspace_width > 0 and p.rho0 > 0
        assert nf.point_obstacles.shape == (n_trees, 2) and nf.goal_image.shape == (2,)


def test_explicit_params_reproduce_the_function():
    nf = shared_nf("cluttered20")
    again = NavigationFunction(nf.forest, nf.goal, params=nf.params)
    assert again.params == nf.params or again.params.as_dict() == nf.params.as_dict()
    q = random_free_points(shared_world("cluttered20"), 200, np.random.default_rng(4))
    np.testing.assert_array_equal(again.value(q), nf.value(q))
    np.testing.assert_array_equal(again.gradient(q), nf.gradient(q))


def test_override_K():
    world = shared_world("simple")
    goal = world.regions["b"].center
    nf = NavigationFunction(world, goal, K=7)
    assert nf.params.K == 7
    base = NavigationFunction(world, goal)
    assert base.params.K != 7
    q = random_free_points(world, 50, np.random.default_rng(0))
    assert not np.allclose(nf.value(q), base.value(q))
    # the chain does not depend on K
    np.testing.assert_array_equal(nf.transform(q)[0], base.transform(q)[0])
    with pytest.raises(NavigationError, match="K"):
        NavigationFunction(shared_world("office"), shared_world("office").regions["p1"].center, K=7)


def test_override_mu():
    world = shared_world("simple")
    nf = NavigationFunction(world, world.regions["a"].center, mu=2.5)
    assert nf.params.mu == 2.5
    f = nf.forest
    q = np.concatenate((grid_over(f.workspace, 60), [f.obstacles[0].center]))
    v = nf.value(q)
    assert np.all((v >= 0) & (v <= 2.5))
    assert np.all(v[~nf.is_free(q)] == 2.5)
    base = NavigationFunction(world, world.regions["a"].center)
    free = nf.is_free(q)
    np.testing.assert_allclose(v[free], 2.5 * base.value(q[free]), rtol=1e-12)


@pytest.mark.parametrize("name", SHARED_WORLDS)
def test_override_width_fraction(name):
    """Widths limited by clearance scale with ``width_fraction``; the others keep their cap."""
    world = shared_world(name)
    goal = list(world.regions.values())[0].center
    base = NavigationFunction(world, goal)
    new_f = 0.3
    nf = NavigationFunction(world, goal, width_fraction=new_f)
    assert nf.params.width_fraction == new_f
    f, p0, p1 = nf.forest, base.params, nf.params
    ratio = new_f / p0.width_fraction
    limited = 0
    for i, (w0, w1) in enumerate(zip(p0.purge_width, p1.purge_width)):
        if math.isnan(w0):
            assert math.isnan(w1)
            continue
        cap = min(p0.width_cap, 2.0 * f.obstacles[i].bounding_radius)
        if w0 < cap * (1 - 1e-9):  # limited by clearance
            limited += 1
            assert w1 == pytest.approx(ratio * w0, rel=1e-12)
        else:
            assert w1 <= w0
    for j, (w0, w1) in enumerate(zip(p0.root_width, p1.root_width)):
        cap = min(p0.width_cap, 2.0 * f.obstacles[f.roots[j]].bounding_radius)
        if w0 < cap * (1 - 1e-9):
            limited += 1
            assert w1 == pytest.approx(ratio * w0, rel=1e-12)
    assert limited > 0


@pytest.mark.parametrize("override", [
    {"K": 0}, {"K": -1.0}, {"K": math.nan}, {"K": math.inf},
    {"mu": 0.0}, {"mu": -1.0}, {"mu": math.nan},
    {"width_fraction": 0.5}, {"width_fraction": 0.7}, {"width_fraction": 0.0}, {"width_fraction": -0.1},
    {"width_fraction": math.nan},
    {"rho_fraction": 1.0}, {"rho_fraction": 0.0}, {"width_cap": 0.0}, {"width_cap": -1.0},
], ids=lambda d: "-".join(f"{k}={v}" for k, v in d.items()))
def test_bad_overrides(override):
    world = shared_world("simple")
    with pytest.raises(NavigationError):
        NavigationFunction(world, world.regions["a"].center, **override)


@pytest.mark.parametrize("name", SHARED_WORLDS)
def test_K_must_exceed_number_of_trees(name):
    world = shared_world(name)
    n = len(world.forest(0.0).roots)
    goal = list(world.regions.values())[0].center
    with pytest.raises(NavigationError, match="K"):
        NavigationFunction(world, goal, K=n)
    assert NavigationFunction(world, goal, K=n + 0.5).params.K == n + 0.5
