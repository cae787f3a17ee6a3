"""Squircle fitting of point clusters, conservative completion, decomposition, inflation.

Paper 001 section 4.1.2 models every obstacle as a squircle (FORMATS.md): centre ``c``, half
extents ``a = width/2``, ``b = height/2``, rotation ``theta`` and curvature ``s``. In the
normalised frame ``x = p_x / a``, ``y = p_y / b`` with ``p = R(-theta)(q - c)``,

.. math::  g(q)^2 = \\beta(q) + 1 = \\tfrac12\\left(x^2 + y^2 + \\sqrt{x^4 + y^4 + (2 - 4 s^2) x^2 y^2}\\right)

``g`` is a gauge (positively homogeneous of degree 1, ``g = 1`` on the boundary), so the point
of the boundary on the ray from ``c`` through ``q`` is ``c + (q - c) / g`` and the *radial
error* is

.. math::  e(q) = |q - c| \\, (1 - 1 / g(q))   \\qquad (> 0 \\text{ outside}).

:func:`fit_squircle` minimises ``sum e(q_i)^2`` over the cluster's points plus a penalty for
free-space evidence inside the estimate and a penalty ``0.1 sqrt(N) max(a - a0, 0)`` (and for
``b``) on extents beyond the starting rectangle's (the unseen side of a partial view is not
constrained by data), each radial error weighted by ``g / (|q - c| |grad g|)`` (so that it is
the distance to the boundary to first order, :func:`_distance_weights`), by Levenberg-Marquardt
(:func:`_lm`, a numba kernel: :mod:`perception._fit_kernel`) over ``(c, log a, log b, theta,
s)``, started from OpenCV's ``minAreaRect`` (``s = 0.9``) and ``fitEllipse`` (``s = 0.1``) of
the points; of the two results the one with the smaller total
cost is kept, the free-space penalty deciding between fits of comparable point error. A refit
is warm (``init``, the previous estimates): the nearest previous estimate is solved first and
kept when it still explains the points and the free space, else the rectangle seed is the
alternative (:func:`fit_squircle`); in :func:`fit_cluster` a previous estimate the data does not
contradict is kept without a fit (:func:`_kept`). Then the *conservative completion*:

1. a face of the estimate counts as seen when at least two points lie on it and were seen
   from outside it (the beam direction points into the face); along an axis whose two faces
   were not both seen the extent is at least ``min_unseen``, grown away from the seen face
   (behind it, where the beams did not reach);
2. extents are at least ``min_extent`` and at most ``max_extent``;
3. the estimate is scaled about its centre until every observed point lies on or inside its
   boundary, up to ``inside_tol``.

:func:`fit_cluster` decomposes clusters a single squircle does not explain (paper 001
section 4.2.1): when the RMS radial error exceeds ``split_tol`` the cluster is split at its
corners - connected components, then runs of points whose local direction (principal axis of
their neighbours) agrees modulo 90 degrees, runs that still bend split by the modes of their
directions (:func:`_mode_split`: walls crossing at a shallow angle) and then cut where they bend
(each side of a cut split into its connected components, :func:`_connected`) - and the
runs one rectangle explains together without swallowing free space (the faces of one wall) are
merged back; every piece is fitted on its own, and adjacent pieces overlap once inflated,
forming a tree (cycles broken by :func:`_break_cycles`); a piece is then refitted without the
returns its neighbours already contain when that makes it smaller and changes no overlap
(:func:`_tighten`; docs/perception.md, "Decomposition").

:func:`inflate` grows a squircle by the robot radius (configuration-space obstacle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np
from scipy.optimize import least_squares

from navigation._geom_kernel import _arr
from navigation.geometry import Squircle

from . import _fit_kernel, _shape_kernel
from .config import PerceptionConfig
from .errors import ScanError

__all__ = ["Fit", "gauge", "radial_error", "fit_squircle", "fit_cluster", "inflate", "rect_error"]

_S_MAX = 0.99
_NO_POINTS = np.zeros((0, 2))
_MAX_POINTS = 160  # points used by one least-squares fit (evenly subsampled)
_MAX_FREE = 200
_LM_NFEV = 30
_INFLATE_LINEAR = 5  # inflation steps tried in order before bisection (:func:`inflate`)
_DISTANCE_WEIGHTS = True  # fit distances to first order (:func:`_distance_weights`), not radial errors
_REWEIGHT_TOL = 0.1  # distance weights moving more than this during a solve: solved again with the new ones
_CONTAIN_DISTANCE = True  # containment and "within inside_tol" by distance (:func:`_outside`), not radial error
_FITS = 0  # fit_squircle calls in this process (:func:`fit_count`)
_SOLVER = "lm"  # "lm" (:func:`_lm`) or "scipy" (``least_squares``, trust region reflective)


@dataclass(frozen=True, slots=True, eq=False)
class Fit:
    """A fitted squircle and how well it explains its points.

    Attributes
    ----------
    squircle : Squircle
    rms : float
        RMS radial error of the points (m) of the least-squares fit, before completion.
    closed : bool
        True when every face was seen (no completion was needed).
    indices : ndarray of int
        Indices of the points (in the array given to :func:`fit_cluster`) this piece explains.
    p95 : float
        95th percentile of the points' absolute radial errors (m), same fit as ``rms``.
    """

    squircle: Squircle
    rms: float
    closed: bool
    indices: np.ndarray
    p95: float = 0.0


def _p95(a: np.ndarray) -> float:
    """``np.percentile(a, 95)`` (linear interpolation, the same value) by one ``np.partition``:
    ``np.percentile`` costs about 0.1 ms per call of its own, and a refit takes a few dozen."""
    n = len(a)
    if n < 2 or not np.isfinite(a).all():
        return float(np.percentile(a, 95))
    v = (n - 1) * 0.95
    lo = math.floor(v)
    if v >= n - 1:
        return float(np.max(a))
    part = np.partition(a, (lo, lo + 1))
    x0, x1 = float(part[lo]), float(part[lo + 1])
    t = v - lo
    d = x1 - x0
    return x1 - d * (1 - t) if t >= 0.5 else x0 + d * t


def _median(a: np.ndarray) -> float:
    """``float(np.median(a))`` of a non-empty 1-D array (the middle value, or the mean of the two
    middle values ``(x0 + x1) / 2``, the same arithmetic) by one ``np.partition``; NaNs go to
    ``np.median``."""
    n = len(a)
    if n == 0 or not np.isfinite(a).all():
        return float(np.median(a))
    h = n // 2
    if n % 2:
        return float(np.partition(a, h)[h])
    part = np.partition(a, (h - 1, h))
    return (float(part[h - 1]) + float(part[h])) / 2


def _params(sq: Squircle) -> np.ndarray:
    return np.array([sq.center[0], sq.center[1], math.log(sq.width / 2), math.log(sq.height / 2), sq.theta, sq.s])


def _gauge_xy(x: np.ndarray, y: np.ndarray, s) -> np.ndarray:
    x2, y2 = x * x, y * y
    return np.sqrt(0.5 * (x2 + y2 + np.sqrt(np.maximum(x2 * x2 + y2 * y2 + (2.0 - 4.0 * s * s) * x2 * y2, 0.0))))


def _local(p: np.ndarray, q: np.ndarray):
    c, sn = math.cos(p[4]), math.sin(p[4])
    dx, dy = q[:, 0] - p[0], q[:, 1] - p[1]
    return dx * c + dy * sn, dy * c - dx * sn


def gauge(sq: Squircle, q) -> np.ndarray:
    """Gauge ``g(q) = sqrt(beta(q) + 1)`` of ``sq`` at points ``q (N, 2)`` (``< 1`` inside)."""
    q = _arr(np.asarray(q, dtype=float).reshape(-1, 2))
    # compiled (:mod:`perception._shape_kernel`): ``_gauge_xy`` of ``_local`` row by row, bit-identical
    return _shape_kernel.gauge(sq.center, sq.width, sq.height, sq.theta, sq.s, q)


def radial_error(sq: Squircle, q) -> np.ndarray:
    """Signed radial error ``|q - c| (1 - 1/g(q))`` of points ``q (N, 2)`` (positive outside)."""
    q = _arr(np.asarray(q, dtype=float).reshape(-1, 2))
    # compiled: ``np.linalg.norm(q - c, axis=1) * (1 - 1 / max(gauge, 1e-9))`` row by row, bit-identical
    return _shape_kernel.radial_error(sq.center, sq.width, sq.height, sq.theta, sq.s, q)


def _outside(sq: Squircle, q) -> np.ndarray:
    """How far points are outside ``sq``: the radial error times the distance weight (the
    distance to first order) with ``_CONTAIN_DISTANCE``, else the radial error."""
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    r = radial_error(sq, q)
    if _CONTAIN_DISTANCE and len(q):
        r = r * _distance_weights(_params(sq), q)
    return r


def _residuals(p: np.ndarray, q: np.ndarray, free: np.ndarray, w_free: float, ref=None, wq=None) -> np.ndarray:
    u, v = _local(p, q)
    a, b = math.exp(p[2]), math.exp(p[3])
    reg = np.zeros(0) if ref is None else ref[2] * np.array([max(a - ref[0], 0.0), max(b - ref[1], 0.0)])
    g = np.maximum(_gauge_xy(u / a, v / b, p[5]), 1e-6)
    r = np.hypot(u, v) * (1.0 - 1.0 / g)
    if wq is not None:
        r = r * wq
    if len(free):
        fu, fv = _local(p, free)
        gf = np.maximum(_gauge_xy(fu / a, fv / b, p[5]), 0.2)
        pen = w_free * np.hypot(fu, fv) * np.maximum(1.0 / gf - 1.0, 0.0)
        return np.concatenate((r, pen, reg))
    return np.concatenate((r, reg))


def _gauge_jac(u, v, p):
    """Gauge ``g`` at local coordinates ``(u, v)`` of parameters ``p`` and its exact derivatives
    ``(N, 6)`` with respect to ``p = (cx, cy, log a, log b, theta, s)``, plus ``rho = |(u, v)|``
    and its derivatives."""
    a, b, s = math.exp(p[2]), math.exp(p[3]), p[5]
    c, sn = math.cos(p[4]), math.sin(p[4])
    x, y = u / a, v / b
    x2, y2 = x * x, y * y
    k = 2.0 - 4.0 * s * s
    R = np.sqrt(np.maximum(x2 * x2 + y2 * y2 + k * x2 * y2, 1e-300))
    B = 0.5 * (x2 + y2 + R)
    g = np.sqrt(np.maximum(B, 1e-300))
    dBx = x + (2.0 * x2 * x + k * x * y2) / (2.0 * R)
    dBy = y + (2.0 * y2 * y + k * x2 * y) / (2.0 * R)
    dBs = -2.0 * s * x2 * y2 / R
    # chain rule through u, v (p0, p1, p4), a = e^p2, b = e^p3
    du = np.array([-c, -sn, 0.0, 0.0])  # du/d(p0, p1) ; du/dp4 = v
    dv = np.array([sn, -c, 0.0, 0.0])  # dv/d(p0, p1) ; dv/dp4 = -u
    dg = np.empty((len(u), 6))
    gx, gy = dBx / (2.0 * g * a), dBy / (2.0 * g * b)  # dg/du, dg/dv
    dg[:, 0] = gx * du[0] + gy * dv[0]
    dg[:, 1] = gx * du[1] + gy * dv[1]
    dg[:, 2] = -dBx * x / (2.0 * g)
    dg[:, 3] = -dBy * y / (2.0 * g)
    dg[:, 4] = gx * v - gy * u
    dg[:, 5] = dBs / (2.0 * g)
    rho = np.maximum(np.hypot(u, v), 1e-300)
    drho = np.zeros((len(u), 6))
    drho[:, 0] = (u * du[0] + v * dv[0]) / rho
    drho[:, 1] = (u * du[1] + v * dv[1]) / rho
    return g, dg, np.hypot(u, v), drho


def _residuals_jac(p: np.ndarray, q: np.ndarray, free: np.ndarray, w_free: float, ref=None, wq=None) -> np.ndarray:
    """Exact Jacobian ``(len(residuals), 6)`` of :func:`_residuals` (clamps differentiate to 0;
    the point weights ``wq`` are constants)."""
    u, v = _local(p, q)
    g, dg, rho, drho = _gauge_jac(u, v, p)
    clamp = g < 1e-6
    g = np.maximum(g, 1e-6)
    dg[clamp] = 0.0
    Jq = drho * (1.0 - 1.0 / g)[:, None] + (rho / (g * g))[:, None] * dg
    J = [Jq if wq is None else Jq * wq[:, None]]
    if len(free):
        fu, fv = _local(p, free)
        gf, dgf, rf, drf = _gauge_jac(fu, fv, p)
        active = gf < 1.0  # 1/gf - 1 > 0 (the clamp at 0.2 lies inside this set)
        low = gf < 0.2
        gf = np.maximum(gf, 0.2)
        dgf[low] = 0.0
        Jf = w_free * (drf * np.maximum(1.0 / gf - 1.0, 0.0)[:, None] - (rf / (gf * gf))[:, None] * dgf)
        Jf[~active] = 0.0
        J.append(Jf)
    if ref is not None:
        Jr = np.zeros((2, 6))
        a, b = math.exp(p[2]), math.exp(p[3])
        Jr[0, 2] = ref[2] * a if a > ref[0] else 0.0
        Jr[1, 3] = ref[2] * b if b > ref[1] else 0.0
        J.append(Jr)
    return np.concatenate(J)


class _Rect(NamedTuple):
    """Minimum-area rectangle of a point set (OpenCV ``minAreaRect``): centre, extents, angle."""

    cx: float
    cy: float
    w: float
    h: float
    t: float

    @classmethod
    def of(cls, points: np.ndarray) -> "_Rect":
        (cx, cy), (w, h), ang = cv2.minAreaRect(points.astype(np.float32))
        return cls(float(cx), float(cy), float(w), float(h), math.radians(ang))

    def local_abs(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``|u|, |v|``: distances of ``q (N, 2)`` from the centre along the rectangle's axes."""
        c, s = math.cos(self.t), math.sin(self.t)
        dx, dy = q[:, 0] - self.cx, q[:, 1] - self.cy
        return np.abs(dx * c + dy * s), np.abs(dy * c - dx * s)

    def error(self, points: np.ndarray) -> float:
        """RMS distance of ``points`` inside the rectangle to its boundary."""
        if not len(points):
            return math.nan
        # compiled (:func:`perception._shape_kernel.rect_test`): ``|u|, |v|`` of :meth:`local_abs`,
        # ``d = max(min(w / 2 - |u|, h / 2 - |v|), 0)``, ``sqrt(mean(d * d))`` by numpy's pairwise sum
        return float(_shape_kernel.rect_test(points, None, self.cx, self.cy, self.w, self.h, self.t, 0.0)[0])

    def free_inside(self, free, margin: float) -> int:
        """Free points deeper than ``margin`` inside the rectangle."""
        if free is None or not len(free):
            return 0
        # compiled: ``|u| < w / 2 - margin and |v| < h / 2 - margin`` counted
        return int(_shape_kernel.rect_test(_NO_POINTS, free, self.cx, self.cy, self.w, self.h, self.t, margin,
                                           False)[1])


