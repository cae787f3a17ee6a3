"""The compiled geometry kernels (navigation._geom_kernel): exact distances and ray lengths against
independent references (refined brute force, bisection), gap bounds against the numpy function."""

import numpy as np
import pytest

from navigation import forest as F
from navigation import geometry as G
from navigation.geometry import Squircle, pack


def _random_rows(rng, n):
    return pack([Squircle(tuple(rng.uniform(-3, 3, 2)), float(rng.uniform(0.1, 3)), float(rng.uniform(0.1, 3)),
                          float(rng.uniform(-np.pi, np.pi)), float(rng.choice([0.0, rng.uniform(0, 0.999), 0.99])))
                 for _ in range(n)])


def _brute_distance(row, q):
    """Distance from ``q`` to the boundary of ``row``: the best of 4096 evenly spaced angles,
    refined by bounded scalar minimisation around the 3 best discrete local minima."""
    from scipy.optimize import minimize_scalar

    psi = np.linspace(0, 2 * np.pi, 4096, endpoint=False)
    d = np.hypot(*(G.point_at_rows(row[None], psi[None])[0] - q).T)
    local = np.nonzero((d <= np.roll(d, 1)) & (d <= np.roll(d, -1)))[0]
    best = d.min()
    h = 2 * np.pi / 4096
    for j in local[np.argsort(d[local])[:3]]:
        f = lambda a: float(np.hypot(*(G.point_at_rows(row[None], np.array([[a]]))[0, 0] - q)))
        r = minimize_scalar(f, bounds=(psi[j] - h, psi[j] + h), method="bounded", options={"xatol": 1e-13})
        best = min(best, r.fun)
    return best


@pytest.mark.parametrize("seed", range(3))
def test_signed_distance_agrees_with_a_refined_brute_force(seed):
    """Signed distances (geometry.signed_distance_rows, compiled) agree with a dense, refined brute
    force to 1e-9 m at points inside, near and far from random squircles; the sign is that of
    beta."""
    rng = np.random.default_rng(seed)
    P = _random_rows(rng, 60)
    q = P[:, :2] + rng.normal(scale=rng.choice([0.05, 1.0, 4.0], size=(60, 1)), size=(60, 2))
    got = G.signed_distance_rows(P, q)
    assert np.all(np.isfinite(got))
    ref = np.array([_brute_distance(P[k], q[k]) for k in range(60)])
    assert np.max(np.abs(np.abs(got) - ref)) <= 1e-9
    assert np.array_equal(got < 0, G.beta_rows(P, q[:, 0], q[:, 1]) < 0)


