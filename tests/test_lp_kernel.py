"""Guarantees of the compiled Chebyshev-centre solver (navigation._lp_kernel, behind
navigation.forest._max_min_slack): it solves the common-centre linear program (checked against
scipy's HiGHS) on the forest's own inputs and on random polygons, and a row's result does not
depend on its batch. (When it replaced the numpy solver it agreed with it to 2e-11 scale on
every captured world input.)"""

from __future__ import annotations

import functools

import numpy as np
import pytest

import navigation.forest as F
from navigation._center_kernel import polygon_constraints
from navigation._lp_kernel import max_min_slack
from navigation.forest import build_forest, separation
from navigation.geometry import Squircle, pack
from navigation.world import load_world

from .conftest import world_file
from .worldgen import random_forest_world

WS = Squircle((5.0, 5.0), 10.0, 10.0, 0.0, 0.99)
#: random worlds whose solver inputs are captured: (obstacles, seed)
SIZES_SEEDS = [(5, 0), (5, 1), (5, 2), (12, 0), (12, 1), (12, 2), (20, 0), (20, 1), (35, 0), (50, 0)]
#: more of them for the slow sweep
SLOW_SIZES_SEEDS = [(n, seed) for n in (5, 8, 12, 20, 35, 50) for seed in range(3, 11)]
PAD = 1e100  #: half-planes with a = 0 and b >= PAD are padding
#: widest start box of the random LPs, in scales. The forest's common-centre LPs stay below 10
#: on the random worlds. With wider boxes (30-110) the solver (numpy and kernel alike) can stop
#: short of the optimum (up to 0.1 scale seen), where rounding can also change its path.
MAX_BOX = 20.0
#: distance of t from the LP optimum, relative to the row's scale (the numpy docstring's bound)
OPTIMAL = 1e-4


@functools.lru_cache(maxsize=None)
def _thin_worlds() -> tuple[list[Squircle], ...]:
    """Obstacle lists whose common centres are refined by ``_thin_centers``: a 3 mm wall overlap,
    a wall crossing the workspace boundary by 3 mm, and thin lenses (0.3-2 cm) of random squircles
    (as in tests/test_forest.py)."""
    def wall(cx, cy, length):
        return Squircle((cx, cy), length, 0.2, 0.0, 0.99)

    worlds = [[wall(3.0, 3.0, 1.0), wall(3.0, 3.2 - 3e-3, 1.0), wall(0.5 - 3e-3, 5.0, 1.0)]]
    rng = np.random.default_rng(100)
    for _ in range(8):
        a = Squircle((5.0, 5.0), rng.uniform(0.3, 2.5), rng.uniform(0.15, 0.6), rng.uniform(0, 3.1),
                     float(rng.choice([0.99, 0.9, 0.5, 0.0])))
        th = rng.uniform(0, 2 * np.pi)
        u = np.array([np.cos(th), np.sin(th)])
        w, h, rot = rng.uniform(0.2, 2.0), rng.uniform(0.15, 0.6), rng.uniform(0, 3.1)
        s = float(rng.choice([0.99, 0.5]))
        lo, hi = 0.0, 6.0  # bisect the touching distance along u, then push in
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if separation(a, Squircle(tuple(5.0 + mid * u), w, h, rot, s)) > 0 else (mid, hi)
        worlds.append([a, Squircle(tuple(5.0 + (lo - rng.uniform(0.003, 0.02)) * u), w, h, rot, s)])
    return tuple(worlds)


def _capture(workspace: Squircle, obstacles, monkeypatch) -> list[tuple]:
    """The arguments of every ``_max_min_slack`` call of a cold ``build_forest``."""
    calls = []
    reference = F._max_min_slack

    def recorder(a, b, lo, hi, scale, **kw):
        calls.append((a.copy(), b.copy(), lo.copy(), hi.copy(), scale.copy()))
        return reference(a, b, lo, hi, scale, **kw)

    with monkeypatch.context() as m:
        m.setattr(F, "_max_min_slack", recorder)
        F.clear_cache()
        build_forest(workspace, obstacles)
    F.clear_cache()
    return calls


@pytest.fixture(scope="module")
def captured():
    """``{"worlds": [...], "thin": [...]}``: recorded solver inputs of the random worlds,
    office and cluttered20 (common centres), and of the thin-overlap worlds (thin centres)."""
    worlds = [random_forest_world(seed, n_obstacles=n, max_depth=4) for n, seed in SIZES_SEEDS]
    worlds += [load_world(world_file(name)) for name in ("office", "cluttered20")]
    return {"worlds": _capture_worlds([(w.workspace, w.obstacles) for w in worlds]),
            "thin": _capture_worlds([(WS, obs) for obs in _thin_worlds()])}


def _capture_worlds(cases) -> list[tuple]:
    """The solver inputs of cold builds of ``(workspace, obstacles)`` cases."""
    mp = pytest.MonkeyPatch()
    try:
        return [c for workspace, obstacles in cases for c in _capture(workspace, obstacles, mp)]
    finally:
        mp.undo()


