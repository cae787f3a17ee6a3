"""Guarantee: the analytic derivatives are the derivatives of the values.

Checked against a reference built from values only: Richardson-extrapolated central
differences, ``D4(h) = (4 D(h/2) - D(h)) / 3`` with ``D(h) = (f(q + h e) - f(q - h e)) / 2h``
(error ``O(h^4)``). The fields are steep near obstacles and, near the corners where a leaf's
boundary crosses its parent's, vary on the scale of the distance to the nearest boundary, so the
step is ``h = min(1e-6 max(1, |q|_inf), 1e-3 c)`` with ``c`` the exact clearance of the (original,
workspace) point: ``1e-6`` m in the open, smaller where the field has finer structure. (With
``h = 1e-6`` alone the *reference* is wrong at points a few micrometres from such a corner: there
Richardson at ``h = 1e-6`` is off by tens of percent while ``h = 1e-8`` agrees with the analytic
gradient to 1e-6.)

Checked:

* ``phi_NF``: value -> gradient and gradient -> Hessian, on every shared world (three goals,
  the centres of its first regions) and on random forest worlds; relative error = max abs error
  over the components / max abs component of the analytic quantity, at most ``1e-5`` at every
  sampled point where the field is not saturated (``value < mu (1 - 1e-6)``);
* every stage of ``nf.chain`` on its own domain (points mapped through the previous stages;
  the clearance ``c`` of the step rule is then the distance to the boundary of that domain):
  Jacobian (relative, as above) and second derivatives (error relative to
  ``max|H| + max|J| / 1 m``: the second derivatives vanish where a stage is affine, e.g. at the
  edge of its shells, so a purely relative error would measure rounding noise there);
* the chain rule: the composition of the stage values, Jacobians and second derivatives equals
  ``nf.transform``.

Sample points: uniform free points plus points ``1e-4 .. 1e-1`` m outside every obstacle and
inside the workspace boundary (the steep part of the field).
"""

from __future__ import annotations


import numpy as np
import pytest

from navigation import NavigationFunction

from .conftest import random_world as _random, shared_world as _shared
from .worldgen import random_free_points

SHARED_WORLDS = ("simple", "office", "cluttered20")
RANDOM_SEEDS = tuple(range(10))
SLOW_RANDOM_SEEDS = tuple(range(50))
TOL = 1e-5  # relative error of an analytic derivative against the reference
SATURATED = 1e-6  # value >= mu (1 - SATURATED): the logistic is flat to rounding, skip
OFFSETS = (1e-4, 1e-3, 1e-2, 1e-1)  # distances outside the boundaries (m)
N_UNIFORM = 200


# ---------------------------------------------------------------------- helpers
def _goals(world, n: int = 3) -> list[tuple[float, float]]:
    return [r.center for r in list(world.regions.values())[:n]]


def clearance(forest, q: np.ndarray) -> np.ndarray:
    """Exact distance of free points ``q (N, 2)`` to the nearest boundary."""
    c = -forest.workspace.distance(q)
    for o in forest.obstacles:
        c = np.minimum(c, o.distance(q))
    return c


def near_boundary_points(forest, offsets=OFFSETS, per_boundary: int = 32) -> np.ndarray:
    """Free points at the given distances (along the normal) outside every obstacle boundary
    and inside the workspace boundary."""
    out = []
    for sq, sign in [(forest.workspace, -1.0)] + [(o, 1.0) for o in forest.obstacles]:
        b = sq.boundary_points(per_boundary)
        n = sq.gradient(b)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        out.extend(b + sign * d * n for d in offsets)
    q = np.concatenate(out)
    free = q[forest.workspace.beta(q) < 0]
    for o in forest.obstacles:
        free = free[o.beta(free) > 0]
    return free


def sample_points(world, seed: int) -> np.ndarray:
    rng = np.random.default_rng([seed, 0x1AC0])  # not the stream that placed the world's regions
    return np.concatenate((random_free_points(world, N_UNIFORM, rng), near_boundary_points(world.forest(0.0))))


