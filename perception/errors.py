"""Errors of the perception layer (under :class:`navigation.errors.PerceptionError`).

Every error names the offending message field or argument; none of them is a bare numpy
traceback.
"""

from __future__ import annotations

from navigation.errors import PerceptionError

__all__ = ["PerceptionError", "ScanError", "StampError", "PoseJumpError"]


class ScanError(PerceptionError, ValueError):
    """A ``scan``/``points``/``pose`` message (or array) is malformed; ``.field`` names the field.

    Examples: a missing ``ranges`` field, a non-numeric ``angle_increment``, a beam count that
    differs from the lidar's, an empty scan.
    """

    def __init__(self, message: str, field: str | None = None):
        super().__init__(message)
        self.field = field


class StampError(ScanError):
    """A stamp is stale (older than the last one processed), in the future, or does not match
    the pose the scan is paired with."""


class PoseJumpError(ScanError):
    """The pose of a scan is implausibly far from the last accepted pose (a localisation jump)."""
