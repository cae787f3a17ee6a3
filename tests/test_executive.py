"""Missions end to end (issue 6 items 4-6): the executive in closed loop with the simulator and
perception completes the missions of the shared worlds and of random forest worlds with zero
collisions, every command finite and within the robot's limits; a walled-off region moves it to
``blocked`` (stopped, the region named); bad input is refused without a traceback.

Default run: ``simple``, ``office`` (with its urgent ``u1`` event at 60 s), ``cluttered20`` and
one random forest world; ``-m slow`` runs 60 random forest worlds (``tests/worldgen.py`` with
``gap=0.3``, seeds 0-59; 0-19 are the benchmarks' worlds, 20-59 were never used to tune
anything) with a visit-all mission over their 4 regions.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from navigation.clearance import forest_clearance
from navigation.control import UNLIMITED
from navigation.world import World
from perception import ObstacleMap
from service.sim import Simulator
from tamp.executive import Executive, ExecutiveConfig, ExecutiveState, reachable_speed
from tamp.harmonic_tree import NoTreePathError, TreeFailure, plan_tree
from tamp.errors import LtlSyntaxError, TampError, UnknownRegionError
from tamp.run import main, run_mission

from .conftest import ROOT, shared_world, world_file
from .worldgen import random_forest_world

STATUS_FIELDS = {"stamp", "state", "task", "plan", "target", "waypoint", "obstacles", "message"}


def _check_run(r: dict) -> None:
    assert r["collisions"] == 0, r
    assert r["bad_commands"] == 0, r
    assert r["completed"], f"{r['world']}: state {r['state']} after {r['execution_time']:.0f} s: {r['message']}"


@pytest.mark.parametrize("name", ["simple", "office", "cluttered20"])
def test_shared_world_mission_completes_safely(name):
    world = shared_world(name)
    if name == "office":
        # the world file's urgent request (F u1) comes at 60 s, after the robot has finished
        # the rest of the mission (about 45 s): sent at 20 s it arrives mid-mission
        world = dataclasses.replace(world, events=tuple(dataclasses.replace(e, time=20.0) for e in world.events))
    r = run_mission(world, max_time=300)
    _check_run(r)
    if name == "office":
        # the urgent request is served
        assert "u1" in r["visited"], r["visited"]
        assert r["execution_time"] > 20.0
    assert r["replans"] >= 1 or name == "simple"


def _random_mission(seed: int):
    world = random_forest_world(seed, gap=0.3)
    return world, " & ".join(f"F {name}" for name in world.regions)


def _check_random(seed: int):
    world, task = _random_mission(seed)
    _check_run(run_mission(world, task, max_time=300))


@pytest.mark.parametrize("seed", [0])
def test_random_world_visit_all_completes_safely(seed):
    _check_random(seed)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(60))
def test_random_world_visit_all_completes_safely_full(seed):
    _check_random(seed)


def test_a_leg_from_a_region_runs_through_its_centre_when_the_tree_from_the_robot_is_longer():
    """Legs from a region (module doc): sweep world ``random698``, where the tree from the
    robot's position in ``r4`` to ``r2`` ran 4.5 m east through ``r3`` against 2.8 m from
    ``r4``'s centre; entering ``r3`` re-planned back through ``r4`` and the robot went
    between the two for 300 s. Through the centre it completes, short of its tour's 1.25 x."""
    world, task = _random_mission(698)
    r = run_mission(world, task, max_time=300)
    _check_run(r)
    assert set(r["visited"]) == set(world.regions) and r["execution_time"] < 100.0, r["visited"]
    assert r["distance"] < 9.0


def test_via_centre_is_the_robot_then_the_transition_tree_from_the_centre():
    """``Executive._via_centre``: ``None`` away from a region, without an evaluated tree, or
    when the tree from the robot is within the slack; else the robot's pose followed by the
    transition tree's waypoints from this region's centre (reversed, headings turned, when
    the tree runs from the other region)."""
    from types import SimpleNamespace

    from tamp.executive import VIA_CENTRE_SLACK

    world, task = _random_mission(0)
    ex = Executive(world, task, known=True)
    a, b = sorted(world.regions)[:2]
    ca, cb = world.regions[a].center, world.regions[b].center
    mid = ((ca[0] + cb[0]) / 2, (ca[1] + cb[1]) / 2 + 0.3)
    wps = np.array([(ca[0], ca[1], 0.1), (mid[0], mid[1], 0.2), (cb[0], cb[1], 0.3)])
    tree = SimpleNamespace(waypoints=wps, translations=np.hypot(*np.diff(wps[:, :2], axis=0).T))
    length = float(tree.translations.sum())
    p = (ca[0] + 0.1, ca[1], 0.0)
    long = SimpleNamespace(translations=np.array([length + 0.1 + VIA_CENTRE_SLACK + 0.05]))
    short = SimpleNamespace(translations=np.array([length + 0.1 + VIA_CENTRE_SLACK - 0.05]))
    ex._pair[(a, b)] = tree
    ex._at_region = None
    assert ex._via_centre(p, b, long) is None  # not at a region
    ex._at_region = a
    assert ex._via_centre(p, b, short) is None
    via = ex._via_centre(p, b, long)
    assert via[0] == p and np.allclose(via[1:], wps)
    none = NoTreePathError(p, wps[-1], TreeFailure.DISCONNECTED)
    assert np.allclose(ex._via_centre(p, b, none)[1:], wps)  # no tree from the robot
    ex._at_region = b  # driven backwards from b
    q = (cb[0], cb[1] - 0.1, 1.0)
    via = ex._via_centre(q, a, long)
    assert via[0] == q and np.allclose(np.array(via[1:])[:, :2], wps[::-1, :2])
    assert np.allclose([math.cos(v[2] - (w + math.pi)) for v, w in zip(via[1:], wps[::-1, 2])], 1.0)
    del ex._pair[(a, b)]
    assert ex._via_centre(q, a, long) is None  # no evaluated transition


def _noisy(world: World, sigma: float) -> World:
    return dataclasses.replace(world, lidar=dataclasses.replace(world.lidar, noise_std=sigma))


def _check_noisy(world: World, task, sigma: float) -> None:
    world = _noisy(world, sigma)
    assert Executive(world, task).omap.config.noise_std == sigma  # perception set up for the sensor
    _check_run(run_mission(world, task, max_time=300, seed=0))


@pytest.mark.parametrize("name,sigma", [("office", 0.01), ("random2", 0.02)])
def test_a_mission_with_a_noisy_lidar_completes_safely(name, sigma):
    """Every world file here has a noise-free lidar; with range noise (simulator seed 0) the
    same missions complete without touching anything (``benchmarks.executive --noise``)."""
    world, task = (shared_world(name), None) if name == "office" else _random_mission(int(name[6:]))
    _check_noisy(world, task, sigma)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [s for s in range(100, 160) if s != 103])
def test_a_mission_with_a_noisy_lidar_completes_safely_full(seed):
    # (random103 with 1 cm noise stops blocked: its only way to r1 is a passage 5 cm wider than
    # the robot that the noisy estimates close; docs/history.md, executive "Thirty-fifth session")
    _check_noisy(*_random_mission(seed), 0.01)


def test_a_region_behind_a_passage_the_noisy_estimates_close_is_reported_blocked_safely():
    """``random103`` with 1 cm noise: the estimates close the 0.31 m passage to ``r1`` (0.2 m
    robot); the robot looks, then stops ``blocked`` naming ``r1``, without a collision."""
    world, task = _random_mission(103)
    r = run_mission(_noisy(world, 0.01), task, max_time=120, seed=0)
    assert r["collisions"] == 0 and r["bad_commands"] == 0
    if not r["completed"]:  # (a better perception may one day resolve the passage)
        assert r["state"] == "blocked" and "r1" in r["message"], r["message"]


def test_a_sweep_world_whose_robot_once_stopped_blocked_for_good_completes():
    """``python -m benchmarks.executive --sweep`` found it (thirty-second session): on 103 no
    roadmap vertex saw through the passages out of a pocket (narrow passages); the gap search
    saved it until the roadmaps' snug inflation (thirty-seventh session), with which the
    vertices see through (the gap search keeps its tests: the slits here and in
    ``test_harmonic_tree.py``)."""
    world, task = _random_mission(103)
    r = run_mission(world, task, max_time=300)
    _check_run(r)


def test_a_region_under_a_cycle_merge_is_reached():
    """``random520`` (``--sweep``, thirty-second session): two bars seen from above close a
    cycle of estimates, and the forest repair merged them into one squircle over ``r1``, which
    lies under them (reachable: 2.33 m with every obstacle known). Going to look completed it
    from the thirty-second to the thirty-sixth session; with the snug inflation (thirty-seventh)
    its three looks all stayed above the cover and it stopped ``blocked`` naming ``r1``. Since
    the thirty-eighth session a repair's cover is trimmed clear of the region discs as a refit
    is (``perception.map``, "Clearances"): the robot completes, without collision or bad
    command."""
    world, task = _random_mission(520)
    r = run_mission(world, task, max_time=300)
    assert r["collisions"] == 0 and r["bad_commands"] == 0
    assert r["completed"], r["message"]


# ---------------------------------------------------------------------- blocked
def _corridor(gap: float) -> World:
    """A 4 x 1.5 m corridor cut by an (unknown) wall from the top that leaves ``gap`` at the
    bottom: region ``b`` is behind it. With ``gap = 0.24`` the robot (radius 0.1) fits in
    principle, but no harmonic tree keeps the safety buffer (0.15 m, fallback 0.03 m)."""
    top = 1.6
    h = top - gap
    return World.from_dict({
        "name": "walled", "workspace": {"center": [2.0, 0.75], "width": 4.0, "height": 1.5, "s": 0.99},
        "obstacles": [{"center": [2.6, gap + h / 2], "width": 0.2, "height": h, "s": 0.99}],
        "regions": {"a": {"center": [1.5, 0.75], "radius": 0.15}, "b": {"center": [3.5, 0.75], "radius": 0.15}},
        "robot": {"radius": 0.1, "start": [0.5, 0.75, 0.0], "v_max": 0.5, "omega_max": 1.5},
        "lidar": {"range": 1.5, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10},
        "task": "F a & F b"})


def test_walled_off_region_blocks_and_stops():
    world = _corridor(0.24)
    ex = Executive(world)
    sim = Simulator(world, seed=0)
    states = []
    for _ in range(300):
        res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
        assert math.isfinite(res.v) and math.isfinite(res.omega)
        assert set(res.status) == STATUS_FIELDS
        states.append(res.status["state"])
        if res.status["state"] == "blocked":
            assert (res.v, res.omega) == (0.0, 0.0)
            assert "b" in res.status["message"] and ex.unreachable == ("b",), res.status["message"]
        sim.step((res.v, res.omega))
    assert states[-1] == "blocked", ex.messages
    assert not sim.metrics.collisions
    # a wider gap lets a tree through: the same mission completes
    _check_run(run_mission(_corridor(0.6), max_time=200))


