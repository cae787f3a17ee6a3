r"""Descent along the normalised negative gradient of a navigation function.

The holonomic use of eq. (9): from each start, follow the normalised negative gradient flow
``dq/ds = -n(q)``, ``n = grad phi_NF / |grad phi_NF|``. Its trajectories are those of the
gradient flow ``dq/dt = -grad phi_NF`` (``ds = |grad phi_NF| dt`` only reparametrises them), so
only their direction matters and saturation of the logistic does not. Near chained walls the
chain of maps is strongly anisotropic and the flow runs along narrow, stiff valleys (see
docs/navigation.md, "Conditioning next to chained walls"), where explicit steps zig-zag with
vanishing length.
Steps are therefore *linearly implicit* (a Rosenbrock-Euler step of the gradient flow, stable
for stiff flows): with the exact gradient ``g`` and Hessian ``H``,

.. math::  (I + \tau |H|)\,\Delta q = -\tau g,

where ``|H|`` has the eigenvectors of ``H`` and the absolute values of its eigenvalues (so the
system is positive definite and ``Delta q`` always points downhill; where ``H`` is positive
definite this is the linearised backward-Euler step). The time step ``tau`` is chosen per
point so that ``|Delta q|`` equals the wanted step length ``alpha`` (when even
``tau -> inf``, the Newton step on ``|H|``, is shorter, that step is taken): across a stiff
valley the step relaxes onto the valley floor, along it it advances ``alpha``. To first order
in ``tau`` the step is ``-tau g``, the flow itself. A step is accepted only if the new point
and ``checks`` points along the segment are free and the value decreases; otherwise ``alpha``
is halved. ``alpha`` starts at ``min(step, 4 x the previous accepted length)``. Many starts
advance together, one vectorised evaluation per step. Used by the tests (convergence
guarantee), the picture CLI and as a reference trajectory generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._arrays import as_points

__all__ = ["DescentResult", "descend", "descend_many"]


@dataclass(frozen=True)
class DescentResult:
    """One descent run.

    ``path (K, 2)`` visited points (start first); ``reached`` True when it ended within ``tol``
    of the goal; ``reason`` one of ``"goal"``, ``"stalled"`` (no decreasing free step: a
    critical point), ``"max_steps"``, ``"not_free"`` (the start was not free); ``steps``.
    """

    path: np.ndarray
    reached: bool
    reason: str
    steps: int


def descend(nf, start, **kwargs) -> DescentResult:
    """Descend from one start ``(2,)``; keyword arguments as :func:`descend_many`."""
    pts, _ = as_points(start, "start")
    if len(pts) != 1:
        raise ValueError(f"descend takes one start (2,), got shape {np.shape(start)}; use descend_many")
    return descend_many(nf, pts, **kwargs)[0]


def descend_many(nf, starts, *, step: float | None = None, tol: float = 1e-3, max_steps: int = 100_000,
                 max_halvings: int = 40, checks: int = 4) -> list[DescentResult]:
    """Descend from every row of ``starts (N, 2)`` together.

    Parameters
    ----------
    nf : NavigationFunction
    step : float, optional
        Longest step (m); default 1 % of the workspace's larger extent.
    tol : float
        Success radius around the goal (m).
    max_steps, max_halvings : int
        Iteration limits (per run, and per step of the line search). Most runs take a few
        hundred steps; runs that pass next to chained walls creep along narrow valleys of the
        field (docs/navigation.md, "Conditioning next to chained walls") with steps of 1e-5 m
        and have taken up to about 20 000 (office); the default cap leaves room for that.
    checks : int
        Interior points of each step's segment that must be free as well.
    """
    pts, _ = as_points(starts, "starts")
    ws = nf.forest.workspace
    if step is None:
        step = 0.01 * max(ws.width, ws.height)
    goal = nf.goal
    n = len(pts)
    paths = [[p.copy()] for p in pts]
    reason = np.array(["running"] * n, dtype=object)
    q = pts.copy()
    free0 = nf.is_free(q)
    reason[~free0] = "not_free"
    active = np.nonzero(free0)[0]
    steps = np.zeros(n, dtype=int)
    last = np.full(n, float(step))
    fractions = np.arange(1, checks + 1) / (checks + 1.0)
    for _ in range(max_steps):
        if len(active) == 0:
            break
        dist = np.linalg.norm(q[active] - goal, axis=1)
        done = dist <= tol
        reason[active[done]] = "goal"
        active = active[~done]
        if len(active) == 0:
            break
        ev = nf.evaluate(q[active], order=2)
        g = ev.gradient
        norm = np.linalg.norm(g, axis=1)
        ok = (norm > 0) & np.all(np.isfinite(ev.hessian), axis=(1, 2))
        reason[active[~ok]] = "stalled"
        active, g, v0, hess = active[ok], g[ok], ev.value[ok], ev.hessian[ok]
        if len(active) == 0:
            break
        lam, vec = np.linalg.eigh(hess)
        lam = np.abs(lam)
        gc = np.einsum("nij,ni->nj", vec, g)  # gradient in the eigenbasis of H
        alpha = np.minimum(np.minimum(step, 4.0 * last[active]), np.linalg.norm(q[active] - goal, axis=1))
        pending = np.arange(len(active))
        accepted = np.zeros(len(active), dtype=bool)
        for _ in range(max_halvings):
            if len(pending) == 0:
                break
            rows = active[pending]
            delta = _implicit_step(gc[pending], lam[pending], vec[pending], alpha[pending])
            cand = q[rows] + delta
            seg = q[rows][:, None, :] + fractions[None, :, None] * delta[:, None, :]
            seg_free = nf.is_free(seg.reshape(-1, 2)).reshape(len(rows), -1).all(1)
            vc = nf.evaluate(cand, order=0)
            good = vc.free & seg_free & (vc.value < v0[pending])
            acc = pending[good]
            q[active[acc]] = cand[good]
            last[active[acc]] = np.linalg.norm(delta[good], axis=1)
            accepted[acc] = True
            alpha[pending[~good]] *= 0.5
            pending = pending[~good]
        for i in active[accepted]:
            paths[i].append(q[i].copy())
            steps[i] += 1
        reason[active[~accepted]] = "stalled"
        active = active[accepted]
    reason[reason == "running"] = "max_steps"
    return [DescentResult(np.array(paths[i]), reason[i] == "goal", str(reason[i]), int(steps[i])) for i in range(n)]


def _implicit_step(gc: np.ndarray, lam: np.ndarray, vec: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """``Delta q`` solving ``(I + tau |H|) Delta q = -tau g`` with ``|Delta q| = alpha`` (module doc).

    ``gc (M, 2)`` is the gradient in the eigenbasis ``vec (M, 2, 2)`` of ``H``, ``lam (M, 2)`` the
    absolute eigenvalues. ``|Delta q|`` grows monotonically with ``tau`` (to the Newton step on
    ``|H|``), so ``tau`` is found by bisection; where even the Newton step is shorter than
    ``alpha``, it is returned.
    """
    def length(t):
        return np.linalg.norm(t[:, None] * gc / (1.0 + t[:, None] * lam), axis=1)

    gn = np.linalg.norm(gc, axis=1)
    hi = alpha / gn  # length(hi) <= alpha; grow until it reaches alpha or saturates
    lo = np.zeros_like(hi)
    for _ in range(40):
        short = length(hi) < alpha
        if not np.any(short):
            break
        lo = np.where(short, hi, lo)
        hi = np.where(short, hi * 16.0, hi)
    newton = length(hi) < alpha  # the Newton step on |H| is shorter than alpha
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        big = length(mid) > alpha
        hi = np.where(big, mid, hi)
        lo = np.where(big, lo, mid)
    with np.errstate(divide="ignore", invalid="ignore"):
        coef = np.where(newton[:, None], np.where(lam > 0, 1.0 / lam, 0.0), lo[:, None] / (1.0 + lo[:, None] * lam))
    step = np.einsum("nij,nj->ni", vec, -coef * gc)
    bad = ~np.all(np.isfinite(step), axis=1) | (np.linalg.norm(step, axis=1) == 0)
    if np.any(bad):  # the explicit step -alpha n (cannot happen with a finite, nonzero gradient)
        g = np.einsum("nij,nj->ni", vec[bad], gc[bad])
        step[bad] = -alpha[bad, None] * g / np.linalg.norm(g, axis=1)[:, None]
    return step
