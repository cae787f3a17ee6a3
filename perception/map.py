"""``ObstacleMap``: the one stateful object of the perception layer (paper 001 sections 3, 4.1.2).

The map starts knowing only the workspace and grows from scans:

1. **Ingestion** (:mod:`perception.ingest`): a scan and the pose at its stamp become world
   points; bad messages are rejected with a :class:`~perception.errors.ScanError` (logged), NaN
   beams are trimmed (logged). Returns within ``ws_band`` of the workspace boundary (distance
   to first order, not the radial error) are the boundary itself and are dropped; with range
   noise (a band of ``0.01 + 5 sigma``) only those whose beam meets the boundary within
   ``ws_band`` beyond them: an obstacle's face near the boundary seen obliquely stays.
2. **Evidence**: returns are averaged in ``voxel`` cells (with the directions they were seen
   from); the beams' paths, up to ``free_margin`` before their returns (``range_max`` for no
   return), mark ``free_cell`` cells as free.
3. **Clustering** (incremental): a new cell joins every cell within ``link`` (looked up on the voxel grid) and the
   cells of its neighbouring beams when the range discontinuity between them is below the
   breakpoint rule (:meth:`PerceptionConfig.breakpoint`); clusters that become connected merge.
4. **Refit** of a cluster only when its data contradicts its estimates: a new cell more than
   ``refit_tol`` outside them, or a newly free cell more than ``free_tol`` inside them (so the
   same scan processed twice changes nothing). A return more than ``0.75 radius`` outside (it
   would soon leave the inflated estimate) refits at once; other contradictions make the
   cluster pending: refitted at most once every 5 scans, together with a scan that refits
   anyway (one forest check), or alone after 20 scans (up to 4 times longer for free space
   that the last refits could not clear, unless the cluster's returns have grown 1.05 times
   since its last refit, ``_FUTILE_GROWTH``; such a futile refit, and a repair merging two
   estimates, leave the cluster pending; a pending refit after a futile one is skipped while
   the cluster's returns, nearby free cells and estimates are those of that refit). Pending
   refits run after the others, longest waiting first, while the update has run fewer than
   ``_PENDING_BUDGET`` squircle fits (:func:`perception.fit.fit_count`); one put off is due
   at the next update, an overdue one runs regardless. The
   cluster is fitted by
   :func:`perception.fit.fit_cluster` (one squircle or a decomposition), extended through the
   workspace boundary when it touches it (walls on the boundary): its returns within
   ``ws_touch`` of the boundary get virtual copies just beyond it, moved along the cluster's
   own line through them (the principal axis of its returns within ``link``; the boundary's
   normal where they do not form a line or the line runs along the boundary), so a wall that
   meets the boundary at an angle is continued straight instead of being widened by copies
   shifted sideways off its faces.
5. **Clearances**: an estimate is trimmed (the face towards the disc moved back, the far side
   kept) so that, inflated, it neither contains the robot's position (robot disc kept clear)
   nor reaches into a region disc; an estimate that cannot be trimmed is removed, logged.
   This holds for the covers the forest repairs below make too (a merged pair, a grown face):
   they are trimmed clear of the region discs after each repair, as a refit's estimates are.
6. **Forest check**: the inflated estimates (grown by the robot radius with
   :func:`perception.fit.inflate`) with the workspace shrunk by the radius must be accepted by
   :func:`navigation.build_forest` (checked with :func:`navigation.forest.check_forest`, which
   raises what it would without computing the terms only navigation needs). The check runs on
   the changed estimates and everything
   near them (bounding circles within ``min_gap``), which is equivalent to checking the whole
   map because the untouched part was accepted before; it is skipped when a cheap certificate
   proves that it passes (:meth:`ObstacleMap._certified`: changed estimates inside the
   workspace, clear of or deeply overlapping their neighbours, adding no cycle). A :class:`~navigation.ForestError` is
   repaired conservatively: a too-close or shallow pair is grown by 3 cm per try (the smaller
   estimate's face towards the other), a cycle is
   broken by merging the two closest members into one squircle covering both, after three
   tries a pair is merged; a cycle through estimates of different clusters merges the clusters
   and re-decomposes them together; if repairs fail the update of those estimates is reverted (logged).

Every update returns a :class:`MapUpdate` listing the added, updated and removed estimate ids.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from navigation.errors import ForestError
from navigation.forest import Forest, build_forest, check_forest
from navigation.geometry import Squircle

from . import _shape_kernel
from .config import PerceptionConfig
from .errors import PoseJumpError, ScanError, StampError
from .fit import fit_cluster, fit_count, fit_squircle, gauge, inflate, radial_error, rect_error
from .ingest import Scan, parse_points, parse_pose, parse_scan

__all__ = ["Estimate", "MapUpdate", "ObstacleMap"]

log = logging.getLogger("perception")

_MAX_CELL_COUNT = 50  # returns averaged per cell (later ones are ignored: bounded work)
_REPAIR_STEPS = 16
_GROW_STEP = 0.03
_TRIM_BOTH = True  # a trim may move either axis's face towards the disc (the cut keeping more area)
_REFIT_EVERY = 5  # scans between non-urgent refits of one cluster
_REFIT_LATEST = 20  # scans after which a pending (non-urgent) refit runs even on a quiet scan
_MERGES_PER_UPDATE = 2  # cycle merges one estimate may take part in within one update
_SKIP_SAME = True  # a pending refit after a futile one waits while the cluster's data is unchanged
_MAX_BACKOFF = 2  # futile free-space refits double the wait, at most 2 ** _MAX_BACKOFF times
_FUTILE_GROWTH = 1.05  # ... unless the cluster's returns have grown this many times since (0: off)
_PENDING_BUDGET = 4  # squircle fits an update may have run before a due pending refit waits (0: off)


@dataclass(frozen=True, slots=True, eq=False)
class Estimate:
    """One obstacle estimate.

    Attributes
    ----------
    id : int
        Stable identifier (kept while the estimate is refined).
    squircle : Squircle
        The estimate of the obstacle itself.
    inflated : Squircle
        ``squircle`` grown by the robot radius (what navigation uses).
    cluster : int
        Cluster the estimate explains (several estimates: a decomposed cluster).
    rms : float
        RMS radial error of its fit (m).
    closed : bool
        Every face was seen (no conservative completion needed).
    """

    id: int
    squircle: Squircle
    inflated: Squircle
    cluster: int
    rms: float = 0.0
    closed: bool = False


@dataclass(frozen=True, slots=True)
class MapUpdate:
    """What one update changed (for incremental navigation updates).

    Attributes
    ----------
    stamp : float or None
    added, updated, removed : tuple of int
        Estimate ids.
    points : int
        Returns used (after trimming).
    trimmed : int
        Beams or points dropped (non-finite, too short, on the workspace boundary, outside).
    notes : tuple of str
        Logged reasons (trims, repairs, reverts).
    fits : int
        Squircle fits the update ran (:func:`perception.fit.fit_count`): its fitting work,
        about 1 ms each, deterministic where its time is not. The executive defers a re-plan
        past a heavy update (``ExecutiveConfig.defer_fits``).
    """

    stamp: float | None
    added: tuple[int, ...] = ()
    updated: tuple[int, ...] = ()
    removed: tuple[int, ...] = ()
    points: int = 0
    trimmed: int = 0
    notes: tuple[str, ...] = ()
    fits: int = 0

    @property
    def changed(self) -> bool:
        """True when any estimate was added, updated or removed."""
        return bool(self.added or self.updated or self.removed)


_SAMPLE_CACHE: dict[tuple[int, int], tuple[Squircle, np.ndarray]] = {}
_OFFSETS: dict[int, np.ndarray] = {}
_CERT_MARGIN = 0.01  # m beyond min_gap / min_overlap that the forest certificate asks for


def _samples(sq: Squircle, n: int = 64) -> np.ndarray:
    """``n`` boundary points of ``sq``, counter-clockwise (cached per object and ``n``)."""
    hit = _SAMPLE_CACHE.get((id(sq), n))
    if hit is not None and hit[0] is sq:
        return hit[1]
    if len(_SAMPLE_CACHE) > 4096:
        _SAMPLE_CACHE.clear()
    pts = _shape_kernel.boundary_points(sq.center, sq.width, sq.height, sq.theta, sq.s, n)  # = sq.boundary_points(n)
    _SAMPLE_CACHE[(id(sq), n)] = (sq, pts)
    return pts


def _spacing(pts: np.ndarray) -> float:
    """Largest distance between consecutive points of a closed polygon."""
    d = pts - np.roll(pts, 1, axis=0)
    return float(np.sqrt(np.max(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])))


def _polygon_depth(pts: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Depth of points ``q (K, 2)`` in the convex polygon of the counter-clockwise boundary points
    ``pts (n, 2)`` of a squircle (distance to the nearest edge line, negative outside one): a
    lower bound of their depth in the squircle, which contains the polygon."""
    e = np.roll(pts, -1, axis=0) - pts
    L = np.hypot(e[:, 0], e[:, 1])
    nx, ny = e[:, 1] / np.maximum(L, 1e-300), -e[:, 0] / np.maximum(L, 1e-300)  # outward normals
    d = (pts[None, :, 0] - q[:, None, 0]) * nx + (pts[None, :, 1] - q[:, None, 1]) * ny
    d[:, L <= 0] = -np.inf  # (a degenerate edge certifies nothing)
    return d.min(axis=1)


def _rect_separation(a: Squircle, b: Squircle) -> float:
    """Largest gap between the projections of the rectangles ``width x height`` of ``a`` and
    ``b`` on their four axes (separating axes): a lower bound of the distance between the two
    squircles, which lie inside their rectangles; ``<= 0`` when no axis separates them."""
    best = -math.inf
    corners = []
    for sq in (a, b):
        c, s = math.cos(sq.theta), math.sin(sq.theta)
        hw, hh = sq.width / 2, sq.height / 2
        corners.append(np.array([[sq.center[0] + sx * hw * c - sy * hh * s, sq.center[1] + sx * hw * s + sy * hh * c]
                                 for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))]))
    for sq in (a, b):
        c, s = math.cos(sq.theta), math.sin(sq.theta)
        for ax in ((c, s), (-s, c)):
            pa = corners[0] @ ax
            pb = corners[1] @ ax
            best = max(best, float(pb.min() - pa.max()), float(pa.min() - pb.max()))
    return best


