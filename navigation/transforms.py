"""The diffeomorphism chain forest -> star -> sphere -> point world (paper 001 eq. 1, 10-19).

Each stage is a map ``f(q) = (1 - sigma(q)) q + sigma(q) T(q)`` (the form of eq. 12 and 19)
built from *ray maps*: along every ray ``q = p + r u`` from a centre ``p`` the map moves the
point to ``p + r' u`` with ``r'`` a function of ``r`` and ``u``. Such a map is a
diffeomorphism wherever ``dr'/dr > 0`` (its Jacobian determinant is ``(r'/r) dr'/dr``), so
each stage below is built with ``dr'/dr >= 1`` everywhere in free space — a guarantee by
construction rather than "for lambda, xi large enough" (Lemma 2). Differences to the paper,
chosen to keep the guarantees and the numerics finite:

* **Switches with compact support.** The paper's switches ``sigma_i = gamma_G bar-beta_i /
  (gamma_G bar-beta_i + lambda beta_i)`` are nonzero everywhere and their products of all
  obstacle functions under/overflow (notes: the authors' code returns non-finite values at most
  points). We use the C-infinity step ``eta`` of eq. (1) (Loizou 2017): each map differs from the
  identity only in a *shell* of width ``h_i`` around its obstacle. Shells of one stage are
  pairwise disjoint, so the stage is the sum of independent displacements. (The goal needs no
  special care: every stage is a diffeomorphism of all of free space; the paper's ``gamma_G``
  factor is not needed.)
  ``h_i`` plays the role of ``1/lambda``, ``1/xi`` and of the paper's geometric constants ``E_i``
  (the paper requires ``O_i(2E_i)`` disjoint and away from the goal; we require the shells to be).
* **Purging (eq. 13-19).** For a leaf ``O_l`` with parent ``O_p`` and common centre ``p``, let
  ``R_l(u)``, ``R_p(u)`` be the exact ray lengths from ``p`` (eq. 15, solved exactly, not by the
  piecewise matrices of eq. 16), ``t = r - R_p`` and ``e = R_l - R_p`` (how far the leaf
  protrudes). The leaf is purged by ``T(q) = q - e u`` (its boundary lands on the parent's, as
  ``v_i`` of eq. 17 does at ``beta_i = 0``) with switch
  ``sigma = omega(e / t) (1 - eta((t - e) / h))`` where ``omega = eta``: ``sigma = 1`` on the
  leaf boundary, ``0`` where the leaf does not protrude (``e <= 0``) or beyond the shell. Because
  ``omega`` depends on ``e/t`` rather than on ``max(e, 0)`` the map is smooth in the interior up to
  the corners where leaf and parent boundaries cross, and ``dr'/dr = 1 + e (omega' e/t^2 (1-eta)
  + omega eta'/h) >= 1``. A leaf whose parent is the workspace boundary is purged the same way
  from a centre outside the workspace, with ``R_p`` the distance to where the ray enters it.
  All leaves of one depth are purged in one stage (eq. 14 applied level by level, deepest first).
* **Star to sphere (eq. 10-12).** Root ``j`` (centre ``c_j``) uses ``T_j(q) = q + (rho_j - R_j(u)) u``
  with ``rho_j < min_u R_j`` and switch ``1 - eta(t/h_j)``, ``t = r - R_j``; the workspace uses
  ``rho_0 >= max_u R_0`` and ``t = R_0 - r``, applied in :class:`SphereToPoint` after the inner
  discs have collapsed (see there). Both give ``dr'/dr >= 1``; boundaries land exactly on the
  circles of radius ``rho``.
* **Sphere to point (eq. 1).** As in the navigation-math note, with ``eta_delta(x) = eta(x/delta)``
  and one ``delta_j`` per disc; ``psi`` sends the outer circle to infinity.

Every map works on :class:`~navigation._jet.Jet` pairs (forward-mode values, gradients and
Hessians with respect to the original query point), so compositions carry exact derivatives.
``map(points, order)`` evaluates one stage on its own and returns ``(y, J, H)`` with shapes
``(N, 2)``, ``(N, 2, 2)`` (``J[n, i, j] = d y_i / d x_j``) and ``(N, 2, 2, 2)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import _chain_kernel
from ._arrays import as_points
from ._jet import _EDGE, Jet, smoothstep_coeffs
from .geometry import _root_jet, ray_length_center_jet, ray_length_packed

__all__ = ["PurgeStage", "StarToSphere", "SphereToPoint", "Chain", "jets_to_arrays"]


def _eta(j: Jet) -> Jet:
    e, d1, d2 = smoothstep_coeffs(j.v, j.order)
    return j.apply(e, d1, d2)


def _polar(x: Jet, y: Jet, c: np.ndarray):
    """Distance ``r`` and unit direction ``u`` of ``q - c`` (jets).

    Analytic first and second partials of ``r = |d|``, ``u = d / r`` (``d = q - c``), chained
    through ``(x, y)`` in one stacked :meth:`Jet.compose2` (instead of nine jet operations).
    """
    dx = x.v - c[..., 0]
    dy = y.v - c[..., 1]
    r = np.hypot(dx, dy)
    ir = 1.0 / r
    ux, uy = dx * ir, dy * ir
    if x.order == 0:
        return Jet(r[:, None]), Jet(ux[:, None]), Jet(uy[:, None])
    xx, xy, yy = ux * ux * ir, ux * uy * ir, uy * uy * ir  # u u^T / r
    ir2 = ir * ir
    a = uy * (2.0 * ux * ux - uy * uy) * ir2
    b = ux * (2.0 * uy * uy - ux * ux) * ir2
    f = np.array((r, ux, uy))
    fx = np.array((ux, yy, -xy))
    fy = np.array((uy, -xy, xx))
    if x.order == 1:
        out = Jet.compose2(f, fx, fy, None, None, None, x, y).a
    else:
        fxx = np.array((yy, -3.0 * ux * uy * uy * ir2, a))
        fxy = np.array((-xy, a, b))
        fyy = np.array((xx, b, -3.0 * ux * ux * uy * ir2))
        out = Jet.compose2(f, fx, fy, fxx, fxy, fyy, x, y).a
    return Jet(out[0]), Jet(out[1]), Jet(out[2])


def _pairs(x: Jet, y: Jet, rows: np.ndarray, margin: np.ndarray):
    """Indices ``(point, obstacle)`` of points within ``margin`` of each squircle's bounding
    rectangle (rows packed as in :func:`navigation.geometry.pack`): a superset of the points
    within ``margin`` of the squircle, outside which a stage's displacement vanishes."""
    dx = x.v[:, None] - rows[None, :, 0]
    dy = y.v[:, None] - rows[None, :, 1]
    lx = np.abs(dx * rows[:, 2] + dy * rows[:, 3])
    ly = np.abs(dy * rows[:, 2] - dx * rows[:, 3])
    return np.nonzero((lx < rows[:, 4] + margin) & (ly < rows[:, 5] + margin))


