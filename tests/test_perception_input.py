"""Guarantee: bad sensor input is rejected or trimmed with a logged reason and a specific
exception type, and never changes the obstacle map."""

from __future__ import annotations

import json
import logging
import math

import numpy as np
import pytest

from navigation.errors import HarmonicTampError, PerceptionError
from perception import ObstacleMap, PerceptionConfig, PoseJumpError, ScanError, StampError, parse_points, parse_scan
from service.sim import Simulator

from .conftest import shared_world


@pytest.fixture()
def setup():
    world = shared_world("simple")
    sim = Simulator(world, seed=0)
    omap = ObstacleMap.from_world(world)
    return world, sim, omap


def _msgs(sim, stamp=0.0):
    return sim.scan_message(stamp=stamp), sim.pose_message(stamp=stamp)


def test_errors_belong_to_the_product_hierarchy():
    for cls in (ScanError, StampError, PoseJumpError):
        assert issubclass(cls, PerceptionError) and issubclass(cls, HarmonicTampError)
        assert issubclass(cls, ValueError)


def test_scan_points_are_world_frame_returns(setup):
    world, sim, _ = setup
    msg, pose = _msgs(sim)
    sc = parse_scan(msg, pose, beams=world.lidar.beams)
    expected = sim.scan_points(np.array(msg["ranges"]))
    hit = np.array(msg["ranges"]) < msg["range_max"]
    assert sc.hit.sum() == hit.sum() == len(sc.points)
    np.testing.assert_allclose(sc.points, expected, atol=1e-12)
    # JSON text and bytes are accepted too
    sc2 = parse_scan(json.dumps(msg), json.dumps(pose).encode())
    np.testing.assert_allclose(sc2.points, sc.points)


@pytest.mark.parametrize("bad", [float("nan"), -1.0])
def test_invalid_ranges_are_trimmed_and_logged(setup, caplog, bad):
    world, sim, omap = setup
    msg, pose = _msgs(sim)
    ranges = list(msg["ranges"])
    hit = [k for k, r in enumerate(ranges) if r < msg["range_max"]]
    for k in hit[:5]:
        ranges[k] = bad
    msg = dict(msg, ranges=ranges)
    with caplog.at_level(logging.INFO, logger="perception"):
        upd = omap.update_scan(msg, pose)
    assert upd.trimmed >= 5 and any("trimmed 5 invalid beam" in n for n in upd.notes)
    assert "trimmed 5 invalid beam" in caplog.text
    for sq in omap.obstacles():
        assert all(math.isfinite(v) for v in (*sq.center, sq.width, sq.height, sq.theta, sq.s))


def test_infinite_range_is_no_return(setup):
    world, sim, _ = setup
    msg, pose = _msgs(sim)
    msg = dict(msg, ranges=[math.inf] * len(msg["ranges"]))
    sc = parse_scan(msg, pose)
    assert len(sc.points) == 0 and not sc.hit.any() and sc.dropped == 0


def _snapshot(omap):
    return json.dumps(omap.to_message(stamp=0.0)), omap.last_stamp, omap.last_pose


