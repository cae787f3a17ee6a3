"""The crawl guard (navigation.tracker): when it engages the controller's stand-off, and that the
tracker's commands are the controller's with or without it."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import navigation
from navigation import CrawlConfig, CrawlGuard, Tracker
from navigation.tracker import Mode
from navigation.control import (ESCAPE_BELOW, ESCAPE_SPEED, RATE_LIMITED, UNLIMITED, ControllerConfig, _band, _direction,
                                track_waypoints)
from navigation.errors import NavigationError
from navigation.oriented import OrientedField, wrap_angle
from tamp.routes import TreeRoutes

from .conftest import shared_world
from .test_control import run_closed_loop
from .worldgen import random_forest_world, random_free_points

DT = 0.1
FAR = (10.0, 10.0)  # a goal far from every position used below


def _feed(guard, positions, t0=0.0, goal=FAR):
    return [guard.update(t0 + k * DT, q, goal) for k, q in enumerate(positions)]


def test_a_robot_standing_still_engages_the_guard_after_the_window_for_hold_seconds():
    cfg = CrawlConfig(window=3.0, hold=10.0)
    g = CrawlGuard(cfg)
    on = _feed(g, [(1.0, 1.0)] * 200)
    first = on.index(True)
    assert first == 30  # 3 s of samples at 0.1 s
    assert all(on[first:first + 100])  # held for 10 s
    assert g.engagements >= 1 and g.engaged_until > 0


def test_a_moving_robot_or_one_near_its_goal_does_not_engage_it():
    g = CrawlGuard(CrawlConfig())
    assert not any(_feed(g, [(0.05 * k, 0.0) for k in range(200)]))  # 0.5 m/s
    g = CrawlGuard(CrawlConfig())
    assert not any(_feed(g, [(1.0, 1.0)] * 200, goal=(1.1, 1.0)))  # within goal_radius
    g = CrawlGuard(CrawlConfig(min_progress=0.1))
    # 4 cm/s: 0.12 m per 3 s window, just above the threshold
    assert not any(_feed(g, [(0.004 * k, 0.0) for k in range(200)]))
    g = CrawlGuard(CrawlConfig(min_progress=0.1))
    assert any(_feed(g, [(0.002 * k, 0.0) for k in range(200)]))  # 2 cm/s crawls


def test_a_pause_or_a_clock_reset_starts_the_history_over():
    g = CrawlGuard(CrawlConfig(window=3.0))
    assert not any(_feed(g, [(1.0, 1.0)] * 20))  # 2 s of standing
    # the robot was not tracked for 5 s (planning): 2 more seconds must not complete a window
    assert not any(_feed(g, [(1.0, 1.0)] * 20, t0=7.0))
    g.reset()
    assert not any(_feed(g, [(1.0, 1.0)] * 25, t0=100.0))
    assert not any(_feed(g, [(1.0, 1.0)] * 25, t0=0.0))  # time went back



def _circle(n, radius=0.2, step=0.05, centre=(1.0, 1.0)):
    """``n`` positions 0.1 s apart driving round a circle at 0.5 m/s (one lap: 1.26 m)."""
    a = step / radius
    return [(centre[0] + radius * math.cos(a * k), centre[1] + radius * math.sin(a * k)) for k in range(n)]


def test_a_loop_engages_wall_following_then_the_plain_controller_alternately():
    """Driving round a 1.26 m circle at full speed never crawls; after the first lap (at least
    ``loop_length`` of path, back within ``loop_radius``) the guard switches to wall following
    for ``hold`` seconds, at the next lap after that to the plain controller, then again to
    wall following."""
    cfg = CrawlConfig(hold=5.0)
    g = CrawlGuard(cfg)
    modes = _feed(g, _circle(400))
    first = modes.index(Mode.FOLLOW)
    assert 20 <= first <= 26 and set(modes[:first]) == {Mode.PLAIN}  # one lap: 25 steps
    assert set(modes[first:first + 50]) == {Mode.FOLLOW}  # held for 5 s
    second = first + 50 + modes[first + 50:].index(Mode.PLAIN)
    assert second == first + 50  # a lap is already behind it: detected at once
    third = second + modes[second:].index(Mode.FOLLOW)
    assert third == second + 50
    assert g.loops >= 3 and g.engagements == 0
    # never within goal_radius of the goal, nor with loop_radius = 0
    assert not any(_feed(CrawlGuard(cfg), _circle(400), goal=(1.0, 1.0)))
    assert not any(_feed(CrawlGuard(CrawlConfig(loop_radius=0.0)), _circle(400)))
    # a pause starts the loop history over: a lap split by one is not a loop
    g = CrawlGuard(cfg)
    assert not any(_feed(g, _circle(15)) + _feed(g, _circle(40)[15:], t0=10.0))


def test_a_loop_needs_the_same_heading_when_the_heading_is_known():
    """Driving out 0.6 m and back along the same line passes every point again, in the
    opposite heading: not a loop when the guard knows the heading (``loop_heading``), a
    position loop when it does not. Round a circle the heading repeats with the position."""
    line = [(1.0 + 0.05 * k, 1.0) for k in range(13)]
    out_and_back = line + line[::-1][1:]
    headings = [0.0] * 13 + [math.pi] * 12
    g = CrawlGuard(CrawlConfig())
    assert not any(g.update(k * DT, q, FAR, h) for k, (q, h) in enumerate(zip(out_and_back, headings)))
    g = CrawlGuard(CrawlConfig())
    assert any(g.update(k * DT, q, FAR) for k, q in enumerate(out_and_back))
    g = CrawlGuard(CrawlConfig())
    circle = _circle(60)
    assert Mode.FOLLOW in [g.update(k * DT, q, FAR, 0.25 * k + math.pi / 2) for k, q in enumerate(circle)]
    with pytest.raises(NavigationError, match="heading"):
        CrawlGuard().update(0.0, (1.0, 1.0), FAR, math.nan)

def test_a_loop_ends_a_crawl_engagement():
    """A robot that crawls (stand-off engaged) and then loops is switched to wall following at
    once; the loop's hold replaces the crawl's."""
    g = CrawlGuard(CrawlConfig(window=1.0, hold=30.0))
    crawl = _feed(g, [(1.0, 1.0)] * 20)
    assert crawl[-1] == Mode.STANDOFF and g.engagements == 1
    modes = _feed(g, _circle(60, centre=(1.0, 0.8)), t0=2.0)  # the circle passes through (1, 1)
    assert Mode.FOLLOW in modes and g.engaged_until == -math.inf


def test_tracker_commands_in_each_mode_are_the_controllers():
    """Wall following is the stand-off of the crawl configuration plus the turn limit."""
    cfg = ControllerConfig(**UNLIMITED)  # commands compared with the pure function of the pose
    crawl = CrawlConfig(turn=0.4)
    t = Tracker(cfg, crawl)
    assert t.config_for(Mode.PLAIN) == cfg
    assert t.config_for(Mode.STANDOFF) == replace(cfg, standoff=crawl.standoff, standoff_pull=crawl.pull,
                                                  standoff_reach=crawl.reach)
    assert t.config_for(Mode.FOLLOW) == replace(t.config_for(Mode.STANDOFF), turn_share=0.4)
    with pytest.raises(NavigationError, match="mode"):
        t.config_for(7)
    world = shared_world("simple")
    field = OrientedField(navigation.NavigationFunction(world, goal=(3.0, 2.0), inflation=world.robot.radius), 0.0)
    seen = set()
    for k, q in enumerate(_circle(120, radius=0.25, centre=(1.2, 1.2))):
        pose = (q[0], q[1], 0.2 * k + math.pi / 2)  # heading along the circle
        cmd = t.command(k * DT, pose, field)
        assert cmd == track_waypoints(pose, field, None, t.config_for(t.mode))
        assert t.engaged == (t.mode != Mode.PLAIN)
        seen.add(t.mode)
    assert Mode.FOLLOW in seen


def test_wall_following_after_a_loop_rescues_a_run_that_never_crawls():
    """random18 (``gap=0.3``), start 12 of the slow closed-loop test's sampling: the robot goes
    into the junction of a chained wall, down the wall and round its end at full speed, out
    across the open and back into the junction, round and round, never slow enough for the
    crawl guard. After the first loop the guard follows the wall flow with the turn limit, and
    the robot goes round the wall's end to the goal pose."""
    _assert_rescued(*_slow_test_case(18, 12), before=CrawlConfig(loop_radius=0.0))


