"""Simulator of the robot and its lidar against a world's ground truth (issue 4, item 3).

A unicycle integrated exactly along arcs with velocity saturation
(:mod:`~service.sim.kinematics`), a planar lidar ray-casting the true squircles exactly, with
seedable Gaussian range noise (:mod:`~service.sim.lidar`), and collision detection of the
robot disc with a swept, certified check that stops the robot before any contact
(:mod:`~service.sim.collision`). :class:`Simulator` ties them together and speaks the ``pose``,
``scan``, ``points`` and ``cmd_vel`` messages of the bus contract (``shared/FORMATS.md``)::

    from service.sim import Simulator
    sim = Simulator(navigation.load_world("office"), seed=0)     # dt = 0.1 s
    sim.apply_cmd_vel({"stamp": 0.0, "v": 0.3, "omega": 0.2})
    result = sim.step()                  # StepResult: pose, command, clipped, collision...
    sim.pose_message(), sim.scan_message(), sim.metrics

See ``docs/simulator.md``.
"""

from .collision import WORKSPACE, ClearanceMap, Sweep
from .errors import CollisionStartError, CommandError, PoseError, SimulatorError
from .kinematics import arc_pose, arc_positions, saturate, wrap_angle
from .lidar import LidarConfig, RayCaster
from .simulator import CollisionEvent, Pose, SimConfig, SimMetrics, Simulator, StepResult

__all__ = [
    "ClearanceMap",
    "CollisionEvent",
    "CollisionStartError",
    "CommandError",
    "LidarConfig",
    "Pose",
    "PoseError",
    "RayCaster",
    "SimConfig",
    "SimMetrics",
    "Simulator",
    "SimulatorError",
    "StepResult",
    "Sweep",
    "WORKSPACE",
    "arc_pose",
    "arc_positions",
    "saturate",
    "wrap_angle",
]