def test_a_robot_inside_a_grown_obstacle_is_not_blocked_and_creeps_out():
    """A robot whose position lies inside an obstacle grown by its radius (an estimate grown up
    to it, or here a known obstacle 5 cm away) cannot start a harmonic tree; the region it heads
    for is not walled off for that (its transition keeps the straight-line cost), and the
    controller's escape creeps it out along the field until the trees can start again."""
    world = shared_world("simple")
    ex = Executive(world, known=True)
    x, y, th = 1.25, 1.5, 0.0  # 5 cm from obstacle 0 (a 0.4 m square at (1.0, 1.5)), robot radius 0.1 m
    r = world.robot.radius
    d0 = float(world.obstacles[0].distance((x, y)))
    for k in range(100):
        res = ex.tick({"stamp": 0.1 * k, "x": x, "y": y, "theta": th}, now=0.1 * k)
        assert res.status["state"] == "executing", res.status["message"]
        assert math.isfinite(res.v) and math.isfinite(res.omega) and res.v >= 0.0
        x, y, th = x + 0.1 * res.v * math.cos(th), y + 0.1 * res.v * math.sin(th), th + 0.1 * res.omega
        if float(world.obstacles[0].distance((x, y))) > r + 0.01:
            break
    assert float(world.obstacles[0].distance((x, y))) > r + 0.01 > d0, (x, y, ex.messages)


def test_blocked_executive_resumes_when_the_mission_changes():
    world = _corridor(0.24)
    ex = Executive(world)
    sim = Simulator(world, seed=0)
    for _ in range(200):
        res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
        sim.step((res.v, res.omega))
    assert ex.state is ExecutiveState.BLOCKED
    ex.request("F a", "replace")
    for _ in range(400):
        res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
        if ex.state is ExecutiveState.DONE:
            break
        sim.step((res.v, res.omega))
    assert ex.state is ExecutiveState.DONE and "a" in ex.visited, ex.messages


def _open_corridor() -> World:
    """``_corridor(0.6)`` with its wall known: the robot can reach ``b``."""
    d = json.loads(json.dumps(_corridor(0.6).to_dict()))
    d["known_obstacles"] = [0]
    return World.from_dict(d)


class _ScriptedMap:
    """Stands in for perception: the scans are ignored and the estimates change when told to.

    Only what the executive reads is provided (``update_scan``, ``estimates``, ``inflated``,
    ``obstacles``, ``config``, ``regions``, ``last_returns``, ``refit_near``)."""

    last_returns = np.zeros((0, 2))  # no returns: the motion guard has nothing to keep off

    def refit_near(self, q, reach):
        return 0

    def __init__(self, world: World):
        from perception.map import ObstacleMap

        self._real = ObstacleMap.from_world(world)
        self.config = self._real.config
        self.regions = self._real.regions
        self.radius = float(world.robot.radius)
        self._est = {}
        self._next = None  # MapUpdate delivered by the next update_scan

    def script(self, added=(), removed=(), fits=0):
        from perception.fit import inflate
        from perception.map import Estimate, MapUpdate

        for i, sq in added:
            self._est[i] = Estimate(i, sq, inflate(sq, self.radius), cluster=i)
        for i in removed:
            self._est.pop(i)
        self._next = MapUpdate(None, added=tuple(i for i, _ in added), removed=tuple(removed), fits=fits)

    def update_scan(self, scan, pose, now=None):
        from perception.map import MapUpdate

        upd, self._next = self._next or MapUpdate(None), None
        return upd

    @property
    def estimates(self):
        return dict(self._est)

    def inflated(self):
        return [self._est[k].inflated for k in sorted(self._est)]

    def obstacles(self):
        return [self._est[k].squircle for k in sorted(self._est)]


def test_blocked_executive_resumes_when_a_map_update_reopens_the_way():
    """Issue 6, bad input: blocked by an estimate that closes the corridor, the executive stops;
    when a later map update removes it, the executive re-plans by itself and completes."""
    from navigation.geometry import Squircle

    world = _open_corridor()
    # no looks (look_tries=0): blocked at once (the looks have tests of their own below)
    ex = Executive(world, "F b", known=True, config=ExecutiveConfig(look_tries=0))
    ex.omap = omap = _ScriptedMap(world)
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 20, stop=lambda ex: False)
    assert ex.state is ExecutiveState.EXECUTING
    # a (phantom) estimate fills the gap under the wall: b is walled off
    omap.script(added=[(7, Squircle((2.6, 0.45), 0.2, 0.9, 0.0, 0.99))])
    res = _drive(ex, sim, 5, stop=lambda ex: ex.state is ExecutiveState.BLOCKED)
    assert ex.state is ExecutiveState.BLOCKED and ex.unreachable == ("b",), ex.messages
    for _ in range(30):  # stays stopped while nothing changes
        res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
        assert (res.v, res.omega) == (0.0, 0.0) and ex.state is ExecutiveState.BLOCKED
        sim.step((res.v, res.omega))
    omap.script(removed=[7])  # the estimate goes: the way is open again
    _drive(ex, sim, 600)
    assert ex.state is ExecutiveState.DONE and "b" in ex.visited, ex.messages
    assert not sim.metrics.collisions


@pytest.mark.parametrize("fits, defer", [(9, 5), (4, 5), (9, 0)])
def test_a_replan_after_a_heavy_map_update_waits_one_tick_and_the_robot_brakes(fits, defer):
    """``defer_fits`` (module doc, "Deferred re-plans"): a map update of at least ``defer_fits``
    squircle fits that asks for a re-plan (an estimate walls ``b`` off) leaves the re-plan to
    the next tick, whose command is the rate limit's brake; the next tick re-plans even after
    another heavy update (one tick at most). A lighter update, or ``defer_fits = 0``, re-plans
    at once."""
    from navigation.geometry import Squircle

    world = _open_corridor()
    ex = Executive(world, "F b", known=True, config=ExecutiveConfig(look_tries=0, defer_fits=defer))
    ex.omap = omap = _ScriptedMap(world)
    sim = Simulator(world, seed=0)
    before = _drive(ex, sim, 20, stop=lambda ex: False)
    assert ex.state is ExecutiveState.EXECUTING and before.v > 0.15
    omap.script(added=[(7, Squircle((2.6, 0.45), 0.2, 0.9, 0.0, 0.99))], fits=fits)
    res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
    waits = defer and fits >= defer
    assert res.replanned is not waits and ex.deferred_plans == int(waits)
    if not waits:
        assert ex.state is ExecutiveState.BLOCKED and (res.v, res.omega) == (0.0, 0.0)
        return
    # the brake: v lowered by accel_max dt (1 m/s^2, 0.1 s), omega towards 0 by alpha_max dt
    dv, dw = ex.control.accel_max * 0.1, ex.control.alpha_max * 0.1
    assert ex.state is ExecutiveState.EXECUTING and dv > 0
    assert res.v == pytest.approx(max(0.0, before.v - dv)) and res.v < before.v
    assert res.omega == pytest.approx(math.copysign(max(0.0, abs(before.omega) - dw), before.omega))
    sim.step((res.v, res.omega))
    omap.script(added=[(8, Squircle((1.0, 1.3), 0.1, 0.1, 0.0, 0.99))], fits=fits)  # heavy again
    res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
    assert res.replanned and ex.deferred_plans == 1
    assert ex.state is ExecutiveState.BLOCKED and ex.unreachable == ("b",), ex.messages


def test_defer_fits_is_validated():
    for bad in (-1, 1.5, True, "5"):
        with pytest.raises(TampError, match="defer_fits"):
            ExecutiveConfig(defer_fits=bad)


def test_an_unreachable_region_is_looked_at_from_up_to_look_tries_points_then_blocked():
    """Going to look (module doc): with ``b`` walled off (the 0.24 m gap), the robot first
    drives to the reachable points nearest to ``b``, three of them at least ``LOOK_SPACING``
    apart, and only then stops, blocked; with ``look_tries=0`` it stops at once."""
    from tamp.executive import LOOK_SPACING

    world = _corridor(0.24)
    ex = Executive(world)
    sim = Simulator(world, seed=0)
    res = _drive(ex, sim, 600, stop=lambda ex: ex.state is ExecutiveState.BLOCKED)
    assert ex.state is ExecutiveState.BLOCKED and ex.unreachable == ("b",), ex.messages
    assert (res.v, res.omega) == (0.0, 0.0) and not sim.metrics.collisions
    looks = [m for m in ex.messages if "going to look" in m]
    assert [m.split("(look ")[1] for m in looks] == ["1 of 3)", "2 of 3)", "3 of 3)"], ex.messages
    pts = np.array(ex._looked["b"])
    assert ex.looks == 3 and len(pts) == 3 and min(math.dist(a, b) for a, b in itertools.combinations(pts, 2)) >= LOOK_SPACING
    assert all(pt[0] < 2.6 for pt in pts)  # on the robot's side of the wall
    now = Executive(world, config=ExecutiveConfig(look_tries=0))
    sim = Simulator(world, seed=0)
    _drive(now, sim, 100, stop=lambda ex: ex.state is ExecutiveState.BLOCKED)
    assert now.state is ExecutiveState.BLOCKED and not any("look" in m for m in now.messages)
    assert sim.time < 3.0
    with pytest.raises(TampError, match="look_tries"):
        ExecutiveConfig(look_tries=-1)


def test_a_look_that_shows_the_way_open_completes_the_mission():
    """A phantom estimate closes the way to ``b``; instead of stopping, the robot goes to look,
    and when the phantom goes as the robot comes near (a closer view), the mission completes."""
    from navigation.geometry import Squircle

    world = _open_corridor()
    ex = Executive(world, "F b", known=True)
    ex.omap = omap = _ScriptedMap(world)
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 20, stop=lambda ex: False)
    omap.script(added=[(7, Squircle((2.6, 0.45), 0.2, 0.9, 0.0, 0.99))])
    _drive(ex, sim, 300, stop=lambda ex: math.dist(sim.pose[:2], (2.6, 0.45)) < 0.8)
    assert ex.state is ExecutiveState.EXECUTING and any("going to look" in m for m in ex.messages), ex.messages
    omap.script(removed=[7])
    _drive(ex, sim, 600)
    assert ex.state is ExecutiveState.DONE and "b" in ex.visited, ex.messages
    assert not any(m.startswith("[") and "] blocked:" in m for m in ex.messages)
    assert not sim.metrics.collisions


