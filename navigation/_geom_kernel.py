"""Compiled (numba) kernels of squircle geometry used by the forest construction.

Each kernel runs, row by row, the same algorithm as the numpy function it mirrors in
:mod:`navigation.geometry` or :mod:`navigation.forest`, without numpy's per-call overhead on
small arrays (the forest construction calls these on a few dozen rows at a time):

* :func:`point_xy`: a boundary point of a packed squircle row (the parametrisation of
  :meth:`~navigation.geometry.Squircle.point_at`, :func:`~navigation.geometry.point_at_rows`);
* :func:`signed_distance_rows`: :func:`navigation.geometry.signed_distance_rows` (exact
  point-to-squircle distances: sampled candidates bracketing every local minimum, narrowed by
  nested sampling and polished by Newton steps);
* :func:`ray_length_rows`: :func:`navigation.geometry.ray_length_packed` (exact ray lengths,
  paper 001 eq. 15-16: monotone Newton on the gauge ``sqrt(beta + 1)``);
* :func:`far_gap_rows`: :func:`navigation.forest._far_gaps` (the room beyond a workspace child
  along the rays from its common centre);
* :func:`gap_bound_rows`: :func:`navigation.forest._gap_bound_rows` (lower bounds of the
  distance between two squircles from their bounding rectangles and discs);
* :func:`wall_bound_rows`: :func:`navigation.forest._wall_bounds` (lower bounds of the distance
  from a squircle to the workspace boundary from its bounding rectangle and an inscribed
  polygon);
* :func:`nearest_sample_distance`: the sampled distances of
  :meth:`~navigation.geometry.ExactDistance.sampled` (clearance bounds);
* :func:`boundary_points`, :func:`offset_points`, :func:`beta_gradient`:
  :meth:`~navigation.geometry.Squircle.boundary_points`, :meth:`~navigation.geometry.Squircle.offset_points`
  and :meth:`~navigation.geometry.Squircle.gradient` (arc-length-even boundary samples, the
  offset curve :meth:`~navigation.geometry.Squircle.grow` tests, the exact gradient of the
  jets of :func:`~navigation.geometry.beta_jet`), bit for bit: the operations of the numpy code
  in its order, its cosines and sines computed by numpy.

Packed rows are ``(cx, cy, cos theta, sin theta, half width, half height, s)``
(:func:`navigation.geometry.pack`). Every row is computed independently of the others in its
batch. Results agree with the numpy functions to rounding (tested in
``tests/test_geom_kernel.py``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["point_xy", "point_xy_cs", "beta_rows", "beta_derivatives_xy", "beta_derivatives_rows", "root_partials", "root_partials_rows", "boundary_jet", "signed_distance_rows", "ray_length_rows", "far_gap_rows", "gap_bound_rows", "wall_bound_rows", "sample_table", "boundary_points", "offset_points", "beta_gradient", "refine_brackets"]

_JIT = dict(cache=True, nogil=True)


def _arr(x, dtype=float) -> np.ndarray:
    """``x`` as a C-contiguous, writeable array of ``dtype`` (numba compiles read-only arrays as
    another type: one signature per kernel instead of two)."""
    x = np.ascontiguousarray(x, dtype=dtype)
    return x if x.flags.writeable else x.copy()


@numba.njit(inline="always", **_JIT)
def point_xy(P, k, psi):
    """Boundary point ``(x, y)`` of row ``P[k]`` at the boundary angle ``psi``."""
    return point_xy_cs(P, k, math.cos(psi), math.sin(psi))


@numba.njit(inline="always", **_JIT)
def point_xy_cs(P, k, ux, uy):
    """Boundary point ``(x, y)`` of row ``P[k]`` at the boundary angle with cosine ``ux`` and
    sine ``uy``."""
    m = ux * uy
    s = P[k, 6]
    rho = math.sqrt(2.0 / (1.0 + math.sqrt(max(1.0 - 4.0 * s * s * m * m, 0.0))))
    lx = rho * ux * P[k, 4]
    ly = rho * uy * P[k, 5]
    c, sn = P[k, 2], P[k, 3]
    return P[k, 0] + c * lx - sn * ly, P[k, 1] + sn * lx + c * ly


@numba.njit(inline="always", **_JIT)
def _beta(P, k, qx, qy):
    """Obstacle function of row ``P[k]`` at ``(qx, qy)``."""
    dx, dy = qx - P[k, 0], qy - P[k, 1]
    c, sn = P[k, 2], P[k, 3]
    x = (dx * c + dy * sn) / P[k, 4]
    y = (dy * c - dx * sn) / P[k, 5]
    x2, y2 = x * x, y * y
    s = P[k, 6]
    return 0.5 * (x2 + y2 + math.sqrt(x2 * x2 + y2 * y2 + (2.0 - 4.0 * s * s) * x2 * y2)) - 1.0


@numba.njit(inline="always", **_JIT)
def _jet(p, psi):
    """Boundary point of row ``p (7,)`` at ``psi`` and its first and second ``psi`` derivatives,
    as six floats ``x, y, x', y', x'', y''`` (:func:`navigation.geometry.boundary_jet_rows`)."""
    cs = math.cos(psi)
    sn = math.sin(psi)
    m = cs * sn
    m1 = cs * cs - sn * sn
    m2 = -4.0 * cs * sn
    k = 4.0 * p[6] * p[6]
    h = 1.0 - k * m * m
    if not h >= 1e-300:  # np.maximum(h, 1e-300)
        h = h if h != h else 1e-300
    h1 = -2.0 * k * m * m1
    h2 = -2.0 * k * (m1 * m1 + m * m2)
    g = math.sqrt(h)
    g1 = h1 / (2.0 * g)
    g2 = (h2 - 2.0 * g1 * g1) / (2.0 * g)
    u = 1.0 + g
    r = math.sqrt(2.0 / u)
    r1 = -0.5 * r * g1 / u
    r2 = 0.75 * r * g1 * g1 / (u * u) - 0.5 * r * g2 / u
    lx0 = r * cs
    lx1 = r1 * cs - r * sn
    lx2 = r2 * cs - 2.0 * r1 * sn - r * cs
    ly0 = r * sn
    ly1 = r1 * sn + r * cs
    ly2 = r2 * sn + 2.0 * r1 * cs - r * sn
    c = p[2]
    s_ = p[3]
    hw = p[4]
    hh = p[5]
    x = hw * lx0
    y = hh * ly0
    px = c * x - s_ * y + p[0]
    py = s_ * x + c * y + p[1]
    x = hw * lx1
    y = hh * ly1
    px1 = c * x - s_ * y
    py1 = s_ * x + c * y
    x = hw * lx2
    y = hh * ly2
    px2 = c * x - s_ * y
    py2 = s_ * x + c * y
    return px, py, px1, py1, px2, py2


@numba.njit(**_JIT)
def _jet_kernel(P, psi, out):
    for k in range(psi.shape[0]):
        out[0, k], out[1, k], out[2, k], out[3, k], out[4, k], out[5, k] = _jet(P[k], psi[k])


def boundary_jet(P: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Boundary points of rows ``P (K, 7)`` at angles ``psi (K,)`` and their first and second
    ``psi`` derivatives: ``(6, K)`` rows ``x, y, x', y', x'', y''``
    (:func:`navigation.geometry.boundary_jet_rows`)."""
    P = _arr(P).reshape(-1, 7)
    psi = _arr(psi).reshape(-1)
    out = np.empty((6, len(psi)))
    if len(psi):
        _jet_kernel(P, psi, out)
    return out


