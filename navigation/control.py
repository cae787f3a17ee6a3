"""Smooth harmonic-tracking unicycle controller (paper 001 section 4.1.3, eq. 24-25).

For a pose ``(q, theta)`` and an :class:`~navigation.oriented.OrientedField` with goal pose
``(q_G, theta_G)`` (direction ``theta_gamma(q)`` of the tracked field):

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
  ``ControllerConfig.waypoint_feedforward`` (not in the paper; 1 by default) scales this term
  while the tracked goal is an intermediate waypoint (``beyond > 0``): a robot that passes
  such a goal a few centimetres off its axis meets the field's fast rotation near the goal,
  and the full feed-forward turns it hard towards the goal's heading just before the next
  waypoint's field turns it back (an S-turn at every waypoint, docs/history.md, "Where the chatter comes from"). A smaller
  share lets the heading lag there; the path's end (``beyond = 0``) keeps the whole term.
* **Heading gate on (24a).** Eq. 24a drives forward at ``k_v tanh(d)`` whatever the heading
  error; with a saturated ``omega`` the robot can then drive along its old heading into an
  obstacle. We multiply by ``max(0, cos(theta - theta_gamma))`` (``ControllerConfig.heading_gate``):
  the robot turns in place when it faces away from the field and otherwise moves with a
  positive component along it. At the goal it still converges, since
  ``theta_gamma -> theta_G`` along the arrival direction. :func:`track_point` takes a
  narrower ``gate`` (``max(0, (cos e - cos gate) / (1 - cos gate))``, 0 beyond ``gate``): the
  executive's pursuit of a leg turns on the spot beyond 60 degrees instead of arcing off it.
* **Which direction is tracked** (``ControllerConfig.push_forward``, default off). By default
  ``theta_gamma`` is the direction of ``Upsilon = -grad phi_ONF`` (eq. 23). Where the
  navigation transformation is strongly anisotropic (singular values of ``dPhi/dq`` 50 to 1 and
  more inside free space on ``simple`` and ``office``) that gradient is pinned to ``+-`` the major
  singular direction and flips across thin folds: ``|grad theta_gamma|`` of 10^2-10^4 rad/m
  (measured). At ``dt = 0.1`` s the feed-forward of (24b) then acts as a heading feedback of
  gain ``v |grad theta_gamma|`` far above the sampled-data limit ``2 / dt`` and ``omega``
  alternates between ``+-omega_max`` every period: this is the turn-rate chatter the benchmarks
  flag (docs/control.md, "Turn-rate chatter"). With ``push_forward=True`` the controller tracks
  instead the direction of the push-forward flow ``-(dx'/dq)^(-1) grad_x' phi_O``
  (:attr:`OrientedEval.flow_angle`): its integral curves are the preimages of the point world's
  gradient curves, so it descends ``phi_ONF`` everywhere, keeps the goal, the saddles and the
  arrival heading, and has no folds; within ``boundary_blend`` of a grown boundary (where it
  turns tangential and the safety limit would pin the robot) it is blended smoothly into
  ``Upsilon``'s direction, which points out of the boundary there.
* **Relaxed direction (not in the paper; opt-in: ``ControllerConfig.relax = 1.0``).** Where the
  navigation transformation is strongly anisotropic the integral curves of ``Upsilon`` run in
  valleys of ``phi_ONF`` a few millimetres wide (next to chained walls, at 10 cm from the
  walls of a room), across which the direction of ``Upsilon`` reverses: a robot that takes
  5 cm steps zigzags across the valley, turning in place at each crossing. With
  ``relax = r > 0`` eq. 24 tracks the direction of the linearly implicit step of the
  gradient flow instead, ``d = -(I + (s / |g|) H_+)^(-1) g`` (``g``, ``H``: gradient and
  Hessian of ``phi_O``, :attr:`OrientedEval.potential_gradient` / ``potential_hessian``;
  ``H_+`` its positive part; ``s = r min(v_max, k_v tanh(...)) h`` the step the robot is
  about to take, ``h`` the safety horizon): the cross-valley component, whose Hessian
  eigenvalue is large, is damped by ``1 / (1 + s lambda / |g|)``, the along-valley one is
  kept, as the implicit steps of :mod:`navigation.descent` do. ``d`` is continuous,
  ``d . (-g) = g^T M g > 0`` (``M = (I + (s / |g|) H_+)^(-1)`` is positive definite), so it
  descends ``phi_ONF`` everywhere and keeps the goal, the boundaries' repulsion and (with
  ``s -> 0`` as the robot slows down at the goal, ``H``'s eigenvectors aligned with the
  dipole's axis on it) the arrival heading. The feed-forward of (24b) uses the gradient of
  ``atan2(d)`` with ``M`` frozen over the step (``grad d = -M H``; the exact gradient would need
  third derivatives of the chain): in a valley it is bounded by about ``1 / s`` instead of
  ``|grad theta_gamma|`` of 10^2-10^4 rad/m. The step is capped at :data:`RELAX_ROOM` (10)
  times the clearance ``d(q)`` of the safety limit: next to a grown boundary the Hessian's
  normal eigenvalue grows like ``|g| / d``, and an uncapped step would damp the boundary's
  repulsion until ``d`` looks tangential along the wall (measured: robots then slid into
  estimates perception grew next to them); with the cap it is damped by at most ``1 / 11``, and
  on the boundary itself ``d`` is ``Upsilon``'s direction. ``relax = 0`` is eq. 24 on
  ``Upsilon``. Not the default: measured (docs/control.md, "Relaxed direction") it cuts
  turn-sign flips and mission times on the random worlds, but the closed-loop benchmark loses
  a few more runs in the trenches along chained walls and ``cluttered20``'s mission gets slower.
* **Switch of eq. 25.** ``eta(gamma_n) = (1 + tanh(k_s (eps - gamma_n) / eps)) / 2`` with
  ``gamma_n = |q - q_n|``: the paper's ``eta_eps`` normalised by the margin so that ``k_s = 2``,
  ``eps = 0.1`` m (section 5.1) give a switch that is 0.02 at ``2 eps``, 1/2 at ``eps`` and 0.98
  at the waypoint (taken literally with ``k_s = 2`` 1/m the switch would only reach 0.6 at the
  waypoint). Eq. 25 blends the *commands* ``u = (v, omega)`` of the two waypoints; we blend
  their *directions* instead, ``b = (1 - eta) u_n + eta u_{n+1}`` (unit vectors), and the speed
  factors ``tanh |q - q_n|``, ``tanh |q - q_{n+1}|``, and apply eq. 24 once to ``atan2(b)``
  (its gradient exact, the switch's own gradient included). Blending ``omega`` computed from
  two wrapped heading errors has spurious equilibria (the blend cancels with both ``v`` gated
  to zero when the robot faces away from both directions: the waypoint-continuity test stopped
  0.097 m from its waypoint) and jumps by ``2 pi k_omega eta`` when one error wraps at
  ``+-pi``.
* **Safety limit (not in the paper).** With commands held for a control period ``dt``, a
  saturated ``omega`` and a 5 cm step can carry the robot across the thin layer next to an
  (inflated) boundary in which the field turns away, before the field has turned it. We cap
  ``v <= safe_speed(c d(q))`` (:func:`safe_speed`) where ``d(q)`` is a certified lower bound on
  the distance from ``q`` to the field's obstacles and workspace boundary
  (:attr:`OrientedField.clearance`; those obstacles are grown by the robot radius; the smaller
  of the two waypoints' values during a switch). Without the rate limit (``accel_max = 0``,
  ``brake_share = c = 1``) this is ``v <= (d(q) - m) / safety_horizon`` with the reserve
  ``m =`` :data:`CONTACT_MARGIN` (10 micrometres): if ``dt <= safety_horizon`` (default 0.1 s,
  the paper's control period), a step moves the robot by at most ``v dt <= d(q) - m``, so the
  robot stays in the grown free space at least ``m`` from its boundary and its disc never
  touches an obstacle, whatever the field does (without the reserve a robot heading straight at
  a boundary could use its whole clearance and end in contact: measured once, in a 1 cm gap
  of ``office``, at 1.4 micrometres); the cap only acts within ``v_max * safety_horizon`` (5 cm
  at 0.5 m/s) of a grown boundary. With ``accel_max = a > 0`` the robot, lowering ``v`` by
  ``a * safety_horizon`` per period, stops within the share ``c`` of ``d(q)``; with ``c < 1``
  ``d(q)`` is replaced by the exact clearance below :data:`EXACT_BELOW` and never reaches 0, so
  a robot stopped facing a boundary can turn and leave. The cap is continuous in the pose. It is
  applied to ``v`` before ``v`` enters the feed-forward term of (24b): a robot held still must
  not turn by the amount the field would rotate under a motion it does not make.
  ``safety_horizon=0`` disables it. The guarantee is relative to the obstacles the field was
  built on: estimates that lie inside the true obstacles leave the robot that much less margin.
* **Rate-limited mode (not in the paper; the default since the twenty-seventh session:
  ``accel_max=1.0, alpha_max=6.0, brake_share=0.5``; the issue's bounded change per step;
  :data:`UNLIMITED` turns it off).** Given the previous command
  (``previous = (v, omega, dt)``; :class:`~navigation.tracker.Tracker` passes it), ``v`` and
  ``omega`` move towards eq. 24's values by at most ``accel_max dt`` and ``alpha_max dt``: with
  these values at most 0.1 m/s and 0.6 rad/s per 0.1 s period, which a robot with acceleration
  limits can execute as commanded. Eq. 24b's feed-forward uses the rate-limited ``v``. The
  braking-aware safety limit never needs to override the rate limit while the clearance shrinks
  no faster than the robot moves (the argument of :func:`safe_speed`); where it shrinks faster
  (a field on a new map with an obstacle ahead) the safety limit wins. Where the navigation
  transformation folds the tracked direction (``|grad theta_gamma|`` of 10^2-10^4 rad/m, see
  "Which direction is tracked") eq. 24 alone alternates ``omega`` between ``+-omega_max`` every
  period; the limit turns that into a bounded ramp. It was opt-in until the twenty-seventh
  session: in the trenches along chained walls the unlimited controller gets out by exactly
  that bang-bang turning, and the rate-limited robot did so less often; with the tracker's
  route rescue pursuing its routes it reaches every goal pose of the closed-loop tests and
  benchmark, as the unlimited one does (measured, docs/control.md "Rate-limited mode"). Without
  ``previous`` (or with ``accel_max = alpha_max = 0``) the controller is a pure function of the
  pose; the braking-aware safety limit applies either way.
* **Stand-off from grown boundaries (not in the paper; opt-in: ``ControllerConfig.standoff = D``,
  e.g. 0.03 m; the default 0 leaves every command as without it).** Next
  to chained walls (and the workspace boundary) the navigation transformation is so anisotropic
  that the integral curves of ``Upsilon`` and of the push-forward flow are squeezed into a
  trench 0.5-2 mm from the grown boundary, across which the direction of ``Upsilon`` reverses
  (random12_seed4, obstacle 3 of the chain 0-1-2-3: -0.03 rad and 3.11 rad 1 mm apart) and
  where the flow at 1-3 cm can even point into the wall with the opposite tangential sense to the
  trench's. A robot there is held at 0-30 mm/s by the heading gate and the safety limit and
  times out: that was almost every failure of ``benchmarks.control`` (docs/control.md).
  Within ``R D`` of a grown boundary (``R = standoff_reach``, 2 by default) the tracked
  direction of (24) is therefore changed, in three steps, each with its exact gradient
  (:func:`_standoff`, :func:`_pull`, :func:`_approach_limit`):

  1. *wall flow*: ``theta_gamma`` is blended (weight ``w = smoothstep((R D - delta) / ((R - 1)
     D))``, 1 within ``D``) into the push-forward direction read at ``q_w = q - (delta - 1 mm) nu``, the
     direction in which the trench's integral curves run along the nearest boundary
     (``delta``, ``nu``: first-order distance and normal from that boundary's ``beta``,
     :meth:`OrientedField.boundary_frame`); with ``standoff_gate = g > 0`` only where
     ``theta_gamma`` does not already lead away from that boundary (factor
     ``smoothstep(1 - (u . nu) / g)``, ``u`` the unit vector of ``theta_gamma``; default off, it
     did not help on ``office``, see docs/control.md); with ``standoff_pull = k > 0`` the
     blend ``f`` is then *pulled in* beyond ``D``, ``f - k w ((delta - D) / D) nu``, so that a
     robot following the wall round a convex corner stays near ``D`` instead of leaving the
     band along the tangent (the crawl guard's engaged mode: ``k = 1``, ``R = 4``);
  2. *push out*: within ``D`` the result ``b`` gets an outward component,
     ``u = b + W max(0, s - b . n) n`` (``s = standoff_push = 0.5``, ``W``, ``n``: band weight and
     weighted normal of the boundaries within ``D``), so the robot backs off to about ``D`` and
     follows the wall there, where the safety limit allows ``D / safety_horizon`` (0.3 m/s);
  3. *approach limit* on (24a): ``v max(0, -Theta . n) h <= max(0, delta - D / 3)`` (``h`` the
     safety horizon, :data:`SAFETY_HORIZON` when the safety limit is off; ``n`` as in 2 within
     ``D``, else ``nu``): one step does not take the robot closer than ``D / 3`` to the
     boundary. Without it a robot driving at a wall covers its whole certified clearance in one
     step and can stop where the certified bound is 0 (it is up to 2.5 mm low), where the safety
     limit holds it for good (measured on random12_seed5 and 6).

  Steps 1-2 only change the direction and step 3 only lowers ``v``; the safety limit is applied
  as before, so one step still moves the robot by at most the certified clearance. ``D`` is
  reduced to a quarter of the goal's clearance, so the goal is never inside the band. What is
  given up: within ``R D`` of a boundary ``theta_gamma`` is no longer the direction of a field
  that descends ``phi_ONF`` at ``q`` (the wall flow descends it at ``q_w``), so convergence
  there rests on measurements, not on Lemma 3. Measured (docs/control.md, "Stand-off"): it
  removes the trench time-outs on the five worst random worlds (114 to 148 of 150 runs
  reached) but on ``office`` the robot recirculates along room walls and bounces across
  narrow passages where ``Upsilon`` folds (99 to 92 of 100), which is why it is not the
  default.
* **Turn limit (not in the paper; opt-in: ``ControllerConfig.turn_share = s``; the tracker's
  wall-following mode after a loop uses 0.5).** Eq. 24b turns the robot with the tracked
  direction at ``v grad theta_gamma . Theta``; where that exceeds ``omega_max`` the robot cannot
  follow the direction's curvature and overshoots. Following the wall flow round a wall's
  convex end at 0.5 m/s (turning radius ``v_max / omega_max`` = 0.33 m, the corner's a few
  centimetres) the robot left the stand-off's band, and the unmodified field there took it back
  into the loop it came from (``random18``, docs/control.md "Loops"). With ``s > 0``, within
  the stand-off's wall band, ``v`` is lowered to ``s omega_max / |grad theta_gamma . Theta|``
  (not below :data:`TURN_FLOOR`, 0.1 m/s, where the turning radius is 7 cm at ``omega_max =
  1.5``: where ``Upsilon`` folds, ``|grad theta_gamma|`` of 10^2-10^4 rad/m, the robot is not
  held still). It only lowers ``v``, so the safety limit's guarantee is unchanged. Not on by
  default: on the slow closed-loop test's sampling it also makes the engaged stand-off follow
  walls into pockets that the plain robot overshoots and leaves (measured, docs/control.md).
* **On or outside a grown boundary (escape).** The oriented field's outside contract gives a
  unit vector back into free space, and on the boundary ``Upsilon`` points away from it. The
  safety limit alone would hold a robot there still for good (its clearance is 0, e.g. after
  perception grew an estimate up to the robot): where the clearance of the safety limit is
  below :data:`ESCAPE_BELOW` (1 mm, or negative) and the robot faces within 45 degrees of
  ``Upsilon``'s direction, ``v`` may be up to :data:`ESCAPE_SPEED` (2 cm/s) times the cosine
  of that angle (still at most eq. 24a's value and the approach limit). Moving 2 mm per period
  within 45 degrees of the outward direction increases the distance to a boundary whose
  curvature radius is well above 2 mm (grown obstacles: at least the robot radius) to first
  order; this creep is the one place where the limit is a first-order argument rather than a
  certified bound. The controller turns towards ``Upsilon`` (with the relaxed direction, whose
  step is 0 at clearance 0, that is the tracked direction there) and moves once it faces it.
  Where the tracked direction was changed (the stand-off's wall flow, the push-forward blend)
  and is more than 45 degrees from ``Upsilon``'s, the controller tracks ``Upsilon``'s
  direction itself within the escape band (no feed-forward): otherwise a robot facing along
  the boundary is held by the isotropic safety limit (measured: the engaged stand-off held one
  12.6 micrometres below a wall, in the notch of two grown obstacles, for 100 s).
  At the goal itself ``theta_gamma = theta_G``. Non-finite poses raise
  :class:`~navigation.errors.NavigationError`; commands are always finite.
* **Pursuit of a point (not in the paper; :func:`track_point`).** Eq. 24 with the bearing
  ``atan2(p - q)`` of a point as ``theta_gamma`` (its gradient ``(d_y, -d_x) / |d|^2``,
  ``d = p - q``, exact) and ``tanh(|p - q| + beyond)`` as the speed factor; the heading gate,
  safety limit (of a given field's grown obstacles), escape band, saturation and rate limit
  are those above. :class:`~navigation.tracker.Tracker` pursues the inner waypoints of a rescue
  route this way, along the route's collision-free segments, where the waypoints' own fields
  can run in the same trenches as the field that failed (docs/control.md, "Route rescue").

A controller step is a pure function of the pose and the waypoint fields: one field
evaluation (two with a following waypoint), about a millisecond at 20 obstacles. With the
stand-off, each field's grown boundaries are also evaluated once per step
(:meth:`OrientedField.boundary_scan` at the largest of the three reaches, :func:`_band`), and
within ``R D`` of a boundary the field once more at the wall-flow foot point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import NamedTuple

import numpy as np

from ._arrays import as_points
from .errors import NavigationError, PointsError, check_numbers
from .oriented import BoundaryFrame, OrientedField, wrap_angle

__all__ = ["ControllerConfig", "Command", "track", "track_waypoints", "track_point", "switch_weight", "safe_speed",
           "safety_limit", "stopping_distance", "SAFETY_HORIZON", "RATE_LIMITED", "UNLIMITED"]

RELAX_ROOM = 10.0  #: the relaxation step is at most this many times the clearance (see the module doc)
SAFETY_HORIZON = 0.1  #: default ``ControllerConfig.safety_horizon`` (s), the paper's control period
#: the rate-limited mode's settings, the defaults since the twenty-seventh session (see the module
#: doc): at most 0.1 m/s and 0.6 rad/s of change per 0.1 s period, braking within half the clearance
RATE_LIMITED = MappingProxyType({"accel_max": 1.0, "alpha_max": 6.0, "brake_share": 0.5})
#: eq. 24 without the rate limit (``ControllerConfig(**UNLIMITED)``, the default until the
#: twenty-seventh session): any change per period, the safety limit ``v <= clearance / h``
UNLIMITED = MappingProxyType({"accel_max": 0.0, "alpha_max": 0.0, "brake_share": 1.0})


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
    push_forward : bool
        Track the push-forward flow direction of the oriented potential instead of the
        direction of its gradient (see the module doc; off by default).
    boundary_blend : float
        With ``push_forward``: distance (m) to a grown boundary below which the tracked
        direction is blended into the gradient direction (smoothstep in the certified clearance).
    standoff : float
        ``D`` (m) of the stand-off from grown boundaries (see the module doc; 0, off; 0.03 is
        the measured setting): wall flow within ``standoff_reach D``, pushed out within ``D``, approach
        limited to ``D / 3``.
    standoff_push : float
        Outward component ``s`` of the tracked direction within the stand-off (0.5).
    standoff_gate : float
        If > 0, the wall flow is used only where the tracked direction's component along the
        nearest boundary's normal is below this (0: wherever the band applies).
    standoff_reach : float
        The wall flow's weight falls from 1 at ``D`` to 0 at ``standoff_reach D`` (2.0; must be
        above 1; the crawl guard's engaged mode uses 4.0).
    standoff_pull : float
        ``k`` of the pull towards the stand-off distance between ``D`` and ``standoff_reach D`` (0, off; the
        crawl guard of :class:`~navigation.tracker.Tracker` engages it with 1.0): the wall
        flow ``f`` becomes ``f - k w ((delta - D) / D) nu``, so a robot following a wall stays
        near ``D`` round convex corners instead of leaving the band along the tangent.
    accel_max : float
        ``a`` (m/s^2; 1.0, the rate-limited mode, see the module doc): the deceleration the
        safety limit assumes (the robot must be able to stop within the certified clearance,
        decelerating by ``a`` per second; see :func:`safe_speed`) and, when the previous
        command is given (``previous`` of :func:`track`, as :class:`~navigation.tracker.Tracker`
        does), the largest change of ``v`` per second. 0 (:data:`UNLIMITED`): no rate limit and
        the safety limit ``v <= clearance / safety_horizon``.
    alpha_max : float
        Largest change of ``omega`` per second (rad/s^2; 6.0; 0: off) when the previous command
        is given.
    brake_share : float
        ``c`` in ``(0, 1]`` (0.5; :data:`UNLIMITED`: 1): the robot's stopping distance is at
        most this share of its clearance (:func:`safe_speed`); below 1 the clearance never
        reaches 0.
    relax : float
        ``r`` of the relaxed direction (see the module doc; 0, off; 1.0 is the measured setting):
        eq. 24 tracks the direction of a linearly implicit gradient step of ``r`` times the
        robot's next step instead of ``Upsilon``'s.
    waypoint_feedforward : float
        Share of eq. 24b's feed-forward while the tracked goal is an intermediate waypoint
        (``beyond > 0`` in :func:`track` / :func:`track_waypoints`; module doc); 1: the paper's.
    turn_share : float
        ``s`` of the turn limit (0, off; the tracker's wall-following mode after a loop uses
        0.5): with the stand-off, within its wall band (``standoff_reach D`` of a grown
        boundary), ``v |grad theta_gamma . Theta| <= s omega_max``, but ``v`` is not lowered
        below :data:`TURN_FLOOR` (0.1 m/s): the robot follows the wall flow round a convex
        corner instead of overshooting it (see the module doc).
    """

    k_v: float = 1.0
    k_omega: float = 0.8
    v_max: float = 0.5
    omega_max: float = 1.0
    k_switch: float = 2.0
    switch_margin: float = 0.1
    heading_gate: bool = True
    safety_horizon: float = SAFETY_HORIZON
    push_forward: bool = False
    boundary_blend: float = 0.005
    standoff: float = 0.0
    standoff_push: float = 0.5
    standoff_gate: float = 0.0
    standoff_pull: float = 0.0
    standoff_reach: float = 2.0
    accel_max: float = 1.0
    alpha_max: float = 6.0
    brake_share: float = 0.5
    relax: float = 0.0
    turn_share: float = 0.0
    waypoint_feedforward: float = 1.0

    def __post_init__(self):
        check_numbers(self, ("k_v", "k_omega", "v_max", "omega_max", "k_switch", "switch_margin"), positive=True)
        check_numbers(self, ("safety_horizon", "boundary_blend", "standoff", "standoff_push", "standoff_gate",
                             "standoff_pull", "accel_max", "alpha_max", "relax", "turn_share",
                             "waypoint_feedforward"), positive=False)
        if not self.standoff_reach > 1.0:
            raise NavigationError(f"ControllerConfig.standoff_reach must be > 1, got {self.standoff_reach!r}")
        if not self.brake_share <= 1.0 or not self.brake_share > 0.0:
            raise NavigationError(f"ControllerConfig.brake_share must be in (0, 1], got {self.brake_share!r}")

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
        Direction tracked at the pose (the blend of eq. 25 during a waypoint switch).
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


