"""Route rescue: :class:`tamp.routes.TreeRoutes` and :class:`navigation.Tracker` with ``route=``.

The planner's unit checks (the route ends at the goal pose, every segment is safe at the buffer
it was planned with, the buffer fallback, a walled-off goal, bad input) and the tracker's (a
route is planned on a loop or on every ``route_crawls``-th crawl engagement, its waypoints are
tracked with eq. 25 and the caller's field takes over for the last one, a new goal drops it,
a malformed route is refused), then two closed-loop cases of the slow test's sampling that time
out without a route and reach the goal pose with one.
"""

from __future__ import annotations

import contextlib
import math

import numpy as np
import pytest

import navigation
import tamp.roadmap
from navigation import CrawlConfig, Tracker
from navigation.tracker import Mode
from navigation.control import RATE_LIMITED, UNLIMITED, ControllerConfig
from navigation.errors import NavigationError, TampError
from navigation.oriented import OrientedField
from tamp.roadmap import segments_clear
from tamp.routes import ROUTE_BUFFERS, TreeRoutes

from .conftest import shared_world
from .test_control import run_closed_loop
from .test_tracker import DT, _circle, _slow_test_case


def _field(world, goal, heading):
    return OrientedField(navigation.NavigationFunction(world, goal=goal, inflation=world.robot.radius), heading)


def test_a_route_ends_at_the_goal_pose_and_is_safe_at_its_buffer():
    world = shared_world("office")
    routes = TreeRoutes(world)
    start, goal = (1.0, 1.0, 0.3), (6.4, 3.3, -1.0)
    wps = routes(start, goal)
    assert wps is not None and len(wps) >= 2
    assert np.allclose(wps[-1], goal)
    assert routes.last_buffer == ROUTE_BUFFERS[0]
    rm = routes.roadmap(routes.last_buffer)
    pts = np.array([start[:2]] + [w[:2] for w in wps])
    # every segment between roadmap vertices (not the terminal ones, checked at the terminal
    # rule's levels) misses the buffered obstacles
    assert len(pts) > 3 and segments_clear(rm.P, pts[1:-2], pts[2:-1]).all()


def test_a_pose_pinned_at_a_grown_boundary_gets_a_route_at_buffer_zero():
    """random25 start 18's end of run without a route: held by the safety limit 10 micrometres
    from the grown boundary in a concave notch, no edge to a vertex is safe at any positive
    buffer."""
    world, field, _ = _slow_test_case(25, 18)
    pinned = (1.3228284203082907, 2.0657709913346642, -1.2305517585736307)  # 10.0 um from it
    assert 0.0 < field.clearance.exact(pinned[:2]) < 2e-5
    routes = TreeRoutes(world)
    wps = routes(pinned, (*field.goal, field.heading))
    assert wps is not None and routes.last_buffer == 0.0
    assert TreeRoutes(world, buffers=(0.15, 0.03))(pinned, (*field.goal, field.heading)) is None


def test_a_walled_off_goal_has_no_route():
    world = shared_world("office")
    routes = TreeRoutes(world)
    inside = tuple(float(v) for v in world.obstacles[0].center)
    assert routes((1.0, 1.0, 0.0), (*inside, 0.0)) is None
    assert routes.last_buffer is None


def test_a_buffer_the_workspace_has_no_room_for_is_skipped():
    world = shared_world("simple")
    routes = TreeRoutes(world, buffers=(100.0, 0.0))
    wps = routes((1.0, 1.0, 0.0), (3.0, 2.0, 0.5))
    assert wps is not None and routes.last_buffer == 0.0 and np.allclose(wps[-1], (3.0, 2.0, 0.5))
    assert routes((1.0, 1.0, 0.0), (3.0, 2.0, 0.5)) == wps  # the buffer without room is not retried
    assert TreeRoutes(world, buffers=(100.0,))((1.0, 1.0, 0.0), (3.0, 2.0, 0.5)) is None


@pytest.mark.parametrize("bad", [(), (math.nan,), (-0.1,), "x", None])
def test_bad_route_buffers_are_refused(bad):
    with pytest.raises(TampError):
        TreeRoutes(shared_world("simple"), buffers=bad)


class _Scripted:
    """A route planner that returns a fixed route and records its calls."""

    def __init__(self, route):
        self.route = route
        self.calls = []

    def __call__(self, pose, goal):
        self.calls.append((pose, goal))
        return self.route


