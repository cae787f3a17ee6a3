"""Closed-loop guarantees of issue 4: oriented field + controller + simulator, all obstacles known.

The controller is :class:`navigation.Tracker`, eq. 24-25 (:func:`navigation.track_waypoints`)
with the crawl guard that engages the stand-off while the robot crawls and changes mode when it
loops (:mod:`navigation.tracker`), as the executive drives the robot, plus the route rescue: on
every loop and every crawl engagement the tracker follows the harmonic tree from its pose
to the goal pose (:class:`tamp.routes.TreeRoutes`, its inner waypoints pursued along the tree's
straight segments, :func:`navigation.track_point`; the executive re-plans its own trees instead).

From random start poses to a random goal pose per world (dt = 0.1 s, noise-free, obstacles grown
by the robot radius for the field), the robot must

* never touch an obstacle or the boundary (the simulator's certified swept collision check),
  with every command finite and within ``v_max`` / ``omega_max`` - asserted strictly on every
  world (the controller's safety limit makes this hold whatever the field does), and, with the
  controller's default rate limit (``accel_max=1.0, alpha_max=6.0, brake_share=0.5``,
  docs/control.md "Rate-limited mode"), the bounded change per step of the issue: every command
  within 0.1 m/s and 0.6 rad/s of the previous one, from rest (``run_closed_loop``);
* end within 0.05 m and 0.1 rad of the goal pose - every run, asserted strictly (since the
  twenty-seventh session's pursued routes; before, a share of each world's runs with the
  shortfall reported as an expected failure). Next to chained walls the field's integral
  curves run in trenches the unicycle cannot follow (the open conditioning defect of issue 2,
  docs/navigation.md "Conditioning next to chained walls"); the crawl and loop guard and the
  route rescue are what make every run arrive (docs/control.md).

The same runs without the rate limit (``navigation.control.UNLIMITED``, the default until the
twenty-seventh session) assert the same, but not the bounded change.

Sizes: the default run uses a reduced sample (``simple`` 10 starts, ``office`` 5, random worlds
0-1 with 5 each); ``-m slow`` runs the issue's size, 100 starts on ``simple``, ``office`` and 30
random forest worlds (``tests/worldgen.py``, ``gap=0.3`` so they stay forests when grown by the
robot radius). ``cluttered20`` is not used: grown by the robot radius its obstacles 0, 1 and 2
overlap in a cycle, which a forest of stars cannot represent (the forest construction refuses
it, see tests/test_forest.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import navigation
from navigation.control import UNLIMITED, ControllerConfig
from navigation.tracker import Tracker
from navigation.oriented import OrientedField
from tamp.routes import TreeRoutes

from .conftest import shared_world
from .test_control import run_closed_loop
from .worldgen import random_forest_world, random_free_points

MAX_TIME, DT = 120.0, 0.1  # simulated seconds per run, control period
FAST = [("simple", 10), ("office", 5), ("random0", 5), ("random1", 5)]
FAST_UNLIMITED = [("simple", 10), ("random0", 5)]
SLOW = [("simple", 100), ("office", 100)] + [(f"random{s}", 100) for s in range(30)]


def _world(name: str):
    if name.startswith("random"):
        return random_forest_world(int(name[len("random"):]), gap=0.3)
    return shared_world(name)


def _check_world(name: str, n_starts: int, mode: dict | None = None):
    world = _world(name)
    rng = np.random.default_rng(7)
    r = world.robot.radius
    cfg = ControllerConfig.from_robot(world.robot, **(mode or {}))
    goal = random_free_points(world, 1, rng, margin=r + 0.2)[0]
    field = OrientedField(navigation.NavigationFunction(world, goal=goal, inflation=r),
                          heading=rng.uniform(-math.pi, math.pi))
    failures = []
    routes = TreeRoutes(world)
    for s in random_free_points(world, n_starts, rng, margin=r + 0.05):
        start = (float(s[0]), float(s[1]), float(rng.uniform(-math.pi, math.pi)))
        reached, sim = run_closed_loop(world, field, start, cfg, max_steps=int(round(MAX_TIME / DT)),
                                       tracker=Tracker(cfg, route=routes))
        assert sim.metrics.min_clearance > 0.0 and not sim.metrics.collisions
        if not reached:
            failures.append(f"from {np.round(start, 3).tolist()} ended at {np.round(sim.pose, 3).tolist()}")
    assert not failures, (f"{name}: {len(failures)}/{n_starts} runs did not reach {field} within {MAX_TIME:.0f} s "
                          f"(no collision): " + "; ".join(failures[:5]))


@pytest.mark.parametrize("name,n_starts", FAST, ids=[n for n, _ in FAST])
def test_reaches_goal_pose_safely(name, n_starts):
    _check_world(name, n_starts)


@pytest.mark.slow
@pytest.mark.parametrize("name,n_starts", SLOW, ids=[n for n, _ in SLOW])
def test_reaches_goal_pose_safely_full(name, n_starts):
    _check_world(name, n_starts)


@pytest.mark.parametrize("name,n_starts", FAST_UNLIMITED, ids=[n for n, _ in FAST_UNLIMITED])
def test_unlimited_mode_reaches_goal_pose_safely(name, n_starts):
    """The controller without its rate limit (``UNLIMITED``): the same guarantees but the
    bounded change."""
    _check_world(name, n_starts, UNLIMITED)


@pytest.mark.slow
@pytest.mark.parametrize("name,n_starts", SLOW, ids=[n for n, _ in SLOW])
def test_unlimited_mode_full(name, n_starts):
    _check_world(name, n_starts, UNLIMITED)