# ---------------------------------------------------------------------- narrow passages
def _slit_world(slit: float) -> World:
    """A wall across a 4 x 3 m room with one passage ``slit`` wide at mid-height: open at the
    fallback buffer for ``slit`` > 0.26 m, too narrow for any boundary vertex to see through."""
    h = 1.5 - slit / 2
    return World.from_dict({
        "name": "slit", "workspace": {"center": [2.0, 1.5], "width": 4.0, "height": 3.0, "s": 0.99},
        "obstacles": [{"center": [2.0, h / 2], "width": 0.2, "height": h, "s": 0.99},
                      {"center": [2.0, 3.0 - h / 2], "width": 0.2, "height": h, "s": 0.99}],
        "known_obstacles": [0, 1],
        "regions": {"a": {"center": [0.6, 0.5], "radius": 0.15}, "b": {"center": [3.4, 2.5], "radius": 0.15}},
        "robot": {"radius": 0.1, "start": [0.6, 0.5, 0.0], "v_max": 0.5, "omega_max": 1.5},
        "lidar": {"range": 2.0, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10},
        "task": "F b"})


@pytest.mark.parametrize("slit", [0.28, 0.3])  # from 0.31 m the snugly grown walls' vertices see through
def test_a_region_behind_a_passage_no_roadmap_vertex_sees_through_is_reached_not_blocked(slit):
    """No roadmap has a path to ``b`` (the passage is too narrow for the boundary vertices);
    the executive adds the passage's vertices to the fallback roadmap (``gap_searches``) and
    drives through instead of stopping blocked for good (seen on a random world)."""
    world = _slit_world(slit)
    ex = Executive(world, known=True)
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 400)
    assert ex.state is ExecutiveState.DONE and ex.visited == ["b"], ex.messages
    assert ex.gap_searches >= 1 and not any("blocked" in m for m in ex.messages)
    assert not sim.metrics.collisions


def _gap_world() -> World:
    """Two known walls across a 4 x 3 m room leave a 0.4 m gap between them (open at the
    fallback buffer only, for a robot of radius 0.1) and a 0.7 m opening at the bottom: from
    ``a`` to ``b`` the gap is about 1.9 m, the way round at the paper's buffer about 4.9 m."""
    return World.from_dict({
        "name": "gap", "workspace": {"center": [2.0, 1.5], "width": 4.0, "height": 3.0, "s": 0.99},
        "obstacles": [{"center": [2.0, 2.55], "width": 0.2, "height": 1.1, "s": 0.99},
                      {"center": [2.0, 1.15], "width": 0.2, "height": 0.9, "s": 0.99}],
        "known_obstacles": [0, 1],
        "regions": {"a": {"center": [1.5, 2.5], "radius": 0.15}, "b": {"center": [2.5, 2.5], "radius": 0.15}},
        "robot": {"radius": 0.1, "start": [1.5, 2.5, -1.57], "v_max": 0.5, "omega_max": 1.5},
        "lidar": {"range": 2.0, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10},
        "task": "F b"})


@pytest.mark.parametrize("ratio", [0.0, 2.0])
def test_a_long_way_round_is_replaced_by_the_narrow_passage(ratio):
    """``detour_ratio``: the tree at the paper's buffer goes round the bottom (more than twice
    the straight line); the fallback tree through the gap is more than twice shorter and is
    taken (default), or ignored with ``detour_ratio=0`` (and ``seen_detour_ratio=0``). Either
    way the robot arrives without touching anything."""
    _through_the_gap_or_round(_gap_world(), ExecutiveConfig(detour_ratio=ratio, seen_detour_ratio=0.0),
                              bool(ratio), short=2.5, far=4.0, below=0.7)


def _through_the_gap_or_round(world, cfg, through: bool, *, short: float, far: float, below: float):
    """Run ``world``'s mission: through the gap (shorter than ``short``, never below y = 1.5)
    or round the bottom (longer than ``far``, down below y = ``below``), without contact."""
    r = run_mission(world, max_time=200, config=cfg, record=True)
    _check_run(r)
    lowest = min(p[1] for p in r["trajectory"])
    if through:
        assert r["distance"] < short and lowest > 1.5, (r["distance"], lowest)
    else:
        assert r["distance"] > far and lowest < below, (r["distance"], lowest)


def _seen_gap_world() -> World:
    """Two unknown walls across a 4 x 3 m room leave a 0.4 m gap between them (open at the
    fallback buffer only) on the straight line from ``a`` to ``b`` (2 m) and a 0.9 m opening
    at the bottom: the way round at the paper's buffer is about 1.5 times longer, below
    ``detour_ratio`` but above ``seen_detour_ratio``; the robot at ``a`` sees through the gap."""
    return World.from_dict({
        "name": "seen-gap", "workspace": {"center": [2.0, 1.5], "width": 4.0, "height": 3.0, "s": 0.99},
        "obstacles": [{"center": [2.0, 2.4], "width": 0.2, "height": 1.0, "s": 0.99},
                      {"center": [2.0, 1.2], "width": 0.2, "height": 0.6, "s": 0.99}],
        "regions": {"a": {"center": [1.0, 1.7], "radius": 0.15}, "b": {"center": [3.0, 1.7], "radius": 0.15}},
        "robot": {"radius": 0.1, "start": [1.0, 1.7, 0.0], "v_max": 0.5, "omega_max": 1.5},
        "lidar": {"range": 3.0, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10},
        "task": "F b"})


@pytest.mark.parametrize("seen, controller, short", [(1.25, "default", 2.75), (1.25, None, 2.3), (0.0, "default", 0.0)])
def test_a_narrow_passage_seen_free_is_taken_on_a_shorter_way(seen, controller, short):
    """``seen_detour_ratio``: the walls are discovered; the way round is 1.5 times the way
    through the gap, which the robot has seen free: taken by default, not with
    ``seen_detour_ratio=0`` (only ``detour_ratio`` = 2 then). No contact either way. Through
    the gap the executive's default push-forward direction drags the robot up along the upper
    wall, which nearly touches the boundary (the transformation's conditioning there,
    docs/navigation.md), until the progress watchdog re-plans: 2.69 m against 1.93 m with the
    rotated gradient (``controller=None``), still shorter than any way round (> 2.8 m)."""
    cfg = ExecutiveConfig(seen_detour_ratio=seen)
    if controller is None:
        cfg = dataclasses.replace(cfg, controller=None)
    _through_the_gap_or_round(_seen_gap_world(), cfg, bool(seen), short=short, far=2.8, below=0.9)


@pytest.mark.parametrize("ratio", [0.0, 2.0])
def test_a_near_unseen_passage_is_probed_when_a_look_saves_more_than_it_costs(ratio):
    """``probe_ratio``: the walls of the seen-gap world known, a 0.5 m lidar: from ``a`` the gap
    (1 m ahead) has not been seen, so by default the robot goes round (1.5 times longer);
    with ``probe_ratio`` = 2 the saving (about 1 m) exceeds twice the way until the gap is in
    lidar range, and the robot heads for the gap and through it. No contact either way."""
    world = World.from_dict({
        "name": "probe-gap", "workspace": {"center": [2.0, 1.5], "width": 4.0, "height": 3.0, "s": 0.99},
        "obstacles": [{"center": [2.0, 2.4], "width": 0.2, "height": 1.0, "s": 0.99},
                      {"center": [2.0, 1.2], "width": 0.2, "height": 0.6, "s": 0.99}],
        "known_obstacles": [0, 1],
        "regions": {"a": {"center": [1.0, 1.7], "radius": 0.15}, "b": {"center": [3.0, 1.7], "radius": 0.15}},
        "robot": {"radius": 0.1, "start": [1.0, 1.7, 0.0], "v_max": 0.5, "omega_max": 1.5},
        "lidar": {"range": 0.5, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10},
        "task": "F b"})
    _through_the_gap_or_round(world, ExecutiveConfig(probe_ratio=ratio), bool(ratio), short=2.75, far=2.8, below=0.9)
    with pytest.raises(TampError, match="probe_ratio"):
        ExecutiveConfig(probe_ratio=-1.0)


def test_a_passage_counts_as_seen_only_once_the_lidar_crossed_it():
    """``Executive._seen_passage``: the fallback tree through the gap after the scan of the
    start pose (the beams crossed the gap), and with a map that has seen nothing."""
    world = _seen_gap_world()
    ex = Executive(world)
    sim = Simulator(world, seed=0)
    ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)  # discovers the walls
    tree = ex._tree(tuple(world.robot.start), (3.0, 1.7, 0.0))
    assert max(p[1] for p in tree.positions) < 1.9 and min(p[1] for p in tree.positions) > 1.5  # the gap
    assert ex._seen_passage(tree)
    ex.omap = ObstacleMap.from_world(world)  # the same roadmap, no free-space evidence
    assert not ex._seen_passage(tree)


def test_a_leg_through_a_narrow_passage_is_kept_while_no_dearer():
    """Hysteresis of the buffer fallback (``Executive._tree_road``'s ``keep``): once the leg
    goes through the gap (fallback roadmap), a re-plan on the way keeps it while the gap is
    merely no dearer than the way round, though no longer ``seen_detour_ratio`` times cheaper;
    a robot not yet committed to it (no ``keep``) takes the way round. Office's robot turned
    back and forth between two such ways at d3 as their cost ratio crossed 1.25."""
    world = _seen_gap_world()
    ex = Executive(world)
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 12, stop=lambda ex: False)  # out of region a, on its way through the gap
    assert ex.state is ExecutiveState.EXECUTING and ex._at_region is None
    assert ex._leg_road == ("b", 1), ex._leg_road
    p = tuple(sim.pose)
    goal = (3.0, 1.7, math.atan2(1.7 - p[1], 3.0 - p[0]))
    t0 = plan_tree(ex._roads[0].current(), p, goal, ex.weights, ex.config.n_headings)
    t1 = plan_tree(ex._roads[1].current(), p, goal, ex.weights, ex.config.n_headings)
    assert 1.0 < t0.cost / t1.cost and 1.0 < t0.translations.sum() / t1.translations.sum()
    # ratios above the saving from here: only the hysteresis keeps the gap
    ex.config = dataclasses.replace(ex.config, seen_detour_ratio=1.1 * t0.cost / t1.cost,
                                    detour_ratio=1.1 * t0.translations.sum() / t1.translations.sum())
    assert ex._tree_road(p, goal)[1] == 0
    assert ex._tree_road(p, goal, keep=ex._leg_keep("b"))[1] == 1
    ex._need_plan = True  # a re-plan on the way
    _drive(ex, sim, 1, stop=lambda ex: False)
    assert ex.replans >= 1 and ex._leg_road == ("b", 1), ex._leg_road
    _drive(ex, sim, 400)
    assert ex.state is ExecutiveState.DONE and not sim.metrics.collisions
    assert sim.metrics.distance < 2.75, sim.metrics.distance  # through the gap, not round (> 2.8 m)


