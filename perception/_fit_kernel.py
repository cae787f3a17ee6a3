"""Compiled (numba) Levenberg-Marquardt of the squircle fit (:func:`perception.fit._lm`).

:func:`lm` is the numba port of the Levenberg-Marquardt loop of :func:`perception.fit._lm`
with the residuals and the Jacobian of its former ``_Problem`` class inside it (the numpy
versions are :func:`perception.fit._residuals` / :func:`perception.fit._residuals_jac`), over
the six parameters ``p = (cx, cy, log a, log b, theta, s)``. Same algorithm, same constants,
same arithmetic (operation by operation, no fastmath):

* residuals (:func:`_residuals_into`), rows in this order: the points' radial errors
  ``|q - c| (1 - 1 / max(g, 1e-6))`` times the weights ``wq``; the free points' penalties
  ``w_free |f - c| max(1 / max(g, 0.2) - 1, 0)``; the extent regularisation
  ``ref[2] max(a - ref[0], 0)``, ``ref[2] max(b - ref[1], 0)``;
* the Jacobian (:func:`_jacobian_into`) only of the rows that are not identically zero: every
  point, the free points inside the estimate (gauge ``< 1`` at the residuals' evaluation, where
  the penalty is active) and the two regularisation rows; exact derivatives, clamps
  differentiate to 0, then columns scaled by ``scale``;
* the residuals keep each row's ``(u, v, x, y, sqrt(T), rho)`` for the Jacobian at the same
  parameters (:func:`_residuals_keep`, :func:`_jacobian_kept`), and a free point outside the
  estimate's bounding rectangle by more than 0.2 % gets its zero penalty without its gauge (the
  gauge is at least ``max(|x|, |y|)``): the same values, bit for bit (tested against the full
  evaluation, ``kept=False``); about 35 % less time per solve on recorded fits, where free
  points outnumber the points about 3 to 1;
* damping ``mu = 1e-4 max(diag(J^T J))`` at the start, ``mu *= max(1/3, 1 - (2 rho - 1)^3)``
  after an accepted step (``rho``: actual over predicted decrease), ``mu *= nu, nu *= 2`` after a
  rejected one; steps projected onto ``[lo, hi]``; a variable at a bound (within ``1e-12``)
  that the gradient pushes outwards is frozen: the reduced system of the other variables is
  solved (built by hand: numba has no ``np.ix_``);
* stops after ``max_nfev`` residual evaluations, when an accepted step lowers the cost by less
  than ``ftol`` times itself with ``rho > 0.25``, or when the scaled step is below
  ``xtol (xtol + |x / scale|)`` (scipy's tests).

The damped systems ``(J^T J + mu I) h = -J^T r`` (of the free variables, at most 6 x 6) are
solved by Gaussian elimination with partial pivoting (:func:`_solve_into`) instead of
``np.linalg.solve`` (LAPACK ``gesv``, the same algorithm): numpy's LM stopped (``break``) where
``np.linalg.solve`` raised ``LinAlgError``, which LAPACK does for an exactly zero pivot; the
elimination reports that case and the kernel stops there too (numba's ``np.linalg.solve`` also
raises on non-finite input, where numpy's returned NaN and the step was rejected: catching its
error would stop where numpy did not; the elimination returns NaN there, like numpy). Sums
(``J^T J``, ``J^T r``, ``r . r``) are plain sequential loops, so they round differently from
numpy's BLAS: the iterates agree to rounding while the accept / reject decisions agree; a
decision made by a rounding error (``Fn < F`` with ``Fn ~ F``) can take a different, equally
good path (tested on fitting problems recorded from drives, ``tests/test_fit_kernel.py``:
parameters within ``2e-8`` scaled, costs within ``5e-11`` relative, except a near-exact fit
whose two runs stopped one step apart: ``2.5e-15`` absolute on a cost of ``7e-7``). Closed loops that feed the map
back into the robot's motion (the executive benchmark) are sensitive to such last-digit
differences: after a while their runs take other routes, as they do when numpy's result is
perturbed by ``1e-12`` relative.

Optional arguments are passed as flags with dummy arrays: ``has_ref`` (``ref`` is
``(a0, b0, weight)``) and ``has_wq`` (``wq`` the points' weights). :func:`lm` is the Python
wrapper (C-contiguous writeable float arrays via :func:`navigation._geom_kernel._arr`, one
compiled signature); :func:`residuals` and :func:`jacobian` expose the residuals and the
Jacobian rows for tests (:class:`perception.fit._Problem`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from navigation._geom_kernel import _arr

from ._shape_kernel import local_xy

__all__ = ["lm", "residuals", "jacobian"]

_JIT = dict(cache=True, nogil=True)


@numba.njit(**_JIT)
def _residuals_into(p, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, out, g):
    """Residuals at ``p`` into ``out`` (``nq + nf (+ 2)``) and the gauge of every row of ``Q``
    into ``g``."""
    c, sn = math.cos(p[4]), math.sin(p[4])
    a, b = math.exp(p[2]), math.exp(p[3])
    k = 2.0 - 4.0 * p[5] * p[5]
    N = nq + nf
    for i in range(N):
        dx, dy, u, v, x, y = local_xy(Q[i, 0], Q[i, 1], p[0], p[1], c, sn, a, b)
        x2, y2 = x * x, y * y
        T = x2 * x2 + y2 * y2 + k * x2 * y2
        gi = math.sqrt(0.5 * (x2 + y2 + math.sqrt(max(T, 0.0))))
        g[i] = gi
        rho = math.hypot(u, v)
        if i < nq:
            r = rho * (1.0 - 1.0 / max(gi, 1e-6))
            out[i] = r * wq[i] if has_wq else r
        else:
            gf = max(gi, 0.2)
            out[i] = w_free * rho * max(1.0 / gf - 1.0, 0.0)
    if has_ref:
        out[N] = ref[2] * max(a - ref[0], 0.0)
        out[N + 1] = ref[2] * max(b - ref[1], 0.0)


@numba.njit(**_JIT, inline="always")
def _jacobian_row(J, m, point, gg, R, rho, u, v, x, y, x2, y2, a, b, c, sn, s, k, wqi, has_wq, w_free):
    """Row ``m`` of the Jacobian: of a point's radial error (``point``, weighted by ``wqi`` with
    ``has_wq``) or of a free point's penalty (weighted by ``w_free``; a zero row when its gauge
    ``gg`` is not below 1), from the row's local coordinates, ``R = sqrt(T)`` and gauge."""
    R2 = 2.0 * R
    dBx = x + (2.0 * x2 * x + k * x * y2) / R2
    dBy = y + (2.0 * y2 * y + k * x2 * y) / R2
    g2 = 2.0 * gg
    gx, gy = dBx / (g2 * a), dBy / (g2 * b)
    d0 = gx * -c + gy * sn
    d1 = gx * -sn + gy * -c
    d2 = -dBx * x / g2
    d3 = -dBy * y / g2
    d4 = gx * v - gy * u
    d5 = -2.0 * s * x2 * y2 / R / g2
    rc = max(rho, 1e-300)
    dr0 = (u * -c + v * sn) / rc
    dr1 = (u * -sn + v * -c) / rc
    if point:
        if gg < 1e-6:
            d0 = d1 = d2 = d3 = d4 = d5 = 0.0
            gg = 1e-6
        f = rho / (gg * gg)
        e = 1.0 - 1.0 / gg
        J[m, 0] = f * d0 + dr0 * e
        J[m, 1] = f * d1 + dr1 * e
        J[m, 2] = f * d2
        J[m, 3] = f * d3
        J[m, 4] = f * d4
        J[m, 5] = f * d5
        if has_wq:
            for j in range(6):
                J[m, j] *= wqi
    elif gg < 1.0:
        if gg < 0.2:
            d0 = d1 = d2 = d3 = d4 = d5 = 0.0
            gg = 0.2
        f = rho / (gg * gg)
        ef = max(1.0 / gg - 1.0, 0.0)
        J[m, 0] = -(f * d0) + dr0 * ef
        J[m, 1] = -(f * d1) + dr1 * ef
        J[m, 2] = -(f * d2)
        J[m, 3] = -(f * d3)
        J[m, 4] = -(f * d4)
        J[m, 5] = -(f * d5)
        if w_free != 1.0:
            for j in range(6):
                J[m, j] *= w_free
    else:  # selected by the residuals' gauge, inactive by this one (rounding): zero row
        for j in range(6):
            J[m, j] = 0.0


