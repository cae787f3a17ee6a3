"""Compiled exact distance between two squircle boundaries (numba kernels of :mod:`navigation.forest`).

The exact pair distance behind :func:`navigation.forest._pair_distance` (which calls
:func:`pair_distance`), row by row, in plain loops compiled by numba (``cache=True``, no fastmath):

* :func:`newton_pair` minimises ``f(s, t) = |a(s) - b(t)|^2`` over the boundary parameters of two
  packed squircle rows (layout of :func:`navigation.geometry.pack`) by safeguarded Newton with the
  exact derivatives of :func:`navigation.geometry.boundary_jet_rows`: the Newton step where the
  Hessian is positive definite, a Levenberg-Marquardt step elsewhere, clipped to the sampling
  window ``w0`` and halved (at most 16 times) until ``f`` does not increase. A row stops when its
  Newton step is below ``tol`` (radians), when no step along its direction decreases ``f``, when
  the step's first-order decrease is below 1e-13 relative, or when ``f`` decreased by less than
  1e-14 relative.
* :func:`pair_distance_arrays` is the whole of ``_pair_distance`` for stacked boundary samples:
  coarse to fine, every 8th sample of both bodies; each local minimum (along the boundary of
  ``I``, wrapping) of the coarse profile ``min_j |a_i - b_j|`` within ``8 (spacing_a + spacing_b)``
  of its smallest value is a candidate; each candidate is refined to the closest sample pair within
  +-8 samples on both boundaries, then by :func:`newton_pair` (window ``8 w0``); the smallest
  result wins (ties: the first candidate, as numpy's ``argmin`` / stable ``lexsort``).
* :func:`pair_distance` is ``_pair_distance(bodies, I, J, tol)`` itself (groups the rows by
  sample counts, stacks the bodies' arrays and calls :func:`pair_distance_arrays` per group).

The point and jet formulas are those of :func:`navigation.geometry._point_xy_rows` and
:func:`~navigation.geometry.boundary_jet_rows`, operation by operation (results equalled the
former numpy implementation's bit for bit on every captured forest-build input).
Every row is computed independently of the other rows of its batch.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._geom_kernel import _arr, _jet

__all__ = ["newton_pair", "pair_distance_arrays", "pair_distance"]

_STRIDE = 8  # coarse sampling stride of _pair_distance
_HALF = 8  # fine search half-window (samples) and Newton window factor
_BACKTRACK = 16  # step halvings per Newton iteration
_MAX_ITER = 60  # Newton iterations of _pair_distance (the default of _newton_pair)


# ---------------------------------------------------------------------- boundary point and jet
@numba.njit(cache=True, inline="always")
def _point(p, psi):
    """Boundary point ``(x, y)`` of packed row ``p (7,)`` at angle ``psi``
    (:func:`navigation.geometry._point_xy_rows`, same operation order)."""
    ux = math.cos(psi)
    uy = math.sin(psi)
    m = ux * uy
    s = p[6]
    h = 1.0 - 4.0 * s * s * m * m
    if not h >= 0.0:  # np.maximum(h, 0.0) (NaN propagates)
        h = h if h != h else 0.0
    rho = math.sqrt(2.0 / (1.0 + math.sqrt(h)))
    lx = rho * ux * p[4]
    ly = rho * uy * p[5]
    c = p[2]
    sn = p[3]
    return p[0] + c * lx - sn * ly, p[1] + sn * lx + c * ly


@numba.njit(cache=True, inline="always")
def _absmax(a, b):
    """``max(|a|, |b|)`` propagating NaN (``np.abs(step).max(axis=1)``)."""
    a = abs(a)
    b = abs(b)
    if a != a or b != b:
        return math.nan
    return a if a >= b else b


@numba.njit(cache=True, inline="always")
def _clip(x, w):
    """``np.clip(x, -w, w)`` (NaN propagates)."""
    if x < -w:
        return -w
    if x > w:
        return w
    return x


# ---------------------------------------------------------------------- Newton on one pair
@numba.njit(cache=True)
def _newton_row(p, q, s, t, ws, wt, f, tol, max_iter):
    """One row of :func:`newton_pair`: from ``(s, t)`` with value ``f`` and window ``(ws, wt)``;
    returns the final ``(s, t, f)``."""
    for _ in range(max_iter):
        ax, ay, a1x, a1y, a2x, a2y = _jet(p, s)
        bx, by, b1x, b1y, b2x, b2y = _jet(q, t)
        dx = ax - bx
        dy = ay - by
        gs = 2.0 * (dx * a1x + dy * a1y)
        gt = -2.0 * (dx * b1x + dy * b1y)
        hss = 2.0 * ((a1x * a1x + a1y * a1y) + (dx * a2x + dy * a2y))
        htt = 2.0 * ((b1x * b1x + b1y * b1y) - (dx * b2x + dy * b2y))
        hst = -2.0 * (a1x * b1x + a1y * b1y)
        det = hss * htt - hst * hst
        hh = hss * htt
        if not hh >= 1e-300:  # np.maximum(hss * htt, 1e-300)
            hh = hh if hh != hh else 1e-300
        newton = (hss > 0) and (det > 1e-12 * hh)
        # elsewhere shift the Hessian by its smallest eigenvalue and a little more (Levenberg-
        # Marquardt)
        if newton:
            lam = 0.0
        else:
            low = 0.5 * (hss + htt) - math.sqrt(0.25 * ((hss - htt) * (hss - htt)) + hst * hst)
            nl = -low
            if not nl >= 0.0:
                nl = nl if nl != nl else 0.0
            lam = nl + 1e-3 * (abs(hss) + abs(htt)) + 1e-300
        hs = hss + lam
        ht = htt + lam
        den = hs * ht - hst * hst
        ss = _clip(-(ht * gs - hst * gt) / den, ws)
        st = _clip(-(hs * gt - hst * gs) / den, wt)
        # converged: tiny Newton step, or first-order decrease below 1e-13 relative
        gain = -(gs * ss + gt * st)
        if (newton and _absmax(ss, st) <= tol) or gain <= 1e-13 * f + 1e-300:
            break
        before = f
        moved = False
        taken = 0.0
        for _b in range(_BACKTRACK):
            ts = s + ss
            tt = t + st
            x0, y0 = _point(p, ts)
            x1, y1 = _point(q, tt)
            ex = x0 - x1
            ey = y0 - y1
            ft = ex * ex + ey * ey
            if ft <= f:
                s = ts
                t = tt
                f = ft
                taken = _absmax(ss, st)
                moved = True
                break
            ss *= 0.5
            st *= 0.5
        # stop at a tiny Newton step, when no step along the direction decreases f, or when f
        # decreased by less than 1e-14 relative
        if not moved or (newton and taken <= tol) or before - f <= 1e-14 * before:
            break
    return s, t, f


@numba.njit(cache=True)
def _newton_kernel(PI, PJ, c0, w0, f0, tol, max_iter, c, f):
    """:func:`_newton_row` of every row, written to ``c (K, 2)`` and ``f (K,)``."""
    for k in range(PI.shape[0]):
        s, t, v = _newton_row(PI[k], PJ[k], c0[k, 0], c0[k, 1], w0[k, 0], w0[k, 1], f0[k], tol, max_iter)
        c[k, 0] = s
        c[k, 1] = t
        f[k] = v


def newton_pair(PI: np.ndarray, PJ: np.ndarray, c0: np.ndarray, w0: np.ndarray, f0: np.ndarray, *,
                tol: float, max_iter: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """Compiled :func:`navigation.forest._newton_pair`: minimise ``|a(s) - b(t)|^2`` over the
    boundary parameters of rows ``PI``, ``PJ (K, 7)`` from ``c0 (K, 2)`` (value ``f0 (K,)``) within
    windows ``w0 (K, 2)``; returns ``(c (K, 2), f (K,))``."""
    PI = _arr(PI).reshape(-1, 7)
    PJ = _arr(PJ).reshape(-1, 7)
    c0 = _arr(c0).reshape(-1, 2)
    w0 = _arr(w0).reshape(-1, 2)
    f0 = _arr(f0).reshape(-1)
    K = len(c0)
    c, f = np.empty((K, 2)), np.empty(K)
    if K:
        _newton_kernel(PI, PJ, c0, w0, f0, float(tol), int(max_iter), c, f)
    return c, f


# ---------------------------------------------------------------------- whole pair distance
@numba.njit(cache=True)
def _pair_kernel(PI, PJ, A, B, psi_a, psi_b, w_a, w_b, spacing_a, spacing_b, tol, max_iter, d, qa, qb):
    """``_pair_distance`` of every row (Newton: at most ``max_iter`` iterations): distances into
    ``d (K,)``, closest points into ``qa, qb (K, 2)``."""
    K, na, nb = A.shape[0], A.shape[1], B.shape[1]
    nca = (na + _STRIDE - 1) // _STRIDE
    ncb = (nb + _STRIDE - 1) // _STRIDE
    nw = 2 * _HALF + 1
    prof = np.empty(nca)
    kb_all = np.empty(nca, np.intp)
    for k in range(K):
        # coarse: every stride-th sample of both; profile along I of the nearest J sample
        pmin = math.inf
        for i in range(nca):
            ax = A[k, i * _STRIDE, 0]
            ay = A[k, i * _STRIDE, 1]
            best = math.inf
            jb = 0
            for j in range(ncb):
                dx = ax - B[k, j * _STRIDE, 0]
                dy = ay - B[k, j * _STRIDE, 1]
                v = dx * dx + dy * dy
                if v < best or (j == 0):
                    best = v
                    jb = j
            kb_all[i] = jb
            prof[i] = math.sqrt(best)
            if prof[i] < pmin or i == 0:
                pmin = prof[i]
        lim = pmin + _STRIDE * (spacing_a[k] + spacing_b[k])
        bs = 0.0
        bt = 0.0
        bf = math.inf
        found = False
        for i in range(nca):
            pv = prof[i]
            if not (pv <= prof[(i - 1) % nca] and pv <= prof[(i + 1) % nca] and pv <= lim):
                continue
            # fine: all samples within `half` of the coarse candidate (wrapping around)
            ca = i * _STRIDE
            cb = kb_all[i] * _STRIDE
            fbest = math.inf
            fa = 0
            fb = 0
            first = True
            for la in range(nw):
                ia = (ca + la - _HALF) % na
                ax = A[k, ia, 0]
                ay = A[k, ia, 1]
                for lb in range(nw):
                    ib = (cb + lb - _HALF) % nb
                    dx = ax - B[k, ib, 0]
                    dy = ay - B[k, ib, 1]
                    v = dx * dx + dy * dy
                    if first or v < fbest:
                        fbest = v
                        fa = ia
                        fb = ib
                        first = False
            s, t, v = _newton_row(PI[k], PJ[k], psi_a[k, fa], psi_b[k, fb], _HALF * w_a[k], _HALF * w_b[k],
                                  fbest, tol, max_iter)
            # the smallest value wins; ties keep the first candidate; NaN only if all are NaN
            if (not found) or v < bf or (bf != bf and v == v):
                bs, bt, bf = s, t, v
                found = True
        d[k] = math.sqrt(bf)
        qa[k, 0], qa[k, 1] = _point(PI[k], bs)
        qb[k, 0], qb[k, 1] = _point(PJ[k], bt)


def pair_distance_arrays(PI: np.ndarray, PJ: np.ndarray, A: np.ndarray, B: np.ndarray, psi_a: np.ndarray,
                         psi_b: np.ndarray, w_a: np.ndarray, w_b: np.ndarray, spacing_a: np.ndarray,
                         spacing_b: np.ndarray, tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Compiled :func:`navigation.forest._pair_distance` of stacked bodies, one sample-count group.

    Row ``k`` is the pair of squircles ``PI[k]``, ``PJ[k] (7,)`` with boundary samples
    ``A[k] (na, 2)`` at angles ``psi_a[k] (na,)`` and ``B[k] (nb, 2)`` at ``psi_b[k] (nb,)``,
    search windows ``w_a[k]``, ``w_b[k]`` and sample spacings ``spacing_a[k]``, ``spacing_b[k]``
    (the ``pts``, ``psi``, ``w0``, ``spacing`` and ``row`` of :class:`navigation.forest._Body`).
    All rows share ``na`` and ``nb``: call once per group of sample counts (ragged input:
    :func:`pair_distance`). Returns ``(distances (K,), points_on_I (K, 2), points_on_J (K, 2))``.
    """
    PI = _arr(PI).reshape(-1, 7)
    PJ = _arr(PJ).reshape(-1, 7)
    K = len(PI)
    if K == 0:
        return np.empty(0), np.empty((0, 2)), np.empty((0, 2))
    A = _arr(A).reshape(K, -1, 2)
    B = _arr(B).reshape(K, -1, 2)
    psi_a = _arr(psi_a).reshape(K, -1)
    psi_b = _arr(psi_b).reshape(K, -1)
    w_a, w_b, spacing_a, spacing_b = (_arr(x).reshape(K)
                                      for x in (w_a, w_b, spacing_a, spacing_b))
    d, qa, qb = np.empty(K), np.empty((K, 2)), np.empty((K, 2))
    _pair_kernel(PI, PJ, A, B, psi_a, psi_b, w_a, w_b, spacing_a, spacing_b, float(tol), _MAX_ITER, d, qa, qb)
    return d, qa, qb