def test_leg_waypoints_in_a_narrow_passage_are_centred():
    """``ExecutiveConfig.centre_reach``: the fallback tree through the 0.4 m gap turns at
    vertices 3 cm off the grown wall ends; the leg's waypoint in the gap is moved to its middle
    (y = 1.8, clearance 0.1 at most for a robot of radius 0.1), farther from both walls than
    the tree's vertex, waypoints with clearance ``buffer`` stay where they are, and every
    segment of the leg stays clear at the fallback buffer."""
    legs = {}
    for reach in (0.0, 0.12):
        world = _gap_world()
        ex = Executive(world, config=ExecutiveConfig(centre_reach=reach))
        sim = Simulator(world, seed=0)
        ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
        assert ex._leg_road == ("b", 1)
        legs[reach] = W = np.array([w[:2] for w in ex.leg])
        rm = ex._roads[-1].current()
        assert rm.visible(W[:-1], W[1:]).all()
        clear = forest_clearance(ex.forest)
        legs[reach, "c"] = clear(W)
    (W0, c0), (W1, c1) = (legs[0.0], legs[0.0, "c"]), (legs[0.12], legs[0.12, "c"])
    assert len(W0) == len(W1)
    gap = np.nonzero(np.abs(W1[:, 0] - 2.0) < 0.1)[0]
    assert len(gap) == 1 and abs(W1[gap[0], 1] - 1.8) < 0.015, W1
    assert c1[gap[0]] > c0[gap[0]] + 0.005 and c1.min() > c0.min()
    wide = c0 >= ExecutiveConfig().buffer
    assert np.array_equal(W0[wide], W1[wide])
    assert np.all(c1 >= c0 - 1e-9)


def test_reachable_speed_is_the_speed_of_the_circle_through_the_waypoint():
    """``reachable_speed``: ``omega_max d / (2 sin a)``; a point abeam at 0.3 m is reached on
    a half circle of radius 0.15 m; straight ahead there is no cap; behind the robot the cap is
    the abeam one (``a`` capped at 90 degrees)."""
    assert reachable_speed((0.0, 0.0, 0.0), (0.0, 0.3), 1.5) == pytest.approx(0.225)
    assert reachable_speed((1.0, 1.0, math.pi / 2), (1.5, 1.0 + math.sqrt(3) / 2), 1.5) == pytest.approx(1.5)
    assert reachable_speed((0.0, 0.0, 0.3), (2.0 * math.cos(0.3), 2.0 * math.sin(0.3)), 1.5) == math.inf
    assert reachable_speed((0.0, 0.0, 0.0), (-0.3, 0.0001), 1.5) == pytest.approx(0.225, rel=1e-3)


@pytest.mark.parametrize("cap", [True, False])
def test_the_executive_never_drives_faster_than_it_can_turn_onto_its_waypoint(cap):
    """``ExecutiveConfig.turn_cap``: on the way through the gap every command's speed is at
    most ``reachable_speed`` of the waypoint tracked (the motion guard and the safety limit
    only lower it further); without it the robot drives faster somewhere. Both arrive. (The
    cap is for the waypoints' fields, ``pursuit=0``: pursuing the leg, no waypoint is aimed at.)"""
    world = _seen_gap_world()
    unlimited = dataclasses.replace(ExecutiveConfig().controller, **UNLIMITED)  # the cap is off with the rate limit
    ex = Executive(world, config=ExecutiveConfig(turn_cap=cap, controller=unlimited, pursuit=0.0))
    sim = Simulator(world, seed=0)
    over = 0
    for _ in range(400):
        pose = tuple(sim.pose)
        res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
        if ex.state is ExecutiveState.DONE:
            break
        if ex.leg and res.v > reachable_speed(pose, ex.leg[ex.wp], ex.control.omega_max) + 1e-9:
            over += 1
        sim.step((res.v, res.omega))
    assert ex.state is ExecutiveState.DONE and not sim.metrics.collisions
    assert (over == 0) if cap else (over > 0), over


@pytest.mark.parametrize("cap", [True, False])
def test_the_rate_limited_executive_brakes_towards_the_speed_it_can_turn_at(cap):
    """In the rate-limited mode (the default controller) ``turn_cap_rate_limited`` passes
    ``reachable_speed`` of the waypoint tracked to the tracker as ``v_cap``: every command is
    then at most that speed or as slow as braking at ``accel_max`` from the previous command
    allows, and within the rate bound of the previous command; without it the robot drives
    faster than it can turn somewhere. Both arrive without collision. (Fields: ``pursuit=0``.)"""
    world = _seen_gap_world()
    ex = Executive(world, config=ExecutiveConfig(turn_cap_rate_limited=cap, pursuit=0.0))
    assert ex.control.accel_max > 0
    sim = Simulator(world, seed=0)
    over = late = 0
    prev = None
    for _ in range(400):
        pose = tuple(sim.pose)
        res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
        if ex.state is ExecutiveState.DONE:
            break
        if ex.leg:
            reach = reachable_speed(pose, ex.leg[ex.wp], ex.control.omega_max)
            over += res.v > reach + 1e-9
            if prev is not None:
                late += res.v > max(reach, prev - ex.control.accel_max * 0.1) + 1e-9
                assert abs(res.v - prev) <= ex.control.accel_max * 0.1 + 1e-9
        prev = res.v
        sim.step((res.v, res.omega))
    assert ex.state is ExecutiveState.DONE and not sim.metrics.collisions
    assert (late == 0) if cap else (over > 0), (over, late)


def test_boundary_buffer_opens_the_first_roadmap_along_the_known_boundary():
    """``boundary_buffer`` (opt-in): a known wall leaves a 0.51 m gap to the workspace boundary,
    closed for the first roadmap at the paper's buffer (2 (r + 0.15) = 0.5 m plus the vertex
    offset; 0.52 m was until the snug inflation rounded the wall's top corners) and open when
    the boundary is owed 0.03 m; the mission drives through it without touching anything, and
    the option is validated."""
    world = World.from_dict({
        "name": "edge", "workspace": {"center": [2.0, 1.5], "width": 4.0, "height": 3.0, "s": 0.99},
        "obstacles": [{"center": [2.0, 1.245], "width": 0.2, "height": 2.49, "s": 0.99}],
        "known_obstacles": [0],
        "regions": {"a": {"center": [1.0, 2.6], "radius": 0.15}, "b": {"center": [3.0, 2.6], "radius": 0.15}},
        "robot": {"radius": 0.1, "start": [1.0, 2.6, 0.0], "v_max": 0.5, "omega_max": 1.5},
        "lidar": {"range": 2.0, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10},
        "task": "F b"})
    goal = (3.0, 2.6, 0.0)
    for bw, opens in ((None, False), (0.03, True)):
        ex = Executive(world, config=ExecutiveConfig(boundary_buffer=bw))
        assert ex._roads[0].current().config.wall_buffer == (0.15 if bw is None else bw)
        try:
            plan_tree(ex._roads[0].current(), world.robot.start, goal, ex.weights, ex.config.n_headings)
            found = True
        except NoTreePathError:
            found = False
        assert found is opens
    r = run_mission(world, max_time=120, config=ExecutiveConfig(boundary_buffer=0.03))
    assert r["completed"] and r["collisions"] == 0 and r["distance"] < 3.0
    for bad in (-0.1, float("nan"), "0.03"):
        with pytest.raises(TampError, match="boundary_buffer"):
            ExecutiveConfig(boundary_buffer=bad)


def test_config_ratios_and_windows_are_validated():
    with pytest.raises(TampError, match="refit_window"):
        ExecutiveConfig(refit_window=3)  # fewer than refit_min_edges (4): it could never refit
    with pytest.raises(TampError, match="detour_ratio"):
        ExecutiveConfig(detour_ratio=-1.0)
    with pytest.raises(TampError, match="centre_reach"):
        ExecutiveConfig(centre_reach=float("nan"))
    with pytest.raises(TampError, match="seen_detour_ratio"):
        ExecutiveConfig(seen_detour_ratio=0.5)
    with pytest.raises(TampError, match="seen_share"):
        ExecutiveConfig(seen_share=0.0)
    with pytest.raises(TampError, match="seen_share"):
        ExecutiveConfig(seen_share=1.5)


def test_crawl_guard_option_is_validated_on_by_default_and_can_be_turned_off():
    from navigation import CrawlConfig

    with pytest.raises(TampError, match="crawl_guard"):
        ExecutiveConfig(crawl_guard=0.03)
    assert ExecutiveConfig().crawl_guard == CrawlConfig()
    r = run_mission(_gap_world(), max_time=200, config=ExecutiveConfig(crawl_guard=None))
    assert r["completed"] and r["collisions"] == 0 and r["bad_commands"] == 0


def test_speed_to_leg_end_drives_a_mission_and_measures_the_rest_of_the_leg():
    """With ``speed_to_leg_end`` the controller's ``beyond`` is the leg's path length after the
    current waypoint (0 on the last one), and the mission completes safely."""
    world = _gap_world()
    ex = Executive(world, config=ExecutiveConfig(speed_to_leg_end=True))
    ex.leg = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 2.0, 0.0), (4.0, 6.0, 0.0))
    ex.wp = 1
    assert ex._beyond() == pytest.approx(2.0 + 5.0)
    ex.wp = 3
    assert ex._beyond() == 0.0
    assert Executive(world)._beyond() == 0.0  # off by default
    r = run_mission(world, max_time=200, config=ExecutiveConfig(speed_to_leg_end=True))
    assert r["completed"] and r["collisions"] == 0 and r["bad_commands"] == 0


