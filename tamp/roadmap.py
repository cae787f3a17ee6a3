"""Visibility roadmap of a squircle world: the vertex set ``V`` and free-vicinity edges of the
harmonic trees (paper 001 section 4.1.1, eq. 7) and its trimming / regeneration when obstacles
are discovered (section 4.2.3, steps I and II).

The paper generates the vertices of every tree ``T_{g -> g'} = (V, B, gamma, (v_0, v_G))`` "by
the visibility graph from Huang and Chung (2004) ... and a safety buffer of 0.15 m" and connects
"any vertex ... to all vertices within its free vicinity". Every tree of one world shares these
positions and edges; only the terminals ``v_0``, ``v_G`` and the headings differ, so they are
built once per obstacle set here and :mod:`tamp.harmonic_tree` adds terminals, headings, edge
costs (eq. 26) and A* (eq. 8).

Safety notion
-------------
The robot is a disc of radius ``r``; the buffer is ``b``. A point or segment is *safe* when it
stays at Euclidean distance ``>= r + b`` from every obstacle and ``>= r + b_W`` from the
workspace boundary, i.e. at clearance ``>= b`` (``b_W``) in the robot's configuration space
(obstacles inflated by ``r``). ``b_W = b`` unless ``RoadmapConfig.boundary_buffer`` says
otherwise: the paper's buffer is one number, and a caller whose boundary is known exactly while
its obstacles are estimates (the executive) may keep a smaller margin from the boundary.
This is certified exactly, without sampling: every obstacle ``O_j`` is replaced by the squircle
``G_j = O_j.grow_snug(r + b)``, which contains ``O_j`` grown by ``r + b``
(:meth:`navigation.Squircle.grow_snug`: since the thirty-seventh session a rounder ``s`` where
that reaches less far beyond the neighbourhood; :meth:`~navigation.Squircle.grow`, which keeps
``s``, reached ``(sqrt 2 - 1)(r + b)`` beyond it at sharp corners and closed passages between a
corner and another shape that the buffer leaves open), and the workspace by
``W' = W.grow(-(r + b_W))``. Squircles are convex (``beta + 1`` is the square of a norm), so

* a segment avoids ``G_j`` iff ``min_t beta_j(a + t (b - a)) > 0``; ``beta_j`` is convex along
  the segment, and the minimum is bracketed by bisection on the sign of its exact derivative
  with the certified lower bound ``max(f(lo) + f'(lo) (hi - lo), f(hi) - f'(hi) (hi - lo))``
  (tangent lines of a convex function); undecided segments count as blocked;
* a segment lies in ``W'`` iff both its ends do.

The test is per (segment, obstacle) pair, so "safe against the old and the new obstacles" is
the same verdict as "safe against all of them": trimming after a discovery gives exactly the
roadmap built from scratch (tested).

Vertices
--------
For each ``G_j``, ``vertices_per_obstacle`` boundary points at normalised angles
``psi_k = 2 pi k / n`` (with ``n`` a multiple of 8 these include the four corners of a rounded
rectangle, the vertices of its visibility graph, and the four side midpoints), each pushed
``offset`` metres along the outward normal (so it lies at distance ``offset`` from ``G_j``:
edges can leave it). A vertex is kept when it is outside every ``G_k`` and inside ``W'``.
Optional extra candidates (potential-biased regeneration, :func:`descent_candidates`) are kept
under the same rule.

Narrow passages
---------------
The boundary vertices sit ``offset`` from their ``G_j``; in a passage narrower than that
between two ``G_j`` (or a ``G_j`` and ``W'``) they fall inside the other one, and no vertex
may see through it although the free space is connected there (seen on a random world: the
fallback roadmap had the region ``r1`` in a component of its own while a 1 cm grid of the same
free space joined it to the robot, and the executive stopped, blocked, for good).
:meth:`Roadmap.gap_candidates` returns points along the middle of every passage narrower
than ``max_gap`` (midpoints between the facing boundaries), out to where it widens and the
boundary vertices see them; ``with_obstacles(extra=...)`` adds the safe ones. The executive
does so when no roadmap has a path (docs/harmonic_trees.md).

Symbols
-------
=========================  ===========================================================
``r``                      robot radius (inflation), m
``b``                      safety buffer (paper: 0.15 m), m
``G_j``                    obstacle ``j`` grown by ``r + b``
``b_W``                    buffer from the workspace boundary (default ``b``), m
``W'``                     workspace shrunk by ``r + b_W``
``V``                      vertex positions ``(n_V, 2)``
``pairs``                  visible vertex pairs ``(n_E, 2)``, ``i < j``
=========================  ===========================================================
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from navigation.errors import WorldError
from navigation.geometry import Squircle, beta_rows, pack

from ._segment_kernel import segments_clear_rows
from .errors import TampError

__all__ = ["RoadmapConfig", "Roadmap", "segments_clear", "descent_candidates", "grown"]

_BISECTION_STEPS = 60
_CHUNK = 200_000  # (segment, obstacle) pairs evaluated at once


@dataclass(frozen=True, slots=True)
class RoadmapConfig:
    """Parameters of the visibility roadmap.

    Parameters
    ----------
    buffer : float
        Safety buffer ``b`` beyond the robot-inflated obstacles (m); paper 001 uses 0.15.
    offset : float
        Distance of a vertex outside its buffered obstacle ``G_j`` (m), > 0 so that edges can
        leave it.
    vertices_per_obstacle : int
        Boundary vertices per obstacle, a positive multiple of 4 (8 includes the corners);
        doubled for an obstacle until the chords between neighbouring vertices miss it.
    vicinity : float
        Longest edge (m): the "free vicinity" of a vertex; ``inf`` connects every visible pair.
    boundary_buffer : float or None
        Buffer ``b_W`` from the workspace boundary (m); ``None``: ``buffer``.
    """

    buffer: float = 0.15
    offset: float = 0.05
    vertices_per_obstacle: int = 8
    vicinity: float = math.inf
    boundary_buffer: float | None = None

    @property
    def wall_buffer(self) -> float:
        """``b_W``: the buffer kept from the workspace boundary."""
        return self.buffer if self.boundary_buffer is None else self.boundary_buffer

    def __post_init__(self):
        for name in ("buffer", "offset", "vicinity"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or math.isnan(v):
                raise TampError(f"RoadmapConfig.{name} must be a number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if not (math.isfinite(self.buffer) and self.buffer >= 0):
            raise TampError(f"RoadmapConfig.buffer must be finite and >= 0, got {self.buffer}")
        if not (math.isfinite(self.offset) and self.offset > 0):
            raise TampError(f"RoadmapConfig.offset must be finite and > 0, got {self.offset}")
        if not self.vicinity > 0:
            raise TampError(f"RoadmapConfig.vicinity must be > 0, got {self.vicinity}")
        bw = self.boundary_buffer
        if bw is not None:
            if isinstance(bw, bool) or not isinstance(bw, (int, float)) or not (math.isfinite(bw) and bw >= 0):
                raise TampError(f"RoadmapConfig.boundary_buffer must be None or a finite number >= 0, got {bw!r}")
            object.__setattr__(self, "boundary_buffer", float(bw))
        n = self.vertices_per_obstacle
        if isinstance(n, bool) or not isinstance(n, int) or n < 4 or n % 4:
            raise TampError(f"RoadmapConfig.vertices_per_obstacle must be a positive multiple of 4, got {n!r}")


def grown(sq: Squircle, amount: float) -> Squircle:
    """``sq.grow_snug(amount)`` (memoised; :meth:`Squircle.grow` when shrinking) with a
    :class:`WorldError` on failure.

    Raises
    ------
    WorldError
        The squircle cannot be shrunk that much (``amount < 0``).
    """
    try:
        return sq.grow_snug(amount)
    except ValueError as err:
        raise WorldError(f"cannot grow {sq} by {amount:g}: {err}", "workspace") from None


# ---------------------------------------------------------------------- exact segment tests
def _point_segment_distance(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances ``(K, M)`` from centres ``c (M, 2)`` to segments ``[a, b] (K, 2)``."""
    return np.sqrt(_point_segment_distance2(c, a, b))


