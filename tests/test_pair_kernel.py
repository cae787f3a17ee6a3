"""The compiled pair-distance kernels (navigation._pair_kernel, which navigation.forest's
_pair_distance calls) on inputs captured from real forest builds: closest points on the
boundaries, distances against dense sampling, independence of the batch."""

from __future__ import annotations

import functools

import numpy as np
from scipy.spatial import cKDTree

import navigation
import navigation.forest as F
from navigation import _pair_kernel as PK
from navigation.geometry import beta_rows

from .conftest import world_file
from .worldgen import random_forest_world

TOL = 1e-12  # absolute agreement of distances (grouped vs ungrouped; points vs distance)
SEEDS = [(seed, n) for n in (5, 10, 20) for seed in range(4)]


def _worlds():
    """(name, world) of the captured worlds: random forests of several seeds and sizes, office,
    cluttered20."""
    out = [(f"random{n}-{seed}", random_forest_world(seed, n_obstacles=n, max_depth=4)) for seed, n in SEEDS]
    for name in ("office", "cluttered20"):
        out.append((name, navigation.load_world(world_file(name))))
    return out


@functools.lru_cache(maxsize=None)
def _captured():
    """Per world, the arguments of every ``_pair_distance`` call of a cold ``build_forest``
    followed by the full ``distances`` and ``wall_distance``."""
    pair = F._pair_distance
    out = []
    for name, w in _worlds():
        rec_p = []

        def rp(bodies, I, J, tol=1e-12):
            rec_p.append((list(bodies), np.array(I), np.array(J), tol))
            return pair(bodies, I, J, tol)

        F._pair_distance = rp
        try:
            F.clear_cache()
            forest = F.build_forest(w.workspace, w.obstacles)
            forest.distances, forest.wall_distance  # noqa: B018 (lazy: all exact pair distances)
        finally:
            F._pair_distance = pair
        out.append((name, rec_p))
    F.clear_cache()
    return out


def _pair_calls():
    """Every captured ``_pair_distance`` call as ``(name, bodies, I, J, tol)``."""
    return [(name, *args) for name, rec_p in _captured() for args in rec_p]


def test_captured_inputs_cover_both_groups():
    """The captured calls include obstacle pairs (256 x 256 samples) and obstacle/workspace
    pairs (256 x 1024)."""
    counts = {(len(b[i].pts), len(b[j].pts)) for _, b, I, J, _ in _pair_calls() for i, j in zip(I, J)}
    assert {(256, 256), (256, 1024)} <= counts


def test_pair_distance_arrays_one_group():
    """:func:`pair_distance_arrays` on one stacked group per sample-count pair equals
    :func:`pair_distance` (which groups ragged rows itself) row by row."""
    for name, bodies, I, J, tol in _pair_calls():
        d0, a0, b0 = PK.pair_distance(bodies, I, J, tol)
        for na in sorted({len(bodies[j].pts) for j in J}):
            k = np.array([t for t in range(len(I)) if len(bodies[J[t]].pts) == na])
            bi, bj = [bodies[i] for i in I[k]], [bodies[j] for j in J[k]]
            d, a, b = PK.pair_distance_arrays(
                np.stack([x.row for x in bi]), np.stack([x.row for x in bj]),
                np.stack([x.pts for x in bi]), np.stack([x.pts for x in bj]),
                np.stack([x.psi for x in bi]), np.stack([x.psi for x in bj]),
                [x.w0 for x in bi], [x.w0 for x in bj], [x.spacing for x in bi], [x.spacing for x in bj], tol)
            np.testing.assert_allclose(d, d0[k], rtol=0, atol=TOL, err_msg=name)
            np.testing.assert_allclose(a, a0[k], rtol=0, atol=1e-9, err_msg=name)
            np.testing.assert_allclose(b, b0[k], rtol=0, atol=1e-9, err_msg=name)


def test_pair_points_on_boundaries_and_distance():
    """The returned points lie on their boundaries (|beta| < 1e-9) and their distance is the
    returned distance (1e-12)."""
    for name, bodies, I, J, tol in _pair_calls():
        d, a, b = PK.pair_distance(bodies, I, J, tol)
        PI = np.stack([bodies[i].row for i in I])
        PJ = np.stack([bodies[j].row for j in J])
        assert np.all(np.abs(beta_rows(PI, a[:, 0], a[:, 1])) < 1e-9), name
        assert np.all(np.abs(beta_rows(PJ, b[:, 0], b[:, 1])) < 1e-9), name
        np.testing.assert_allclose(np.hypot(*(a - b).T), d, rtol=0, atol=TOL, err_msg=name)


@functools.lru_cache(maxsize=None)
def _dense(sq, n: int = 4096):
    """``n`` boundary points of ``sq`` evenly spaced in arc length, their KD-tree and half the
    largest spacing."""
    p = sq.point_at(sq.boundary_psi(n))
    return p, cKDTree(p), 0.5 * np.linalg.norm(p - np.roll(p, 1, axis=0), axis=1).max()


def test_pair_distance_against_dense_sampling():
    """Against the closest pair of 4096 boundary samples per body (every obstacle/workspace row,
    every 5th obstacle pair): the exact distance is never above the sampled one (1e-12) and below
    it by at most the sampling error (half the sum of the dense sample spacings)."""
    rows = 0
    for name, bodies, I, J, tol in _pair_calls():
        d, _, _ = PK.pair_distance(bodies, I, J, tol)
        for k, (i, j) in enumerate(zip(I, J)):
            if k % 5 and len(bodies[j].pts) == len(bodies[i].pts):
                continue
            pa, _, ea = _dense(bodies[i].sq)
            _, tb, eb = _dense(bodies[j].sq)
            # points farther than the allowed error are not searched (reported as inf: fails)
            dense = tb.query(pa, distance_upper_bound=d[k] + ea + eb + 1e-9)[0].min()
            assert d[k] <= dense + 1e-12, (name, k)
            assert dense - d[k] <= ea + eb, (name, k)
            rows += 1
    assert rows > 300


def test_rows_independent_of_batch():
    """A row's result does not depend on the other rows of its batch (each row alone, and the
    batch reversed, give the same bits)."""
    for name, bodies, I, J, tol in _pair_calls()[:12]:
        d, a, b = PK.pair_distance(bodies, I, J, tol)
        dr, ar, br = PK.pair_distance(bodies, I[::-1], J[::-1], tol)
        assert np.array_equal(dr[::-1], d) and np.array_equal(ar[::-1], a) and np.array_equal(br[::-1], b)
        for k in range(len(I)):
            d1, a1, b1 = PK.pair_distance(bodies, I[k:k + 1], J[k:k + 1], tol)
            assert d1[0] == d[k] and np.array_equal(a1[0], a[k]) and np.array_equal(b1[0], b[k])


def test_empty_inputs():
    """Empty batches give empty outputs of the right shapes."""
    c, f = PK.newton_pair(np.zeros((0, 7)), np.zeros((0, 7)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0),
                          tol=1e-12)
    assert c.shape == (0, 2) and f.shape == (0,)
    d, a, b = PK.pair_distance_arrays(np.zeros((0, 7)), np.zeros((0, 7)), np.zeros((0, 256, 2)),
                                      np.zeros((0, 256, 2)), np.zeros((0, 256)), np.zeros((0, 256)),
                                      np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0))
    assert d.shape == (0,) and a.shape == (0, 2) and b.shape == (0, 2)
    d, a, b = PK.pair_distance([], np.zeros(0, np.intp), np.zeros(0, np.intp))
    assert d.shape == (0,) and a.shape == (0, 2) and b.shape == (0, 2)
