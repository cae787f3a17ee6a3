"""Numba kernels of the boundary sampling and the extreme-beta search of :mod:`navigation.forest`.

:func:`sample_rows` mirrors :func:`navigation.forest._sample_rows`: ``n`` boundary angles per
packed squircle row, evenly spaced in arc length (as :meth:`Squircle.boundary_psi`: arc length on
``8 n`` chords of the parametrisation, inverted by linear interpolation), their points, the
search window ``w0`` (1.5 x the largest angle gap) and the sample ``spacing`` (largest chord).
The chords are those of the unit squircle (same ``s``) scaled by the half-extents, as in the
numpy version; the cosines and sines of the ``8 n + 1`` grid angles are computed once (per
``n``), not per row. (Measuring the arc length on one quarter and mirroring it, which the
symmetry of a squircle allows, was 2.3 times faster and moved samples by ~1e-15, but that
perturbation changed a cluttered20 mission's path onto a perception defect, see
docs/executive.md "Motion guard": kept as it was until that is fixed.)

:func:`extreme_betas_arrays` mirrors :func:`navigation.forest._extreme_betas` with its grid
pattern search :func:`navigation.forest._pattern_min` (``m = 9``, ``shrink = 0.3``,
``tol = 1e-13``, ``max_rounds = 200``, 1-D, no rotation): per row the ``min`` (``sign = +1``) or
``max`` (``-1``) of another squircle's beta along a body's boundary. The sampled extreme is kept
when it is farther from zero than beta can change between neighbouring samples (twice the sample
spacing times the largest gradient norm of beta over the samples, paper 001 eq. 4 derivatives as
:func:`navigation.geometry.beta_gradient_rows`), else refined by the pattern search on the
boundary parameter (move to the best grid point if strictly better, else shrink the grid).

Rows are independent: a row's result does not depend on the other rows of its batch. Formulas
follow the former numpy code operation by operation (same order of floating-point operations),
so results agree to rounding; the one difference is in :func:`sample_rows`' inversion of the
arc length, which compares ``u`` with the targets directly where the numpy code compares them
after adding ``2 k`` (row ``k`` of its batch): an index may differ by one where a target lies
within an ulp of ``2 k`` of a node, which moves ``psi`` by an ulp-sized amount. The chord lengths use an inline
``hypot`` (glibc's algorithm, bit-identical to it) and the largest gradient norm computes
``hypot`` only where it can be the largest: both give numpy's values, faster. Kernels use
``error_model="numpy"``: a division by zero gives inf or NaN (as numpy) instead of raising.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from ._geom_kernel import _arr

from .geometry import COS, CX, CY, HH, HW, S, SIN

__all__ = ["sample_rows", "extreme_betas_arrays", "workspace_relation_codes", "pair_relation_codes"]

_M, _SHRINK, _TOL, _MAX_ROUNDS = 9, 0.3, 1e-13, 200  # the pattern search of _extreme_betas
_OFFS = np.linspace(-1.0, 1.0, _M)  # its grid offsets (forest._grid(9, 1))
_OFFS.flags.writeable = False
_HUGE, _TINY, _EPS = 2.0 ** 511, 2.0 ** -511, 2.0 ** -54  # glibc hypot's range limits


@functools.lru_cache(maxsize=16)
def _fine_grid(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``8 n + 1`` grid angles of :func:`sample_rows` on ``[0, 2 pi]`` with their cosines and
    sines (numpy's, as the numpy version; read-only)."""
    fine = np.linspace(0.0, 2 * np.pi, 8 * n + 1)
    out = (fine, np.cos(fine), np.sin(fine))
    for a in out:
        a.flags.writeable = False
    return out


# ---------------------------------------------------------------------- scalar formulas
@numba.njit(cache=True, error_model="numpy")
def _rho(s: float, cu: float, su: float) -> float:
    """Unit-squircle radius at the angle of cosine ``cu``, sine ``su`` (``point_at`` formula)."""
    m = cu * su
    return math.sqrt(2.0 / (1.0 + math.sqrt(max(1.0 - 4.0 * s * s * m * m, 0.0))))


