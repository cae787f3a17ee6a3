"""The product's exception hierarchy (one root, messages that name the culprit).

Every error the product raises on bad input derives from :class:`HarmonicTampError`,
so a caller (the service, the CLI) can catch one type and answer with a clear message.
The subclasses also derive from the matching builtin (``ValueError``, ``SyntaxError``)
so ordinary Python code that expects those keeps working.
"""

from __future__ import annotations

import math

__all__ = [
    "check_numbers",
    "HarmonicTampError",
    "NavigationError",
    "WorldError",
    "ForestError",
    "PointsError",
    "OutsideFreeSpaceError",
    "SingularJacobianError",
    "PerceptionError",
    "TampError",
    "ServiceError",
]


class HarmonicTampError(Exception):
    """Root of every error raised by harmonic-tamp on bad input or impossible requests."""


class NavigationError(HarmonicTampError):
    """A navigation-layer request cannot be served (geometry, worlds, navigation functions)."""


class WorldError(NavigationError, ValueError):
    """A world description is invalid; the message names the offending field.

    Attributes
    ----------
    field : str or None
        Dotted path of the offending field (``"obstacles[3].width"``), when known.
    """

    def __init__(self, message: str, field: str | None = None):
        super().__init__(message)
        self.field = field


class ForestError(WorldError):
    """Obstacles that the forest-of-stars construction cannot organise.

    Attributes
    ----------
    obstacles : tuple of int
        Indices of the obstacles involved (``-1`` stands for the workspace boundary).
    rule : str
        Short name of the violated rule (``"cycle"``, ``"two-parents"``, ``"too-close"``...).
    """

    def __init__(self, message: str, obstacles=(), rule: str = ""):
        super().__init__(message, field="obstacles")
        self.obstacles = tuple(int(i) for i in obstacles)
        self.rule = rule


class PointsError(NavigationError, ValueError):
    """An array of points has the wrong shape or non-finite entries; the message names it."""


class OutsideFreeSpaceError(NavigationError, ValueError):
    """A point that must lie in free space (a goal, a start) does not."""


class SingularJacobianError(NavigationError, ArithmeticError):
    """A transformation that must be a diffeomorphism produced a singular Jacobian."""


class PerceptionError(HarmonicTampError):
    """Sensor data that cannot be turned into obstacles."""


class TampError(HarmonicTampError):
    """Mission-layer failure (LTL, automata, plans)."""


class ServiceError(HarmonicTampError):
    """The running service cannot honour a request."""


def check_numbers(obj, names, *, positive: bool, error: type = None) -> None:
    """Raise ``error`` (default :class:`NavigationError`) naming ``<Class>.<name>`` unless each
    attribute ``name`` of the config object ``obj`` is a finite real number (booleans refused),
    ``> 0`` when ``positive``, else ``>= 0``."""
    for name in names:
        v = getattr(obj, name)
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and (v > 0 if positive else v >= 0)
        if not ok:
            what = "a positive finite number" if positive else "a finite number >= 0"
            raise (error or NavigationError)(f"{type(obj).__name__}.{name} must be {what}, got {v!r}")
