"""Commands for stale poses (issue 7): the node recomputes a slow tick's command on the newest
pose (``NodeConfig.refresh``), and a sped-up simulator waits for the service's answer to each
pose (``SimNodeConfig.pace``). No bus: the nodes' inboxes and publishers are driven directly."""

from __future__ import annotations

import json
import time

import pytest

from service.brain import BrainTick
from service.messages import encode
from service.errors import ServiceError
from service.node import NodeConfig, ServiceNode
from service.sim import Simulator
from service.sim_node import SimNode, SimNodeConfig

from .conftest import shared_world


class _Recorder:
    """Stands in for a publisher or the node's outputs: keeps what was put."""

    def __init__(self):
        self.out = []

    def put(self, payload):
        self.out.append(json.loads(payload))


class _SlowBrain:
    """A brain whose tick with a scan lets the robot move on meanwhile: a newer pose arrives in
    the node's inbox during that tick. The command is the pose's x, to see which pose it used."""

    def __init__(self, node, newer: bytes):
        self.node, self.newer, self.calls = node, newer, []

    def tick(self, pose, *, scan=None, scan_pose=None, points=None, now):
        self.calls.append((pose.stamp, scan is not None))
        if scan is not None and self.newer is not None:
            self.node._inbox["pose"].append((self.newer, time.monotonic()))
        return BrainTick(v=0.1, omega=pose.x, status={"state": "executing", "task": None, "plan": None,
                                                      "target": None, "waypoint": None, "obstacles": 0,
                                                      "message": ""})

    def status(self):
        return {}

    def obstacles(self):
        return []


def _node(refresh: bool):
    sim = Simulator(shared_world("simple"), seed=0)
    node = ServiceNode(None, NodeConfig(refresh=refresh))
    cmds = []
    node._publish_cmd = lambda v, w, **extra: cmds.append((v, w, extra))
    node._publish_status = lambda st, force=False: None
    node._publish_obstacles = lambda: None
    node._t0 = time.monotonic()
    node._inbox["pose"].append((encode(sim.pose_message()), node._t0))
    node._inbox["scan"].append((encode(sim.scan_message()), node._t0))
    x0 = sim.pose[0]
    sim.step((0.5, 0.0))
    newer = encode(sim.pose_message())
    node.brain = _SlowBrain(node, newer)
    return node, sim, cmds, x0


@pytest.mark.parametrize("refresh", [True, False])
def test_a_slow_ticks_command_is_recomputed_on_the_newest_pose(refresh):
    node, sim, cmds, x0 = _node(refresh)
    node.step()
    (v, w, extra), = cmds
    x1 = sim.pose[0]
    if refresh:
        # ticked again without the scan, on the pose that arrived meanwhile; that command is sent
        assert node.brain.calls == [(0.0, True), (sim.time, False)]
        assert extra["pose_stamp"] == sim.time and w == pytest.approx(x1) and node.stats.refreshed == 1
    else:
        assert node.brain.calls == [(0.0, True)]
        assert extra["pose_stamp"] == 0.0 and w == pytest.approx(x0) and node.stats.refreshed == 0
    assert x0 != x1


def _sim_node(pace: bool, answer: bool) -> SimNode:
    node = SimNode(Simulator(shared_world("simple"), seed=0), SimNodeConfig(speed=50.0, pace=pace))
    node._pub_scan, node._pub_metrics = _Recorder(), _Recorder()

    class _Pose(_Recorder):
        def put(self, payload):
            super().put(payload)
            if answer:  # a service that answers every pose at once
                stamp = json.loads(payload)["stamp"]
                node._on_cmd(type("S", (), {"payload": type("P", (), {"to_bytes": lambda self: json.dumps(
                    {"stamp": 0.0, "v": 0.0, "omega": 0.0, "pose_stamp": stamp}).encode()})()})())

    node._pub_pose = _Pose()
    return node


@pytest.mark.parametrize("pace, answer, waits", [(True, False, 5), (True, True, 0), (False, False, 0)])
def test_a_paced_simulator_waits_for_the_answer_to_each_pose(pace, answer, waits):
    """Five steps at speed 50 without answers wait past their schedule each time (real-time
    pace at worst); answered at once, or without pacing, none waits."""
    node = _sim_node(pace, answer)
    node.run(duration=0.5)
    assert node.sim.time == pytest.approx(0.5)
    assert node.waited == waits
    assert node.metrics()["waited"] == waits


def _sample(payload: bytes):
    return type("S", (), {"payload": type("P", (), {"to_bytes": lambda self: payload})()})()


