"""Guarantees of navigation.forest: trees, parents and common centres of overlapping obstacles,
exact distances, and the rules of the forest of stars (paper 001 section 4.1.2)."""

from __future__ import annotations

import numpy as np
import pytest

from navigation._center_kernel import polygon_constraints
from navigation.errors import ForestError
from navigation.forest import NO_PARENT, WORKSPACE, Forest, build_forest, common_center, separation
from navigation.geometry import Squircle, pack
from navigation.world import load_world

from .conftest import world_file
from .worldgen import GAP, MIN_OVERLAP, random_forest_world, random_free_points

WS = Squircle((5.0, 5.0), 10.0, 10.0, 0.0, 0.99)


def wall(cx: float, cy: float, length: float, thick: float = 0.2, theta: float = 0.0, s: float = 0.99) -> Squircle:
    return Squircle((cx, cy), length, thick, theta, s)


def vwall(cx: float, cy: float, length: float, thick: float = 0.2) -> Squircle:
    return Squircle((cx, cy), thick, length, 0.0, 0.99)


# An interior chain of five walls (rooted at its middle), a chain of three hanging from the
# bottom of the workspace, and a lone circle.
COMB = [
    wall(3.0, 5.0, 1.0),  # 0
    vwall(3.4, 5.2, 1.2),  # 1
    wall(3.9, 5.7, 1.2),  # 2  centre of the interior chain
    vwall(4.4, 6.2, 1.2),  # 3
    wall(4.9, 6.7, 1.2),  # 4
    vwall(7.0, 0.6, 1.8),  # 5  crosses the bottom boundary
    wall(7.6, 1.4, 1.4),  # 6
    vwall(8.2, 2.0, 1.4),  # 7
    Squircle((2.0, 8.0), 0.6, 0.6, 0.0, 0.0),  # 8  lone circle
]


@pytest.fixture(scope="module")
def comb() -> Forest:
    return build_forest(WS, COMB)


# ---------------------------------------------------------------------- invariants
def check_invariants(f: Forest, max_depth: int | None = None) -> None:
    """Structural and geometric guarantees every forest satisfies."""
    m = len(f)
    assert len(f.parent) == len(f.depth) == len(f.tree_of) == len(f.children) == len(f.source_index) == m
    assert f.center.shape == (m, 2) and f.center_depth.shape == (m,)
    assert f.distances.shape == (m, m) and f.wall_distance.shape == (m,)
    kept = set(f.source_index)
    assert kept.isdisjoint(k for k, _ in f.dropped)
    assert list(f.source_index) == sorted(f.source_index)
    for t, r in enumerate(f.roots):
        assert f.parent[r] == NO_PARENT and f.depth[r] == 0 and f.tree_of[r] == t
    for i in range(m):
        p = f.parent[i]
        assert tuple(sorted(f.children[i])) == tuple(j for j in range(m) if f.parent[j] == i)
        if p == NO_PARENT:
            assert i in f.roots
            continue
        if p == WORKSPACE:
            assert f.depth[i] == 1 and f.tree_of[i] == -1
            # the common centre is inside the obstacle and outside the workspace
            assert f.obstacles[i].beta(f.center[i]) < 0 < f.workspace.beta(f.center[i])
            assert f.wall_distance[i] == 0.0
        else:
            assert f.depth[i] == f.depth[p] + 1 and f.tree_of[i] == f.tree_of[p]
            assert f.obstacles[i].beta(f.center[i]) < 0 and f.obstacles[p].beta(f.center[i]) < 0
            assert f.distances[i, p] == 0.0
        assert f.center_depth[i] >= 1e-3
    if max_depth is not None:
        assert max(f.depth, default=0) <= max_depth
    # distances: symmetric, zero on the diagonal and exactly for parent/child pairs
    assert np.array_equal(f.distances, f.distances.T)
    assert np.all(np.diag(f.distances) == 0.0)
    related = {(i, f.parent[i]) for i in range(m) if f.parent[i] >= 0}
    related |= {(b, a) for a, b in related}
    for i in range(m):
        for j in range(i + 1, m):
            assert (f.distances[i, j] == 0.0) == ((i, j) in related)
            if (i, j) not in related:
                assert f.distances[i, j] >= 1e-3
    for i in range(m):
        assert (f.wall_distance[i] == 0.0) == (f.parent[i] == WORKSPACE)
    # levels: every non-root once, deepest first, consistent with depth
    levels = f.levels()
    flat = [i for lev in levels for i in lev]
    assert sorted(flat) == [i for i in range(m) if f.parent[i] != NO_PARENT]
    assert [f.depth[lev[0]] for lev in levels] == list(range(len(levels), 0, -1))
    for lev in levels:
        assert len({f.depth[i] for i in lev}) == 1


def check_geometry(f: Forest, samples: int = 256) -> None:
    """Overlaps and disjointness seen independently, with Squircle.beta on boundary samples."""
    pts = [o.boundary_points(samples) for o in f.obstacles]
    m = len(f)
    for i in range(m):
        for j in range(i + 1, m):
            overlap = np.any(f.obstacles[j].beta(pts[i]) < 0) or np.any(f.obstacles[i].beta(pts[j]) < 0)
            assert overlap == (f.distances[i, j] == 0.0), (i, j)