def _point_segment_distance2(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Squared distances ``(K, M)`` from centres ``c (M, 2)`` to segments ``[a, b] (K, 2)``
    (component arrays, no ``(K, M, 2)`` temporaries)."""
    dx, dy = (b[:, 0] - a[:, 0])[:, None], (b[:, 1] - a[:, 1])[:, None]
    dd = dx * dx + dy * dy
    rx = c[None, :, 0] - a[:, 0][:, None]
    ry = c[None, :, 1] - a[:, 1][:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(dd > 0, (rx * dx + ry * dy) / np.where(dd > 0, dd, 1.0), 0.0)
    np.clip(t, 0.0, 1.0, out=t)
    fx = rx - t * dx
    fy = ry - t * dy
    return fx * fx + fy * fy


def segments_clear(P: np.ndarray, a, b) -> np.ndarray:
    """True where segment ``[a_k, b_k]`` misses every squircle of the packed rows ``P (M, 7)``.

    Parameters
    ----------
    P : (M, 7) array
        Packed squircles (:func:`navigation.geometry.pack`), e.g. the buffered obstacles ``G_j``.
    a, b : (K, 2) arrays
        Segment ends.

    Returns
    -------
    (K,) bool
        Exact (up to rounding, conservative when undecided) per the module docstring. The
        workspace is not checked here: by convexity a segment is inside it iff its ends are.
        Compiled: :func:`tamp._segment_kernel.segments_clear_rows`, pair by pair.
    """
    return segments_clear_rows(P, a, b, _BISECTION_STEPS)


# ---------------------------------------------------------------------- roadmap
_MAX_VERTICES = 64  # boundary vertices of one obstacle at most (see _boundary_vertices)


def _boundary_vertices(G: Squircle, n: int, offset: float) -> np.ndarray:
    """``n`` points at normalised angles ``2 pi k / n`` on ``G``, pushed ``offset`` outwards, with
    ``n`` doubled (up to ``_MAX_VERTICES``) until every chord between neighbouring points misses
    ``G``: around a large rounded obstacle (an ellipse of 1 m semi-axis: sagitta of a 45 degree
    arc 0.076 m > offset 0.05 m) the 8 points' chords cut through it, and the roadmap could
    not go around it. Memoised per (squircle, n, offset)."""
    return _boundary_vertices_cached(G, int(n), float(offset)).copy()


@functools.lru_cache(maxsize=4096)
def _boundary_vertices_cached(G: Squircle, n: int, offset: float) -> np.ndarray:
    P = pack([G])
    while True:
        pts = G.point_at(2.0 * np.pi * np.arange(n) / n)
        normal = G.gradient(pts)
        normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        pts = pts + offset * normal
        if n >= _MAX_VERTICES or segments_clear(P, pts, np.roll(pts, -1, axis=0)).all():
            return pts
        n *= 2


def _outside_all(P: np.ndarray, ws: Squircle, pts: np.ndarray) -> np.ndarray:
    """Points strictly outside every row of ``P`` and strictly inside ``ws``."""
    if len(pts) == 0:
        return np.zeros(0, dtype=bool)
    ok = ws.beta(pts) < 0
    if len(P):
        ok &= np.all(beta_rows(P[None, :, :], pts[:, None, 0], pts[:, None, 1]) > 0, axis=1)
    return ok


@dataclass(frozen=True, slots=True, eq=False)
class Roadmap:
    """Visibility roadmap shared by every harmonic tree of one obstacle set (immutable).

    Build with :meth:`build` or :meth:`from_world`; revise with :meth:`with_obstacles`.

    Attributes
    ----------
    workspace : Squircle
        The true workspace.
    obstacles : tuple of Squircle
        The true (not inflated) obstacles the roadmap avoids.
    radius : float
        Robot radius ``r``.
    config : RoadmapConfig
    buffered : tuple of Squircle
        ``G_j = obstacles[j].grow_snug(r + b)``.
    free_workspace : Squircle
        ``W' = workspace.grow(-(r + b_W))``.
    P : (M, 7) array
        ``pack(buffered)``.
    points : (n_V, 2) array
        Vertex positions.
    owner : (n_V,) int array
        Obstacle index a vertex was generated from, ``-1`` for extra (biased) candidates.
    pairs : (n_E, 2) int array
        Visible pairs ``i < j`` (segment safe and no longer than ``vicinity``).
    """

    workspace: Squircle
    obstacles: tuple
    radius: float
    config: RoadmapConfig
    buffered: tuple
    free_workspace: Squircle
    P: np.ndarray
    points: np.ndarray
    owner: np.ndarray
    pairs: np.ndarray
    _adj: tuple = field(repr=False)
    _memo: dict = field(default_factory=dict, repr=False)  # per-roadmap tables of the searches

    # ------------------------------------------------------------------ construction
    @classmethod
    def build(cls, workspace: Squircle, obstacles, radius: float = 0.0, config: RoadmapConfig | None = None,
              extra=None) -> "Roadmap":
        """Roadmap of ``obstacles`` in ``workspace`` for a robot of ``radius``.

        Parameters
        ----------
        extra : (K, 2) array, optional
            Additional candidate vertices (e.g. :func:`descent_candidates`), kept when safe.

        Raises
        ------
        WorldError
            ``radius`` negative or the workspace too small for ``radius + boundary buffer``.
        """
        config = RoadmapConfig() if config is None else config
        radius = float(radius)
        if not (math.isfinite(radius) and radius >= 0):
            raise WorldError(f"robot radius must be finite and >= 0, got {radius}", "robot.radius")
        obstacles = tuple(obstacles)
        amount = radius + config.buffer
        wall = radius + config.wall_buffer
        ws = grown(workspace, -wall) if wall > 0 else workspace
        G = tuple(grown(o, amount) if amount > 0 else o for o in obstacles)
        P = pack(G) if G else np.zeros((0, 7))
        pts, owner = cls._candidates(G, range(len(G)), config)
        pts, owner = cls._with_extra(pts, owner, extra)
        keep = _outside_all(P, ws, pts)
        pts, owner = pts[keep], owner[keep]
        n = len(pts)
        i, j = np.triu_indices(n, 1)
        pairs = cls._visible(P, pts, i, j, config.vicinity)
        return cls._make(workspace, obstacles, radius, config, G, ws, P, pts, owner, pairs)

    @classmethod
    def from_world(cls, world, config: RoadmapConfig | None = None, *, known_only: bool = False,
                   extra=None) -> "Roadmap":
        """Roadmap of a :class:`navigation.World`: all its obstacles, or only the known ones."""
        obstacles = world.known if known_only else world.obstacles
        return cls.build(world.workspace, obstacles, world.robot.radius, config, extra)

    @staticmethod
    def _candidates(G, indices, config):
        pts = [np.zeros((0, 2))]
        owner = [np.zeros(0, dtype=np.intp)]
        n = config.vertices_per_obstacle
        for k in indices:
            pts.append(_boundary_vertices(G[k], n, config.offset))
            owner.append(np.full(len(pts[-1]), k, dtype=np.intp))
        return np.concatenate(pts), np.concatenate(owner)

    @staticmethod
    def _with_extra(pts, owner, extra):
        if extra is None:
            return pts, owner
        extra = np.asarray(extra, dtype=float).reshape(-1, 2)
        if not np.all(np.isfinite(extra)):
            raise TampError("extra candidate vertices must be finite")
        return np.concatenate([pts, extra]), np.concatenate([owner, np.full(len(extra), -1, dtype=np.intp)])

    @staticmethod
    def _visible(P, pts, i, j, vicinity) -> np.ndarray:
        i, j = np.asarray(i, dtype=np.intp), np.asarray(j, dtype=np.intp)
        if vicinity < math.inf:
            near = np.linalg.norm(pts[i] - pts[j], axis=1) <= vicinity
            i, j = i[near], j[near]
        ok = segments_clear(P, pts[i], pts[j])
        return np.stack([i[ok], j[ok]], axis=1) if ok.any() else np.zeros((0, 2), dtype=np.intp)

    @classmethod
    def _make(cls, workspace, obstacles, radius, config, G, ws, P, pts, owner, pairs) -> "Roadmap":
        n = len(pts)
        pairs = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
        if len(pairs):
            order = np.lexsort((pairs[:, 1], pairs[:, 0]))
            pairs = pairs[order]
        src = np.concatenate([pairs[:, 0], pairs[:, 1]])
        dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
        order = np.argsort(src, kind="stable")
        src, dst = src[order], dst[order]
        indptr = np.searchsorted(src, np.arange(n + 1))
        vec = pts[dst] - pts[src]
        length = np.hypot(vec[:, 0], vec[:, 1])
        angle = np.arctan2(vec[:, 1], vec[:, 0])
        return cls(workspace, tuple(obstacles), float(radius), config, tuple(G), ws, P, pts, owner, pairs,
                   (indptr, dst, length, angle))

    # ------------------------------------------------------------------ queries
    def neighbours(self, i: int):
        """``(j, length, angle)`` arrays of the vertices visible from vertex ``i``
        (``angle`` is the direction of ``points[j] - points[i]``)."""
        indptr, dst, length, angle = self._adj
        s = slice(indptr[i], indptr[i + 1])
        return dst[s], length[s], angle[s]

    def graph(self):
        """The roadmap as a ``scipy.sparse.csr_matrix`` ``(n_V, n_V)`` of edge lengths, both
        directions of every visible pair (for ``scipy.sparse.csgraph``)."""
        from scipy.sparse import csr_matrix

        indptr, dst, length, _ = self._adj
        n = len(self.points)
        return csr_matrix((length, dst, indptr), shape=(n, n))

    def safe_points(self, q) -> np.ndarray:
        """True where the points ``q (K, 2)`` are outside every ``G_j`` and inside ``W'``."""
        return _outside_all(self.P, self.free_workspace, np.asarray(q, dtype=float).reshape(-1, 2))

    def visible(self, a, b) -> np.ndarray:
        """True where the segments ``[a_k, b_k]`` are safe (ends inside ``W'``, no ``G_j`` hit)."""
        a = np.asarray(a, dtype=float).reshape(-1, 2)
        b = np.asarray(b, dtype=float).reshape(-1, 2)
        ok = (self.free_workspace.beta(a) < 0) & (self.free_workspace.beta(b) < 0)
        return ok & segments_clear(self.P, a, b)

    def gap_candidates(self, max_gap: float = 0.15, samples: int = 96, spacing: float = 0.02) -> np.ndarray:
        """Candidate vertices along the narrow passages of the roadmap's free space (``extra``
        for :meth:`with_obstacles`; module doc, "Narrow passages"): for every boundary sample
        of a buffered obstacle ``G_j`` (``samples`` per obstacle) less than ``max_gap`` from
        another ``G_k`` or from the boundary of the shrunk workspace ``W'``, the midpoint
        between it and the nearest point there (the nearest of ``G_k``'s samples; the foot of
        ``W'``'s exact distance along its normal). The midpoints run along the passage and out
        of its mouths, where the boundary vertices see them. One candidate per ``spacing``
        cell, ``(K, 2)``, not checked for safety (:meth:`with_obstacles` keeps the safe ones)."""
        if not (max_gap > 0 and spacing > 0 and samples >= 3):
            raise TampError(f"gap_candidates: need max_gap > 0, spacing > 0, samples >= 3 "
                            f"(got {max_gap}, {spacing}, {samples})")
        G, ws = self.buffered, self.free_workspace
        if not G:
            return np.zeros((0, 2))
        B = np.stack([g.boundary_points(samples) for g in G])  # (m, S, 2)
        centre = B.mean(axis=1)
        reach = np.linalg.norm(B - centre[:, None, :], axis=2).max(axis=1)
        mids = [np.zeros((0, 2))]
        # obstacle - obstacle (bounding circles within max_gap): each sample and its nearest
        j, k = np.nonzero(np.linalg.norm(centre[:, None] - centre[None], axis=2) - reach[:, None] - reach[None]
                          <= max_gap)
        for a_i, b_i in zip(j, k):
            if a_i == b_i:
                continue
            d = np.linalg.norm(B[a_i][:, None, :] - B[b_i][None, :, :], axis=2)
            v = np.argmin(d, axis=1)
            near = d[np.arange(samples), v] <= max_gap
            mids.append(0.5 * (B[a_i][near] + B[b_i][v[near]]))
        # obstacle - boundary of W': each sample near it and its foot along W's normal
        flat = B.reshape(-1, 2)
        dist = -np.asarray(ws.distance(flat), dtype=float).reshape(-1)
        near = (dist > 0.0) & (dist <= max_gap)
        if near.any():
            n = np.asarray(ws.gradient(flat[near]), dtype=float).reshape(-1, 2)
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
            mids.append(flat[near] + 0.5 * dist[near, None] * n)
        m = np.concatenate(mids)
        if not len(m):
            return m
        _, first = np.unique(np.floor(m / spacing).astype(np.int64), axis=0, return_index=True)
        return m[np.sort(first)]

    # ------------------------------------------------------------------ revision (4.2.3)
    def with_obstacles(self, new, extra=None) -> "Roadmap":
        """The roadmap after discovering the obstacles ``new`` (paper 001 section 4.2.3 I-II).

        (I) Trimming: vertices inside a new buffered obstacle and edges whose segment hits one
        are removed; every other edge is kept without re-checking (the test is per obstacle).
        (II) Regeneration: the boundary vertices of the new obstacles and the ``extra``
        candidates (potential-biased, e.g. :func:`descent_candidates`) are added when safe and
        connected to every visible vertex.

        Without ``extra`` the result equals ``Roadmap.build`` on ``obstacles + new`` (same
        vertices in the same order, same edges).
        """
        new = tuple(new)
        for k, o in enumerate(new):
            if not isinstance(o, Squircle):
                raise TampError(f"new obstacles[{k}]: expected a navigation.Squircle, got {type(o).__name__}")
        if not new and extra is None:
            return self
        amount = self.radius + self.config.buffer
        G_new = tuple(grown(o, amount) if amount > 0 else o for o in new)
        P_new = pack(G_new) if G_new else np.zeros((0, 7))
        m_old = len(self.buffered)
        G = self.buffered + G_new
        P = np.concatenate([self.P, P_new])
        # (I) trimming: old vertices and old edges against the new obstacles only
        keep = _outside_all(P_new, self.free_workspace, self.points)
        old_index = np.full(len(self.points), -1, dtype=np.intp)
        old_index[keep] = np.arange(int(keep.sum()))
        pairs = self.pairs[keep[self.pairs[:, 0]] & keep[self.pairs[:, 1]]] if len(self.pairs) else self.pairs
        if len(pairs) and len(P_new):
            pairs = pairs[segments_clear(P_new, self.points[pairs[:, 0]], self.points[pairs[:, 1]])]
        pairs = old_index[pairs]
        pts_old, owner_old = self.points[keep], self.owner[keep]
        # (II) regeneration: the new obstacles' vertices, then the biased extras
        cand, cowner = self._candidates(G, range(m_old, len(G)), self.config)
        cand, cowner = self._with_extra(cand, cowner, extra)
        ok = _outside_all(P, self.free_workspace, cand)
        cand, cowner = cand[ok], cowner[ok]
        n_old, n_new = len(pts_old), len(cand)
        pts = np.concatenate([pts_old, cand])
        owner = np.concatenate([owner_old, cowner])
        # new-old and new-new pairs against every obstacle
        ii, jj = np.meshgrid(np.arange(n_old + n_new), np.arange(n_old, n_old + n_new), indexing="ij")
        sel = ii < jj
        new_pairs = self._visible(P, pts, ii[sel], jj[sel], self.config.vicinity)
        all_pairs = np.concatenate([pairs.reshape(-1, 2), new_pairs])
        return self._make(self.workspace, self.obstacles + new, self.radius, self.config, G,
                          self.free_workspace, P, pts, owner, all_pairs)


    def without_obstacles(self, indices) -> "Roadmap":
        """The roadmap with the obstacles ``self.obstacles[k]``, ``k`` in ``indices``, removed (an
        estimate that perception replaced or dropped).

        Every vertex and edge of ``self`` that does not belong to a removed obstacle stays valid
        (it was safe against a superset). What the removed obstacles hid is added back: the
        boundary vertices of the remaining obstacles that lay inside a removed ``G_j``, their
        visible pairs, and the pairs between remaining vertices whose segment comes near a
        removed ``G_j`` (within its bounding circle) and is safe now. Without extra candidates
        the result has the vertices and edges of ``Roadmap.build`` on the remaining obstacles
        (in another vertex order); extra candidates a removed obstacle had rejected are not
        recovered.
        """
        gone = np.zeros(len(self.obstacles), dtype=bool)
        gone[np.asarray(list(indices), dtype=np.intp)] = True
        if not gone.any():
            return self
        kept = np.nonzero(~gone)[0]
        remap = np.full(len(self.obstacles), -1, dtype=np.intp)
        remap[kept] = np.arange(len(kept))
        G = tuple(self.buffered[k] for k in kept)
        P = self.P[kept]
        P_gone = self.P[gone]
        # vertices: drop the removed obstacles' own, keep the others (owners renumbered)
        keep = (self.owner < 0) | ~gone[np.maximum(self.owner, 0)]
        old_index = np.full(len(self.points), -1, dtype=np.intp)
        old_index[keep] = np.arange(int(keep.sum()))
        pts_old = self.points[keep]
        owner_old = np.where(self.owner[keep] >= 0, remap[np.maximum(self.owner[keep], 0)], -1)
        pairs = self.pairs[keep[self.pairs[:, 0]] & keep[self.pairs[:, 1]]] if len(self.pairs) else self.pairs
        pairs = old_index[pairs].reshape(-1, 2)
        # vertices the removed obstacles hid: candidates of the remaining obstacles that are safe
        # now and lie inside a removed G_j (the others were kept before or are still unsafe)
        # (only obstacles whose buffered bounding circle meets a removed one's can have such)
        rk = np.hypot(P[:, 4], P[:, 5]) + self.config.offset
        rg = np.hypot(P_gone[:, 4], P_gone[:, 5])
        gap = np.linalg.norm(P[:, None, :2] - P_gone[None, :, :2], axis=2)
        near_gone = np.nonzero(np.any(gap <= rk[:, None] + rg[None, :], axis=1))[0]
        cand, cowner = self._candidates(G, near_gone, self.config)
        hidden = np.zeros(len(cand), dtype=bool)
        if len(cand):
            hidden = np.any(beta_rows(P_gone[None, :, :], cand[:, None, 0], cand[:, None, 1]) <= 0, axis=1)
        ok = hidden & _outside_all(P, self.free_workspace, cand)
        cand, cowner = cand[ok], cowner[ok]
        n_old, n_new = len(pts_old), len(cand)
        pts = np.concatenate([pts_old, cand])
        owner = np.concatenate([owner_old, cowner])
        # old-old pairs that were not visible and pass near a removed obstacle: test again
        i, j = np.triu_indices(n_old, 1)
        if len(pairs):
            is_pair = np.zeros((n_old, n_old), dtype=bool)
            is_pair[pairs[:, 0], pairs[:, 1]] = True
            sel = ~is_pair[i, j]
            i, j = i[sel], j[sel]
        if len(i):
            radius = np.hypot(P_gone[:, 4], P_gone[:, 5])
            near = np.zeros(len(i), dtype=bool)
            step = max(1, _CHUNK // len(P_gone))
            for lo in range(0, len(i), step):
                hi = min(len(i), lo + step)
                d2 = _point_segment_distance2(P_gone[:, :2], pts_old[i[lo:hi]], pts_old[j[lo:hi]])
                near[lo:hi] = np.any(d2 <= ((radius * (1.0 + 1e-9)) ** 2)[None, :], axis=1)
            i, j = i[near], j[near]
        reopened = self._visible(P, pts, i, j, self.config.vicinity)
        # pairs of the hidden vertices with every vertex
        ii, jj = np.meshgrid(np.arange(n_old + n_new), np.arange(n_old, n_old + n_new), indexing="ij")
        sel = ii < jj
        new_pairs = self._visible(P, pts, ii[sel], jj[sel], self.config.vicinity)
        all_pairs = np.concatenate([pairs, reopened, new_pairs])
        return self._make(self.workspace, tuple(self.obstacles[k] for k in kept), self.radius, self.config, G,
                          self.free_workspace, P, pts, owner, all_pairs)


def descent_candidates(nf, start, spacing: float = 0.5, **descend_options) -> np.ndarray:
    """Potential-biased regeneration candidates (paper 001 section 4.2.3 II): points every
    ``spacing`` metres (of arc length) along the gradient descent of the navigation function
    ``nf`` from ``start`` towards its goal, start and goal excluded.

    The descent follows the potential's steepest change, so these vertices fill the part of the
    workspace the potential routes the robot through. ``descend_options`` go to
    :func:`navigation.descend`. Returns ``(K, 2)`` (possibly empty).
    """
    from navigation.descent import descend

    if not (isinstance(spacing, (int, float)) and spacing > 0):
        raise TampError(f"spacing must be > 0, got {spacing!r}")
    path = descend(nf, np.asarray(start, dtype=float).reshape(2), **descend_options).path
    if len(path) < 2:
        return np.zeros((0, 2))
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))])
    targets = np.arange(spacing, arc[-1] - 0.5 * spacing, spacing)
    if targets.size == 0:
        return np.zeros((0, 2))
    return np.stack([np.interp(targets, arc, path[:, 0]), np.interp(targets, arc, path[:, 1])], axis=1)
