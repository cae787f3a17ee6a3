"""Harmonic navigation functions on forests of squircles (paper 001 eq. 2 and 9).

``NavigationFunction(world, goal)`` composes the chain of :mod:`navigation.transforms`
(forest -> star -> sphere -> point world) with the harmonic potential of eq. (2),

.. math::

    \\phi_P(x) = \\ln\\|x - P_G\\|^2 - \\frac{1}{K} \\sum_{j=1}^{N} \\ln\\|x - P_j\\|^2,

and maps it to ``(0, mu)`` with the logistic function (eq. 9):
``phi_NF = mu * g / (1 + g)``, ``g = exp(phi_P)``. Written this way the function is smooth at
the goal (``g = |x - P_G|^2 prod_j |x - P_j|^(-2/K)``), and it is evaluated in the form
that cannot overflow: ``g`` directly where ``g < 1`` and ``logistic(phi_P)`` elsewhere. Values,
gradients and Hessians are exact (forward-mode jets through the chain, analytic derivatives of
the potential). ``phi_P`` has a single minimum at ``P_G`` and only saddles otherwise when
``K > N`` (N = number of interior trees = point obstacles); the chain is a diffeomorphism
of free space onto the point world, so ``phi_NF`` has one minimum, at the goal, is ``mu`` on
every boundary and has only isolated saddles.

Parameter rule (``NavParams``, recorded on the object, every entry overridable)
-------------------------------------------------------------------------------
======================  =======================================================================
``K``                   ``N + 2`` (paper 001 section 5.1: 2, plus 1 per independent obstacle)
``mu``                  1 (section 5.1)
``width_fraction f``    0.45: every shell width is ``f`` times the clearance it must respect,
                        so shells of one stage (``< 0.5`` of any gap each) never meet
purge width ``h_i``     ``f * min(distance to every obstacle present when leaf i is purged but
                        its parent, to the workspace boundary)`` (``Forest.clearance``), capped at ``width_cap``
                        (1 m) and twice the leaf's size. For a child of the workspace the
                        boundary distance is ``Forest.far_gap``: the room beyond the leaf along
                        its purge rays (a wider shell would move the opposite side of the
                        workspace into free space and break the diffeomorphism there)
root width ``h_j``      ``f * min(distance to other roots, to the boundary)`` (``Forest.clearance``),
                        capped
workspace width ``h_0`` ``workspace_fraction`` (0.8) times the workspace's inscribed radius (its map
                        acts after the inner discs have become points: see ``SphereToPoint``)
``rho_j``               ``rho_fraction`` (0.5) times the root's inscribed radius
``rho_0``               the workspace's half diagonal (>= every ray length from its centre)
``delta_j``             ``(r_in_j - rho_j) + 0.9 h_j``: the collapse stays inside the image of
                        the root's shell
======================  =======================================================================

The goal does not constrain the shells: every stage is a diffeomorphism of the whole free space,
so a goal inside a shell simply has a moved image ``P_G = Phi(q_G)`` (the paper's ``gamma_G``
factor in the switches, and its ``E_G``, are not needed). The parameters therefore depend on the
forest only.

These replace the paper's ``lambda``, ``xi`` (switch steepness: our ``1/h``) and ``E_i``
(separation constants: our clearances); see :mod:`navigation.transforms` for why.

Outside free space (inside an obstacle, on a boundary or within ``FREE_MARGIN`` of it, outside
the workspace) every evaluation
is defined and finite and flagged ``free = False``: ``value = mu``, ``gradient`` a unit vector
pointing away from free space (so ``-gradient`` leads back to it, across the most violated
boundary), ``hessian = 0``, ``potential = +inf``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ._arrays import as_points, restore
from ._jet import Jet, logistic
from .errors import NavigationError, OutsideFreeSpaceError, check_numbers
from .forest import WORKSPACE, Forest
from .geometry import pack
from .transforms import Chain, PurgeStage, SphereToPoint, StarToSphere, jets_to_arrays

__all__ = ["NavParams", "NavEval", "NavigationFunction", "FREE_MARGIN"]

#: Points whose obstacle function is within this of 0 (about 1e-12 m from a boundary, where the
#: outer map's distance to infinity is below rounding) count as on the boundary, i.e. not free.
FREE_MARGIN = 1e-12


@dataclass(frozen=True, slots=True)
class NavParams:
    """Parameters of a navigation function (see the module docstring for the rule).

    Per-obstacle arrays are indexed like ``forest.obstacles`` (``purge_width``; ``nan`` for
    roots) or like ``forest.roots`` (``root_width``, ``rho``, ``delta``).
    """

    K: float
    mu: float = 1.0
    width_fraction: float = 0.45
    rho_fraction: float = 0.5
    width_cap: float = 1.0
    workspace_fraction: float = 0.8
    purge_width: tuple = ()
    root_width: tuple = ()
    workspace_width: float = math.nan
    rho: tuple = ()
    rho0: float = math.nan
    delta: tuple = ()

    def __post_init__(self):
        check_numbers(self, ("K", "mu", "width_fraction", "rho_fraction", "width_cap", "workspace_fraction"),
                      positive=True)
        if not self.width_fraction < 0.5:
            raise NavigationError(f"NavParams.width_fraction must be < 0.5 so shells never meet, "
                                  f"got {self.width_fraction}")
        if not self.workspace_fraction < 1.0:
            raise NavigationError(f"NavParams.workspace_fraction must be < 1, got {self.workspace_fraction}")
        if not self.rho_fraction < 1.0:
            raise NavigationError(f"NavParams.rho_fraction must be < 1, got {self.rho_fraction}")

    def as_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in
                ((n, getattr(self, n)) for n in self.__slots__)}


@dataclass(frozen=True)
class NavEval:
    """Result of :meth:`NavigationFunction.evaluate` for ``N`` points.

    ``value (N,)``, ``gradient (N, 2)``, ``hessian (N, 2, 2)`` (``None`` below the requested
    order), ``potential (N,)`` = ``phi_P`` of eq. (2) at the image point (``-inf`` at the goal,
    ``+inf`` outside free space), ``free (N,)`` bool.
    """

    value: np.ndarray
    gradient: np.ndarray | None
    hessian: np.ndarray | None
    potential: np.ndarray
    free: np.ndarray


def _beta_values(p: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Obstacle functions of packed squircles ``p (M, 7)`` at ``pts (N, 2)``: ``(N, M)``."""
    dx = pts[:, 0, None] - p[None, :, 0]
    dy = pts[:, 1, None] - p[None, :, 1]
    x = (dx * p[:, 2] + dy * p[:, 3]) / p[:, 4]
    y = (dy * p[:, 2] - dx * p[:, 3]) / p[:, 5]
    x2, y2 = x * x, y * y
    r2 = x2 + y2
    # beta + 1 = r2 (1 + sqrt(1 - 4 s^2 (x2/r2)(y2/r2))) / 2: no r2^2, so no overflow far away
    safe = np.where(r2 > 0, r2, 1.0)
    m = (x2 / safe) * (y2 / safe)
    return 0.5 * r2 * (1.0 + np.sqrt(np.maximum(1.0 - 4.0 * p[:, 6] ** 2 * m, 0.0))) - 1.0