@pytest.mark.parametrize("bad", [{"window": 0.0}, {"hold": -1.0}, {"min_progress": math.nan}, {"standoff": True},
                                 {"max_gap": math.inf}, {"pull": -1.0}, {"reach": 1.0}, {"reach": math.nan},
                                 {"loop_radius": -0.05}, {"loop_length": 0.0}, {"loop_window": math.inf},
                                 {"loop_heading": 0.0},
                                 {"turn": math.nan}])
def test_bad_crawl_config_is_refused(bad):
    with pytest.raises(NavigationError):
        CrawlConfig(**bad)


def test_non_finite_input_is_refused():
    g = CrawlGuard()
    with pytest.raises(NavigationError):
        g.update(0.0, (math.nan, 0.0), FAR)
    t = Tracker()
    world = shared_world("simple")
    field = OrientedField(navigation.NavigationFunction(world, goal=(3.0, 2.0), inflation=world.robot.radius), 0.0)
    with pytest.raises(NavigationError):
        t.command(0.0, (1.0, math.inf, 0.0), field)


def test_tracker_commands_are_the_controllers_with_and_without_the_stand_off():
    world = shared_world("office")
    r = world.robot.radius
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    rng = np.random.default_rng(3)
    goal = random_free_points(world, 1, rng, margin=r + 0.2)[0]
    field = OrientedField(navigation.NavigationFunction(world, goal=goal, inflation=r), heading=0.3)
    plain = Tracker(cfg, crawl=None)
    crawl = CrawlConfig(window=1.0, hold=2.0, standoff=0.04)
    guarded = Tracker(cfg, crawl)
    on_cfg = replace(cfg, standoff=0.04, standoff_pull=crawl.pull, standoff_reach=crawl.reach)
    q = random_free_points(world, 1, rng, margin=r + 0.05)[0]
    seen = set()
    for k in range(40):  # the robot stands still at q: the guard engages after 1 s
        pose = (q[0], q[1], 0.1 * k)
        assert plain.command(k * DT, pose, field) == track_waypoints(pose, field, None, cfg)
        cmd = guarded.command(k * DT, pose, field)
        assert cmd == track_waypoints(pose, field, None, on_cfg if guarded.engaged else cfg)
        seen.add(guarded.engaged)
    assert seen == {True, False}