def rect_error(points: np.ndarray) -> float:
    """RMS distance of ``points (N, 2)`` to the boundary of their minimum-area rectangle."""
    if len(points) < 3:
        return 0.0
    return _Rect.of(points).error(points)


def _rect_test(points: np.ndarray, free, margin: float) -> tuple[float, int, _Rect]:
    """``rect_error``, the free points deeper than ``margin`` inside the rectangle (both 0 below
    3 points), and the rectangle, from one ``minAreaRect`` of the (non-empty) ``points``."""
    r = _Rect.of(points) if len(points) else _Rect(0.0, 0.0, 0.0, 0.0, 0.0)
    if len(points) < 3:
        return 0.0, 0, r
    # ``r.error(points), r.free_inside(free, margin)`` in one compiled pass (bit-identical)
    e, n_free = _shape_kernel.rect_test(points, free, r.cx, r.cy, r.w, r.h, r.t, margin)
    return float(e), int(n_free), r


def _piece_cost(points: np.ndarray, free, margin: float) -> float:
    """Decomposition cost of a piece: ``n rect_error`` plus ``margin / 2`` per free point its
    rectangle would swallow (free space must stay free)."""
    e, n_free, _ = _rect_test(points, free, margin)
    return len(points) * e + 0.5 * margin * n_free


_PICKS: dict[tuple[int, int], np.ndarray] = {}  # (length, n) -> the rows _subsample picks


def _subsample(a: np.ndarray, n: int) -> np.ndarray:
    """``n`` rows of ``a`` evenly spaced (``np.linspace(0, len(a) - 1, n)`` truncated; the index
    arrays are kept per length, a fit subsamples its points and free points several times)."""
    if len(a) <= n:
        return a
    key = (len(a), n)
    pick = _PICKS.get(key)
    if pick is None:
        if len(_PICKS) > 4096:
            _PICKS.clear()
        pick = _PICKS[key] = np.linspace(0, len(a) - 1, n).astype(int)
    return a[pick]


def _near_free(free: np.ndarray, q: np.ndarray, cfg: PerceptionConfig) -> np.ndarray:
    """At most ``_MAX_FREE`` free points for a fit, evenly subsampled among those within
    ``min_unseen + free_cell`` of a point of ``q``: only those can lie inside an estimate of
    ``q`` (its extent beyond the points is the unseen minimum), and subsampling all of them
    left most of the ones near a long wall out of the fit (its estimates kept covering free
    space, and the free space kept triggering refits)."""
    if len(free) > _MAX_FREE:
        # compiled (:func:`perception._shape_kernel.near_mask`): the free points the k-d tree
        # query ``cKDTree(q).query(free, distance_upper_bound=...)`` finds (the same selection)
        free = free[_shape_kernel.near_mask(q, free, cfg.min_unseen + cfg.free_cell)]
    return _subsample(free, _MAX_FREE)


def _seeds(points: np.ndarray, views: np.ndarray | None, cfg: PerceptionConfig,
           ellipse: bool = True) -> list[np.ndarray]:
    """Initial parameter vectors from ``minAreaRect`` and ``fitEllipse`` (OpenCV; not with
    ``ellipse`` False: the rectangle's only)."""
    P = points.astype(np.float32)
    (cx, cy), (w, h), ang = cv2.minAreaRect(P)
    t = math.radians(ang)
    hw, hh = max(w / 2, cfg.min_extent / 2), max(h / 2, cfg.min_extent / 2)
    c = np.array([cx, cy])
    # a thin view (one face): put the unseen thickness behind it, away from the sensor
    if views is not None and len(views):
        vbar = views.mean(axis=0)
        ax = np.array([math.cos(t), math.sin(t)])
        ay = np.array([-math.sin(t), math.cos(t)])
        if 2 * hw < cfg.min_unseen:
            c = c + ax * math.copysign(cfg.min_unseen / 2 - hw, float(vbar @ ax) or 1.0)
            hw = cfg.min_unseen / 2
        if 2 * hh < cfg.min_unseen:
            c = c + ay * math.copysign(cfg.min_unseen / 2 - hh, float(vbar @ ay) or 1.0)
            hh = cfg.min_unseen / 2
    seeds = [np.array([c[0], c[1], math.log(hw), math.log(hh), t, 0.9])]
    if ellipse and len(P) >= 5:
        try:
            (ex, ey), (ea, eb), eang = cv2.fitEllipse(P)
        except cv2.error:  # degenerate (collinear) points
            ea = eb = float("nan")
        if (np.isfinite([ex, ey, ea, eb]).all() and min(ea, eb) > cfg.min_extent
                and max(ea, eb) < 3 * max(w, h, cfg.min_unseen)):
            seeds.append(np.array([ex, ey, math.log(ea / 2), math.log(eb / 2), math.radians(eang), 0.1]))
    return seeds


def _warm_seed(init, q: np.ndarray, cfg: PerceptionConfig) -> np.ndarray | None:
    """Parameters of the squircle of ``init`` that fits ``q`` best (smallest median absolute
    radial error of up to 32 points), when it lies within ``min_unseen`` of them; else None."""
    if not init:
        return None
    qq = _subsample(q, 32)
    m = qq.mean(axis=0)  # (once, not per previous estimate)
    near = [sq for sq in init if not math.dist(sq.center, m) > sq.bounding_radius + cfg.min_unseen]
    if not near:
        return None
    # the medians of all of them in one compiled pass (:func:`perception._shape_kernel.warm_medians`:
    # ``_median(np.abs(radial_error(sq, qq)))``, bit-identical); None: a non-finite error
    med = _shape_kernel.warm_medians(near, _arr(qq))
    best = None
    for k, sq in enumerate(near):
        e = float(med[k]) if med is not None else _median(np.abs(radial_error(sq, qq)))
        if e <= cfg.min_unseen and (best is None or e < best[0]):
            best = (e, sq)
    return None if best is None else _params(best[1])


