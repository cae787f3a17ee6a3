"""Squircles: obstacle functions with exact derivatives, ray lengths, distances, inflation.

Implements the squircle model of paper 001 eq. (4) (paper 004 eq. 3) in the parametrisation of
``shared/FORMATS.md``, and the ray lengths of paper 001 eq. (15) (from the centre: closed form of
paper 004 eq. 5; from any interior point: exact root of the boundary equation, which replaces
the piecewise approximation of eq. (16) so that purged leaves land exactly on their parent).

Symbols
-------
====================  ==========================================================
``c``                 centre ``(2,)``
``A``                 half-extents ``diag(width/2, height/2)``
``R(theta)``          rotation by ``theta`` (counter-clockwise)
``s``                 curvature parameter, ``0 <= s < 1`` (0 ellipse, -> 1 rectangle)
``x, y``              normalised coordinates ``A^-1 R(-theta) (q - c)``
``beta(q)``           ``(x^2 + y^2 + sqrt(x^4 + y^4 + (2 - 4 s^2) x^2 y^2)) / 2 - 1``
``rho_sc(u)``         unit-squircle ray length ``sqrt(2 / (1 + sqrt(1 - 4 s^2 u_x^2 u_y^2)))``
====================  ==========================================================

``beta < 0`` inside, ``= 0`` on the boundary (the quartic ``x^2 + y^2 - s^2 x^2 y^2 = 1``),
``> 0`` outside. ``beta + 1`` is the square of the squircle's gauge (a norm), hence convex: along
a ray from an interior point ``beta`` crosses zero exactly once, which the ray-length solver uses.

Every point function accepts ``(2,)`` or ``(N, 2)`` and returns the same kind.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from dataclasses import field as dc_field

import numpy as np
from scipy.special import ellipe, ellipk

from . import _geom_kernel
from ._arrays import as_points, restore, to_float, to_floats
from ._jet import Jet
from .errors import WorldError

__all__ = ["Squircle", "ExactDistance", "pack", "beta_rows", "point_at_rows", "beta_jet", "ray_length_center_jet", "ray_length_jet", "ray_length_packed"]

#: Smallest width or height of a squircle (m): a nanometre; below it the construction's
#: ratios of extents underflow (a world file's 1e-300 m wide obstacle divided by zero).
MIN_SIZE = 1e-9

#: Largest coordinate, extent or radius a world file may give (m): a thousand kilometres. Finite
#: values far beyond it (1e300) overflow the construction's squares to infinities.
MAX_LENGTH = 1e6

# Columns of a packed squircle array (see :func:`pack`).
CX, CY, COS, SIN, HW, HH, S = range(7)


@dataclass(frozen=True, slots=True)
class Squircle:
    """A squircle ``{q : beta(q) <= 0}`` (FORMATS.md).

    Parameters
    ----------
    center : (2,) sequence of float
    width, height : float
        Full extents (at least :data:`MIN_SIZE`, a nanometre).
    theta : float
        Rotation in radians, counter-clockwise.
    s : float
        Curvature in ``[0, 1)``: 0 is the ellipse, values near 1 the rounded rectangle.

    Examples
    --------
    >>> sq = Squircle((0.0, 0.0), 2.0, 1.0, 0.0, 0.99)
    >>> float(sq.beta([1.0, 0.0]))
    0.0
    >>> float(sq.ray_length_from_center([0.0, 1.0]))
    0.5
    """

    center: tuple[float, float]
    width: float
    height: float
    theta: float = 0.0
    s: float = 0.99
    _hash: int = dc_field(init=False, repr=False, compare=False, default=0)

    def __hash__(self) -> int:
        # cached: squircles key the forest memo and the geometry caches (many lookups per build)
        return self._hash

    def __post_init__(self):
        c = tuple(float(v) for v in to_floats(self.center).reshape(-1))
        if len(c) != 2:
            raise WorldError(f"squircle center must have 2 coordinates, got {len(c)}", "center")
        object.__setattr__(self, "center", c)
        for name in ("width", "height", "theta", "s"):
            v = getattr(self, name)
            try:
                v = to_float(v)
            except (TypeError, ValueError):
                raise WorldError(f"squircle {name} must be a number, got {v!r}", name) from None
            object.__setattr__(self, name, v)
        for name, v in (("center", c[0]), ("center", c[1]), ("width", self.width), ("height", self.height),
                        ("theta", self.theta), ("s", self.s)):
            if not math.isfinite(v):
                raise WorldError(f"squircle {name} must be finite, got {v!r}", name)
        if not (self.width >= MIN_SIZE and self.height >= MIN_SIZE):
            raise WorldError(f"squircle width and height must be at least {MIN_SIZE:g} m, got "
                             f"{self.width} x {self.height}", "width" if not self.width >= MIN_SIZE else "height")
        if not 0.0 <= self.s < 1.0:
            raise WorldError(f"squircle s must be in [0, 1), got {self.s}", "s")
        object.__setattr__(self, "_hash", hash((self.center, self.width, self.height, self.theta, self.s)))

    # ------------------------------------------------------------------ constructors / IO
    @classmethod
    def from_dict(cls, d, field: str = "squircle") -> "Squircle":
        """Build from the FORMATS.md JSON object; errors name ``field`` (e.g. ``obstacles[3]``)."""
        if not isinstance(d, dict):
            raise WorldError(f"{field}: expected an object with center/width/height, got {type(d).__name__}", field)
        unknown = set(d) - {"center", "width", "height", "theta", "s"}
        if unknown:
            raise WorldError(f"{field}: unknown squircle field(s) {sorted(unknown)}", f"{field}.{sorted(unknown)[0]}")
        for key in ("center", "width", "height"):
            if key not in d:
                raise WorldError(f"{field}: missing field '{key}'", f"{field}.{key}")
        center = d["center"]
        if (not isinstance(center, (list, tuple)) or len(center) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in center)):
            raise WorldError(f"{field}.center: expected [x, y] numbers, got {center!r}", f"{field}.center")
        for key in ("width", "height", "theta", "s"):
            if key in d and (not isinstance(d[key], (int, float)) or isinstance(d[key], bool)):
                raise WorldError(f"{field}.{key}: expected a number, got {d[key]!r}", f"{field}.{key}")
        try:
            sq = cls(tuple(center), d["width"], d["height"], d.get("theta", 0.0), d.get("s", 0.99))
        except WorldError as err:
            raise WorldError(f"{field}.{err.field}: {err}", f"{field}.{err.field}") from None
        for key, v in (("center", max(map(abs, sq.center))), ("width", sq.width), ("height", sq.height)):
            if not v <= MAX_LENGTH:
                raise WorldError(f"{field}.{key}: must be at most {MAX_LENGTH:g} m in magnitude, got {d[key]!r}",
                                 f"{field}.{key}")
        return sq

    def to_dict(self) -> dict:
        return {"center": list(self.center), "width": self.width, "height": self.height,
                "theta": self.theta, "s": self.s}

    # ------------------------------------------------------------------ derived constants
    @property
    def c(self) -> np.ndarray:
        return np.array(self.center)

    @property
    def half_extents(self) -> np.ndarray:
        return np.array([self.width / 2.0, self.height / 2.0])

    @property
    def bounding_radius(self) -> float:
        """Radius of a disc around the centre that contains the squircle (half diagonal)."""
        return 0.5 * math.hypot(self.width, self.height)

    @property
    def inscribed_radius(self) -> float:
        """Shortest ray from the centre to the boundary, ``min(width, height) / 2``."""
        return 0.5 * min(self.width, self.height)

    @property
    def area(self) -> float:
        """Enclosed area: ``(width / 2) (height / 2) A(s)``, ``A(s)`` the unit squircle's area
        (an integral over the boundary angle, memoised per ``s``)."""
        return _area(self)

    def packed(self) -> np.ndarray:
        """Parameters as one row ``[cx, cy, cos, sin, width/2, height/2, s]`` (see :func:`pack`)."""
        return pack([self])[0]

    # ------------------------------------------------------------------ obstacle function
    def beta(self, q) -> np.ndarray:
        """Obstacle function (eq. 4): ``< 0`` inside, ``0`` on the boundary, ``> 0`` outside."""
        pts, single = as_points(q)
        return restore(beta_rows(_packed_row(self), pts[:, 0], pts[:, 1]), single)

    def gradient(self, q) -> np.ndarray:
        """Exact gradient of :meth:`beta`, shape ``(2,)`` or ``(N, 2)`` (0 at the centre)."""
        pts, single = as_points(q)
        # compiled: beta_jet(self.packed(), *Jet.variables(pts, 1)).gradient(), the same bits
        p = _packed_row(self)
        return restore(_geom_kernel.beta_gradient(p, 4.0 * p[..., S] ** 2, pts), single)

    def hessian(self, q) -> np.ndarray:
        """Exact Hessian of :meth:`beta`, shape ``(2, 2)`` or ``(N, 2, 2)``.

        ``beta`` is only C^1 at the centre (for ``s > 0``); there the Hessian of the
        isotropic part ``(x^2 + y^2)`` doubled is returned.
        """
        pts, single = as_points(q)
        x, y = Jet.variables(pts, 2)
        return restore(beta_jet(self.packed(), x, y).hessian(), single)

    def contains(self, q, margin: float = 0.0) -> np.ndarray:
        """True where ``q`` lies in the closed squircle grown by ``margin`` metres.

        ``margin`` may be negative (a point deeper than ``-margin`` inside). Uses the exact
        Euclidean :meth:`distance`.
        """
        return self.distance(q) <= margin

    # ------------------------------------------------------------------ rays
    def ray_length_from_center(self, directions) -> np.ndarray:
        """Distance from the centre to the boundary along unit ``directions`` (paper 004 eq. 5)."""
        d, single = as_points(directions, "directions")
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        ux, uy = Jet.constant(d[:, 0], 0), Jet.constant(d[:, 1], 0)
        return restore(ray_length_center_jet(self.packed(), ux, uy).v.copy(), single)

    def ray_length(self, origin, directions) -> np.ndarray:
        """Exact distance from an interior ``origin`` to the boundary along unit ``directions``.

        Implements the ray length of eq. (15) for an off-centre origin exactly (root of the
        boundary quartic along the ray) instead of the piecewise approximation of eq. (16).

        Raises
        ------
        ValueError
            If ``origin`` is not strictly inside the squircle.
        """
        o = np.asarray(origin, dtype=float).reshape(2)
        if not self.beta(o) < 0:
            raise ValueError(f"ray origin {o.tolist()} is not strictly inside the squircle")
        d, single = as_points(directions, "directions")
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        p = np.broadcast_to(self.packed(), (len(d), 7))
        return restore(ray_length_packed(p, np.broadcast_to(o, d.shape), d), single)

    # ------------------------------------------------------------------ boundary, distance
    def point_at(self, psi) -> np.ndarray:
        """Boundary point at normalised-frame angle ``psi`` (array), shape ``psi.shape + (2,)``."""
        psi = np.asarray(psi, dtype=float)
        ux, uy = np.cos(psi), np.sin(psi)
        m = ux * uy
        rho = np.sqrt(2.0 / (1.0 + np.sqrt(np.maximum(1.0 - 4.0 * self.s ** 2 * m * m, 0.0))))
        lx = rho * ux * (self.width / 2.0)
        ly = rho * uy * (self.height / 2.0)
        ct, st = math.cos(self.theta), math.sin(self.theta)
        return np.stack((self.center[0] + ct * lx - st * ly, self.center[1] + st * lx + ct * ly), axis=-1)

    def boundary_points(self, n: int = 256) -> np.ndarray:
        """``n`` boundary points, counter-clockwise, evenly spaced in arc length, shape ``(n, 2)``."""
        if n < 3:
            raise ValueError(f"boundary_points needs n >= 3, got {n}")
        # compiled (the numpy form below, operation for operation: the same bits):
        #   fine = linspace(0, 2 pi, 8 n + 1); arc = [0, cumsum(|diff(point_at(fine))|)]
        #   point_at(interp(linspace(0, arc[-1], n, endpoint=False), arc, fine))
        return _geom_kernel.boundary_points(_packed_row(self), self.s ** 2, int(n))

    def boundary_psi(self, n: int) -> np.ndarray:
        """Normalised-frame angles of :meth:`boundary_points` (for local refinement)."""
        fine = np.linspace(0.0, 2 * np.pi, 8 * n + 1)
        pts = self.point_at(fine)
        arc = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
        return np.interp(np.linspace(0.0, arc[-1], n, endpoint=False), arc, fine)

    def distance(self, q, samples: int = 256) -> np.ndarray:
        """Signed Euclidean distance to the boundary (negative inside), exact to ~1e-10 m.

        Computed by :class:`ExactDistance` (nearest of at least ``samples`` boundary samples at
        most 5 cm apart, every near-minimal local minimum refined over the boundary parameter by
        ten rounds of 16 samples); the samples of a squircle are computed once and cached.
        """
        pts, single = as_points(q)
        ed = _exact_distance(self, int(samples))
        return restore(ed.signed(pts, np.zeros(len(pts), dtype=np.intp)), single)

    # ------------------------------------------------------------------ inflation
    def grow(self, r: float, samples: int = 720) -> "Squircle":
        """A squircle that contains this one grown by ``r`` (``r > 0``, robot inflation) or is
        contained in it shrunk by ``-r`` (``r < 0``), with the same centre, rotation and ``s``.

        Extents change by ``2 k r``; ``k >= 1`` is increased until the inner shape's offset
        curve at distance ``|r|`` (``samples`` boundary points moved ``|r|`` along their outward
        normals) lies inside the outer shape: for convex shapes that is the containment of the
        Minkowski sum with the disc of radius ``|r|``, i.e. every point within ``|r|`` of the
        inner shape is in the outer one (``k`` is 1 for ellipses and for rectangles with
        rounded corners); a 1e-9 m safety margin is added.

        The result is memoised per ``(squircle, r, samples)`` (the map grows the same estimates
        again and again).

        Raises
        ------
        ValueError
            If shrinking would make the squircle empty.
        """
        r = float(r)
        if not math.isfinite(r):
            raise ValueError(f"grow radius must be finite, got {r}")
        if r == 0.0:
            return self
        return _grow(self, r, int(samples))

    def grow_snug(self, r: float, samples: int = 720) -> "Squircle":
        """A squircle that contains this one grown by ``r > 0`` and hugs that neighbourhood
        closer than :meth:`grow` where this one has sharp corners (``r <= 0``: :meth:`grow`).

        :meth:`grow` keeps ``s``; the ``r``-neighbourhood of a nearly rectangular squircle has
        corners rounded with radius ``r``, so its grown shape reaches up to ``(sqrt 2 - 1) r``
        beyond the neighbourhood at the corners (10 cm for ``r = 0.25`` and ``s = 0.99``) and a
        passage between a corner and another shape closes early. Here ``s' <= s`` is chosen as
        well: for each ``s'`` (a grid over ``log(1 - s')`` refined by golden-section search),
        the least ``k >= 1`` whose squircle (same centre and rotation, extents grown by
        ``2 k r``) contains the offset curve at distance ``r``, and of those the shape for which
        the larger of its largest reach beyond the neighbourhood (along the outward normals)
        and three times its sides' own outward move ``(k - 1) r`` is least (a passage between
        two flat sides pays the move twice; ``_SNUG_SIDE``); ``s' = s`` is a candidate, so the
        result never reaches further than the snug ``k`` at ``s``. Largest reach for
        ``s = 0.99``, 0.3 x 0.69 m: 4.1 -> 1.5 cm at ``r = 0.13`` (sides 0.5 cm out), 8.0 ->
        2.4 cm at ``r = 0.25`` (0.8 cm out). Containment is tested at the ``samples`` offset
        points (even in arc length, as :meth:`grow`) and at the offset points of 129 boundary
        points per quadrant even in the normal's angle (a sharp corner has little arc length but
        turns the normal by 90 degrees); between them the curve bulges by micrometres, so a
        1e-5 m margin is added on every side, and the result is checked again with :meth:`beta`
        at both sets (``k`` raised in 1e-6 relative steps until it holds). Compiled search (over
        ``log(1 - s')``): :func:`navigation._geom_kernel.snug_shape`; memoised per
        ``(squircle, r, samples)``.

        Raises
        ------
        ValueError
            ``r`` not finite, or shrinking would make the squircle empty.
        """
        r = float(r)
        if not math.isfinite(r):
            raise ValueError(f"grow radius must be finite, got {r}")
        if r <= 0.0:
            return self.grow(r, samples)
        return _grow_snug(self, r, int(samples))

    def offset_points(self, r: float, n: int = 256) -> np.ndarray:
        """``n`` boundary points moved ``r`` along their outward unit normals (the offset curve
        at distance ``r``; for ``r > 0`` exactly ``r`` from the squircle), shape ``(n, 2)``."""
        return _offset(self, self.boundary_points(n), r)

    def _grow_uncached(self, r: float, samples: int) -> "Squircle":
        if r < 0 and -2 * r >= min(self.width, self.height):
            raise ValueError(f"cannot shrink a {self.width} x {self.height} squircle by {-r}")
        k = 1.0
        # growing: the offset curve is this squircle's, the same for every candidate
        fixed = self.offset_points(r, samples) if r > 0 else None
        for _ in range(60):
            ext = 2.0 * k * r + math.copysign(2e-9, r)
            cand = Squircle(self.center, self.width + ext, self.height + ext, self.theta, self.s)
            if cand.width <= 0 or cand.height <= 0:
                raise ValueError(f"cannot shrink a {self.width} x {self.height} squircle by {-r}")
            if r > 0:
                ok = np.all(cand.beta(fixed) <= 0.0)
            else:
                ok = np.all(self.beta(cand.offset_points(-r, samples)) <= 0.0)
            if ok:
                return cand
            k *= 1.05
        raise ValueError(f"could not grow squircle by {r}")  # pragma: no cover


# ---------------------------------------------------------------------- packed, vectorised core
def pack(squircles) -> np.ndarray:
    """Stack squircles as rows ``[cx, cy, cos(theta), sin(theta), width/2, height/2, s]``."""
    out = np.empty((len(squircles), 7))
    for i, sq in enumerate(squircles):
        out[i] = (sq.center[0], sq.center[1], math.cos(sq.theta), math.sin(sq.theta),
                  sq.width / 2.0, sq.height / 2.0, sq.s)
    return out


def beta_rows(P: np.ndarray, x, y) -> np.ndarray:
    """``beta`` (eq. 4) of packed rows ``P (..., 7)`` at ``(x, y)`` (plain arrays, broadcasting)."""
    u, w = _normalised(P, x, y)
    u2, w2 = u * u, w * w
    root = np.sqrt(np.maximum(u2 * u2 + w2 * w2 + (2.0 - 4.0 * P[..., S] ** 2) * u2 * w2, 0.0))
    return 0.5 * (u2 + w2 + root) - 1.0


@functools.lru_cache(maxsize=8192)
def _packed_row(sq: Squircle) -> np.ndarray:
    """:meth:`Squircle.packed` (memoised, read-only)."""
    row = pack([sq])[0]
    row.flags.writeable = False
    return row


@functools.lru_cache(maxsize=8192)
def _grow(sq: Squircle, r: float, samples: int) -> Squircle:
    """Memoised :meth:`Squircle.grow`."""
    return sq._grow_uncached(r, samples)


_SNUG_SIDE = 3.0  # weight of the sides' own outward move against the largest reach
_SNUG_MARGIN = 1e-5  # m on every side: the offset curve between its samples (measured: < 4 um)


def _offset(sq: Squircle, b: np.ndarray, r: float) -> np.ndarray:
    """The boundary points ``b`` of ``sq`` moved ``r`` along their outward unit normals
    (compiled: ``b + r g / |g|`` with ``g = sq.gradient(b)``, beta_jet at order 1, the same bits)."""
    p = _packed_row(sq)
    return _geom_kernel.offset_points(p, 4.0 * p[..., S] ** 2, b, float(r))


@functools.lru_cache(maxsize=128)
def _snug_base(sq: Squircle, samples: int):
    """What :func:`_grow_snug` needs of ``sq`` for any radius: its ``samples`` arc-length-even
    boundary points (:meth:`Squircle.boundary_points`) and the compiled search's normal-angle
    samples (:func:`navigation._geom_kernel.normal_samples`, about 40 % of the compiled part).
    The roadmaps grow every new estimate by two radii (the main and the fallback buffer), so
    the second growth reuses them, soon after the first: 128 shapes are kept (about 16 kB
    each); the arrays are read-only."""
    b = sq.boundary_points(samples)
    normals = _geom_kernel.normal_samples(sq.width / 2.0, sq.height / 2.0, sq.s)
    for a in (b, *normals):
        a.flags.writeable = False
    return b, normals


@functools.lru_cache(maxsize=8192)
def _grow_snug(sq: Squircle, r: float, samples: int) -> Squircle:
    """Memoised :meth:`Squircle.grow_snug` (``r > 0``)."""
    b, normals = _snug_base(sq, samples)
    p = _offset(sq, b, r)  # sq.offset_points(r, samples), from the shared boundary points
    ct, st = math.cos(sq.theta), math.sin(sq.theta)
    rot = np.array([[ct, -st], [st, ct]])  # row vectors times rot: world -> own frame
    c = np.asarray(sq.center)
    s2, k, _, corner = _geom_kernel.snug_shape(sq.width / 2.0, sq.height / 2.0, sq.s, r, (p - c) @ rot,
                                               side=_SNUG_SIDE, normals=normals)
    if not math.isfinite(k):  # pragma: no cover - s' = s always has a finite k
        return sq.grow(r, samples)
    corners = np.concatenate([corner * f for f in ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))]) @ rot.T + c
    for _ in range(60):
        ext = 2.0 * (k * r + _SNUG_MARGIN)
        cand = Squircle(sq.center, sq.width + ext, sq.height + ext, sq.theta, float(s2))
        if np.all(cand.beta(p) <= 0.0) and np.all(cand.beta(corners) <= 0.0):
            return cand
        k *= 1.0 + 1e-6
    return sq.grow(r, samples)  # pragma: no cover


def _area(sq: Squircle) -> float:
    """Area of ``sq`` (see :attr:`Squircle.area`): ``(width / 2) (height / 2) A(s)``."""
    return 0.25 * sq.width * sq.height * _unit_area(sq.s)


@functools.lru_cache(maxsize=256)
def _unit_area(s: float) -> float:
    """Area of the squircle with half-extents 1 and parameter ``s``.

    In the parametrisation of :meth:`Squircle.point_at` the boundary is ``rho(psi) (cos psi,
    sin psi)`` with ``rho^2 = 2 / (1 + sqrt(1 - s^2 sin^2 2 psi))``, so the area is
    ``(1/2) int_0^{2 pi} rho^2 dpsi = 4 int_0^{pi/2} dphi / (1 + sqrt(1 - s^2 sin^2 phi))``
    (``phi = 2 psi``). With ``1 / (1 + g) = (1 - g) / (s^2 sin^2 phi)`` and an integration by
    parts against ``-cot phi`` this is ``(4 / s^2) (E(s) - (1 - s^2) K(s))``, ``K`` and ``E`` the
    complete elliptic integrals of modulus ``s`` (``scipy.special.ellipk`` / ``ellipe`` take
    the parameter ``m = s^2``): ``pi`` at ``s = 0``, the unit disc, tending to 4, the square, as
    ``s -> 1``. Below ``s = 0.2`` the difference cancels (relative error ~1e-16 / s^2), so there
    the power series is summed instead: ``1 / (1 + sqrt(1 - x)) = sum_n c_n x^(n-1)`` with
    ``c_n = C(2n, n) / ((2n - 1) 4^n)`` and ``int_0^{pi/2} sin^(2k) = (pi / 2) C(2k, k) / 4^k``
    give ``A = 2 pi sum_n c_n C(2n - 2, n - 1) 4^(1 - n) s^(2n - 2)`` (terms fall by ``s^2 <=
    0.04``: about 12 terms; within 1e-15 of a 4096-node trapezoidal rule, tested). Scaling by
    the half-extents gives any squircle's area.
    """
    m = s * s
    if s >= 0.2:
        return float(4.0 * (ellipe(m) - (1.0 - m) * ellipk(m)) / m)
    total, mp = 0.0, 1.0
    for coeff in _AREA_SERIES:
        term = coeff * mp
        total += term
        if term < 1e-18 * total:
            break
        mp *= m
    return 2.0 * math.pi * total


#: coefficients ``c_n C(2n - 2, n - 1) / 4^(n - 1)`` of :func:`_unit_area`'s series, n = 1 .. 40
_AREA_SERIES = tuple(math.comb(2 * n, n) / ((2 * n - 1) * 4.0 ** n) * math.comb(2 * n - 2, n - 1) / 4.0 ** (n - 1)
                     for n in range(1, 41))


def point_at_rows(P: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Boundary points ``(K, ..., 2)`` of rows ``P (K, 7)`` at normalised angles ``psi (K, ...)``
    (the parametrisation of :meth:`Squircle.point_at`)."""
    return np.stack(_point_xy_rows(P, psi), axis=-1)


def _point_xy_rows(P: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates ``x, y (K, ...)`` of :func:`point_at_rows`."""
    C = P.T.reshape((7, -1) + (1,) * (psi.ndim - 1))
    ux, uy = np.cos(psi), np.sin(psi)
    m = ux * uy
    s = C[S]
    rho = np.sqrt(2.0 / (1.0 + np.sqrt(np.maximum(1.0 - 4.0 * s * s * m * m, 0.0))))
    lx = rho * ux * C[HW]
    ly = rho * uy * C[HH]
    c, sn = C[COS], C[SIN]
    return C[CX] + c * lx - sn * ly, C[CY] + sn * lx + c * ly


def boundary_jet_rows(P: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boundary points of rows ``P (K, 7)`` at angles ``psi (K, ...)`` and their first and second
    derivatives with respect to ``psi`` (exact), each of shape ``psi.shape + (2,)``.

    Same parametrisation as :meth:`Squircle.point_at`: with ``m = cos psi sin psi``,
    ``g = sqrt(1 - 4 s^2 m^2)`` and ``rho = sqrt(2 / (1 + g))`` the point is
    ``c + R(theta) (hw rho cos psi, hh rho sin psi)``. ``g >= sqrt(1 - s^2) > 0`` for ``s < 1``.
    Compiled: :func:`navigation._geom_kernel.boundary_jet`.
    """
    psi = np.asarray(psi, dtype=float)
    rows = np.repeat(np.asarray(P, dtype=float).reshape(-1, 7), psi[0].size if psi.ndim > 1 else 1, axis=0)
    j = _geom_kernel.boundary_jet(rows, psi.reshape(-1))  # compiled, one row at a time
    return tuple(np.stack((j[2 * o], j[2 * o + 1]), axis=-1).reshape(psi.shape + (2,)) for o in range(3))


class ExactDistance:
    """Exact signed Euclidean distances to the boundaries of a fixed list of squircles.

    The one exact point-to-squircle distance of the project (:meth:`Squircle.distance` and the
    simulator use it), vectorised over (point, squircle) pairs with the boundary samples
    computed once. Samples are evenly spaced in arc length, at most ``spacing`` metres apart
    and at least ``min_samples`` per squircle. Every discrete local minimum of the sampled
    distance within half a spacing of the smallest one is a candidate (a point inside a
    squircle can have several nearly equal local minima); each candidate brackets a local
    minimum of the true distance between its two neighbouring samples, and ``stages`` rounds
    of ``m`` samples shrink every bracket ``m / 2`` times. The result is the smallest refined
    candidate, with an error below 1e-9 m (tested against a dense brute force). Negative
    inside (``beta < 0``).

    Parameters
    ----------
    squircles : sequence of Squircle
    spacing : float
        Largest arc length between boundary samples (metres).
    stages, m : int
        Refinement rounds and samples per round.
    split : int, optional
        Squircles ``[0, split)`` and ``[split, len)`` (e.g. obstacles and a large workspace)
        get separate sample counts.
    min_samples : int
        Fewest boundary samples per squircle.
    lazy : bool
        Fetch a squircle's samples (:func:`_sample_table`, memoised) only when a query first
        needs it instead of all at construction. The sample counts are the same (they depend on
        every squircle's perimeter), hence so is every result; a table that is mostly queried
        near a few of its squircles (:class:`navigation.clearance.ClearanceBound`) then samples
        only those.
    """

    def __init__(self, squircles, spacing: float = 0.005, stages: int = 4, m: int = 128, split: int | None = None,
                 min_samples: int = 256, lazy: bool = False):
        self.squircles = tuple(squircles)
        self.P = pack(self.squircles) if self.squircles else np.zeros((0, 7))
        self.stages = stages
        self.m = m
        # groups of squircles sharing one sample count: [0, split) and [split, len) (the workspace)
        split = len(self.squircles) if split is None else split
        self._groups = []
        self._sizes = []  # samples per squircle of each group
        self._have = None if not lazy else np.zeros(len(self.squircles), dtype=bool)  # lazy: fetched yet
        for lo, hi in ((0, split), (split, len(self.squircles))):
            if hi <= lo:
                continue
            perim = _max_perimeter(self.squircles[lo:hi])
            n = _sample_count(perim / spacing, min_samples)
            self._sizes.append(n)
            if lazy:
                self._groups.append((lo, hi, np.empty((hi - lo, n)), np.empty((hi - lo, n, 2)), np.empty(hi - lo)))
                continue
            tables = [_sample_table(sq, n) for sq in self.squircles[lo:hi]]
            psi = np.stack([t[0] for t in tables])
            pts = np.stack([t[1] for t in tables])
            self._groups.append((lo, hi, psi, pts, 0.5 * np.array([t[2] for t in tables])))

    def _fetch(self, j: np.ndarray) -> None:
        """Lazy tables: make sure the samples of the squircles ``j`` (indices) are in place."""
        if self._have is None:
            return
        missing = j[~self._have[j]]
        if not len(missing):
            return
        for i in np.unique(missing).tolist():
            for (lo, hi, psi_g, pts_g, half_g), n in zip(self._groups, self._sizes):
                if lo <= i < hi:
                    psi, pts, arc = _sample_table(self.squircles[i], n)
                    psi_g[i - lo], pts_g[i - lo], half_g[i - lo] = psi, pts, 0.5 * arc
            self._have[i] = True

    def boundary_samples(self, i: int) -> np.ndarray:
        """Boundary samples ``(n, 2)`` of squircle ``i``."""
        for lo, hi, _, pts_g, _ in self._groups:
            if lo <= i < hi:
                self._fetch(np.array([i]))
                return pts_g[i - lo]
        raise IndexError(f"no squircle {i} among {len(self.squircles)}")

    def sampled(self, q: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unsigned distances ``d`` of the points ``q (K, 2)`` to the nearest boundary samples of
        the squircles ``j (K,)``, and ``h``, half the largest arc between consecutive samples.

        The exact unsigned distance to the boundary lies in ``[d - h, d]``.
        """
        q = np.asarray(q, dtype=float).reshape(-1, 2)
        j = np.asarray(j, dtype=np.intp).reshape(-1)
        self._fetch(j)
        d = np.empty(len(q))
        h = np.empty(len(q))
        for lo, hi, _, pts_g, half_arc in self._groups:
            sel = np.nonzero((j >= lo) & (j < hi))[0]
            if sel.size:
                g = j[sel] - lo
                d[sel] = _geom_kernel.nearest_sample_distance(pts_g, g, q[sel])
                h[sel] = half_arc[g]
        return d, h

    def signed(self, q: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Signed distances of the points ``q (K, 2)`` to the squircles ``j (K,)`` (indices)."""
        q = np.asarray(q, dtype=float).reshape(-1, 2)
        j = np.asarray(j, dtype=np.intp).reshape(-1)
        if len(q) == 0:
            return np.empty(0)
        self._fetch(j)
        pair, los, his = [], [], []
        for lo, hi, psi_g, pts_g, half_gap in self._groups:
            sel = np.nonzero((j >= lo) & (j < hi))[0]
            if sel.size == 0:
                continue
            g = j[sel] - lo
            if hi - lo == 1:  # one squircle: broadcast its samples instead of gathering copies
                px, py = pts_g[:, :, 0], pts_g[:, :, 1]
            else:
                px, py = pts_g[g, :, 0], pts_g[g, :, 1]
            d2 = (px - q[sel, 0, None]) ** 2 + (py - q[sel, 1, None]) ** 2  # (k, n)
            r, k = _candidates(d2, half_gap[g])
            lo, hi = _brackets(psi_g[g[r]], k)
            pair.append(sel[r])
            los.append(lo)
            his.append(hi)
        pair = np.concatenate(pair)
        best = _refine_brackets(self.P[j[pair]], q[pair], np.concatenate(los), np.concatenate(his), self.stages,
                                self.m)
        return _signed(self.P[j], q, pair, best)


def _candidates(d2: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows and indices of the discrete local minima of the sampled squared distances
    ``d2 (K, n)`` (circular) within ``half (K,)`` (half the longest arc between samples) of
    each row's smallest distance: every local minimum of the true distance is bracketed by one."""
    local = (d2 <= np.roll(d2, 1, axis=1)) & (d2 <= np.roll(d2, -1, axis=1))
    local &= d2 <= (np.sqrt(d2.min(axis=1)) + half)[:, None] ** 2
    return np.nonzero(local)


def _brackets(psi: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The angles of the samples either side of sample ``k[c]`` of the rows ``psi (C, n)``
    (wrapping around by ``2 pi``): the bracket of candidate ``c``."""
    n, c = psi.shape[1], np.arange(len(k))
    lo = np.where(k > 0, psi[c, k - 1], psi[:, -1] - 2.0 * math.pi)
    hi = np.where(k < n - 1, psi[c, (k + 1) % n], psi[:, 0] + 2.0 * math.pi)
    return lo, hi


def _signed(P: np.ndarray, q: np.ndarray, pair: np.ndarray, best: np.ndarray) -> np.ndarray:
    """Signed distances of the points ``q (K, 2)`` to their squircles ``P (K, 7)`` from the
    refined squared distances ``best`` of candidates belonging to points ``pair``."""
    dist = np.full(len(q), np.inf)
    np.minimum.at(dist, pair, np.sqrt(best))
    return np.where(beta_rows(P, q[:, 0], q[:, 1]) < 0.0, -dist, dist)


def _refine_brackets(P: np.ndarray, q: np.ndarray, lo: np.ndarray, hi: np.ndarray, stages: int, m: int) -> np.ndarray:
    """Smallest squared distance from ``q (K, 2)`` to the boundary arcs ``psi in [lo, hi]`` of rows
    ``P (K, 7)``, each arc bracketing one local minimum: ``stages`` rounds of ``m + 1`` samples,
    each shrinking the bracket to two sample steps around the best sample. Compiled:
    :func:`navigation._geom_kernel.refine_brackets`, the same arithmetic."""
    return _geom_kernel.refine_brackets(P, q, lo, hi, stages, m)


def signed_distance_rows(P: np.ndarray, q: np.ndarray, n: int = 128, stages: int = 3, m: int = 16,
                         polish: int = 4) -> np.ndarray:
    """Signed distances (negative inside) of the points ``q (K, 2)`` to the squircles of the rows
    ``P (K, 7)``, one squircle per point, without precomputed tables.

    The method of :class:`ExactDistance` on ``n`` boundary samples at evenly spaced angles,
    computed on the fly: the arc between samples ``k`` and ``k + 1`` is at most its chord over
    ``cos(alpha)``, ``alpha`` the angle between the neighbouring chords (which bounds the
    turning of a convex curve over the arc), so every discrete local minimum within half the
    longest arc of the smallest sampled distance is a candidate; each is narrowed by ``stages``
    rounds of nested sampling (``m + 1`` angles, the bracket shrinks ``m / 2``-fold per round)
    and then polished by up to ``polish`` Newton steps on the stationarity of the squared
    distance in the boundary angle (exact first and second derivatives of the boundary); a
    Newton step that leaves the bracket, or meets a spot where the squared distance is not
    convex, ends the polish. Only boundary points are measured, so every step can only lower
    the result towards the true distance. Arcs turning by more than 84 degrees make every
    discrete local minimum a candidate. The error is below 1e-9 m (tested against a dense brute
    force; in practice ~1e-15). Compiled: :func:`navigation._geom_kernel.signed_distance_rows`,
    point by point.
    """
    return _geom_kernel.signed_distance_rows(P, q, n, stages, m, polish)


@functools.lru_cache(maxsize=4096)
def _exact_distance(sq: Squircle, min_samples: int) -> ExactDistance:
    """The (immutable) distance table of one squircle, built once."""
    return ExactDistance([sq], spacing=0.05, stages=10, m=16, min_samples=min_samples)


def clear_geometry_cache() -> None:
    """Forget the memoised per-squircle tables (distance samples, areas)."""
    _exact_distance.cache_clear()
    _unit_area.cache_clear()
    _grow.cache_clear()
    _grow_snug.cache_clear()
    _snug_base.cache_clear()
    _sample_table.cache_clear()
    _perimeter.cache_clear()
    _packed_row.cache_clear()


def _sample_count(needed: float, min_samples: int) -> int:
    """Samples per squircle of a group: at least ``needed`` and ``min_samples``, rounded up to
    ``min_samples`` times a power of 1.25 (at most 8192). The rounding keeps the count, hence
    every memoised per-squircle table, unchanged while the group's longest boundary grows by
    less than 25 % (a growing wall estimate would otherwise re-sample every table of the group
    at each map change); it costs at most 25 % more samples."""
    n = float(min_samples)
    while n < needed and n < 8192:
        n *= 1.25
    return int(min(8192, math.ceil(n)))


@functools.lru_cache(maxsize=8192)
def _sample_table(sq: Squircle, n: int) -> tuple[np.ndarray, np.ndarray, float]:
    """``n`` arc-length-even boundary angles of ``sq``, the points, and the largest arc between
    consecutive samples (memoised: perception and the executive build many tables over mostly
    the same squircles)."""
    psi, pts, arc = _geom_kernel.sample_table(sq.packed(), n)  # compiled; as boundary_psi, point_at, _max_arc
    for a in (psi, pts):
        a.flags.writeable = False
    return psi, pts, arc


def _max_perimeter(squircles) -> float:
    """``max(_perimeter(sq) for sq in squircles)``, measuring only the squircles that can have
    the largest: :func:`_perimeter` (a polygon inscribed in a convex curve) is at most the
    curve's perimeter, which is at most that of the bounding rectangle, ``2 (width + height)``;
    a squircle whose rectangle's perimeter is below a measured one cannot change the maximum."""
    best = -math.inf
    for bound, sq in sorted(((2.0 * (sq.width + sq.height), sq) for sq in squircles), key=lambda t: -t[0]):
        if bound * (1.0 + 1e-9) < best:
            break
        best = max(best, _perimeter(sq))
    return best


@functools.lru_cache(maxsize=8192)
def _perimeter(sq: Squircle) -> float:
    pts = sq.point_at(np.linspace(0.0, 2.0 * math.pi, 2049))
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def _normalised(p: np.ndarray, x, y):
    """Normalised coordinates ``A^-1 R(-theta)(q - c)`` (jets or arrays)."""
    dx = x - p[..., CX]
    dy = y - p[..., CY]
    lx = dx * p[..., COS] + dy * p[..., SIN]
    ly = dy * p[..., COS] - dx * p[..., SIN]
    return lx * (1.0 / p[..., HW]), ly * (1.0 / p[..., HH])


def beta_jet(p: np.ndarray, x: Jet, y: Jet) -> Jet:
    """Eq. (4) on jets; ``p`` is a packed row or an array of rows broadcasting with the jets."""
    u, w = _normalised(p, x, y)
    u2, w2 = u.square(), w.square()
    r2 = u2 + w2
    disc = r2.square() - (u2 * w2) * (4.0 * p[..., S] ** 2)
    tiny = disc.v < 1e-200
    if np.any(tiny):
        safe = Jet.where(tiny, Jet.constant(1.0, disc.order, disc.v.shape), disc)
        root = safe.sqrt()
        # at the centre sqrt(disc) ~ (x^2 + y^2): use it (value 0, continuous derivatives)
        root = Jet.where(tiny, r2, root)
    else:
        root = disc.sqrt()
    return (r2 + root) * 0.5 - 1.0


def ray_length_packed(p: np.ndarray, o: np.ndarray, d: np.ndarray, entry: np.ndarray | None = None) -> np.ndarray:
    """Exact distances from origins ``o`` along unit directions ``d`` to the boundary of rows ``p``.

    Rows with ``entry`` False (default): ``o`` is inside; the exit distance is returned.
    Rows with ``entry`` True: ``o`` is outside and the ray is known to enter the squircle; the
    entry distance (first crossing) is returned. Newton's method on the gauge
    ``g = sqrt(beta + 1)`` along the ray (a norm of an affine function of ``r``, hence convex and
    nearly linear, so few steps are needed; the root ``g = 1`` is that of ``beta``), started
    where the ray crosses the bounding rectangle, i.e. on the far side of the wanted root: the
    iterates are monotone and cannot skip it. Arrays ``p (K, 7)``, ``o (K, 2)``, ``d (K, 2)``,
    ``entry (K,)``. Compiled: :func:`navigation._geom_kernel.ray_length_rows`, each row iterated to
    its own convergence.
    """
    return _geom_kernel.ray_length_rows(p, o, d, entry)


def beta_gradient_rows(P: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact gradient ``(b_x, b_y)`` of ``beta`` of rows ``P (..., 7)`` at ``(qx, qy)``
    (broadcasting; not defined at a squircle's centre, where it is NaN)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        _, bx, by, *_ = _beta_derivatives(P, qx, qy)
    return bx, by


def _beta_derivatives(p: np.ndarray, qx: np.ndarray, qy: np.ndarray):
    """``beta`` at points ``(qx, qy)`` with its exact gradient and packed Hessian in ``q``.

    Analytic formulas of eq. (4) (no jets), broadcasting the rows ``p (..., 7)`` against ``qx``,
    ``qy``; used away from the centre (``x^4 + y^4 + (2 - 4s^2) x^2 y^2 > 0``; NaN at it).
    Compiled: :func:`navigation._geom_kernel.beta_derivatives_xy`, the one copy of the formulas
    (the transformation chain's kernels use it too). Returns
    ``(beta, b_x, b_y, b_xx, b_xy, b_yy)``, each of the broadcast shape.
    """
    p = np.asarray(p, dtype=float)
    qx = np.asarray(qx, dtype=float)
    qy = np.asarray(qy, dtype=float)
    shape = np.broadcast_shapes(p.shape[:-1], qx.shape, qy.shape)
    P = np.broadcast_to(p, shape + (7,)).reshape(-1, 7)
    out = _geom_kernel.beta_derivatives_rows(P, np.broadcast_to(qx, shape).reshape(-1),
                                             np.broadcast_to(qy, shape).reshape(-1))
    return tuple(out[:, j].reshape(shape) for j in range(6))


def _beta_value(p: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> np.ndarray:
    """The ``beta`` of :func:`_beta_derivatives` without the derivatives: the same operations in
    the same order, so the same bits (an image computed at order 0 must equal the one computed
    with derivatives)."""
    *_, k, x2, y2 = _local(p, qx, qy)
    return 0.5 * (x2 + y2 + np.sqrt(x2 * x2 + y2 * y2 + k * x2 * y2)) - 1.0


def _local(p: np.ndarray, qx: np.ndarray, qy: np.ndarray):
    """The normalised frame of :func:`_beta_derivatives` and :func:`_beta_value`: ``(cos, sin,
    1 / hw, 1 / hh, x, y, k = 2 - 4 s^2, x^2, y^2)`` of rows ``p`` at ``(qx, qy)``."""
    c, sn = p[..., COS], p[..., SIN]
    ihw, ihh = 1.0 / p[..., HW], 1.0 / p[..., HH]
    dx, dy = qx - p[..., CX], qy - p[..., CY]
    x = (dx * c + dy * sn) * ihw
    y = (dy * c - dx * sn) * ihh
    return c, sn, ihw, ihh, x, y, 2.0 - 4.0 * p[..., S] ** 2, x * x, y * y


def _root_jet(p: np.ndarray, o: np.ndarray, r0: np.ndarray, ux: Jet, uy: Jet) -> Jet:
    """Jet of the ray length ``r(u)`` defined by ``beta(o + r u) = 0``, given its value ``r0``.

    Implicit function theorem on ``F(r, u) = beta(o + r u)``: with the analytic partials of
    ``F`` at the root (from :func:`_beta_derivatives`), ``r_a = -F_a / F_r`` and
    ``r_ab = -(F_ab + F_ar r_b + F_br r_a + F_rr r_a r_b) / F_r``, then the chain rule through
    the direction jets (:meth:`Jet.compose2`). Exact derivatives, one pass, no jet solve.
    """
    if ux.order == 0:
        return Jet.constant(r0, 0)
    vx, vy = ux.v, uy.v
    n = len(vx)
    # compiled (navigation._geom_kernel.root_partials, which the chain's kernels use too)
    out = _geom_kernel.root_partials_rows(np.broadcast_to(p, (n, 7)), np.broadcast_to(o, (n, 2)),
                                          np.broadcast_to(r0, (n,)), vx, vy)
    ra, rb, raa, rab, rbb = (out[:, j] for j in range(5))
    if ux.order == 1:
        return Jet.compose2(r0, ra, rb, None, None, None, ux, uy)
    return Jet.compose2(r0, ra, rb, raa, rab, rbb, ux, uy)


def ray_length_jet(p: np.ndarray, o: np.ndarray, ux: Jet, uy: Jet, entry: np.ndarray | None = None) -> Jet:
    """Jet of the exact ray length (see :func:`ray_length_packed`) along unit direction jets.

    The root is found in floating point; its derivatives with respect to the direction follow
    from the implicit function theorem (:func:`_root_jet`), so the value, gradient and Hessian
    of the result are exact.
    """
    d = np.stack((ux.v, uy.v), axis=1)
    r0 = ray_length_packed(p, o, d, entry)
    return _root_jet(p, o, r0, ux, uy)


def ray_length_center_jet(p: np.ndarray, ux: Jet, uy: Jet) -> Jet:
    """Jet of the ray length from the centre along unit direction jets (paper 004 eq. 5).

    ``beta + 1`` is the square of the squircle's gauge, a norm about the centre, so the boundary
    point along ``u`` is ``c + u / gauge(u)`` and ``R(u) = (beta(c + u) + 1)^(-1/2)`` (the same
    number as eq. 5), differentiated analytically through :func:`_beta_derivatives`.
    """
    qx = p[..., CX] + ux.v
    qy = p[..., CY] + uy.v
    if ux.order == 0:  # the value alone, by the same operations as _beta_derivatives
        return Jet((1.0 / np.sqrt(_beta_value(p, qx, qy) + 1.0))[..., None])
    b, bx, by, bxx, bxy, byy = _beta_derivatives(p, qx, qy)
    r = 1.0 / np.sqrt(b + 1.0)  # the same value at every order (the goal's image must match)
    r3 = -0.5 * r * r * r  # d/db (b + 1)^(-1/2)
    if ux.order == 1:
        return Jet.compose2(r, r3 * bx, r3 * by, None, None, None, ux, uy)
    r5 = -1.5 * r3 * r * r  # d2/db2 = (3/4) (b + 1)^(-5/2)
    return Jet.compose2(r, r3 * bx, r3 * by, r5 * bx * bx + r3 * bxx, r5 * bx * by + r3 * bxy,
                        r5 * by * by + r3 * byy, ux, uy)
