"""The methods compared by the evaluation suite (issue 8; paper 001 section 5.3, Table 1).

Every method runs through the same simulator, lidar, perception (:class:`perception.ObstacleMap`),
mission automaton (:class:`tamp.MissionPlanner`, mission events included) and metrics. The
baselines are thin subclasses of :class:`tamp.Executive` that replace only the layer they
differ in, so that a difference in the table is the difference between the methods and not
between two copies of the surrounding machinery:

=========  ===========================================================================
``HT``     the full system: :func:`tamp.run.run_mission` with :class:`tamp.Executive`.
``HT-fields``  the full system executed as in paper 001 (eq. 24-25 on each waypoint's
           oriented field, ``ExecutiveConfig(pursuit=0)``) instead of pursuing the tree's path
           (docs/executive.md "Pursuit of the leg"): the two rows show what the pursuit changes.
``OHPF``   :class:`OHPFExecutive`: the same task planning and online plan adaptation
           (transition costs and feasibility from the harmonic trees' roadmap, re-planning on
           discoveries), but the robot drives every task transition with *one* oriented field
           to the region (arrival heading along the tree's last segment): no intermediate
           waypoints, i.e. no second-layer trees in execution.
``NF``     :class:`NFExecutive`: the plain navigation function (negated gradient of
           ``phi_NF``, no dipole, no heading) tracked by the eq. 24 unicycle controller
           (without the crawl guard, which the other methods' executive has); the
           plan is the initial one on straight-line costs, never re-costed (no adaptation);
           the potential is rebuilt on every map change (it must contain what was seen).
``RRT*``   :class:`RRTStarExecutive`: OMPL's ``RRTstar`` (``ompl`` Python bindings) on the
           known + estimated obstacles grown by the robot radius and a margin, followed by
           a pure-pursuit path follower; the task plan is the initial one (no adaptation);
           the path is re-planned when a changed obstacle blocks its remainder.
``RRT*-buffer``  :class:`RRTStarBufferExecutive`: ``RRT*`` keeping HT's clearance, the
           harmonic trees' buffer (``ExecutiveConfig.buffer``, paper 001's 0.15 m) instead of
           5 cm: the two RRT* rows separate what the clearance costs from what the method does.
``oracle`` :func:`oracle_tour`: a lower bound on the travel distance with full knowledge (the
           shortest collision-free tour touching the region discs in order; distance only).
=========  ===========================================================================

:func:`run_method` runs one method on one world through :func:`tamp.run.run_mission` (the
baselines as its ``executive_cls``) and returns its fields plus the trajectory.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import replace

import numpy as np

from navigation.clearance import forest_clearance
from navigation.control import ControllerConfig
from navigation.errors import NavigationError
from navigation.geometry import beta_rows, pack
from navigation.potential import NavigationFunction
from perception.fit import inflate
from tamp.errors import NoPlanError
from tamp.executive import Executive, ExecutiveConfig, ExecutiveState
from tamp.navmap import START
from tamp.run import run_mission

__all__ = ["METHODS", "ADAPTATION", "CLEARANCE", "OHPFExecutive", "NFExecutive", "RRTStarExecutive",
           "RRTStarBufferExecutive", "PlainField",
           "ompl_status", "run_method", "oracle_tour", "tour_distances", "chatter", "chatter_sources"]

METHODS = ("HT", "HT-fields", "OHPF", "NF", "RRT*", "RRT*-buffer", "oracle")
#: the paper's "Adaptation" column: does the task plan adapt to what the robot discovers
ADAPTATION = {"HT": True, "HT-fields": True, "OHPF": True, "NF": False, "RRT*": False, "RRT*-buffer": False,
              "oracle": None}


# --------------------------------------------------------------------------------------- OHPF
class OHPFExecutive(Executive):
    """HT's planning and adaptation, executed with one oriented field per task transition.

    The leg is still computed (its last segment gives the arrival heading, and the executive's
    checks of the leg against discovered obstacles still trigger re-planning), but the robot
    always tracks the field of the leg's *last* waypoint, the region: the intermediate
    waypoints of the harmonic tree are not used.
    """

    def _command(self, p):
        if self.leg:
            self.wp = len(self.leg) - 1
        return super()._command(p)


# ----------------------------------------------------------------------------------------- NF
class PlainField:
    """The negated gradient of a navigation function, in the interface the controller uses.

    :func:`navigation.control.track` reads ``goal``, ``clearance(q, far)`` and
    ``evaluate(q).angle`` / ``.angle_gradient``; here ``theta = atan2(-grad phi_NF)`` and its
    exact gradient ``(a_x grad a_y - a_y grad a_x) / |a|^2`` with ``grad a = -Hess phi_NF``.
    Outside free space the navigation function's gradient already points back in.
    """

    class _Eval:
        __slots__ = ("angle", "angle_gradient")

        def __init__(self, angle, angle_gradient):
            self.angle, self.angle_gradient = angle, angle_gradient

    def __init__(self, nf: NavigationFunction):
        self.nf = nf
        self.goal = np.asarray(nf.goal, dtype=float).reshape(2)
        self.clearance = forest_clearance(nf.forest)

    def evaluate(self, q):
        ev = self.nf.evaluate(np.asarray(q, dtype=float).reshape(1, 2), order=2)
        a = -np.asarray(ev.gradient, dtype=float).reshape(2)
        H = np.asarray(ev.hessian, dtype=float).reshape(2, 2)
        m2 = float(a @ a)
        if not (m2 > 1e-24) or not np.isfinite(H).all():
            return self._Eval(0.0, np.zeros(2))
        grad = (-a[0] * H[1] + a[1] * H[0]) / m2
        return self._Eval(math.atan2(a[1], a[0]), grad)


class _FixedPlanMixin:
    """No task adaptation: transitions keep their initial straight-line costs (never evaluated
    by trees), and a discovered obstacle never re-plans the task (the potential or the path is
    updated instead, see the subclasses)."""

    def _evaluate(self, u, v, p) -> bool:  # noqa: ARG002 - the executive's signature
        return False

    def _on_map_change(self, upd) -> None:
        before = self._need_plan
        super()._on_map_change(upd)
        if self._need_plan and not before and self.state is ExecutiveState.EXECUTING:
            self._need_plan = False
            self._path_hit()

    def _path_hit(self) -> None:
        """A changed obstacle meets the remainder of the current leg."""


class NFExecutive(_FixedPlanMixin, Executive):
    """Plain navigation function to each region of the initial plan (see the module doc)."""

    def __init__(self, world, task=None, *, known: bool = False, config: ExecutiveConfig | None = None):
        # the negated gradient itself is tracked (:class:`PlainField` has no push-forward flow),
        # by eq. 24 alone: no crawl guard (its stand-off reads the push-forward flow next to walls)
        cfg = config or ExecutiveConfig()
        ctl = replace(cfg.controller or ControllerConfig(), push_forward=False)
        super().__init__(world, task, known=known, config=replace(cfg, controller=ctl, crawl_guard=None))

    def _set_leg(self, p, target) -> None:
        c = self.world.regions[target].center
        self.leg = (tuple(p), (float(c[0]), float(c[1]), 0.0))
        self.wp, self._stalled, self.target = 1, 0, target
        if self.state is not ExecutiveState.EXECUTING:
            self._note(f"executing: next region {target}")
        self.state = ExecutiveState.EXECUTING

    def _field(self, wp):
        key = ("nf", wp[:2], id(self.forest))
        f = self._fields.get(key)
        if f is None:
            try:
                f = PlainField(NavigationFunction(self.forest, goal=wp[:2]))
            except NavigationError as err:
                self._note(f"goal {np.round(wp[:2], 3).tolist()} not in free space ({err})")
                return None
            self._fields[key] = f
        return f


# --------------------------------------------------------------------------------------- RRT*
def ompl_status() -> tuple[bool, str]:
    """``(usable, detail)``: whether ``ompl``'s Python bindings import and solve a trivial query."""
    try:
        from ompl import base as ob, geometric as og, util as ou  # noqa: F401
    except Exception as err:  # noqa: BLE001 - any import failure means "not available"
        return False, f"import ompl failed: {type(err).__name__}: {err}"
    try:
        path = _rrt_star([(0.0, 0.0), (1.0, 1.0)], (0.1, 0.1), (0.9, 0.9), lambda x, y: True, 50)
    except Exception as err:  # noqa: BLE001
        return False, f"ompl imported but RRTstar failed: {type(err).__name__}: {err}"
    if path is None:
        return False, "ompl imported but RRTstar found no path in an empty square"
    import importlib.metadata

    import ompl

    version = getattr(ompl, "__version__", None)
    if version is None:  # the nanobind wheels (ompl 2) have no ``__version__``: the installed distribution's
        try:
            version = importlib.metadata.version("ompl")
        except importlib.metadata.PackageNotFoundError:
            version = "(version unknown)"
    return True, f"ompl {version} ({ompl.__file__})"