@numba.njit(**_JIT)
def _fine_kernel(n):
    F = 8 * n + 1
    step = 2.0 * math.pi / (F - 1)
    fine, fc, fs = np.empty(F), np.empty(F), np.empty(F)
    for i in range(F):  # numpy.linspace(0, 2 pi, F): i * step, the last exactly 2 pi
        fine[i] = i * step if i < F - 1 else 2.0 * math.pi
        fc[i], fs[i] = math.cos(fine[i]), math.sin(fine[i])  # (point_xy's cosine and sine)
    return fine, fc, fs


_FINE_TABLE: dict = {}  # n -> the fine grid of _sample_table_kernel, its cosines and sines


def _fine_grid(n: int):
    hit = _FINE_TABLE.get(n)
    if hit is None:
        if len(_FINE_TABLE) >= 32:
            _FINE_TABLE.clear()
        hit = _FINE_TABLE[n] = _fine_kernel(n)
    return hit


@numba.njit(**_JIT)
def _sample_table_kernel(P, n, sub, psi, pts, fine, fc, fs):
    F = 8 * n + 1
    arc = np.empty(F)
    arc[0] = 0.0
    px, py = point_xy_cs(P, 0, fc[0], fs[0])  # point_xy(P, 0, fine[i]), the trigonometry cached
    for i in range(1, F):
        x, y = point_xy_cs(P, 0, fc[i], fs[i])
        arc[i] = arc[i - 1] + math.sqrt((x - px) ** 2 + (y - py) ** 2)
        px, py = x, y
    total = arc[F - 1]
    j = 0
    for t in range(n):  # numpy.interp of numpy.linspace(0, total, n, endpoint=False)
        target = t * (total / n)
        while j + 1 < F - 1 and arc[j + 1] <= target:
            j += 1
        slope = (fine[j + 1] - fine[j]) / (arc[j + 1] - arc[j])
        psi[t] = slope * (target - arc[j]) + fine[j] if arc[j + 1] != arc[j] else fine[j]
        pts[t, 0], pts[t, 1] = point_xy(P, 0, psi[t])
    # the largest arc between consecutive samples, on sub chords each (numpy's pairwise sum of
    # the sub chord lengths when sub = 16: eight partial sums, then a tree)
    best = -math.inf
    seg = np.empty(sub)
    for t in range(n):
        a = psi[t]
        b = psi[t + 1] if t + 1 < n else psi[0] + 2.0 * math.pi
        qx, qy = pts[t, 0], pts[t, 1]  # point_xy(P, 0, a + (b - a) * 0.0): a + 0.0 is a (a >= 0)
        for u in range(1, sub + 1):
            frac = u * (1.0 / sub) if u < sub else 1.0
            x, y = point_xy(P, 0, a + (b - a) * frac)
            seg[u - 1] = math.sqrt((x - qx) ** 2 + (y - qy) ** 2)
            qx, qy = x, y
        if sub == 16:
            r0, r1, r2, r3 = seg[0] + seg[8], seg[1] + seg[9], seg[2] + seg[10], seg[3] + seg[11]
            r4, r5, r6, r7 = seg[4] + seg[12], seg[5] + seg[13], seg[6] + seg[14], seg[7] + seg[15]
            s = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        else:
            s = 0.0
            for u in range(sub):
                s += seg[u]
        best = max(best, s)
    return best * (1.0 + 1e-6)


def sample_table(row: np.ndarray, n: int, sub: int = 16) -> tuple[np.ndarray, np.ndarray, float]:
    """``n`` arc-length-even boundary angles of the squircle ``row (7,)`` (arc length on ``8 n``
    chords, inverted by linear interpolation), their points and the largest arc between
    consecutive samples (measured on ``sub`` chords, times ``1 + 1e-6``):
    :func:`navigation.geometry._sample_table`."""
    P = _arr(row).reshape(1, 7)
    psi, pts = np.empty(n), np.empty((n, 2))
    arc = _sample_table_kernel(P, int(n), int(sub), psi, pts, *_fine_grid(int(n)))
    return psi, pts, float(arc)


@numba.njit(**_JIT)
def _nearest_sample_kernel(pts_g, g, q, out):
    for k in range(len(g)):
        P = pts_g[g[k]]
        qx, qy = q[k, 0], q[k, 1]
        best = np.inf
        for s in range(P.shape[0]):
            dx = P[s, 0] - qx
            dy = P[s, 1] - qy
            v = dx * dx + dy * dy
            if v < best:
                best = v
            elif v != v:  # numpy's min propagates NaN
                best = v
                break
        out[k] = math.sqrt(best)