@numba.njit(cache=True, error_model="numpy")
def _point(row, psi: float) -> tuple[float, float]:
    """Boundary point of packed row ``row`` at angle ``psi`` (:func:`geometry.point_at_rows`)."""
    cu, su = math.cos(psi), math.sin(psi)
    rho = _rho(row[S], cu, su)
    lx = rho * cu * row[HW]
    ly = rho * su * row[HH]
    c, sn = row[COS], row[SIN]
    return row[CX] + c * lx - sn * ly, row[CY] + sn * lx + c * ly


@numba.njit(cache=True, error_model="numpy")
def _beta(row, qx: float, qy: float) -> float:
    """Obstacle function of packed row ``row`` at ``(qx, qy)`` (:func:`forest._beta`)."""
    dx = qx - row[CX]
    dy = qy - row[CY]
    c, sn = row[COS], row[SIN]
    x = (dx * c + dy * sn) / row[HW]
    y = (dy * c - dx * sn) / row[HH]
    x2, y2 = x * x, y * y
    s = row[S]
    return 0.5 * (x2 + y2 + math.sqrt(x2 * x2 + y2 * y2 + (2.0 - 4.0 * s * s) * x2 * y2)) - 1.0


@numba.njit(cache=True, error_model="numpy")
def _beta_grad(row, ihw: float, ihh: float, k: float, qx: float, qy: float) -> tuple[float, float]:
    """Gradient of beta of packed row ``row`` at ``(qx, qy)`` given ``ihw = 1 / hw``,
    ``ihh = 1 / hh`` and ``k = 2 - 4 s^2`` (:func:`geometry.beta_gradient_rows`; NaN at the
    centre)."""
    c, sn = row[COS], row[SIN]
    dx, dy = qx - row[CX], qy - row[CY]
    x = (dx * c + dy * sn) * ihw
    y = (dy * c - dx * sn) * ihh
    x2, y2 = x * x, y * y
    d = x2 * x2 + y2 * y2 + k * x2 * y2
    i1 = 0.25 / math.sqrt(d)
    gx = x + x * (4.0 * x2 + 2.0 * k * y2) * i1
    gy = y + y * (4.0 * y2 + 2.0 * k * x2) * i1
    return gx * (c * ihw) + gy * (-sn * ihh), gx * (sn * ihw) + gy * (c * ihh)


@numba.njit(cache=True, error_model="numpy")
def _hypot(x: float, y: float) -> tuple[float, bool]:
    """``(hypot(x, y), ok)`` inline and branch-free (loops over it vectorise; three times faster
    than calling libm): the corrected ``sqrt(x^2 + y^2)`` of Borges ("An improved algorithm for
    hypot(a, b)", 2019) that glibc >= 2.35 uses without FMA, bit-identical to its ``hypot`` and
    within an ulp of any libm's. ``ok`` is false out of its range (tiny but not zero, huge,
    non-finite): the caller then uses ``math.hypot``."""
    x, y = abs(x), abs(y)
    ax, ay = max(x, y), min(x, y)
    h = math.sqrt(ax * ax + ay * ay)
    steep = h <= 2.0 * ay
    delta = h - (ay if steep else ax)
    t1 = ax * (2.0 * delta - ax) if steep else 2.0 * delta * (ax - 2.0 * ay)
    t2 = (delta - 2.0 * (ax - ay)) * delta if steep else (4.0 * delta - ay) * ay + delta * delta
    out = ax + ay if ay <= ax * _EPS else h - (t1 + t2) / (2.0 * h)
    return out, x + y <= _HUGE and (ay >= _TINY or ay == 0.0)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _nanmax(a: float, b: float) -> float:
    """``max(a, b)`` propagating NaN (as ``np.max``)."""
    return a if math.isnan(a) or a >= b else b


@numba.njit(cache=True, error_model="numpy", inline="always")
def _nanmin(a: float, b: float) -> float:
    """``min(a, b)`` propagating NaN (as ``np.min``)."""
    return a if math.isnan(a) or a <= b else b