def test_the_guard_rescues_a_run_that_crawls_with_the_plain_controller():
    """random12_seed4, start 1 of the closed-loop benchmark's sampling: the plain controller
    crawls in a trench along a chained wall and times out after 120 s; with the guard the robot
    reaches the goal pose, touching nothing."""
    world = random_forest_world(4, gap=0.3)
    r = world.robot.radius
    field = OrientedField(navigation.NavigationFunction(world, goal=(4.066351196001362, 4.563777886388609),
                                                        inflation=r), heading=-2.3589923559454644)
    start = (2.0644817134044633, 4.090604854854552, -0.30103502123228365)
    _assert_rescued(world, field, start, before=None)


def _assert_rescued(world, field, start, before: CrawlConfig | None):
    """From ``start`` the robot times out (120 s) with ``Tracker(cfg, before)`` (``None``: the
    plain controller), the failure the case is for (if the field improves, pick another case),
    and reaches the goal pose with the default ``Tracker``, whose guard engages (a crawl or a
    loop), touching nothing."""
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    reached, _ = run_closed_loop(world, field, start, cfg, max_steps=1200,
                                 tracker=None if before is None else Tracker(cfg, before))
    assert not reached
    tracker = Tracker(cfg)
    reached, sim = run_closed_loop(world, field, start, cfg, max_steps=1200, tracker=tracker)
    assert reached, f"ended at {sim.pose} after {sim.time:.1f} s"
    assert tracker.guard.engagements + tracker.guard.loops >= 1
    assert sim.metrics.min_clearance > 0.0 and not sim.metrics.collisions


def test_the_pull_keeps_the_engaged_robot_on_the_wall_round_a_convex_corner():
    """random17 (``gap=0.3``), start 2 of the slow closed-loop test's sampling: the trench runs
    from a shallow junction along the chained wall and round its convex corner. Without the
    pull (``CrawlConfig(pull=0, reach=2)``, the guard before it) the engaged robot follows the
    wall at 2.5 cm to the corner, drives along the tangent out of the 6 cm band, and the
    unmodified field takes it back to the junction, round and round until the 120 s timeout;
    with the default pull it stays on the wall round the corner and reaches the goal pose."""
    _assert_rescued(*_slow_test_case(17, 2), before=CrawlConfig(pull=0.0, reach=2.0, loop_radius=0.0))


def _slow_test_case(seed: int, index: int):
    """``(world, field, start)`` of start ``index`` on random world ``seed`` (``gap=0.3``) in
    tests/test_closed_loop.py's sampling (``default_rng(7)``: goal, heading, 100 starts, then one
    heading per start)."""
    world = random_forest_world(seed, gap=0.3)
    r = world.robot.radius
    rng = np.random.default_rng(7)
    goal = random_free_points(world, 1, rng, margin=r + 0.2)[0]
    field = OrientedField(navigation.NavigationFunction(world, goal=goal, inflation=r),
                          heading=rng.uniform(-math.pi, math.pi))
    s = random_free_points(world, 100, rng, margin=r + 0.05)[index]
    headings = rng.uniform(-math.pi, math.pi, size=index + 1)  # drawn one by one after the points
    return world, field, (float(s[0]), float(s[1]), float(headings[index]))


