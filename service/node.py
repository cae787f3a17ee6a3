"""The bus adapter: one Zenoh session, the keys of the bus contract, one control loop.

:class:`ServiceNode` (the one stateful object of the service layer) owns the Zenoh session and
the optional Rerun telemetry. Zenoh callbacks only append raw payloads to bounded per-key
queues; :meth:`ServiceNode.run` is the control loop: at ``rate`` Hz it drains the queues,
validates every message (:mod:`service.messages`), answers queued ``task`` queries, applies the
watchdog, ticks the :class:`~service.brain.Brain` and publishes.

Keys under ``prefix`` (default ``tamp/<robot>``), FORMATS.md "Bus contract (Zenoh)":

========== ========== ==================================================================
key        direction  here
========== ========== ==================================================================
scan       in         validated, paired with the received pose nearest its stamp (see
                      "Sensor messages and their poses")
points     in         validated (all coordinates finite), paired like ``scan``
pose       in         validated; the latest is the robot pose
cmd_vel    out        every tick; optional extra fields ``pose_stamp``, ``scan_stamp``
                      (stamps of the inputs the command was computed from)
status     out        latched (advanced publisher, cache of 1) on change and every
                      ``status_period`` s; optional extra field ``warnings`` (count)
obstacles  out        latched, on change
task       queryable  replies from the control thread between ticks
alive      token      while the node runs
========== ========== ==================================================================

Bad input (garbage bytes, wrong JSON, missing fields, NaN/inf, stamps not newer than the last
one on the same key) is dropped; the reason goes to ``status.message`` as ``"warning: ..."``
and the brain never sees it, so the state is unchanged. Output stamps are this process's wall
clock (``time.time()``); the brain's ``now`` is the robot clock (the latest pose stamp).

Watchdog: when no valid pose, or no valid scan/points, arrived for ``watchdog`` seconds (wall
clock, counted from the start as well), the node publishes zero velocity and state ``blocked``
with the reason, without ticking the brain; when both are fresh again it resumes.

Sensor messages and their poses: a scan (or points message) is integrated at the pose of its
stamp (``Brain.tick``'s ``scan_pose``), the command computed for the newest pose. A scan whose
stamp is newer than every pose received so far waits for its pose, at most ``pair_wait`` s (wall
clock); a pose arrival then wakes the loop. (The simulator publishes a step's pose before its
scan, but Zenoh delivers the two keys on different threads: the node, woken by the scan, often
ran its tick before the pose was in; measured on the demo, 16 of 436 scans went to the
executive paired with the pose a step older and were refused by perception's stamp check.)
Every sensor message that is ready is integrated, oldest first: all but the newest through
``Brain.observe`` when the brain has it (else a tick each), the newest by the tick; none is
superseded.

Rerun telemetry (:class:`service.viz.Telemetry`) never runs between a scan's arrival and its
command: the tick captures what it logs, and the logging runs in the loop's idle time
(:meth:`ServiceNode.run`).

Fresh commands (``NodeConfig.refresh``, default on): the controller's speed limit
``v <= clearance / safety_horizon`` certifies a step that *starts at the pose the command was
computed for*. When a tick is slow (a scan that changes the map, a loaded machine, a sped-up
simulation) the robot has moved on by the time its command goes out, and a command computed for
the old pose can carry it into an obstacle (measured: the demo at ``--speed 4`` on a loaded
2-core machine, 35-55 ms ticks, 260 blocked steps, none at ``--speed 1``). So when poses newer
than the one the tick used arrived during the tick, the node ticks the brain again on the newest
pose, without sensor data (a few milliseconds: the map and plan are already up to date), and
publishes that command instead; ``stats.refreshed`` counts them.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import zenoh
from zenoh.ext import CacheConfig, declare_advanced_publisher

from .brain import Brain, BrainTick
from .errors import MessageError, ServiceError, TaskErrorCode, TaskRejected
from .messages import (
    PoseMsg,
    ServiceState,
    cmd_vel_message,
    encode,
    obstacles_message,
    parse_points,
    parse_pose,
    parse_scan,
    parse_task_request,
    status_message,
    task_ok_reply,
)

__all__ = ["NodeConfig", "ServiceNode", "zenoh_config", "DEFAULT_LISTEN"]

log = logging.getLogger("service.node")

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
_JSON = zenoh.Encoding.APPLICATION_JSON
_QUEUE = 64  # per input key; older messages are dropped first (no growing queue)
_TELEMETRY_GRACE = 0.002  # s after a tick before deferred Rerun logging starts (see run)


def zenoh_config(*, listen=None, connect=None, config_file=None, mode: str = "peer") -> zenoh.Config:
    """A Zenoh configuration for the bus.

    Without ``config_file``: ``mode`` (peer), multicast and gossip scouting off, ``listen`` /
    ``connect`` endpoints as given (``None``: listen on :data:`DEFAULT_LISTEN`, connect to
    nothing), timestamping on (needed by the latched ``status``). With ``config_file`` (JSON5,
    as Zenoh documents it: TLS, access control...) the file is used as is, and only
    ``listen`` / ``connect`` given explicitly override its endpoints; timestamping is enabled.

    Raises
    ------
    ServiceError
        The file cannot be read or an endpoint is refused; the message names it.
    """
    try:
        if config_file is not None:
            path = Path(config_file)
            if not path.is_file():
                raise ServiceError(f"--zenoh-config: no such file {str(path)!r}")
            cfg = zenoh.Config.from_file(str(path))
        else:
            cfg = zenoh.Config()
            cfg.insert_json5("mode", json.dumps(mode))
            cfg.insert_json5("scouting/multicast/enabled", "false")
            cfg.insert_json5("scouting/gossip/enabled", "false")
            if listen is None:
                listen = [DEFAULT_LISTEN]
            if connect is None:
                connect = []
        if listen is not None:
            cfg.insert_json5("listen/endpoints", json.dumps(list(listen)))
        if connect is not None:
            cfg.insert_json5("connect/endpoints", json.dumps(list(connect)))
        cfg.insert_json5("timestamping/enabled", "true")
    except ServiceError:
        raise
    except Exception as err:  # zenoh.ZError: flat, sometimes cryptic
        what = f"--zenoh-config {config_file}" if config_file else f"listen={listen} connect={connect}"
        raise ServiceError(f"invalid Zenoh configuration ({what}): {err}") from None
    return cfg


@dataclass(frozen=True, slots=True)
class NodeConfig:
    """Settings of a :class:`ServiceNode` (frozen, validated).

    Attributes
    ----------
    robot : str
        Robot id; the key prefix defaults to ``tamp/<robot>``.
    prefix : str, optional
        Key prefix (overrides ``robot``).
    rate : float
        Control rate (Hz, wall clock).
    watchdog : float
        Seconds without a valid pose or scan/points before the node stops the robot.
    status_period : float
        Longest time between two ``status`` publications (s).
    listen, connect : tuple of str, optional
        Zenoh endpoints (``None``: see :func:`zenoh_config`).
    zenoh_config : str, optional
        Zenoh JSON5 configuration file, passed through.
    refresh : bool
        Recompute the command on the newest pose when newer poses arrived during a tick (see
        the module doc, "Fresh commands").
    pair_wait : float
        Longest wall time (s) a scan or points message newer than every received pose waits
        for the pose of its stamp (0.1; module doc, "Sensor messages and their poses"); after
        it, it is integrated at the nearest pose received.
    """

    robot: str = "robot"
    prefix: str | None = None
    rate: float = 10.0
    watchdog: float = 1.0
    status_period: float = 1.0
    listen: tuple[str, ...] | None = None
    connect: tuple[str, ...] | None = None
    zenoh_config: str | None = None
    refresh: bool = True
    pair_wait: float = 0.1

    def __post_init__(self):
        for name in ("rate", "watchdog", "status_period"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ServiceError(f"NodeConfig.{name} must be a finite number > 0, got {v!r}")
        v = self.pair_wait
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise ServiceError(f"NodeConfig.pair_wait must be a finite number >= 0, got {v!r}")
        key = self.key_prefix
        if not key or key.startswith("/") or key.endswith("/") or "//" in key or any(c in key for c in "*$?#"):
            raise ServiceError(f"key prefix {key!r} is not a valid Zenoh key (no wildcards, no empty chunks)")
        for name in ("listen", "connect"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, tuple(str(e) for e in v))

    @property
    def key_prefix(self) -> str:
        return self.prefix if self.prefix is not None else f"tamp/{self.robot}"

    def key(self, name: str) -> str:
        return f"{self.key_prefix}/{name}"


@dataclass
class _Stats:
    ticks: int = 0
    overruns: int = 0
    received: dict = field(default_factory=lambda: {"pose": 0, "scan": 0, "points": 0, "task": 0})
    dropped: dict = field(default_factory=lambda: {"pose": 0, "scan": 0, "points": 0})
    warnings: int = 0
    refreshed: int = 0  #: commands recomputed on a newer pose after a slow tick
    held: int = 0  #: sensor messages that waited for the pose of their stamp
    unpaired: int = 0  #: sensor messages integrated at the nearest pose after ``pair_wait``
    tick_times: deque = field(default_factory=lambda: deque(maxlen=10000))


class ServiceNode:
    """The service on the bus; use with ``with``.

    Parameters
    ----------
    brain : Brain
        The task executive (e.g. :class:`service.brain.ExecutiveBrain`).
    config : NodeConfig
    telemetry : service.viz.Telemetry, optional
        Rerun streaming; nothing is logged without it (or when it has no sink).
    session : zenoh.Session, optional
        Use this session instead of opening one (tests; the node then does not close it).
    """

    def __init__(self, brain: Brain, config: NodeConfig | None = None, *, telemetry=None, session=None):
        self.brain = brain
        self.config = config or NodeConfig()
        self.telemetry = telemetry
        self._own_session = session is None
        self._session = session
        self._inbox = {k: deque(maxlen=_QUEUE) for k in ("pose", "scan", "points")}
        self._queries: deque = deque()
        self._declared: list = []
        self._stop = threading.Event()
        self._wake = threading.Event()  # set by scan/points arrivals and stop()
        self.stats = _Stats()
        self._last_stamp: dict[str, float] = {}
        self._pose: PoseMsg | None = None
        self._poses: deque[PoseMsg] = deque(maxlen=50)
        # valid scan / points messages not integrated yet, oldest first: (kind, msg, arrival)
        self._sensors: deque = deque(maxlen=_QUEUE)
        self._await_pose = False  # a sensor message waits for its pose: a pose arrival wakes the loop
        self._held_msg = None  # the sensor message last counted in stats.held
        self._rx = {"pose": None, "sensor": None}
        self._warnings: list[str] = []  # this tick's, shown in status.message
        self._blocked: str | None = None
        self._status: dict | None = None
        self._status_sent = (None, -math.inf)  # (content without stamp, monotonic time)
        self._last_cmd = (0.0, 0.0)
        self._tasks = 0
        self._t0 = None
        self._open = False
        self._defer_telemetry = False  # in run(): telemetry captures in the tick, logs while waiting

    # ------------------------------------------------------------------ lifecycle
    def __enter__(self) -> "ServiceNode":
        self.open()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def session(self) -> zenoh.Session:
        return self._session

    def open(self) -> None:
        """Open the session (unless given) and declare every key."""
        c = self.config
        if self._session is None:
            self._session = zenoh.open(zenoh_config(listen=c.listen, connect=c.connect, config_file=c.zenoh_config))
        s = self._session
        for name in ("pose", "scan", "points"):
            self._declared.append(s.declare_subscriber(c.key(name), self._enqueue(name)))
        self._pub_cmd = s.declare_publisher(c.key("cmd_vel"), encoding=_JSON,
                                            congestion_control=zenoh.CongestionControl.DROP)
        self._pub_status = declare_advanced_publisher(s, c.key("status"), encoding=_JSON,
                                                      cache=CacheConfig(max_samples=1))
        self._pub_obstacles = declare_advanced_publisher(s, c.key("obstacles"), encoding=_JSON,
                                                         cache=CacheConfig(max_samples=1))
        self._declared += [self._pub_cmd, self._pub_status, self._pub_obstacles]
        self._declared.append(s.declare_queryable(c.key("task"), self._queries.append, complete=True))
        self._token = s.liveliness().declare_token(c.key("alive"))
        self._t0 = time.monotonic()
        self._open = True
        log.info("service node up on %s", c.key_prefix)

    def _enqueue(self, name: str):
        box = self._inbox[name]

        sensor = name in ("scan", "points")

        def callback(sample, _box=box, _sensor=sensor):  # Zenoh thread: enqueue only
            _box.append((sample.payload.to_bytes(), time.monotonic()))
            if _sensor or self._await_pose:
                self._wake.set()

        return callback

    def stop(self) -> None:
        """Ask :meth:`run` to return (thread- and signal-safe)."""
        self._stop.set()
        self._wake.set()

    def close(self) -> None:
        """Publish a zero command and a final status, undeclare everything, close the session."""
        if not self._open:
            return
        self._open = False
        try:
            self._publish_cmd(0.0, 0.0)
            st = dict(self._status or self._idle_status())
            st["message"] = "service stopped"
            self._publish_status(st, force=True)
        except Exception as err:  # closing must not fail half-way
            log.warning("final publication failed: %s", err)
        for q in list(self._queries):
            self._reply_error(q, TaskRejected(TaskErrorCode.INVALID_REQUEST, "the service is shutting down"))
        self._queries.clear()
        try:
            self._token.undeclare()
        except Exception:
            pass
        for d in reversed(self._declared):
            try:
                d.undeclare()
            except Exception:
                pass
        self._declared.clear()
        if self._own_session:
            self._session.close()
        if self.telemetry is not None:
            self.telemetry.close()

    # ------------------------------------------------------------------ loop
    def run(self, duration: float | None = None, *, until=None) -> None:
        """Run the control loop until :meth:`stop`, ``duration`` wall seconds, or
        ``until(node)`` returning true (checked after every tick).

        A tick runs every ``1 / config.rate`` s, and also as soon as a scan or points message
        arrives (so a command answers a scan within one tick's compute time); the periodic
        schedule restarts after such a tick.

        With Rerun telemetry, a tick only captures what it logs; the logging runs while the
        loop waits for the next period (``Telemetry.idle``, from 2 ms after the tick, so that
        the command leaves first), and a scan arrival interrupts it between two pieces of it.
        When the loop returns, everything captured is logged."""
        period = 1.0 / self.config.rate
        tel = self.telemetry if self.telemetry is not None and self.telemetry.enabled else None
        start = time.monotonic()
        nxt = start
        self._defer_telemetry = tel is not None
        try:
            while not self._stop.is_set():
                self._wake.clear()
                t0 = time.monotonic()
                self.step()
                if until is not None and until(self):
                    break
                now = time.monotonic()
                if duration is not None and now - start >= duration:
                    break
                if now - t0 > period:
                    self.stats.overruns += 1
                nxt = t0 + period if t0 + period > now else now
                if tel is not None:  # Rerun logging while waiting; a scan arrival interrupts it
                    # first let the command leave (2 cores: logging right away delayed its delivery)
                    if not self._wake.wait(min(_TELEMETRY_GRACE, max(0.0, nxt - now))):
                        tel.idle(nxt, self._wake.is_set)
                    now = time.monotonic()
                self._wake.wait(max(0.0, nxt - now))
        finally:
            self._defer_telemetry = False
            if tel is not None:
                tel.flush_pending()

    def step(self) -> BrainTick | None:
        """One control period (normally called by :meth:`run`)."""
        t_start = time.perf_counter()
        mono = time.monotonic()
        self._drain()
        self._serve_tasks()
        scan = points = None
        reason = self._watchdog(mono)
        out = None
        if reason is not None:
            self._last_cmd = (0.0, 0.0)
            self._publish_cmd(0.0, 0.0)
            st = self._idle_status()
            st["state"], st["message"] = ServiceState.BLOCKED.value, reason
            if self._blocked is None:
                log.warning("watchdog: %s", reason)
            self._blocked = reason
        elif self._pose is None:  # start-up, within the watchdog time
            self._publish_cmd(0.0, 0.0)
            st = self._idle_status()
            st["message"] = "waiting for the first pose"
        else:
            if self._blocked is not None:
                log.info("watchdog: inputs fresh again, resuming")
                self._warn_once(f"recovered: inputs fresh again after '{self._blocked}'")
                self._blocked = None
            ready = self._ready_sensors(mono)
            try:
                map_changed = False
                for kind, msg in ready[:-1]:  # further messages of this period, oldest first
                    map_changed |= self._observe(kind, msg)
                if ready:
                    kind, msg = ready[-1]
                    scan, points = (msg, None) if kind == "scan" else (None, msg)
                out = self.brain.tick(self._pose, scan=scan, points=points, now=self._pose.stamp,
                                      scan_pose=self._pose_at(msg.stamp) if ready else None)
                if map_changed and not out.map_changed:
                    out = dataclasses.replace(out, map_changed=True)
                v, w = float(out.v), float(out.omega)
                st = dict(out.status)
                used = self._pose
                if self.config.refresh and self._inbox["pose"]:
                    self._drain(("pose",))
                    if self._pose.stamp > used.stamp:  # the robot moved on during the tick
                        again = self.brain.tick(self._pose, now=self._pose.stamp)
                        v, w, st = float(again.v), float(again.omega), dict(again.status)
                        self.stats.refreshed += 1
                if not (math.isfinite(v) and math.isfinite(w)):
                    raise ServiceError(f"brain returned a non-finite command ({v!r}, {w!r})")
            except Exception as err:  # the brain must not take the service down
                log.exception("brain tick failed")
                v = w = 0.0
                st = dict(self._status or self._idle_status())
                st["state"], st["message"] = ServiceState.ERROR.value, f"internal error in the executive: {err}"
                out = None
            self._last_cmd = (v, w)
            self._publish_cmd(v, w, pose_stamp=self._pose.stamp, scan_stamp=None if scan is None else scan.stamp)
            if out is not None and (out.map_changed or self.stats.ticks == 0):
                self._publish_obstacles()
        if self._warnings:
            w = self._warnings
            text = "; ".join(w[:3]) + (f"; and {len(w) - 3} more" if len(w) > 3 else "")
            st["message"] = f"warning: {text}" + (f" | {st['message']}" if st.get("message") else "")
        self._publish_status(st)
        self._warnings = []
        self.stats.ticks += 1
        dt = time.perf_counter() - t_start
        self.stats.tick_times.append(dt)
        if self.telemetry is not None and self.telemetry.enabled:
            self.telemetry.log_tick(self, scan=scan, points=points, out=out, status=self._status, compute=dt,
                                    defer=self._defer_telemetry)
        return out

    # ------------------------------------------------------------------ inputs
    def _warn(self, msg: str) -> None:
        self.stats.warnings += 1
        self._warnings.append(msg)
        log.warning("%s", msg)

    def _warn_once(self, msg: str) -> None:
        self._warnings.append(msg)

    def _fresh(self, key: str, stamp: float) -> bool:
        last = self._last_stamp.get(key)
        if last is not None and stamp <= last:
            what = "duplicated" if stamp == last else "out of order"
            self._warn(f"{key}: stamp {stamp:.6g} is {what} (last accepted {last:.6g}): dropped")
            return False
        self._last_stamp[key] = stamp
        return True

    def _drain(self, keys=("pose", "scan", "points")):
        """Validate everything received on ``keys`` since the last tick: poses update the
        robot pose, valid scan and points messages join the sensor queue."""
        parsers = {"pose": parse_pose, "scan": parse_scan, "points": parse_points}
        for key in keys:
            box = self._inbox[key]
            while box:
                payload, rx = box.popleft()
                self.stats.received[key] += 1
                try:
                    msg = parsers[key](payload)
                except MessageError as err:
                    self.stats.dropped[key] += 1
                    self._warn(f"{err} (message dropped)")
                    continue
                except Exception as err:  # a parser bug must not take the service down
                    self.stats.dropped[key] += 1
                    self._warn(f"{key}: unreadable message ({type(err).__name__}: {err}) (dropped)")
                    continue
                if not self._fresh(key, msg.stamp):
                    self.stats.dropped[key] += 1
                    continue
                if key == "pose":
                    self._pose = msg
                    self._poses.append(msg)
                    self._rx["pose"] = rx
                else:
                    self._rx["sensor"] = rx
                    if len(self._sensors) == self._sensors.maxlen:
                        self.stats.dropped[self._sensors[0][0]] += 1
                        self._warn(f"{self._sensors[0][0]}: more than {_QUEUE} messages waiting: the oldest dropped")
                    self._sensors.append((key, msg, rx))

    def _ready_sensors(self, mono: float) -> list:
        """The queued sensor messages to integrate now, oldest first, as ``(kind, msg)``: those
        with a pose at or after their stamp, and those that waited ``pair_wait`` s (module doc,
        "Sensor messages and their poses")."""
        latest = self._pose.stamp if self._pose is not None else -math.inf
        ready = []
        while self._sensors:
            kind, msg, rx = self._sensors[0]
            if msg.stamp > latest + 1e-9:  # its pose has not arrived
                if mono - rx < self.config.pair_wait:
                    if self._held_msg is not msg:
                        self._held_msg = msg
                        self.stats.held += 1
                    break
                self.stats.unpaired += 1
            self._sensors.popleft()
            ready.append((kind, msg))
        self._await_pose = bool(self._sensors)
        return ready

    def _observe(self, kind: str, msg) -> bool:
        """Integrate one further sensor message without a command (``Brain.observe``, or a tick
        whose command is not sent); whether the map changed."""
        pose = self._pose_at(msg.stamp)
        scan, points = (msg, None) if kind == "scan" else (None, msg)
        observe = getattr(self.brain, "observe", None)
        if observe is not None:
            return bool(observe(pose, scan=scan, points=points, now=self._pose.stamp))
        return bool(self.brain.tick(self._pose, scan=scan, points=points, scan_pose=pose, now=self._pose.stamp).map_changed)

    def _pose_at(self, stamp: float) -> PoseMsg | None:
        return min(self._poses, key=lambda p: abs(p.stamp - stamp), default=None)

    def restart_watchdog(self) -> None:
        """Count the watchdog's "none received yet" time from now instead of from :meth:`open`
        (a caller that started its inputs' source after opening the node, e.g. the demo's
        simulator process)."""
        self._t0 = time.monotonic()

    def _watchdog(self, mono: float) -> str | None:
        wd = self.config.watchdog
        for name, what in (("pose", "pose"), ("sensor", "scan or points")):
            rx = self._rx[name]
            age = mono - (rx if rx is not None else self._t0)
            if age > wd:
                never = " (none received yet)" if rx is None else ""
                return f"no fresh {what} for {age:.1f} s (watchdog {wd:g} s){never}: stopped"
        return None

    # ------------------------------------------------------------------ tasks
    def _serve_tasks(self) -> None:
        while self._queries:
            q = self._queries.popleft()
            self.stats.received["task"] += 1
            try:
                req = parse_task_request(q.payload.to_bytes() if q.payload is not None else b"")
                plan = self.brain.request_task(req)
                self._tasks += 1
                reply = task_ok_reply(f"{self.config.robot}-{self._tasks}", plan)
                q.reply(q.key_expr, encode(reply), encoding=_JSON)
                log.info("task accepted: %s %r", req.mode, req.formula)
            except TaskRejected as err:
                self._reply_error(q, err)
            except Exception as err:  # never leave a query unanswered
                log.exception("task request failed")
                self._reply_error(q, TaskRejected(TaskErrorCode.INVALID_REQUEST, f"internal error: {err}"))
            finally:
                q.drop()

    def _reply_error(self, q, err: TaskRejected) -> None:
        log.info("task refused: %s", err)
        try:
            q.reply_err(encode(err.to_reply()), encoding=_JSON)
        except Exception as e:
            log.warning("could not reply to a task query: %s", e)

    # ------------------------------------------------------------------ outputs
    def _idle_status(self) -> dict:
        try:
            st = dict(self.brain.status())
        except Exception:
            st = {}
        st.setdefault("state", ServiceState.IDLE.value)
        return st

    def _publish_cmd(self, v: float, w: float, **extra) -> None:
        msg = cmd_vel_message(time.time(), v, w)
        msg.update({k: x for k, x in extra.items() if x is not None})
        self._pub_cmd.put(encode(msg))

    def _publish_status(self, st: dict, force: bool = False) -> None:
        fields = {k: st.get(k) for k in ("task", "plan", "target", "waypoint", "message")}
        msg = status_message(time.time(), st.get("state", "idle"), obstacles=st.get("obstacles") or 0,
                             warnings=self.stats.warnings, **fields)
        self._status = msg
        content = {k: v for k, v in msg.items() if k not in ("stamp", "warnings")}
        mono = time.monotonic()
        last, t = self._status_sent
        if force or content != last or mono - t >= self.config.status_period:
            self._pub_status.put(encode(msg))
            self._status_sent = (content, mono)

    def _publish_obstacles(self) -> None:
        try:
            self._pub_obstacles.put(encode(obstacles_message(time.time(), self.brain.obstacles())))
        except Exception as err:
            log.warning("obstacles not published: %s", err)

    # ------------------------------------------------------------------ introspection
    @property
    def status(self) -> dict | None:
        """The last status published (or built)."""
        return self._status

    @property
    def command(self) -> tuple[float, float]:
        return self._last_cmd

    @property
    def pose(self) -> PoseMsg | None:
        return self._pose