def nearest_sample_distance(pts_g: np.ndarray, g: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Distances ``(K,)`` of the points ``q (K, 2)`` to the nearest of the boundary samples
    ``pts_g[g[k]] (n, 2)``: ``sqrt(((pts_g[g] - q[:, None]) ** 2).sum(-1).min(1))`` bit for bit
    (:meth:`navigation.geometry.ExactDistance.sampled`), without its ``(K, n, 2)`` temporaries
    (a clearance query near the workspace boundary gathers thousands of its samples per point)."""
    out = np.empty(len(g))
    _nearest_sample_kernel(_arr(pts_g), _arr(g, np.intp), _arr(q), out)
    return out


@numba.njit(**_JIT)
def points_into(out, ux, uy, cx, cy, hw, hh, c, sn, s2):
    """:meth:`navigation.geometry.Squircle.point_at` of the squircle with centre ``(cx, cy)``,
    half sizes ``hw, hh``, rotation cosine/sine ``c, sn`` at the angles with cosines ``ux`` and
    sines ``uy`` into ``out``, with ``s^2`` given (``s2``: ``point_at`` squares ``s`` with
    Python's ``**``, i.e. ``pow``, for about 0.1 % of the values of ``s`` one unit in the last
    place from ``s * s``) and the operations in ``point_at``'s order."""
    for i in range(len(ux)):
        m = ux[i] * uy[i]
        rho = math.sqrt(2.0 / (1.0 + math.sqrt(max(1.0 - 4.0 * s2 * m * m, 0.0))))
        lx = rho * ux[i] * hw
        ly = rho * uy[i] * hh
        out[i, 0] = cx + c * lx - sn * ly
        out[i, 1] = cy + sn * lx + c * ly


@numba.njit(**_JIT)
def _points_cs(P, s2, ux, uy, out):
    """:func:`points_into` for the squircle of row ``P[0]``."""
    points_into(out, ux, uy, P[0, 0], P[0, 1], P[0, 4], P[0, 5], P[0, 2], P[0, 3], s2)


@numba.njit(**_JIT)
def _arc_psi_kernel(P, s2, fine, fc, fs, n):
    """The angles of ``Squircle.boundary_points`` (up to its final ``point_at``) of row ``P[0]``:
    :func:`arc_inverse` over the boundary points of the ``fine`` grid (cosines ``fc``, sines
    ``fs``)."""
    pts = np.empty((len(fine), 2))
    _points_cs(P, s2, fc, fs, pts)
    return arc_inverse(pts, fine, n)


@numba.njit(**_JIT)
def arc_inverse(pts, fine, n):
    """Angles of ``n`` points evenly spaced in arc length along the polyline ``pts (F, 2)``
    sampled at the angles ``fine (F,)``: arc length as ``concatenate(([0],
    cumsum(norm(diff(pts)))))``, inverted at ``linspace(0, arc[-1], n, endpoint=False)`` as
    ``np.interp`` does, operation for operation (``Squircle.boundary_points``; perception's
    compiled twin uses it too)."""
    F = len(fine)
    arc = np.empty(F)
    arc[0] = 0.0
    for k in range(1, F):
        dx = pts[k, 0] - pts[k - 1, 0]
        dy = pts[k, 1] - pts[k - 1, 1]
        seg = math.sqrt(dx * dx + dy * dy)
        arc[k] = seg if k == 1 else arc[k - 1] + seg
    last = arc[F - 1]
    step = last / n
    psi = np.empty(n)
    j = 0
    for i in range(n):
        if step == 0.0:  # np.linspace's branch for a zero step
            x = (i / n) * last + 0.0
        else:
            x = i * step + 0.0
        if math.isnan(x):
            psi[i] = x
            continue
        if x < arc[0]:  # np.interp outside the samples
            psi[i] = fine[0]
            continue
        if x > arc[F - 1]:
            psi[i] = fine[F - 1]
            continue
        while j + 1 < F and arc[j + 1] <= x:  # the last sample <= x (the targets increase)
            j += 1
        if j == F - 1:
            psi[i] = fine[j]
        elif arc[j] == x:
            psi[i] = fine[j]
        else:
            slope = (fine[j + 1] - fine[j]) / (arc[j + 1] - arc[j])
            r = slope * (x - arc[j]) + fine[j]
            if math.isnan(r):
                r = slope * (x - arc[j + 1]) + fine[j + 1]
                if math.isnan(r) and fine[j] == fine[j + 1]:
                    r = fine[j]
            psi[i] = r
    return psi


_FINE: dict = {}  # n -> the fine grid of boundary_points and numpy's cosines and sines of it


def boundary_points(row: np.ndarray, s2: float, n: int) -> np.ndarray:
    """:meth:`navigation.geometry.Squircle.boundary_points` of the squircle ``row (7,)`` (``s2``:
    its ``s ** 2`` as Python forms it), bit for bit. The cosines and sines stay numpy's (those of
    the fine grid depend only on ``n`` and are cached; those of the interpolated angles are
    numpy's between the two kernels), as in :func:`perception._shape_kernel.boundary_points`."""
    n = int(n)
    hit = _FINE.get(n)
    if hit is None:
        if len(_FINE) >= 32:
            _FINE.clear()
        fine = np.linspace(0.0, 2 * np.pi, 8 * n + 1)
        hit = _FINE[n] = (fine, np.cos(fine), np.sin(fine))
    P = _arr(row).reshape(1, 7)
    psi = _arc_psi_kernel(P, float(s2), hit[0], hit[1], hit[2], n)
    out = np.empty((n, 2))
    _points_cs(P, float(s2), np.cos(psi), np.sin(psi), out)
    return out


@numba.njit(inline="always", **_JIT)
def _beta_grad(P, k4, px, py):
    """The gradient of ``beta`` of row ``P[0]`` at ``(px, py)`` as :func:`navigation.geometry.beta_jet`
    computes it at order 1 (``k4 = 4 s^2`` as it forms it), column by column of its jets."""
    cx, cy, c, s, hw, hh = P[0, 0], P[0, 1], P[0, 2], P[0, 3], P[0, 4], P[0, 5]
    ihw, ihh = 1.0 / hw, 1.0 / hh
    dxv, dyv = px - cx, py - cy
    # the normalised coordinates (value, d/dx, d/dy)
    u0, u1, u2 = (dxv * c + dyv * s) * ihw, (1.0 * c + 0.0 * s) * ihw, (0.0 * c + 1.0 * s) * ihw
    w0, w1, w2 = (dyv * c - dxv * s) * ihh, (0.0 * c - 1.0 * s) * ihh, (1.0 * c - 0.0 * s) * ihh
    du, dw = 2.0 * u0, 2.0 * w0
    U0, U1, U2 = u0 * u0, u1 * du, u2 * du  # u.square()
    W0, W1, W2 = w0 * w0, w1 * dw, w2 * dw
    R0, R1, R2 = U0 + W0, U1 + W1, U2 + W2  # r2
    dr = 2.0 * R0
    D0 = R0 * R0 - (U0 * W0) * k4  # r2.square() - (u2 * w2) * k4
    D1 = R1 * dr - (U1 * W0 + U0 * W1) * k4
    D2 = R2 * dr - (U2 * W0 + U0 * W2) * k4
    if D0 < 1e-200:  # at the centre: the root's jet is r2's
        Q1, Q2 = R1, R2
    else:
        d1 = 0.5 / math.sqrt(D0)
        Q1, Q2 = D1 * d1, D2 * d1
    return (R1 + Q1) * 0.5, (R2 + Q2) * 0.5


@numba.njit(error_model="numpy", **_JIT)  # 0 / 0 at a centre is NaN, as in numpy
def _offset_kernel(P, k4, pts, r, out):
    for t in range(pts.shape[0]):
        px, py = pts[t, 0], pts[t, 1]
        gx, gy = _beta_grad(P, k4, px, py)
        # b + r g / |g|
        nrm = math.sqrt(gx * gx + gy * gy)
        out[t, 0] = px + (r * gx) / nrm
        out[t, 1] = py + (r * gy) / nrm


@numba.njit(error_model="numpy", **_JIT)
def _gradient_kernel(P, k4, pts, out):
    for t in range(pts.shape[0]):
        out[t, 0], out[t, 1] = _beta_grad(P, k4, pts[t, 0], pts[t, 1])


def beta_gradient(row: np.ndarray, k4: float, pts: np.ndarray) -> np.ndarray:
    """The exact gradient ``(N, 2)`` of ``beta`` of the squircle ``row (7,)`` at ``pts (N, 2)``:
    :meth:`navigation.geometry.Squircle.gradient` (``beta_jet`` at order 1, ``k4 = 4 s^2`` as it
    forms it), the same operations in the same order."""
    pts = _arr(pts).reshape(-1, 2)
    out = np.empty_like(pts)
    _gradient_kernel(_arr(row).reshape(1, 7), float(k4), pts, out)
    return out


def offset_points(row: np.ndarray, k4: float, pts: np.ndarray, r: float) -> np.ndarray:
    """The points ``pts (n, 2)`` moved ``r`` along the unit gradient of ``beta`` of the squircle
    ``row (7,)`` (``k4 = 4 s^2`` as :func:`navigation.geometry.beta_jet` forms it): the gradient
    of ``beta_jet`` at order 1 and ``pts + r g / |g|`` with the same operations in the same order
    (:meth:`navigation.geometry.Squircle.offset_points`)."""
    pts = _arr(pts).reshape(-1, 2)
    out = np.empty_like(pts)
    _offset_kernel(_arr(row).reshape(1, 7), float(k4), pts, float(r), out)
    return out


@numba.njit(**_JIT)
def _refine_kernel(P, q, lo, hi, stages, grid, best):
    m = grid.shape[0] - 1
    for k in range(q.shape[0]):
        qx, qy = q[k, 0], q[k, 1]
        a, b = lo[k], hi[k]
        bk = math.inf
        for _ in range(stages):
            vb, cb = math.inf, a
            for t in range(m + 1):
                ps = a + (b - a) * grid[t]
                px, py = point_xy(P, k, ps)
                v = (px - qx) ** 2 + (py - qy) ** 2
                if v < vb:
                    vb, cb = v, ps
            bk = min(bk, vb)
            step = (b - a) / m
            a, b = cb - step, cb + step
        best[k] = bk


def refine_brackets(P: np.ndarray, q: np.ndarray, lo: np.ndarray, hi: np.ndarray, stages: int, m: int) -> np.ndarray:
    """Smallest squared distance from ``q (K, 2)`` to the boundary arcs ``psi in [lo, hi]`` of rows
    ``P (K, 7)`` by nested sampling (``stages`` rounds of ``m + 1`` samples):
    :func:`navigation.geometry._refine_brackets`, compiled, the same arithmetic."""
    q = _arr(q).reshape(-1, 2)
    best = np.empty(len(q))
    if len(q):
        _refine_kernel(_arr(P).reshape(-1, 7), q, _arr(lo), _arr(hi), int(stages),
                       np.linspace(0.0, 1.0, int(m) + 1), best)
    return best


@numba.njit(**_JIT)
def _beta_kernel(P, q):
    K, n = q.shape[0], q.shape[1]
    out = np.empty((K, n))
    last = P.shape[0] - 1
    for k in range(K):
        r = min(k, last)
        for j in range(n):
            out[k, j] = _beta(P, r, q[k, j, 0], q[k, j, 1])
    return out


def beta_rows(P: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Obstacle function of packed rows ``P (K, 7)`` (or one row, ``(1, 7)``, for all) at the
    points ``q (K, ..., 2)``: ``(K, ...)``, the formula of :func:`navigation.forest._beta`."""
    q = np.asarray(q, dtype=float)
    P = _arr(P, dtype=float).reshape(-1, 7)
    K = q.shape[0]
    out = _beta_kernel(P, _arr(q).reshape(K, -1, 2))
    return out.reshape(q.shape[:-1])


@numba.njit(**_JIT)
def _signed_distance_kernel(P, q, n, stages, m, polish):
    K = q.shape[0]
    out = np.empty(K)
    bx = np.empty(n)
    by = np.empty(n)
    d2 = np.empty(n)
    cx, cy, cl = np.empty(n), np.empty(n), np.empty(n)
    dpsi = 2.0 * math.pi / n
    cs = np.empty(n)
    sn = np.empty(n)
    for j in range(n):
        cs[j], sn[j] = math.cos(j * dpsi), math.sin(j * dpsi)
    for k in range(K):
        qx, qy = q[k, 0], q[k, 1]
        for j in range(n):
            bx[j], by[j] = point_xy_cs(P, k, cs[j], sn[j])
        # chords j -> j + 1 (direction and length)
        for j in range(n):
            jp = j + 1 if j + 1 < n else 0
            cx[j], cy[j] = bx[jp] - bx[j], by[jp] - by[j]
            cl[j] = math.hypot(cx[j], cy[j])
        # half the longest arc between samples (chord over the cosine of the turn between the
        # neighbouring chords j - 1 and j + 1, capped)
        half = 0.0
        dmin = math.inf
        for j in range(n):
            jm = j - 1 if j > 0 else n - 1
            jp = j + 1 if j + 1 < n else 0
            cos = (cx[jm] * cx[jp] + cy[jm] * cy[jp]) / max(cl[jm] * cl[jp], 1e-300)
            arc = cl[j] / max(cos, 0.1) if cos > 0.1 else math.inf
            half = max(half, 0.5 * arc)
            d2[j] = (bx[j] - qx) ** 2 + (by[j] - qy) ** 2
            dmin = min(dmin, d2[j])
        limit = (math.sqrt(dmin) + half) ** 2
        best = math.inf
        for j in range(n):
            if d2[j] > limit:
                continue
            if d2[j] <= d2[j - 1 if j > 0 else n - 1] and d2[j] <= d2[j + 1 if j + 1 < n else 0]:
                lo = (j - 1) * dpsi if j > 0 else (n - 1) * dpsi - 2.0 * math.pi
                hi = ((j + 1) % n) * dpsi if j < n - 1 else 2.0 * math.pi
                for _ in range(stages):
                    kb, vb = 0, math.inf
                    # the m + 1 angles lo + t h by rotation (two sines and cosines per stage;
                    # the recurrence's rounding, ~m ulps of the angle, moves no point by 1e-15)
                    h = (hi - lo) / m
                    c, s = math.cos(lo), math.sin(lo)
                    ch, sh = math.cos(h), math.sin(h)
                    for t in range(m + 1):
                        px, py = point_xy_cs(P, k, c, s)
                        v = (px - qx) ** 2 + (py - qy) ** 2
                        if v < vb:
                            kb, vb = t, v
                        c, s = c * ch - s * sh, s * ch + c * sh
                    best = min(best, vb)
                    centre = lo + kb * h
                    lo, hi = centre - h, centre + h
                # polish: Newton on the stationarity of |x(psi) - q|^2 inside the last bracket
                # (quadratic from there); a step that leaves the bracket or meets a non-convex
                # spot stops it. Only boundary points are measured, so the result can only
                # move towards the true distance.
                ps = 0.5 * (lo + hi)
                for _ in range(polish):
                    px, py, dx1, dy1, dx2, dy2 = _jet(P[k], ps)
                    ex, ey = px - qx, py - qy
                    best = min(best, ex * ex + ey * ey)
                    g1 = ex * dx1 + ey * dy1
                    g2 = dx1 * dx1 + dy1 * dy1 + ex * dx2 + ey * dy2
                    if not g2 > 0.0:
                        break
                    step = g1 / g2
                    ps -= step
                    if not lo <= ps <= hi:
                        break
                    if abs(step) <= 1e-15:
                        break
                else:
                    px, py = point_xy(P, k, ps)
                    best = min(best, (px - qx) ** 2 + (py - qy) ** 2)
        dist = math.sqrt(best)
        out[k] = -dist if _beta(P, k, qx, qy) < 0.0 else dist
    return out


def signed_distance_rows(P: np.ndarray, q: np.ndarray, n: int = 128, stages: int = 3, m: int = 16,
                         polish: int = 4) -> np.ndarray:
    """Signed distances (negative inside) of the points ``q (K, 2)`` to the squircles of the rows
    ``P (K, 7)``: :func:`navigation.geometry.signed_distance_rows`, compiled."""
    q = _arr(q, dtype=float).reshape(-1, 2)
    P = _arr(P, dtype=float).reshape(-1, 7)
    if len(q) == 0:
        return np.empty(0)
    return _signed_distance_kernel(P, q, int(n), int(stages), int(m), int(polish))


@numba.njit(inline="always", **_JIT)
def _ray(p, k, ox, oy, dx_, dy_, en):
    """Exact distance from ``(ox, oy)`` along the unit direction ``(dx_, dy_)`` to the boundary
    of row ``p[k]``: the exit, or the entry where ``en`` (see :func:`ray_length_rows`)."""
    c, sn = p[k, 2], p[k, 3]
    ihw, ihh = 1.0 / p[k, 4], 1.0 / p[k, 5]
    dx, dy = ox - p[k, 0], oy - p[k, 1]
    x0 = (dx * c + dy * sn) * ihw
    y0 = (dy * c - dx * sn) * ihh
    ax = (dx_ * c + dy_ * sn) * ihw
    ay = (dy_ * c - dx_ * sn) * ihh
    # crossing of the bounding rectangle [-1, 1]^2: beyond the wanted root
    if ax == 0.0:
        tx_lo, tx_hi = -math.inf, math.inf
    else:
        t1, t2 = (-1.0 - x0) / ax, (1.0 - x0) / ax
        tx_lo, tx_hi = min(t1, t2), max(t1, t2)
    if ay == 0.0:
        ty_lo, ty_hi = -math.inf, math.inf
    else:
        t1, t2 = (-1.0 - y0) / ay, (1.0 - y0) / ay
        ty_lo, ty_hi = min(t1, t2), max(t1, t2)
    if en:
        r = max(max(tx_lo, ty_lo), 0.0)
        hi = r + 2.0 * math.hypot(p[k, 4], p[k, 5])
        sax, say = -ax, -ay
    else:
        r = min(tx_hi, ty_hi)
        hi = r
        sax, say = ax, ay
    kk = 2.0 - 4.0 * p[k, 6] ** 2
    for _ in range(100):
        x = x0 + r * ax
        y = y0 + r * ay
        x2, y2 = x * x, y * y
        root = math.sqrt(max(x2 * (x2 + kk * y2) + y2 * y2, 1e-300))
        g2 = 0.5 * (x2 + y2 + root)
        half = 0.5 / root
        fp = x * sax * ((x2 + x2 + kk * y2) * half + 1.0) + y * say * ((y2 + y2 + kk * x2) * half + 1.0)
        g = math.sqrt(g2)
        r_new = r
        if fp > 0.0 and g2 >= 1.0:
            step = (g2 - 1.0) * (g + g) / ((g + 1.0) * fp)
            r_new = r + step if en else r - step
        r_new = min(max(r_new, 0.0), hi)
        if abs(r_new - r) <= 4e-16 * (1.0 + r):
            return r_new
        r = r_new
    return r


@numba.njit(**_JIT)
def _ray_length_kernel(p, o, d, entry):
    K = p.shape[0]
    out = np.empty(K)
    for k in range(K):
        out[k] = _ray(p, k, o[k, 0], o[k, 1], d[k, 0], d[k, 1], entry[k])
    return out


@numba.njit(**_JIT)
def _sector(pts, ws, ox, oy):
    """The directions from ``(ox, oy)`` (inside the convex child whose counter-clockwise boundary
    samples are ``pts``) in which the child's boundary can lie inside the workspace: from the
    angle of the last sample outside it before the samples inside to that of the first one after
    (the boundary's angle seen from an interior point increases along it, so the crossings lie in
    between); ``(start, width)``, the whole circle when no sample (or every one) is inside."""
    n = pts.shape[0]
    inside = np.empty(n, np.bool_)
    count = 0
    for i in range(n):
        inside[i] = _beta(ws, 0, pts[i, 0], pts[i, 1]) < 0.0
        count += inside[i]
    if count == 0 or count == n:
        return 0.0, 4.0 * math.pi
    start = 0
    for i in range(n):  # the first inside sample after an outside one (the run is circular)
        if inside[i] and not inside[i - 1]:
            start = i
            break
    end = start
    while inside[(end + 1) % n]:
        end += 1
    before, after = pts[(start - 1) % n], pts[(end + 1) % n]
    a0 = math.atan2(before[1] - oy, before[0] - ox)
    a1 = math.atan2(after[1] - oy, after[0] - ox)
    return a0, (a1 - a0) % (2.0 * math.pi)


@numba.njit(inline="always", **_JIT)
def _far_ray(P, k, ws, ox, oy, x0, y0, c, s, ihw, ihh, cj, sj, aj, a0, width):
    """The far gap along one ray from ``(ox, oy)`` (direction ``(cj, sj)``, angle ``aj``) of
    :func:`_far_gap_kernel`: the workspace exit minus the child's exit, ``inf`` where the ray
    cannot end its child exit inside the workspace (outside the sector ``a0 .. a0 + width``,
    missing the workspace's bounding rectangle) or does not."""
    if (aj - a0) % (2.0 * math.pi) > width + 1e-9:
        return math.inf  # its leaf exit lies outside the workspace
    # a ray that misses the workspace's bounding rectangle (slab test in its frame, with a
    # margin) cannot end its leaf exit inside the workspace
    ax = (cj * c + sj * s) * ihw
    ay = (sj * c - cj * s) * ihh
    lo, hi = 0.0, math.inf
    if ax != 0.0:
        t1, t2 = (-1.0 - 1e-9 - x0) / ax, (1.0 + 1e-9 - x0) / ax
        lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    elif abs(x0) > 1.0 + 1e-9:
        return math.inf
    if ay != 0.0:
        t1, t2 = (-1.0 - 1e-9 - y0) / ay, (1.0 + 1e-9 - y0) / ay
        lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    elif abs(y0) > 1.0 + 1e-9:
        return math.inf
    if lo > hi:
        return math.inf
    r_leaf = _ray(P, k, ox, oy, cj, sj, False)
    if _beta(ws, 0, ox + r_leaf * cj, oy + r_leaf * sj) < 0.0:
        return _ray(ws, 0, ox, oy, cj, sj, False) - r_leaf
    return math.inf


@numba.njit(**_JIT)
def _far_gap_kernel(P, centres, ws, cs, sn, angles, pts, stride):
    K = P.shape[0]
    n = cs.shape[0]
    out = np.empty(K)
    c, s = ws[0, 2], ws[0, 3]
    ihw, ihh = 1.0 / ws[0, 4], 1.0 / ws[0, 5]
    val = np.empty(n)
    if stride < 1 or n % stride != 0:
        stride = 1
    nc = n // stride
    for k in range(K):
        ox, oy = centres[k, 0], centres[k, 1]
        dx, dy = ox - ws[0, 0], oy - ws[0, 1]
        x0 = (dx * c + dy * s) * ihw
        y0 = (dy * c - dx * s) * ihh
        a0, width = _sector(pts[k], ws, ox, oy)
        best = math.inf
        # coarse: every stride-th ray
        for i in range(nc):
            j = i * stride
            val[j] = _far_ray(P, k, ws, ox, oy, x0, y0, c, s, ihw, ihh, cs[j], sn[j], angles[j], a0, width)
            best = min(best, val[j])
        if stride > 1:
            # fine: the rays on both sides of every coarse local minimum (an untraced ray counts
            # as +inf, so a traced ray at the end of the traced set is refined towards it when
            # the values fall towards that end)
            for i in range(nc):
                j = i * stride
                v = val[j]
                if v == math.inf or v > val[((i - 1) % nc) * stride] or v > val[((i + 1) % nc) * stride]:
                    continue
                for d in range(1, stride):
                    for jj in ((j - d) % n, (j + d) % n):
                        best = min(best, _far_ray(P, k, ws, ox, oy, x0, y0, c, s, ihw, ihh, cs[jj], sn[jj],
                                                  angles[jj], a0, width))
        out[k] = best
    return out


def far_gap_rows(P: np.ndarray, centres: np.ndarray, ws_row: np.ndarray, n: int, pts: np.ndarray,
                 stride: int = 4) -> np.ndarray:
    """Per row of ``P (K, 7)`` (children of the workspace ``ws_row``, with counter-clockwise
    boundary samples ``pts (K, m, 2)``), on ``n`` rays from ``centres (K, 2)`` (inside the
    children) in evenly spaced directions, those whose exit from the child lies inside the
    workspace: the smallest difference between the workspace's exit distance and the child's
    (exact ray lengths); ``inf`` where no ray reaches into the workspace. Only the rays within
    the samples' bracket of the child's arc inside the workspace, and that meet the workspace's
    bounding rectangle, are traced (the others cannot end inside it). Coarse to fine: every
    ``stride``-th ray first, then the rays between each coarse local minimum and its coarse
    neighbours (``stride = 1``: every ray; the minimum is the same unless the difference has
    a dip narrower than ``stride`` rays that is not next to a coarse local minimum)."""
    P = _arr(P, dtype=float).reshape(-1, 7)
    if len(P) == 0:
        return np.empty(0)
    a = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return _far_gap_kernel(P, _arr(centres, dtype=float).reshape(-1, 2), _arr(ws_row, dtype=float).reshape(1, 7),
                           np.cos(a), np.sin(a), a, _arr(pts).reshape(len(P), -1, 2), int(stride))


def ray_length_rows(p: np.ndarray, o: np.ndarray, d: np.ndarray, entry: np.ndarray | None = None) -> np.ndarray:
    """Exact distances from origins ``o (K, 2)`` along unit directions ``d (K, 2)`` to the
    boundary of rows ``p (K, 7)`` (exit, or entry where ``entry``):
    :func:`navigation.geometry.ray_length_packed`, compiled, each row iterated to its own
    convergence."""
    p = _arr(p, dtype=float).reshape(-1, 7)
    if len(p) == 0:
        return np.empty(0)
    o = _arr(np.broadcast_to(o, (len(p), 2)), dtype=float)
    d = _arr(np.broadcast_to(d, (len(p), 2)), dtype=float)
    e = np.zeros(len(p), dtype=np.bool_) if entry is None else _arr(entry, dtype=np.bool_)
    return _ray_length_kernel(p, o, d, e)


@numba.njit(inline="always", **_JIT)
def _corner(P, k, t):
    """Corner ``t`` (0..3, counter-clockwise from (+, +)) of row ``P[k]``'s bounding rectangle."""
    sx = 1.0 if t == 0 or t == 3 else -1.0
    sy = 1.0 if t < 2 else -1.0
    lx, ly = sx * P[k, 4], sy * P[k, 5]
    return P[k, 0] + P[k, 2] * lx - P[k, 3] * ly, P[k, 1] + P[k, 3] * lx + P[k, 2] * ly


@numba.njit(inline="always", **_JIT)
def _corners(P, k, out):
    """The four corners of row ``P[k]``'s bounding rectangle (:func:`_corner`) into ``out (4, 2)``."""
    for t in range(4):
        out[t, 0], out[t, 1] = _corner(P, k, t)


@numba.njit(inline="always", **_JIT)
def _corner_edge2(ca, cb):
    """Smallest squared distance from the corners ``ca (4, 2)`` of one rectangle to the edges of
    the rectangle with corners ``cb (4, 2)`` (counter-clockwise)."""
    best = math.inf
    for e in range(4):
        ax_, ay_ = cb[e, 0], cb[e, 1]
        f = e + 1 if e < 3 else 0
        ex, ey = cb[f, 0] - ax_, cb[f, 1] - ay_
        inv = 1.0 / (ex * ex + ey * ey)
        for u in range(4):
            vx, vy = ca[u, 0] - ax_, ca[u, 1] - ay_
            t = min(max((vx * ex + vy * ey) * inv, 0.0), 1.0)
            wx, wy = vx - t * ex, vy - t * ey
            best = min(best, wx * wx + wy * wy)
    return best


@numba.njit(**_JIT)
def _gap_bound_kernel(A, B):
    E = A.shape[0]
    out = np.empty(E)
    ca, cb = np.empty((4, 2)), np.empty((4, 2))
    for k in range(E):
        dx, dy = B[k, 0] - A[k, 0], B[k, 1] - A[k, 1]
        sep = False
        for axis in range(4):
            if axis == 0:
                nx, ny = A[k, 2], A[k, 3]
            elif axis == 1:
                nx, ny = -A[k, 3], A[k, 2]
            elif axis == 2:
                nx, ny = B[k, 2], B[k, 3]
            else:
                nx, ny = -B[k, 3], B[k, 2]
            ra = A[k, 4] * abs(nx * A[k, 2] + ny * A[k, 3]) + A[k, 5] * abs(-nx * A[k, 3] + ny * A[k, 2])
            rb = B[k, 4] * abs(nx * B[k, 2] + ny * B[k, 3]) + B[k, 5] * abs(-nx * B[k, 3] + ny * B[k, 2])
            if abs(nx * dx + ny * dy) > ra + rb:
                sep = True
        rect = 0.0
        if sep:  # separated rectangles: their distance is the nearest corner-edge distance
            _corners(A, k, ca)
            _corners(B, k, cb)
            rect = math.sqrt(min(_corner_edge2(ca, cb), _corner_edge2(cb, ca)))
        disc = math.hypot(dx, dy) - math.hypot(A[k, 4], A[k, 5]) - math.hypot(B[k, 4], B[k, 5])
        out[k] = max(max(rect, disc), 0.0)
    return out


@numba.njit(**_JIT)
def _wall_bound_kernel(P, v):
    K, n = P.shape[0], v.shape[0]
    out = np.empty(K)
    a = np.empty((n, 2))
    b = np.empty(n)
    for e in range(n):  # unit outward normals and offsets of the counter-clockwise polygon
        f = e + 1 if e + 1 < n else 0
        ex, ey = v[f, 0] - v[e, 0], v[f, 1] - v[e, 1]
        nrm = math.sqrt(ey * ey + ex * ex)
        a[e, 0], a[e, 1] = ey / nrm, -ex / nrm
        b[e] = a[e, 0] * v[e, 0] + a[e, 1] * v[e, 1]
    for k in range(K):
        best = math.inf
        for u in range(4):
            px, py = _corner(P, k, u)
            for e in range(n):
                best = min(best, b[e] - px * a[e, 0] - py * a[e, 1])
        out[k] = max(best, 0.0)
    return out


def wall_bound_rows(P: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per row of ``P (K, 7)``: the smallest slack of the corners of its bounding rectangle over
    the edges of the convex polygon with counter-clockwise vertices ``v (n, 2)`` (0 where a
    corner is outside): a lower bound of the distance from the squircle to the polygon's
    boundary (:func:`navigation.forest._wall_bounds`)."""
    P = _arr(P, dtype=float).reshape(-1, 7)
    if len(P) == 0:
        return np.empty(0)
    return _wall_bound_kernel(P, _arr(v, dtype=float).reshape(-1, 2))


def gap_bound_rows(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Lower bounds ``(E,)`` of the distances between the squircles of rows ``A[k]`` and
    ``B[k]``: :func:`navigation.forest._gap_bound_rows`, compiled."""
    A = _arr(A, dtype=float).reshape(-1, 7)
    B = _arr(B, dtype=float).reshape(-1, 7)
    if len(A) == 0:
        return np.empty(0)
    return _gap_bound_kernel(A, B)


@numba.njit(inline="always", **_JIT)
def beta_derivatives_xy(P, k, qx, qy):
    """``beta`` of row ``P[k]`` at ``(qx, qy)`` with its exact gradient and packed Hessian in
    ``q``: ``(beta, b_x, b_y, b_xx, b_xy, b_yy)``, the analytic formulas of eq. (4) (used away from
    the centre, where ``x^4 + y^4 + (2 - 4s^2) x^2 y^2 > 0``; NaN at the centre)."""
    c, sn = P[k, 2], P[k, 3]
    ihw, ihh = 1.0 / P[k, 4], 1.0 / P[k, 5]
    dx, dy = qx - P[k, 0], qy - P[k, 1]
    x = (dx * c + dy * sn) * ihw
    y = (dy * c - dx * sn) * ihh
    kk = 2.0 - 4.0 * (P[k, 6] * P[k, 6])
    x2, y2 = x * x, y * y
    kxy = kk * x * y
    d = x2 * x2 + y2 * y2 + kk * x2 * y2
    root = math.sqrt(d)
    i1 = 0.25 / root  # 1 / (4 sqrt(D))
    i3 = 0.5 * i1 / d  # 1 / (8 D^(3/2))
    dd_x = x * (4.0 * x2 + 2.0 * kk * y2)
    dd_y = y * (4.0 * y2 + 2.0 * kk * x2)
    gx = x + dd_x * i1
    gy = y + dd_y * i1
    hxx = 1.0 + (12.0 * x2 + 2.0 * kk * y2) * i1 - dd_x * dd_x * i3
    hxy = 4.0 * kxy * i1 - dd_x * dd_y * i3
    hyy = 1.0 + (12.0 * y2 + 2.0 * kk * x2) * i1 - dd_y * dd_y * i3
    # back to q: (x, y) = M (q - c) with M = [[c, s] / hw, [-s, c] / hh]
    ax, bx = c * ihw, sn * ihw
    ay, by = -sn * ihh, c * ihh
    beta = 0.5 * (x2 + y2 + root) - 1.0
    b_x = gx * ax + gy * ay
    b_y = gx * bx + gy * by
    b_xx = hxx * ax * ax + 2.0 * hxy * ax * ay + hyy * ay * ay
    b_xy = hxx * ax * bx + hxy * (ax * by + ay * bx) + hyy * ay * by
    b_yy = hxx * bx * bx + 2.0 * hxy * bx * by + hyy * by * by
    return beta, b_x, b_y, b_xx, b_xy, b_yy


@numba.njit(error_model="numpy", **_JIT)  # 0 / 0 at a centre is NaN, as in numpy
def _beta_derivatives_kernel(P, qx, qy, out):
    for i in range(len(qx)):
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4], out[i, 5] = beta_derivatives_xy(P, i, qx[i], qy[i])


def beta_derivatives_rows(P: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    """:func:`beta_derivatives_xy` of row ``P[i]`` at ``(qx[i], qy[i])`` for every ``i``: shape ``(N, 6)``."""
    out = np.empty((len(qx), 6))
    _beta_derivatives_kernel(_arr(P).reshape(-1, 7), _arr(qx).reshape(-1), _arr(qy).reshape(-1), out)
    return out


@numba.njit(inline="always", **_JIT)
def root_partials(P, k, ox, oy, r0, vx, vy):
    """Partials ``(r_a, r_b, r_aa, r_ab, r_bb)`` of the ray length ``r(u)`` of row ``P[k]`` from
    ``(ox, oy)`` (``beta(o + r u) = 0``, value ``r0``) with respect to the direction
    ``u = (a, b)`` at ``u = (vx, vy)``: the implicit function theorem on ``F(r, u) = beta(o + r u)``,
    ``r_a = -F_a / F_r``, ``r_ab = -(F_ab + F_ar r_b + F_br r_a + F_rr r_a r_b) / F_r``."""
    qx = ox + r0 * vx
    qy = oy + r0 * vy
    _, bx, by, bxx, bxy, byy = beta_derivatives_xy(P, k, qx, qy)
    inv = -1.0 / (bx * vx + by * vy)  # -1 / F_r
    ra = r0 * bx * inv
    rb = r0 * by * inv
    hux = bxx * vx + bxy * vy  # (H u)_x
    huy = bxy * vx + byy * vy
    f_rr = vx * hux + vy * huy
    f_ra = bx + r0 * hux
    f_rb = by + r0 * huy
    r2 = r0 * r0
    raa = (r2 * bxx + 2.0 * f_ra * ra + f_rr * ra * ra) * inv
    rab = (r2 * bxy + f_ra * rb + f_rb * ra + f_rr * ra * rb) * inv
    rbb = (r2 * byy + 2.0 * f_rb * rb + f_rr * rb * rb) * inv
    return ra, rb, raa, rab, rbb


@numba.njit(error_model="numpy", **_JIT)
def _root_partials_kernel(P, o, r0, vx, vy, out):
    for i in range(len(r0)):
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4] = root_partials(P, i, o[i, 0], o[i, 1], r0[i], vx[i], vy[i])


def root_partials_rows(P: np.ndarray, o: np.ndarray, r0: np.ndarray, vx: np.ndarray, vy: np.ndarray) -> np.ndarray:
    """:func:`root_partials` of row ``P[i]`` from ``o[i]`` for every ``i``: shape ``(N, 5)``."""
    out = np.empty((len(r0), 5))
    _root_partials_kernel(_arr(P).reshape(-1, 7), _arr(o).reshape(-1, 2), _arr(r0).reshape(-1), _arr(vx).reshape(-1),
                          _arr(vy).reshape(-1), out)
    return out


# ---------------------------------------------------------------------- snug inflation
@numba.njit(inline="always", **_JIT)
def _gauge2(x, y, A, B, c):
    """``beta + 1`` (the squared gauge) of the point ``(x, y)`` in the local frame of the
    squircle with half extents ``A, B`` and ``c = 2 - 4 s^2``."""
    u, w = x / A, y / B
    u2, w2 = u * u, w * w
    return 0.5 * (u2 + w2 + math.sqrt(max(u2 * u2 + w2 * w2 + c * u2 * w2, 0.0)))


@numba.njit(inline="always", **_JIT)
def _gauge2_dx(x, y, A, B, c):
    """The exact partial derivatives of :func:`_gauge2` in ``x`` and ``y``."""
    u, w = x / A, y / B
    u2, w2 = u * u, w * w
    R = math.sqrt(max(u2 * u2 + w2 * w2 + c * u2 * w2, 0.0))
    if R > 0.0:
        gu = u + (u2 * u + 0.5 * c * u * w2) / R
        gw = w + (w2 * w + 0.5 * c * w * u2) / R
    else:
        gu, gw = u, w
    return gu / A, gw / B


@numba.njit(**_JIT)
def _snug_k(a, b, r, c, P, h):
    """The least ``k >= 1`` (to 1e-12 relative) for which every point of ``P (n, 2)`` (local
    frame) has ``_gauge2 <= 1`` with half extents ``a + k r + h``, ``b + k r + h``; ``inf``
    when none below 1e6 does. Containment is monotone in ``k`` (the unit ball is convex and
    symmetric about both axes): each pass takes the point outside by most at the current ``k``
    and raises ``k`` by bisection until it is inside, until none is outside."""
    K = 1.0
    for _ in range(P.shape[0]):
        worst, i = 1.0, -1
        A, B = a + K * r + h, b + K * r + h
        for j in range(P.shape[0]):
            g = _gauge2(P[j, 0], P[j, 1], A, B, c)
            if g > worst:
                worst, i = g, j
        if i < 0:
            return K
        x, y = P[i, 0], P[i, 1]
        lo, hi = K, 2.0 * K
        while _gauge2(x, y, a + hi * r + h, b + hi * r + h, c) > 1.0:
            lo, hi = hi, 2.0 * hi
            if hi > 1e6:
                return math.inf
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if _gauge2(x, y, a + mid * r + h, b + mid * r + h, c) <= 1.0:
                hi = mid
            else:
                lo = mid
            if hi - lo <= 1e-12 * hi:
                break
        K = hi
    return K


@numba.njit(**_JIT)
def _snug_excess(a, b, r, c, k, Bp, N, h):
    """The largest distance, less ``r``, from the boundary points ``Bp (m, 2)`` along their
    outward unit normals ``N`` to the boundary of the squircle with half extents ``a + k r + h``,
    ``b + k r + h`` (local frame): how far that squircle reaches beyond the ``r``-offset.
    Each exit is the root of the convex ``_gauge2(b + t n) - 1``, found by Newton steps kept
    inside a shrinking bracket (bisection where a step leaves it)."""
    A, B = a + k * r + h, b + k * r + h
    worst = 0.0
    for i in range(Bp.shape[0]):
        bx, by, nx, ny = Bp[i, 0], Bp[i, 1], N[i, 0], N[i, 1]
        lo = r
        if _gauge2(bx + lo * nx, by + lo * ny, A, B, c) > 1.0:
            lo = 0.0  # the offset point itself is outside: only when k is below the snug one
        hi = max(2.0 * r, 1e-9)
        while _gauge2(bx + hi * nx, by + hi * ny, A, B, c) <= 1.0:
            lo, hi = hi, 2.0 * hi
        t = hi
        for _ in range(60):
            x, y = bx + t * nx, by + t * ny
            f = _gauge2(x, y, A, B, c) - 1.0
            if f > 0.0:
                hi = t
            else:
                lo = t
            gx, gy = _gauge2_dx(x, y, A, B, c)
            df = gx * nx + gy * ny
            step = t - f / df if df > 0.0 else 0.5 * (lo + hi)
            if not (lo < step < hi):
                step = 0.5 * (lo + hi)
            if hi - lo <= 1e-12 * hi or step == t:
                break
            t = step
        worst = max(worst, hi - r)
    return worst


@numba.njit(inline="always", **_JIT)
def _normal_angle(L, c, psi):
    """The angle of the outward normal at the boundary angle ``psi`` of the row ``L[0]`` (a
    squircle in its own frame: centre 0, rotation 0)."""
    x, y = point_xy(L, 0, psi)
    gx, gy = _gauge2_dx(x, y, L[0, 4], L[0, 5], c)
    return math.atan2(gy, gx)


@numba.njit(**_JIT)
def _normal_samples(a, b, s, m):
    """``m`` boundary points of the first quadrant (own frame) whose outward normals make the
    angles ``pi / 2 j / (m - 1)`` with the x axis (to 1e-6 rad of boundary angle), and those
    unit normals: the bracketing step of a 256-step scan of the boundary angle, then 12
    bisection steps (the normal turns monotonically along a convex curve). A sharp corner has
    little arc length but turns its normal by 90 degrees: samples even in arc length leave it
    sparse, these do not."""
    c = 2.0 - 4.0 * s * s
    L = np.empty((1, 7))  # the squircle in its own frame, a packed row for point_xy
    L[0, 0], L[0, 1], L[0, 2], L[0, 3], L[0, 4], L[0, 5], L[0, 6] = 0.0, 0.0, 1.0, 0.0, a, b, s
    G = 256
    Bp = np.empty((m, 2))
    N = np.empty((m, 2))
    i = 0
    a_hi = _normal_angle(L, c, 0.5 * math.pi / G)
    for j in range(m):
        phi = 0.5 * math.pi * j / (m - 1)
        if j == 0:
            psi = 0.0
        elif j == m - 1:
            psi = 0.5 * math.pi
        else:
            while a_hi < phi and i < G - 1:
                i += 1
                a_hi = _normal_angle(L, c, 0.5 * math.pi * (i + 1) / G)
            lo, hi = 0.5 * math.pi * i / G, 0.5 * math.pi * (i + 1) / G
            for _ in range(12):
                psi = 0.5 * (lo + hi)
                if _normal_angle(L, c, psi) < phi:
                    lo = psi
                else:
                    hi = psi
            psi = 0.5 * (lo + hi)
        x, y = point_xy(L, 0, psi)
        gx, gy = _gauge2_dx(x, y, a, b, c)
        g = math.sqrt(gx * gx + gy * gy)
        Bp[j, 0], Bp[j, 1], N[j, 0], N[j, 1] = x, y, gx / g, gy / g
    return Bp, N


@numba.njit(**_JIT)
def _snug_eval(a, b, r, s2, P, Bp, N, h, side):
    """The objective ``J`` at ``s'`` = ``s2``: the larger of the largest reach of the snug
    ``k``'s squircle and ``side`` times the sides' own ``(k - 1) r`` (``inf`` without a ``k``)."""
    c = 2.0 - 4.0 * s2 * s2
    k = _snug_k(a, b, r, c, P, h)
    if not math.isfinite(k):
        return math.inf
    return max(_snug_excess(a, b, r, c, k, Bp, N, h), side * (k - 1.0) * r)


@numba.njit(**_JIT)
def _snug_kernel(a, b, s, r, arc, Bn, Nn, grid, refine, h, side):
    m = Bn.shape[0]
    n_arc = arc.shape[0]
    # containment points, folded into the first quadrant (the shapes are symmetric about both
    # axes): the offset points of the arc-length samples and of the normal-angle samples
    full = np.empty((n_arc + m, 2))
    for i in range(n_arc):
        full[i, 0], full[i, 1] = abs(arc[i, 0]), abs(arc[i, 1])
    for j in range(m):
        full[n_arc + j, 0], full[n_arc + j, 1] = Bn[j, 0] + r * Nn[j, 0], Bn[j, 1] + r * Nn[j, 1]
    # the search: every fourth arc sample and every normal sample for k, every fourth normal
    # sample as a ray, over q = log(1 - s') (even steps crowd towards sharp corners)
    n_sub = (n_arc + 3) // 4
    sub = np.empty((n_sub + m, 2))
    for i in range(n_sub):
        sub[i] = full[4 * i]
    for j in range(m):
        sub[n_sub + j] = full[n_arc + j]
    rays_b, rays_n = Bn[::4].copy(), Nn[::4].copy()
    q0 = math.log(max(1.0 - s, 1e-12))
    best_q, best_e = q0, _snug_eval(a, b, r, s, sub, rays_b, rays_n, h, side)
    j_best = 0
    for j in range(1, grid + 1):
        q = q0 * (1.0 - j / grid)
        e = _snug_eval(a, b, r, 1.0 - math.exp(q), sub, rays_b, rays_n, h, side)
        if e < best_e:
            best_q, best_e, j_best = q, e, j
    # golden-section search between the grid neighbours of the best
    lo = q0 * (1.0 - max(j_best - 1, 0) / grid)
    hi = q0 * (1.0 - min(j_best + 1, grid) / grid)
    g = 0.5 * (math.sqrt(5.0) - 1.0)
    x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
    e1 = _snug_eval(a, b, r, 1.0 - math.exp(x1), sub, rays_b, rays_n, h, side)
    e2 = _snug_eval(a, b, r, 1.0 - math.exp(x2), sub, rays_b, rays_n, h, side)
    for _ in range(refine):
        if e1 < e2:
            hi, x2, e2 = x2, x1, e1
            x1 = hi - g * (hi - lo)
            e1 = _snug_eval(a, b, r, 1.0 - math.exp(x1), sub, rays_b, rays_n, h, side)
        else:
            lo, x1, e1 = x1, x2, e2
            x2 = lo + g * (hi - lo)
            e2 = _snug_eval(a, b, r, 1.0 - math.exp(x2), sub, rays_b, rays_n, h, side)
    if e1 < best_e:
        best_q, best_e = x1, e1
    if e2 < best_e:
        best_q, best_e = x2, e2
    s2 = min(max(1.0 - math.exp(best_q), 0.0), s)
    k = _snug_k(a, b, r, 2.0 - 4.0 * s2 * s2, full, h)  # every point, at the chosen s'
    return s2, k, best_e, full[n_arc:].copy()


def normal_samples(a: float, b: float, s: float, m: int = 129) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_normal_samples` (``(m, 2)`` points and unit normals, first quadrant, own frame):
    they depend on the shape only, not on the offset, so a caller growing one squircle by
    several radii computes them once (:func:`navigation.geometry._snug_base`)."""
    return _normal_samples(float(a), float(b), float(s), int(m))


def snug_shape(a: float, b: float, s: float, r: float, offset: np.ndarray, m: int = 129, grid: int = 4,
               refine: int = 8, h: float = 1e-9, side: float = 1.0, normals=None):
    """``(s', k, J, corner)`` for :meth:`navigation.geometry.Squircle.grow_snug`, in the
    squircle's own frame (half extents ``a, b``, parameter ``s``, offset ``r``): the least
    ``k`` whose squircle (half extents ``a + k r + h``, ``b + k r + h``, parameter ``s'``)
    contains the ``offset (n, 2)`` points (the offset curve at arc-length-even samples) and
    the offset points of ``m`` boundary points per quadrant even in normal angle
    (``corner (m, 2)``, first quadrant; the shapes are symmetric about both axes), with ``s'``
    in ``[0, s]`` minimising ``J``: the larger of the largest reach beyond the ``r``-offset
    (along every fourth of those normals) and ``side`` times the sides' own move ``(k - 1) r``.
    Search over ``log(1 - s')``: ``grid + 1`` even steps, then ``refine`` golden-section steps
    between the best one's neighbours, on every fourth arc-length sample; the final ``k`` on
    all of them. ``normals``: :func:`normal_samples` ``(a, b, s, m)`` if already computed (the
    same arrays, so the same result)."""
    Bn, Nn = normal_samples(a, b, s, m) if normals is None else normals
    return _snug_kernel(float(a), float(b), float(s), float(r), _arr(offset).reshape(-1, 2), _arr(Bn), _arr(Nn),
                        int(grid), int(refine), float(h), float(side))
