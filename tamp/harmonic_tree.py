"""Oriented harmonic trees: waypoint paths between two task poses (paper 001 section 4.1.1,
eq. 7-8), their edge costs (eq. 26) and their online revision (section 4.2.3).

A harmonic tree ``T_{g -> g'} = (V, B, gamma, (v_0, v_G))`` (eq. 7) has the oriented vertices
``V = {v_0, v_G} u (roadmap positions x headings)``, the directed edges ``B`` between vertices
whose positions see each other safely (:class:`tamp.roadmap.Roadmap`), and the edge cost of
eq. 26::

    gamma(v_n, v_{n+1}) = d(q_n, q_{n+1}) + w . Q_gamma(theta_n, theta_{n+1})
    Q_gamma = [ |theta_gamma(q_n) - theta_n| , |theta_{q_{n+1} - q_n} - theta_{n+1}| ]

A* (eq. 8) with the admissible, consistent heuristic ``|q - q_G|`` finds the cheapest path
``P = v_0 v_1 ... v_G``; its cost ``sum gamma`` is the navigation-map cost of the transition
(the equation after eq. 26).

Where the paper is vague, and what we chose
-------------------------------------------
* ``theta_gamma(q_n)`` is the direction at ``q_n`` of the oriented field that drives the robot
  to ``v_{n+1}``. Evaluating it needs one navigation function and one
  :class:`navigation.OrientedField` per target pose (15-70 ms each on the shared worlds, for
  hundreds of targets per tree), so we use the cheap estimate ``theta_gamma(q_n) ~
  theta_{q_{n+1} - q_n}``: the edge is a safe straight segment, and the field of a goal in plain
  sight starts out along it (exactly so in an obstacle-free disc, approximately elsewhere). The
  first term then measures the initial turn, the second the final steering, as the paper
  describes them. :func:`rotation_terms` and :func:`edge_cost` accept an explicit
  ``theta_gamma`` for callers that evaluate the field.
* A zero-length edge (start and goal at one position) has no direction; its terms are
  ``[|theta_{n+1} - theta_n|, 0]`` (rotation in place).
* Orientations: every roadmap position carries ``n_headings`` headings ``2 pi k / n_headings``
  (paper: "augmented by orientations"); the terminals carry exactly their own heading.
* Angle differences are wrapped to ``[0, pi]``.
* Infeasibility is an exception, :class:`NoTreePathError`, with a :class:`TreeFailure` reason
  (the start or goal is not in free space, or no path exists): a navigation map removes the
  transition (section 4.2.4) on catching it.

Revision (section 4.2.3): :func:`revise_trees` trims and regenerates the shared roadmap
(:meth:`tamp.roadmap.Roadmap.with_obstacles`, steps I-II) and re-runs A* for every tree with the
current weights (step III). :meth:`RotationWeights.fit` is the least-squares update
``w* = (Q^T Q)^-1 Q^T (gamma* - d)`` from the measured costs of traversed edges; the new weights
apply to every tree (pass them to :func:`plan_tree` / :func:`revise_trees`).

Symbols
-------
=====================  ==============================================================
``v_n = (q_n, theta_n)``  oriented vertex (position m, heading rad)
``d``                  translation ``|q_{n+1} - q_n|`` (m)
``Q_gamma``            rotation terms ``(2,)`` (rad)
``w = (w_1, w_2)``     rotation weights (m / rad), paper's initial value ``(0.1, 0.1)``
``gamma``              edge cost (eq. 26)
=====================  ==============================================================
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from navigation.errors import TampError
from navigation.geometry import beta_rows, pack

from ._astar_kernel import astar
from .roadmap import Roadmap, grown, segments_clear

__all__ = [
    "RotationWeights",
    "HarmonicTree",
    "TreeFailure",
    "NoTreePathError",
    "RevisionResult",
    "rotation_terms",
    "edge_cost",
    "plan_tree",
    "tree_graph",
    "revise_trees",
    "headings",
]

_HALVINGS = 8  # buffer halvings tried for a terminal inside the buffer zone


def _wrap_abs(a):
    """``|a|`` after wrapping to ``(-pi, pi]``: a value in ``[0, pi]``."""
    return np.abs(np.remainder(np.asarray(a, dtype=float) + np.pi, 2.0 * np.pi) - np.pi)


def headings(n: int) -> np.ndarray:
    """The heading set ``2 pi k / n`` wrapped to ``(-pi, pi]``, shape ``(n,)``."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise TampError(f"n_headings must be a positive int, got {n!r}")
    h = np.remainder(2.0 * np.pi * np.arange(n) / n + np.pi, 2.0 * np.pi) - np.pi
    return np.where(h == -np.pi, np.pi, h)


