"""The refit's compiled geometry (perception._shape_kernel) and the plain-Python pieces of
perception.fit that replaced numpy / networkx / scipy calls give bit-identical results."""

import math
import random

import networkx as nx
import numpy as np
from scipy.spatial import cKDTree

from navigation._geom_kernel import _arr
from navigation.geometry import Squircle
from perception import _shape_kernel as K
from perception import fit as F


def _random_squircles(n, seed=0):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        s = float(rng.choice([0.0, 0.1, 0.5, 0.9, 0.99, rng.uniform(0.0, 0.999)]))
        yield rng, Squircle(tuple(rng.normal(size=2) * 5), rng.uniform(0.02, 4), rng.uniform(0.02, 4),
                            rng.uniform(-7, 7), s)


def test_boundary_points_gauge_spacing_clear_identical():
    for rng, sq in _random_squircles(1500):
        n = int(rng.choice([3, 16, 64, 96, 256, 384]))
        ref = sq.boundary_points(n)
        got = K.boundary_points(sq.center, sq.width, sq.height, sq.theta, sq.s, n)
        assert np.array_equal(ref, got)
        pts = ref + rng.normal(size=ref.shape) * rng.uniform(0, 1)
        o = Squircle(tuple(np.asarray(sq.center) + rng.normal(size=2)), rng.uniform(0.02, 4), rng.uniform(0.02, 4),
                     rng.uniform(-7, 7), float(rng.uniform(0, 0.99)))
        assert bool(np.any(F.gauge(o, pts) <= 1.0)) == K.gauge_any_inside(o.center, o.width, o.height, o.theta,
                                                                           o.s, _arr(pts))
        sp = float(np.max(np.linalg.norm(ref - np.roll(ref, 1, axis=0), axis=1)))
        assert K.spacing(got) == sp
        dmin = float(cKDTree(ref).query(pts)[0].min())
        for r in (dmin - sp / 2, np.nextafter(dmin - sp / 2, 1.0), np.nextafter(dmin - sp / 2, -1.0),
                  dmin - sp / 2 - 0.01, dmin - sp / 2 + 0.01):
            assert (dmin - sp / 2 >= r) == K.clear_of(got, _arr(pts), sp / 2, float(r))


def _inflate_reference(sq, r, samples=96):
    """perception.fit.inflate before the kernels (Squircle.boundary_points and a k-d tree)."""
    if r == 0:
        return sq
    ref = sq.boundary_points(4 * samples)
    spacing = float(np.max(np.linalg.norm(ref - np.roll(ref, 1, axis=0), axis=1)))
    tree = cKDTree(ref)

    def cand(n):
        ext = 2 * 1.03 ** n * r + 2e-9
        return Squircle(sq.center, sq.width + ext, sq.height + ext, sq.theta, sq.s)

    def clear(c):
        d, _ = tree.query(c.boundary_points(samples))
        return float(d.min()) - spacing / 2 >= r

    for n in range(F._INFLATE_LINEAR):
        c = cand(n)
        if clear(c):
            return c
    lo, hi = F._INFLATE_LINEAR - 1, 79
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if clear(cand(mid)):
            hi = mid
        else:
            lo = mid
    return cand(hi)


def _overlap_reference(a, b, grow):
    if math.dist(a.center, b.center) > a.bounding_radius + b.bounding_radius + 2 * grow:
        return False
    A = Squircle(a.center, a.width + 2 * grow, a.height + 2 * grow, a.theta, a.s)
    B = Squircle(b.center, b.width + 2 * grow, b.height + 2 * grow, b.theta, b.s)
    return bool(np.any(F.gauge(B, A.boundary_points(64)) <= 1.0) or np.any(F.gauge(A, B.boundary_points(64)) <= 1.0))


