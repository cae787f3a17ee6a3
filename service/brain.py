"""The service's view of the task executive: a small protocol and its adapter.

:class:`~service.node.ServiceNode` drives any object that satisfies :class:`Brain`; it never
imports the executive itself. :class:`ExecutiveBrain` adapts :class:`tamp.executive.Executive`
(paper 001 sections 4.1.4 and 4.2) to the protocol.

Calls happen on the node's control thread only (callbacks merely enqueue), so a brain needs no
locking.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from navigation.errors import HarmonicTampError, TampError

from .errors import TaskErrorCode, TaskRejected
from .messages import PointsMsg, PoseMsg, ScanMsg, TaskRequest

__all__ = ["Brain", "BrainTick", "ExecutiveBrain", "task_error_code"]


@dataclass(frozen=True, slots=True)
class BrainTick:
    """One control period's output.

    Attributes
    ----------
    v, omega : float
        The unicycle command.
    status : dict
        The FORMATS.md ``status`` fields (``state``, ``task``, ``plan``, ``target``,
        ``waypoint``, ``obstacles``, ``message``); the node sets ``stamp``.
    compute : float
        Wall seconds the brain spent.
    map_changed : bool
        The obstacle estimate changed (the node then publishes ``obstacles``).
    replanned : bool
    """

    v: float
    omega: float
    status: dict
    compute: float = 0.0
    map_changed: bool = False
    replanned: bool = False


@runtime_checkable
class Brain(Protocol):
    """What the node needs from a task executive."""

    def tick(self, pose: PoseMsg, *, scan: ScanMsg | None = None, scan_pose: PoseMsg | None = None,
             points: PointsMsg | None = None, now: float) -> BrainTick:
        """One control period. ``pose`` is the latest pose; ``scan`` (new since the last tick,
        or ``None``) was taken at ``scan_pose`` (the received pose nearest its stamp, may be
        ``pose``); ``points`` likewise; ``now`` is the robot clock (latest pose stamp).

        A brain may also have ``observe(pose, *, scan=None, points=None, now) -> bool``: the
        node then integrates the further sensor messages of a period with it (the map changed:
        True) before the tick; without it, it ticks once per message and sends the last
        tick's command."""

    def request_task(self, request: TaskRequest) -> dict:
        """Apply a mission change; return the plan summary (``status.plan`` shape).

        Raises :class:`~service.errors.TaskRejected` (the running mission then continues)."""

    def status(self) -> dict:
        """The current ``status`` fields without ticking."""

    def obstacles(self) -> list:
        """The current obstacle estimate (``Squircle`` objects or squircle dicts)."""

    def summary(self) -> dict:
        """JSON-safe progress: at least ``completed`` (bool) and ``visited`` (region list)."""


def task_error_code(err: BaseException) -> TaskErrorCode:
    """The contract code for a mission-layer error (``tamp.errors`` types)."""
    from tamp.errors import InvalidRequestError, LtlSyntaxError, NoPlanError, UnknownRegionError, UnsatisfiableError

    if isinstance(err, LtlSyntaxError):
        return TaskErrorCode.PARSE_ERROR
    if isinstance(err, UnknownRegionError):
        return TaskErrorCode.UNKNOWN_REGION
    if isinstance(err, (UnsatisfiableError, NoPlanError)):
        return TaskErrorCode.UNSATISFIABLE
    if isinstance(err, InvalidRequestError):
        return TaskErrorCode.INVALID_REQUEST
    return TaskErrorCode.INVALID_REQUEST


def _pose_dict(p: PoseMsg) -> dict:
    return {"stamp": p.stamp, "x": p.x, "y": p.y, "theta": p.theta}


def _points_message(points: PointsMsg | None) -> dict | None:
    """The ``points`` message the executive's perception reads (``ObstacleMap.update_points``).
    Until the forty-eighth session the bare array went through, which perception refuses
    ("points message must be a JSON object"): every ``points`` message on the bus was dropped."""
    if points is None:
        return None
    return {"stamp": points.stamp, "points": points.points}


