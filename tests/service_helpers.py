"""Helpers for the service tests: loopback Zenoh sessions on free ports, a node in a thread."""

from __future__ import annotations

import itertools
import json
import os
import socket
import threading
import time
from collections import deque
from contextlib import contextmanager

import zenoh

from service.node import NodeConfig, ServiceNode, zenoh_config

_count = itertools.count()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def unique_prefix(name: str) -> str:
    return f"test{os.getpid()}/{name}{next(_count)}"


def client(endpoint: str) -> zenoh.Session:
    """A peer session that connects to ``endpoint`` and listens nowhere."""
    return zenoh.open(zenoh_config(listen=[], connect=[endpoint]))


def wait_for(pred, timeout: float = 10.0, period: float = 0.02):
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        v = pred()
        if v:
            return v
        time.sleep(period)
    return pred()


class Recorder:
    """Subscribes to a key and keeps the decoded JSON payloads."""

    def __init__(self, session, key: str, n: int = 10000):
        self.items: deque = deque(maxlen=n)
        self._sub = session.declare_subscriber(key, lambda s: self.items.append(json.loads(s.payload.to_bytes())))

    @property
    def last(self):
        return self.items[-1] if self.items else None

    def close(self):
        self._sub.undeclare()


@contextmanager
def running_node(brain, *, rate: float = 20.0, watchdog: float = 1.0, status_period: float = 1.0,
                 telemetry=None):
    """A ServiceNode listening on a free loopback port, run in a thread; yields
    ``(node, client_session, prefix)``."""
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    prefix = unique_prefix("svc")
    cfg = NodeConfig(prefix=prefix, rate=rate, watchdog=watchdog, status_period=status_period, listen=(endpoint,))
    node = ServiceNode(brain, cfg, telemetry=telemetry)
    node.open()
    th = threading.Thread(target=node.run, name="service-node", daemon=True)
    th.start()
    cl = client(endpoint)
    try:
        # the node is reachable once its liveliness token is seen
        assert wait_for(lambda: any(r.ok for r in cl.liveliness().get(f"{prefix}/alive", timeout=1.0)), 10.0)
        yield node, cl, prefix
    finally:
        node.stop()
        th.join(10.0)
        node.close()
        cl.close()
        assert not th.is_alive()


def ask(session, prefix: str, payload, timeout: float = 20.0) -> tuple[bool, dict]:
    """Send a task query; ``(ok_reply, decoded JSON)``."""
    if not isinstance(payload, (bytes, str)):
        payload = json.dumps(payload)
    replies = list(session.get(f"{prefix}/task", payload=payload, timeout=timeout))
    assert len(replies) == 1, replies
    r = replies[0]
    if r.ok is not None:
        return True, json.loads(r.ok.payload.to_bytes())
    return False, json.loads(r.err.payload.to_bytes())


class Feeder:
    """Drives a real Simulator from the test thread and publishes its pose and scan on the bus."""

    def __init__(self, session, prefix: str, sim):
        self.sim = sim
        self.pose = session.declare_publisher(f"{prefix}/pose")
        self.scan = session.declare_publisher(f"{prefix}/scan")
        self.points = session.declare_publisher(f"{prefix}/points")

    def tick(self):
        self.sim.step()
        self.pose.put(json.dumps(self.sim.pose_message()))
        self.scan.put(json.dumps(self.sim.scan_message()))

    def run(self, seconds: float, period: float = 0.05):
        t_end = time.monotonic() + seconds
        while time.monotonic() < t_end:
            self.tick()
            time.sleep(period)

    def close(self):
        for p in (self.pose, self.scan, self.points):
            p.undeclare()
