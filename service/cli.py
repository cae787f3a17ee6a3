"""``tamp-service``: the task-and-motion-planning service on a Zenoh bus.

Subcommands:

* ``run``  serves one robot: subscribes ``scan``/``points``/``pose``, publishes ``cmd_vel``,
  ``status`` and ``obstacles``, answers ``task`` queries (bus contract: docs/service.md);
* ``demo`` runs the service together with the simulator as a separate process talking to it
  only over Zenoh on loopback, shows progress and ends with a summary.

Exit status: 0 when the service ran (and stopped on SIGINT/SIGTERM, ``--duration`` or, for
``demo``, mission completion), 2 with one ``error: ...`` line on stderr for bad arguments, an
invalid world or task, or a Zenoh configuration that cannot be opened.
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import json
import logging
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections import deque
from pathlib import Path

from navigation._argtypes import positive, seed

__all__ = ["main", "build_parser", "stop_child"]

EPILOG = """environment:
  RUST_LOG        Zenoh's own log filter (e.g. RUST_LOG=zenoh=info); Zenoh is quiet by default.
  ZENOH_CONFIG    not read: pass a configuration file with --zenoh-config instead.

keys (prefix tamp/<robot>): scan, points, pose (in); cmd_vel, status, obstacles (out);
task (queryable); alive (liveliness token). See docs/service.md.
"""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2 (the project's CLI contract)
        self.exit(2, f"error: {message}\n")


def _split_port(text: str) -> tuple[str, int | None]:
    """``HOST:PORT`` -> ``(HOST, PORT)``; the port ``None`` unless it is an integer in 1..65535."""
    host, _, port = text.rpartition(":")
    return host, int(port) if port.isdigit() and 1 <= int(port) <= 65535 else None


def _viewer(text: str) -> str:
    """``--viewer``: a Rerun URL (``rerun://``, ``rerun+http://``, ``rerun+https://``) or
    ``HOST:PORT`` with a port in 1..65535."""
    if "://" in text:
        if not text.startswith(("rerun://", "rerun+http://", "rerun+https://")):
            raise argparse.ArgumentTypeError(f"expected a rerun://, rerun+http:// or rerun+https:// URL, got {text!r}")
        return text
    host, port = _split_port(text)
    if not host or port is None:
        raise argparse.ArgumentTypeError(f"expected HOST:PORT (e.g. 127.0.0.1:9876) or a rerun+http:// URL, "
                                         f"got {text!r}")
    return text


def _serve(text: str) -> tuple[str, int]:
    """``--serve``: ``PORT`` (on 127.0.0.1) or ``IP:PORT``, the address of the Rerun gRPC server
    the service hosts. Rerun binds IP literals only (``0.0.0.0`` for every interface)."""
    import ipaddress

    host, port = _split_port(text)
    host = host.strip("[]") or "127.0.0.1"
    try:
        ipaddress.ip_address(host)
    except ValueError:
        host = ""
    if not host or port is None:
        raise argparse.ArgumentTypeError(f"expected PORT or IP:PORT (e.g. 9876, 0.0.0.0:9876), got {text!r}")
    return host, port


def _common(p: argparse.ArgumentParser, *, default_world: str | None) -> None:
    p.add_argument("--world", default=default_world,
                   help="world file (FORMATS.md) or built-in name (simple, office, cluttered20)")
    p.add_argument("--task", default=None, help="LTL mission over region names (default: the world's task)")
    p.add_argument("--known", action="store_true", help="every obstacle of the world is known at start")
    p.add_argument("--robot", default="robot", help="robot id; keys live under tamp/<robot>")
    p.add_argument("--prefix", default=None, help="key prefix (overrides tamp/<robot>)")
    p.add_argument("--listen", action="append", default=None, metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on (repeatable; default tcp/127.0.0.1:7447 for run, "
                        "a free loopback port for demo)")
    p.add_argument("--connect", action="append", default=None, metavar="ENDPOINT",
                   help="Zenoh endpoint to connect to (repeatable), e.g. a router")
    p.add_argument("--zenoh-config", default=None, metavar="FILE",
                   help="Zenoh JSON5 configuration file, used as is (TLS, access control...); "
                        "--listen/--connect override its endpoints")
    p.add_argument("--record", default=None, metavar="PATH.rrd", help="write a Rerun recording")
    p.add_argument("--viewer", type=_viewer, default=None, metavar="ADDR",
                   help="stream to a Rerun viewer over gRPC (HOST:PORT or a rerun+http:// URL), "
                        "e.g. one started with 'rerun --bind 127.0.0.1 --port 9876'; messages wait in "
                        "memory while the viewer is not there")
    p.add_argument("--serve", type=_serve, default=None, metavar="[IP:]PORT",
                   help="host a Rerun gRPC server (on 127.0.0.1 unless IP is given) that viewers connect to "
                        "at any time: 'rerun --connect rerun+http://127.0.0.1:PORT/proxy'; it keeps at most "
                        "--serve-memory of the newest data")
    p.add_argument("--serve-memory", default="256MiB", metavar="SIZE",
                   help="memory limit of the --serve server (e.g. 512MiB, 2GiB): the oldest data goes first")
    p.add_argument("--rate", type=positive, default=10.0, help="control rate (Hz, simulated time for demo)")
    p.add_argument("--watchdog", type=positive, default=1.0,
                   help="seconds without a fresh pose or scan before the robot is stopped (blocked)")
    p.add_argument("--accel-max", type=positive, default=None, metavar="A",
                   help="the robot's acceleration limit (m/s^2) for the controller's rate limit: each "
                        "command within A*dt of the last in v, braking within half the clearance "
                        "(docs/control.md 'Rate-limited mode'; default 1 m/s^2)")
    p.add_argument("--alpha-max", type=positive, default=None, metavar="B",
                   help="the robot's turn-rate acceleration limit (rad/s^2) for the controller's rate "
                        "limit (default 6 rad/s^2)")
    p.add_argument("--unlimited", action="store_true",
                   help="no rate limit: eq. 24's command at every period, whatever the last one was "
                        "(navigation.control.UNLIMITED; for a base that smooths its own commands)")
    p.add_argument("--no-crawl-guard", action="store_true",
                   help="track with eq. 24 alone: never engage the stand-off that walks a crawling robot "
                        "along the wall, nor switch modes when it loops (docs/control.md 'Crawl guard', "
                        "'Pull-in', 'Loops')")
    p.add_argument("--fields", action="store_true",
                   help="track each waypoint's oriented field (paper 001 eq. 24-25) instead of pursuing the "
                        "harmonic tree's path 0.3 m ahead (docs/executive.md 'Pursuit')")
    p.add_argument("-v", "--verbose", action="store_true", help="log every warning and state change")


def build_parser() -> argparse.ArgumentParser:
    fmt = argparse.ArgumentDefaultsHelpFormatter
    p = _Parser(prog="tamp-service", description=__doc__.split("\n\n")[0] + " LTL missions for a unicycle "
                "robot with harmonic navigation functions.", epilog=EPILOG,
                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="{run,demo}", parser_class=_Parser)
    r = sub.add_parser("run", help="serve a robot on the bus", formatter_class=fmt, epilog=EPILOG,
                       description="Serve one robot: run the task executive on the bus until SIGINT/SIGTERM "
                                   "or --duration.")
    _common(r, default_world=None)
    r.add_argument("--duration", type=positive, default=None, help="stop after this many wall seconds")
    d = sub.add_parser("demo", help="run the service and a simulated robot over Zenoh on loopback",
                       formatter_class=fmt, epilog=EPILOG,
                       description="Run the service and the simulator (a child process) over Zenoh on "
                                   "loopback until the mission completes or --duration, then print a summary.")
    _common(d, default_world="office")
    d.add_argument("--duration", type=positive, default=300.0, help="give up after this many simulated seconds")
    d.add_argument("--speed", type=positive, default=1.0,
                   help="simulation speed-up (simulated s per wall s), at most: the simulator waits for the "
                        "service's answer to each pose, never running slower than real time")
    d.add_argument("--seed", type=seed, default=0, help="lidar noise seed of the simulator (>= 0)")
    d.add_argument("--points", action="store_true",
                   help="the simulator publishes 'points' (world-frame returns) instead of 'scan'")
    d.add_argument("--json", action="store_true", help="print the summary as one JSON object on stdout")
    d.add_argument("--keep-going", action="store_true",
                   help="run until --duration even after the mission completes (a recurrent mission "
                        "completes after one round of its cycle): a patrol, a soak run")
    return p


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _executive_config(a):
    """The executive's configuration from the options: its default controller (rate-limited,
    docs/control.md "Rate-limited mode") with ``--accel-max`` / ``--alpha-max`` as given, or
    without the rate limit with ``--unlimited``; no crawl guard with ``--no-crawl-guard``;
    each waypoint's field tracked (no pursuit) with ``--fields``; ``None`` (the executive's
    defaults) when none of them is given."""
    if a.accel_max is None and a.alpha_max is None and not a.unlimited and not a.no_crawl_guard and not a.fields:
        return None
    from navigation.control import UNLIMITED
    from tamp.executive import ExecutiveConfig

    over = {"crawl_guard": None} if a.no_crawl_guard else {}
    if a.fields:
        over["pursuit"] = 0.0
    given = dict(UNLIMITED) if a.unlimited else {}
    given.update({k: v for k, v in (("accel_max", a.accel_max), ("alpha_max", a.alpha_max)) if v is not None})
    if given:
        over["controller"] = dataclasses.replace(ExecutiveConfig().controller, **given)
    return ExecutiveConfig(**over)


def _setup(a):
    """World, brain, node config, telemetry; raises HarmonicTampError/OSError on bad input."""
    import navigation

    from tamp.run import prepare

    from .brain import ExecutiveBrain
    from .errors import ServiceError, TaskErrorCode, TaskRejected
    from .node import NodeConfig
    from .viz import Telemetry

    if a.world is None:
        raise ServiceError("--world is required for run (a world file or built-in name)")
    world = navigation.load_world(a.world)
    # compile now (first run on a machine), not at the robot's first map change; say so if it takes
    seconds = prepare(lambda: print("tamp-service: compiling the navigation kernels (first run on this machine "
                                    "only, up to about a minute) ...", file=sys.stderr, flush=True))
    if seconds > 1.0:
        print(f"tamp-service: navigation kernels ready in {seconds:.1f} s (cached from now on)", file=sys.stderr,
              flush=True)
    try:
        brain = ExecutiveBrain(world, a.task, known=a.known, config=_executive_config(a))
    except Exception as err:
        from .brain import task_error_code
        from navigation.errors import TampError

        if isinstance(err, TampError):
            code = task_error_code(err)
            # the formula's own errors name --task; the others (a world beyond the navigation
            # map's region limit, say) are not the task's fault
            about_task = code is not TaskErrorCode.INVALID_REQUEST
            raise TaskRejected(code, f"--task: {err}" if about_task else str(err)) from None
        raise
    gc.collect()  # the world and the brain join the frozen start-up heap (see tamp.run.prepare)
    gc.freeze()
    return world, brain, NodeConfig, Telemetry


def _install_signals(stop) -> None:
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop())


def _cmd_run(a) -> int:
    from .node import ServiceNode

    world, brain, NodeConfig, Telemetry = _setup(a)
    cfg = NodeConfig(robot=a.robot, prefix=a.prefix, rate=a.rate, watchdog=a.watchdog,
                     listen=tuple(a.listen) if a.listen else None, connect=tuple(a.connect) if a.connect else None,
                     zenoh_config=a.zenoh_config)
    tel = _telemetry(Telemetry, a)
    tel.log_world(world)
    node = ServiceNode(brain, cfg, telemetry=tel)
    _install_signals(node.stop)
    with node:
        print(f"tamp-service: serving {cfg.key_prefix} ({world.name}); Ctrl-C to stop", file=sys.stderr, flush=True)
        node.run(a.duration)
    print(f"tamp-service: stopped after {node.stats.ticks} ticks", file=sys.stderr)
    return 0


def _telemetry(Telemetry, a):
    """The Rerun stream of ``--record`` / ``--viewer`` / ``--serve``; says where viewers connect."""
    tel = Telemetry.from_options(record=a.record, viewer=a.viewer, serve=a.serve, serve_memory=a.serve_memory)
    if a.serve is not None:
        host, port = a.serve
        shown = f"[{host}]" if ":" in host else host
        print(f"tamp-service: Rerun viewers connect with: rerun --connect rerun+http://{shown}:{port}/proxy "
              f"(the server keeps the newest {a.serve_memory})", file=sys.stderr, flush=True)
    return tel


def _repo_root() -> str:
    return str(Path(__file__).resolve().parent.parent)


SIM_START = 60.0  # s the demo waits for its simulator's first pose and scan before the node runs


def _cmd_demo(a) -> int:
    import numpy as np

    from .node import ServiceNode

    world, brain, NodeConfig, Telemetry = _setup(a)
    listen = list(a.listen) if a.listen else [f"tcp/127.0.0.1:{_free_port()}"]
    cfg = NodeConfig(robot=a.robot, prefix=a.prefix, rate=a.rate * a.speed, watchdog=a.watchdog,
                     listen=tuple(listen), connect=tuple(a.connect) if a.connect else None,
                     zenoh_config=a.zenoh_config)
    tel = _telemetry(Telemetry, a)
    tel.log_world(world, true_obstacles=True)
    node = ServiceNode(brain, cfg, telemetry=tel)
    env = dict(os.environ)
    env["PYTHONPATH"] = _repo_root() + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    sim_cmd = [sys.executable, "-m", "service.sim_node", "--world", str(a.world), "--prefix", cfg.key_prefix,
               "--connect", listen[0], "--speed", repr(a.speed), "--seed", str(a.seed),
               "--duration", repr(a.duration)] + (["--points"] if a.points else [])
    metrics: deque = deque(maxlen=1)
    stopped = threading.Event()

    def stop():
        stopped.set()
        node.stop()

    _install_signals(stop)
    wall0 = time.monotonic()
    last = [None]

    def progress(n) -> bool:
        st = n.status or {}
        key = (st.get("state"), st.get("target"))
        if key != last[0]:
            last[0] = key
            t = n.pose.stamp if n.pose is not None else 0.0
            print(f"[{t:7.1f} s] {st.get('state')}" + (f" -> {st.get('target')}" if st.get("target") else "")
                  + (f"  ({st.get('message')})" if a.verbose and st.get("message") else ""), file=sys.stderr, flush=True)
        if brain.summary()["completed"] and not a.keep_going:
            return True
        if n.pose is not None and n.pose.stamp >= a.duration - 1e-9:
            return True
        return sim.poll() is not None

    with node:
        sub = node.session.declare_subscriber(cfg.key("sim/metrics"), lambda s: metrics.append(s.payload.to_bytes()))
        # the node's watchdog counts from the node's start: wait (up to SIM_START s) for the
        # simulator process's first pose and scan (or points) and restart it then, so that the simulator's
        # start-up (imports, session) does not show as a watchdog stop ("blocked: no fresh
        # pose") at the start of every demo
        up = {"pose": threading.Event(), "points" if a.points else "scan": threading.Event()}
        first = [node.session.declare_subscriber(cfg.key(k), lambda s, e=e: e.set()) for k, e in up.items()]
        sim = subprocess.Popen(sim_cmd, env=env, stdout=subprocess.DEVNULL)
        try:
            print(f"tamp-service demo: {world.name}, task {brain.summary()['task']!r}, speed x{a.speed:g}, "
                  f"bus {listen[0]} prefix {cfg.key_prefix}", file=sys.stderr, flush=True)
            t_up = time.monotonic() + SIM_START
            while (not all(e.wait(0.05) for e in up.values()) and sim.poll() is None
                   and time.monotonic() < t_up and not stopped.is_set()):
                pass
            for f in first:
                f.undeclare()
            node.restart_watchdog()
            node.run(a.duration + 30.0, until=progress)  # paced: real time at worst
            time.sleep(min(0.5, 2.0 / a.speed))  # let the simulator's last metrics arrive
            sim_rc = sim.poll()  # None: still running (stopped below), as it should be
        finally:
            stop_child(sim)
            sub.undeclare()
    summary = brain.summary()
    m = json.loads(metrics[-1]) if metrics else {}
    ticks = np.asarray(node.stats.tick_times) * 1e3
    out = {"world": world.name, "task": summary["task"], "completed": summary["completed"],
           "interrupted": stopped.is_set(), "state": summary["state"], "visited": summary["visited"],
           "accepting_visits": summary.get("accepting_visits"),
           "sim_time": m.get("time"), "wall_time": time.monotonic() - wall0, "sim_waited": m.get("waited"),
           "distance": m.get("distance"),
           "collisions": len(m.get("collisions", [])) if isinstance(m.get("collisions"), list) else m.get("collisions"),
           "min_clearance": m.get("min_clearance"), "replans": summary["replans"],
           "planning_time": summary["planning_time"], "max_replan_time": summary["max_replan_time"],
           "obstacles": summary["obstacles"], "ticks": node.stats.ticks, "overruns": node.stats.overruns,
           "refreshed": node.stats.refreshed, "sensor_held": node.stats.held, "sensor_unpaired": node.stats.unpaired,
           "tick_p50_ms": float(np.percentile(ticks, 50)) if len(ticks) else None,
           "tick_p95_ms": float(np.percentile(ticks, 95)) if len(ticks) else None,
           "warnings": node.stats.warnings, "record": a.record}
    if tel.enabled or tel.times:
        viz = np.asarray(tel.times) * 1e3
        fld = np.asarray(tel.field_times) * 1e3
        out["telemetry"] = {"tick_p50_ms": float(np.percentile(viz, 50)) if len(viz) else None,
                            "tick_p95_ms": float(np.percentile(viz, 95)) if len(viz) else None,
                            "field_calls": int(len(fld)),
                            "field_mean_ms": float(fld.mean()) if len(fld) else None,
                            "field_max_ms": float(fld.max()) if len(fld) else None,
                            "field_ms_per_tick": float(fld.sum() / len(viz)) if len(viz) else None}
    if a.json:
        print(json.dumps(out))
    else:
        f = lambda x, spec: "-" if x is None else format(x, spec)  # noqa: E731
        print(f"demo summary ({out['world']}, task {out['task']!r})\n"
              f"  completed      {out['completed']}{' (interrupted)' if out['interrupted'] else ''} "
              f"(state {out['state']})\n"
              f"  visited        {' '.join(out['visited']) or '-'}"
              + (f" ({out['accepting_visits']} arrivals at the accepting state)" if not summary.get("cosafe", True)
                 else "") + "\n"
              f"  simulated time {f(out['sim_time'], '.1f')} s in {out['wall_time']:.1f} s wall "
              f"({f(out['sim_waited'], 'd')} steps waited for the service)\n"
              f"  distance       {f(out['distance'], '.2f')} m, collisions {f(out['collisions'], 'd')}, "
              f"min clearance {f(out['min_clearance'], '.3f')} m\n"
              f"  planning       {out['replans']} re-plans, {out['planning_time']:.3f} s total, "
              f"max re-plan {out['max_replan_time'] * 1e3:.1f} ms\n"
              f"  control loop   {out['ticks']} ticks, p50 {f(out['tick_p50_ms'], '.1f')} ms, "
              f"p95 {f(out['tick_p95_ms'], '.1f')} ms, {out['overruns']} overruns, "
              f"{out['refreshed']} commands refreshed, {out['sensor_held']} scans waited for their pose, "
              f"{out['warnings']} input warnings"
              + (f"\n  recording      {out['record']}" if out["record"] else "")
              + (f"\n  rerun logging  p50 {f(out['telemetry']['tick_p50_ms'], '.2f')} ms, "
                 f"p95 {f(out['telemetry']['tick_p95_ms'], '.2f')} ms per tick; "
                 f"navigation function and field: {out['telemetry']['field_calls']} calls "
                 f"(arrows, heat-map chunks), mean {f(out['telemetry']['field_mean_ms'], '.1f')} ms, "
                 f"max {f(out['telemetry']['field_max_ms'], '.1f')} ms, "
                 f"{f(out['telemetry']['field_ms_per_tick'], '.2f')} ms per tick"
                 if "telemetry" in out else ""))
    if sim_rc not in (None, 0):
        print(f"error: the simulator process exited with status {sim_rc} (its error is above)",
              file=sys.stderr)
        return 2
    return 0


def stop_child(proc: subprocess.Popen, timeout: float = 10.0) -> None:
    """Stop a child process: SIGTERM, then SIGKILL if it has not exited after ``timeout`` s."""
    if proc.poll() is not None:
        return
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def main(argv=None) -> int:
    """Entry point of the ``tamp-service`` console script."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.ERROR,
                        format="%(levelname)s %(name)s: %(message)s")
    from navigation.errors import HarmonicTampError

    try:
        return _cmd_run(args) if args.command == "run" else _cmd_demo(args)
    except (HarmonicTampError, OSError) as err:
        print(f"error: {err}".splitlines()[0], file=sys.stderr)
        return 2
    except Exception as err:  # zenoh.ZError when a session cannot be opened (port in use...)
        if type(err).__module__.startswith("zenoh"):
            print(f"error: zenoh: {err}".splitlines()[0], file=sys.stderr)
            return 2
        raise
    finally:
        gc.unfreeze()  # (a caller that goes on, e.g. a test, gets its collector back)


if __name__ == "__main__":
    sys.exit(main())