@dataclass
class ExecutiveBrain:
    """:class:`Brain` over :class:`tamp.executive.Executive`.

    Parameters
    ----------
    world : navigation.World
    task : str, optional
        Initial mission (default: the world's ``task``).
    known : bool
        All obstacles of ``world`` known at start (no perception).
    config : tamp.executive.ExecutiveConfig, optional

    Notes
    -----
    * A scan or points message is integrated at the pose of its stamp (``scan_pose``) and the
      command is computed for the latest pose (``Executive.tick``'s ``sensor_pose``);
      :meth:`observe` integrates a further message without a command.
    * ``regions`` in a task request are added or moved with the mission change
      (:meth:`tamp.executive.Executive.request`, rules of ``Executive.set_regions``): a region
      that breaks a rule is refused with ``invalid_request`` whose message starts with
      ``regions.<name>:`` and ends with ``[rule: workspace|free_space|disjoint|alphabet|format]``;
      nothing changes then. Regions given with their current centre and radius are no change.
    * A mission counts as completed when the executive reports ``done`` (co-safe missions) or,
      for a recurrent mission, after two arrivals at the accepting state of its lasso (the rule
      of :func:`tamp.run.run_mission`).
    """

    world: object
    task: str | None = None
    known: bool = False
    config: object = None
    _ex: object = field(init=False, repr=False)
    _ids: int = field(init=False, default=0)

    def __post_init__(self):
        from tamp.executive import Executive

        self._ex = Executive(self.world, self.task, known=self.known, config=self.config)

    @property
    def executive(self):
        return self._ex

    def tick(self, pose, *, scan=None, scan_pose=None, points=None, now):
        sensor = None if scan_pose is None or (scan is None and points is None) else _pose_dict(scan_pose)
        r = self._ex.tick(_pose_dict(pose), scan=scan.message if scan is not None else None,
                          points=_points_message(points), now=now, sensor_pose=sensor)
        return BrainTick(r.v, r.omega, dict(r.status), r.compute, r.map_changed, r.replanned)

    def observe(self, pose, *, scan=None, points=None, now) -> bool:
        """Integrate one more sensor message taken at ``pose`` (``Executive.observe``)."""
        return self._ex.observe(_pose_dict(pose), scan=scan.message if scan is not None else None,
                                points=_points_message(points), now=now)

    def request_task(self, request: TaskRequest) -> dict:
        try:
            plan = self._ex.request(request.formula, request.mode, regions=request.regions or None)
        except TampError as err:
            raise TaskRejected(task_error_code(err), str(err)) from None
        except HarmonicTampError as err:  # any other refusal of the product
            raise TaskRejected(TaskErrorCode.INVALID_REQUEST, str(err)) from None
        return plan.to_dict()

    def status(self) -> dict:
        return self._ex.status()

    def obstacles(self) -> list:
        return self._ex.obstacles

    def summary(self) -> dict:
        ex = self._ex
        return {"completed": ex.completed, "state": ex.state.value, "task": ex.task,
                "cosafe": not ex.recurrent, "accepting_visits": ex.accepting_visits,
                "visited": list(ex.visited), "replans": ex.replans, "planning_time": ex.planning_time,
                "max_replan_time": max(ex.replan_times, default=0.0), "obstacles": len(ex.obstacles),
                "map_changes": ex.map_changes}

    def leg(self):
        """Waypoints of the current leg ``(K, 3)`` and the index of the current one (for Rerun)."""
        return list(self._ex.leg), self._ex.wp

    def regions(self) -> dict:
        """The executive's current regions, name -> ``navigation.world.Region`` (for Rerun)."""
        return self._ex.regions

    def field(self):
        """The oriented field tracked now (``navigation.OrientedField``, its ``.nf`` the
        navigation function), or ``None``; never builds one (for Rerun)."""
        return self._ex.current_field
