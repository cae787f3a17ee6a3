"""The simulator: one stateful object that owns the robot's true pose, time and metrics.

:class:`Simulator` integrates the unicycle exactly (:mod:`service.sim.kinematics`), refuses
to move the robot disc into an obstacle or out of the workspace (:mod:`service.sim.collision`)
and produces lidar scans of the ground truth (:mod:`service.sim.lidar`). It speaks the bus
contract of ``shared/FORMATS.md``:

* ``pose``: ``{"stamp", "x", "y", "theta"}`` (:meth:`Simulator.pose_message`);
* ``scan``: ``{"stamp", "angle_min", "angle_increment", "range_min", "range_max", "ranges"}``
  (:meth:`Simulator.scan_message`); a beam without a return carries exactly ``range_max``
  (JSON has no ``inf``; the contract reads ``>= range_max`` as no return);
* ``points``: ``{"stamp", "points": [[x, y], ...]}`` (:meth:`Simulator.points_message`);
* ``cmd_vel``: ``{"stamp", "v", "omega"}`` is accepted by :meth:`Simulator.apply_cmd_vel`.

Stamps are simulated seconds (``Simulator.time``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from navigation._arrays import to_float
from navigation.world import World, load_world
from perception.ingest import decode_object

from .collision import WORKSPACE, ClearanceMap
from .errors import CollisionStartError, CommandError, PoseError, SimulatorError
from .kinematics import arc_pose, saturate, wrap_angle
from .lidar import LidarConfig, RayCaster

__all__ = ["SimConfig", "Simulator", "StepResult", "CollisionEvent", "SimMetrics", "Pose"]

Pose = tuple[float, float, float]


def _finite(x, what: str, err=SimulatorError, field_name: str | None = None) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating)):
        raise err(f"{what}: expected a number, got {x!r}", *([field_name] if err is CommandError else []))
    v = to_float(x)
    if not math.isfinite(v):
        raise err(f"{what}: must be finite, got {x!r}", *([field_name] if err is CommandError else []))
    return v


@dataclass(frozen=True, slots=True)
class SimConfig:
    """Simulator settings.

    Attributes
    ----------
    dt : float
        Integration step (s); 0.1 s as in paper 001.
    contact_tol : float
        A disc clearance below this (m) is a contact (touching counts as a collision).
    stop_margin : float
        After a contact the robot stops at the last certified pose with at least this
        clearance (m) (or its clearance at the step's start, if smaller).
    max_samples : int
        Clearance evaluations allowed per step before a grazing path is conservatively stopped.
    boundary_spacing : float
        Spacing of the boundary samples of the clearance computation (m).
    """

    dt: float = 0.1
    contact_tol: float = 1e-6
    stop_margin: float = 1e-4
    max_samples: int = 4096
    boundary_spacing: float = 0.005

    def __post_init__(self):
        for name in ("dt", "contact_tol", "stop_margin", "boundary_spacing"):
            v = _finite(getattr(self, name), f"SimConfig.{name}")
            if v <= 0:
                raise SimulatorError(f"SimConfig.{name}: must be > 0, got {v}")
            object.__setattr__(self, name, v)
        if self.stop_margin < self.contact_tol:
            raise SimulatorError(f"SimConfig.stop_margin ({self.stop_margin}) must be >= contact_tol "
                                 f"({self.contact_tol})")
        if isinstance(self.max_samples, bool) or not isinstance(self.max_samples, int) or self.max_samples < 2:
            raise SimulatorError(f"SimConfig.max_samples: expected an int >= 2, got {self.max_samples!r}")


@dataclass(frozen=True, slots=True)
class CollisionEvent:
    """A step whose motion reached an obstacle or the workspace boundary.

    ``time`` is the simulated time of the contact, ``pose`` the pose the robot was stopped at
    (collision-free), ``obstacle`` the obstacle index or ``"workspace"``, ``command`` the
    (saturated) ``(v, omega)`` that was being executed.
    """

    time: float
    pose: Pose
    obstacle: int | str
    command: tuple[float, float]

    def to_dict(self) -> dict:
        return {"time": self.time, "pose": list(self.pose), "obstacle": self.obstacle, "command": list(self.command)}


@dataclass(frozen=True, slots=True)
class StepResult:
    """What one :meth:`Simulator.step` did.

    ``command`` is the executed (saturated) ``(v, omega)``, ``requested`` the one asked for,
    ``clipped`` whether saturation changed it; ``collision`` is the event of a blocked step
    (else None); ``clearance`` the exact disc clearance at the new ``pose``.
    """

    time: float
    pose: Pose
    command: tuple[float, float]
    requested: tuple[float, float]
    clipped: bool
    collision: CollisionEvent | None
    clearance: float


@dataclass(frozen=True, slots=True)
class SimMetrics:
    """Accumulated metrics: simulated ``time`` (s), ``steps``, ``distance`` travelled (m, arc
    length), ``min_clearance`` (m, exact disc clearance, minimum over every pose evaluated so
    far: the start, each step's end and the sub-samples of the swept checks that came within a
    step length of an obstacle), ``collisions`` (one event per blocked step) and
    ``clipped_commands`` (steps whose command was saturated)."""

    time: float
    steps: int
    distance: float
    min_clearance: float
    collisions: tuple[CollisionEvent, ...]
    clipped_commands: int

    def to_dict(self) -> dict:
        return {"time": self.time, "steps": self.steps, "distance": self.distance,
                "min_clearance": self.min_clearance, "collisions": [e.to_dict() for e in self.collisions],
                "clipped_commands": self.clipped_commands}


@dataclass
class _State:
    pose: Pose
    clearance: float
    time: float = 0.0
    steps: int = 0
    command: tuple[float, float] = (0.0, 0.0)
    distance: float = 0.0
    min_clearance: float = math.inf
    collisions: list = field(default_factory=list)
    clipped: int = 0


class Simulator:
    """Unicycle + lidar simulator of a world's ground truth (the one stateful object of the layer).

    Parameters
    ----------
    world : World
        Ground truth: ``workspace``, ``obstacles`` (all of them, known or not), ``robot``
        (radius, start, ``v_max``, ``omega_max``) and ``lidar``.
    seed : int, numpy.random.Generator or None
        Seed of the range-noise generator.
    dt : float or None
        Step (s); overrides ``config.dt``.
    config : SimConfig or None
    pose : (x, y, theta) or None
        Start pose; default ``world.robot.start``.
    lidar : LidarConfig or None
        Overrides the world's lidar.

    Raises
    ------
    PoseError
        The start pose is not three finite numbers.
    CollisionStartError
        The robot disc at the start pose touches an obstacle or the workspace boundary.

    Examples
    --------
    >>> sim = Simulator(load_world("simple"), seed=0)
    >>> r = sim.step((0.5, 0.0))                  # 0.1 s at 0.5 m/s along the heading
    >>> round(r.pose[0] - 0.5, 12), r.collision is None
    (0.05, True)
    >>> msg = sim.scan_message()
    >>> len(msg["ranges"]), msg["range_max"]
    (360, 1.5)
    """

    def __init__(self, world: World, *, seed=None, dt: float | None = None, config: SimConfig | None = None,
                 pose=None, lidar: LidarConfig | None = None):
        if not isinstance(world, World):
            raise SimulatorError(f"expected a navigation.World, got {type(world).__name__}")
        cfg = config or SimConfig()
        if dt is not None:
            cfg = SimConfig(dt, cfg.contact_tol, cfg.stop_margin, cfg.max_samples, cfg.boundary_spacing)
        self.world = world
        self.config = cfg
        self.lidar = lidar or LidarConfig.from_spec(world.lidar)
        if not (seed is None or isinstance(seed, np.random.Generator)
                or (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0)):
            raise SimulatorError(f"seed must be None, a numpy Generator or an integer >= 0, got {seed!r}")
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self._clear = ClearanceMap(world.workspace, world.obstacles, world.robot.radius, cfg.boundary_spacing)
        self._rays = RayCaster(world.workspace, world.obstacles)
        self._beams = self.lidar.angles()
        self._state: _State
        self.reset(world.robot.start if pose is None else pose)

    @classmethod
    def from_file(cls, path, **kwargs) -> "Simulator":
        """A simulator of the world file ``path`` (or built-in world name); see :func:`navigation.load_world`."""
        return cls(load_world(path), **kwargs)

    # ------------------------------------------------------------------ state
    @property
    def pose(self) -> Pose:
        """True pose ``(x, y, theta)``, theta in ``(-pi, pi]``."""
        return self._state.pose

    @property
    def time(self) -> float:
        """Simulated time (s): ``steps * dt`` since the last :meth:`reset`."""
        return self._state.time

    @property
    def dt(self) -> float:
        return self.config.dt

    @property
    def command(self) -> tuple[float, float]:
        """The held command ``(v, omega)`` as requested (saturated when executed)."""
        return self._state.command

    @property
    def clearance(self) -> float:
        """Exact clearance of the robot disc at the current pose (m)."""
        return self._state.clearance

    @property
    def metrics(self) -> SimMetrics:
        s = self._state
        return SimMetrics(s.time, s.steps, s.distance, s.min_clearance, tuple(s.collisions), s.clipped)

    def clearance_at(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Exact disc clearance at centres ``q (K, 2)`` and the nearest obstacle index (-1 workspace)."""
        return self._clear.clearance(np.asarray(q, dtype=float).reshape(-1, 2))

    def reset(self, pose=None, time: float = 0.0) -> None:
        """Place the robot at ``pose`` (default: the world's start), zero the command and metrics.

        Raises
        ------
        PoseError, CollisionStartError
            As for the constructor.
        """
        p = self._check_pose(self.world.robot.start if pose is None else pose)
        c = self._check_free(p)
        self._state = _State(pose=p, clearance=c, time=_finite(time, "time", PoseError), min_clearance=c)

    def _check_pose(self, pose) -> Pose:
        try:
            vals = list(pose)
        except TypeError:
            raise PoseError(f"pose: expected (x, y, theta), got {pose!r}") from None
        if len(vals) != 3:
            raise PoseError(f"pose: expected (x, y, theta), got {len(vals)} value(s): {pose!r}")
        x, y, th = (_finite(v, f"pose.{n}", PoseError) for v, n in zip(vals, ("x", "y", "theta")))
        return (x, y, wrap_angle(th))

    def _check_free(self, p: Pose) -> float:
        c, who = self._clear.clearance(np.array(p[:2]))
        c, who = float(c[0]), int(who[0])
        if c < self.config.contact_tol:
            name = "the workspace boundary" if who == WORKSPACE else f"obstacles[{who}]"
            raise CollisionStartError(
                f"pose ({p[0]:.6g}, {p[1]:.6g}): the robot disc (radius {self.world.robot.radius:g}) is in collision "
                f"with {name} (clearance {c:.3g} m < contact_tol {self.config.contact_tol:g})",
                "workspace" if who == WORKSPACE else who, c)
        return c

    # ------------------------------------------------------------------ commands
    def set_command(self, v, omega) -> tuple[float, float]:
        """Hold the command ``(v, omega)`` (requested values; saturated when executed).

        Raises
        ------
        CommandError
            ``v`` or ``omega`` is not a finite number.
        """
        cmd = (_finite(v, "v", CommandError, "v"), _finite(omega, "omega", CommandError, "omega"))
        self._state.command = cmd
        return cmd

    def apply_cmd_vel(self, message) -> tuple[float, float]:
        """Hold the command of a bus ``cmd_vel`` message ``{"stamp", "v", "omega"}``.

        ``message`` is a mapping or its JSON text (``str`` / ``bytes``). Extra fields are
        ignored (the contract may gain optional fields). Returns the held ``(v, omega)``.

        Raises
        ------
        CommandError
            Not a JSON object, a field missing, not a number (booleans are refused) or not
            finite; ``field`` names it. The held command is then unchanged.
        """
        message = decode_object(message, lambda reason: CommandError(f"cmd_vel: payload {reason}"))
        for key in ("stamp", "v", "omega"):
            if key not in message:
                raise CommandError(f"cmd_vel: missing field {key!r}", key)
        _finite(message["stamp"], "cmd_vel.stamp", CommandError, "stamp")
        v = _finite(message["v"], "cmd_vel.v", CommandError, "v")
        omega = _finite(message["omega"], "cmd_vel.omega", CommandError, "omega")
        return self.set_command(v, omega)

    # ------------------------------------------------------------------ motion
    def step(self, cmd=None) -> StepResult:
        """Advance ``dt`` seconds with ``cmd = (v, omega)`` (held from then on) or the held command.

        The command is saturated to ``|v| <= v_max``, ``|omega| <= omega_max`` and integrated
        exactly along an arc. If the arc reaches an obstacle or the boundary, the robot stops
        at the last collision-free pose before it (see :mod:`service.sim.collision`) and a
        :class:`CollisionEvent` is recorded and returned; time still advances by ``dt``.

        Raises
        ------
        CommandError
            ``cmd`` is not a pair of finite numbers.
        """
        if cmd is not None:
            try:
                v, omega = cmd
            except (TypeError, ValueError):
                raise CommandError(f"command: expected (v, omega), got {cmd!r}") from None
            self.set_command(v, omega)
        s, cfg, robot = self._state, self.config, self.world.robot
        req = s.command
        v, omega, clipped = saturate(req[0], req[1], robot.v_max, robot.omega_max)
        t0 = s.time
        sw = self._clear.sweep(s.pose, v, omega, cfg.dt, s.clearance, contact_tol=cfg.contact_tol,
                               stop_margin=cfg.stop_margin, max_samples=cfg.max_samples)
        pose = arc_pose(s.pose, v, omega, sw.t_stop) if sw.t_stop > 0.0 else s.pose
        if v != 0.0 and sw.t_stop > 0.0:
            c, _ = self._clear.clearance(np.array(pose[:2]))
            c = float(c[0])
        else:
            c = s.clearance
        event = None
        if sw.contact:
            event = CollisionEvent(t0 + sw.t_contact, pose, "workspace" if sw.owner == WORKSPACE else sw.owner,
                                   (v, omega))
            s.collisions.append(event)
        s.pose, s.clearance = pose, c
        s.steps += 1
        s.time = t0 + cfg.dt
        s.distance += abs(v) * sw.t_stop
        s.min_clearance = min(s.min_clearance, c, sw.min_clearance)
        s.clipped += int(clipped)
        return StepResult(s.time, pose, (v, omega), req, clipped, event, c)

    # ------------------------------------------------------------------ sensing
    def true_ranges(self, pose=None) -> np.ndarray:
        """Noise-free ranges ``(beams,)`` at ``pose`` (default: the current one); ``inf`` = no return."""
        p = self.pose if pose is None else self._check_pose(pose)
        return self._rays.cast(p[:2], p[2] + self._beams, self.lidar.range)

    def scan(self, pose=None) -> np.ndarray:
        """One lidar scan ``(beams,)`` with range noise (see :mod:`service.sim.lidar`); ``inf`` = no return."""
        r = self.true_ranges(pose)
        if self.lidar.noise_std > 0.0:
            hit = np.isfinite(r)
            noisy = r[hit] + self.rng.normal(0.0, self.lidar.noise_std, int(hit.sum()))
            noisy = np.maximum(noisy, self.lidar.range_min)
            r[hit] = np.where(noisy >= self.lidar.range, math.inf, noisy)
        return r

    def scan_points(self, ranges=None, pose=None) -> np.ndarray:
        """World-frame points ``(N, 2)`` of the returns of ``ranges`` (default: a new :meth:`scan`)
        taken at ``pose`` (default: the current one)."""
        p = self.pose if pose is None else self._check_pose(pose)
        r = self.scan(p) if ranges is None else np.asarray(ranges, dtype=float).reshape(-1)
        if r.shape != self._beams.shape:
            raise SimulatorError(f"ranges: expected {len(self._beams)} values, got {r.shape}")
        hit = np.isfinite(r) & (r < self.lidar.range)
        a = p[2] + self._beams[hit]
        return np.stack((p[0] + r[hit] * np.cos(a), p[1] + r[hit] * np.sin(a)), axis=1)

    # ------------------------------------------------------------------ messages
    def _stamp(self, stamp) -> float:
        return self.time if stamp is None else _finite(stamp, "stamp")

    def pose_message(self, stamp: float | None = None) -> dict:
        """Bus ``pose`` message ``{"stamp", "x", "y", "theta"}`` of the true pose."""
        x, y, th = self.pose
        return {"stamp": self._stamp(stamp), "x": x, "y": y, "theta": th}

    def scan_message(self, stamp: float | None = None, ranges=None) -> dict:
        """Bus ``scan`` message of ``ranges`` (default: a new :meth:`scan`); no return -> ``range_max``."""
        r = self.scan() if ranges is None else np.asarray(ranges, dtype=float).reshape(-1)
        rmax = self.lidar.range
        out = np.where(np.isfinite(r) & (r < rmax), r, rmax)
        return {"stamp": self._stamp(stamp), "angle_min": self.lidar.angle_min,
                "angle_increment": self.lidar.angle_increment, "range_min": self.lidar.range_min,
                "range_max": rmax, "ranges": out.tolist()}

    def points_message(self, stamp: float | None = None, ranges=None) -> dict:
        """Bus ``points`` message ``{"stamp", "points": [[x, y], ...]}`` (world frame) of a scan."""
        return {"stamp": self._stamp(stamp), "points": self.scan_points(ranges).tolist()}