def _rrt_star(bounds, start, goal, valid, iterations, resolution: float = 0.005, seed: int = 1):
    """OMPL ``RRTstar`` in the plane (path-length objective), then OMPL's path simplifier; the
    waypoints ``(N, 2)``, or ``None`` without an exact solution. ``iterations``: the iterations
    of its loop, an int or a sequence of stages; the planner goes on growing the same tree
    stage after stage until one ends with an exact solution (``(n, n)`` gives the path of
    ``2 n`` iterations in one go, checked after the first ``n``, without doing them twice).

    Reproducible: OMPL's random numbers are seeded with ``seed`` (>= 1) before the query's
    objects are made, and the planner stops after a fixed amount of work instead of a time, so
    a query's path depends only on its inputs, on any machine and whatever ran before."""
    from ompl import base as ob, geometric as og, util as ou

    # OMPL logs an error when it is reseeded after its first draw: the RNGs made from now on
    # (this query's planner and samplers) follow the new seed, which is all that is needed
    ou.setLogLevel(ou.LOG_NONE)
    ou.RNG.setSeed(int(seed))
    ou.setLogLevel(ou.LOG_WARN)
    (x0, y0), (x1, y1) = bounds
    space = ob.RealVectorStateSpace(2)
    b = ob.RealVectorBounds(2)
    b.setLow(0, x0), b.setHigh(0, x1), b.setLow(1, y0), b.setHigh(1, y1)
    space.setBounds(b)
    si = ob.SpaceInformation(space)
    si.setStateValidityChecker(lambda s: bool(valid(s[0], s[1])))
    si.setStateValidityCheckingResolution(resolution)
    si.setup()
    s, g = space.allocState(), space.allocState()
    s[0], s[1], g[0], g[1] = float(start[0]), float(start[1]), float(goal[0]), float(goal[1])
    pdef = ob.ProblemDefinition(si)
    pdef.setStartAndGoalStates(s, g, 0.02)
    pdef.setOptimizationObjective(ob.PathLengthOptimizationObjective(si))
    planner = og.RRTstar(si)
    planner.setProblemDefinition(pdef)
    planner.setup()
    for stage in np.atleast_1d(iterations):
        calls = [0]

        def done(n=int(stage)) -> bool:  # evaluated once per iteration of RRT*'s loop
            calls[0] += 1
            return calls[0] > n

        planner.solve(ob.PlannerTerminationCondition(done))
        if pdef.hasExactSolution():
            break
    if not pdef.hasExactSolution():
        return None
    path = pdef.getSolutionPath()
    og.PathSimplifier(si).simplifyMax(path)
    return np.array([(path.getState(i)[0], path.getState(i)[1]) for i in range(path.getStateCount())])