# ---------------------------------------------------------------------- eq. 26
def rotation_terms(q_from, theta_from, q_to, theta_to, theta_gamma=None) -> np.ndarray:
    """``Q_gamma(theta_n, theta_{n+1})`` of eq. 26 for ``K`` edges, shape ``(K, 2)`` (or ``(2,)``).

    Parameters
    ----------
    q_from, q_to : (2,) or (K, 2)
        Edge ends.
    theta_from, theta_to : float or (K,)
        Headings at the ends.
    theta_gamma : float or (K,), optional
        Direction of the oriented field at ``q_from``; default the segment direction (module
        docstring).
    """
    a = np.asarray(q_from, dtype=float)
    b = np.asarray(q_to, dtype=float)
    single = a.ndim == 1 and b.ndim == 1
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    v = b - a
    length = np.hypot(v[:, 0], v[:, 1])
    th0 = np.broadcast_to(np.asarray(theta_from, dtype=float), length.shape)
    th1 = np.broadcast_to(np.asarray(theta_to, dtype=float), length.shape)
    phi = np.where(length > 0, np.arctan2(v[:, 1], v[:, 0]), th1)
    tg = phi if theta_gamma is None else np.broadcast_to(np.asarray(theta_gamma, dtype=float), length.shape)
    Q = np.stack([_wrap_abs(tg - th0), _wrap_abs(phi - th1)], axis=1)
    return Q[0] if single else Q


def edge_cost(q_from, theta_from, q_to, theta_to, weights=None, theta_gamma=None):
    """Edge cost ``gamma = d + w . Q_gamma`` of eq. 26 (float, or ``(K,)`` for ``(K, 2)`` ends)."""
    w = (weights if weights is not None else RotationWeights()).as_array()
    a = np.asarray(q_from, dtype=float)
    b = np.asarray(q_to, dtype=float)
    Q = rotation_terms(a, theta_from, b, theta_to, theta_gamma)
    d = np.linalg.norm(np.atleast_2d(b) - np.atleast_2d(a), axis=1)
    cost = d + np.atleast_2d(Q) @ w
    return float(cost[0]) if (a.ndim == 1 and b.ndim == 1) else cost