def _angle_of(u: np.ndarray, du: np.ndarray) -> tuple[float, np.ndarray] | None:
    """Direction ``atan2(u)`` of a vector ``u`` and its gradient from the Jacobian ``du``
    (``du[i]`` the gradient of ``u[i]``); ``None`` when ``u`` vanishes."""
    u2 = float(u @ u)
    if not u2 > 1e-12:
        return None
    return math.atan2(u[1], u[0]), (u[0] * du[1] - u[1] * du[0]) / u2


def _unit_blend(t0: float, g0: np.ndarray, t1: float, g1: np.ndarray, w: float, grad_w: np.ndarray):
    """Direction of ``b = (1 - w) u(t0) + w u(t1)`` and its gradient, given the gradients
    ``g0``, ``g1`` of ``t0``, ``t1`` and ``grad_w`` of ``w``; ``None`` when ``b`` vanishes."""
    u0 = np.array([math.cos(t0), math.sin(t0)])
    u1 = np.array([math.cos(t1), math.sin(t1)])
    b = (1.0 - w) * u0 + w * u1
    jb = ((1.0 - w) * np.outer((-u0[1], u0[0]), g0) + w * np.outer((-u1[1], u1[0]), g1)
          + np.outer(u1 - u0, grad_w))
    return _angle_of(b, jb)


