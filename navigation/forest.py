"""Forest of stars: organise overlapping squircle obstacles into trees (paper 001, section 4.1.2).

The leaf-purging transformation of paper 001 (eq. 13-19, ``shared/notes/navigation-math.md``,
"Forest of stars") needs the obstacles arranged as a *forest of stars*: obstacles that overlap
form trees; each non-root obstacle ``O_i`` has one parent ``O_i*`` and a common centre
``p_i in O_i ∩ O_i*``; leaves are purged into their parents level by level, deepest first. An
obstacle that crosses the workspace boundary is a child of the workspace: that tree's root is the
workspace and its leaves are eventually purged into the boundary.

:func:`build_forest` computes this structure exactly (no bounding boxes): overlaps, Euclidean
distances between obstacles and to the workspace boundary, and for every parent/child pair the
point deepest inside both (the centre of the largest disc inscribed in the intersection).

Rules
-----
:func:`build_forest` raises :class:`~navigation.errors.ForestError` (``.rule``, ``.obstacles``
given as indices of the *input* list, ``-1`` for the workspace boundary) when

``"cycle"``
    the overlap graph (obstacles plus one node for the workspace boundary, linked to every
    obstacle that crosses it) is not a forest. In particular a connected group of obstacles may
    touch the workspace boundary at most once, and one obstacle may not cross it twice.
``"too-close"``
    two obstacles, or an obstacle and the workspace boundary, do not overlap but are closer than
    ``min_gap``: the purging and the safety margins ``E_i`` need a clear gap.
``"shallow-overlap"``
    an overlap (or a crossing of the workspace boundary) is a grazing contact: the deepest point
    of the intersection is less than ``min_overlap`` inside both sets, so no well-conditioned
    common centre exists.
``"covers-workspace"``
    an obstacle contains the whole workspace (there is no free space).

Obstacles that change nothing are dropped, not rejected, and listed in :attr:`Forest.dropped`:
obstacles entirely outside the workspace, and obstacles contained in another obstacle.

Memo (incremental rebuilds)
---------------------------
Every expensive step depends on one obstacle (boundary samples, relation to the workspace) or
on one pair (overlap and containment, distance, common centre), and is memoised in a bounded
LRU keyed by the squircles themselves. Rebuilding after a map change (paper 001 section 4.2.2:
an obstacle added as a new star or a new leaf, updated or removed) therefore costs only the
steps that involve changed obstacles, and gives the result of a cold build (up to rounding,
1e-12 m; tested). :func:`clear_cache` empties the memo (benchmarks use it to time cold builds).

Distances
---------
The navigation function needs, per obstacle, only the smallest distance its shell must respect
(:attr:`Forest.clearance`), and the rules need only the pairs closer than ``min_gap``. Every pair
first gets a cheap lower bound (bounding rectangles and discs, :func:`_gap_bounds`); exact
distances are computed for the pairs below ``min_gap`` and, in a few batched rounds, for the
pairs whose bound is the current minimum of some obstacle, until every minimum is exact. The full
matrix :attr:`Forest.distances` is computed on first access. Exact obstacle-obstacle and
obstacle-workspace distances: closest pair of coarse boundary samples
(every local minimum within the sampling error is a candidate), refined on the samples and then
by Newton on both boundary parameters with exact derivatives; point-to-boundary distances are
:meth:`Squircle.distance`.

Root choice: an interior tree is rooted at its graph centre (the member of least eccentricity,
which minimises the number of purge levels), ties broken by larger area, then lower index. A
tree that touches the workspace boundary is rooted at the workspace; the crossing obstacle is its
child.

Symbols
-------
==================  ==========================================================
``O_i``             obstacle ``i`` (a :class:`~navigation.geometry.Squircle`)
``O_i*``            its parent (an obstacle, or the workspace boundary)
``p_i``             common centre of ``O_i`` and ``O_i*`` (:attr:`Forest.center`)
``depth(q)``        ``-distance(q)``: how deep ``q`` lies inside an obstacle
==================  ==========================================================
"""

from __future__ import annotations

import functools
import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import networkx as nx
import numpy as np

from ._center_kernel import center_programs
from ._geom_kernel import beta_rows, far_gap_rows, gap_bound_rows, wall_bound_rows
from ._lp_kernel import max_min_slack
from ._memo import Memo
from ._pair_kernel import pair_distance
from ._sample_kernel import (PAIR_APART, PAIR_FIRST_INSIDE, PAIR_OVERLAP, PAIR_SECOND_INSIDE, WS_COVERS, WS_CROSSES,
                             WS_CROSSES_TWICE, WS_INSIDE, WS_OUTSIDE, pair_relation_codes,
                             sample_rows, workspace_relation_codes)
from .errors import ForestError
from .geometry import (Squircle, boundary_jet_rows, clear_geometry_cache, pack, point_at_rows,
                       signed_distance_rows)

__all__ = ["WORKSPACE", "NO_PARENT", "Forest", "build_forest", "check_forest", "separation", "common_center",
           "clear_cache"]

#: ``Forest.parent`` value of an obstacle whose parent is the workspace boundary.
WORKSPACE = -1
#: ``Forest.parent`` value of the root of an interior tree.
NO_PARENT = -2

_SAMPLES = 256  # boundary samples per obstacle
_WS_SAMPLES = 1024  # boundary samples of the workspace
_POLY = 128  # vertices of the polygons inscribed in a child and its parent (common centres)
_WS_TANGENTS = 8  # tangent lines of the workspace tried for a child of the workspace
_THIN_TANGENTS = 48  # tangent lines per boundary arc of a thin intersection
_FAR_RAYS = 720  # rays from the common centre of a workspace child sampling its far gap
_THIN = 0.01  # common-centre depths below this are refined with exact distances
_CONTAINED = 1e-12  # beta tolerance of the containment test
_MEMO_SIZE = 65536  # pairwise results kept by the memo (a few hundred bytes each)
_BODY_SIZE = 1024  # boundary-sample sets kept by the memo


# Every expensive step of build_forest is a function of one obstacle (its boundary samples), of
# a pair (overlap, containment, distance) or of a child/parent pair (common centre), computed row
# by row: a row's result does not depend on the other rows of its batch. Keying these results by
# the squircles themselves (frozen, hashable) makes a rebuild after a map change cost only the
# rows that involve changed obstacles (paper 001 section 4.2.2: re-use the stored terms of the
# unchanged obstacles) and gives the result of a cold build.
_PAIRS = Memo(_MEMO_SIZE)
_BODIES = Memo(_BODY_SIZE)


def clear_cache() -> None:
    """Forget every memoised body and pairwise result (benchmarks use it to time cold builds)."""
    _PAIRS.clear()
    _BODIES.clear()
    clear_geometry_cache()


