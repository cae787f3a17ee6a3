"""Compiled Chebyshev-centre solver for the common centres of the forest (paper 001, section 4.1.2).

:func:`max_min_slack` maximises ``t(q) = min_k (b_k - a_k . q)`` per row: the centre ``q`` of
the largest disc inside a polygon of half-planes ``a_k . q <= b_k`` (``a_k`` unit normals), a
3-variable linear program. It is the numba port of :func:`navigation.forest._max_min_slack`,
used by :func:`navigation.forest._common_centers` and :func:`navigation.forest._thin_centers`
(the common centre ``p_i in O_i ∩ O_i*`` of a child and its parent, ``shared/notes/
navigation-math.md``, "Forest of stars"), and runs the same algorithm with the same constants:

1. start at the best point of a ``grid x grid`` grid over the box ``[lo, hi]``;
2. Newton steps on the soft minimum ``t_tau = -tau log sum_k exp(-s_k / tau)`` of the slacks
   ``s_k = b_k - a_k . q`` (concave, ``t - tau log K <= t_tau <= t``; gradient
   ``-sum_k w_k a_k``, Hessian ``-Cov_w(a) / tau``, ``w`` the soft-min weights), limited to a
   trust radius (``min(scale, 64 tau)`` at the start of a stage, doubled up to ``scale`` after
   a full step, the accepted length after backtracking), halved up to 30 times until ``t_tau``
   does not decrease;
3. ``tau`` goes from ``0.05 scale`` down by 8x per stage (``stages`` stages of at most ``steps``
   steps); a row leaves a stage when its Newton step is below ``1e-6 scale``;
4. the returned ``t`` is the exact ``min_k`` slack at the returned point.

Each row is solved on its own, in plain loops. Padded half-planes (``a = 0``, ``b >= 1e100``, as
the forest pads rows to a common width with ``b = 1e200``) have soft-min weight exactly 0 and are
skipped. Results agree with the numpy function to rounding while the iteration paths agree;
numpy's vectorised ``exp`` and pairwise sums round differently from these loops, so an
acceptance test ``t_tau(new) >= t_tau(old)`` decided by a rounding error can take a different
path, to a point equally close to the optimum (about ``1e-4 scale`` with the defaults).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._geom_kernel import _arr

__all__ = ["max_min_slack"]

_PAD = 1e100  #: a half-plane with ``a = 0`` and ``b`` at least this is padding (weight 0)


@numba.njit(cache=True)
def _soft_min_row(ax, ay, b, n, qx, qy, tau, w):
    """Soft minimum of the first ``n`` slacks ``b - a . q`` at ``q = (qx, qy)``; writes the
    weights (the soft-min's gradient with respect to the slacks) into ``w`` and returns
    ``(soft minimum, exact minimum)``."""
    m = np.inf
    for k in range(n):
        s = b[k] - ax[k] * qx - ay[k] * qy
        w[k] = s
        if s < m:
            m = s
    zs = 0.0
    for k in range(n):
        d = -(w[k] - m) / tau
        # weights below exp(-50) ~ 2e-22 (relative to the largest, 1) are dropped: they cannot
        # change the sum ``zs >= 1`` nor, above rounding, the weighted moments; exp is the
        # kernel's main cost and most half-planes are far from the minimum after the first stage
        z = math.exp(d) if d > -50.0 else 0.0
        w[k] = z
        zs += z
    for k in range(n):
        w[k] = w[k] / zs
    return m - tau * math.log(zs), m


@numba.njit(cache=True)
def _min_slack_row(ax, ay, b, n, qx, qy):
    """Exact minimum of the first ``n`` slacks ``b - a . q`` at ``q = (qx, qy)``."""
    m = np.inf
    for k in range(n):
        s = b[k] - ax[k] * qx - ay[k] * qy
        if s < m:
            m = s
    return m


@numba.njit(cache=True)
def _max_min_slack_rows(a, b, lo, hi, scale, stages, steps, grid, points, t):
    """Solve every row of ``a (E, K, 2)``, ``b (E, K)``, ``lo, hi (E, 2)``, ``scale (E,)``;
    writes ``points (E, 2)`` and ``t (E,)``."""
    E, K = b.shape
    ax = np.empty(K)
    ay = np.empty(K)
    bb = np.empty(K)
    w = np.empty(K)
    wt = np.empty(K)
    for e in range(E):
        # the half-planes with a nonzero weight, in order (all of them if all are padding)
        n = 0
        for k in range(K):
            if a[e, k, 0] == 0.0 and a[e, k, 1] == 0.0 and b[e, k] >= _PAD:
                continue
            ax[n] = a[e, k, 0]
            ay[n] = a[e, k, 1]
            bb[n] = b[e, k]
            n += 1
        if n == 0:
            for k in range(K):
                ax[k] = a[e, k, 0]
                ay[k] = a[e, k, 1]
                bb[k] = b[e, k]
            n = K
        sc = scale[e]
        # start: the best point of the grid (the first one on ties)
        cx = lo[e, 0] + (hi[e, 0] - lo[e, 0]) * (0.5 / grid)
        cy = lo[e, 1] + (hi[e, 1] - lo[e, 1]) * (0.5 / grid)
        best = -np.inf
        for i in range(grid):
            px = lo[e, 0] + (hi[e, 0] - lo[e, 0]) * ((i + 0.5) / grid)
            for j in range(grid):
                py = lo[e, 1] + (hi[e, 1] - lo[e, 1]) * ((j + 0.5) / grid)
                tt = _min_slack_row(ax, ay, bb, n, px, py)
                if tt > best:
                    best, cx, cy = tt, px, py
        tau = 0.05 * sc
        for _ in range(stages):
            radius = min(sc, 64.0 * tau)
            f, _m = _soft_min_row(ax, ay, bb, n, cx, cy, tau, w)
            for _ in range(steps):
                m0 = m1 = m2 = m3 = m4 = 0.0
                for k in range(n):
                    m0 += w[k] * ax[k]
                    m1 += w[k] * ay[k]
                    m2 += w[k] * (ax[k] * ax[k])
                    m3 += w[k] * (ax[k] * ay[k])
                    m4 += w[k] * (ay[k] * ay[k])
                gx, gy = -m0, -m1
                cxx = m2 - gx * gx + 1e-12
                cxy = m3 - gx * gy
                cyy = m4 - gy * gy + 1e-12
                fac = tau / (cxx * cyy - cxy * cxy)
                sx = fac * (cyy * gx - cxy * gy)
                sy = fac * (cxx * gy - cxy * gx)
                length = math.hypot(sx, sy)
                if not length > 1e-6 * sc:
                    break  # this row leaves the stage
                r = min(1.0, radius / length)
                sx, sy = sx * r, sy * r
                full = True
                for _ in range(30):  # backtracking
                    ft, _m = _soft_min_row(ax, ay, bb, n, cx + sx, cy + sy, tau, wt)
                    if ft >= f:
                        cx += sx
                        cy += sy
                        f = ft
                        w, wt = wt, w
                        radius = min(2.0 * radius, sc) if full else math.hypot(sx, sy)
                        break
                    sx, sy = 0.5 * sx, 0.5 * sy
                    full = False
            tau = 0.125 * tau
        points[e, 0] = cx
        points[e, 1] = cy
        t[e] = _min_slack_row(ax, ay, bb, n, cx, cy)


def max_min_slack(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, scale: np.ndarray, *,
                  stages: int = 4, steps: int = 10, grid: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Maximise ``t(q) = min_k (b_k - a_k . q)`` per row: the Chebyshev centre of the polygon of
    half-planes ``a (E, K, 2)`` (unit normals; padding ``a = 0``, ``b = 1e200``), ``b (E, K)``,
    started on a ``grid x grid`` grid over the box ``[lo, hi]`` (``(E, 2)``), with step scale
    ``scale (E,)``. Same algorithm and results as :func:`navigation.forest._max_min_slack`
    (see the module docstring). Returns the points ``(E, 2)`` and their exact ``t (E,)``.
    """
    a = _arr(a)
    b = _arr(b)
    lo = _arr(lo)
    hi = _arr(hi)
    scale = _arr(scale)
    E = len(a)
    if E == 0:
        return np.empty((0, 2)), np.empty(0)
    if b.shape[1] == 0:
        raise ValueError("max_min_slack: every row needs at least one half-plane, got b of shape "
                         f"{b.shape}")
    if grid < 1:
        raise ValueError(f"max_min_slack: grid must be at least 1, got {grid}")
    points = np.empty((E, 2))
    t = np.empty(E)
    _max_min_slack_rows(a, b, lo, hi, scale, int(stages), int(steps), int(grid), points, t)
    return points, t
