"""Shape handling shared by every point function: ``(2,)`` or ``(N, 2)`` in, the same kind out."""

from __future__ import annotations

import math

import numpy as np

from .errors import PointsError

__all__ = ["as_points", "restore", "to_float", "to_floats"]


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


def to_float(v) -> float:
    """``float(v)``, with an integer beyond the float range (JSON may write ``1e400`` out as
    digits) as the infinity of its sign instead of an ``OverflowError``; callers that need a
    finite number then refuse it as non-finite."""
    try:
        return float(v)
    except OverflowError:
        return math.inf if v > 0 else -math.inf


def to_floats(seq) -> np.ndarray:
    """``np.array(seq, dtype=float)`` with integers beyond the float range (also in nested
    lists) as infinities (:func:`to_float`); ``TypeError``/``ValueError`` as numpy raises them."""
    try:
        return np.array(seq, dtype=float)
    except OverflowError:
        def conv(v):
            if isinstance(v, (list, tuple)):
                return [conv(u) for u in v]
            return to_float(v) if isinstance(v, int) and not isinstance(v, bool) else v
        return np.array(conv(list(seq)), dtype=float)
