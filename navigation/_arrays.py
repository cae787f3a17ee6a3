"""Shape handling shared by every point function: ``(2,)`` or ``(N, 2)`` in, the same kind out."""

from __future__ import annotations

import numpy as np

from .errors import PointsError

__all__ = ["as_points", "restore"]


def as_points(x, name: str = "q", *, finite: bool = True) -> tuple[np.ndarray, bool]:
    """Promote ``x`` to a float64 ``(N, 2)`` array.

    Returns ``(points, single)`` where ``single`` says the input was one ``(2,)`` point, so
    that :func:`restore` can squeeze results back (the ``scipy.spatial.transform.Rotation``
    convention). Raises :class:`~navigation.errors.PointsError` naming ``name`` on a bad shape
    or, with ``finite=True``, on NaN/inf entries.
    """
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as err:
        raise PointsError(f"Expected `{name}` to be numeric points, got {type(x).__name__}.") from err
    single = a.ndim == 1
    if single:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 2:
        raise PointsError(f"Expected `{name}` to have shape (2,) or (N, 2), got {np.shape(x)}.")
    if finite and not np.all(np.isfinite(a)):
        bad = int(np.argmax(~np.all(np.isfinite(a), axis=1)))
        raise PointsError(f"`{name}` has non-finite coordinates (first at row {bad}: {a[bad].tolist()}).")
    return a, single


def restore(result: np.ndarray, single: bool) -> np.ndarray:
    """Undo the promotion of :func:`as_points` on a per-point result."""
    return result[0] if single else result