@dataclass(frozen=True, slots=True)
class RotationWeights:
    """The rotation weights ``w = (w_1, w_2)`` of eq. 26, shared by every tree (> 0).

    Examples
    --------
    >>> w = RotationWeights(0.17, 0.23)
    >>> d = np.array([1.0, 2.0, 0.5]); Q = np.array([[0.1, 0.5], [1.0, 0.2], [0.3, 0.3]])
    >>> fit = RotationWeights.fit(d, Q, d + Q @ w.as_array())
    >>> round(fit.w1, 12), round(fit.w2, 12)
    (0.17, 0.23)
    """

    w1: float = 0.1
    w2: float = 0.1

    def __post_init__(self):
        for name in ("w1", "w2"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not (math.isfinite(v) and v > 0):
                raise TampError(f"RotationWeights.{name} must be a finite number > 0, got {v!r}")
            object.__setattr__(self, name, float(v))

    def as_array(self) -> np.ndarray:
        return np.array([self.w1, self.w2])

    @classmethod
    def fit(cls, translation, rotation, measured, *, floor: float = 1e-6) -> "RotationWeights":
        """Least-squares weights from traversed edges (paper 001 section 4.2.3, step III).

        ``w* = (Q^T Q)^-1 Q^T (gamma* - d)``, computed with :func:`numpy.linalg.lstsq`; a
        component that comes out below ``floor`` (the paper needs ``w > 0``) is set to ``floor``
        (only possible when the measurements contradict the model).

        Parameters
        ----------
        translation : (H,)
            Translations ``d`` of the traversed edges (:attr:`HarmonicTree.translations`).
        rotation : (H, 2)
            Their rotation terms ``Q_gamma`` (:attr:`HarmonicTree.rotations`).
        measured : (H,)
            Measured costs ``gamma*``.

        Raises
        ------
        TampError
            Shapes disagree, values are not finite, or ``Q^T Q`` is singular (fewer than two
            independent samples).
        """
        d = np.asarray(translation, dtype=float).reshape(-1)
        Q = np.asarray(rotation, dtype=float)
        g = np.asarray(measured, dtype=float).reshape(-1)
        if Q.ndim != 2 or Q.shape[1] != 2 or len(Q) != len(d) or len(g) != len(d):
            raise TampError(f"fit needs translation (H,), rotation (H, 2), measured (H,); got shapes "
                            f"{d.shape}, {Q.shape}, {g.shape}")
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(Q)) and np.all(np.isfinite(g))):
            raise TampError("fit needs finite samples")
        if len(d) < 2 or np.linalg.matrix_rank(Q) < 2:
            raise TampError(f"cannot fit the rotation weights: Q^T Q is singular ({len(d)} sample(s), rank "
                            f"{np.linalg.matrix_rank(Q) if len(d) else 0}); keep the current weights")
        w, *_ = np.linalg.lstsq(Q, g - d, rcond=None)
        w = np.maximum(w, floor)
        return cls(float(w[0]), float(w[1]))


# ---------------------------------------------------------------------- results and errors
class TreeFailure(enum.Enum):
    """Why no harmonic tree path exists."""

    START_BLOCKED = "start_blocked"  #: the start position is not in the robot's free space
    GOAL_BLOCKED = "goal_blocked"  #: the goal position is not in the robot's free space
    DISCONNECTED = "disconnected"  #: no safe path joins them (e.g. a walled-off goal)


class NoTreePathError(TampError):
    """No harmonic-tree path between two poses.

    Attributes
    ----------
    start, goal : tuple of float
        The poses ``(x, y, theta)``.
    reason : TreeFailure
    """

    def __init__(self, start, goal, reason: TreeFailure, detail: str = ""):
        self.start = tuple(float(v) for v in start)
        self.goal = tuple(float(v) for v in goal)
        self.reason = reason
        what = {
            TreeFailure.START_BLOCKED: "the start position is not in free space",
            TreeFailure.GOAL_BLOCKED: "the goal position is not in free space",
            TreeFailure.DISCONNECTED: "no safe path connects them (the goal is walled off)",
        }[reason]
        msg = (f"no harmonic-tree path from ({self.start[0]:.3f}, {self.start[1]:.3f}) to "
               f"({self.goal[0]:.3f}, {self.goal[1]:.3f}): {what}")
        super().__init__(msg + (f" ({detail})" if detail else ""))


