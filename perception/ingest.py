"""Scan ingestion: bus ``scan``/``points``/``pose`` messages to world-frame points.

The bus contract (``shared/FORMATS.md``): a ``scan`` holds ``stamp``, ``angle_min``,
``angle_increment``, ``range_min``, ``range_max`` and ``ranges`` in the robot frame (angle 0 =
heading) at the pose of ``stamp``; a range that is not finite or is ``>= range_max`` is no
return. A ``points`` message holds world-frame surface points. A ``pose`` holds ``stamp``,
``x``, ``y``, ``theta``.

Beam ``k`` at robot pose ``(x, y, theta)`` with range ``r_k`` gives the world point

.. math::  q_k = (x, y) + r_k (\\cos a_k, \\sin a_k), \\qquad a_k = \\theta + \\text{angle\\_min} + k\\,\\text{angle\\_increment}.

NaN ranges and ranges below ``range_min`` are dropped (counted in :attr:`Scan.dropped`);
infinite ones and ones ``>= range_max`` are no returns (they still prove the beam's path free
up to ``range_max``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from navigation._arrays import to_float, to_floats

from .errors import ScanError

__all__ = ["Scan", "Pose", "parse_pose", "parse_scan", "parse_points", "as_message", "decode_object"]

Pose = tuple[float, float, float]


@dataclass(frozen=True, slots=True, eq=False)
class Scan:
    """One scan in the world frame.

    Attributes
    ----------
    stamp : float
    pose : (x, y, theta)
        Pose of the sensor at ``stamp``.
    angles : ndarray, shape (B,)
        World-frame beam angles.
    ranges : ndarray, shape (B,)
        Ranges; ``inf`` for no return, ``nan`` for dropped beams.
    hit : ndarray of bool, shape (B,)
        Beams with a return.
    points : ndarray, shape (N, 2)
        World-frame return points (``N = hit.sum()``).
    range_max : float
    dropped : int
        Beams dropped as invalid (NaN, or below ``range_min``).
    """

    stamp: float
    pose: Pose
    angles: np.ndarray
    ranges: np.ndarray
    hit: np.ndarray
    points: np.ndarray
    range_max: float
    dropped: int

    @property
    def origin(self) -> np.ndarray:
        return np.array(self.pose[:2])


def decode_object(payload, fail) -> Mapping:
    """A bus payload as a mapping: a mapping as is, or its UTF-8 JSON text (``str``/``bytes``).

    The one decoder of the project's JSON messages (perception, the simulator's ``cmd_vel``, the
    service's bus adapter). ``fail(reason)`` builds the exception to raise; ``reason`` reads
    ``"is not UTF-8 (...)"``, ``"is not JSON: ..."`` (nesting too deep included) or ``"must be a
    JSON object, got <type>"``.
    """
    if isinstance(payload, (bytes, bytearray)):
        try:
            payload = bytes(payload).decode("utf-8")
        except UnicodeDecodeError as err:
            raise fail(f"is not UTF-8 ({err.reason} at byte {err.start})") from None
    if isinstance(payload, str):
        try:
            payload = json.loads(payload)
        except json.JSONDecodeError as err:
            raise fail(f"is not JSON: {err.msg} at char {err.pos}") from None
        except RecursionError:
            raise fail("is not JSON: nested too deeply") from None
    if not isinstance(payload, Mapping):
        raise fail(f"must be a JSON object, got {type(payload).__name__}")
    return payload


def as_message(msg, kind: str) -> Mapping:
    """A ``kind`` message as a mapping (:func:`decode_object`); :class:`ScanError` otherwise."""
    return decode_object(msg, lambda reason: ScanError(f"{kind} message {reason}"))


def _number(msg: Mapping, key: str, kind: str) -> float:
    if key not in msg:
        raise ScanError(f"{kind}.{key}: missing field", key)
    v = msg[key]
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
        raise ScanError(f"{kind}.{key}: expected a number, got {v!r}", key)
    x = to_float(v)
    if not math.isfinite(x):
        raise ScanError(f"{kind}.{key}: must be finite, got {v!r}", key)
    return x


def parse_pose(pose) -> tuple[float | None, Pose]:
    """``(stamp or None, (x, y, theta))`` from a ``pose`` message or a 3-sequence.

    Raises
    ------
    ScanError
        Missing or non-finite fields, or not three numbers.
    """
    if isinstance(pose, (Mapping, str, bytes, bytearray)):
        m = as_message(pose, "pose")
        stamp = _number(m, "stamp", "pose")
        return stamp, (_number(m, "x", "pose"), _number(m, "y", "pose"), _number(m, "theta", "pose"))
    try:
        arr = to_floats(pose).reshape(-1)
    except (TypeError, ValueError):
        raise ScanError(f"pose: expected (x, y, theta) or a pose message, got {pose!r}", "pose") from None
    if arr.shape != (3,):
        raise ScanError(f"pose: expected 3 numbers (x, y, theta), got shape {arr.shape}", "pose")
    if not np.all(np.isfinite(arr)):
        raise ScanError(f"pose: must be finite, got {arr.tolist()}", "pose")
    return None, (float(arr[0]), float(arr[1]), float(arr[2]))


def parse_scan(msg, pose, *, beams: int | None = None) -> Scan:
    """Turn a ``scan`` message taken at ``pose`` into a world-frame :class:`Scan`.

    Parameters
    ----------
    msg : mapping, str or bytes
        The ``scan`` message (FORMATS.md bus contract).
    pose : pose message or (x, y, theta)
        Sensor pose at the scan's stamp.
    beams : int, optional
        Expected beam count (the lidar's); a different count is rejected.

    Returns
    -------
    Scan

    Raises
    ------
    ScanError
        Missing/non-numeric fields, non-finite header numbers, ``range_max <= range_min``,
        an empty ``ranges`` list, a beam count different from ``beams``.
    """
    m = as_message(msg, "scan")
    stamp = _number(m, "stamp", "scan")
    a0 = _number(m, "angle_min", "scan")
    da = _number(m, "angle_increment", "scan")
    rmin = _number(m, "range_min", "scan")
    rmax = _number(m, "range_max", "scan")
    if not 0.0 <= rmin < rmax:
        raise ScanError(f"scan.range_max: need 0 <= range_min < range_max, got {rmin:g}, {rmax:g}", "range_max")
    raw = m.get("ranges")
    if not isinstance(raw, (list, tuple, np.ndarray)):
        raise ScanError(f"scan.ranges: expected a list of numbers, got {type(raw).__name__}", "ranges")
    if len(raw) == 0:
        raise ScanError("scan.ranges: empty scan (no beams)", "ranges")
    if beams is not None and len(raw) != beams:
        raise ScanError(f"scan.ranges: expected {beams} beams (the lidar's), got {len(raw)}", "ranges")
    try:
        r = to_floats([np.nan if v is None else v for v in raw] if not isinstance(raw, np.ndarray) else raw).reshape(-1)
    except (TypeError, ValueError):
        bad = next((v for v in raw if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)))), "?")
        raise ScanError(f"scan.ranges: expected numbers, got {bad!r}", "ranges") from None
    _, p = parse_pose(pose)
    invalid = np.isnan(r) | (r < rmin) | (r == -np.inf)
    r = np.where(invalid, np.nan, r)
    hit = ~invalid & np.isfinite(r) & (r < rmax)
    r = np.where(~invalid & ~hit, np.inf, r)
    with np.errstate(over="ignore", invalid="ignore"):  # refused just below
        ang = p[2] + a0 + da * np.arange(len(r))
    if not np.isfinite(ang).all():
        raise ScanError(f"scan.angle_increment: the beams' angles overflow ({a0:g} + {len(r) - 1} x {da:g})",
                        "angle_increment")
    rh = r[hit]
    pts = np.stack((p[0] + rh * np.cos(ang[hit]), p[1] + rh * np.sin(ang[hit])), axis=1)
    return Scan(stamp, p, ang, r, hit, pts, rmax, int(invalid.sum()))


def parse_points(msg) -> tuple[float, np.ndarray, int]:
    """``(stamp, points (N, 2), dropped)`` of a ``points`` message; non-finite rows are dropped.

    Raises
    ------
    ScanError
        Missing stamp, ``points`` not a list of ``[x, y]`` pairs.
    """
    m = as_message(msg, "points")
    stamp = _number(m, "stamp", "points")
    raw = m.get("points")
    if not isinstance(raw, (list, tuple, np.ndarray)):
        raise ScanError(f"points.points: expected a list of [x, y], got {type(raw).__name__}", "points")
    if len(raw) == 0:
        return stamp, np.zeros((0, 2)), 0
    try:
        pts = to_floats(raw)
    except (TypeError, ValueError):
        raise ScanError("points.points: expected a list of [x, y] number pairs", "points") from None
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ScanError(f"points.points: expected shape (N, 2), got {pts.shape}", "points")
    ok = np.all(np.isfinite(pts), axis=1)
    return stamp, pts[ok], int((~ok).sum())