@pytest.mark.parametrize("seed", range(5))
def test_ray_length_ends_on_the_boundary_at_the_first_crossing(seed):
    """Exit lengths from interior points and entry lengths from outside
    (geometry.ray_length_packed, compiled) end on the boundary (|beta| <= 1e-9) and agree with
    bisection on the sign of beta to 1e-12 relative; no sampled point before an entry is inside."""
    rng = np.random.default_rng(seed)
    P = _random_rows(rng, 500)
    a = rng.uniform(0, 2 * np.pi, 500)
    d = np.stack((np.cos(a), np.sin(a)), 1)
    psi = rng.uniform(0, 2 * np.pi, 500)
    o_in = P[:, :2] + rng.uniform(0, 0.9, (500, 1)) * (G.point_at_rows(P, psi[:, None])[:, 0] - P[:, :2])
    got = G.ray_length_packed(P, o_in, d)
    tip = o_in + got[:, None] * d
    assert np.max(np.abs(G.beta_rows(P, tip[:, 0], tip[:, 1]))) <= 1e-9
    lo, hi = np.zeros(500), np.full(500, 2 * np.hypot(P[:, 4], P[:, 5]) + 1)
    for _ in range(200):  # bisection on the sign of beta (inside at lo, outside at hi)
        mid = 0.5 * (lo + hi)
        x = o_in + mid[:, None] * d
        inside = G.beta_rows(P, x[:, 0], x[:, 1]) < 0
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    assert np.max(np.abs(got - lo) / (1 + lo)) <= 1e-12
    o_out = P[:, :2] - 10.0 * d
    got = G.ray_length_packed(P, o_out, d, np.ones(500, bool))
    tip = o_out + got[:, None] * d
    assert np.max(np.abs(G.beta_rows(P, tip[:, 0], tip[:, 1]))) <= 1e-9
    before = o_out[:, None] + (got[:, None] * np.linspace(0, 1 - 1e-9, 50))[..., None] * d[:, None]
    assert np.all(G.beta_rows(P[:, None], before[..., 0], before[..., 1]) >= -1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_gap_bound_never_exceeds_the_distance(seed):
    """forest._gap_bound_rows (compiled) is a lower bound of the exact distance between random
    squircles, and is 0 for overlapping ones."""
    rng = np.random.default_rng(seed)
    A, B = _random_rows(rng, 300), _random_rows(rng, 300)
    got = F._gap_bound_rows(A, B)
    assert np.all(np.isfinite(got)) and np.all(got >= 0)
    for k in range(0, 300, 5):
        a = Squircle((A[k, 0], A[k, 1]), 2 * A[k, 4], 2 * A[k, 5], float(np.arctan2(A[k, 3], A[k, 2])), A[k, 6])
        b = Squircle((B[k, 0], B[k, 1]), 2 * B[k, 4], 2 * B[k, 5], float(np.arctan2(B[k, 3], B[k, 2])), B[k, 6])
        sep = F.separation(a, b)
        assert got[k] <= sep + 1e-9
        if sep == 0.0:
            assert got[k] == 0.0


def test_gap_bound_exact_cases():
    """Axis-aligned rectangles side by side: the rectangle bound is their gap; diagonal: the
    corner-to-corner distance; far apart round ones: the disc bound."""
    a = pack([Squircle((0.0, 0.0), 2.0, 2.0, 0.0, 0.99)])
    side = pack([Squircle((3.5, 0.5), 2.0, 2.0, 0.0, 0.99)])
    diag = pack([Squircle((3.0, 4.0), 2.0, 2.0, 0.0, 0.99)])
    rot = pack([Squircle((10.0, 0.0), 2.0, 2.0, 0.3, 0.0)])
    assert F._gap_bound_rows(a, side)[0] == pytest.approx(1.5, abs=1e-12)
    assert F._gap_bound_rows(a, diag)[0] == pytest.approx(np.hypot(1.0, 2.0), abs=1e-12)
    assert F._gap_bound_rows(a, rot)[0] >= 10.0 - 2 * np.sqrt(2) - 1e-12


def test_empty_inputs():
    assert G.signed_distance_rows(np.zeros((0, 7)), np.zeros((0, 2))).shape == (0,)
    assert G.ray_length_packed(np.zeros((0, 7)), np.zeros((0, 2)), np.zeros((0, 2))).shape == (0,)
    assert F._gap_bound_rows(np.zeros((0, 7)), np.zeros((0, 7))).shape == (0,)


def test_far_gaps_equal_the_brute_force_over_all_rays():
    """far_gap_rows (which skips the rays outside the samples' bracket of the child's arc inside
    the workspace and those missing its bounding rectangle, and traces every 4th ray first and
    the others only next to coarse local minima) equals the
    minimum over every ray whose child exit lies inside the workspace of the exit-distance
    difference, on the workspace children of random worlds."""
    from navigation._geom_kernel import far_gap_rows

    from .worldgen import random_forest_world

    checked = 0
    for seed in range(8):
        w = random_forest_world(seed, n_obstacles=12, max_depth=3)
        forest = w.forest(0.0)
        kids = [i for i, p in enumerate(forest.parent) if p == -1]
        if not kids:
            continue
        P, ws = pack([forest.obstacles[i] for i in kids]), pack([w.workspace])[0]
        centres = forest.center[kids]
        from navigation.forest import _SAMPLES, _bodies

        pts = np.stack([b.pts for b in _bodies([forest.obstacles[i] for i in kids], _SAMPLES)])
        got = far_gap_rows(P, centres, ws, 720, pts)
        a = np.linspace(0.0, 2.0 * np.pi, 720, endpoint=False)
        u = np.stack((np.cos(a), np.sin(a)), 1)
        for k in range(len(kids)):
            o = np.repeat(centres[k][None], 720, 0)
            r_leaf = G.ray_length_packed(np.repeat(P[k][None], 720, 0), o, u)
            tip = o + r_leaf[:, None] * u
            inside = G.beta_rows(ws, tip[:, 0], tip[:, 1]) < 0
            ref = np.min(G.ray_length_packed(np.repeat(ws[None], inside.sum(), 0), o[inside], u[inside])
                         - r_leaf[inside]) if inside.any() else np.inf
            assert got[k] == ref
            checked += 1
    assert checked >= 10


def test_sample_table_is_boundary_psi_and_its_points():
    """The compiled distance table (geometry._sample_table) has exactly Squircle.boundary_psi's
    angles and Squircle.point_at's points, and its largest arc is the numpy one: the largest sum
    of 16 chord lengths per gap between consecutive samples, times 1 + 1e-6 (bit for bit)."""
    from navigation._geom_kernel import sample_table

    rng = np.random.default_rng(5)
    for _ in range(40):
        sq = Squircle(tuple(rng.uniform(-5, 5, 2)), float(rng.uniform(0.05, 8)), float(rng.uniform(0.05, 8)),
                      float(rng.uniform(-3.2, 3.2)), float(rng.choice([0.0, rng.uniform(0, 0.999), 0.99])))
        n = int(rng.choice([16, 64, 200]))
        psi, pts, arc = sample_table(sq.packed(), n)
        assert np.array_equal(psi, sq.boundary_psi(n)) and np.array_equal(pts, sq.point_at(psi))
        b = np.append(psi[1:], psi[0] + 2 * np.pi)
        fine = sq.point_at(psi[:, None] + (b - psi)[:, None] * np.linspace(0, 1, 17)[None, :])
        assert arc == np.linalg.norm(np.diff(fine, axis=1), axis=-1).sum(axis=1).max() * (1.0 + 1e-6)


def test_boundary_points_and_offset_points_are_the_numpy_forms():
    """Squircle.boundary_points, offset_points and gradient (compiled) give the bits of their numpy
    forms: arc length on 8 n chords inverted by numpy.interp, point_at (which squares s with
    Python's pow, one unit in the last place from s * s for about 0.1 % of the values), and the
    offset along beta_jet's gradient; also for such values of s."""
    from navigation._jet import Jet

    rng = np.random.default_rng(11)
    pow_s = [float(x) for x in rng.uniform(0, 1, 20000) if float(x) ** 2 != float(x) * float(x)]
    assert pow_s
    for k in range(60):
        s = pow_s[k % len(pow_s)] if k % 3 == 0 else float(rng.choice([0.0, rng.uniform(0, 0.999), 0.99]))
        sq = Squircle(tuple(rng.uniform(-5, 5, 2)), float(rng.uniform(0.05, 8)), float(rng.uniform(0.05, 8)),
                      float(rng.uniform(-3.2, 3.2)), s)
        n = int(rng.choice([3, 16, 64, 200, 720]))
        fine = np.linspace(0.0, 2 * np.pi, 8 * n + 1)
        arc = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(sq.point_at(fine), axis=0), axis=1))))
        ref = sq.point_at(np.interp(np.linspace(0.0, arc[-1], n, endpoint=False), arc, fine))
        assert np.array_equal(sq.boundary_points(n), ref)
        r = float(rng.uniform(-0.02, 0.5))
        g = G.beta_jet(sq.packed(), *Jet.variables(ref, 1)).gradient()
        assert np.array_equal(sq.offset_points(r, n), ref + r * g / np.linalg.norm(g, axis=1, keepdims=True))
        # Squircle.gradient (compiled) is beta_jet's, also off the boundary and at the centre
        q = np.concatenate((rng.uniform(-9, 9, (20, 2)), ref[:5], np.array([sq.center])))
        with np.errstate(all="ignore"):
            assert np.array_equal(sq.gradient(q), G.beta_jet(sq.packed(), *Jet.variables(q, 1)).gradient())


