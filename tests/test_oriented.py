"""Oriented harmonic fields (paper 001 eq. 20-23, built as a dipolar potential; see
navigation.oriented): exact Jacobians, boundary behaviour, finite values everywhere, and
integral curves that reach the goal along the desired heading."""

from __future__ import annotations

import numpy as np
import pytest

import navigation
from navigation.errors import NavigationError
from navigation.oriented import OrientedField, wrap_angle

from .conftest import random_world, shared_world
from .worldgen import random_free_points

WORLDS = [("simple", None), ("cluttered20", None)] + [(None, s) for s in range(5)]


def _world(name, seed):
    return shared_world(name) if name else random_world(seed)


def _field(world, rng, heading=None):
    goal = random_free_points(world, 1, rng, margin=0.2)[0]
    nf = navigation.NavigationFunction(world, goal=goal)
    return OrientedField(nf, heading=rng.uniform(-np.pi, np.pi) if heading is None else heading)


@pytest.mark.parametrize("name,seed", WORLDS)
def test_jacobian_matches_finite_differences(name, seed):
    world = _world(name, seed)
    rng = np.random.default_rng(11 if seed is None else seed)
    field = _field(world, rng)
    pts = random_free_points(world, 300, rng, margin=0.02)
    ev = field.evaluate(pts)
    # away from the direction cut (Delta = pi) where the field is only one-sided smooth
    h = 1e-6
    fd = np.stack([(field.field(pts + e) - field.field(pts - e)) / (2 * h) for e in np.eye(2) * h], axis=2)
    scale = np.abs(ev.jacobian).max(axis=(1, 2)) + 1e-12
    err = np.abs(fd - ev.jacobian).max(axis=(1, 2)) / scale
    smooth = ~ev.degenerate & (err < 1e-3)  # a point within h of the cut jumps by O(1)
    assert smooth.mean() > 0.97, f"too many points on the cut: {1 - smooth.mean():.3f}"
    assert np.median(err) < 1e-6
    assert np.all(err[smooth] < 1e-4), f"max relative error {err[smooth].max():.2e}"


@pytest.mark.parametrize("name,seed", WORLDS)
def test_finite_everywhere_and_descent_on_boundaries(name, seed):
    world = _world(name, seed)
    rng = np.random.default_rng(5)
    field = _field(world, rng)
    ws = world.workspace
    lo = np.array(ws.center) - max(ws.width, ws.height) / 2 - 0.2
    grid = rng.uniform(lo, lo + max(ws.width, ws.height) + 0.4, size=(2000, 2))
    ev = field.evaluate(grid)
    assert np.isfinite(ev.field).all() and np.isfinite(ev.jacobian).all()
    assert np.isfinite(ev.angle).all() and np.isfinite(ev.angle_gradient).all()
    # outside free space: the navigation function's contract (unit vector back into free space)
    nev = field.nf.evaluate(grid[~ev.free], order=1)
    np.testing.assert_allclose(ev.field[~ev.free], -nev.gradient, atol=1e-12)
    # next to boundaries the oriented value tends to mu and the field points into free space
    near = random_free_points(world, 400, rng)
    phi = field.nf.value(near)
    close = near[phi > 0.999]
    ev_near = field.evaluate(close)
    assert np.all(ev_near.value > 0.99 * field.mu)
    nf_dir = -field.nf.gradient(close)
    cos = np.einsum("ni,ni->n", ev_near.field, nf_dir) / (
        np.linalg.norm(ev_near.field, axis=1) * np.linalg.norm(nf_dir, axis=1))
    assert np.all(cos > 0.9), f"min cos to -grad phi_NF next to boundaries {cos.min():.3f}"


def _follow(field, start, max_steps=20000):
    """Integral curve of the normalised field: unit-speed Euler steps of at most 1 cm, halved
    whenever the direction reverses (a step that jumped across the bottom of a valley), so the
    curve follows valleys along walls instead of bouncing. Returns (end point, last direction)."""
    q = np.array(start, dtype=float)
    h, prev, last = 0.01, None, None
    for _ in range(max_steps):
        ev = field.evaluate(q)
        if ev.degenerate:
            break
        d = np.array([np.cos(ev.angle), np.sin(ev.angle)])
        h = 0.5 * h if prev is not None and d @ prev < 0 else min(0.01, 1.2 * h)
        q = q + min(h, 0.3 * np.linalg.norm(q - field.goal)) * d
        assert field.nf.is_free(q), f"left free space from {start}"
        prev = last = d
        if np.linalg.norm(q - field.goal) < 1e-4:
            break
    return q, last