@numba.njit(**_JIT, inline="always")
def _reference_rows(J, rows, m, N, ref, a, b):
    """The two regularisation rows after row ``m - 1`` (numbered ``N``, ``N + 1``); returns the
    new row count."""
    for j in range(6):
        J[m, j] = 0.0
        J[m + 1, j] = 0.0
    J[m, 2] = ref[2] * a if a > ref[0] else 0.0
    J[m + 1, 3] = ref[2] * b if b > ref[1] else 0.0
    rows[m] = N
    rows[m + 1] = N + 1
    return m + 2


@numba.njit(**_JIT)
def _jacobian_into(p, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, g, J, rows):
    """The Jacobian rows of :func:`_residuals_into` at ``p`` that are not identically zero (every
    point, the free points with gauge ``g < 1`` where ``g`` is the gauge :func:`_residuals_into`
    returned at ``p``, the regularisation rows) into ``J[:m]`` and their row numbers into
    ``rows[:m]``; returns ``m``."""
    a, b, s = math.exp(p[2]), math.exp(p[3]), p[5]
    c, sn = math.cos(p[4]), math.sin(p[4])
    k = 2.0 - 4.0 * s * s
    N = nq + nf
    m = 0
    for i in range(N):
        if i >= nq and not g[i] < 1.0:
            continue
        dx, dy, u, v, x, y = local_xy(Q[i, 0], Q[i, 1], p[0], p[1], c, sn, a, b)
        x2, y2 = x * x, y * y
        T = x2 * x2 + y2 * y2 + k * x2 * y2
        rho = math.hypot(u, v)
        R = math.sqrt(max(T, 1e-300))
        gg = math.sqrt(max(0.5 * (x2 + y2 + R), 1e-300))
        _jacobian_row(J, m, i < nq, gg, R, rho, u, v, x, y, x2, y2, a, b, c, sn, s, k,
                      wq[i] if has_wq else 1.0, has_wq, w_free)
        rows[m] = i
        m += 1
    if has_ref:
        m = _reference_rows(J, rows, m, N, ref, a, b)
    return m