def _direction(q: np.ndarray, field: OrientedField, cfg: ControllerConfig, band: "_Band | None",
               beyond: float = 0.0, room: float = math.inf):
    """``(theta_gamma, grad theta_gamma, tanh(|q - q_G| + beyond))`` of one field: the gradient
    direction, or with ``cfg.push_forward`` the push-forward direction blended into it next to
    boundaries; with the stand-off, changed within its band (``band = _band(q, field, cfg)``).
    ``beyond``: path length (m) still to go after the field's goal (see :func:`track`);
    ``room``: the clearance, which caps the relaxation step."""
    ev = field.evaluate(q)
    speed = math.tanh(float(np.linalg.norm(q - field.goal)) + beyond)
    tg, grad = float(ev.angle), np.asarray(ev.angle_gradient, dtype=float)
    if cfg.relax > 0 and bool(ev.free) and not bool(ev.degenerate):
        out = _relaxed(ev, min(cfg.relax * min(cfg.v_max, cfg.k_v * speed) * _horizon(cfg), RELAX_ROOM * room))
        if out is not None:
            tg, grad = out
    if cfg.push_forward:
        tf, gf = float(ev.flow_angle), np.asarray(ev.flow_gradient, dtype=float)
        delta = cfg.boundary_blend
        c = float(field.clearance(q, delta)) if delta > 0 else delta
        if c >= delta:
            tg, grad = tf, gf
        else:
            # smoothstep weight of the gradient direction; the clearance bound has no exact
            # gradient, so the weight is treated as locally constant in the feed-forward
            out = _unit_blend(tf, gf, tg, grad, _smoothstep(1.0 - c / delta)[0], np.zeros(2))
            if out is not None:
                tg, grad = out
    if band is not None and bool(ev.free) and not bool(ev.degenerate):
        tg, grad = _standoff(q, tg, grad, field, cfg, band)
    return tg, grad, speed, float(ev.angle)


