"""Perception: lidar scans to a consistent forest of squircle obstacles, online.

Implements, for the online exploration of paper 001 (Wang & Guo 2025):

* section 3 (the robot knows only the workspace boundary and discovers obstacles with its
  lidar): scan ingestion (:mod:`perception.ingest`) and the obstacle map
  (:class:`ObstacleMap`, the one stateful object of this layer);
* section 4.1.2 (obstacles are squircles organised as a forest of stars): squircle fitting
  of point clusters (:func:`fit_squircle`, nonlinear least squares seeded from OpenCV),
  conservative completion of partial views, inflation by the robot radius, and a map that
  :func:`navigation.build_forest` accepts after every update;
* section 4.2.1 (obstacles a single squircle cannot describe become trees of overlapping
  squircles): decomposition of clusters at corners (:func:`fit_cluster`).

Public entry points::

    m = perception.ObstacleMap.from_world(world)     # workspace, robot radius, regions, lidar
    upd = m.update_scan(scan_msg, pose_msg)          # -> MapUpdate(added, updated, removed, ...)
    m.obstacles(), m.inflated(), m.forest(), m.to_message()

Thresholds (:class:`PerceptionConfig`) derive from the lidar's range, angular resolution and
noise by documented rules and can be overridden. Bad input raises a
:class:`~perception.errors.ScanError` (a ``navigation.errors.PerceptionError``) and is logged
on the ``perception`` logger; the map is never changed by it. See ``docs/perception.md``.
"""

from .config import PerceptionConfig
from .errors import PerceptionError, PoseJumpError, ScanError, StampError
from .fit import Fit, fit_cluster, fit_squircle, gauge, inflate, radial_error, rect_error
from .ingest import Scan, parse_points, parse_pose, parse_scan
from .map import Estimate, MapUpdate, ObstacleMap

__all__ = [
    "Estimate",
    "Fit",
    "MapUpdate",
    "ObstacleMap",
    "PerceptionConfig",
    "PerceptionError",
    "PoseJumpError",
    "Scan",
    "ScanError",
    "StampError",
    "fit_cluster",
    "fit_squircle",
    "gauge",
    "inflate",
    "parse_points",
    "parse_pose",
    "parse_scan",
    "radial_error",
    "rect_error",
]
