"""Guarantee: the compiled Levenberg-Marquardt of the squircle fit (``perception._fit_kernel``,
behind ``perception.fit._lm``) gives the result of the numpy LM it replaced.

The numpy LM (``_NumpyProblem`` / ``_numpy_lm`` below, a verbatim copy of the former
``perception.fit._Problem`` / ``_lm``; kept here only as the reference of the comparison) and
the kernel are run on fitting problems recorded from drives of the simulator's lidar through
``office`` (noise-free) and ``cluttered20`` (1 cm range noise): the ``_lm`` calls of
``ObstacleMap`` refits, as they are, and from randomly perturbed starts and evaluation budgets
(fixed seeds). Tolerances: parameters within ``1e-7`` in the solver's scaled variables
(``|dx| / scale``), cost ``0.5 |r|^2`` within ``1e-9`` relative plus ``1e-9 |r|`` (what
residuals within their own tolerance change it by, to first order), residual vectors within
``1e-9``, on the problems as recorded (measured on 566 problems: parameters within ``2e-8``,
residuals within ``7e-12``; costs within ``5e-11`` relative but on one problem, whose cost is
``7e-7`` (a near-exact fit), ``3.4e-9`` relative, ``2.5e-15`` absolute: the two stop one
step apart at the same point to rounding). From perturbed starts a decision can be made by a rounding error and
the paths part: there the kernel's cost is never worse than numpy's by more than ``1e-6``
relative and the parameters agree to ``1e-7`` on at least 95 % of the problems (measured: at
least 125 of 127, parameters within ``3e-8``, cost at most ``7e-10`` relative above numpy's).
Whole fits (``fit_squircle``: seeds, warm starts, completion) agree with fits by the numpy LM
within ``1e-6`` (squircle parameters) and ``1e-7`` (RMS, 95th percentile; measured ``2e-13``).
The kernel's elimination agrees with ``np.linalg.solve`` and reports the singular systems on
which it raises. No timing is asserted.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import navigation
import perception.fit as pfit
from perception import ObstacleMap, _fit_kernel
from perception.evaluation import drive, tour
from service.sim import LidarConfig, Simulator

_local = pfit._local


class _NumpyProblem:
    """The residuals of :func:`_residuals` and their Jacobian for :func:`_lm`, with the points and
    the free points in one array (one ``_local`` / gauge evaluation per call instead of two), and
    the Jacobian built only from the rows that are not identically zero there: the points, the
    free points inside the estimate (``g < 1``, where the penalty is active: outside it the
    penalty and its derivatives are 0) and the extent regularisation. Same values as
    :func:`_residuals` / :func:`_residuals_jac` (tested); a free point outside the estimate, most
    of them, costs nothing in the Jacobian. :meth:`jacobian` is evaluated where :meth:`residuals`
    was last (the accepted step of :func:`_lm`) and takes the local coordinates and the terms of
    the gauge from it (the same numbers, computed once: the arithmetic of :func:`_gauge_jac`
    with fewer array operations)."""

    __slots__ = ("Q", "nq", "nf", "w_free", "ref", "wq", "_at", "_terms")

    def __init__(self, q: np.ndarray, free: np.ndarray, w_free: float, ref=None, wq=None):
        self.nq, self.nf = len(q), len(free)
        self.Q = np.concatenate((q, free)) if len(free) else q
        self.w_free, self.ref, self.wq = w_free, ref, wq
        self._at, self._terms = None, None

    def residuals(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(residuals, g)``: :func:`_residuals` at ``p`` and the gauge of every row of ``Q``."""
        u, v = _local(p, self.Q)
        a, b = math.exp(p[2]), math.exp(p[3])
        # (:func:`_gauge_xy`, its terms kept for :meth:`jacobian`)
        x, y = u / a, v / b
        x2, y2 = x * x, y * y
        T = x2 * x2 + y2 * y2 + (2.0 - 4.0 * p[5] * p[5]) * x2 * y2
        g = np.sqrt(0.5 * (x2 + y2 + np.sqrt(np.maximum(T, 0.0))))
        rho = np.hypot(u, v)
        self._at, self._terms = p, (u, v, x, y, x2, y2, T, rho)
        nq = self.nq
        n = nq + self.nf + (0 if self.ref is None else 2)
        out = np.empty(n)
        r = rho[:nq] * (1.0 - 1.0 / np.maximum(g[:nq], 1e-6))
        out[:nq] = r if self.wq is None else r * self.wq
        if self.nf:
            gf = np.maximum(g[nq:], 0.2)
            out[nq:nq + self.nf] = self.w_free * rho[nq:] * np.maximum(1.0 / gf - 1.0, 0.0)
        if self.ref is not None:
            ref = self.ref
            out[n - 2] = ref[2] * max(a - ref[0], 0.0)
            out[n - 1] = ref[2] * max(b - ref[1], 0.0)
        return out, g

    def jacobian(self, p: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """``(J, rows)``: the rows ``rows`` of :func:`_residuals_jac` at ``p`` (``None``: all rows),
        the others being zero there; ``g`` is the gauge :meth:`residuals` returned at ``p``."""
        if self._at is not p:
            self.residuals(p)
        nq, nf = self.nq, self.nf
        rows = None
        u, v, x, y, x2, y2, T, rho = self._terms
        if nf:
            act = np.flatnonzero(g[nq:] < 1.0)
            if len(act) < nf:
                rows = np.concatenate((np.arange(nq), nq + act))
                u, v, x, y, x2, y2, T, rho = (t[rows] for t in self._terms)
            nf = len(act)
        # :func:`_gauge_jac`, term by term (the same arithmetic)
        a, b, s = math.exp(p[2]), math.exp(p[3]), p[5]
        c, sn = math.cos(p[4]), math.sin(p[4])
        k = 2.0 - 4.0 * s * s
        R = np.sqrt(np.maximum(T, 1e-300))
        gg = np.sqrt(np.maximum(0.5 * (x2 + y2 + R), 1e-300))
        R2 = 2.0 * R
        dBx = x + (2.0 * x2 * x + k * x * y2) / R2
        dBy = y + (2.0 * y2 * y + k * x2 * y) / R2
        g2 = 2.0 * gg
        gx, gy = dBx / (g2 * a), dBy / (g2 * b)
        m = len(u)
        dg = np.empty((m, 6))
        dg[:, 0] = gx * -c + gy * sn
        dg[:, 1] = gx * -sn + gy * -c
        dg[:, 2] = -dBx * x / g2
        dg[:, 3] = -dBy * y / g2
        dg[:, 4] = gx * v - gy * u
        dg[:, 5] = -2.0 * s * x2 * y2 / R / g2
        rc = np.maximum(rho, 1e-300)
        dr0 = (u * -c + v * sn) / rc
        dr1 = (u * -sn + v * -c) / rc
        n = nq + nf + (0 if self.ref is None else 2)
        J = np.empty((n, 6))
        gq, dq = gg[:nq], dg[:nq]
        clamp = gq < 1e-6
        if np.any(clamp):
            dq[clamp] = 0.0
            gq = np.maximum(gq, 1e-6)
        Jq = J[:nq]
        np.multiply((rho[:nq] / (gq * gq))[:, None], dq, out=Jq)
        e = 1.0 - 1.0 / gq
        Jq[:, 0] += dr0[:nq] * e
        Jq[:, 1] += dr1[:nq] * e
        if self.wq is not None:
            Jq *= self.wq[:, None]
        if nf:
            gf, dgf, rf = gg[nq:], dg[nq:], rho[nq:]
            active = gf < 1.0
            low = gf < 0.2
            gf = np.maximum(gf, 0.2)
            dgf[low] = 0.0
            Jf = J[nq:nq + nf]
            np.multiply((rf / (gf * gf))[:, None], dgf, out=Jf)
            np.negative(Jf, out=Jf)
            ef = np.maximum(1.0 / gf - 1.0, 0.0)
            Jf[:, 0] += dr0[nq:] * ef
            Jf[:, 1] += dr1[nq:] * ef
            if self.w_free != 1.0:
                Jf *= self.w_free
            Jf[~active] = 0.0
        if self.ref is not None:
            ref = self.ref
            J[n - 2:] = 0.0
            J[n - 2, 2] = ref[2] * a if a > ref[0] else 0.0
            J[n - 1, 3] = ref[2] * b if b > ref[1] else 0.0
            if rows is not None:
                N = self.nq + self.nf
                rows = np.concatenate((rows, (N, N + 1)))
        return J, rows


def _numpy_lm(x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, scale: np.ndarray, args: tuple, *, max_nfev: int = 30,
        xtol: float = 1e-4, ftol: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """The former numpy body of :func:`perception.fit._lm` (see its docstring), kept verbatim as
    the compiled kernel's reference."""
    prob = _NumpyProblem(*args)
    x = x0.copy()
    r, gx = prob.residuals(x)
    F = 0.5 * float(r @ r)
    J, rows = prob.jacobian(x, gx)
    J *= scale
    nfev, mu, nu = 1, None, 2.0
    eye = np.eye(len(x))
    hi_, lo_ = hi - 1e-12, lo + 1e-12
    while nfev < max_nfev:
        A = J.T @ J
        g = J.T @ (r if rows is None else r[rows])
        if mu is None:
            mu = 1e-4 * max(float(np.max(np.diag(A))), 1e-12)
        # variables at a bound that the descent direction pushes outwards stay there
        up, down = x >= hi_, x <= lo_
        free_ = ~((up & (g < 0)) | (down & (g > 0))) if (up.any() or down.any()) else None
        try:
            if free_ is None or free_.all():
                h = np.linalg.solve(A + mu * eye, -g)
            else:
                h = np.zeros_like(x)
                h[free_] = np.linalg.solve((A + mu * eye)[np.ix_(free_, free_)], -g[free_])
        except np.linalg.LinAlgError:
            break
        # (np.clip, np.linalg.norm: the same numbers without the wrappers' overhead)
        xn = np.minimum(np.maximum(x + h * scale, lo), hi)
        hz = (xn - x) / scale
        xs = x / scale
        small = math.sqrt(float(hz @ hz)) < xtol * (xtol + math.sqrt(float(xs @ xs)))
        rn, gn = prob.residuals(xn)
        nfev += 1
        Fn = 0.5 * float(rn @ rn)
        if math.isfinite(Fn) and Fn < F:
            pred = -(float(g @ hz) + 0.5 * float(hz @ A @ hz))
            rho = (F - Fn) / pred if pred > 0 else 0.0
            x, r, dF, F = xn, rn, F - Fn, Fn
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
            if (dF < ftol * F and rho > 0.25) or small:
                break
            J, rows = prob.jacobian(x, gn)
            J *= scale
        else:
            if small:
                break
            mu *= nu
            nu *= 2.0
    return x, r


# ---------------------------------------------------------------------------------------------
# recorded problems

_DRIVES = (("office", 0.0, 3), ("cluttered20", 0.01, 3))


@pytest.fixture(scope="module")
def recorded():
    """``(lm_calls, fit_calls)`` of ``ObstacleMap`` refits on short drives: every ``_lm`` call
    ``(x0, lo, hi, scale, args, kwargs, (x, r))`` and every ``fit_squircle`` call
    ``(points, kwargs, Fit)`` (the kernel running, as in the service)."""
    lm_calls, fit_calls = [], []
    lm, fit = pfit._lm, pfit.fit_squircle

    def rec_lm(x0, lo, hi, scale, args, **kw):
        out = lm(x0, lo, hi, scale, args, **kw)
        q, free, w, ref, wq = args
        lm_calls.append((x0.copy(), lo.copy(), hi.copy(), scale.copy(),
                         (q.copy(), np.array(free, float).copy(), w, ref, None if wq is None else wq.copy()),
                         dict(kw), (out[0].copy(), out[1].copy())))
        return out

    def rec_fit(points, **kw):
        f = fit(points, **kw)
        fit_calls.append((np.array(points, float).copy(),
                          {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in kw.items()}, f))
        return f

    mp = pytest.MonkeyPatch()
    mp.setattr(pfit, "_lm", rec_lm)
    mp.setattr(pfit, "fit_squircle", rec_fit)
    try:
        for name, noise, goals in _DRIVES:
            world = navigation.load_world(name)
            lidar = dataclasses.replace(LidarConfig.from_spec(world.lidar), noise_std=noise)
            sim = Simulator(world, seed=11, lidar=lidar)
            poses = tour(sim, goals, np.random.default_rng(11))
            drive(sim, ObstacleMap.from_world(world, noise_std=noise), poses)
    finally:
        mp.undo()
    assert len(lm_calls) >= 50 and len(fit_calls) >= 30
    return lm_calls, fit_calls


def _cost(r):
    return 0.5 * float(r @ r)


def _scaled_dx(x, y, scale):
    return float(np.max(np.abs(x - y) / scale))


def test_recorded_problems_cover_the_solver(recorded):
    """The recorded problems exercise free points, the regularisation, the weights and bounds
    (variables ending at a bound: the reduced systems)."""
    lm_calls, _ = recorded
    at_bound = sum(bool(np.any((x >= hi - 1e-12) | (x <= lo + 1e-12))) for _, lo, hi, _, _, _, (x, _) in lm_calls)
    assert at_bound >= 10
    assert sum(len(c[4][1]) > 0 for c in lm_calls) >= 10  # free points
    assert all(c[4][3] is not None and c[4][4] is not None for c in lm_calls)


def test_kernel_matches_numpy_lm_on_recorded_problems(recorded):
    lm_calls, _ = recorded
    for x0, lo, hi, scale, args, kw, (x, r) in lm_calls:
        xn, rn = _numpy_lm(x0, lo, hi, scale, args, **kw)
        assert _scaled_dx(x, xn, scale) <= 1e-7
        assert abs(_cost(r) - _cost(rn)) <= 1e-9 * _cost(rn) + 1e-9 * float(np.linalg.norm(rn))
        assert r.shape == rn.shape and np.allclose(r, rn, rtol=0, atol=1e-9)


@pytest.mark.parametrize("seed", range(3))
def test_kernel_matches_numpy_lm_from_perturbed_starts(recorded, seed):
    """Random starts around the recorded ones (inside the bounds, some on them), random budgets,
    ``w_free`` and with or without ``ref`` / ``wq``."""
    lm_calls, _ = recorded
    rng = np.random.default_rng(seed)
    close = 0
    for x0, lo, hi, scale, (q, free, w, ref, wq), kw, _ in lm_calls:
        x0 = np.clip(x0 + rng.normal(scale=3.0, size=6) * scale, lo, hi)
        if rng.random() < 0.2:
            x0[5] = hi[5]  # s on its upper bound
        args = (q, free if rng.random() < 0.8 else free[:0], float(rng.choice([1.0, 2.0])),
                ref if rng.random() < 0.8 else None, wq if rng.random() < 0.8 else None)
        kw = dict(max_nfev=int(rng.integers(2, 40)))
        xk, rk = pfit._lm(x0, lo, hi, scale, args, **kw)
        xn, rn = _numpy_lm(x0, lo, hi, scale, args, **kw)
        assert np.all(np.isfinite(xk)) and np.all(lo <= xk) and np.all(xk <= hi)
        assert _cost(rk) <= _cost(rn) * (1 + 1e-6) + 1e-12
        close += _scaled_dx(xk, xn, scale) <= 1e-7 and abs(_cost(rk) - _cost(rn)) <= 1e-9 * _cost(rn) + 1e-300
    assert close >= 0.95 * len(lm_calls)


def test_fit_squircle_matches_the_numpy_lm(recorded, monkeypatch):
    """Whole fits (seeds, warm starts, completion) with the kernel and with the numpy LM."""
    _, fit_calls = recorded
    monkeypatch.setattr(pfit, "_lm", _numpy_lm)
    for points, kw, f in fit_calls:
        g = pfit.fit_squircle(points, **kw)
        a, b = f.squircle, g.squircle
        assert np.allclose((*a.center, a.width, a.height, a.theta, a.s), (*b.center, b.width, b.height, b.theta, b.s),
                           rtol=0, atol=1e-6)
        assert abs(f.rms - g.rms) <= 1e-7 and abs(f.p95 - g.p95) <= 1e-7 and f.closed == g.closed


def test_problem_wrapper_is_the_kernel(recorded):
    """``fit._Problem`` (the kernel's residuals and Jacobian rows) agrees with the numpy problem
    on recorded problems at their solutions."""
    lm_calls, _ = recorded
    for _, _, _, _, args, _, (x, _) in lm_calls[::5]:
        rk, gk = pfit._Problem(*args).residuals(x)
        rn, gn = _NumpyProblem(*args).residuals(x)
        assert np.allclose(rk, rn, rtol=0, atol=1e-13) and np.allclose(gk, gn, rtol=0, atol=1e-13)
        Jk, rows_k = pfit._Problem(*args).jacobian(x, gk)
        Jn, rows_n = _NumpyProblem(*args).jacobian(x, gn)
        assert (rows_k is None) == (rows_n is None)
        assert rows_k is None or np.array_equal(rows_k, rows_n)
        assert np.allclose(Jk, Jn, rtol=0, atol=1e-12 * max(1.0, np.abs(Jn).max()))


@pytest.mark.parametrize("seed", range(2))
def test_kept_rows_are_bit_identical(recorded, seed):
    """The kernel's residuals and Jacobians from the kept row terms (``kept=True``, the default:
    free points far outside the estimate skipped) give the result of the full evaluation
    (``kept=False``) bit for bit: on the recorded problems (seed 0) and from perturbed starts,
    budgets and free-space weights (seed 1; ``s`` up to its bound, points near the centre)."""
    lm_calls, _ = recorded
    rng = np.random.default_rng(seed)
    for x0, lo, hi, scale, (q, free, w, ref, wq), kw, _ in lm_calls:
        if seed:
            x0 = np.clip(x0 + rng.normal(scale=3.0, size=6) * scale, lo, hi)
            if rng.random() < 0.2:
                x0[5] = hi[5]
            if rng.random() < 0.2:
                q = np.concatenate((q, x0[None, :2]))  # a point at the centre (T = 0)
                wq = None if wq is None else np.append(wq, 1.0)
            w = float(rng.choice([1.0, 2.0, 0.5]))
            kw = dict(max_nfev=int(rng.integers(2, 40)))
        a = _fit_kernel.lm(x0, lo, hi, scale, q, free, w, ref, wq, **kw)
        b = _fit_kernel.lm(x0, lo, hi, scale, q, free, w, ref, wq, **kw, kept=False)
        assert np.array_equal(a[0], b[0], equal_nan=True) and np.array_equal(a[1], b[1], equal_nan=True)


@pytest.mark.parametrize("n", range(1, 7))
def test_solver_matches_lapack_and_reports_singular_systems(n):
    """The kernel's elimination solves what ``np.linalg.solve`` solves, and reports the exactly
    singular systems on which ``np.linalg.solve`` raises (numpy's LM stopped there, the kernel
    too)."""
    rng = np.random.default_rng(n)
    for _ in range(50):
        J = rng.normal(size=(n + 3, n))
        M = J.T @ J + 1e-3 * np.eye(n)
        rhs = rng.normal(size=n)
        sol = np.empty(6)
        assert _fit_kernel._solve_into(np.pad(M, ((0, 6 - n), (0, 6 - n))), np.pad(rhs, (0, 6 - n)), n, sol)
        assert np.allclose(sol[:n], np.linalg.solve(M, rhs), rtol=1e-10, atol=1e-12)
    S = np.zeros((6, 6))
    S[:n, :n] = rng.normal(size=(n, n))
    S[:, 0] = 0.0  # a zero column: singular
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.solve(S[:n, :n], np.ones(n))
    assert not _fit_kernel._solve_into(S.copy(), np.ones(6), n, np.empty(6))
    # non-finite systems: no error, NaN steps (numpy's solve returns NaN, the step is rejected)
    N = np.eye(6)
    N[n - 1, 0] = np.nan
    sol = np.empty(6)
    assert _fit_kernel._solve_into(N, np.ones(6), n, sol) and np.isnan(sol[:n]).any()
