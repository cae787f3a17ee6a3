"""Compiled (numba) assembly of the common-centre linear programs of the forest construction.

:func:`navigation.forest._common_centers` finds a point deep inside the intersection of a child
and its parent (or, for a child of the workspace, deep inside the child and beyond the
workspace boundary) as the Chebyshev centre of a polygon of half-planes, solved by
:func:`navigation._lp_kernel.max_min_slack`. This module builds those half-planes, row by row:

* the polygons inscribed in the squircles (``n`` boundary points at evenly spaced angles,
  counter-clockwise; unit outward edge normals ``a``, offsets ``b = a . v``), whose depth
  ``min_k (b_k - a_k . q)`` is a lower bound of the depth in the (convex) squircle;
* for a child and an inner parent: the edges of both polygons whose bounding boxes meet the box
  that contains the intersection (the others are redundant: the polygon of the intersection is
  the intersection of the half-planes of its own edges, pieces of such edges);
* for a child of the workspace: up to ``n_tangents`` tangent lines of the workspace at its
  boundary samples inside the child (evenly spread over that arc; a line is kept only where the
  normal turned by more than ``turn`` since the last kept one), each giving one program with
  the child's edges near its vertices outside the workspace and the half-plane beyond the line.

Same rules and the same row order as the numpy code it replaced (rows of inner pairs first, in
order, then the workspace children's lines); rows are padded to a common width with void
half-planes (``a = 0``, ``b = 1e200``), which the solver ignores.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from ._geom_kernel import _arr, _beta, _jet, point_xy_cs

__all__ = ["center_programs", "polygon_constraints"]

_JIT = dict(cache=True, nogil=True)


@functools.lru_cache(maxsize=8)
def _angles(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Cosines and sines of ``n`` evenly spaced angles from 0 (read-only)."""
    psi = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    c, s = np.cos(psi), np.sin(psi)
    c.flags.writeable = s.flags.writeable = False
    return c, s


@numba.njit(**_JIT)
def _polygon(P, k, cs, sn, v, a, b):
    """Vertices ``v (n, 2)``, unit outward edge normals ``a (n, 2)`` and offsets ``b (n,)`` of
    the polygon inscribed in row ``P[k]`` (edge ``j`` from vertex ``j`` to ``j + 1``)."""
    n = cs.shape[0]
    for j in range(n):
        v[j, 0], v[j, 1] = point_xy_cs(P, k, cs[j], sn[j])
    for j in range(n):
        jn = (j + 1) % n
        ax, ay = v[jn, 1] - v[j, 1], -(v[jn, 0] - v[j, 0])
        nrm = math.sqrt(ax * ax + ay * ay)
        ax, ay = ax / nrm, ay / nrm
        a[j, 0], a[j, 1] = ax, ay
        b[j] = ax * v[j, 0] + ay * v[j, 1]