def test_inflate_and_overlap_identical():
    prev = None
    for rng, sq in _random_squircles(300, seed=1):
        r = float(rng.choice([0.0, 0.05, 0.2, rng.uniform(0, 1)]))
        a, b = F.inflate(sq, r), _inflate_reference(sq, r)
        assert (a.center, a.width, a.height, a.theta, a.s) == (b.center, b.width, b.height, b.theta, b.s)
        if prev is not None:
            for g in (0.0, 0.2, 0.5):
                assert F._overlap(prev, sq, g) == _overlap_reference(prev, sq, g)
                near = Squircle(tuple(np.asarray(prev.center) + rng.normal(size=2) * 0.5), sq.width, sq.height,
                                sq.theta, sq.s)
                assert F._overlap(prev, near, g) == _overlap_reference(prev, near, g)
        prev = sq


def test_cycle_basis_is_networkx():
    rnd = random.Random(0)
    for _ in range(3000):
        n, p = rnd.randint(1, 12), rnd.random()
        G = nx.Graph()
        G.add_nodes_from(range(n))
        adj = {k: [] for k in range(n)}
        for a in range(n):
            for b in range(a + 1, n):
                if rnd.random() < p:
                    G.add_edge(a, b)
                    adj[a].append(b)
                    adj[b].append(a)
        assert F._cycle_basis(adj) == nx.cycle_basis(G)


def test_cell_key_equality_is_that_of_unique_cells():
    from perception.config import PerceptionConfig

    cfg = PerceptionConfig.from_lidar()
    rng = np.random.default_rng(3)
    base = rng.uniform(-3, 3, size=(40, 2))
    for _ in range(300):
        a = base[rng.permutation(40)] + rng.normal(size=(40, 2)) * rng.choice([0.0, 0.2 * cfg.voxel, 2 * cfg.voxel])
        b = base.copy()
        same = np.array_equal(np.unique(np.floor(a / cfg.voxel).astype(np.int64), axis=0),
                              np.unique(np.floor(b / cfg.voxel).astype(np.int64), axis=0))
        assert (F._cell_key(a, cfg) == F._cell_key(b, cfg)) == same


def _local_ref(p, q):
    c, sn = math.cos(p[4]), math.sin(p[4])
    dx, dy = q[:, 0] - p[0], q[:, 1] - p[1]
    return dx * c + dy * sn, dy * c - dx * sn


def _gauge_ref(sq, q):
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    u, v = _local_ref(F._params(sq), q)
    return F._gauge_xy(u / (sq.width / 2), v / (sq.height / 2), sq.s)


def _radial_ref(sq, q):
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    g = np.maximum(_gauge_ref(sq, q), 1e-9)
    return np.linalg.norm(q - np.asarray(sq.center), axis=1) * (1.0 - 1.0 / g)


def _rect_ref(r, points, free, margin):
    c, s = math.cos(r.t), math.sin(r.t)

    def local_abs(q):
        dx, dy = q[:, 0] - r.cx, q[:, 1] - r.cy
        return np.abs(dx * c + dy * s), np.abs(dy * c - dx * s)

    u, v = local_abs(points)
    d = np.maximum(np.minimum(r.w / 2 - u, r.h / 2 - v), 0.0)
    e = float(np.sqrt(np.mean(d * d)))
    if free is None or not len(free):
        return e, 0
    u, v = local_abs(free)
    return e, int(np.count_nonzero((u < r.w / 2 - margin) & (v < r.h / 2 - margin)))


def test_gauge_radial_error_rect_identical():
    for rng, sq in _random_squircles(1500, seed=2):
        n = int(rng.integers(1, 400))
        q = np.asarray(sq.center) + rng.normal(size=(n, 2)) * rng.uniform(0.01, 3)
        assert np.array_equal(F.gauge(sq, q), _gauge_ref(sq, q))
        assert np.array_equal(F.radial_error(sq, q), _radial_ref(sq, q))
        assert np.array_equal(F.radial_error(sq, q[0]), _radial_ref(sq, q[0]))
        if n >= 3:
            free = None if n % 3 == 0 else q[::2] + rng.normal(size=q[::2].shape) * 0.05
            margin = float(rng.uniform(0, 0.1))
            e, nf, r = F._rect_test(q, free, margin)
            assert (e, nf) == _rect_ref(r, q, free, margin)
            assert F.rect_error(q) == _rect_ref(r, q, None, 0.0)[0]
            assert r.free_inside(free, margin) == _rect_ref(r, q, free, margin)[1]


