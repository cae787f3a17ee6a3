"""Guarantee: the chain ``Phi`` is a diffeomorphism of free space onto the point world that
sends every boundary where it must go.

* Points ``1e-5 .. 1e-7`` m outside an obstacle of an interior tree map next to that tree's point
  obstacle ``P_j`` (the nearest of all ``P``), closer and closer as the offset shrinks; points
  next to an obstacle of a tree attached to the workspace, or next to the workspace boundary,
  map far away, farther and farther (the workspace boundary goes to infinity).
* ``phi_NF -> mu`` on every boundary.
* ``det dPhi > 0`` at every sampled free point (orientation-preserving, nonsingular), for the
  whole chain and for every stage.
* Each stage is the identity (value, Jacobian and second derivatives) away from its obstacles:
  a purge stage farther than the shell width from every leaf it purges, the star-to-sphere
  stage farther than the shell width from every root.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import navigation
from navigation import NavigationFunction

from .conftest import world_file
from .worldgen import random_forest_world, random_free_points

SHARED_WORLDS = ("simple", "office", "cluttered20")
RANDOM_SEEDS = tuple(range(10))
SLOW_RANDOM_SEEDS = tuple(range(50))
OFFSETS = (1e-5, 1e-6, 1e-7)  # m outside each boundary, decreasing
N_FREE = 2000


@functools.lru_cache(maxsize=None)
def _world(kind: str, key):
    if kind == "hanging":  # a wall hanging from the boundary, ``key`` m above the opposite side
        from .test_convergence import _hanging_wall_world

        return _hanging_wall_world(key)
    return navigation.load_world(world_file(key)) if kind == "shared" else random_forest_world(key)


@functools.lru_cache(maxsize=None)
def _nf(kind: str, key) -> NavigationFunction:
    w = _world(kind, key)
    return NavigationFunction(w, list(w.regions.values())[0].center)


WORLD_CASES = ([("shared", n) for n in SHARED_WORLDS] + [("random", s) for s in RANDOM_SEEDS]
               + [("hanging", 0.4)])
WORLD_IDS = [f"{k}-{v}" for k, v in WORLD_CASES]


def approach(nf: NavigationFunction, sq, sign: float, n: int = 64):
    """Points at ``OFFSETS`` along the normal on the free side of boundary ``sq`` (sign +1 for
    an obstacle, -1 for the workspace), kept where all of them are free: ``(len(OFFSETS), K, 2)``."""
    b = sq.boundary_points(n)
    normal = sq.gradient(b)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    q = np.stack([b + sign * d * normal for d in OFFSETS])
    keep = np.all([nf.is_free(p) for p in q], axis=0)
    return q[:, keep]


def boundaries(nf: NavigationFunction):
    """``(label, squircle, sign, tree)`` for the workspace (tree -1) and every obstacle."""
    f = nf.forest
    yield "workspace boundary", f.workspace, -1.0, -1
    for i, o in enumerate(f.obstacles):
        yield f"obstacle {i} (input #{f.source_index[i]})", o, 1.0, f.tree_of[i]


# ---------------------------------------------------------------------- boundaries
def check_boundaries_to_points(nf: NavigationFunction, name: str) -> None:
    P = nf.point_obstacles
    c0 = np.asarray(nf.forest.workspace.center, dtype=float)
    checked = 0
    for label, sq, sign, tree in boundaries(nf):
        q = approach(nf, sq, sign)
        if q.shape[1] == 0:
            continue
        checked += 1
        x = np.stack([nf.transform(p)[0] for p in q])  # (offsets, K, 2)
        where = f"{name}, {label}"
        if tree >= 0:
            d = np.linalg.norm(x - P[tree], axis=2)
            nearest = np.argmin(np.linalg.norm(x[-1][:, None, :] - P[None], axis=2), axis=1)
            assert np.all(nearest == tree), f"{where}: maps nearer to another point obstacle than P_{tree}"
            shrink = d[1:] / d[:-1]
            i = np.unravel_index(np.argmax(shrink), shrink.shape)
            assert np.all(shrink < 0.5), (f"{where}: distance to P_{tree} does not shrink with the offset "
                                          f"(ratio {shrink[i]:.3g} at q={q[i[0] + 1, i[1]].tolist()})")
            assert np.all(d[-1] < 1e-3), (f"{where}: at {OFFSETS[-1]:g} m the image is still "
                                          f"{d[-1].max():.3g} from P_{tree}")
        else:
            r = np.linalg.norm(x - c0, axis=2)
            grow = r[1:] / r[:-1]
            i = np.unravel_index(np.argmin(grow), grow.shape)
            assert np.all(grow > 2.0), (f"{where}: |Phi(q)| does not grow as the offset shrinks "
                                        f"(ratio {grow[i]:.3g} at q={q[i[0] + 1, i[1]].tolist()})")
            assert np.all(r[-1] > 1e4), f"{where}: at {OFFSETS[-1]:g} m |Phi(q)| is only {r[-1].min():.3g}"
    assert checked == len(nf.forest.obstacles) + 1


@pytest.mark.parametrize(("kind", "key"), WORLD_CASES, ids=WORLD_IDS)
def test_boundaries_map_to_points_or_infinity(kind, key):
    check_boundaries_to_points(_nf(kind, key), f"{kind} {key}")


@pytest.mark.slow
@pytest.mark.parametrize("seed", SLOW_RANDOM_SEEDS)
def test_boundaries_map_to_points_or_infinity_many(seed):
    check_boundaries_to_points(_nf("random", seed), f"random {seed}")


def _boundary_values(nf: NavigationFunction):
    for label, sq, sign, _ in boundaries(nf):
        q = approach(nf, sq, sign)
        if q.shape[1]:
            yield label, q, np.stack([nf.value(p) for p in q])


@pytest.mark.parametrize(("kind", "key"), WORLD_CASES, ids=WORLD_IDS)
def test_value_tends_to_mu_on_every_boundary(kind, key):
    """The value increases towards ``mu`` as the offset shrinks (strictly, at every sample)."""
    nf = _nf(kind, key)
    mu = nf.params.mu
    for label, q, v in _boundary_values(nf):
        assert np.all(v <= mu)
        rising = np.diff(v, axis=0) > 0
        assert rising.all(), f"{label}: value does not increase towards the boundary at {q[1:][~rising][:3].tolist()}"
        gap_ratio = (mu - v[-1]) / (mu - v[0])
        assert np.all(gap_ratio < 1.0)


_SLOW_NEAR_MU = {("shared", "office"), ("shared", "cluttered20")} | {("random", s) for s in (0, 2, 3, 4, 7, 8, 9)}
_NEAR_MU_XFAIL = pytest.mark.xfail(strict=False, reason=(
    "conditioning target beyond the checks of issue 2 (known limitation): next to chained walls the "
    "chain amplifies normal distances "
    "(docs/navigation.md), so the value approaches mu slowly (e.g. 0.94, 0.97, 0.987 at 1e-5, 1e-6, "
    "1e-7 m); the limit itself is checked by test_value_tends_to_mu_on_every_boundary"))


@pytest.mark.parametrize(("kind", "key"), [pytest.param(*c, id=i, marks=[_NEAR_MU_XFAIL] if c in _SLOW_NEAR_MU else [])
                                           for c, i in zip(WORLD_CASES, WORLD_IDS)])
def test_value_near_mu_next_to_every_boundary(kind, key):
    """``value >= mu (1 - 1e-3)`` at 1e-7 m from every boundary (a conditioning target). An
    expected failure on the worlds where the chain's conditioning next to chained walls misses it
    (``_SLOW_NEAR_MU``); a guarantee on the others (``simple``, random seeds 1, 5 and 6, the
    hanging wall)."""
    nf = _nf(kind, key)
    mu = nf.params.mu
    failures = []
    for label, q, v in _boundary_values(nf):
        low = v[-1] < mu * (1 - 1e-3)
        if low.any():
            k = int(np.argmin(v[-1]))
            failures.append(f"{label}: {low.sum()} of {len(low)} samples, lowest value {v[-1][k]:.6f} "
                            f"at q={q[-1][k].tolist()} (values at offsets {OFFSETS}: {v[:, k].round(6).tolist()})")
    assert not failures, (f"{kind} {key} (K={nf.params.K}, {len(nf.forest.roots)} trees): value below "
                          f"mu (1 - 1e-3) at {OFFSETS[-1]:g} m from\n  " + "\n  ".join(failures))


# ---------------------------------------------------------------------- nonsingular Jacobian
def check_jacobian_determinant(world, nf: NavigationFunction, seed: int) -> None:
    q = random_free_points(world, N_FREE, np.random.default_rng([seed, 0xD1FF]))
    _, J, _ = nf.transform(q, 1)
    det = np.linalg.det(J)
    bad = ~(det > 0)
    assert not bad.any(), (f"{world.name}: det dPhi <= 0 (or NaN) at {bad.sum()} of {len(q)} free points, "
                           f"e.g. {q[bad][:3].tolist()} det={det[bad][:3].tolist()}")
    x = q
    for k, stage in enumerate(nf.chain.stages):
        y, Js, _ = stage(x, 1)
        det = np.linalg.det(Js)
        bad = ~(det > 0)
        assert not bad.any(), (f"{world.name}: stage {k} ({stage.name}) has det <= 0 at {bad.sum()} points, "
                               f"e.g. q={q[bad][:3].tolist()} det={det[bad][:3].tolist()}")
        x = y


@pytest.mark.parametrize(("kind", "key"), WORLD_CASES, ids=WORLD_IDS)
def test_jacobian_nonsingular(kind, key):
    check_jacobian_determinant(_world(kind, key), _nf(kind, key), seed=WORLD_CASES.index((kind, key)))


@pytest.mark.slow
@pytest.mark.parametrize("seed", SLOW_RANDOM_SEEDS)
def test_jacobian_nonsingular_many(seed):
    check_jacobian_determinant(_world("random", seed), _nf("random", seed), seed=seed)


# ---------------------------------------------------------------------- identity away from obstacles
def check_identity_away(world, nf: NavigationFunction, seed: int) -> None:
    f, p = nf.forest, nf.params
    stages = nf.chain.stages
    levels = f.levels()
    names = [s.name for s in stages]
    assert names[:len(levels)] == ["purge"] * len(levels) and names[len(levels)] == "star_to_sphere", names
    # each purge stage acts on the obstacles of its level, star-to-sphere on the roots
    acts_on = [(list(level), [p.purge_width[i] for i in level]) for level in levels]
    acts_on.append((list(f.roots), list(p.root_width)))
    rng = np.random.default_rng([seed, 0x1D])
    q = random_free_points(world, N_FREE, rng)
    x = q
    for k, (members, widths) in enumerate(acts_on):
        stage = stages[k]
        y, J, H = stage(x, 2)
        far = np.ones(len(x), dtype=bool)
        for i, w in zip(members, widths):
            assert w > 0 and math.isfinite(w)
            far &= f.obstacles[i].distance(x) > w * (1 + 1e-9)
        label = f"{world.name} stage {k} ({stage.name})"
        assert far.any(), f"{label}: no sample point away from its obstacles (test is vacuous)"
        moved = np.any(y[far] != x[far], axis=1)
        assert not moved.any(), (f"{label}: moves {moved.sum()} points that are farther than the shell width "
                                 f"from every obstacle it acts on, e.g. x={x[far][moved][:3].tolist()} -> "
                                 f"{y[far][moved][:3].tolist()}")
        np.testing.assert_array_equal(J[far], np.broadcast_to(np.eye(2), J[far].shape), err_msg=label)
        np.testing.assert_array_equal(H[far], 0.0, err_msg=label)
        x = y


@pytest.mark.parametrize(("kind", "key"), WORLD_CASES, ids=WORLD_IDS)
def test_stages_are_identity_away_from_their_obstacles(kind, key):
    check_identity_away(_world(kind, key), _nf(kind, key), seed=7)


def test_purge_stage_moves_only_its_shell():
    """One leaf (``simple``): the purge stage is the identity beyond the leaf's shell width and
    moves points inside it."""
    nf = _nf("shared", "simple")
    f, p = nf.forest, nf.params
    stage = nf.chain.stages[0]
    (leaf,) = f.levels()[0]
    rng = np.random.default_rng(0)
    q = random_free_points(_world("shared", "simple"), 500, rng)
    far = f.obstacles[leaf].distance(q) > p.purge_width[leaf]
    y, J, _ = stage(q[far], 1)
    np.testing.assert_array_equal(y, q[far])
    np.testing.assert_array_equal(J, np.broadcast_to(np.eye(2), J.shape))
    # and points inside the shell of a protruding leaf do move
    near = ~far
    assert near.any()
    assert np.any(np.any(stage(q[near], 0)[0] != q[near], axis=1))


def test_point_world_images():
    """``P_j`` are distinct and finite, ``P_G`` is the goal's image and differs from every ``P_j``."""
    for kind, key in WORLD_CASES[:3]:
        nf = _nf(kind, key)
        P, G = nf.point_obstacles, nf.goal_image
        assert P.shape == (len(nf.forest.roots), 2) and np.all(np.isfinite(P))
        np.testing.assert_allclose(nf.transform(nf.goal)[0][0], G, rtol=1e-12, atol=1e-12)
        d = np.linalg.norm(P[:, None] - P[None], axis=2) + np.eye(len(P))
        assert np.all(d > 0)
        assert np.all(np.linalg.norm(P - G, axis=1) > 0)
