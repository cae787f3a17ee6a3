"""Perception thresholds, derived from the lidar's range, angular resolution and noise.

Every threshold has a documented rule (see ``docs/perception.md``, "Threshold rules") and can
be overridden by keyword: ``PerceptionConfig.from_lidar(world.lidar, link=0.05)``.

Symbols: ``R`` lidar range (m), ``da`` angular resolution (rad), ``sigma`` range noise (m),
``lam`` the smallest incidence angle at which a surface still counts as continuous.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from .errors import ScanError

__all__ = ["PerceptionConfig"]


@dataclass(frozen=True, slots=True)
class PerceptionConfig:
    """Thresholds of scan ingestion, clustering, fitting and the obstacle map (metres, seconds).

    Build it with :meth:`from_lidar`; direct construction takes every value explicitly.

    Attributes
    ----------
    range_max, angle_increment, noise_std :
        The lidar's range, angular resolution and range noise the rules start from.
    voxel :
        Cell of the point store: returns falling in one cell are averaged (``0.02``).
    free_cell :
        Cell of the free-space evidence grid (``0.04``).
    free_margin :
        A beam proves free only the part of its path that ends this far before its return:
        ``free_cell / sqrt(2) + 3 sigma + 0.01`` (so a free cell's centre is never inside the
        surface that stopped the beam).
    incidence :
        ``lam`` of the breakpoint rule (15 degrees).
    link :
        Points closer than this belong to one cluster: ``max(4 R da, 3 voxel) + 3 sigma`` (twice the
        spacing of neighbouring returns at full range on a surface facing the sensor).
    split_tol :
        RMS radial error above which a cluster is decomposed: ``0.012 + 2 sigma``.
    refit_tol :
        A new point farther than this outside its estimate triggers a refit: ``0.04 + 2 sigma``
        (smaller than a robot radius, so such points are still inside the inflated estimate).
    free_tol :
        A newly free cell deeper than this inside an estimate triggers a refit: ``0.03 + 2 sigma``.
    inside_tol :
        After a fit, every observed point lies at most this far outside the estimate:
        ``0.003 + 2 sigma``.
    min_unseen :
        Minimum extent given to an obstacle behind a face whose back was never seen (``0.15``).
    min_extent :
        Smallest width/height of an estimate (``0.02``).
    max_extent :
        Largest width/height of an estimate (``2 R + 1``).
    min_piece :
        Fewest points of a decomposed piece (``6``).
    ws_band :
        Returns within this of the workspace boundary are the boundary itself: ``0.01 + 5 sigma``
        (a noisy return of the boundary beyond 3 sigma formed a phantom estimate on it in 23 of the
        33 noisy drives of the slow perception test; beyond 5 sigma: about 3e-7 per return).
        With noise, a return in the band is dropped only when its beam, continued by
        ``ws_band``, leaves the workspace (``ObstacleMap``, step 1).
    ws_touch :
        A cluster with points within this of the workspace boundary is extended through it
        (a wall on the boundary): ``link + 0.01 + 3 sigma`` (the ``3 sigma`` band of before; with
        ``link + ws_band`` a wall near the boundary of the office was joined to it, IoU 0.72 -> 0.61).
    clearance_margin :
        Extra clearance kept between an estimate and the robot disc or a region disc (``0.005``).
    max_pose_jump :
        Largest accepted distance between the poses of consecutive scans (``1.0``).
    max_stamp_skew :
        Largest accepted difference between a scan's stamp and its pose's stamp (``0.05``).
    max_future :
        Largest accepted lead of a stamp over ``now`` when ``now`` is given (``0.5``).
    min_gap, min_overlap :
        Passed to :func:`navigation.build_forest` when validating the map (``1e-3`` each).
    """

    range_max: float
    angle_increment: float
    noise_std: float
    voxel: float
    free_cell: float
    free_margin: float
    incidence: float
    link: float
    split_tol: float
    refit_tol: float
    free_tol: float
    inside_tol: float
    min_unseen: float = 0.15
    min_extent: float = 0.02
    max_extent: float = 3.0
    min_piece: int = 6
    ws_band: float = 0.01
    ws_touch: float = 0.05
    clearance_margin: float = 0.005
    max_pose_jump: float = 1.0
    max_stamp_skew: float = 0.05
    max_future: float = 0.5
    min_gap: float = 1e-3
    min_overlap: float = 1e-3

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ScanError(f"PerceptionConfig.{f.name}: expected a finite number, got {v!r}", f.name)
            if v < 0 or (v == 0 and f.name not in ("noise_std", "min_gap", "min_overlap", "clearance_margin")):
                raise ScanError(f"PerceptionConfig.{f.name}: must be > 0, got {v!r}", f.name)
        if self.min_extent > self.min_unseen or self.min_unseen > self.max_extent:
            raise ScanError("PerceptionConfig: need min_extent <= min_unseen <= max_extent", "min_unseen")

    @classmethod
    def from_lidar(cls, lidar=None, *, range_max: float | None = None, angle_increment: float | None = None,
                   noise_std: float | None = None, **overrides) -> "PerceptionConfig":
        """Thresholds for a lidar (a ``navigation.world.LidarSpec`` or ``service.sim.LidarConfig``),
        by the rules of the class docstring; keyword ``overrides`` replace any derived value.

        ``range_max``, ``angle_increment`` and ``noise_std`` may be given instead of ``lidar``.
        """
        if lidar is not None:
            R = float(getattr(lidar, "range"))
            beams = int(getattr(lidar, "beams"))
            fov = float(getattr(lidar, "fov"))
            da = fov / beams if abs(fov - 2 * math.pi) < 1e-5 else fov / max(beams - 1, 1)
            sig = float(getattr(lidar, "noise_std", 0.0))
        else:
            R, da, sig = 10.0, math.radians(1.0), 0.0
        R = R if range_max is None else float(range_max)
        da = da if angle_increment is None else float(angle_increment)
        sig = sig if noise_std is None else float(noise_std)
        da = max(da, 1e-4)
        voxel = overrides.get("voxel", 0.02)
        free_cell = overrides.get("free_cell", 0.04)
        link = max(4 * R * da, 3 * voxel) + 3 * sig
        ws_band = 0.01 + 5 * sig
        base = dict(range_max=R, angle_increment=da, noise_std=sig, voxel=voxel, free_cell=free_cell,
                    free_margin=free_cell / math.sqrt(2) + 3 * sig + 0.01, incidence=math.radians(15.0),
                    link=link, split_tol=0.012 + 2 * sig, refit_tol=0.04 + 2 * sig, free_tol=0.03 + 2 * sig,
                    inside_tol=0.003 + 2 * sig, max_extent=2 * R + 1.0, ws_band=ws_band,
                    ws_touch=link + 0.01 + 3 * sig)
        unknown = set(overrides) - {f.name for f in fields(cls)}
        if unknown:
            raise ScanError(f"PerceptionConfig: unknown threshold(s) {sorted(unknown)}", sorted(unknown)[0])
        base.update(overrides)
        return cls(**base)

    def breakpoint(self, r):
        """Largest distance between consecutive returns of one surface at range ``r``
        (adaptive breakpoint rule): ``r sin(da) / sin(lam - da) + 3 sigma``."""
        return r * math.sin(self.angle_increment) / math.sin(self.incidence - self.angle_increment) + 3 * self.noise_std

    def with_(self, **changes) -> "PerceptionConfig":
        """A copy with ``changes`` (validated)."""
        return replace(self, **changes)