# ---------------------------------------------------------------------- shared worlds
class TestSharedWorlds:
    def test_simple_has_one_tree_of_two(self):
        f = load_world(world_file("simple")).forest()
        check_invariants(f)
        assert f.tree_of[2] == f.tree_of[3]
        assert {f.parent[2], f.parent[3]} == {NO_PARENT, 2} or {f.parent[2], f.parent[3]} == {NO_PARENT, 3}
        assert f.parent[0] == f.parent[1] == NO_PARENT
        assert len(f.roots) == 3 and WORKSPACE not in f.parent
        assert f.levels() == [(3,)]  # equal eccentricity: the larger obstacle (2) is the root

    def test_office_builds_and_has_workspace_children(self):
        f = load_world(world_file("office")).forest(0.0)
        check_invariants(f)
        check_geometry(f)
        ws_children = [i for i in range(len(f)) if f.parent[i] == WORKSPACE]
        assert {8, 11, 13, 15, 18, 19, 21} <= set(ws_children)
        assert f.parent[20] == 19 and f.parent[17] == 16 and f.parent[16] == 15
        assert f.depth[17] == 3
        assert f.tree_members(-1) == tuple(sorted(i for i in range(len(f)) if f.tree_of[i] == -1))

    def test_cluttered20_builds_with_deep_trees(self):
        f = load_world(world_file("cluttered20")).forest(0.0)
        check_invariants(f)
        check_geometry(f)
        assert WORKSPACE not in f.parent
        # the chain 0-1-2-3 is one tree, rooted at its centre: three purge levels
        t = f.tree_of[0]
        assert set(f.tree_members(t)) == {0, 1, 2, 3}
        assert max(f.depth[i] for i in f.tree_members(t)) + 1 >= 3
        assert f.roots[t] in (1, 2)

    def test_cluttered20_inflated_closes_a_cycle(self):
        with pytest.raises(ForestError) as info:
            load_world(world_file("cluttered20")).forest(0.1)
        assert info.value.rule == "cycle"
        assert set(info.value.obstacles) == {0, 1, 2}
        assert "0, 1 and 2" in str(info.value) and "cycle" in str(info.value)


# ---------------------------------------------------------------------- structure
class TestStructure:
    def test_parents_depths_and_roots(self, comb):
        check_invariants(comb)
        check_geometry(comb)
        assert comb.roots == (2, 8)
        assert comb.parent == (1, 2, NO_PARENT, 2, 3, WORKSPACE, 5, 6, NO_PARENT)
        assert comb.depth == (2, 1, 0, 1, 2, 1, 2, 3, 0)
        assert comb.tree_of == (0, 0, 0, 0, 0, -1, -1, -1, 1)
        assert comb.children[2] == (1, 3) and comb.children[8] == ()

    def test_levels_deepest_first(self, comb):
        assert comb.levels() == [(7,), (0, 4, 6), (1, 3, 5)]
        assert comb.max_depth == 3

    def test_accessors(self, comb):
        assert len(comb) == 9
        assert comb.is_leaf(0) and comb.is_leaf(7) and not comb.is_leaf(2)
        assert comb.is_root(2) and not comb.is_root(5)
        assert comb.tree_members(0) == (0, 1, 2, 3, 4)
        assert comb.tree_members(-1) == (5, 6, 7)
        assert comb.tree_members(1) == (8,)
        with pytest.raises(IndexError):
            comb.tree_members(2)
        text = comb.describe()
        assert "2 interior tree(s)" in text and "workspace boundary" in text and "#7 (depth 3" in text

    def test_root_ties_go_to_the_larger_obstacle(self):
        small, big = wall(3.0, 3.0, 0.8), vwall(3.3, 3.4, 1.4, 0.3)
        assert build_forest(WS, [small, big]).roots == (1,)
        assert build_forest(WS, [big, small]).roots == (0,)

    def test_arrays_are_read_only(self, comb):
        for name in ("center", "center_depth", "distances", "wall_distance", "far_gap", "clearance"):
            with pytest.raises(ValueError):
                getattr(comb, name)[0, ...] = 1.0

    def test_empty(self):
        f = build_forest(WS, [])
        assert len(f) == 0 and f.levels() == [] and f.roots == () and f.center.shape == (0, 2)


