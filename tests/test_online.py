"""navigation.online: a versioned world whose navigation functions, after any sequence of
changes, equal the ones built from scratch (issue 6 item 1, paper 001 section 4.2.2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from navigation import NavigationFunction, build_forest
from navigation.errors import ForestError, WorldError
from navigation.forest import clear_cache
from navigation.geometry import Squircle
from navigation.online import OnlineWorld

from .worldgen import random_forest_world

WS = Squircle((5.0, 5.0), 10.0, 10.0, 0.0, 0.99)


def _free_points(forest, n, rng):
    """Random points of the forest's free space (its obstacles are already inflated)."""
    lo, hi = np.array(forest.workspace.center) - 0.5 * np.array([forest.workspace.width, forest.workspace.height]), \
        np.array(forest.workspace.center) + 0.5 * np.array([forest.workspace.width, forest.workspace.height])
    out = []
    while len(out) < n:
        q = rng.uniform(lo, hi, size=(4 * n, 2))
        ok = forest.workspace.beta(q) < -1e-3
        for o in forest.obstacles:
            ok &= o.beta(q) > 1e-3
        out.extend(q[ok])
    return np.array(out[:n])


def _scratch(ow: OnlineWorld, goal):
    """The navigation function built from nothing (memo cleared) for ``ow``'s current obstacles."""
    clear_cache()
    r = ow.inflation
    ws = ow.workspace.grow(-r) if r else ow.workspace
    obs = [ow.obstacles[k].grow(r) if r else ow.obstacles[k] for k in ow.ids]
    return NavigationFunction(build_forest(ws, obs), goal)


@pytest.mark.parametrize("seed", range(8))
def test_incremental_equals_scratch_after_random_changes(seed):
    rng = np.random.default_rng(seed)
    world = random_forest_world(seed, n_obstacles=10, max_depth=3)
    pool = list(world.obstacles)
    goal = list(world.regions.values())[0].center
    clear_cache()
    ow = OnlineWorld(world.workspace, {k: pool[k] for k in range(3)})
    next_id = 3
    compared = 0
    for _ in range(7):
        op = rng.integers(4)
        ids = ow.ids
        try:
            if op <= 1 and next_id < len(pool):  # discover (add) the next obstacle
                ow.apply(added={next_id: pool[next_id]})
                next_id += 1
            elif op == 2 and len(ids) > 1:  # remove one
                ow.apply(removed=[ids[int(rng.integers(len(ids)))]])
            else:  # refine one estimate: shift and grow it slightly
                k = ids[int(rng.integers(len(ids)))]
                o = ow.obstacles[k]
                ow.apply(updated={k: Squircle(tuple(np.add(o.center, rng.normal(scale=0.01, size=2))),
                                              o.width * 1.01, o.height, o.theta, o.s)})
        except ForestError:
            continue  # refused changes leave the world as it was (tested below)
        nf = ow.navigation_function(goal)
        q = _free_points(nf.forest, 200, rng)
        inc = nf.evaluate(q, 1)
        ref = _scratch(ow, goal).evaluate(q, 1)
        # the scratch build cleared the memo; rebuild the warm state the next change starts from
        ow._forest = ow._build(ow.obstacles)
        assert np.allclose(inc.value, ref.value, rtol=1e-9, atol=1e-12)
        scale = np.maximum(np.linalg.norm(ref.gradient, axis=1, keepdims=True), 1e-12)
        assert np.all(np.abs(inc.gradient - ref.gradient) <= 1e-9 * scale + 1e-12)
        compared += 1
    assert compared >= 3


