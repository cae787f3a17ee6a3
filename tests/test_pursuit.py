"""Pursuit of the harmonic tree's path (``ExecutiveConfig.pursuit``): the look-ahead point on
the leg, pulled back where the line to it is not clear, the field where nothing ahead is clear,
and missions driven that way (tamp.executive, module doc "Pursuit")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navigation.world import World
from tamp.errors import TampError
from tamp.executive import PURSUIT_MARGIN, Executive, ExecutiveConfig
from tamp.run import run_mission

from .conftest import shared_world


def _world(obstacles=()) -> World:
    return World.from_dict({
        "name": "pursuit", "workspace": {"center": [2.0, 1.5], "width": 4.0, "height": 3.0, "s": 0.99},
        "obstacles": [{"center": list(c), "width": w, "height": h, "s": 0.9} for c, w, h in obstacles],
        "regions": {"a": {"center": [3.5, 2.5], "radius": 0.15}},
        "robot": {"radius": 0.1, "start": [0.5, 0.5, 0.0], "v_max": 0.5, "omega_max": 1.0},
        "lidar": {"range": 1.5, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10},
        "task": "F a"})


def _executive(obstacles=(), look=0.3, **kw) -> Executive:
    return Executive(_world(obstacles), known=True, config=ExecutiveConfig(pursuit=look, **kw))


def _leg(ex: Executive, *pts) -> None:
    ex.leg = tuple((float(x), float(y), 0.0) for x, y in pts)
    ex.wp = 1


def test_the_point_pursued_is_the_look_ahead_along_a_straight_leg():
    ex = _executive()
    _leg(ex, (0.5, 0.5), (1.5, 0.5), (3.0, 0.5))
    point, rest = ex._carrot(np.array([0.7, 0.55]))
    assert point == pytest.approx([1.0, 0.5])
    assert rest == pytest.approx(2.0)
    assert ex.wp == 1
    # past the first waypoint's segment: the next segment is the robot's
    point, rest = ex._carrot(np.array([1.6, 0.52]))
    assert ex.wp == 2
    assert point == pytest.approx([1.9, 0.5]) and rest == pytest.approx(1.1)


def test_the_point_pursued_rounds_a_corner_along_a_clear_line_and_stops_at_the_leg_end():
    ex = _executive()
    _leg(ex, (0.5, 0.5), (1.0, 0.5), (1.0, 0.7))
    point, rest = ex._carrot(np.array([0.9, 0.5]))
    assert point == pytest.approx([1.0, 0.7]) and rest == pytest.approx(0.0)  # the leg's end
    _leg(ex, (0.5, 0.5), (1.0, 0.5), (1.0, 2.5))
    point, rest = ex._carrot(np.array([0.9, 0.5]))
    assert point == pytest.approx([1.0, 0.7]) and rest == pytest.approx(1.8)


def test_a_corner_whose_chord_is_blocked_is_pursued_to_its_waypoint_and_a_blocked_way_falls_back_to_the_field():
    # an obstacle inside the turn: its inflated shape (radius 0.1 + margin) covers the chord
    # from (0.6, 0.5) to the look-ahead point (1.0, 0.9), not the leg's segments
    ex = _executive([((0.75, 0.8), 0.1, 0.1)], look=0.8)
    assert not ex._clear_line(np.array([0.6, 0.5]), np.array([1.0, 0.9]))
    _leg(ex, (0.2, 0.5), (1.0, 0.5), (1.0, 2.5))
    point, rest = ex._carrot(np.array([0.6, 0.5]))
    assert point == pytest.approx([1.0, 0.5]) and rest == pytest.approx(2.0)
    # an obstacle on the leg itself (an estimate grew over it): nothing ahead is clear
    ex = _executive([((1.2, 0.5), 0.1, 0.1)])
    _leg(ex, (0.5, 0.5), (2.0, 0.5), (3.0, 0.5))
    assert ex._carrot(np.array([0.9, 0.5])) is None
    # the margin: a line passing the inflated shape closer than PURSUIT_MARGIN is not clear
    ex = _executive([((1.2, 0.8), 0.2, 0.2)])
    inflated_edge = 0.8 - 0.1 - 0.1  # bottom face of the obstacle grown by the radius
    assert ex._clear_line(np.array([0.5, inflated_edge - 2 * PURSUIT_MARGIN]),
                          np.array([2.0, inflated_edge - 2 * PURSUIT_MARGIN]))
    assert not ex._clear_line(np.array([0.5, inflated_edge - 0.5 * PURSUIT_MARGIN]),
                              np.array([2.0, inflated_edge - 0.5 * PURSUIT_MARGIN]))


def test_a_point_ahead_whose_line_misses_the_inflated_obstacles_only_within_the_margin_is_pursued():
    """A passage narrower than the margin leaves beside the robot's offset from its path: the
    line to the point ahead on the robot's own segment passes an obstacle grown by the radius
    closer than ``PURSUIT_MARGIN`` but clear of it; the point is pursued (before the
    forty-third session the waypoint's field took over and crawled at the passage's
    entrance). Round a corner the same holds for the point ahead on the robot's segment, not
    for the look-ahead point beyond the corner."""
    ex = _executive([((1.3, 0.8), 0.8, 0.2)])
    y = 0.8 - 0.1 - 0.1 - 0.5 * PURSUIT_MARGIN  # half the margin below the inflated bottom face
    q = np.array([1.0, y])
    assert not ex._clear_line(q, np.array([1.3, y])) and ex._clear_line(q, np.array([1.3, y]), exact=True)
    _leg(ex, (0.5, y), (3.0, y))
    point, rest = ex._carrot(q)
    assert point == pytest.approx([1.3, y]) and rest == pytest.approx(1.7)
    # a corner ahead whose next segment runs into the obstacle: the chord is blocked, the
    # corner fails the margin, the point ahead on the segment is pursued by the inflated
    # obstacle alone
    _leg(ex, (0.5, y), (1.2, y), (1.2, y + 0.5))
    assert not ex._clear_line(q, np.array([1.2, y + 0.1]), exact=True)
    point, rest = ex._carrot(q)
    assert point == pytest.approx([1.2, y]) and rest == pytest.approx(0.5)
    assert ex.wp == 1
    # an obstacle over the way ahead (an estimate grew over the leg): nothing is clear
    ex = _executive([((1.3, 0.8), 0.8, 0.2), ((1.25, y), 0.05, 0.05)])
    _leg(ex, (0.5, y), (3.0, y))
    assert ex._carrot(q) is None


def test_pursuit_is_validated():
    with pytest.raises(TampError):
        ExecutiveConfig(pursuit=-0.1)
    with pytest.raises(TampError):
        ExecutiveConfig(pursuit=math.nan)
    for bad in (0.0, -0.5, math.pi / 2 + 1e-9, math.nan, math.inf, "wide", True, None):
        with pytest.raises(TampError, match="pursuit_gate"):
            ExecutiveConfig(pursuit_gate=bad)


@pytest.mark.parametrize("off", [50.0, 70.0, 85.0])
def test_the_pursuit_turns_on_the_spot_while_the_point_is_beyond_its_gate(off):
    """``pursuit_gate`` (60 degrees by default): the robot moves off only once the pursued point
    is within the gate of its heading; eq. 24a's own gate (``pi / 2``) drives off at up to 90
    degrees. Rate-limited mode (the executive's default), from rest."""
    assert ExecutiveConfig().pursuit_gate == pytest.approx(math.pi / 3)
    cmds = {}
    for gate in (math.pi / 3, math.pi / 2):
        ex = _executive(pursuit_gate=gate)
        assert ex.control.accel_max > 0
        _leg(ex, (0.5, 0.5), (3.0, 0.5))
        ex._pursuable = True
        cmds[gate] = [ex._command((0.5, 0.5, math.radians(off)))]
        assert ex._pursued
    v60, w60 = cmds[math.pi / 3][0]
    v90, w90 = cmds[math.pi / 2][0]
    assert w60 < 0 and w90 < 0  # turning towards the point either way
    assert v90 > 0.0
    if off > 60.0:
        assert v60 == 0.0
    else:
        assert 0.0 < v60 <= v90  # (both within the rate limit from rest here)


def _flips_per_metre(r: dict) -> float:
    """Sign flips of the executed turn rate between consecutive 0.1 s periods (both above
    0.05 rad/s) per metre: ``benchmarks.methods.chatter``."""
    P = np.asarray(r["trajectory"], dtype=float)
    w = np.arctan2(np.sin(np.diff(P[:, 2])), np.cos(np.diff(P[:, 2]))) / 0.1
    on = np.abs(w) > 0.05
    flips = int(np.count_nonzero(on[1:] & on[:-1] & (np.sign(w[1:]) != np.sign(w[:-1]))))
    return flips / r["distance"]


@pytest.mark.parametrize("name", ["simple", "office"])
def test_pursuit_drives_shared_missions_safely_with_less_than_half_the_fields_weaving(name):
    world = shared_world(name)
    pursued = run_mission(world, max_time=300, record=True)  # the default: pursuit
    assert ExecutiveConfig().pursuit > 0
    fields = run_mission(world, max_time=300, record=True, config=ExecutiveConfig(pursuit=0.0))
    for r in (pursued, fields):
        assert r["completed"] and r["collisions"] == 0 and r["bad_commands"] == 0, r["message"]
    # (measured on 46d72b1: simple 0.00 against 1.22, office 0.14 against 3.04 flips per metre)
    assert _flips_per_metre(pursued) < min(1.0, 0.5 * _flips_per_metre(fields))