def test_every_third_crawl_engagement_plans_a_route_that_is_tracked_waypoint_by_waypoint():
    world = shared_world("office")
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    field = _field(world, (6.4, 3.3), 0.0)
    planner = _Scripted([(3.0, 2.2, 0.0), (5.0, 3.0, 0.5), (9.0, 9.0, 9.0)])  # the last pose is replaced
    crawl = CrawlConfig(window=1.0, hold=1.0, route_crawls=3)
    t = Tracker(cfg, crawl, route=planner)
    k = 0
    while t.guard.engagements < crawl.route_crawls:  # standing still: the guard engages every 1-2 s
        assert t.route == () and not planner.calls
        t.command(k * DT, (1.0, 1.0, 0.0), field)
        k += 1
    t.command(k * DT, (1.0, 1.0, 0.0), field)
    assert len(planner.calls) == 1 and t.routes == 1
    assert planner.calls[0][1] == (6.4, 3.3, 0.0)
    assert t.route == ((3.0, 2.2, 0.0), (5.0, 3.0, 0.5), (6.4, 3.3, 0.0))
    # the command pursues the first waypoint (route_pursuit), beyond = the rest of the route
    rest = math.dist((3.0, 2.2), (5.0, 3.0)) + math.dist((5.0, 3.0), (6.4, 3.3))
    assert t.command(k * DT, (1.0, 1.0, 0.0), field) == navigation.track_point(
        (1.0, 1.0, 0.0), (3.0, 2.2), field, cfg, beyond=rest)
    assert t.mode is Mode.PLAIN
    # within route_tolerance of a waypoint the next one is tracked; the last is the caller's field
    t.command((k + 1) * DT, (3.05, 2.2, 0.0), field)
    assert t.route[0] == (5.0, 3.0, 0.5)
    t.command((k + 2) * DT, (5.0, 3.02, 0.0), field)
    assert t.route == ((6.4, 3.3, 0.0),)
    # a new goal drops the route and the failures so far
    other = _field(world, (6.0, 1.0), 1.0)
    t.command((k + 3) * DT, (5.0, 3.02, 0.0), other)
    assert t.route == () and len(planner.calls) == 1


@pytest.mark.parametrize("deviation", [0.3, 0.0], ids=["default", "off"])
def test_a_robot_that_strays_from_its_route_gets_a_new_one_from_where_it_is(deviation):
    """More than ``route_deviation`` (0.3 m) from the segment it follows (from the pose the
    route was planned at to the next waypoint), at least one guard window after the last
    route, the tracker plans a new route from the robot's pose (``route_strays``); with 0,
    never."""
    world = shared_world("office")
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    field = _field(world, (6.4, 3.3), 0.0)
    planner = _Scripted([(3.0, 2.2, 0.0), (5.0, 3.0, 0.5), (9.0, 9.0, 9.0)])
    crawl = CrawlConfig(window=1.0, hold=1.0, route_crawls=1)
    t = Tracker(cfg, crawl, route=planner, route_deviation=deviation)
    k = 0
    while not planner.calls:  # standing still until a crawl asks for the first route
        t.command(k * DT, (1.0, 1.0, 0.0), field)
        k += 1
    planned_at = (k - 1) * DT
    a, b = np.array([1.0, 1.0]), np.array([3.0, 2.2])
    u = (b - a) / np.linalg.norm(b - a)
    for j in range(1, 16):  # driving along +x at 0.5 m/s (no crawl): away from the segment
        q = np.array([1.0 + 0.05 * j, 1.0])
        off = abs(float(u[0] * (q - a)[1] - u[1] * (q - a)[0]))  # distance from the segment's line
        t.command((k - 1 + j) * DT, (q[0], q[1], 0.0), field)
        if deviation and off > deviation and (j * DT) >= crawl.window - 1e-9:
            break
    assert t.guard.engagements == 1  # no crawl: the planner was asked again only for the stray
    if deviation:
        assert len(planner.calls) == 2 and t.route_strays == 1 and t.routes == 2
        assert planner.calls[1][0][:2] == (q[0], q[1]) and (k - 1 + j) * DT - planned_at >= crawl.window - 1e-9
        assert t.route[0] == (3.0, 2.2, 0.0)  # the new route, tracked from the start
    else:
        assert len(planner.calls) == 1 and t.route_strays == 0


