r"""Descent along the normalised negative gradient of a navigation function.

The holonomic use of eq. (9): from each start, follow the normalised negative gradient flow
``dq/ds = -n(q)``, ``n = grad phi_NF / |grad phi_NF|`` (only the direction is used, so saturation
of the logistic does not matter). Near obstacles the chain of maps is strongly anisotropic and
the flow runs along narrow valleys, where explicit steps zig-zag with vanishing length. Steps
are therefore *linearly implicit* (Rosenbrock-Euler, stable for stiff flows): with the exact
Hessian ``H``,

.. math::  (I + \alpha A)\,\Delta q = -\alpha n,\qquad A = (I - n n^T) H / |\nabla\phi|,

which damps the across-valley component and keeps the along-valley one. A step is accepted only
if the new point and ``checks`` points along the segment are free and the value decreases;
otherwise ``alpha`` is halved (falling back to the explicit step ``-alpha n`` when the implicit
one is not a descent direction). Many starts advance together, one vectorised evaluation per
step. Used by the tests (convergence guarantee), the picture CLI and as a reference
trajectory generator.
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


def descend_many(nf, starts, *, step: float | None = None, tol: float = 1e-3, max_steps: int = 5000,
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
        Iteration limits (per run, and per step of the line search).
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
        ok = norm > 0
        reason[active[~ok]] = "stalled"
        active, g, norm, v0, hess = active[ok], g[ok], norm[ok], ev.value[ok], ev.hessian[ok]
        if len(active) == 0:
            break
        nvec = g / norm[:, None]
        proj = np.eye(2)[None] - nvec[:, :, None] * nvec[:, None, :]
        a_mat = proj @ hess / norm[:, None, None]
        alpha = np.minimum(step, np.linalg.norm(q[active] - goal, axis=1))
        pending = np.arange(len(active))
        accepted = np.zeros(len(active), dtype=bool)
        for _ in range(max_halvings):
            if len(pending) == 0:
                break
            rows = active[pending]
            al = alpha[pending]
            sys_m = np.eye(2)[None] + al[:, None, None] * a_mat[pending]
            det = np.linalg.det(sys_m)
            safe = np.abs(det) > 1e-12
            rhs = -al[:, None] * nvec[pending]
            delta = rhs.copy()
            if np.any(safe):
                delta[safe] = np.linalg.solve(sys_m[safe], rhs[safe][:, :, None])[:, :, 0]
            length = np.linalg.norm(delta, axis=1)
            bad = ~np.isfinite(length) | ((delta * nvec[pending]).sum(1) >= 0)
            delta[bad] = rhs[bad]
            length = np.linalg.norm(delta, axis=1)
            long = length > al
            delta[long] *= (al[long] / length[long])[:, None]
            cand = q[rows] + delta
            seg = q[rows][:, None, :] + fractions[None, :, None] * delta[:, None, :]
            seg_free = nf.is_free(seg.reshape(-1, 2)).reshape(len(rows), -1).all(1)
            vc = nf.evaluate(cand, order=0)
            good = vc.free & seg_free & (vc.value < v0[pending])
            acc = pending[good]
            q[active[acc]] = cand[good]
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