def test_kinds_and_k_increment():
    ow = OnlineWorld(WS)
    a = Squircle((3.0, 3.0), 1.0, 0.2, 0.0, 0.99)
    ch = ow.apply(added={1: a})
    assert ch.kinds == ((1, "star"),) and ch.version == 1
    k1 = ow.navigation_function((8.0, 8.0)).params.K
    ch = ow.apply(added={2: Squircle((7.0, 7.0), 0.5, 0.5, 0.0, 0.0)})
    assert ch.kinds == ((2, "star"),)
    assert ow.navigation_function((8.0, 8.0)).params.K == k1 + 1  # a new star raises K (eq. 39)
    ch = ow.apply(added={3: Squircle((3.4, 3.3), 0.2, 0.8, 0.0, 0.99)})  # overlaps a: a new leaf
    assert ch.kinds == ((3, "leaf"),)
    assert ow.navigation_function((8.0, 8.0)).params.K == k1 + 1
    ch = ow.apply(added={4: Squircle((9.9, 5.0), 0.6, 0.4, 0.0, 0.99)})  # crosses the boundary
    assert ch.kinds == ((4, "leaf"),)
    ch = ow.apply(added={5: Squircle((3.0, 3.0), 0.5, 0.1, 0.0, 0.99)})  # inside a
    assert ch.kinds == ((5, "dropped"),)


def test_refused_change_keeps_the_previous_version():
    ow = OnlineWorld(WS, {0: Squircle((3.0, 5.0), 2.0, 0.2, 0.0, 0.99)})
    before = (ow.version, ow.forest, ow.ids)
    nf = ow.navigation_function((8.0, 8.0))
    with pytest.raises(ForestError):  # 0.5 mm from obstacle 0 without overlapping it
        ow.apply(added={1: Squircle((3.0, 5.2005), 2.0, 0.2, 0.0, 0.99)})
    assert (ow.version, ow.forest, ow.ids) == before
    assert ow.navigation_function((8.0, 8.0)) is nf


@pytest.mark.parametrize("kwargs, field", [
    ({"removed": [9]}, "removed"),
    ({"updated": {9: WS}}, "updated"),
    ({"added": {0: WS}}, "added"),
    ({"added": {"a": WS}}, "id"),
    ({"added": {2: "not a squircle"}}, "obstacles"),
])
def test_bad_changes_are_refused_by_name(kwargs, field):
    ow = OnlineWorld(WS, {0: Squircle((3.0, 5.0), 2.0, 0.2, 0.0, 0.99)})
    with pytest.raises(WorldError) as err:
        ow.apply(**kwargs)
    assert err.value.field == field
    assert ow.version == 0


def test_apply_update_takes_a_perception_map_update():
    @dataclass
    class Update:  # the fields of perception.MapUpdate that matter
        added: tuple = ()
        updated: tuple = ()
        removed: tuple = ()

    est = {4: Squircle((3.0, 3.0), 1.0, 0.2, 0.0, 0.99), 6: Squircle((7.0, 7.0), 0.5, 0.5, 0.0, 0.0)}
    ow = OnlineWorld(WS, inflation=0.1)
    ch = ow.apply_update(Update(added=(4, 6)), est)
    assert ch.added == (4, 6) and ow.ids == (4, 6)
    assert ow.forest.obstacles[0] == est[4].grow(0.1)
    ch = ow.apply_update(Update(removed=(4,)), est)
    assert ow.ids == (6,) and ch.version == 2
    with pytest.raises(WorldError):
        ow.apply_update(Update(added=(5,)), est)


def test_inflation_is_validated():
    with pytest.raises(WorldError):
        OnlineWorld(WS, inflation=-0.1)
    with pytest.raises(WorldError):
        OnlineWorld(WS, inflation=6.0)


def test_doctests():
    import doctest

    import navigation.online as online

    failed, attempted = doctest.testmod(online)
    assert attempted > 0 and failed == 0


def test_benchmark_quick_run(tmp_path, capsys):
    import json

    from benchmarks import online as bench

    assert bench.main(["--quick", "--sizes", "5", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "online.json").read_text())
    (row,) = data["worlds"]
    assert row["n_obstacles"] == 5 and row["samples"] >= 1
    assert row["update"] > 0 and row["rebuild"] > 0
    assert "| random5 | 5 |" in capsys.readouterr().out