# ---------------------------------------------------------------------- common centres
class TestCommonCentre:
    def test_cross_of_two_walls(self):
        f = build_forest(WS, [wall(5.0, 5.0, 2.0, 0.4), vwall(5.0, 5.0, 2.0, 0.4)])
        # the intersection is the 0.4 x 0.4 square: inscribed disc of radius 0.2 at the centre
        assert f.center_depth[1] == pytest.approx(0.2, abs=1e-3)
        assert np.allclose(f.center[1], (5.0, 5.0), atol=5e-3)

    def test_depth_is_exact_at_the_centre(self, comb):
        for i in range(len(comb)):
            p, c = comb.parent[i], comb.center[i]
            if p == NO_PARENT:
                assert np.allclose(c, comb.obstacles[i].center)
                expected = -comb.obstacles[i].distance(c)
            elif p == WORKSPACE:
                expected = min(-comb.obstacles[i].distance(c), comb.workspace.distance(c))
            else:
                expected = min(-comb.obstacles[i].distance(c), -comb.obstacles[p].distance(c))
            assert comb.center_depth[i] == pytest.approx(expected, abs=1e-9)

    def test_centre_is_near_the_deepest_point(self, comb):
        """Against a brute-force grid of the max-min depth (within 2 % or 1 mm)."""
        for i in (0, 4, 5, 7):
            p = comb.parent[i]
            a = comb.obstacles[i]
            lo, hi = a.boundary_points(64).min(0), a.boundary_points(64).max(0)
            gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 90), np.linspace(lo[1], hi[1], 90))
            q = np.stack((gx.ravel(), gy.ravel()), axis=1)
            q = q[a.beta(q) < 0]
            other = comb.workspace.distance(q) if p == WORKSPACE else -comb.obstacles[p].distance(q)
            best = np.max(np.minimum(-a.distance(q), other))
            assert comb.center_depth[i] >= best - max(0.02 * best, 1e-3)

    @pytest.mark.parametrize("seed", range(2))
    def test_thin_intersections_reach_the_deepest_point(self, seed):
        """Thin overlaps (0.3-2 cm) of random squircles, rounded or square, in any orientation:
        the tangent-line refinement finds the deepest point of the lens to within 2e-5 m of a
        dense brute-force grid over it (and the reported depth is exact at the centre)."""
        rng = np.random.default_rng(100 + seed)
        for _ in range(4):
            a = Squircle((5.0, 5.0), rng.uniform(0.3, 2.5), rng.uniform(0.15, 0.6), rng.uniform(0, 3.1),
                         float(rng.choice([0.99, 0.9, 0.5, 0.0])))
            th = rng.uniform(0, 2 * np.pi)
            u = np.array([np.cos(th), np.sin(th)])
            w, h, rot, s = rng.uniform(0.2, 2.0), rng.uniform(0.15, 0.6), rng.uniform(0, 3.1), float(rng.choice([0.99, 0.5]))
            lo, hi = 0.0, 6.0  # bisect the touching distance along u, then push in by d
            for _ in range(50):
                mid = 0.5 * (lo + hi)
                lo, hi = (lo, mid) if separation(a, Squircle(tuple(5.0 + mid * u), w, h, rot, s)) > 0 else (mid, hi)
            b = Squircle(tuple(5.0 + (lo - rng.uniform(0.003, 0.02)) * u), w, h, rot, s)
            f = build_forest(WS, [a, b])
            k = 1 if f.parent[1] == 0 else 0
            c, depth = f.center[k], f.center_depth[k]
            assert depth == pytest.approx(min(-a.distance(c), -b.distance(c)), abs=1e-9)
            # brute force: a grid over the intersection's bounding box, refined around its best point
            pts = a.boundary_points(2000)
            box = pts[b.beta(pts) < 0]
            pts = b.boundary_points(2000)
            box = np.concatenate((box, pts[a.beta(pts) < 0]))
            lo_, hi_ = box.min(0), box.max(0)
            best, q0 = -np.inf, None
            for _ in range(3):
                gx, gy = np.meshgrid(np.linspace(lo_[0], hi_[0], 80), np.linspace(lo_[1], hi_[1], 80))
                q = np.stack((gx.ravel(), gy.ravel()), axis=1)
                v = np.minimum(-a.distance(q), -b.distance(q))
                i = int(np.argmax(v))
                if v[i] > best:
                    best, q0 = float(v[i]), q[i]
                span = (hi_ - lo_) / 12
                lo_, hi_ = q0 - span, q0 + span
            assert depth >= best - 2e-5, (depth, best)

    def test_public_helpers(self):
        a, b = wall(2.0, 2.0, 1.0), vwall(2.4, 2.2, 1.0)
        p, depth = common_center(a, b)
        assert a.beta(p) < 0 and b.beta(p) < 0 and depth == pytest.approx(0.1, abs=2e-3)
        p, depth = common_center(wall(0.2, 5.0, 1.0), WS, outside_b=True)
        assert WS.beta(p) > 0 and depth == pytest.approx(0.1, abs=2e-3)
        assert separation(a, b) == 0.0
        assert separation(wall(2.0, 2.0, 1.0), wall(2.0, 2.5, 1.0)) == pytest.approx(0.3, abs=1e-9)
        assert separation(Squircle((0, 0), 2, 2), Squircle((0, 0), 0.5, 0.5)) == 0.0  # containment


