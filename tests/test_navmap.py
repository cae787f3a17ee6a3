"""The navigation map: initial costs (paper 001 section 4.1.1), edits, versions, input checks."""

from __future__ import annotations

import doctest
import math

import pytest

import tamp.navmap
from tamp.errors import InvalidRequestError, UnknownRegionError
from tamp.navmap import START, NavigationMap, Node

REGIONS = {"a": (0.0, 0.0), "b": (3.0, 4.0), "c": (-1.0, 2.0)}


def test_doctests():
    assert doctest.testmod(tamp.navmap).failed == 0


def test_nodes_and_fully_connected_structure():
    m = NavigationMap(REGIONS, n_orient=8, w=0.2)
    assert len(m.nodes) == 24 and m.num_region_nodes == 24
    assert m.nodes[0] == Node("a", 0) and m.nodes[-1] == Node("c", 7)
    edges = list(m.edges())
    assert len(edges) == m.num_edges == 24 * 23  # every ordered pair of distinct nodes
    assert all(u != v for u, v, _ in edges)
    # rotating in place is an edge of the fully connected map
    assert m.cost(Node("a", 0), Node("a", 4)) == pytest.approx(0.2 * math.pi)


@pytest.mark.parametrize("k0,k1,gap", [(0, 1, math.pi / 4), (0, 7, math.pi / 4), (1, 6, 3 * math.pi / 4),
                                        (0, 4, math.pi), (2, 2, 0.0)])
def test_initial_cost_wraps_angles(k0, k1, gap):
    m = NavigationMap(REGIONS, n_orient=8, w=0.5)
    assert m.cost(Node("a", k0), Node("b", k1)) == pytest.approx(5.0 + 0.5 * gap)
    assert m.initial_cost(Node("b", k1), Node("a", k0)) == pytest.approx(5.0 + 0.5 * gap)


def test_start_node_edges_out_only():
    m = NavigationMap(REGIONS, n_orient=4, w=1.0, start=(0.0, -1.0, math.pi / 2))
    s = Node(START, 0)
    assert m.nodes[-1] == s and m.num_edges == 12 * 11 + 12
    assert m.cost(s, Node("a", 1)) == pytest.approx(1.0)
    assert m.cost(s, Node("a", 0)) == pytest.approx(1.0 + math.pi / 2)
    assert m.cost(Node("a", 0), s) == math.inf
    with pytest.raises(InvalidRequestError, match="into the start"):
        m.remove_edge(Node("a", 0), s)
    v = m.version
    m.move_start((3.0, 4.0, math.pi / 2))
    assert m.version == v + 1 and m.cost(s, Node("b", 1)) == pytest.approx(0.0)


def test_edits_versions_and_change_log():
    m = NavigationMap(REGIONS, n_orient=2, w=0.1)
    a0, b0, b1 = Node("a", 0), Node("b", 0), Node("b", 1)
    v0 = m.version
    assert m.set_cost(a0, b0, 7.0) == 2  # both directions
    assert m.version == v0 + 1 and m.cost(b0, a0) == 7.0
    assert m.set_cost(a0, b0, 7.0) == 0 and m.version == v0 + 1  # no change, no bump
    n = m.remove_edge("a", "b", symmetric=False)
    assert n == 4 and m.cost(a0, b1) == math.inf and m.cost(b1, a0) < math.inf
    assert m.is_removed(a0, b0) and not m.is_removed(b0, a0)
    ch = m.changes_since(v0)
    e = m.index[a0] * m.num_nodes + m.index[b0]
    assert ch[e] == (pytest.approx(5.0), math.inf)
    assert m.restore_edge("a", "b") == 4
    assert m.cost(a0, b0) == 7.0 and m.cost(a0, b1) == pytest.approx(5.0 + 0.1 * math.pi)
    # back to the costs of v0 except the explicitly set pair
    assert set(m.changes_since(v0)) == {e, m.index[b0] * m.num_nodes + m.index[a0]}
    assert m.changes_since(m.version) == {}
    # region-level set_cost adds the rotation term
    m.set_cost("a", "c", 1.5)
    assert m.cost(Node("a", 0), Node("c", 1)) == pytest.approx(1.5 + 0.1 * math.pi)


def test_the_change_log_is_bounded_and_exact_from_its_floor():
    """Thousands of edits: the log stays within its limit (plus one edit), ``changes_since``
    any version from ``log_floor`` on equals the difference of cost snapshots, and an older
    version answers ``None``."""
    import random

    rng = random.Random(5)
    m = NavigationMap(REGIONS, n_orient=2, w=0.1)
    m.log_limit = 64
    snaps = {m.version: list(m.costs)}
    names = sorted(REGIONS)
    for _ in range(2000):
        u, v = rng.sample(names, 2)
        r = rng.random()
        if r < 0.6:
            m.set_cost(u, v, rng.uniform(0.0, 9.0))
        elif r < 0.8:
            m.remove_edge(u, v)
        else:
            m.restore_edge(u, v)
        assert len(m._log) <= m.log_limit + 8  # an edit of two regions changes at most 8 edges here
        snaps[m.version] = list(m.costs)
    assert m.log_floor > 0
    for version, then in snaps.items():
        ch = m.changes_since(version)
        if version < m.log_floor:
            assert ch is None
            continue
        want = {e: (a, b) for e, (a, b) in enumerate(zip(then, m.costs)) if a != b}
        assert ch == want, version
    assert m.changes_since(m.log_floor - 1) is None and m.changes_since(m.version) == {}


def test_bad_inputs_are_named():
    with pytest.raises(InvalidRequestError, match="n_orient"):
        NavigationMap(REGIONS, n_orient=0)
    with pytest.raises(InvalidRequestError, match="w must be"):
        NavigationMap(REGIONS, w=0.0)
    with pytest.raises(InvalidRequestError, match="'b'.*centre"):
        NavigationMap({"a": (0, 0), "b": (1,)})
    with pytest.raises(InvalidRequestError, match="not finite"):
        NavigationMap({"a": (0, math.nan)})
    with pytest.raises(InvalidRequestError, match="start pose"):
        NavigationMap(REGIONS, start=(0, 0, 0, 0))
    m = NavigationMap(REGIONS)
    with pytest.raises(UnknownRegionError, match="'zz'") as err:
        m.remove_edge("a", "zz")
    assert err.value.names == ("zz",)
    with pytest.raises(InvalidRequestError, match="orientation index 9"):
        m.cost(Node("a", 9), Node("b", 0))
    for bad in (math.inf, math.nan, -1.0, "x"):
        with pytest.raises(InvalidRequestError, match="edge cost"):
            m.set_cost("a", "b", bad)
    with pytest.raises(InvalidRequestError, match="no start node"):
        m.move_start((0, 0))


def test_from_world_uses_start_and_regions():
    m = NavigationMap.from_world("office")
    assert m.regions == ("p1", "p2", "d1", "d2", "d3", "u1")
    assert m.num_nodes == 6 * 8 + 1 and m.start_pose == pytest.approx((3.2, 0.4, math.pi))
