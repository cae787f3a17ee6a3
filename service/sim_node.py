"""The simulator as a separate bus participant (``tamp-service demo`` runs it in a child process).

:class:`SimNode` wraps a :class:`service.sim.Simulator` and speaks only Zenoh: it subscribes to
``<prefix>/cmd_vel`` and publishes ``<prefix>/pose`` every step and ``<prefix>/scan`` (or
``<prefix>/points`` with ``points=True``) at the lidar rate, all stamped with simulated time.
It also publishes ``<prefix>/sim/metrics`` (not part of the contract: the simulator's
:class:`~service.sim.SimMetrics` plus the true pose, once a second) for the demo's summary.

Steps run every ``dt / speed`` wall seconds. A malformed ``cmd_vel`` is dropped (logged). A
valid command is executed for at most ``cmd_timeout`` *simulated* seconds (default 0.1 s, the
controller's safety horizon ``ControllerConfig.safety_horizon``); with no newer command by then
the robot stops, as a real base's own command watchdog does. The controller's speed limit
``v <= clearance / safety_horizon`` is only a no-contact certificate when no command runs longer
than the horizon: a service that falls behind (slow ticks, a sped-up simulation) makes the robot
wait instead of driving on a stale command.

Pacing (``SimNodeConfig.pace``, default on, only with ``speed > 1``): a sped-up simulation
must not outrun the service it tests. After publishing a step's pose the node waits for a
``cmd_vel`` answering it (one with ``pose_stamp`` at least that pose's stamp, or without
``pose_stamp``, received after the pose went out) until the next step is due; when the service
is slower than that, the node waits on for the answer up to ``dt`` wall seconds after the step
started (real time), then steps anyway. ``speed`` is therefore an upper bound: a service that
keeps up runs at ``speed``, one that falls behind slows the simulation down, never below real
time. Without it, a loaded machine at ``--speed 4`` let the robot drive on commands computed for
poses one or two steps old, and on maps that had not yet taken the latest scans (the
controller's certificate holds for the pose and obstacles it was given): the office demo then
touched obstacles in some runs (260 and 2157 blocked steps in 2 of 6 runs at speeds 4 and 6,
with load average 5-7; docs/service.md). ``waited`` (also in the metrics message) counts the steps that waited
past their schedule.

Command line (used by the demo)::

    python -m service.sim_node --world simple --connect tcp/127.0.0.1:7447 [--speed 1] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import signal
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass

import zenoh

from navigation._argtypes import positive, seed
from perception.ingest import decode_object

from .errors import ServiceError
from .messages import encode
from .node import zenoh_config
from .sim import CommandError, Simulator

__all__ = ["SimNode", "SimNodeConfig", "main"]

log = logging.getLogger("service.sim_node")
_JSON = zenoh.Encoding.APPLICATION_JSON


@dataclass(frozen=True, slots=True)
class SimNodeConfig:
    """Settings of a :class:`SimNode`; ``speed`` is simulated seconds per wall second."""

    robot: str = "robot"
    prefix: str | None = None
    speed: float = 1.0
    points: bool = False
    cmd_timeout: float = 0.1
    metrics_period: float = 1.0
    pace: bool = True
    listen: tuple[str, ...] | None = ()
    connect: tuple[str, ...] | None = None
    zenoh_config: str | None = None

    def __post_init__(self):
        for name in ("speed", "cmd_timeout", "metrics_period"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0 or v == float("inf"):
                raise ServiceError(f"SimNodeConfig.{name} must be a finite number > 0, got {v!r}")

    @property
    def key_prefix(self) -> str:
        return self.prefix if self.prefix is not None else f"tamp/{self.robot}"

    def key(self, name: str) -> str:
        return f"{self.key_prefix}/{name}"


class SimNode:
    """A :class:`Simulator` on the bus; use with ``with`` and :meth:`run`."""

    def __init__(self, sim: Simulator, config: SimNodeConfig | None = None, *, session=None):
        self.sim = sim
        self.config = config or SimNodeConfig()
        self._own = session is None
        self._session = session
        self._cmd: deque = deque(maxlen=1)
        self._answered = threading.Event()  # a cmd_vel for the last published pose arrived
        self._pose_stamp = -math.inf  # stamp of the last published pose
        self.waited = 0  # steps that waited past their schedule for the service (pacing)
        self._stop = threading.Event()
        self._last_cmd_t: float | None = None  # simulated time the current command was applied
        self.bad_commands = 0
        rate = float(sim.lidar.rate_hz)
        self._scan_every = max(1, round(1.0 / (sim.dt * rate)))

    def __enter__(self) -> "SimNode":
        c = self.config
        if self._session is None:
            self._session = zenoh.open(zenoh_config(listen=c.listen, connect=c.connect, config_file=c.zenoh_config))
        s = self._session
        self._sub = s.declare_subscriber(c.key("cmd_vel"), self._on_cmd)
        self._pub_pose = s.declare_publisher(c.key("pose"), encoding=_JSON)
        self._pub_scan = s.declare_publisher(c.key("points" if c.points else "scan"), encoding=_JSON)
        self._pub_metrics = s.declare_publisher(c.key("sim/metrics"), encoding=_JSON)
        return self

    def __exit__(self, *exc) -> None:
        for d in (self._sub, self._pub_pose, self._pub_scan, self._pub_metrics):
            try:
                d.undeclare()
            except Exception:
                pass
        if self._own:
            self._session.close()

    def _on_cmd(self, sample) -> None:  # Zenoh thread: enqueue, and note an answer (pacing)
        payload = sample.payload.to_bytes()
        try:  # decoded once, here; step() validates the fields
            message = decode_object(payload, ValueError)
        except Exception:
            self._cmd.append((payload, time.monotonic()))
            return  # malformed: step() drops it with the decoder's reason
        self._cmd.append((message, time.monotonic()))
        stamp = message.get("pose_stamp")
        if stamp is None or (isinstance(stamp, (int, float)) and stamp >= self._pose_stamp - 1e-9):
            self._answered.set()

    def stop(self) -> None:
        self._stop.set()
        self._answered.set()

    def metrics(self) -> dict:
        m = self.sim.metrics.to_dict()
        m.update(pose=list(self.sim.pose), bad_commands=self.bad_commands, waited=self.waited)
        return m

    def step(self) -> None:
        """Apply the newest command, advance one ``dt``, publish pose (and scan)."""
        sim = self.sim
        if self._cmd:
            payload, rx = self._cmd.pop()
            try:
                sim.apply_cmd_vel(payload)
                self._last_cmd_t = sim.time
            except CommandError as err:
                self.bad_commands += 1
                log.warning("cmd_vel dropped: %s", err)
        if self._last_cmd_t is not None and sim.time - self._last_cmd_t >= self.config.cmd_timeout - 1e-9:
            sim.set_command(0.0, 0.0)
            self._last_cmd_t = None
        sim.step()
        self._answered.clear()
        self._pose_stamp = sim.time
        self._pub_pose.put(encode(sim.pose_message()))
        if sim.metrics.steps % self._scan_every == 0:
            msg = sim.points_message() if self.config.points else sim.scan_message()
            self._pub_scan.put(encode(msg))

    def run(self, duration: float | None = None) -> None:
        """Step in real time (times ``speed``) until :meth:`stop` or ``duration`` simulated s."""
        period = self.sim.dt / self.config.speed
        nxt = time.monotonic()
        last_metrics = -1e9
        t_end = None if duration is None else self.sim.time + duration
        pace = self.config.pace and self.config.speed > 1.0
        while not self._stop.is_set() and (t_end is None or self.sim.time < t_end - 1e-9):
            started = time.monotonic()
            self.step()
            now = time.monotonic()
            if now - last_metrics >= self.config.metrics_period:
                self._pub_metrics.put(encode(self.metrics()))
                last_metrics = now
            nxt += period
            if nxt < now:
                nxt = now
            self._stop.wait(nxt - now)
            if pace and not self._answered.is_set():
                # the service has not answered this pose yet: wait, at most until real time
                self._answered.wait(max(0.0, started + self.sim.dt - time.monotonic()))
                self.waited += 1
                nxt = max(nxt, time.monotonic())
        self._pub_metrics.put(encode(self.metrics()))


def main(argv=None) -> int:
    """``python -m service.sim_node``: the simulator alone on the bus (exit 0 on SIGINT/SIGTERM)."""
    import navigation

    p = argparse.ArgumentParser(prog="python -m service.sim_node", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("--world", default="office", help="world file or built-in name")
    p.add_argument("--robot", default="robot", help="robot id (key prefix tamp/<robot>)")
    p.add_argument("--prefix", default=None, help="key prefix (overrides --robot)")
    p.add_argument("--connect", action="append", default=None, help="Zenoh endpoint to connect to (repeatable)")
    p.add_argument("--listen", action="append", default=None, help="Zenoh endpoint to listen on (repeatable)")
    p.add_argument("--zenoh-config", default=None, help="Zenoh JSON5 configuration file")
    p.add_argument("--speed", type=positive, default=1.0, help="simulated seconds per wall second")
    p.add_argument("--seed", type=seed, default=0, help="lidar noise seed (>= 0)")
    p.add_argument("--points", action="store_true", help="publish 'points' instead of 'scan'")
    p.add_argument("--duration", type=positive, default=None, help="stop after this many simulated seconds")
    a = p.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="sim: %(message)s")
    try:
        world = navigation.load_world(a.world)
        cfg = SimNodeConfig(robot=a.robot, prefix=a.prefix, speed=a.speed, points=a.points,
                            listen=tuple(a.listen or ()), connect=tuple(a.connect) if a.connect else None,
                            zenoh_config=a.zenoh_config)
        node = SimNode(Simulator(world, seed=a.seed), cfg)
    except Exception as err:  # HarmonicTampError and file errors: one line, exit 2
        print(f"error: {err}", file=sys.stderr)
        return 2
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: node.stop())
    with node:
        node.run(a.duration)
    print(json.dumps(node.metrics()), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