def pair_distance(bodies, I: np.ndarray, J: np.ndarray, tol: float = 1e-12):
    """Compiled ``navigation.forest._pair_distance(bodies, I, J, tol)``: the rows grouped by the
    sample counts of their bodies (``_Body``: ``row``, ``pts``, ``psi``, ``w0``, ``spacing``),
    each group by :func:`pair_distance_arrays`. Returns ``(distances (K,), points_on_I (K, 2),
    points_on_J (K, 2))``."""
    K = len(I)
    d, qa, qb = np.empty(K), np.empty((K, 2)), np.empty((K, 2))
    if K == 0:
        return d, qa, qb
    groups: dict[tuple[int, int], list[int]] = {}
    for k, (i, j) in enumerate(zip(I, J)):
        groups.setdefault((len(bodies[i].pts), len(bodies[j].pts)), []).append(k)
    for rows in groups.values():
        bi = [bodies[I[k]] for k in rows]
        bj = [bodies[J[k]] for k in rows]
        out = pair_distance_arrays(
            np.array([b.row for b in bi]), np.array([b.row for b in bj]),
            np.array([b.pts for b in bi]), np.array([b.pts for b in bj]),
            np.array([b.psi for b in bi]), np.array([b.psi for b in bj]),
            np.array([b.w0 for b in bi]), np.array([b.w0 for b in bj]),
            np.array([b.spacing for b in bi]), np.array([b.spacing for b in bj]), tol)
        d[rows], qa[rows], qb[rows] = out
    return d, qa, qb