def test_rate_limited_controller_option_drives_a_mission_with_bounded_changes():
    """``ExecutiveConfig(controller=...)`` in the controller's rate-limited mode: the mission of
    ``simple`` (unknown obstacles: map changes, re-plans) completes without contact, and every
    command the executive sends is within 0.1 m/s and 0.6 rad/s of the one before (the braking-aware
    safety limit never had to override the rate limit, the stops included); the robot's limits
    come from the world, not from the given config."""
    from navigation.control import RATE_LIMITED, ControllerConfig

    with pytest.raises(TampError, match="controller"):
        ExecutiveConfig(controller={"accel_max": 1.0})
    cfg = ExecutiveConfig(controller=ControllerConfig(**RATE_LIMITED))
    world = shared_world("simple")
    ex = Executive(world, config=cfg)
    assert ex.control.v_max == world.robot.v_max and ex.control.accel_max == 1.0
    r = run_mission(world, max_time=200, config=cfg, record=True)
    assert r["completed"] and r["collisions"] == 0 and r["bad_commands"] == 0
    c = np.asarray([(0.0, 0.0)] + r["commands"])
    assert np.abs(np.diff(c[:, 0])).max() <= 0.1 + 1e-9 and np.abs(np.diff(c[:, 1])).max() <= 0.6 + 1e-9


# ---------------------------------------------------------------------- rotation weights
def test_rotation_weights_are_refitted_from_traversed_edges():
    """Section 4.2.3 step III: with edges whose measured costs follow ``d + w . Q`` exactly, the
    refit recovers ``w``; every evaluated tree's map cost is then its cost under ``w``."""
    import numpy as np

    from tamp.harmonic_tree import RotationWeights, rotation_terms

    world = shared_world("simple")
    ex = Executive(world, "F a & F b", known=True)
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 5, stop=lambda ex: False)  # plans: trees evaluated
    assert ex._pair or ex._start_pair
    true = RotationWeights(0.3, 0.2)
    rng = np.random.default_rng(0)
    ex.leg = tuple((float(x), float(y), float(t)) for x, y, t in
                   zip(rng.uniform(0, 4, 8), rng.uniform(0, 1.5, 8), rng.uniform(-3, 3, 8)))
    ex._edge_t0 = ex.time = 0.0
    for k in range(1, len(ex.leg)):
        a, b = ex.leg[k - 1], ex.leg[k]
        cost = math.dist(a[:2], b[:2]) + rotation_terms(a[:2], a[2], b[:2], b[2]) @ true.as_array()
        ex.time += cost / ex.control.v_max
        ex._edge_done(k)
    assert ex.weight_fits >= 1
    assert ex.weights.w1 == pytest.approx(0.3, abs=1e-9) and ex.weights.w2 == pytest.approx(0.2, abs=1e-9)
    def assert_costs_follow_the_weights():
        nm = ex.planner.navmap
        for (a, b), tree in ex._pair.items():
            if not isinstance(tree, Exception):
                best = min(nm.cost(u, v) for u in nm.region_nodes(a) for v in nm.region_nodes(b))
                assert best == pytest.approx(tree.recost(ex.weights), rel=1e-12)

    assert_costs_follow_the_weights()
    # a run-time region change rebuilds the map: the kept trees keep the refitted costs
    ex.set_regions({"d": D})
    assert ex._pair
    assert_costs_follow_the_weights()


@pytest.mark.parametrize("window", [None, 6])
def test_rotation_weights_refit_during_a_mission(window):
    """In closed loop (cluttered20) the weights are refitted from the measured edges, stay in
    their bounds, and equal the least-squares fit over the recorded edges: all of them, or with
    ``refit_window`` the last ones only (a long run's memory stays bounded)."""
    import numpy as np

    from tamp.harmonic_tree import RotationWeights

    runs = []

    class Recording(Executive):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            runs.append(self)

    config = ExecutiveConfig() if window is None else ExecutiveConfig(refit_window=window)
    _check_run(run_mission(shared_world("cluttered20"), max_time=300, executive_cls=Recording, config=config))
    ex = runs[0]
    lo, hi = ex.config.weight_bounds
    assert ex.weight_fits >= 1 and len(ex._edges) >= ex.config.refit_min_edges
    if window is not None:
        assert len(ex._edges) == window
    rows = np.array(ex._edges)
    fit = RotationWeights.fit(rows[:, 0], rows[:, 1:3], rows[:, 3])
    assert (ex.weights.w1, ex.weights.w2) == pytest.approx((min(max(fit.w1, lo), hi), min(max(fit.w2, lo), hi)))


# ---------------------------------------------------------------------- bad input
def test_bad_poses_stop_the_robot_and_recover():
    world = shared_world("simple")
    ex = Executive(world)
    for bad in [(float("nan"), 1.0, 0.0), (1.0, 2.0), "pose", {"x": 1.0, "y": 2.0}]:
        res = ex.tick(bad, now=0.0)
        assert (res.v, res.omega) == (0.0, 0.0) and res.status["state"] == "error", res.status
    res = ex.tick((-5.0, -5.0, 0.0), now=0.0)
    assert res.status["state"] == "error" and "outside the workspace" in res.status["message"]
    res = ex.tick(world.robot.start, now=0.1)
    assert res.status["state"] == "executing" and math.isfinite(res.v)


def test_bad_scans_are_dropped_with_a_message():
    world = shared_world("office")
    ex = Executive(world)
    sim = Simulator(world, seed=0)
    for bad in [{"stamp": 0.0}, "not json", {**sim.scan_message(), "ranges": [1.0] * 3}]:
        n = len(ex.messages)
        res = ex.tick(sim.pose_message(), scan=bad, now=0.0)
        assert res.status["state"] == "executing"
        assert any("input dropped" in m for m in ex.messages[n:]), ex.messages[n:]
        assert math.isfinite(res.v) and math.isfinite(res.omega)
    assert len(ex.obstacles) == 0


def test_bad_tasks_are_refused():
    world = shared_world("simple")
    with pytest.raises(LtlSyntaxError):
        Executive(world, "F (a &")
    with pytest.raises(UnknownRegionError):
        Executive(world, "F nowhere")
    with pytest.raises(Exception, match="ExecutiveConfig.buffer"):
        ExecutiveConfig(buffer=-1.0)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "tamp.run", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)


def test_cli_json_contract_and_errors(tmp_path):
    p = _cli(str(world_file("simple")), "--json", "--max-time", "60")
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    for key in ("completed", "collisions", "distance", "execution_time", "planning_time", "max_replan_time",
                "replans", "visited", "oscillation"):
        assert key in out
    assert out["completed"] and out["collisions"] == 0
    bad_world = tmp_path / "bad.json"
    bad_world.write_text(json.dumps({"name": "x"}))
    for args in [(str(bad_world),), (str(tmp_path / "missing.json"),), (str(world_file("simple")), "--task", "F (a"),
                 (str(world_file("simple")), "--task", "F zz"), (str(world_file("simple")), "--max-time", "-1"),
                 (str(world_file("simple")), "--seed", "x"), ()]:
        p = _cli(*args)
        assert p.returncode == 2, (args, p.stderr)
        lines = p.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), (args, p.stderr)
        assert "Traceback" not in p.stderr


def test_main_returns_two_on_bad_arguments(capsys):
    assert main(["--no-such-option"]) == 2
    assert capsys.readouterr().err.startswith("error: ")


def test_prepare_unfreezes_the_heap_at_exit():
    """``tamp.run.prepare`` freezes the start-up heap (``gc.freeze``) and unfreezes it at exit:
    objects left frozen are never freed, and an extension that checks for leaks at teardown
    reports them (nanobind's "leaked instances" from OMPL after the evaluation suite)."""
    code = ("import atexit, gc\n"
            "atexit.register(lambda: print('frozen at exit', gc.get_freeze_count()))\n"
            "from tamp.run import prepare\n"
            "prepare(); prepare()\n"
            "print('frozen', gc.get_freeze_count() > 0)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert "frozen True" in out.stdout and "frozen at exit 0" in out.stdout, out.stdout
    assert "leaked" not in out.stderr, out.stderr


def test_known_obstacles_that_are_not_a_forest_are_left_to_perception():
    # cluttered20 grown by the robot radius: obstacles 0, 1, 2 overlap in a cycle
    ex = Executive(shared_world("cluttered20"), known=True)
    assert any("not a forest of stars" in m for m in ex.messages), ex.messages
    assert ex.known == [] and ex.omap is not None
    # all obstacles of simple are a forest: no perception at all
    ex = Executive(shared_world("simple"), known=True)
    assert len(ex.known) == 4 and ex.omap is None


# ---------------------------------------------------------------------- run-time regions
D = {"center": [2.0, 0.4], "radius": 0.15}  # free in simple.json, away from a, b, c


def _drive(ex, sim, ticks: int, stop=lambda ex: ex.state is ExecutiveState.DONE):
    for _ in range(ticks):
        res = ex.tick(sim.pose_message(), scan=sim.scan_message(), now=sim.time)
        assert math.isfinite(res.v) and math.isfinite(res.omega)
        if stop(ex):
            return res
        sim.step((res.v, res.omega))
    return res


def test_a_patrol_keeps_every_region_after_an_urgent_request():
    """``office`` patrolled (``G F p1 & G F d1 & G F d3``) with its urgent ``F u1`` at 60 s: after
    serving it the robot goes round all three regions again. Planning from the whole set of
    automaton states let the plans take turns between runs: the robot went between ``p1`` and
    ``d3`` for good and still counted accepting visits (MissionPlanner, "One run of the
    automaton"). The run completes after one suffix round (accepting twice), so the visits after
    ``u1`` hold every region at least once (the bug alternated between two of them), and the
    whole run every region at least twice."""
    r = run_mission(shared_world("office"), "G F p1 & G F d1 & G F d3", max_time=300)
    _check_run(r)
    after = r["visited"][r["visited"].index("u1") + 1:]
    assert {"p1", "d1", "d3"} <= set(after), r["visited"]
    assert all(r["visited"].count(name) >= 2 for name in ("p1", "d1", "d3")), r["visited"]


def test_an_urgent_request_for_a_new_region_is_served_first_and_the_mission_completes():
    world = shared_world("simple")
    ex = Executive(world, "F a & F b")
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 20)
    assert ex.state is ExecutiveState.EXECUTING and not ex.visited
    plan = ex.request("F d", "urgent", regions={"d": D})
    assert plan.urgent_regions == ("d",)
    assert "d" in ex.regions and "d" not in world.regions  # the world object is not mutated
    _drive(ex, sim, 3000)
    assert ex.state is ExecutiveState.DONE, ex.messages[-5:]
    assert ex.visited[0] == "d" and {"a", "b"} <= set(ex.visited), ex.visited
    assert not sim.metrics.collisions


def test_a_moved_region_is_where_the_robot_goes():
    world = shared_world("simple")
    ex = Executive(world, "F b")
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 20)
    assert ex.target == "b"
    new_b = {"center": [1.5, 2.6], "radius": 0.15}
    assert ex.set_regions({"b": new_b, "a": world.regions["a"]}) == ("b",)  # a is unchanged
    res = _drive(ex, sim, 3000)
    assert ex.state is ExecutiveState.DONE, ex.messages[-5:]
    assert ex.visited == ["b"]
    x, y, _ = sim.pose
    assert math.dist((x, y), new_b["center"]) <= new_b["radius"]
    assert "b moved to (1.5, 2.6)" in " ".join(ex.messages)
    assert res.status["state"] == "done"


