"""Errors of the simulator: bad poses, bad commands and malformed bus messages.

They sit under :class:`navigation.errors.ServiceError` (the simulator belongs to the service
layer) and derive from :class:`ValueError`; a pose in collision is also an
:class:`navigation.errors.OutsideFreeSpaceError`, so navigation-level callers can catch it as
such.
"""

from __future__ import annotations

from navigation.errors import OutsideFreeSpaceError, ServiceError

__all__ = ["SimulatorError", "CommandError", "PoseError", "CollisionStartError"]


class SimulatorError(ServiceError, ValueError):
    """The simulator refuses an input (configuration, pose, command or message)."""


class CommandError(SimulatorError):
    """A velocity command or a ``cmd_vel`` message is malformed or not finite.

    Attributes
    ----------
    field : str or None
        The offending field (``"v"``, ``"omega"``, ``"stamp"``), when known.
    """

    def __init__(self, message: str, field: str | None = None):
        super().__init__(message)
        self.field = field


class PoseError(SimulatorError):
    """A pose that is not three finite numbers ``(x, y, theta)``."""


class CollisionStartError(PoseError, OutsideFreeSpaceError):
    """A pose whose robot disc touches or overlaps an obstacle or the workspace boundary.

    Attributes
    ----------
    obstacle : int or str
        Index of the nearest obstacle, or ``"workspace"``.
    clearance : float
        Signed clearance of the robot disc there (m; ``<= 0`` in contact or penetrating).
    """

    def __init__(self, message: str, obstacle: int | str, clearance: float):
        super().__init__(message)
        self.obstacle = obstacle
        self.clearance = clearance
