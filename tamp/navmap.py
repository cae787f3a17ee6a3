"""The weighted navigation map over regions times orientations (paper 001 section 4.1.1).

The map is the graph ``G = (G x Theta, E, d, (g_0, theta_0))`` of [1]_ section 4.1.1: its nodes
are pairs (region, orientation) with orientations ``theta_k = 2 pi k / n_orient``, it is
initialised *fully connected* (the actual feasibility and costs are only known once the local
controllers exist, section 4.1.1) with the initial cost

.. math::

    d((g, \\theta), (g', \\theta')) = \\|g - g'\\|_2 + w\\,|\\theta - \\theta'|

(angle difference wrapped to ``[0, pi]``), and section 4.2.4 later *re-costs* edges and
*removes* the ones whose local path no longer exists. Every pair of distinct nodes is joined
in both directions, including two orientations of the same region (rotating in place costs
``w |theta - theta'|``), as "fully connected over ``G x Theta``" says; there are no self-loops.

An optional *start pose* adds one extra node :data:`START` (``Node("@start", 0)``) with edges
to every region node and none into it: the robot's initial pose when it is not inside a region.

Symbols
-------
=================  ==============================================================
``g``              region centre (m)
``theta_k``        orientation ``2 pi k / n_orient`` (rad)
``w``              weight of the rotation term (m/rad), ``w > 0``
``d``              edge cost; ``inf`` means "no edge" (removed / blocked)
=================  ==============================================================

State lives in one object: the current cost of every edge, the set of removed edges (with the
cost they had), a version counter bumped by every change, and a log of changes from which
:meth:`NavigationMap.changes_since` tells a cache exactly which edges changed and how. The log
is bounded (a long-running executive re-costs thousands of edges a minute): beyond
``log_limit`` entries its older half is dropped, whole versions at a time, and
``changes_since`` a version older than what it keeps (``log_floor``) answers ``None``: treat
every edge as changed.

References
----------
.. [1] Wang and Guo, "Harmonic trees for LTL tasks in unknown environments", 2025 (paper 001).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import NamedTuple, Union

from .errors import InvalidRequestError, UnknownRegionError

__all__ = ["Node", "NodeLike", "START", "NavigationMap", "MAX_REGIONS"]

START = "@start"  #: region field of the virtual start node (not a valid region name)

#: Most regions a navigation map holds. The map is dense (``N = regions x n_orient`` nodes,
#: ``N^2`` costs) and the product with a mission's automaton multiplies it: visiting 12 of 100
#: regions plans in about 27 s and 0.86 GB (forty-eighth session), while a request adding 676
#: regions ran out of memory in the product search. A world or a request beyond it is refused.
MAX_REGIONS = 100
INF = math.inf


class Node(NamedTuple):
    """A node of the navigation map: region name and orientation index ``k``."""

    region: str
    k: int


NodeLike = Union[Node, tuple, str]


def _center(value, name: str) -> tuple[float, float]:
    c = getattr(value, "center", None)
    if c is None and isinstance(value, Mapping):
        c = value.get("center")
    if c is None:
        c = value
    try:
        x, y = (float(v) for v in c)
    except (TypeError, ValueError) as err:
        raise InvalidRequestError(
            f"region {name!r}: centre must be a pair of numbers, got {c!r}") from err
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InvalidRequestError(f"region {name!r}: centre {c!r} is not finite")
    return x, y


def _angle_gap(a: float, b: float) -> float:
    """``|a - b|`` wrapped to ``[0, pi]``."""
    d = abs(a - b) % (2.0 * math.pi)
    return min(d, 2.0 * math.pi - d)


class NavigationMap:
    """Weighted, directed navigation map over ``regions x orientations`` (section 4.1.1 of [1]_).

    Parameters
    ----------
    regions : mapping name -> centre
        Region names (the atomic propositions) to centres ``(x, y)``; a value may also be a
        :class:`navigation.world.Region` or a ``{"center": [x, y], ...}`` dict.
    n_orient : int, default 8
        Number of orientations ``theta_k = 2 pi k / n_orient``.
    w : float, default 0.1
        Weight ``w > 0`` of the rotation term of the initial cost.
    start : (x, y) or (x, y, theta), optional
        Pose of the virtual :data:`START` node (omitted when ``None``).

    Attributes
    ----------
    nodes : tuple of Node
        All nodes; region nodes are ordered by region (given order) then ``k``; ``START``, if
        any, is last. ``index[node]`` is its position.
    regions : tuple of str
        Region names in the given order.
    version : int
        Bumped by every change of a cost (including removal, restore and start moves).

    Raises
    ------
    InvalidRequestError
        Bad ``n_orient``, ``w``, centres or start pose, or more than :data:`MAX_REGIONS` regions.

    Examples
    --------
    >>> m = NavigationMap({"a": (0, 0), "b": (3, 4)}, n_orient=4, w=0.5)
    >>> round(m.cost(Node("a", 0), Node("b", 1)), 4)  # 5 + 0.5 * pi/2
    5.7854
    >>> m.remove_edge("a", "b")  # every orientation pair, both directions
    32
    >>> m.cost(Node("b", 2), Node("a", 0))
    inf
    """

    def __init__(self, regions: Mapping, *, n_orient: int = 8, w: float = 0.1, start=None):
        if isinstance(n_orient, bool) or not isinstance(n_orient, int) or n_orient < 1:
            raise InvalidRequestError(f"n_orient must be a positive int, got {n_orient!r}")
        w = float(w)
        if not (math.isfinite(w) and w > 0):
            raise InvalidRequestError(f"w must be finite and > 0 (paper 001 section 4.1.1), got {w!r}")
        if not regions:
            raise InvalidRequestError("a navigation map needs at least one region")
        if len(regions) > MAX_REGIONS:
            raise InvalidRequestError(f"{len(regions)} regions: a navigation map holds at most {MAX_REGIONS} "
                                      f"(tamp.navmap.MAX_REGIONS)")
        names = tuple(regions)
        for r in names:
            if not isinstance(r, str) or not r or r == START:
                raise InvalidRequestError(f"invalid region name {r!r}")
        self.regions: tuple[str, ...] = names
        self.centers: dict[str, tuple[float, float]] = {r: _center(regions[r], r) for r in names}
        self.n_orient = n_orient
        self.w = w
        self.thetas: tuple[float, ...] = tuple(2.0 * math.pi * k / n_orient for k in range(n_orient))
        nodes = [Node(r, k) for r in names for k in range(n_orient)]
        self.has_start = start is not None
        if self.has_start:
            nodes.append(Node(START, 0))
        self.nodes: tuple[Node, ...] = tuple(nodes)
        self.index: dict[Node, int] = {n: i for i, n in enumerate(self.nodes)}
        self.num_nodes = N = len(self.nodes)
        self.num_region_nodes = len(names) * n_orient
        #: region index of each node (``-1`` for START)
        self.node_region: tuple[int, ...] = tuple(
            (names.index(n.region) if n.region != START else -1) for n in self.nodes)
        self._region_index = {r: i for i, r in enumerate(names)}
        self.start_pose: tuple[float, float, float] | None = None
        # dense N x N cost matrix, flattened (edge id e = i * N + j); inf on the diagonal,
        # into START, and on removed edges
        self._cost: list[float] = [INF] * (N * N)
        self._removed: dict[int, float] = {}  # edge id -> cost it had before removal
        self.version = 0
        self._log: list[tuple[int, int, float, float]] = []  # (version, edge, old, new)
        #: entries the change log keeps at most (module doc); four full re-costs of the map
        self.log_limit = max(4 * N * N, 4096)
        #: oldest version :meth:`changes_since` can answer for
        self.log_floor = 0
        for i in range(self.num_region_nodes):
            for j in range(self.num_region_nodes):
                if i != j:
                    self._cost[i * N + j] = self.initial_cost(self.nodes[i], self.nodes[j])
        if self.has_start:
            self._set_start(start)

    # ---- construction helpers -----------------------------------------------------------
    @classmethod
    def from_world(cls, world, *, n_orient: int = 8, w: float = 0.1, start="world") -> "NavigationMap":
        """Map of a :class:`navigation.world.World` (or a world name / path for
        :func:`navigation.load_world`); ``start="world"`` uses ``world.robot.start``."""
        if isinstance(world, str) or hasattr(world, "__fspath__"):
            import navigation

            world = navigation.load_world(world)
        if isinstance(start, str) and start == "world":
            start = tuple(world.robot.start)
        return cls(world.regions, n_orient=n_orient, w=w, start=start)

    def initial_cost(self, u: NodeLike, v: NodeLike) -> float:
        """``|g - g'| + w |theta - theta'|`` (section 4.1.1 of [1]_) for region nodes or START."""
        u, v = self.node(u), self.node(v)
        (x0, y0), t0 = self._pose(u)
        (x1, y1), t1 = self._pose(v)
        return math.hypot(x1 - x0, y1 - y0) + self.w * _angle_gap(t0, t1)

    def _pose(self, n: Node):
        if n.region == START:
            x, y, t = self.start_pose
            return (x, y), t
        return self.centers[n.region], self.thetas[n.k]

    def _set_start(self, start) -> None:
        try:
            vals = [float(v) for v in start]
        except (TypeError, ValueError) as err:
            raise InvalidRequestError(f"start pose must be (x, y) or (x, y, theta), got {start!r}") from err
        if len(vals) == 2:
            vals.append(0.0)
        if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
            raise InvalidRequestError(f"start pose must be 2 or 3 finite numbers, got {start!r}")
        self.start_pose = (vals[0], vals[1], vals[2])
        N = self.num_nodes
        s = self.index[Node(START, 0)]
        changes = {}
        for j in range(self.num_region_nodes):
            e = s * N + j
            changes[e] = self.initial_cost(self.nodes[s], self.nodes[j])
            self._removed.pop(e, None)
        self._apply(changes)

    # ---- queries ------------------------------------------------------------------------
    def node(self, n: NodeLike) -> Node:
        """Validate and normalise a node (a :class:`Node` or ``(region, k)`` pair)."""
        if isinstance(n, tuple) and len(n) == 2:
            n = Node(*n)
            if n in self.index:
                return n
            if n.region in self.centers or n.region == START:
                raise InvalidRequestError(f"orientation index {n.k!r} of {n.region!r} is not in "
                                          f"0..{self.n_orient - 1}" if n.region != START else
                                          f"the map has no start node {n!r}")
            raise UnknownRegionError([str(n.region)], self.regions)
        if isinstance(n, str):
            raise InvalidRequestError(f"expected a node (region, k), got the region name {n!r}")
        raise InvalidRequestError(f"expected a node (region, k), got {n!r}")

    def region_nodes(self, region: str) -> tuple[Node, ...]:
        """The ``n_orient`` nodes of ``region`` (UnknownRegionError otherwise)."""
        if region == START and self.has_start:
            return (Node(START, 0),)
        if region not in self._region_index:
            raise UnknownRegionError([str(region)], self.regions)
        return tuple(Node(region, k) for k in range(self.n_orient))

    def nearest_orientation(self, theta: float) -> int:
        """Index ``k`` of the orientation closest to ``theta``."""
        return min(range(self.n_orient), key=lambda k: (_angle_gap(theta, self.thetas[k]), k))

    def cost(self, u: NodeLike, v: NodeLike) -> float:
        """Current cost of the edge ``u -> v`` (``inf`` when removed or absent)."""
        i, j = self.index[self.node(u)], self.index[self.node(v)]
        return self._cost[i * self.num_nodes + j]

    def is_removed(self, u: NodeLike, v: NodeLike) -> bool:
        i, j = self.index[self.node(u)], self.index[self.node(v)]
        return i * self.num_nodes + j in self._removed

    @property
    def costs(self) -> list[float]:
        """The flattened cost matrix (edge id ``i * N + j``); read-only by convention."""
        return self._cost

    @property
    def removed(self) -> dict[int, float]:
        """Removed edge ids -> the cost they had before removal (read-only by convention)."""
        return self._removed

    def edge(self, e: int) -> tuple[Node, Node]:
        """The nodes of edge id ``e``."""
        i, j = divmod(e, self.num_nodes)
        return self.nodes[i], self.nodes[j]

    def edges(self) -> Iterable[tuple[Node, Node, float]]:
        """Every structural edge with its current cost (removed ones with ``inf``)."""
        N = self.num_nodes
        for i in range(N):
            for j in range(N):
                c = self._cost[i * N + j]
                if c < INF or i * N + j in self._removed:
                    yield self.nodes[i], self.nodes[j], c

    @property
    def num_edges(self) -> int:
        """Structural edges (removed ones included)."""
        r = self.num_region_nodes
        return r * (r - 1) + (r if self.has_start else 0)

    def changes_since(self, version: int) -> dict[int, tuple[float, float]] | None:
        """Edges whose cost differs from what it was at ``version``: ``{edge id: (then, now)}``;
        ``None`` when ``version`` is older than the bounded log keeps (``log_floor``, module
        doc): the caller must treat every edge as changed."""
        if version >= self.version:
            return {}
        if version < self.log_floor:
            return None
        out: dict[int, tuple[float, float]] = {}
        # the log is ordered by version; walk back to the first entry after `version`
        lo = len(self._log)
        while lo > 0 and self._log[lo - 1][0] > version:
            lo -= 1
        for _, e, old, _new in self._log[lo:]:
            if e not in out:
                out[e] = old
        return {e: (old, self._cost[e]) for e, old in out.items() if old != self._cost[e]}

    # ---- changes (section 4.2.4) --------------------------------------------------------
    def _pairs(self, u, v, symmetric: bool) -> list[int]:
        """Edge ids between ``u`` and ``v``: nodes, or region names (all orientation pairs)."""
        us = self.region_nodes(u) if isinstance(u, str) else (self.node(u),)
        vs = self.region_nodes(v) if isinstance(v, str) else (self.node(v),)
        N = self.num_nodes
        out = []
        for a in us:
            for b in vs:
                i, j = self.index[a], self.index[b]
                if i == j:
                    continue
                if b.region == START:
                    raise InvalidRequestError("no edge leads into the start node")
                out.append(i * N + j)
                if symmetric and a.region != START:
                    out.append(j * N + i)
        if not out:
            raise InvalidRequestError(f"no edge between {u!r} and {v!r}")
        return out

    def _apply(self, changes: Mapping[int, float]) -> int:
        changed = 0
        for e, c in changes.items():
            old = self._cost[e]
            if old != c:
                if changed == 0:
                    self.version += 1
                self._log.append((self.version, e, old, c))
                self._cost[e] = c
                changed += 1
        if len(self._log) > self.log_limit:
            self._trim_log()
        return changed

    def _trim_log(self) -> None:
        """Drop the log's older half, whole versions at a time (a version's entries are
        contiguous); :meth:`changes_since` answers from ``log_floor`` on."""
        v = self._log[len(self._log) // 2][0]
        k = len(self._log) // 2
        while k < len(self._log) and self._log[k][0] <= v:
            k += 1
        del self._log[:k]
        self.log_floor = v

    def set_cost(self, u, v, cost: float, *, symmetric: bool = True) -> int:
        """Set the cost of ``u -> v`` (and ``v -> u`` when ``symmetric``); returns the number of
        edges whose cost changed.

        ``u`` and ``v`` are nodes, or region names meaning every orientation pair, in which
        case ``cost`` is the translational part and each pair gets
        ``cost + w |theta - theta'|``. A removed edge is restored by setting its cost.

        Raises
        ------
        InvalidRequestError
            ``cost`` is not a finite number >= 0, or there is no such edge.
        UnknownRegionError
            A region name that is not in the map.
        """
        try:
            c = float(cost)
        except (TypeError, ValueError) as err:
            raise InvalidRequestError(f"edge cost must be a number, got {cost!r}") from err
        if not (math.isfinite(c) and c >= 0):
            raise InvalidRequestError(f"edge cost must be finite and >= 0, got {cost!r} "
                                      "(use remove_edge for a blocked transition)")
        per_region = isinstance(u, str) or isinstance(v, str)
        changes = {}
        for e in self._pairs(u, v, symmetric):
            a, b = self.edge(e)
            ce = c + self.w * _angle_gap(self._pose(a)[1], self._pose(b)[1]) if per_region else c
            changes[e] = ce
            self._removed.pop(e, None)
        return self._apply(changes)

    def remove_edge(self, u, v, *, symmetric: bool = True) -> int:
        """Remove (block) ``u -> v`` (and ``v -> u``); nodes or region names as in
        :meth:`set_cost`. Returns the number of edges newly removed."""
        changes = {}
        for e in self._pairs(u, v, symmetric):
            if e not in self._removed:
                self._removed[e] = self._cost[e]
                changes[e] = INF
        return self._apply(changes)

    def restore_edge(self, u, v, *, symmetric: bool = True) -> int:
        """Restore removed edges with the cost they had when removed; returns how many."""
        changes = {}
        for e in self._pairs(u, v, symmetric):
            if e in self._removed:
                changes[e] = self._removed.pop(e)
        return self._apply(changes)

    def move_start(self, pose) -> None:
        """Move the virtual start node to ``pose`` (its edges get their initial costs back)."""
        if not self.has_start:
            raise InvalidRequestError("this map has no start node (build it with start=...)")
        self._set_start(pose)

    def region_pair(self, e: int) -> tuple[str, str]:
        """Region names of edge id ``e`` (``"@start"`` for the start node)."""
        a, b = self.edge(e)
        return a.region, b.region

    def __repr__(self) -> str:
        return (f"NavigationMap({len(self.regions)} regions x {self.n_orient} orientations, "
                f"w={self.w}, start={self.start_pose}, removed={len(self._removed)}, "
                f"version={self.version})")