def _distance_weights(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Per-point weights ``g / (|q - c| |grad g|)`` at parameters ``p`` (the cosine between the
    ray from the centre and the boundary normal; ``grad g . (q - c) = g``): the radial error
    times the weight is the distance to the boundary to first order, ``(g - 1) / |grad g|``.
    Unweighted, a point off a long flat face near its end has a radial error several times its
    distance (the ray meets the face at a grazing angle), so with range noise the fit of a face
    seen from one side grew thick to move its centre away (cluttered20: 0.34 m for a 0.2 m wall)."""
    # compiled (:func:`perception._shape_kernel.distance_weights`): ``_gauge_jac``'s gauge and
    # centre derivatives row by row, ``clip(g / max(rho |grad g|, 1e-12), 0.05, 1)``, bit-identical
    return _shape_kernel.distance_weights(p, q)


class _Problem:
    """The residuals of :func:`_residuals` and their Jacobian as :func:`_lm`'s compiled kernel
    evaluates them (:mod:`perception._fit_kernel`), with the points and the free points in one
    array, and the Jacobian built only from the rows that are not identically zero there: the
    points, the free points inside the estimate (``g < 1``, where the penalty is active: outside
    it the penalty and its derivatives are 0) and the extent regularisation. Same values as
    :func:`_residuals` / :func:`_residuals_jac` (tested); Python access for the tests, the kernel
    calls the same functions inside its loop."""

    __slots__ = ("q", "free", "w_free", "ref", "wq")

    def __init__(self, q: np.ndarray, free: np.ndarray, w_free: float, ref=None, wq=None):
        self.q, self.free, self.w_free, self.ref, self.wq = q, free, w_free, ref, wq

    def residuals(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(residuals, g)``: :func:`_residuals` at ``p`` and the gauge of every point and free point."""
        return _fit_kernel.residuals(p, self.q, self.free, self.w_free, self.ref, self.wq)

    def jacobian(self, p: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """``(J, rows)``: the rows ``rows`` of :func:`_residuals_jac` at ``p`` (``None``: all rows),
        the others being zero there; ``g`` is the gauge :meth:`residuals` returned at ``p``."""
        J, rows = _fit_kernel.jacobian(p, g, self.q, self.free, self.w_free, self.ref, self.wq)
        n = len(self.q) + len(self.free) + (0 if self.ref is None else 2)
        return J, (None if len(rows) == n else rows)


def _lm(x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, scale: np.ndarray, args: tuple, *, max_nfev: int = _LM_NFEV,
        xtol: float = 1e-4, ftol: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """Levenberg-Marquardt on :func:`_residuals` (exact Jacobian :func:`_residuals_jac`) from
    ``x0``, variables scaled by ``scale``, steps projected onto the bounds ``[lo, hi]``; at most
    ``max_nfev`` residual evaluations; stops when the cost falls by less than ``ftol`` times
    itself or the scaled step is below ``xtol (xtol + |x / scale|)`` (scipy's tests). Returns
    ``(x, residuals)``. The six-parameter problem needs no more than a 6 x 6 solve per step;
    ``scipy.optimize.least_squares`` spent about 60 % of a fit in its own bookkeeping
    (measured: 6 ms per fit of 160 points and 200 free points, 2.3 ms of it in the residuals
    and Jacobians). ``args = (q, free, w_free, ref, wq)``; runs in the compiled kernel
    :func:`perception._fit_kernel.lm` (the residuals and Jacobian rows of :class:`_Problem`)."""
    q, free, w_free, ref, wq = args
    return _fit_kernel.lm(x0, lo, hi, scale, q, free, w_free, ref, wq, max_nfev=max_nfev, xtol=xtol, ftol=ftol)


_SCALE = np.array([0.05, 0.05, 0.2, 0.2, 0.1, 0.1])
_BOUNDS: dict[tuple[float, float], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}


def _bounds(cfg: PerceptionConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(lo, hi, lo + 1e-9, hi - 1e-9)``: the bounds of the parameters (extents within
    ``[min_extent, max_extent]``, ``s`` within ``[0, _S_MAX]``), built once per pair of extents
    (read-only)."""
    key = (cfg.min_extent, cfg.max_extent)
    hit = _BOUNDS.get(key)
    if hit is None:
        lo = np.array([-np.inf, -np.inf, math.log(cfg.min_extent / 2), math.log(cfg.min_extent / 2), -np.inf, 0.0])
        hi = np.array([np.inf, np.inf, math.log(cfg.max_extent / 2), math.log(cfg.max_extent / 2), np.inf, _S_MAX])
        hit = _BOUNDS[key] = (lo, hi, lo + 1e-9, hi - 1e-9)
    return hit


def _solve(seed: np.ndarray, q: np.ndarray, free: np.ndarray, cfg: PerceptionConfig, ref_seed=None):
    """Least squares from ``seed``; extents beyond those of ``ref_seed`` (default ``seed``) are
    penalised."""
    lo, hi, lo9, hi9 = _bounds(cfg)
    x0 = np.clip(seed, lo9, hi9)
    scale = _SCALE
    try:
        # extents beyond the seed's (the rectangle of the points, with the unseen minimum) are
        # penalised: the data does not constrain the unseen side, the estimate stays small there
        r0 = x0 if ref_seed is None else np.clip(ref_seed, lo9, hi9)
        ref = (math.exp(r0[2]), math.exp(r0[3]), 0.1 * math.sqrt(len(q)))
        wq = _distance_weights(x0, q) if _DISTANCE_WEIGHTS else None
        if _SOLVER == "scipy":
            res = least_squares(_residuals, x0, jac=_residuals_jac, bounds=(lo, hi), args=(q, free, 1.0, ref, wq),
                                x_scale=scale, method="trf", max_nfev=20, xtol=1e-4, ftol=1e-4)
            x, fun = res.x, res.fun
        else:
            x, fun = _lm(x0, lo, hi, scale, (q, free, 1.0, ref, wq))
            if wq is not None and np.isfinite(x).all():
                # the weights are constants of a solve: taken at the seed, they leave part of the
                # radial error's bias (a centre farther behind a face shortens the radial errors
                # near the face's ends), and a face seen from one side came out thick (simple
                # noisy: 0.36 m for a 0.2 m wall). One more solve from the solution with the
                # weights there, when they moved
                w1 = _distance_weights(x, q)
                if float(np.max(np.abs(w1 - wq))) > _REWEIGHT_TOL:
                    x1, fun1 = _lm(np.clip(x, lo9, hi9), lo, hi, scale, (q, free, 1.0, ref, w1))
                    if np.isfinite(x1).all():
                        x, fun, wq = x1, fun1, w1
    except (ValueError, np.linalg.LinAlgError):
        return None
    if not np.isfinite(x).all():
        return None
    # compiled (:func:`perception._shape_kernel.solve_stats`): the radial errors ``rp`` below, their
    # RMS, the penalty and ``_p95(np.abs(rp))`` (numpy's sums and order statistics, bit-identical)
    rms, pen, p95 = _shape_kernel.solve_stats(fun, len(q), wq)
    if p95 is not None:
        return x, rms, pen, p95
    rp = fun[: len(q)] if wq is None else fun[: len(q)] / wq  # radial errors (the reported RMS)
    return x, float(np.sqrt(np.mean(rp * rp))), float(np.sum(fun[len(q):-2] ** 2)), _p95(np.abs(rp))


def _faces_seen(p: np.ndarray, q: np.ndarray, views: np.ndarray | None) -> np.ndarray:
    """``seen[axis, side]``: face ``side`` (0: negative, 1: positive) of ``axis`` was seen."""
    seen = np.zeros((2, 2), bool)
    if views is None or not len(views):
        return ~seen
    # compiled (:func:`perception._shape_kernel.faces_seen`): per point the local coordinates
    # ``nu, nv`` and view directions ``vu, vv``; a face is seen when at least 2 points on it
    # (``|n| >= |other n|``, ``sgn n > 0.3``) were seen looking into it (``sgn vc < -0.05``)
    return _shape_kernel.faces_seen(p, q, views)


def _check_views(views, q: np.ndarray) -> np.ndarray | None:
    """The view directions ``views`` (None: none) checked, one row per point of ``q``."""
    vw = None if views is None else _check(views, "views")
    if vw is not None and len(vw) != len(q):
        raise ScanError(f"views: expected {len(q)} rows (one per point), got {len(vw)}", "views")
    return vw


def _complete(p: np.ndarray, q: np.ndarray, views, cfg: PerceptionConfig) -> tuple[np.ndarray, bool]:
    """Conservative completion (module docstring, steps 1-2)."""
    p = p.copy()
    seen = _faces_seen(p, q, views)
    c, s = math.cos(p[4]), math.sin(p[4])
    axes = (np.array([c, s]), np.array([-s, c]))
    for k in range(2):
        h = math.exp(p[2 + k])
        if seen[k].all() or 2 * h >= cfg.min_unseen:
            continue
        new = cfg.min_unseen / 2
        if seen[k, 1] and not seen[k, 0]:
            shift = -(new - h)  # the + face stays, grow towards -
        elif seen[k, 0] and not seen[k, 1]:
            shift = new - h
        else:
            shift = 0.0
        p[0:2] += axes[k] * shift
        p[2 + k] = math.log(new)
    for k in (2, 3):
        p[k] = min(max(p[k], math.log(cfg.min_extent / 2)), math.log(cfg.max_extent / 2))
    return p, bool(seen.all())


def _contain(p: np.ndarray, q: np.ndarray, tol: float) -> np.ndarray:
    """Grow the extents until every point is within ``tol`` of the inside: each axis by what the
    points beyond its faces need (an elongated shape is not inflated along its length for a
    point beyond its side), then, to be sure, uniformly. With ``_CONTAIN_DISTANCE`` ``tol`` is a
    distance (to first order: the radial tolerance of each point is ``tol`` over its
    :func:`_distance_weights` at ``p``)."""
    if _CONTAIN_DISTANCE and len(q):
        for _ in range(3):  # the weights at the grown shape
            p1 = _shape_kernel.contain(p, q, tol / _distance_weights(p, q))
            if np.array_equal(p1, p):
                break
            p = p1
        return p
    return _shape_kernel.contain(p, q, tol)  # compiled, the same steps (bit-identical)


def _to_squircle(p: np.ndarray) -> Squircle:
    th = math.remainder(float(p[4]), 2 * math.pi)
    return Squircle((float(p[0]), float(p[1])), 2 * math.exp(p[2]), 2 * math.exp(p[3]), th,
                    float(min(max(p[5], 0.0), _S_MAX)))


def fit_count() -> int:
    """How many times :func:`fit_squircle` has run in this process (it also runs inside
    :func:`fit_cluster`): the unit of fitting work, about 1 ms each on the drives (an
    :class:`~perception.map.ObstacleMap` update reports its own as ``MapUpdate.fits``).
    Deterministic where a measured time is not."""
    return _FITS


def fit_squircle(points, *, views=None, free=None, config: PerceptionConfig | None = None, init=None) -> Fit:
    """Fit one squircle to a cluster (module docstring), conservatively completed.

    Parameters
    ----------
    points : array_like, shape (N, 2), N >= 1
        Surface points of one obstacle (world frame).
    views : array_like, shape (N, 2), optional
        Unit directions from the sensor to each point (which side each point was seen from).
    free : array_like, shape (F, 2), optional
        Points known to be free (the beams passed there); penalised inside the estimate.
    config : PerceptionConfig, optional
    init : iterable of Squircle, optional
        Previous estimates of this obstacle (warm start): the one closest to the points seeds
        the first least-squares solve; the OpenCV seeds are solved only when that fit does not
        explain the points (RMS within ``split_tol``, 95th percentile within ``3 split_tol``,
        free-space penalty within ``free_tol^2``).

    Returns
    -------
    Fit

    Raises
    ------
    ScanError
        If ``points`` is empty, not ``(N, 2)`` or not finite.
    """
    global _FITS
    _FITS += 1
    cfg = config or PerceptionConfig.from_lidar()
    q = _check(points, "points")
    if len(q) == 0:
        raise ScanError("points: cannot fit a squircle to an empty cluster", "points")
    vw = _check_views(views, q)
    fr = np.zeros((0, 2)) if free is None else _check(free, "free")
    qs = _subsample(q, _MAX_POINTS)
    vs = None if vw is None else _subsample(vw, _MAX_POINTS)
    fs = _near_free(fr, qs, cfg)
    if len(q) < 3:  # too few points for a shape: a min_unseen square behind them
        return Fit(_to_squircle(_few(q, vw, fs, cfg)), 0.0, False, np.arange(len(q)))
    best = None
    warm = _warm_seed(init, qs, cfg)
    seeds = _seeds(qs, vs, cfg, ellipse=warm is None)  # (the ellipse seed is not solved after a warm one)
    # with a warm start the previous estimate stands for its basin: the rectangle seed is the
    # alternative (the ellipse seed only without a warm start)
    for k, seed in enumerate(([warm] + seeds[:1]) if warm is not None else seeds):
        if best is not None and best[1] <= 0.5 * cfg.split_tol and best[2] == 0.0:
            break  # the warm or rectangle seed already explains the points and the free space
        out = _solve(seed, qs, fs, cfg, ref_seed=seeds[0] if (k == 0 and warm is not None) else None)
        if out is None:
            continue
        x, rms, pen, p95 = out
        if (k == 0 and warm is not None and rms <= cfg.split_tol and p95 <= 3 * cfg.split_tol
                and pen <= cfg.free_tol ** 2):
            # the previous estimate, refined, still explains the points (the decomposition's
            # criterion) and keeps the free space free (within about one free cell ``free_tol``
            # deep): the same basin as before, no new seeds
            best = (x, rms, pen, 0.0, p95)
            break
        cost = rms * rms * len(qs) + pen
        # fits of comparable point error: the one keeping free space truthful wins
        if best is None or cost < best[3] * 0.999:
            best = (x, rms, pen, cost, p95)
    if best is None:
        x, rms, p95 = seeds[0], 1.0, 1.0
    else:
        x, rms, p95 = best[0], best[1], best[4]
    x, closed = _complete(x, qs, vs, cfg)
    x = _contain(x, q, cfg.inside_tol)
    return Fit(_to_squircle(x), rms, closed, np.arange(len(q)), p95)


_FEW_SHIFTS = (0.0, 0.25, -0.25, 0.5, -0.5, 0.75, -0.75, 1.0, -1.0)  # lateral shifts, half-widths
_FEW_FREE = False  # the few-returns square slides sideways off free space (off by default: measured,
# docs/perception.md "One or two returns"; random520's robot then stops blocked for good)


def _few(q: np.ndarray, vw, fs: np.ndarray, cfg: PerceptionConfig) -> np.ndarray:
    """Parameters of the estimate of one or two returns: a ``min_unseen`` square behind them
    (centred ``min_unseen / 2`` beyond their mean along the mean view direction), grown to
    contain them. Which side of the returns the obstacle extends to is not seen; where the
    centred square would hold free points (``fs``, the beams passed there) more than
    ``free_tol`` inside, it slides sideways (across the view, by up to its half-width, so that
    the returns stay on its near face) to the shift, in :data:`_FEW_SHIFTS` order (the
    smallest first), holding the fewest (with :data:`_FEW_FREE`; off by default). Measured
    case: a grazing return at the corner of a wall's end (``cluttered20``, the wall at (3.06,
    0.82)) put half of the centred square into the 0.28 m passage beside the wall, which the
    lidar had seen free, and closed it. Why it is off: on ``random520`` the slid squares led to
    a forest repair covering two bars and the region under them with one estimate, and the robot
    stopped ``blocked`` for good (docs/perception.md)."""
    c = q.mean(axis=0)
    half = cfg.min_unseen / 2
    n = None
    if vw is not None:
        n = vw.mean(axis=0)
        nn = float(np.linalg.norm(n))
        n = n / nn if nn > 0 else None
    if n is not None:
        c = c + n * half

    def square(centre):
        p = np.array([centre[0], centre[1], math.log(half), math.log(half), 0.0, 0.5])
        return _contain(p, q, cfg.inside_tol)

    p = square(c)
    if not _FEW_FREE or n is None or not len(fs):
        return p
    side = np.array([-n[1], n[0]])
    best, best_k = p, None
    for t in _FEW_SHIFTS:
        pt = p if t == 0.0 else square(c + side * (t * half))
        k = int(np.count_nonzero(radial_error(_to_squircle(pt), fs) < -cfg.free_tol))
        if best_k is None or k < best_k:
            best, best_k = pt, k
        if k == 0:
            break
    return best


def _distances(sq: Squircle, q: np.ndarray) -> tuple[float, float]:
    """RMS and 95th percentile of the distances of the points ``q`` to ``sq``'s boundary, to
    first order (radial errors times :func:`_distance_weights`)."""
    d = np.abs(radial_error(sq, q)) * _distance_weights(_params(sq), q)
    return float(np.sqrt(np.mean(d * d))), _p95(d)


def _check(a, name: str) -> np.ndarray:
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise ScanError(f"{name}: expected an (N, 2) array of numbers", name) from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        if arr.size == 0:
            return np.zeros((0, 2))
        raise ScanError(f"{name}: expected shape (N, 2), got {arr.shape}", name)
    if not np.isfinite(arr).all():
        raise ScanError(f"{name}: contains non-finite values", name)
    return arr


def _best_cut(points: np.ndarray, min_piece: int, free=None, margin: float = 0.04):
    r = _Rect.of(points)
    c, s = math.cos(r.t), math.sin(r.t)
    dx, dy = points[:, 0] - r.cx, points[:, 1] - r.cy
    best = None
    for coord in (dx * c + dy * s, dy * c - dx * s):
        for cut in np.quantile(coord, np.linspace(0.1, 0.9, 17)):  # (one sort for the 17 cuts)
            left = coord <= cut
            nl = int(left.sum())
            if nl < min_piece or len(points) - nl < min_piece:
                continue
            cost = _piece_cost(points[left], free, margin) + _piece_cost(points[~left], free, margin)
            if best is None or cost < best[0]:
                best = (cost, left)
    return best


def _split(points: np.ndarray, idx: np.ndarray, tol: float, min_piece: int, depth: int,
           force: bool = False, free=None, margin: float = 0.04) -> list[np.ndarray]:
    sub = points[idx]
    whole = _piece_cost(sub, free, margin)
    if depth == 0 or len(idx) < 2 * min_piece or (not force and whole <= tol * len(idx)):
        return [idx]
    cut = _best_cut(sub, min_piece, free, margin)
    if cut is None:
        return [idx]
    cost, left = cut
    if cost >= 0.9 * whole:  # not a clear improvement: keep it whole
        return [idx]
    return (_split(points, idx[left], tol, min_piece, depth - 1, free=free, margin=margin)
            + _split(points, idx[~left], tol, min_piece, depth - 1, free=free, margin=margin))


def _connected(points: np.ndarray, parts: list[np.ndarray], cfg: PerceptionConfig) -> list[np.ndarray]:
    """``parts`` (index arrays into ``points``) split into their connected components (pairs
    closer than ``link``): a straight cut can leave returns of two walls that do not touch on
    one side, and such a piece is a thin rectangle across free space (random12 noisy: a 1.9 m
    sliver of three arms of a zig-zag chain, cheap for the cut's cost because its rectangle is
    too thin to hold a free cell). Components of fewer than ``min_piece`` returns join the piece
    of their nearest return; a part whose components are all that small stays whole."""
    from scipy.spatial import cKDTree

    out, small = [], []
    for p in parts:
        comps = _components(points[p], cfg.link) if len(p) > 1 else []
        big = [p[c] for c in comps if len(c) >= cfg.min_piece]
        if len(comps) <= 1 or not big:
            out.append(p)
            continue
        out += big
        small += [p[c] for c in comps if len(c) < cfg.min_piece]
    if small:
        owner = np.repeat(np.arange(len(out)), [len(o) for o in out])
        tree = cKDTree(points[np.concatenate(out)])
        extra: list[list[np.ndarray]] = [[] for _ in out]
        for c in small:
            d, j = tree.query(points[c])
            extra[int(owner[j[int(np.argmin(d))]])].append(c)
        out = [np.concatenate([o] + e) if e else o for o, e in zip(out, extra)]
    return out


def _merge_parts(points: np.ndarray, parts: list[np.ndarray], cfg: PerceptionConfig, free=None) -> list[np.ndarray]:
    """Merge adjacent pieces whose union one rectangle explains (``rect_error <= split_tol``),
    best pair first: the recursive cuts may split a straight wall (the bar of a T, the corner
    of an L) that a single squircle describes."""
    from scipy.spatial import cKDTree

    parts = list(parts)
    while len(parts) > 1:
        trees = [cKDTree(points[p]) for p in parts]
        best = None
        for a in range(len(parts)):
            for b in range(a + 1, len(parts)):
                d, _ = trees[a].query(points[parts[b]], distance_upper_bound=cfg.link)
                if not np.isfinite(d).any():
                    continue
                e, n_free, _ = _rect_test(points[np.concatenate((parts[a], parts[b]))], free, cfg.free_cell)
                if e <= cfg.split_tol and n_free == 0 and (best is None or e < best[0]):
                    best = (e, a, b)
        if best is None:
            break
        _, a, b = best
        parts[a] = np.concatenate((parts[a], parts[b]))
        del parts[b]
    return parts


def _components(points: np.ndarray, link: float) -> list[np.ndarray]:
    """Index sets of the connected components of ``points`` (pairs closer than ``link``)."""
    from scipy.spatial import cKDTree

    n = len(points)
    pairs = cKDTree(points).query_pairs(link, output_type="ndarray")
    if not len(pairs):
        return [np.array([i]) for i in range(n)]
    _, lab = _shape_kernel.component_labels(n, pairs)  # = connected_components of the pairs (same labels)
    order = np.argsort(lab, kind="stable")
    return np.split(order, np.cumsum(np.bincount(lab))[:-1])


def _segments(points: np.ndarray, cfg: PerceptionConfig) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Split a cluster at its corners (paper 001 section 4.2.1): index sets of connected runs
    of points whose local direction (principal axis of the points within ``radius``) is the
    same modulo 90 degrees. Points at a corner (no dominant direction) join the run of their
    nearest straight neighbour; runs of fewer than ``min_piece`` points join their nearest run.
    Faces of one rectangle share the direction modulo 90 degrees; walls meeting at a corner
    under another angle, and any concave corner, separate runs. Also returns each point's
    direction and straightness (:func:`_directions`)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    psi, straight = _directions(points, cfg, tree)
    pairs = _linked(tree, psi, straight, cfg)
    return _labelled_runs(points, pairs, straight, cfg), psi, straight


def _linked(tree, psi: np.ndarray, straight: np.ndarray, cfg: PerceptionConfig, mode=None) -> np.ndarray:
    """Pairs of straight neighbours (within ``max(2.5 voxel, 0.05) + 2 sigma``) whose
    directions agree modulo 90 degrees (:func:`_direction_tol`) and, with ``mode``, that
    belong to the same direction mode."""
    pairs = tree.query_pairs(max(2.5 * cfg.voxel, 0.05) + 2 * cfg.noise_std, output_type="ndarray")
    if len(pairs):
        a, b = pairs[:, 0], pairs[:, 1]
        dpsi = np.abs(psi[a] - psi[b])
        dpsi = np.minimum(dpsi, math.pi / 2 - dpsi)
        keep = straight[a] & straight[b] & (dpsi < _direction_tol(cfg))
        if mode is not None:
            keep &= mode[a] == mode[b]
        pairs = pairs[keep]
    return pairs


_MODES = True  # a run that bends is first split by the modes of its directions (:func:`_mode_split`)
_MODE_VALLEY = 0.5  # two direction modes are distinct when the density between them falls below this share


def _mode_split(points: np.ndarray, psi: np.ndarray, straight: np.ndarray,
                cfg: PerceptionConfig) -> list[np.ndarray] | None:
    """Split a run whose directions (mod 90 degrees) form two or more distinct modes: index
    sets of the connected runs of straight points within :func:`_direction_tol` of one mode
    (the other points join the run of their nearest point in a large run, as in
    :func:`_segments`). None when the directions have a single mode.

    The direction links of :func:`_segments` chain: near a shallow concave corner the local
    directions (principal axes over a few centimetres) turn gradually from one face's to the
    other's, every neighbouring pair agrees within the tolerance, and two walls crossing at
    48 degrees became one run (``random12`` noisy: a run along the faces of both walls of an
    X, cut by :func:`_split` into pieces across the corners). Modes are the peaks of the
    directions' density (a Gaussian kernel of half the tolerance on the circle of directions
    mod 90 degrees) holding at least ``min_piece`` straight points, at least twice the
    tolerance apart, with the density along one of the arcs between them below
    ``_MODE_VALLEY`` times the lower peak: the faces and ends of one rectangle share a mode, a
    curved wall has none distinct."""
    from scipy.spatial import cKDTree

    tol = _direction_tol(cfg)
    ang = psi[straight]
    if len(ang) < 2 * cfg.min_piece:
        return None
    bins = 180
    grid = (np.arange(bins) + 0.5) * (math.pi / 2) / bins
    d = np.abs(grid[:, None] - ang[None, :])
    d = np.minimum(d, math.pi / 2 - d)
    dens = np.exp(-0.5 * (d / (0.5 * tol)) ** 2).sum(axis=1)
    peaks = [i for i in range(bins) if dens[i] >= dens[i - 1] and dens[i] > dens[(i + 1) % bins]]
    peaks.sort(key=lambda i: -dens[i])
    modes: list[int] = []
    for i in peaks:
        if int(np.count_nonzero(d[i] < tol)) < cfg.min_piece:
            continue
        ok = True
        for j in modes:
            sep = abs(i - j)
            sep = min(sep, bins - sep)
            if sep * (math.pi / 2) / bins < 2 * tol:
                ok = False
                break
            # the density falls between the two peaks along one of the arcs joining them (along
            # the other, the directions at a concave corner turn from one face's to the other's)
            arc = (np.arange(bins) - i) % bins <= (j - i) % bins
            if min(dens[arc].min(), dens[~arc].min()) > _MODE_VALLEY * min(dens[i], dens[j]):
                ok = False
                break
        if ok:
            modes.append(i)
    if len(modes) < 2:
        return None
    dm = np.abs(psi[:, None] - grid[modes][None, :])
    dm = np.minimum(dm, math.pi / 2 - dm)
    mode = np.argmin(dm, axis=1)
    assigned = straight & (dm.min(axis=1) < tol)
    tree = cKDTree(points)
    runs = _labelled_runs(points, _linked(tree, psi, assigned, cfg, mode), assigned, cfg)
    return runs if len(runs) > 1 else None


def _direction_tol(cfg: PerceptionConfig) -> float:
    """Directions (mod 90 degrees) closer than this agree: ``12 + 300 sigma`` degrees (``sigma``
    in metres: 15 degrees at 1 cm noise)."""
    return math.radians(12.0 + 300.0 * cfg.noise_std)


def _directions(points: np.ndarray, cfg: PerceptionConfig, tree=None) -> tuple[np.ndarray, np.ndarray]:
    """Each point's local direction modulo 90 degrees (the principal axis of its up to 24
    neighbours within ``max(0.06, 3 voxel) + 3 sigma``), in ``[0, pi / 2)``, and whether it is
    *straight* (the spread across that axis small against the spread along it, plus the range
    noise, which the averaged returns keep partly)."""
    from scipy.spatial import cKDTree

    n = len(points)
    tree = cKDTree(points) if tree is None else tree
    radius = max(0.06, 3 * cfg.voxel) + 3 * cfg.noise_std
    k = min(n, 24)
    d, nb = tree.query(points, k=k)
    w = (d <= radius).astype(float)
    cnt = w.sum(axis=1)
    P = points[np.minimum(nb, n - 1)]
    mu = (P * w[..., None]).sum(axis=1) / cnt[:, None]
    D = (P - mu[:, None, :]) * w[..., None]
    sxx, syy, sxy = (D[..., 0] ** 2).sum(1), (D[..., 1] ** 2).sum(1), (D[..., 0] * D[..., 1]).sum(1)
    tr, det = sxx + syy, sxx * syy - sxy * sxy
    disc = np.sqrt(np.maximum(tr * tr / 4 - det, 0.0))
    l1, l2 = tr / 2 + disc, np.maximum(tr / 2 - disc, 0.0)
    # straight: spread across the local direction small against the spread along it (plus
    # the range noise, which the averaged returns keep partly)
    sn, st = np.sqrt(l2 / np.maximum(cnt, 1)), np.sqrt(l1 / np.maximum(cnt, 1))
    straight = (cnt >= 4) & (sn <= 0.2 * st + cfg.noise_std)
    psi = np.mod(0.5 * np.arctan2(2 * sxy, sxx - syy), math.pi / 2)
    return psi, straight


def _labelled_runs(points: np.ndarray, pairs: np.ndarray, straight: np.ndarray,
                   cfg: PerceptionConfig) -> list[np.ndarray]:
    """The connected runs of straight points linked by ``pairs``; corner points and runs of
    fewer than ``min_piece`` points join the run of their nearest point in a large run."""
    from scipy.spatial import cKDTree

    n = len(points)
    _, lab = _shape_kernel.component_labels(n, pairs)  # = connected_components of the pairs (same labels)
    lab = np.where(straight, lab, -1)
    sizes = np.bincount(lab[lab >= 0], minlength=n) if (lab >= 0).any() else np.zeros(n, int)
    big = (lab >= 0) & (sizes[np.maximum(lab, 0)] >= max(cfg.min_piece, 3))
    if not big.any():
        return [np.arange(n)]
    # corner points and tiny runs join the run of their nearest point in a large run
    src = np.nonzero(big)[0]
    _, j = cKDTree(points[src]).query(points[~big])
    lab = lab.copy()
    lab[~big] = lab[src[j]]
    _, inv = np.unique(lab, return_inverse=True)
    order = np.argsort(inv, kind="stable")
    return np.split(order, np.cumsum(np.bincount(inv))[:-1])


def _ellipse_error(points: np.ndarray) -> float:
    """RMS radial error of ``points`` to OpenCV's ``fitEllipse`` of them (``inf`` if it fails)."""
    if len(points) < 6:
        return 0.0
    try:
        (ex, ey), (ea, eb), ang = cv2.fitEllipse(points.astype(np.float32))
    except cv2.error:
        return math.inf
    if not (np.isfinite([ex, ey, ea, eb]).all() and min(ea, eb) > 1e-3) or max(ea, eb) > 4.0:
        return math.inf
    e = radial_error(Squircle((float(ex), float(ey)), float(ea), float(eb), math.radians(ang), 0.0), points)
    return float(np.sqrt(np.mean(e * e)))