# ---------------------------------------------------------------------- distances
class TestDistances:
    def test_pair_distance_matches_brute_force(self, comb):
        rng = np.random.default_rng(3)
        m = len(comb)
        for _ in range(12):
            i, j = rng.choice(m, 2, replace=False)
            if comb.distances[i, j] == 0:
                continue
            a, b = comb.obstacles[i], comb.obstacles[j]
            psi = a.boundary_psi(2000)
            d = b.distance(a.point_at(psi))
            k = int(np.argmin(d))
            fine = np.linspace(psi[k - 1], psi[(k + 1) % len(psi)] + (2 * np.pi if k + 1 == len(psi) else 0), 401)
            brute = min(d.min(), b.distance(a.point_at(fine)).min())
            assert comb.distances[i, j] <= brute + 1e-12
            assert comb.distances[i, j] >= brute - 1e-8

    def test_gap_bounds_are_lower_bounds_and_tight_for_walls(self):
        """The rectangle/disc lower bounds never exceed the exact distance (random squircles of
        every shape and rotation), and are within the corner rounding of it for s = 0.99 (a
        corner recedes along the diagonal by ``(sqrt 2 - sqrt(2 / (1 + sqrt(1 - s^2))))`` half-extents,
        under 0.07 of the half diagonal)."""
        import navigation.forest as F

        rng = np.random.default_rng(11)
        for trial in range(40):
            k = 6
            sq = [Squircle(tuple(rng.uniform(0, 10, 2)), rng.uniform(0.1, 3.0), rng.uniform(0.1, 3.0),
                           rng.uniform(-np.pi, np.pi), 0.99 if trial % 2 else rng.uniform(0.0, 0.999))
                  for _ in range(k)]
            lb = F._gap_bounds(pack(sq))
            assert lb.shape == (k, k) and np.all(lb >= 0) and np.all(np.diag(lb) == 0)
            assert np.array_equal(lb, lb.T)
            for i in range(k):
                for j in range(i + 1, k):
                    d = separation(sq[i], sq[j])
                    assert lb[i, j] <= d + 1e-12, (trial, i, j, lb[i, j], d)
                    if trial % 2 and d > 0:  # near-rectangles: the bound is close
                        assert d - lb[i, j] <= 0.07 * (sq[i].bounding_radius + sq[j].bounding_radius)

    def test_wall_bounds_are_lower_bounds(self):
        """The inscribed-polygon bound of the distance to the workspace boundary never exceeds
        the exact distance, and is within the bounding rectangle's corners of it."""
        import navigation.forest as F

        rng = np.random.default_rng(12)
        ws = F._Body(WS, F._WS_SAMPLES)
        sq = [Squircle(tuple(rng.uniform(2, 8, 2)), rng.uniform(0.1, 2.0), rng.uniform(0.1, 2.0),
                       rng.uniform(-np.pi, np.pi), rng.uniform(0.0, 0.999)) for _ in range(60)]
        lb = F._wall_bounds(pack(sq), ws)
        f = build_forest(WS, [sq[0]])
        for k, s in enumerate(sq):
            exact = build_forest(WS, [s]).wall_distance[0]
            assert 0.0 <= lb[k] <= exact + 1e-12, (k, lb[k], exact)
            assert exact - lb[k] <= 0.3 * s.bounding_radius + 1e-3  # a disc: its square corners
        assert f.wall_distance.shape == (1,)

    @pytest.mark.parametrize("seed", range(8))
    def test_clearance_is_the_minimum_of_the_exact_distances(self, seed):
        """Forest.clearance (computed from lower bounds and only the exact distances that can be
        the minimum) equals the minimum over the full exact distance matrix."""
        w = random_forest_world(seed, n_obstacles=20 + seed, max_depth=4)
        f = build_forest(w.workspace, w.obstacles)
        D, depth = f.distances, np.asarray(f.depth)
        for i in range(len(f)):
            if f.parent[i] == NO_PARENT:
                others = [k for k in f.roots if k != i]
                base = f.wall_distance[i]
            else:
                others = [k for k in np.nonzero(depth <= depth[i])[0] if k != i and k != f.parent[i]]
                base = f.far_gap[i] if f.parent[i] == WORKSPACE else f.wall_distance[i]
            want = min([base] + [D[i, k] for k in others])
            assert f.clearance[i] == pytest.approx(want, abs=1e-12), i

    def test_known_gaps(self):
        f = build_forest(WS, [wall(3.0, 3.0, 1.0), wall(3.0, 3.5, 1.0), Squircle((6.0, 3.0), 1.0, 1.0, 0.0, 0.0)])
        assert f.distances[0, 1] == pytest.approx(0.3, abs=1e-9)
        assert f.distances[0, 2] == pytest.approx(6.0 - 0.5 - 3.5, abs=1e-9)
        # nearest to the bottom (circle) and left (wall) sides; the workspace corners are rounded
        assert f.wall_distance[2] == pytest.approx(-WS.distance([6.0, 2.5]), abs=1e-4)
        assert f.wall_distance[0] == pytest.approx(-WS.distance([2.5, 3.0]), abs=1e-4)

    def test_far_gap_of_a_wall_hanging_from_the_boundary(self):
        """A wall hanging from the top side ends ``gap`` above the bottom side: straight down from
        its common centre the workspace is left ``gap`` beyond the wall, and no ray through the
        wall finds less (its rounded end bends away); other obstacles have no far gap."""
        ws = Squircle((2.0, 0.75), 4.0, 1.5, 0.0, 0.99)
        hanging = Squircle((2.6, 1.15), 0.2, 1.1, 0.0, 0.99)  # from y = 0.6 up through the top (1.5)
        post = Squircle((1.0, 0.75), 0.2, 0.2, 0.0, 0.99)
        f = build_forest(ws, [hanging, post])
        assert f.parent == (WORKSPACE, NO_PARENT)
        assert f.far_gap[0] == pytest.approx(0.6, abs=2e-3)
        assert f.far_gap[0] <= 0.6 + 1e-9
        assert f.far_gap[1] == np.inf

    def test_wall_distance_matches_brute_force(self, comb):
        for i in range(len(comb)):
            if comb.parent[i] == WORKSPACE:
                continue
            brute = (-comb.workspace.distance(comb.obstacles[i].boundary_points(3000))).min()
            assert brute - 1e-6 <= comb.wall_distance[i] <= brute + 1e-12