@pytest.mark.parametrize("regions, rule", [
    ({"d": {"center": [3.9, 1.5], "radius": 0.15}}, "workspace"),
    ({"d": {"center": [1.0, 1.5], "radius": 0.1}}, "free_space"),      # on obstacle 0 (known)
    ({"d": {"center": [1.25, 1.5], "radius": 0.1}}, "free_space"),     # clear of it, not with the robot radius
    ({"d": {"center": [0.7, 0.5], "radius": 0.1}}, "disjoint"),        # overlaps a
    ({"a": {"center": [3.5, 2.3], "radius": 0.15}}, "disjoint"),       # a moved onto b
    ({"d": {"center": [2.0, 0.4], "radius": -1.0}}, "format"),
    ({"d": {"centre": [2.0, 0.4], "radius": 0.1}}, "format"),
])
def test_refused_regions_name_the_region_and_rule_and_change_nothing(regions, rule):
    from tamp.errors import InvalidRequestError
    from tamp.executive import RegionError

    world = shared_world("simple")
    ex = Executive(world, "F a & F b", known=True)
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 10)
    before = (ex.status(), dict(ex.regions), ex.planner, ex.task)
    for call in (lambda: ex.set_regions(regions), lambda: ex.request("F b", "add", regions=regions)):
        with pytest.raises(RegionError) as err:
            call()
        assert isinstance(err.value, InvalidRequestError)
        assert err.value.rule.value == rule and err.value.region == next(iter(regions))
        assert str(err.value).startswith(f"regions.{err.value.region}:") and f"[rule: {rule}]" in str(err.value)
        assert (ex.status(), dict(ex.regions), ex.planner, ex.task) == before


def test_more_regions_than_the_navigation_map_holds_are_refused_first_and_change_nothing():
    """A request that adds 676 regions ran out of memory in the product search (forty-eighth
    session); beyond tamp.navmap.MAX_REGIONS the first region past the limit is named."""
    from tamp.executive import RegionError
    from tamp.navmap import MAX_REGIONS, NavigationMap
    from tamp.errors import InvalidRequestError

    world = shared_world("simple")
    ex = Executive(world, "F a & F b", known=True)
    before = (ex.status(), dict(ex.regions), ex.planner, ex.task)
    extra = MAX_REGIONS - len(world.regions) + 1
    regions = {f"q{i}": {"center": [0.0, 0.0], "radius": 0.01} for i in range(extra)}  # (the count is checked first)
    for call in (lambda: ex.set_regions(regions), lambda: ex.request("F q0", "replace", regions=regions)):
        with pytest.raises(RegionError) as err:
            call()
        assert err.value.rule.value == "count" and err.value.region == f"q{extra - 1}"
        assert f"{MAX_REGIONS + 1} regions after the change" in str(err.value)
        assert (ex.status(), dict(ex.regions), ex.planner, ex.task) == before
    NavigationMap({f"r{i}": (i, 0) for i in range(MAX_REGIONS)}, n_orient=2)
    with pytest.raises(InvalidRequestError, match="at most"):
        NavigationMap({f"r{i}": (i, 0) for i in range(MAX_REGIONS + 1)}, n_orient=2)


def test_a_refused_mission_keeps_the_regions_out():
    from tamp.errors import UnsatisfiableError

    world = shared_world("simple")
    ex = Executive(world, "F a & F b")
    plan = ex.plan
    with pytest.raises(UnsatisfiableError):
        ex.request("F d & G !d", "replace", regions={"d": D})
    assert "d" not in ex.regions and ex.task == "F a & F b" and ex.plan is plan
    assert ex.request("F d", "add", regions={"d": D}).prefix_regions  # the same region is fine with a mission
    assert "d" in ex.regions and "F d" in ex.task


def test_a_mission_over_all_regions_that_cannot_read_a_new_one_needs_replace():
    world = shared_world("simple")
    ex = Executive(world, "(a U b) & G !c")  # every region is in the formula; a visit to d breaks a U b
    with pytest.raises(Exception, match=r"regions\.d: .*\[rule: alphabet\]"):
        ex.set_regions({"d": D})
    assert "d" not in ex.regions
    ex.request("F d & F b", "replace", regions={"d": D})
    assert "d" in ex.regions and ex.task == "F d & F b"


def test_trees_between_unmoved_regions_are_kept():
    world = shared_world("simple")
    ex = Executive(world, "G F a & G F c", known=True)  # a -> c goes round the bar at (2.6, 0.9)
    sim = Simulator(world, seed=0)
    _drive(ex, sim, 5)
    pairs = dict(ex._pair)
    assert ("a", "c") in pairs
    cost = ex.planner.navmap.cost(("a", 0), ("c", 0))
    assert cost > ex.planner.navmap.initial_cost(("a", 0), ("c", 0))  # the tree's cost
    ex.set_regions({"d": D, "b": {"center": [3.5, 2.3], "radius": 0.15}})
    assert all(ex._pair.get(k) is v for k, v in pairs.items() if "b" not in k)
    assert not any("b" in k for k in ex._pair)
    assert ex.planner.navmap.cost(("a", 0), ("c", 0)) == cost  # the evaluated cost, not the initial one


def test_a_region_placed_around_the_robot_counts_as_entered():
    world = shared_world("simple")
    ex = Executive(world, "F a", known=True)
    x, y, _ = world.robot.start
    ex.set_regions({"s": {"center": [x, y], "radius": 0.1}})
    ex.tick(world.robot.start, now=0.0)
    assert ex.visited == ["s"] and ex.state is ExecutiveState.EXECUTING and ex.target == "a"


# ---------------------------------------------------------------------- roadmaps and legs
def _sets(rm):
    import numpy as np

    V = {tuple(np.round(p, 9)) for p in rm.points}
    E = {frozenset((tuple(np.round(rm.points[a], 9)), tuple(np.round(rm.points[b], 9)))) for a, b in rm.pairs}
    return V, E


def test_roadmaps_follow_the_obstacle_model_lazily_and_exactly():
    from navigation.geometry import Squircle
    from tamp.executive import _Roads
    from tamp.roadmap import Roadmap, RoadmapConfig

    world = shared_world("office")
    r = world.robot.radius
    known = list(world.obstacles[:10])
    model = {("known", i): o for i, o in enumerate(known)}
    roads = _Roads(world.workspace, r, 0.15, model, rebuild_after=2)
    roads.current()
    # an estimate updated twice before the roadmap is needed: only its current shape goes in
    o = world.obstacles[12]
    for scale in (0.8, 0.9, 1.0):
        model[("estimate", 0)] = Squircle(o.center, o.width * scale, o.height * scale, o.theta, o.s)
    rm = roads.current()
    assert rm.obstacles[-1] is model[("estimate", 0)] and len(rm.obstacles) == 11
    assert roads.stale == 0
    # a grown replacement covers the old shape: not stale; a moved one is
    model[("estimate", 0)] = Squircle(o.center, o.width * 1.2, o.height * 1.2, o.theta, o.s)
    roads.current()
    assert roads.stale == 0 and roads.outdated
    for k, dx in enumerate((0.3, 0.6)):
        model[("estimate", 0)] = Squircle((o.center[0] + dx, o.center[1]), o.width, o.height, o.theta, o.s)
        roads.current()
        assert roads.stale == k + 1
    # one more stale shape than rebuild_after: the stale shapes are taken out exactly
    del model[("estimate", 0)]
    rm = roads.current()
    assert roads.stale == 0 and not roads.outdated and roads.removals == 1
    scratch = Roadmap.build(world.workspace, list(model.values()), r, RoadmapConfig(buffer=0.15))
    assert set(map(id, rm.obstacles)) == set(map(id, model.values()))
    assert _sets(rm) == _sets(scratch)


def test_leg_shortcuts_drop_out_and_back_waypoints_and_stay_safe():
    import numpy as np

    world = shared_world("office")
    ex = Executive(world, known=True)
    rm = ex._roads[0].current()
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(200):
        a, b = rm.points[rng.choice(len(rm.points), 2, replace=False)]
        if not rm.visible(a[None], b[None])[0]:
            continue
        # a detour out and back: a vertex visible from a, then b
        back = [p for p in rm.points if rm.visible(a[None], p[None])[0] and rm.visible(p[None], b[None])[0]
                and np.linalg.norm(p - a) > 0.1]
        if not back:
            continue
        p = back[rng.integers(len(back))]
        leg = ((*a, 0.0), (*p, 0.0), (*b, 0.0))
        out = ex._shortcut(leg)
        assert out == (leg[0], leg[-1])
        checked += 1
        if checked >= 10:
            break
    assert checked >= 5
    # a tree's own path: a subsequence with the same ends, never longer, every segment safe
    names = list(world.regions)
    for s, g in zip(names[:-1], names[1:]):
        cs, cg = world.regions[s].center, world.regions[g].center
        tree = ex._tree((*cs, 0.0), (*cg, 0.0))
        wps = tuple(tuple(w) for w in tree.waypoints)
        out = ex._shortcut(wps)
        assert out[0] == wps[0] and out[-1] == wps[-1] and set(out) <= set(wps)
        length = lambda w: sum(math.dist(p[:2], q[:2]) for p, q in zip(w[:-1], w[1:]))
        assert length(out) <= length(wps) + 1e-12
        # segments that skip a waypoint are visible at the buffer (the others are tree edges)
        idx = [wps.index(w) for w in out]
        skips = [(out[k], out[k + 1]) for k in range(len(out) - 1) if idx[k + 1] > idx[k] + 1]
        if skips:
            a = np.array([u[:2] for u, _ in skips])
            b = np.array([v[:2] for _, v in skips])
            assert rm.visible(a, b).all()


class _Returns:
    """A map stand-in for the motion guard: fixed returns, records ``refit_near`` calls."""

    def __init__(self, pts, estimates=()):
        self.last_returns = np.asarray(pts, dtype=float)
        self.estimates_ = list(estimates)
        self.asked = []

    def obstacles(self):
        return self.estimates_

    def refit_near(self, q, reach):
        self.asked.append((tuple(q), reach))
        return 1

    def observed_free(self, q):
        return np.zeros(len(np.asarray(q).reshape(-1, 2)), bool)