def _box_error(points: np.ndarray) -> float:
    """RMS radial error of ``points`` to the best of the squircles (``s`` 0.8, 0.95 or 0.99)
    inscribed in their minimum-area rectangle: how well one rounded rectangle explains them."""
    if len(points) < 3:
        return 0.0
    (cx, cy), (w, h), ang = cv2.minAreaRect(points.astype(np.float32))
    w, h = max(w, 1e-3), max(h, 1e-3)
    best = math.inf
    for s_ in (0.8, 0.95, 0.99):
        e = radial_error(Squircle((float(cx), float(cy)), float(w), float(h), math.radians(ang), s_), points)
        best = min(best, float(np.sqrt(np.mean(e * e))))
    return best


def _merge_runs(points: np.ndarray, parts: list[np.ndarray], cfg: PerceptionConfig, free=None,
                reach: float = 0.35) -> list[np.ndarray]:
    """Merge runs whose union one rectangle explains (``rect_error <= split_tol``) without
    swallowing free space, best pair (smallest error, then smallest rectangle) first: the faces
    of one wall, seen from both sides or around its end. Runs farther apart than ``reach``
    (the thickest wall plus a margin) are not merged."""
    parts = [np.asarray(p) for p in parts]
    if len(parts) <= 1:
        return parts
    alive = dict(enumerate(parts))
    trees: dict[int, tuple] = {}  # runs sorted by x (:func:`perception._shape_kernel.min_gap`)
    lo = [points[p].min(axis=0) for p in parts]
    hi = [points[p].max(axis=0) for p in parts]
    gap: dict[tuple[int, int], float] = {}  # a merged run's gap is the smaller of its parts'
    for a in range(len(parts)):
        for b in range(a + 1, len(parts)):
            # runs whose bounding boxes are farther apart than ``reach`` have no pair of points
            # within it: their gap is infinite (what the query returns), so it is not queried
            dx = max(lo[b][0] - hi[a][0], lo[a][0] - hi[b][0], 0.0)
            dy = max(lo[b][1] - hi[a][1], lo[a][1] - hi[b][1], 0.0)
            if dx * dx + dy * dy > (1.001 * reach) ** 2:
                continue
            if a not in trees:
                trees[a] = _shape_kernel.sorted_x(points[parts[a]])
            # compiled: ``cKDTree(run a).query(run b, distance_upper_bound=reach)[0].min()``, the same value
            gap[(a, b)] = _shape_kernel.min_gap(trees[a], points[parts[b]], reach)
    cache: dict[tuple[int, int], tuple] = {}

    def cand(a, b):
        key = (a, b) if a < b else (b, a)
        if key not in cache:
            cache[key] = None
            if gap.get(key, math.inf) <= reach:
                e, n_free, r = _rect_test(points[np.concatenate((alive[a], alive[b]))], free, cfg.free_cell)
                if e <= 1.5 * cfg.split_tol and n_free == 0:
                    cache[key] = (round(e / max(cfg.split_tol, 1e-9) * 4) / 4, r.w * r.h)
        return cache[key]

    nxt = len(parts)
    while len(alive) > 1:
        best = None
        ks = list(alive)
        for x, a in enumerate(ks):
            for b in ks[x + 1:]:
                c = cand(a, b)
                if c is not None and (best is None or c < best[0]):
                    best = (c, a, b)
        if best is None:
            break
        _, a, b = best
        merged = np.concatenate((alive.pop(a), alive.pop(b)))
        for o in alive:
            ga = gap.get((min(a, o), max(a, o)), math.inf)
            gb = gap.get((min(b, o), max(b, o)), math.inf)
            gap[(o, nxt)] = min(ga, gb)
        alive[nxt] = merged
        nxt += 1
    return list(alive.values())


def _overlap(a: Squircle, b: Squircle, grow: float) -> bool:
    """Whether ``a`` and ``b``, both grown by about ``grow``, overlap (boundary samples)."""
    if math.dist(a.center, b.center) > a.bounding_radius + b.bounding_radius + 2 * grow:
        return False
    # the grown squircles' samples and gauges in compiled kernels (bit-identical to
    # ``gauge(B, A.boundary_points(64)) <= 1`` and the converse: :mod:`perception._shape_kernel`)
    A = (a.center, a.width + 2 * grow, a.height + 2 * grow, a.theta, a.s)
    B = (b.center, b.width + 2 * grow, b.height + 2 * grow, b.theta, b.s)
    return (_shape_kernel.gauge_any_inside(*B, _shape_kernel.boundary_points(*A, 64))
            or _shape_kernel.gauge_any_inside(*A, _shape_kernel.boundary_points(*B, 64)))


def _cycle_basis(adj: dict[int, list[int]]) -> list[list[int]]:
    """``networkx.cycle_basis`` of the graph with adjacency lists ``adj`` (nodes in insertion
    order, neighbours in the order the edges were added): the same algorithm line by line, so
    the same cycles in the same order (networkx's per-call overhead was most of the time spent
    on graphs of a few pieces)."""
    gnodes = dict.fromkeys(adj)
    cycles = []
    while gnodes:
        root = gnodes.popitem()[0]
        stack = [root]
        pred = {root: root}
        used = {root: set()}
        while stack:
            z = stack.pop()
            zused = used[z]
            for nbr in adj[z]:
                if nbr not in used:
                    pred[nbr] = z
                    stack.append(nbr)
                    used[nbr] = {z}
                elif nbr == z:
                    cycles.append([z])
                elif nbr not in zused:
                    pn = used[nbr]
                    cycle = [nbr, z]
                    p = pred[z]
                    while p not in pn:
                        cycle.append(p)
                        p = pred[p]
                    cycle.append(p)
                    cycles.append(cycle)
                    used[nbr].add(z)
        for node in pred:
            gnodes.pop(node, None)
    return cycles