@pytest.mark.parametrize("alternate", [True, False], ids=["alternate", "guard-mode"])
def test_odd_numbered_routes_are_followed_with_the_plain_controller(alternate):
    """``CrawlConfig.route_alternate`` (routes tracked with fields, ``route_pursuit=False``):
    the first route (asked for by a crawl, which engages the
    stand-off) is followed with the plain controller, the second in the guard's mode; the
    caller's field after a route is tracked in the guard's mode again. Off: every route in the
    guard's mode."""
    world = shared_world("office")
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    field = _field(world, (6.4, 3.3), 0.0)
    planner = _Scripted([(3.0, 2.2, 0.0), (9.0, 9.0, 9.0)])
    t = Tracker(cfg, CrawlConfig(window=1.0, hold=2.0, route_crawls=1, route_pursuit=False, route_alternate=alternate),
                route=planner)
    k, modes = 0, {}
    pose = (1.0, 1.0, 0.0)  # standing still: a crawl every window, each asking for a route
    while t.routes < 2:
        cmd = t.command(k * DT, pose, field)
        if t.routes:
            modes.setdefault(t.routes, t.mode)
            assert t.guard.engaged_until > k * DT  # the crawl engaged the stand-off ...
            assert cmd == navigation.track_waypoints(pose, t._route_field(0), field, t.config_for(t.mode),
                                                     beyond=math.dist((3.0, 2.2), (6.4, 3.3)))
        k += 1
    assert modes == ({1: Mode.PLAIN, 2: Mode.STANDOFF} if alternate else {1: Mode.STANDOFF, 2: Mode.STANDOFF})
    t.command(k * DT, (3.0, 2.25, 0.0), field)  # the route's waypoint passed: the caller's field
    assert t.route == ((6.4, 3.3, 0.0),) and t.mode is Mode.STANDOFF


@pytest.mark.parametrize("reach", [0.5, 0.0], ids=["default", "off"])
def test_the_goal_of_a_route_is_pursued_until_the_robot_is_near_it(reach):
    """``route_goal`` (0.5 m): after the route's inner waypoints the goal position is pursued
    too, until the robot first comes within ``route_goal`` of it; from then on (and with 0,
    all along) the caller's field leads to the goal pose, even if the robot leaves that disc."""
    world = shared_world("office")
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    field = _field(world, (6.4, 3.3), 0.0)
    planner = _Scripted([(9.0, 9.0, 9.0)])  # the goal pose alone (replaced by the caller's)
    t = Tracker(cfg, CrawlConfig(window=1.0, hold=1.0, route_crawls=1), route=planner, route_goal=reach)
    k = 0
    while not t.routes:
        t.command(k * DT, (5.0, 2.0, 0.0), field)
        k += 1
    for pose, pursued in [((5.0, 2.0, 0.0), True), ((6.1, 3.0, 0.5), False), ((5.0, 2.0, 0.0), False)]:
        cmd = t.command(k * DT, pose, field)
        k += 1
        want = (navigation.track_point(pose, (6.4, 3.3), field, cfg) if pursued and reach
                else navigation.track_waypoints(pose, field, None, t.config_for(t.mode)))
        assert cmd == want and t.route == ((6.4, 3.3, 0.0),)


def test_rescue_plans_a_route_now_that_is_pursued_like_the_guards():
    """``Tracker.rescue``: a caller's own failure detector (the executive's progress watchdog)
    gets a route from the pose to the field's goal at once, pursued by ``command`` as a route
    the guard asked for (bearing of its first inner waypoint); a new goal drops it; without a
    planner, or when the planner finds none, nothing changes and it says so."""
    world = shared_world("office")
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    field = _field(world, (6.4, 3.3), 0.0)
    pose = (5.0, 2.0, 0.0)
    assert not Tracker(cfg).rescue(0.0, pose, field)  # no planner
    none = _Scripted(None)
    t = Tracker(cfg, route=none)
    assert not t.rescue(0.0, pose, field) and t.route_misses == 1 and not t.route
    planner = _Scripted([(5.5, 2.0, 0.0), (9.0, 9.0, 9.0)])
    t = Tracker(cfg, route=planner)
    assert t.rescue(0.0, pose, field) and t.routes == 1
    assert planner.calls == [(pose, (6.4, 3.3, 0.0))]
    assert t.route == ((5.5, 2.0, 0.0), (6.4, 3.3, 0.0))
    cmd = t.command(DT, pose, field)
    assert cmd == navigation.track_point(pose, (5.5, 2.0), field, cfg, beyond=float(np.hypot(0.9, 1.3)))
    assert t.mode is Mode.PLAIN
    other = _field(world, (1.0, 1.0), 0.0)
    assert t.command(2 * DT, pose, other) == navigation.track_waypoints(pose, other, None, cfg) and not t.route