def test_lazy_distance_tables_give_the_same_numbers():
    """ExactDistance(lazy=True) samples a squircle when a query first needs it, with the sample
    counts of the eager table: the same signed and sampled distances, bit for bit."""
    rng = np.random.default_rng(12)
    sqs = [Squircle(tuple(rng.uniform(-3, 3, 2)), float(rng.uniform(0.1, 3)), float(rng.uniform(0.1, 3)),
                    float(rng.uniform(-np.pi, np.pi)), float(rng.choice([0.0, rng.uniform(0, 0.999), 0.99])))
           for _ in range(6)] + [Squircle((0.0, 0.0), 12.0, 10.0, 0.2, 0.99)]
    eager = G.ExactDistance(sqs, spacing=0.01, split=6, min_samples=64)
    lazy = G.ExactDistance(sqs, spacing=0.01, split=6, min_samples=64, lazy=True)
    for _ in range(5):
        q = rng.uniform(-5, 5, (9, 2))
        j = rng.integers(0, 7, 9)
        assert np.array_equal(lazy.signed(q, j), eager.signed(q, j))
        assert all(np.array_equal(a, b) for a, b in zip(lazy.sampled(q, j), eager.sampled(q, j)))
    assert all(np.array_equal(lazy.boundary_samples(i), eager.boundary_samples(i)) for i in range(7))


