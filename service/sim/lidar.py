"""Planar lidar: beam angles, exact ray casting against the true squircles, range noise.

Conventions
-----------
Beams. ``beams`` rays over ``fov`` centred on the heading, in the robot frame (angle 0 =
heading, counter-clockwise positive). A full circle (``fov`` within 1e-5 rad of ``2 pi``;
world files write ``6.283185``) has ``angle_min = -pi`` and ``angle_increment = 2 pi / beams``
(no beam counted twice; the last one is at ``pi - 2 pi / beams``). A partial fan has
``angle_min = -fov / 2`` and ``angle_increment = fov / (beams - 1)``, so that its first and
last beams lie on its edges; a single beam looks along the heading (``angle_min = 0``,
``angle_increment = 0``).

Ranges. Rays start at the robot centre. The true range of a beam is the exact distance to the
first crossing with any obstacle boundary or with the workspace boundary (from inside); it is
a return when it is below ``range``, otherwise there is no return (``inf`` in arrays; the
bus message encodes it as ``range_max``, see :mod:`service.sim.simulator`). A sensor inside an
obstacle sees 0 on every beam.

Noise. ``noise_std > 0`` adds independent Gaussian noise to every return, drawn from the
simulator's seedable :class:`numpy.random.Generator`; a noisy range is clipped at
``range_min`` (0: noise never makes a range negative) and a noisy range at or beyond ``range``
becomes no return. Beams without a return get no noise.

Exactness. Candidate (beam, obstacle) pairs are those whose ray meets the obstacle's bounding
circle before ``range``. For each, Newton's method on ``beta`` along the ray
(:func:`navigation.geometry.ray_length_packed`, ``entry=True``) starts on the near side of the
bounding rectangle; ``beta`` is convex along a ray, so the iterates increase monotonically to
the first crossing when there is one, and stop where ``beta`` is still positive when the ray
misses (they cannot pass a root). A pair is a hit when ``beta`` at the result is at most
``1e-12``. The workspace exit uses the same solver with ``entry=False``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navigation._arrays import to_float
from navigation.geometry import Squircle, beta_rows, pack, ray_length_packed
from navigation.world import LidarSpec

from .errors import SimulatorError

__all__ = ["LidarConfig", "RayCaster", "FULL_CIRCLE_TOL"]

#: a field of view within this of 2 pi is a full circle
FULL_CIRCLE_TOL = 1e-5
_HIT_TOL = 1e-12


@dataclass(frozen=True, slots=True)
class LidarConfig:
    """Lidar parameters (world file ``lidar``) and the beam layout derived from them.

    Attributes
    ----------
    range : float
        Maximum range (m); returns at or beyond it are no return. Also the message's ``range_max``.
    fov : float
        Field of view (rad), centred on the heading, ``0 < fov <= 2 pi``.
    beams : int
        Number of beams (>= 1).
    noise_std : float
        Standard deviation of the Gaussian range noise (m, >= 0).
    rate_hz : float
        Scan rate (Hz) the service should publish at (the simulator scans on request).
    range_min : float
        Smallest reported range (m), 0 by default.
    """

    range: float
    fov: float
    beams: int
    noise_std: float = 0.0
    rate_hz: float = 10.0
    range_min: float = 0.0

    def __post_init__(self):
        for name in ("range", "fov", "noise_std", "rate_hz", "range_min"):
            x = getattr(self, name)
            if (isinstance(x, bool) or not isinstance(x, (int, float, np.integer, np.floating))
                    or not math.isfinite(to_float(x))):
                raise SimulatorError(f"lidar {name}: expected a finite number, got {x!r}")
            object.__setattr__(self, name, float(x))
        if self.range <= 0 or self.rate_hz <= 0:
            raise SimulatorError(f"lidar range and rate_hz must be > 0, got {self.range}, {self.rate_hz}")
        if not 0.0 < self.fov <= 2.0 * math.pi + FULL_CIRCLE_TOL:
            raise SimulatorError(f"lidar fov must be in (0, 2 pi], got {self.fov}")
        if self.noise_std < 0 or not 0.0 <= self.range_min < self.range:
            raise SimulatorError(f"lidar noise_std must be >= 0 and 0 <= range_min < range, got "
                                 f"{self.noise_std}, {self.range_min}")
        b = self.beams
        if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or b < 1:
            raise SimulatorError(f"lidar beams: expected a whole number >= 1, got {b!r}")
        object.__setattr__(self, "beams", int(b))

    @classmethod
    def from_spec(cls, spec: LidarSpec) -> "LidarConfig":
        """From a world file's :class:`navigation.world.LidarSpec`."""
        return cls(spec.range, spec.fov, spec.beams, spec.noise_std, spec.rate_hz)

    @property
    def full_circle(self) -> bool:
        return abs(self.fov - 2.0 * math.pi) <= FULL_CIRCLE_TOL

    @property
    def angle_min(self) -> float:
        """Angle of the first beam in the robot frame (rad)."""
        if self.full_circle:
            return -math.pi
        return 0.0 if self.beams == 1 else -0.5 * self.fov

    @property
    def angle_increment(self) -> float:
        """Angle between consecutive beams (rad)."""
        if self.full_circle:
            return 2.0 * math.pi / self.beams
        return 0.0 if self.beams == 1 else self.fov / (self.beams - 1)

    def angles(self) -> np.ndarray:
        """Beam angles ``(beams,)`` in the robot frame: ``angle_min + k angle_increment``."""
        return self.angle_min + self.angle_increment * np.arange(self.beams)