@dataclass(frozen=True, slots=True, eq=False)
class HarmonicTree:
    """The A* path of one harmonic tree (eq. 8) with its eq. 26 costs.

    Attributes
    ----------
    start, goal : tuple (x, y, theta)
    waypoints : tuple of (x, y, theta)
        ``v_0 v_1 ... v_G``; first is ``start``, last is ``goal``.
    vertices : tuple of int
        Roadmap vertex index of every waypoint (``-1`` for the terminals).
    translations : (N,) array
        ``d`` of each of the ``N = len(waypoints) - 1`` edges.
    rotations : (N, 2) array
        ``Q_gamma`` of each edge.
    edge_costs : (N,) array
        ``gamma`` of each edge (eq. 26).
    cost : float
        ``sum(edge_costs)``: the navigation-map cost of the transition.
    weights : RotationWeights
        The weights the costs were computed with.
    n_headings : int
    expanded : int
        Nodes A* expanded.
    """

    start: tuple
    goal: tuple
    waypoints: tuple
    vertices: tuple
    translations: np.ndarray
    rotations: np.ndarray
    edge_costs: np.ndarray
    cost: float
    weights: RotationWeights
    n_headings: int
    expanded: int = 0

    @property
    def positions(self) -> np.ndarray:
        """Waypoint positions ``(N + 1, 2)``."""
        return np.array([w[:2] for w in self.waypoints])

    def recost(self, weights: RotationWeights) -> float:
        """The cost of this same path under other weights (no search)."""
        return float(self.translations.sum() + (self.rotations @ weights.as_array()).sum()) if len(
            self.translations) else 0.0