def _scatter(x: Jet, y: Jet, n: np.ndarray, dx: Jet, dy: Jet) -> tuple[Jet, Jet]:
    """``(x, y)`` plus the displacements ``(dx, dy)`` of the (point, obstacle) pairs at points ``n``
    (sorted, as :func:`numpy.nonzero` returns them; a point may repeat)."""
    ax, ay = x.a.copy(), y.a.copy()
    if len(n) < 2 or np.all(n[1:] != n[:-1]):  # no repeated point: plain fancy-index add
        ax[n] += dx.a
        ay[n] += dy.a
    else:
        np.add.at(ax, n, dx.a)
        np.add.at(ay, n, dy.a)
    return Jet(ax), Jet(ay)


def jets_to_arrays(x: Jet, y: Jet):
    """Values ``(N, 2)``, Jacobians ``(N, 2, 2)`` and second derivatives ``(N, 2, 2, 2)``."""
    val = np.stack((x.v, y.v), axis=1)
    jac = hess = None
    if x.order >= 1:
        jac = np.stack((x.g, y.g), axis=1)
    if x.order >= 2:
        hess = np.stack((x.hessian(), y.hessian()), axis=1)
    return val, jac, hess


class _Stage:
    """Common evaluation of one stage on plain points."""

    name = "stage"

    def apply(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:  # pragma: no cover - abstract
        raise NotImplementedError

    def __call__(self, points, order: int = 1):
        """Evaluate this stage alone at ``points`` of its domain: ``(y, J, H)`` (see module doc)."""
        pts, _ = as_points(points, "points")
        x, y = Jet.variables(pts, order)
        return jets_to_arrays(*self.apply(x, y))


@dataclass(frozen=True, eq=False)
class PurgeStage(_Stage):
    """Purging of all leaves of one depth into their parents (eq. 13-19, see module doc).

    Attributes (arrays over the ``L`` leaves of the stage)
    ------------------------------------------------------
    leaf, parent : (L, 7) packed squircles; for a workspace parent the packed workspace
    parent_is_workspace : (L,) bool
    centre : (L, 2) common centres ``p_i``
    width : (L,) shell widths ``h_i`` (the stage is the identity farther than ``h_i`` from leaf i)
    """

    leaf: np.ndarray
    parent: np.ndarray
    parent_is_workspace: np.ndarray
    centre: np.ndarray
    width: np.ndarray
    name: str = "purge"

    def apply(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:
        n, k = _pairs(x, y, self.leaf, self.width * 1.0001)
        if len(n) == 0:
            return x, y
        c = self.centre[k]
        # plain values first: one solve for the leaf's and the parent's ray lengths
        dx, dy = x.v[n] - c[:, 0], y.v[n] - c[:, 1]
        r0 = np.hypot(dx, dy)
        ir = 1.0 / r0
        ux0, uy0 = dx * ir, dy * ir  # the values _polar gives
        m = len(n)
        rows = np.concatenate((self.leaf[k], self.parent[k]))
        origin = np.concatenate((c, c))
        both = ray_length_packed(rows, origin, np.stack((np.concatenate((ux0, ux0)), np.concatenate((uy0, uy0))), axis=1),
                                 np.concatenate((np.zeros(m, dtype=bool), self.parent_is_workspace[k])))
        rl0, rp0 = both[:m], both[m:]
        # pairs whose switch is exactly 0 (the leaf does not protrude along the ray, or the point
        # is beyond the shell: eta is exactly 0 resp. 1 there, with zero derivatives) move nothing;
        # the same expressions as below decide it, so dropping them changes no bit of the result
        with np.errstate(divide="ignore", invalid="ignore"):
            live = ((rl0 - rp0) * (1.0 / (r0 - rp0)) > _EDGE) & ((r0 - rl0) * (1.0 / self.width[k]) < 1.0 - _EDGE)
        if not live.all():
            if not live.any():
                return x, y
            n, k, c, m = n[live], k[live], c[live], int(np.count_nonzero(live))
            keep = np.concatenate((live, live))
            rows, origin, both = rows[keep], origin[keep], both[keep]
        r, ux, uy = _polar(x[n], y[n], c)
        both = _root_jet(rows, origin, both, Jet(np.concatenate((ux.a, ux.a))), Jet(np.concatenate((uy.a, uy.a))))
        r_leaf, r_par = both[:m], both[m:]
        t = r - r_par
        e = r_leaf - r_par
        # both switches in one smoothstep evaluation
        z = _eta(Jet(np.concatenate(((e / t).a, ((r - r_leaf) * (1.0 / self.width[k])).a))))
        sigma = z[:m] * (1.0 - z[m:])
        shift = e * sigma
        return _scatter(x, y, n, -(shift * ux), -(shift * uy))


@dataclass(frozen=True, eq=False)
class StarToSphere(_Stage):
    """Star world to sphere world for the roots (eq. 10-12 with compact switches, module doc).

    ``roots`` (R, 7) packed root squircles, ``rho`` (R,) sphere radii, shell ``width`` (R,).
    The workspace's own sphere map is applied by :class:`SphereToPoint`, after the inner
    spheres have collapsed to points (see there).
    """

    roots: np.ndarray
    rho: np.ndarray
    width: np.ndarray
    name: str = "star_to_sphere"

    def apply(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:
        if len(self.roots) == 0:
            return x, y
        n, k = _pairs(x, y, self.roots, self.width * 1.0001)
        if len(n) == 0:
            return x, y
        p = self.roots[k]
        r, ux, uy = _polar(x[n], y[n], p[:, :2])
        big_r = ray_length_center_jet(p, ux, uy)
        sw = 1.0 - _eta((r - big_r) * (1.0 / self.width[k]))
        shift = (self.rho[k] - big_r) * sw
        return _scatter(x, y, n, shift * ux, shift * uy)


@dataclass(frozen=True, eq=False)
class SphereToPoint(_Stage):
    """Sphere world to the unbounded point world, eq. (1) and the navigation-math note.

    1. ``collapse``: discs ``(centres (R, 2), rho (R,))`` collapse onto their centres within
       ``delta`` (R,) of their boundary (``Phi_M->P~``);
    2. ``outer``: the workspace squircle becomes the disc ``(c0, rho0)`` (its star-to-sphere map,
       eq. 10-11 with ``T_0(q) = q + (rho0 - R_0(u)) u`` and switch ``1 - eta((R_0 - r)/width0)``);
    3. ``psi``: the open disc goes onto the plane.

    Step 2 comes after step 1 (the paper applies all sphere maps before the collapse): once the
    inner obstacles are points, the workspace map only has to avoid its own centre, so its shell
    can be thick (``width0`` ~ the workspace's inscribed radius) instead of squeezing the
    rounding of the whole boundary into the gap between the boundary and the nearest obstacle.
    The composition is still a diffeomorphism (each step is), and the points ``P_j`` are the
    images of the centres.
    """

    centres: np.ndarray
    rho: np.ndarray
    delta: np.ndarray
    workspace: np.ndarray
    rho0: float
    width0: float
    name: str = "sphere_to_point"

    @property
    def c0(self) -> np.ndarray:
        return self.workspace[:2]

    def collapse(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:
        """``Phi_M->P~``: disc ``i`` collapses to its centre (identity beyond ``delta_i``)."""
        if len(self.centres) == 0:
            return x, y
        d2 = (x.v[:, None] - self.centres[None, :, 0]) ** 2 + (y.v[:, None] - self.centres[None, :, 1]) ** 2
        reach = self.rho + self.delta
        n, k = np.nonzero(d2 < (reach * reach)[None, :])
        if len(n) == 0:
            return x, y
        c = self.centres[k]
        r, ux, uy = _polar(x[n], y[n], c)
        z = (r - self.rho[k]) * (1.0 / self.delta[k])
        eta = _eta(z)
        s = z * (1.0 - eta) + eta  # s_delta(b) of Loizou (2017) with b = r - rho
        shrink = (1.0 - s) * r  # move towards the centre by (1 - s) r
        return _scatter(x, y, n, -(shrink * ux), -(shrink * uy))

    def outer(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:
        """Workspace squircle onto the circle of radius ``rho0`` (``dr'/dr >= 1``)."""
        w = self.workspace
        d2 = (x.v - w[0]) ** 2 + (y.v - w[1]) ** 2
        inner = min(w[4], w[5]) - self.width0  # every ray from the centre is >= min half extent
        sel = d2 > inner * inner
        if not np.any(sel):
            return x, y
        every = bool(np.all(sel))
        xs, ys = (x, y) if every else (x[sel], y[sel])
        r, ux, uy = _polar(xs, ys, w[None, :2])
        big_r = ray_length_center_jet(w, ux, uy)
        sw = 1.0 - _eta((big_r - r) * (1.0 / self.width0))
        shift = (self.rho0 - big_r) * sw
        if every:  # the common case in the thick shell: no gather/scatter
            return x + shift * ux, y + shift * uy
        return _scatter(x, y, np.nonzero(sel)[0], shift * ux, shift * uy)

    def psi(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:
        """``psi``: the outer circle of radius ``rho0`` goes to infinity.

        ``psi(q) = c0 + G(r) d`` with ``d = q - c0``, ``r = |d|``, ``G(r) = rho0 / (rho0 - r)``;
        analytic partials (``G' = G^2 / rho0``, ``G'' = 2 G^3 / rho0^2``) chained through
        ``(x, y)`` in one stacked :meth:`Jet.compose2`. On or beyond the circle the gap is
        clamped to the smallest positive float with zero derivatives.
        """
        c0, rho0 = self.c0, self.rho0
        dx = x.v - c0[0]
        dy = y.v - c0[1]
        r = np.hypot(dx, dy)
        ok = r < rho0
        gain = rho0 / np.where(ok, rho0 - r, np.finfo(float).tiny)
        f = np.array((c0[0] + dx * gain, c0[1] + dy * gain))
        if x.order == 0:
            return Jet(f[0][:, None]), Jet(f[1][:, None])
        # at the centre itself psi is C1 (G(r) = 1 + r / rho0 + ...: its second derivatives are
        # bounded but depend on the direction of approach): use the limit along +x there
        pos = r > 0.0
        ir = 1.0 / np.where(pos, r, 1.0)
        ux, uy = np.where(pos, dx * ir, 1.0), np.where(pos, dy * ir, 0.0)
        g1 = np.where(ok, gain * gain * (1.0 / rho0), 0.0)  # G'
        t = r * g1
        fx = np.array((gain + t * ux * ux, t * ux * uy))
        fy = np.array((fx[1], gain + t * uy * uy))
        if x.order == 1:
            out = Jet.compose2(f, fx, fy, None, None, None, x, y).a
        else:
            pp = 2.0 * t * gain * (1.0 / rho0) - g1  # r G'' - G'
            ax = g1 + pp * ux * ux
            ay = g1 + pp * uy * uy
            fxx = np.array((ux * (2.0 * g1 + ax), uy * ax))
            fxy = np.array((uy * ax, ux * ay))
            fyy = np.array((ux * ay, uy * (2.0 * g1 + ay)))
            out = Jet.compose2(f, fx, fy, fxx, fxy, fyy, x, y).a
        return Jet(out[0]), Jet(out[1])

    def apply(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:
        return self.psi(*self.outer(*self.collapse(x, y)))


@dataclass(frozen=True, eq=False)
class Chain(_Stage):
    """The composition ``Phi_M->P o Phi_S->M o Phi_F->S`` of eq. (9): purges, then the rest.

    The result of the last call on at most :data:`_MEMO_POINTS` points is kept: navigation
    functions of different goals on one forest share their chain
    (:class:`~navigation.potential.NavigationFunction`), and the controller evaluates the fields
    of the current and the following waypoint at the same point (a repeated call returns copies
    of the same numbers)."""

    stages: tuple
    name: str = "chain"
    _last: list = field(default_factory=lambda: [None], init=False, repr=False, compare=False)
    _compiled: list = field(default_factory=lambda: [None], init=False, repr=False, compare=False)

    def apply(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:
        key = None
        if x.a.shape[0] <= _MEMO_POINTS:
            key = (x.a.shape, x.a.tobytes(), y.a.shape, y.a.tobytes())
            last = self._last[0]
            if last is not None and last[0] == key:
                return Jet(last[1].copy()), Jet(last[2].copy())
        x, y = self._apply_compiled(x, y)
        if key is not None:
            self._last[0] = (key, x.a.copy(), y.a.copy())
        return x, y

    def _apply_compiled(self, x: Jet, y: Jet) -> tuple[Jet, Jet]:
        """The stages in the compiled kernels of :mod:`navigation._chain_kernel` (the same
        formulas point by point; the stages' arrays are packed once per chain). The kernels
        carry second-order jets; lower orders are padded with zero derivatives and cut back, so
        the values (and gradients) are the same bits at every order. Jets of any leading shape
        ``(..., C)`` run as rows ``(-1, C)``."""
        calls = self._compiled[0]
        if calls is None:
            calls = self._compiled[0] = [_kernel_call(st) for st in self.stages]
        shape, c = x.a.shape[:-1], x.a.shape[-1]
        xa, ya = x.a.reshape(-1, c), y.a.reshape(-1, c)
        if c == 6:
            X = np.ascontiguousarray(xa, dtype=float)
            Y = np.ascontiguousarray(ya, dtype=float)
        else:
            X = np.zeros((xa.shape[0], 6))
            Y = np.zeros((ya.shape[0], 6))
            X[:, :c] = xa
            Y[:, :c] = ya
        for kernel, args in calls:
            OX, OY = np.empty_like(X), np.empty_like(Y)
            kernel(X, Y, *args, OX, OY)
            X, Y = OX, OY
        if c != 6:
            X, Y = X[:, :c].copy(), Y[:, :c].copy()
        return Jet(X.reshape(shape + (c,))), Jet(Y.reshape(shape + (c,)))


def _kernel_call(stage):
    """``(kernel, arguments)`` of one stage for :meth:`Chain._apply_compiled`."""
    f = lambda a: np.ascontiguousarray(a, dtype=float)  # noqa: E731
    if isinstance(stage, PurgeStage):
        return _chain_kernel.purge, (f(stage.leaf).reshape(-1, 7), f(stage.parent).reshape(-1, 7),
                                     np.ascontiguousarray(stage.parent_is_workspace, dtype=np.bool_),
                                     f(stage.centre).reshape(-1, 2), f(stage.width).reshape(-1))
    if isinstance(stage, StarToSphere):
        return _chain_kernel.star_to_sphere, (f(stage.roots).reshape(-1, 7), f(stage.rho).reshape(-1),
                                              f(stage.width).reshape(-1))
    if isinstance(stage, SphereToPoint):
        return _chain_kernel.sphere_to_point, (f(stage.centres).reshape(-1, 2), f(stage.rho).reshape(-1),
                                               f(stage.delta).reshape(-1), f(stage.workspace).reshape(1, 7),
                                               float(stage.rho0), float(stage.width0))
    raise TypeError(f"no compiled kernel for stage {type(stage).__name__}")  # pragma: no cover


_MEMO_POINTS = 4  #: largest input of :meth:`Chain.apply` whose result is kept
