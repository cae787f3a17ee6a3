"""The service over real Zenoh sessions on loopback: task replies, bad input, watchdog, presence.

Each test opens its own node on a free port with a unique key prefix; a second session
connects to it over TCP, as a robot or an operator would.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time

import numpy as np
import pytest
from zenoh.ext import HistoryConfig, declare_advanced_subscriber

import navigation
from service.brain import ExecutiveBrain
from service.sim import Simulator

from .conftest import world_file
from .service_helpers import Feeder, Recorder, ask, running_node, wait_for


@pytest.fixture
def simple():
    return navigation.load_world(world_file("simple"))


def test_task_replies_follow_the_contract_and_refusals_keep_the_mission(simple):
    brain = ExecutiveBrain(simple, "F a & F b")
    with running_node(brain) as (node, cl, prefix):
        ok, rep = ask(cl, prefix, {"formula": "F b & F c", "mode": "replace"})
        assert ok and rep["ok"] is True and rep["task_id"] and rep["plan"]["prefix"], rep
        accepted = brain.status()["task"]
        cases = [
            ({"formula": "F (a &", "mode": "replace"}, "parse_error"),
            ({"formula": "F zz"}, "unknown_region"),
            ({"formula": "F a & G !a"}, "unsatisfiable"),
            ({"formula": "F a", "mode": "sometimes"}, "invalid_request"),
            ([1, 2, 3], "invalid_request"),
            ({"task": "F a"}, "invalid_request"),
            (b"\xff\xfe garbage", "invalid_request"),
            # a run-time region on a known obstacle (simple.json knows all of them)
            ({"formula": "F a", "regions": {"d": {"center": [1.0, 1.5], "radius": 0.1}}}, "invalid_request"),
        ]
        for payload, code in cases:
            ok, rep = ask(cl, prefix, payload)
            assert not ok, (payload, rep)
            assert rep["ok"] is False and rep["error"]["code"] == code, (payload, rep)
            assert isinstance(rep["error"]["message"], str) and rep["error"]["message"]
            assert brain.status()["task"] == accepted
        ok, rep = ask(cl, prefix, {"formula": "F a", "mode": "urgent"})
        assert ok, rep
        assert wait_for(lambda: node.status and node.status["task"] == brain.status()["task"])


def _inject_everywhere(cl, prefix, sim, feed):
    """Bad payloads on every input key, one key at a time with valid data in between; returns
    how many were sent."""
    good = {"pose": sim.pose_message(), "scan": sim.scan_message(),
            "points": {"stamp": sim.time, "points": [[1.0, 1.0], [1.1, 1.0]]}}
    sent = 0
    for key, msg in good.items():
        bad = [b"\xff\x00\x13garbage", b"{not json", b"[]", json.dumps({"stamp": 1.0}).encode()]
        for field, value in msg.items():
            if isinstance(value, (int, float)):
                for lit in ("NaN", "Infinity", "-Infinity"):
                    bad.append(json.dumps(dict(msg, **{field: 98765.25})).replace("98765.25", lit).encode())
        if key == "points":
            bad.append(json.dumps(dict(msg, points=[[1.0, 98765.25]])).replace("98765.25", "NaN").encode())
        for b in bad:
            cl.put(f"{prefix}/{key}", b)
            sent += 1
        feed.run(0.3)
    return sent


def test_bad_input_on_every_key_is_dropped_with_a_warning_and_no_state_change(simple):
    brain = ExecutiveBrain(simple, "F a & F b")
    sim = Simulator(simple, seed=0)
    with running_node(brain, rate=20.0, watchdog=2.0) as (node, cl, prefix):
        status = Recorder(cl, f"{prefix}/status")
        feed = Feeder(cl, prefix, sim)
        feed.run(1.0)
        assert wait_for(lambda: status.last and status.last["state"] == "executing", 5.0), status.last
        n0 = len(status.items)
        sent = _inject_everywhere(cl, prefix, sim, feed)
        feed.run(0.6)
        # duplicated and out-of-order stamps on pose and scan
        for key, msg in (("pose", sim.pose_message()), ("scan", sim.scan_message())):
            cl.put(f"{prefix}/{key}", json.dumps(msg))
            cl.put(f"{prefix}/{key}", json.dumps(dict(msg, stamp=msg["stamp"] - 5.0)))
        feed.run(0.6)
        after = list(status.items)[n0:]
        assert after and all(s["state"] == "executing" for s in after), [s["state"] for s in after]
        warnings = [s["message"] for s in after if s["message"].startswith("warning:")]
        assert warnings, "no warning reached status.message"
        text = " | ".join(warnings)
        for key in ("pose", "scan", "points"):
            assert f"{key}:" in text
        assert "duplicated" in text and "out of order" in text
        assert after[-1]["warnings"] >= sent + 2
        assert sum(node.stats.dropped.values()) >= sent + 2
        feed.close()
        status.close()


def test_watchdog_stops_the_robot_and_recovers(simple):
    # the fed simulator does not move the robot: start it facing its first waypoint (south,
    # towards ``a``) so that the executive's first command drives (v > 0) rather than turns
    x, y, _ = simple.robot.start
    world = dataclasses.replace(simple, robot=dataclasses.replace(simple.robot, start=(x, y, -math.pi / 2)))
    brain = ExecutiveBrain(world, "F a & F b")
    sim = Simulator(world, seed=0)
    with running_node(brain, rate=20.0, watchdog=0.5) as (node, cl, prefix):
        status = Recorder(cl, f"{prefix}/status")
        cmd = Recorder(cl, f"{prefix}/cmd_vel")
        feed = Feeder(cl, prefix, sim)
        feed.run(1.0)
        assert wait_for(lambda: status.last and status.last["state"] == "executing", 5.0)
        assert wait_for(lambda: cmd.last and cmd.last["v"] > 0, 3.0)
        time.sleep(1.0)  # sensors silent
        assert status.last["state"] == "blocked" and "no fresh pose" in status.last["message"]
        assert cmd.last["v"] == 0.0 and cmd.last["omega"] == 0.0
        feed.run(0.6)
        assert wait_for(lambda: status.last["state"] == "executing", 3.0), status.last
        assert wait_for(lambda: cmd.last["v"] != 0.0, 3.0)
        feed.close()
        cmd.close()
        status.close()


def test_liveliness_token_and_latched_status(simple):
    brain = ExecutiveBrain(simple, "F a")
    with running_node(brain, status_period=0.2) as (node, cl, prefix):
        got = []
        sub = declare_advanced_subscriber(cl, f"{prefix}/status", handler=lambda s: got.append(json.loads(
            s.payload.to_bytes())), history=HistoryConfig(detect_late_publishers=True))
        assert wait_for(lambda: got, 5.0)
        assert {"stamp", "state", "task", "plan", "target", "waypoint", "obstacles", "message"} <= set(got[0])
        # published at least once a second even when nothing changes
        n = len(got)
        time.sleep(1.1)
        assert len(got) >= n + 2
        sub.undeclare()
        alive = list(cl.liveliness().get(f"{prefix}/alive", timeout=2.0))
        assert any(r.ok for r in alive)
        node.stop()
        node.close()
        assert wait_for(lambda: not any(r.ok for r in cl.liveliness().get(f"{prefix}/alive", timeout=1.0)), 5.0)


def test_task_with_new_regions_is_served_over_the_bus_and_refused_regions_change_nothing(simple):
    brain = ExecutiveBrain(simple, "F a & F b")
    sim = Simulator(simple, seed=0)
    d = {"center": [2.0, 0.4], "radius": 0.15}
    with running_node(brain, rate=20.0, watchdog=2.0) as (node, cl, prefix):
        status = Recorder(cl, f"{prefix}/status")
        cmds = Recorder(cl, f"{prefix}/cmd_vel")
        pose = cl.declare_publisher(f"{prefix}/pose")
        scan = cl.declare_publisher(f"{prefix}/scan")

        def drive(seconds, until=lambda: False):
            """Closed loop over the bus: the simulator executes the latest cmd_vel."""
            t_end = time.monotonic() + seconds
            while time.monotonic() < t_end and not until():
                c = cmds.last
                sim.step((c["v"], c["omega"]) if c else (0.0, 0.0))
                pose.put(json.dumps(sim.pose_message()))
                scan.put(json.dumps(sim.scan_message()))
                time.sleep(0.05)

        drive(1.0)
        assert wait_for(lambda: status.last and status.last["state"] == "executing", 5.0), status.last
        # refused: each names the region and the rule; the mission and the regions stay
        accepted = brain.status()["task"]
        for regions, rule in (({"d": {"center": [3.9, 1.5], "radius": 0.15}}, "workspace"),
                              ({"d": {"center": [1.0, 1.5], "radius": 0.1}}, "free_space"),
                              ({"d": {"center": [0.7, 0.5], "radius": 0.1}}, "disjoint")):
            ok, rep = ask(cl, prefix, {"formula": "F d", "mode": "urgent", "regions": regions})
            assert not ok and rep["error"]["code"] == "invalid_request", rep
            msg = rep["error"]["message"]
            assert msg.startswith("regions.d:") and f"[rule: {rule}]" in msg, msg
            assert brain.status()["task"] == accepted and "d" not in brain.regions()
        # accepted: the new region is served first, then the mission goes on
        ok, rep = ask(cl, prefix, {"formula": "F d", "mode": "urgent", "regions": {"d": d}})
        assert ok and rep["plan"]["urgent"] == ["d"], rep
        assert "d" in brain.regions()
        assert wait_for(lambda: status.last["target"] == "d", 5.0), status.last
        drive(40.0, until=lambda: "d" in brain.executive.visited)
        assert brain.executive.visited[:1] == ["d"], brain.executive.visited
        assert not sim.metrics.collisions
        pose.undeclare()
        scan.undeclare()
        cmds.close()
        status.close()


def test_obstacles_key_carries_the_estimate_as_squircles_a_world_file_reads():
    """``<prefix>/obstacles`` (FORMATS.md): ``{"stamp", "obstacles": [squircle, ...]}`` on
    change. Every squircle loads with the world-file reader and the estimate covers what the
    lidar has seen from the start (no test subscribed to this key before)."""
    world = navigation.load_world(world_file("office"))
    brain = ExecutiveBrain(world, "F d1")
    sim = Simulator(world, seed=0)
    with running_node(brain, rate=20.0, watchdog=2.0) as (node, cl, prefix):
        obs = Recorder(cl, f"{prefix}/obstacles")
        feed = Feeder(cl, prefix, sim)
        feed.run(1.5)
        assert wait_for(lambda: obs.last, 5.0)
        msg = obs.last
        feed.close()
        obs.close()
    assert set(msg) == {"stamp", "obstacles"} and math.isfinite(msg["stamp"])
    squircles = [navigation.Squircle.from_dict(o) for o in msg["obstacles"]]
    assert len(squircles) == len(brain._ex.obstacles) > 0
    # the lidar's returns off the workspace boundary all lie on or inside the estimate
    hits = sim.scan_points()
    hits = hits[np.abs(world.workspace.distance(hits)) > 0.02]
    assert len(hits) > 50
    nearest = np.min([sq.distance(hits) for sq in squircles], axis=0)
    assert np.all(nearest <= 0.02), np.sort(nearest)[-5:]