def _optimum(a: np.ndarray, b: np.ndarray) -> float:
    """HiGHS optimum of ``max t s.t. a_k . q + t <= b_k`` (padding left out)."""
    from scipy.optimize import linprog

    keep = ~((a == 0).all(1) & (b >= PAD))
    res = linprog([0, 0, -1], A_ub=np.column_stack((a[keep], np.ones(keep.sum()))), b_ub=b[keep],
                  bounds=[(None, None)] * 3, method="highs")
    assert res.status == 0, res.message
    return float(res.x[2])


def _random_polygons(seed: int, rows: int):
    """Random convex polygons inscribed in random ellipses (3-128 vertices at jittered even
    angles, aspect ratios up to 30, scale 0.5-1 times the minor semi-axis as the forest takes the
    smaller half-width, start box at most ``MAX_BOX`` scales wide) and intersections of two of
    them, each padded with ``a = 0``, ``b = 1e200`` to a common width plus a random amount:
    ``(a, b, lo, hi, scale)``."""
    rng = np.random.default_rng(seed)

    def polygon():
        k = int(rng.integers(3, 129))
        ang = np.sort((np.arange(k) + rng.uniform(-0.4, 0.4, k)) * (2 * np.pi / k) + rng.uniform(0, 2 * np.pi))
        r1 = rng.uniform(0.05, 3.0)
        r2 = r1 / rng.uniform(1.0, 30.0)
        rot = rng.uniform(0, np.pi)
        R = np.array([[np.cos(rot), -np.sin(rot)], [np.sin(rot), np.cos(rot)]])
        v = np.stack((r1 * np.cos(ang), r2 * np.sin(ang)), 1) @ R.T + rng.uniform(-5, 5, 2)
        e = np.roll(v, -1, axis=0) - v
        n = np.stack((e[:, 1], -e[:, 0]), 1)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return n, (n * v).sum(1), v, r2

    A, B, LO, HI, L = [], [], [], [], []
    while len(A) < rows:
        n, b, v, r = polygon()
        lo, hi = v.min(0), v.max(0)
        if rng.random() < 0.5:  # intersect with a second polygon moved near the first one's centre
            n2, b2, v2, r2 = polygon()
            shift = v.mean(0) - v2.mean(0) + rng.uniform(-0.3, 0.3, 2) * r
            n, b, r = np.concatenate((n, n2)), np.concatenate((b, b2 + n2 @ shift)), min(r, r2)
            lo = np.maximum(lo, (v2 + shift).min(0))  # the box of the intersection, as the forest
            hi = np.maximum(np.minimum(hi, (v2 + shift).max(0)), lo)  # gives it
        scale = r * rng.uniform(0.5, 1.0)
        if np.max(hi - lo) > MAX_BOX * scale:
            continue
        A.append(n)
        B.append(b)
        LO.append(lo)
        HI.append(hi)
        L.append(scale)
    width = max(len(b) for b in B) + int(rng.integers(0, 5))
    a = np.stack([np.concatenate((x, np.zeros((width - len(x), 2)))) for x in A])
    b = np.stack([np.concatenate((x, np.full(width - len(x), 1e200))) for x in B])
    return a, b, np.array(LO), np.array(HI), np.array(L)


def _feasible_lps(a, b, lo, hi, scale):
    """Keep the rows whose LP has a positive optimum (the polygons do intersect)."""
    ok = np.array([_optimum(a[e], b[e]) > 1e-3 * scale[e] for e in range(len(a))])
    return a[ok], b[ok], lo[ok], hi[ok], scale[ok]


def test_only_padding():
    """A row of padding only: the first grid point (the centre of the first of 5 x 5 cells) and
    ``t = 1e200``."""
    a, b = np.zeros((1, 3, 2)), np.full((1, 3), 1e200)
    lo, hi, scale = np.array([[0.0, 1.0]]), np.array([[2.0, 3.0]]), np.array([0.5])
    c, t = max_min_slack(a, b, lo, hi, scale)
    assert np.allclose(c, [[0.2, 1.2]], rtol=0, atol=1e-15) and np.array_equal(t, [1e200])


def test_empty_batch():
    c, t = max_min_slack(np.zeros((0, 4, 2)), np.zeros((0, 4)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0))
    assert c.shape == (0, 2) and t.shape == (0,)