def test_integral_curves_arrive_with_the_desired_heading():
    """Integral curves of Upsilon from random starts on ``simple`` reach the goal and arrive
    along the desired heading (last step, 1e-4 m from the goal)."""
    world = shared_world("simple")
    rng = np.random.default_rng(1)
    for _ in range(3):
        goal = random_free_points(world, 1, rng, margin=0.2)[0]
        nf = navigation.NavigationFunction(world, goal=goal)
        field = OrientedField(nf, heading=rng.uniform(-np.pi, np.pi))
        for start in random_free_points(world, 6, rng, margin=0.05):
            q, last = _follow(field, start)
            assert np.linalg.norm(q - field.goal) < 1e-4, f"{field}: from {start} stopped at {q}"
            arrival = np.arctan2(last[1], last[0])
            assert abs(wrap_angle(arrival - field.heading)) < 0.1, f"{field}: from {start} arrived at {arrival}"


def test_bad_parameters_are_refused():
    nf = navigation.NavigationFunction(shared_world("simple"), goal=(1.0, 1.0))
    with pytest.raises(NavigationError, match="heading"):
        OrientedField(nf, heading=float("nan"))
    with pytest.raises(NavigationError, match="strength"):
        OrientedField(nf, heading=0.0, strength=-1.0)


def test_shapes_follow_the_input():
    nf = navigation.NavigationFunction(shared_world("simple"), goal=(1.0, 1.0))
    f = OrientedField(nf, heading=0.3)
    assert f.field([0.5, 0.2]).shape == (2,)
    assert f.jacobian([0.5, 0.2]).shape == (2, 2)
    assert f.field(np.zeros((0, 2))).shape == (0, 2)
    ev = f.evaluate([1.0, 1.0])
    assert ev.degenerate and ev.angle == pytest.approx(0.3)


@pytest.mark.parametrize("name", ["simple", "office", "random4"])
def test_boundary_frame_derivatives_match_finite_differences(name):
    """``OrientedField.boundary_frame`` (the controller's stand-off): band weight, weighted
    normal, nearest first-order distance and normal, each with its exact gradient."""
    from .worldgen import random_forest_world

    world = random_forest_world(4, gap=0.3) if name == "random4" else shared_world(name)
    r = world.robot.radius
    rng = np.random.default_rng(2)
    goal = random_free_points(world, 1, rng, margin=r + 0.2)[0]
    field = OrientedField(navigation.NavigationFunction(world, goal=goal, inflation=r), heading=0.3)
    reach, h, checked = 0.06, 1e-7, 0
    for q in random_free_points(world, 1500, rng, margin=r + 0.001):
        fr = field.boundary_frame(q, reach)
        if fr is None:
            assert float(field.clearance(q, reach)) >= reach - 0.02 or not field.evaluate(q).free
            continue
        assert 0.0 < fr.weight <= 1.0 and abs(np.linalg.norm(fr.normal) - 1.0) < 1e-12
        checked += 1
        for k, e in enumerate(np.eye(2) * h):
            p, m = field.boundary_frame(q + e, reach), field.boundary_frame(q - e, reach)
            if p is None or m is None:
                continue
            pairs = [((p.weight - m.weight) / (2 * h), fr.weight_gradient[k]),
                     (wrap_angle(p.angle - m.angle) / (2 * h), fr.angle_gradient[k]),
                     ((p.normal - m.normal) / (2 * h), fr.normal_jacobian[:, k])]
            if np.allclose(p.normal, m.normal, atol=1e-5):  # same nearest boundary on both sides
                pairs.append(((p.distance - m.distance) / (2 * h), fr.distance_gradient[k]))
            for fd, exact in pairs:
                assert np.allclose(fd, exact, rtol=1e-4, atol=1e-4 * (1 + np.abs(exact).max())), (q, k, fd, exact)
    assert checked >= 30
    # far from every boundary, and inside an obstacle: no frame
    assert field.boundary_frame(field.goal, 0.1) is None
    assert field.boundary_frame(field.nf.forest.obstacles[0].center, reach) is None
    assert field.goal_clearance == pytest.approx(field.clearance.exact(field.goal))