def test_rate_limited_tracker_starts_from_rest_follows_what_was_sent_and_restarts_after_a_gap():
    """In the rate-limited mode the tracker's first command is within one period's change of
    rest, later ones within ``accel_max dt`` / ``alpha_max dt`` of the last command or of what
    the caller reported sending (:meth:`Tracker.applied`), and after more than ``max_gap``
    seconds without a command it starts from rest again. The default mode's commands are the
    controller's, whatever came before."""
    world = shared_world("office")
    r = world.robot.radius
    field = OrientedField(navigation.NavigationFunction(world, goal=(6.4, 3.3), inflation=r), heading=0.0)
    cfg = ControllerConfig.from_robot(world.robot, **RATE_LIMITED)
    pose = (3.0, 2.2, 2.5)  # open space, facing away from the field: eq. 24 asks for a hard turn
    tr = Tracker(cfg, crawl=None)
    first = tr.command(0.0, pose, field)
    assert first.v <= 0.1 + 1e-12 and abs(first.omega) <= 0.6 + 1e-12
    second = tr.command(0.05, pose, field)
    assert abs(second.v - first.v) <= 0.05 + 1e-12 and abs(second.omega - first.omega) <= 0.3 + 1e-12
    tr.applied(0.05, 0.0, 0.0)  # the caller stopped the robot instead
    third = tr.command(0.15, pose, field)
    assert third.v <= 0.1 + 1e-12 and abs(third.omega) <= 0.6 + 1e-12
    tr.applied(0.15, 0.4, -1.0)
    late = tr.command(5.0, pose, field)  # long gap: from rest
    assert late.v <= 0.1 + 1e-12 and abs(late.omega) <= 0.6 + 1e-12
    plain = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    tr = Tracker(plain, crawl=None)
    tr.applied(0.0, 0.5, 1.5)
    assert tr.command(0.1, pose, field) == track_waypoints(pose, field, None, plain)


def test_brake_lowers_the_last_command_by_the_rate_limit_towards_rest():
    """:meth:`Tracker.brake`: ``|v|`` lowered by ``accel_max dt`` and ``|omega|`` by ``alpha_max dt``
    from the last command sent, never past 0; ``(0, 0)`` from rest, after a gap or without the
    rate limit; a non-finite time is refused."""
    cfg = ControllerConfig(v_max=0.5, omega_max=1.5, **RATE_LIMITED)  # 1 m/s^2, 6 rad/s^2
    tr = Tracker(cfg, crawl=None)
    assert tr.brake(0.0) == (0.0, 0.0)  # no command yet: at rest
    tr.applied(1.0, 0.45, -1.2)
    v, w = tr.brake(1.1)
    assert v == pytest.approx(0.35) and w == pytest.approx(-0.6)
    v, w = tr.brake(1.25)  # 0.25 s: omega reaches 0, v does not
    assert v == pytest.approx(0.2) and w == 0.0
    tr.applied(2.0, 0.05, 0.3)
    assert tr.brake(2.1) == (0.0, 0.0)  # never past rest
    tr.applied(3.0, -0.3, 0.0)
    assert tr.brake(3.1) == pytest.approx((-0.2, 0.0))  # towards rest from either side
    assert tr.brake(4.0) == (0.0, 0.0)  # after more than max_gap: from rest
    plain = Tracker(ControllerConfig(v_max=0.5, omega_max=1.5, **UNLIMITED), crawl=None)
    plain.applied(0.0, 0.5, 1.5)
    assert plain.brake(0.1) == (0.0, 0.0)
    with pytest.raises(NavigationError, match="finite"):
        tr.brake(float("nan"))