def _break_cycles(q, vw, free, fits: list[Fit], cfg: PerceptionConfig, grow: float, init=None,
                  cache=None) -> list[Fit]:
    """Merge pieces until the pieces grown by ``grow`` (the robot radius) overlap as a tree:
    in the smallest cycle, a piece whose points the others contain is dropped, unless the best
    merge (below) swallows no free point and leaves less obstacle area; else every
    overlapping pair is refitted as one piece, and the one whose
    fit swallows the fewest free points deeper than ``free_tol``, then explains its points
    (the decomposition's criterion), then has the union one rectangle explains best, becomes
    one piece. Chosen by the rectangle alone, a wall merged with a corner piece of its
    neighbour at a junction came out thick over the free space beside it (``random17``
    noise-free: four walls 0.15-0.26 m thick fitted 0.33-0.38 m, IoU 0.628 -> 0.839). When
    that best merge swallows free space, a piece of the cycle refitted to the returns the
    others do not contain (:func:`_shrink`) is taken instead if it leaves the cycle. When it
    swallows free space or does not explain its returns, a piece of the cycle is dissolved into
    the others instead if they, refitted with its returns, keep the free space free and explain
    them no worse (:func:`_dissolve`; errors up to the merge's, at most ``_DISSOLVE_SLACK``
    times the criterion: at 1.35 times, a dissolve of the X of two crossing walls in
    ``random4`` gave a 0.39 x 1.0 m ellipse that blocked a region). A piece is dropped only
    into pieces that explain their own returns and hold fewer than 3 free cells deeper than
    ``free_cell`` (:func:`_explains`): a thick piece over free space is no cover (``random10`` noisy: two wall pieces dropped into a 0.92 x 0.41 m box holding
    27 free cells)."""
    fits = list(fits)
    fr = None if free is None or not len(free) else np.asarray(free, dtype=float)
    memo: dict[tuple[int, int], tuple] = {}  # overlaps of pairs of squircles (kept alive here)
    while len(fits) > 2:
        # the overlap graph (a few nodes: plain adjacency lists in networkx's neighbour order);
        # pairs of unchanged pieces are not tested again
        adj: dict[int, list[int]] = {k: [] for k in range(len(fits))}
        for a in range(len(fits)):
            for b in range(a + 1, len(fits)):
                sa, sb = fits[a].squircle, fits[b].squircle
                hit = memo.get((id(sa), id(sb)))
                if hit is None or hit[0] is not sa or hit[1] is not sb:
                    hit = memo[(id(sa), id(sb))] = (sa, sb, _overlap(sa, sb, grow))
                if hit[2]:
                    adj[a].append(b)
                    adj[b].append(a)
        cycles = _cycle_basis(adj)
        if not cycles:
            break
        cyc = min(cycles, key=len)
        # a piece whose points the others already cover is redundant: drop it
        # (``errs[a]``: the :func:`_outside` errors of piece ``a``'s points in every other piece, in
        # order, shape (others, points); :func:`_shrink` reads them too)
        drop = None
        errs: dict[int, np.ndarray] = {}
        # a piece that does not explain its own returns (or swallows free space) is no cover to
        # drop another piece into
        clean = np.array([not _DROP_CLEAN or _explains(g, fr, cfg) for g in fits])
        for a in sorted(cyc, key=lambda k: len(fits[k].indices)):
            errs[a] = np.array([_outside(fits[k].squircle, q[fits[a].indices]) for k in range(len(fits)) if k != a])
            covers = np.delete(clean, a)
            if covers.any() and float(errs[a][covers].min(axis=0).max()) <= cfg.inside_tol:
                drop = a
                break
        # else merge the overlapping pair whose fit keeps the free space free and explains its
        # points, then whose union one rectangle explains best, counting the free space its
        # rectangle would swallow (the faces of one wall, not two walls); a drop unless that
        # merge, swallowing no free space, leaves less obstacle area: a redundant piece is
        # also dropped when the piece covering it is the one fitted too thick (simple noisy:
        # the right face of a wall dropped inside its left face's 0.33 m deep piece)
        # (lazily: the pairs by their rectangle's cost, cheapest first; the first whose fit
        # swallows no free point and explains its returns is the least of all, the pairs after
        # it need no fit)
        pairs = []
        for a in cyc:
            for b in cyc:
                if a < b and b in adj[a]:
                    idx = np.concatenate((fits[a].indices, fits[b].indices))
                    pairs.append((_piece_cost(q[idx], fr, cfg.free_cell) / len(idx), a, b, idx))
        if _LAZY_PAIRS:
            pairs.sort(key=lambda t: t[0])  # stable: ties keep the order above
        best = None
        for cost, a, b, idx in pairs:
            f = _fit_piece(q, vw, fr, idx, cfg, init, cache)
            explains = _explains(f, fr, cfg, free=False)
            deep = _deep(f.squircle, fr, cfg)
            c = (deep, not explains, cost)
            if best is None or c < best[0]:
                best = (c, a, b, idx, f)
            if _LAZY_PAIRS and not deep and explains:
                break
        if best is not None and best[0][0] > 0 and drop is None:
            # every merge swallows free space: shrink a piece instead, refitted to its returns
            # that no other piece contains, when that ends its overlap with a neighbour in the
            # cycle without swallowing free space (random12 noisy: the pair merges of a zig-zag
            # chain's cycle swallowed 300-600 free cells each)
            shrunk = _shrink(q, vw, fr, fits, cyc, adj, errs, cfg, grow, init, cache)
            if shrunk is not None:
                a, f, rest = shrunk
                fits[a] = f
                for k, idx_k in rest:
                    _hand_over(fits, k, idx_k)
                continue
        if _DISSOLVE and best is not None and drop is None and (best[0][0] > 0 or best[0][1]):
            # no merge both keeps the free space free and explains its returns: dissolve a piece
            # of the cycle into the others instead, when they, refitted with its returns, do
            # (random22 noisy: a piece of a wall's face holding part of a bump's outline, merged
            # with the wall, made the wall 0.40 m thick where it is 0.23 m)
            merged = best[4]
            dissolved = _dissolve(q, vw, fr, fits, cyc, errs, cfg, init, cache,
                                  max(cfg.split_tol, min(merged.rms, _DISSOLVE_SLACK * cfg.split_tol)),
                                  max(3 * cfg.split_tol, min(merged.p95, 3 * _DISSOLVE_SLACK * cfg.split_tol)))
            if dissolved is not None:
                a, refits = dissolved
                for k, f in refits:
                    fits[k] = f
                del fits[a]
                continue
        if drop is not None:
            area = sum(g.squircle.area for g in fits)
            c, a, b, idx, f = best
            if c[0] > 0 or area - fits[a].squircle.area - fits[b].squircle.area + f.squircle.area >= \
                    area - fits[drop].squircle.area:
                keep_idx = fits[drop].indices
                del fits[drop]
                # its points stay explained: give them to the piece that contains them best
                _hand_over(fits, int(np.argmin([radial_error(g.squircle, q[keep_idx]).max() for g in fits])), keep_idx)
                continue
        _, a, b, idx, f = best
        fits[a] = Fit(f.squircle, f.rms, f.closed, idx, f.p95)
        del fits[b]
    return fits


_LAZY_PAIRS = True  # _break_cycles fits the pairs cheapest rectangle first, up to the best

_TIGHTEN = True
_TIGHTEN_AREA = 0.9
_TIGHTEN_PASSES = 3


def _tighten(q, vw, fr, fits: list[Fit], cfg: PerceptionConfig, grow: float, init, cache) -> list[Fit]:
    """Pieces refitted without the returns other pieces already contain (within
    ``inside_tol``): at a junction the piece of one arm need not cover the returns of the
    other. A piece is replaced by the fit of its own returns when that fit explains them, keeps
    the free space free, is smaller by ``1 - _TIGHTEN_AREA``, lies within the old piece (so that,
    inflated by any amount, it overlaps nothing the old one did not) and overlaps (grown by ``grow``)
    exactly the pieces the old one did (the pieces' tree is unchanged); the returns it gave up
    go to the piece that contains them best. Largest pieces first, in passes until no piece
    changes (at most ``_TIGHTEN_PASSES``: a piece tightened later can leave returns of an earlier
    one to it alone, `random13` noisy: a group's IoU 0.734 after one pass, 0.827 after two)."""
    fits = list(fits)
    for _ in range(_TIGHTEN_PASSES):
        fits, changed = _tighten_pass(q, vw, fr, fits, cfg, grow, init, cache)
        if not changed:
            break
    return fits


def _tighten_pass(q, vw, fr, fits: list[Fit], cfg: PerceptionConfig, grow: float, init, cache):
    """One pass of :func:`_tighten`: ``(fits, whether any piece changed)``."""
    changed = False
    for a in sorted(range(len(fits)), key=lambda k: -fits[k].squircle.area):
        g = fits[a]
        others = [k for k in range(len(fits)) if k != a]
        if not others:
            break
        err = np.array([_outside(fits[k].squircle, q[g.indices]) for k in others])
        covered = err.min(axis=0) <= cfg.inside_tol
        keep = g.indices[~covered]
        if not covered.any() or len(keep) < cfg.min_piece:
            continue
        f = _fit_piece(q, vw, fr, keep, cfg, init, cache)
        if not _clean(f, fr, cfg) or f.squircle.area > _TIGHTEN_AREA * g.squircle.area:
            continue
        if float(radial_error(g.squircle, f.squircle.boundary_points(64)).max()) > cfg.inside_tol:
            continue  # not within the old piece: it could overlap others once inflated
        if any(_overlap(f.squircle, fits[k].squircle, grow) != _overlap(g.squircle, fits[k].squircle, grow)
               for k in others):
            continue
        owner = np.array(others)[np.argmin(err[:, covered], axis=0)]
        fits[a] = Fit(f.squircle, f.rms, f.closed, keep, f.p95)
        changed = True
        for k in np.unique(owner):
            _hand_over(fits, int(k), g.indices[covered][owner == k])
    return fits, changed


_EXTEND = True
_EXTEND_AREA = 0.95  # the pair's union must shrink at least by this factor
_EXTEND_CELL = 0.01  # grid step (m) of the union area


def _long_axis(sq: Squircle) -> tuple[np.ndarray, float, float]:
    """Unit vector of ``sq``'s long axis, its half-length and half-thickness."""
    th = sq.theta if sq.width >= sq.height else sq.theta + math.pi / 2
    return np.array([math.cos(th), math.sin(th)]), max(sq.width, sq.height) / 2, min(sq.width, sq.height) / 2


def _union_area(sqs: list[Squircle], h: float = _EXTEND_CELL) -> float:
    """Area of the union of ``sqs``, counted on a grid of step ``h`` over their bounding box."""
    b = np.concatenate([s.boundary_points(64) for s in sqs])
    lo, hi = b.min(axis=0), b.max(axis=0)
    xs, ys = np.meshgrid(np.arange(lo[0], hi[0], h) + h / 2, np.arange(lo[1], hi[1], h) + h / 2)
    g = np.stack((xs.ravel(), ys.ravel()), axis=1)
    inside = np.zeros(len(g), bool)
    for s in sqs:
        inside |= radial_error(s, g) < 0
    return float(np.count_nonzero(inside)) * h * h


def _extend(q, vw, fr, fits: list[Fit], cfg: PerceptionConfig, grow: float, init, cache) -> list[Fit]:
    """Walls continued through a piece: a piece ``P`` that does not explain its returns (the
    criterion of :func:`_explains`, by its recorded errors) gives the returns it holds in the
    band of an elongated piece ``A`` it overlaps (within ``A``'s half-thickness plus
    ``split_tol`` of its long axis, beyond its end on ``P``'s side) to ``A``: a wall whose end
    pokes through another wall (``random0`` noise-free: the 5 cm stub of a 0.18 m wall beyond a
    0.19 m wall, whose returns made the crossed wall's piece 0.29 m thick, RMS 0.020 m). Both
    are refitted; the new pair is taken when both explain their returns, keep every free cell
    out (none deeper than ``free_tol``), overlap (grown by ``grow``) each other and exactly the
    pieces the old ones did (the pieces' tree is unchanged), and cover at least ``1 -
    _EXTEND_AREA`` less area together (:func:`_union_area`: ``A`` extended through ``P`` adds
    mostly area ``P`` covers). ``A`` must be at least 1.5 times as long as thick. With
    ``_EXTEND_BACK`` the band also ends at ``A``'s farthest return, and a move that leaves
    ``P`` clean but not ``A`` gets a second step: ``P`` takes back ``A``'s returns in ``P``'s
    own band beyond ``P``'s returns (:func:`_band_beyond`), then those it contains within
    ``inside_tol``; that pair is taken when both are clean, the tree is unchanged and the union
    is no larger (``random12`` noise-free: a bar poking through a wall whose end is flush with
    the bar's face, IoU 0.774 -> 0.870). With ``_EXTEND_CORE`` a hand-over that leaves a piece
    unclean is tried once more by :func:`_core_split` (``P``'s wall fitted without a wide band of
    ``A``'s axis; walls crossing obliquely), under the same tree and area conditions. With
    ``_EXTEND_HELD`` a ``P`` whose solve explained its returns is judged again by the distances
    of the returns it holds (containment grows a piece round returns its solve did not explain:
    ``random42`` noise-free, a wall's piece 0.27 m thick round the end of a wall poking out of it
    at 45 degrees, solve RMS 0.85 ``split_tol``, held returns 2.1 times the criterion), and a
    second step that finds no band to take back falls through to :func:`_core_split`. With
    ``_EXTEND_GIVE`` a hand-over that leaves ``A`` clean but not ``P`` also gives ``A`` the
    returns of ``P`` it contains (within ``inside_tol``) when ``P`` refitted without them is
    clean: noisy returns of ``A``'s faces just outside the band at an oblique crossing
    (``random63`` noisy: walls in an X at 48 degrees, three such returns made the other wall's
    piece 0.50 m thick for a 0.26 m wall)."""
    fits = list(fits)
    n = len(fits)
    for p in range(n):
        by_dist = None  # (P explains the returns it holds now, by their distances)
        for a in range(n):
            P, A = fits[p], fits[a]
            if a == p:
                continue
            if _explains(P, fr, cfg, free=False):
                if not _EXTEND_HELD:
                    continue
                if by_dist is None:
                    by_dist = _worst_piece(q, [P], cfg) <= 1.0
                if by_dist:
                    continue
            sa, sp = A.squircle, P.squircle
            e, half_len, half_thick = _long_axis(sa)
            if half_len < 1.5 * half_thick or not _overlap(sa, sp, 0.0):
                continue
            c = np.asarray(sa.center)
            d = q[P.indices] - c
            u, v = d @ e, d @ np.array([-e[1], e[0]])
            side = 1.0 if float((np.asarray(sp.center) - c) @ e) >= 0 else -1.0
            end = half_len - cfg.split_tol
            if _EXTEND_BACK:
                end = min(end, float(((q[A.indices] - c) @ e * side).max()))  # or beyond its returns
            band = (np.abs(v) <= half_thick + cfg.split_tol) & (side * u > end)
            n_band = int(np.count_nonzero(band))
            if n_band < 3 or len(P.indices) - n_band < cfg.min_piece:
                continue
            fa = _fit_piece(q, vw, fr, np.concatenate((A.indices, P.indices[band])), cfg, init, cache)
            fp = _fit_piece(q, vw, fr, P.indices[~band], cfg, init, cache)
            area = _EXTEND_AREA
            if _EXTEND_BACK and _clean(fp, fr, cfg) and not _clean(fa, fr, cfg):
                # the donor is clean now, the receiver not: a bar whose piece held the corner of
                # the wall it runs into, and whose own end pokes out of that wall's far face
                # (random12): the clean bar takes back its end, then the returns it contains
                back = _band_beyond(q, fp, fa)
                if back is None:
                    if not _EXTEND_HELD:
                        continue
                else:
                    fp = _fit_piece(q, vw, fr, np.concatenate((fp.indices, fa.indices[back])), cfg, init, cache)
                    rest = fa.indices[~back]
                    rest = rest[_outside(fp.squircle, q[rest]) > cfg.inside_tol]
                    if len(rest) < cfg.min_piece:
                        continue
                    fa = _fit_piece(q, vw, fr, rest, cfg, init, cache)
                    area = 1.0  # both explain their returns now, where the donor did not: no larger
            elif _EXTEND_GIVE and _clean(fa, fr, cfg) and not _clean(fp, fr, cfg):
                # the receiver is clean, the donor not: stray returns of the receiver's wall
                # outside the band (noisy faces at an oblique crossing) go to it too
                given = _give_to(q, vw, fr, fa, fp, cfg, init, cache)
                if given is not None and _clean(given[1], fr, cfg):
                    fa, fp = given
            if not (_clean(fa, fr, cfg) and _clean(fp, fr, cfg)):
                if not _EXTEND_CORE:
                    continue
                core = _core_split(q, vw, fr, A, P, u, v, side, end, half_thick, cfg, init, cache)
                if core is None:
                    continue
                fa, fp = core
                area = _EXTEND_AREA
            if not _overlap(fa.squircle, fp.squircle, grow) or any(
                    _overlap(f.squircle, fits[k].squircle, grow) != _overlap(g.squircle, fits[k].squircle, grow)
                    for k in range(n) if k not in (a, p) for f, g in ((fa, A), (fp, P))):
                continue
            if _union_area([fa.squircle, fp.squircle]) > area * _union_area([sa, sp]):
                continue
            if _EXTEND_BACK:
                # every return stays with a piece (the returns fp contains that fa gave up)
                held = np.union1d(fa.indices, fp.indices)
                lost = np.setdiff1d(np.union1d(A.indices, P.indices), held)
                if len(lost):
                    fp = Fit(fp.squircle, fp.rms, fp.closed, np.concatenate((fp.indices, lost)), fp.p95)
            fits[a], fits[p] = fa, fp
            break
    return fits