# ---------------------------------------------------------------------- rules
class TestRules:
    def _raises(self, obstacles, rule, involved, workspace=WS, **kw) -> ForestError:
        with pytest.raises(ForestError) as info:
            build_forest(workspace, obstacles, **kw)
        err = info.value
        assert err.rule == rule
        assert set(err.obstacles) == set(involved)
        for k in involved:
            assert (str(k) if k >= 0 else "workspace") in str(err)
        return err

    def test_cycle_of_three(self):
        tri = [wall(3.0, 2.0, 2.4), vwall(2.0, 3.0, 2.4), wall(2.9, 2.9, 3.68, theta=-np.pi / 4)]
        err = self._raises(tri, "cycle", (0, 1, 2))
        assert "cycle" in str(err)

    def test_cycle_through_the_workspace(self):
        obs = [wall(0.85, 3.0, 2.3), wall(0.85, 6.0, 2.3), vwall(1.5, 4.5, 3.6), Squircle((8, 8), 0.5, 0.5)]
        self._raises(obs, "cycle", (0, 1, 2, -1))

    def test_wall_crossing_the_boundary_twice(self):
        self._raises([wall(5.0, 5.0, 10.6)], "cycle", (0, -1))

    def test_too_close(self):
        outside = Squircle((20.0, 20.0), 1.0, 1.0)
        err = self._raises([outside, wall(3.0, 3.0, 1.0), wall(3.0, 3.2 + 5e-4, 1.0)], "too-close", (1, 2))
        assert "1 and 2" in str(err)
        # the same pair is fine with a smaller min_gap
        f = build_forest(WS, [wall(3.0, 3.0, 1.0), wall(3.0, 3.2 + 5e-4, 1.0)], min_gap=1e-4)
        assert f.distances[0, 1] == pytest.approx(5e-4, abs=1e-9)

    def test_too_close_to_the_workspace_boundary(self):
        self._raises([wall(0.5005, 5.0, 1.0)], "too-close", (0, -1))

    def test_shallow_overlap(self):
        self._raises([wall(3.0, 3.0, 1.0), wall(3.0, 3.2 - 5e-4, 1.0)], "shallow-overlap", (0, 1))
        f = build_forest(WS, [wall(3.0, 3.0, 1.0), wall(3.0, 3.2 - 5e-4, 1.0)], min_overlap=1e-4)
        assert f.center_depth[1] == pytest.approx(2.5e-4, abs=2e-5)

    def test_shallow_crossing_of_the_boundary(self):
        self._raises([wall(0.5 - 5e-4, 5.0, 1.0)], "shallow-overlap", (0, -1))
        f = build_forest(WS, [wall(0.5 - 5e-4, 5.0, 1.0)], min_overlap=1e-5)
        assert f.center_depth[0] == pytest.approx(2.5e-4, abs=1e-6)
        assert np.allclose(f.center[0], (-2.5e-4, 5.0), atol=1e-5)

    @pytest.mark.parametrize("overlap", [2.4e-3, 3e-3])
    def test_thin_but_sufficient_overlaps_are_measured_exactly(self, overlap):
        """Just above min_overlap: accepted, with the exact half-thickness as depth."""
        f = build_forest(WS, [wall(3.0, 3.0, 1.0), wall(3.0, 3.2 - overlap, 1.0), wall(0.5 - overlap, 5.0, 1.0)])
        assert f.center_depth[1] == pytest.approx(overlap / 2, abs=1e-6)
        assert f.center_depth[2] == pytest.approx(overlap / 2, abs=1e-6)

    def test_obstacle_covering_the_workspace(self):
        self._raises([Squircle((5, 5), 30.0, 30.0)], "covers-workspace", (0,))


