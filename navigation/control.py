"""Smooth harmonic-tracking unicycle controller (paper 001 section 4.1.3, eq. 24-25).

For a pose ``(q, theta)`` and an :class:`~navigation.oriented.OrientedField` with goal pose
``(q_G, theta_G)`` (direction ``theta_gamma(q)`` of ``Upsilon``):

.. math::

    v &= k_v \\tanh(\\|q - q_G\\|)\\,\\max(0, \\cos(\\theta - \\theta_\\gamma))      && (24a)\\\\
    \\omega &= -k_\\omega\\,\\mathrm{wrap}(\\theta - \\theta_\\gamma)
              + v\\,\\nabla\\theta_\\gamma(q) \\cdot (\\cos\\theta, \\sin\\theta)          && (24b)

then saturated to ``|v| <= v_max``, ``|omega| <= omega_max`` (world file ``robot``).

Choices where the paper is silent or loose, and why:

* **(24b) feed-forward.** The paper writes ``v [grad theta_gamma]^T J_gamma Theta``; the
  derivative of ``theta_gamma`` along the motion ``q' = v Theta`` is
  ``v (d theta_gamma / d Upsilon)^T J_Upsilon Theta = v grad_q theta_gamma . Theta``, which is
  what we use (``grad_q theta_gamma`` exact, from :meth:`OrientedField.evaluate`).
* **Heading gate on (24a).** Eq. 24a drives forward at ``k_v tanh(d)`` whatever the heading
  error; with a saturated ``omega`` the robot can then drive along its old heading into an
  obstacle. We multiply by ``max(0, cos(theta - theta_gamma))`` (``ControllerConfig.heading_gate``):
  the robot turns in place when it faces away from the field and otherwise moves with a
  positive component along ``Upsilon``. At the goal it still converges, since
  ``theta_gamma -> theta_G`` along the arrival direction.
* **Switch of eq. 25.** ``u = u(q, q_n) + eta(gamma_n)(u(q, q_{n+1}) - u(q, q_n))`` with
  ``gamma_n = |q - q_n|`` and ``eta(gamma) = (1 + tanh(k_s (eps - gamma) / eps)) / 2``: the
  paper's ``eta_eps`` normalised by the margin so that ``k_s = 2``, ``eps = 0.1`` m (section 5.1)
  give a switch that is 0.02 at ``2 eps``, 1/2 at ``eps`` and 0.98 at the waypoint (taken
  literally with ``k_s = 2`` 1/m the switch would only reach 0.6 at the waypoint).
  Commands are blended before saturation, so they are continuous in the pose.
* **Safety limit (not in the paper).** With commands held for a control period ``dt``, a
  saturated ``omega`` and a 5 cm step can carry the robot across the thin layer next to an
  (inflated) boundary in which the field turns away, before the field has turned it. We cap
  ``v <= d(q) / safety_horizon`` where ``d(q)`` is a certified lower bound on the distance from
  ``q`` to the field's obstacles and workspace boundary (:attr:`OrientedField.clearance`; those
  obstacles are grown by the robot radius). If ``dt <= safety_horizon`` (default 0.1 s, the
  paper's control period), a step moves the robot by at most ``v dt <= d(q)``, so the robot
  stays in the grown free space and its disc never touches an obstacle, whatever the field
  does. The cap is continuous in the pose and only acts within ``v_max * safety_horizon``
  (5 cm at 0.5 m/s) of a grown boundary. It is applied to ``v`` before ``v`` enters the
  feed-forward term of (24b): a robot held still must not turn by the amount the field would
  rotate under a motion it does not make. ``safety_horizon=0`` disables it. (A horizon of
  0.2 s, moving at most half the clearance per step, gave the same success but more turn-rate
  oscillation, measured with ``benchmarks.control``.)
* **Outside free space or degenerate field.** The oriented field's outside contract gives a
  unit vector back into free space: the controller turns towards it and only moves once it
  faces it (heading gate). At the goal itself ``theta_gamma = theta_G``. Non-finite poses raise
  :class:`~navigation.errors.NavigationError`; commands are always finite.

A controller step is a pure function of the pose and the waypoint fields: one field
evaluation (two with a following waypoint), about a millisecond at 20 obstacles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import NavigationError
from .oriented import OrientedField, wrap_angle

__all__ = ["ControllerConfig", "Command", "track", "track_waypoints", "switch_weight"]


@dataclass(frozen=True, slots=True)
class ControllerConfig:
    """Gains and limits of eq. 24-25 (defaults: paper 001 section 5.1).

    Attributes
    ----------
    k_v, k_omega : float
        Gains of eq. 24 (1.0 and 0.8).
    v_max, omega_max : float
        Saturation limits (m/s, rad/s); use :meth:`from_robot` to take them from a world.
    k_switch, switch_margin : float
        ``k_s`` and ``eps`` of eq. 25 (2.0 and 0.1 m).
    heading_gate : bool
        Multiply eq. 24a by ``max(0, cos(theta - theta_gamma))`` (see the module doc).
    safety_horizon : float
        Cap ``v <= clearance / safety_horizon`` (s; 0.1, the paper's control period; 0 turns
        the cap off). Safe for control periods up to ``safety_horizon`` (see the module doc).
    """

    k_v: float = 1.0
    k_omega: float = 0.8
    v_max: float = 0.5
    omega_max: float = 1.0
    k_switch: float = 2.0
    switch_margin: float = 0.1
    heading_gate: bool = True
    safety_horizon: float = 0.1

    def __post_init__(self):
        for name in ("k_v", "k_omega", "v_max", "omega_max", "k_switch", "switch_margin"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise NavigationError(f"ControllerConfig.{name} must be a positive finite number, got {value!r}")
        h = self.safety_horizon
        if not (isinstance(h, (int, float)) and math.isfinite(h) and h >= 0):
            raise NavigationError(f"ControllerConfig.safety_horizon must be a finite number >= 0, got {h!r}")

    @classmethod
    def from_robot(cls, robot, **overrides) -> "ControllerConfig":
        """Limits from a world's ``robot`` spec (``v_max``, ``omega_max``); gains by default."""
        return cls(v_max=float(robot.v_max), omega_max=float(robot.omega_max), **overrides)