def _contain_ref(p, q, tol):
    p = p.copy()
    for _ in range(4):
        u, v = _local_ref(p, q)
        a, b = math.exp(p[2]), math.exp(p[3])
        g = F._gauge_xy(u / a, v / b, p[5])
        need = g / (1.0 + tol / np.maximum(np.hypot(u, v), 1e-9))
        out = need > 1.0
        if not np.any(out):
            return p
        on_x = np.abs(u / a) >= np.abs(v / b)
        for k, sel in ((2, out & on_x), (3, out & ~on_x)):
            if np.any(sel):
                p[k] += math.log(float(need[sel].max())) + 1e-9
    u, v = _local_ref(p, q)
    g = F._gauge_xy(u / math.exp(p[2]), v / math.exp(p[3]), p[5])
    need = g / (1.0 + tol / np.maximum(np.hypot(u, v), 1e-9))
    f = float(need.max()) if len(need) else 1.0
    if f > 1.0:
        p[2] += math.log(f) + 1e-9
        p[3] += math.log(f) + 1e-9
    return p


def test_contain_identical():
    for rng, sq in _random_squircles(2000, seed=4):
        p = F._params(sq)
        n = int(rng.integers(1, 300))
        q = np.asarray(sq.center) + rng.normal(size=(n, 2)) * rng.uniform(0.01, 3)
        tol = float(rng.choice([0.0, 0.01, rng.uniform(0, 0.1)]))
        assert np.array_equal(K.contain(p, q, tol), _contain_ref(p, q, tol))
        per_point = tol / rng.uniform(0.05, 1.0, n)  # per-point tolerances (containment by distance)
        assert np.array_equal(K.contain(p, q, per_point), _contain_ref(p, q, per_point))


def test_component_labels_are_scipys():
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(5)
    for _ in range(2000):
        n = int(rng.integers(1, 80))
        m = int(rng.integers(0, 2 * n))
        pairs = np.sort(rng.integers(0, n, size=(m, 2)), axis=1)
        pairs = pairs[pairs[:, 0] < pairs[:, 1]]
        g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
        k, lab = connected_components(g, directed=False)
        k2, lab2 = K.component_labels(n, pairs)
        assert k == k2 and np.array_equal(lab, lab2)


def _distance_weights_ref(p, q):
    u, v = _local_ref(p, q)
    g, dg, rho, _ = F._gauge_jac(u, v, p)
    grad = np.hypot(dg[:, 0], dg[:, 1])
    return np.clip(g / np.maximum(rho * grad, 1e-12), 0.05, 1.0)


def test_distance_weights_identical():
    for rng, sq in _random_squircles(2000, seed=6):
        p = F._params(sq)
        n = int(rng.integers(1, 200))
        q = np.asarray(sq.center) + rng.normal(size=(n, 2)) * rng.uniform(0.01, 3)
        if n > 3:
            q[0] = sq.center  # at the centre (rho = 0)
        assert np.array_equal(F._distance_weights(p, q), _distance_weights_ref(p, q))