@pytest.mark.parametrize("heading", [0.0, 0.3, -0.5])
def test_motion_guard_keeps_the_disc_off_the_returns(heading):
    """Issue 4/6 safety: a face seen a little outside its estimate (cluttered20: 8 mm) must not
    be touched. Returns on the line x = 1 (a wall), the robot 2 cm from touching it and driving
    at it: the guard slows it so that no point of the next period's arc comes closer than
    ``guard_margin`` to a return... unless it already is, then closer than now; it keeps the
    turn rate, leaves a command moving away untouched and asks perception to refit there."""
    world = _open_corridor()
    ex = Executive(world, "F b", known=True)
    r, m = ex.radius, ex.config.guard_margin
    ys = np.linspace(-1.0, 1.0, 401)
    ex.omap = omap = _Returns(np.stack((np.full_like(ys, 1.0), ys), 1))
    p = (1.0 - r - 0.02, 0.0, heading)
    for v, w in [(0.5, 0.0), (0.5, 1.0), (0.2, -1.5)]:
        got = ex._guard(p, v, w)
        assert 0.0 <= got < v
        t = np.linspace(0, ex.config.guard_horizon, 50)
        th = heading + w * t
        if abs(w) > 1e-9:
            xs = p[0] + got / w * (np.sin(th) - np.sin(heading))
        else:
            xs = p[0] + got * t * np.cos(heading)
        # the wall is straight: the disc's clearance is 1 - x - r
        assert np.min(1.0 - xs - r) >= min(m, 0.02) - 2e-3
    assert omap.asked
    assert ex._guard(p, -0.3, 0.0) == -0.3  # backing away from the wall
    assert ex._guard((1.0 - r - 0.02, 0.0, np.pi), 0.5, 0.0) == 0.5  # driving away
    far = (0.0, 0.0, heading)
    assert ex._guard(far, 0.5, 0.0) == 0.5  # nothing within reach


def test_motion_guard_keeps_noise_more_with_a_noisy_lidar():
    """With lidar range noise ``sigma`` the guard keeps ``guard_margin + guard_noise sigma`` from
    the returns (one scan's draw must not release a hold the last one asked for); the same
    world with a noise-free lidar keeps ``guard_margin``, and ``guard_noise = 0`` turns the extra
    off. The robot drives at the wall of returns at x = 1 from 4 cm."""
    base = _open_corridor()
    noisy = dataclasses.replace(base, lidar=dataclasses.replace(base.lidar, noise_std=0.02))
    ys = np.linspace(-1.0, 1.0, 401)
    wall = np.stack((np.full_like(ys, 1.0), ys), 1)

    def clearance_after(world, **cfg):
        ex = Executive(world, "F b", config=ExecutiveConfig(**cfg))
        ex.omap = _Returns(wall)
        r = ex.radius
        v = ex._guard((1.0 - r - 0.04, 0.0, 0.0), 0.5, 0.0)
        return 1.0 - (1.0 - r - 0.04 + v * ex.config.guard_horizon) - r

    m = ExecutiveConfig().guard_margin
    plain, wide, off = clearance_after(base), clearance_after(noisy), clearance_after(noisy, guard_noise=0.0)
    assert m - 2e-3 <= plain < m + 0.01
    assert m + 0.02 - 2e-3 <= wide < m + 0.02 + 0.01
    assert off == pytest.approx(plain)
    with pytest.raises(TampError):
        ExecutiveConfig(guard_noise=-1.0)


def test_motion_guard_hold_ends_in_a_slide_around_the_return():
    """A post of returns that no estimate covers stands across the straight way to ``a``: the
    field leads the robot into it and the motion guard holds it; after ``GUARD_HOLD_TICKS`` held
    ticks the robot slides around it (turning away, slowly, within the guard), and the mission
    completes with the disc never closer to a return than the guard allows."""
    from tamp.executive import GUARD_HOLD_TICKS

    world = _open_corridor()
    ex = Executive(world, "F a", known=True)
    ys = np.linspace(0.68, 0.82, 15)
    post = np.stack((np.full_like(ys, 1.0), ys), 1)
    ex.omap = _Returns(post)
    x, y, th = 0.5, 0.75, 0.0
    r, m = ex.radius, ex.config.guard_margin
    closest, held = np.inf, 0
    for k in range(900):
        res = ex.tick({"stamp": 0.1 * k, "x": x, "y": y, "theta": th}, now=0.1 * k)
        if ex.state is ExecutiveState.DONE:
            break
        assert math.isfinite(res.v) and math.isfinite(res.omega)
        for _ in range(10):  # the period's arc, finely
            x, y, th = x + 0.01 * res.v * math.cos(th), y + 0.01 * res.v * math.sin(th), th + 0.01 * res.omega
            closest = min(closest, float(np.min(np.hypot(post[:, 0] - x, post[:, 1] - y))) - r)
        held = max(held, ex._held)
    assert ex.state is ExecutiveState.DONE, (x, y, ex.messages[-5:])
    assert held >= GUARD_HOLD_TICKS and any("sliding around it" in msg for msg in ex.messages)
    assert closest >= m - 2e-3, closest


def test_a_return_that_holds_the_robot_twice_is_avoided_by_the_trees():
    """The second hold at the same return (within ``GUARD_SAME_SPOT``) puts a small disc there
    into the roadmaps' obstacle model (not the forest), drops the trees it blocks and asks for a
    re-plan; a third hold there adds nothing."""
    from navigation.control import Command
    from tamp.executive import GUARD_HOLD_TICKS

    world = _open_corridor()
    ex = Executive(world, "F a", known=True)
    ex.omap = _Returns(np.zeros((0, 2)))
    ex.tick({"stamp": 0.0, "x": 0.5, "y": 0.75, "theta": 0.0}, now=0.0)
    field = ex._field(ex.leg[ex.wp])
    cmd = Command(0.0, 0.0, 0.0, True)
    p = (0.88, 0.75, 0.0)
    for k, spot in enumerate([(1.0, 0.75), (1.0, 0.76), (1.01, 0.75)]):
        ex.time += 5.0
        ex._blocker, ex._held = spot, GUARD_HOLD_TICKS
        ex._need_plan = False
        out = ex._slid(p, field, cmd)
        assert out is not None and out.omega != 0.0 and out.v >= 0.0
        phantoms = [key for key in ex._model if key[0] == "guard"]
        assert len(phantoms) == (0 if k == 0 else 1)
        assert ex._need_plan == (k == 1)
    assert ex.forest is not None and len(ex.forest.obstacles) == len(world.obstacles)


def test_motion_guard_ignores_returns_inside_an_estimate():
    # the same wall, covered by an estimate (its face on the returns): the navigation function
    # keeps the robot off it; the guard must not close a narrow passage
    from navigation.geometry import Squircle

    world = _open_corridor()
    ex = Executive(world, "F b", known=True)
    ys = np.linspace(-1.0, 1.0, 401)
    wall = Squircle((1.1, 0.0), 0.2, 2.4, 0.0, 0.99)
    ex.omap = _Returns(np.stack((np.full_like(ys, 1.0), ys), 1), [wall])
    p = (1.0 - ex.radius - 0.01, 0.0, 0.0)
    assert ex._guard(p, 0.5, 0.0) == 0.5
    # moved 1 cm back, the face leaves the returns 1 cm outside it: the guard acts again
    ex.omap = _Returns(np.stack((np.full_like(ys, 1.0), ys), 1), [Squircle((1.11, 0.0), 0.2, 2.4, 0.0, 0.99)])
    assert ex._guard(p, 0.5, 0.0) < 0.5


def test_motion_guard_off():
    world = _open_corridor()
    ex = Executive(world, "F b", known=True, config=ExecutiveConfig(guard_margin=None))
    ys = np.linspace(-1.0, 1.0, 401)
    ex.omap = _Returns(np.stack((np.full_like(ys, 1.0), ys), 1))
    assert ex._guard((1.0 - ex.radius - 0.005, 0.0, 0.0), 0.5, 0.0) == 0.5


# ---------------------------------------------------------------------- short edges, commitment
def test_subdivide_cuts_long_segments_into_equal_parts_on_the_segment():
    """``_subdivide``: ends kept, every part at most ``max_len`` (and the fewest such equal
    parts), every new point on its segment."""
    from tamp.executive import _subdivide

    rng = np.random.default_rng(5)
    for _ in range(200):
        wps = tuple((float(x), float(y), float(t)) for x, y, t in rng.uniform(-3, 3, size=(int(rng.integers(2, 6)), 3)))
        max_len = float(rng.uniform(0.1, 1.5))
        out = _subdivide(wps, max_len)
        assert out[0] == wps[0] and out[-1] == wps[-1]
        pts = np.array([w[:2] for w in out])
        assert np.all(np.linalg.norm(np.diff(pts, axis=0), axis=1) <= max_len + 1e-9)
        k = 0
        for a, b in zip(wps, wps[1:]):
            d = math.dist(a[:2], b[:2])
            n = max(1, math.ceil(d / max_len - 1e-9))
            assert out[k + n] == tuple(b)
            for j in range(1, n):  # on the segment, evenly spaced
                assert np.allclose(out[k + j][:2], np.add(a[:2], j / n * np.subtract(b[:2], a[:2])), atol=1e-12)
            k += n
        assert k == len(out) - 1
    assert _subdivide(((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)), 0.0 + 2.0) == ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))


def _open_two_regions(task: str) -> World:
    return World.from_dict({
        "name": "open", "workspace": {"center": [2.0, 1.5], "width": 4.0, "height": 3.0, "s": 0.99},
        "obstacles": [],
        "regions": {"a": {"center": [0.6, 1.5], "radius": 0.15}, "b": {"center": [3.4, 1.5], "radius": 0.15}},
        "robot": {"radius": 0.1, "start": [1.9, 1.5, 3.14159], "v_max": 0.5, "omega_max": 1.5},
        "lidar": {"range": 1.5, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10},
        "task": task})


def test_leg_waypoints_are_at_most_max_segment_apart():
    world = _open_two_regions("F a")
    for max_seg in (0.4, 0.25):
        ex = Executive(world, known=True, config=ExecutiveConfig(max_segment=max_seg))
        ex.tick(tuple(world.robot.start))
        assert ex.leg and ex.target == "a"
        pts = np.array([w[:2] for w in ex.leg])
        gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        assert np.all(gaps <= max_seg + 1e-9) and len(ex.leg) >= math.ceil(1.3 / max_seg) + 1
    ex = Executive(world, known=True, config=ExecutiveConfig(max_segment=0.0))
    ex.tick(tuple(world.robot.start))
    assert len(ex.leg) == 2  # the tree's own waypoints: one straight edge