def test_a_pursued_waypoint_is_passed_near_the_segment_to_the_next_one():
    """``Tracker._passable``: a pursued waypoint within ``route_tolerance`` counts as passed once
    the robot is within ``PASS_CLOSE`` (3 cm) of the route's segment from it to the next one
    (at the waypoint, beside the segment, or past it), not while it is off to the side."""
    close = navigation.tracker.PASS_CLOSE
    here, after = (1.0, 1.0, 0.0), (2.0, 1.0, 0.0)
    for q, passed in [((1.0, 1.0), True), ((0.9, 1.0 + 0.9 * close), False), ((1.1, 1.0 + 0.9 * close), True),
                      ((1.1, 1.0 - 1.1 * close), False), ((1.0 - 0.9 * close, 1.0), True), ((1.0, 1.1), False)]:
        assert Tracker._passable(np.array(q), here, after) is passed, q
    assert Tracker._passable(np.array([1.01, 1.0]), here, here)  # a zero-length segment: the waypoint


def _fails_then_arrives(seed: int, index: int, mode, failing, monkeypatch=None, patched=()):
    """Start ``index`` of random world ``seed`` in the slow test's sampling, with the controller
    ``ControllerConfig.from_robot(robot, **mode)``: times out (120 s) with the tracker
    ``failing(cfg, routes)`` builds (with ``monkeypatch.setattr(*p)`` for each ``p`` in
    ``patched`` during that run) and reaches the goal pose with ``Tracker(cfg, route=routes)``,
    touching nothing. Returns the failing tracker."""
    world, field, start = _slow_test_case(seed, index)
    cfg = ControllerConfig.from_robot(world.robot, **mode)
    routes = TreeRoutes(world)
    bad = failing(cfg, routes)
    with monkeypatch.context() if patched else contextlib.nullcontext() as m:
        for p in patched:
            m.setattr(*p)
        reached, _ = run_closed_loop(world, field, start, cfg, max_steps=1200, tracker=bad)
    assert not reached  # the failure the case is for (if the field improves, pick another case)
    tracker = Tracker(cfg, route=routes)
    reached, sim = run_closed_loop(world, field, start, cfg, max_steps=1200, tracker=tracker)
    assert reached, f"ended at {sim.pose} after {sim.time:.1f} s"
    assert tracker.routes >= 1 and sim.metrics.min_clearance > 0.0 and not sim.metrics.collisions
    return bad


def test_a_pursued_route_round_a_corner_rescues_a_rate_limited_run(monkeypatch):
    """random23 start 61 of the slow test's sampling, in the rate-limited mode: the route's first
    waypoint is 9 cm from the robot, so within ``route_tolerance`` at once, and the second lies
    behind the corner of a wall; pursued from there its bearing leads into the wall, and the
    robot, held by the safety limit, turns back and forth in the escape band until the 120 s
    limit (as when every waypoint within the tolerance counts as passed, ``PASS_CLOSE`` above
    it). With the pass rule it first reaches the route's segment, then the goal pose."""
    _fails_then_arrives(23, 61, RATE_LIMITED, lambda cfg, routes: Tracker(cfg, route=routes), monkeypatch,
                        [(navigation.tracker, "PASS_CLOSE", 1.0)])


def test_a_loop_plans_a_route_and_no_route_leaves_the_callers_field():
    world = shared_world("office")
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    field = _field(world, (6.4, 3.3), 0.0)
    planner = _Scripted(None)
    t = Tracker(cfg, CrawlConfig(), route=planner)
    for k, q in enumerate(_circle(200, centre=(2.0, 2.0))):  # far from the goal: a loop every lap
        pose = (q[0], q[1], 0.25 * k + math.pi / 2)
        assert t.command(k * DT, pose, field) == navigation.track_waypoints(pose, field, None, t.config_for(t.mode))
    assert t.guard.loops >= 2 and len(planner.calls) == t.guard.loops
    assert t.routes == 0 and t.route_misses == len(planner.calls) and t.route == ()


def test_a_route_through_an_obstacle_is_dropped():
    world = shared_world("office")
    cfg = ControllerConfig.from_robot(world.robot, **UNLIMITED)
    field = _field(world, (6.4, 3.3), 0.0)
    t = Tracker(cfg, CrawlConfig(window=1.0, hold=1.0, route_crawls=1), route=_Scripted([(4.5, 2.6, 0.5), (0, 0, 0)]))
    for k in range(40):  # (4.5, 2.6) lies in a grown obstacle: no field leads there
        pose = (1.0, 1.0, 0.0)
        assert t.command(k * DT, pose, field) == navigation.track_waypoints(pose, field, None, t.config_for(t.mode))
    assert t.routes >= 1 and t.route_misses == t.routes and t.route == ()


