"""Mission planning: lasso plans in the product of the navigation map and the mission automaton.

Implements paper 001 [1]_ section 4.1.1 (product and nested-Dijkstra prefix-suffix plan),
section 4.2.4 (re-planning from the current product state as the map changes) and the run-time
mission changes of section 5.2 (an urgent request served first), plus ``replace`` and ``add``
(FORMATS.md ``events[].mode``).

Symbols
-------
==========  ==================================================================
``G``       navigation map (:class:`tamp.navmap.NavigationMap`)
``A_phi``   mission automaton (:class:`tamp.ltl.Buchi`)
``A^``      product ``G x A_phi`` (:class:`tamp.product.Product`)
``alpha``   weight of the suffix cost: a plan minimises ``prefix + alpha * suffix``
==========  ==================================================================

References
----------
.. [1] Wang and Guo, "Harmonic trees for LTL tasks in unknown environments", 2025 (paper 001).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from navigation.errors import TampError

from ._product_kernel import settle
from .errors import (InvalidRequestError, NoPlanError, UnknownRegionError, brief,
                     UnsatisfiableError)
from .ltl import ops
from .ltl.automaton import Buchi
from .navmap import START, NavigationMap, Node
from .product import Product

__all__ = ["MissionPlanner", "MissionMode", "Plan"]

INF = math.inf

#: Why a mission is unsatisfiable once translated over disjoint regions (``UnsatisfiableError``).
_DISJOINT = "the regions are disjoint: the robot is in one region at a time at most"


class MissionMode(str, Enum):
    """How a new mission combines with the active one (FORMATS.md ``events[].mode``)."""

    REPLACE = "replace"
    ADD = "add"
    URGENT = "urgent"

    @classmethod
    def parse(cls, value) -> "MissionMode":
        """The mode named ``value`` (a member or its string value).

        Raises
        ------
        InvalidRequestError
            Listing the valid modes.
        """
        if isinstance(value, cls):
            return value
        v = getattr(value, "value", value)  # e.g. navigation.world.EventMode
        try:
            return cls(v)
        except ValueError:
            valid = ", ".join(repr(m.value) for m in cls)
            raise InvalidRequestError(f"{value!r} is not a valid mission mode, must be one of {valid}") from None


def _merge(regions: Iterable[str]) -> tuple[str, ...]:
    out: list[str] = []
    for r in regions:
        if not out or out[-1] != r:
            out.append(r)
    return tuple(out)


@dataclass(frozen=True)
class Plan:
    """A lasso plan ``urgent . prefix . suffix^omega`` over map nodes.

    Attributes
    ----------
    prefix : tuple of Node
        From the node where the main mission's plan starts (the current node, or the end of
        ``urgent``) to the accepting product state, both included.
    suffix : tuple of Node
        The cycle after the accepting state, ending with it again (``suffix[-1] == prefix[-1]``,
        ``len(suffix) >= 1``); repeated forever.
    prefix_cost, suffix_cost : float
        Sums of map edge costs along ``prefix`` and along the cycle.
    alpha : float
        The planner's suffix weight; ``cost = urgent_cost + prefix_cost + alpha * suffix_cost``.
    prefix_states, suffix_states : tuple of (Node, int)
        The product states (node, main-automaton state) along ``prefix`` / ``suffix``.
    urgent : tuple of Node
        Path serving the pending urgent request first, from the current node to the node where
        it is served (both included), or ``()``; ``prefix[0] == urgent[-1]`` then.
    urgent_cost : float
    """

    prefix: tuple[Node, ...]
    suffix: tuple[Node, ...]
    prefix_cost: float
    suffix_cost: float
    alpha: float
    prefix_states: tuple[tuple[Node, int], ...]
    suffix_states: tuple[tuple[Node, int], ...]
    urgent: tuple[Node, ...] = ()
    urgent_cost: float = 0.0

    @property
    def cost(self) -> float:
        """``urgent_cost + prefix_cost + alpha * suffix_cost`` (what the planner minimises,
        the urgent part first)."""
        return self.urgent_cost + self.prefix_cost + self.alpha * self.suffix_cost

    @property
    def route(self) -> tuple[Node, ...]:
        """Nodes to visit from the current one (excluded): urgent part, then prefix; the suffix
        follows forever."""
        return self.urgent[1:] + self.prefix[1:]

    @property
    def urgent_regions(self) -> tuple[str, ...]:
        """Regions of ``urgent`` after the current node (rotations in place merged)."""
        return _merge(n.region for n in self.urgent[1:])

    @property
    def prefix_regions(self) -> tuple[str, ...]:
        """Regions to visit for the prefix, after its first node (rotations merged)."""
        return _merge(n.region for n in self.prefix[1:])

    @property
    def suffix_regions(self) -> tuple[str, ...]:
        """Regions of one round of the suffix cycle (rotations merged)."""
        return _merge(n.region for n in self.suffix)

    def to_dict(self) -> dict:
        """JSON-ready summary (FORMATS.md ``status.plan``: prefix and suffix region sequences)."""
        return {"urgent": list(self.urgent_regions), "prefix": list(self.prefix_regions),
                "suffix": list(self.suffix_regions), "cost": self.cost,
                "prefix_cost": self.prefix_cost, "suffix_cost": self.suffix_cost,
                "urgent_cost": self.urgent_cost, "alpha": self.alpha}


# ---- search core (pure functions over a product and a cost vector) --------------------------
@dataclass
class _Cycle:
    """Result of one cycle search from an accepting product state ``a``."""

    cost: float | None          # exact cheapest cycle cost (inf: none), None when aborted
    lower: float                # lower bound on the cycle cost (== cost when exact)
    path: tuple[int, ...]       # product states after a, ending with a (exact only)
    used: frozenset[int]        # map edge ids on the path
    settled: frozenset[int]     # map nodes whose out-edges the search scanned


def _cycle(prod: Product, costs, a: int, bound: float) -> _Cycle:
    """Cheapest cycle ``a -> ... -> a`` (at least one edge); gives up (``cost=None``) once the
    frontier reaches ``bound``."""
    Q, N = prod.Q, prod.N
    size = N * Q
    dist = [INF] * size
    pred = [-1] * size
    n0, q0 = divmod(a, Q)
    settled = {n0}
    heap = []
    base = n0 * N
    for t, n2 in prod.row(q0):
        c = costs[base + n2]
        if c < dist[t]:
            dist[t] = c
            pred[t] = a
            heap.append((c, t))
    heapq.heapify(heap)
    row = prod.row
    while heap:
        d, s = heapq.heappop(heap)
        if d > dist[s]:
            continue
        if s == a:
            path = [a]
            cur = pred[a]
            while cur != a:
                path.append(cur)
                cur = pred[cur]
            path.reverse()
            nodes = [a // Q] + [p // Q for p in path]
            used = frozenset(nodes[i] * N + nodes[i + 1] for i in range(len(nodes) - 1))
            return _Cycle(d, d, tuple(path), used, frozenset(settled))
        if d >= bound:
            return _Cycle(None, d, (), frozenset(), frozenset(settled))
        n, q = divmod(s, Q)
        settled.add(n)
        base = n * N
        for t, n2 in row(q):
            nd = d + costs[base + n2]
            if nd < dist[t]:
                dist[t] = nd
                pred[t] = s
                heapq.heappush(heap, (nd, t))
    return _Cycle(INF, INF, (), frozenset(), frozenset(settled))


@dataclass
class _Lasso:
    prefix: tuple[int, ...]
    prefix_cost: float
    cycle: _Cycle
    cycles_computed: int = 0
    cycles_reused: int = 0


def _nested_dijkstra(prod: Product, costs, sources: Iterable[int], alpha: float,
                     cache: dict[int, _Cycle] | None) -> _Lasso | None:
    """Nested Dijkstra of [1]_ section 4.1.1: Dijkstra from ``sources`` over the product; each
    accepting state ``a`` met (in order of prefix cost ``P(a)``) gets its cheapest cycle
    ``C(a)`` (second Dijkstra, cached in ``cache``); returns the minimiser of
    ``P(a) + alpha * C(a)``. The outer search stops once ``P >= best`` and each cycle search
    once ``P(a) + alpha * C >= best`` (costs are >= 0), which never changes the optimum. The
    outer search is compiled (:func:`tamp._product_kernel.settle`, run to the end); its
    accepting states are walked here in the order it settled them, up to that stop."""
    Q, N = prod.Q, prod.N
    ptr, row_t, row_n, accepting = prod.row_arrays()
    c = np.asarray(costs, dtype=float)
    if c.shape != (N * N,):
        raise TampError(f"expected {N * N} map edge costs, got {c.shape}")
    # the outer Dijkstra, compiled, settles every state; the accepting ones are taken here in
    # the order it settled them, and the walk stops where the search would (P >= best)
    dist, pred, order = settle(ptr, row_t, row_n, c, Q, N, np.asarray(list(sources), dtype=np.int64), accepting)
    best, best_a, best_cycle = INF, -1, None
    computed = reused = 0
    for s in order.tolist():
        d = float(dist[s])
        if d >= best:
            break
        bound = (best - d) / alpha if alpha > 0 else INF
        cyc = cache.get(s) if cache is not None else None
        if cyc is not None and (cyc.cost is not None or cyc.lower >= bound):
            reused += 1
        else:
            cyc = _cycle(prod, costs, s, bound)
            computed += 1
            if cache is not None:
                cache[s] = cyc
        if cyc.cost is not None and cyc.cost < INF and d + alpha * cyc.cost < best:
            best, best_a, best_cycle = d + alpha * cyc.cost, s, cyc
    if best_cycle is None:
        return None
    path = [best_a]
    while pred[path[-1]] != -1:
        path.append(int(pred[path[-1]]))
    path.reverse()
    return _Lasso(tuple(path), float(dist[best_a]), best_cycle, computed, reused)


def _invalidated(cyc: _Cycle, changes: Mapping[int, tuple[float, float]], N: int) -> bool:
    """Whether map changes (edge -> (old, new)) can change a cached cycle result.

    Exact result: invalid when an edge on its path got dearer, or an edge leaving a node it
    scanned got cheaper (any path through an unscanned edge costs at least the found cycle).
    Aborted result (lower bound): invalid when a scanned edge got cheaper.
    """
    for e, (old, new) in changes.items():
        if new > old:
            if cyc.cost is not None and e in cyc.used:
                return True
        elif e // N in cyc.settled:
            return True
    return False


# ---- mission bookkeeping ---------------------------------------------------------------------
@dataclass(eq=False)  # identity: the plan cache's key holds the mission itself
class _Mission:
    text: str
    buchi: Buchi
    product: Product
    letters: frozenset[int]
    cycles: dict[int, _Cycle] = field(default_factory=dict)
    done: frozenset[int] = frozenset()  # universal states (every continuation accepted)


def _new_mission(text: str, buchi: Buchi, navmap: NavigationMap, letters: frozenset[int]) -> _Mission:
    return _Mission(text, buchi, Product(navmap, buchi), letters, done=ops.universal_states(buchi, letters))


@dataclass(eq=False)  # identity, as _Mission
class _Urgent:
    text: str
    buchi: Buchi
    done: frozenset[int]
    states: frozenset[int]


class MissionPlanner:
    """Plans and re-plans an LTL mission over a navigation map (paper 001 sections 4.1.1, 4.2.4,
    5.2). The one stateful object of the mission layer.

    Parameters
    ----------
    world : World, str, path or mapping
        A :class:`navigation.world.World`, a world name / file for :func:`navigation.load_world`
        (its ``regions``, ``robot.start`` and ``task`` are used), or a mapping region name ->
        centre (``(x, y)``, a ``Region`` or ``{"center": ...}``).
    formula : str, Formula or Buchi, optional
        The mission (LTL over region names, FORMATS.md syntax, or an automaton whose APs are
        region names). Default: the world's ``task``; no mission when there is none.
    n_orient : int, default 8
        Orientations per region (``theta_k = 2 pi k / n_orient``).
    w : float, default 0.1
        Rotation weight of the initial cost ``|g - g'| + w |theta - theta'|``.
    alpha : float, default 1.0
        Suffix weight: plans minimise ``prefix cost + alpha * suffix cost``.
    start : optional
        Where the robot is: a region name (orientation 0), a :class:`Node`, or a pose
        ``(x, y[, theta])``. A pose inside a region disc (radii known from a world or region
        dicts) starts at that region's nearest orientation node, otherwise at the virtual start
        node. Default: the world's ``robot.start``; for a bare mapping, the first region.

    Conventions
    -----------
    Product states carry the automaton state after reading the current node's label (see
    :mod:`tamp.product`). A mission given while the robot is in a region is evaluated on the
    trace that starts with that region (the region's letter is read at once); at the virtual
    start node the trace starts with the next region reached.

    Plans
    -----
    :meth:`plan` returns the :class:`Plan` minimising ``prefix + alpha * suffix`` from the
    current product states, found by the nested Dijkstra of section 4.1.1: a Dijkstra over the
    product from the current states; every accepting product state ``a`` it settles gets its
    cheapest cycle by a second Dijkstra; the best ``P(a) + alpha C(a)`` wins. Both searches
    stop as soon as they cannot improve the best lasso found so far.

    Re-planning (section 4.2.4)
    ---------------------------
    Change the map with :meth:`set_cost`, :meth:`remove_edge`, :meth:`restore_edge` (or on
    :attr:`navmap` directly), then call :meth:`replan` (same as :meth:`plan`). Reused:

    * the product structure (:class:`~tamp.product.Product` rows): it never depends on costs
      or removals, so it survives every map change and every :meth:`advance`;
    * the letter -> successor tables of the automaton (cached in the :class:`Buchi`);
    * the cycle result of every accepting product state computed before (whatever the current
      state was), unless a changed edge can affect it: an exact cycle is dropped when an edge
      on it got dearer or was removed, or when an edge leaving a map node its search scanned
      got cheaper or was restored; a pruned (lower-bound) result only in the latter case;
    * the plan itself when neither the map nor the current state changed.

    The prefix Dijkstra is re-run from the current states (it stops at the best lasso cost).
    ``last_stats`` tells how many cycle searches ran and how many were reused.

    One run of the automaton (recurrent missions)
    ---------------------------------------------
    The automaton is nondeterministic, so a trace leads to a *set* of states. A plan picks one
    of them and a lasso from it; planning afresh from the whole set at every region would let
    each plan pick a different run, and a robot that follows every plan's first step need not
    follow any accepting run: on ``office`` with ``G F p1 & G F d1 & G F d3`` the plans took
    turns between two runs, each of which had "already" visited the region the other still
    owed, and the robot went between ``p1`` and ``d3`` for good, never to ``d1`` again. So
    :meth:`advance` *commits*: arriving at the region the plan goes to next, the states become
    the plan's state there (with any universal state the trace also reached: a co-safe mission
    is done as soon as one run is). Every later plan then extends the same run, and arriving
    at the lasso's accepting state is an accepting visit of that run. The uncommitted set is
    kept (:attr:`reachable`): when no lasso starts from the committed state (the map changed),
    :meth:`plan` plans from the whole set instead, and ``add`` conjoins with it.

    Mission changes (section 5.2 and FORMATS.md events)
    ---------------------------------------------------
    :meth:`request` with a :class:`MissionMode` (or its string):

    * ``replace``: the new mission from now on;
    * ``add``: conjunction with what remains of the current mission, progress kept. The
      current automaton restarted in its current state set (:func:`tamp.ltl.ops.from_states`)
      is intersected (:func:`tamp.ltl.ops.intersect`, two-copy flag product) with the new
      formula's automaton started on the current region. Chosen over translating
      ``old & new`` from scratch because the remaining obligations of the old formula are
      exactly its automaton's current states; re-translating would need to map progress
      between unrelated automata, which is not possible in general;
    * ``urgent``: a co-safe request (e.g. ``F u1``) served first, from the current position,
      by the cheapest path in the product of the map with the urgent automaton *and* the main
      one (the main automaton is tracked along it, as the trace really visits those regions;
      its end state must stay live). It ends at a product state where the urgent automaton is
      in a universal state (every continuation accepted,
      :func:`tamp.ltl.ops.universal_states`); the main mission then resumes from its
      automaton state there. Several urgent requests are served first-come first-served.

    Every request is checked and planned before it is committed: if it is refused (any error
    below) the previous mission stays active.

    Progress
    --------
    :meth:`advance` as the robot reaches a region (or node) reads its label in the main and
    urgent automata; :meth:`set_position` moves the robot to a free pose (virtual start node).

    Raises
    ------
    LtlSyntaxError
        The formula does not parse (``position`` points at the problem).
    UnknownRegionError
        The formula names regions that are not in the map (``names``).
    UnsatisfiableError
        No word over the map's letters (one region at a time) satisfies the mission, or an
        ``add`` contradicts what remains of the current mission.
    NoPlanError
        No accepting lasso from the current state in the current map; ``blocked`` lists the
        removed transitions (region pairs) that a plan would need, found by planning on the
        map with removed edges restored at a large penalty.
    InvalidRequestError
        Bad mode, bad parameters, or an urgent request that is not co-safe.

    Examples
    --------
    >>> p = MissionPlanner({"a": (0, 0), "b": (4, 0), "c": (0, 3)}, "G F b & G F c", start="a")
    >>> p.plan().prefix_regions, p.plan().suffix_regions
    (('b', 'c'), ('b', 'c'))
    >>> p.remove_edge("b", "c")  # 8 x 8 orientation pairs, both directions
    128
    >>> p.replan().suffix_regions
    ('a', 'b', 'a', 'c')
    """

    def __init__(self, world, formula=None, *, n_orient: int = 8, w: float = 0.1,
                 alpha: float = 1.0, start=None):
        alpha_f = float(alpha)
        if not (math.isfinite(alpha_f) and alpha_f >= 0):
            raise InvalidRequestError(f"alpha must be finite and >= 0, got {alpha!r}")
        self.alpha = alpha_f
        task = None
        if isinstance(world, str) or hasattr(world, "__fspath__"):
            import navigation

            world = navigation.load_world(world)
        if hasattr(world, "regions") and hasattr(world, "robot"):
            regions = world.regions
            task = getattr(world, "task", None) or None
            if start is None:
                start = tuple(world.robot.start)
        elif isinstance(world, Mapping):
            regions = world
        else:
            raise InvalidRequestError(f"expected a world or a mapping of regions, got {type(world).__name__}")
        self._radii = {}
        for name, r in regions.items():
            rad = getattr(r, "radius", None)
            if rad is None and isinstance(r, Mapping):
                rad = r.get("radius")
            if rad is not None:
                self._radii[name] = float(rad)
        pose = None
        if start is None:
            start = next(iter(regions))
        if not isinstance(start, str) and not isinstance(start, Node):
            pose = start
        self.navmap = NavigationMap(regions, n_orient=n_orient, w=w, start=pose)
        self._node = self._resolve_start(start)
        self._mission: _Mission | None = None
        self._states: frozenset[int] = frozenset()     # the committed run's state(s) (class doc)
        self._reachable: frozenset[int] = frozenset()  # every state the trace leads to
        self._urgent: list[_Urgent] = []
        self._violated: str | None = None
        self._seen_version = self.navmap.version
        self._plan_key = None
        self._plan: Plan | None = None
        self.visited: list[str] = []
        self.last_stats: dict = {}
        if formula is None:
            formula = task
        if formula is not None:
            self.request(formula, MissionMode.REPLACE)

    # ---- regions changed at run time -------------------------------------------------------
    def with_regions(self, regions, *, pose, moved=(), check=None) -> "MissionPlanner":
        """A planner over ``regions`` (a mapping name -> region) that carries this one's mission
        on: the mission and urgent requests with their automaton states, the violation flag, the
        visited trace and the robot's node (kept when its region did not move, else the start
        node at ``pose``). The product is rebuilt over the new map; automata and their states do
        not depend on the map. ``self`` is not changed.

        ``check(text, buchi, states, letters, old_letters, urgent)``, if given, is called for the
        mission (``urgent=False``) and for each urgent request (``urgent=True``) with the
        automaton's singleton letters over the new and the old region names, and may raise to
        refuse the change (the executive's alphabet rule).
        """
        planner = MissionPlanner(regions, None, n_orient=self.navmap.n_orient, w=self.navmap.w, alpha=self.alpha,
                                 start=pose)
        node = self.node
        if node.region != START and node.region not in set(moved):
            planner._node = planner.navmap.index[node]
        else:
            planner.set_position(pose)
        names, old_names = planner.navmap.regions, self.navmap.regions
        m = self._mission
        if m is not None:
            letters = ops.singleton_letters(m.buchi, names)
            if check is not None:
                check(m.text, m.buchi, self._states, letters, m.letters, False)
            planner._mission = _new_mission(m.text, m.buchi, planner.navmap, letters)
            planner._states, planner._reachable = self._states, self._reachable
            planner._violated = self._violated
        for u in self._urgent:  # urgent requests survive every mode, replace included
            letters = ops.singleton_letters(u.buchi, names)
            if check is not None:
                check(u.text, u.buchi, u.states, letters, ops.singleton_letters(u.buchi, old_names), True)
            planner._urgent.append(_Urgent(u.text, u.buchi, ops.universal_states(u.buchi, letters), u.states))
        planner.visited = list(self.visited)
        planner._seen_version = planner.navmap.version
        return planner

    # ---- positions ------------------------------------------------------------------------
    def _resolve_start(self, start) -> int:
        m = self.navmap
        if isinstance(start, Node) or (isinstance(start, tuple) and len(start) == 2 and isinstance(start[0], str)):
            return m.index[m.node(start)]
        if isinstance(start, str):
            return m.index[m.region_nodes(start)[0]]
        x, y, theta = m.start_pose
        for name, rad in self._radii.items():
            cx, cy = m.centers[name]
            if math.hypot(x - cx, y - cy) <= rad:
                return m.index[Node(name, m.nearest_orientation(theta))]
        return m.index[Node(START, 0)]

    @property
    def node(self) -> Node:
        """The map node the robot is at (last region reached, or the start node)."""
        return self.navmap.nodes[self._node]

    @property
    def mission(self) -> str | None:
        """Text of the active mission (``None`` when there is none)."""
        return self._mission.text if self._mission else None

    @property
    def automaton(self) -> Buchi | None:
        """The active mission's automaton (after ``add``: the intersection)."""
        return self._mission.buchi if self._mission else None

    @property
    def product(self) -> Product | None:
        return self._mission.product if self._mission else None

    @property
    def current(self) -> tuple[tuple[Node, int], ...]:
        """Current product states ``(node, q)`` of the main mission."""
        return tuple((self.node, q) for q in sorted(self._states))

    @property
    def done_states(self) -> frozenset[int]:
        """The main automaton's universal states (every continuation accepted: a co-safe
        mission is done in one of them); empty without a mission or for a recurrent one."""
        return self._mission.done if self._mission is not None else frozenset()

    @property
    def reachable(self) -> frozenset[int]:
        """Every main-automaton state the trace so far leads to (:attr:`current` holds the
        committed run's; class doc, "One run of the automaton")."""
        return self._reachable

    @property
    def pending_urgent(self) -> tuple[str, ...]:
        """Texts of the urgent requests not yet served, in serving order."""
        return tuple(u.text for u in self._urgent)

    def _letter(self, buchi: Buchi, n: int) -> int | None:
        r = self.navmap.node_region[n]
        return None if r < 0 else buchi.mask([self.navmap.regions[r]])

    def _read(self, buchi: Buchi, states: Iterable[int], n: int) -> frozenset[int]:
        m = self._letter(buchi, n)
        if m is None:
            return frozenset(states)
        out: set[int] = set()
        for q in states:
            out.update(buchi.successors(q, m))
        return frozenset(out)

    def advance(self, target, theta: float | None = None) -> tuple[tuple[Node, int], ...]:
        """The robot reached ``target`` (a region name or a :class:`Node`): read its label.

        With a region name the node is the one of orientation nearest ``theta``, or, without
        ``theta``, the node of that region the current plan enters next (orientation 0 if it
        has none). Returns the new :attr:`current` product states. When the main automaton has
        no successor the mission is violated: :meth:`plan` then raises :class:`NoPlanError`
        until a mission is replaced.
        """
        m = self.navmap
        if isinstance(target, str):
            nodes = m.region_nodes(target)
            if theta is not None:
                node = Node(target, m.nearest_orientation(float(theta)))
            else:
                node = nodes[0]
                if self._plan is not None:
                    for n in self._plan.route + self._plan.suffix:
                        if n.region == target:
                            node = n
                            break
        else:
            node = m.node(target)
            if node.region == START:
                raise InvalidRequestError("advance: use set_position to move to a free pose")
        expected = self._expected_state(node.region)
        n = m.index[node]
        self._node = n
        self.visited.append(node.region)
        if self._mission is not None and self._violated is None:
            buchi = self._mission.buchi
            self._reachable = self._read(buchi, self._reachable, n)
            states = self._read(buchi, self._states, n)
            if expected is not None and expected in states:
                # commit to the plan's run (class doc); a universal state stays: done is done
                states = frozenset((expected,)) | (states & self._mission.done)
            self._states = states or self._reachable
            if not self._reachable:
                self._violated = node.region
        for u in self._urgent:
            u.states = self._read(u.buchi, u.states, n)
        # a request is served once one of its runs is in a universal state (also "in passing")
        self._urgent = [u for u in self._urgent if not (u.states & u.done)]
        return self.current

    def _expected_state(self, region: str) -> int | None:
        """The main-automaton state the current plan has at its next node, when that node is
        in ``region``; ``None`` otherwise (no plan, an urgent path still before its end, or the
        robot entered a region the plan does not go to next)."""
        p = self._plan
        if p is None or self._plan_key is None or self._plan_key[1] != self._node:
            return None
        if len(p.urgent) > 1:
            # the main states along an urgent path are not the plan's; its end is prefix[0]
            nxt = p.prefix_states[0] if len(p.urgent) == 2 else None
        elif len(p.prefix_states) > 1:
            nxt = p.prefix_states[1]
        else:
            nxt = p.suffix_states[0] if p.suffix_states else None
        if nxt is None or nxt[0].region != region:
            return None
        return nxt[1]

    def set_position(self, pose) -> None:
        """The robot is at the free pose ``(x, y[, theta])`` (between regions): it becomes the
        virtual start node (its edges get their initial costs), automaton states unchanged.
        Requires a planner built with a start pose."""
        self.navmap.move_start(pose)
        self._node = self.navmap.index[Node(START, 0)]

    # ---- map changes (section 4.2.4) ------------------------------------------------------
    def set_cost(self, u, v, cost: float, *, symmetric: bool = True) -> int:
        """:meth:`NavigationMap.set_cost` on the planner's map."""
        return self.navmap.set_cost(u, v, cost, symmetric=symmetric)

    def remove_edge(self, u, v, *, symmetric: bool = True) -> int:
        """:meth:`NavigationMap.remove_edge` on the planner's map (a blocked transition)."""
        return self.navmap.remove_edge(u, v, symmetric=symmetric)

    def restore_edge(self, u, v, *, symmetric: bool = True) -> int:
        """:meth:`NavigationMap.restore_edge` on the planner's map."""
        return self.navmap.restore_edge(u, v, symmetric=symmetric)

    def _sync(self) -> None:
        """Drop the cached cycle results that map changes since the last sync may affect."""
        m = self.navmap
        if m.version == self._seen_version:
            return
        changes = m.changes_since(self._seen_version)
        self._seen_version = m.version
        if self._mission is None or not changes:
            if changes is None and self._mission is not None:
                self._mission.cycles.clear()  # older than the map's log keeps: all may have changed
            return
        N = m.num_nodes
        cache = self._mission.cycles
        for a in [a for a, c in cache.items() if _invalidated(c, changes, N)]:
            del cache[a]

    # ---- missions -------------------------------------------------------------------------
    def _compile(self, formula) -> tuple[str, Buchi, frozenset[int]]:
        """Parse, check region names, translate, check satisfiability; returns the text, the
        trimmed automaton and its letters."""
        known = self.navmap.regions
        if isinstance(formula, Buchi):
            buchi, text = formula, formula.name or "<automaton>"
            aps = set(buchi.aps)
        else:
            from .ltl import syntax, translate

            f = syntax.parse(formula)
            text = str(f)
            aps = set(f.aps)
            unknown = aps - set(known)
            if unknown:
                raise UnknownRegionError(unknown, known)
            # regions are disjoint discs: one region at a time (translate.py, step 0), which
            # keeps visiting n regions polynomial in the alphabet instead of 2^n letters
            buchi = translate.to_buchi(f, exclusive=True)
        unknown = aps - set(known)
        if unknown:
            raise UnknownRegionError(unknown, known)
        letters = ops.singleton_letters(buchi, known)
        if not buchi.accepting:
            raise UnsatisfiableError(text, "its automaton has no accepting state" if isinstance(formula, Buchi)
                                     else _DISJOINT)
        if ops.is_empty(buchi, letters):
            raise UnsatisfiableError(text, _DISJOINT)
        return text, ops.trim(buchi, letters), letters

    def _initial_states(self, buchi: Buchi) -> frozenset[int]:
        return self._read(buchi, (buchi.initial,), self._node)

    def request(self, formula, mode=MissionMode.REPLACE) -> Plan:
        """Apply a mission change and return the new plan (the previous mission stays active
        when this raises). ``mode`` is a :class:`MissionMode` or ``"replace"``, ``"add"``,
        ``"urgent"``."""
        mode = MissionMode.parse(mode)
        if mode is MissionMode.URGENT:
            return self._request_urgent(formula)
        text, buchi, letters = self._compile(formula)
        if mode is MissionMode.ADD and self._mission is not None:
            old = self._mission
            if self._violated is not None or not self._reachable:
                raise NoPlanError(f"cannot add to the mission {brief(old.text)}: it was violated at "
                                  f"region {self._violated!r}; replace it instead")
            rest = ops.from_states(old.buchi, self._reachable)
            new = ops.from_states(buchi, self._initial_states(buchi))
            text = f"({old.text}) & ({text})"
            inter = ops.intersect(rest, new, name=text)
            both_letters = ops.singleton_letters(inter, self.navmap.regions)
            inter = ops.trim(inter, both_letters)
            if not inter.accepting or ops.is_empty(inter, both_letters):
                raise UnsatisfiableError(text, "the added mission contradicts what remains of "
                                               "the current one")
            buchi, letters, states = inter, both_letters, frozenset((inter.initial,))
        else:
            states = self._initial_states(buchi)
        mission = _new_mission(text, buchi, self.navmap, letters)
        plan = self._compute(mission, states, self._urgent)
        self._mission, self._states, self._reachable, self._violated = mission, states, states, None
        self._seen_version = self.navmap.version
        self._set_plan(plan)
        return plan

    def _request_urgent(self, formula) -> Plan:
        text, buchi, letters = self._compile(formula)
        done = ops.universal_states(buchi, letters)
        if not done:
            raise InvalidRequestError(
                f"urgent request {brief(text)} is not co-safe (no finite path serves it for good); "
                "urgent requests are reachability tasks such as 'F u1'")
        states = self._initial_states(buchi)
        queue = list(self._urgent)
        if not states & done:
            queue.append(_Urgent(text, buchi, done, states))
        if self._mission is None:
            raise InvalidRequestError("an urgent request needs an active mission to resume; "
                                      "use mode 'replace'")
        self._sync()
        plan = self._compute_current(queue)
        self._urgent = queue
        self._set_plan(plan)
        return plan

    def _compute_current(self, urgent: list[_Urgent]) -> Plan:
        """The plan from the committed run's state; when none has a lasso, from every state the
        trace leads to, which then become the current ones (class doc)."""
        try:
            return self._compute(self._mission, self._states, urgent)
        except NoPlanError:
            if self._reachable == self._states or self._violated is not None:
                raise
            plan = self._compute(self._mission, self._reachable, urgent)
            self._states = self._reachable
            return plan

    def _set_plan(self, plan: Plan) -> None:
        self._plan = plan
        self._plan_key = self._key()

    def _key(self):
        # the objects themselves, not their id(): a later mission could reuse a freed one's id
        return (self.navmap.version, self._node, self._states, self._mission,
                tuple((u, u.states) for u in self._urgent))

    # ---- planning -------------------------------------------------------------------------
    def plan(self, current: Iterable[tuple] | None = None) -> Plan:
        """The optimal plan from the current product states (or from ``current``, an iterable
        of ``(node, q)`` product states of the main mission, sharing one node; pending urgent
        requests are then ignored). Cached while nothing changes.

        Raises
        ------
        NoPlanError
            No mission, a violated mission, or no accepting lasso in the current map.
        """
        if self._mission is None:
            raise NoPlanError("no active mission")
        self._sync()
        if current is None:
            if self._plan is not None and self._plan_key == self._key():
                return self._plan
            plan = self._compute_current(self._urgent)
            self._set_plan(plan)
            return plan
        current = [(self.navmap.node(n), int(q)) for n, q in current]
        nodes = {n for n, _ in current}
        if len(nodes) != 1:
            raise InvalidRequestError(f"current product states must share one node, got {sorted(nodes)}")
        for _, q in current:
            if not 0 <= q < self._mission.buchi.num_states:
                raise InvalidRequestError(f"automaton state {q} is not in 0..{self._mission.buchi.num_states - 1}")
        saved = self._node
        self._node = self.navmap.index[current[0][0]]
        try:
            return self._compute(self._mission, frozenset(q for _, q in current), [])
        finally:
            self._node = saved

    replan = plan
    """Re-plan after map changes from the current (or given) product states; see :meth:`plan`
    and the class docstring for what is reused."""

    def _compute(self, mission: _Mission, states: frozenset[int], urgent: list[_Urgent]) -> Plan:
        if self._violated is not None and mission is self._mission:
            raise NoPlanError(f"the mission {brief(mission.text)} was violated on entering region "
                              f"{self._violated!r}; no continuation satisfies it")
        if not states:
            raise NoPlanError(f"the mission {brief(mission.text)} cannot be satisfied from "
                              f"{self.node.region!r}: its automaton has no run from here")
        node = self._node
        ucost, upath = 0.0, ()
        if urgent:
            res = self._urgent_path(urgent[0], mission, node, states, self.navmap.costs)
            if res is None:
                blocked = self._blocked_urgent(urgent[0], mission, node, states)
                raise NoPlanError(
                    f"the urgent request {brief(urgent[0].text)} cannot be served from {self.node} in the "
                    f"current map" + _blocked_text(blocked), blocked)
            ucost, upath, node, states = res
        prod = mission.product
        sources = [node * prod.Q + q for q in sorted(states)]
        lasso = _nested_dijkstra(prod, self.navmap.costs, sources, self.alpha, mission.cycles)
        if lasso is None:
            blocked = self._blocked_lasso(mission, sources)
            raise NoPlanError(
                f"no accepting lasso for the mission {brief(mission.text)} from {self.navmap.nodes[node]} "
                "in the current map" + _blocked_text(blocked), blocked)
        self.last_stats = {"cycles_computed": lasso.cycles_computed,
                           "cycles_reused": lasso.cycles_reused}
        dec = prod.decode
        pre = tuple(dec(s) for s in lasso.prefix)
        suf = tuple(dec(s) for s in lasso.cycle.path)
        return Plan(tuple(n for n, _ in pre), tuple(n for n, _ in suf), lasso.prefix_cost,
                    lasso.cycle.cost, self.alpha, pre, suf,
                    tuple(self.navmap.nodes[i] for i in upath), ucost)

    def _urgent_path(self, u: _Urgent, mission: _Mission, node: int, states: frozenset[int], costs):
        """Cheapest path in ``map x U x A`` from the current node and state sets to a state
        where ``U`` is universal (served) and ``A`` still has a run; returns ``(cost, node
        path, end node, main state set at the end)`` or ``None``."""
        m = self.navmap
        A, U = mission.buchi, u.buchi
        N = m.num_nodes
        letters_a = [self._letter(A, n) for n in range(N)]
        letters_u = [self._letter(U, n) for n in range(N)]
        targets = [n for n in range(m.num_region_nodes)]
        dist: dict[tuple, float] = {}
        pred: dict[tuple, tuple | None] = {}
        heap = []
        for qu in sorted(u.states):
            for qa in sorted(states):
                s = (node, qu, qa)
                dist[s] = 0.0
                pred[s] = None
                heap.append((0.0, s))
        heapq.heapify(heap)
        end = None
        while heap:
            d, s = heapq.heappop(heap)
            if d > dist[s]:
                continue
            n, qu, qa = s
            if qu in u.done and pred[s] is not None:
                end = s
                break
            base = n * N
            for n2 in targets:
                c = costs[base + n2]
                if c == INF:
                    continue
                nd = d + c
                for qu2 in U.successors(qu, letters_u[n2]):
                    for qa2 in A.successors(qa, letters_a[n2]):
                        t = (n2, qu2, qa2)
                        if nd < dist.get(t, INF):
                            dist[t] = nd
                            pred[t] = s
                            heapq.heappush(heap, (nd, t))
        if end is None:
            return None
        path = [end]
        while pred[path[-1]] is not None:
            path.append(pred[path[-1]])
        path.reverse()
        nodes = tuple(p[0] for p in path)
        end_states = frozenset(states)
        for n in nodes[1:]:
            end_states = self._read(A, end_states, n)
        return dist[end], nodes, nodes[-1], end_states

    # ---- diagnostics for NoPlanError ------------------------------------------------------
    def _penalised_costs(self) -> list[float]:
        m = self.navmap
        costs = list(m.costs)
        finite = [c for c in costs if c < INF]
        big = 1e6 * (1.0 + (max(finite) if finite else 1.0))
        for e, old in m.removed.items():
            costs[e] = old + big
        return costs

    def _blocked_of(self, edges: Iterable[int]) -> tuple[tuple[str, str], ...]:
        m = self.navmap
        out = []
        for e in edges:
            if e in m.removed:
                pair = m.region_pair(e)
                if pair not in out:
                    out.append(pair)
        return tuple(out)

    def _blocked_lasso(self, mission: _Mission, sources) -> tuple[tuple[str, str], ...]:
        if not self.navmap.removed:
            return ()
        lasso = _nested_dijkstra(mission.product, self._penalised_costs(), sources, max(self.alpha, 1.0), None)
        if lasso is None:
            return ()
        N, Q = self.navmap.num_nodes, mission.product.Q
        states = list(lasso.prefix) + list(lasso.cycle.path)
        nodes = [s // Q for s in states]
        return self._blocked_of(nodes[i] * N + nodes[i + 1] for i in range(len(nodes) - 1))

    def _blocked_urgent(self, u, mission, node, states) -> tuple[tuple[str, str], ...]:
        if not self.navmap.removed:
            return ()
        res = self._urgent_path(u, mission, node, states, self._penalised_costs())
        if res is None:
            return ()
        nodes = res[1]
        N = self.navmap.num_nodes
        return self._blocked_of(nodes[i] * N + nodes[i + 1] for i in range(len(nodes) - 1))

    def __repr__(self) -> str:
        return (f"MissionPlanner(mission={self.mission!r}, node={self.node}, "
                f"states={sorted(self._states)}, urgent={list(self.pending_urgent)}, {self.navmap!r})")


def _blocked_text(blocked) -> str:
    if not blocked:
        return ""
    return "; blocked transitions it would need: " + ", ".join(f"{a} -> {b}" for a, b in blocked)