class TestDropped:
    def test_outside_and_contained_obstacles_are_dropped(self):
        big = wall(3.0, 3.0, 2.0, 0.6)
        obs = [Squircle((20.0, 5.0), 1.0, 1.0), big, Squircle((3.2, 3.0), 0.3, 0.3, 0.0, 0.0), wall(6.0, 6.0, 1.0)]
        f = build_forest(WS, obs)
        assert f.source_index == (1, 3)
        assert dict(f.dropped) == {0: "entirely outside the workspace", 2: "contained in obstacle 1"}
        assert f.obstacles == (big, obs[3])
        check_invariants(f)

    def test_identical_obstacles_keep_the_first(self):
        a = wall(3.0, 3.0, 1.0)
        f = build_forest(WS, [a, a])
        assert f.source_index == (0,) and f.dropped == ((1, "contained in obstacle 0"),)

    def test_type_errors(self):
        with pytest.raises(TypeError, match=r"obstacles\[1\]"):
            build_forest(WS, [wall(3, 3, 1), {"center": [0, 0]}])


# ---------------------------------------------------------------------- random worlds
@pytest.fixture(scope="module")
def random_worlds():
    return [random_forest_world(seed) for seed in range(50)]


class TestRandomWorlds:
    def test_fifty_random_worlds_satisfy_the_invariants(self, random_worlds):
        for w in random_worlds:
            f = w.forest(0.0)
            assert len(f) == 12 and f.dropped == ()
            check_invariants(f, max_depth=4 + 1)
            # worldgen's promises: clear overlaps, clear gaps, walls on the boundary, a deep tree
            nonroot = [i for i in range(len(f)) if f.parent[i] != NO_PARENT]
            assert min(f.center_depth[nonroot]) >= MIN_OVERLAP - 1e-6
            off = f.distances[f.distances > 0]
            assert off.size == 0 or off.min() >= GAP - 1e-6
            assert WORKSPACE in f.parent
            assert f.max_depth == 4

    def test_random_worlds_overlaps_seen_independently(self, random_worlds):
        for w in random_worlds[:10]:
            check_geometry(w.forest(0.0))

    def test_regions_and_start_are_valid(self, random_worlds):
        for w in random_worlds[:10]:
            w.validate()
            assert w.name.startswith("random12_seed")
            assert list(w.regions) == ["r1", "r2", "r3", "r4"]
            assert w.task == "F r1 & F r2 & F r3 & F r4"

    def test_generation_is_deterministic(self, random_worlds):
        assert random_forest_world(7).to_dict() == random_worlds[7].to_dict()
        assert random_forest_world(8).to_dict() != random_worlds[7].to_dict()

    @pytest.mark.parametrize("n", [3, 20])
    def test_sizes(self, n):
        w = random_forest_world(100 + n, n_obstacles=n)
        f = w.forest(0.0)
        assert len(w.obstacles) == n
        check_invariants(f, max_depth=5)
        assert f.max_depth == min(4, n) if n >= 4 else f.max_depth <= n

    def test_free_points(self, random_worlds):
        w = random_worlds[0]
        rng = np.random.default_rng(0)
        pts = random_free_points(w, 200, rng, margin=0.1)
        assert pts.shape == (200, 2)
        assert np.all(-w.workspace.distance(pts) >= 0.1 - 1e-9)
        for o in w.obstacles:
            assert np.all(o.distance(pts) >= 0.1 - 1e-9)
        again = random_free_points(w, 200, np.random.default_rng(0), margin=0.1)
        assert np.array_equal(pts, again)

    def test_twenty_obstacles(self):
        # (its build time is measured by ``python -m benchmarks.navigation``, not asserted here)
        w = random_forest_world(1, n_obstacles=20)
        f = build_forest(w.workspace, w.obstacles)
        check_invariants(f, max_depth=5)


@pytest.mark.slow
def test_fifty_obstacles():
    w = random_forest_world(0, n_obstacles=50)
    assert (w.workspace.width, w.workspace.height) == (10.0, 10.0)
    f = build_forest(w.workspace, w.obstacles)
    check_invariants(f, max_depth=5)
    check_geometry(f, samples=128)


# ---------------------------------------------------------------------- fast paths = reference
@pytest.fixture(scope="module")
def bodies():
    """Boundary samples of the office obstacles and, last, its workspace."""
    from navigation.forest import _SAMPLES, _WS_SAMPLES, _Body

    w = load_world("office")
    return [_Body(o, _SAMPLES) for o in w.obstacles] + [_Body(w.workspace, _WS_SAMPLES)]


