"""Second-order forward-mode automatic differentiation in two variables, over numpy arrays.

A :class:`Jet` carries, for every element of an array, the value of a quantity and (up to
order 2) its exact first and second derivatives with respect to the two coordinates of the
query point ``q = (q_x, q_y)``. Arithmetic and elementary functions propagate them by the
chain rule, so any expression written with jets yields exact gradients and Hessians (no
finite differences). Storage is one array of shape ``(..., C)`` with columns

====  =======================================  ==========
C     columns                                  order
====  =======================================  ==========
1     ``v``                                    0
3     ``v, d_x, d_y``                          1
6     ``v, d_x, d_y, d_xx, d_xy, d_yy``        2
====  =======================================  ==========

This module is private: the public maps expose values, Jacobians ``(N, 2, 2)`` and
second-derivative tensors ``(N, 2, 2, 2)`` built from jets.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Jet", "ncols", "smoothstep_coeffs", "logistic"]

_NCOLS = {0: 1, 1: 3, 2: 6}
_ORDER = {1: 0, 3: 1, 6: 2}


def ncols(order: int) -> int:
    """Number of stored columns for a derivative order (0, 1 or 2)."""
    return _NCOLS[order]


def _outer(g: np.ndarray) -> np.ndarray:
    """Symmetric outer product ``g g^T`` in packed ``(xx, xy, yy)`` form."""
    return g.take(_PI, axis=-1) * g.take(_PJ, axis=-1)


def _sym_cross(g: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Packed ``g k^T + k g^T``."""
    return g.take(_PI, axis=-1) * k.take(_PJ, axis=-1) + k.take(_PI, axis=-1) * g.take(_PJ, axis=-1)


# packed (xx, xy, yy) as products g[_PI] * g[_PJ] of gradient components
_PI = np.array([0, 0, 1])
_PJ = np.array([0, 1, 1])


class Jet:
    """Value and exact derivatives (w.r.t. the 2-D query point) of an array quantity."""

    __slots__ = ("a",)
    __array_priority__ = 100  # make ndarray <op> Jet defer to Jet's reflected operators

    def __init__(self, a: np.ndarray):
        self.a = a

    # ------------------------------------------------------------------ construction
    @staticmethod
    def variables(points: np.ndarray, order: int) -> tuple["Jet", "Jet"]:
        """Seed jets for the coordinates of ``points`` (shape ``(N, 2)``)."""
        n = points.shape[0]
        c = _NCOLS[order]
        x = np.zeros((n, c))
        y = np.zeros((n, c))
        x[:, 0] = points[:, 0]
        y[:, 0] = points[:, 1]
        if order >= 1:
            x[:, 1] = 1.0
            y[:, 2] = 1.0
        return Jet(x), Jet(y)

    @staticmethod
    def constant(value, order: int, shape=None) -> "Jet":
        """A jet with zero derivatives."""
        v = np.asarray(value, dtype=float)
        if shape is not None:
            v = np.broadcast_to(v, shape)
        a = np.zeros(v.shape + (_NCOLS[order],))
        a[..., 0] = v
        return Jet(a)

    # ------------------------------------------------------------------ accessors
    @property
    def order(self) -> int:
        return _ORDER[self.a.shape[-1]]

    @property
    def v(self) -> np.ndarray:
        """Values, shape ``(...)``."""
        return self.a[..., 0]

    @property
    def g(self) -> np.ndarray:
        """Gradients, shape ``(..., 2)`` (order >= 1)."""
        return self.a[..., 1:3]

    @property
    def h(self) -> np.ndarray:
        """Packed Hessians ``(xx, xy, yy)``, shape ``(..., 3)`` (order 2)."""
        return self.a[..., 3:6]

    def __getitem__(self, idx) -> "Jet":
        if isinstance(idx, tuple):
            return Jet(self.a[idx + (slice(None),)])
        return Jet(self.a[idx])

    def __len__(self) -> int:
        return self.a.shape[0]

    def copy(self) -> "Jet":
        return Jet(self.a.copy())

    def gradient(self) -> np.ndarray:
        return self.a[..., 1:3].copy()

    def hessian(self) -> np.ndarray:
        """Full symmetric Hessians, shape ``(..., 2, 2)``."""
        h = self.a[..., 3:6]
        out = np.empty(h.shape[:-1] + (2, 2))
        out[..., 0, 0] = h[..., 0]
        out[..., 0, 1] = out[..., 1, 0] = h[..., 1]
        out[..., 1, 1] = h[..., 2]
        return out

    # ------------------------------------------------------------------ elementwise rule
    def apply(self, f0: np.ndarray, f1: np.ndarray | None = None, f2: np.ndarray | None = None) -> "Jet":
        """Compose with a scalar function given its value ``f0``, derivative ``f1``, ``f2``."""
        a = self.a
        c = a.shape[-1]
        if c == 1:
            return Jet(np.asarray(f0, dtype=float)[..., None].copy())
        out = a * f1[..., None]
        out[..., 0] = f0
        if c == 6:
            out[..., 3:6] += f2[..., None] * _outer(a[..., 1:3])
        return Jet(out)

    # ------------------------------------------------------------------ arithmetic
    def __neg__(self) -> "Jet":
        return Jet(-self.a)

    def __add__(self, other) -> "Jet":
        if isinstance(other, Jet):
            return Jet(self.a + other.a)
        out = self.a.copy()
        out[..., 0] += other
        return Jet(out)

    __radd__ = __add__

    def __sub__(self, other) -> "Jet":
        if isinstance(other, Jet):
            return Jet(self.a - other.a)
        out = self.a.copy()
        out[..., 0] -= other
        return Jet(out)

    def __rsub__(self, other) -> "Jet":
        out = -self.a
        out[..., 0] += other
        return Jet(out)

    def __mul__(self, other) -> "Jet":
        if not isinstance(other, Jet):
            return Jet(self.a * np.asarray(other, dtype=float)[..., None])
        a, b = self.a, other.a
        out = a * b[..., :1]
        if a.shape[-1] > 1:
            out[..., 1:] += a[..., :1] * b[..., 1:]
            if a.shape[-1] == 6:
                out[..., 3:6] += _sym_cross(a[..., 1:3], b[..., 1:3])
        return Jet(out)

    __rmul__ = __mul__

    def reciprocal(self) -> "Jet":
        v = self.a[..., 0]
        r = 1.0 / v
        return self.apply(r, -r * r, 2.0 * r * r * r)

    def __truediv__(self, other) -> "Jet":
        if isinstance(other, Jet):
            return self * other.reciprocal()
        return Jet(self.a / np.asarray(other, dtype=float)[..., None])

    def __rtruediv__(self, other) -> "Jet":
        return self.reciprocal() * other

    def square(self) -> "Jet":
        v = self.a[..., 0]
        return self.apply(v * v, 2.0 * v, np.full_like(v, 2.0))

    def sqrt(self) -> "Jet":
        v = self.a[..., 0]
        r = np.sqrt(v)
        d1 = 0.5 / r
        return self.apply(r, d1, -0.5 * d1 / v)

    def exp(self) -> "Jet":
        e = np.exp(self.a[..., 0])
        return self.apply(e, e, e)

    def log(self) -> "Jet":
        v = self.a[..., 0]
        r = 1.0 / v
        return self.apply(np.log(v), r, -r * r)

    # ------------------------------------------------------------------ structure
    @staticmethod
    def where(mask: np.ndarray, a: "Jet", b: "Jet") -> "Jet":
        return Jet(np.where(mask[..., None], a.a, b.a))

    @staticmethod
    def compose2(f, fx, fy, fxx, fxy, fyy, x: "Jet", y: "Jet") -> "Jet":
        """Jet of ``f(x, y)`` from the partial derivatives of ``f`` (analytic, at ``(x.v, y.v)``)."""
        c = x.a.shape[-1]
        out = np.empty(np.shape(f) + (c,))
        out[..., 0] = f
        if c >= 3:
            xg, yg = x.a[..., 1:3], y.a[..., 1:3]
            out[..., 1:3] = fx[..., None] * xg + fy[..., None] * yg
        if c == 6:
            out[..., 3:6] = (
                fx[..., None] * x.a[..., 3:6]
                + fy[..., None] * y.a[..., 3:6]
                + fxx[..., None] * _outer(xg)
                + fyy[..., None] * _outer(yg)
                + fxy[..., None] * _sym_cross(xg, yg)
            )
        return Jet(out)