class RRTStarExecutive(_FixedPlanMixin, Executive):
    """OMPL RRT* path to each region of the initial plan, pure-pursuit path following.

    Class attributes (documented in ``docs/evaluation.md``): ``iterations`` of RRT* per query
    (about 1 s on the 2-core reference machine; the same tree continued to twice as many when
    no exact solution is found;
    OMPL seeded with ``seed`` per query, so every run is reproducible), obstacles grown by
    ``radius + margin``,
    pure pursuit with look-ahead ``lookahead`` m and speed ``v_max cos(alpha)``, turning in
    place when the look-ahead point is more than ``rotate_angle`` off the heading (Nav2's
    regulated pure pursuit rotates to the path's heading beyond 0.785 rad by default); a robot
    held still for ``stuck_time`` while driving (against an obstacle the map missed) backs up for
    ``backup_time`` at ``backup_speed`` and re-plans (a recovery, as Nav2's behaviour tree runs).
    Every command passes the robot's rate limit (``ControllerConfig.accel_max``, ``alpha_max``:
    :meth:`navigation.Tracker.smooth`), as Nav2's velocity smoother does after its controller,
    so RRT* drives the robot the other methods drive.
    """

    iterations = 700  # RRT* iterations per query: 500-900 a second in these worlds (forty-sixth session)
    seed = 1  # OMPL's seed for every query (``ompl.util.RNG.setSeed``; at least 1)
    margin = 0.05
    fallback_margin = 0.0  # the last retry's margin, where no path keeps ``margin``
    lookahead = 0.25
    rotate_angle = math.pi / 4
    stuck_time = 1.0  # s held still while driving before the recovery (Nav2's progress checker: 10 s)
    backup_speed = -0.1  # m/s and s of the recovery's back-up (Nav2's BackUp: 0.15 m at 0.025 m/s)
    backup_time = 1.0

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.recoveries = 0  # back-ups (see the class doc)
        self._dirty = False
        self._last_q, self._last_v, self._still_since, self._backing_until = None, 0.0, 0.0, None

    def _valid_fn(self, p, margin):
        r = self.radius + margin
        rows = pack([inflate(o, r) for o in self.obstacles]) if self.obstacles else None
        ws = pack([self.world.workspace.grow(-r)])
        px, py = float(p[0]), float(p[1])
        near = 0.1 + margin  # the robot may sit in the margin of a fresh estimate: let it leave
        # ... leave, not go deeper: next to the robot a state inside a grown obstacle the robot is
        # inside too is valid only no deeper than the robot (a path into the obstacle it touches
        # held random2's robot against it for the whole mission)
        b0 = beta_rows(rows, np.array([px]), np.array([py])) if rows is not None else None

        def valid(x, y):
            xa, ya = np.array([x]), np.array([y])
            if not beta_rows(ws, xa, ya)[0] < 0:
                return False
            if rows is None:
                return True
            b = beta_rows(rows, xa, ya)
            if (x - px) ** 2 + (y - py) ** 2 < near * near:
                return bool(((b > 0) | ((b0 <= 0) & (b >= b0))).all())
            return bool((b > 0).all())

        return valid

    def _set_leg(self, p, target) -> None:
        c = self.world.regions[target].center
        pts = self.world.workspace.boundary_points(256)
        bounds = (tuple(pts.min(axis=0)), tuple(pts.max(axis=0)))
        path = None
        # at the margin ``iterations``, continued to twice as many without an exact solution
        # (the same path as a second query of 2 n from the same seed, without redoing the
        # first n), then twice as many at the fallback margin
        for margin, stages in ((self.margin, (self.iterations, self.iterations)),
                               (self.fallback_margin, (2 * self.iterations,))):
            path = _rrt_star(bounds, p[:2], c, self._valid_fn(p, margin), stages, seed=self.seed)
            if path is not None:
                break
        if path is None:
            self._blocked(NoPlanError(f"RRT* found no path from the robot to {target}", ((START, target),)))
            return
        path[0] = p[:2]
        self.leg = tuple((float(x), float(y), 0.0) for x, y in path)
        self.wp, self._stalled, self.target, self._dirty = 1, 0, target, False
        if self.state is not ExecutiveState.EXECUTING:
            self._note(f"executing: next region {target}")
        self.state = ExecutiveState.EXECUTING

    def _path_hit(self) -> None:
        self._dirty = True

    def _command(self, p):
        # every command passes the robot's rate limit (the controller's ``accel_max`` and
        # ``alpha_max``, which HT and the other baselines drive with), as Nav2's velocity
        # smoother does after its controller
        v, w = self._tracker.smooth(self.time, *self._follow(p))
        self._last_v = v
        return v, w

    def _follow(self, p):
        # recovery: a robot held still while driving (the simulator stops it at a contact) backs
        # up for ``backup_time`` at ``backup_speed``, then re-plans from where it is
        q = (float(p[0]), float(p[1]))
        last, self._last_q = self._last_q, q
        if last is None or math.dist(q, last) > 1e-4 or self._last_v <= 0.0:
            self._still_since = self.time
        if self._backing_until is not None and self.time < self._backing_until - 1e-9:
            return self.backup_speed, 0.0
        if self._backing_until is not None:
            self._backing_until, self._dirty = None, True  # backed up: re-plan from here
        elif self.time - self._still_since >= self.stuck_time - 1e-9:
            self.recoveries += 1
            self._backing_until = self.time + self.backup_time
            self._note(f"held still for {self.stuck_time:g} s while driving: backing up, then re-planning")
            return self.backup_speed, 0.0
        if self._dirty and self.target is not None:
            t0 = time.perf_counter()
            self._set_leg(p, self.target)
            dt = time.perf_counter() - t0
            self.planning_time += dt
            self.replan_times.append(dt)
            self.replans += 1
            if self.state is not ExecutiveState.EXECUTING:
                return 0.0, 0.0
        return self._pursue(p)

    def _pursue(self, p):
        """Pure pursuit along the leg: look-ahead point ``lookahead`` m beyond the projection."""
        q = np.array(p[:2])
        pts = np.array([w[:2] for w in self.leg])
        # advance past segments whose end is behind us or reached
        while self.wp < len(pts) - 1 and (np.linalg.norm(q - pts[self.wp]) < self.config.waypoint_tolerance):
            self.wp += 1
        a, b = pts[self.wp - 1], pts[self.wp]
        ab = b - a
        t = float(np.clip(np.dot(q - a, ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0))
        proj = a + t * ab
        remaining, cur, k = self.lookahead, proj, self.wp
        look = pts[-1]
        while k < len(pts):
            seg = pts[k] - cur
            d = float(np.linalg.norm(seg))
            if d >= remaining:
                look = cur + seg * (remaining / d)
                break
            remaining -= d
            cur, k = pts[k], k + 1
        dx, dy = look - q
        dist_goal = float(np.linalg.norm(pts[-1] - q))
        alpha = math.atan2(math.sin(math.atan2(dy, dx) - p[2]), math.cos(math.atan2(dy, dx) - p[2]))
        vmax, wmax = self.control.v_max, self.control.omega_max
        if abs(alpha) > self.rotate_angle:
            return 0.0, math.copysign(wmax, alpha)
        v = min(vmax, self.control.k_v * math.tanh(dist_goal)) * math.cos(alpha)
        L = max(float(np.hypot(dx, dy)), 1e-6)
        w = 2.0 * v * math.sin(alpha) / L
        if abs(w) > wmax:  # keep the curvature: slow down instead of cutting the corner
            v *= wmax / abs(w)
            w = math.copysign(wmax, w)
        return v, w


# ------------------------------------------------------------------------------ closed loop
def _flips(poses, dt: float) -> tuple[np.ndarray, float]:
    """Ticks ``k`` whose executed turn rate flipped sign against the period before (both
    ``|omega| > 0.05`` rad/s), and the distance travelled (m), from the poses at each tick."""
    if len(poses) < 3:
        return np.zeros(0, dtype=int), 0.0
    P = np.asarray(poses, dtype=float)
    w = np.arctan2(np.sin(np.diff(P[:, 2])), np.cos(np.diff(P[:, 2]))) / dt  # w[k]: the command of tick k
    dist = float(np.linalg.norm(np.diff(P[:, :2], axis=0), axis=1).sum())
    on = np.abs(w) > 0.05
    flips = on[1:] & on[:-1] & (np.sign(w[1:]) != np.sign(w[:-1]))
    return np.flatnonzero(flips) + 1, dist


def chatter(poses, dt: float) -> float:
    """Turn-rate chatter: sign flips of the *executed* turn rate between consecutive control
    periods (both ``|omega| > 0.05`` rad/s), per metre travelled. Computed from the recorded
    poses, the same way for every method."""
    ticks, dist = _flips(poses, dt)
    return len(ticks) / dist if dist > 1e-9 else 0.0


def chatter_sources(poses, waypoints, replanned, dt: float) -> dict:
    """Where the flips :func:`chatter` counts happen, by what changed at the tick of the second
    of the two periods: ``replan`` (the executive re-planned on that tick), ``handover`` (the
    tracked waypoint changed without a re-plan: the robot passed an intermediate waypoint and
    the next one's field took over), ``tracking`` (neither: the field or the controller turned
    the robot round on its own). ``poses``, ``waypoints`` (``status.waypoint`` per tick) and
    ``replanned`` are :func:`tamp.run.run_mission`'s recorded lists. Counts, and per metre."""
    ticks, dist = _flips(poses, dt)
    out = {"handover": 0, "replan": 0, "tracking": 0}
    for k in ticks:
        if replanned[k]:
            out["replan"] += 1
        elif waypoints[k] != waypoints[k - 1]:
            out["handover"] += 1
        else:
            out["tracking"] += 1
    out["per_m"] = {key: (n / dist if dist > 1e-9 else 0.0) for key, n in list(out.items())}
    return out


_DEFAULTS = ExecutiveConfig()  # HT's buffers, which the clearance-matched baselines keep


class RRTStarBufferExecutive(RRTStarExecutive):
    """:class:`RRTStarExecutive` keeping HT's clearance: the obstacles grown by the robot radius
    plus the harmonic trees' ``buffer`` (paper 001: 0.15 m) instead of 5 cm, and where no path
    keeps it, HT's ``fallback_buffer`` (0.03 m) in the last retry, as HT's trees fall back to it."""

    margin = _DEFAULTS.buffer
    fallback_margin = _DEFAULTS.fallback_buffer


_CLASSES = {"OHPF": OHPFExecutive, "NF": NFExecutive, "RRT*": RRTStarExecutive, "RRT*-buffer": RRTStarBufferExecutive}
#: the executive configuration of the baselines: the defaults without the route rescue and
#: without going to look before stopping blocked, which both drive along harmonic trees (HT's
#: execution layer; docs/executive.md), and tracking fields, not pursuing a tree's path
BASELINE_CONFIG = ExecutiveConfig(route_rescue=False, look_tries=0, pursuit=0.0)
#: HT with the paper's execution: every default but the pursuit of the leg
FIELDS_CONFIG = ExecutiveConfig(pursuit=0.0)
#: the clearance (m beyond the robot radius) each method keeps from obstacles where it can, the
#: buffer of :func:`oracle_tour`'s yardstick for it (``None``: no nominal clearance, NF's field);
#: HT and OHPF go through narrow passages at ``fallback_buffer``, so they can undercut theirs
CLEARANCE = {"HT": _DEFAULTS.buffer, "HT-fields": FIELDS_CONFIG.buffer, "OHPF": BASELINE_CONFIG.buffer,
             "NF": None, "RRT*": RRTStarExecutive.margin, "RRT*-buffer": RRTStarBufferExecutive.margin}


def run_method(method: str, world, task=None, *, seed: int = 0, max_time: float = 300.0,
               rrt_seed: int | None = None) -> dict:
    """Run ``method`` (one of :data:`METHODS` but ``oracle``) on ``world``'s mission (or ``task``).
    ``seed``: the simulator's; ``rrt_seed``: OMPL's for the RRT* methods (default
    :attr:`RRTStarExecutive.seed`; at least 1)."""
    if rrt_seed is not None and not (isinstance(rrt_seed, int) and rrt_seed >= 1):
        raise ValueError(f"rrt_seed must be an integer of at least 1 (OMPL ignores 0), got {rrt_seed!r}")
    if method == "HT":
        r = run_mission(world, task, seed=seed, max_time=max_time, record=True)
    elif method == "HT-fields":
        r = run_mission(world, task, seed=seed, max_time=max_time, record=True, config=FIELDS_CONFIG)
    elif method in _CLASSES:
        # the route rescue pursues harmonic trees' segments: part of HT's execution, not the baselines'
        cls = _CLASSES[method]
        if rrt_seed is not None and issubclass(cls, RRTStarExecutive):
            cls = type(cls.__name__, (cls,), {"seed": rrt_seed})
        r = run_mission(world, task, seed=seed, max_time=max_time, record=True, executive_cls=cls,
                        config=BASELINE_CONFIG)
    else:
        raise ValueError(f"unknown method {method!r}, must be one of {', '.join(m for m in METHODS if m != 'oracle')}")
    dt = 1.0 / world.lidar.rate_hz
    r["chatter"] = chatter(r["trajectory"], dt)
    r["chatter_sources"] = chatter_sources(r["trajectory"], r["waypoints"], r["replanned"], dt)
    return r


# ------------------------------------------------------------------------------------ oracle
ORACLE_OFFSET = 0.005  #: distance (m) of the oracle roadmap's vertices off the robot-grown obstacles
ORACLE_RING = 64  #: touch points sampled on each region's disc boundary


def tour_distances(world, names, *, ring: int = ORACLE_RING, offset: float = ORACLE_OFFSET, buffer: float = 0.0):
    """Shortest collision-free path lengths with every obstacle known, from the robot's start and
    from points on the boundaries of the discs of the regions ``names``: ``(D, s, rings)``.
    ``rings[name]`` are the roadmap vertex indices of that region's touch points, ``s`` the
    start's; ``D`` has a row per source, the start first and then every touch point in
    ``rings`` order, and a column per roadmap vertex (``inf`` where unreachable).

    The roadmap (:class:`tamp.roadmap.Roadmap`) keeps no buffer: the obstacles grown by the
    robot radius, vertices ``offset`` outside them (chords between neighbours missing them),
    every visible pair joined. A region counts as visited when the robot's centre enters its
    disc, so a leg may end on the disc's boundary: ``ring`` points on it (a start inside a
    disc is one of its points). A path a metre long past a rounded corner is at most about
    ``offset`` times the turn longer than the exact shortest one.

    With ``buffer > 0`` the obstacles are grown by ``radius + buffer`` and the workspace shrunk
    by as much: the shortest tour of a robot that keeps ``buffer`` from everything, the yardstick
    of a method with that clearance (:data:`CLEARANCE`; touch points inside the grown obstacles
    are dropped, and a disc left without any is unreachable)."""
    from scipy.sparse.csgraph import dijkstra

    from tamp.roadmap import Roadmap, RoadmapConfig

    start = np.asarray(world.robot.start[:2], dtype=float)
    ang = 2.0 * np.pi * np.arange(ring) / ring
    unit = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    cand, owner = [start[None, :]], [np.array([-1])]
    for k, name in enumerate(names):
        reg = world.regions[name]
        c = np.asarray(reg.center, dtype=float)
        cand.append(c + reg.radius * (1.0 - 1e-9) * unit)
        owner.append(np.full(ring, k))
        if np.linalg.norm(start - c) <= reg.radius:
            cand.append(start[None, :])
            owner.append(np.array([k]))
    cand, owner = np.concatenate(cand), np.concatenate(owner)
    config = RoadmapConfig(buffer=float(buffer), offset=offset)
    rm = Roadmap.build(world.workspace, world.obstacles, world.robot.radius, config, extra=cand)
    keep = rm.safe_points(cand)
    if not keep[0]:
        raise ValueError(f"the start {tuple(start)} is not in the free space of {world.name}"
                         + (f" at buffer {buffer:g} m" if buffer else ""))
    idx = np.flatnonzero(rm.owner == -1)  # the kept candidates, in order
    if len(idx) != int(keep.sum()):
        raise RuntimeError("the oracle's roadmap kept other touch points than its free-space test")
    vid = np.full(len(cand), -1)
    vid[keep] = idx
    rings = {name: vid[(owner == k) & keep] for k, name in enumerate(names)}
    sources = np.concatenate([[vid[0]], *rings.values()])
    return dijkstra(rm.graph(), directed=False, indices=sources), vid[0], rings


def oracle_tour(world, sequence, visit_all: bool = False, *, buffer: float = 0.0) -> tuple[float | None, list[str]]:
    """Lower bound on the travel distance of a run that enters the regions of ``sequence`` in
    that order, every obstacle known (:func:`tour_distances`): from the start to a point of the
    first disc, from there to a point of the next, and so on, minimised over the points by
    dynamic programming over the discs. With ``visit_all`` the smallest over every order of
    the distinct regions of ``sequence`` (a lower bound for any method on a visit-all
    mission). Returns the length (``None`` when no order has a path) and the order used.
    ``buffer``: the tour keeping that clearance beyond the robot radius (:func:`tour_distances`),
    the yardstick of a method that keeps it; ``0`` (default) is the lower bound.

    Since the forty-fifth session; before, the tour of the executive benchmark
    (:func:`benchmarks.executive.full_knowledge_tour`: from region centre to region centre,
    roadmap vertices 5 cm off the grown obstacles), which runs could undercut."""
    seq = list(sequence)
    orders = [seq]
    distinct = list(dict.fromkeys(seq))
    if visit_all and len(distinct) <= 6:
        orders = [list(o) for o in itertools.permutations(distinct)]
    if not seq:
        return 0.0, seq
    D, s, rings = tour_distances(world, distinct, buffer=buffer)
    row = {int(v): k for k, v in enumerate(np.concatenate([[s], *rings.values()]))}
    best, best_order = None, seq
    for order in orders:
        cost, at = np.zeros(1), np.array([s])
        for name in order:
            to = rings[name]
            if not len(to):
                cost = np.zeros(0)
                break
            legs = D[[row[int(a)] for a in at]][:, to]
            cost, at = np.min(cost[:, None] + legs, axis=0), to
        d = float(cost.min()) if len(cost) else math.inf
        if math.isfinite(d) and (best is None or d < best):
            best, best_order = d, order
    return best, best_order
