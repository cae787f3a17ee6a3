"""Compiled (numba) kernels of the squircle geometry of a refit (:mod:`perception.fit`).

Each kernel runs the same arithmetic, operation by operation (no fastmath, no reassociation),
as the numpy code it mirrors, so its results are bit-identical (tested in
``tests/test_shape_kernel.py``):

* :func:`boundary_points`: :meth:`navigation.geometry.Squircle.boundary_points` (``8 n + 1``
  samples of :meth:`~navigation.geometry.Squircle.point_at`, arc length by ``np.linalg.norm``
  of their differences and ``np.cumsum``, ``np.linspace`` targets, ``np.interp``). The
  cosines and sines stay numpy's (``np.cos`` / ``np.sin`` may use SIMD code that rounds
  differently from libm's): those of the fine grid depend only on ``n`` and are cached, those
  of the interpolated angles are computed by numpy between the two kernels;
* :func:`gauge_any_inside`: ``np.any(perception.fit.gauge(sq, pts) <= 1.0)``;
* :func:`clear_of`: ``float(cKDTree(ref).query(pts)[0].min()) - spacing / 2 >= r`` of
  :func:`perception.fit.inflate` (brute force: the minimum over every pair of
  ``sqrt(dx * dx + dy * dy)``, the distance the k-d tree reports), stopping at the first pair
  that decides;
* :func:`spacing`: ``float(np.max(np.linalg.norm(ref - np.roll(ref, 1, axis=0), axis=1)))``;
* :func:`gauge` / :func:`radial_error`: :func:`perception.fit.gauge` / :func:`perception.fit.radial_error`
  (elementwise: the same operations per row);
* :func:`rect_test`: ``_Rect.error`` and ``_Rect.free_inside`` of :mod:`perception.fit` in one
  pass; the mean of the squared distances is numpy's pairwise summation
  (:func:`_pairwise_sum`, the algorithm of ``np.add.reduce`` on a contiguous array), so the
  RMS is the same to the last bit;
* :func:`contain`: :func:`perception.fit._contain` (the maxima of ``need`` over the points
  beyond each pair of faces are exact, so the loop takes the same steps);
* :func:`component_labels`: ``scipy.sparse.csgraph.connected_components`` of an edge list by
  union-find, the same labels (scipy's ``coo_matrix`` and graph checks cost more than the
  search on the small graphs of a cluster);
* :func:`distance_weights`: :func:`perception.fit._distance_weights`;
* :func:`accumulate`: ``np.add.at`` of a scan's returns into the map's cell sums (in order);
* :func:`free_cells`: the cells a scan's beams cross (``ObstacleMap._mark_free``: the same
  products, sums, divisions and floors per sample; the cosines and sines are numpy's);
* :func:`faces_seen`: :func:`perception.fit._faces_seen` (the same local coordinates and
  comparisons per point);
* :func:`warm_medians`: ``fit._median(np.abs(fit.radial_error(sq, q)))`` of several squircles
  (the radial errors of :func:`radial_error`, the median by a sort: the same order statistics
  and ``(x0 + x1) / 2``);
* :func:`solve_stats`: the RMS, penalty and 95th percentile ``fit._solve`` reports (numpy's
  pairwise sums, :func:`_pairwise_sum`, and ``fit._p95``'s interpolation of the order
  statistics);
* :func:`min_gap`: ``cKDTree(a).query(b, distance_upper_bound=r)[0].min()`` (the square root of
  the smallest ``dx * dx + dy * dy`` below ``r * r``, else ``inf``: what the k-d tree reports);
* :func:`box_mask`: ``((pts >= lo) & (pts <= hi)).all(axis=1)`` (the same comparisons);
* :func:`near_mask`: ``np.isfinite(cKDTree(q).query(f, distance_upper_bound=r)[0])`` of
  :func:`perception.fit._near_free` (the k-d tree keeps a point when ``dx * dx + dy * dy < r *
  r``; here the points sorted by ``x``, only those within ``r`` in ``x`` tested, stopping at the
  first hit).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from navigation._geom_kernel import _arr, arc_inverse, points_into

__all__ = ["boundary_points", "gauge_any_inside", "clear_of", "spacing", "gauge", "radial_error", "rect_test",
           "contain", "component_labels",
           "distance_weights", "near_mask", "faces_seen", "warm_medians", "solve_stats", "box_mask", "min_gap",
           "sorted_x", "warm_up"]

_JIT = dict(cache=True, nogil=True)


@numba.njit(inline="always", **_JIT)
def local_xy(qx, qy, cx, cy, c, sn, a, b):
    """The offset ``(dx, dy)`` of ``(qx, qy)`` from the centre ``(cx, cy)``, its coordinates
    ``(u, v)`` in the frame rotated by ``(c, sn) = (cos, sin)``, and the normalised ``(u / a,
    v / b)``."""
    dx, dy = qx - cx, qy - cy
    u = dx * c + dy * sn
    v = dy * c - dx * sn
    return dx, dy, u, v, u / a, v / b


@numba.njit(inline="always", **_JIT)
def gauge_xy(x2, y2, k):
    """The gauge ``sqrt(beta + 1)`` at squared normalised coordinates ``x2, y2`` (``k = 2 - 4 s^2``)."""
    return math.sqrt(0.5 * (x2 + y2 + math.sqrt(max(x2 * x2 + y2 * y2 + k * x2 * y2, 0.0))))


_FINE: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}


@numba.njit(**_JIT)
def _psi_kernel(ux, uy, fine, cx, cy, hw, hh, ct, st, s2, n):
    """Angles of ``n`` boundary points evenly spaced in arc length (``boundary_points`` up to the
    final ``point_at``): the navigation kernel's ``arc_inverse`` over this module's points."""
    pts = np.empty((len(fine), 2))
    points_into(pts, ux, uy, cx, cy, hw, hh, ct, st, s2)
    return arc_inverse(pts, fine, n)


@numba.njit(**_JIT)
def _points_kernel(ux, uy, cx, cy, hw, hh, ct, st, s2):
    out = np.empty((len(ux), 2))
    points_into(out, ux, uy, cx, cy, hw, hh, ct, st, s2)
    return out


def _fine(n: int):
    hit = _FINE.get(n)
    if hit is None:
        fine = np.linspace(0.0, 2 * np.pi, 8 * n + 1)
        hit = _FINE[n] = (fine, np.cos(fine), np.sin(fine))
    return hit


def boundary_points(center, width: float, height: float, theta: float, s: float, n: int) -> np.ndarray:
    """``Squircle(center, width, height, theta, s).boundary_points(n)`` (bit-identical)."""
    if n < 3:
        raise ValueError(f"boundary_points needs n >= 3, got {n}")
    fine, fc, fs = _fine(n)
    cx, cy = float(center[0]), float(center[1])
    hw, hh = width / 2.0, height / 2.0
    ct, st = math.cos(theta), math.sin(theta)
    s2 = s ** 2
    psi = _psi_kernel(fc, fs, fine, cx, cy, hw, hh, ct, st, s2, n)
    return _points_kernel(np.cos(psi), np.sin(psi), cx, cy, hw, hh, ct, st, s2)


@numba.njit(**_JIT)
def _any_inside_kernel(pts, cx, cy, c, sn, hw, hh, k):
    for i in range(len(pts)):
        dx, dy, u, v, x, y = local_xy(pts[i, 0], pts[i, 1], cx, cy, c, sn, hw, hh)
        x2, y2 = x * x, y * y
        g = gauge_xy(x2, y2, k)
        if g <= 1.0:
            return True
    return False


def gauge_any_inside(center, width: float, height: float, theta: float, s: float, pts: np.ndarray) -> bool:
    """``np.any(perception.fit.gauge(Squircle(center, width, height, theta, s), pts) <= 1.0)``."""
    return bool(_any_inside_kernel(pts, float(center[0]), float(center[1]), math.cos(theta), math.sin(theta),
                                   width / 2, height / 2, 2.0 - 4.0 * s * s))


@numba.njit(**_JIT)
def _spacing_kernel(ref):
    n = len(ref)
    best = -math.inf
    for i in range(n):
        j = i - 1 if i > 0 else n - 1
        dx = ref[i, 0] - ref[j, 0]
        dy = ref[i, 1] - ref[j, 1]
        d = math.sqrt(dx * dx + dy * dy)
        if d > best or math.isnan(d):
            best = d
    return best


def spacing(ref: np.ndarray) -> float:
    """Largest distance between consecutive points of the closed polygon ``ref``."""
    return float(_spacing_kernel(ref))


@numba.njit(**_JIT)
def _clear_kernel(ref, pts, half, r):
    for i in range(len(pts)):
        for j in range(len(ref)):
            dx = pts[i, 0] - ref[j, 0]
            dy = pts[i, 1] - ref[j, 1]
            if not (math.sqrt(dx * dx + dy * dy) - half >= r):
                return False
    return True


def clear_of(ref: np.ndarray, pts: np.ndarray, half: float, r: float) -> bool:
    """``min over pairs |pts_i - ref_j| - half >= r``."""
    return bool(_clear_kernel(ref, pts, half, r))


@numba.njit(**_JIT)
def _pairwise_block(a, lo, n):
    """numpy's pairwise sum of ``a[lo:lo + n]``, ``n <= 128`` (no further halving)."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    stop = n - n % 8
    while i < stop:
        k = lo + i
        r0 += a[k]
        r1 += a[k + 1]
        r2 += a[k + 2]
        r3 += a[k + 3]
        r4 += a[k + 4]
        r5 += a[k + 5]
        r6 += a[k + 6]
        r7 += a[k + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@numba.njit(**_JIT)
def _pairwise_sum(a, lo, n):
    """``np.add.reduce`` of the contiguous ``a[lo:lo + n]``: numpy's pairwise summation (blocks of
    at most 128 summed in 8 interleaved partial sums, larger ranges halved at multiples of 8:
    ``sum(lo, n) = sum(lo, n2) + sum(lo + n2, n - n2)``), its recursion run on an explicit stack
    (a recursive cached kernel called from another kernel crashed numba 0.68)."""
    if n <= 128:
        return _pairwise_block(a, lo, n)
    fl = np.empty(64, np.int64)  # frames: start, length, phase (0 new, 1 left pending, 2 right pending)
    fn = np.empty(64, np.int64)
    ph = np.zeros(64, np.int64)
    lv = np.zeros(64)
    sp = 0
    fl[0], fn[0], ph[0] = lo, n, 0
    while True:
        m = fn[sp]
        if m > 128:  # split: the left half first
            n2 = m // 2
            n2 -= n2 % 8
            ph[sp] = 1
            fl[sp + 1], fn[sp + 1], ph[sp + 1] = fl[sp], n2, 0
            sp += 1
            continue
        ret = _pairwise_block(a, fl[sp], m)
        sp -= 1
        while sp >= 0:  # return ``ret`` to the parent frames
            if ph[sp] == 1:  # left half done: the right half next
                lv[sp] = ret
                ph[sp] = 2
                n2 = fn[sp] // 2
                n2 -= n2 % 8
                fl[sp + 1], fn[sp + 1], ph[sp + 1] = fl[sp] + n2, fn[sp] - n2, 0
                sp += 1
                break
            ret = lv[sp] + ret  # both halves done
            sp -= 1
        if sp < 0:
            return ret


@numba.njit(**_JIT)
def _gauge_rows(q, cx, cy, c, sn, hw, hh, k, floor, radial):
    """The gauge (``radial``: the radial error) of every row of ``q``."""
    out = np.empty(len(q))
    for i in range(len(q)):
        dx, dy, u, v, x, y = local_xy(q[i, 0], q[i, 1], cx, cy, c, sn, hw, hh)
        x2, y2 = x * x, y * y
        g = gauge_xy(x2, y2, k)
        if radial:
            out[i] = math.sqrt(dx * dx + dy * dy) * (1.0 - 1.0 / max(g, floor))
        else:
            out[i] = g
    return out


def gauge(center, width: float, height: float, theta: float, s: float, q: np.ndarray) -> np.ndarray:
    """:func:`perception.fit.gauge` of the squircle at the rows of ``q`` (C-contiguous floats)."""
    return _gauge_rows(q, float(center[0]), float(center[1]), math.cos(theta), math.sin(theta), width / 2,
                       height / 2, 2.0 - 4.0 * s * s, 0.0, False)


def radial_error(center, width: float, height: float, theta: float, s: float, q: np.ndarray) -> np.ndarray:
    """:func:`perception.fit.radial_error` of the squircle at the rows of ``q`` (C-contiguous floats)."""
    return _gauge_rows(q, float(center[0]), float(center[1]), math.cos(theta), math.sin(theta), width / 2,
                       height / 2, 2.0 - 4.0 * s * s, 1e-9, True)


@numba.njit(**_JIT)
def _rect_kernel(points, free, cx, cy, c, s, hw, hh, margin, want_error):
    """``(_Rect.error(points) if want_error else 0, _Rect.free_inside(free, margin))``."""
    n = len(points)
    err = 0.0
    if want_error:
        dd = np.empty(n)
        for i in range(n):
            dx, dy = points[i, 0] - cx, points[i, 1] - cy
            u = abs(dx * c + dy * s)
            v = abs(dy * c - dx * s)
            d = max(min(hw - u, hh - v), 0.0)
            dd[i] = d * d
        err = math.sqrt(_pairwise_sum(dd, 0, n) / n)
    cnt = 0
    wl, hl = hw - margin, hh - margin
    for i in range(len(free)):
        dx, dy = free[i, 0] - cx, free[i, 1] - cy
        u = abs(dx * c + dy * s)
        v = abs(dy * c - dx * s)
        if u < wl and v < hl:
            cnt += 1
    return err, cnt


_NO_FREE = np.zeros((0, 2))


def rect_test(points: np.ndarray, free, cx: float, cy: float, w: float, h: float, t: float, margin: float,
              want_error: bool = True) -> tuple[float, int]:
    """RMS distance of ``points`` inside the rectangle to its boundary (``_Rect.error``; 0 when
    not ``want_error``) and the free points deeper than ``margin`` inside it (``_Rect.free_inside``)."""
    fr = _NO_FREE if free is None or not len(free) else _arr(free)
    return _rect_kernel(_arr(points), fr, cx, cy, math.cos(t), math.sin(t), w / 2, h / 2, margin, want_error)


@numba.njit(**_JIT)
def _need_into(need, ux, p, q, tol):
    """``need = g / (1 + tol / max(hypot(u, v), 1e-9))`` of :func:`perception.fit._contain` (and
    ``ux = |u / a| >= |v / b|``) at parameters ``p``."""
    c, sn = math.cos(p[4]), math.sin(p[4])
    a, b = math.exp(p[2]), math.exp(p[3])
    k = 2.0 - 4.0 * p[5] * p[5]
    for i in range(len(q)):
        dx, dy, u, v, x, y = local_xy(q[i, 0], q[i, 1], p[0], p[1], c, sn, a, b)
        x2, y2 = x * x, y * y
        g = gauge_xy(x2, y2, k)
        need[i] = g / (1.0 + tol[i] / max(math.hypot(u, v), 1e-9))
        ux[i] = abs(x) >= abs(y)


@numba.njit(**_JIT)
def _contain_kernel(p, q, tol):
    p = p.copy()
    n = len(q)
    need = np.empty(n)
    on_x = np.empty(n, np.bool_)
    for _ in range(4):
        _need_into(need, on_x, p, q, tol)
        mx = -math.inf
        my = -math.inf
        anyx = False
        anyy = False
        for i in range(n):
            if need[i] > 1.0:
                if on_x[i]:
                    anyx = True
                    if need[i] > mx:
                        mx = need[i]
                else:
                    anyy = True
                    if need[i] > my:
                        my = need[i]
        if not (anyx or anyy):
            return p
        if anyx:
            p[2] += math.log(mx) + 1e-9
        if anyy:
            p[3] += math.log(my) + 1e-9
    _need_into(need, on_x, p, q, tol)
    f = 1.0
    if n:
        f = need[0]
        for i in range(1, n):
            if need[i] > f:
                f = need[i]
    if f > 1.0:
        p[2] += math.log(f) + 1e-9
        p[3] += math.log(f) + 1e-9
    return p


def contain(p: np.ndarray, q: np.ndarray, tol) -> np.ndarray:
    """:func:`perception.fit._contain` (the same steps, bit-identical); ``tol`` a float or one
    radial tolerance per point."""
    q = _arr(q)
    t = np.full(len(q), float(tol)) if np.ndim(tol) == 0 else _arr(np.asarray(tol, dtype=float).reshape(len(q)))
    return _contain_kernel(_arr(p), q, t)


@numba.njit(**_JIT)
def _find(parent, v):
    r = v
    while parent[r] != r:
        r = parent[r]
    while parent[v] != r:  # path compression
        parent[v], v = r, parent[v]
    return r


@numba.njit(**_JIT)
def _component_labels(n, pairs):
    parent = np.arange(n)
    for k in range(len(pairs)):
        ra, rb = _find(parent, pairs[k, 0]), _find(parent, pairs[k, 1])
        if ra != rb:
            if ra < rb:
                parent[rb] = ra
            else:
                parent[ra] = rb
    lab = np.empty(n, np.int64)
    root_lab = np.full(n, -1, np.int64)
    cnt = 0
    for v in range(n):
        r = _find(parent, v)
        if root_lab[r] < 0:
            root_lab[r] = cnt
            cnt += 1
        lab[v] = root_lab[r]
    return cnt, lab


def component_labels(n: int, pairs: np.ndarray) -> tuple[int, np.ndarray]:
    """``scipy.sparse.csgraph.connected_components`` (undirected) of the graph on ``n`` nodes
    with the edges ``pairs (E, 2)``: the number of components and every node's label, labels
    numbered in the order of their smallest node (scipy's order: it labels the component of
    each node not yet labelled, in increasing node order)."""
    return _component_labels(int(n), _arr(np.asarray(pairs).reshape(-1, 2), np.int64))


@numba.njit(**_JIT)
def _distance_weights_kernel(p, q):
    c, sn = math.cos(p[4]), math.sin(p[4])
    a, b, s = math.exp(p[2]), math.exp(p[3]), p[5]
    k = 2.0 - 4.0 * s * s
    out = np.empty(len(q))
    for i in range(len(q)):
        dx, dy, u, v, x, y = local_xy(q[i, 0], q[i, 1], p[0], p[1], c, sn, a, b)
        x2, y2 = x * x, y * y
        R = math.sqrt(max(x2 * x2 + y2 * y2 + k * x2 * y2, 1e-300))
        B = 0.5 * (x2 + y2 + R)
        g = math.sqrt(max(B, 1e-300))
        dBx = x + (2.0 * x2 * x + k * x * y2) / (2.0 * R)
        dBy = y + (2.0 * y2 * y + k * x2 * y) / (2.0 * R)
        gx, gy = dBx / (2.0 * g * a), dBy / (2.0 * g * b)
        d0 = gx * -c + gy * sn
        d1 = gx * -sn + gy * -c
        grad = math.hypot(d0, d1)
        rho = math.hypot(u, v)
        w = g / max(rho * grad, 1e-12)
        out[i] = min(max(w, 0.05), 1.0)
    return out


def distance_weights(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """:func:`perception.fit._distance_weights` (the gauge and its centre derivatives of
    ``fit._gauge_jac``, row by row: bit-identical)."""
    return _distance_weights_kernel(_arr(p), _arr(q))


@numba.njit(**_JIT)
def _free_cells_kernel(a0, a1, t, L, c, sn, cell, rows, cols, flat, out):
    count = 0
    for b in range(len(L)):
        for k in range(len(t)):
            if not t[k] < L[b]:
                continue
            i = math.floor((a0 + t[k] * c[b]) / cell)
            j = math.floor((a1 + t[k] * sn[b]) / cell)
            if i >= 0 and j >= 0 and i < rows and j < cols:
                lin = i * cols + j
                if not flat[lin]:
                    out[count] = lin
                    count += 1
    return count


def free_cells(a0: float, a1: float, t: np.ndarray, L: np.ndarray, c: np.ndarray, sn: np.ndarray, cell: float,
               shape, flat: np.ndarray) -> np.ndarray:
    """The linear indices (unsorted, repeated) of the cells not yet free (``flat`` False) that the
    samples ``t (K,)`` along beams of lengths ``L (B,)``, cosines ``c`` and sines ``sn`` cross:
    the cell of ``((a0 + t c) / cell, (a1 + t sn) / cell)`` floored, inside ``shape``, for
    ``t < L`` (``ObstacleMap._mark_free``'s numpy arithmetic, sample by sample)."""
    out = np.empty(len(t) * len(L), dtype=np.int64)
    n = _free_cells_kernel(float(a0), float(a1), _arr(t), _arr(L), _arr(c), _arr(sn), float(cell),
                           int(shape[0]), int(shape[1]), flat, out)
    return out[:n]


@numba.njit(**_JIT)
def _near_kernel(xs, ys, f, r, out):
    r2 = r * r
    pad = r + 1e-9 * (1.0 + abs(r))  # (a superset of the window: |dx| >= r gives dx * dx >= r * r)
    n = len(xs)
    for i in range(len(f)):
        fx, fy = f[i, 0], f[i, 1]
        j = np.searchsorted(xs, fx - pad - 1e-9 * abs(fx))
        hit = False
        while j < n and xs[j] <= fx + pad + 1e-9 * abs(fx):
            dx = fx - xs[j]
            dy = fy - ys[j]
            if dx * dx + dy * dy < r2:
                hit = True
                break
            j += 1
        out[i] = hit


def near_mask(q: np.ndarray, f: np.ndarray, r: float) -> np.ndarray:
    """Which rows of ``f (M, 2)`` lie closer than ``r`` to a row of ``q (N, 2)``:
    ``np.isfinite(cKDTree(q).query(f, distance_upper_bound=r)[0])`` (the same squared distances
    compared with ``r * r``, strictly)."""
    order = np.argsort(q[:, 0], kind="stable")
    out = np.empty(len(f), dtype=np.bool_)
    _near_kernel(_arr(q[order, 0]), _arr(q[order, 1]), _arr(f), float(r), out)
    return out


@numba.njit(**_JIT)
def _gap_kernel(xs, ys, f, r):
    best = r * r
    found = False
    n = len(xs)
    for i in range(len(f)):
        fx, fy = f[i, 0], f[i, 1]
        w = math.sqrt(best)
        pad = w + 1e-9 * (1.0 + w) + 1e-9 * abs(fx)  # (a superset of the window: |dx| >= w, dx * dx >= best)
        j = np.searchsorted(xs, fx - pad)
        while j < n and xs[j] <= fx + pad:
            dx = fx - xs[j]
            dy = fy - ys[j]
            d2 = dx * dx + dy * dy
            if d2 < best:
                best = d2
                found = True
            j += 1
    return math.sqrt(best) if found else math.inf


def sorted_x(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of ``a (N, 2)`` sorted by ``x``, as ``(xs, ys)`` (for :func:`min_gap`)."""
    order = np.argsort(a[:, 0], kind="stable")
    return _arr(a[order, 0]), _arr(a[order, 1])


def min_gap(a_sorted: tuple[np.ndarray, np.ndarray], b: np.ndarray, r: float) -> float:
    """``float(cKDTree(a).query(b, distance_upper_bound=r)[0].min())`` for the points ``a`` given
    by :func:`sorted_x`: the distance between the closest pair closer than ``r`` (the same
    squared distances, strictly below ``r * r``, and square root), else ``inf``."""
    return float(_gap_kernel(a_sorted[0], a_sorted[1], _arr(b), float(r)))


@numba.njit(**_JIT)
def _box_kernel(pts, lo0, lo1, hi0, hi1, out):
    for i in range(len(pts)):
        x, y = pts[i, 0], pts[i, 1]
        out[i] = x >= lo0 and y >= lo1 and x <= hi0 and y <= hi1


def box_mask(pts: np.ndarray, lo, hi) -> np.ndarray:
    """``((pts >= lo) & (pts <= hi)).all(axis=1)`` of the rows of ``pts (N, 2)`` and the corners
    ``lo``, ``hi`` (2,)."""
    out = np.empty(len(pts), dtype=np.bool_)
    _box_kernel(_arr(pts), float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]), out)
    return out


@numba.njit(**_JIT)
def _faces_kernel(p, q, views, c, s, a, b):
    cnt = np.zeros((2, 2), np.int64)
    for i in range(len(q)):
        dx, dy, u, v, nu, nv = local_xy(q[i, 0], q[i, 1], p[0], p[1], c, s, a, b)
        vu = views[i, 0] * c + views[i, 1] * s
        vv = views[i, 1] * c - views[i, 0] * s
        if abs(nu) >= abs(nv):
            n, vc, axis = nu, vu, 0
        else:
            n, vc, axis = nv, vv, 1
        if -n > 0.3 and -vc < -0.05:
            cnt[axis, 0] += 1
        if n > 0.3 and vc < -0.05:
            cnt[axis, 1] += 1
    return cnt


def faces_seen(p: np.ndarray, q: np.ndarray, views: np.ndarray) -> np.ndarray:
    """:func:`perception.fit._faces_seen` with ``views`` given: ``seen[axis, side]`` (bool (2, 2))."""
    cnt = _faces_kernel(_arr(p), _arr(q), _arr(views), math.cos(p[4]), math.sin(p[4]), math.exp(p[2]),
                        math.exp(p[3]))
    return cnt >= 2


@numba.njit(**_JIT)
def _median_sorted(e, n):
    e.sort()
    h = n // 2
    if n % 2:
        return e[h]
    return (e[h - 1] + e[h]) / 2


@numba.njit(**_JIT)
def _warm_kernel(geo, q):
    n = len(q)
    out = np.empty(len(geo))
    e = np.empty(n)
    finite = True
    for k in range(len(geo)):
        cx, cy, c, sn, hw, hh, kk = geo[k, 0], geo[k, 1], geo[k, 2], geo[k, 3], geo[k, 4], geo[k, 5], geo[k, 6]
        for i in range(n):
            dx, dy, u, v, x, y = local_xy(q[i, 0], q[i, 1], cx, cy, c, sn, hw, hh)
            x2, y2 = x * x, y * y
            g = gauge_xy(x2, y2, kk)
            ei = abs(math.sqrt(dx * dx + dy * dy) * (1.0 - 1.0 / max(g, 1e-9)))
            if not math.isfinite(ei):
                finite = False
            e[i] = ei
        out[k] = _median_sorted(e, n)
    return out, finite


def warm_medians(squircles, q: np.ndarray) -> np.ndarray | None:
    """``[fit._median(np.abs(fit.radial_error(sq, q))) for sq in squircles]`` for a non-empty
    ``q``; None when an error is not finite (``np.median``'s NaN rules: the caller's)."""
    geo = np.array([(float(sq.center[0]), float(sq.center[1]), math.cos(sq.theta), math.sin(sq.theta),
                     sq.width / 2, sq.height / 2, 2.0 - 4.0 * sq.s * sq.s) for sq in squircles]).reshape(-1, 7)
    out, finite = _warm_kernel(geo, _arr(q))
    return out if finite else None


@numba.njit(**_JIT)
def _p95_kernel(a):
    n = len(a)
    v = (n - 1) * 0.95
    lo = math.floor(v)
    if v >= n - 1:
        return a.max()
    a.sort()
    x0, x1 = a[lo], a[lo + 1]
    t = v - lo
    d = x1 - x0
    return x1 - d * (1 - t) if t >= 0.5 else x0 + d * t


@numba.njit(**_JIT)
def _solve_stats_kernel(fun, nq, wq, has_wq):
    rp = np.empty(nq)
    sq = np.empty(nq)
    finite = True
    for i in range(nq):
        r = fun[i] / wq[i] if has_wq else fun[i]
        rp[i] = abs(r)
        sq[i] = r * r
        if not math.isfinite(r):
            finite = False
    rms = math.sqrt(_pairwise_sum(sq, 0, nq) / nq)
    m = len(fun) - 2 - nq
    pen_sq = np.empty(max(m, 0))
    for i in range(m):
        pen_sq[i] = fun[nq + i] * fun[nq + i]
    pen = _pairwise_sum(pen_sq, 0, m) if m > 0 else 0.0
    p95 = _p95_kernel(rp) if (finite and nq >= 2) else math.nan
    return rms, pen, p95, finite and nq >= 2


def solve_stats(fun: np.ndarray, nq: int, wq) -> tuple[float, float, float | None]:
    """``(sqrt(mean(rp^2)), sum(fun[nq:-2]^2), _p95(|rp|))`` of ``fit._solve``, ``rp = fun[:nq] /
    wq`` (``fun[:nq]`` without ``wq``), ``nq >= 1``, ``len(fun) >= nq + 2``; the 95th percentile is
    None where ``fit._p95`` goes to ``np.percentile`` (fewer than 2 points, non-finite errors)."""
    has_wq = wq is not None
    rms, pen, p95, ok = _solve_stats_kernel(_arr(fun), int(nq), _arr(wq) if has_wq else _NO_W, has_wq)
    return rms, pen, (p95 if ok else None)


_NO_W = np.zeros(1)


@numba.njit(**_JIT)
def _accumulate_kernel(n, total, view, ij, pts, vd, sel):
    for k in range(len(ij)):
        if sel[k]:
            i, j = ij[k, 0], ij[k, 1]
            n[i, j] += 1
            total[i, j, 0] += pts[k, 0]
            total[i, j, 1] += pts[k, 1]
            view[i, j, 0] += vd[k, 0]
            view[i, j, 1] += vd[k, 1]


def accumulate(n: np.ndarray, total: np.ndarray, view: np.ndarray, ij: np.ndarray, pts: np.ndarray,
               vd: np.ndarray, sel: np.ndarray) -> None:
    """``np.add.at`` of 1, ``pts`` and ``vd`` into the cells ``ij`` of ``n``, ``total`` and ``view``
    for the rows ``sel``, in place (the returns in order, as ``np.add.at`` adds them)."""
    _accumulate_kernel(n, total, view, _arr(ij, np.int64), _arr(pts), _arr(vd), _arr(sel, np.bool_))


def warm_up() -> None:
    """Compile (or load from numba's cache) every kernel of this module."""
    accumulate(np.zeros((2, 2), np.int32), np.zeros((2, 2, 2)), np.zeros((2, 2, 2)), np.array([[0, 1]]),
               np.ones((1, 2)), np.ones((1, 2)), np.ones(1, bool))
    free_cells(0.5, 0.5, np.array([0.1, 0.2]), np.array([0.15, 0.3]), np.ones(2), np.zeros(2), 0.1, (8, 8),
               np.zeros(64, bool))
    p = boundary_points((0.1, -0.2), 1.0, 0.5, 0.3, 0.9, 16)
    gauge_any_inside((0.0, 0.0), 1.0, 0.5, 0.3, 0.9, _arr(p))
    spacing(p)
    clear_of(p, _arr(0.5 * p), 0.01, 0.1)
    gauge((0.0, 0.0), 1.0, 0.5, 0.3, 0.9, p)
    radial_error((0.0, 0.0), 1.0, 0.5, 0.3, 0.9, p)
    rect_test(p, None, 0.0, 0.0, 1.0, 0.5, 0.3, 0.04)
    rect_test(p, p, 0.0, 0.0, 1.0, 0.5, 0.3, 0.04, False)
    contain(np.array([0.0, 0.0, -0.5, -1.0, 0.3, 0.9]), p, 0.01)
    component_labels(4, np.array([[0, 2], [1, 3]]))
    component_labels(3, np.zeros((0, 2), np.int64))
    distance_weights(np.array([0.0, 0.0, -0.5, -1.0, 0.3, 0.9]), p)
    near_mask(p, 0.5 * p, 0.1)
    box_mask(p, (0.0, 0.0), (1.0, 1.0))
    min_gap(sorted_x(p), 0.5 * p, 0.3)
    from navigation.geometry import Squircle

    faces_seen(np.array([0.0, 0.0, -0.5, -1.0, 0.3, 0.9]), p, p)
    warm_medians([Squircle((0.0, 0.0), 1.0, 0.5, 0.3, 0.9)], p)
    solve_stats(np.ones(8), 5, np.ones(5))
    solve_stats(np.ones(8), 5, None)
