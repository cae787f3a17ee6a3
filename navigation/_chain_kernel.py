"""Compiled second-order evaluation of the transformation chain (:mod:`navigation.transforms`)
and of the oriented field (:mod:`navigation.oriented`).

The stages of :class:`~navigation.transforms.Chain` (purges, star to sphere, sphere to point;
paper 001 eq. 1, 10-19) evaluated point by point with second-order jets held in local
variables: the same formulas, in the same order, as the numpy jets of :mod:`navigation._jet`
and :mod:`navigation.transforms`, without numpy's per-call overhead on the one or two points a
controller step evaluates (measured: the chain was 45 % of a 2 ms step on ``office``). Then
:func:`oriented` composes the oriented potential of eq. 23 (as built in
:mod:`navigation.oriented`) with the chain's jets and returns the field, its Jacobian and the
two tracked directions with their exact gradients.

A jet is a 6-tuple ``(v, d_x, d_y, d_xx, d_xy, d_yy)`` of derivatives with respect to the query
point, as the columns of :class:`~navigation._jet.Jet` at order 2. Arrays ``X``, ``Y`` of shape
``(N, 6)`` carry the two coordinates of ``N`` points. The results agree with the numpy path to
rounding (``tests/test_chain_kernel.py``: relative 1e-12 on values, Jacobians and second
derivatives; the libm functions may differ from numpy's in the last bit).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._geom_kernel import _ray
from ._geom_kernel import beta_derivatives_xy as _beta_derivatives
from ._geom_kernel import root_partials
from ._jet import _EDGE

__all__ = ["purge", "star_to_sphere", "sphere_to_point", "oriented", "potential_rows"]

_JIT = dict(cache=True, nogil=True)
_TINY = float(np.finfo(float).tiny)


# ------------------------------------------------------------------------------- jet algebra
@numba.njit(**_JIT)
def _compose2(f, fx, fy, fxx, fxy, fyy, X, Y):
    """``Jet.compose2``: the jet of ``f(x, y)`` from its partials at ``(x.v, y.v)``."""
    x1, x2, x3, x4, x5 = X[1], X[2], X[3], X[4], X[5]
    y1, y2, y3, y4, y5 = Y[1], Y[2], Y[3], Y[4], Y[5]
    g1 = fx * x1 + fy * y1
    g2 = fx * x2 + fy * y2
    h3 = fx * x3 + fy * y3 + fxx * (x1 * x1) + fyy * (y1 * y1) + fxy * (x1 * y1 + y1 * x1)
    h4 = fx * x4 + fy * y4 + fxx * (x1 * x2) + fyy * (y1 * y2) + fxy * (x1 * y2 + y1 * x2)
    h5 = fx * x5 + fy * y5 + fxx * (x2 * x2) + fyy * (y2 * y2) + fxy * (x2 * y2 + y2 * x2)
    return (f, g1, g2, h3, h4, h5)


@numba.njit(**_JIT)
def _apply(a, f0, f1, f2):
    """``Jet.apply``: compose with a scalar function of value ``f0``, derivatives ``f1``, ``f2``."""
    g1, g2 = a[1], a[2]
    return (f0, a[1] * f1, a[2] * f1, a[3] * f1 + f2 * (g1 * g1), a[4] * f1 + f2 * (g1 * g2),
            a[5] * f1 + f2 * (g2 * g2))


@numba.njit(**_JIT)
def _mul(a, b):
    """``Jet.__mul__`` of two jets."""
    b0 = b[0]
    a0 = a[0]
    return (a0 * b0, a[1] * b0 + a0 * b[1], a[2] * b0 + a0 * b[2],
            a[3] * b0 + a0 * b[3] + (a[1] * b[1] + b[1] * a[1]),
            a[4] * b0 + a0 * b[4] + (a[1] * b[2] + b[1] * a[2]),
            a[5] * b0 + a0 * b[5] + (a[2] * b[2] + b[2] * a[2]))


@numba.njit(**_JIT)
def _scale(a, c):
    """``Jet * constant``."""
    return (a[0] * c, a[1] * c, a[2] * c, a[3] * c, a[4] * c, a[5] * c)


@numba.njit(**_JIT)
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3], a[4] - b[4], a[5] - b[5])


@numba.njit(**_JIT)
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3], a[4] + b[4], a[5] + b[5])


@numba.njit(**_JIT)
def _rsub(c, a):
    """``constant - Jet``."""
    return (-a[0] + c, -a[1], -a[2], -a[3], -a[4], -a[5])


@numba.njit(**_JIT)
def _neg(a):
    return (-a[0], -a[1], -a[2], -a[3], -a[4], -a[5])


@numba.njit(**_JIT)
def _reciprocal(a):
    r = 1.0 / a[0]
    return _apply(a, r, -r * r, 2.0 * r * r * r)


@numba.njit(**_JIT)
def _logistic(z):
    ez = math.exp(-abs(z))
    q = 1.0 / (1.0 + ez)
    return q if z >= 0 else ez * q


@numba.njit(**_JIT)
def _eta(a):
    """``_eta`` of :mod:`navigation.transforms`: the C-infinity step of Loizou (2017) applied
    to a jet (``smoothstep_coeffs`` at order 2)."""
    x = a[0]
    inner = (x > _EDGE) and (x < 1.0 - _EDGE)
    xi = min(max(x, _EDGE), 1.0 - _EDGE)
    ix = 1.0 / xi
    iu = 1.0 / (1.0 - xi)
    z = iu - ix
    lz = _logistic(z)
    if inner:
        eta = lz
    elif x >= 1.0 - _EDGE:
        eta = 1.0
    else:
        eta = 0.0
    w = lz * (1.0 - lz) if inner else 0.0
    z1 = iu * iu + ix * ix
    d1 = w * z1
    z2 = 2.0 * (iu * iu * iu - ix * ix * ix)
    d2 = w * ((1.0 - 2.0 * lz) * z1 * z1 + z2)
    return _apply(a, eta, d1, d2)


# ---------------------------------------------------------------------------- geometry pieces
@numba.njit(**_JIT)
def _polar(X, Y, cx, cy):
    """``_polar`` of :mod:`navigation.transforms`: jets of ``r = |q - c|`` and ``u = (q - c) / r``."""
    dx = X[0] - cx
    dy = Y[0] - cy
    r = math.hypot(dx, dy)
    ir = 1.0 / r
    ux, uy = dx * ir, dy * ir
    xx, xy, yy = ux * ux * ir, ux * uy * ir, uy * uy * ir
    ir2 = ir * ir
    a = uy * (2.0 * ux * ux - uy * uy) * ir2
    b = ux * (2.0 * uy * uy - ux * ux) * ir2
    jr = _compose2(r, ux, uy, yy, -xy, xx, X, Y)
    jx = _compose2(ux, yy, -xy, -3.0 * ux * uy * uy * ir2, a, b, X, Y)
    jy = _compose2(uy, -xy, xx, a, b, -3.0 * ux * ux * uy * ir2, X, Y)
    return jr, jx, jy


@numba.njit(**_JIT)
def _root_jet(P, k, ox, oy, r0, ux, uy):
    """``navigation.geometry._root_jet``: the jet of the ray length ``r(u)`` of row ``P[k]``
    from ``(ox, oy)`` (``beta(o + r u) = 0``) given its value ``r0``."""
    ra, rb, raa, rab, rbb = root_partials(P, k, ox, oy, r0, ux[0], uy[0])
    return _compose2(r0, ra, rb, raa, rab, rbb, ux, uy)


@numba.njit(**_JIT)
def _center_ray_jet(P, k, ux, uy):
    """``navigation.geometry.ray_length_center_jet`` of row ``P[k]``."""
    qx = P[k, 0] + ux[0]
    qy = P[k, 1] + uy[0]
    b, bx, by, bxx, bxy, byy = _beta_derivatives(P, k, qx, qy)
    r = 1.0 / math.sqrt(b + 1.0)
    r3 = -0.5 * r * r * r
    r5 = -1.5 * r3 * r * r
    return _compose2(r, r3 * bx, r3 * by, r5 * bx * bx + r3 * bxx, r5 * bx * by + r3 * bxy,
                     r5 * by * by + r3 * byy, ux, uy)


@numba.njit(**_JIT)
def _near(P, k, px, py, margin):
    """``_pairs``' test: ``(px, py)`` within ``margin`` of row ``P[k]``'s bounding rectangle."""
    dx = px - P[k, 0]
    dy = py - P[k, 1]
    lx = abs(dx * P[k, 2] + dy * P[k, 3])
    ly = abs(dy * P[k, 2] - dx * P[k, 3])
    return lx < P[k, 4] + margin and ly < P[k, 5] + margin


@numba.njit(**_JIT)
def _load(A, n):
    return (A[n, 0], A[n, 1], A[n, 2], A[n, 3], A[n, 4], A[n, 5])


@numba.njit(**_JIT)
def _store(A, n, a):
    for j in range(6):
        A[n, j] = a[j]


# ------------------------------------------------------------------------------------ stages
@numba.njit(error_model="numpy", **_JIT)  # 1 / 0 is inf, as in numpy
def purge(X, Y, leaf, parent, is_ws, centre, width, OX, OY):
    """:meth:`navigation.transforms.PurgeStage.apply` on the jets ``X``, ``Y`` (N, 6) into ``OX``, ``OY``."""
    for n in range(X.shape[0]):
        x = _load(X, n)
        y = _load(Y, n)
        ax, ay = x, y
        for k in range(leaf.shape[0]):
            if not _near(leaf, k, x[0], y[0], width[k] * 1.0001):
                continue
            cx, cy = centre[k, 0], centre[k, 1]
            dx, dy = x[0] - cx, y[0] - cy
            r0 = math.hypot(dx, dy)
            ir = 1.0 / r0
            ux0, uy0 = dx * ir, dy * ir
            rl0 = _ray(leaf, k, cx, cy, ux0, uy0, False)
            rp0 = _ray(parent, k, cx, cy, ux0, uy0, is_ws[k])
            # the pairs whose switch is exactly 0 move nothing (as in the numpy path)
            if not ((rl0 - rp0) * (1.0 / (r0 - rp0)) > _EDGE and (r0 - rl0) * (1.0 / width[k]) < 1.0 - _EDGE):
                continue
            r, ux, uy = _polar(x, y, cx, cy)
            r_leaf = _root_jet(leaf, k, cx, cy, rl0, ux, uy)
            r_par = _root_jet(parent, k, cx, cy, rp0, ux, uy)
            t = _sub(r, r_par)
            e = _sub(r_leaf, r_par)
            z1 = _eta(_mul(e, _reciprocal(t)))
            z2 = _eta(_scale(_sub(r, r_leaf), 1.0 / width[k]))
            sigma = _mul(z1, _rsub(1.0, z2))
            shift = _mul(e, sigma)
            ax = _add(ax, _neg(_mul(shift, ux)))
            ay = _add(ay, _neg(_mul(shift, uy)))
        _store(OX, n, ax)
        _store(OY, n, ay)


@numba.njit(error_model="numpy", **_JIT)
def star_to_sphere(X, Y, roots, rho, width, OX, OY):
    """:meth:`navigation.transforms.StarToSphere.apply` on the jets ``X``, ``Y`` into ``OX``, ``OY``."""
    for n in range(X.shape[0]):
        x = _load(X, n)
        y = _load(Y, n)
        ax, ay = x, y
        for k in range(roots.shape[0]):
            if not _near(roots, k, x[0], y[0], width[k] * 1.0001):
                continue
            r, ux, uy = _polar(x, y, roots[k, 0], roots[k, 1])
            big_r = _center_ray_jet(roots, k, ux, uy)
            sw = _rsub(1.0, _eta(_scale(_sub(r, big_r), 1.0 / width[k])))
            shift = _mul(_rsub(rho[k], big_r), sw)
            ax = _add(ax, _mul(shift, ux))
            ay = _add(ay, _mul(shift, uy))
        _store(OX, n, ax)
        _store(OY, n, ay)


@numba.njit(error_model="numpy", **_JIT)
def sphere_to_point(X, Y, centres, rho, delta, ws, rho0, width0, OX, OY):
    """:meth:`navigation.transforms.SphereToPoint.apply` (collapse, outer, psi) on the jets
    ``X``, ``Y`` into ``OX``, ``OY``; ``ws`` is the packed workspace as a ``(1, 7)`` array."""
    inner = min(ws[0, 4], ws[0, 5]) - width0
    c0x, c0y = ws[0, 0], ws[0, 1]
    for n in range(X.shape[0]):
        x = _load(X, n)
        y = _load(Y, n)
        # collapse: disc j onto its centre
        ax, ay = x, y
        for k in range(centres.shape[0]):
            ddx = x[0] - centres[k, 0]
            ddy = y[0] - centres[k, 1]
            reach = rho[k] + delta[k]
            if not (ddx * ddx + ddy * ddy < reach * reach):
                continue
            r, ux, uy = _polar(x, y, centres[k, 0], centres[k, 1])
            z = _scale(_add(r, (-rho[k], 0.0, 0.0, 0.0, 0.0, 0.0)), 1.0 / delta[k])
            eta = _eta(z)
            s = _add(_mul(z, _rsub(1.0, eta)), eta)
            shrink = _mul(_rsub(1.0, s), r)
            ax = _add(ax, _neg(_mul(shrink, ux)))
            ay = _add(ay, _neg(_mul(shrink, uy)))
        x, y = ax, ay
        # outer: the workspace onto the circle of radius rho0
        ddx = x[0] - c0x
        ddy = y[0] - c0y
        if ddx * ddx + ddy * ddy > inner * inner:
            r, ux, uy = _polar(x, y, c0x, c0y)
            big_r = _center_ray_jet(ws, 0, ux, uy)
            sw = _rsub(1.0, _eta(_scale(_sub(big_r, r), 1.0 / width0)))
            shift = _mul(_rsub(rho0, big_r), sw)
            x = _add(x, _mul(shift, ux))
            y = _add(y, _mul(shift, uy))
        # psi: the open disc onto the plane
        dx = x[0] - c0x
        dy = y[0] - c0y
        r = math.hypot(dx, dy)
        ok = r < rho0
        gain = rho0 / (rho0 - r if ok else _TINY)
        if r > 0.0:
            ir = 1.0 / r
            ux, uy = dx * ir, dy * ir
        else:  # the centre: psi is C1 there (G(r) = 1 + r / rho0 + ...); the limit along +x
            ux, uy = 1.0, 0.0
        g1 = gain * gain * (1.0 / rho0) if ok else 0.0
        t = r * g1
        fx0, fx1 = gain + t * ux * ux, t * ux * uy
        fy0, fy1 = fx1, gain + t * uy * uy
        pp = 2.0 * t * gain * (1.0 / rho0) - g1
        bx = g1 + pp * ux * ux
        by = g1 + pp * uy * uy
        px = _compose2(c0x + dx * gain, fx0, fy0, ux * (2.0 * g1 + bx), uy * bx, ux * by, x, y)
        py = _compose2(c0y + dy * gain, fx1, fy1, uy * bx, ux * by, uy * (2.0 * g1 + by), x, y)
        _store(OX, n, px)
        _store(OY, n, py)


# ------------------------------------------------------------------------- oriented potential
@numba.njit(**_JIT)
def _potential(rx, ry, c, ax_, ay_, pts, inv_k):
    """The oriented potential ``phi_O`` of :mod:`navigation.oriented` at the normalised
    point-world coordinates ``x' = (rx, ry)`` (goal at 0) and its first and second derivatives
    in ``x'``: the sink ``ln |x'|^2``, the dipole ``c (x'.p) / |x'|^2`` along ``p = (ax_, ay_)``
    and the point obstacles ``-(1/K) sum_j ln |x' - P'_j|^2`` (``inv_k = 1/K``)."""
    d = rx * rx + ry * ry
    inv = 1.0 / d
    inv2, inv3 = inv * inv, inv * inv * inv
    # sink ln |x'|^2
    f = math.log(d)
    fx, fy = 2 * rx * inv, 2 * ry * inv
    fxx = 2 * inv - 4 * rx * rx * inv2
    fxy = -4 * rx * ry * inv2
    fyy = 2 * inv - 4 * ry * ry * inv2
    # dipole c (x'.p)/|x'|^2
    nn = rx * ax_ + ry * ay_
    f = f + c * nn * inv
    fx = fx + c * (ax_ * inv - 2 * nn * rx * inv2)
    fy = fy + c * (ay_ * inv - 2 * nn * ry * inv2)
    fxx = fxx + c * (-4 * ax_ * rx * inv2 - 2 * nn * inv2 + 8 * nn * rx * rx * inv3)
    fxy = fxy + c * (-2 * (ax_ * ry + ay_ * rx) * inv2 + 8 * nn * rx * ry * inv3)
    fyy = fyy + c * (-4 * ay_ * ry * inv2 - 2 * nn * inv2 + 8 * nn * ry * ry * inv3)
    # point obstacles -(1/K) sum_j ln |x' - P'_j|^2
    if pts.shape[0]:
        s0 = s1 = s2 = s3 = s4 = s5 = 0.0
        for j in range(pts.shape[0]):
            dx = rx - pts[j, 0]
            dy = ry - pts[j, 1]
            d2 = dx * dx + dy * dy
            iv = 1.0 / d2
            iv2 = iv * iv
            s0 += math.log(d2)
            s1 += 2 * dx * iv
            s2 += 2 * dy * iv
            s3 += 2 * iv - 4 * dx * dx * iv2
            s4 += -4 * dx * dy * iv2
            s5 += 2 * iv - 4 * dy * dy * iv2
        f = f - inv_k * s0
        fx = fx - inv_k * s1
        fy = fy - inv_k * s2
        fxx = fxx - inv_k * s3
        fxy = fxy - inv_k * s4
        fyy = fyy - inv_k * s5
    return f, fx, fy, fxx, fxy, fyy


@numba.njit(error_model="numpy", **_JIT)
def potential_rows(rx, ry, c, axis, pts, inv_k, out):
    """:func:`_potential` at every ``(rx[i], ry[i])`` into ``out (N, 6)``."""
    for i in range(len(rx)):
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4], out[i, 5] = _potential(
            rx[i], ry[i], c, axis[0], axis[1], pts, inv_k)


@numba.njit(error_model="numpy", **_JIT)
def oriented(X, Y, pg, A, c, axis, pts, inv_k, mu, floor, out_s, out_v, out_f):
    """:meth:`navigation.oriented.OrientedField._evaluate` at free points away from the goal,
    from the chain's jets ``X``, ``Y`` (N, 6): the normalised point-world coordinates
    ``x' = A (x - P_G)``, the oriented potential ``phi_O`` (sink, dipole of strength ``c`` along
    ``axis``, point obstacles ``pts`` weighted by ``inv_k``) composed with them, and from it

    * ``out_s[n] = (value, angle, flat, flow_ok, flow_angle)``: ``mu logistic(phi_O)``, the
      direction of ``-grad phi_O`` (0 where ``|grad|^2 <= floor``: ``flat``), whether the
      push-forward direction was defined (``flow_ok``) and its angle;
    * ``out_v[n] = (field_x, field_y, grad_angle_x, grad_angle_y, flow_grad_x, flow_grad_y,
      g_x, g_y)``;
    * ``out_f[n] = (J_xx, J_xy, J_yx, J_yy, H_xx, H_xy, H_yy)``: the field's Jacobian and
      ``phi_O``'s Hessian.

    The same formulas as the numpy code; the 2 x 2 solves of the push-forward direction are
    written out (Cramer's rule instead of LAPACK's LU: equal to rounding)."""
    a00, a01, a10, a11 = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    ax_, ay_ = axis[0], axis[1]
    for n in range(X.shape[0]):
        x = _load(X, n)
        y = _load(Y, n)
        cx = _add(x, (-pg[0], 0.0, 0.0, 0.0, 0.0, 0.0))
        cy = _add(y, (-pg[1], 0.0, 0.0, 0.0, 0.0, 0.0))
        Xp = _add(_scale(cx, a00), _scale(cy, a01))
        Yp = _add(_scale(cx, a10), _scale(cy, a11))
        rx, ry = Xp[0], Yp[0]
        f, fx, fy, fxx, fxy, fyy = _potential(rx, ry, c, ax_, ay_, pts, inv_k)
        phi = _compose2(f, fx, fy, fxx, fxy, fyy, Xp, Yp)
        v, g0, g1, h00, h01, h11 = phi
        s = _logistic(v)
        sc = s * _logistic(-v)
        scc = sc * (_logistic(-v) - s)
        out_s[n, 0] = mu * s
        out_v[n, 0] = -mu * sc * g0
        out_v[n, 1] = -mu * sc * g1
        out_f[n, 0] = -mu * (scc * g0 * g0 + sc * h00)
        out_f[n, 1] = -mu * (scc * g0 * g1 + sc * h01)
        out_f[n, 2] = -mu * (scc * g1 * g0 + sc * h01)
        out_f[n, 3] = -mu * (scc * g1 * g1 + sc * h11)
        out_f[n, 4], out_f[n, 5], out_f[n, 6] = h00, h01, h11
        out_v[n, 6], out_v[n, 7] = g0, g1
        a0, a1 = -g0, -g1
        m2 = a0 * a0 + a1 * a1
        flat = not (m2 > floor)
        out_s[n, 2] = 1.0 if flat else 0.0
        if flat:
            out_s[n, 1] = 0.0
            out_v[n, 2] = out_v[n, 3] = 0.0
        else:
            out_s[n, 1] = math.atan2(a1, a0)
            out_v[n, 2] = (-a0 * h01 + a1 * h00) / m2
            out_v[n, 3] = (-a0 * h11 + a1 * h01) / m2
        # push-forward direction -(dx'/dq)^(-1) grad_x' phi_O (OrientedField._flow)
        out_s[n, 3] = 0.0
        j00, j01, j10, j11 = Xp[1], Xp[2], Yp[1], Yp[2]
        det = j00 * j11 - j01 * j10
        if flat or not math.isfinite(det) or not abs(det) > 0:
            continue
        idet = 1.0 / det
        w0 = (j11 * fx - j01 * fy) * idet
        w1 = (j00 * fy - j10 * fx) * idet
        # dw = J^(-1) (H_x' J - T), T_ik = sum_j (d^2 x'_i / dq_j dq_k) w_j
        m00 = fxx * j00 + fxy * j10 - (Xp[3] * w0 + Xp[4] * w1)
        m01 = fxx * j01 + fxy * j11 - (Xp[4] * w0 + Xp[5] * w1)
        m10 = fxy * j00 + fyy * j10 - (Yp[3] * w0 + Yp[4] * w1)
        m11 = fxy * j01 + fyy * j11 - (Yp[4] * w0 + Yp[5] * w1)
        dw00 = (j11 * m00 - j01 * m10) * idet
        dw01 = (j11 * m01 - j01 * m11) * idet
        dw10 = (j00 * m10 - j10 * m00) * idet
        dw11 = (j00 * m11 - j10 * m01) * idet
        wm2 = w0 * w0 + w1 * w1
        if not (math.isfinite(wm2) and wm2 > floor and math.isfinite(dw00) and math.isfinite(dw01)
                and math.isfinite(dw10) and math.isfinite(dw11)):
            continue
        out_s[n, 3] = 1.0
        out_s[n, 4] = math.atan2(-w1, -w0)
        out_v[n, 4] = (w0 * dw10 - w1 * dw00) / wm2
        out_v[n, 5] = (w0 * dw11 - w1 * dw01) / wm2