def _graph_components(n: int, e0: np.ndarray, e1: np.ndarray) -> np.ndarray:
    """Connected components of the undirected graph of ``n`` nodes and edges ``(e0[k], e1[k])``:
    component ids numbered in the order of their smallest node (as
    ``scipy.sparse.csgraph.connected_components``). Hooking to the smaller root and pointer
    jumping in numpy: 80 us for the graphs of one scan's new cells, against 230 us for
    building the sparse matrix and calling scipy."""
    lab = np.arange(n)
    if not len(e0):
        return lab
    while True:
        a, b = lab[e0], lab[e1]
        m = np.minimum(a, b)
        new = lab.copy()
        np.minimum.at(new, a, m)
        np.minimum.at(new, b, m)
        while True:
            nxt = new[new]
            if np.array_equal(nxt, new):
                break
            new = nxt
        if np.array_equal(new, lab):
            break
        lab = new
    return np.unique(lab, return_inverse=True)[1].reshape(-1)


def _same(a: Squircle, b: Squircle) -> bool:
    return (a.center == b.center and a.width == b.width and a.height == b.height and a.theta == b.theta
            and a.s == b.s)


def _scale(sq: Squircle, d: float) -> Squircle:
    """``sq`` with both extents grown by ``2 d`` (a superset for ``d > 0``)."""
    return Squircle(sq.center, sq.width + 2 * d, sq.height + 2 * d, sq.theta, sq.s)


def _frame(sq: Squircle, p):
    """``p`` in the frame of ``sq``: ``(u, h, axes)``, its coordinates along the two axes of
    ``sq``, the half-extents ``(width / 2, height / 2)`` and the axes' unit vectors."""
    c, s = math.cos(sq.theta), math.sin(sq.theta)
    dx, dy = p[0] - sq.center[0], p[1] - sq.center[1]
    return (dx * c + dy * s, dy * c - dx * s), (sq.width / 2, sq.height / 2), ((c, s), (-s, c))


def _facing_axis(u, h) -> int:
    """The axis whose face ``p`` (frame coordinates ``u``, half-extents ``h``) lies in front of:
    the larger ``|u| / h`` (0 on a tie)."""
    return 0 if abs(u[0]) / h[0] >= abs(u[1]) / h[1] else 1


def _rect_gap(sq: Squircle, p) -> float:
    """Distance from ``p`` to the rectangle ``width x height`` of ``sq`` (0 inside): a lower
    bound of the distance to ``sq``, which lies inside it (``g >= max(|x|, |y|)``)."""
    u, h, _ = _frame(sq, p)
    return math.hypot(max(abs(u[0]) - h[0], 0.0), max(abs(u[1]) - h[1], 0.0))


def _extend(sq: Squircle, p: np.ndarray, d: float) -> Squircle:
    """``sq`` with its face towards ``p`` moved out by ``d`` (the opposite face stays): a
    superset for ``d > 0``."""
    u, h, axes = _frame(sq, p)
    k = _facing_axis(u, h)
    sgn = 1.0 if u[k] >= 0 else -1.0
    ax = axes[k]
    ctr = (sq.center[0] + ax[0] * sgn * d / 2, sq.center[1] + ax[1] * sgn * d / 2)
    w, hh = (sq.width + d, sq.height) if k == 0 else (sq.width, sq.height + d)
    return Squircle(ctr, w, hh, sq.theta, sq.s)


@dataclass
class _Cluster:
    single: bool = False  # decomposition disabled
    ids: list = field(default_factory=list)
    failed_at: int = 0  # cells when its last update had to be reverted (retry after growth)
    last_fit: int = -10**9  # scan count at its last refit
    pending: bool = False  # contradicted by data while not due: refit when due
    by_points: bool = False  # the pending contradiction includes returns outside its estimates
    futile: int = 0  # refits in a row that left free space deeper than free_tol inside (backoff)
    deferred: bool = False  # a due pending refit the update's budget put off: due at the next update
    data: tuple = ()  # fingerprint of its returns and nearby free cells at its last refit
    cells: int = 0  # return cells at its last refit
    result: tuple = ()  # the squircles its last refit left (before trims)
    cache: dict = field(default_factory=dict)  # fit_cluster's memo of its pieces (refit cost)