def test_smooth_moves_the_last_command_towards_the_wanted_one_by_the_rate_limit():
    """:meth:`Tracker.smooth` (the evaluation's RRT* follower sends its commands through it): each
    component moves from the last command sent by at most its limit times ``dt``, reaches the
    wanted value when that is nearer, starts from rest without a recent command, is unlimited
    where the limit is 0; :meth:`Tracker.brake` is ``smooth`` towards rest; non-finite input is
    refused."""
    cfg = ControllerConfig(v_max=0.5, omega_max=1.5, **RATE_LIMITED)  # 1 m/s^2, 6 rad/s^2
    tr = Tracker(cfg, crawl=None)
    assert tr.smooth(0.0, 0.5, 1.5) == pytest.approx((0.1, 0.6))  # from rest, one period
    tr.applied(1.0, 0.3, 0.2)
    assert tr.smooth(1.1, 0.5, -1.5) == pytest.approx((0.4, -0.4))
    assert tr.smooth(1.1, 0.32, 0.1) == pytest.approx((0.32, 0.1))  # within reach: as wanted
    assert tr.smooth(1.1, -0.1, 0.2) == pytest.approx((0.2, 0.2))  # towards reverse, one step
    assert tr.smooth(1.2, 0.0, 0.0) == tr.brake(1.2)
    assert tr.smooth(2.0, 0.5, 1.5) == pytest.approx((0.1, 0.6))  # after more than max_gap
    no_alpha = Tracker(ControllerConfig(v_max=0.5, omega_max=1.5, accel_max=1.0, alpha_max=0.0), crawl=None)
    no_alpha.applied(0.0, 0.0, 0.0)
    assert no_alpha.smooth(0.1, 0.5, -1.5) == pytest.approx((0.1, -1.5))
    plain = Tracker(ControllerConfig(v_max=0.5, omega_max=1.5, **UNLIMITED), crawl=None)
    assert plain.smooth(0.1, 0.5, 1.5) == (0.5, 1.5)
    for bad in ((float("nan"), 0.1, 0.0), (0.1, float("inf"), 0.0), (0.1, 0.0, float("nan"))):
        with pytest.raises(NavigationError, match="finite"):
            tr.smooth(*bad)


def test_the_engaged_stand_off_does_not_hold_a_robot_in_the_escape_band():
    """random13 start 8 of the slow closed-loop test: the engaged stand-off's wall flow, in the
    notch of two grown obstacles, points along the wall the robot is 25 micrometres from, where
    the isotropic safety limit allows 0.15 mm/s: the robot stood there for 100 s. Within the
    escape band the controller tracks ``Upsilon`` (away from the wall) instead, creeps out at
    ``ESCAPE_SPEED`` once it faces it, and the run reaches the goal pose, touching nothing."""
    world, field, start = _slow_test_case(13, 8)
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    engaged = Tracker(cfg).config_for(Mode.STANDOFF)
    q = np.array([3.7472, 3.8469])
    assert 0.0 < field.clearance.exact(q) < ESCAPE_BELOW
    band = _band(q, field, engaged)
    away = float(field.evaluate(q).angle)
    wall_flow = _direction(q, field, engaged, band)[0]
    assert math.cos(wrap_angle(wall_flow - away)) < math.sqrt(0.5)  # the case: along the wall
    along = track_waypoints((*q, wall_flow), field, None, engaged)
    assert along.theta_gamma == away and along.omega * wrap_angle(wall_flow - away) < 0  # turns away
    facing = track_waypoints((*q, away), field, None, engaged)
    assert facing.v == pytest.approx(ESCAPE_SPEED, rel=1e-6) and abs(facing.omega) < 0.05
    tracker = Tracker(cfg, route=TreeRoutes(world))
    reached, sim = run_closed_loop(world, field, start, cfg, max_steps=1200, tracker=tracker)
    assert reached, f"ended at {sim.pose} after {sim.time:.1f} s"
    assert sim.metrics.min_clearance > 0.0 and not sim.metrics.collisions


def test_pursue_is_track_point_rate_limited_from_the_last_command_sent():
    """``Tracker.pursue``: eq. 24 on the bearing of a point (``track_point``, the field's safety
    limit), rate-limited from the last command, which it records; the plain mode."""
    from navigation.control import track_point

    world = shared_world("simple")
    field = OrientedField(navigation.NavigationFunction(world, goal=(3.0, 2.0), inflation=world.robot.radius), 0.0)
    cfg = ControllerConfig.from_robot(world.robot, **RATE_LIMITED)
    tr = Tracker(cfg)
    pose, point = (1.0, 1.0, 0.0), np.array([1.2, 1.3])
    first = tr.pursue(0.0, pose, point, field, beyond=0.5)
    assert first == track_point(pose, point, field, cfg, previous=(0.0, 0.0, 0.1), beyond=0.5)
    assert tr.mode is Mode.PLAIN
    second = tr.pursue(0.1, pose, point, field)
    assert second == track_point(pose, point, field, cfg, previous=(first.v, first.omega, 0.1))
    assert abs(second.omega - first.omega) <= cfg.alpha_max * 0.1 + 1e-12