def _same_frame(a, b) -> bool:
    """Bit-for-bit equality of two ``BoundaryFrame | None`` (signed zeros included)."""
    if a is None or b is None:
        return a is None and b is None
    return all(np.asarray(x, dtype=float).tobytes() == np.asarray(y, dtype=float).tobytes() for x, y in zip(a, b))


@pytest.mark.parametrize("name", ["office", "random4"])
def test_boundary_scan_frames_equal_separate_boundary_frames(name):
    """``OrientedField.boundary_scan`` evaluates the boundaries once for several reaches (the
    controller's stand-off reads three from one scan): the frame it gives for a smaller reach is
    bit for bit ``boundary_frame`` at that reach, ``None`` cases included; a larger one is refused."""
    from .worldgen import random_forest_world

    world = random_forest_world(4, gap=0.3) if name == "random4" else shared_world(name)
    r = world.robot.radius
    rng = np.random.default_rng(5)
    goal = random_free_points(world, 1, rng, margin=r + 0.2)[0]
    field = OrientedField(navigation.NavigationFunction(world, goal=goal, inflation=r), heading=-0.7)
    top, reaches = 0.08, (0.01, 0.02, 0.03, 0.03 / 3 + 0.5 * 0.1, 0.06, 0.08)
    framed = dropped = 0
    for q in random_free_points(world, 400, rng, margin=r + 0.0005):
        scan = field.boundary_scan(q, top)
        if scan is None:
            assert all(field.boundary_frame(q, reach) is None for reach in reaches)
            continue
        for reach in reaches:
            sep = field.boundary_frame(q, reach)
            assert _same_frame(scan.frame(reach), sep), (q, reach)
            framed += sep is not None
        dropped += int(0 < (scan._delta < 0.03).sum() < len(scan._delta))  # the smaller reach drops some
        with pytest.raises(ValueError):
            scan.frame(top * 1.5)
    assert framed >= 100 and dropped >= 3, (framed, dropped)


def test_clearance_exact_is_the_minimum_over_every_shape():
    """ClearanceBound.exact measures only the shapes that can be the nearest: the same number as
    the minimum of the signed distances to every obstacle and the workspace boundary."""
    import numpy as np

    import navigation
    from navigation.clearance import ClearanceBound

    world = navigation.load_world("office")
    forest = world.forest(world.robot.radius)
    bound = ClearanceBound(forest.workspace, forest.obstacles)
    full = navigation.geometry.ExactDistance(tuple(forest.obstacles) + (forest.workspace,), spacing=0.005,
                                             split=len(forest.obstacles), min_samples=64)
    rng = np.random.default_rng(3)
    lo, hi = np.array(forest.workspace.center) - 6.0, np.array(forest.workspace.center) + 6.0
    m = len(forest.obstacles)
    for q in rng.uniform(lo, hi, (150, 2)):
        d = full.signed(np.repeat(q[None], m + 1, axis=0), np.arange(m + 1))
        d[m] = -d[m]
        assert bound.exact(q) == float(d.min())


def test_navigation_functions_on_one_forest_share_the_goal_free_parts():
    """The parameters, the chain and the point obstacles depend on the forest only: a second
    goal on the same forest reuses them, with the numbers of a function built from scratch."""
    import numpy as np

    import navigation
    from navigation import potential

    world = navigation.load_world("office")
    forest = world.forest(world.robot.radius)
    a = navigation.NavigationFunction(forest, goal=world.robot.start[:2])
    goal = world.regions[sorted(world.regions)[0]].center
    b = navigation.NavigationFunction(forest, goal=goal)
    assert b.chain is a.chain and b.params is a.params
    potential._SHARED.clear()
    c = navigation.NavigationFunction(forest, goal=goal)
    assert c.chain is not b.chain and repr(c.params) == repr(b.params)  # (nan entries: not ==)
    q = np.array([world.robot.start[:2], goal]) + 0.05
    for order in (0, 1, 2):
        eb, ec = b.evaluate(q, order), c.evaluate(q, order)
        assert all(np.array_equal(x, y) for x, y in zip((eb.value, eb.gradient, eb.hessian, eb.potential),
                                                         (ec.value, ec.gradient, ec.hessian, ec.potential)))
    assert np.array_equal(b.point_obstacles, c.point_obstacles) and np.array_equal(b.goal_image, c.goal_image)