_EXTEND_BACK = True  # _extend's second step: the clean donor takes back its end
_EXTEND_GIVE = True  # _extend's band hand-over: a clean receiver also takes the donor's returns it contains
_EXTEND_HELD = True  # _extend also for a piece whose solve explained its returns but whose held returns miss the criterion
_EXTEND_CORE = True  # _extend's alternative: the crossed wall fitted without a wide band, the returns outside it handed over


def _give_contained(q, vw, fr, fits: list[Fit], cfg: PerceptionConfig, grow: float, init, cache) -> list[Fit]:
    """Returns a clean neighbour already explains, handed over to it: a piece ``P`` whose
    returns miss the criterion by their distances (:func:`_worst_piece`) gives every return it
    holds that lies inside, or within ``inside_tol`` outside, a piece ``A`` it overlaps and
    that meets the criterion, and is refitted on the rest. ``A`` keeps its squircle (the
    returns given lie on or in it). Taken when the refitted ``P`` explains its returns and
    keeps every free cell out (:func:`_clean_distances`), ``A`` still meets the criterion with
    the returns given, the refitted ``P`` overlaps (grown by ``grow``) exactly the pieces the
    old one did (the pieces' tree is unchanged) and the pair's union is no larger
    (:func:`_union_area`). Repeated while a piece is taken (a piece made clean may take
    returns in turn). In a chain of walls meeting obliquely, a wall's piece held the end of
    the next wall, which the next wall's piece fitted exactly (``random47`` noise-free: the
    end walls' pieces 0.36 and 0.23 m thick for 0.28 and 0.18 m walls; refitted without those
    returns 0.284 and 0.185 m)."""
    fits = list(fits)
    n = len(fits)
    worst = [_worst_piece(q, [f], cfg) for f in fits]
    changed = True
    while changed:
        changed = False
        for p in sorted(range(n), key=lambda k: -worst[k]):
            if worst[p] <= 1.0:
                break
            for a in range(n):
                P, A = fits[p], fits[a]
                if a == p or worst[a] > 1.0 or not _overlap(A.squircle, P.squircle, 0.0):
                    continue
                given = _give_to(q, vw, fr, A, P, cfg, init, cache)
                if given is None:
                    continue
                b, g = given
                if not _clean_distances(g, q, fr, cfg):
                    continue
                w_b = _worst_piece(q, [b], cfg)
                if w_b > 1.0:
                    continue
                if any(_overlap(g.squircle, fits[k].squircle, grow) != _overlap(P.squircle, fits[k].squircle, grow)
                       for k in range(n) if k != p):
                    continue
                if _union_area([A.squircle, g.squircle]) > _union_area([A.squircle, P.squircle]):
                    continue
                fits[p], fits[a] = g, b
                worst[p], worst[a] = _worst_piece(q, [g], cfg), w_b
                changed = True
                break
    return fits


_GIVE = True  # _give_contained after _extend


def _give_to(q, vw, fr, receiver: Fit, donor: Fit, cfg: PerceptionConfig, init, cache) -> tuple[Fit, Fit] | None:
    """The returns of ``donor`` that ``receiver`` contains (inside, or within ``inside_tol``
    outside) handed over to it: ``(receiver holding them too, its squircle and records kept;
    donor refitted on the rest)``, or None when there are none or fewer than ``min_piece``
    would be left (for :func:`_extend` and :func:`_give_contained`, which judge the result)."""
    give = _outside(receiver.squircle, q[donor.indices]) <= cfg.inside_tol
    n_give = int(np.count_nonzero(give))
    if not n_give or len(donor.indices) - n_give < cfg.min_piece:
        return None
    rest = _fit_piece(q, vw, fr, donor.indices[~give], cfg, init, cache)
    taken = Fit(receiver.squircle, receiver.rms, receiver.closed,
                np.concatenate((receiver.indices, donor.indices[give])), receiver.p95)
    return taken, rest


def _clean_distances(f: Fit, q: np.ndarray, fr, cfg: PerceptionConfig) -> bool:
    """:func:`_clean` with the criterion on the distances of ``f``'s returns to its squircle
    (:func:`_worst_piece`), not its solve's radial errors."""
    return _worst_piece(q, [f], cfg) <= 1.0 and not _deep(f.squircle, fr, cfg)


def _core_split(q, vw, fr, A: Fit, P: Fit, u, v, side: float, end: float, half_thick: float,
                cfg: PerceptionConfig, init, cache):
    """For :func:`_extend`, when handing ``A``'s band over did not leave both pieces clean: a
    wall ``P`` crossed obliquely by the elongated ``A``, whose end pokes out of ``P``'s far
    face. The band of ``A``'s axis at ``A``'s half-thickness plus ``split_tol`` holds, across
    an oblique crossing, returns of ``P``'s faces too, and misses part of the poking end
    (``random35`` noisy: walls crossing at 59 degrees, the crossed wall's piece 0.31 m thick
    for a 0.19 m wall). So ``P``'s wall is fitted without a wide band (``A``'s half-thickness
    plus ``3 split_tol``, from ``3 split_tol`` before ``A``'s end; ``u``, ``v``: ``P``'s
    returns along and across ``A``'s axis), the band's returns it does not contain (within
    ``inside_tol``) go to ``A`` and the rest back to ``P``. Both pieces are judged by their
    distances (:func:`_clean_distances`: the radial errors of a long noisy bar exceed them
    several times near its ends). Returns the refitted ``(A, P)`` or None."""
    wide = (np.abs(v) <= half_thick + 3 * cfg.split_tol) & (side * u > end - 3 * cfg.split_tol)
    if len(P.indices) - int(np.count_nonzero(wide)) < cfg.min_piece:
        return None
    g = _fit_piece(q, vw, fr, P.indices[~wide], cfg, init, cache)
    if not _clean_distances(g, q, fr, cfg):
        return None
    out = _outside(g.squircle, q[P.indices[wide]]) > cfg.inside_tol
    if np.count_nonzero(out) < 3:
        return None
    fa = _fit_piece(q, vw, fr, np.concatenate((A.indices, P.indices[wide][out])), cfg, init, cache)
    fp = _fit_piece(q, vw, fr, np.concatenate((P.indices[~wide], P.indices[wide][~out])), cfg, init, cache)
    if not (_clean_distances(fa, q, fr, cfg) and _clean_distances(fp, q, fr, cfg)):
        return None
    return fa, fp


def _clean(f: Fit, fr, cfg: PerceptionConfig, scale: float = 1.0) -> bool:
    """``f`` explains its returns (the criterion scaled by ``scale``, by its recorded errors)
    and holds no free cell deeper than ``free_tol``."""
    return _explains(f, fr, cfg, free=False, scale=scale) and not _deep(f.squircle, fr, cfg)


def _band_beyond(q: np.ndarray, b: Fit, g: Fit) -> np.ndarray | None:
    """Mask of the returns of ``g`` in the band of the elongated piece ``b`` (within its
    half-thickness of its long axis) beyond ``b``'s own returns on ``g``'s side; None when
    ``b`` is not elongated (1.5 times as long as thick) or fewer than 3 returns qualify."""
    e, half_len, half_thick = _long_axis(b.squircle)
    if half_len < 1.5 * half_thick:
        return None
    c = np.asarray(b.squircle.center)
    side = 1.0 if float((np.asarray(g.squircle.center) - c) @ e) >= 0 else -1.0
    reach = float(((q[b.indices] - c) @ e * side).max())
    d = q[g.indices] - c
    m = (np.abs(d @ np.array([-e[1], e[0]])) <= half_thick) & (d @ e * side > reach)
    return m if np.count_nonzero(m) >= 3 else None


def _deep(sq: Squircle, fr, cfg: PerceptionConfig, depth: float | None = None) -> int:
    """The free cells of ``fr`` (None or empty: none) deeper than ``depth`` (default
    ``free_tol``) inside ``sq``."""
    if fr is None or not len(fr):
        return 0
    return int(np.count_nonzero(radial_error(sq, fr) < -(cfg.free_tol if depth is None else depth)))


def _hand_over(fits: list[Fit], k: int, idx: np.ndarray) -> None:
    """Give the returns ``idx`` (which piece ``k`` contains) to piece ``k`` of ``fits``, in place."""
    g = fits[k]
    fits[k] = Fit(g.squircle, g.rms, g.closed, np.concatenate((g.indices, idx)), g.p95)


def _shrink(q, vw, fr, fits: list[Fit], cyc, adj, errs, cfg: PerceptionConfig, grow: float, init, cache):
    """For :func:`_break_cycles`: the piece of the cycle ``cyc`` refitted to its returns that no
    other piece contains (within ``inside_tol``) whose fit overlaps fewer of its neighbours in
    the cycle, keeps every free cell out (none deeper than ``free_tol``) and explains its returns;
    the smallest such piece by area. ``errs[a]`` holds the :func:`_outside` errors of piece ``a``'s
    points in every other piece (in order; shape (others, points)). Returns
    ``(a, fit, [(k, indices)])`` - the returns it gave up go to the piece ``k`` that contains
    them best - or None."""
    best = None
    for a in cyc:
        idx = fits[a].indices
        others = [k for k in range(len(fits)) if k != a]
        err = errs[a]
        covered = err.min(axis=0) <= cfg.inside_tol
        keep = idx[~covered]
        if len(keep) < cfg.min_piece or len(keep) == len(idx):
            continue
        f = _fit_piece(q, vw, fr, keep, cfg, init, cache)
        if not _clean(f, fr, cfg):
            continue
        nb = [b for b in cyc if b != a and b in adj[a]]
        if all(_overlap(f.squircle, fits[b].squircle, grow) for b in nb):
            continue
        if best is None or f.squircle.area < best[0]:
            owner = np.array(others)[np.argmin(err[:, covered], axis=0)]
            rest = [(int(k), idx[covered][owner == k]) for k in np.unique(owner)]
            best = (f.squircle.area, a, Fit(f.squircle, f.rms, f.closed, keep, f.p95), rest)
    return None if best is None else best[1:]


_DISSOLVE = True
_DROP_CLEAN = True
_DISSOLVE_SLACK = 1.1  # a dissolve's refits: errors up to the best merge's, at most this times the criterion


def _dissolve(q, vw, fr, fits: list[Fit], cyc, errs, cfg: PerceptionConfig, init, cache, rms_max: float,
              p95_max: float):
    """For :func:`_break_cycles`: a piece of the cycle ``cyc`` whose returns, each given to the
    other piece nearest to it (smallest absolute radial error), leave every receiving piece,
    refitted with them, within ``rms_max`` RMS and ``p95_max`` 95th percentile radial error (the
    decomposition's criterion, or the best merge's errors where they are larger: no worse than
    that merge) and keeping every free cell out (none deeper than ``free_tol``); of those, the
    one leaving the least total area. ``errs[a]`` holds the radial errors of piece ``a``'s
    points in every other piece (in order; shape (others, points)). Returns
    ``(a, [(k, refit of piece k)])`` (indices into ``fits`` before ``a`` is removed) or None."""
    best = None
    for a in cyc:
        others = [k for k in range(len(fits)) if k != a]
        owner = np.array(others)[np.argmin(np.abs(errs[a]), axis=0)]
        refits, area = [], 0.0
        for k in np.unique(owner):
            k = int(k)
            idx = np.concatenate((fits[k].indices, fits[a].indices[owner == k]))
            f = _fit_piece(q, vw, fr, idx, cfg, init, cache)
            if f.rms > rms_max or f.p95 > p95_max:
                break
            if _deep(f.squircle, fr, cfg):
                break
            refits.append((k, Fit(f.squircle, f.rms, f.closed, idx, f.p95)))
            area += f.squircle.area - fits[k].squircle.area
        else:
            area -= fits[a].squircle.area
            if best is None or area < best[0]:
                best = (area, a, refits)
    return None if best is None else best[1:]