class ObstacleMap:
    """Online obstacle map built from lidar scans (see the module docstring).

    Parameters
    ----------
    workspace : Squircle
        Known outer boundary.
    robot_radius : float
        Inflation radius (robot disc).
    regions : iterable of (center, radius) or mapping name -> Region, optional
        Regions of interest; estimates are trimmed so that the region disc grown by the robot
        radius stays free.
    config : PerceptionConfig, optional
        Thresholds (default: :meth:`PerceptionConfig.from_lidar` with its defaults).
    beams : int, optional
        Expected beam count of ``scan`` messages; others are rejected.

    Build it from a world with :meth:`from_world`.
    """

    def __init__(self, workspace: Squircle, robot_radius: float, *, regions=(), config: PerceptionConfig | None = None,
                 beams: int | None = None):
        if not isinstance(workspace, Squircle):
            raise ScanError(f"workspace must be a Squircle, got {type(workspace).__name__}", "workspace")
        r = float(robot_radius)
        if not (math.isfinite(r) and r >= 0):
            raise ScanError(f"robot_radius must be finite and >= 0, got {robot_radius!r}", "robot_radius")
        self.workspace = workspace
        self.radius = r
        self.config = config or PerceptionConfig.from_lidar()
        self.beams = beams
        if isinstance(regions, Mapping):
            regions = [(reg.center, reg.radius) for reg in regions.values()]
        self.regions = [(np.asarray(c, dtype=float).reshape(2), float(rr)) for c, rr in regions]
        self.cspace_workspace = workspace.grow(-r) if r > 0 else workspace
        wsb = self.cspace_workspace.boundary_points(4096)
        self._ws_tree = cKDTree(wsb)
        self._ws_spacing = float(np.max(np.linalg.norm(wsb - np.roll(wsb, 1, axis=0), axis=1)))
        cfg = self.config
        bp = workspace.boundary_points(512)
        self._lo = bp.min(axis=0) - 0.1
        hi = bp.max(axis=0) + 0.1
        self._shape = tuple(int(v) for v in np.ceil((hi - self._lo) / cfg.voxel)) 
        self._fshape = tuple(int(v) for v in np.ceil((hi - self._lo) / cfg.free_cell))
        self._n = np.zeros(self._shape, np.int32)
        self._sum = np.zeros(self._shape + (2,))
        self._view = np.zeros(self._shape + (2,))
        self._lab = np.full(self._shape, -1, np.int32)
        self._box: dict[int, tuple[int, int, int, int]] = {}  # label -> its cells' window [i0, i1) x [j0, j1)
        self._free = np.zeros(self._fshape, bool)
        self._est: dict[int, Estimate] = {}
        self._clusters: dict[int, _Cluster] = {}
        self._next_id = 0
        self._next_label = 0
        self._attempts: dict[tuple, int] = {}
        self._alias: dict[int, int] = {}
        self.last_stamp: float | None = None
        self.last_pose: tuple[float, float, float] | None = None
        self.scans = 0
        #: world-frame returns of the last update (the workspace boundary's and those inside
        #: the robot disc left out): what the executive's motion guard keeps the robot off
        self.last_returns = np.zeros((0, 2))
        self._urgent: set[int] = set()  # clusters to refit at the next update (refit_near)
        #: counters: refit triggers (``refit_new``, ``refit_merged``, ``refit_grown``,
        #: ``refit_free``, ``refit_near``), ``forest_checks`` (calls of check_forest), ``forest_certified``
        #: (forest checks found unnecessary by :meth:`_certified`), ``repairs``,
        #: ``reverts``, ``recovered`` (returns a region trim left uncovered, fitted again)
        self.stats: Counter = Counter()

    def refit_near(self, q, reach: float) -> int:
        """Refit, at the next update, the clusters of the estimates within ``reach`` of the
        point ``q`` (the executive asks when its motion guard finds the robot about to touch a
        return its estimates leave outside: a contradiction too small for the refit rules,
        which wait for ``refit_tol``, but not for the robot next to it). A cluster refitted in
        the last ``_REFIT_LATEST`` scans is not marked again (a robot held by the guard next to
        a return its refits cannot cover would otherwise refit it at every scan). Returns how
        many clusters were marked."""
        q = np.asarray(q, dtype=float).reshape(1, 2)
        marked = 0
        for e in self._est.values():
            cl = self._clusters.get(e.cluster)
            if cl is None or e.cluster in self._urgent or self.scans - cl.last_fit < _REFIT_LATEST:
                continue
            if float(e.squircle.distance(q)[0]) <= reach:
                self._urgent.add(e.cluster)
                marked += 1
        return marked

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_world(cls, world, config: PerceptionConfig | None = None, **overrides) -> "ObstacleMap":
        """A map for ``world`` (a :class:`navigation.World`): its workspace, robot radius,
        regions and lidar (thresholds by :meth:`PerceptionConfig.from_lidar`, ``overrides``
        replacing any of them). Known obstacles are not added (the map starts empty)."""
        cfg = config or PerceptionConfig.from_lidar(world.lidar, **overrides)
        return cls(world.workspace, world.robot.radius, regions=world.regions, config=cfg, beams=world.lidar.beams)

    # ------------------------------------------------------------------ read access
    def __len__(self) -> int:
        return len(self._est)

    @property
    def estimates(self) -> dict[int, Estimate]:
        """Current estimates by id (a copy)."""
        return dict(self._est)

    def obstacles(self) -> list[Squircle]:
        """Estimated obstacles (not inflated), in id order."""
        return [self._est[k].squircle for k in sorted(self._est)]

    def inflated(self) -> list[Squircle]:
        """Estimates grown by the robot radius, in id order (the configuration-space obstacles)."""
        return [self._est[k].inflated for k in sorted(self._est)]

    def forest(self) -> Forest:
        """:func:`navigation.build_forest` of :meth:`inflated` in the workspace shrunk by the
        robot radius (always accepted: the map keeps it so)."""
        cfg = self.config
        return build_forest(self.cspace_workspace, self.inflated(), min_gap=cfg.min_gap, min_overlap=cfg.min_overlap)

    def to_message(self, stamp: float | None = None) -> dict:
        """The bus ``obstacles`` message ``{"stamp", "obstacles": [squircle, ...]}`` (not inflated)."""
        return {"stamp": self.last_stamp if stamp is None else float(stamp),
                "obstacles": [sq.to_dict() for sq in self.obstacles()]}

    def point_cloud(self) -> tuple[np.ndarray, np.ndarray]:
        """Averaged return points ``(N, 2)`` and their cluster labels ``(N,)``."""
        idx = np.nonzero(self._n > 0)
        return self._sum[idx] / self._n[idx][:, None], self._lab[idx]

    # ------------------------------------------------------------------ input checks
    def _check_stamp_pose(self, stamp: float, pose_stamp: float | None, pose, now: float | None) -> None:
        cfg = self.config
        if pose_stamp is not None and abs(pose_stamp - stamp) > cfg.max_stamp_skew:
            raise StampError(f"scan stamp {stamp:.3f} does not match the pose stamp {pose_stamp:.3f} "
                             f"(more than max_stamp_skew = {cfg.max_stamp_skew:g} s apart)", "stamp")
        if self.last_stamp is not None and stamp < self.last_stamp:
            raise StampError(f"stale stamp {stamp:.3f}: older than the last processed {self.last_stamp:.3f}", "stamp")
        if now is not None and stamp > now + cfg.max_future:
            raise StampError(f"stamp {stamp:.3f} is in the future (now = {now:.3f}, "
                             f"max_future = {cfg.max_future:g} s)", "stamp")
        if pose is not None:
            if not self.workspace.beta(np.array(pose[:2])) < 0:
                raise PoseJumpError(f"pose ({pose[0]:.3f}, {pose[1]:.3f}) is outside the workspace", "pose")
            if self.last_pose is not None:
                jump = math.dist(pose[:2], self.last_pose[:2])
                if jump > cfg.max_pose_jump:
                    raise PoseJumpError(f"pose ({pose[0]:.3f}, {pose[1]:.3f}) is {jump:.3f} m from the last "
                                        f"accepted pose (more than max_pose_jump = {cfg.max_pose_jump:g} m)", "pose")

    def _reject(self, err: ScanError):
        log.warning("perception: rejected input: %s", err)
        raise err

    # ------------------------------------------------------------------ public updates
    def update_scan(self, scan, pose, *, now: float | None = None) -> MapUpdate:
        """Integrate one ``scan`` message taken at ``pose`` (pose message or ``(x, y, theta)``).

        Parameters
        ----------
        scan : mapping, str or bytes
            Bus ``scan`` message.
        pose : mapping or sequence
            The pose at the scan's stamp; a pose message's stamp must match the scan's within
            ``max_stamp_skew``.
        now : float, optional
            Current time; stamps more than ``max_future`` ahead are rejected.

        Returns
        -------
        MapUpdate

        Raises
        ------
        ScanError
            Malformed message, empty scan, wrong beam count (logged; the map is unchanged).
        StampError
            Stale, future or mismatched stamp.
        PoseJumpError
            Pose outside the workspace or farther than ``max_pose_jump`` from the last one.
        """
        try:
            pose_stamp, p = parse_pose(pose)
            sc = parse_scan(scan, p, beams=self.beams)
            self._check_stamp_pose(sc.stamp, pose_stamp, p, now)
        except ScanError as err:
            self._reject(err)
        notes = []
        if sc.dropped:
            notes.append(f"trimmed {sc.dropped} invalid beam(s) (NaN or below range_min)")
            log.info("perception: scan %.3f: %s", sc.stamp, notes[-1])
        return self._integrate(sc.stamp, p, sc.points, sc, notes, sc.dropped)

    def update_points(self, message, pose=None, *, now: float | None = None) -> MapUpdate:
        """Integrate a bus ``points`` message (world-frame returns).

        ``pose`` (the sensor pose, optional) tells which side the points were seen from; without
        it the last scan's pose is used. Points carry no free-space evidence.

        Raises
        ------
        ScanError, StampError, PoseJumpError
            As :meth:`update_scan`.
        """
        try:
            stamp, pts, dropped = parse_points(message)
            pose_stamp, p = (None, self.last_pose) if pose is None else parse_pose(pose)
            self._check_stamp_pose(stamp, pose_stamp, p if pose is not None else None, now)
        except ScanError as err:
            self._reject(err)
        notes = []
        if dropped:
            notes.append(f"trimmed {dropped} non-finite point(s)")
            log.info("perception: points %.3f: %s", stamp, notes[-1])
        return self._integrate(stamp, p, pts, None, notes, dropped)

    def observed_free(self, q) -> np.ndarray:
        """Which points ``q (N, 2)`` lie in a ``free_cell`` cell that a beam has crossed (the
        free-space evidence, step 2 of the module docstring): ``(N,)`` bool, False outside the
        grid. The executive takes a narrow passage on a long detour only through space seen
        free (``ExecutiveConfig.seen_detour_ratio``)."""
        q = np.asarray(q, dtype=float).reshape(-1, 2)
        out = np.zeros(len(q), bool)
        fin = np.isfinite(q).all(axis=1)
        ij, ok = self._cells(np.where(fin[:, None], q, 0.0), self.config.free_cell, self._fshape)
        ok &= fin
        out[ok] = self._free[ij[ok, 0], ij[ok, 1]]
        return out

    # ------------------------------------------------------------------ the update
    def _cells(self, q: np.ndarray, size: float, shape) -> tuple[np.ndarray, np.ndarray]:
        ij = np.floor((q - self._lo) / size).astype(np.int64)
        ok = (ij[:, 0] >= 0) & (ij[:, 1] >= 0) & (ij[:, 0] < shape[0]) & (ij[:, 1] < shape[1])
        return ij, ok

    def _boundary_distance(self, q: np.ndarray) -> np.ndarray:
        """Distance of points ``q (N, 2)`` inside the workspace to its boundary, to first
        order: ``(1 - g) / |grad g|`` with the gauge ``g = sqrt(beta + 1)`` (``grad g =
        grad beta / 2 g``). Not the radial error ``|q - c| (1 - 1/g)``, which exceeds the
        distance by up to ``|q - c| / b`` (about 2 near the corners of a 7 x 4 m workspace)
        and would let noisy returns of the boundary through as obstacles."""
        ws = self.workspace
        g = np.maximum(gauge(ws, q), 1e-9)
        dg = np.linalg.norm(ws.gradient(q), axis=1) / (2.0 * g)
        return (1.0 - g) / np.maximum(dg, 1e-12)

    def _integrate(self, stamp: float, pose, pts: np.ndarray, scan: Scan | None, notes: list, trimmed: int) -> MapUpdate:
        cfg = self.config
        fits0 = fit_count()  # (MapUpdate.fits)
        # --- trim: the workspace boundary itself, returns inside the robot disc, off-grid points
        beam_of = np.nonzero(scan.hit)[0] if scan is not None else None  # the beam of each return
        keep = np.ones(len(pts), bool)
        if len(pts):
            keep &= self._boundary_distance(pts) > cfg.ws_band
            if beam_of is not None and cfg.noise_std > 0 and not keep.all():
                # with range noise the band is wide (5 sigma): a return in it is the boundary's
                # only if its beam meets the boundary within the band's reach beyond it; the
                # face of an obstacle near the boundary seen obliquely stays
                band = np.flatnonzero(~keep)
                ang = scan.angles[beam_of[band]]
                beyond = pts[band] + cfg.ws_band * np.stack((np.cos(ang), np.sin(ang)), axis=1)
                keep[band] = self._boundary_distance(beyond) > 0.0
            if pose is not None:
                keep &= np.hypot(pts[:, 0] - pose[0], pts[:, 1] - pose[1]) > self.radius
        pts_k = pts[keep]
        self.last_returns = pts_k
        if beam_of is not None:
            beam_of = beam_of[keep]
        n_trim = int((~keep).sum())
        # --- free-space evidence (beams)
        new_free = np.zeros((0, 2))
        if scan is not None:
            new_free = self._mark_free(scan)
        # --- occupied cells
        new_cells = np.zeros((0, 2), np.int64)
        scan_cell = None
        if len(pts_k):
            ij, ok = self._cells(pts_k, cfg.voxel, self._shape)
            n_trim += int((~ok).sum())
            ij, pts_k = ij[ok], pts_k[ok]
            if beam_of is not None:
                beam_of = beam_of[ok]
            fresh = self._n[ij[:, 0], ij[:, 1]] == 0
            if pose is not None:
                vd = pts_k - np.asarray(pose[:2])
                vd /= np.maximum(np.linalg.norm(vd, axis=1, keepdims=True), 1e-12)
            else:
                vd = np.zeros_like(pts_k)
            under = self._n[ij[:, 0], ij[:, 1]] < _MAX_CELL_COUNT
            sel = under
            # np.add.at of 1, the points and the view directions of the rows sel (compiled, the
            # same additions in the same order)
            _shape_kernel.accumulate(self._n, self._sum, self._view, ij, pts_k, vd, sel)
            # np.unique(ij[fresh], axis=0) by the cells' row-major codes (the same rows, order)
            W = self._shape[1]
            lin = np.unique(ij[fresh, 0] * W + ij[fresh, 1])
            new_cells = np.stack((lin // W, lin % W), axis=1)
            scan_cell = ij
        touched = self._cluster_new(new_cells, scan_cell, beam_of, scan)
        # --- which clusters need a refit
        refit: set[int] = set(touched["new"]) | set(touched["merged"])
        urgent = {lab for lab in self._urgent if lab in self._clusters} - refit
        refit |= urgent
        self.stats["refit_near"] += len(urgent)
        self._urgent.clear()
        for lab in touched["new"]:
            host = self._associate(lab)
            if host is not None:  # returns of an obstacle already estimated: same cluster
                self._merge_labels(host, [lab])
                refit.discard(lab)
                refit.add(host)
        for lab in touched["grown"]:
            if lab in refit:
                continue
            cells = touched["cells"][lab]
            q = self._sum[cells[:, 0], cells[:, 1]] / self._n[cells[:, 0], cells[:, 1]][:, None]
            err = self._cluster_error(lab, q)
            # urgent when a return is about to leave the inflated estimate; otherwise pending
            if err > 0.75 * self.radius:
                refit.add(lab)
                self.stats["refit_grown"] += 1
            elif err > cfg.refit_tol:
                self._clusters[lab].pending = True
                self._clusters[lab].by_points = True
        self.stats["refit_new"] += len(touched["new"])
        self.stats["refit_merged"] += len(touched["merged"])
        if len(new_free) and self._est:
            contra = {lab for lab in self._contradicted(new_free, pose) if lab in self._clusters}
            for lab in contra - refit:
                self._clusters[lab].pending = True
            self.stats["refit_free"] += len(contra - refit)
        waiting: set[int] = set()  # pending refits after a futile one
        due: dict[int, bool] = {}  # pending refits due now -> overdue (waited _REFIT_LATEST times)
        if len(new_cells) or len(new_free):  # (a repeated scan brings nothing new: no refit)
            # pending refits (returns still inside the inflated estimates, free space inside an
            # estimate: accuracy, not safety) are at most one per cluster every
            # ``_REFIT_EVERY`` scans and ride along with a scan that refits anyway (one forest
            # check for all); on quiet scans they wait up to ``_REFIT_LATEST`` scans
            busy = bool(refit)
            for lab, cl in self._clusters.items():
                age = self.scans - cl.last_fit
                # free space that the last refits could not clear (the same fit would come
                # back) waits twice as long per futile refit, up to 4 times (returns do not)
                wait = 1 if cl.by_points else 2 ** min(cl.futile, _MAX_BACKOFF)
                if (_FUTILE_GROWTH and wait > 1 and cl.pending and age >= _REFIT_EVERY
                        and len(self._label_cells(lab)[0]) >= _FUTILE_GROWTH * cl.cells):
                    # returns inside its estimates that the futile refit did not have: new data
                    # for the decomposition, no backoff (random73 noise-free: refitted futile
                    # at 234 returns, 273 at the drive's end, whose decomposition is clean)
                    wait = 1
                if (cl.pending and lab not in refit and age >= _REFIT_EVERY * wait
                        and (busy or cl.deferred or age >= _REFIT_LATEST * wait)):
                    if cl.futile:
                        waiting.add(lab)  # refitted only if its data changed since (_refit)
                    due[lab] = age >= _REFIT_LATEST * wait
        proposed = dict(self._est)
        changed: set[int] = set()
        removed: set[int] = set()
        # the refits the data asks for first, then the due pending ones, longest waiting first,
        # while the update has run fewer than ``_PENDING_BUDGET`` squircle fits (an overdue one
        # regardless); one put off is due at the next update (the work of a heavy update is
        # spread over the next, lighter ones)
        later = sorted(due, key=lambda lab: (self._clusters[lab].last_fit, lab))
        for lab in sorted(refit) + later:
            cl = self._clusters.get(lab)
            if lab in due and cl is not None:
                cl.deferred = bool(_PENDING_BUDGET and not due[lab] and fit_count() - fits0 >= _PENDING_BUDGET)
                if cl.deferred:
                    self.stats["refit_put_off"] += 1
                    continue
            if cl is not None and cl.failed_at:
                n = len(self._label_cells(lab)[0])
                if n < 1.2 * cl.failed_at + 5:
                    continue  # its last refit was reverted: wait for more data
            self._refit(lab, proposed, changed, removed, pose, futile_ok=lab not in waiting)
        # --- clearances of the robot disc (it moved) and of the regions
        if pose is not None:
            self._clear_robot(pose, proposed, changed, removed, notes)
        update = self._commit(stamp, proposed, changed, removed, notes, pose)
        self.last_stamp = stamp
        if pose is not None and scan is not None:
            self.last_pose = tuple(pose)
        self.scans += 1
        return MapUpdate(stamp, update[0], update[1], update[2], len(pts_k), trimmed + n_trim, tuple(notes),
                         fit_count() - fits0)

    def _mark_free(self, scan: Scan) -> np.ndarray:
        """Mark the cells the beams crossed as free; return the centres of newly free cells."""
        cfg = self.config
        valid = ~np.isnan(scan.ranges)
        L = np.where(scan.hit, scan.ranges - cfg.free_margin, scan.range_max)[valid]
        # a beam from the pose (inside the workspace, so inside the grid) leaves the grid within
        # its diagonal: longer beams (a lidar claiming a 1e8 m range) add no cell, only samples
        L = np.minimum(L, cfg.free_cell * math.hypot(*self._fshape))
        ang = scan.angles[valid]
        step = cfg.free_cell / 2
        t = np.arange(step, max(float(L.max(initial=0.0)), 0.0), step)
        if not len(t) or not len(L):
            return np.zeros((0, 2))
        # cell indices of the samples t < L of every beam, those not yet free (compiled: per
        # sample ((pose - lo) + t cos) / free_cell floored, as the numpy form
        #   m = t[None] < L[:, None]; fx = ((pose - lo) + t[None] * cos(ang)[:, None])[m] / free_cell
        # did; cos and sin numpy's, once per beam)
        flat = self._free.reshape(-1)  # a view (C-contiguous)
        lin = _shape_kernel.free_cells(scan.pose[0] - self._lo[0], scan.pose[1] - self._lo[1], t, L, np.cos(ang),
                                       np.sin(ang), cfg.free_cell, self._fshape, flat)
        # only the samples in cells not yet free need sorting (few once the area is explored)
        lin = np.unique(lin)
        flat[lin] = True
        fi, fj = lin // self._fshape[1], lin % self._fshape[1]
        return self._lo + (np.stack((fi, fj), axis=1) + 0.5) * cfg.free_cell

    def _cluster_new(self, new_cells: np.ndarray, scan_cell, beam_of, scan) -> dict:
        """Give labels to new cells (joining, possibly merging, clusters). Returns the labels of
        ``new`` clusters, ``merged`` clusters, ``grown`` clusters and their new cells."""
        cfg = self.config
        out = {"new": [], "merged": [], "grown": [], "cells": {}}
        if not len(new_cells):
            return out
        k = int(math.ceil(cfg.link / cfg.voxel)) + 1
        H, W = self._shape
        i0, j0 = np.maximum(new_cells.min(axis=0) - k, 0)
        i1, j1 = np.minimum(new_cells.max(axis=0) + k + 1, self._shape)
        # Links within ``link`` of a new cell, found on the grid (the cells up to ``k`` cells
        # away: a point lies in its cell). Links between two old cells are not needed: old cells
        # within ``link`` of each other already share a label (each cell joined every cell
        # within ``link`` when it was added), so the old cells of one label are joined through
        # one node per label instead (a k-d tree of every occupied cell around the new ones,
        # 0.8 ms per scan with new cells on office, is not needed).
        off = self._grid_offsets(k)
        cand = (new_cells[:, None, :] + off[None, :, :]).reshape(-1, 2)
        src = np.repeat(np.arange(len(new_cells)), len(off))
        ok = (cand[:, 0] >= 0) & (cand[:, 1] >= 0) & (cand[:, 0] < H) & (cand[:, 1] < W)
        cand, src = cand[ok], src[ok]
        ok = self._n[cand[:, 0], cand[:, 1]] > 0
        cand, src = cand[ok], src[ok]
        qn = self._sum[new_cells[:, 0], new_cells[:, 1]] / self._n[new_cells[:, 0], new_cells[:, 1]][:, None]
        qc = self._sum[cand[:, 0], cand[:, 1]] / self._n[cand[:, 0], cand[:, 1]][:, None]
        ok = np.hypot(qc[:, 0] - qn[src, 0], qc[:, 1] - qn[src, 1]) <= cfg.link
        new_lin = new_cells[:, 0] * W + new_cells[:, 1]
        ea, eb = [new_lin[src[ok]]], [cand[ok, 0] * W + cand[ok, 1]]
        # along-scan continuity: consecutive beams without a range discontinuity (cells of the
        # window around the new cells)
        if scan is not None and beam_of is not None and len(beam_of) > 1:
            r = scan.ranges[beam_of]
            pts_b = np.stack((scan.pose[0] + r * np.cos(scan.angles[beam_of]),
                              scan.pose[1] + r * np.sin(scan.angles[beam_of])), axis=1)
            d = np.linalg.norm(np.diff(pts_b, axis=0), axis=1)
            adj = (np.diff(beam_of) == 1) & (d <= cfg.breakpoint(np.minimum(r[:-1], r[1:])))
            t = np.flatnonzero(adj)
            A, B = scan_cell[t], scan_cell[t + 1]
            inw = ((A[:, 0] >= i0) & (A[:, 0] < i1) & (A[:, 1] >= j0) & (A[:, 1] < j1)
                   & (B[:, 0] >= i0) & (B[:, 0] < i1) & (B[:, 1] >= j0) & (B[:, 1] < j1))
            la, lb = A[inw, 0] * W + A[inw, 1], B[inw, 0] * W + B[inw, 1]
            ea.append(la[la != lb])
            eb.append(lb[la != lb])
        ea, eb = np.concatenate(ea), np.concatenate(eb)
        nodes = np.unique(np.concatenate((new_lin, ea, eb)))  # row-major order, as the window's cells
        labs = self._lab.reshape(-1)[nodes]
        si, sj = nodes // W, nodes % W
        n = len(nodes)
        old_at = np.flatnonzero(labs >= 0)
        ulab, inv = np.unique(labs[old_at], return_inverse=True)
        e0 = np.concatenate((np.searchsorted(nodes, ea), old_at))
        e1 = np.concatenate((np.searchsorted(nodes, eb), n + inv.reshape(-1)))
        comp = _graph_components(n + len(ulab), e0, e1)[:n]
        is_new = labs < 0
        for c in np.unique(comp[is_new]):
            members = comp == c
            old = sorted(set(int(v) for v in labs[members]) - {-1})
            cells = np.stack((si[members & is_new], sj[members & is_new]), axis=1)
            if not old:
                lab = self._next_label
                self._next_label += 1
                self._clusters[lab] = _Cluster()
                out["new"].append(lab)
            else:
                lab = old[0]
                if len(old) > 1:
                    self._merge_labels(lab, old[1:])
                    out["merged"].append(lab)
                else:
                    out["grown"].append(lab)
            self._lab[cells[:, 0], cells[:, 1]] = lab
            self._grow_box(lab, (int(cells[:, 0].min()), int(cells[:, 0].max()) + 1,
                                 int(cells[:, 1].min()), int(cells[:, 1].max()) + 1))
            prev = out["cells"].get(lab)
            out["cells"][lab] = cells if prev is None else np.concatenate((prev, cells))
        cells: dict[int, np.ndarray] = {}
        for lab, c in out["cells"].items():
            r = self._resolve(lab)
            cells[r] = c if r not in cells else np.concatenate((cells[r], c))
        out["cells"] = cells
        out["new"] = sorted({self._resolve(lab) for lab in out["new"]})
        out["merged"] = sorted({self._resolve(lab) for lab in out["merged"]} - set(out["new"]))
        out["grown"] = sorted({self._resolve(lab) for lab in out["grown"]} - set(out["merged"]) - set(out["new"]))
        return out

    @staticmethod
    def _grid_offsets(k: int) -> np.ndarray:
        """Cell offsets ``(di, dj)`` with ``|di|, |dj| <= k``, shape ``((2k+1)^2, 2)``."""
        hit = _OFFSETS.get(k)
        if hit is None:
            r = np.arange(-k, k + 1)
            hit = _OFFSETS[k] = np.stack(np.meshgrid(r, r, indexing="ij"), axis=-1).reshape(-1, 2)
        return hit

    def _grow_box(self, lab: int, box) -> None:
        old = self._box.get(lab)
        self._box[lab] = box if old is None else (min(old[0], box[0]), max(old[1], box[1]),
                                                  min(old[2], box[2]), max(old[3], box[3]))

    def _label_cells(self, lab: int) -> tuple[np.ndarray, np.ndarray]:
        """``np.nonzero(self._lab == lab)`` (the same indices in the same order), searched in the
        window of the label's cells only."""
        box = self._box.get(lab)
        if box is None:
            return np.zeros(0, np.intp), np.zeros(0, np.intp)
        i0, i1, j0, j1 = box
        ii, jj = np.nonzero(self._lab[i0:i1, j0:j1] == lab)
        return ii + i0, jj + j0

    def _merge_labels(self, keep: int, others: Iterable[int]) -> None:
        others = list(others)
        boxes = [self._box.pop(o) for o in others if o in self._box]
        if boxes:  # (the cells of ``others`` lie in their windows)
            i0, i1 = min(b[0] for b in boxes), max(b[1] for b in boxes)
            j0, j1 = min(b[2] for b in boxes), max(b[3] for b in boxes)
            win = self._lab[i0:i1, j0:j1]
            win[np.isin(win, others)] = keep
            self._grow_box(keep, (i0, i1, j0, j1))
        for o in others:
            self._alias[o] = keep
            cl = self._clusters.pop(o, None)
            if cl is not None:
                self._clusters[keep].ids.extend(cl.ids)
                self._clusters[keep].single |= cl.single
                self._clusters[keep].cache.pop("one", None)  # a new cluster as a whole

    def _associate(self, lab: int) -> int | None:
        """Cluster of the estimate that contains most returns of the new cluster ``lab``
        (within ``refit_tol``), if any: association of new clusters with existing estimates."""
        if not self._est:
            return None
        idx = self._label_cells(lab)
        q = self._sum[idx] / self._n[idx][:, None]
        best = None
        for e in self._est.values():
            sq = e.squircle
            if (np.hypot(q[:, 0] - sq.center[0], q[:, 1] - sq.center[1]) <= sq.bounding_radius + 0.05).any():
                share = float(np.mean(radial_error(sq, q) <= self.config.refit_tol))
                if share >= 0.5 and (best is None or share > best[0]):
                    best = (share, self._resolve(e.cluster))
        if best is None or best[1] == lab or best[1] not in self._clusters:
            return None
        return best[1]

    def _resolve(self, lab: int) -> int:
        while lab in self._alias:
            lab = self._alias[lab]
        return lab

    def _cluster_error(self, lab: int, q: np.ndarray) -> float:
        """Largest distance of points ``q`` outside the union of the cluster's estimates."""
        ids = [i for i in self._clusters[lab].ids if i in self._est]
        if not ids:
            return math.inf
        err = np.min([radial_error(self._est[i].squircle, q) for i in ids], axis=0)
        return float(err.max())

    def _contradicted(self, free: np.ndarray, pose) -> set[int]:
        """Clusters with an estimate containing a newly free cell deeper than ``free_tol``."""
        cfg = self.config
        out = set()
        lo, hi = free.min(axis=0), free.max(axis=0)
        for e in self._est.values():
            sq = e.squircle
            rb = sq.bounding_radius
            c = np.asarray(sq.center)
            if (c + rb < lo).any() or (c - rb > hi).any() or e.cluster in out:
                continue
            near = free[np.hypot(free[:, 0] - c[0], free[:, 1] - c[1]) < rb]
            if len(near) and float(radial_error(sq, near).min()) < -cfg.free_tol:
                out.add(e.cluster)
        return out

    def _cluster_data(self, lab: int):
        cfg = self.config
        idx = self._label_cells(lab)
        n = self._n[idx][:, None]
        q = self._sum[idx] / n
        v = self._view[idx]
        v = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
        # free cells around the cluster
        pad = cfg.min_unseen + 0.05
        lo = np.floor((q.min(axis=0) - pad - self._lo) / cfg.free_cell).astype(int)
        hi = np.ceil((q.max(axis=0) + pad - self._lo) / cfg.free_cell).astype(int)
        lo = np.maximum(lo, 0)
        hi = np.minimum(hi, self._fshape)
        fi, fj = np.nonzero(self._free[lo[0]:hi[0], lo[1]:hi[1]])
        free = self._lo + (np.stack((fi + lo[0], fj + lo[1]), axis=1) + 0.5) * cfg.free_cell
        tree = cKDTree(q) if len(q) else None  # (also for the virtual returns below)
        if len(free) and tree is not None:
            # a free cell holding returns is not evidence (grazing beams)
            d, _ = tree.query(free, distance_upper_bound=cfg.free_cell)
            free = free[~np.isfinite(d)]
        # a cluster touching the workspace boundary continues through it
        ws = self.workspace
        e_ws = radial_error(ws, q)
        near = e_ws > -cfg.ws_touch
        if near.any():
            # virtual returns just outside the boundary, continuing the faces that reach it
            qn = q[near]
            nrm = ws.gradient(qn)
            nrm = nrm / np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
            step = _face_directions(tree, q, qn, nrm, cfg.link)
            depth = (-e_ws[near] + cfg.ws_touch + 0.03) / np.einsum("ij,ij->i", step, nrm)
            virt = qn + step * depth[:, None]
            q = np.concatenate((q, virt))
            v = np.concatenate((v, nrm))
        return q, v, free

    def _refit(self, lab: int, proposed: dict, changed: set, removed: set, pose, futile_ok: bool = True) -> None:
        cl = self._clusters.get(lab)
        if cl is None:
            return
        q, v, free = self._cluster_data(lab)
        if not len(q):
            return
        data = (len(q), hash(q.tobytes()), len(free), hash(np.ascontiguousarray(free).tobytes()))
        if (not futile_ok and _SKIP_SAME and data == cl.data and len(cl.result) == len(cl.ids)
                and all(i in proposed and proposed[i].squircle is sq for i, sq in zip(cl.ids, cl.result))):
            # the same returns and free cells as at its last, futile, refit, and its estimates
            # as that refit left them (no repair merged or grew one since): the same fit would
            # come back; wait again (it stays pending)
            cl.last_fit = self.scans
            self.stats["refit_skipped"] += 1
            return
        cl.data = data
        cl.cells = len(self._label_cells(lab)[0])
        old = [i for i in cl.ids if i in proposed]
        # an estimate the free space contradicts deeply (a free cell more than ``2 free_tol``
        # inside) is no warm start: warm-started from such a box over the free space between
        # the arms of a Y of walls, random13 noisy's pieces came back as the same box (258
        # free cells inside; cold, four pieces along the arms)
        init = [proposed[i].squircle for i in old]
        if len(free):
            init = [sq for sq in init if float(radial_error(sq, free).min()) >= -2 * self.config.free_tol]
        fits = fit_cluster(q, views=v, free=free, config=self.config, split=not cl.single, grow=1.05 * self.radius,
                           init=init, cache=cl.cache)
        new_ids = []
        # a piece that kept its previous estimate (the same squircle object) keeps its id;
        # the others take the remaining ids in order, then new ones
        kept = {id(proposed[i].squircle): i for i in old}
        own, used = [], set()
        for f in fits:
            i = kept.get(id(f.squircle))
            own.append(None if i in used else i)
            used.add(i)
        spare = [i for i in old if i not in own]
        for f, i in zip(fits, own):
            sq = f.squircle
            if i is not None:
                new_ids.append(i)
                continue
            if spare:
                i = spare.pop(0)
                if _same(proposed[i].squircle, sq):
                    new_ids.append(i)
                    continue
            else:
                i = self._next_id
                self._next_id += 1
            proposed[i] = Estimate(i, sq, inflate(sq, self.radius), lab, f.rms, f.closed)
            changed.add(i)
            new_ids.append(i)
        for i in spare:
            proposed.pop(i, None)
            removed.add(i)
            changed.discard(i)
        cl.ids = new_ids
        cl.failed_at = 0
        cl.last_fit = self.scans
        cl.by_points = cl.deferred = False
        ids = [i for i in new_ids if i in proposed]
        deep = bool(len(free) and ids) and any(
            float(radial_error(proposed[i].squircle, free).min()) < -self.config.free_tol for i in ids)
        cl.futile = cl.futile + 1 if deep else 0
        # a futile refit stays pending (refitted after the backoff's wait): the free cells it
        # left inside its estimates are old, no new free cell would mark it again, and its
        # estimates stayed as they were for the rest of a drive (random17 noisy: 169 free cells
        # inside one estimate, not refitted in its last 100 scans)
        cl.pending = deep
        cl.result = tuple(proposed[i].squircle for i in ids)
        # regions: keep their discs (grown by the radius) free; decompose rather than uncover
        # (returns a trim left outside the cluster's estimates, a piece that bridged free space
        # around the region, get estimates of their own)
        self._clear_regions(new_ids, proposed, changed, removed, None, lab, (q, v, free))

    def _recover(self, lab: int, proposed: dict, changed: set, data=None) -> list[int]:
        """Returns of cluster ``lab`` that its estimates (after a trim) leave more than
        ``refit_tol`` outside, fitted with ``fit_cluster`` as estimates of their own; returns
        the new ids. ``data``: the cluster's ``(q, v, free)`` when already at hand."""
        cl = self._clusters.get(lab)
        if cl is None:
            return []
        q, v, free = self._cluster_data(lab) if data is None else data
        if not len(q):
            return []
        ids = [i for i in cl.ids if i in proposed]
        err = (np.min([radial_error(proposed[i].squircle, q) for i in ids], axis=0) if ids
               else np.full(len(q), np.inf))
        lost = err > self.config.refit_tol
        if not np.count_nonzero(lost):
            return []
        extra = fit_cluster(q[lost], views=v[lost], free=free, config=self.config, split=not cl.single,
                            grow=1.05 * self.radius)
        add = []
        for f in extra:
            i = self._next_id
            self._next_id += 1
            proposed[i] = Estimate(i, f.squircle, inflate(f.squircle, self.radius), lab, f.rms, f.closed)
            changed.add(i)
            add.append(i)
        cl.ids.extend(add)
        self.stats["recovered"] += int(np.count_nonzero(lost))
        return add

    def _trim_regions(self, ids, proposed, changed, removed) -> bool:
        """Trim the changed estimates ``ids`` clear of every region disc grown by the radius;
        True when any was trimmed or removed."""
        any_trim = False
        for i in list(ids):
            if i in changed:
                for c, rr in self.regions:
                    if self._trim(i, c, rr + self.radius, proposed, changed, removed, f"region at {c.tolist()}"):
                        any_trim = True
        return any_trim

    def _clear_regions(self, ids, proposed, changed, removed, notes, lab=None, data=None) -> None:
        """Trim the estimates ``ids`` clear of the region discs, decomposing rather than
        uncovering: the returns a trim left outside their cluster's estimates get estimates of
        their own (:meth:`_recover`), trimmed too. A refit calls it for its cluster ``lab``
        (whose ``(q, v, free)`` are ``data``; no note); the forest repairs for the covers they
        make (two estimates merged to break a cycle can span a region between them:
        ``random520``, two bars over ``r1`` merged into one squircle over it, and the robot
        stopped blocked with ``r1`` walled off), each estimate's own cluster recovering, with
        a note in ``notes``."""
        trimmed = []
        for i in ids:
            own = lab if lab is not None else (self._resolve(proposed[i].cluster) if i in proposed else None)
            if self._trim_regions([i], proposed, changed, removed):
                trimmed.append(own)
        add = []
        for own in dict.fromkeys(own for own in trimmed if own is not None):
            add += self._recover(own, proposed, changed, data if own == lab else None)
        self._trim_regions(add, proposed, changed, removed)
        if trimmed and notes is not None:
            notes.append(f"trimmed {len(trimmed)} repaired estimate(s) clear of the region discs"
                         + (f", fitted {len(add)} estimate(s) to the returns left outside" if add else ""))

    def _clear_robot(self, pose, proposed, changed, removed, notes, only=None, recover: bool = True) -> None:
        """Trim every estimate clear of the robot disc. Decompose rather than uncover (as for the
        regions): returns a trim left more than ``refit_tol`` outside their cluster's estimates
        (a piece that bridged the free space the robot drives through, e.g. two walls merged
        to break a cycle) get estimates of their own, themselves trimmed clear of the robot;
        random18 noise-free lost 4.5 % of its hit boundary points to such trims."""
        p = np.asarray(pose[:2], dtype=float)
        trimmed = []
        for i in list(proposed if only is None else only):
            e = proposed[i]
            if math.dist(e.inflated.center, p) > e.inflated.bounding_radius + self.radius:
                continue
            if _rect_gap(e.inflated, p) > 0 and _rect_gap(e.squircle, p) >= self.radius + self.config.clearance_margin:
                continue  # (a squircle lies inside its rectangle: the exact distance is larger)
            if e.inflated.beta(p) <= 0 or e.squircle.distance(p) < self.radius + self.config.clearance_margin:
                msg = self._trim(i, p, self.radius, proposed, changed, removed, "robot disc")
                if msg:
                    notes.append(msg)
                    trimmed.append(self._resolve(e.cluster))
        if recover and only is None and trimmed:
            add = []
            for lab in dict.fromkeys(trimmed):
                add += self._recover(lab, proposed, changed)
            if add:
                notes.append(f"fitted {len(add)} estimate(s) to returns a robot-disc trim left outside")
                self._clear_robot(pose, proposed, changed, removed, notes, only=add)

    def _trim(self, i: int, p: np.ndarray, clearance: float, proposed, changed, removed, what: str) -> str:
        """Move the face of estimate ``i`` facing ``p`` back until the inflated estimate keeps
        ``clearance`` (plus ``clearance_margin``) from ``p``; remove it if that leaves nothing."""
        cfg = self.config
        e = proposed.get(i)
        if e is None:
            return ""
        sq = e.squircle
        need = clearance + cfg.clearance_margin
        # (the inflated estimate reaches beyond ``bounding_radius + radius`` at its corners:
        # inflate grows the extents by 2 k r, k >= 1; cluttered20 noisy covered the robot)
        if math.dist(sq.center, p) > max(sq.bounding_radius + need, e.inflated.bounding_radius):
            return ""
        if _rect_gap(sq, p) >= need and e.inflated.beta(p) > 0:
            return ""  # (the rectangle gap is a lower bound of the distance: no exact distance needed)
        d0 = float(sq.distance(p))
        if d0 >= need and e.inflated.beta(p) > 0:
            return ""
        # the face p lies in front of (the larger of |u| / h), and, with ``_TRIM_BOTH``, the
        # other axis's face towards p: the cut keeping more area is taken. A region disc off a
        # wall's corner cut the wall along its whole length from the side (random41 noisy: the
        # returns of the face left outside were fitted as pieces of their own, which closed
        # cycles with the wall, merged into an ellipse over free space, IoU 0.597); moving its
        # end back loses a few centimetres of the wall
        cuts = [c for c in (self._cut(sq, p, need, k) for k in self._trim_axes(sq, p)) if c is not None]
        if not cuts:
            proposed.pop(i, None)
            changed.discard(i)
            removed.add(i)
            cl = self._clusters.get(e.cluster)
            if cl is not None and i in cl.ids:
                cl.ids.remove(i)
            msg = f"removed estimate {i}: it cannot be trimmed clear of the {what}"
            log.warning("perception: %s", msg)
            return msg
        sq, inf, _ = max(cuts, key=lambda c: (c[2], c[0].area))
        proposed[i] = Estimate(i, sq, inf, e.cluster, e.rms, e.closed)
        changed.add(i)
        msg = f"trimmed estimate {i} clear of the {what}"
        log.info("perception: %s", msg)
        return msg

    @staticmethod
    def _trim_axes(sq: Squircle, p: np.ndarray) -> list[int]:
        """The axes whose face towards ``p`` a trim may move: the one ``p`` lies in front of
        (:func:`_facing_axis`) first, then, with ``_TRIM_BOTH``, the other."""
        k = _facing_axis(*_frame(sq, p)[:2])
        return [k, 1 - k] if _TRIM_BOTH else [k]

    def _cut(self, sq: Squircle, p: np.ndarray, need: float, k: int) -> tuple[Squircle, Squircle, bool] | None:
        """Move the face of ``sq`` on axis ``k`` towards ``p`` back until the inflated squircle
        keeps ``need`` from ``p`` (the opposite face stays); ``(cut, inflated, clear)`` (clear
        False: still short after 12 steps), or None when less than ``min_extent`` would be left."""
        inf = None
        for _ in range(12):
            u, h, axes = _frame(sq, p)
            sgn = 1.0 if u[k] >= 0 else -1.0
            face = abs(u[k]) - need - 0.01  # new position of the face towards p
            newh = (face + h[k]) / 2
            if newh * 2 < self.config.min_extent:
                return None
            shift = sgn * (face - h[k]) / 2
            ctr = np.asarray(sq.center) + np.array(axes[k]) * shift
            w, hh = (2 * newh, sq.height) if k == 0 else (sq.width, 2 * newh)
            sq = Squircle((float(ctr[0]), float(ctr[1])), w, hh, sq.theta, sq.s)
            # clear by ``need``? (the rectangle gap is a lower bound of the distance: the exact
            # distance only when it does not already decide; the inflation only when clear)
            if _rect_gap(sq, p) >= need or float(sq.distance(p)) >= need:
                inf = inflate(sq, self.radius)
                if inf.beta(p) > 0:
                    return sq, inf, True
                need += 0.02  # the inflation (extents + 2 k r) bulges past the offset: cut deeper
                inf = None
        return sq, (inf if inf is not None else inflate(sq, self.radius)), False

    # ------------------------------------------------------------------ forest check and repair
    def _near(self, a: Estimate, b: Estimate, pad: float) -> bool:
        """The inflated estimates overlap, or come within about ``pad`` of each other."""
        A, B = a.inflated, b.inflated
        if math.dist(A.center, B.center) > A.bounding_radius + B.bounding_radius + pad:
            return False
        for X, Y in ((A, B), (B, A)):
            pts = _samples(X)
            c = np.asarray(X.center)
            u = pts - c
            pts = pts + u / np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12) * pad
            if (gauge(Y, pts) <= 1.0).any():
                return True
        return False

    def _subset(self, proposed: dict, seeds: set) -> list[int]:
        """Ids of the estimates connected to ``seeds`` by overlap or near contact (within
        ``min_gap`` plus 2 cm) of their inflated squircles."""
        if not seeds:
            return []
        pad = self.config.min_gap + 0.02
        todo = [i for i in seeds if i in proposed]
        out = set(todo)
        while todo:
            i = todo.pop()
            for j, e in proposed.items():
                if j not in out and self._near(proposed[i], e, pad):
                    out.add(j)
                    todo.append(j)
        return sorted(out)

    def _ws_inside(self, sq: Squircle, need: float) -> bool:
        """``sq`` lies inside the workspace shrunk by the radius, farther than ``need`` from its
        boundary (lower bounds of the distance, cheapest first): the depth of a point ``p`` of a
        squircle is at least ``(1 - g(p)) r`` (``g`` the gauge about its centre, ``r = min(width,
        height) / 2`` the radius of a disc about the centre it contains), first for the bounding
        disc of ``sq``, then for its 64 boundary samples, then their distance to the nearest of
        4096 samples of the workspace boundary; less one sample spacing of each (every boundary
        point is that close to a sample)."""
        ws = self.cspace_workspace
        rin = min(ws.width, ws.height) / 2
        if (1.0 - float(gauge(ws, np.asarray(sq.center))[0])) * rin - sq.bounding_radius > need:
            return True
        pts = _samples(sq)
        g = gauge(ws, pts)
        if not bool((g < 1.0).all()):
            return False
        sp = _spacing(pts)
        if float((1.0 - g).min()) * rin - sp > need:
            return True
        return float(self._ws_tree.query(pts)[0].min()) - self._ws_spacing - sp > need

    def _ws_crossing(self, sq: Squircle, deep: float) -> bool:
        """``sq`` provably crosses the boundary of the workspace shrunk by the radius once (one
        arc of its boundary outside, long enough that the construction's 256 samples find it
        and its complement) near the middle of a face, and a point of ``sq`` deeper than
        ``deep`` in it lies farther than ``deep`` outside the workspace.

        In the frame of that face (``y`` along its outward normal, the workspace ``W`` inside
        the rectangle ``|y| <= Y``): the bottom corners of the rectangle of ``sq`` lie in ``W``,
        so by convexity ``W`` meets the rectangle in ``y <= psi(x)`` with ``psi`` concave; below
        ``Y_lo = min(psi(x0), psi(x1))`` the boundary of ``sq`` is inside ``W``, above ``Y``
        outside; between the two it runs along two legs, one on each side, on which
        ``y - psi(x(y))`` increases (slope ``>= 1 - |psi'| |dx/dy| > 0``: ``|psi'|`` is largest at
        ``x0`` or ``x1``, ``psi`` being concave, and ``|dx/dy|`` at the ends of a leg, the normal of
        a convex curve turning monotonically), so each leg crosses once."""
        ws = self.cspace_workspace
        cw = np.asarray(ws.center, dtype=float)
        ct, st = math.cos(ws.theta), math.sin(ws.theta)
        du, dv = sq.center[0] - cw[0], sq.center[1] - cw[1]
        cu, cv = du * ct + dv * st, dv * ct - du * st
        if abs(cv) / ws.height >= abs(cu) / ws.width:  # top or bottom face
            ey = np.array([-st, ct]) * (1.0 if cv >= 0 else -1.0)
            ex = np.array([ct, st])
            Y = ws.height / 2
        else:
            ey = np.array([ct, st]) * (1.0 if cu >= 0 else -1.0)
            ex = np.array([-st, ct])
            Y = ws.width / 2
        M = np.stack((ex, ey))  # world offsets -> face frame

        def world(x, y):
            return cw + np.outer(x, ex) + np.outer(y, ey)

        pts = (_samples(sq) - cw) @ M.T
        top, bot = pts[int(np.argmax(pts[:, 1]))], pts[int(np.argmin(pts[:, 1]))]
        c, sn = math.cos(sq.theta), math.sin(sq.theta)
        hw, hh = sq.width / 2, sq.height / 2
        rect = (np.array([[sq.center[0] + a * hw * c - b * hh * sn, sq.center[1] + a * hw * sn + b * hh * c]
                          for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1))]) - cw) @ M.T
        x0, x1, y0 = float(rect[:, 0].min()), float(rect[:, 0].max()), float(rect[:, 1].min())
        # the construction's samples are about perimeter / 256 apart (perimeter <= 2 (w + h))
        arc = 4.0 * 2.0 * (sq.width + sq.height) / 256
        if top[1] - Y <= max(deep, arc / 2) or y0 >= Y:
            return False
        if not bool((gauge(ws, world(np.array([x0, x1]), np.array([y0, y0]))) < 1.0).all()):
            return False

        def bisect(inside, outside, g):
            """Points of ``g``'s boundary between ``inside`` (g < 1) and ``outside`` (g >= 1), (K, 2)
            face-frame arrays: ``(lo, mid)``, the last point inside (a bound on the safe side)
            and the midpoint (within 1e-7 of the bracket's length: the slopes there are used
            with a margin of 2)."""
            lo, hi = inside.copy(), outside.copy()
            for _ in range(24):
                mid = 0.5 * (lo + hi)
                ins = g(mid) < 1.0
                lo[ins], hi[~ins] = mid[ins], mid[~ins]
            return lo, 0.5 * (lo + hi)

        gw = lambda P: gauge(ws, world(P[:, 0], P[:, 1]))  # noqa: E731
        ge = lambda P: gauge(sq, world(P[:, 0], P[:, 1]))  # noqa: E731
        lo, psi = bisect(np.array([[x0, y0], [x1, y0]]), np.array([[x0, Y + 1e-6], [x1, Y + 1e-6]]), gw)
        y_lo = float(lo[:, 1].min())
        if y_lo - bot[1] <= arc / 2:
            return False
        grad = ws.gradient(world(psi[:, 0], psi[:, 1])) @ M.T
        if not bool((grad[:, 1] > 0).all()):
            return False
        kappa = float(np.max(np.abs(grad[:, 0]) / grad[:, 1]))  # |psi'| at x0 and x1
        # the legs' ends: boundary points of ``sq`` at heights y_lo and Y, left and right of the
        # chord from its bottom to its top sample (inside ``sq``)
        hs = np.array([y_lo, Y, y_lo, Y])
        t = (hs - bot[1]) / (top[1] - bot[1])
        mid = bot + t[:, None] * (top - bot)
        if not bool((ge(mid) < 1.0).all()):
            return False
        far = np.stack((np.array([x0 - 1e-3, x0 - 1e-3, x1 + 1e-3, x1 + 1e-3]), hs), axis=1)
        _, ends = bisect(mid, far, ge)
        n = sq.gradient(world(ends[:, 0], ends[:, 1])) @ M.T
        if not bool((np.abs(n[:, 0]) > 1e-12).all()):
            return False
        slope = float(np.max(np.abs(n[:, 1] / n[:, 0])))  # |dx/dy| at the ends of the legs
        if kappa * slope > 0.5:
            return False
        # a point deep in ``sq`` and beyond the face (W lies in |y| <= Y): on the chord
        cand = bot + ((Y + np.array([0.25, 0.5, 0.75]) * (top[1] - Y) - bot[1]) / (top[1] - bot[1]))[:, None] * (top - bot)
        depth = np.minimum(_polygon_depth(_samples(sq) - cw, (cand[:, 0:1] * ex + cand[:, 1:2] * ey)),
                           cand[:, 1] - Y)
        return float(depth.max()) > deep

    def _certified(self, proposed: dict, seeds: set, sub: list[int]) -> bool:
        """True when the forest check of ``sub`` (the changed estimates ``seeds`` and the
        estimates near them) provably passes, so that it need not run.

        Sufficient conditions, with a margin ``_CERT_MARGIN`` beyond ``min_gap`` and
        ``min_overlap`` (far above the accuracy of the construction's distances and common
        centres):

        * every changed estimate lies inside the workspace (shrunk by the radius), farther than
          ``min_gap`` plus the margin from its boundary (:meth:`_ws_inside`);
        * every other estimate whose bounding disc comes within ``min_gap`` plus the margin of a
          changed one is either separated from it by more than that (separating axes of the two
          rectangles, :func:`_rect_separation`) or overlaps it with a point deeper than
          ``min_overlap`` plus the margin in both (depth in the inscribed polygons of 64 boundary
          samples, :func:`_polygon_depth`, at the mean of the samples of each inside the other):
          no too-close pair, no shallow overlap, whatever the orientation of the tree;
        * the graph of possible overlaps among ``sub`` and the workspace boundary (an edge
          between two estimates unless their rectangles are separated, between an unchanged
          estimate and the boundary unless it lies inside the workspace) has no cycle: a superset
          of the construction's overlap graph (contained estimates are dropped there, which only
          removes edges), so that graph is a forest.

        The estimates outside ``sub`` are unchanged and connected to it by no possible overlap.
        Then the construction accepts the map, as it accepted it before the change: with
        isolated changes (a refitted piece that keeps its overlaps, a new lone obstacle) the
        check's common centres and distances are not computed."""
        cfg = self.config
        seeds = {i for i in seeds if i in proposed}
        if not seeds:
            return True
        gap = cfg.min_gap + _CERT_MARGIN
        deep = cfg.min_overlap + _CERT_MARGIN
        W = -1
        parent = {i: i for i in sub}
        parent[W] = W

        def find(i):
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        def link(i, j) -> bool:
            ri, rj = find(i), find(j)
            if ri == rj:
                return False  # a possible cycle
            parent[ri] = rj
            return True

        in_sub = set(sub)
        for i in seeds:
            E = proposed[i].inflated
            if not self._ws_inside(E, gap):
                if not self._ws_crossing(E, deep):
                    return False  # near the boundary, or a crossing not certain: the construction decides
                if not link(i, W):
                    return False
        for i in sub:
            if i not in seeds and not self._ws_inside(proposed[i].inflated, 0.0) and not link(i, W):
                return False
        for i in seeds:
            E = proposed[i].inflated
            for j, f in proposed.items():
                if j == i or j in in_sub:
                    continue
                F = f.inflated
                if math.dist(E.center, F.center) > E.bounding_radius + F.bounding_radius + gap:
                    continue
                if _rect_separation(E, F) <= gap:
                    return False  # near the changed estimate but not in ``sub``
        for x, i in enumerate(sub):
            E = proposed[i].inflated
            for j in sub[x + 1:]:
                F = proposed[j].inflated
                changed = i in seeds or j in seeds
                need = gap if changed else 0.0
                if math.dist(E.center, F.center) > E.bounding_radius + F.bounding_radius + need:
                    continue
                sep = _rect_separation(E, F)
                if sep > need:
                    continue
                if changed:
                    if sep > 0:
                        return False  # separated by less than ``gap``: a too-close pair?
                    pa, pb = _samples(E), _samples(F)
                    ia, ib = pa[gauge(F, pa) < 1.0], pb[gauge(E, pb) < 1.0]
                    cand = [c.mean(axis=0) for c in (ia, ib, np.concatenate((ia, ib))) if len(c)]
                    if not cand:
                        return False
                    cand = np.array(cand)
                    d = np.minimum(_polygon_depth(pa, cand), _polygon_depth(pb, cand))
                    if float(d.max()) <= deep:
                        return False  # not certainly a deep overlap
                if not link(i, j):
                    return False
        return True

    def _validate(self, proposed: dict, seeds: set):
        sub = self._subset(proposed, seeds)
        if not sub:
            return None, sub
        cfg = self.config
        if self._certified(proposed, seeds, sub):
            self.stats["forest_certified"] += 1
            return None, sub
        self.stats["forest_checks"] += 1
        try:
            check_forest(self.cspace_workspace, [proposed[i].inflated for i in sub], min_gap=cfg.min_gap,
                         min_overlap=cfg.min_overlap)
        except ForestError as err:
            return err, sub
        return None, sub

    def _set(self, proposed: dict, i: int, sq: Squircle, changed: set, cluster: int | None = None) -> None:
        e = proposed[i]
        proposed[i] = Estimate(i, sq, inflate(sq, self.radius), e.cluster if cluster is None else cluster, e.rms, e.closed)
        changed.add(i)

    def _merge(self, proposed: dict, a: int, b: int, changed: set, removed: set) -> bool:
        """Replace estimates ``a`` and ``b`` by one squircle covering both (False when that
        squircle would be much larger than the two together: no merge)."""
        ea, eb = proposed[a], proposed[b]
        pts = np.concatenate((ea.squircle.boundary_points(96), eb.squircle.boundary_points(96)))
        f = fit_squircle(pts, config=self.config)
        if f.squircle.width * f.squircle.height > 6.0 * (ea.squircle.width * ea.squircle.height
                                                          + eb.squircle.width * eb.squircle.height):
            return False
        cl = self._clusters.get(ea.cluster)
        if cl is not None:
            if b in cl.ids:
                cl.ids.remove(b)
            if a not in cl.ids:
                cl.ids.append(a)
        proposed.pop(b)
        changed.discard(b)
        removed.add(b)
        self._set(proposed, a, f.squircle, changed, ea.cluster)
        return True

    def _repair(self, err: ForestError, sub: list[int], proposed: dict, changed: set, removed: set, notes) -> bool:
        ids = [sub[k] for k in err.obstacles if 0 <= k < len(sub)]
        ws = -1 in err.obstacles
        rule = err.rule
        if not ids:
            return False
        if rule == "covers-workspace":
            for i in ids:
                proposed.pop(i, None)
                changed.discard(i)
                removed.add(i)
            return True
        if rule in ("too-close", "shallow-overlap") or (rule == "cycle" and ws and len(ids) == 1):
            # (one estimate crossing the workspace boundary twice: grown, its two crossings join)
            key = (rule,) + tuple(sorted(ids)) + ((-1,) if ws else ())
            n = self._attempts.get(key, 0)
            self._attempts[key] = n + 1
            if n >= 6:
                return False
            i = min(ids, key=lambda k: proposed[k].squircle.area)
            others = [k for k in ids if k != i]
            if others:
                # a pair: only the face of the smaller estimate towards the other moves out (the
                # rest of it stays where the data put it)
                toward = np.asarray(proposed[others[0]].squircle.center, dtype=float)
                self._set(proposed, i, _extend(proposed[i].squircle, toward, _GROW_STEP), changed)
                notes.append(f"grew estimate {i} by {_GROW_STEP} m towards estimate {others[0]} ({rule})")
            else:
                self._set(proposed, i, _scale(proposed[i].squircle, _GROW_STEP), changed)
                notes.append(f"grew estimate {i} by {_GROW_STEP} m ({rule})")
            return True
        if rule == "cycle" and len(ids) >= 2:
            labs = sorted({self._resolve(proposed[i].cluster) for i in ids} & set(self._clusters))
            if len(labs) >= 2:
                # estimates of different clusters closing a cycle: parts of one obstacle group
                # seen separately (not yet linked by returns). Re-decompose them together: one
                # cluster, refitted as a tree of pieces (no box over the free space between)
                self._merge_labels(labs[0], labs[1:])
                self._refit(labs[0], proposed, changed, removed, None)
                notes.append(f"refitted clusters {labs} together (cycle of estimates {sorted(ids)})")
                return True
            # merge the overlapping pair a single squircle explains best (pairs of one
            # cluster first: they are pieces of one obstacle)
            cands = []
            for x in range(len(ids)):
                for y in range(x + 1, len(ids)):
                    ea, eb = proposed[ids[x]], proposed[ids[y]]
                    if not self._near(ea, eb, 0.0):
                        continue
                    other = self._resolve(ea.cluster) != self._resolve(eb.cluster)
                    pts = np.concatenate((_samples(ea.squircle), _samples(eb.squircle)))
                    cands.append((other, rect_error(pts), ids[x], ids[y]))
            for _, _, a, b in sorted(cands):
                # an estimate merged ``_MERGES_PER_UPDATE`` times in one update is growing by
                # merges (office, jittered start: trimmed clear of the robot disc, the returns
                # the trim left out fitted again, merged again, seven times, into a 5.6 m
                # squircle over space seen free that walled d3 off): no more; unrepaired, the
                # update is reverted
                if max(self._attempts.get(("merge", a), 0), self._attempts.get(("merge", b), 0)) >= _MERGES_PER_UPDATE:
                    continue
                if self._merge(proposed, a, b, changed, removed):
                    self._attempts[("merge", a)] = self._attempts.get(("merge", a), 0) + 1
                    notes.append(f"merged estimates {a} and {b} (cycle)")
                    # the cover of the pair may hold free space its pieces kept free: the
                    # cluster is refitted once due (pending), not left as merged
                    cl = self._clusters.get(self._resolve(proposed[a].cluster))
                    if cl is not None:
                        cl.pending = True
                    return True
            return False
        return False

    def _commit(self, stamp, proposed: dict, changed: set, removed: set, notes: list, pose):
        self._attempts.clear()
        for _ in range(_REPAIR_STEPS):
            seeds = {i for i in changed if i in proposed}
            err, sub = self._validate(proposed, seeds)
            if err is None:
                break
            self.stats["repairs"] += 1
            if not self._repair(err, sub, proposed, changed, removed, notes):
                break
            # a repair's cover (a merged pair, a grown face) obeys the clearances too
            self._clear_regions([i for i in changed if i in proposed], proposed, changed, removed, notes)
            if pose is not None:
                self._clear_robot(pose, proposed, changed, removed, notes)
        else:
            err = ForestError("repairs did not converge")
        if err is not None:
            # revert the estimates this update touched (the previous map was accepted)
            self.stats["reverts"] += 1
            msg = f"reverted estimates {sorted(changed | removed)}: {err}"
            log.warning("perception: %s", msg)
            notes.append(msg)
            for i in changed | removed:
                lab = self._resolve(proposed[i].cluster if i in proposed else self._est[i].cluster) \
                    if (i in proposed or i in self._est) else None
                cl = self._clusters.get(lab) if lab is not None else None
                if cl is not None:
                    cl.failed_at = len(self._label_cells(lab)[0])
                if i in self._est:
                    proposed[i] = self._est[i]
                else:
                    proposed.pop(i, None)
            changed, removed = set(), set()
            if pose is not None:  # the restored estimates may reach the robot's new position
                self._clear_robot(pose, proposed, changed, removed, notes, recover=False)
                if changed and self._validate(proposed, set(changed))[0] is not None:
                    for i in changed | removed:
                        if i in self._est:
                            proposed[i] = self._est[i]
                    changed, removed = set(), set()
        added = tuple(sorted(i for i in changed if i in proposed and i not in self._est))
        updated = tuple(sorted(i for i in changed if i in proposed and i in self._est
                               and not _same(self._est[i].squircle, proposed[i].squircle)))
        gone = tuple(sorted(i for i in removed if i in self._est and i not in proposed))
        self._est = {i: proposed[i] for i in sorted(proposed)}
        # keep cluster id lists consistent with the estimates
        for lab, cl in self._clusters.items():
            cl.ids = [i for i in dict.fromkeys(cl.ids) if i in self._est and self._resolve(self._est[i].cluster) == lab]
        for i, e in list(self._est.items()):
            lab = self._resolve(e.cluster)
            if lab != e.cluster:
                e = self._est[i] = Estimate(i, e.squircle, e.inflated, lab, e.rms, e.closed)
            cl = self._clusters.get(e.cluster)
            if cl is not None and i not in cl.ids:
                cl.ids.append(i)
        return added, updated, gone