class TestFastPathsMatchReferences:
    """The build's fast computations (table-free distances, the common-centre LP, coarse-to-fine
    pair distances) return what reference computations return."""

    def test_signed_distance_rows_equals_the_tabled_distance(self):
        """The table-free distance of the forest build equals :meth:`Squircle.distance` (itself
        tested against a dense brute force) on random shapes from posts to workspaces, inside and
        outside, round to nearly square."""
        from navigation.geometry import signed_distance_rows

        rng = np.random.default_rng(7)
        for _ in range(150):
            sq = Squircle(tuple(rng.uniform(-2, 2, 2)), rng.uniform(0.05, 12), rng.uniform(0.05, 3), rng.uniform(0, 3),
                          float(rng.choice([0.0, 0.5, 0.9, 0.99, 0.999])))
            q = sq.c + rng.normal(size=(40, 2)) * rng.uniform(0.01, 3)
            d = signed_distance_rows(np.repeat(sq.packed()[None], len(q), 0), q)
            assert np.allclose(d, sq.distance(q), rtol=0, atol=1e-12)

    def test_chebyshev_centre_solves_the_linear_program(self):
        """The soft-min Newton solver of the common-centre LP matches scipy's HiGHS on random
        intersections of two polygons (value to 1e-4 of the size), and reports the exact depth
        of the polygon intersection at its point."""
        from scipy.optimize import linprog

        import navigation.forest as F

        rng = np.random.default_rng(3)
        rows_a, rows_b, lo, hi, scale, ref = [], [], [], [], [], []
        for _ in range(40):
            a = Squircle(tuple(rng.uniform(-0.5, 0.5, 2)), rng.uniform(0.2, 3), rng.uniform(0.1, 1), rng.uniform(0, 3))
            b = Squircle(tuple(rng.uniform(-0.5, 0.5, 2)), rng.uniform(0.2, 3), rng.uniform(0.1, 1), rng.uniform(0, 3))
            na, nb, v = polygon_constraints(pack([a, b]), 64)
            A, B = np.concatenate(na), np.concatenate(nb)
            res = linprog([0, 0, -1], A_ub=np.column_stack((A, np.ones(len(A)))), b_ub=B,
                          bounds=[(None, None)] * 3, method="highs")
            rows_a.append(A)
            rows_b.append(B)
            lo.append(np.maximum(v[0].min(0), v[1].min(0)))
            hi.append(np.maximum(np.minimum(v[0].max(0), v[1].max(0)), lo[-1]))
            scale.append(min(a.inscribed_radius, b.inscribed_radius))
            ref.append(res.x[2])
        c, t = F._max_min_slack(np.stack(rows_a), np.stack(rows_b), np.array(lo), np.array(hi), np.array(scale))
        assert np.allclose(t, [min(bb - aa @ cc) for aa, bb, cc in zip(rows_a, rows_b, c)], rtol=0, atol=1e-12)
        assert np.all(t <= np.array(ref) + 1e-12)
        assert np.allclose(t, ref, rtol=0, atol=1e-4 * np.array(scale))

    def test_pair_distance_is_the_dense_minimum(self, bodies):
        """Coarse-to-fine samples + Newton find the global minimum of the boundary distance for
        every pair of office obstacles and every obstacle-workspace pair (walls with nearly
        parallel faces included): never above a dense brute force, at most 1e-9 below it."""
        import navigation.forest as F

        n = len(bodies) - 1
        I, J = np.triu_indices(n, 1)
        I, J = np.concatenate((I, np.arange(n))), np.concatenate((J, np.full(n, n)))
        d, pa, pb = F._pair_distance(bodies, I, J)
        assert np.allclose(np.linalg.norm(pa - pb, axis=1), d, rtol=0, atol=1e-12)
        for k, (i, j) in enumerate(zip(I, J)):
            a, b = bodies[i].sq, bodies[j].sq
            if F._pair_relation(bodies[i], bodies[j]) is not None if j < n else \
                    F._workspace_relation(bodies[i], bodies[j]) != "inside":
                continue  # overlapping pairs have no boundary gap to compare
            psi = a.boundary_psi(4000)
            dd = np.abs(b.distance(a.point_at(psi)))
            m = int(np.argmin(dd))
            fine = np.linspace(psi[m - 1], psi[(m + 1) % len(psi)] + (2 * np.pi if m + 1 == len(psi) else 0), 401)
            brute = min(dd.min(), np.abs(b.distance(a.point_at(fine))).min())
            assert brute - 1e-9 <= d[k] <= brute + 1e-12, (i, j, d[k], brute)


# ---------------------------------------------------------------------- memo (incremental rebuilds)
def _assert_same_forest(a: Forest, b: Forest) -> None:
    for name in ("obstacles", "source_index", "dropped", "parent", "children", "depth", "roots", "tree_of"):
        assert getattr(a, name) == getattr(b, name), name
    for name in ("center", "center_depth", "distances", "wall_distance", "far_gap", "clearance"):
        assert np.allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-12), name