@numba.njit(**_JIT)
def _residuals_keep(p, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, out, g, keep):
    """:func:`_residuals_into` (the same values in ``out``), keeping what :func:`_jacobian_kept`
    needs of every row: ``keep[i] = (u, v, x, y, sqrt(max(T, 0)), rho)``. A free point outside
    the estimate's bounding rectangle by more than 0.2 % (``|u| >= 1.002 a`` or ``|v| >= 1.002 b``,
    so ``|x|`` or ``|y| >= 1.001``; its gauge is at least ``max(|x|, |y|)`` since ``k >= -2``) has
    penalty ``w_free rho max(1 / g - 1, 0) = +0.0`` and no Jacobian row: ``out[i] = 0.0`` and
    ``g[i] = inf`` without its gauge."""
    c, sn = math.cos(p[4]), math.sin(p[4])
    a, b = math.exp(p[2]), math.exp(p[3])
    k = 2.0 - 4.0 * p[5] * p[5]
    far_ok = k >= -2.0 and w_free >= 0.0 and w_free < math.inf
    fa, fb = 1.002 * a, 1.002 * b  # |u| >= 1.002 a: |u / a| >= 1.001 (no division for the far free points)
    N = nq + nf
    for i in range(N):
        if i >= nq and far_ok:
            dx, dy = Q[i, 0] - p[0], Q[i, 1] - p[1]
            if abs(dx * c + dy * sn) >= fa or abs(dy * c - dx * sn) >= fb:
                out[i] = 0.0
                g[i] = math.inf
                continue
        dx, dy, u, v, x, y = local_xy(Q[i, 0], Q[i, 1], p[0], p[1], c, sn, a, b)
        x2, y2 = x * x, y * y
        T = x2 * x2 + y2 * y2 + k * x2 * y2
        sT = math.sqrt(max(T, 0.0))
        gi = math.sqrt(0.5 * (x2 + y2 + sT))
        g[i] = gi
        rho = math.hypot(u, v)
        keep[i, 0] = u
        keep[i, 1] = v
        keep[i, 2] = x
        keep[i, 3] = y
        keep[i, 4] = sT
        keep[i, 5] = rho
        if i < nq:
            r = rho * (1.0 - 1.0 / max(gi, 1e-6))
            out[i] = r * wq[i] if has_wq else r
        else:
            gf = max(gi, 0.2)
            out[i] = w_free * rho * max(1.0 / gf - 1.0, 0.0)
    if has_ref:
        out[N] = ref[2] * max(a - ref[0], 0.0)
        out[N + 1] = ref[2] * max(b - ref[1], 0.0)