@pytest.mark.parametrize("payload, held, bad, answers", [
    (json.dumps({"stamp": 0.0, "v": 0.2, "omega": -0.3, "pose_stamp": 0.0}).encode(), (0.2, -0.3), 0, True),
    (b"\xff\xfe garbage", (0.0, 0.0), 1, False),
    (b"{not json", (0.0, 0.0), 1, False),
    (b"[1, 2]", (0.0, 0.0), 1, False),
    # a JSON object answers the pose (pacing) even when its fields are then refused
    (json.dumps({"stamp": 0.0, "v": float("nan"), "omega": 0.0}).encode(), (0.0, 0.0), 1, True),
])
def test_the_simulator_node_applies_a_decoded_cmd_vel_and_drops_a_malformed_one(payload, held, bad, answers):
    """``_on_cmd`` decodes a payload once; ``step`` applies it, or drops and counts it."""
    node = _sim_node(pace=False, answer=False)
    node._on_cmd(_sample(payload))
    assert node._answered.is_set() == answers
    node.step()
    assert node.bad_commands == bad
    assert node.sim.command == pytest.approx(held)


# ----------------------------------------------------------- a scan that arrives before its pose
class _PairBrain:
    """Records what each call integrated: ``("tick", pose stamp, sensor stamp, sensor pose
    stamp)`` and ``("observe", ...)`` (when ``observing``)."""

    def __init__(self, observing: bool):
        self.calls = []
        if observing:
            self.observe = self._observe

    def tick(self, pose, *, scan=None, scan_pose=None, points=None, now):
        msg = scan if scan is not None else points
        self.calls.append(("tick", pose.stamp, None if msg is None else msg.stamp,
                           None if scan_pose is None else scan_pose.stamp))
        return BrainTick(v=0.0, omega=0.0, status={"state": "executing", "task": None, "plan": None, "target": None,
                                                   "waypoint": None, "obstacles": 0, "message": ""})

    def _observe(self, pose, *, scan=None, points=None, now):
        self.calls.append(("observe", now, (scan if scan is not None else points).stamp, pose.stamp))
        return False

    def status(self):
        return {}

    def obstacles(self):
        return []


def _pair_node(observing: bool = True, pair_wait: float = 0.1):
    node = ServiceNode(_PairBrain(observing), NodeConfig(pair_wait=pair_wait))
    node._publish_cmd = lambda v, w, **extra: None
    node._publish_status = lambda st, force=False: None
    node._publish_obstacles = lambda: None
    node._t0 = time.monotonic()
    sim = Simulator(shared_world("simple"), seed=0)

    def put(key):
        node._inbox[key].append((encode(sim.pose_message() if key == "pose" else sim.scan_message()), time.monotonic()))
    return node, sim, put


def test_a_scan_newer_than_every_pose_waits_for_its_pose_and_a_pose_wakes_the_loop():
    node, sim, put = _pair_node()
    put("pose"), put("scan")
    node.step()
    sim.step((0.3, 0.0))
    put("scan")  # its pose is late
    node.step()
    assert node.stats.held == 1 and node._await_pose
    node._wake.clear()
    node._enqueue("pose")(_sample(encode(sim.pose_message())))  # the pose arrives: the loop wakes
    assert node._wake.is_set()
    node.step()
    t = sim.time
    assert node.brain.calls == [("tick", 0.0, 0.0, 0.0), ("tick", 0.0, None, None), ("tick", t, t, t)]
    assert not node._await_pose and node.stats.unpaired == 0


@pytest.mark.parametrize("observing", [True, False])
def test_every_ready_sensor_message_is_integrated_oldest_first_none_superseded(observing):
    """A held scan and a newer one ready in the same period: the older through ``observe`` (or
    a tick of its own without it), the newer by the tick, each at the pose of its stamp."""
    node, sim, put = _pair_node(observing)
    put("pose"), put("scan")
    node.step()
    sim.step((0.3, 0.0))
    put("scan")
    node.step()  # held
    t1 = sim.time
    put("pose")
    sim.step((0.3, 0.0))
    put("pose"), put("scan")
    node.step()
    t2 = sim.time
    older = ("observe", t2, t1, t1) if observing else ("tick", t2, t1, t1)
    assert node.brain.calls[2:] == [older, ("tick", t2, t2, t2)]


def test_a_scan_whose_pose_does_not_come_is_integrated_at_the_nearest_pose_after_pair_wait():
    node, sim, put = _pair_node(pair_wait=0.05)
    put("pose")
    sim.step((0.3, 0.0))
    put("scan")
    node.step()
    assert node.brain.calls == [("tick", 0.0, None, None)] and node.stats.held == 1
    time.sleep(0.06)
    node.step()
    assert node.brain.calls[1] == ("tick", 0.0, sim.time, 0.0) and node.stats.unpaired == 1


def test_pair_wait_is_validated():
    with pytest.raises(ServiceError, match="pair_wait"):
        NodeConfig(pair_wait=-1.0)
    with pytest.raises(ServiceError, match="pair_wait"):
        NodeConfig(pair_wait=float("nan"))