def test_goal_transform_gives_the_goal_image_of_order_zero():
    """An oriented field takes ``P_G`` from the chain at order 1 (with its Jacobian): the chain's
    values are the same at every order, so P_G is the order-0 image, bit for bit."""
    import numpy as np

    import navigation

    world = navigation.load_world("office")
    forest = world.forest(world.robot.radius)
    for name in sorted(world.regions):
        goal = world.regions[name].center
        a = navigation.NavigationFunction(forest, goal=goal)
        b = navigation.NavigationFunction(forest, goal=goal)
        pg, jac = b.goal_transform()
        assert np.array_equal(pg, a.goal_image)  # (a: order 0)
        assert np.array_equal(jac, a.transform(np.asarray(goal, dtype=float)[None], order=1)[1][0])


def test_repeated_chain_and_clearance_queries_return_fresh_copies_of_the_same_numbers():
    """Chain.apply and ClearanceBound keep their last answers (two fields of one forest are asked
    at the same point): a repeated query gives the same numbers, in arrays of its own."""
    import numpy as np

    import navigation
    from navigation._jet import Jet
    from navigation.clearance import forest_clearance

    world = navigation.load_world("office")
    forest = world.forest(world.robot.radius)
    nf = navigation.NavigationFunction(forest, goal=world.robot.start[:2])
    q = np.array([[world.robot.start[0] + 0.3, world.robot.start[1] + 0.1]])
    x1, y1 = nf.chain.apply(*Jet.variables(q, 2))
    ref = (x1.a.copy(), y1.a.copy())
    x1.a[:] = 0.0  # a caller's change must not reach the kept answer
    x2, y2 = nf.chain.apply(*Jet.variables(q, 2))
    assert np.array_equal(x2.a, ref[0]) and np.array_equal(y2.a, ref[1])
    x3, _ = nf.chain.apply(*Jet.variables(q, 1))  # another order: computed
    assert x3.a.shape[-1] == 3 and np.array_equal(x3.a[:, 0], ref[0][:, 0])
    bound = forest_clearance(forest)
    pts = np.array([[world.robot.start[0], world.robot.start[1]], [1.0, 1.0]])
    a = bound(pts, 0.5)
    a_ref = a.copy()
    a[:] = -1.0
    assert np.array_equal(bound(pts, 0.5), a_ref) and bound(pts[0], 0.5) == a_ref[0]


@pytest.mark.parametrize("name,seed", [("office", None), (None, 2)])
def test_potential_gradient_and_hessian_match_the_field_and_finite_differences(name, seed):
    """``potential_gradient`` is ``grad phi_O`` (parallel to ``-Upsilon``, the logistic only
    scales it) and ``potential_hessian`` its exact Jacobian."""
    world = _world(name, seed)
    rng = np.random.default_rng(4)
    field = _field(world, rng)
    pts = random_free_points(world, 200, rng, margin=0.02)
    ev = field.evaluate(pts)
    ok = ~ev.degenerate
    g = ev.potential_gradient[ok]
    cos = -np.einsum("ni,ni->n", g, ev.field[ok]) / (np.linalg.norm(g, axis=1) * np.linalg.norm(ev.field[ok], axis=1))
    assert np.all(cos > 1 - 1e-9)
    h = 1e-6
    fd = np.stack([(field.evaluate(pts + e).potential_gradient - field.evaluate(pts - e).potential_gradient) / (2 * h)
                   for e in np.eye(2) * h], axis=2)
    H = ev.potential_hessian
    assert np.allclose(H, np.swapaxes(H, 1, 2))
    err = np.abs(fd - H).max(axis=(1, 2)) / (np.abs(H).max(axis=(1, 2)) + 1e-12)
    assert np.median(err[ok]) < 1e-6 and np.mean(err[ok] < 1e-4) > 0.97, f"max relative error {err[ok].max():.2e}"