@numba.njit(**_JIT)
def _jacobian_kept(p, nq, nf, w_free, ref, has_ref, wq, has_wq, g, keep, J, rows):
    """:func:`_jacobian_into` (the same rows, the same values) from the rows' ``(u, v, x, y,
    sqrt(max(T, 0)), rho)`` and gauge that :func:`_residuals_keep` kept at ``p``: ``T`` and the
    gauge are recomputed only where the clamps ``max(T, 1e-300)`` / ``max(B, 1e-300)`` of the
    Jacobian differ from those of the residuals."""
    a, b, s = math.exp(p[2]), math.exp(p[3]), p[5]
    c, sn = math.cos(p[4]), math.sin(p[4])
    k = 2.0 - 4.0 * s * s
    N = nq + nf
    m = 0
    for i in range(N):
        if i >= nq and not g[i] < 1.0:
            continue
        u, v, x, y, sT, rho = keep[i, 0], keep[i, 1], keep[i, 2], keep[i, 3], keep[i, 4], keep[i, 5]
        x2, y2 = x * x, y * y
        if sT > 1e-100:  # T far above 1e-300: the residuals' square root
            R = sT
        else:
            T = x2 * x2 + y2 * y2 + k * x2 * y2
            R = math.sqrt(max(T, 1e-300))
        B = 0.5 * (x2 + y2 + R)
        gg = g[i] if (R == sT and B >= 1e-300) else math.sqrt(max(B, 1e-300))
        _jacobian_row(J, m, i < nq, gg, R, rho, u, v, x, y, x2, y2, a, b, c, sn, s, k,
                      wq[i] if has_wq else 1.0, has_wq, w_free)
        rows[m] = i
        m += 1
    if has_ref:
        m = _reference_rows(J, rows, m, N, ref, a, b)
    return m


@numba.njit(**_JIT)
def _normal_equations(J, rows, m, r, scale, A, grad):
    """``A = Js^T Js``, ``grad = Js^T r[rows]`` of the first ``m`` rows of ``J`` with columns
    scaled by ``scale`` (``Js``)."""
    for j in range(6):
        grad[j] = 0.0
        for l in range(6):
            A[j, l] = 0.0
    for i in range(m):
        ri = r[rows[i]]
        for j in range(6):
            J[i, j] *= scale[j]
        for j in range(6):
            Jij = J[i, j]
            grad[j] += Jij * ri
            for l in range(j, 6):
                A[j, l] += Jij * J[i, l]
    for j in range(6):
        for l in range(j):
            A[j, l] = A[l, j]


@numba.njit(**_JIT)
def _solve_into(M, rhs, n, sol):
    """Solve the leading ``n x n`` system ``M sol = rhs`` in place (``M`` and ``rhs`` are
    overwritten) by Gaussian elimination with partial pivoting; False when a pivot is exactly zero
    (where LAPACK's ``gesv`` reports a singular matrix and ``np.linalg.solve`` raises)."""
    for kk in range(n):
        piv = kk
        big = abs(M[kk, kk])
        for i in range(kk + 1, n):
            if abs(M[i, kk]) > big:
                big = abs(M[i, kk])
                piv = i
        if M[piv, kk] == 0.0:
            return False
        if piv != kk:
            for j in range(n):
                t = M[kk, j]
                M[kk, j] = M[piv, j]
                M[piv, j] = t
            t = rhs[kk]
            rhs[kk] = rhs[piv]
            rhs[piv] = t
        d = M[kk, kk]
        for i in range(kk + 1, n):
            f = M[i, kk] / d
            if f != 0.0:
                for j in range(kk + 1, n):
                    M[i, j] -= f * M[kk, j]
                rhs[i] -= f * rhs[kk]
    for i in range(n - 1, -1, -1):
        t = rhs[i]
        for j in range(i + 1, n):
            t -= M[i, j] * sol[j]
        sol[i] = t / M[i, i]
    return True


@numba.njit(**_JIT)
def _dot(a, b, n):
    t = 0.0
    for i in range(n):
        t += a[i] * b[i]
    return t