# ---------------------------------------------------------------------- boundary samples
@numba.njit(cache=True, error_model="numpy")
def _chords(hw: float, hh: float, ux, uy, seg) -> None:
    """Chord lengths ``seg[i] = hypot(hw (ux[i+1] - ux[i]), hh (uy[i+1] - uy[i]))``."""
    bad = False
    for i in range(seg.shape[0]):  # vectorised
        seg[i], ok = _hypot(hw * (ux[i + 1] - ux[i]), hh * (uy[i + 1] - uy[i]))
        bad |= not ok
    if bad:
        for i in range(seg.shape[0]):
            x, y = hw * (ux[i + 1] - ux[i]), hh * (uy[i + 1] - uy[i])
            if not _hypot(x, y)[1]:
                seg[i] = math.hypot(x, y)


@numba.njit(cache=True, error_model="numpy")
def _order_by_s(P):
    """Row indices of ``P (K, 7)`` by increasing ``s`` (insertion sort: few rows, and
    ``np.argsort`` would double the compile time)."""
    order = np.arange(P.shape[0])
    for i in range(1, order.shape[0]):
        k, j = order[i], i
        while j > 0 and P[order[j - 1], S] > P[k, S]:
            order[j] = order[j - 1]
            j -= 1
        order[j] = k
    return order


@numba.njit(cache=True, error_model="numpy")
def _sample_kernel(P, fine, cf, sf, psi, pts, w0, spacing):
    """Fill ``psi (K, n)``, ``pts (K, n, 2)``, ``w0 (K,)``, ``spacing (K,)`` of rows ``P (K, 7)``
    from the grid angles ``fine (F,)`` and their cosines ``cf`` and sines ``sf``."""
    K, n = psi.shape
    F = fine.shape[0]
    h = fine[1] - fine[0]
    ux, uy, u, seg = np.empty(F), np.empty(F), np.empty(F), np.empty(F - 1)
    s_prev = np.nan
    for k in _order_by_s(P):  # rows of equal s share the unit chords
        row = P[k]
        s = row[S]
        if not s == s_prev:  # unit-squircle points
            for i in range(F):
                rho = _rho(s, cf[i], sf[i])
                ux[i] = rho * cf[i]
                uy[i] = rho * sf[i]
            s_prev = s
        hw, hh = row[HW], row[HH]
        _chords(hw, hh, ux, uy, seg)
        u[0] = 0.0
        for i in range(F - 1):  # arc length on the chords
            u[i + 1] = u[i] + seg[i]
        total = u[F - 1]
        for i in range(F):
            u[i] = u[i] / total
        j = 0
        for t in range(n):  # invert: last node with u <= target, linear interpolation
            target = t / n
            while j + 1 < F and u[j + 1] <= target:
                j += 1
            idx = min(j, F - 2)
            u0, u1 = u[idx], u[idx + 1]
            frac = (target - u0) / (u1 - u0 if u1 > u0 else 1.0)
            psi[k, t] = fine[idx] + frac * h
        gap, chord = -np.inf, -np.inf
        for t in range(n):
            pts[k, t, 0], pts[k, t, 1] = _point(row, psi[k, t])
        for t in range(n):
            g = (psi[k, t + 1] if t + 1 < n else psi[k, 0] + 2.0 * np.pi) - psi[k, t]
            gap = _nanmax(gap, g)
            dx = pts[k, t, 0] - pts[k, t - 1, 0]
            dy = pts[k, t, 1] - pts[k, t - 1, 1]
            chord = _nanmax(chord, math.sqrt(dx * dx + dy * dy))
        w0[k] = 1.5 * gap
        spacing[k] = chord


def sample_rows(P: np.ndarray, n: int):
    """:func:`navigation.forest._sample_rows` (numba kernel): ``n`` boundary angles per row of
    ``P (K, 7)``, evenly spaced in arc length, and ``(P, psi (K, n), pts (K, n, 2), w0 (K,),
    spacing (K,))``."""
    P = _arr(P)
    n = int(n)
    K = len(P)
    psi, pts = np.empty((K, n)), np.empty((K, n, 2))
    w0, spacing = np.empty(K), np.empty(K)
    if K and n:
        _sample_kernel(P, *_fine_grid(n), psi, pts, w0, spacing)
    return P, psi, pts, w0, spacing