# ---------------------------------------------------------------------- result
@dataclass(frozen=True, slots=True, eq=False)
class Forest:
    """Obstacles organised as a forest of stars (paper 001 section 4.1.2).

    Obstacle indices ``0 .. M-1`` refer to :attr:`obstacles` (the kept obstacles, in input
    order); :attr:`source_index` maps them back to the input list.

    Attributes
    ----------
    workspace : Squircle
    obstacles : tuple of Squircle, length M
    source_index : tuple of int
        Index of each kept obstacle in the input list.
    dropped : tuple of (int, str)
        Input index and reason of each obstacle left out (outside the workspace, or contained
        in another obstacle).
    parent : tuple of int
        Parent obstacle index, :data:`WORKSPACE` or :data:`NO_PARENT` (interior root).
    children : tuple of tuple of int
    depth : tuple of int
        Interior roots 0; children of the workspace 1; a child's depth is its parent's + 1.
    roots : tuple of int
        Roots of the interior trees; interior tree ``t`` is rooted at ``roots[t]``.
    tree_of : tuple of int
        Tree of each obstacle: ``-1`` for the workspace tree, ``0 .. len(roots)-1`` otherwise.
    center : ndarray, shape (M, 2)
        Common centre ``p_i`` of obstacle ``i`` and its parent (for a workspace child: deep in
        the obstacle and outside the workspace); a root's own centre.
    center_depth : ndarray, shape (M,)
        ``min`` of the depths of ``center[i]`` in ``O_i`` and in its parent (outside the
        workspace for workspace children); a root's depth inside itself.
    far_gap : ndarray, shape (M,)
        For a child of the workspace: the smallest distance, along the rays from its common
        centre on which it reaches into the workspace, from its boundary to the workspace
        boundary beyond it (the room its purge shell has there); ``inf`` for other obstacles.
    clearance : ndarray, shape (M,)
        The room around obstacle ``i`` that its shell in the transformation chain must respect
        (exact, the minimum of exact distances): for a non-root, the distance to the nearest
        obstacle still present when it is purged (depth <= its depth, its parent excepted) and
        to the workspace boundary (``far_gap`` for a workspace child, ``wall_distance``
        otherwise); for an interior root, the distance to the nearest other root and to the
        workspace boundary. ``inf`` when nothing bounds it.
    distances : ndarray, shape (M, M)
        Euclidean distance between obstacles (0 where they overlap and on the diagonal).
    wall_distance : ndarray, shape (M,)
        Distance to the workspace boundary (0 for obstacles that cross it).

    ``distances`` and ``wall_distance`` are not needed to build the navigation function
    (``clearance`` is), so they are computed on first access (exact, memoised) rather than at
    construction.
    """

    workspace: Squircle
    obstacles: tuple[Squircle, ...]
    source_index: tuple[int, ...]
    dropped: tuple[tuple[int, str], ...]
    parent: tuple[int, ...]
    children: tuple[tuple[int, ...], ...]
    depth: tuple[int, ...]
    roots: tuple[int, ...]
    tree_of: tuple[int, ...]
    center: np.ndarray
    center_depth: np.ndarray
    far_gap: np.ndarray
    clearance: np.ndarray
    _lazy: dict = field(default_factory=dict, repr=False)

    def __len__(self) -> int:
        return len(self.obstacles)

    @property
    def distances(self) -> np.ndarray:
        """Euclidean distances between obstacles ``(M, M)`` (see the class docstring)."""
        d = self._lazy.get("distances")
        if d is None:
            m = len(self.obstacles)
            d = np.zeros((m, m))
            I, J = _triu(m)
            apart = np.array([self.parent[i] != j and self.parent[j] != i for i, j in zip(I, J)], bool)
            I, J = I[apart], J[apart]
            if I.size:
                d[I, J] = d[J, I] = _distances(_bodies(self.obstacles, _SAMPLES), I, J)
            d.flags.writeable = False
            self._lazy["distances"] = d
        return d

    @property
    def wall_distance(self) -> np.ndarray:
        """Distance of every obstacle to the workspace boundary ``(M,)`` (see the class docstring)."""
        d = self._lazy.get("wall_distance")
        if d is None:
            d = np.zeros(len(self.obstacles))
            inner = np.array([i for i, p in enumerate(self.parent) if p != WORKSPACE], dtype=np.intp)
            if inner.size:
                bodies = _bodies(self.obstacles, _SAMPLES) + _bodies([self.workspace], _WS_SAMPLES)
                d[inner] = _distances(bodies, inner, np.full(inner.size, len(self.obstacles)))
            d.flags.writeable = False
            self._lazy["wall_distance"] = d
        return d

    @property
    def max_depth(self) -> int:
        """Largest depth of any obstacle (0 for an empty forest)."""
        return max(self.depth, default=0)

    def is_leaf(self, i: int) -> bool:
        """True when obstacle ``i`` has no children."""
        return not self.children[i]

    def is_root(self, i: int) -> bool:
        """True when obstacle ``i`` is the root of an interior tree."""
        return self.parent[i] == NO_PARENT

    def tree_members(self, t: int) -> tuple[int, ...]:
        """Obstacles of tree ``t`` (``-1``: the workspace tree), in index order."""
        if t != -1 and not 0 <= t < len(self.roots):
            raise IndexError(f"tree {t} does not exist (trees -1 .. {len(self.roots) - 1})")
        return tuple(i for i, k in enumerate(self.tree_of) if k == t)

    def levels(self) -> list[tuple[int, ...]]:
        """Purge levels, deepest first (eq. 13-14).

        Every non-root obstacle appears once, grouped by depth from the largest depth down to
        depth 1; after purging a level, the parents (one level up) are the new leaves.
        """
        movable = [i for i in range(len(self)) if self.parent[i] != NO_PARENT]
        if not movable:
            return []
        top = max(self.depth[i] for i in movable)
        return [tuple(i for i in movable if self.depth[i] == d) for d in range(top, 0, -1)]

    def describe(self) -> str:
        """Short human-readable summary (obstacles are shown by their input index ``#k``)."""
        m = len(self)
        n_ws = sum(1 for p in self.parent if p == WORKSPACE)
        lines = [f"forest of {m} obstacle(s): {len(self.roots)} interior tree(s), "
                 f"{n_ws} attached to the workspace boundary, max depth {self.max_depth}"]
        for k, reason in self.dropped:
            lines.append(f"  dropped #{k}: {reason}")

        def render(i: int, indent: int) -> None:
            lines.append(f"{'  ' * indent}#{self.source_index[i]} (depth {self.depth[i]}, "
                         f"overlap {self.center_depth[i]:.3f} m)")
            for c in self.children[i]:
                render(c, indent + 1)

        tops = [i for i in range(m) if self.parent[i] == WORKSPACE]
        if tops:
            lines.append("  workspace boundary")
            for i in tops:
                render(i, 2)
        for t, r in enumerate(self.roots):
            lines.append(f"  tree {t}: root #{self.source_index[r]} ({len(self.tree_members(t))} obstacle(s))")
            for c in self.children[r]:
                render(c, 2)
        return "\n".join(lines)