@pytest.mark.parametrize("discount,expected", [(0.2, "a"), (0.0, "b")])
def test_replan_between_regions_keeps_the_committed_region_unless_much_cheaper(discount, expected):
    """``F a | F b``: the robot heads for the nearer ``a``; re-planned from a pose (facing
    neither region, so the turns cost the same) 7 % nearer to ``b``, it keeps ``a`` with the
    commitment discount and turns to ``b`` without it."""
    world = _open_two_regions("F a | F b")
    ex = Executive(world, known=True, config=ExecutiveConfig(commit_discount=discount))
    ex.tick((1.9, 1.5, math.pi))
    assert ex.target == "a"
    p = (2.05, 1.5, math.pi / 2)  # 1.45 m to a's centre, 1.35 m to b's
    ex._need_plan = True
    ex.tick(p)
    assert ex.state is ExecutiveState.EXECUTING and ex.target == expected


def test_commit_discount_is_validated():
    for bad in (-0.1, 1.0, float("nan"), "0.2"):
        with pytest.raises(TampError, match="commit_discount"):
            ExecutiveConfig(commit_discount=bad)
    with pytest.raises(TampError, match="max_segment"):
        ExecutiveConfig(max_segment=-1.0)


def test_a_waypoint_is_passed_within_the_tolerance_or_beyond_its_line():
    """``_passed``: within ``waypoint_tolerance``, or within ``pass_beyond`` and beyond the line
    through the waypoint across its heading; ``pass_beyond=0``: the tolerance only."""
    world = _open_two_regions("F a")
    wp = (2.0, 1.5, math.pi / 2)  # heading +y: "beyond" is y >= 1.5
    ex = Executive(world, known=True)
    tol = ex.config.waypoint_tolerance
    assert ex._passed(np.array([2.1, 1.45]), wp, tol)  # within 0.15 m, before the line
    assert ex._passed(np.array([2.25, 1.55]), wp, tol)  # 0.25 m to the side, beyond
    assert not ex._passed(np.array([2.2, 1.4]), wp, tol)  # 0.22 m, before the line
    assert not ex._passed(np.array([2.4, 1.6]), wp, tol)  # beyond, but 0.41 m away
    plain = Executive(world, known=True, config=ExecutiveConfig(pass_beyond=0.0))
    assert not plain._passed(np.array([2.25, 1.55]), wp, tol)
    assert plain._passed(np.array([2.1, 1.45]), wp, tol)


@pytest.mark.parametrize("angle, hold", [(math.pi / 3, 2.0), (math.pi / 3, 0.2), (0.0, 2.0)])
def test_turning_onto_a_leg_on_the_spot(angle, hold):
    """``align_angle`` / ``align_time``: a robot 80 degrees off its leg (inside eq. 24a's
    90-degree gate, so eq. 24 alone drives off at once, on a curve) first turns on the spot
    until within ``align_angle``, for at most ``align_time`` seconds; then eq. 24 as usual. (The
    pursuit's own narrower gate, ``pursuit_gate``, would hold the robot beyond 60 degrees
    whatever the rule: eq. 24a's gate here, to test the rule alone.)"""
    world = _open_two_regions("F a")  # a is straight ahead to the west (heading pi)
    unlimited = dataclasses.replace(ExecutiveConfig().controller, **UNLIMITED)  # off with the rate limit
    cfg = ExecutiveConfig(align_angle=angle, align_time=hold, controller=unlimited, pursuit_gate=math.pi / 2)
    ex = Executive(world, known=True, config=cfg)
    x, y, _ = world.robot.start
    theta = math.pi - math.radians(80)
    t, dt, moved_at = 0.0, 0.1, None
    for _ in range(40):
        res = ex.tick((x, y, theta), now=t)
        assert math.isfinite(res.v) and math.isfinite(res.omega)
        err = abs(math.remainder(math.pi - theta, 2 * math.pi))
        if res.v > 1e-9 and moved_at is None:
            moved_at = (t, err)
        if moved_at is None and angle:
            assert res.omega > 0  # turning towards the leg (counter-clockwise)
        x += res.v * dt * math.cos(theta)
        y += res.v * dt * math.sin(theta)
        theta += res.omega * dt
        t += dt
    assert moved_at is not None
    t_move, err_move = moved_at
    if angle == 0.0:
        assert t_move == 0.0  # eq. 24 alone: off at once
    elif hold == 2.0:
        assert err_move <= angle + 0.05 and t_move > 0.0  # turned first (the field is near the leg's line)
    else:
        assert err_move > angle and t_move == pytest.approx(hold, abs=0.11)  # released by the time bound
    assert ex.state is not ExecutiveState.BLOCKED


def test_turning_onto_a_leg_is_validated_and_off_in_the_rate_limited_mode():
    with pytest.raises(TampError, match="align_angle"):
        ExecutiveConfig(align_angle=math.pi / 2)
    with pytest.raises(TampError, match="align_angle"):
        ExecutiveConfig(align_angle=-0.1)
    with pytest.raises(TampError, match="align_time"):
        ExecutiveConfig(align_time=-1.0)
    world = _open_two_regions("F a")
    from navigation.control import RATE_LIMITED, ControllerConfig

    ex = Executive(world, known=True, config=ExecutiveConfig(controller=ControllerConfig(**RATE_LIMITED)))
    x, y, _ = world.robot.start
    ex.tick((x, y, math.pi - math.radians(80)), now=0.0)
    assert ex._align_until == -math.inf


@pytest.mark.parametrize("stuck_time", [6.0, 3.0, 0.0])
def test_no_progress_towards_a_waypoint_re_plans_from_where_the_robot_is(stuck_time):
    """Progress watchdog (``stuck_time`` / ``stuck_progress``): a robot that does not come
    closer to its waypoint (here it is held in place while commanded forward, so neither the
    stall guard nor arrival fires) is re-planned from where it is once ``stuck_time`` seconds
    have passed, and again after each further ``stuck_time``; ``stuck_time = 0`` never
    (``route_rescue`` off: with it the first firing follows a tree instead, test below)."""
    world = _open_two_regions("F a")
    ex = Executive(world, known=True, config=ExecutiveConfig(stuck_time=stuck_time, route_rescue=False))
    x, y, _ = world.robot.start
    pose = (x, y, math.pi)  # facing region a: eq. 24 drives forward
    fired = []
    for k in range(101):
        t = 0.1 * k
        before = len(ex.replan_times)
        res = ex.tick(pose, now=t)
        assert math.isfinite(res.v) and math.isfinite(res.omega)
        assert res.v > 0.0 or ex._need_plan or len(ex.replan_times) > before
        if len(ex.replan_times) > before:
            fired.append(round(t, 1))
    notes = [m for m in ex.messages if "no progress" in m]
    if stuck_time == 0.0:
        assert not fired and not notes
    else:
        assert len(notes) == len(fired) == int(10.0 // (stuck_time + 0.1))
        assert fired[0] == pytest.approx(stuck_time + 0.1, abs=0.11)  # noted on one tick, re-planned on the next
    assert ex.state is ExecutiveState.EXECUTING


def test_with_route_rescue_the_watchdog_first_follows_a_tree_to_the_waypoint_then_re_plans():
    """``route_rescue``: the first time the watchdog fires on a waypoint, the tracker gets a
    harmonic tree from the robot to that waypoint (``Tracker.rescue``, pursued along its
    segments) instead of a re-plan; if the robot still makes no progress, the next firing
    re-plans as without the option. Held in place as in the test above (the crawl guard,
    seeing the robot crawl, may ask for routes of its own too)."""
    world = _open_two_regions("F a")
    ex = Executive(world, known=True, config=ExecutiveConfig(stuck_time=3.0, route_rescue=True))
    x, y, _ = world.robot.start
    pose = (x, y, math.pi)
    events = []
    for k in range(80):
        before, routes = len(ex.replan_times), ex._tracker.routes
        res = ex.tick(pose, now=0.1 * k)
        assert math.isfinite(res.v) and math.isfinite(res.omega)
        if ex._tracker.routes > routes:
            events.append("route")
        if len(ex.replan_times) > before and k > 0:
            events.append("re-plan")
    notes = [m for m in ex.messages if "no progress" in m]
    assert events[0] == "route" and "re-plan" in events, events  # (the crawl guard may add routes)
    assert "following a harmonic tree" in notes[0] and "re-planning" in notes[1]
    assert ex.rescues >= 1 and ex.state is ExecutiveState.EXECUTING
    with pytest.raises(TampError, match="route_rescue"):
        ExecutiveConfig(route_rescue=1)


def test_progress_watchdog_settings_are_validated():
    for name in ("stuck_time", "stuck_progress"):
        with pytest.raises(TampError, match=name):
            ExecutiveConfig(**{name: -1.0})
        with pytest.raises(TampError, match=name):
            ExecutiveConfig(**{name: float("nan")})


def test_a_scan_is_integrated_at_its_own_pose_by_tick_and_by_observe():
    """``sensor_pose`` integrates a scan at the pose of its stamp while the command is for the
    newer pose (perception refuses the pair otherwise); ``observe`` integrates one between
    ticks and the next tick reports the map change. Both give the map a tick at the scan's
    own pose gives."""
    world = shared_world("office")
    sim = Simulator(world, seed=0)
    pose0, scan0 = sim.pose_message(), sim.scan_message()
    sim.step((0.3, 0.2))
    pose1 = sim.pose_message()

    ref = Executive(world)
    ref.tick(pose0, scan=scan0, now=pose0["stamp"])
    assert ref.map_changes == 1 and ref.obstacles

    skewed = Executive(world)
    skewed.tick(pose1, scan=scan0, now=pose1["stamp"])  # the scan paired with the wrong pose
    assert skewed.map_changes == 0 and any("max_stamp_skew" in m for m in skewed.messages)

    ex = Executive(world)
    res = ex.tick(pose1, scan=scan0, now=pose1["stamp"], sensor_pose=pose0)
    assert res.map_changed and not any("input dropped" in m for m in ex.messages)
    assert ex.obstacles == ref.obstacles
    assert math.isfinite(res.v) and math.isfinite(res.omega)

    ob = Executive(world)
    assert ob.observe(pose0, scan=scan0, now=pose1["stamp"]) is True
    assert ob.obstacles == ref.obstacles
    assert ob.tick(pose1, now=pose1["stamp"]).map_changed  # reported once, by the next tick
    assert not ob.tick(pose1, now=pose1["stamp"]).map_changed
    assert ob.observe(pose0, scan=scan0, now=pose1["stamp"]) is False  # the same scan: nothing new
    assert ob.observe({"x": "nan"}, scan=scan0) is False and "input dropped: sensor pose" in ob.messages[-1]