def _split_memo(q: np.ndarray, run: np.ndarray, cfg: PerceptionConfig, fr, cache, used: set, force: bool, compute):
    """``compute()`` (the cuts of ``run``: index arrays into ``q``), memoised in ``cache`` by the
    run's cells in order, ``force`` and the number of free points in its bounding box (the cuts
    depend on them): the runs of a large cluster away from its new cells are cut the same way
    at every refit."""
    if cache is None:
        return compute()
    sub = q[run]
    n_free = 0
    if fr is not None and len(fr):
        lo, hi = sub.min(axis=0) - cfg.free_cell, sub.max(axis=0) + cfg.free_cell
        n_free = int(np.count_nonzero(_shape_kernel.box_mask(fr, lo, hi)))  # ((fr >= lo) & (fr <= hi)).all(axis=1)
    # the cells in the run's order (cached cuts are positions within the run)
    key = ("cuts", force, n_free, len(run), hash(np.floor(sub / cfg.voxel).astype(np.int64).tobytes()))
    used.add(key)
    hit = cache.get(key)
    if hit is not None:
        return [run[j] for j in hit]
    parts = compute()
    pos = np.empty(int(run.max()) + 1, dtype=np.int64)
    pos[run] = np.arange(len(run))
    cache[key] = [pos[p] for p in parts]
    return parts


def _runs(q: np.ndarray, cfg: PerceptionConfig, fr, depth: int, cache=None, used=None) -> list[np.ndarray]:
    """Split a cluster at its corners: connected components, then runs of one direction (mod
    90 deg), runs that still bend cut where they bend, then the runs one rectangle explains
    together (faces of one wall) merged again."""
    parts = []
    for comp in _components(q, cfg.link):
        if len(comp) < 2 * cfg.min_piece:
            parts.append(comp)
            continue
        segs, psi, straight = _segments(q[comp], cfg)
        for seg in segs:
            run = comp[seg]
            if _explained_run(q[run], cfg):
                parts.append(run)  # straight (faces of one wall) or curved (an ellipse)
            else:  # a bend the directions did not separate: cut it where it bends
                parts.extend(_split_memo(q, run, cfg, fr, cache, used, False, lambda run=run, seg=seg: _bend_cuts(
                    q, run, psi[seg], straight[seg], cfg, fr, depth)))
    parts = _merge_runs(q, parts, cfg, fr)
    return parts


def _explained_run(points: np.ndarray, cfg: PerceptionConfig) -> bool:
    """One rectangle (faces of one wall) or one ellipse (a curved obstacle) explains a run."""
    return rect_error(points) <= cfg.split_tol or _ellipse_error(points) <= cfg.split_tol


def _bend_cuts(q: np.ndarray, run: np.ndarray, psi: np.ndarray, straight: np.ndarray, cfg: PerceptionConfig, fr,
               depth: int) -> list[np.ndarray]:
    """Cuts of a run that bends: first by the modes of its directions (:func:`_mode_split`,
    ``psi`` and ``straight`` of its points), then each sub-run that still bends where it bends
    (:func:`_split`), in connected components (:func:`_connected`)."""
    subs = _mode_split(q[run], psi, straight, cfg) if _MODES else None
    if subs is None:
        subs = [np.arange(len(run))]
    parts = []
    for sub in subs:
        idx = run[sub]
        if len(subs) > 1 and _explained_run(q[idx], cfg):
            parts.append(idx)
        else:
            parts.extend(_split(q, idx, cfg.split_tol, cfg.min_piece, depth, free=fr, margin=cfg.free_cell))
    return _connected(q, parts, cfg)


def _cell_key(points: np.ndarray, cfg: PerceptionConfig) -> tuple:
    """Key of a point set by the ``voxel`` cells of its points (stable while averaged returns
    move within their cells)."""
    # the set of cells as sorted unique linear codes (``np.unique(..., axis=0)`` of the rows,
    # 10x slower, gave the same key equality: the code is one-to-one for cell indices below
    # 2^31 in magnitude)
    return len(points), hash(np.unique(_cell_codes(points, cfg)).tobytes())


def _reusable(f: Fit, q: np.ndarray, free, cfg: PerceptionConfig) -> bool:
    """``f`` (a previous fit of the same cells) still holds: every point within ``inside_tol``
    of its inside, no free point deeper than ``free_tol`` inside it."""
    if float(_outside(f.squircle, q).max()) > cfg.inside_tol:
        return False
    return free is None or not len(free) or float(radial_error(f.squircle, free).min()) >= -cfg.free_tol


def _kept(init, q: np.ndarray, vw, free, cfg: PerceptionConfig, errs) -> Fit | None:
    """The previous estimate (of ``init``) that the data does not contradict and that explains
    the points as well as when it was fitted: no point more than ``refit_tol`` outside it and no
    free point deeper than ``free_tol`` inside it (the map's own refit triggers), RMS radial
    error within ``split_tol`` and 95th percentile within ``3 split_tol`` (the decomposition's
    criterion), and RMS at most ``1.1`` times (plus 1 mm) the RMS of its own points when it was
    fitted (``errs``: id -> (squircle, rms), kept in the cluster's cache; an estimate that was
    trimmed or grown since has no record). It is kept as it is (the same squircle object: no
    least squares, and the map sees no change, so no inflation and no forest check for it);
    None when no previous estimate qualifies."""
    if not init or not errs or len(q) < 3:
        return None
    m = q.mean(axis=0)
    for sq in init:
        rec = errs.get(id(sq))
        if rec is None or rec[0] is not sq or math.dist(sq.center, m) > sq.bounding_radius:
            continue
        e = radial_error(sq, q)
        if float(e.max()) > cfg.refit_tol:
            continue
        rms = float(np.sqrt(np.mean(e * e)))
        if rms > min(cfg.split_tol, 1.1 * rec[1] + 1e-3):
            continue
        p95 = _p95(np.abs(e))
        if p95 > 3 * cfg.split_tol:
            continue
        if free is not None and len(free) and float(radial_error(sq, free).min()) < -cfg.free_tol:
            continue
        closed = bool(_faces_seen(_params(sq), q, vw).all())
        return Fit(sq, rms, closed, np.arange(len(q)), p95)
    return None


def _record(cache, sq: Squircle, q: np.ndarray) -> None:
    """Remember the RMS radial error of the points ``q`` a new estimate ``sq`` was fitted to
    (for :func:`_kept`)."""
    if cache is not None:
        e = radial_error(sq, q)
        cache.setdefault("err", {})[id(sq)] = (sq, float(np.sqrt(np.mean(e * e))))


def _fit_piece(q, vw, free, idx, cfg: PerceptionConfig, init=None, cache=None) -> Fit:
    """:func:`fit_squircle` of the points ``idx`` of a cluster, with the free points near them
    (warm-started from ``init``). With ``cache`` (a dict kept by the caller between refits of
    one cluster) a piece of the same cells as before whose previous fit still holds
    (:func:`_reusable`) keeps it (same squircle object, no least squares)."""
    fr = None
    if free is not None and len(free):
        lo, hi = q[idx].min(axis=0) - 0.3, q[idx].max(axis=0) + 0.3
        fr = free[_shape_kernel.box_mask(free, lo, hi)]  # ((free >= lo) & (free <= hi)).all(axis=1), compiled
    key = None
    if cache is not None:
        key = _cell_key(q[idx], cfg)
        touched = cache.get("touched")
        if touched is not None:
            touched.add(key)
        prev = cache.get(key)
        if prev is not None and _reusable(prev, q[idx], fr, cfg):
            return Fit(prev.squircle, prev.rms, prev.closed, idx, prev.p95)
    f = _kept(init, q[idx], None if vw is None else vw[idx], fr, cfg, None if cache is None else cache.get("err"))
    if f is None:
        f = fit_squircle(q[idx], views=None if vw is None else vw[idx], free=fr, config=cfg, init=init)
        _record(cache, f.squircle, q[idx])
    f = Fit(f.squircle, f.rms, f.closed, idx, f.p95)
    if key is not None:
        cache[key] = f
    return f


def fit_cluster(points, *, views=None, free=None, config: PerceptionConfig | None = None,
                max_pieces: int = 16, split: bool = True, grow: float = 0.0, init=None,
                cache: dict | None = None) -> list[Fit]:
    """Fit a cluster with one squircle, or decompose it into overlapping pieces (section 4.2.1).

    Parameters are those of :func:`fit_squircle`; ``max_pieces`` bounds the decomposition
    (depth ``log2(max_pieces)``), ``split=False`` forces a single squircle. With ``grow > 0``
    (the robot radius) pieces are merged until, grown by ``grow``, they overlap as a tree
    (no cycle), which the forest of stars needs. ``init`` (the cluster's previous estimates)
    warm-starts every least-squares fit (:func:`fit_squircle`). ``cache`` (a dict the caller
    keeps per cluster, empty at first) lets pieces whose cells did not change, and whose fit still
    holds their points and the free space, keep their previous fit; it also remembers whether
    the whole cluster was explained by one squircle, so that a cluster that was decomposed
    (RMS of the single squircle above ``2 split_tol``) and has grown by less than half since is
    decomposed again without first fitting it whole.

    **Local refit.** A cluster last decomposed into pieces (recorded in ``cache``) is refitted
    piece by piece when its returns allow (:func:`_local_refit`: the new returns go to the
    nearest piece, only the pieces they or the free space changed are refitted, taken when
    those meet ``_LOCAL_TOL`` times the criterion and the pieces' tree is unchanged), until
    it has ``_LOCAL_GROWTH`` times the returns of its last full decomposition.

    **Cold second opinion.** Warm starts keep each piece in the basin of its previous estimate,
    and a decomposition shaped by an early, partial view can survive the data that would undo
    it (``random27``: the arm of a V fitted short from one side, 0.74 m of its 0.99 m, kept by
    its warm start at RMS 0.0065 m where a cold fit gives 0.0012 m; the end of that arm poking
    out below the other arm then went to the other arm's piece, 0.40 m thick for a 0.26 m wall,
    RMS 0.028 m). When a piece of the warm decomposition misses the criterion of
    :func:`_explains` by more than ``_COLD_WORST`` times (RMS / ``split_tol`` or 95th
    percentile / ``3 split_tol``, as its fit recorded them), the cluster is also decomposed
    cold (no ``init``, an empty ``cache``); the cold pieces replace the warm ones (and their
    memo the cluster's) when every cold piece explains all the returns it holds, they hold no
    more free cells and they cover no more area. (Taking a cold decomposition whose worst
    piece was merely better than the warm one's, not within the criterion, lowered
    ``random12`` noisy from 0.832 to 0.674 IoU; trying cold at any miss, ``_COLD_WORST = 1``,
    tried 8 futile cold decompositions in one executive mission.) With ``_COLD_DEEP`` a piece
    that misses the criterion at all calls for the cold try too when a piece holds a free cell
    deeper than ``free_tol``, and the cold pieces are also taken when they hold fewer free
    cells, their worst piece is better and they cover no more area (``random24`` noisy: a warm
    ellipse 0.42 m wide over a 0.19 m wall and a stub, RMS 1.5 ``split_tol``, 12 free cells
    inside; cold, 1 free cell and 0.58 instead of 0.74 m^2). A cluster is tried cold again
    only after its returns have grown by ``_COLD_GROWTH`` times since its last cold try, or,
    with ``_COLD_WORSE``, when its warm pieces hold more free cells deeper than ``free_tol``
    than the pieces that try returned (``random85`` noise-free: a good cold decomposition at
    193 returns, then, refitted warm together with a cluster that joined it, a wall's piece
    holding returns of the other wall, 4 free cells inside, RMS 1.9 ``split_tol``, at 230
    returns, short of the 1.2 times: IoU 0.730), or, with ``_COLD_AGAIN`` (off by default), at
    any new return while a warm piece is more than ``_COLD_AGAIN`` times over the criterion.
    With ``_COLD_HALF`` (off by default) the cold pieces are also taken when their worst piece
    is below that share of the warm one's, with no more free cells and no more area
    (``random42`` noise-free with 2.5 and 0.5: a warm ellipse over the middle wall of a chain,
    2.75 times over the criterion, kept for the drive's last 9 returns; the cold try at its
    last return, worst 2.14 against 4.73 and 0.57 against 0.69 m^2, is taken: IoU 0.737 ->
    0.896; but the repeated cold tries lift ``random50``'s executive tick p95 from 13 to 24 ms).

    Returns
    -------
    list of Fit
        One fit when its RMS radial error is within ``split_tol`` (or ``split`` is False),
        else one per piece; ``Fit.indices`` say which points each piece explains.
    """
    cfg = config or PerceptionConfig.from_lidar()
    q = _check(points, "points")
    vw = _check_views(views, q)
    init = None if init is None else list(init)
    cache = {} if cache is None else cache
    fits = _fit_cluster(q, vw, free, cfg, max_pieces, split, grow, init, cache)
    if not (_COLD_CHECK and split and len(fits) > 1):
        return fits
    fr = None if free is None else _check(free, "free")
    worst = _worst_recorded(fits, cfg)
    if not (worst > _COLD_WORST or (_COLD_DEEP and worst > 1.0 and any(_deep(f.squircle, fr, cfg) for f in fits))):
        return fits
    tried = cache.get("cold")
    deep = sum(_deep(f.squircle, fr, cfg) for f in fits)  # (of the pieces returned, recorded below)
    if (tried is not None and len(q) < _COLD_GROWTH * tried[0] and not (_COLD_WORSE and deep > tried[1])
            and not (_COLD_AGAIN and worst > _COLD_AGAIN and len(q) > tried[0])):
        return fits
    fresh: dict = {}
    cold = _fit_cluster(q, vw, free, cfg, max_pieces, split, grow, None, fresh)
    w_cold = _worst_piece(q, cold, cfg)
    d_cold = sum(_deep(f.squircle, fr, cfg, cfg.free_cell) for f in cold)
    d_warm = sum(_deep(f.squircle, fr, cfg, cfg.free_cell) for f in fits)
    w_warm = _worst_piece(q, fits, cfg) if w_cold > 1.0 else math.inf  # (only needed then)
    if ((w_cold <= 1.0 or (_COLD_DEEP and d_cold < d_warm and w_cold < w_warm)
         or (_COLD_HALF and w_cold < _COLD_HALF * w_warm))
            and d_cold <= d_warm and sum(f.squircle.area for f in cold) <= sum(f.squircle.area for f in fits)):
        cache.clear()
        cache.update(fresh)
        fits = cold
        deep = sum(_deep(f.squircle, fr, cfg) for f in cold)
    # (returns at this try, free cells deeper than ``free_tol`` in what it returns)
    cache["cold"] = (len(q), deep)
    return fits