@numba.njit(**_JIT)
def _lm_kernel(x0, lo, hi, scale, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, max_nfev, xtol, ftol, kept):
    """The Levenberg-Marquardt loop of :func:`perception.fit._lm` (module docstring); returns
    ``(x, residuals at x)``. With ``kept`` the residuals and Jacobians are those of
    :func:`_residuals_keep` / :func:`_jacobian_kept` (the same values, less arithmetic), else
    :func:`_residuals_into` / :func:`_jacobian_into`."""
    N = nq + nf
    n = N + 2 if has_ref else N
    x = x0.copy()
    r = np.empty(n)
    rn = np.empty(n)
    gx = np.empty(N)
    gn = np.empty(N)
    J = np.empty((n, 6))
    rows = np.empty(n, np.int64)
    A = np.empty((6, 6))
    grad = np.empty(6)
    M = np.empty((6, 6))
    rhs = np.empty(6)
    sol = np.empty(6)
    h = np.empty(6)
    xn = np.empty(6)
    hz = np.empty(6)
    free_ = np.empty(6, np.int64)
    kx = np.empty((N if kept else 0, 6))
    kn = np.empty((N if kept else 0, 6))
    if kept:
        _residuals_keep(x, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, r, gx, kx)
    else:
        _residuals_into(x, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, r, gx)
    F = 0.5 * _dot(r, r, n)
    if kept:
        m = _jacobian_kept(x, nq, nf, w_free, ref, has_ref, wq, has_wq, gx, kx, J, rows)
    else:
        m = _jacobian_into(x, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, gx, J, rows)
    _normal_equations(J, rows, m, r, scale, A, grad)
    nfev = 1
    mu = -1.0  # not set yet
    nu = 2.0
    while nfev < max_nfev:
        if mu < 0.0:
            dmax = A[0, 0]  # np.max(np.diag(A)), NaN propagating
            for j in range(1, 6):
                if A[j, j] > dmax or A[j, j] != A[j, j]:
                    dmax = A[j, j]
            mu = 1e-4 * max(dmax, 1e-12)
        # variables at a bound that the descent direction pushes outwards stay there
        nfree = 0
        for j in range(6):
            up = x[j] >= hi[j] - 1e-12
            down = x[j] <= lo[j] + 1e-12
            if not ((up and grad[j] < 0.0) or (down and grad[j] > 0.0)):
                free_[nfree] = j
                nfree += 1
        for j in range(6):
            h[j] = 0.0
        for jj in range(nfree):
            j = free_[jj]
            rhs[jj] = -grad[j]
            for ll in range(nfree):
                M[jj, ll] = A[j, free_[ll]]
            M[jj, jj] += mu
        if not _solve_into(M, rhs, nfree, sol):
            break  # singular (numpy: LinAlgError)
        for jj in range(nfree):
            h[free_[jj]] = sol[jj]
        hh = 0.0
        xx = 0.0
        for j in range(6):
            t = x[j] + h[j] * scale[j]
            # np.minimum(np.maximum(t, lo), hi), NaN propagating
            if t < lo[j]:
                t = lo[j]
            if t > hi[j]:
                t = hi[j]
            xn[j] = t
            hz[j] = (t - x[j]) / scale[j]
            hh += hz[j] * hz[j]
            xs = x[j] / scale[j]
            xx += xs * xs
        small = math.sqrt(hh) < xtol * (xtol + math.sqrt(xx))
        if kept:
            _residuals_keep(xn, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, rn, gn, kn)
        else:
            _residuals_into(xn, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, rn, gn)
        nfev += 1
        Fn = 0.5 * _dot(rn, rn, n)
        if math.isfinite(Fn) and Fn < F:
            gh = 0.0
            hAh = 0.0
            for j in range(6):
                gh += grad[j] * hz[j]
                Ah = 0.0
                for l in range(6):
                    Ah += hz[l] * A[l, j]
                hAh += Ah * hz[j]
            pred = -(gh + 0.5 * hAh)
            rho = (F - Fn) / pred if pred > 0 else 0.0
            x, xn = xn, x
            r, rn = rn, r
            gx, gn = gn, gx
            kx, kn = kn, kx
            dF = F - Fn
            F = Fn
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
            if (dF < ftol * F and rho > 0.25) or small:
                break
            if kept:
                m = _jacobian_kept(x, nq, nf, w_free, ref, has_ref, wq, has_wq, gx, kx, J, rows)
            else:
                m = _jacobian_into(x, Q, nq, nf, w_free, ref, has_ref, wq, has_wq, gx, J, rows)
            _normal_equations(J, rows, m, r, scale, A, grad)
        else:
            if small:
                break
            mu *= nu
            nu *= 2.0
    return x, r


