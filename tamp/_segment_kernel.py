"""Compiled (numba) exact segment / squircle tests of the roadmap (:func:`tamp.roadmap.segments_clear`).

For every segment ``[a_k, b_k]`` and every packed squircle row of ``P`` (the buffered obstacles)
near it, the test of :func:`tamp.roadmap._blocked`, pair by pair: ``beta`` of the squircle is
convex along the segment, so a pair whose segment misses the bounding circle (the bounding
rectangle's half-diagonal, with a 1e-9 relative margin) or is separated from the bounding
rectangle on the frame's axes or the segment's normal cannot block; an end inside blocks; a
minimum at an end (outside) does not; otherwise the minimum is bracketed on the sign of the
exact derivative, certified positive by the tangent lines at the bracket ends (their crossing
is a lower bound of the convex ``beta`` there) or found non-positive at the split point, for
at most ``steps`` bracketing steps (the split is where the derivative's chord vanishes, kept a
quarter of the bracket from either end); pairs still undecided count as blocked. Same
arithmetic as the numpy version, so the same verdicts; a segment stops being tested at its
first blocking squircle.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from navigation._geom_kernel import _arr

__all__ = ["segments_clear_rows"]

_JIT = dict(cache=True, nogil=True)


@numba.njit(inline="always", **_JIT)
def _line_beta(x0, y0, dx, dy, k, t):
    """``beta`` at parameter ``t`` of the line in the squircle's normalised frame, and its
    derivative in ``t`` (:func:`tamp.roadmap._line_beta`)."""
    x, y = x0 + t * dx, y0 + t * dy
    x2, y2 = x * x, y * y
    root = math.sqrt(max(x2 * x2 + y2 * y2 + k * x2 * y2, 0.0))
    beta = 0.5 * (x2 + y2 + root) - 1.0
    num = 4.0 * x2 * x * dx + 4.0 * y2 * y * dy + k * (2.0 * x * dx * y2 + 2.0 * x2 * y * dy)
    droot = num / (2.0 * root) if root > 0 else 0.0
    return beta, x * dx + y * dy + 0.5 * droot


@numba.njit(**_JIT)
def _pair_blocks(P, m, ax_, ay_, bx_, by_, steps):
    """Whether segment ``[(ax_, ay_), (bx_, by_)]`` is not certified to miss row ``P[m]``."""
    cx, cy, c, s = P[m, 0], P[m, 1], P[m, 2], P[m, 3]
    ex, ey = ax_ - cx, ay_ - cy
    ddx, ddy = bx_ - ax_, by_ - ay_
    x0 = (c * ex + s * ey) / P[m, 4]
    y0 = (-s * ex + c * ey) / P[m, 5]
    dx = (c * ddx + s * ddy) / P[m, 4]
    dy = (-s * ddx + c * ddy) / P[m, 5]
    k = 2.0 - 4.0 * P[m, 6] ** 2
    x1, y1 = x0 + dx, y0 + dy
    tol = 1.0 + 1e-9
    if (min(x0, x1) > tol or max(x0, x1) < -tol or min(y0, y1) > tol or max(y0, y1) < -tol
            or abs(dy * x0 - dx * y0) > tol * (abs(dx) + abs(dy))):
        return False
    f0, g0 = _line_beta(x0, y0, dx, dy, k, 0.0)
    f1, g1 = _line_beta(x0, y0, dx, dy, k, 1.0)
    if not (f0 > 0 and f1 > 0):
        return True  # an end inside the squircle
    if not (g0 < 0 and g1 > 0):
        return False  # the minimum is at an end, outside
    lo, hi, flo, glo, fhi, ghi = 0.0, 1.0, f0, g0, f1, g1
    for _ in range(steps):
        denom = ghi - glo
        tstar = min(max((flo - fhi + ghi * hi - glo * lo) / denom, lo), hi)
        if max(flo + glo * (tstar - lo), fhi + ghi * (tstar - hi)) > 0:
            return False  # certified positive on the bracket
        width = hi - lo
        mid = min(max(lo - glo * width / denom, lo + 0.25 * width), hi - 0.25 * width)
        fm, gm = _line_beta(x0, y0, dx, dy, k, mid)
        if fm <= 0:
            return True
        if gm < 0:
            lo, flo, glo = mid, fm, gm
        else:
            hi, fhi, ghi = mid, fm, gm
    return True  # undecided


@numba.njit(**_JIT)
def _clear_kernel(P, a, b, steps, out):
    M = P.shape[0]
    for k in range(a.shape[0]):
        ax_, ay_, bx_, by_ = a[k, 0], a[k, 1], b[k, 0], b[k, 1]
        dx, dy = bx_ - ax_, by_ - ay_
        dd = dx * dx + dy * dy
        clear = True
        for m in range(M):
            # near: the squircle's centre within its half-diagonal of the segment
            rx, ry = P[m, 0] - ax_, P[m, 1] - ay_
            t = (rx * dx + ry * dy) / dd if dd > 0 else 0.0
            t = min(max(t, 0.0), 1.0)
            fx, fy = rx - t * dx, ry - t * dy
            reach = math.hypot(P[m, 4], P[m, 5]) * (1.0 + 1e-9)
            if fx * fx + fy * fy > reach * reach:
                continue
            if _pair_blocks(P, m, ax_, ay_, bx_, by_, steps):
                clear = False
                break
        out[k] = clear


def segments_clear_rows(P: np.ndarray, a: np.ndarray, b: np.ndarray, steps: int) -> np.ndarray:
    """``(K,)`` True where segment ``[a_k, b_k]`` misses every squircle of ``P (M, 7)`` (see the
    module docstring; :func:`tamp.roadmap.segments_clear`)."""
    a, b = _arr(a).reshape(-1, 2), _arr(b).reshape(-1, 2)
    out = np.ones(len(a), dtype=np.bool_)
    if len(a) and len(P):
        _clear_kernel(_arr(P).reshape(-1, 7), a, b, int(steps), out)
    return out


def warm_up() -> float:
    """Compile (or load from numba's cache) the kernel (see :mod:`navigation.kernels`); returns
    the seconds it took."""
    import time

    t0 = time.perf_counter()
    P = np.array([[0.0, 0.0, 1.0, 0.0, 1.0, 0.5, 0.9]])
    segments_clear_rows(P, np.array([[-2.0, 0.1], [-2.0, 3.0]]), np.array([[2.0, 0.2], [2.0, 3.0]]), 60)
    return time.perf_counter() - t0