@dataclass(frozen=True, slots=True)
class Command:
    """One controller output.

    Attributes
    ----------
    v, omega : float
        Saturated command.
    theta_gamma : float
        Direction of the (current waypoint's) field at the pose.
    clipped : bool
        Saturation (or the safety limit) changed the raw command.
    """

    v: float
    omega: float
    theta_gamma: float
    clipped: bool


def _pose(pose) -> tuple[np.ndarray, float]:
    try:
        p = np.asarray(pose, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        p = np.empty(0)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise NavigationError(f"pose must be three finite numbers (x, y, theta), got {pose!r}")
    return p[:2], float(p[2])


def _raw(q: np.ndarray, theta: float, field: OrientedField, cfg: ControllerConfig):
    """Eq. 24 with ``v`` limited before it enters the feed-forward term of ``omega``."""
    ev = field.evaluate(q)
    tg = float(ev.angle)
    err = wrap_angle(theta - tg)
    v = cfg.k_v * math.tanh(float(np.linalg.norm(q - field.goal)))
    if cfg.heading_gate:
        v *= max(0.0, math.cos(err))
    raw = v
    v = min(v, cfg.v_max)
    if cfg.safety_horizon > 0 and v > 0.0:
        v = min(v, float(field.clearance(q, cfg.v_max * cfg.safety_horizon)) / cfg.safety_horizon)
    ff = float(np.dot(ev.angle_gradient, (math.cos(theta), math.sin(theta))))
    omega = -cfg.k_omega * err + v * ff
    return v, omega, tg, v != raw


def _saturate(v: float, omega: float, cfg: ControllerConfig):
    ws = min(max(omega, -cfg.omega_max), cfg.omega_max)
    return v, ws, ws != omega


def track(pose, field: OrientedField, config: ControllerConfig = ControllerConfig()) -> Command:
    """Eq. 24: command that tracks ``field`` from ``pose = (x, y, theta)``.

    Raises
    ------
    NavigationError
        Non-finite or malformed pose.
    """
    q, theta = _pose(pose)
    v, omega, tg, limited = _raw(q, theta, field, config)
    v, omega, clipped = _saturate(v, omega, config)
    return Command(v, omega, tg, clipped or limited)


def switch_weight(distance: float, config: ControllerConfig = ControllerConfig()) -> float:
    """``eta(gamma_n)`` of eq. 25 (normalised form, see the module doc)."""
    eps = config.switch_margin
    return 0.5 * (1.0 + math.tanh(config.k_switch * (eps - float(distance)) / eps))


def track_waypoints(pose, current: OrientedField, following: OrientedField | None = None,
                    config: ControllerConfig = ControllerConfig()) -> Command:
    """Eq. 25: blend of the commands towards ``current`` and ``following`` waypoints.

    With ``following=None`` this is :func:`track` towards ``current``.
    """
    q, theta = _pose(pose)
    v0, w0, tg, limited = _raw(q, theta, current, config)
    if following is not None:
        eta = switch_weight(float(np.linalg.norm(q - current.goal)), config)
        if eta > 0.0:
            v1, w1, tg1, limited1 = _raw(q, theta, following, config)
            limited = limited or limited1
            v0, w0 = v0 + eta * (v1 - v0), w0 + eta * (w1 - w0)
            if eta > 0.5:
                tg = tg1
    v, omega, clipped = _saturate(v0, w0, config)
    return Command(v, omega, tg, clipped or limited)