def fd_steps(q: np.ndarray, clear: np.ndarray) -> np.ndarray:
    """Per-point steps: ``1e-6`` scaled by ``max(1, |q|)``, at most ``1e-3`` of the clearance."""
    return np.minimum(1e-6 * np.maximum(1.0, np.abs(q).max(axis=1)), 1e-3 * clear)


def richardson(f, q: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Derivative of ``f: (N, 2) -> (N, ...)`` at ``q``, shape ``(N, ..., 2)`` (last axis: d/dq_j)."""
    cols = []
    for j in range(2):
        e = np.zeros_like(q)
        e[:, j] = 1.0

        def central(step):
            diff = f(q + step[:, None] * e) - f(q - step[:, None] * e)
            return diff / (2.0 * step.reshape((-1,) + (1,) * (diff.ndim - 1)))

        cols.append((4.0 * central(0.5 * h) - central(h)) / 3.0)
    return np.stack(cols, axis=-1)


def _maxabs(a: np.ndarray) -> np.ndarray:
    return np.abs(a).reshape(len(a), -1).max(axis=1)


def relative_error(analytic: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per point: max abs error / max abs analytic component."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return _maxabs(analytic - reference) / _maxabs(analytic)


def _report(label: str, q: np.ndarray, err: np.ndarray, extra: dict, limit: int = 8) -> str:
    bad = np.nonzero(~(err <= TOL))[0]
    bad = bad[np.argsort(-np.nan_to_num(err[bad], nan=np.inf))][:limit]
    lines = [f"{label}: {np.count_nonzero(~(err <= TOL))} of {len(err)} points above {TOL:g} "
             f"(max {np.nanmax(err):.3e}); worst:"]
    for i in bad:
        more = ", ".join(f"{k}={np.asarray(v[i]).tolist()}" for k, v in extra.items())
        lines.append(f"  q={q[i].tolist()} rel.err={err[i]:.3e} {more}")
    return "\n".join(lines)


def check_navigation_derivatives(world, goal, seed: int) -> None:
    """value -> gradient and gradient -> Hessian at every unsaturated sample point."""
    nf = NavigationFunction(world, goal)
    q = sample_points(world, seed)
    ev = nf.evaluate(q, 2)
    assert ev.free.all()
    keep = (ev.value < nf.params.mu * (1.0 - SATURATED)) & np.any(q != nf.goal, axis=1)
    # the samples reach into the steep part of the field: most of them must be checked
    assert keep.mean() > 0.5, f"only {keep.sum()} of {len(q)} sample points are unsaturated"
    q, value, grad, hess = q[keep], ev.value[keep], ev.gradient[keep], ev.hessian[keep]
    h = fd_steps(q, clearance(nf.forest, q))
    err_g = relative_error(grad, richardson(nf.value, q, h))
    err_h = relative_error(hess, richardson(nf.gradient, q, h))
    info = {"value": value, "h": h}
    assert np.all(err_g <= TOL), _report(f"{world.name} goal {goal}: gradient vs FD of value", q, err_g,
                                         {**info, "gradient": grad})
    assert np.all(err_h <= TOL), _report(f"{world.name} goal {goal}: Hessian vs FD of gradient", q, err_h,
                                         {**info, "hessian": hess})


def stage_clearances(nf):
    """For each stage of ``nf.chain``, a function giving the exact distance of points of its
    domain to the domain's boundary.

    The domain of a stage is the image of free space under the previous stages: purging level
    ``k`` (deepest first) acts on the workspace minus the obstacles not purged yet (depth <= that
    level's depth), star-to-sphere on the workspace minus the roots, sphere-to-point on the
    workspace minus the discs ``(centre of root j, rho_j)``.
    """
    f, stages = nf.forest, nf.chain.stages
    names = [s.name for s in stages]
    levels = f.levels()
    assert names == ["purge"] * len(levels) + ["star_to_sphere", "sphere_to_point"], names
    depth = np.asarray(f.depth)

    def squircles(present):
        def clear(x):
            c = -f.workspace.distance(x)
            for i in np.nonzero(present)[0]:
                c = np.minimum(c, f.obstacles[i].distance(x))
            return c
        return clear

    out = [squircles(depth <= depth[level[0]]) for level in levels]
    out.append(squircles(depth == 0))
    centres = np.array([f.obstacles[j].center for j in f.roots]).reshape(-1, 2)
    rho = np.asarray(nf.params.rho, dtype=float)

    def discs(x):
        c = -f.workspace.distance(x)
        for cj, rj in zip(centres, rho):
            c = np.minimum(c, np.linalg.norm(x - cj, axis=1) - rj)
        return c

    out.append(discs)
    return out


def check_stages(world, seed: int) -> None:
    """Each stage's derivatives against FD on its own domain, and the chain rule."""
    nf = NavigationFunction(world, _goals(world, 1)[0])
    q = sample_points(world, seed)
    x = q
    J_acc = np.broadcast_to(np.eye(2), (len(q), 2, 2)).copy()
    H_acc = np.zeros((len(q), 2, 2, 2))
    for k, (stage, clear) in enumerate(zip(nf.chain.stages, stage_clearances(nf))):
        y, J, H = stage(x, 2)
        assert y.shape == x.shape and J.shape == (len(x), 2, 2) and H.shape == (len(x), 2, 2, 2)
        assert np.all(np.isfinite(y)) and np.all(np.isfinite(J)) and np.all(np.isfinite(H)), \
            f"stage {k} ({stage.name}) is not finite on its domain"
        c = clear(x)
        assert np.all(c > 0), f"stage {k} ({stage.name}): points mapped outside its domain"
        h = fd_steps(x, c)
        label = f"{world.name} stage {k} ({stage.name})"
        err_j = relative_error(J, richardson(lambda p: stage(p, 0)[0], x, h))
        assert np.all(err_j <= TOL), _report(f"{label}: Jacobian vs FD of values", q, err_j,
                                             {"x": x, "J": J, "h": h})
        with np.errstate(divide="ignore", invalid="ignore"):
            err_h = _maxabs(H - richardson(lambda p: stage(p, 1)[1], x, h)) / (_maxabs(H) + _maxabs(J))
        assert np.all(err_h <= TOL), _report(f"{label}: second derivatives vs FD of Jacobian", q, err_h,
                                             {"x": x, "H": H, "h": h})
        # chain rule, second order: d2(f o g) = d2f[dg, dg] + df d2g
        H_acc = np.einsum("niab,naj,nbk->nijk", H, J_acc, J_acc) + np.einsum("nia,najk->nijk", J, H_acc)
        J_acc = J @ J_acc
        x = y
    x_chain, J_chain, H_chain = nf.transform(q, 2)
    np.testing.assert_allclose(x, x_chain, rtol=1e-12, atol=1e-12)
    err = relative_error(J_chain, J_acc)
    assert np.all(err <= 1e-9), _report(f"{world.name}: product of stage Jacobians vs nf.transform", q, err,
                                        {"J": J_chain})
    err = relative_error(H_chain, H_acc)
    assert np.all(err <= 1e-9), _report(f"{world.name}: composed second derivatives vs nf.transform", q, err,
                                        {"H": H_chain})


# ---------------------------------------------------------------------- the navigation function
@pytest.mark.parametrize("name", SHARED_WORLDS)
@pytest.mark.parametrize("goal_index", range(3))
def test_navigation_derivatives_shared_world(name, goal_index):
    world = _shared(name)
    check_navigation_derivatives(world, _goals(world)[goal_index], seed=goal_index)


@pytest.mark.parametrize("seed", RANDOM_SEEDS)
def test_navigation_derivatives_random_world(seed):
    world = _random(seed)
    for k, goal in enumerate(_goals(world)):
        check_navigation_derivatives(world, goal, seed=1000 * seed + k)


@pytest.mark.slow
@pytest.mark.parametrize("seed", SLOW_RANDOM_SEEDS)
def test_navigation_derivatives_random_world_many(seed):
    world = _random(seed)
    for k, goal in enumerate(_goals(world)):
        check_navigation_derivatives(world, goal, seed=1000 * seed + k)


def test_derivatives_near_the_goal():
    """At and around the goal (value ~ 0, gradient ~ 0) the derivatives are still exact."""
    world = _shared("office")
    goal = np.array(_goals(world, 1)[0])
    nf = NavigationFunction(world, goal)
    rng = np.random.default_rng(5)
    r = np.array([1e-5, 1e-4, 1e-3, 1e-2])[:, None]
    u = rng.normal(size=(4, 2))
    q = goal + r * u / np.linalg.norm(u, axis=1, keepdims=True)
    ev = nf.evaluate(q, 2)
    h = fd_steps(q, clearance(nf.forest, q))
    assert np.all(relative_error(ev.gradient, richardson(nf.value, q, h)) <= TOL)
    assert np.all(relative_error(ev.hessian, richardson(nf.gradient, q, h)) <= TOL)
    at = nf.evaluate(goal, 2)
    assert at.value[0] == 0.0 and np.all(at.gradient == 0.0)
    assert np.all(np.linalg.eigvalsh(at.hessian[0]) > 0), "the goal is a non-degenerate minimum"


# ---------------------------------------------------------------------- the stages of the chain
@pytest.mark.parametrize("name", SHARED_WORLDS)
def test_stage_derivatives_shared_world(name):
    check_stages(_shared(name), seed=7)


@pytest.mark.parametrize("seed", RANDOM_SEEDS)
def test_stage_derivatives_random_world(seed):
    check_stages(_random(seed), seed=seed)


@pytest.mark.slow
@pytest.mark.parametrize("seed", SLOW_RANDOM_SEEDS)
def test_stage_derivatives_random_world_many(seed):
    check_stages(_random(seed), seed=seed)


# ---------------------------------------------------------------------- fast paths = reference
def _reference_purge(stage, x, y):
    """The purge map of eq. (13-19) written out plainly: every candidate pair goes through the
    jet solve (``ray_length_jet``) and both switches, however small."""
    from navigation._jet import Jet
    from navigation.geometry import ray_length_jet
    from navigation.transforms import _eta, _pairs, _polar

    n, k = _pairs(x, y, stage.leaf, stage.width * 1.0001)
    if len(n) == 0:
        return x, y
    c = stage.centre[k]
    r, ux, uy = _polar(x[n], y[n], c)
    m = len(n)
    both = ray_length_jet(np.concatenate((stage.leaf[k], stage.parent[k])), np.concatenate((c, c)),
                          Jet(np.concatenate((ux.a, ux.a))), Jet(np.concatenate((uy.a, uy.a))),
                          entry=np.concatenate((np.zeros(m, dtype=bool), stage.parent_is_workspace[k])))
    r_leaf, r_par = both[:m], both[m:]
    e = r_leaf - r_par
    sigma = _eta(e / (r - r_par)) * (1.0 - _eta((r - r_leaf) * (1.0 / stage.width[k])))
    shift = e * sigma
    ax, ay = x.a.copy(), y.a.copy()
    np.add.at(ax, n, (-(shift * ux)).a)
    np.add.at(ay, n, (-(shift * uy)).a)
    return Jet(ax), Jet(ay)


@pytest.mark.parametrize("name", ["office", "cluttered20"])
def test_purge_shortcuts_match_the_plain_formula(name):
    """Purge stages skip pairs whose switch is exactly zero and solve once in plain floats; the
    result equals the plain formula (value, gradient, Hessian), point by point and in a batch."""
    from navigation._jet import Jet
    from navigation.transforms import PurgeStage

    world = _shared(name)
    nf = NavigationFunction(world, _goals(world, 1)[0])
    pts = random_free_points(world, 400, np.random.default_rng(4))
    for batch in (pts, *pts[:60, None, :]):
        x, y = Jet.variables(batch, 2)
        for st in nf.chain.stages:
            if not isinstance(st, PurgeStage):
                break
            fx, fy = st.apply(x, y)
            rx, ry = _reference_purge(st, x, y)
            np.testing.assert_allclose(fx.a, rx.a, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(fy.a, ry.a, rtol=1e-12, atol=1e-12)
            x, y = fx, fy