class TestLinearProgram:
    """The returned point and value solve ``max t s.t. a_k . q + t <= b_k``."""

    @staticmethod
    def _check(a, b, c, t, scale, tol):
        for e in range(len(a)):
            keep = ~((a[e] == 0).all(1) & (b[e] >= PAD))
            slack = b[e][keep] - a[e][keep] @ c[e]
            assert t[e] == pytest.approx(slack.min(), abs=1e-12 * max(1.0, np.abs(b[e][keep]).max()))
            opt = _optimum(a[e], b[e])
            assert t[e] <= opt + 1e-9  # a feasible point: never above the optimum
            assert opt - t[e] <= tol[e], (e, (opt - t[e]) / scale[e])

    def test_captured_world_inputs_are_solved(self, captured):
        for a, b, lo, hi, scale in captured["worlds"]:
            c, t = max_min_slack(a, b, lo, hi, scale)
            self._check(a, b, c, t, scale, OPTIMAL * scale)

    def test_captured_thin_inputs_are_solved(self, captured):
        """Thin-centre LPs (up to 96 tangents, scale the thickness of the lens box): within the
        soft minimum's bias ``tau log K`` at the last ``tau`` (0.05 scale / 8^3), about 4.5e-4
        scale; the numpy solver gives the same values (1.5e-4 scale on one of these rows)."""
        for a, b, lo, hi, scale in captured["thin"]:
            c, t = max_min_slack(a, b, lo, hi, scale)
            k = (~((a == 0).all(2) & (b >= PAD))).sum(1)
            self._check(a, b, c, t, scale, 0.05 / 8 ** 3 * np.log(k) * scale)

    @pytest.mark.parametrize("seed", range(4))
    def test_random_convex_polygons_are_solved(self, seed):
        a, b, lo, hi, scale = _feasible_lps(*_random_polygons(seed, 60))
        assert len(a) >= 30
        c, t = max_min_slack(a, b, lo, hi, scale)
        self._check(a, b, c, t, scale, OPTIMAL * scale)

    def test_inscribed_polygons_of_squircles_are_solved(self):
        """Random intersections of the forest's inscribed polygons (as tests/test_forest.py
        checks the numpy solver)."""
        rng = np.random.default_rng(3)
        A, B, LO, HI, L = [], [], [], [], []
        for _ in range(40):
            p = Squircle(tuple(rng.uniform(-0.5, 0.5, 2)), rng.uniform(0.2, 3), rng.uniform(0.1, 1), rng.uniform(0, 3))
            q = Squircle(tuple(rng.uniform(-0.5, 0.5, 2)), rng.uniform(0.2, 3), rng.uniform(0.1, 1), rng.uniform(0, 3))
            na, nb, v = polygon_constraints(pack([p, q]), 64)
            A.append(np.concatenate(na))
            B.append(np.concatenate(nb))
            LO.append(np.maximum(v[0].min(0), v[1].min(0)))
            HI.append(np.maximum(np.minimum(v[0].max(0), v[1].max(0)), LO[-1]))
            L.append(min(p.inscribed_radius, q.inscribed_radius))
        a, b, lo, hi, scale = np.stack(A), np.stack(B), np.array(LO), np.array(HI), np.array(L)
        c, t = max_min_slack(a, b, lo, hi, scale)
        self._check(a, b, c, t, scale, OPTIMAL * scale)


@pytest.mark.slow
class TestSweep:
    """More worlds and polygons: optimality."""

    def test_random_worlds(self):
        worlds = [random_forest_world(seed, n_obstacles=n, max_depth=4) for n, seed in SLOW_SIZES_SEEDS]
        for a, b, lo, hi, scale in _capture_worlds([(w.workspace, w.obstacles) for w in worlds]):
            c, t = max_min_slack(a, b, lo, hi, scale)
            TestLinearProgram._check(a, b, c, t, scale, OPTIMAL * scale)

    @pytest.mark.parametrize("seed", range(4, 30))
    def test_random_convex_polygons(self, seed):
        a, b, lo, hi, scale = _feasible_lps(*_random_polygons(seed, 60))
        c, t = max_min_slack(a, b, lo, hi, scale)
        TestLinearProgram._check(a, b, c, t, scale, OPTIMAL * scale)


class TestRowsAreIndependent:
    """A row's result does not depend on its batch or on its padding (the forest's memo relies
    on that)."""

    def test_row_alone_equals_row_in_batch(self):
        a, b, lo, hi, scale = _random_polygons(11, 30)
        c, t = max_min_slack(a, b, lo, hi, scale)
        for e in range(len(a)):
            ce, te = max_min_slack(a[e:e + 1], b[e:e + 1], lo[e:e + 1], hi[e:e + 1], scale[e:e + 1])
            assert np.array_equal(ce[0], c[e]) and te[0] == t[e]

    def test_extra_padding_changes_nothing(self):
        a, b, lo, hi, scale = _random_polygons(12, 30)
        c, t = max_min_slack(a, b, lo, hi, scale)
        a2 = np.concatenate((a, np.zeros((len(a), 7, 2))), axis=1)
        b2 = np.concatenate((b, np.full((len(a), 7), 1e200)), axis=1)
        c2, t2 = max_min_slack(a2, b2, lo, hi, scale)
        assert np.array_equal(c, c2) and np.array_equal(t, t2)