def _relaxed(ev, step: float):
    """Direction of the linearly implicit step ``d = (I + (step / |g|) H_+)^(-1) (-g)`` (``g``,
    ``H``: gradient and Hessian of ``phi_O``; ``H_+`` its positive part) and its gradient with
    the relaxation matrix frozen; ``None`` where it is undefined."""
    g = np.asarray(ev.potential_gradient, dtype=float)
    H = np.asarray(ev.potential_hessian, dtype=float)
    ng = math.hypot(g[0], g[1])
    if not (ng > 0.0 and step > 0.0):
        return None
    lam, E = np.linalg.eigh(H)
    M = (E * (1.0 / (1.0 + (step / ng) * np.maximum(lam, 0.0)))) @ E.T
    d = -(M @ g)
    dd = -(M @ H)  # rows: gradients of d_x, d_y
    n2 = float(d @ d)
    if not n2 > 1e-300:
        return None
    return math.atan2(d[1], d[0]), (d[0] * dd[1] - d[1] * dd[0]) / n2


def _smoothstep(x: float) -> tuple[float, float]:
    """``S(x) = x^2 (3 - 2x)`` on ``[0, 1]`` (clamped) and ``S'(x)``."""
    x = min(max(x, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x)


WALL_OFFSET = 0.001  #: distance (m) from the grown boundary at which the wall flow is read


def _horizon(cfg: ControllerConfig) -> float:
    """Step duration the approach limit assumes: the safety horizon, or its default (the paper's
    control period) when the safety limit is off."""
    return cfg.safety_horizon if cfg.safety_horizon > 0 else SAFETY_HORIZON


class _Band(NamedTuple):
    """The stand-off's view of one field's grown boundaries at one pose (:func:`_band`)."""

    D: float  #: stand-off distance for this field, ``min(cfg.standoff, goal clearance / 4)``
    wall: BoundaryFrame | None  #: reach ``standoff_reach D``: wall flow (:func:`_standoff`)
    push: BoundaryFrame | None  #: reach ``D``: push out, and the approach limit's normal
    approach: BoundaryFrame | None  #: reach ``D / 3 + v_max h``: approach limit (:func:`_approach_limit`)


def _band(q: np.ndarray, field: OrientedField, cfg: ControllerConfig) -> "_Band | None":
    """The boundary frames one controller step needs from ``field`` at ``q``, all read from one
    boundary scan at the largest reach (:meth:`OrientedField.boundary_scan`: the grown boundaries
    are evaluated once per field and pose; each frame equals ``field.boundary_frame(q, reach)``
    bit for bit). ``None`` when the stand-off is off for this field (``D = 0``)."""
    if not cfg.standoff > 0:
        return None
    D = min(cfg.standoff, 0.25 * field.goal_clearance)
    if not D > 0:
        return None
    reaches = (cfg.standoff_reach * D, D, D / 3.0 + cfg.v_max * _horizon(cfg))
    scan = field.boundary_scan(q, max(reaches))
    if scan is None:  # no boundary within the largest reach, or q not in free space
        return _Band(D, None, None, None)
    frames = {r: scan.frame(r) for r in set(reaches)}
    return _Band(D, *(frames[r] for r in reaches))


def _standoff(q: np.ndarray, tg: float, grad: np.ndarray, field: OrientedField, cfg: ControllerConfig,
              band: _Band):
    """Stand-off from grown boundaries (see the module doc), with its exact gradient.

    Within ``R D`` (``R = cfg.standoff_reach``) of a grown boundary (``D = min(cfg.standoff,
    goal clearance / 4)``) the tracked direction ``f`` is blended (weight 1 within ``D``) into
    the *wall flow* ``f_w``, the push-forward direction at the point
    ``q_w = q - (delta - WALL_OFFSET) nu`` next to the nearest boundary (pulled in beyond ``D``
    with ``cfg.standoff_pull``, :func:`_pull`); within ``D`` the result ``b`` is pushed out,
    ``u = b + W max(0, s - b.n) n``
    (``n``, ``W``: weighted normal and band weight of the boundaries within ``D``,
    ``s = cfg.standoff_push``); the frames come from ``band`` (:func:`_band`)."""
    D, fr = band.D, band.wall
    if fr is None:
        return tg, grad
    width = (cfg.standoff_reach - 1.0) * D
    wp, dwp = _smoothstep((cfg.standoff_reach * D - fr.distance) / width)
    dwp = dwp * (-1.0 / width) * fr.distance_gradient
    if wp > 0.0 and cfg.standoff_gate:
        # only where the tracked direction does not already lead away from the nearest boundary
        nu = fr.normal
        f = np.array([math.cos(tg), math.sin(tg)])
        c = float(f @ nu)
        gc = float(np.array([-f[1], f[0]]) @ nu) * grad + fr.normal_jacobian.T @ f
        gate, dgate = _smoothstep(1.0 - c / cfg.standoff_gate)
        dwp = gate * dwp + wp * dgate * (-1.0 / cfg.standoff_gate) * gc
        wp = wp * gate
    if wp > 0.0:
        nu, off = fr.normal, fr.distance - WALL_OFFSET
        qw = q - off * nu
        ew = field.evaluate(qw)
        if bool(ew.free) and not bool(ew.degenerate):
            jw = np.eye(2) - np.outer(nu, fr.distance_gradient) - off * fr.normal_jacobian
            gw = jw.T @ np.asarray(ew.flow_gradient, dtype=float)
            out = _unit_blend(tg, grad, float(ew.flow_angle), gw, wp, dwp)
            if out is not None:
                tg, grad = out
                if cfg.standoff_pull > 0.0 and fr.distance > D:
                    tg, grad = _pull(tg, grad, fr, D, wp, dwp, cfg.standoff_pull)
    fo = band.push
    if fo is None:
        return tg, grad
    w, gw, tn, gn = fo.weight, fo.weight_gradient, fo.angle, fo.angle_gradient
    f = np.array([math.cos(tg), math.sin(tg)])
    n = np.array([math.cos(tn), math.sin(tn)])
    pf, pn = np.array([-f[1], f[0]]), np.array([-n[1], n[0]])
    a = cfg.standoff_push - float(f @ n)
    if a <= 0.0 or w <= 0.0:
        return tg, grad
    u = f + w * a * n
    grad_a = -(float(pf @ n) * grad + float(pn @ f) * gn)
    du = np.outer(pf, grad) + np.outer(a * n, gw) + w * np.outer(n, grad_a) + w * a * np.outer(pn, gn)
    return _angle_of(u, du) or (tg, grad)


def _pull(tg: float, grad: np.ndarray, fr: BoundaryFrame, D: float, wp: float, dwp: np.ndarray, k: float):
    """Pull towards the stand-off distance between ``D`` and ``R D`` (``ControllerConfig.standoff_pull
    = k``): ``u = f - k wp ((delta - D) / D) nu`` with ``f`` the unit vector of ``tg``, ``wp`` the
    wall-flow weight and ``nu``, ``delta`` the nearest boundary's normal and first-order distance;
    direction of ``u`` and its exact gradient. Without it a robot following a wall round a convex
    corner drives along the tangent out of the band, where the unmodified direction takes it back
    into the trench it was leaving (docs/control.md, "Pull-in")."""
    e = (fr.distance - D) / D
    c = k * wp * e
    if not c > 0.0:
        return tg, grad
    f = np.array([math.cos(tg), math.sin(tg)])
    pf = np.array([-f[1], f[0]])
    nu = fr.normal
    grad_c = k * (dwp * e + wp * fr.distance_gradient / D)
    u = f - c * nu
    du = np.outer(pf, grad) - np.outer(nu, grad_c) - c * fr.normal_jacobian
    return _angle_of(u, du) or (tg, grad)


def _blend(q: np.ndarray, current: OrientedField, following: OrientedField, cfg: ControllerConfig, bands,
           beyond: float = 0.0, room: float = math.inf):
    """Eq. 25 on directions (see the module doc): direction of ``(1 - eta) u_n + eta u_{n+1}``,
    its exact gradient (the switch's gradient included) and the blended speed factor
    (``bands``: the two fields' :func:`_band`; ``beyond``: path length after ``current``'s
    goal, so ``beyond - |q_{n+1} - q_n|`` after ``following``'s)."""
    t0, g0, s0, out0 = _direction(q, current, cfg, bands[0], beyond, room)
    diff = q - current.goal
    gamma = float(np.linalg.norm(diff))
    eta, deta = _switch(gamma, cfg)
    if eta <= 0.0:
        return t0, g0, s0, out0
    t1, g1, s1, _ = _direction(q, following, cfg, bands[1],
                            max(0.0, beyond - float(np.linalg.norm(following.goal - current.goal))) if beyond else 0.0,
                            room)
    grad_eta = deta * diff / gamma if gamma > 0 else np.zeros(2)
    speed = (1.0 - eta) * s0 + eta * s1
    out = _unit_blend(t0, g0, t1, g1, eta, grad_eta)
    if out is None:  # opposite directions at eta = 1/2 (measure zero): the dominant waypoint's
        return (t1, g1, speed, out0) if eta > 0.5 else (t0, g0, speed, out0)
    return (*out, speed, out0)


def _approach_limit(theta: float, bands, cfg: ControllerConfig) -> float:
    """Speed limit of the stand-off (see the module doc): ``v max(0, -Theta . n) h <=
    max(0, delta - D / 3)`` with ``delta`` the first-order distance to the nearest grown boundary
    (within ``D / 3 + v_max h``), ``n`` the weighted normal of :func:`_standoff` within ``D`` and
    the nearest boundary's normal farther out; ``h`` is :func:`_horizon`. ``bands``: each
    field's :func:`_band` at the pose."""
    if not cfg.standoff > 0:
        return math.inf
    h = _horizon(cfg)
    heading = np.array([math.cos(theta), math.sin(theta)])
    limit = math.inf
    for band in bands:
        fr = None if band is None else band.approach
        if fr is None:
            continue
        # within D: the weighted normal the tracked direction is pushed along (so a robot facing
        # the tracked direction is never held); farther out: the nearest boundary's normal
        near = band.push
        normal = fr.normal if near is None else np.array([math.cos(near.angle), math.sin(near.angle)])
        inward = -float(heading @ normal)
        if inward > 0.0:
            limit = min(limit, max(0.0, fr.distance - band.D / 3.0) / (h * inward))
    return limit


TURN_FLOOR = 0.1  #: speed (m/s) the turn limit never goes below (see ``ControllerConfig.turn_share``)


def _turn_share(bands, cfg: ControllerConfig) -> float:
    """The share ``s`` of ``omega_max`` the turn limit lets the feed-forward of (24b) use:
    ``cfg.turn_share`` within the stand-off's wall band of a field (``bands``: the fields'
    :func:`_band`), else 0 (no limit)."""
    if cfg.turn_share > 0.0 and any(b is not None and b.wall is not None for b in bands):
        return cfg.turn_share
    return 0.0


def stopping_distance(v: float, config: ControllerConfig = ControllerConfig()) -> float:
    """Distance (m) the robot covers from speed ``v`` until it stands, holding each command for
    one safety horizon ``h`` and lowering ``v`` by ``a h`` per command (``a = accel_max``):
    ``D(v) = h sum_{j >= 0} max(0, v - j a h)``; ``v h`` when ``accel_max`` is 0 (it stops at
    the next command). The inverse of :func:`safe_speed`."""
    h = _horizon(config)
    a = config.accel_max
    if not v > 0.0:
        return 0.0
    if not a > 0.0:
        return v * h
    d = a * h
    m = math.ceil(v / d - 1e-12)  # number of positive terms
    return h * (m * v - d * m * (m - 1) / 2.0)


def safe_speed(clearance: float, config: ControllerConfig = ControllerConfig()) -> float:
    """The safety limit: the largest ``v`` with ``stopping_distance(v) <= clearance``.

    With ``a = accel_max`` and ``h = safety_horizon`` the stopping distance is piecewise linear,
    ``h (m v - a h m (m - 1) / 2)`` for ``v`` in ``((m - 1) a h, m a h]``, so the limit is
    ``(clearance / h + a h m (m - 1) / 2) / m`` with ``m`` the smallest integer such that
    ``m (m + 1) >= 2 clearance / (a h^2)``. ``a = 0`` gives ``clearance / h``. Continuous and
    increasing in ``clearance``, at most ``clearance / h``.

    The controller's safety limit is ``safe_speed(c d)`` for the clearance ``d`` and
    ``c = ControllerConfig.brake_share``. Why it keeps the rate-limited controller safe without
    overriding the rate limit: since ``D(v) = v h + D(v - a h)``, a robot at ``v`` with
    ``D(v) <= c d`` that moves ``v h`` has clearance ``d' >= d - v h`` afterwards (the
    clearance is 1-Lipschitz along the motion), and ``D(v - a h) = D(v) - v h <= c d - v h
    <= c d'``: braking by the rate limit is always allowed. Each step uses at most the share
    ``c`` of the clearance (``v h <= D(v) <= c d``), so with ``c < 1`` the clearance never
    reaches 0 (it shrinks by the factor ``1 - c`` per step at worst) and a robot that stopped
    facing a boundary can always turn and leave.
    """
    if not clearance > 0.0:
        return 0.0
    h = _horizon(config)
    a = config.accel_max
    if not a > 0.0:
        return clearance / h
    d = a * h
    x = 2.0 * clearance / (d * h)
    m = max(1, math.ceil((math.sqrt(1.0 + 4.0 * x) - 1.0) / 2.0 - 1e-12))
    while m * (m + 1) < x:  # guard the rounding of the square root
        m += 1
    while m > 1 and (m - 1) * m >= x:
        m -= 1
    return (clearance / h + d * m * (m - 1) / 2.0) / m


def _previous(previous) -> tuple[float, float, float] | None:
    if previous is None:
        return None
    try:
        v, w, dt = (float(x) for x in previous)
    except (TypeError, ValueError):
        raise NavigationError(f"previous must be (v, omega, dt), got {previous!r}") from None
    if not (math.isfinite(v) and math.isfinite(w) and math.isfinite(dt) and dt >= 0.0):
        raise NavigationError(f"previous must be finite (v, omega, dt >= 0), got {previous!r}")
    return v, w, dt


ESCAPE_BELOW = 0.001  #: clearance (m) below which the robot may creep out along ``Upsilon``
ESCAPE_SPEED = 0.02  #: speed (m/s) of that creep


def _command(theta: float, tg: float, grad: np.ndarray, speed: float, clearance: float,
             cfg: ControllerConfig, approach: float = math.inf, previous=None, away: float | None = None,
             turn: float = 0.0, feedforward: float = 1.0, gate: float = math.pi / 2) -> Command:
    """Eq. 24 on the direction ``tg`` (gradient ``grad``): heading gate, saturation, safety
    limit and rate limit applied to ``v`` before it enters the feed-forward term (times
    ``feedforward``), then ``omega`` and its rate limit (``previous = (v, omega, dt)``, see
    :func:`track`)."""
    if away is not None and clearance < ESCAPE_BELOW and math.cos(wrap_angle(tg - away)) < math.sqrt(0.5):
        # within the escape band a direction changed by the stand-off (or the push-forward
        # blend) may run along the boundary, where the isotropic safety limit allows no speed:
        # track Upsilon, which points away from the boundary, and creep out (module doc)
        tg, grad = away, np.zeros(2)
    err = wrap_angle(theta - tg)
    v = cfg.k_v * speed
    if cfg.heading_gate:
        v *= _gate(err, gate)
    raw = v
    prev = _previous(previous)
    rate_v = prev is not None and cfg.accel_max > 0
    limit = _speed_limit(clearance, cfg) if v > 0.0 or rate_v else cfg.v_max
    v = min(v, limit, approach)
    ff = grad[0] * math.cos(theta) + grad[1] * math.sin(theta)
    if turn > 0.0 and abs(ff) * v > turn * cfg.omega_max:
        # turn limit: no faster than the robot can turn with the tracked direction (share
        # ``turn`` of omega_max for the feed-forward), but not below TURN_FLOOR
        v = max(min(v, TURN_FLOOR), turn * cfg.omega_max / abs(ff))
    escape = 0.0
    if away is not None and clearance < ESCAPE_BELOW and v < ESCAPE_SPEED and raw > 0.0:
        # the safety limit holds a robot on (or inside) a grown boundary still for good; creep
        # out while it faces within 45 degrees of Upsilon, which points away from the boundary
        c = math.cos(wrap_angle(theta - away))
        if c > math.sqrt(0.5):
            escape = min(ESCAPE_SPEED * c, raw, approach)
            v = max(v, escape)
    if rate_v:
        pv, _, dt = prev
        dv = cfg.accel_max * dt
        # the rate limit, within [0, v_max] and the safety limit (which it never has to
        # override while the clearance shrinks no faster than the robot moves, see safe_speed)
        # or the escape creep
        v = max(0.0, min(max(v, pv - dv), pv + dv, max(limit, escape)))
    omega = -cfg.k_omega * err + feedforward * v * ff
    ws = min(max(omega, -cfg.omega_max), cfg.omega_max)
    if prev is not None and cfg.alpha_max > 0:
        _, pw, dt = prev
        dw = cfg.alpha_max * dt
        ws = min(max(ws, pw - dw), pw + dw, cfg.omega_max)
        ws = max(ws, -cfg.omega_max)
    return Command(v, ws, tg, ws != omega or v != raw)


def _gate(err: float, gate: float) -> float:
    """The heading gate's factor on ``v`` for the heading error ``err``: ``max(0, cos err)``
    (``gate = pi / 2``), or ``max(0, (cos err - cos gate) / (1 - cos gate))`` for a smaller
    ``gate``: 1 on the tracked direction, 0 (turn on the spot) beyond ``gate``, continuous."""
    c = math.cos(err)
    if gate >= math.pi / 2:
        return max(0.0, c)
    g = math.cos(gate)
    return max(0.0, (c - g) / (1.0 - g))


EXACT_BELOW = 0.005  #: clearance bound (m) below which the safety limit uses the exact clearance
#: clearance (m) the safety limit keeps in reserve: ten times the simulator's contact tolerance
#: (1e-6 m, ``service.sim``), so a step that uses the whole allowance ends short of contact
CONTACT_MARGIN = 1e-5


def _speed_limit(clearance: float, cfg: ControllerConfig) -> float:
    """The safety limit on ``v`` for the clearance ``clearance`` of :func:`_clearance`:
    ``safe_speed(brake_share (clearance - CONTACT_MARGIN))``, at most ``v_max`` (``v_max`` with
    the limit off)."""
    if cfg.safety_horizon > 0:
        return min(cfg.v_max, safe_speed(cfg.brake_share * (clearance - CONTACT_MARGIN), cfg))
    return cfg.v_max


def safety_limit(q, fields, config: ControllerConfig = ControllerConfig()) -> float:
    """The speed (m/s) the controller's safety limit allows at the position ``q (2,)`` for the
    oriented ``fields`` it tracks (their grown obstacles and workspace): what a supervisor
    that replaces a command (the executive's slide around a lidar return) must keep to."""
    return _speed_limit(_clearance(np.asarray(q, dtype=float).reshape(2), tuple(fields), config), config)


def _clearance(q: np.ndarray, fields, cfg: ControllerConfig) -> float:
    """The clearance the safety limit uses: the certified bound of each field (up to 2.5 mm
    low); where it is below :data:`EXACT_BELOW`, the exact clearance (1e-9 m accurate, less
    that), so that a robot next to a boundary is not held by the bound's slack: with a bound of
    0 and an exact clearance of 2 mm the robot would stand still for good, whichever way the
    field points (measured: executive runs stalled so). With ``brake_share < 1`` the clearance
    then provably stays positive (:func:`safe_speed`); with ``brake_share = 1`` a step still
    moves the robot by at most its clearance."""
    if cfg.safety_horizon <= 0:
        return math.inf
    cap = stopping_distance(cfg.v_max, cfg) / cfg.brake_share  # the safety limit is v_max beyond it
    out = math.inf
    for bound in {id(f.clearance): f.clearance for f in fields}.values():  # fields of one forest share it
        b = float(bound(q, cap))
        if b < EXACT_BELOW:
            b = max(b, bound.exact(q) - 1e-9)
        out = min(out, b)
    return out


def track(pose, field: OrientedField, config: ControllerConfig = ControllerConfig(),
          previous=None, beyond: float = 0.0, v_cap: float = math.inf) -> Command:
    """Eq. 24: command that tracks ``field`` from ``pose = (x, y, theta)``.

    ``previous = (v, omega, dt)``: the command sent ``dt`` seconds ago; the new one then
    differs from it by at most ``accel_max dt`` in ``v`` and ``alpha_max dt`` in ``omega``
    (the rate limit; ``None``: no limit, a pure function of the pose). The safety limit and
    the saturation hold either way.

    ``beyond``: path length (m) the robot still has to go after ``field``'s goal, when that goal
    is an intermediate waypoint of a longer path (0: it is the end). Eq. 24a's speed factor is
    then ``tanh(|q - q_G| + beyond)`` instead of ``tanh |q - q_G|``, so the robot slows down
    for the end of its path, not for every waypoint on the way (see the module doc).

    ``v_cap``: a speed (m/s) the caller wants ``v`` at most, applied with the safety and
    approach limits, before the rate limit (which then brakes towards it at ``accel_max``) and
    before ``v`` enters the feed-forward of eq. 24b (``inf``: none).

    Raises
    ------
    NavigationError
        Non-finite or malformed pose, previous command or ``beyond``; ``v_cap`` NaN or negative.
    """
    q, theta = _pose(pose)
    beyond = _beyond(beyond)
    v_cap = _v_cap(v_cap)
    band = _band(q, field, config)
    room = _clearance(q, (field,), config)
    tg, grad, speed, away = _direction(q, field, config, band, beyond, room)
    return _command(theta, tg, grad, speed, room, config,
                    min(_approach_limit(theta, (band,), config), v_cap), previous, away, _turn_share((band,), config),
                    _feedforward(beyond, config))


def track_point(pose, point, field: OrientedField, config: ControllerConfig = ControllerConfig(),
                previous=None, beyond: float = 0.0, v_cap: float = math.inf, gate: float = math.pi / 2) -> Command:
    """Eq. 24 on the bearing of a visible ``point (2,)`` instead of a field's direction.

    ``theta_gamma = atan2(p - q)``, its gradient exact (``(d_y, -d_x) / |d|^2`` for
    ``d = p - q``), the speed factor ``tanh(|p - q| + beyond)``; the heading gate, saturation,
    safety limit (on ``field``'s grown obstacles and workspace), escape band (``field``'s
    ``Upsilon``), ``v_cap`` and rate limit exactly as :func:`track`. Not in the paper: the route rescue of
    :class:`~navigation.tracker.Tracker` uses it for the straight segments of a route whose
    fields run the long way round (module doc there). The safety limit alone keeps the robot
    off the boundaries: a point that is not visible is approached until the robot stops.
    ``gate`` (radians, in ``(0, pi / 2]``) narrows the heading gate: ``v`` times
    ``max(0, (cos e - cos gate) / (1 - cos gate))`` for the heading error ``e``, 0 beyond
    ``gate`` (turn on the spot); ``pi / 2`` is eq. 24a's ``max(0, cos e)``. The executive's
    pursuit of the leg uses 60 degrees (``tamp.executive``, module doc "Pursuit").

    Raises
    ------
    NavigationError
        Non-finite or malformed pose, point, previous command or ``beyond``; ``v_cap`` NaN or
        negative; ``gate`` outside ``(0, pi / 2]``.
    """
    q, theta = _pose(pose)
    beyond = _beyond(beyond)
    v_cap = _v_cap(v_cap)
    gate = _gate_angle(gate)
    p, single = as_points(point, "point")
    if not single:
        raise PointsError(f"Expected `point` to have shape (2,), got {np.shape(point)}.")
    room = _clearance(q, (field,), config)
    # Upsilon's direction is read only where the escape band needs it (one field evaluation)
    away = float(field.evaluate(q).angle) if room < ESCAPE_BELOW else None
    tg, grad, dist = _bearing(q, p[0])
    if tg is None:  # on the point: hold the heading
        tg = theta
    return _command(theta, tg, grad, math.tanh(dist + beyond), room, config, v_cap, previous, away, gate=gate)


def _bearing(q: np.ndarray, p: np.ndarray) -> tuple[float | None, np.ndarray, float]:
    """``(atan2(p - q), its exact gradient in q, |p - q|)``; the angle ``None`` (gradient 0)
    within 1e-12 m of ``p``. With ``d = p - q``: ``grad = (d_y, -d_x) / |d|^2``."""
    d = p - q
    r2 = float(d @ d)
    if not r2 > 1e-24:
        return None, np.zeros(2), math.sqrt(r2)
    return math.atan2(d[1], d[0]), np.array([d[1], -d[0]]) / r2, math.sqrt(r2)


def _non_negative(value, what: str, finite: bool) -> float:
    """``value`` as a float ``>= 0`` (and finite with ``finite``), else a NavigationError
    saying ``what`` it must be."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if not (x >= 0.0 and (math.isfinite(x) or not finite)):
        raise NavigationError(f"{what}, got {value!r}")
    return x


def _v_cap(v_cap) -> float:
    return _non_negative(v_cap, "v_cap must be a speed >= 0 (m/s) or inf", finite=False)


def _gate_angle(gate) -> float:
    """``gate`` as a float in ``(0, pi / 2]`` (radians), else a NavigationError."""
    x = _non_negative(gate, "gate must be an angle in (0, pi / 2] radians", finite=True)
    if not 0.0 < x <= math.pi / 2:
        raise NavigationError(f"gate must be an angle in (0, pi / 2] radians, got {gate!r}")
    return x


def _beyond(beyond) -> float:
    return _non_negative(beyond, "beyond must be a finite path length >= 0 (m)", finite=True)


def _feedforward(beyond: float, cfg: ControllerConfig) -> float:
    """Share of eq. 24b's feed-forward: ``waypoint_feedforward`` towards an intermediate
    waypoint (``beyond > 0``), else 1."""
    return cfg.waypoint_feedforward if beyond > 0.0 else 1.0


def switch_weight(distance: float, config: ControllerConfig = ControllerConfig()) -> float:
    """``eta(gamma_n)`` of eq. 25 (normalised form, see the module doc)."""
    return _switch(float(distance), config)[0]


def _switch(gamma: float, cfg: ControllerConfig) -> tuple[float, float]:
    """``eta(gamma)`` of eq. 25 and its derivative ``d eta / d gamma`` (one tanh)."""
    eps = cfg.switch_margin
    th = math.tanh(cfg.k_switch * (eps - gamma) / eps)
    return 0.5 * (1.0 + th), -0.5 * cfg.k_switch / eps * (1.0 - th * th)


def track_waypoints(pose, current: OrientedField, following: OrientedField | None = None,
                    config: ControllerConfig = ControllerConfig(), previous=None, beyond: float = 0.0,
                    v_cap: float = math.inf) -> Command:
    """Eq. 25: track the blend of the current and following waypoints' fields.

    With ``following=None`` this is :func:`track` towards ``current``; ``previous`` and
    ``v_cap`` as there. ``beyond``: path length after ``current``'s goal (through
    ``following``'s and on), as in :func:`track`; ``following``'s speed factor uses
    ``beyond - |q_{n+1} - q_n|``.
    """
    q, theta = _pose(pose)
    if following is None:
        return track(pose, current, config, previous, beyond, v_cap)
    beyond = _beyond(beyond)
    v_cap = _v_cap(v_cap)
    bands = (_band(q, current, config), _band(q, following, config))
    room = _clearance(q, (current, following), config)
    tg, grad, speed, away = _blend(q, current, following, config, bands, beyond, room)
    return _command(theta, tg, grad, speed, room, config,
                    min(_approach_limit(theta, bands, config), v_cap), previous, away, _turn_share(bands, config),
                    _feedforward(beyond, config))