class TestMemo:
    """build_forest memoises per-obstacle and pairwise results keyed by the squircles: a rebuild
    after any sequence of map changes equals a cold build (up to rounding)."""

    @pytest.mark.parametrize("seed", range(6))
    def test_changes_then_rebuild_equals_cold_build(self, seed):
        from navigation.forest import clear_cache

        rng = np.random.default_rng(100 + seed)
        world = random_forest_world(seed, n_obstacles=10, max_depth=3)
        pool = list(world.obstacles)
        current = pool[: len(pool) // 2]
        clear_cache()
        checked = 0
        for step in range(8):
            op = rng.integers(3)
            if op == 0 and len(current) < len(pool):  # add one not yet present
                current = current + [next(o for o in pool if o not in current)]
            elif op == 1 and len(current) > 1:  # remove one
                k = int(rng.integers(len(current)))
                current = current[:k] + current[k + 1:]
            else:  # update one: move it a little
                k = int(rng.integers(len(current)))
                o = current[k]
                moved = Squircle(tuple(np.add(o.center, rng.normal(scale=0.01, size=2))), o.width, o.height,
                                 o.theta, o.s)
                current = current[:k] + [moved] + current[k + 1:]
            try:
                warm = build_forest(world.workspace, current)
            except ForestError as err:
                clear_cache()
                with pytest.raises(ForestError) as cold_err:
                    build_forest(world.workspace, current)
                assert (cold_err.value.rule, cold_err.value.obstacles) == (err.rule, err.obstacles)
                checked += 1
                continue
            # cold build with the memo cleared; then restore the warm state for the next step
            clear_cache()
            cold = build_forest(world.workspace, current)
            _assert_same_forest(warm, cold)
            checked += 1
        assert checked == 8

    def test_refusals_are_repeated_from_the_memo(self):
        a, b = wall(5.0, 5.0, 2.0), wall(5.0, 5.0, 1.0, thick=0.1)  # b lies inside a
        c = vwall(5.9, 5.0, 1.0)
        d = vwall(4.1, 5.0, 1.0)
        e = wall(5.0, 5.45, 2.0)  # closes the cycle a-c-e-d
        for _ in range(2):
            with pytest.raises(ForestError) as err:
                build_forest(WS, [a, c, d, e])
            assert err.value.rule == "cycle"
        for _ in range(2):
            assert build_forest(WS, [a, b]).dropped == ((1, "contained in obstacle 0"),)

    def test_lru_bound(self):
        from navigation._memo import Memo

        m = Memo(3)
        for k in range(5):
            m.put(k, k * 10)
        assert m.get(0) is None and m.get(1) is None
        assert m.get(2) == 20
        m.put(5, 50)  # evicts 3, the least recently used
        assert m.get(3) is None and m.get(2) == 20 and m.get(5) == 50

    def test_batched_lookups_behave_like_single_ones(self):
        """get_many / put_many: the same values, hit and miss counts and eviction order as the
        same get / put calls one by one."""
        from navigation._memo import Memo

        a, b = Memo(4), Memo(4)
        items = [(k, k * 10) for k in range(6)]
        a.put_many(items)
        for k, v in items:
            b.put(k, v)
        keys = [0, 3, 5, 9, 2, 3]
        assert a.get_many(keys) == [b.get(k) for k in keys] == [None, 30, 50, None, 20, 30]
        assert (a.hits, a.misses) == (b.hits, b.misses) == (4, 2)
        a.put_many([(7, 70)])
        b.put(7, 70)
        assert a.get_many(range(10)) == [b.get(k) for k in range(10)]


def test_check_forest_refuses_exactly_what_build_forest_refuses():
    """``check_forest`` stops before the far gaps and clearances: on random obstacle sets (many
    refused: cycles, near misses, grazing overlaps, obstacles covering or crossing the boundary
    twice) it raises the same rule for the same obstacles, and accepts what is accepted."""
    from navigation.errors import ForestError
    from navigation.forest import check_forest, clear_cache

    rng = np.random.default_rng(11)
    ws = Squircle((2.5, 2.5), 5.0, 5.0, 0.0, 0.95)
    a = Squircle((2.0, 2.0), 1.0, 0.4, 0.0, 0.9)
    crafted = [[a, Squircle((2.0, 2.4004), 1.0, 0.4, 0.0, 0.9)],  # 0.4 mm apart: too close
               [a, Squircle((2.0, 2.3998), 1.0, 0.4, 0.0, 0.9)],  # 0.2 mm deep: grazing
               [Squircle((2.5, 2.5), 6.0, 6.0, 0.0, 0.9)]]  # covers the workspace
    sets = crafted + [[Squircle(tuple(rng.uniform(0.0, 5.0, 2)), rng.uniform(0.2, 2.0), rng.uniform(0.1, 0.6),
                                rng.uniform(-np.pi, np.pi), rng.choice([0.0, 0.9, 0.99]))
                       for _ in range(rng.integers(2, 8))] for _ in range(80)]
    seen = set()
    for trial, obs in enumerate(sets):
        outcome = []
        for fn in (build_forest, check_forest):
            if trial % 2:
                clear_cache()
            try:
                fn(ws, obs)
                outcome.append(None)
            except ForestError as err:
                outcome.append((err.rule, tuple(err.obstacles)))
        assert outcome[0] == outcome[1], (trial, outcome)
        seen.add(None if outcome[0] is None else outcome[0][0])
    assert {None, "cycle", "too-close", "shallow-overlap", "covers-workspace"} <= seen, seen