# ---------------------------------------------------------------------- extreme betas
@numba.njit(cache=True, error_model="numpy")
def _max_grad_norm(other, pts, g) -> float:
    """Largest ``|grad beta|`` (``hypot``) of packed row ``other`` over the points ``pts (n, 2)``,
    NaN if any is NaN (as ``np.max``); ``g (n,)`` is scratch.

    Exactly ``max_i hypot(b_x, b_y)``, with ``hypot`` computed only where the squared norm
    ``b_x^2 + b_y^2`` (a few ulp accurate) is within ``1e-12`` of the largest one: the others
    cannot be the largest ``hypot``. Twice as fast as ``hypot`` everywhere.
    """
    ihw, ihh = 1.0 / other[HW], 1.0 / other[HH]
    k = 2.0 - 4.0 * (other[S] * other[S])
    n = pts.shape[0]
    for i in range(n):  # vectorised
        bx, by = _beta_grad(other, ihw, ihh, k, pts[i, 0], pts[i, 1])
        g[i] = bx * bx + by * by
    top, finite = -np.inf, True
    for i in range(n):
        top = max(top, g[i])
        finite &= g[i] < np.inf  # NaN, inf: hypot everywhere
    gmax = -np.inf
    for i in range(n):
        if not finite or g[i] >= top * (1.0 - 1e-12):
            gmax = _nanmax(gmax, math.hypot(*_beta_grad(other, ihw, ihh, k, pts[i, 0], pts[i, 1])))
    return gmax


@numba.njit(cache=True, error_model="numpy")
def _pattern_min(other, body, sg: float, c0: float, w0: float, f0: float, offs, shrink: float,
                 tol: float, max_rounds: int) -> tuple[float, float]:
    """One row of :func:`forest._pattern_min` (1-D) on ``sg * beta(other, point_at(body, psi))``:
    returns ``(psi, value)``."""
    c, w, best = c0, w0, f0
    for _ in range(max_rounds):  # every row does one round at least, as in the numpy version
        kb, vb = -1, np.inf
        for i in range(offs.shape[0]):  # numpy argmin: the first NaN, else the first minimum
            qx, qy = _point(body, c + w * offs[i])
            v = sg * _beta(other, qx, qy)
            if math.isnan(v):
                kb, vb = i, v
                break
            if kb < 0 or v < vb:
                kb, vb = i, v
        if vb < best:
            c = c + w * offs[kb]
            best = vb
        else:
            w *= shrink
        if not w > tol:
            break
    return c, best


@numba.njit(cache=True, error_model="numpy")
def _extreme_row(other, sg, vals, row, psi, pts, spacing, w0, offs, shrink, tol, max_rounds, scratch):
    """One row of :func:`forest._extreme_betas` (see the module docstring): ``min`` (``sg = +1``)
    or ``max`` (``-1``) of ``other``'s beta along the body ``row`` sampled at ``psi (n,)``,
    ``pts (n, 2)``, given its values ``vals (n,)`` there; ``scratch (n,)``."""
    n = vals.shape[0]
    a, va = 0, sg * vals[0]
    if not math.isnan(va):  # numpy argmin: the first NaN, else the first minimum
        for j in range(1, n):
            v = sg * vals[j]
            if math.isnan(v):
                a, va = j, v
                break
            if v < va:
                a, va = j, v
    # refine unless |va| > 2 spacing max|grad beta| + 1e-12 (NaN: refine)
    g = _max_grad_norm(other, pts, scratch)
    if not abs(va) > 2.0 * spacing * g + 1e-12:  # NaN included
        _, va = _pattern_min(other, row, sg, psi[a], w0, va, offs, shrink, tol, max_rounds)
    return sg * va


