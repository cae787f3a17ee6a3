"""Random forest-of-stars worlds for tests and benchmarks (deterministic per seed).

:func:`random_forest_world` builds trees of overlapping squircles, mostly wall-like rounded
rectangles, some ellipses and circles: interior trees, and trees hanging from walls that cross
the workspace boundary. Children overlap their parent by a clear margin; distinct trees and
non-adjacent obstacles keep a clear gap. The result is accepted by
:func:`navigation.forest.build_forest` with inflation 0 and holds regions ``r1 .. rn`` and a
start pose in free space.

:func:`random_free_points` samples the free space of a world uniformly.

The geometric checks of a candidate obstacle go from cheap to exact (boundary samples, then
the private, vectorised exact pair distance of :mod:`navigation.forest`), so that one
20-obstacle world is generated in well under two seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from navigation.errors import ForestError, WorldError
from navigation.forest import _SAMPLES, _pair_distance
from navigation.forest import _Body as _ForestBody
from navigation.geometry import Squircle
from scipy.spatial import cKDTree
from navigation.world import LidarSpec, Region, RobotSpec, World, load_world

__all__ = ["random_forest_world", "random_free_points", "GAP", "MIN_OVERLAP", "MIN_PROTRUSION"]

GAP = 0.15  #: clearance between distinct trees and between non-adjacent obstacles (m)
MIN_OVERLAP = 0.05  #: depth of the common centre of a child and its parent (m)
MIN_PROTRUSION = 0.1  #: how far a boundary wall sticks out of the workspace (m)
REGION_RADIUS = 0.15
ROBOT_RADIUS = 0.1


class _Retry(Exception):
    """This attempt cannot be completed; start again with the next random numbers."""


def _auto_size(n: int) -> tuple[float, float]:
    side = 5.0 if n <= 20 else 10.0 * math.sqrt(n / 50.0)
    return (side, side)


def _random_shape(rng: np.random.Generator, center, wall_only: bool = False, long: bool = False) -> Squircle:
    """Mostly a wall (rounded rectangle 0.3-1.2 x 0.15-0.3 m), else an ellipse or a circle.

    ``long`` asks for a wall of at least 0.8 m (room for children along it).
    """
    theta = float(rng.uniform(0.0, math.pi))
    if wall_only or long or rng.random() < 0.8:
        return Squircle(tuple(center), float(rng.uniform(0.8 if long else 0.3, 1.2)), float(rng.uniform(0.15, 0.3)),
                        theta, float(rng.uniform(0.9, 0.99)))
    w = float(rng.uniform(0.25, 0.6))
    h = w if rng.random() < 0.5 else float(rng.uniform(0.2, 0.6))
    return Squircle(tuple(center), w, h, theta, 0.0 if rng.random() < 0.6 else float(rng.uniform(0.0, 0.6)))


class _Body(_ForestBody):
    """The forest's boundary samples plus what the generator's checks query: a k-d tree of the
    samples, their bounding box and (on first use) a k-d tree of ``n_dense`` samples."""

    __slots__ = ("tree", "lo", "hi", "n_dense", "_dense_tree")

    def __init__(self, sq: Squircle, n: int, n_dense: int = 1024):
        super().__init__(sq, n)
        self.tree = cKDTree(self.pts)
        self.lo = self.pts.min(axis=0)
        self.hi = self.pts.max(axis=0)
        self.n_dense = n_dense
        self._dense_tree = None

    def dense_tree(self) -> cKDTree:
        if self._dense_tree is None:
            self._dense_tree = cKDTree(self.sq.boundary_points(self.n_dense))
        return self._dense_tree


@dataclass
class _Node:
    tree: int
    parent: int | None  # index in the tree's node list, None for the tree's first node
    depth: int  # generation depth (wall roots 1, interior roots 0)


@dataclass
class _Placer:
    """Placed obstacles with their boundary samples, and the exact checks of a candidate."""

    ws: Squircle
    size: tuple[float, float]
    gap: float = GAP
    squircles: list = field(default_factory=list)
    bodies: list = field(default_factory=list)

    def __post_init__(self):
        self.ws_body = _Body(self.ws, 1024, n_dense=4096)

    def _far_enough(self, body: _Body, other: _Body) -> bool | None:
        """True/False when boundary samples decide ``distance >= gap``; None when too close to call.

        The closest pair of samples is at most half a sample spacing (each) farther apart than
        the closest boundary points.
        """
        d = float(other.tree.query(body.pts)[0].min())
        if d < self.gap:
            return False
        if d - 0.5 * (body.spacing + other.spacing) >= self.gap:
            return True
        return None

    def _clear_of_others(self, body: _Body, exclude: int | None) -> bool:
        """``body`` is at least ``gap`` from every placed obstacle except ``exclude``."""
        if not self.bodies:
            return True
        c = np.array([b.sq.center for b in self.bodies])
        r = np.array([b.radius for b in self.bodies])
        near = np.nonzero(np.linalg.norm(c - body.sq.c, axis=1) < r + body.radius + self.gap)[0]
        exact = []
        for k in (int(k) for k in near if k != exclude):
            other = self.bodies[k]
            # containment is invisible to a boundary-to-boundary distance
            if other.sq.beta(body.sq.c) <= 0 or body.sq.beta(other.sq.c) <= 0:
                return False
            verdict = self._far_enough(body, other)
            if verdict is False:
                return False
            if verdict is None:
                exact.append(k)
        if not exact:
            return True
        pool = [body] + [self.bodies[k] for k in exact]
        d, _, _ = _pair_distance(pool, np.zeros(len(exact), int), np.arange(1, len(exact) + 1), tol=1e-9)
        return bool(np.all(d >= self.gap))

    def _inside_workspace(self, body: _Body) -> bool:
        """``body`` lies inside the workspace, at least ``gap`` from its boundary."""
        W, H = self.size
        x, y = body.pts[:, 0], body.pts[:, 1]
        # the workspace squircle lies inside the W x H rectangle: a quick, safe rejection
        if np.min(np.minimum.reduce([x, y, W - x, H - y])) < self.gap:
            return False
        if np.any(self.ws.beta(body.pts) >= 0):
            return False
        verdict = self._far_enough(body, self.ws_body)
        if verdict is not None:
            return verdict
        d, _, _ = _pair_distance([body, self.ws_body], np.array([0]), np.array([1]), tol=1e-9)
        return bool(d[0] >= self.gap)

    def truncate(self, n: int) -> None:
        """Forget the obstacles placed after the first ``n``."""
        del self.squircles[n:]
        del self.bodies[n:]

    def try_add(self, sq: Squircle, parent: int | None, wall_root: bool = False) -> bool:
        """Place ``sq`` if it satisfies every rule (cheap tests first); True when placed."""
        body = _Body(sq, _SAMPLES)
        if wall_root:
            if not self._crosses_boundary(body):
                return False
        elif not self._inside_workspace(body):
            return False
        if parent is not None and not self._shares_parent(body, parent):
            return False
        if not self._clear_of_others(body, parent):
            return False
        if parent is not None and not self._overlaps_parent(body, parent):
            return False
        self.squircles.append(sq)
        self.bodies.append(body)
        return True

    def _shares_parent(self, body: _Body, parent: int) -> bool:
        """Child and parent overlap, and neither swallows the other (cheap sample test)."""
        pb = self.bodies[parent]
        out_child = np.mean(pb.sq.beta(body.pts) > 0)
        out_parent = np.mean(body.sq.beta(pb.pts) > 0)
        return bool(0.4 <= out_child < 1.0 and out_parent >= 0.4)

    def _overlaps_parent(self, body: _Body, parent: int) -> bool:
        """The deepest point of child ∩ parent is at least ``MIN_OVERLAP`` inside both."""
        return _grid_depth(body, self.bodies[parent], outside=False) >= MIN_OVERLAP

    def _crosses_boundary(self, body: _Body) -> bool:
        vals = self.ws.beta(body.pts)
        out = vals > 0
        if out.all() or not out.any() or np.count_nonzero(out & ~np.roll(out, 1)) != 1:
            return False
        W, H = self.size
        x, y = body.pts[:, 0], body.pts[:, 1]
        protrusion = np.max(np.maximum.reduce([-x, -y, x - W, y - H]))
        if protrusion < MIN_PROTRUSION:
            return False
        if not self._clear_of_others(body, None):
            return False
        return _grid_depth(body, self.ws_body, outside=True) >= MIN_OVERLAP


def _grid_depth(a: _Body, b: _Body, outside: bool, n: int = 25) -> float:
    """A lower bound of ``max min(depth in a, depth in b)`` (``b``: distance outside it).

    Evaluated on an ``n x n`` grid over the common bounding box with distances to dense
    boundary samples, which overestimate true distances by at most ``h^2 / (8 d)`` (sample
    spacing ``h``); a margin of 1 mm covers that.
    """
    lo, hi = (a.lo, a.hi) if outside else (np.maximum(a.lo, b.lo), np.minimum(a.hi, b.hi))
    if np.any(hi <= lo):
        return -np.inf
    t = (np.arange(n) + 0.5) / n
    gx, gy = np.meshgrid(lo[0] + t * (hi[0] - lo[0]), lo[1] + t * (hi[1] - lo[1]), indexing="ij")
    q = np.stack((gx.ravel(), gy.ravel()), axis=1)
    da = a.dense_tree().query(q)[0] * np.where(a.sq.beta(q) < 0, 1.0, -1.0)
    db = b.dense_tree().query(q)[0] * np.where(b.sq.beta(q) < 0, 1.0, -1.0) * (-1.0 if outside else 1.0)
    return float(np.max(np.minimum(da, db))) - 1e-3


def _rect_clearance(p: np.ndarray, size: tuple[float, float]) -> float:
    W, H = size
    return float(min(p[0], p[1], W - p[0], H - p[1]))


def _room(placer: "_Placer", p: np.ndarray, exclude: int) -> float:
    """Free room around ``p``: distance to the workspace rectangle and to placed obstacles."""
    room = _rect_clearance(p, placer.size)
    for k, b in enumerate(placer.bodies):
        if k != exclude and np.linalg.norm(p - b.sq.c) < b.radius + room:
            room = min(room, float(b.tree.query(p)[0]))
    return room


def _child_candidate(rng: np.random.Generator, placer: "_Placer", par: int, long: bool = False) -> Squircle:
    """A shape whose axis passes through a point well inside the parent and sticks out of it,
    towards free room (away from the boundary and the other obstacles)."""
    parent = placer.squircles[par]
    long_ = np.array([math.cos(parent.theta), math.sin(parent.theta)])
    span = 0.5 * max(parent.width - parent.height, 0.0)
    if parent.height > parent.width:
        long_ = np.array([-long_[1], long_[0]])
        span = 0.5 * (parent.height - parent.width)
    cands = [parent.c + rng.uniform(-0.9, 0.9) * span * long_ for _ in range(4)]
    a = max(cands, key=lambda p: _room(placer, p, par))
    shape = _random_shape(rng, (0.0, 0.0), long=long)
    # the child's long axis makes an angle of at least 35 degrees with the parent's long axis
    phi = parent.theta + math.copysign(rng.uniform(math.radians(35), math.radians(145)), rng.uniform(-1, 1))
    d = np.array([math.cos(phi), math.sin(phi)])
    u = rng.uniform(0.3, 0.85) * 0.5 * shape.width
    c = max((a + u * d, a - u * d), key=lambda p: _room(placer, p, par) + 0.1 * rng.random())
    return Squircle(tuple(c), shape.width, shape.height, phi, shape.s)


def _wall_root_candidate(rng: np.random.Generator, size: tuple[float, float]) -> Squircle:
    W, H = size
    side = int(rng.integers(4))
    length = W if side in (0, 2) else H
    t = rng.uniform(0.7, length - 0.7)
    # boundary point and inward normal per side: bottom, right, top, left
    p, n = [((t, 0.0), (0.0, 1.0)), ((W, t), (-1.0, 0.0)), ((t, H), (0.0, -1.0)), ((0.0, t), (1.0, 0.0))][side]
    ang = math.atan2(n[1], n[0]) + rng.uniform(-0.5, 0.5)
    d = np.array([math.cos(ang), math.sin(ang)])
    width = float(rng.uniform(0.7, 1.2))
    thick = float(rng.uniform(0.15, 0.3))
    protrude = rng.uniform(0.15, 0.3)
    c = np.array(p) + d * (0.5 * width - protrude / max(abs(float(d @ n)), 0.5))
    return Squircle(tuple(c), width, thick, ang, float(rng.uniform(0.9, 0.99)))


def _plan(rng: np.random.Generator, n: int, max_depth: int, wall_fraction: float) -> list[list[_Node]]:
    """Tree shapes: one deep tree first, then wall trees up to ``wall_fraction``, then interior trees."""
    trees: list[list[_Node]] = []
    left = n
    n_walls = int(round(wall_fraction * n))
    if max_depth >= 1 and left > 0:
        if n_walls > 0:  # a chain hanging from the boundary: depths 1 .. max_depth
            k = min(max_depth, left)
            trees.append([_Node(0, None if i == 0 else i - 1, i + 1) for i in range(k)])
            n_walls -= k
        else:  # an interior chain whose centre is max_depth from both ends
            k = min(2 * max_depth + 1, left)
            trees.append([_Node(0, None if i == 0 else i - 1, i) for i in range(k)])
        left -= k
    while left > 0:
        wall = n_walls > 0
        k = int(min(left, rng.choice([1, 2, 3]) if wall else rng.choice([1, 2, 3, 4, 5], p=[.25, .25, .2, .15, .15])))
        t = len(trees)
        nodes = [_Node(t, None, 1 if wall else 0)]
        for _ in range(k - 1):
            options = [i for i, nd in enumerate(nodes) if nd.depth < max_depth]
            if not options:
                break
            p = int(rng.choice(options))
            nodes.append(_Node(t, p, nodes[p].depth + 1))
        if wall:
            n_walls -= len(nodes)
        trees.append(nodes)
        left -= len(nodes)
    return trees


def _attempt(rng: np.random.Generator, name: str, n: int, max_depth: int, size, n_regions: int,
             wall_fraction: float, gap: float = GAP) -> World:
    W, H = size
    ws = Squircle((W / 2.0, H / 2.0), W, H, 0.0, 0.99)
    placer = _Placer(ws, (W, H), gap=gap)
    trees = _plan(rng, n, max_depth, wall_fraction)
    margin = gap + 0.2

    def free_root(long: bool = False) -> bool:
        for _ in range(200):
            cand = _random_shape(rng, rng.uniform((margin, margin), (W - margin, H - margin)), long=long)
            if placer.try_add(cand, None):
                return True
        return False

    for t, nodes in enumerate(trees):
        has_children = {nd.parent for nd in nodes if nd.parent is not None}
        for _ in range(10 if t == 0 else 1):  # the deep tree is retried as a whole
            start = len(placer.squircles)
            index: list[int] = []  # placer index of each node
            for k, nd in enumerate(nodes):
                long = k in has_children
                if nd.parent is None:
                    if nd.depth == 1:
                        placed = any(placer.try_add(_wall_root_candidate(rng, (W, H)), None, wall_root=True)
                                     for _ in range(200))
                    else:
                        placed = free_root(long)
                else:
                    par = index[nd.parent]
                    placed = any(placer.try_add(_child_candidate(rng, placer, par, long), par) for _ in range(40))
                if not placed and t > 0 and nd.parent is not None:
                    placed = free_root()  # give up the attachment: a tree of its own
                if not placed:
                    break
                index.append(len(placer.squircles) - 1)
            if len(index) == len(nodes):
                break
            placer.truncate(start)
        else:
            raise _Retry

    obstacles = tuple(placer.squircles)
    probe = World(name, ws, obstacles, (), {}, RobotSpec(ROBOT_RADIUS, (0.0, 0.0, 0.0), 0.5, 1.5),
                  LidarSpec(1.0, 2 * math.pi, 360, 0.0, 10.0), "true")
    try:
        forest = probe.forest(0.0)
    except ForestError as err:  # pragma: no cover - the checks above make this rare
        raise _Retry from err
    # regions r1..rn and the start, in free space with the robot radius (plus a little margin)
    pts = random_free_points(probe, 8 * (n_regions + 1) + 16, rng, margin=REGION_RADIUS + ROBOT_RADIUS + 0.02)
    regions: dict[str, Region] = {}
    start = None
    for p in pts:
        if len(regions) < n_regions:
            if all(math.dist(p, r.center) > 2 * REGION_RADIUS + 0.1 for r in regions.values()):
                key = f"r{len(regions) + 1}"
                regions[key] = Region(key, (float(p[0]), float(p[1])), REGION_RADIUS)
        elif all(math.dist(p, r.center) > REGION_RADIUS + ROBOT_RADIUS + 0.05 for r in regions.values()):
            start = (float(p[0]), float(p[1]), float(rng.uniform(-math.pi, math.pi)))
            break
    if len(regions) < n_regions or start is None:
        raise _Retry
    task = " & ".join(f"F {key}" for key in regions) if regions else "true"
    world = World(name, ws, obstacles, (), regions, RobotSpec(ROBOT_RADIUS, start, 0.5, 1.5),
                  probe.lidar, task)
    world.validate()
    world._forests.update(probe._forests)  # same workspace and obstacles: reuse the forest
    assert world.forest(0.0) is forest
    return world


def random_forest_world(seed: int, n_obstacles: int = 12, max_depth: int = 4, size=None, n_regions: int = 4,
                        wall_fraction: float = 0.3, gap: float = GAP) -> World:
    """A random world whose obstacles form a forest of stars (deterministic per ``seed``).

    Parameters
    ----------
    seed : int
    n_obstacles : int
        Number of obstacles (0 .. about 50).
    max_depth : int
        Largest purge depth: one tree reaches it when ``n_obstacles`` allows (a chain hanging
        from a boundary wall, or, with ``wall_fraction == 0``, an interior chain of
        ``2 max_depth + 1`` obstacles, since interior trees are rooted at their centre); no
        obstacle is deeper.
    size : (float, float) or None
        Workspace extents; None picks 5 x 5 m up to 20 obstacles, then grows the side with
        ``sqrt(n)`` (10 x 10 m for 50).
    n_regions : int
        Regions ``r1 .. rn`` (radius 0.15 m); the task visits all of them.
    wall_fraction : float
        Share of the obstacles in trees attached to the workspace boundary.
    gap : float
        Clearance between distinct trees, between non-adjacent obstacles and from the workspace
        boundary (default :data:`GAP`). A robot of radius ``r`` needs ``gap > 2 r`` for the
        obstacles grown by ``r`` (its configuration space) to remain a forest.

    Raises
    ------
    RuntimeError
        If no world could be generated (too many obstacles for ``size``).
    """
    if n_obstacles < 0 or max_depth < 0 or n_regions < 0 or not 0.0 <= wall_fraction <= 1.0:
        raise ValueError("n_obstacles, max_depth, n_regions must be >= 0 and wall_fraction in [0, 1]")
    size = _auto_size(n_obstacles) if size is None else (float(size[0]), float(size[1]))
    rng = np.random.default_rng(seed)
    name = f"random{n_obstacles}_seed{seed}"
    for _ in range(50):
        try:
            return _attempt(rng, name, n_obstacles, max_depth, size, n_regions, wall_fraction, gap)
        except (_Retry, WorldError):
            continue
    raise RuntimeError(f"could not generate a forest world with {n_obstacles} obstacles in {size[0]} x {size[1]} m")


def random_free_points(world: World, n: int, rng: np.random.Generator, margin: float = 0.0) -> np.ndarray:
    """``n`` points uniform in the free space of ``world.forest(0)``, at least ``margin`` from
    every obstacle and from the workspace boundary. Shape ``(n, 2)``.

    Rejection sampling: candidates uniform in the workspace's bounding box are kept when they
    are outside every obstacle (``beta > 0``) and inside the workspace, and, for ``margin > 0``,
    when the exact :meth:`Squircle.distance` to every nearby obstacle and to the workspace
    boundary is at least ``margin``.

    Raises
    ------
    RuntimeError
        If the free space (shrunk by ``margin``) is too small to sample.
    """
    forest = world.forest(0.0)
    ws = forest.workspace
    pts = ws.boundary_points(256)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    out: list[np.ndarray] = []
    total = 0
    tried = 0
    batch = max(64, 4 * n)
    while total < n:
        if tried > 2000 * max(n, 1) + 100_000:
            raise RuntimeError(f"free space of {world.name} too small to sample {n} points with margin {margin}")
        q = rng.uniform(lo, hi, size=(batch, 2))
        tried += batch
        ok = ws.beta(q) < 0
        for o in forest.obstacles:
            ok &= o.beta(q) > 0
        if margin > 0:
            idx = np.nonzero(ok)[0]
            if idx.size:
                ok[idx] &= -ws.distance(q[idx]) >= margin
            for o in forest.obstacles:
                idx = np.nonzero(ok)[0]
                idx = idx[np.linalg.norm(q[idx] - o.c, axis=1) < o.bounding_radius + margin]
                if idx.size:
                    ok[idx] &= o.distance(q[idx]) >= margin
        good = q[ok]
        out.append(good)
        total += len(good)
    return np.concatenate(out)[:n]


def empty_world(name: str, start) -> World:
    """The world file ``name`` without its obstacles, the robot starting at ``start`` ``(x, y)``
    heading east: its regions and workspace, where the shortest paths are straight lines."""
    w = load_world(name)
    return replace(w, obstacles=(), known_obstacles=(),
                   robot=replace(w.robot, start=(float(start[0]), float(start[1]), 0.0)))