def polygon_constraints(P: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Half-planes ``a . q <= b`` of the polygons inscribed in the squircles ``P (K, 7)``:
    ``(a (K, n, 2), b (K, n), vertices (K, n, 2))`` (see the module docstring)."""
    P = _arr(P).reshape(-1, 7)
    cs, sn = _angles(int(n))
    v, a, b = np.empty((len(P), n, 2)), np.empty((len(P), n, 2)), np.empty((len(P), n))
    for k in range(len(P)):
        _polygon(P, k, cs, sn, v[k], a[k], b[k])
    return a, b, v


@numba.njit(inline="always", **_JIT)
def _near(v, j, lox, loy, hix, hiy):
    """Whether the bounding box of edge ``j`` of the polygon ``v`` meets the box ``[lo, hi]``."""
    n = v.shape[0]
    jn = (j + 1) % n
    return (min(v[j, 0], v[jn, 0]) <= hix and min(v[j, 1], v[jn, 1]) <= hiy
            and max(v[j, 0], v[jn, 0]) >= lox and max(v[j, 1], v[jn, 1]) >= loy)


@numba.njit(inline="always", **_JIT)
def _round_half_even(x):
    """``numpy.round`` of a non-negative float (ties to even)."""
    f = math.floor(x)
    d = x - f
    if d > 0.5 or (d == 0.5 and f % 2.0 == 1.0):
        return int(f) + 1
    return int(f)


@numba.njit(**_JIT)
def _tangent_lines(PI, rows, ws_row, ws_pts, ws_psi, n_tangents, cos_turn, owner, la, lb):
    """Tangent half-planes ``la . q <= lb`` beyond the workspace boundary for the workspace
    children ``rows`` of ``PI``: at most ``n_tangents`` per child, written from index 0 of
    ``owner`` / ``la`` / ``lb``; returns their count."""
    nw = ws_pts.shape[0]
    count = 0
    inside = np.empty(nw, np.int64)
    for r in range(rows.shape[0]):
        e = rows[r]
        m = 0
        best, kbest = math.inf, 0
        for j in range(nw):
            val = _beta(PI, e, ws_pts[j, 0], ws_pts[j, 1])
            if val < 0.0:  # one arc: the child crosses the boundary once
                inside[m] = j
                m += 1
            if val < best:
                best, kbest = val, j
        if m == 0:
            inside[0] = kbest
            m = 1
        c = min(n_tangents, m)
        last_pick, last_kept = -1, -1
        for i in range(c):
            pos = m - 1 if i == c - 1 else _round_half_even(i * ((m - 1) / (c - 1)) if c > 1 else 0.0)
            pick = inside[pos]
            if pick == last_pick:  # numpy.unique of the (sorted) picks
                continue
            last_pick = pick
            px, py, dx, dy, _, _ = _jet(ws_row, ws_psi[pick])
            nrm = math.sqrt(dx * dx + dy * dy)
            nx, ny = dy / nrm, -dx / nrm
            if last_kept >= 0 and not (nx * -la[last_kept, 0] + ny * -la[last_kept, 1] < cos_turn):
                continue  # the normal turned by less than the threshold since the last kept line
            owner[count] = e
            la[count, 0], la[count, 1] = -nx, -ny
            lb[count] = -(nx * px + ny * py)
            last_kept = count
            count += 1
    return count


@numba.njit(**_JIT)
def _programs(PI, PJ, outside, ws_row, ws_pts, ws_psi, cs, sn, n_tangents, cos_turn):
    E = PI.shape[0]
    n = cs.shape[0]
    vI = np.empty((E, n, 2))
    aI = np.empty((E, n, 2))
    bI = np.empty((E, n))
    vJ = np.empty((E, n, 2))
    aJ = np.empty((E, n, 2))
    bJ = np.empty((E, n))
    for e in range(E):
        _polygon(PI, e, cs, sn, vI[e], aI[e], bI[e])
        if not outside[e]:
            _polygon(PJ, e, cs, sn, vJ[e], aJ[e], bJ[e])
    ws_rows = np.nonzero(outside)[0]
    lowner = np.empty(E * n_tangents, np.int64)
    la = np.empty((E * n_tangents, 2))
    lb = np.empty(E * n_tangents)
    nl = 0
    if ws_rows.shape[0] > 0:
        nl = _tangent_lines(PI, ws_rows, ws_row, ws_pts, ws_psi, n_tangents, cos_turn, lowner, la, lb)
    inner = np.nonzero(~outside)[0]
    R = inner.shape[0] + nl
    A = np.zeros((R, 2 * n + 1, 2))
    B = np.full((R, 2 * n + 1), 1e200)
    LO = np.empty((R, 2))
    HI = np.empty((R, 2))
    L = np.empty(R)
    owner = np.empty(R, np.int64)
    width = 1
    W = ws_row.reshape(1, 7)
    for r in range(inner.shape[0]):
        e = inner[r]
        lox = max(vI[e, :, 0].min(), vJ[e, :, 0].min())
        loy = max(vI[e, :, 1].min(), vJ[e, :, 1].min())
        hix = max(min(vI[e, :, 0].max(), vJ[e, :, 0].max()), lox)
        hiy = max(min(vI[e, :, 1].max(), vJ[e, :, 1].max()), loy)
        w = 0
        for j in range(n):
            if _near(vI[e], j, lox, loy, hix, hiy):
                A[r, w, 0], A[r, w, 1], B[r, w] = aI[e, j, 0], aI[e, j, 1], bI[e, j]
                w += 1
        for j in range(n):
            if _near(vJ[e], j, lox, loy, hix, hiy):
                A[r, w, 0], A[r, w, 1], B[r, w] = aJ[e, j, 0], aJ[e, j, 1], bJ[e, j]
                w += 1
        width = max(width, w)
        LO[r, 0], LO[r, 1], HI[r, 0], HI[r, 1] = lox, loy, hix, hiy
        L[r] = min(PI[e, 4], PI[e, 5], PJ[e, 4], PJ[e, 5])
        owner[r] = e
    out_w = np.empty(n, np.bool_)
    r = inner.shape[0]
    t = 0
    while t < nl:
        e = lowner[t]
        # the child's vertices outside the workspace and their neighbours span the box
        for j in range(n):
            out_w[j] = _beta(W, 0, vI[e, j, 0], vI[e, j, 1]) >= 0.0
        lox, loy, hix, hiy = math.inf, math.inf, -math.inf, -math.inf
        anyo = False
        for j in range(n):
            if out_w[j] or out_w[(j - 1) % n] or out_w[(j + 1) % n]:
                anyo = True
                lox, loy = min(lox, vI[e, j, 0]), min(loy, vI[e, j, 1])
                hix, hiy = max(hix, vI[e, j, 0]), max(hiy, vI[e, j, 1])
        if not anyo:
            lox, loy = vI[e, :, 0].min(), vI[e, :, 1].min()
            hix, hiy = vI[e, :, 0].max(), vI[e, :, 1].max()
        w0 = 0
        for j in range(n):
            if _near(vI[e], j, lox, loy, hix, hiy):
                A[r, w0, 0], A[r, w0, 1], B[r, w0] = aI[e, j, 0], aI[e, j, 1], bI[e, j]
                w0 += 1
        first = r
        while t < nl and lowner[t] == e:  # one program per tangent line of this child
            if r > first:
                A[r, :w0] = A[first, :w0]
                B[r, :w0] = B[first, :w0]
            A[r, w0, 0], A[r, w0, 1], B[r, w0] = la[t, 0], la[t, 1], lb[t]
            LO[r, 0], LO[r, 1], HI[r, 0], HI[r, 1] = lox, loy, hix, hiy
            L[r] = min(PI[e, 4], PI[e, 5])
            owner[r] = e
            width = max(width, w0 + 1)
            r += 1
            t += 1
    return A[:, :width].copy(), B[:, :width].copy(), LO, HI, L, owner


def center_programs(PI: np.ndarray, PJ: np.ndarray, outside: np.ndarray, ws_row: np.ndarray | None,
                    ws_pts: np.ndarray | None, ws_psi: np.ndarray | None, *, n: int, n_tangents: int,
                    turn: float):
    """The common-centre linear programs of the pairs ``(PI[e], PJ[e])`` (packed rows; where
    ``outside[e]``, ``PJ[e]`` is the workspace ``ws_row`` with boundary samples ``ws_pts`` at
    angles ``ws_psi``): ``(A (R, W, 2), B (R, W), LO (R, 2), HI (R, 2), L (R,), owner (R,))``,
    half-planes ``A[r] . q <= B[r]`` of program ``r`` for pair ``owner[r]``, its start box and
    scale (the inputs of :func:`navigation._lp_kernel.max_min_slack`)."""
    PI = _arr(PI).reshape(-1, 7)
    PJ = _arr(PJ).reshape(-1, 7)
    outside = _arr(outside, np.bool_)
    if ws_row is None:
        ws_row, ws_pts, ws_psi = np.zeros(7), np.zeros((0, 2)), np.zeros(0)
    cs, sn = _angles(int(n))
    return _programs(PI, PJ, outside, _arr(ws_row), _arr(ws_pts), _arr(ws_psi), cs, sn, int(n_tangents),
                     math.cos(turn))