# ---------------------------------------------------------------------- terminals
def _pose(p, name: str) -> np.ndarray:
    try:
        a = np.asarray(p, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise TampError(f"{name} must be a pose (x, y, theta), got {p!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise TampError(f"{name} must be a finite pose (x, y, theta), got {p!r}")
    a[2] = math.pi - float(np.remainder(math.pi - a[2], 2.0 * math.pi))  # wrap to (-pi, pi]
    return a


@dataclass(frozen=True, slots=True)
class _Terminal:
    """A start or goal position with the buffer levels its incident edges are checked with."""

    q: np.ndarray
    amounts: np.ndarray  # per obstacle: r + level (level = b unless the terminal sits in the buffer)
    P: np.ndarray  # packed obstacles grown by ``amounts``


def _terminal(rm: Roadmap, q: np.ndarray, start, goal, reason: TreeFailure) -> _Terminal:
    """Buffer levels for edges at ``q``: ``b`` where ``q`` is outside ``G_j``, else the largest
    ``min(b, c / 2) / 2^k`` (``c`` the exact clearance of ``q`` to the inflated obstacle) whose
    grown squircle leaves ``q`` outside. Raises when ``q`` is not in free space at all."""
    r, b = rm.radius, rm.config.buffer
    m = len(rm.obstacles)
    amounts = np.full(m, r + b)
    rows = rm.P.copy()
    # W' (the workspace shrunk by r + b_W) lies inside the workspace shrunk by r: a point of W'
    # needs no exact distance
    in_free = bool(rm.free_workspace.beta(q) < 0)
    if not in_free and not (rm.workspace.beta(q) < 0 and -float(rm.workspace.distance(q)) > r):
        raise NoTreePathError(start, goal, reason, "outside the workspace shrunk by the robot radius")
    if not in_free:
        c = -float(rm.workspace.distance(q)) - r
        level = min(rm.config.wall_buffer, 0.5 * c)
        for _ in range(_HALVINGS):
            if grown(rm.workspace, -(r + level)).beta(q) < 0:
                break
            level *= 0.5
        else:
            raise NoTreePathError(start, goal, reason, "too close to the workspace boundary")
    if m:
        inside = np.nonzero(beta_rows(rm.P, q[0], q[1]) <= 0)[0]
        for j in inside:
            o = rm.obstacles[j]
            c = float(o.distance(q)) - r
            if c <= 0:
                raise NoTreePathError(start, goal, reason, f"inside obstacle {j} inflated by the robot radius")
            level = min(b, 0.5 * c)
            for _ in range(_HALVINGS):
                # the plain inflation: a new amount per terminal, and grow is cheaper than
                # grow_snug (both contain the neighbourhood; this one reaches further at corners)
                sq = o.grow(r + level) if r + level > 0 else o
                if sq.beta(q) > 0:
                    break
                level *= 0.5
            else:
                raise NoTreePathError(start, goal, reason, f"too close to obstacle {j}")
            amounts[j] = r + level
            rows[j] = pack([sq])[0]
    return _Terminal(q[:2].copy(), amounts, rows)


@dataclass(frozen=True, slots=True, eq=False)
class _Problem:
    """One tree's terminals wired to the roadmap."""

    rm: Roadmap
    start: np.ndarray
    goal: np.ndarray
    theta: np.ndarray  # heading set
    from_start: tuple  # (vertices, lengths, angles)
    to_goal: tuple  # (vertices, lengths, angles from vertex to goal)
    direct: bool


def _visible_from(rm: Roadmap, t: _Terminal):
    pts = rm.points
    if len(pts) == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0)
    vec = pts - t.q
    length = np.hypot(vec[:, 0], vec[:, 1])
    cand = np.nonzero(length <= rm.config.vicinity)[0]
    ok = segments_clear(t.P, np.broadcast_to(t.q, (len(cand), 2)), pts[cand])
    v = cand[ok]
    return v, length[v], np.arctan2(vec[v, 1], vec[v, 0])


_WIRED_KEPT = 32  # terminals a roadmap keeps (:func:`_wired`)


def _wired(rm: Roadmap, q: np.ndarray, start, goal, reason: TreeFailure):
    """:func:`_terminal` at ``q`` and the roadmap vertices it sees (:func:`_visible_from`),
    memoised per roadmap and position: both depend on nothing else, and the trees of one
    re-plan share their start (the robot) and often their goals. Failures are not kept (their
    message names the tree's start and goal); at most ``_WIRED_KEPT`` positions per roadmap,
    the oldest dropped first, so a roadmap that outlives many re-plans does not grow."""
    key = ("wired", q.tobytes())
    hit = rm._memo.get(key)
    if hit is None:
        t = _terminal(rm, q, start, goal, reason)
        vis = _visible_from(rm, t)
        for a in (t.q, t.amounts, t.P, *vis):
            a.flags.writeable = False
        hit = (t, vis)
        wired = [k for k in rm._memo if k[0] == "wired"]
        if len(wired) >= _WIRED_KEPT:
            del rm._memo[wired[0]]
        rm._memo[key] = hit
    return hit


def _problem(rm: Roadmap, start, goal, n_headings: int) -> _Problem:
    if not isinstance(rm, Roadmap):
        raise TampError(f"expected a tamp.roadmap.Roadmap, got {type(rm).__name__}")
    s = _pose(start, "start")
    g = _pose(goal, "goal")
    theta = headings(n_headings)
    ts, fs = _wired(rm, s[:2], s, g, TreeFailure.START_BLOCKED)
    tg, (vg, lg, ag) = _wired(rm, g[:2], s, g, TreeFailure.GOAL_BLOCKED)
    # edges run vertex -> goal: reverse the direction
    tog = (vg, lg, np.arctan2(-np.sin(ag), -np.cos(ag)))
    direct = False
    if math.dist(s[:2], g[:2]) <= rm.config.vicinity:
        rows = np.where((ts.amounts <= tg.amounts)[:, None], ts.P, tg.P) if len(ts.P) else ts.P
        direct = bool(segments_clear(rows, s[None, :2], g[None, :2])[0])
    return _Problem(rm, s, g, theta, fs, tog, direct)


# ---------------------------------------------------------------------- A* (eq. 8)
def plan_tree(roadmap: Roadmap, start, goal, weights: RotationWeights | None = None, n_headings: int = 8) -> HarmonicTree:
    """The cheapest waypoint path of the harmonic tree from ``start`` to ``goal`` (eq. 7-8, 26).

    Parameters
    ----------
    roadmap : Roadmap
        Shared vertex positions and safe edges (:class:`tamp.roadmap.Roadmap`).
    start, goal : (3,) sequence
        Poses ``(x, y, theta)``.
    weights : RotationWeights, optional
        Default ``(0.1, 0.1)`` (paper 001 section 5).
    n_headings : int
        Headings per roadmap position.

    Returns
    -------
    HarmonicTree

    Raises
    ------
    NoTreePathError
        With ``reason`` START_BLOCKED / GOAL_BLOCKED (position not in free space) or
        DISCONNECTED (no path).
    TampError
        Malformed poses or parameters.
    """
    weights = RotationWeights() if weights is None else weights
    if not isinstance(weights, RotationWeights):
        raise TampError(f"weights must be RotationWeights, got {type(weights).__name__}")
    pb = _problem(roadmap, start, goal, n_headings)
    return _astar(pb, weights, n_headings)


def _heading_graph(rm: Roadmap, H: int, weights: RotationWeights):
    """The search graph of the harmonic trees of ``rm`` without terminals, as CSR arrays.

    Eq. 26 on a roadmap edge ``e = (i -> j)`` from heading ``h`` to heading ``h'`` costs
    ``d_e + w1 |angle_e - theta_h| + w2 |angle_e - theta_h'|``: the sum of a part that depends
    on ``h`` and one that depends on ``h'``. So every directed edge gets a node ``E_e`` with
    edges ``(i, h) -> E_e`` (``d_e + w1 |angle_e - theta_h|``) and ``E_e -> (j, h')``
    (``w2 |angle_e - theta_h'|``): the same path costs with ``2 H`` instead of ``H^2`` edges per
    roadmap edge. Node ids: ``(i, h) -> i H + h``, ``E_e -> n H + e``, the goal ``n H + n_E``, the
    start ``n H + n_E + 1`` (last, so its row is appended per tree). Every ``(i, h)`` row ends
    with an edge to the goal whose cost a tree sets (``inf``: not visible). Cached per roadmap,
    heading count and weights (data) and per roadmap and heading count (structure).
    """
    key = ("graph", H)
    struct = rm._memo.get(key)
    indptr_v, dst, length, angle = rm._adj
    n, n_e = len(rm.points), len(dst)
    if struct is None:
        theta = headings(H)
        table = _wrap_abs(angle[:, None] - theta[None, :])  # (n_e, H)
        deg = np.diff(indptr_v)
        # rows (i, h): the out-edge nodes of i, then the goal
        row_len = np.concatenate([np.repeat(deg + 1, H), np.full(n_e, H), [0]])
        indptr = np.concatenate([[0], np.cumsum(row_len)])
        n_v = n * H
        idx_v = np.empty(int(indptr[n_v]), dtype=np.int32)
        goal_pos = indptr[1:n_v + 1] - 1
        mask = np.ones(len(idx_v), dtype=bool)
        mask[goal_pos] = False
        # row (i, h) holds the edge nodes n H + e, e in indptr_v[i] .. indptr_v[i + 1], in order
        rv = np.repeat(np.arange(n), H)  # vertex of each (i, h) row
        rd = deg[rv]
        row_of = np.repeat(np.arange(n_v), rd)  # row of each (i, h) -> E_e entry
        first = np.cumsum(rd) - rd
        e_of = indptr_v[rv[row_of]] + (np.arange(int(rd.sum())) - first[row_of])
        h_of = row_of % H
        idx_v[mask] = n_v + e_of
        idx_v[goal_pos] = n_v + n_e
        idx_e = ((dst[:, None] * H) + np.arange(H)[None, :]).ravel().astype(np.int32)
        # the vertex where each (i, h) node and each edge node (at its edge's head) sits: the
        # A* heuristic's position
        vertex_of = np.concatenate([rv, dst]).astype(np.intp)
        struct = {"theta": theta, "table": table, "indptr": indptr.astype(np.int32), "vertex_of": vertex_of,
                  "indices": np.concatenate([idx_v, idx_e]).astype(np.int32), "goal_pos": goal_pos,
                  "mask": mask, "e_of": e_of, "h_of": h_of, "n_v": n_v, "n_e": n_e, "data": {}}
        rm._memo[key] = struct
    wkey = (weights.w1, weights.w2)
    data = struct["data"].get(wkey)
    if data is None:
        table = struct["table"]
        dv = np.full(len(struct["mask"]), np.inf)
        dv[struct["mask"]] = length[struct["e_of"]] + weights.w1 * table[struct["e_of"], struct["h_of"]]
        data = np.concatenate([dv, (weights.w2 * table).ravel()])
        if len(struct["data"]) > 4:
            struct["data"].clear()
        struct["data"][wkey] = data
    return struct, data


def _astar(pb: _Problem, weights: RotationWeights, H: int) -> HarmonicTree:
    """Shortest path of eq. 8 from the start pose to the goal pose over ``(vertex, heading)``
    nodes (:func:`_heading_graph` plus this tree's terminal edges), by A* with the heuristic
    ``|q - q_G|`` (compiled: :func:`tamp._astar_kernel.astar`). Every edge costs at least the
    distance it moves, so the heuristic is consistent: the optimum of Dijkstra's algorithm,
    with the search stopped once the goal is settled.
    """
    rm = pb.rm
    w1, w2 = weights.w1, weights.w2
    n = len(rm.points)
    struct, data = _heading_graph(rm, H, weights)
    theta = struct["theta"]
    n_v, n_e = struct["n_v"], struct["n_e"]
    G, S = n_v + n_e, n_v + n_e + 1
    th0, thG = float(pb.start[2]), float(pb.goal[2])
    qg = pb.goal[:2]
    data = data.copy()
    # vertex -> goal edges: d + w1 |phi - theta_h| + w2 |phi - theta_G| (phi = thG on a zero-length edge)
    vg, lg, ag = pb.to_goal
    if len(vg):
        phi = np.where(lg > 0, ag, thG)
        c = (lg + w2 * _wrap_abs(phi - thG))[:, None] + w1 * _wrap_abs(phi[:, None] - theta[None, :])
        data[struct["goal_pos"][(vg[:, None] * H + np.arange(H)[None, :]).ravel()]] = c.ravel()
    # start row: start -> (j, h') and start -> goal
    js, ls, angs = pb.from_start
    cols = [(js[:, None] * H + np.arange(H)[None, :]).ravel()]
    vals = [((ls + w1 * _wrap_abs(angs - th0))[:, None] + w2 * _wrap_abs(angs[:, None] - theta[None, :])).ravel()]
    if pb.direct:
        d = float(np.linalg.norm(qg - pb.start[:2]))
        phi = math.atan2(qg[1] - pb.start[1], qg[0] - pb.start[0]) if d > 0 else thG
        cols.append(np.array([G]))
        vals.append(np.array([d + w1 * float(_wrap_abs(phi - th0)) + w2 * float(_wrap_abs(phi - thG))]))
    cols, vals = np.concatenate(cols).astype(np.int32), np.concatenate(vals)
    dv = np.hypot(rm.points[:, 0] - qg[0], rm.points[:, 1] - qg[1]) if n else np.zeros(0)
    h = np.concatenate([dv[struct["vertex_of"]], [0.0, 0.0]])
    cost, pred, reached = astar(struct["indptr"], struct["indices"], data, cols, vals, h, G)
    if not math.isfinite(cost):
        raise NoTreePathError(pb.start, pb.goal, TreeFailure.DISCONNECTED,
                              f"{n} roadmap vertices, {len(rm.pairs)} edges")
    expanded = int(np.count_nonzero(reached[:n_v]))
    # path reconstruction (edge nodes skipped)
    chain = [G]
    while chain[-1] != S:
        chain.append(int(pred[chain[-1]]))
    chain = [v for v in reversed(chain) if v < n_v or v >= G]
    poses, verts = [], []
    for node in chain:
        if node == S:
            poses.append(tuple(pb.start.tolist()))
            verts.append(-1)
        elif node == G:
            poses.append(tuple(pb.goal.tolist()))
            verts.append(-1)
        else:
            i, h = divmod(node, H)
            poses.append((float(rm.points[i, 0]), float(rm.points[i, 1]), float(theta[h])))
            verts.append(i)
    arr = np.array(poses)
    Q = rotation_terms(arr[:-1, :2], arr[:-1, 2], arr[1:, :2], arr[1:, 2])
    d = np.linalg.norm(np.diff(arr[:, :2], axis=0), axis=1)
    costs = d + Q @ weights.as_array()
    return HarmonicTree(tuple(poses[0]), tuple(poses[-1]), tuple(poses), tuple(verts), d, Q, costs,
                        float(costs.sum()), weights, H, expanded)


def tree_graph(roadmap: Roadmap, start, goal, weights: RotationWeights | None = None, n_headings: int = 8):
    """The harmonic tree of eq. 7 as an explicit :class:`networkx.DiGraph` (for inspection and
    brute-force checks; :func:`plan_tree` never builds it).

    Nodes are ``"start"``, ``"goal"`` and ``(vertex, heading_index)``; edge attribute ``weight`` is
    the eq. 26 cost. Raises :class:`NoTreePathError` for a blocked start or goal, like
    :func:`plan_tree`.
    """
    import networkx as nx

    weights = RotationWeights() if weights is None else weights
    pb = _problem(roadmap, start, goal, n_headings)
    rm, H, theta = pb.rm, n_headings, pb.theta
    Gr = nx.DiGraph()
    Gr.add_node("start")
    Gr.add_node("goal")
    for i in range(len(rm.points)):
        for h in range(H):
            Gr.add_node((i, h))

    def add(u, q_from, th_from, v, q_to, th_to):
        Gr.add_edge(u, v, weight=edge_cost(q_from, th_from, q_to, th_to, weights))

    for v in pb.from_start[0]:
        for h in range(H):
            add("start", pb.start[:2], pb.start[2], (int(v), h), rm.points[v], theta[h])
    if pb.direct:
        add("start", pb.start[:2], pb.start[2], "goal", pb.goal[:2], pb.goal[2])
    for i, j in rm.pairs:
        for a, b in ((i, j), (j, i)):
            for h in range(H):
                for k in range(H):
                    add((int(a), h), rm.points[a], theta[h], (int(b), k), rm.points[b], theta[k])
    for v in pb.to_goal[0]:
        for h in range(H):
            add((int(v), h), rm.points[v], theta[h], "goal", pb.goal[:2], pb.goal[2])
    return Gr


# ---------------------------------------------------------------------- revision (4.2.3)
@dataclass(frozen=True, slots=True, eq=False)
class RevisionResult:
    """Outcome of :func:`revise_trees`.

    Attributes
    ----------
    roadmap : Roadmap
        The trimmed and regenerated roadmap.
    trees : dict
        Key -> revised :class:`HarmonicTree` for every pair that still has a path.
    blocked : dict
        Key -> :class:`NoTreePathError` for every pair that lost its path.
    changed : frozenset
        Keys whose waypoint sequence changed (or that became blocked).
    """

    roadmap: Roadmap
    trees: dict
    blocked: dict
    changed: frozenset = field(default_factory=frozenset)


def revise_trees(roadmap: Roadmap, trees: Mapping, new_obstacles=(), *, weights: RotationWeights | None = None,
                 extra=None) -> RevisionResult:
    """Local revision of every harmonic tree after discovering ``new_obstacles`` and/or updating
    the weights (paper 001 section 4.2.3).

    (I) trimming and (II) regeneration happen once, on the shared roadmap
    (:meth:`Roadmap.with_obstacles`, with ``extra`` potential-biased candidates); (III) every
    tree's path is searched again by A* with ``weights`` (default: each tree's own). Without
    ``extra`` every revised tree equals :func:`plan_tree` on the roadmap built from scratch.

    Parameters
    ----------
    trees : mapping key -> HarmonicTree
        The current trees (any hashable keys, e.g. pairs of navigation-map nodes).
    """
    rm = roadmap.with_obstacles(new_obstacles, extra=extra)
    out, blocked, changed = {}, {}, set()
    for key, tree in trees.items():
        w = tree.weights if weights is None else weights
        try:
            t = plan_tree(rm, tree.start, tree.goal, w, tree.n_headings)
        except NoTreePathError as err:
            blocked[key] = err
            changed.add(key)
            continue
        out[key] = t
        if t.waypoints != tree.waypoints:
            changed.add(key)
    return RevisionResult(rm, out, blocked, frozenset(changed))