def _face_directions(tree: cKDTree, q: np.ndarray, qn: np.ndarray, nrm: np.ndarray, reach: float) -> np.ndarray:
    """Unit directions along which the cluster's surface through each point ``qn`` (next to
    the workspace boundary, outward normals ``nrm``) leaves the workspace: the principal axis
    of the cluster's points ``q`` (``tree``: their k-d tree) within ``reach`` of it, oriented
    outwards; the normal itself where those points do not form a line (fewer than 3, or a
    variance along the axis below 4 times the variance across it) or the line is more than 60
    degrees from the normal (a face along the boundary)."""
    out = nrm.copy()
    pairs = tree.sparse_distance_matrix(cKDTree(qn), reach, output_type="coo_matrix")
    i, k = pairs.row, pairs.col
    m = len(qn)
    n = np.bincount(k, minlength=m).astype(float)
    ok = n >= 3
    if not ok.any():
        return out
    nn = np.maximum(n, 1.0)
    mx = np.bincount(k, weights=q[i, 0], minlength=m) / nn
    my = np.bincount(k, weights=q[i, 1], minlength=m) / nn
    dx, dy = q[i, 0] - mx[k], q[i, 1] - my[k]
    a = np.bincount(k, weights=dx * dx, minlength=m)
    b = np.bincount(k, weights=dx * dy, minlength=m)
    c = np.bincount(k, weights=dy * dy, minlength=m)
    half = np.hypot(0.5 * (a - c), b)
    lam_hi, lam_lo = 0.5 * (a + c) + half, 0.5 * (a + c) - half
    phi = 0.5 * np.arctan2(2.0 * b, a - c)  # the major axis
    ax = np.stack((np.cos(phi), np.sin(phi)), axis=1)
    cos = np.einsum("ij,ij->i", ax, nrm)
    use = ok & (lam_hi > 4.0 * lam_lo) & (np.abs(cos) >= 0.5)
    out[use] = ax[use] * np.sign(cos[use])[:, None]
    return out