def test_sampled_distances_are_the_numpy_form():
    """ExactDistance.sampled's distances (compiled: nearest_sample_distance) are the bits of
    ``sqrt(((pts[g] - q[:, None]) ** 2).sum(-1).min(1))``, a NaN sample giving NaN as numpy's
    min does; and the table's sampled distances are those of its boundary samples."""
    from navigation._geom_kernel import nearest_sample_distance

    rng = np.random.default_rng(13)
    for n in (1, 7, 64, 4441):
        pts = rng.normal(size=(3, n, 2)) * rng.uniform(0.01, 10)
        g = rng.integers(0, 3, 25)
        q = rng.normal(size=(25, 2)) * 3
        ref = np.sqrt(((pts[g] - q[:, None, :]) ** 2).sum(-1).min(axis=1))
        assert np.array_equal(nearest_sample_distance(pts, g, q), ref)
    pts[1, 3] = np.nan
    assert np.isnan(nearest_sample_distance(pts, np.array([1, 0]), np.zeros((2, 2)))).tolist() == [True, False]
    assert nearest_sample_distance(pts, np.zeros(0, np.intp), np.zeros((0, 2))).shape == (0,)
    sqs = [Squircle((0.0, 0.0), 1.0, 0.5, 0.3, 0.9), Squircle((0.0, 0.0), 8.0, 6.0, 0.0, 0.99)]
    table = G.ExactDistance(sqs, spacing=0.01, split=1, min_samples=64, lazy=True)
    q = rng.uniform(-3, 3, (10, 2))
    j = rng.integers(0, 2, 10)
    d, _ = table.sampled(q, j)
    assert np.array_equal(d, [np.sqrt(((table.boundary_samples(i) - p) ** 2).sum(-1).min()) for p, i in zip(q, j)])


def test_max_perimeter_skips_only_shapes_that_cannot_be_the_largest():
    rng = np.random.default_rng(13)
    for _ in range(200):
        sqs = [Squircle(tuple(rng.uniform(-3, 3, 2)), float(rng.uniform(0.01, 6)), float(rng.uniform(0.01, 6)),
                        float(rng.uniform(-np.pi, np.pi)), float(rng.choice([0.0, rng.uniform(0, 0.999), 0.99])))
               for _ in range(int(rng.integers(1, 12)))]
        assert G._max_perimeter(sqs) == max(G._perimeter(sq) for sq in sqs)