@numba.njit(cache=True, error_model="numpy")
def _extreme_kernel(others, sign, vals, rows, psi, pts, spacing, w0, offs, shrink, tol, max_rounds, out):
    """Fill ``out (K,)`` with the rows of :func:`forest._extreme_betas` (see the module docstring)."""
    K, n = vals.shape
    scratch = np.empty(n)
    for k in range(K):
        out[k] = _extreme_row(others[k], sign[k], vals[k], rows[k], psi[k], pts[k], spacing[k], w0[k], offs,
                              shrink, tol, max_rounds, scratch)


def extreme_betas_arrays(others: np.ndarray, sign: np.ndarray, vals: np.ndarray, body_rows: np.ndarray,
                         psi: np.ndarray, pts: np.ndarray, spacing: np.ndarray, w0: np.ndarray) -> np.ndarray:
    """:func:`navigation.forest._extreme_betas` (numba kernel) on stacked body fields: per row
    ``k`` the ``min`` (``sign[k] = +1``) or ``max`` (``-1``) of the beta of ``others[k] (7,)``
    along the boundary of the body ``body_rows[k]`` sampled at ``psi[k] (n,)``, ``pts[k] (n, 2)``
    (``spacing[k]``, ``w0[k]``), given the values ``vals[k] (n,)`` there. Returns ``(K,)``."""
    vals = _arr(vals)
    K = len(vals)
    out = np.empty(K)
    if K == 0:
        return out
    if vals.ndim != 2 or vals.shape[1] == 0:
        raise ValueError("extreme_betas_arrays needs vals of shape (K, n) with n >= 1")
    _extreme_kernel(_arr(others), _arr(sign), vals, _arr(body_rows), _arr(psi), _arr(pts), _arr(spacing),
                    _arr(w0), _OFFS, _SHRINK, _TOL, _MAX_ROUNDS, out)
    return out


# ---------------------------------------------------------------------- relations
#: codes of :func:`workspace_relation_codes`
WS_INSIDE, WS_OUTSIDE, WS_COVERS, WS_CROSSES, WS_CROSSES_TWICE = 0, 1, 2, 3, 4
#: codes of :func:`pair_relation_codes`
PAIR_APART, PAIR_OVERLAP, PAIR_SECOND_INSIDE, PAIR_FIRST_INSIDE = 0, 1, 2, 3


@numba.njit(cache=True, error_model="numpy")
def _beta_on(other, pts, out):
    """``beta`` of packed row ``other`` at the points ``pts (n, 2)`` into ``out (n,)``."""
    for i in range(pts.shape[0]):
        out[i] = _beta(other, pts[i, 0], pts[i, 1])


@numba.njit(cache=True, error_model="numpy")
def _ws_kernel(ws, ws_pts, idx, rows, psi, pts, spacing, w0, offs, shrink, tol, max_rounds, out):
    n = pts.shape[1]
    vals = np.empty(n)
    scratch = np.empty(n)
    wvals = np.empty(ws_pts.shape[0])
    for r in range(idx.shape[0]):
        k = idx[r]
        _beta_on(ws, pts[k], vals)
        lo, hi = np.inf, -np.inf
        for i in range(n):  # as numpy's min / max: NaN propagates
            lo = _nanmin(lo, vals[i])
            hi = _nanmax(hi, vals[i])
        code = -1
        if hi < 0.0:
            e = _extreme_row(ws, -1.0, vals, rows[k], psi[k], pts[k], spacing[k], w0[k], offs, shrink, tol,
                             max_rounds, scratch)
            if e <= 0.0:
                code = WS_INSIDE
        if lo > 0.0:
            e = _extreme_row(ws, 1.0, vals, rows[k], psi[k], pts[k], spacing[k], w0[k], offs, shrink, tol,
                             max_rounds, scratch)
            if e > 0.0:
                _beta_on(rows[k], ws_pts, wvals)
                covers = True
                for i in range(wvals.shape[0]):
                    covers &= wvals[i] <= 0.0
                code = WS_COVERS if covers else WS_OUTSIDE
        if code < 0:  # circular runs of samples outside the workspace (1 if all are)
            runs, every = 0, True
            for i in range(n):
                o = vals[i] > 0.0
                every &= o
                if o and not vals[i - 1] > 0.0:
                    runs += 1
            code = WS_CROSSES_TWICE if (not every and runs > 1) else WS_CROSSES
        out[r] = code


