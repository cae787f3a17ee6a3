"""Drive the simulator along a recorded path and score an :class:`ObstacleMap` against the truth.

Used by the tests (``tests/test_perception*.py``) and the benchmark
(``benchmarks/perception.py``); not needed by the service.

* :func:`tour` records a collision-free path: from the start, straight segments to random
  free points (segments whose every 2 cm sample keeps ``margin`` clearance), sampled every
  ``step`` metres.
* :func:`drive` feeds the simulator's scans at those poses to a map (bus messages, as the
  service would), timing every update, and collects the noise-free hit points.
* :func:`score` computes the figures of the issue: safety (share of true boundary points hit
  by a beam that lie inside the union of the inflated estimates; the robot's position never
  inside one), accuracy (IoU with the truth of every group of overlapping true obstacles whose
  visible boundary was seen all round, inside the workspace, against the estimates that group
  owns - each estimate belongs to the group holding most of its area -, rotation error of
  isolated rectangles).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from navigation.geometry import Squircle

from .map import ObstacleMap

__all__ = ["tour", "drive", "score", "DriveResult", "Score", "components"]


def _clear(sim, q: np.ndarray) -> np.ndarray:
    return sim.clearance_at(np.atleast_2d(q))[0]


def tour(sim, n_goals: int, rng: np.random.Generator, *, step: float = 0.05, margin: float = 0.05,
         tries: int = 24) -> np.ndarray:
    """Poses ``(K, 3)`` along a collision-free path through ``n_goals`` random free points.

    ``sim`` is a :class:`service.sim.Simulator` (its ground truth decides clearance); the path
    starts at ``sim.pose`` and keeps a disc clearance of at least ``margin``.
    """
    ws = sim.world.workspace
    bp = ws.boundary_points(256)
    lo, hi = bp.min(axis=0), bp.max(axis=0)
    cur = np.array(sim.pose[:2])
    poses = [tuple(sim.pose)]
    for _ in range(n_goals):
        # among reachable candidates, go to the one farthest from the path so far (coverage)
        seen = np.array([p[:2] for p in poses[:: max(len(poses) // 200, 1)]])
        best = None
        for _ in range(tries):
            g = rng.uniform(lo, hi)
            L = float(np.linalg.norm(g - cur))
            if L < 0.3:
                continue
            n = max(int(L / 0.02), 2)
            seg = cur + np.linspace(0.0, 1.0, n)[:, None] * (g - cur)
            if not np.all(_clear(sim, seg) >= margin):
                continue
            far = float(np.min(np.linalg.norm(seen - g, axis=1)))
            if best is None or far > best[0]:
                best = (far, g, L)
        if best is None:
            continue
        _, g, L = best
        th = math.atan2(g[1] - cur[1], g[0] - cur[0])
        k = max(int(math.ceil(L / step)), 1)
        for t in np.linspace(0.0, 1.0, k + 1)[1:]:
            q = cur + t * (g - cur)
            poses.append((float(q[0]), float(q[1]), th))
        cur = g
    return np.array(poses)


@dataclass
class DriveResult:
    """What :func:`drive` recorded."""

    times: list = field(default_factory=list)  # wall seconds per update
    cpu_times: list = field(default_factory=list)  # process CPU seconds per update (less load-sensitive)
    updates: list = field(default_factory=list)  # MapUpdate per scan
    hits: list = field(default_factory=list)  # noise-free obstacle hit points per scan
    robot_covered: int = 0  # scans after which an inflated estimate contained the robot
    scan_safety: list = field(default_factory=list)  # per scan: (inside, total) of its true hits
    stable_failures: int = 0  # re-processed scans that changed the map


def drive(sim, omap: ObstacleMap, poses: np.ndarray, *, dt: float = 0.1, check=None, repeat_every: int = 0) -> DriveResult:
    """Feed the scans at ``poses`` to ``omap``; ``check(omap, update)`` is called after each one.

    ``repeat_every > 0`` re-processes every n-th scan a second time (with a later stamp) and
    counts the repeats that changed the map (:attr:`DriveResult.stable_failures`).
    """
    res = DriveResult()
    ws = sim.world.workspace
    lid = sim.lidar
    beams = lid.angles()
    for k, pose in enumerate(poses):
        stamp = k * dt
        true = sim.true_ranges(tuple(pose))
        noisy = true.copy()
        if lid.noise_std > 0:
            hit = np.isfinite(true)
            nz = true[hit] + sim.rng.normal(0.0, lid.noise_std, int(hit.sum()))
            nz = np.maximum(nz, lid.range_min)
            noisy[hit] = np.where(nz >= lid.range, math.inf, nz)
        rmax = lid.range
        msg = {"stamp": stamp, "angle_min": lid.angle_min, "angle_increment": lid.angle_increment,
               "range_min": lid.range_min, "range_max": rmax,
               "ranges": np.where(np.isfinite(noisy) & (noisy < rmax), noisy, rmax).tolist()}
        pmsg = {"stamp": stamp, "x": float(pose[0]), "y": float(pose[1]), "theta": float(pose[2])}
        c0 = time.process_time()
        t0 = time.perf_counter()
        upd = omap.update_scan(msg, pmsg)
        res.times.append(time.perf_counter() - t0)
        res.cpu_times.append(time.process_time() - c0)
        res.updates.append(upd)
        h = np.isfinite(true)
        a = pose[2] + beams[h]
        pts = np.stack((pose[0] + true[h] * np.cos(a), pose[1] + true[h] * np.sin(a)), axis=1)
        if len(pts):
            pts = pts[ws.beta(pts) < -1e-6]  # the workspace boundary is known, not an obstacle
        res.hits.append(pts)
        infl = omap.inflated()
        if infl and any(float(s.beta(np.array(pose[:2]))) <= 0 for s in infl):
            res.robot_covered += 1
        res.scan_safety.append((int(_inside_any(infl, pts).sum()) if len(pts) else 0, len(pts)))
        if repeat_every and k % repeat_every == 0:
            before = omap.to_message()["obstacles"]
            msg2 = dict(msg, stamp=stamp + 1e-3)
            pmsg2 = dict(pmsg, stamp=stamp + 1e-3)
            omap.update_scan(msg2, pmsg2)
            if omap.to_message()["obstacles"] != before:
                res.stable_failures += 1
        if check is not None:
            check(omap, upd)
    return res


def _inside_any(squircles, q: np.ndarray) -> np.ndarray:
    out = np.zeros(len(q), bool)
    for s in squircles:
        out |= s.beta(q) <= 0 if len(q) else out
    return out


def components(obstacles) -> list[list[int]]:
    """Groups of overlapping obstacles (connected components of the overlap graph)."""
    n = len(obstacles)
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    pts = [o.boundary_points(128) for o in obstacles]
    for i in range(n):
        for j in range(i + 1, n):
            a, b = obstacles[i], obstacles[j]
            if math.dist(a.center, b.center) > a.bounding_radius + b.bounding_radius:
                continue
            if np.any(a.beta(pts[j]) <= 0) or np.any(b.beta(pts[i]) <= 0):
                parent[find(i)] = find(j)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(find(i), []).append(i)
    return list(groups.values())


@dataclass
class Score:
    """Figures of one drive (see the module docstring)."""

    safety: float  # share of hit true boundary points inside the final inflated map
    scan_safety: float  # same, each scan's hits against the map right after that scan
    robot_covered: int
    groups_seen: int
    iou: list  # IoU of each group seen all round
    rotation_errors: list  # degrees, isolated rectangles seen all round
    estimates: int
    stable_failures: int = 0
    iou_groups: list = field(default_factory=list)  # true obstacle indices of each IoU entry


def score(world, omap: ObstacleMap, res: DriveResult, *, seen_radius: float = 0.03, seen_share: float = 0.9,
          cell: float = 0.01) -> Score:
    """Score the final map of a drive against ``world``'s ground truth."""
    ws = world.workspace
    hits = np.concatenate([h for h in res.hits if len(h)] or [np.zeros((0, 2))])
    infl = omap.inflated()
    est = omap.obstacles()
    safety = float(_inside_any(infl, hits).mean()) if len(hits) else 1.0
    ins = sum(a for a, _ in res.scan_safety)
    tot = sum(b for _, b in res.scan_safety)
    scan_safety = ins / tot if tot else 1.0
    obs = list(world.obstacles)
    from scipy.spatial import cKDTree

    tree = cKDTree(hits) if len(hits) else None
    ious, rots, seen_groups, groups = [], [], 0, []
    comps = components(obs)
    # each estimate belongs to the group of true obstacles holding most of its area (samples)
    owner = []
    for e in est:
        b = e.boundary_points(64)
        c = np.asarray(e.center)
        samp = np.concatenate([c + f * (b - c) for f in (0.25, 0.5, 0.75, 1.0)])
        counts = [sum(int(np.count_nonzero(obs[i].beta(samp) <= 0)) for i in g) for g in comps]
        if max(counts) > 0:
            owner.append(int(np.argmax(counts)))
        else:
            owner.append(int(np.argmin([min(math.dist(e.center, obs[i].center) - obs[i].bounding_radius for i in g)
                                        for g in comps])))
    for gi, grp in enumerate(comps):
        # visible boundary: inside the workspace, not inside another member
        bps = []
        for i in grp:
            b = obs[i].boundary_points(256)
            ok = ws.beta(b) < 0
            ok &= np.hypot(*(b - np.asarray(ws.center)).T) >= 0  # keep shape
            for j in grp:
                if j != i:
                    ok &= obs[j].beta(b) > 0
            b = b[ok]
            if len(b):
                from .fit import radial_error

                b = b[radial_error(ws, b) < -0.03]
            bps.append(b)
        bp = np.concatenate(bps) if bps else np.zeros((0, 2))
        if tree is None or len(bp) < 10:
            continue
        d, _ = tree.query(bp, distance_upper_bound=seen_radius)
        if np.mean(np.isfinite(d)) < seen_share:
            continue
        seen_groups += 1
        lo = np.min([obs[i].boundary_points(64).min(axis=0) for i in grp], axis=0) - 0.3
        hi = np.max([obs[i].boundary_points(64).max(axis=0) for i in grp], axis=0) + 0.3
        xs = np.arange(lo[0], hi[0], cell) + cell / 2
        ys = np.arange(lo[1], hi[1], cell) + cell / 2
        X, Y = np.meshgrid(xs, ys)
        G = np.stack((X.ravel(), Y.ravel()), axis=1)
        inws = ws.beta(G) < 0
        G = G[inws]
        truth = _inside_any([obs[i] for i in grp], G)
        near = [e for e, o in zip(est, owner) if o == gi]
        mine = _inside_any(near, G)
        union = np.sum(truth | mine)
        ious.append(float(np.sum(truth & mine) / union) if union else 1.0)
        groups.append(list(grp))
        if len(grp) == 1:
            o = obs[grp[0]]
            if o.s >= 0.9 and max(o.width, o.height) >= 1.5 * min(o.width, o.height):
                best, bi = 0.0, None
                for e in near:
                    m = e.beta(G) <= 0
                    u = np.sum(truth | m)
                    v = np.sum(truth & m) / u if u else 0.0
                    if v > best:
                        best, bi = v, e
                if bi is not None:
                    rots.append(_axis_error(o, bi))
    return Score(safety, scan_safety, res.robot_covered, seen_groups, ious, rots, len(est), res.stable_failures,
                 groups)


def _axis_error(a: Squircle, b: Squircle) -> float:
    """Angle (degrees, 0..90) between the long axes of ``a`` and ``b``."""
    ta = a.theta + (0.0 if a.width >= a.height else math.pi / 2)
    tb = b.theta + (0.0 if b.width >= b.height else math.pi / 2)
    d = abs(math.remainder(ta - tb, math.pi))
    return math.degrees(d)