def _problem_arrays(q, free, ref, wq):
    q = _arr(q).reshape(-1, 2)
    free = _arr(free).reshape(-1, 2)
    Q = _arr(np.concatenate((q, free))) if len(free) else q
    refa = _arr(ref) if ref is not None else np.zeros(3)
    wqa = _arr(wq) if wq is not None else np.zeros(1)
    return Q, len(q), len(free), refa, ref is not None, wqa, wq is not None


def lm(x0, lo, hi, scale, q, free, w_free: float, ref=None, wq=None, *, max_nfev: int = 30,
       xtol: float = 1e-4, ftol: float = 1e-4, kept: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Levenberg-Marquardt of the squircle fit (module docstring) from ``x0`` with bounds
    ``[lo, hi]``, variable scales ``scale``, points ``q (N, 2)``, free points ``free (M, 2)``
    (possibly empty), free-space weight ``w_free``, optional extent regularisation ``ref = (a0,
    b0, weight)`` and point weights ``wq (N,)``. Returns ``(x, residuals at x)``. ``kept=False``
    evaluates every row in full (:func:`_residuals_into`, :func:`_jacobian_into`): the same
    result, bit for bit (tested), more slowly."""
    Q, nq, nf, refa, has_ref, wqa, has_wq = _problem_arrays(q, free, ref, wq)
    return _lm_kernel(_arr(x0), _arr(lo), _arr(hi), _arr(scale), Q, nq, nf, float(w_free), refa, has_ref,
                      wqa, has_wq, int(max_nfev), float(xtol), float(ftol), bool(kept))


def residuals(p, q, free, w_free: float, ref=None, wq=None) -> tuple[np.ndarray, np.ndarray]:
    """``(residuals, gauge of every point and free point)`` at ``p`` (the kernel's evaluation)."""
    Q, nq, nf, refa, has_ref, wqa, has_wq = _problem_arrays(q, free, ref, wq)
    out = np.empty(nq + nf + (2 if has_ref else 0))
    g = np.empty(nq + nf)
    _residuals_into(_arr(p), Q, nq, nf, float(w_free), refa, has_ref, wqa, has_wq, out, g)
    return out, g


def jacobian(p, g, q, free, w_free: float, ref=None, wq=None) -> tuple[np.ndarray, np.ndarray]:
    """``(J, rows)``: the Jacobian rows ``rows`` of the residuals at ``p`` that are not identically
    zero (unscaled), ``g`` being the gauge :func:`residuals` returned at ``p``."""
    Q, nq, nf, refa, has_ref, wqa, has_wq = _problem_arrays(q, free, ref, wq)
    n = nq + nf + (2 if has_ref else 0)
    J = np.empty((n, 6))
    rows = np.empty(n, np.int64)
    m = _jacobian_into(_arr(p), Q, nq, nf, float(w_free), refa, has_ref, wqa, has_wq, _arr(g), J, rows)
    return J[:m], rows[:m]


def warm_up() -> float:
    """Compile (or load from numba's cache) the fit kernel with the argument types the map uses
    (see :mod:`navigation.kernels`); returns the seconds it took."""
    import time

    t0 = time.perf_counter()
    a = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    q = np.stack((np.cos(a), 0.5 * np.sin(a)), axis=1)
    x0 = np.array([0.05, -0.02, np.log(0.9), np.log(0.45), 0.1, 0.5])
    lo = np.array([-np.inf, -np.inf, -5.0, -5.0, -np.inf, 0.0])
    hi = np.array([np.inf, np.inf, 3.0, 3.0, np.inf, 0.99])
    scale = np.array([0.05, 0.05, 0.2, 0.2, 0.1, 0.1])
    lm(x0, lo, hi, scale, q, np.zeros((0, 2)), 1.0)
    lm(x0, lo, hi, scale, q, 0.5 * q, 1.0, (1.0, 0.5, 0.5), np.ones(len(q)))
    lm(x0, lo, hi, scale, q, 0.5 * q, 1.0, kept=False)
    from . import _shape_kernel  # the refit's geometry kernels

    _shape_kernel.warm_up()
    return time.perf_counter() - t0

