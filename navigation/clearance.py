"""Cheap certified lower bounds on the clearance of points in a forest world.

The controller's safety limit (:mod:`navigation.control`) needs, at every step, a distance
``d(q)`` such that the disc of radius ``d(q)`` around ``q`` is free. Exact point-to-squircle
distances need an iterative search; this module gives a certified lower bound instead, at
most half a boundary-sample arc (2.5 mm by default) below the exact distance, from the boundary
samples of :class:`~navigation.geometry.ExactDistance` (the exact distance lies in
``[d - h, d]`` for the distance ``d`` to the nearest sample and half the largest arc ``h``):

* an obstacle squircle lies inside its bounding rectangle (``|u|, |w| <= 1`` in normalised
  coordinates whenever ``beta <= 0``), so the closed-form distance to the rectangle is a lower
  bound; where it is below the distance still in question, the sampled bound refines it;
* for the workspace, the distance to its bounding rectangle's boundary is an upper bound, and
  that minus the largest distance from a boundary sample to the rectangle's boundary (plus
  ``h``) a lower bound; where the lower bound is below the distance still in question (at most
  ``far``), the sampled bound refines it.

Each refined bound is the larger of the two lower bounds. All bounds are vectorised over
``(N, 2)`` points; points inside an obstacle or outside the workspace get bound 0.
"""

from __future__ import annotations

import functools

import numpy as np

from ._arrays import as_points, restore
from .geometry import ExactDistance, beta_rows

__all__ = ["ClearanceBound", "forest_clearance"]


def _local(rows: np.ndarray, pts: np.ndarray):
    """Coordinates of ``pts (N, 2)`` in the frames of ``rows (M, 7)``: two ``(N, M)`` arrays."""
    dx = pts[:, None, 0] - rows[None, :, 0]
    dy = pts[:, None, 1] - rows[None, :, 1]
    return dx * rows[:, 2] + dy * rows[:, 3], dy * rows[:, 2] - dx * rows[:, 3]