#: forest -> (params, chain, point obstacles) of the default parameter rule, for the last
#: ``_SHARED_SIZE`` forests (a forest hashes by identity; insertion order is age)
_SHARED: dict = {}
_SHARED_SIZE = 32


class NavigationFunction:
    """The navigation function ``phi_NF`` of eq. (9) for a forest world and a goal.

    Parameters
    ----------
    world : World or Forest
        A :class:`~navigation.world.World` (its forest is built with ``inflation``) or a
        :class:`~navigation.forest.Forest`.
    goal : (2,) array_like
        Goal point; must lie in free space.
    inflation : float
        Radius by which obstacles grow and the workspace shrinks (configuration space of a disc
        robot) when ``world`` is a World. Default 0: the world's obstacles as given.
    params : NavParams, optional
        Complete parameters (skips the rule).
    **overrides
        Any scalar field of :class:`NavParams` (``K``, ``mu``, ``width_fraction``,
        ``rho_fraction``, ``width_cap``): the rule runs with these values.

    Raises
    ------
    OutsideFreeSpaceError
        The goal is not in free space (the message names the obstacle).
    NavigationError
        Parameters that break a guarantee (``K <= N``, ...).
    ForestError
        (from the forest construction) obstacles the method cannot organise.

    Examples
    --------
    >>> from navigation import load_world, NavigationFunction
    >>> nf = NavigationFunction(load_world("simple"), goal=(3.5, 2.5))
    >>> float(nf.value([3.5, 2.5]))
    0.0
    """

    def __init__(self, world, goal, *, inflation: float = 0.0, params: NavParams | None = None, **overrides):
        forest = world if isinstance(world, Forest) else world.forest(inflation)
        self.forest: Forest = forest
        g, _ = as_points(goal, "goal")
        if g.shape[0] != 1:
            raise OutsideFreeSpaceError(f"goal must be one point (2,), got shape {np.shape(goal)}")
        self.goal = g[0].copy()
        self._ws = pack([forest.workspace])
        self._obs = pack(forest.obstacles) if len(forest.obstacles) else np.zeros((0, 7))
        self._rows = np.concatenate((self._ws, self._obs))
        self._check_goal()
        # with the parameter rule's defaults, the parameters, the chain and the point obstacles
        # depend on the forest only: shared by every goal on one forest (_SHARED)
        shared = params is None and not overrides
        parts = _SHARED.get(forest) if shared else None
        if parts is None:
            if params is None:
                params = self._rule(**overrides)
            elif overrides:
                params = replace(params, **overrides)
            n_trees = len(forest.roots)
            if not params.K > n_trees:
                raise NavigationError(f"K = {params.K} must exceed the number of interior trees N = {n_trees} "
                                      "(eq. 2: otherwise phi_P does not grow at infinity)")
            self.params = params
            self.chain = self._build_chain()
            roots = np.array([forest.obstacles[j].center for j in forest.roots]).reshape(-1, 2)
            last: SphereToPoint = self.chain.stages[-1]
            self._points = (self._image(roots, lambda x, y: last.psi(*last.outer(x, y))) if len(roots)
                            else np.zeros((0, 2)))
            self._points.flags.writeable = False
            if shared:
                _SHARED[forest] = (self.params, self.chain, self._points)
                if len(_SHARED) > _SHARED_SIZE:
                    del _SHARED[next(iter(_SHARED))]  # the oldest forest
        else:
            self.params, self.chain, self._points = parts
        self._goal_image = None  # P_G, computed when first needed (_goal)
        self._goal_jacobian = None

    # ------------------------------------------------------------------ construction
    def _check_goal(self):
        f = self.forest
        if not _beta_values(self._ws, self.goal[None])[0, 0] < 0:
            raise OutsideFreeSpaceError(f"goal {self.goal.tolist()} is outside the workspace")
        if len(f.obstacles):
            b = _beta_values(self._obs, self.goal[None])[0]
            if np.any(b <= 0):
                i = int(np.argmin(b))
                where = "on the boundary of" if b[i] == 0 else "inside"
                raise OutsideFreeSpaceError(
                    f"goal {self.goal.tolist()} lies {where} obstacle {f.source_index[i]}")

    def _rule(self, **overrides) -> NavParams:
        f = self.forest
        base = NavParams(K=len(f.roots) + 2.0)
        base = replace(base, **overrides) if overrides else base
        frac, cap = base.width_fraction, base.width_cap
        m = len(f.obstacles)
        purge = np.full(m, np.nan)
        for level in f.levels():
            for i in level:
                # the shell must not reach another obstacle present at its purge, nor the workspace
                # boundary: beyond the leaf (a workspace child, along its purge rays) or anywhere
                # (an inner leaf); Forest.clearance is the smallest of these distances
                size = 2.0 * f.obstacles[i].bounding_radius
                purge[i] = min(frac * f.clearance[i], cap, size)
        roots = list(f.roots)
        root_w, rho, delta = [], [], []
        for j in roots:
            sq = f.obstacles[j]
            h = min(frac * f.clearance[j], cap, 2.0 * sq.bounding_radius)
            r_in = sq.inscribed_radius
            root_w.append(h)
            rho.append(base.rho_fraction * r_in)
            delta.append((r_in - base.rho_fraction * r_in) + 0.9 * h)
        ws = f.workspace
        h0 = base.workspace_fraction * ws.inscribed_radius
        return replace(base, purge_width=tuple(purge), root_width=tuple(root_w), workspace_width=h0,
                       rho=tuple(rho), rho0=ws.bounding_radius, delta=tuple(delta))

    def _build_chain(self) -> Chain:
        f, prm = self.forest, self.params
        stages = []
        purge = np.asarray(prm.purge_width, dtype=float)
        for level in f.levels():
            level = np.asarray(level, dtype=int)
            par = np.array([f.parent[i] for i in level])
            is_ws = par == WORKSPACE
            parent_rows = np.where(is_ws[:, None], self._ws[0][None, :], self._obs[np.where(is_ws, 0, par)])
            centre = np.asarray(f.center)[level]
            h = purge[level]
            stages.append(PurgeStage(self._obs[level], parent_rows, is_ws, centre, h))
        roots = np.asarray(f.roots, dtype=int)
        rows = self._obs[roots] if len(roots) else np.zeros((0, 7))
        rw = np.asarray(prm.root_width, dtype=float)
        stages.append(StarToSphere(rows, np.asarray(prm.rho, float), rw))
        stages.append(SphereToPoint(rows[:, :2].copy(), np.asarray(prm.rho, float), np.asarray(prm.delta, float),
                                    self._ws[0].copy(), float(prm.rho0), float(prm.workspace_width)))
        return Chain(tuple(stages))

    @staticmethod
    def _image(pts: np.ndarray, fn) -> np.ndarray:
        x, y = fn(Jet.constant(pts[:, 0], 0), Jet.constant(pts[:, 1], 0))
        return np.stack((x.v, y.v), axis=1)

    # ------------------------------------------------------------------ queries
    @property
    def point_obstacles(self) -> np.ndarray:
        """Point obstacles ``P_j`` of eq. (2), ``(N, 2)``, in the order of ``forest.roots``."""
        return self._points.copy()

    @property
    def goal_image(self) -> np.ndarray:
        """``P_G``, the goal's image in the point world."""
        return self._goal().copy()

    def _goal(self) -> np.ndarray:
        """``P_G`` (computed once, by the chain at order 0 unless :meth:`goal_transform` came
        first: the chain's values are the same at every order)."""
        if self._goal_image is None:
            self._goal_image = self._image(self.goal[None], self.chain.apply)[0]
        return self._goal_image

    def goal_transform(self) -> tuple[np.ndarray, np.ndarray]:
        """``(P_G, J)``: the goal's image and the chain's Jacobian there (:meth:`transform` at
        order 1), computed once (an oriented field normalises its point world with them)."""
        if self._goal_jacobian is None:
            x, jac, _ = self.transform(self.goal[None], order=1)
            self._goal_jacobian = jac[0]
            if self._goal_image is None:
                self._goal_image = x[0]
        return self._goal_image, self._goal_jacobian

    def is_free(self, q) -> np.ndarray:
        """True where ``q`` lies strictly inside the workspace and outside every obstacle."""
        pts, single = as_points(q)
        return restore(self._free(pts), single)

    def _free(self, pts: np.ndarray) -> np.ndarray:
        b = _beta_values(self._rows, pts)  # workspace first, then the obstacles: one pass
        free = b[:, 0] < -FREE_MARGIN
        if b.shape[1] > 1:
            free &= np.all(b[:, 1:] > FREE_MARGIN, axis=1)
        return free

    def value(self, q) -> np.ndarray:
        """``phi_NF(q)`` in ``[0, mu]``, shape ``()`` or ``(N,)``."""
        pts, single = as_points(q)
        return restore(self._evaluate(pts, 0).value, single)

    def gradient(self, q) -> np.ndarray:
        """Exact gradient of ``phi_NF``, shape ``(2,)`` or ``(N, 2)``."""
        pts, single = as_points(q)
        return restore(self._evaluate(pts, 1).gradient, single)

    def hessian(self, q) -> np.ndarray:
        """Exact Hessian of ``phi_NF``, shape ``(2, 2)`` or ``(N, 2, 2)``."""
        pts, single = as_points(q)
        return restore(self._evaluate(pts, 2).hessian, single)

    def evaluate(self, q, order: int = 2) -> NavEval:
        """Value and derivatives up to ``order`` (0, 1, 2) for ``(N, 2)`` (or ``(2,)``) points.

        Always returns arrays with a leading ``N`` axis (a ``(2,)`` input gives ``N = 1``).
        """
        if order not in (0, 1, 2):
            raise NavigationError(f"order must be 0, 1 or 2, got {order!r}")
        pts, _ = as_points(q)
        return self._evaluate(pts, order)

    def transform(self, q, order: int = 1):
        """The chain ``Phi`` (free space -> point world) at free points: ``(x, J, H)``.

        Raises :class:`OutsideFreeSpaceError` if a point is not free.
        """
        pts, _ = as_points(q)
        free = self._free(pts)
        if not np.all(free):
            bad = int(np.argmin(free))
            raise OutsideFreeSpaceError(f"point {pts[bad].tolist()} (row {bad}) is not in free space")
        return jets_to_arrays(*self.chain.apply(*Jet.variables(pts, order)))

    # ------------------------------------------------------------------ evaluation
    def _evaluate(self, pts: np.ndarray, order: int) -> NavEval:
        n = len(pts)
        mu = self.params.mu
        value = np.full(n, mu)
        potential = np.full(n, np.inf)
        grad = np.zeros((n, 2)) if order >= 1 else None
        hess = np.zeros((n, 2, 2)) if order >= 2 else None
        free = self._free(pts)
        every = bool(free.all())
        idx = slice(None) if every else np.nonzero(free)[0]  # all free: no gather/scatter
        if every or len(idx):
            x, y = self.chain.apply(*Jet.variables(pts[idx], order))
            nf, phi = self._potential(x, y)
            value[idx] = mu * nf.v
            potential[idx] = phi
            if order >= 1:
                grad[idx] = mu * nf.g
            if order >= 2:
                hess[idx] = mu * nf.hessian()
        if every:
            return NavEval(value, grad, hess, potential, free)
        out = np.nonzero(~free)[0]
        if len(out) and order >= 1:
            grad[out] = self._outside_direction(pts[out])
        return NavEval(value, grad, hess, potential, free)

    def _potential(self, x: Jet, y: Jet) -> tuple[Jet, np.ndarray]:
        """Jet of ``g/(1+g)`` (eq. 9 without ``mu``) and the values of ``phi_P`` (eq. 2)."""
        px, py = x.v, y.v
        inv_k = 1.0 / self.params.K
        # log h = -(1/K) sum_j ln |x - P_j|^2, with analytic gradient and Hessian in x
        if len(self._points):
            dx = px[:, None] - self._points[None, :, 0]
            dy = py[:, None] - self._points[None, :, 1]
            d2 = dx * dx + dy * dy
            inv = 1.0 / d2
            lh = -inv_k * np.log(d2).sum(1)
            lhx = -inv_k * (2.0 * dx * inv).sum(1)
            lhy = -inv_k * (2.0 * dy * inv).sum(1)
            inv2 = inv * inv
            lhxx = -inv_k * (2.0 * inv - 4.0 * dx * dx * inv2).sum(1)
            lhxy = -inv_k * (-4.0 * dx * dy * inv2).sum(1)
            lhyy = -inv_k * (2.0 * inv - 4.0 * dy * dy * inv2).sum(1)
        else:
            lh = lhx = lhy = lhxx = lhxy = lhyy = np.zeros_like(px)
        goal = self._goal()
        gx, gy = px - goal[0], py - goal[1]
        dg = gx * gx + gy * gy
        with np.errstate(divide="ignore"):
            phi = np.log(dg) + lh
        near = phi < 0
        n_near = int(np.count_nonzero(near))
        out = np.empty_like(x.a)
        if n_near:
            # one branch only (the common case for few points): no masked copies
            i = slice(None) if n_near == len(near) else near
            xs, ys = x[i], y[i]
            two, zero = np.full(n_near, 2.0), np.zeros(n_near)
            both = Jet.compose2(np.array((dg[i], lh[i])), np.array((2 * gx[i], lhx[i])), np.array((2 * gy[i], lhy[i])),
                                np.array((two, lhxx[i])), np.array((zero, lhxy[i])), np.array((two, lhyy[i])), xs, ys)
            g = both[0] * both[1].exp()  # |x - P_G|^2 h
            q = 1.0 / (1.0 + g.v)
            out[i] = g.apply(g.v * q, q * q, -2.0 * q * q * q).a
        if n_near < len(near):
            i = slice(None) if n_near == 0 else ~near
            xs, ys = x[i], y[i]
            inv_d = 1.0 / dg[i]
            fx = 2 * gx[i] * inv_d + lhx[i]
            fy = 2 * gy[i] * inv_d + lhy[i]
            fxx = 2 * inv_d - 4 * gx[i] ** 2 * inv_d ** 2 + lhxx[i]
            fxy = -4 * gx[i] * gy[i] * inv_d ** 2 + lhxy[i]
            fyy = 2 * inv_d - 4 * gy[i] ** 2 * inv_d ** 2 + lhyy[i]
            phi_jet = Jet.compose2(phi[i], fx, fy, fxx, fxy, fyy, xs, ys)
            s = logistic(phi[i])
            c = logistic(-phi[i])  # 1 - s without cancellation
            out[i] = phi_jet.apply(s, s * c, s * c * (c - s)).a
        return Jet(out), phi

    def _outside_direction(self, pts: np.ndarray) -> np.ndarray:
        """Unit vectors pointing away from free space at non-free points (see module doc)."""
        f = self.forest
        sqs = [f.workspace] + list(f.obstacles)
        rows = np.concatenate((self._ws, self._obs))
        b = _beta_values(rows, pts)
        b[:, 0] = -b[:, 0]  # workspace: violated where beta_ws >= 0
        worst = np.argmin(b, axis=1)
        out = np.empty((len(pts), 2))
        for k in np.unique(worst):
            sel = worst == k
            # far outside, the outward radial direction is the answer and avoids overflow
            far = np.linalg.norm(pts - np.array(sqs[k].center), axis=1) > 4.0 * sqs[k].bounding_radius
            if k == 0 and np.any(sel & far):
                d = pts[sel & far] - np.array(sqs[0].center)
                out[sel & far] = d / np.linalg.norm(d, axis=1, keepdims=True)
                sel = sel & ~far
                if not np.any(sel):
                    continue
            g = sqs[k].gradient(pts[sel])
            if k > 0:
                g = -g  # inside an obstacle, free space lies along +grad beta: point the other way
            norm = np.linalg.norm(g, axis=1, keepdims=True)
            fallback = pts[sel] - np.array(sqs[k].center)
            fallback = -fallback if k > 0 else fallback
            fb_norm = np.linalg.norm(fallback, axis=1, keepdims=True)
            fallback = np.where(fb_norm > 0, fallback / np.where(fb_norm > 0, fb_norm, 1.0), [[1.0, 0.0]])
            out[sel] = np.where(norm > 1e-300, g / np.where(norm > 1e-300, norm, 1.0), fallback)
        return out

    def __repr__(self) -> str:
        f = self.forest
        return (f"NavigationFunction(goal={self.goal.tolist()}, obstacles={len(f.obstacles)}, "
                f"trees={len(f.roots)}, K={self.params.K}, mu={self.params.mu})")
