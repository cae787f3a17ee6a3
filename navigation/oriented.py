"""Oriented harmonic fields (paper 001 section 4.1.2, Definition 3, eq. 20-23).

Goal: a field ``Upsilon(q)`` whose integral curves reach the goal ``q_G`` arriving along the
desired heading ``theta_G``, that equals a collision-avoiding descent field on every boundary,
and that has no attractor but the goal (Lemma 3).

What we implement, and why it differs from eq. 20-22
----------------------------------------------------
Eq. 20-22 rotate ``-grad phi_NF`` by angles built from ``sgn(.)`` terms and a switch
``s_d(phi_NF)``. Taken literally the rotation jumps wherever ``delta_theta`` changes sign (which
happens everywhere near the goal, where ``-grad phi_NF`` points at ``q_G``); interpolating the
two end rotations smoothly along the shorter arc instead leaves a cut where the dipole
direction opposes the descent direction, and on worlds with obstacles that cut can be
*attracting*: we measured integral curves that chatter across it and stop (``s_d ~ 0.5``,
opposite unit vectors average to zero) on the ``simple`` world. A rotated gradient field has no
reason to keep the navigation function's guarantees.

We keep the paper's intent (eq. 23: a field obtained from the harmonic potential that is
dipole-like at the goal with axis ``theta_G`` and descends the navigation function elsewhere)
but build it as the negated gradient of one scalar **oriented potential**, formed in the point
world of eq. 2 where harmonic functions add::

    x'       = A (Phi(q) - P_G),   A = (J J^T)^(-1/2),   J = dPhi/dq at q_G
    phi_O(x') = ln|x'|^2 - (1/K) sum_j ln|x' - P'_j|^2 + c x'.p / |x'|^2,   P'_j = A (P_j - P_G)
    phi_ONF(q) = mu * logistic(phi_O(x'(q)))             (eq. 9 applied to phi_O)
    Upsilon(q) = -grad phi_ONF(q)                          (eq. 23 with Gamma folded in)

``Phi`` is the navigation transformation (diffeomorphism free space -> point world), ``P_G`` the
goal image, ``P_j`` the point obstacles. The linear map ``A`` makes the Jacobian of
``q -> x'`` at the goal the rotation ``A J`` (the point world stays a point world: ``x'`` is still
a diffeomorphic image of free space). The last term is a harmonic **dipole** at the goal with
axis ``p = A J p_G`` (``p_G = (cos theta_G, sin theta_G)``, a unit vector since ``A J`` is a
rotation) and strength ``c > 0``. Without the normalisation a dipole cannot be aimed at every
heading: for a non-conformal ``J`` the q-space gradient flow of a point-world dipole has no
stable inflow in a cone around ``J``'s major axis (measured), because gradients do not push
forward like tangent vectors. Consequences, each a guarantee:

* ``phi_O`` is harmonic in ``x'`` away from the goal and the ``P'_j`` (sum of harmonic
  functions), so it has no local minimum or maximum there, only saddles; it tends to ``+inf`` at
  every ``P_j`` and at infinity (the images of the obstacle and workspace boundaries, where the
  logarithms dominate the bounded dipole term), so ``phi_ONF -> mu`` on every boundary and
  ``-grad phi_ONF`` points away from every boundary (no collision);
* near the goal the dipole ``c cos(angle)/|x'|`` dominates the logarithm: ``phi_O -> -inf``
  only from behind the goal (``x'.p < 0``), and the integral curves of the dipole are the circles
  through the goal tangent to ``p``, all entering it from behind; since ``x' ~ (A J)(q - q_G)``
  with ``A J`` a rotation, the q-space gradient curves enter ``q_G`` along ``p_G``: arrival with
  heading ``theta_G``;
* the field is the gradient of one smooth function: it is smooth everywhere in free space except
  at the goal itself, and its Jacobian ``-Hess phi_ONF`` is exact (forward-mode jets through the
  chain, analytic derivatives in the point world).

``c`` (``strength``, in metres since ``x'`` is locally a rotated copy of ``q - q_G``) sets how far
from the goal the dipole takes over; the default is ``DIPOLE_FRACTION = 0.3`` times the goal's
exact clearance to the nearest obstacle or the workspace boundary.

The controller needs only the *direction* ``theta_gamma`` of ``Upsilon`` and its gradient; both
are computed from ``phi_O`` (the logistic does not change directions), so they stay accurate
where ``phi_ONF`` saturates next to boundaries.

Push-forward direction
----------------------
:meth:`OrientedField.evaluate` also returns ``flow_angle``, the direction of
``-(dx'/dq)^(-1) grad_x' phi_O`` (the gradient of ``phi_ONF`` for the metric pulled back from
the normalised point world), and its exact gradient ``flow_gradient`` (second derivatives of the
chain from the same jets). Its integral curves are the preimages of the point world's gradient
curves, so everything above holds for them too, exactly rather than only at the goal: ``phi_ONF``
decreases along them (``grad phi_ONF . flow = -mu logistic' |grad_x' phi_O|^2 < 0``), they
reach no boundary, the critical points are the same, and at the goal ``dx'/dq = A J`` is a
rotation, so they arrive along ``theta_G``. Where ``dPhi/dq`` is strongly anisotropic (singular
values 50 to 1 and more inside free space on ``simple`` and ``office``) the direction of ``Upsilon``
itself is pinned to plus or minus the major singular direction and flips across thin folds
(``|grad theta_gamma|`` 10^2-10^4 rad/m); the push-forward direction follows the point world's
curves through such regions (measured on ``office``: 99th percentile of
``|grad theta|`` 134 rad/m for ``Upsilon``, 33 rad/m for the push-forward). Next to a grown
boundary it turns tangential (``dPhi/dq`` collapses the boundary to a point), while ``Upsilon``
points out of it. ``Upsilon`` (``field``, ``jacobian``, ``angle``) is unchanged;
:func:`navigation.control.track` uses the push-forward direction only with
``ControllerConfig(push_forward=True)``.

:meth:`OrientedField.boundary_frame` (first-order distances and normals of the grown boundaries
near a point, exact gradients; :meth:`OrientedField.boundary_scan` evaluates the boundaries once
for several reaches) and :attr:`OrientedField.goal_clearance` serve the controller's
opt-in stand-off (:mod:`navigation.control`); they are not part of the field.

Evaluation: at free points the chain's jets and everything above (``phi_O``, the field, its
Jacobian, both directions and their gradients) run point by point in the compiled kernel
:func:`navigation._chain_kernel.oriented`; :meth:`OrientedField._core_numpy` is the numpy
reference it is tested against (``tests/test_chain_kernel.py``, equal to rounding).

Degenerate points: the goal itself (``|q - q_G| < GOAL_TOLERANCE``) and critical points
(``|grad phi_O| < GRADIENT_FLOOR``) are flagged ``degenerate``: field 0, direction ``theta_G``
(goal) or 0, zero derivatives. Outside free space the navigation function's outside contract
applies: the field is the unit vector back into free space (``-nf.gradient``), flagged
``free = False``. Values are always finite.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from . import _chain_kernel
from ._arrays import as_points, restore
from ._jet import Jet, logistic
from .clearance import forest_clearance
from .errors import NavigationError, OutsideFreeSpaceError
from .geometry import _beta_derivatives, pack

__all__ = ["OrientedField", "OrientedEval", "BoundaryFrame", "BoundaryScan", "wrap_angle", "DIPOLE_FRACTION",
           "GRADIENT_FLOOR", "GOAL_TOLERANCE"]

DIPOLE_FRACTION = 0.3
_COMPILED = True  #: evaluate the field in the compiled kernel (False: the numpy reference)
GRADIENT_FLOOR = 1e-300
GOAL_TOLERANCE = 1e-9


def wrap_angle(a):
    """Wrap angles to ``(-pi, pi]`` (array or float)."""
    w = np.remainder(np.asarray(a, dtype=float) + np.pi, 2.0 * np.pi) - np.pi
    w = np.where(w == -np.pi, np.pi, w)
    return w if np.ndim(w) else float(w)


@dataclass(frozen=True)
class OrientedEval:
    """The oriented field at ``N`` points (unbatched arrays for a ``(2,)`` input).

    Attributes
    ----------
    value : (N,)
        ``phi_ONF`` in ``[0, mu]``.
    field : (N, 2)
        ``Upsilon = -grad phi_ONF`` (eq. 23).
    jacobian : (N, 2, 2)
        ``J[n, i, j] = d Upsilon_i / d q_j``.
    angle : (N,)
        Direction ``theta_gamma`` of the field, in ``(-pi, pi]``.
    angle_gradient : (N, 2)
        Exact ``grad theta_gamma`` (0 at degenerate points).
    free : (N,) bool
        Free-space flag of the navigation function.
    degenerate : (N,) bool
        Goal or critical point: the field vanishes and its direction is conventional.
    flow_angle : (N,)
        Direction of the push-forward flow ``-(dx'/dq)^(-1) grad_x' phi_O`` (see the module
        doc, "Push-forward direction"), in ``(-pi, pi]``; equal to ``angle`` outside free space,
        at the goal and at critical points.
    flow_gradient : (N, 2)
        Exact gradient of ``flow_angle``.
    potential_gradient, potential_hessian : (N, 2), (N, 2, 2)
        Gradient and Hessian of the oriented potential ``phi_O`` (before the logistic) with
        respect to ``q`` (zeros outside free space and at degenerate points); the controller's
        relaxed direction (:mod:`navigation.control`) uses them.
    """

    value: np.ndarray
    field: np.ndarray
    jacobian: np.ndarray
    angle: np.ndarray
    angle_gradient: np.ndarray
    free: np.ndarray
    degenerate: np.ndarray
    flow_angle: np.ndarray
    flow_gradient: np.ndarray
    potential_gradient: np.ndarray
    potential_hessian: np.ndarray


class BoundaryFrame(NamedTuple):
    """Grown boundaries near a point (:meth:`OrientedField.boundary_frame`,
    :meth:`BoundaryScan.frame`); every gradient exact.

    Attributes
    ----------
    weight, weight_gradient : float, (2,)
        Band weight ``1 - prod_i (1 - w_i)``, ``w_i = smoothstep(2 (reach - delta_i) / reach)``
        (1 within ``reach / 2`` of a boundary, 0 beyond ``reach`` of all).
    angle, angle_gradient : float, (2,)
        Direction of the weighted normal ``sum_i w_i nu_i`` (into free space).
    distance, distance_gradient : float, (2,)
        ``delta`` of the nearest boundary (first-order distance).
    normal, normal_jacobian : (2,), (2, 2)
        Unit normal ``nu`` of the nearest boundary and ``d nu / d q``.
    """

    weight: float
    weight_gradient: np.ndarray
    angle: float
    angle_gradient: np.ndarray
    distance: float
    distance_gradient: np.ndarray
    normal: np.ndarray
    normal_jacobian: np.ndarray


class BoundaryScan:
    """The grown boundaries within ``reach`` of one point (:meth:`OrientedField.boundary_scan`),
    evaluated once: per boundary ``i`` (forest order) the first-order distance ``delta_i``, the
    unit normal ``nu_i`` into free space and their exact gradients.

    :meth:`frame` gives the :class:`BoundaryFrame` for any reach up to ``reach``: a smaller reach
    only drops the boundaries beyond it and narrows the band weights, the per-boundary values do
    not depend on it. The frame is the one :meth:`OrientedField.boundary_frame` returns for that
    reach, bit for bit (``boundary_frame`` is ``boundary_scan(q, r).frame(r)``, and each
    per-boundary value is computed row by row); the controller's stand-off reads its three
    reaches from one scan per field and pose.
    """

    __slots__ = ("reach", "_delta", "_grad_delta", "_nu", "_dnu")

    def __init__(self, reach: float, delta: np.ndarray, grad_delta: np.ndarray, nu: np.ndarray,
                 dnu: np.ndarray):
        self.reach = reach
        self._delta, self._grad_delta, self._nu, self._dnu = delta, grad_delta, nu, dnu

    def __repr__(self) -> str:
        return f"BoundaryScan(reach={self.reach:.4g}, boundaries={len(self._delta)})"

    def frame(self, reach: float) -> "BoundaryFrame | None":
        """:class:`BoundaryFrame` of the boundaries within ``reach`` (at most the scan's), or
        ``None`` when none is that close or their weighted normals cancel.

        Raises
        ------
        ValueError
            ``reach`` exceeds the scan's (boundaries beyond it were not evaluated).
        """
        reach = float(reach)
        if not (math.isfinite(reach) and reach > 0):
            return None
        if reach > self.reach:
            raise ValueError(f"reach {reach} exceeds the scan's {self.reach}")
        sel = self._delta < reach
        if not sel.any():
            return None
        delta, grad_delta, nu, dnu = (a[sel] for a in (self._delta, self._grad_delta, self._nu, self._dnu))
        t = np.clip(2.0 * (reach - delta) / reach, 0.0, 1.0)
        w = t * t * (3.0 - 2.0 * t)
        dw = (6.0 * t * (1.0 - t) * (-2.0 / reach))[:, None] * grad_delta
        one = 1.0 - w
        weight = 1.0 - float(np.prod(one))
        grad_weight = np.zeros(2)
        for i in range(len(w)):
            grad_weight += dw[i] * float(np.prod(np.delete(one, i)))
        N = (w[:, None] * nu).sum(0)
        dN = (nu[:, :, None] * dw[:, None, :] + w[:, None, None] * dnu).sum(0)
        n2 = float(N @ N)
        if not n2 > 1e-12:
            return None
        angle = math.atan2(N[1], N[0])
        angle_gradient = (N[0] * dN[1] - N[1] * dN[0]) / n2
        i = int(np.argmin(delta))
        out = BoundaryFrame(weight, grad_weight, angle, angle_gradient, float(delta[i]), grad_delta[i],
                            nu[i], dnu[i])
        finite = all(np.isfinite(np.asarray(v, dtype=float)).all() for v in out)
        return out if finite else None  # pragma: no cover (finite)


class OrientedField:
    """Oriented harmonic field to the goal pose ``(nf.goal, heading)`` (see the module doc).

    Parameters
    ----------
    nf : NavigationFunction
        Navigation function whose goal is the goal position (its forest, chain and ``K``,
        ``mu`` are reused; nothing is rebuilt).
    heading : float
        Desired arrival heading ``theta_G`` (radians).
    strength : float, optional
        Dipole strength ``c`` in point-world units; default from :data:`DIPOLE_FRACTION`.

    Raises
    ------
    NavigationError
        Non-finite heading or non-positive strength.

    Examples
    --------
    >>> import navigation
    >>> nf = navigation.NavigationFunction(navigation.load_world("simple"), goal=(1.0, 1.0))
    >>> field = OrientedField(nf, heading=0.0)
    >>> field.field([[0.5, 0.5]]).shape
    (1, 2)
    """

    def __init__(self, nf, heading: float, *, strength: float | None = None):
        heading = float(heading)
        if not math.isfinite(heading):
            raise NavigationError(f"heading must be finite, got {heading}")
        self.nf = nf
        self.heading = wrap_angle(heading)
        self.goal = np.asarray(nf.goal, dtype=float).reshape(2)
        self.mu = float(nf.params.mu)
        self._inv_k = 1.0 / float(nf.params.K)
        self._points = np.asarray(nf.point_obstacles, dtype=float).reshape(-1, 2)
        # Linear normalisation of the point world at the goal: x' = A (x - P_G) with
        # A = (J J^T)^(-1/2), so that A J (the Jacobian of q -> x' at the goal) is a rotation.
        pg, J = nf.goal_transform()  # (one chain evaluation gives P_G and J)
        self._pg = np.asarray(pg, dtype=float).reshape(2).copy()
        w, V = np.linalg.eigh(J @ J.T)
        A = (V / np.sqrt(w)) @ V.T
        self._A = A
        self._points = (self._points - self._pg) @ A.T
        axis = A @ J @ np.array([math.cos(self.heading), math.sin(self.heading)])
        self._axis = axis / np.linalg.norm(axis)
        self.clearance = forest_clearance(nf.forest)
        """Certified lower bound ``q -> d`` on the distance to the field's obstacles and
        workspace boundary (:class:`~navigation.clearance.ClearanceBound`; the obstacles are
        those the navigation function was built on, grown by its ``inflation``)."""
        if strength is None:
            strength = DIPOLE_FRACTION * max(self.clearance.exact(self.goal), 1e-6)
        strength = float(strength)
        if not (math.isfinite(strength) and strength > 0):
            raise NavigationError(f"strength must be a positive finite number, got {strength}")
        self.strength = strength

    def __repr__(self) -> str:
        return (f"OrientedField(goal={self.goal.tolist()}, heading={self.heading:.4f}, "
                f"strength={self.strength:.4g})")

    # ------------------------------------------------------------------ public queries
    def field(self, q) -> np.ndarray:
        """``Upsilon(q)``, shape ``(2,)`` or ``(N, 2)``."""
        pts, single = as_points(q, "q")
        return restore(self._evaluate(pts).field, single)

    def jacobian(self, q) -> np.ndarray:
        """Exact Jacobian of ``Upsilon``, shape ``(2, 2)`` or ``(N, 2, 2)``."""
        pts, single = as_points(q, "q")
        return restore(self._evaluate(pts).jacobian, single)

    def direction(self, q):
        """``(theta_gamma, grad theta_gamma)``: the field's direction and its exact gradient."""
        pts, single = as_points(q, "q")
        ev = self._evaluate(pts)
        return restore(ev.angle, single), restore(ev.angle_gradient, single)

    @property
    def goal_clearance(self) -> float:
        """Exact clearance of the goal (distance to the nearest grown obstacle or the workspace
        boundary), computed once."""
        c = getattr(self, "_goal_clearance", None)
        if c is None:
            c = self._goal_clearance = float(self.clearance.exact(self.goal))
        return c

    def boundary_frame(self, q, reach: float) -> "BoundaryFrame | None":
        """Boundaries of the field's forest within ``reach`` of one point ``q (2,)`` (see
        :class:`BoundaryFrame`), or ``None`` when none is that close, ``q`` is not in free space,
        or the weighted normals cancel. Not part of the oriented field; used by the
        controller's stand-off (:mod:`navigation.control`).

        For every obstacle of the forest (grown by the inflation) and the workspace boundary,
        ``delta_i = sigma_i beta_i / |grad beta_i|`` is the first-order (one Newton step)
        distance to its boundary (``sigma = +1`` for obstacles, ``-1`` for the workspace) and
        ``nu_i = sigma_i grad beta_i / |grad beta_i|`` the unit normal into free space; all
        derivatives are exact (Hessians of ``beta``).

        Same as ``boundary_scan(q, reach).frame(reach)``; for several reaches at one point, scan
        once with the largest (:meth:`boundary_scan`)."""
        scan = self.boundary_scan(q, reach)
        return None if scan is None else scan.frame(reach)

    def boundary_scan(self, q, reach: float) -> "BoundaryScan | None":
        """The per-boundary part of :meth:`boundary_frame` at one point ``q (2,)``, for the
        boundaries within ``reach``: evaluated once, it gives the frame for any reach up to
        ``reach`` (:meth:`BoundaryScan.frame`) without re-evaluating the boundaries. ``None``
        when ``q`` is not in free space or no boundary is within ``reach`` (then every frame up
        to ``reach`` is ``None``)."""
        q = np.asarray(q, dtype=float).reshape(2)
        reach = float(reach)
        if not (math.isfinite(reach) and reach > 0):
            return None
        rows = getattr(self, "_boundary_rows", None)
        if rows is None:
            forest = self.nf.forest
            rows = pack(tuple(forest.obstacles) + (forest.workspace,))
            sign = np.ones(len(rows))
            sign[-1] = -1.0
            self._boundary_rows = rows = (rows, sign)
        P, sign = rows
        with np.errstate(all="ignore"):
            b, bx, by, bxx, bxy, byy = _beta_derivatives(P, q[0], q[1])
            L2 = bx * bx + by * by
            L = np.sqrt(L2)
            delta = sign * b / L
        near = (np.isfinite(delta) & np.isfinite(bxx) & np.isfinite(bxy) & np.isfinite(byy) & (L2 > 0)
                & (delta < reach))
        if (sign * b <= 0).any() or not near.any():
            return None  # on or inside an obstacle / outside the workspace, or far from every boundary
        b, bx, by, bxx, bxy, byy, L, L2, delta, sg = (a[near] for a in (b, bx, by, bxx, bxy, byy, L, L2,
                                                                       delta, sign))
        g = np.stack([bx, by], 1)  # (k, 2)
        H = np.stack([np.stack([bxx, bxy], 1), np.stack([bxy, byy], 1)], 1)  # (k, 2, 2)
        Hg = np.einsum("kij,kj->ki", H, g)
        grad_delta = sg[:, None] * (g / L[:, None] - b[:, None] * Hg / (L2 * L)[:, None])
        nu = sg[:, None] * g / L[:, None]
        ghat = g / L[:, None]
        proj = np.eye(2)[None] - ghat[:, :, None] * ghat[:, None, :]
        dnu = sg[:, None, None] * (proj @ H) / L[:, None, None]  # d nu_i / d q_j
        return BoundaryScan(reach, delta, grad_delta, nu, dnu)

    def evaluate(self, q) -> OrientedEval:
        """Everything at once (see :class:`OrientedEval`); unbatched for ``(2,)`` input."""
        pts, single = as_points(q, "q")
        ev = self._evaluate(pts)
        if not single:
            return ev
        return OrientedEval(*(getattr(ev, f.name)[0] for f in fields(OrientedEval)))

    # ------------------------------------------------------------------ evaluation
    def _potential_jet(self, x: Jet, y: Jet) -> Jet:
        """Jet of ``phi_O`` at normalised point-world coordinates ``x' = (x, y)`` (goal at 0)."""
        return Jet.compose2(*self._potential_derivatives(x.v, y.v), x, y)

    def _potential_derivatives(self, rx: np.ndarray, ry: np.ndarray):
        """``phi_O`` and its first and second derivatives w.r.t. ``x' = (rx, ry)``: the sink
        ``ln |x'|^2``, the dipole ``c (x'.p)/|x'|^2`` and the point obstacles
        ``-(1/K) sum_j ln |x' - P'_j|^2`` (compiled: :func:`navigation._chain_kernel.potential_rows`,
        the formulas the field's kernel uses)."""
        rx = np.ascontiguousarray(rx, dtype=float).reshape(-1)
        ry = np.ascontiguousarray(ry, dtype=float).reshape(-1)
        out = np.empty((len(rx), 6))
        _chain_kernel.potential_rows(rx, ry, float(self.strength), self._axis, self._points, self._inv_k, out)
        return tuple(out[:, j] for j in range(6))

    def _evaluate(self, pts: np.ndarray) -> OrientedEval:
        n = len(pts)
        mu = self.mu
        value = np.full(n, mu)
        field = np.zeros((n, 2))
        jac = np.zeros((n, 2, 2))
        angle = np.zeros(n)
        grad_angle = np.zeros((n, 2))
        flow_angle = np.zeros(n)
        flow_gradient = np.zeros((n, 2))
        pot_g = np.zeros((n, 2))
        pot_h = np.zeros((n, 2, 2))
        free = np.asarray(self.nf.is_free(pts), dtype=bool).reshape(n)
        at_goal = np.linalg.norm(pts - self.goal, axis=1) < GOAL_TOLERANCE
        degenerate = at_goal & free
        angle[degenerate] = self.heading
        flow_angle[degenerate] = self.heading
        value[degenerate] = 0.0
        idx = np.nonzero(free & ~at_goal)[0]
        if len(idx):
            x, y = self.nf.chain.apply(*Jet.variables(pts[idx], 2))
            core = self._core_compiled if _COMPILED else self._core_numpy
            (value[idx], field[idx], jac[idx], angle[idx], grad_angle[idx], flat, g, H,
             flow_angle[idx], flow_gradient[idx]) = core(x, y)
            degenerate[idx] = flat
            # the potential's derivatives where they are regular and finite, else zeros
            ok = ~flat & np.isfinite(g).all(axis=1) & np.isfinite(H).all(axis=(1, 2))
            pot_g[idx] = np.where(ok[:, None], g, 0.0)
            pot_h[idx] = np.where(ok[:, None, None], H, 0.0)
        out = np.nonzero(~free)[0]
        if len(out):
            back = -np.asarray(self.nf.evaluate(pts[out], order=1).gradient)
            field[out] = back
            angle[out] = np.arctan2(back[:, 1], back[:, 0])
            flow_angle[out] = angle[out]
        if not (np.isfinite(field).all() and np.isfinite(jac).all() and np.isfinite(grad_angle).all()
                and np.isfinite(flow_gradient).all()):
            raise OutsideFreeSpaceError("oriented field is not finite here")  # pragma: no cover
        return OrientedEval(value, field, jac, wrap_angle(angle), grad_angle, free, degenerate,
                            wrap_angle(flow_angle), flow_gradient, pot_g, pot_h)

    def _core_numpy(self, x: Jet, y: Jet):
        """The field at free points away from the goal from the chain's jets ``x``, ``y``:
        ``(value, field, jacobian, angle, angle_gradient, flat, gradient and Hessian of phi_O,
        flow_angle, flow_gradient)`` (numpy; the reference of :meth:`_core_compiled`)."""
        mu = self.mu
        m = len(x)
        a = self._A
        cx, cy = x - self._pg[0], y - self._pg[1]
        X, Y = cx * a[0, 0] + cy * a[0, 1], cx * a[1, 0] + cy * a[1, 1]
        f, fx, fy, fxx, fxy, fyy = self._potential_derivatives(X.v, Y.v)
        phi = Jet.compose2(f, fx, fy, fxx, fxy, fyy, X, Y)
        v = phi.v
        g = phi.g  # (M, 2) gradient of phi_O w.r.t. q
        H = phi.hessian()  # (M, 2, 2)
        s = logistic(v)
        sc = s * logistic(-v)  # logistic'
        scc = sc * (logistic(-v) - s)  # logistic''
        value = mu * s
        # Upsilon = -mu logistic'(phi) grad phi ; J = -mu (logistic'' g g^T + logistic' H)
        field = -mu * sc[:, None] * g
        jac = -mu * (scc[:, None, None] * g[:, :, None] * g[:, None, :] + sc[:, None, None] * H)
        a = -g
        m2 = np.einsum("ni,ni->n", a, a)
        flat = ~(m2 > GRADIENT_FLOOR)
        safe = np.where(flat, 1.0, m2)
        angle = np.where(flat, 0.0, np.arctan2(a[:, 1], a[:, 0]))
        # d atan2(a_y, a_x)/dq = (a_x grad a_y - a_y grad a_x)/|a|^2 with grad a = -H
        ga = (-a[:, 0, None] * H[:, 1, :] + a[:, 1, None] * H[:, 0, :]) / safe[:, None]
        grad_angle = np.where(flat[:, None], 0.0, ga)
        flow_angle, flow_gradient = angle.copy(), grad_angle.copy()
        self._flow(X, Y, fx, fy, fxx, fxy, fyy, ~flat, np.arange(m), flow_angle, flow_gradient)
        return value, field, jac, angle, grad_angle, flat, g, H, flow_angle, flow_gradient

    def _core_compiled(self, x: Jet, y: Jet):
        """:meth:`_core_numpy` in the compiled kernel :func:`navigation._chain_kernel.oriented`
        (the same formulas point by point; equal to rounding)."""
        m = len(x)
        out_s, out_v, out_f = np.empty((m, 5)), np.empty((m, 8)), np.empty((m, 7))
        _chain_kernel.oriented(np.ascontiguousarray(x.a), np.ascontiguousarray(y.a), self._pg, self._A,
                               float(self.strength), self._axis, self._points, self._inv_k, self.mu,
                               GRADIENT_FLOOR, out_s, out_v, out_f)
        flow = out_s[:, 3] > 0.5
        return (out_s[:, 0], out_v[:, 0:2], out_f[:, 0:4].reshape(m, 2, 2), out_s[:, 1], out_v[:, 2:4],
                out_s[:, 2] > 0.5, out_v[:, 6:8], out_f[:, [4, 5, 5, 6]].reshape(m, 2, 2),
                np.where(flow, out_s[:, 4], out_s[:, 1]), np.where(flow[:, None], out_v[:, 4:6], out_v[:, 2:4]))

    @staticmethod
    def _flow(X: Jet, Y: Jet, fx, fy, fxx, fxy, fyy, regular, idx, flow_angle, flow_gradient) -> None:
        """Direction of the push-forward flow ``-(dx'/dq)^(-1) grad_x' phi_O`` and its exact
        gradient, written into ``flow_angle[idx]``, ``flow_gradient[idx]`` where the point-world
        gradient is not degenerate (``regular``) and ``dx'/dq`` is invertible; elsewhere the
        values already there (those of ``Upsilon``) stay.

        With ``J = dx'/dq`` and ``g = grad_x' phi_O(x'(q))``, ``w = J^(-1) g`` has the derivative
        ``dw/dq = J^(-1) (H_x' J - T)``, ``T_ik = sum_j (d^2 x'_i / dq_j dq_k) w_j``."""
        J = np.stack([X.g, Y.g], axis=1)  # J[m, i, j] = d x'_i / d q_j
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        ok = regular & np.isfinite(det) & (np.abs(det) > 0)
        if not ok.any():
            return
        J = J[ok]
        g = np.stack([fx, fy], axis=1)[ok]
        H = np.stack([np.stack([fxx, fxy], 1), np.stack([fxy, fyy], 1)], 1)[ok]
        w = np.linalg.solve(J, g[..., None])[..., 0]
        second = np.stack([X.hessian(), Y.hessian()], axis=1)[ok]  # d^2 x'_i / dq_j dq_k
        dw = np.linalg.solve(J, H @ J - np.einsum("mijk,mj->mik", second, w))
        m2 = np.einsum("mi,mi->m", w, w)
        good = np.isfinite(m2) & (m2 > GRADIENT_FLOOR) & np.isfinite(dw).all(axis=(1, 2))
        sel = np.nonzero(ok)[0][good]
        w, dw, m2 = w[good], dw[good], m2[good]
        # direction of a = -w; d atan2(a_y, a_x) = (a_x grad a_y - a_y grad a_x)/|a|^2, grad a = -dw
        flow_angle[idx[sel]] = np.arctan2(-w[:, 1], -w[:, 0])
        flow_gradient[idx[sel]] = (w[:, 0, None] * dw[:, 1, :] - w[:, 1, None] * dw[:, 0, :]) / m2[:, None]