def workspace_relation_codes(ws_row, ws_pts, idx, rows, psi, pts, spacing, w0) -> np.ndarray:
    """:func:`navigation.forest._workspace_relations` of the bodies ``idx`` (stacked fields
    ``rows (N, 7)``, ``psi (N, n)``, ``pts (N, n, 2)``, ``spacing``, ``w0 (N,)``) and the
    workspace ``ws_row (7,)`` with boundary samples ``ws_pts``: one code per body
    (:data:`WS_INSIDE`, :data:`WS_OUTSIDE`, :data:`WS_COVERS`, :data:`WS_CROSSES`,
    :data:`WS_CROSSES_TWICE`), the same rules and extreme-beta refinement as the numpy code."""
    idx = _arr(idx, np.intp)
    out = np.empty(len(idx), np.intp)
    if len(idx):
        _ws_kernel(_arr(ws_row).reshape(7), _arr(ws_pts).reshape(-1, 2), idx, _arr(rows), _arr(psi), _arr(pts),
                   _arr(spacing), _arr(w0), _OFFS, _SHRINK, _TOL, _MAX_ROUNDS, out)
    return out


@numba.njit(cache=True, error_model="numpy")
def _pair_rel_kernel(I, J, rows, psi, pts, spacing, w0, contained, offs, shrink, tol, max_rounds, out):
    n = pts.shape[1]
    va = np.empty(n)
    vb = np.empty(n)
    scratch = np.empty(n)
    for r in range(I.shape[0]):
        a, b = I[r], J[r]
        _beta_on(rows[b], pts[a], va)  # B's beta on A's samples
        _beta_on(rows[a], pts[b], vb)
        mina, minb, maxa, maxb = np.inf, np.inf, -np.inf, -np.inf
        for i in range(n):  # as numpy's min / max: NaN propagates
            mina, maxa = _nanmin(mina, va[i]), _nanmax(maxa, va[i])
            minb, maxb = _nanmin(minb, vb[i]), _nanmax(maxb, vb[i])
        over = mina < 0.0 or minb < 0.0
        if not over:
            over = _extreme_row(rows[b], 1.0, va, rows[a], psi[a], pts[a], spacing[a], w0[a], offs, shrink, tol,
                                max_rounds, scratch) < 0.0
        code = PAIR_APART
        if over:
            if maxb <= contained and _extreme_row(rows[a], -1.0, vb, rows[b], psi[b], pts[b], spacing[b], w0[b],
                                                  offs, shrink, tol, max_rounds, scratch) <= contained:
                code = PAIR_SECOND_INSIDE
            elif maxa <= contained and _extreme_row(rows[b], -1.0, va, rows[a], psi[a], pts[a], spacing[a], w0[a],
                                                    offs, shrink, tol, max_rounds, scratch) <= contained:
                code = PAIR_FIRST_INSIDE
            else:
                code = PAIR_OVERLAP
        out[r] = code


def pair_relation_codes(I, J, rows, psi, pts, spacing, w0, contained: float) -> np.ndarray:
    """:func:`navigation.forest._pair_relations` of the body pairs ``(I[r], J[r])`` (stacked
    fields as :func:`workspace_relation_codes`, every body with the same sample count): one
    code per pair (:data:`PAIR_APART`, :data:`PAIR_OVERLAP`, :data:`PAIR_SECOND_INSIDE`: ``J``
    inside ``I`` up to ``contained`` in beta, :data:`PAIR_FIRST_INSIDE`), the same rules and
    extreme-beta refinement as the numpy code."""
    I = _arr(I, np.intp)
    J = _arr(J, np.intp)
    out = np.empty(len(I), np.intp)
    if len(I):
        _pair_rel_kernel(I, J, _arr(rows), _arr(psi), _arr(pts), _arr(spacing), _arr(w0), float(contained), _OFFS,
                         _SHRINK, _TOL, _MAX_ROUNDS, out)
    return out