_COLD_CHECK = True
_COLD_WORST = 2.0  # a warm piece this many times over the criterion calls for a cold try
_COLD_GROWTH = 1.2
_COLD_DEEP = True  # ... or a piece that misses the criterion at all when a piece holds a free cell deeper than free_tol
_COLD_WORSE = True  # tried again before that growth when the warm pieces hold more deep free cells than the last try left
# measured, not the default (docs/perception.md, "Cold second opinion"): random42 noise-free
# 0.737 -> 0.896 with 2.5 and 0.5, but the repeated cold tries lift random50's executive tick
# p95 from 13 to 24 ms
_COLD_AGAIN = 0.0  # ... or, at any new return, while a warm piece is this many times over the criterion (0: off)
_COLD_HALF = 0.0  # a cold try is also taken when its worst piece is below this share of the warm one's (0: off)


def _worst_recorded(fits: list[Fit], cfg: PerceptionConfig) -> float:
    """The worst piece against :func:`_explains`' criterion, by the errors its fit recorded
    (``Fit.rms`` / ``split_tol``, ``Fit.p95`` / ``3 split_tol``; NaN: infinite)."""
    worst = 0.0
    for f in fits:
        w = max(f.rms / cfg.split_tol, f.p95 / (3 * cfg.split_tol))
        worst = max(worst, w if w == w else math.inf)
    return worst


def _worst_piece(q: np.ndarray, fits: list[Fit], cfg: PerceptionConfig) -> float:
    """The worst piece of a decomposition against :func:`_explains`' criterion: the largest of
    RMS / ``split_tol`` and 95th percentile / ``3 split_tol`` of each piece's distances to all
    the returns it holds (:func:`_distances`; a piece's ``Fit.rms`` is that of its least-squares
    solution, before returns were handed over to it)."""
    worst = 0.0
    for f in fits:
        rms, p95 = _distances(f.squircle, _subsample(q[f.indices], _MAX_POINTS))
        worst = max(worst, rms / cfg.split_tol, p95 / (3 * cfg.split_tol))
    return worst


def _fit_cluster(q: np.ndarray, vw, free, cfg: PerceptionConfig, max_pieces: int, split: bool, grow: float,
                 init, cache: dict) -> list[Fit]:
    """:func:`fit_cluster` without the cold second opinion (checked arguments); with
    ``_LOCAL`` the pieces returned are recorded for the next call's local refit."""
    fits = _decompose(q, vw, free, cfg, max_pieces, split, grow, init, cache)
    if _LOCAL:
        if len(fits) > 1:
            codes = _cell_codes(q, cfg)
            cache["last"] = [(f.squircle, np.sort(codes[f.indices]), f.rms, f.p95, f.closed) for f in fits]
        else:
            cache.pop("last", None)
    return fits


_LOCAL = True
_LOCAL_TOL = 0.5  # a piece refitted locally must meet this share of the decomposition's criterion
_LOCAL_GROWTH = 1.25  # ... and only until the cluster has this many times the returns of its last full decomposition
_LOCAL_MEMO = 48  # a local refit trims the cluster's memo to its pieces beyond this many entries


def _cell_codes(points: np.ndarray, cfg: PerceptionConfig) -> np.ndarray:
    """The ``voxel`` cell of each point as one integer (the codes of :func:`_cell_key`)."""
    cells = np.floor(points / cfg.voxel).astype(np.int64)
    return (cells[:, 0] << 32) + cells[:, 1]


def _local_refit(q, vw, fr, cfg: PerceptionConfig, grow: float, init, cache: dict) -> list[Fit] | None:
    """The last decomposition of the cluster (``cache["last"]``: its pieces and their cells)
    carried forward without decomposing again: each return in a new cell goes to the piece
    nearest to it (smallest absolute radial error); a piece that gained returns, holds a free
    cell deeper than ``free_tol`` or has a return more than ``inside_tol`` outside it is
    refitted (warm-started from ``init``), the others are kept as they are. Taken when at
    least one piece was refitted, every refitted piece meets ``_LOCAL_TOL`` times the
    criterion of :func:`_explains` and keeps every free cell out, and the pieces, grown by
    ``grow``, overlap exactly as before (the pieces' tree is unchanged); else None (decompose
    again). Only when ``init`` is exactly the last decomposition's pieces (the map neither
    trimmed, grew nor dropped one since) and the cluster has fewer than ``_LOCAL_GROWTH``
    times the returns of its last full decomposition."""
    last = cache.get("last")
    if not last or init is None or len(init) != len(last) or len(q) >= _LOCAL_GROWTH * cache.get("full", 0):
        return None
    ids = {id(sq) for sq in init}
    if any(id(rec[0]) not in ids for rec in last):
        return None
    codes = _cell_codes(q, cfg)
    member = np.full(len(q), -1)
    for k, rec in enumerate(last):
        member[np.isin(codes, rec[1], assume_unique=True)] = k
    new = np.nonzero(member < 0)[0]
    if len(new):
        err = np.abs(np.array([radial_error(rec[0], q[new]) for rec in last]))
        member[new] = np.argmin(err, axis=0)
    gained = np.zeros(len(last), bool)
    gained[member[new]] = True
    fits, redone = [], []
    for k, (sq, cells, rms, p95, closed) in enumerate(last):
        idx = np.nonzero(member == k)[0]
        if len(idx) < len(cells):
            return None  # returns were dropped: decompose again
        if not gained[k] and float(_outside(sq, q[idx]).max()) <= cfg.inside_tol and not _deep(sq, fr, cfg):
            fits.append(Fit(sq, rms, closed, idx, p95))
            continue
        f = _fit_piece(q, vw, fr, idx, cfg, init, cache)
        if not _clean(f, fr, cfg, scale=_LOCAL_TOL):
            return None
        fits.append(f)
        redone.append(k)
    if not redone:
        return None
    for a in redone:
        for b in range(len(fits)):
            if b != a and _overlap(fits[a].squircle, fits[b].squircle, grow) != _overlap(last[a][0], last[b][0], grow):
                return None
    entries = [k for k in cache if isinstance(k, tuple)]
    if len(entries) > _LOCAL_MEMO:
        keep = {_cell_key(q[f.indices], cfg) for f in fits}
        for k in entries:
            if k not in keep:
                del cache[k]
    return fits


def _decompose(q: np.ndarray, vw, free, cfg: PerceptionConfig, max_pieces: int, split: bool, grow: float,
               init, cache: dict) -> list[Fit]:
    """:func:`_fit_cluster` before recording the pieces; a full decomposition records its
    returns in ``cache["full"]`` (the local refit's growth gate)."""
    one_memo = cache.get("one")
    one = None
    if split and one_memo is not None and one_memo[1] > 2 * cfg.split_tol and len(q) < 1.5 * one_memo[0]:
        pass  # decomposed before and not yet grown much: decompose again (``one`` only if needed)
    else:
        one = _fit_one(q, vw, free, cfg, init, cache, split)
        if one is not None:
            return _kept_records(cache, [one])
    depth = max(int(math.log2(max(max_pieces, 1))), 0)
    fr = None if free is None else _check(free, "free")
    if _LOCAL and split and grow > 0:
        refit = _local_refit(q, vw, fr, cfg, grow, init, cache)
        if refit is not None:
            return _kept_records(cache, refit)
    used: set = set()
    if _KEEP_TOUCHED:
        cache["touched"] = set()  # the cells of every piece fitted in this decomposition
    parts = _runs(q, cfg, fr, depth, cache, used)
    fits = []
    for idx in parts:
        f = _fit_piece(q, vw, fr, idx, cfg, init, cache)
        if (len(idx) >= 2 * cfg.min_piece and not _explains(f, fr, cfg, free=False)
                and len(fits) + len(parts) < max_pieces):
            # not one squircle yet (walls meeting at right angles): recursive cuts
            sub = _split_memo(q, idx, cfg, fr, cache, used, True, lambda idx=idx: _merge_parts(q, _connected(q, _split(
                q, idx, cfg.split_tol, cfg.min_piece, depth, force=True, free=fr, margin=cfg.free_cell), cfg), cfg, fr))
            if len(sub) > 1:
                fits.extend(_fit_piece(q, vw, fr, j, cfg, init, cache) for j in sub)
                continue
        fits.append(f)
    # pieces that kept the same previous estimate are one piece (its points together)
    uniq: dict[int, Fit] = {}
    for f in fits:
        g = uniq.get(id(f.squircle))
        uniq[id(f.squircle)] = f if g is None else Fit(g.squircle, g.rms, g.closed,
                                                       np.concatenate((g.indices, f.indices)), g.p95)
    fits = list(uniq.values())
    if len(fits) <= 1:
        cache.pop("touched", None)
        if one is None:
            one = _fit_one(q, vw, free, cfg, init, cache, False)
        return _kept_records(cache, [one])
    if grow > 0:
        fits = _break_cycles(q, vw, free, fits, cfg, grow, init, cache)
    loose = [_cell_key(q[f.indices], cfg) for f in fits]
    if _TIGHTEN:
        fits = _tighten(q, vw, fr, fits, cfg, grow, init, cache)
    if _EXTEND and len(fits) > 1:
        fits = _extend(q, vw, fr, fits, cfg, grow, init, cache)
    if _GIVE and len(fits) > 1:
        fits = _give_contained(q, vw, fr, fits, cfg, grow, init, cache)
    # keep only the pieces of this decomposition (bounded memory): those returned and, with
    # ``_KEEP_TOUCHED``, every piece fitted on the way (the parts before cycles were broken,
    # the pairs tried as merges)
    keep = {_cell_key(q[f.indices], cfg) for f in fits} | set(loose) | cache.pop("touched", set())
    for k in [k for k in cache if k not in ("one", "err", "cold", "last") and k not in keep and k not in used]:
        del cache[k]
    if _LOCAL:
        cache["full"] = len(q)  # returns at the last full decomposition
    return _kept_records(cache, fits)


_KEEP_TOUCHED = True


def _kept_records(cache: dict, fits: list[Fit]) -> list[Fit]:
    """Keep only the error records (:func:`_record`) of the estimates returned (bounded memory)."""
    errs = cache.get("err")
    if errs:
        cache["err"] = {id(f.squircle): errs[id(f.squircle)] for f in fits if id(f.squircle) in errs}
    return fits


def _fit_one(q, vw, free, cfg: PerceptionConfig, init, cache: dict, split: bool) -> Fit | None:
    """The single-squircle fit of a whole cluster (warm-started only from a single previous
    estimate, not from a piece), recorded in ``cache["one"]``; returned when it explains the
    cluster (or ``split`` is False), else None."""
    single = init if init and len(init) == 1 else None
    fr = None if free is None else _check(free, "free")
    one = _kept(single, q, vw, fr, cfg, cache.get("err"))
    if one is None:
        one = fit_squircle(q, views=vw, free=free, config=cfg, init=single)
        _record(cache, one.squircle, q)
    cache["one"] = (len(q), one.rms, one)
    if not split or len(q) < 2 * cfg.min_piece:
        return one
    test = one
    if _FINAL_CHECK:
        # the errors of the estimate returned, not only of the least-squares solution before
        # completion and containment: scaled to hold every return, an ellipse over a rectangle
        # and its rounded neighbour passed at 0.027 m where its returns lie 0.045 m (RMS) from
        # it (random28 noisy, IoU 0.684). With ``_ONE_DISTANCE`` those distances alone: the
        # solve's radial errors exceed them several times near a long face's ends (random76
        # noisy: a 1.19 x 0.16 m bar 1.3 cm RMS from its squircle, radial RMS 0.038 m, was
        # decomposed into two pieces, IoU 0.637; one squircle, 0.86)
        rms, p95 = _distances(one.squircle, _subsample(q, _MAX_POINTS))
        if not _ONE_DISTANCE:
            rms, p95 = max(rms, one.rms), max(p95, one.p95)
        test = Fit(one.squircle, rms, one.closed, one.indices, p95)
    return one if _explains(test, fr, cfg) else None


_FINAL_CHECK = True
_ONE_DISTANCE = True  # a whole cluster's single squircle is judged by its distances alone (not also its solve's radial errors)


def _explains(f: Fit, fr, cfg: PerceptionConfig, free: bool = True, scale: float = 1.0) -> bool:
    """One squircle explains its returns: RMS radial error within ``scale split_tol``, 95th
    percentile within ``3 scale split_tol`` (a NaN error explains nothing) and (with ``free``)
    fewer than 3 free cells of ``fr`` deeper than ``free_cell`` inside it."""
    if not (f.rms <= scale * cfg.split_tol and f.p95 <= 3 * scale * cfg.split_tol):
        return False
    return not free or _deep(f.squircle, fr, cfg, cfg.free_cell) < 3


def inflate(sq: Squircle, r: float, samples: int = 96) -> Squircle:
    """A squircle containing ``sq`` grown by ``r >= 0`` (same centre, rotation and ``s``).

    Extents grow by ``2 k r`` with ``k = 1.03^n``, ``n`` the smallest of ``0 .. 79`` for which
    ``samples`` boundary points of the candidate are at least ``r`` from ``sq`` (distances to
    ``4 samples`` boundary points of ``sq``, minus half their spacing, a lower bound of the true
    distance). Candidates are nested (larger ``k``, larger squircle): ``n = 0 .. 4`` are tried in
    order (the estimates of the drives need ``n = 1..3``), larger ``n`` are found by bisection.
    A fast variant of :meth:`navigation.Squircle.grow`
    for per-scan use.
    """
    r = float(r)
    if not math.isfinite(r) or r < 0:
        raise ValueError(f"inflate radius must be finite and >= 0, got {r}")
    if r == 0:
        return sq
    # boundary samples and distances in compiled kernels (:mod:`perception._shape_kernel`, the
    # same arithmetic as ``Squircle.boundary_points`` and the k-d tree's nearest distances:
    # bit-identical); a candidate becomes a Squircle only when it is returned
    ref = _shape_kernel.boundary_points(sq.center, sq.width, sq.height, sq.theta, sq.s, 4 * samples)
    half = _shape_kernel.spacing(ref) / 2

    def ext(n: int) -> float:
        return 2 * 1.03 ** n * r + 2e-9

    def cand(n: int) -> Squircle:
        e = ext(n)
        return Squircle(sq.center, sq.width + e, sq.height + e, sq.theta, sq.s)

    def clear(n: int) -> bool:
        e = ext(n)
        pts = _shape_kernel.boundary_points(sq.center, sq.width + e, sq.height + e, sq.theta, sq.s, samples)
        return _shape_kernel.clear_of(ref, pts, half, r)

    # the steps of the estimates are small (n = 1..3 on the drives): the first few are tried in
    # order (the linear search, 1-4 tests instead of 8 for the bisection from 0..79), then bisection
    for n in range(_INFLATE_LINEAR):
        if clear(n):
            return cand(n)
    lo, hi = _INFLATE_LINEAR - 1, 79  # clear(cand(hi)) is assumed (k = 1.03^79 ~ 10: far enough)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if clear(mid):
            hi = mid
        else:
            lo = mid
    return cand(hi)