@pytest.mark.parametrize("case, err, match", [
    ("empty", ScanError, "empty scan"),
    ("beams", ScanError, "expected 360 beams"),
    ("missing", ScanError, "angle_increment: missing field"),
    ("nonnumber", ScanError, "range_max: expected a number"),
    ("nanheader", ScanError, "angle_min: must be finite"),
    ("notjson", ScanError, "not JSON"),
    ("stale", StampError, "stale stamp"),
    ("future", StampError, "in the future"),
    ("skew", StampError, "does not match the pose stamp"),
    ("jump", PoseJumpError, "from the last accepted pose"),
    ("outside", PoseJumpError, "outside the workspace"),
    ("posenan", ScanError, "pose.x: must be finite"),
])
def test_bad_input_is_rejected_and_leaves_the_map_unchanged(setup, caplog, case, err, match):
    world, sim, omap = setup
    msg, pose = _msgs(sim, stamp=1.0)
    omap.update_scan(msg, pose)  # a first good scan: the map is not empty
    before = _snapshot(omap)
    now = None
    msg, pose = _msgs(sim, stamp=2.0)
    if case == "empty":
        msg = dict(msg, ranges=[])
    elif case == "beams":
        msg = dict(msg, ranges=msg["ranges"][:-1])
    elif case == "missing":
        msg = {k: v for k, v in msg.items() if k != "angle_increment"}
    elif case == "nonnumber":
        msg = dict(msg, range_max="far")
    elif case == "nanheader":
        msg = dict(msg, angle_min=float("nan"))
    elif case == "notjson":
        msg = "{not json"
    elif case == "stale":
        msg, pose = _msgs(sim, stamp=0.5)
    elif case == "future":
        now = 1.0  # stamp 2.0 leads by 1 s > max_future
    elif case == "skew":
        pose = dict(pose, stamp=2.5)
    elif case == "jump":
        pose = dict(pose, x=pose["x"] + 2.0)
    elif case == "outside":
        pose = dict(pose, x=-5.0)
    elif case == "posenan":
        pose = dict(pose, x=float("nan"))
    with caplog.at_level(logging.WARNING, logger="perception"):
        with pytest.raises(err, match=match):
            omap.update_scan(msg, pose, now=now)
    assert "rejected input" in caplog.text
    assert _snapshot(omap) == before


def test_points_messages(setup):
    world, sim, omap = setup
    msg = sim.points_message(stamp=0.0)
    stamp, pts, dropped = parse_points(msg)
    assert stamp == 0.0 and pts.shape == (len(msg["points"]), 2) and dropped == 0
    bad = dict(msg, points=msg["points"] + [[float("nan"), 1.0]])
    upd = omap.update_points(bad, sim.pose_message(stamp=0.0))
    assert upd.trimmed >= 1 and upd.changed
    pts = np.array(msg["points"])
    pts = pts[world.workspace.beta(pts) < -0.05]  # returns on the workspace boundary are dropped
    inside = np.zeros(len(pts), bool)
    for sq in omap.inflated():
        inside |= sq.beta(pts) <= 0
    assert len(pts) and inside.all()
    with pytest.raises(ScanError, match=r"expected shape \(N, 2\)"):
        omap.update_points({"stamp": 1.0, "points": [[1.0, 2.0, 3.0]]})
    with pytest.raises(ScanError, match="points.stamp: missing field"):
        omap.update_points({"points": []})


def test_config_rules_and_overrides():
    world = shared_world("office")
    cfg = PerceptionConfig.from_lidar(world.lidar)
    da = 2 * math.pi / 360
    assert cfg.link == pytest.approx(max(4 * 1.0 * da, 3 * 0.02))
    noisy = PerceptionConfig.from_lidar(world.lidar, noise_std=0.01)
    assert noisy.link == pytest.approx(cfg.link + 0.03)
    assert noisy.split_tol > cfg.split_tol and noisy.refit_tol > cfg.refit_tol
    assert PerceptionConfig.from_lidar(world.lidar, link=0.05).link == 0.05
    with pytest.raises(ScanError, match="unknown threshold"):
        PerceptionConfig.from_lidar(world.lidar, linkk=0.05)
    with pytest.raises(ScanError, match="link: must be > 0"):
        PerceptionConfig.from_lidar(world.lidar, link=-1.0)
    # the breakpoint grows with range
    assert cfg.breakpoint(1.0) > cfg.breakpoint(0.5) > 0


def test_deeply_nested_json_is_refused_not_a_crash():
    """Every JSON decoder of the project is perception.ingest.decode_object: too deep a nesting
    is a clear error for scans and for the simulator's cmd_vel alike."""
    from navigation import load_world
    from service.sim import CommandError, Simulator

    deep = "[" * 100_000 + "]" * 100_000
    with pytest.raises(ScanError, match="nested too deeply"):
        parse_points(deep)
    with pytest.raises(CommandError, match="nested too deeply"):
        Simulator(load_world("simple"), seed=0).apply_cmd_vel(deep)
