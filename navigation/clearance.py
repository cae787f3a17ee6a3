"""Cheap certified lower bounds on the clearance of points in a forest world.

The controller's safety limit (:mod:`navigation.control`) needs, at every step, a distance
``d(q)`` such that the disc of radius ``d(q)`` around ``q`` is free. Exact point-to-squircle
distances need an iterative search; this module gives a certified lower bound instead, at
most half a boundary-sample spacing (2.5 mm by default) below the exact distance:

* an obstacle squircle lies inside its bounding rectangle (``|u|, |w| <= 1`` in normalised
  coordinates whenever ``beta <= 0``), so the closed-form distance to the rectangle is a lower
  bound; where it is below the distance still in question, the obstacle's boundary samples
  refine it as for the workspace below;
* the workspace boundary is sampled at construction (arc-length spacing at most ``spacing``);
  the distance to the nearest sample minus half the largest spacing is a lower bound of the
  distance to the boundary (the nearest boundary point lies within half a spacing, along the
  boundary, of a sample). It is only computed where it matters: the distance to the
  workspace's bounding rectangle minus the largest distance from a boundary sample to that
  rectangle's boundary is a lower bound, and points where it is at least ``far`` keep it.

All bounds are vectorised over ``(N, 2)`` points; points inside an obstacle or outside the
workspace get bound 0.
"""

from __future__ import annotations

import numpy as np

from ._arrays import as_points, restore

__all__ = ["ClearanceBound"]



def _local(rows: np.ndarray, pts: np.ndarray):
    """Coordinates of ``pts (N, 2)`` in the frames of ``rows (M, 7)``: two ``(N, M)`` arrays."""
    dx = pts[:, None, 0] - rows[None, :, 0]
    dy = pts[:, None, 1] - rows[None, :, 1]
    return dx * rows[:, 2] + dy * rows[:, 3], dy * rows[:, 2] - dx * rows[:, 3]


class ClearanceBound:
    """Lower bound on the distance from points to the obstacles and the workspace boundary.

    Parameters
    ----------
    workspace : navigation.Squircle
    obstacles : sequence of navigation.Squircle

    Examples
    --------
    >>> import navigation
    >>> world = navigation.load_world("simple")
    >>> bound = ClearanceBound(world.workspace, world.obstacles)
    >>> float(bound(world.workspace.center)) >= 0.0
    True
    """

    def __init__(self, workspace, obstacles, spacing: float = 0.005):
        self._workspace = workspace
        self._obstacles = tuple(obstacles)
        self._obs_samples, self._obs_half = [], []
        for o in self._obstacles:
            m = int(np.clip(np.ceil(2.0 * (o.width + o.height) / spacing), 64, 65536))
            op = np.asarray(o.point_at(o.boundary_psi(m)), dtype=float)
            self._obs_samples.append(op)
            self._obs_half.append(0.5 * float(np.linalg.norm(np.diff(np.vstack((op, op[:1])), axis=0), axis=1).max()))
        self._ws = workspace.packed()
        self._rows = np.array([o.packed() for o in obstacles], dtype=float).reshape(-1, 7)
        perimeter = 2.0 * (workspace.width + workspace.height)  # >= the squircle's perimeter
        n = int(np.clip(np.ceil(perimeter / spacing), 256, 65536))
        bp = np.asarray(workspace.point_at(workspace.boundary_psi(n)), dtype=float)
        self._samples = bp
        self._half = 0.5 * float(np.linalg.norm(np.diff(np.vstack((bp, bp[:1])), axis=0), axis=1).max())
        u, w = _local(self._ws[None], bp)
        self._gap = float(np.minimum(self._ws[4] - np.abs(u[:, 0]), self._ws[5] - np.abs(w[:, 0])).max()) + self._half

    def __call__(self, q, far: float = np.inf) -> np.ndarray:
        """Lower bound ``(N,)`` (or a float for ``(2,)``) on the clearance of ``q``.

        Where the clearance is at least ``far`` the bound may be any value ``>= far``.
        """
        pts, single = as_points(q, "q")
        u, w = _local(self._ws[None], pts)
        d = np.minimum(self._ws[4] - np.abs(u[:, 0]), self._ws[5] - np.abs(w[:, 0]))  # upper bound
        inside = d > 0
        inside[inside] = np.asarray(self._workspace.beta(pts[inside]), dtype=float).reshape(-1) < 0.0
        near = np.nonzero(inside & (d - self._gap < far))[0]
        if len(near):
            diff = self._samples[None, :, :] - pts[near, None, :]
            d[near] = np.sqrt(np.einsum("nkc,nkc->nk", diff, diff).min(axis=1)) - self._half
        d = np.where(inside, d, 0.0)
        if len(self._rows):
            u, w = _local(self._rows, pts)
            ex = np.maximum(np.abs(u) - self._rows[:, 4], 0.0)
            ey = np.maximum(np.abs(w) - self._rows[:, 5], 0.0)
            rect = np.sqrt(ex * ex + ey * ey)  # (N, M) lower bounds
            n, k = np.nonzero(rect < np.minimum(d, far)[:, None])
            for j in np.unique(k):
                sel = n[k == j]
                diff = self._obs_samples[j][None, :, :] - pts[sel, None, :]
                dj = np.sqrt(np.einsum("nkc,nkc->nk", diff, diff).min(axis=1)) - self._obs_half[j]
                inside = np.asarray(self._obstacles[j].beta(pts[sel]), dtype=float).reshape(-1) <= 0.0
                rect[sel, j] = np.where(inside, 0.0, np.maximum(dj, 0.0))
            d = np.minimum(d, rect.min(axis=1))
        return restore(np.maximum(d, 0.0), single)