def test_median_is_numpys():
    rng = np.random.default_rng(7)
    for _ in range(3000):
        n = int(rng.integers(1, 70))
        a = np.abs(rng.normal(size=n)) * rng.uniform(1e-4, 1)
        if n > 4 and rng.random() < 0.3:
            a[: n // 2] = a[0]  # ties
        assert F._median(a) == float(np.median(a))


def test_free_cells_are_the_numpy_forms_cells():
    """free_cells gives the set of not-yet-free cells of ObstacleMap._mark_free's numpy form."""
    from perception import _shape_kernel as K

    rng = np.random.default_rng(21)
    for _ in range(30):
        B, cell = int(rng.integers(1, 400)), float(rng.choice([0.05, 0.1, 0.07]))
        L = rng.uniform(-0.5, 6.0, B)
        ang = rng.uniform(-np.pi, np.pi, B)
        t = np.arange(cell / 2, max(float(L.max(initial=0.0)), 0.0), cell / 2)
        a0, a1 = float(rng.uniform(-1, 9)), float(rng.uniform(-1, 9))
        shape = (int(rng.integers(10, 120)), int(rng.integers(10, 120)))
        flat = rng.uniform(size=shape[0] * shape[1]) < 0.3
        m = t[None, :] < L[:, None]
        fx = (a0 + t[None, :] * np.cos(ang)[:, None])[m] / cell
        fy = (a1 + t[None, :] * np.sin(ang)[:, None])[m] / cell
        i, j = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
        ok = (i >= 0) & (j >= 0) & (i < shape[0]) & (j < shape[1])
        lin = i[ok] * shape[1] + j[ok]
        ref = np.unique(lin[~flat[lin]])
        got = np.unique(K.free_cells(a0, a1, t, L, np.cos(ang), np.sin(ang), cell, shape, flat))
        assert np.array_equal(got, ref)


def test_accumulate_is_add_at():
    """accumulate adds as np.add.at does (repeated cells, in order: the same sums to the bit)."""
    from perception import _shape_kernel as K

    rng = np.random.default_rng(22)
    for _ in range(20):
        shape = (int(rng.integers(2, 30)), int(rng.integers(2, 30)))
        k = int(rng.integers(0, 300))
        ij = np.stack((rng.integers(0, shape[0], k), rng.integers(0, shape[1], k)), axis=1).astype(np.int64)
        pts, vd = rng.normal(size=(k, 2)) * 7.3, rng.normal(size=(k, 2))
        sel = rng.uniform(size=k) < 0.8
        n0 = rng.integers(0, 50, shape).astype(np.int32)
        s0, v0 = rng.normal(size=shape + (2,)), rng.normal(size=shape + (2,))
        n1, s1, v1 = n0.copy(), s0.copy(), v0.copy()
        np.add.at(n0, (ij[sel, 0], ij[sel, 1]), 1)
        np.add.at(s0, (ij[sel, 0], ij[sel, 1]), pts[sel])
        np.add.at(v0, (ij[sel, 0], ij[sel, 1]), vd[sel])
        K.accumulate(n1, s1, v1, ij, pts, vd, sel)
        assert np.array_equal(n0, n1) and np.array_equal(s0, s1) and np.array_equal(v0, v1)


def test_near_mask_is_the_kd_trees_selection():
    """near_mask selects the free points cKDTree.query(..., distance_upper_bound=r) finds, also
    for points exactly at distance r (strictly closer only) and on a grid of free cells."""
    rng = np.random.default_rng(5)
    for it in range(600):
        q = rng.normal(size=(int(rng.integers(1, 160)), 2)) * rng.uniform(0.05, 3) + rng.normal(size=2) * 10
        if it % 3 == 0:  # grid cells (ties in x) and points on them
            f = (np.stack(np.meshgrid(np.arange(-30, 30), np.arange(-30, 30)), axis=-1).reshape(-1, 2) + 0.5) * 0.1
            f = f + np.round(q.mean(axis=0), 1)
            q[: len(q) // 2] = f[rng.integers(0, len(f), len(q) // 2)]
        else:
            f = rng.normal(size=(int(rng.integers(0, 600)), 2)) * rng.uniform(0.1, 4) + q.mean(axis=0)
        r = float(rng.choice([0.1, 0.25, rng.uniform(0.01, 1.0)]))
        if it % 5 == 0 and len(f):  # a free point exactly at distance r of a point (in x)
            f[0] = q[0] + (r, 0.0)
        want = np.isfinite(cKDTree(q).query(f, distance_upper_bound=r)[0]) if len(f) else np.zeros(0, bool)
        assert np.array_equal(K.near_mask(q, f, r), want)


def _faces_seen_ref(p, q, views):
    """``fit._faces_seen``'s numpy form."""
    seen = np.zeros((2, 2), bool)
    u, v = F._local(p, q)
    a, b = math.exp(p[2]), math.exp(p[3])
    nu, nv = u / a, v / b
    c, s = math.cos(p[4]), math.sin(p[4])
    vu, vv = views[:, 0] * c + views[:, 1] * s, views[:, 1] * c - views[:, 0] * s
    on_u = np.abs(nu) >= np.abs(nv)
    for axis, (n, vc, on) in enumerate(((nu, vu, on_u), (nv, vv, ~on_u))):
        for side, sgn in enumerate((-1.0, 1.0)):
            seen[axis, side] = int((on & (sgn * n > 0.3) & (sgn * vc < -0.05)).sum()) >= 2
    return seen


def test_faces_seen_identical():
    for rng, sq in _random_squircles(2000, seed=8):
        p = F._params(sq)
        n = int(rng.integers(1, 120))
        q = np.asarray(sq.center) + rng.normal(size=(n, 2)) * rng.uniform(0.01, 3)
        views = rng.normal(size=(n, 2))
        views /= np.linalg.norm(views, axis=1, keepdims=True)
        if n > 3:  # on the diagonals (|x| = |y|) and at the thresholds
            q[0] = sq.center
            views[1] = (0.0, 0.0)
        assert np.array_equal(F._faces_seen(p, q, views), _faces_seen_ref(p, q, views))


def test_warm_medians_identical():
    rng = np.random.default_rng(9)
    sqs = [sq for _, sq in _random_squircles(400, seed=9)]
    for _ in range(400):
        n = int(rng.integers(1, 40))
        q = rng.normal(size=(n, 2)) * rng.uniform(0.01, 5)
        some = [sqs[i] for i in rng.integers(0, len(sqs), int(rng.integers(1, 8)))]
        got = K.warm_medians(some, _arr(q))
        assert got is not None
        want = [F._median(np.abs(F.radial_error(sq, q))) for sq in some]
        assert np.array_equal(got, np.array(want))


def test_solve_stats_identical():
    """solve_stats: the RMS, penalty and 95th percentile of fit._solve's numpy form."""
    rng = np.random.default_rng(10)
    for _ in range(3000):
        nq, nf = int(rng.integers(1, 300)), int(rng.integers(0, 400))
        fun = rng.normal(size=nq + nf + 2) * rng.uniform(1e-4, 1)
        if nf and rng.random() < 0.5:
            fun[nq: nq + nf][rng.random(nf) < 0.7] = 0.0
        if nq > 4 and rng.random() < 0.3:
            fun[: nq // 2] = fun[0]  # ties
        wq = rng.uniform(0.05, 1.0, nq) if rng.random() < 0.8 else None
        rp = fun[:nq] if wq is None else fun[:nq] / wq
        rms, pen, p95 = K.solve_stats(fun, nq, wq)
        assert rms == float(np.sqrt(np.mean(rp * rp)))
        assert pen == float(np.sum(fun[nq:-2] ** 2))
        if nq < 2:
            assert p95 is None
        else:
            assert p95 == F._p95(np.abs(rp))


def test_box_mask_identical():
    rng = np.random.default_rng(11)
    for _ in range(500):
        pts = np.round(rng.normal(size=(int(rng.integers(0, 300)), 2)) * 2, int(rng.integers(0, 4)))
        lo = np.round(rng.normal(size=2), 1)
        hi = lo + np.round(rng.uniform(0, 3, 2), 1)
        assert np.array_equal(K.box_mask(pts, lo, hi), ((pts >= lo) & (pts <= hi)).all(axis=1))


def test_min_gap_is_the_kd_trees():
    """min_gap: the smallest distance cKDTree.query(..., distance_upper_bound=r) reports."""
    rng = np.random.default_rng(12)
    for it in range(1500):
        a = rng.normal(size=(int(rng.integers(1, 150)), 2)) * rng.uniform(0.01, 2)
        b = rng.normal(size=(int(rng.integers(1, 150)), 2)) * rng.uniform(0.01, 2) + rng.normal(size=2) * 0.7
        if it % 4 == 0:  # on a grid: ties
            a, b = np.round(a, 1), np.round(b, 1)
        r = float(rng.choice([0.35, 0.1, rng.uniform(0.01, 1.0)]))
        want = float(cKDTree(a).query(b, distance_upper_bound=r)[0].min())
        assert K.min_gap(K.sorted_x(a), b, r) == want