def logistic(z: np.ndarray) -> np.ndarray:
    """Numerically stable logistic ``1 / (1 + exp(-z))`` (``exp(-|z|)`` never overflows)."""
    z = np.asarray(z, dtype=float)
    ez = np.exp(-np.abs(z))
    q = 1.0 / (1.0 + ez)
    return np.where(z >= 0, q, ez * q)


# Below _EDGE the C-infinity step exp(-1/x)-based is < 1e-280 with all derivatives: treat as 0.
_EDGE = 1.5e-3


def smoothstep_coeffs(x: np.ndarray, order: int):
    """The C-infinity step ``eta(x)`` of Loizou (2017) and its first two derivatives.

    ``eta(x) = sigma(x) / (sigma(x) + sigma(1 - x))`` with ``sigma(x) = exp(-1/x)`` for
    ``x > 0`` and 0 otherwise: 0 for ``x <= 0``, 1 for ``x >= 1``, strictly increasing between,
    flat to all orders at both ends. Evaluated stably as ``logistic(1/(1-x) - 1/x)``.

    Returns ``(eta, eta', eta'')`` (derivatives ``None`` when ``order`` does not need them).
    Branch-free (every element is evaluated at ``x`` clipped to the open interval, then masked),
    so one call costs a fixed handful of array operations whatever the mix of elements.
    """
    x = np.asarray(x, dtype=float)
    inner = (x > _EDGE) & (x < 1.0 - _EDGE)
    xi = np.clip(x, _EDGE, 1.0 - _EDGE)
    ix = 1.0 / xi
    iu = 1.0 / (1.0 - xi)
    z = iu - ix
    lz = logistic(z)
    eta = np.where(inner, lz, np.where(x >= 1.0 - _EDGE, 1.0, 0.0))
    d1 = d2 = None
    if order >= 1:
        w = np.where(inner, lz * (1.0 - lz), 0.0)
        z1 = iu * iu + ix * ix
        d1 = w * z1
        if order >= 2:
            z2 = 2.0 * (iu * iu * iu - ix * ix * ix)
            d2 = w * ((1.0 - 2.0 * lz) * z1 * z1 + z2)
    return eta, d1, d2
