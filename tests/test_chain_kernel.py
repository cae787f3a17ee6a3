"""Guarantee: the compiled second-order chain (``navigation._chain_kernel``, used by
``Chain.apply``) computes what the numpy jets of every stage compute, and the compiled oriented
field (``_chain_kernel.oriented``) what its numpy reference computes.

On every shared world and on random forest worlds, at uniform free points and at points
1e-4 .. 1e-1 m outside every obstacle and inside the workspace boundary (where the shells and
the psi map are steepest), the values, gradients and packed second derivatives of both
coordinates agree to 1e-12 relative to ``max(1, |component|)``; they are not bit-identical
everywhere (numba's ``hypot``, ``exp`` may differ from numpy's in the last bit). The
derivatives themselves are checked against finite differences in ``tests/test_jacobians.py``,
which now runs through the compiled path.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from navigation import NavigationFunction
from navigation._jet import Jet

from .conftest import random_world, shared_world
from .test_jacobians import sample_points


def _numpy_path(chain, x: Jet, y: Jet):
    for st in chain.stages:
        x, y = st.apply(x, y)
    return x, y


def _check(world, goal, seed: int) -> None:
    nf = NavigationFunction(world, goal=goal)
    q = sample_points(world, seed)
    x, y = Jet.variables(q, 2)
    with np.errstate(all="ignore"):  # points next to the workspace boundary overflow psi in both paths
        ref = np.concatenate([j.a for j in _numpy_path(nf.chain, x, y)], axis=1)
    got = np.concatenate([j.a for j in nf.chain._apply_compiled(x, y)], axis=1)
    assert got.shape == ref.shape == (len(q), 12)
    assert np.array_equal(np.isfinite(got), np.isfinite(ref))
    fin = np.isfinite(ref)
    err = np.abs(got[fin] - ref[fin]) / np.maximum(1.0, np.abs(ref[fin]))
    assert err.max(initial=0.0) <= 1e-12, f"max relative difference {err.max():.3g}"


@pytest.mark.parametrize("name", ["simple", "office"])
def test_compiled_chain_matches_numpy_jets_shared_world(name):
    world = shared_world(name)
    for goal in [r.center for r in list(world.regions.values())[:2]]:
        _check(world, goal, 0)


@pytest.mark.parametrize("seed", range(6))
def test_compiled_chain_matches_numpy_jets_random_world(seed):
    world = random_world(seed)
    _check(world, list(world.regions.values())[0].center, seed)


def test_chain_apply_gives_the_same_values_at_every_order():
    """Every order goes through the kernels (lower orders padded with zero derivatives), so the
    values are the same bits at orders 0, 1 and 2 and the gradients at orders 1 and 2 (the
    goal's image is computed at order 0, the renderer evaluates at order 1)."""
    world = shared_world("office")
    nf = NavigationFunction(world, goal=list(world.regions.values())[0].center)
    q = sample_points(world, 1)[:50]
    out = [nf.chain.apply(*Jet.variables(q, order)) for order in (0, 1, 2)]
    assert nf.chain._compiled[0] is not None  # the stages were packed once
    for k, (x, y) in enumerate(out):
        assert x.a.shape == y.a.shape == (len(q), (1, 3, 6)[k])
        np.testing.assert_array_equal(np.stack((x.v, y.v), 1), np.stack((out[2][0].v, out[2][1].v), 1))
    np.testing.assert_array_equal(out[1][0].g, out[2][0].g)
    np.testing.assert_array_equal(out[1][1].g, out[2][1].g)


@pytest.mark.parametrize("name", ["simple", "office", "random0", "random1", "random2"])
def test_compiled_oriented_field_matches_numpy(name, monkeypatch):
    """``OrientedField`` evaluated in the compiled kernel (``_chain_kernel.oriented``) equals
    the numpy reference (``_core_numpy``) to rounding at uniform free points and near the goal:
    values, field, Jacobian, directions and their gradients, the potential's derivatives; the
    free and degenerate flags exactly. The push-forward gradient solves ``dx'/dq``, whose
    condition number reaches 1e7 next to chained walls: there the two 2 x 2 solves (Cramer's
    rule, LAPACK's LU) differ by up to about 1e-8 relative, hence its looser bound. The two share
    the point-world potential's formulas (``_chain_kernel._potential``; its derivatives are
    checked against finite differences in ``tests/test_oriented.py``): what is compared here is
    the composition with the chain's jets, the logistic, the directions and their gradients."""
    from navigation import oriented
    from navigation.oriented import OrientedEval, OrientedField

    from .worldgen import random_forest_world, random_free_points

    # (random worlds with a gap that keeps them forests when grown by the robot radius)
    world = shared_world(name) if not name.startswith("random") else random_forest_world(int(name[6:]), gap=0.3)
    rng = np.random.default_rng(11)
    r = world.robot.radius
    for _ in range(2):
        goal = random_free_points(world, 1, rng, margin=r + 0.2)[0]
        of = OrientedField(NavigationFunction(world, goal=goal, inflation=r), heading=rng.uniform(-np.pi, np.pi))
        pts = np.concatenate([random_free_points(world, 200, rng, margin=1e-3),
                              goal + rng.normal(scale=1e-3, size=(10, 2)), goal + rng.normal(scale=0.05, size=(10, 2))])
        monkeypatch.setattr(oriented, "_COMPILED", False)
        ref = of.evaluate(pts)
        monkeypatch.setattr(oriented, "_COMPILED", True)
        got = of.evaluate(pts)
        for f in [fl.name for fl in dataclasses.fields(OrientedEval)]:
            a, b = np.asarray(getattr(ref, f)), np.asarray(getattr(got, f))
            assert a.shape == b.shape, f
            if a.dtype == bool:
                assert np.array_equal(a, b), f
                continue
            if f in ("angle", "flow_angle"):
                d = np.abs(np.remainder(a - b + np.pi, 2 * np.pi) - np.pi)
            else:
                d = np.abs(a - b) / np.maximum(1.0, np.abs(a))
            assert d.max() <= (1e-7 if f == "flow_gradient" else 1e-12), f"{f}: {d.max():.3g}"