class RayCaster:
    """Exact ray casting against fixed squircles inside a workspace (immutable).

    Parameters
    ----------
    workspace : Squircle
    obstacles : sequence of Squircle
    """

    def __init__(self, workspace: Squircle, obstacles):
        self.workspace = workspace
        self.obstacles = tuple(obstacles)
        self._P = pack(self.obstacles) if self.obstacles else np.zeros((0, 7))
        self._W = pack([workspace])[0]
        self._c = self._P[:, :2].copy()
        self._R2 = np.array([o.bounding_radius for o in self.obstacles]).reshape(-1) ** 2

    def cast(self, origin, angles, max_range: float = math.inf) -> np.ndarray:
        """Exact ranges ``(B,)`` from ``origin (2,)`` along world-frame ``angles (B,)``.

        A range is the distance to the first obstacle or workspace boundary crossing; ``inf``
        where it is ``>= max_range``; 0 on every beam when ``origin`` is inside an obstacle or
        not inside the workspace.
        """
        o = np.asarray(origin, dtype=float).reshape(2)
        ang = np.asarray(angles, dtype=float).reshape(-1)
        B = len(ang)
        d = np.stack((np.cos(ang), np.sin(ang)), axis=1)
        if not beta_rows(self._W, o[0], o[1]) < 0.0 or np.any(beta_rows(self._P, o[0], o[1]) <= 0.0):
            return np.zeros(B)
        W = np.broadcast_to(self._W, (B, 7))
        ranges = ray_length_packed(W, np.broadcast_to(o, (B, 2)), d)
        if len(self._P):
            w = self._c - o  # (M, 2)
            tc = d @ w.T  # (B, M): distance along the ray to the foot of the centre
            perp2 = (w * w).sum(1)[None, :] - tc * tc
            half = np.sqrt(np.maximum(self._R2[None, :] - perp2, 0.0))
            near = np.minimum(ranges, max_range)[:, None]
            cand = (perp2 < self._R2[None, :]) & (tc + half > 0.0) & (tc - half < near)
            b, m = np.nonzero(cand)
            if b.size:
                p = self._P[m]
                oo = np.broadcast_to(o, (b.size, 2))
                r = ray_length_packed(p, oo, d[b], np.ones(b.size, dtype=bool))
                hit = beta_rows(p, o[0] + r * d[b, 0], o[1] + r * d[b, 1]) <= _HIT_TOL
                np.minimum.at(ranges, b[hit], r[hit])
        ranges[ranges >= max_range] = math.inf
        return ranges
