"""Closed-loop tracking with a crawl guard: the stand-off of eq. 24's controller only where needed.

:func:`~navigation.control.track` is a pure function of the pose. Next to chained walls the
navigation transformation is so anisotropic that the integral curves of the tracked field are
squeezed into a trench a millimetre or two from a grown boundary, where the safety limit holds
the robot at millimetres per second (docs/control.md, "Stand-off"): the default controller then
*crawls* and may time out. The stand-off (``ControllerConfig.standoff``) removes most of those
crawls but changes the motion everywhere near walls, and on ``office`` it recirculates along
room walls that the default controller leaves at once.

:class:`Tracker` keeps the default controller and turns the stand-off on only while the robot
crawls. The one piece of state is :class:`CrawlGuard`: over the last ``window`` seconds the
robot travelled less than ``min_progress`` metres while farther than ``goal_radius`` from the
goal it tracks; the guard then engages the stand-off for ``hold`` seconds (re-engaging at once
if the crawl goes on). The command of each step is still :func:`~navigation.control.track_waypoints`
with either the caller's configuration or the same with ``standoff`` set, so every safety
property of the controller holds in both modes (the safety limit is applied either way; the
stand-off only changes the tracked direction near boundaries and lowers ``v``).

While engaged the stand-off also *pulls* the robot back towards the wall between ``D`` and
``reach D`` (``ControllerConfig.standoff_pull``, ``standoff_reach``; the wall flow's weight falls
from 1 at ``D`` to 0 at ``reach D``): the trench along a chained wall often runs round the
wall's convex corner, and a robot following it at ``D`` without the pull drove along the
tangent out of the narrow band, where the unmodified field took it back into the junction it
had crawled out of, round and round until the timeout (docs/control.md, "Pull-in").

The guard also watches for *loops*: the robot comes back within ``loop_radius`` (5 cm) of a
position it passed at least ``loop_length`` (1 m) of path earlier, heading within
``loop_heading`` (45 degrees) of the way it headed then (the way back along an out-and-back
path is not a loop), within the last ``loop_window`` seconds (60), away from the goal. A loop
is a failure of the mode the robot was in, so the guard changes it for ``hold`` seconds,
alternating: the first loop (and every odd one) engages the *wall-following* mode, the
stand-off with the pull and the turn limit (``ControllerConfig.turn_share = turn``, 0.5: the
robot slows down where the wall flow turns faster than it can, so it follows the flow round a
wall's convex end instead of overshooting into the field that leads back into the loop); the
second (and every even one) forces the *plain* controller, with the crawl detection paused,
since the robot can also circle while following walls (into a pocket the plain robot would have
overshot and left). A loop through
which the robot never crawls (``random18``: into the junction of a chain, down a wall and round
its end at full speed, out across the open) was out of the crawl guard's reach before
(docs/control.md, "Loops").

With a *route planner* (``Tracker(config, crawl, route=planner)``, a callable ``planner(pose,
goal_pose)`` returning oriented waypoints ending at the goal pose, or ``None``;
:class:`tamp.routes.TreeRoutes` plans the harmonic tree of paper 001 eq. 7-8, 26, the way the
executive guides a mission) the tracker answers every loop and every crawl engagement (every
``route_crawls``-th, 1 by default) with a new route from the robot's pose. It *pursues* the
route's inner waypoints one after the other (``CrawlConfig.route_pursuit``, the default): eq. 24
on the bearing of the waypoint (:func:`~navigation.control.track_point`, the heading gate, the
safety limit of the caller's forest, the saturation and the rate limit as for a field), i.e.
along the tree's straight segments, which are collision-free at the buffer they were planned
with; it passes a waypoint within ``route_tolerance`` (0.15 m) once it is within
:data:`PASS_CLOSE` (3 cm) of the segment from it to the next one, and hands over to the caller's
field (and its ``following``) for the last one, the goal pose, once the robot has come within
``route_goal`` (0.5 m) of it (a route can be the goal pose alone: the goal is in sight, but the
caller's field takes the robot round in circles in a narrow passage). The route is asked for because
the field fails here, and a waypoint's own navigation function fails the same way: its flow
can run along the same trench, round the obstacle the long way (random1 start 35: every
waypoint's field led the robot into the channel between an X of two bars and the workspace
boundary, with the direction reversing across the channel, docs/control.md "Route rescue").
With ``route_pursuit=False`` each waypoint is tracked with its own field (a navigation function
on the caller's forest, built when first tracked) and eq. 25's switch to the next one, and the
routes alternate their mode (``CrawlConfig.route_alternate``): the first route (and every
odd-numbered one) with the plain controller, every even-numbered one in the guard's mode. The
guard keeps watching (its goal is the tracked waypoint), so a route that fails too is replaced
by the next one; a new goal from the caller drops the route. A route is a plan from the pose it
was planned at: when the robot strays more than ``route_deviation`` (0.3 m) from the segment it
follows (from that pose, or the last waypoint passed, to the next waypoint), the tracker plans
a new route from where it is, at most once per guard ``window`` (3 s). A caller with a
failure detector of its own asks for a route at once with :meth:`Tracker.rescue` (the
executive's progress watchdog, ``tamp.executive``). Measured in docs/control.md, "Route
rescue".

Not in the paper: paper 001 tracks the field with eq. 24 alone. This is a supervisor around it
for the conditioning problem of the transformation (issue 2, docs/navigation.md "Conditioning
next to chained walls").
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace
from enum import IntEnum

import numpy as np

from .control import Command, ControllerConfig, _horizon, _pose, track_point, track_waypoints
from .errors import NavigationError, check_numbers
from .oriented import OrientedField
from .potential import NavigationFunction

__all__ = ["CrawlConfig", "CrawlGuard", "Mode", "Tracker"]

#: a pursued route waypoint within ``route_tolerance`` counts as passed once the robot is this
#: close (m) to the route's segment from it to the next one (``Tracker._passable``)
PASS_CLOSE = 0.03


def _to_segment(q: np.ndarray, a, b) -> float:
    """Distance (m) from the position ``q`` to the segment from ``a`` to ``b``."""
    a = np.asarray(a, dtype=float)
    ab = np.asarray(b, dtype=float) - a
    n2 = float(ab @ ab)
    u = min(1.0, max(0.0, float((q - a) @ ab) / n2)) if n2 > 0 else 0.0
    return math.hypot(*(q - a - u * ab))


@dataclass(frozen=True, slots=True)
class CrawlConfig:
    """When the crawl guard engages the stand-off.

    Attributes
    ----------
    window : float
        Seconds over which progress is measured (3).
    min_progress : float
        Path length (m) below which the robot crawls (0.1: 3.3 cm/s on average).
    goal_radius : float
        No crawl is declared within this distance (m) of the tracked goal, where eq. 24a slows
        the robot down on purpose (0.25).
    hold : float
        Seconds the stand-off stays engaged (10).
    max_gap : float
        Longest interval (s) between two updates that still counts as one stretch of tracking
        (0.5); after a longer one (the robot stopped for planning, a blocked mission) the
        history starts over, so a pause is not taken for a crawl.
    standoff : float
        ``ControllerConfig.standoff`` used while engaged (0.03 m, the measured setting).
    pull : float
        ``ControllerConfig.standoff_pull`` used while engaged (1.0; 0 turns the pull off).
    reach : float
        ``ControllerConfig.standoff_reach`` used while engaged (4.0: the wall flow's weight falls
        from 1 at ``standoff`` to 0 at four times it).
    loop_radius : float
        A loop: the robot comes back within this distance (m) of a position it passed (0.05;
        0 turns the loop detection off) ...
    loop_heading : float
        ... heading within this angle (rad) of the heading it had then (pi / 4: a return along
        the way it came is not a loop) ...
    loop_length : float
        ... at least this much path (m) earlier (1.0) ...
    loop_window : float
        ... within the last this many seconds (60).
    turn : float
        ``ControllerConfig.turn_share`` of the wall-following mode after a loop (0.5).
    route_crawls : int
        With a route planner (``Tracker(..., route=...)``): every loop, and every
        ``route_crawls``-th crawl engagement (1: every one), asks for a new route to the goal.
    route_pursuit : bool
        Each inner waypoint of a route is *pursued*: eq. 24 on the bearing of the waypoint
        (:func:`~navigation.control.track_point`), along the route's straight, collision-free
        segments (True); False: tracked with a field of its own and eq. 25's switch, in the
        mode ``route_alternate`` chooses. Either way the goal pose at the route's end is
        tracked with the caller's field.
    route_alternate : bool
        Without ``route_pursuit``: the first route (and every odd-numbered one) is followed
        with the plain controller, every even-numbered one in the guard's mode (True); False:
        every route in the guard's mode.
    """

    window: float = 3.0
    min_progress: float = 0.1
    goal_radius: float = 0.25
    hold: float = 10.0
    max_gap: float = 0.5
    standoff: float = 0.03
    pull: float = 1.0
    reach: float = 4.0
    loop_radius: float = 0.05
    loop_heading: float = math.pi / 4
    loop_length: float = 1.0
    loop_window: float = 60.0
    turn: float = 0.5
    route_crawls: int = 1
    route_pursuit: bool = True
    route_alternate: bool = True

    def __post_init__(self):
        check_numbers(self, ("window", "min_progress", "goal_radius", "hold", "max_gap", "standoff", "loop_heading",
                             "loop_length", "loop_window"), positive=True)
        check_numbers(self, ("pull", "loop_radius", "turn"), positive=False)
        if not self.reach > 1.0:
            raise NavigationError(f"CrawlConfig.reach must be > 1, got {self.reach!r}")
        n = self.route_crawls
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise NavigationError(f"CrawlConfig.route_crawls must be an integer >= 1, got {n!r}")
        for name in ("route_pursuit", "route_alternate"):
            if not isinstance(getattr(self, name), bool):
                raise NavigationError(f"CrawlConfig.{name} must be True or False, got {getattr(self, name)!r}")


class Mode(IntEnum):
    """What the tracker drives with (:meth:`CrawlGuard.update`); truthy when the stand-off is on."""

    PLAIN = 0  #: the caller's controller
    STANDOFF = 1  #: the stand-off with the pull (after a crawl)
    FOLLOW = 2  #: the stand-off with the pull and the turn limit (wall following, after a loop)


class CrawlGuard:
    """Crawl and loop detection over the recent positions (see the module doc).

    ``update(t, q, goal, heading)`` is called once per control period with the time (s), the
    position, the tracked goal and the robot's heading, and returns the :class:`Mode` for this
    period (``engagements`` and ``loops`` count the crawls and loops seen).
    """

    __slots__ = ("config", "_hist", "_length", "_until", "engagements", "_loop", "_loop_n", "_loop_mode",
                 "_loop_until", "loops")

    def __init__(self, config: CrawlConfig = CrawlConfig()):
        self.config = config
        self._hist: deque = deque()  # (t, cumulative path length, x, y) of the crawl window
        self._length = 0.0
        self._until = -math.inf
        self.engagements = 0  #: how often a crawl engaged the stand-off
        self._loop = np.empty((256, 5))  # rows (t, cumulative path length, x, y, heading) of the loop window
        self._loop_n = 0
        self._loop_mode = Mode.PLAIN
        self._loop_until = -math.inf
        self.loops = 0  #: how many loops were detected

    def reset(self) -> None:
        """Forget the history (a new leg, a teleported robot)."""
        self._hist.clear()
        self._length = 0.0
        self._until = -math.inf
        self._loop_n = 0
        self._loop_until = -math.inf

    @property
    def engaged_until(self) -> float:
        """Time until which the stand-off is engaged by a crawl (``-inf``: never engaged since the
        reset)."""
        return self._until

    def update(self, t: float, q, goal, heading: float | None = None) -> Mode:
        """The :class:`Mode` for the control period at time ``t`` (s), position ``q``, tracked
        ``goal`` and, if known, the robot's ``heading`` (rad; without it a loop is a return to
        the same position in any heading)."""
        t = float(t)
        x, y = float(q[0]), float(q[1])
        if heading is not None:
            heading = float(heading)
        if not (math.isfinite(t) and math.isfinite(x) and math.isfinite(y)) or \
                (heading is not None and not math.isfinite(heading)):
            raise NavigationError(f"CrawlGuard.update needs a finite time, position and heading, "
                                  f"got {t}, {q!r}, {heading!r}")
        h = self._hist
        if h and not 0.0 <= t - h[-1][0] <= self.config.max_gap:
            self.reset()  # time went back, or the robot was not under control meanwhile: start over
        if h:
            self._length += math.hypot(x - h[-1][2], y - h[-1][3])
        h.append((t, self._length, x, y))
        c = self.config
        while len(h) > 1 and h[1][0] <= t - c.window:
            h.popleft()  # keep one sample at or before the window's start
        far = math.hypot(x - float(goal[0]), y - float(goal[1])) > c.goal_radius
        looped = self._looped(t, x, y, far, heading)
        if looped is not None:
            return looped
        if t < self._until:
            return Mode.STANDOFF
        full = t - h[0][0] >= c.window - 1e-9
        if full and self._length - h[0][1] < c.min_progress and far:
            self._until = t + c.hold
            self.engagements += 1
            return Mode.STANDOFF
        return Mode.PLAIN

    def _looped(self, t: float, x: float, y: float, far: bool, heading: float | None) -> "Mode | None":
        """Record the pose in the loop window; the mode a loop imposes (detected now or within
        the last ``hold`` seconds), else ``None``."""
        c = self.config
        if not c.loop_radius > 0:
            return None
        buf, n = self._loop, self._loop_n
        if n and buf[0, 0] < t - c.loop_window:  # drop the samples older than the window
            k = int(np.searchsorted(buf[:n, 0], t - c.loop_window))
            buf[:n - k] = buf[k:n]
            n -= k
        if n == len(buf):
            buf = self._loop = np.concatenate([buf, np.empty_like(buf)])
        buf[n] = (t, self._length, x, y, math.nan if heading is None else heading)
        n += 1
        self._loop_n = n
        if t < self._loop_until:
            return self._loop_mode
        if not far:
            return None
        # the samples passed at least loop_length of path ago (the path length never decreases)
        m = int(np.searchsorted(buf[:n, 1], self._length - c.loop_length, side="right"))
        if m == 0:
            return None
        d2 = (buf[:m, 2] - x) ** 2 + (buf[:m, 3] - y) ** 2
        if heading is not None:  # the same pose: not the way back along an out-and-back path
            turned = np.abs(np.remainder(buf[:m, 4] - heading + math.pi, 2.0 * math.pi) - math.pi)
            d2 = np.where(turned >= c.loop_heading, math.inf, d2)  # NaN (no heading then): a position loop
        if not float(d2.min()) < c.loop_radius ** 2:
            return None
        # a loop: the mode the robot was in does not get it out; alternate wall following and
        # the plain controller for hold seconds, and forget the loop
        self.loops += 1
        self._loop_mode = Mode.FOLLOW if self.loops % 2 == 1 else Mode.PLAIN
        self._loop_until = t + c.hold
        self._until = -math.inf
        buf[0] = buf[n - 1]
        self._loop_n = 1
        return self._loop_mode


class Tracker:
    """Eq. 24-25 with the crawl guard and the rate limit: :func:`track_waypoints` with
    ``config`` (:attr:`Mode.PLAIN`), with ``config`` and the stand-off of ``crawl``
    (``standoff``, ``pull``, ``reach``) while a crawl engaged it (:attr:`Mode.STANDOFF`), or with
    the same and ``turn_share = crawl.turn`` for ``crawl.hold`` seconds after the first, third,
    ... loop (:attr:`Mode.FOLLOW`; the even-numbered loops force :attr:`Mode.PLAIN` for that
    long), given the previous command (``previous`` of :func:`~navigation.control.track`).

    The rate limit (with ``config.accel_max`` / ``alpha_max`` > 0, the controller's opt-in
    rate-limited mode): each command differs from the previous one by at most
    ``config.accel_max dt`` in ``v`` and ``config.alpha_max dt`` in ``omega``, ``dt`` the time
    since that command (1 m/s^2 and 6 rad/s^2: 0.1 m/s and 0.6 rad/s per 0.1 s period). The
    previous command is the last :meth:`command`, or what the caller reports it actually sent
    (:meth:`applied`, e.g. a stop or a slower command of a supervisor). The first command, and
    the first after more than ``max_gap`` seconds without one, start from rest (``(0, 0)``, one
    ``safety_horizon`` ago). The safety limit (:func:`~navigation.control.safe_speed`) accounts
    for the braking: while the clearance shrinks no faster than the robot moves (a
    static, known world) the rate limit never has to be overridden; where it shrinks faster (an
    obstacle discovered ahead) the safety limit wins and ``v`` drops at once.

    ``crawl=None`` disables the guard (the commands of :func:`track_waypoints` with ``config``),
    and with it the route rescue.

    ``route`` (optional): the route planner of the module doc, a callable ``(pose, goal_pose) ->
    waypoints or None``; ``route_tolerance``: the distance (m) within which a route waypoint
    counts as passed (0.15, the executive's ``waypoint_tolerance``); ``route_deviation``: the
    distance (m) from the followed segment beyond which the route is planned again from the
    robot's pose (0.3; 0 turns it off); ``route_goal``: with ``CrawlConfig.route_pursuit`` the
    route's last waypoint, the goal pose, is pursued too until the robot first comes within
    this distance (m) of it, and only then tracked with the caller's field (0.5; 0: the field
    for the whole last segment). ``routes`` and ``route_misses`` count the routes
    planned and the calls that found none (or a waypoint outside the field's free space);
    ``route_strays`` the routes planned because the robot strayed. A malformed route (not one
    or more finite poses) raises :class:`NavigationError`. While the robot pursues a route
    waypoint (``CrawlConfig.route_pursuit``), or follows an odd-numbered route with fields
    (``CrawlConfig.route_alternate``), :attr:`mode` is :attr:`Mode.PLAIN` whatever the guard
    says.
    """

    def __init__(self, config: ControllerConfig = ControllerConfig(), crawl: CrawlConfig | None = CrawlConfig(),
                 max_gap: float = 0.5, route=None, route_tolerance: float = 0.15, route_deviation: float = 0.3,
                 route_goal: float = 0.5):
        self.config = config
        self.guard = CrawlGuard(crawl) if crawl is not None else None
        if route is not None and not callable(route):
            raise NavigationError(f"route must be a callable (pose, goal) -> waypoints or None, got {route!r}")
        self._route_fn = route if crawl is not None else None
        self.route_tolerance, self.route_deviation, self.route_goal = route_tolerance, route_deviation, route_goal
        check_numbers(self, ("route_tolerance",), positive=True)
        check_numbers(self, ("route_deviation", "route_goal"), positive=False)
        self.route_tolerance, self.route_deviation, self.route_goal = map(float, (route_tolerance, route_deviation,
                                                                                  route_goal))
        self._target = None  # the caller's current field the route leads to
        self._route: tuple = ()  # its waypoints (x, y, theta), the last one the target's goal pose
        self._route_fields: list = []  # one field per waypoint but the last (built when first tracked)
        self._route_rest = np.zeros(0)  # path length from each waypoint to the route's end
        self._route_i = 0  # the waypoint tracked now
        self._route_free = -1  # the last waypoint found in free space (pursuit)
        self._goal_near = False  # the robot came within route_goal of the route's goal pose
        self._route_from = (0.0, 0.0)  # the position the route was planned from
        self._planned_at = -math.inf  # time of the last route planned
        self._failures = 0  # the guard's failures (loops, every route_crawls-th crawl) already answered
        self.routes = 0  #: how many routes were planned
        self.route_misses = 0  #: how often the planner found no route
        self.route_strays = 0  #: how many routes were planned because the robot strayed from the last one
        if crawl is None:  # never leaves Mode.PLAIN
            self._configs = dict.fromkeys(Mode, config)
        else:
            engaged = replace(config, standoff=crawl.standoff, standoff_pull=crawl.pull, standoff_reach=crawl.reach)
            self._configs = {Mode.PLAIN: config, Mode.STANDOFF: engaged,
                             Mode.FOLLOW: replace(engaged, turn_share=crawl.turn)}
        self._mode = Mode.PLAIN
        self.max_gap = float(max_gap)
        self._sent: tuple[float, float, float] | None = None  # (t, v, omega) of the last command

    @property
    def engaged(self) -> bool:
        """Whether the last :meth:`command` used the stand-off."""
        return self._mode != Mode.PLAIN

    @property
    def mode(self) -> Mode:
        """The :class:`Mode` of the last :meth:`command`."""
        return self._mode

    def config_for(self, mode: Mode) -> ControllerConfig:
        """The controller configuration the tracker drives with in ``mode``."""
        try:
            return self._configs[Mode(mode)]
        except ValueError:
            raise NavigationError(f"mode must be one of {', '.join(m.name for m in Mode)}, got {mode!r}") from None

    def applied(self, t: float, v: float, omega: float) -> None:
        """Record the command actually sent at time ``t`` (when the caller changed or replaced
        the last :meth:`command`): the next command's rate limit starts from it."""
        t, v, omega = float(t), float(v), float(omega)
        if math.isfinite(t) and math.isfinite(v) and math.isfinite(omega):
            self._sent = (t, v, omega)

    def brake(self, t: float) -> tuple[float, float]:
        """``(v, omega)`` at time ``t`` towards rest as fast as the rate limit allows:
        :meth:`smooth` towards ``(0, 0)``. No safety limit is applied: the caller checks the
        motion (the executive's motion guard). Not recorded: report what is sent with
        :meth:`applied`."""
        return self.smooth(t, 0.0, 0.0)

    def smooth(self, t: float, v: float, omega: float) -> tuple[float, float]:
        """The command ``(v, omega)`` wanted at time ``t`` as the rate limit lets it follow the
        last command (:meth:`command` or :meth:`applied`; rest without a recent one): ``v``
        moved from the last by at most ``accel_max dt`` and ``omega`` by at most ``alpha_max
        dt`` (a limit of 0 leaves that component as wanted), as a velocity smoother does.
        Nothing else is applied (no safety limit, no saturation) and nothing is recorded."""
        t, v, omega = float(t), float(v), float(omega)
        if not (math.isfinite(t) and math.isfinite(v) and math.isfinite(omega)):
            raise NavigationError(f"t, v and omega must be finite, got {t!r}, {v!r}, {omega!r}")
        pv, pw, dt = self._previous(t)
        cfg = self.config
        if cfg.accel_max > 0:
            v = min(max(v, pv - cfg.accel_max * dt), pv + cfg.accel_max * dt)
        if cfg.alpha_max > 0:
            omega = min(max(omega, pw - cfg.alpha_max * dt), pw + cfg.alpha_max * dt)
        return v, omega

    def _previous(self, t: float) -> tuple[float, float, float]:
        s = self._sent
        if s is not None and 0.0 <= t - s[0] <= self.max_gap:
            return s[1], s[2], t - s[0]
        return 0.0, 0.0, _horizon(self.config)  # from rest, one period ago

    def command(self, t: float, pose, current: OrientedField, following: OrientedField | None = None,
                beyond: float = 0.0, v_cap: float = math.inf) -> Command:
        """The command for ``pose = (x, y, theta)`` at time ``t`` (s) towards ``current``
        (blended into ``following`` near ``current``'s goal, eq. 25; ``beyond``: the path length
        after ``current``'s goal, ``v_cap``: a speed cap before the rate limit,
        :func:`~navigation.control.track`)."""
        q, th = _pose(pose)  # the controller's pose check, before the guard records the position
        t = float(t)
        point = None  # a route waypoint pursued along the straight segment
        if self._route_fn is not None:
            current, following, beyond, point = self._routed(t, q, th, current, following, beyond)
        goal = current.goal if point is None else point
        mode = self.guard.update(t, q, goal, th) if self.guard is not None else Mode.PLAIN
        if point is not None:
            mode = Mode.PLAIN  # the bearing has no stand-off
        elif self._on_route() and self.guard.config.route_alternate and self.routes % 2 == 1:
            mode = Mode.PLAIN  # an odd-numbered route (the one tracked now) with the plain controller
        self._mode = mode
        if point is not None:
            cmd = track_point(pose, point, current, self.config, previous=self._previous(t), beyond=beyond,
                              v_cap=v_cap)
        else:
            cmd = track_waypoints(pose, current, following, self._configs[mode],
                                  previous=self._previous(t), beyond=beyond, v_cap=v_cap)
        self._sent = (t, cmd.v, cmd.omega)
        return cmd

    def pursue(self, t: float, pose, point, field: OrientedField, beyond: float = 0.0,
               v_cap: float = math.inf, gate: float = math.pi / 2) -> Command:
        """The command towards ``point`` (eq. 24 on its bearing, :func:`~navigation.control.track_point`,
        the safety limit of ``field``'s forest), rate-limited from the last command."""
        t = float(t)
        self._mode = Mode.PLAIN
        cmd = track_point(pose, point, field, self.config, previous=self._previous(t), beyond=beyond, v_cap=v_cap,
                          gate=gate)
        self._sent = (t, cmd.v, cmd.omega)
        return cmd

    def rescue(self, t: float, pose, current: OrientedField) -> bool:
        """Plan a route from ``pose`` to ``current``'s goal pose now, for a caller whose own
        watch says the field fails (the executive's progress watchdog); it is pursued by
        :meth:`command` as one the guard asked for. False without a route planner or when it
        finds none."""
        if self._route_fn is None:
            return False
        q, th = _pose(pose)
        if current is not self._target:  # a new goal (the route and index are reset by _plan)
            self._target, self._failures = current, self._guard_failures()
        self._plan(float(t), q, th, current)
        return bool(self._route)

    @property
    def route(self) -> tuple:
        """The waypoints ``(x, y, theta)`` of the route tracked now, from the current one to the
        goal pose (empty without a route)."""
        return self._route[self._route_i:]

    def _on_route(self) -> bool:
        """Whether a route waypoint before the goal pose is tracked (not the caller's field)."""
        return self._route_i < len(self._route) - 1

    def _guard_failures(self) -> int:
        """The guard's failures a route answers: its loops and every ``route_crawls``-th crawl
        engagement."""
        g = self.guard
        return g.loops + g.engagements // g.config.route_crawls

    def _routed(self, t: float, q: np.ndarray, th: float, current: OrientedField, following, beyond: float):
        """``(current, following, beyond, point)`` to track: the caller's (``point`` None), or
        along the route: with ``CrawlConfig.route_pursuit`` the caller's field (for the safety
        limit), ``None``, the path length after the waypoint and the waypoint's position;
        otherwise the waypoint's field, the next one's and the path length after it."""
        failures = self._guard_failures()
        if current is not self._target:  # a new goal: forget the route and the failures so far
            self._target, self._route, self._route_i, self._failures = current, (), 0, failures
        if failures > self._failures:
            self._failures = failures
            self._plan(t, q, th, current)
        elif self._strayed(t, q):
            self.route_strays += 1
            self._plan(t, q, th, current)
        route = self._route
        if not route:
            return current, following, beyond, None
        i, last = self._route_i, len(route) - 1
        tol2 = self.route_tolerance ** 2
        pursue = self.guard.config.route_pursuit
        while i < last and (q[0] - route[i][0]) ** 2 + (q[1] - route[i][1]) ** 2 < tol2:
            if pursue and not self._passable(q, route[i], route[i + 1]):
                break  # pursue waypoint i until the next one is in sight
            i += 1
        self._route_i = i
        if not self._on_route():
            if self._pursue_goal(q):
                return current, None, float(beyond), np.array(route[i][:2])
            return current, following, beyond, None
        rest = float(self._route_rest[i]) + float(beyond)  # path length after waypoint i
        try:
            if pursue:
                point = np.array(route[i][:2])
                if i > self._route_free:  # each waypoint checked once, when first pursued
                    if not bool(current.nf.is_free(point)):
                        raise NavigationError(f"route waypoint {route[i]} is outside the free space")
                    self._route_free = i
                return current, None, rest, point
            cur = self._route_field(i)
            fol = self._route_field(i + 1) if i + 1 < last else current
        except NavigationError:  # a waypoint outside the field's free space: drop the route
            self._route, self._route_i = (), 0
            self.route_misses += 1
            return current, following, beyond, None
        return cur, fol, rest, None

    @staticmethod
    def _passable(q: np.ndarray, here, after) -> bool:
        """Whether a pursued waypoint ``here`` (within ``route_tolerance``) counts as passed:
        the robot is within :data:`PASS_CLOSE` of it or of the route's segment from it to the
        waypoint ``after`` it. The segment is collision-free at the route's buffer, and so,
        nearly, is the bearing line from a robot beside it. Passing a waypoint within 0.15 m
        while the robot was off the segment, with the next waypoint behind a corner, sent the
        bearing into the wall: held by the safety limit, the robot turned back and forth in the
        escape band (random23 start 61, rate-limited)."""
        return _to_segment(q, here[:2], after[:2]) <= PASS_CLOSE

    def _pursue_goal(self, q: np.ndarray) -> bool:
        """Whether the route's goal position is pursued: with ``route_pursuit``, until the robot
        first comes within ``route_goal`` of it (then the caller's field, for the heading)."""
        if self._goal_near or not (self.route_goal > 0 and self.guard.config.route_pursuit):
            return False
        g = self._route[-1]
        self._goal_near = (q[0] - g[0]) ** 2 + (q[1] - g[1]) ** 2 <= self.route_goal ** 2
        return not self._goal_near

    def _strayed(self, t: float, q: np.ndarray) -> bool:
        """Whether the robot is farther than ``route_deviation`` from the segment to the route
        waypoint it tracks (from the pose the route was planned at, or the waypoint before),
        at least one guard ``window`` after the last route was planned."""
        i, route = self._route_i, self._route
        if not (self.route_deviation > 0 and self._on_route() and t - self._planned_at >= self.guard.config.window):
            return False
        return _to_segment(q, self._route_from if i == 0 else route[i - 1][:2], route[i][:2]) > self.route_deviation

    def _plan(self, t: float, q: np.ndarray, th: float, current: OrientedField) -> None:
        goal = (float(current.goal[0]), float(current.goal[1]), float(current.heading))
        self._route, self._route_i, self._planned_at = (), 0, t
        wps = self._route_fn((float(q[0]), float(q[1]), th), goal)
        if wps is None:
            self.route_misses += 1
            return
        try:
            arr = np.array(wps, dtype=float)
        except (TypeError, ValueError):
            arr = None
        if arr is None or arr.ndim != 2 or arr.shape[1] != 3 or not len(arr) or not np.all(np.isfinite(arr)):
            raise NavigationError(f"a route must be one or more finite poses (x, y, theta), got {wps!r}")
        wps = arr
        wps[-1] = goal  # the route ends at the caller's goal pose, tracked with the caller's field
        steps = np.hypot(*np.diff(wps[:, :2], axis=0).T)
        self._route_rest = np.concatenate((np.cumsum(steps[::-1])[::-1], [0.0]))
        self._route = tuple(tuple(w) for w in wps)
        self._route_from = (float(q[0]), float(q[1]))
        self._route_fields = [None] * (len(wps) - 1)
        self._route_free = -1
        self._goal_near = False
        self.routes += 1

    def _route_field(self, i: int) -> OrientedField:
        f = self._route_fields[i]
        if f is None:
            x, y, heading = self._route[i]
            f = self._route_fields[i] = OrientedField(NavigationFunction(self._target.nf.forest, goal=(x, y)),
                                                      heading=heading)
        return f
