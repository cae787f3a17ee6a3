"""Bus message schemas: validation of every input key and builders for every output key.

The bus contract is ``shared/FORMATS.md`` ("Bus contract (Zenoh)"). Inputs (``scan``,
``points``, ``pose``, ``task`` requests) arrive as raw Zenoh payloads; each ``parse_*`` here
turns one into a small frozen record or raises :class:`~service.errors.MessageError` (a task
request: :class:`~service.errors.TaskRejected` with code ``invalid_request``) with a reason
that names the key and the field. They never raise anything else, whatever the bytes.

Field-level parsing is not duplicated: scans, points and poses go through
:mod:`perception.ingest` (the parser the obstacle map uses), mission modes through
:meth:`tamp.MissionMode.parse`, regions through :class:`navigation.world.Region`.

Outputs (``cmd_vel``, ``status``, ``obstacles``, ``task`` replies) are built as plain dicts by
the ``*_message`` builders and serialised with :func:`encode` (strict JSON: no NaN).

Contract choices made here (the contract leaves them open):

* a ``scan`` range that is not finite is a no-return beam (the contract says so), but a
  non-finite *header* number (``stamp``, ``angle_min``...) drops the message;
* a ``points`` message with any non-finite coordinate is dropped as a whole (the contract's
  "non-finite numbers" rule), rather than silently losing rows;
* payloads over :data:`MAX_PAYLOAD` bytes are dropped before decoding.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from navigation.errors import WorldError
from navigation.world import Region
from perception import ingest
from perception.errors import ScanError
from tamp.executive import ExecutiveState

from .errors import MessageError, TaskErrorCode, TaskRejected

__all__ = [
    "MAX_PAYLOAD",
    "ServiceState",
    "PoseMsg",
    "ScanMsg",
    "PointsMsg",
    "TaskRequest",
    "decode",
    "encode",
    "parse_pose",
    "parse_scan",
    "parse_points",
    "parse_task_request",
    "cmd_vel_message",
    "status_message",
    "obstacles_message",
    "task_ok_reply",
]

MAX_PAYLOAD = 4 * 1024 * 1024
"""Largest accepted input payload (bytes); a 1080-beam scan is about 9 KB."""


#: ``status.state`` values of the bus contract: the executive's states.
ServiceState = ExecutiveState


@dataclass(frozen=True, slots=True)
class PoseMsg:
    """A validated ``pose`` message."""

    stamp: float
    x: float
    y: float
    theta: float

    @property
    def pose(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.theta)


@dataclass(frozen=True, slots=True, eq=False)
class ScanMsg:
    """A validated ``scan`` message (robot frame); ``message`` is the decoded mapping, ready
    for :func:`perception.ingest.parse_scan` with the pose of ``stamp``."""

    stamp: float
    message: Mapping
    beams: int


@dataclass(frozen=True, slots=True, eq=False)
class PointsMsg:
    """A validated ``points`` message: world-frame points ``(N, 2)``, all finite."""

    stamp: float
    points: np.ndarray


@dataclass(frozen=True, slots=True)
class TaskRequest:
    """A validated ``task`` request. ``mode`` is a :class:`tamp.MissionMode`; ``regions`` maps
    new or redefined region names to :class:`navigation.world.Region` (empty when absent)."""

    formula: str
    mode: object
    regions: Mapping[str, Region] = field(default_factory=dict)


# ------------------------------------------------------------------ encoding
def _default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Enum):
        return o.value
    if isinstance(o, (tuple, set, frozenset)):
        return list(o)
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def encode(message: Mapping) -> bytes:
    """Strict UTF-8 JSON of an output message (``ValueError`` on NaN/inf: outputs are finite)."""
    return json.dumps(message, allow_nan=False, separators=(",", ":"), default=_default).encode("utf-8")


def decode(payload, key: str) -> Mapping:
    """The JSON object of a raw payload (``bytes``/``str``/mapping/``ZBytes``).

    Raises
    ------
    MessageError
        Too large, not UTF-8, not JSON, or not an object.
    """
    if hasattr(payload, "to_bytes"):  # zenoh.ZBytes
        payload = payload.to_bytes()
    if isinstance(payload, (bytes, bytearray, str)) and len(payload) > MAX_PAYLOAD:
        raise MessageError(key, f"payload of {len(payload)} bytes exceeds the {MAX_PAYLOAD} byte limit")
    return ingest.decode_object(payload, lambda reason: MessageError(key, f"payload {reason}"))


def _from_scan_error(key: str, err: ScanError) -> MessageError:
    reason = str(err)
    if reason.startswith(f"{key}."):  # perception names "scan.field: ..."; keep the field part only
        reason = reason[len(key) + 1:]
    elif reason.startswith(f"{key}:"):
        reason = reason[len(key) + 1:].lstrip()
    return MessageError(key, reason, getattr(err, "field", None))


# ------------------------------------------------------------------ inputs
def parse_pose(payload) -> PoseMsg:
    """A ``pose`` message ``{"stamp", "x", "y", "theta"}``, all finite numbers.

    Raises
    ------
    MessageError
    """
    m = decode(payload, "pose")
    try:
        stamp, (x, y, theta) = ingest.parse_pose(m)
    except ScanError as err:
        raise _from_scan_error("pose", err) from None
    return PoseMsg(stamp, x, y, theta)


def parse_scan(payload, *, beams: int | None = None) -> ScanMsg:
    """A ``scan`` message, validated by :func:`perception.ingest.parse_scan` (finite header,
    ``0 <= range_min < range_max``, a non-empty list of numbers; ``beams`` if given).

    Raises
    ------
    MessageError
    """
    m = decode(payload, "scan")
    raw = m.get("ranges")
    if isinstance(raw, list):  # ingest flattens nested lists; a range is one number (or null)
        bad = next((v for v in raw if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)))), None)
        if bad is not None:
            raise MessageError("scan", f"ranges: expected numbers (or null), got {bad!r}", "ranges")
    try:
        scan = ingest.parse_scan(m, (0.0, 0.0, 0.0), beams=beams)
    except ScanError as err:
        raise _from_scan_error("scan", err) from None
    except (TypeError, ValueError) as err:  # defensive: a shape numpy refuses
        raise MessageError("scan", f"ranges: {err}", "ranges") from None
    return ScanMsg(scan.stamp, m, len(scan.ranges))


def parse_points(payload) -> PointsMsg:
    """A ``points`` message ``{"stamp", "points": [[x, y], ...]}`` with finite coordinates.

    Raises
    ------
    MessageError
    """
    m = decode(payload, "points")
    try:
        stamp, pts, dropped = ingest.parse_points(m)
    except ScanError as err:
        raise _from_scan_error("points", err) from None
    if dropped:
        raise MessageError("points", f"points: {dropped} point(s) with non-finite coordinates", "points")
    return PointsMsg(stamp, pts)


def parse_task_request(payload) -> TaskRequest:
    """A ``task`` request ``{"formula": str, "mode": "replace"|"add"|"urgent", "regions"?}``.

    ``mode`` defaults to ``"replace"``. ``regions`` (optional) maps names to
    ``{"center": [x, y], "radius": r}``. The formula is only checked to be a non-empty string
    here; parsing it is the brain's job (``parse_error``).

    Raises
    ------
    TaskRejected
        Code ``invalid_request``, naming the field.
    """
    from tamp.errors import InvalidRequestError
    from tamp.planner import MissionMode

    try:
        m = decode(payload, "task")
    except MessageError as err:
        raise TaskRejected(TaskErrorCode.INVALID_REQUEST, str(err)) from None
    extra = sorted(set(m) - {"formula", "mode", "regions"})
    if extra:
        raise TaskRejected(TaskErrorCode.INVALID_REQUEST, f"task: unknown field(s) {', '.join(map(repr, extra))}; "
                                                          "expected 'formula', 'mode', 'regions'")
    formula = m.get("formula")
    if not isinstance(formula, str) or not formula.strip():
        raise TaskRejected(TaskErrorCode.INVALID_REQUEST, f"task.formula: expected a non-empty string, got {formula!r}")
    try:
        mode = MissionMode.parse(m.get("mode", "replace"))
    except InvalidRequestError as err:
        raise TaskRejected(TaskErrorCode.INVALID_REQUEST, f"task.mode: {err}") from None
    raw = m.get("regions")
    regions: dict[str, Region] = {}
    if raw is not None:
        if not isinstance(raw, Mapping):
            raise TaskRejected(TaskErrorCode.INVALID_REQUEST,
                               f"task.regions: expected an object name -> {{center, radius}}, got {type(raw).__name__}")
        for name, spec in raw.items():
            if not isinstance(spec, Mapping) or set(spec) - {"center", "radius"} or not {"center", "radius"} <= set(spec):
                raise TaskRejected(TaskErrorCode.INVALID_REQUEST,
                                   f"task.regions.{name}: expected {{\"center\": [x, y], \"radius\": r}}")
            try:
                regions[name] = Region(name, spec["center"], spec["radius"])
            except WorldError as err:
                raise TaskRejected(TaskErrorCode.INVALID_REQUEST, f"task.regions.{name}.{err}") from None
    return TaskRequest(formula, mode, regions)


# ------------------------------------------------------------------ outputs
def _finite(x, what: str) -> float:
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"{what} must be finite, got {x!r}")
    return v


def cmd_vel_message(stamp: float, v: float, omega: float) -> dict:
    """``{"stamp", "v", "omega"}``; ``ValueError`` when a value is not finite."""
    return {"stamp": _finite(stamp, "stamp"), "v": _finite(v, "v"), "omega": _finite(omega, "omega")}


STATUS_FIELDS = ("stamp", "state", "task", "plan", "target", "waypoint", "obstacles", "message")


def status_message(stamp: float, state, *, task=None, plan=None, target=None, waypoint=None,
                   obstacles: int = 0, message: str = "", **extra) -> dict:
    """A ``status`` message with every contract field (extra optional fields appended).

    ``state`` is a :class:`ServiceState` or its value; ``plan`` a mapping with ``prefix`` and
    ``suffix`` region lists, or ``None``; ``target`` a region name; ``waypoint`` ``[x, y]`` or
    ``[x, y, theta]``.
    """
    out = {"stamp": _finite(stamp, "stamp"), "state": ServiceState.parse(state).value, "task": task,
           "plan": plan, "target": target, "waypoint": None if waypoint is None else [float(w) for w in waypoint],
           "obstacles": int(obstacles), "message": str(message)}
    out.update(extra)
    return out


def obstacles_message(stamp: float, squircles) -> dict:
    """``{"stamp", "obstacles": [squircle, ...]}`` from ``Squircle`` objects or squircle dicts."""
    return {"stamp": _finite(stamp, "stamp"),
            "obstacles": [sq.to_dict() if hasattr(sq, "to_dict") else dict(sq) for sq in squircles]}


def task_ok_reply(task_id: str, plan) -> dict:
    """The accepted reply ``{"ok": true, "task_id", "plan"}``."""
    return {"ok": True, "task_id": str(task_id), "plan": plan}