@pytest.mark.parametrize("route", [[(1.0, math.nan, 0.0)], [], [(1.0, 2.0)], [(1.0, 2.0), (3.0, 4.0), (5.0, 6.0)],
                                   "abc", [(1.0, 2.0, 0.0), (3.0, 4.0)]])
def test_a_malformed_route_is_refused(route):
    world = shared_world("office")
    field = _field(world, (6.4, 3.3), 0.0)
    t = Tracker(ControllerConfig.from_robot(world.robot, **UNLIMITED), CrawlConfig(window=1.0, hold=1.0, route_crawls=1),
                route=_Scripted(route))
    with pytest.raises(NavigationError):
        for k in range(40):
            t.command(k * DT, (1.0, 1.0, 0.0), field)


@pytest.mark.parametrize("bad", [{"route": 3}, {"route_tolerance": 0.0}, {"route_tolerance": math.nan},
                                 {"route_deviation": -0.1}, {"route_deviation": math.inf}, {"route_deviation": "far"},
                                 {"route_goal": -0.5}, {"route_goal": math.nan}, {"route_goal": None}])
def test_bad_tracker_route_arguments_are_refused(bad):
    with pytest.raises(NavigationError):
        Tracker(**bad)


@pytest.mark.parametrize("bad", [0, 1.5, True, -2])
def test_bad_route_crawls_is_refused(bad):
    with pytest.raises(NavigationError):
        CrawlConfig(route_crawls=bad)


@pytest.mark.parametrize("name", ["route_pursuit", "route_alternate"])
@pytest.mark.parametrize("bad", [1, "yes", None])
def test_bad_route_flags_are_refused(name, bad):
    with pytest.raises(NavigationError, match=name):
        CrawlConfig(**{name: bad})


@pytest.mark.parametrize("seed,index", [(21, 26), (25, 18)], ids=["loops-at-a-chain-end", "pinned-in-a-notch"])
def test_a_route_rescues_a_run_the_guard_alone_loses(seed, index):
    """Starts of the slow closed-loop test's sampling that time out (120 s) with the guard alone:
    random21 start 26 circles at the end of a chained wall (start 8, the case until the
    twenty-sixth session, now reaches the goal pose with the guard alone: the escape band's
    direction, navigation.control); random25 start 18 ends pinned in a
    concave notch 10 micrometres from the grown boundary (crawl engagements, no loop). With the
    harmonic tree to the goal as a route (:class:`TreeRoutes`) both reach the goal pose,
    touching nothing."""
    _fails_then_arrives(seed, index, UNLIMITED, lambda cfg, routes: Tracker(cfg))


def test_a_pursued_route_goal_rescues_a_rate_limited_run_that_circles_in_a_passage():
    """random13 start 98 of the slow test's sampling, in the rate-limited mode: the robot
    reaches the narrow passage between the top obstacle group and the workspace boundary, under
    a metre from the goal, where a route can be the goal pose alone (the straight line is clear)
    and the caller's field takes the robot round in circles: with ``route_goal=0`` it times out.
    Pursuing the goal position until 0.5 m from it, it reaches the goal pose, every command
    within the rate limit (``run_closed_loop``)."""
    _fails_then_arrives(13, 98, RATE_LIMITED, lambda cfg, routes: Tracker(cfg, route=routes, route_goal=0.0))


def _plain_grown(sq, amount):
    return sq.grow(amount)


def test_a_route_pursued_along_its_segments_rescues_a_run_its_fields_lose(monkeypatch):
    """random1 start 35 of the slow test's sampling: the caller's field leads the robot into
    the channel between an X of two bars and the workspace boundary, and every route waypoint's
    field does the same (their flow runs along the boundary, the long way round, with its
    direction reversing across the channel): with the routes tracked by their fields
    (``route_pursuit=False``) the robot turns back and forth there until the 120 s limit. Pursued
    along the route's straight segments it reaches the goal pose, touching nothing. The routes
    are planned on roadmaps of the plain inflation (:meth:`navigation.Squircle.grow`, the
    roadmaps' until the thirty-seventh session): with the snug one they take another channel,
    which the fields pass."""
    monkeypatch.setattr(tamp.roadmap, "grown", _plain_grown)
    fields = _fails_then_arrives(1, 35, UNLIMITED,
                                 lambda cfg, routes: Tracker(cfg, CrawlConfig(route_pursuit=False), route=routes))
    assert fields.routes >= 2  # the fields failed route after route