def _inside_rectangle(rows: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Distance ``(N, M)`` from ``pts`` to the boundaries of the rectangles of ``rows``
    (negative outside): an upper bound on the distance to the boundary of an enclosing squircle."""
    u, w = _local(rows, pts)
    return np.minimum(rows[:, 4] - np.abs(u), rows[:, 5] - np.abs(w))


class ClearanceBound:
    """Lower bound on the distance from points to the obstacles and the workspace boundary.

    Parameters
    ----------
    workspace : navigation.Squircle
    obstacles : sequence of navigation.Squircle
    spacing : float
        Largest arc between boundary samples (m); the bound is at most ``spacing / 2`` low.

    Examples
    --------
    >>> import navigation
    >>> world = navigation.load_world("simple")
    >>> bound = ClearanceBound(world.workspace, world.obstacles)
    >>> float(bound(world.workspace.center)) >= 0.0
    True
    """

    def __init__(self, workspace, obstacles, spacing: float = 0.005):
        self._m = m = len(obstacles)
        # the samples of a squircle are fetched when a query first needs them: a field's queries
        # stay near its goal and the robot, where few of the forest's shapes are
        self._table = ExactDistance(tuple(obstacles) + (workspace,), spacing=spacing, split=m, min_samples=64,
                                    lazy=True)
        self._rows = self._table.P[:m]
        self._ws = self._table.P[m:]
        self._gap = _workspace_gap(workspace, spacing)
        self._memo: dict = {}  # (points, far) -> bound of the last few calls

    def exact(self, q) -> float:
        """Exact clearance of one point ``q (2,)``: the smallest distance to an obstacle or to the
        workspace boundary (negative inside an obstacle or outside the workspace), 1e-9 m
        accurate (:meth:`ExactDistance.signed` on this bound's tables).

        At a point outside every obstacle and inside the workspace only the obstacles that can
        be the nearest are measured: those whose bounding rectangle is no farther than the
        smallest upper bound on a distance (the workspace's bounding rectangle; for an obstacle,
        the distance to its boundary point towards its centre) plus 1e-6 m. Every other obstacle's computed
        distance (at least its rectangle's, less rounding) exceeds the result, so the minimum is
        the same number as over all of them."""
        p = np.asarray(q, dtype=float).reshape(1, 2)
        m = self._m
        k = np.arange(m + 1)
        if m:
            u, w = _local(self._rows, p)
            u, w = u[0], w[0]
            b = beta_rows(self._rows, p[0, 0], p[0, 1])
            if (b > 0.0).all() and beta_rows(self._ws[0], p[0, 0], p[0, 1]) < 0.0:
                ex = np.maximum(np.abs(u) - self._rows[:, 4], 0.0)
                ey = np.maximum(np.abs(w) - self._rows[:, 5], 0.0)
                lower = np.sqrt(ex * ex + ey * ey)
                # outside a squircle the boundary point on the segment to its centre c is
                # c + (q - c) / g, g = sqrt(beta + 1) the squircle's gauge (a norm about c)
                upper = np.hypot(u, w) * (1.0 - 1.0 / np.sqrt(b + 1.0))
                best = min(float(upper.min()), float(_inside_rectangle(self._ws, p)[0, 0]))
                k = np.append(np.nonzero(lower <= best + 1e-6)[0], m)
        d = self._table.signed(np.repeat(p, len(k), axis=0), k)
        d[-1] = -d[-1]  # inside the workspace: its signed distance is negative
        return float(d.min())

    def __call__(self, q, far: float = np.inf) -> np.ndarray:
        """Lower bound ``(N,)`` (or a float for ``(2,)``) on the clearance of ``q``.

        Where the clearance is at least ``far`` the bound may be any value ``>= far``.
        """
        pts, single = as_points(q, "q")
        # the fields of one forest share this bound and the controller asks each of them at the
        # same point: the last few answers are kept (copies of the same numbers)
        key = None
        if len(pts) <= 4 and np.ndim(far) == 0:
            key = (pts.tobytes(), len(pts), float(far), single)
            hit = self._memo.get(key)
            if hit is not None:
                return hit.copy() if isinstance(hit, np.ndarray) else hit
        out = self._bound(pts, far, single)
        if key is not None:
            if len(self._memo) >= 8:
                self._memo.clear()
            self._memo[key] = out.copy() if isinstance(out, np.ndarray) else out
        return out

    def _bound(self, pts: np.ndarray, far, single: bool):
        m = self._m
        upper = _inside_rectangle(self._ws, pts)[:, 0]
        inside = upper > 0
        inside[inside] = beta_rows(self._ws[0], pts[inside, 0], pts[inside, 1]) < 0.0
        bound = np.empty((len(pts), m + 1))
        bound[:, m] = upper - self._gap
        if m:
            u, w = _local(self._rows, pts)
            ex = np.maximum(np.abs(u) - self._rows[:, 4], 0.0)
            ey = np.maximum(np.abs(w) - self._rows[:, 5], 0.0)
            bound[:, :m] = np.sqrt(ex * ex + ey * ey)
        n, j = np.nonzero(bound < np.minimum(upper, far)[:, None])
        if len(n):
            d, h = self._table.sampled(pts[n], j)
            refined = np.maximum(d - h, bound[n, j])
            obstacle = j < m
            hit = beta_rows(self._table.P[j[obstacle]], pts[n[obstacle], 0], pts[n[obstacle], 1]) <= 0.0
            refined[np.nonzero(obstacle)[0][hit]] = 0.0
            bound[n, j] = refined
        d = np.where(inside, bound.min(axis=1), 0.0)
        return restore(np.maximum(d, 0.0), single)


@functools.lru_cache(maxsize=64)
def _workspace_gap(workspace, spacing: float) -> float:
    """The largest distance from a boundary sample of ``workspace`` to its bounding rectangle's
    boundary plus half the largest arc between samples (the workspace's own sample count: it is
    a group of its own in a :class:`ClearanceBound`'s table), computed once per workspace."""
    table = ExactDistance((workspace,), spacing=spacing, min_samples=64)
    _, half = table.sampled(np.zeros((1, 2)), np.array([0]))
    return float(_inside_rectangle(table.P, table.boundary_samples(0)).max()) + float(half[0])


@functools.lru_cache(maxsize=32)
def forest_clearance(forest) -> ClearanceBound:
    """The :class:`ClearanceBound` of a forest's workspace and obstacles, built once per forest
    (its boundary tables take tens of milliseconds; every field on one forest shares them)."""
    return ClearanceBound(forest.workspace, forest.obstacles)
