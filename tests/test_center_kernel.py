"""The common-centre programs (navigation._center_kernel): every program's value at a point of its
polygon is a lower bound of the point's depth in both sets, so the solved centres are at least that deep;
programs of the workspace children carry one tangent half-plane each, beyond the boundary."""

import numpy as np
import pytest

from navigation._center_kernel import center_programs
from navigation._lp_kernel import max_min_slack
from navigation.forest import separation
from navigation.geometry import Squircle, pack, signed_distance_rows

from .worldgen import random_forest_world


def _slack(A, B, q):
    """``min_k (B_k - A_k . q)`` over the non-void half-planes of one program."""
    keep = B < 1e100
    return np.min(B[keep] - A[keep] @ q)


@pytest.mark.parametrize("seed", range(4))
def test_inner_programs_bound_the_depth(seed):
    """Child/parent pairs: at the solved centre and at random points inside a program's polygon,
    its slack is at most the exact depth in both squircles (1e-12), so the centres are at least
    as deep as the programs' values."""
    rng = np.random.default_rng(seed)
    pairs = []
    while len(pairs) < 40:
        a = Squircle(tuple(rng.uniform(-1, 1, 2)), rng.uniform(0.2, 3), rng.uniform(0.1, 1), rng.uniform(0, 3),
                     rng.choice([0.5, 0.9, 0.99]))
        b = Squircle(tuple(rng.uniform(-1, 1, 2)), rng.uniform(0.2, 3), rng.uniform(0.1, 1), rng.uniform(0, 3), 0.99)
        if separation(a, b) == 0.0:  # overlapping, as a child and its parent
            pairs.append((a, b))
    PI, PJ = pack([p for p, _ in pairs]), pack([q for _, q in pairs])
    A, B, LO, HI, L, owner = center_programs(PI, PJ, np.zeros(len(pairs), bool), None, None, None,
                                             n=128, n_tangents=8, turn=0.05)
    assert list(owner) == list(range(len(pairs)))
    c, t = max_min_slack(A, B, LO, HI, L)
    for r, e in enumerate(owner):
        pts = np.vstack((c[r], c[r] + rng.normal(scale=0.3, size=(20, 2))))
        depth = np.minimum(-signed_distance_rows(np.repeat(PI[e:e + 1], 21, 0), pts),
                           -signed_distance_rows(np.repeat(PJ[e:e + 1], 21, 0), pts))
        for q, d in zip(pts, depth):
            s = _slack(A[r], B[r], q)
            if s > 0:  # inside the program's polygon (the edges far from the intersection are left out)
                assert s <= d + 1e-12
        if t[r] > 0:
            assert depth[0] >= t[r] - 1e-12


def test_workspace_children_programs():
    """Workspace children of random worlds: one program per kept tangent line (at most 8), whose
    last half-plane is beyond a tangent line of the workspace, so any point with positive slack
    lies outside the workspace; the programs' slack bounds the depth in the child."""
    for seed in range(6):
        w = random_forest_world(seed, n_obstacles=12, max_depth=3)
        forest = w.forest(0.0)
        kids = [i for i, p in enumerate(forest.parent) if p == -1 and i not in forest.roots]
        if not kids:
            continue
        from navigation.forest import _WS_SAMPLES, _Body
        ws = _Body(w.workspace, _WS_SAMPLES)
        PI = pack([forest.obstacles[i] for i in kids])
        A, B, LO, HI, L, owner = center_programs(PI, np.repeat(ws.row[None], len(kids), 0), np.ones(len(kids), bool),
                                                 ws.row, ws.pts, ws.psi, n=128, n_tangents=8, turn=0.05)
        assert set(owner) == set(range(len(kids))) and np.all(np.bincount(owner) <= 8)
        c, t = max_min_slack(A, B, LO, HI, L)
        for r, e in enumerate(owner):
            if t[r] > 0:
                d_ws = signed_distance_rows(ws.row[None], c[r][None])[0]
                d_in = -signed_distance_rows(PI[e:e + 1], c[r][None])[0]
                assert d_ws >= t[r] - 1e-12 and d_in >= t[r] - 1e-12