# ---------------------------------------------------------------------- vectorised primitives
def _xy(P: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """Boundary points ``(K, ..., 2)`` of packed squircles ``P (K, 7)`` at angles ``psi (K, ...)``:
    :func:`~navigation.geometry.point_at_rows`."""
    return point_at_rows(P, psi)


def _beta(P: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Obstacle function of packed squircles ``P (K, 7)`` (or one, ``(1, 7)``) at points
    ``q (K, ..., 2)``: :func:`navigation._geom_kernel.beta_rows`."""
    return beta_rows(P, q)


class _Body:
    """Boundary samples of one squircle (evenly spaced in arc length) with its packed row."""

    __slots__ = ("sq", "row", "psi", "pts", "w0", "spacing", "radius")

    def __init__(self, sq: Squircle, n: int, _arrays=None):
        """``_arrays``: this squircle's ``(row, psi, pts, w0, spacing)`` row of a
        :func:`_sample_rows` batch."""
        if _arrays is None:
            _arrays = tuple(a[0] for a in _sample_rows(pack([sq]), n))
        self.sq = sq
        self.row, self.psi, self.pts, w0, spacing = _arrays
        self.w0, self.spacing = float(w0), float(spacing)
        self.radius = sq.bounding_radius


def _sample_rows(P: np.ndarray, n: int):
    """``n`` boundary angles per squircle row of ``P (K, 7)``, evenly spaced in arc length (as
    :meth:`Squircle.boundary_psi`: arc length on ``8 n`` chords, inverted by linear
    interpolation), their points, and per row the search window ``w0`` (1.5 x the largest
    angle gap) and the sample ``spacing`` (largest chord): ``(P, psi (K, n), pts (K, n, 2),
    w0 (K,), spacing (K,))``. Compiled: :func:`navigation._sample_kernel.sample_rows`."""
    return sample_rows(P, n)


@functools.lru_cache(maxsize=64)
def _triu(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(n, 1)`` (read-only, memoised: numpy builds a mask each call)."""
    I, J = np.triu_indices(n, 1)
    I.flags.writeable = J.flags.writeable = False
    return I, J


def _bodies(squircles: Sequence[Squircle], n: int) -> list["_Body"]:
    """Memoised :class:`_Body` of each squircle; the missing ones are sampled in one batch."""
    out = _BODIES.get_many([(sq, n) for sq in squircles])
    todo = [k for k, b in enumerate(out) if b is None]
    if todo:
        arrays = _sample_rows(pack([squircles[k] for k in todo]), n)
        for t, k in enumerate(todo):
            out[k] = _Body(squircles[k], n, tuple(a[t] for a in arrays))
        _BODIES.put_many(((squircles[k], n), out[k]) for k in todo)
    return out


def _signed_distance(bodies: Sequence[_Body], bid: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Exact signed distances of points ``q (K, 2)`` to bodies ``bid (K,)`` (negative inside):
    :func:`~navigation.geometry.signed_distance_rows`."""
    bid = np.asarray(bid, dtype=np.intp)
    return signed_distance_rows(np.array([bodies[b].row for b in bid]) if len(bid) else np.zeros((0, 7)), q)


def _gap_bound_rows(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Lower bounds ``(E,)`` of the distances between the squircles of rows ``A[k]`` and ``B[k]``.

    A squircle lies inside its bounding rectangle and inside its bounding disc, so the exact
    distance between two rectangles (0 when a separating-axis test finds no separating axis
    among their four edge directions, otherwise the smallest corner-to-edge distance) and the
    gap between the discs both bound the squircles' distance from below; the larger is
    returned (the rectangle is tight for the near-rectangular squircles of walls, the disc for
    round ones). Compiled: :func:`navigation._geom_kernel.gap_bound_rows`.
    """
    return gap_bound_rows(A, B)


def _gap_bounds(P: np.ndarray) -> np.ndarray:
    """:func:`_gap_bound_rows` of every pair of rows ``P (K, 7)`` as a symmetric ``(K, K)``
    matrix (diagonal 0). Not memoised: the compiled bound of all 190 pairs of 20 obstacles
    costs less than looking them up."""
    K = len(P)
    out = np.zeros((K, K))
    I, J = _triu(K)
    if I.size:
        out[I, J] = out[J, I] = _gap_bound_rows(P[I], P[J])
    return out


def _wall_bounds(P: np.ndarray, ws: _Body) -> np.ndarray:
    """Lower bounds ``(K,)`` of the distances from squircles ``P (K, 7)`` inside the workspace
    to its boundary.

    The polygon through every 4th boundary sample of the workspace lies inside it, so the
    distance from a point to the polygon's boundary bounds its distance to the workspace
    boundary from below; a squircle lies inside its bounding rectangle, whose distance to the
    boundary of a convex polygon containing it is the smallest slack of its corners over the
    polygon's edges. 0 where a corner is not inside the polygon. Not memoised (the compiled
    bound of 20 squircles costs less than looking them up).
    """
    return wall_bound_rows(P, ws.pts[::4])  # counter-clockwise


def _pair_distance(bodies: Sequence[_Body], I: np.ndarray, J: np.ndarray, tol: float = 1e-12):
    """Minimum distance between the boundaries of bodies ``I[k]`` and ``J[k]``.

    Coarse to fine: every 8th boundary sample of both bodies; each local minimum (along the
    boundary of ``I``) of the coarse distance that lies within the coarse sampling error of the
    smallest is a candidate; each candidate is refined to the closest pair of samples within 8
    samples on both boundaries, then by Newton on both boundary parameters with exact
    derivatives (:func:`navigation._pair_kernel.newton_pair`); the smallest result wins. For disjoint convex sets the
    facing local minimum is unique; for an obstacle inside the workspace the distance to the
    boundary can have several nearly equal local minima (near a corner), all of which are
    refined. Returns ``(distances (K,), points_on_I (K, 2), points_on_J (K, 2))``. Compiled:
    :func:`navigation._pair_kernel.pair_distance`.
    """
    return pair_distance(bodies, I, J, tol)


def _max_min_slack(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray, scale: np.ndarray, *,
                   stages: int = 4, steps: int = 10, grid: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Maximise ``t(q) = min_k (b_k - a_k . q)`` per row: the Chebyshev centre of the polygon of
    half-planes ``a (E, K, 2)`` (unit normals), ``b (E, K)``, i.e. a 3-variable linear program.

    Starts at the best point of a ``grid x grid`` grid over the box ``[lo, hi]`` (``(E, 2)``).
    ``t`` is concave, and so is its soft minimum ``t_tau = -tau log sum_k exp(-s_k / tau)`` of
    the slacks ``s_k`` (``t - tau log K <= t_tau <= t``), which is smooth with one maximiser.
    Newton steps on ``t_tau`` (exact gradient ``-sum_k w_k a_k`` and Hessian ``-Cov_w(a) / tau``), backtracked
    until ``t_tau`` does not decrease and limited to ``scale``, follow ``tau`` from
    ``0.05 scale`` down by 8x per stage (``stages`` stages of at most ``steps`` steps); a row
    leaves a stage when its Newton step is below ``1e-6 scale``. Returns the points ``(E, 2)``
    and their exact ``t``, within about ``1e-4 scale`` of the optimum with the defaults (tested
    against HiGHS): ample for a common centre, whose depth is then evaluated exactly. Compiled:
    :func:`navigation._lp_kernel.max_min_slack`, row by row.
    """
    return max_min_slack(a, b, lo, hi, scale, stages=stages, steps=steps, grid=grid)


def _common_centers(bodies: Sequence[_Body], I: np.ndarray, J: np.ndarray, outside: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Points deep inside ``O_I ∩ O_J`` (``O_I \\ W`` where ``outside``: ``J`` is the workspace)
    and their exact depths ``min(depth in I, depth in J)`` (``distance outside J``).

    A child and its parent: the centre of the largest disc inside both inscribed polygons
    (:func:`navigation._center_kernel.center_programs`, a linear program solved by
    :func:`_max_min_slack`); the
    disc lies in both squircles, and its radius is below the true largest one by at most the
    polygons' sagitta (sub-millimetre). A child of the workspace: ``O_I \\ W`` is not convex,
    but the points beyond a tangent line of the (convex) workspace at one of its boundary
    points inside ``O_I`` lie outside ``W`` by at least their distance to that line; each of up
    to ``_WS_TANGENTS`` such lines gives a linear program (the polygon of ``O_I`` and the
    half-plane beyond the line) and the best result is kept. The depth at the chosen point is
    then evaluated exactly (:func:`_signed_distance`); intersections thinner than ``_THIN``
    are refined on exact distances (:func:`_thin_centers`). Returns ``(points (E, 2), depth (E,))``.
    """
    E = len(I)
    if E == 0:
        return np.empty((0, 2)), np.empty(0)
    sgn = np.where(outside, 1.0, -1.0)  # depth in J = sgn * signed distance to J
    PI = np.array([bodies[i].row for i in I])
    PJ = np.array([bodies[j].row for j in J])
    ws = np.nonzero(outside)[0]
    wsb = bodies[J[ws[0]]] if ws.size else None
    A, B, LO, HI, L, owner = center_programs(PI, PJ, outside, *((wsb.row, wsb.pts, wsb.psi) if wsb is not None else (None,) * 3),
                                             n=_POLY, n_tangents=_WS_TANGENTS, turn=0.05)
    c, t = _max_min_slack(A, B, LO, HI, L)
    order = np.lexsort((-t, owner))  # per owner, the largest t first
    first = order[np.concatenate(([True], owner[order][1:] != owner[order][:-1]))]
    c = c[first][np.argsort(owner[first])]
    dI, dJ = np.split(_signed_distance(bodies, np.concatenate((I, J)), np.concatenate((c, c))), 2)
    depth = np.minimum(-dI, sgn * dJ)
    # Thin intersections: the polygons lose up to their sagitta; refine on exact distances.
    thin = np.nonzero(depth < _THIN)[0]
    if thin.size:
        c[thin], depth[thin] = _thin_centers(bodies, I[thin], J[thin], sgn[thin], c[thin], depth[thin])
    return c, depth


def _arc_tangents(body: _Body, inside: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` boundary points of ``body`` spread over the arc of its samples flagged ``inside``
    (one circular run; widened by one sample gap at each end, or the neighbourhood of the
    sample of largest ``inside`` score when none is flagged), with their outward unit normals:
    ``(points (n, 2), normals (n, 2), psi (n,))``."""
    psi = body.psi
    m = len(psi)
    if inside.dtype == bool:
        idx = np.nonzero(inside)[0]
    else:
        idx = np.nonzero(inside > 0)[0]
        if idx.size == 0:
            idx = np.array([int(np.argmax(inside))])
    if idx.size == m:
        lo, hi = 0.0, 2.0 * np.pi
    else:
        # the run starts after the first gap in the flags (circularly)
        flags = np.zeros(m, bool)
        flags[idx] = True
        start = int(np.nonzero(flags & ~np.roll(flags, 1))[0][0])
        length = int(np.argmin(np.roll(flags, -start))) or m
        a, b = start - 1, start + length  # one sample beyond each end
        lo = psi[a % m] - (2.0 * np.pi if a < 0 else 0.0)
        hi = psi[b % m] + 2.0 * np.pi * (b // m)
        if hi <= lo:
            hi += 2.0 * np.pi
    ps = np.linspace(lo, hi, n)
    x, dx, _ = boundary_jet_rows(np.broadcast_to(body.row, (n, 7)), ps)
    normal = np.stack((dx[:, 1], -dx[:, 0]), axis=1) / np.linalg.norm(dx, axis=1, keepdims=True)
    return x, normal, ps


def _thin_centers(bodies: Sequence[_Body], I: np.ndarray, J: np.ndarray, sgn: np.ndarray, c: np.ndarray,
                  depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Common centres of thin intersections (lens-shaped, about as thin as the polygons'
    sagitta), from tangent lines instead of inscribed polygons.

    Near a thin lens the depth in a convex set is the distance to the nearest of its tangent
    lines at the lens: ``_THIN_TANGENTS`` tangent half-planes of ``O_I`` along its boundary
    arc inside the other set, and of ``O_J`` along its arc inside ``O_I``, make a linear
    program (:func:`_max_min_slack`) whose optimum is the deepest point up to the tangents'
    spacing. A child of the workspace: the points beyond a tangent line of the workspace (at its
    arc inside ``O_I``) lie outside it by at least their distance to the line, so each of
    ``_WS_TANGENTS`` such lines gives one program with the child's half-planes and the best
    result is kept. Every candidate's depth is then evaluated exactly; the better of it and the
    current estimate ``c`` (depth ``depth``) is returned.
    """
    K = len(I)
    A, B, LO, HI, L, owner = [], [], [], [], [], []
    n = _THIN_TANGENTS
    for k in range(K):
        bi, bj = bodies[I[k]], bodies[J[k]]
        score = sgn[k] * _beta(bj.row[None], bi.pts[None])[0]  # > 0: in the J-set
        xi, ni, _ = _arc_tangents(bi, score, n)
        ai, b_i = ni, (ni * xi).sum(-1)
        inside_i = _beta(bi.row[None], bj.pts[None])[0] < 0  # J's samples inside O_I
        xj, nj, _ = _arc_tangents(bj, inside_i if inside_i.any() else -_beta(bi.row[None], bj.pts[None])[0], n)
        box = np.concatenate((xi, xj))
        lo, hi = box.min(0), box.max(0)
        scale = max(float(np.min(hi - lo)), 1e-6)
        if sgn[k] < 0:  # inner parent: inside both
            lines = [(np.concatenate((ai, nj)), np.concatenate((b_i, (nj * xj).sum(-1))))]
        else:  # the workspace: beyond one of its tangent lines
            pick = np.unique(np.linspace(0, n - 1, min(_WS_TANGENTS, n)).round().astype(int))
            lines = [(np.concatenate((ai, -nj[[t]])), np.concatenate((b_i, -(nj[[t]] * xj[[t]]).sum(-1))))
                     for t in pick]
        for a_, b_ in lines:
            A.append(a_)
            B.append(b_)
            LO.append(lo)
            HI.append(hi)
            L.append(scale)
            owner.append(k)
    width = max(len(b) for b in B)
    A = np.array([np.concatenate((a, np.zeros((width - len(a), 2)))) for a in A])
    B = np.array([np.concatenate((b, np.full(width - len(b), 1e200))) for b in B])
    owner = np.asarray(owner)
    q, _ = _max_min_slack(A, B, np.array(LO), np.array(HI), np.array(L))
    dI, dJ = np.split(_signed_distance(bodies, np.concatenate((I[owner], J[owner])), np.concatenate((q, q))), 2)
    d = np.minimum(-dI, sgn[owner] * dJ)
    c, depth = c.copy(), depth.copy()
    for r in np.argsort(-d, kind="stable"):
        k = owner[r]
        if d[r] > depth[k]:
            c[k], depth[k] = q[r], d[r]
    return c, depth


# ---------------------------------------------------------------------- public helpers
def separation(a: Squircle, b: Squircle) -> float:
    """Euclidean distance between two squircles, 0 when they overlap or one contains the other.

    Examples
    --------
    >>> a = Squircle((0.0, 0.0), 1.0, 1.0, s=0.0)
    >>> b = Squircle((2.0, 0.0), 1.0, 1.0, s=0.0)
    >>> round(separation(a, b), 9)
    1.0
    """
    A, B = _Body(a, _SAMPLES), _Body(b, _SAMPLES)
    if _overlap(A, B):
        return 0.0
    return float(_pair_distance([A, B], np.array([0]), np.array([1]))[0][0])


def common_center(a: Squircle, b: Squircle, *, outside_b: bool = False) -> tuple[np.ndarray, float]:
    """Point deep inside ``a ∩ b`` (``a`` minus ``b`` when ``outside_b``) and its depth.

    The depth is ``min(-a.distance(p), -b.distance(p))`` (``b.distance(p)`` when
    ``outside_b``); it is negative when the sets do not overlap.

    Examples
    --------
    >>> a = Squircle((0.0, 0.0), 2.0, 0.4, s=0.99)
    >>> b = Squircle((0.0, 0.0), 0.4, 2.0, s=0.99)
    >>> p, depth = common_center(a, b)
    >>> bool(abs(depth - 0.2) < 1e-3)
    True
    """
    A = _Body(a, _SAMPLES)
    B = _Body(b, _WS_SAMPLES if outside_b else _SAMPLES)
    c, d = _common_centers([A, B], np.array([0]), np.array([1]), np.array([bool(outside_b)]))
    return c[0], float(d[0])


def _overlap(A: _Body, B: _Body) -> bool:
    """Exact overlap test of two convex squircles (boundaries cross, or containment)."""
    return _pair_relation(A, B) is not None


# ---------------------------------------------------------------------- memoised steps
def _workspace_relation(body: _Body, ws: _Body) -> str:
    """``"inside"``, ``"outside"``, ``"covers"`` (contains the workspace), ``"crosses"`` or
    ``"crosses-twice"``: where obstacle ``body`` lies relative to the workspace ``ws``."""
    return _workspace_relations([body], ws)[0]


def _stacked(bodies: Sequence[_Body]) -> tuple[np.ndarray, ...]:
    """The fields of ``bodies`` (all with the same sample count) stacked for the compiled
    kernels: ``(rows (K, 7), psi (K, n), pts (K, n, 2), spacing (K,), w0 (K,))``."""
    return (np.array([b.row for b in bodies]), np.array([b.psi for b in bodies]), np.array([b.pts for b in bodies]),
            np.array([b.spacing for b in bodies]), np.array([b.w0 for b in bodies]))


_WS_NAMES = {WS_INSIDE: "inside", WS_OUTSIDE: "outside", WS_COVERS: "covers", WS_CROSSES: "crosses",
             WS_CROSSES_TWICE: "crosses-twice"}
_PAIR_NAMES = {PAIR_APART: "", PAIR_OVERLAP: "overlap", PAIR_SECOND_INSIDE: "second-inside",
               PAIR_FIRST_INSIDE: "first-inside"}


def _workspace_relations(bodies: Sequence[_Body], ws: _Body) -> list[str]:
    """:func:`_workspace_relation` of every body (memoised; the missing ones in one batch).

    A body whose samples all lie inside the workspace is ``"inside"`` when the maximum of the
    workspace's beta along its boundary (refined where the sampled extreme is near zero,
    :func:`navigation._sample_kernel.extreme_betas_arrays`) is not positive; one whose
    samples all lie outside is ``"outside"`` (or ``"covers"``, when every workspace sample is
    inside it) when the minimum is positive; otherwise it crosses the boundary, twice or more
    when its samples outside form more than one circular run. Compiled:
    :func:`navigation._sample_kernel.workspace_relation_codes`."""
    keys = [("ws", b.sq, ws.sq) for b in bodies]
    out = _PAIRS.get_many(keys)
    todo = [k for k, r in enumerate(out) if r is None]
    if not todo:
        return out
    rows, psi, pts, spacing, w0 = _stacked([bodies[k] for k in todo])
    codes = workspace_relation_codes(ws.row, ws.pts, np.arange(len(todo)), rows, psi, pts, spacing, w0)
    for r, k in enumerate(todo):
        out[k] = _WS_NAMES[int(codes[r])]
    _PAIRS.put_many((keys[k], out[k]) for k in todo)
    return out


def _pair_relation(a: _Body, b: _Body) -> str | None:
    """``None`` (disjoint), ``"overlap"``, ``"second-inside"`` (``b`` contained in ``a``, up to
    rounding: an identical copy, or one touching from inside, counts) or ``"first-inside"``."""
    return _pair_relations([a], [b])[0]


def _pair_relations(A: Sequence[_Body], B: Sequence[_Body]) -> list[str | None]:
    """:func:`_pair_relation` of every pair ``(A[k], B[k])`` (memoised; the missing ones in one
    batch). The overlap test is exact for convex squircles: a sample of one inside the other,
    else the sign of the (refined) minimum of ``B``'s beta along ``A``'s boundary; containment:
    the (refined) maximum of one's beta along the other's boundary at most ``_CONTAINED``.
    Compiled: :func:`navigation._sample_kernel.pair_relation_codes`."""
    keys = [("ov", a.sq, b.sq) for a, b in zip(A, B)]
    out = _PAIRS.get_many(keys)
    todo = [k for k, r in enumerate(out) if r is None]
    if todo:
        index: dict[int, int] = {}
        members: list[_Body] = []
        for body in [A[k] for k in todo] + [B[k] for k in todo]:
            if id(body) not in index:
                index[id(body)] = len(members)
                members.append(body)
        I = np.array([index[id(A[k])] for k in todo], dtype=np.intp)
        J = np.array([index[id(B[k])] for k in todo], dtype=np.intp)
        codes = pair_relation_codes(I, J, *_stacked(members), _CONTAINED)
        for r, k in enumerate(todo):
            out[k] = _PAIR_NAMES[int(codes[r])]
        _PAIRS.put_many((keys[k], out[k]) for k in todo)
    return [r or None for r in out]


def _distances(bodies: Sequence[_Body], I: np.ndarray, J: np.ndarray) -> np.ndarray:
    """:func:`_pair_distance` of rows ``(I[k], J[k])``, computing only the rows not memoised."""
    keys = [("d", bodies[i].sq, bodies[j].sq) for i, j in zip(I, J)]
    out = np.array(_PAIRS.get_many(keys), dtype=float)  # None -> nan
    todo = np.nonzero(np.isnan(out))[0]
    if todo.size:
        d, _, _ = _pair_distance(bodies, I[todo], J[todo])
        out[todo] = d
        _PAIRS.put_many((keys[t], float(v)) for t, v in zip(todo, d))
    return out


def _centers(bodies: Sequence[_Body], I: np.ndarray, J: np.ndarray, outside: np.ndarray):
    """:func:`_common_centers` of rows ``(I[k], J[k])``, computing only the rows not memoised."""
    keys = [("c", bodies[i].sq, bodies[j].sq, bool(o)) for i, j, o in zip(I, J, outside)]
    found = _PAIRS.get_many(keys)
    todo = np.array([t for t, v in enumerate(found) if v is None], dtype=np.intp)
    c, d = np.empty((len(I), 2)), np.empty(len(I))
    if todo.size:
        c[todo], d[todo] = _common_centers(bodies, I[todo], J[todo], outside[todo])
        _PAIRS.put_many((keys[t], (c[t].copy(), float(d[t]))) for t in todo)
    for t, v in enumerate(found):
        if v is not None:
            c[t], d[t] = v
    return c, d


def _far_gaps(bodies: Sequence[_Body], I: Sequence[int], W: int, centres: np.ndarray, n: int = _FAR_RAYS) -> np.ndarray:
    """:attr:`Forest.far_gap` of the workspace children ``I`` with common centres ``centres``.

    On ``n`` rays from the centre (evenly spaced directions), those whose exit from the child
    lies inside the workspace: the workspace exit distance minus the child's exit distance
    (exact ray lengths); the minimum over them (memoised per child and workspace), found coarse
    to fine (every 4th ray, then the rays next to coarse local minima). Compiled:
    :func:`navigation._geom_kernel.far_gap_rows`.
    """
    ws = bodies[W]
    keys = [("far", bodies[i].sq, ws.sq) for i in I]
    out = np.array(_PAIRS.get_many(keys), dtype=float)  # None -> nan
    todo = np.nonzero(np.isnan(out))[0]
    if todo.size:
        g = far_gap_rows(np.array([bodies[I[t]].row for t in todo]), np.asarray(centres, float)[todo], ws.row, n,
                         np.array([bodies[I[t]].pts for t in todo]))
        out[todo] = g
        _PAIRS.put_many((keys[t], float(v)) for t, v in zip(todo, g))
    return out


def _root_depth(body: _Body) -> float:
    """Depth of a squircle's own centre inside it: ``min(width, height) / 2`` exactly (the
    unit squircle's ray length is >= 1, equal to 1 along the axes, so the shortest ray from the
    centre, which is the distance to the boundary, is the shorter half-extent)."""
    return body.sq.inscribed_radius


def _clearances(parent: Sequence[int], depth: Sequence[int], roots: Sequence[int], far: np.ndarray,
                bound: np.ndarray, exact: np.ndarray, settle, wall: np.ndarray, wall_exact: np.ndarray,
                settle_walls) -> np.ndarray:
    """:attr:`Forest.clearance`: per obstacle, the minimum over its set of relevant obstacles
    (see there) of the exact distances, and of its workspace term.

    Only the distances that can be the minimum are computed: in rounds, every obstacle whose
    smallest current value (an exact distance, or a lower bound from :func:`_gap_bounds` or
    :func:`_wall_bounds`) is a bound gets that pair or wall distance settled (``settle``,
    ``settle_walls``: one batch each per round), until every minimum is exact. The result
    equals the minimum over all exact distances.
    """
    m = len(parent)
    depth = np.asarray(depth, dtype=np.intp)
    par = np.asarray(parent, dtype=np.intp)
    # relevant[i, k]: k is in obstacle i's set (roots: the other roots; others: every obstacle
    # at most as deep, except itself and its parent)
    relevant = depth[None, :] <= depth[:, None]
    relevant[np.arange(m), np.arange(m)] = False
    nonroot = np.nonzero(par != NO_PARENT)[0]
    inner = nonroot[par[nonroot] >= 0]
    relevant[inner, par[inner]] = False
    rows = np.asarray([i for i in range(m) if parent[i] == NO_PARENT], dtype=np.intp)
    if rows.size:
        relevant[rows] = False
        relevant[np.ix_(rows, np.asarray(roots, dtype=np.intp))] = True
        relevant[rows, rows] = False
    on_wall = par != WORKSPACE  # workspace term: wall (else far gap)
    idx = np.arange(m)
    while True:
        base = np.where(on_wall, wall, far)
        masked = np.where(relevant, bound, np.inf)
        k = np.argmin(masked, axis=1) if m else np.zeros(0, np.intp)
        vb = masked[idx, k]
        need = vb < base
        pairs = [(min(i, j), max(i, j)) for i, j in zip(idx[need & ~exact[idx, k]].tolist(),
                                                        k[need & ~exact[idx, k]].tolist())]
        walls = np.nonzero(~need & on_wall & ~wall_exact)[0].tolist()
        if not pairs and not walls:
            break
        settle(pairs)
        settle_walls(walls)
    return np.minimum(np.where(on_wall, wall, far), np.where(relevant, bound, np.inf).min(axis=1, initial=np.inf))


# ---------------------------------------------------------------------- construction
def _bfs_edges(adj: dict[int, list[int]], root: int):
    """Edges ``(parent, child)`` of a breadth-first search of the graph ``adj`` from ``root``,
    neighbours in increasing order (``networkx.bfs_edges(G, root, sort_neighbors=sorted)``)."""
    seen = {root}
    queue = deque([root])
    while queue:
        u = queue.popleft()
        for v in sorted(adj[u]):
            if v not in seen:
                seen.add(v)
                queue.append(v)
                yield u, v


def _eccentricity(adj: dict[int, list[int]], source: int) -> int:
    """Largest number of edges from ``source`` to a node of its (tree) component."""
    far, level, frontier, seen = 0, 0, [source], {source}
    while frontier:
        nxt = [v for u in frontier for v in adj[u] if v not in seen]
        seen.update(nxt)
        if nxt:
            level += 1
            far = level
        frontier = nxt
    return far


def _components(adj: dict[int, list[int]]) -> list[list[int]]:
    """Connected components of the graph ``adj``, each sorted, ordered by their first node."""
    seen: set[int] = set()
    out = []
    for s in adj:
        if s in seen:
            continue
        comp = [s]
        seen.add(s)
        for _, v in _bfs_edges(adj, s):
            comp.append(v)
            seen.add(v)
        out.append(sorted(comp))
    return sorted(out, key=lambda c: c[0])


def _plural(items: Sequence[int]) -> str:
    """``"0, 1 and the workspace boundary"``: input indices, ``-1`` for the boundary (last)."""
    names = [str(k) for k in sorted(items) if k != -1] + (["the workspace boundary"] if -1 in items else [])
    if len(names) == 1:
        return names[0]
    return ", ".join(names[:-1]) + " and " + names[-1]


def build_forest(workspace: Squircle, obstacles: Sequence[Squircle], *, min_gap: float = 1e-3,
                 min_overlap: float = 1e-3) -> Forest:
    """Organise ``obstacles`` inside ``workspace`` as a forest of stars (paper 001 section 4.1.2).

    Parameters
    ----------
    workspace : Squircle
        Outer boundary; the free space is inside it.
    obstacles : sequence of Squircle
        Obstacles; they may overlap each other and cross the workspace boundary.
    min_gap : float
        Smallest allowed distance between obstacles (or an obstacle and the workspace
        boundary) that do not overlap.
    min_overlap : float
        Smallest allowed depth of the common centre of an overlap.

    Returns
    -------
    Forest

    Raises
    ------
    ForestError
        With ``rule`` ``"cycle"``, ``"too-close"``, ``"shallow-overlap"`` or
        ``"covers-workspace"`` (see the module docstring); ``obstacles`` holds input indices,
        ``-1`` standing for the workspace boundary.
    TypeError
        If an obstacle is not a :class:`Squircle`.

    Examples
    --------
    >>> ws = Squircle((0.0, 0.0), 4.0, 4.0)
    >>> wall = Squircle((0.0, 0.0), 1.0, 0.2)
    >>> post = Squircle((0.5, 0.0), 0.2, 1.0)
    >>> f = build_forest(ws, [wall, post])
    >>> f.parent, f.depth, f.levels()
    ((-2, 0), (0, 1), [(1,)])
    """
    return _build(workspace, obstacles, min_gap, min_overlap, full=True)


def check_forest(workspace: Squircle, obstacles: Sequence[Squircle], *, min_gap: float = 1e-3,
                 min_overlap: float = 1e-3) -> None:
    """Raise the :class:`~navigation.errors.ForestError` (or ``TypeError``) that
    :func:`build_forest` would raise for these arguments, else return ``None``.

    Runs the same tests in the same order, and stops before the terms only the navigation
    function needs (:attr:`Forest.far_gap`, :attr:`Forest.clearance`), which cannot refuse a
    configuration; for a map that only needs to know whether the forest construction accepts it
    (perception's forest check). What it computes is memoised as by :func:`build_forest`.
    """
    _build(workspace, obstacles, min_gap, min_overlap, full=False)


def _build(workspace, obstacles, min_gap, min_overlap, *, full: bool) -> Forest | None:
    """:func:`build_forest` (``full``) or :func:`check_forest`."""
    if not isinstance(workspace, Squircle):
        raise TypeError(f"workspace must be a Squircle, got {type(workspace).__name__}")
    obstacles = tuple(obstacles)
    for k, o in enumerate(obstacles):
        if not isinstance(o, Squircle):
            raise TypeError(f"obstacles[{k}] must be a Squircle, got {type(o).__name__}")
    min_gap, min_overlap = float(min_gap), float(min_overlap)
    if not (math.isfinite(min_gap) and min_gap >= 0 and math.isfinite(min_overlap) and min_overlap >= 0):
        raise ValueError(f"min_gap and min_overlap must be finite and >= 0, got {min_gap}, {min_overlap}")

    n = len(obstacles)
    bodies = _bodies(obstacles, _SAMPLES)
    W = n  # body index of the workspace
    bodies.append(_bodies([workspace], _WS_SAMPLES)[0])

    # --- relation of every obstacle to the workspace boundary
    dropped: dict[int, str] = {}
    crossing: set[int] = set()
    for k, rel in enumerate(_workspace_relations(bodies[:n], bodies[W])):
        if rel == "covers":
            raise ForestError(f"obstacle {k} covers the whole workspace: there is no free space",
                              obstacles=(k,), rule="covers-workspace")
        if rel == "outside":
            dropped[k] = "entirely outside the workspace"
        elif rel == "crosses-twice":
            raise ForestError(f"obstacle {k} crosses the workspace boundary more than once, which closes "
                              f"a cycle through the workspace boundary (a wall may touch the boundary only "
                              f"at one place)", obstacles=(k, -1), rule="cycle")
        elif rel == "crosses":
            crossing.add(k)

    # --- candidate pairs (bounding circles), exact overlap and containment
    live = [k for k in range(n) if k not in dropped]
    overlaps: set[tuple[int, int]] = set()
    if len(live) > 1:
        cs = np.array([obstacles[k].center for k in live])
        rs = np.array([bodies[k].radius for k in live])
        margin = max(min_gap, 1e-9) * 2.0
        A, B = _triu(len(live))
        near = np.hypot(cs[A, 0] - cs[B, 0], cs[A, 1] - cs[B, 1]) <= rs[A] + rs[B] + margin
        cand = [(live[a], live[b]) for a, b in zip(A[near].tolist(), B[near].tolist())]
        rels = _pair_relations([bodies[i] for i, _ in cand], [bodies[j] for _, j in cand])
        for (i, j), rel in zip(cand, rels):
            if rel is None:
                continue
            overlaps.add((i, j))
            # containment (redundant obstacles): j inside i, or i inside j
            if rel == "second-inside":
                dropped.setdefault(j, f"contained in obstacle {i}")
            elif rel == "first-inside":
                dropped.setdefault(i, f"contained in obstacle {j}")

    keep = [k for k in range(n) if k not in dropped]
    m = len(keep)
    new = {k: a for a, k in enumerate(keep)}
    edges = sorted((new[i], new[j]) for i, j in overlaps if i in new and j in new)
    ws_children = sorted(new[k] for k in crossing if k in new)

    # --- rule: the overlap graph must be a forest
    adj: dict[int, list[int]] = {v: [] for v in range(m)}
    adj[WORKSPACE] = []
    for a, b in edges + [(WORKSPACE, i) for i in ws_children]:
        adj[a].append(b)
        adj[b].append(a)
    comps = _components(adj)
    if len(edges) + len(ws_children) > m + 1 - len(comps):  # more edges than a forest has: a cycle
        G = nx.Graph()
        G.add_nodes_from(adj)
        G.add_edges_from(edges)
        G.add_edges_from((WORKSPACE, i) for i in ws_children)
        cycles = nx.cycle_basis(G)
        cyc = min(cycles, key=lambda c: (len(c), sorted(c)))
        if WORKSPACE in cyc:  # start the cycle at the workspace for a readable message
            r = cyc.index(WORKSPACE)
            cyc = cyc[r:] + cyc[:r]
        ids = [keep[i] if i != WORKSPACE else -1 for i in cyc]
        path = "-".join("ws" if k == -1 else str(k) for k in ids + ids[:1])
        obst = sorted(k for k in ids if k != -1)
        raise ForestError(f"obstacles {_plural(ids)} overlap in a cycle ({path}); overlapping "
                          f"obstacles must form trees, and each tree may touch the workspace boundary at "
                          f"most once", obstacles=tuple(obst) + ((-1,) if -1 in ids else ()), rule="cycle")

    # --- distances: lower bounds for every pair, exact where a rule needs them
    rows = np.array([bodies[k].row for k in keep]) if m else np.zeros((0, 7))
    bound = _gap_bounds(rows)
    exact = np.zeros((m, m), bool)
    edge_set = set(edges)
    for a, b in edges:
        bound[a, b] = bound[b, a] = 0.0
        exact[a, b] = exact[b, a] = True
    np.fill_diagonal(exact, True)

    def settle(pairs) -> None:
        """Replace the bounds of ``pairs`` (``a < b``) by exact distances (memoised)."""
        pairs = sorted({p for p in pairs if not exact[p]})
        if pairs:
            A, B = np.array(pairs).T
            d = _distances(bodies, np.array([keep[a] for a in A]), np.array([keep[b] for b in B]))
            bound[A, B] = bound[B, A] = d
            exact[A, B] = exact[B, A] = True

    I, J = _triu(m)
    near_pairs = bound[I, J] < min_gap
    I, J = I[near_pairs], J[near_pairs]
    settle((a, b) for a, b in zip(I, J) if (a, b) not in edge_set)
    wall = np.zeros(m)
    wall_exact = np.ones(m, bool)
    inner = [a for a in range(m) if a not in set(ws_children)]
    if inner:
        wall[inner] = _wall_bounds(rows[inner], bodies[W])
        wall_exact[inner] = False

    def settle_walls(idx) -> None:
        """Replace the wall bounds of obstacles ``idx`` by exact distances (memoised)."""
        idx = np.array(sorted({a for a in idx if not wall_exact[a]}), dtype=np.intp)
        if idx.size:
            wall[idx] = _distances(bodies, np.array([keep[a] for a in idx]), np.full(idx.size, W))
            wall_exact[idx] = True

    settle_walls(a for a in inner if wall[a] < min_gap)

    close = [(a, b, bound[a, b]) for a, b in zip(I, J) if (a, b) not in edge_set and bound[a, b] < min_gap]
    if close:
        a, b, v = min(close, key=lambda t: t[2])
        raise ForestError(f"obstacles {keep[a]} and {keep[b]} are {v:.3g} m apart without overlapping "
                          f"(closer than min_gap = {min_gap:g} m): separate them or make them overlap",
                          obstacles=(keep[a], keep[b]), rule="too-close")
    near_wall = [a for a in inner if wall[a] < min_gap]
    if near_wall:
        a = min(near_wall, key=lambda t: wall[t])
        raise ForestError(f"obstacle {keep[a]} is {wall[a]:.3g} m from the workspace boundary without "
                          f"crossing it (closer than min_gap = {min_gap:g} m)",
                          obstacles=(keep[a], -1), rule="too-close")

    # --- trees, roots, parents, depths
    parent = [NO_PARENT] * m
    depth = [0] * m
    tree_of = [0] * m
    roots: list[int] = []
    interior = [c for c in comps if WORKSPACE not in c]

    def orient(root: int, tree_id: int) -> None:
        """Parents and depths by breadth-first search from ``root`` (the workspace: depth 0)."""
        for u, v in _bfs_edges(adj, root):
            parent[v] = u
            depth[v] = (0 if u == WORKSPACE else depth[u]) + 1
            tree_of[v] = tree_id

    orient(WORKSPACE, -1)
    for t, comp in enumerate(interior):
        if len(comp) == 1:
            root = comp[0]
        else:
            ecc = {i: _eccentricity(adj, i) for i in comp}
            low = min(ecc.values())
            centre = [i for i in comp if ecc[i] == low]  # a tree's centre: one or two members
            # ties: the larger area (rounded: equal shapes tie exactly), then the lower index
            root = centre[0] if len(centre) == 1 else \
                min(centre, key=lambda i: (-round(obstacles[keep[i]].area, 9), i))
        roots.append(root)
        tree_of[root] = t
        orient(root, t)
    children = [[] for _ in range(m)]
    for i, p in enumerate(parent):
        if p >= 0:
            children[p].append(i)

    # --- common centres and their depths
    center = np.zeros((m, 2))
    cdepth = np.zeros(m)
    nonroot = [i for i in range(m) if parent[i] != NO_PARENT]
    if nonroot:
        I = np.array([keep[i] for i in nonroot])
        J = np.array([W if parent[i] == WORKSPACE else keep[parent[i]] for i in nonroot])
        c, d = _centers(bodies, I, J, J == W)
        center[nonroot], cdepth[nonroot] = c, d
    if roots:
        center[roots] = np.array([obstacles[keep[r]].center for r in roots])
        cdepth[roots] = [_root_depth(bodies[keep[r]]) for r in roots]
    shallow = [i for i in nonroot if cdepth[i] < min_overlap]
    if shallow:
        i = min(shallow, key=lambda t: cdepth[t])
        other = -1 if parent[i] == WORKSPACE else keep[parent[i]]
        what = ("crosses the workspace boundary" if other == -1 else f"overlaps obstacle {other}")
        raise ForestError(f"obstacle {keep[i]} {what} only by a grazing contact (the intersection is "
                          f"{max(cdepth[i], 0.0):.3g} m deep, less than min_overlap = {min_overlap:g} m): "
                          f"separate them or make them overlap more", obstacles=(keep[i], other),
                          rule="shallow-overlap")
    if not full:
        return None

    far = np.full(m, np.inf)
    ws_kids = [i for i in nonroot if parent[i] == WORKSPACE]
    if ws_kids:
        far[ws_kids] = _far_gaps(bodies, [keep[i] for i in ws_kids], W, center[ws_kids])
    clearance = _clearances(parent, depth, roots, far, bound, exact, settle, wall, wall_exact, settle_walls)
    for arr in (center, cdepth, far, clearance):
        arr.flags.writeable = False
    return Forest(
        workspace=workspace,
        obstacles=tuple(obstacles[k] for k in keep),
        source_index=tuple(keep),
        dropped=tuple(sorted(dropped.items())),
        parent=tuple(parent),
        children=tuple(tuple(c) for c in children),
        depth=tuple(depth),
        roots=tuple(roots),
        tree_of=tuple(tree_of),
        center=center,
        center_depth=cdepth,
        far_gap=far,
        clearance=clearance,
    )
