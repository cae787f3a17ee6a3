"""Unicycle kinematics: exact arcs, velocity saturation and angle wrapping.

The unicycle ``x' = v cos(theta)``, ``y' = v sin(theta)``, ``theta' = omega`` with a command
``(v, omega)`` held constant over a step of ``t`` seconds is integrated exactly: the robot
moves along a circular arc of length ``|v| t`` and turns by ``a = omega t``. Its chord has
length ``v t sinc(a / 2)`` (``sinc(z) = sin(z) / z``) and direction ``theta + a / 2``:

    x(t) = x + v t sinc(a/2) cos(theta + a/2)
    y(t) = y + v t sinc(a/2) sin(theta + a/2)
    theta(t) = wrap(theta + a)

which is a straight line for ``omega = 0`` and numerically safe near it (the series
``1 - z^2/6`` replaces ``sin(z)/z`` for ``|z| < 1e-4``, where its error is below 1e-18).
Headings are wrapped to ``(-pi, pi]``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["wrap_angle", "sinc", "arc_pose", "arc_positions", "saturate"]

_TWO_PI = 2.0 * math.pi


def wrap_angle(a):
    """Angles wrapped to ``(-pi, pi]`` (float in, float out; arrays elementwise).

    Examples
    --------
    >>> wrap_angle(math.pi), wrap_angle(-math.pi), round(wrap_angle(3 * math.pi / 2), 12)
    (3.141592653589793, 3.141592653589793, -1.570796326795)
    """
    if isinstance(a, (float, int)):
        r = math.pi - math.fmod(math.pi - a, _TWO_PI)
        if r > math.pi:  # fmod keeps the sign of its first argument
            r -= _TWO_PI
        if r <= -math.pi:
            r += _TWO_PI
        return r
    a = np.asarray(a, dtype=float)
    r = math.pi - np.mod(math.pi - a, _TWO_PI)
    return np.where(r <= -math.pi, r + _TWO_PI, r)


def sinc(z):
    """``sin(z) / z`` (1 at 0), accurate near 0; float or array."""
    if isinstance(z, (float, int)):
        return 1.0 - z * z / 6.0 if abs(z) < 1e-4 else math.sin(z) / z
    z = np.asarray(z, dtype=float)
    small = np.abs(z) < 1e-4
    safe = np.where(small, 1.0, z)
    return np.where(small, 1.0 - z * z / 6.0, np.sin(safe) / safe)


def arc_pose(pose, v: float, omega: float, t: float) -> tuple[float, float, float]:
    """Pose ``(x, y, theta)`` after ``t`` seconds of the constant command ``(v, omega)`` (exact arc).

    Examples
    --------
    >>> x, y, th = arc_pose((0.0, 0.0, 0.0), 1.0, math.pi / 2, 1.0)  # a quarter circle of radius 2/pi
    >>> round(x, 12), round(y, 12), round(th, 12)
    (0.636619772368, 0.636619772368, 1.570796326795)
    """
    x, y, theta = pose
    a = omega * t
    half = 0.5 * a
    chord = v * t * sinc(half)
    heading = theta + half
    return (x + chord * math.cos(heading), y + chord * math.sin(heading), wrap_angle(theta + a))


def arc_positions(pose, v: float, omega: float, times) -> np.ndarray:
    """Positions ``(K, 2)`` along the arc of ``(v, omega)`` from ``pose`` at the ``times`` ``(K,)``."""
    x, y, theta = pose
    t = np.asarray(times, dtype=float)
    half = 0.5 * omega * t
    chord = v * t * sinc(half)
    heading = theta + half
    return np.stack((x + chord * np.cos(heading), y + chord * np.sin(heading)), axis=-1)


def saturate(v: float, omega: float, v_max: float, omega_max: float) -> tuple[float, float, bool]:
    """``(v, omega)`` clipped to ``|v| <= v_max``, ``|omega| <= omega_max``, and whether it was clipped."""
    vs = min(max(v, -v_max), v_max)
    ws = min(max(omega, -omega_max), omega_max)
    return vs, ws, (vs != v or ws != omega)
