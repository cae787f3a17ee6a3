"""End-to-end mission runs: the executive in closed loop with the simulator (issue 6 item 5).

Library: :func:`run_mission`. Command line (FORMATS.md contract)::

    python -m tamp.run WORLD.json [--task FORMULA] [--known] [--seed N] [--max-time S] [--json]

runs the world's mission (obstacles unknown except ``known_obstacles``; ``--known``: all known)
and prints a summary, or with ``--json`` one JSON object on stdout with ``completed``,
``collisions``, ``distance``, ``execution_time``, ``planning_time``, ``max_replan_time``,
``replans``, ``visited``, ``oscillation`` (and extra fields, see :func:`run_mission`). Progress
(state changes) goes to stderr. Exit 0 when the run worked, whatever the mission's outcome; 2
with one ``error: ...`` line on stderr for bad arguments, an invalid world or a task the
planner refuses.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from navigation.errors import HarmonicTampError
from navigation._argtypes import positive, seed
from navigation.world import World, load_world

from .executive import Executive, ExecutiveConfig, ExecutiveState

__all__ = ["run_mission", "drive", "command_ok", "main", "prepare", "OMEGA_DEADBAND"]

OMEGA_DEADBAND = 0.05  #: |omega| below this (rad/s) does not count for the oscillation measure


def prepare(notice=None) -> float:
    """Get a process ready for a long run: compile (or load from numba's cache) every compiled
    kernel the executive uses (navigation's, perception's fit and shapes, the roadmap's, the
    trees' A*, the planner's product search; see
    :mod:`navigation.kernels`), then move the start-up heap out of the garbage collector's sight
    (``gc.freeze``): it never becomes garbage, and a full collection that scans it (~150 000
    objects, about 100 ms) would otherwise stall some tick. ``notice(message)`` is called once if
    the compilation takes longer than a second (the first run on a machine). Returns the
    seconds it took. The heap is unfrozen at exit (``atexit``): objects left frozen are never
    freed, and extension modules that check for leaks at teardown report them (nanobind's
    "leaked instances" from OMPL after ``python -m benchmarks.evaluation``)."""
    import atexit
    import gc
    import threading

    from navigation.kernels import warm_up
    from perception._fit_kernel import warm_up as warm_up_fit

    from ._astar_kernel import warm_up as warm_up_astar
    from ._product_kernel import warm_up as warm_up_product
    from ._segment_kernel import warm_up as warm_up_segments

    timer = threading.Timer(1.0, notice) if notice is not None else None
    if timer is not None:
        timer.start()
    seconds = warm_up() + warm_up_fit() + warm_up_segments() + warm_up_astar() + warm_up_product()
    if timer is not None:
        timer.cancel()
    gc.collect()
    gc.freeze()
    atexit.unregister(gc.unfreeze)  # (once however often prepare() is called)
    atexit.register(gc.unfreeze)
    return seconds


def _oscillation(omegas, distance: float) -> float:
    """Sign changes of the commanded turn rate (``|omega| > OMEGA_DEADBAND``) per metre."""
    w = np.asarray(omegas, dtype=float)
    s = np.sign(w[np.abs(w) > OMEGA_DEADBAND])
    flips = int(np.count_nonzero(s[1:] != s[:-1])) if len(s) > 1 else 0
    return flips / distance if distance > 1e-9 else 0.0


def drive(ex: Executive, sim, max_time: float):
    """Tick ``ex`` in the simulator ``sim`` until ``max_time`` simulated seconds: the pose at
    every step, a scan at the lidar rate. Yields ``(result, cpu)`` (the tick's
    :class:`~tamp.executive.TickResult` and its process-CPU seconds) before the simulator steps
    with the tick's command; a caller that stops early leaves that command unexecuted."""
    period = 1.0 / sim.world.lidar.rate_hz
    next_scan = 0.0
    while sim.time < max_time - 1e-9:
        pose = sim.pose_message()
        scan = None
        if sim.time >= next_scan - 1e-9:
            scan = sim.scan_message()
            next_scan += period
        c0 = time.process_time()
        res = ex.tick(pose, scan=scan, now=sim.time)
        yield res, time.process_time() - c0
        sim.step((res.v, res.omega))


def command_ok(res, control) -> bool:
    """Whether a tick's command is finite and within ``control``'s speed and turn-rate limits."""
    v, w = res.v, res.omega
    return (math.isfinite(v) and math.isfinite(w) and abs(v) <= control.v_max + 1e-12
            and abs(w) <= control.omega_max + 1e-12)


def run_mission(world, task: str | None = None, known: bool = False, seed: int = 0, max_time: float = 300.0,
                config: ExecutiveConfig | None = None, progress=None, record: bool = False,
                executive_cls: type[Executive] = Executive) -> dict:
    """Run ``world``'s mission (or ``task``) in the simulator with the :class:`Executive`.

    Parameters
    ----------
    world : World or str
        A world or a world file / built-in name.
    task : str, optional
        LTL mission instead of the world's ``task``.
    known : bool
        All obstacles known at start.
    seed : int
        Simulator seed (lidar noise).
    max_time : float
        Simulated seconds before the run is stopped.
    progress : callable(str), optional
        Called with a line on every state or target change.
    record : bool
        Also return the trajectory (``"trajectory"``: the pose at each tick), the commands
        (``"commands"``: ``(v, omega)`` sent at each tick), the waypoint tracked at each tick
        (``"waypoints"``: the ``status`` field ``waypoint``, ``[x, y, theta]`` or ``None``) and
        whether the tick re-planned (``"replanned"``).
    executive_cls : type
        :class:`Executive` or a subclass (the evaluation suite's baselines), constructed as
        ``executive_cls(world, task, known=known, config=config)``.

    Returns
    -------
    dict
        FORMATS.md fields ``completed`` (mission done: a co-safe mission accepted for good, a
        recurrent one after its accepting state was reached twice, i.e. one suffix round),
        ``collisions`` (simulator contact events), ``distance`` (m), ``execution_time``
        (simulated s), ``planning_time`` (wall s: initial synthesis + every re-plan),
        ``max_replan_time`` (wall s), ``replans`` (re-plans after the initial synthesis),
        ``visited`` (regions entered, in order), ``oscillation`` (sign changes of omega per
        metre); and ``world``, ``state``, ``message``, ``initial_planning_time``,
        ``replan_p95``, ``tick_median``, ``tick_p95``, ``tick_max`` (wall s per tick),
        ``tick_cpu_median``, ``tick_cpu_p95``, ``replan_cpu_p95``, ``max_replan_cpu`` (process CPU
        s: the same figures without the time other processes take on a loaded machine),
        ``bad_commands`` (non-finite or out-of-limit commands: must be 0), ``min_clearance``,
        ``map_changes``, ``trees_planned``, ``guard_stops`` (ticks the motion guard slowed),
        ``deferred_plans`` (re-plans that waited a tick after a heavy map update),
        ``gap_searches`` (transitions no roadmap connected: passages searched), ``looks`` (look
        points the robot went to before it could be blocked), ``obstacles`` (estimates at the
        end), ``messages``.

    Raises
    ------
    HarmonicTampError
        Invalid world (``WorldError``) or a task the planner refuses (``TampError``).
    """
    from service.sim import Simulator

    if not isinstance(world, World):
        world = load_world(world)
    max_time = float(max_time)
    if not (math.isfinite(max_time) and max_time > 0):
        raise ValueError(f"max_time must be a positive number of seconds, got {max_time!r}")
    cfg = config or ExecutiveConfig()
    ex = executive_cls(world, task, known=known, config=cfg)
    sim = Simulator(world, seed=seed)
    ticks, cpu, omegas, poses, commands, targets, replanned = [], [], [], [], [], [], []
    bad = 0
    last = None
    blocked_since = None
    completed = False
    for res, dt in drive(ex, sim, max_time):
        cpu.append(dt)
        ticks.append(res.compute)
        v, w = res.v, res.omega
        if not command_ok(res, ex.control):
            bad += 1
        key = (res.status["state"], res.status["target"])
        if progress is not None and key != last:
            progress(f"[{sim.time:6.1f} s] {key[0]}" + (f" -> {key[1]}" if key[1] else "")
                     + (f": {res.status['message']}" if res.status["message"] and key[0] != "executing" else ""))
        last = key
        if ex.completed:
            completed = True
            break
        if ex.state is ExecutiveState.BLOCKED:
            blocked_since = sim.time if blocked_since is None else blocked_since
            if sim.time - blocked_since >= cfg.blocked_timeout:
                break
        else:
            blocked_since = None
        if v != 0.0:
            omegas.append(w)
        if record:
            poses.append(tuple(sim.pose))
            commands.append((v, w))
            targets.append(res.status["waypoint"])
            replanned.append(bool(res.replanned))
    m = sim.metrics
    rt = ex.replan_times
    t = np.asarray(ticks) if ticks else np.zeros(1)
    c = np.asarray(cpu) if cpu else np.zeros(1)
    rc = ex.replan_cpu_times
    out = {
        "world": world.name,
        "completed": bool(completed),
        "collisions": len(m.collisions),
        "distance": float(m.distance),
        "execution_time": float(sim.time),
        "planning_time": float(ex.planning_time),
        "max_replan_time": float(max(rt)) if rt else 0.0,
        "replans": max(ex.replans - 1, 0),  # the first plan is the initial synthesis
        "visited": list(ex.visited),
        "oscillation": _oscillation(omegas, m.distance),
        "state": ex.state.value,
        "message": ex.message,
        "initial_planning_time": float(ex.initial_time or 0.0),
        "replan_p95": float(np.percentile(rt, 95)) if rt else 0.0,
        "tick_median": float(np.median(t)),
        "tick_p95": float(np.percentile(t, 95)),
        "tick_max": float(t.max()),
        "tick_cpu_median": float(np.median(c)),
        "tick_cpu_p95": float(np.percentile(c, 95)),
        "replan_cpu_p95": float(np.percentile(rc, 95)) if rc else 0.0,
        "max_replan_cpu": float(max(rc)) if rc else 0.0,
        "bad_commands": bad,
        "min_clearance": float(m.min_clearance),
        "map_changes": ex.map_changes,
        "trees_planned": ex.trees_planned,
        "guard_stops": ex.guard_stops,
        "deferred_plans": ex.deferred_plans,
        "gap_searches": ex.gap_searches,
        "looks": ex.looks,
        "obstacles": len(ex.obstacles),
        "messages": ex.messages[-20:],
    }
    if record:
        out["trajectory"] = poses
        out["commands"] = commands
        out["waypoints"] = targets
        out["replanned"] = replanned
    return out


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2 (FORMATS.md), no usage dump
        raise _Usage(message)


class _Usage(Exception):
    pass


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="python -m tamp.run", formatter_class=argparse.ArgumentDefaultsHelpFormatter,
                description="Run a world's LTL mission end to end in the simulator (executive + perception "
                            "+ harmonic trees) and report the outcome.")
    p.add_argument("world", help="world file (FORMATS.md) or built-in name (simple, office, cluttered20)")
    p.add_argument("--task", default=None, help="LTL mission over region names instead of the world's task")
    p.add_argument("--known", action="store_true", help="all obstacles known at start (no discovery)")
    p.add_argument("--seed", type=seed, default=0, help="simulator seed (lidar noise, >= 0)")
    p.add_argument("--max-time", type=positive, default=300.0, help="simulated seconds before the run stops")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    return p


def main(argv=None) -> int:
    import gc

    try:
        return _main(argv)
    finally:
        gc.unfreeze()  # (prepare froze the start-up heap; a caller that goes on gets its collector back)


def _main(argv) -> int:
    try:
        args = _parser().parse_args(argv)
        world = load_world(args.world)
        prepare(lambda: print("tamp.run: compiling the kernels (first run on this machine only, up to about a "
                              "minute) ...", file=sys.stderr, flush=True))
        # refuse a bad task before the run starts
        progress = (lambda line: print(line, file=sys.stderr, flush=True))
        t0 = time.perf_counter()
        result = run_mission(world, args.task, args.known, args.seed, args.max_time, progress=progress)
    except _Usage as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except (HarmonicTampError, ValueError, OSError) as err:
        print(f"error: {err}".replace("\n", " "), file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result, allow_nan=False, default=float))
    else:
        print(f"{result['world']}: completed={result['completed']} collisions={result['collisions']} "
              f"distance={result['distance']:.2f} m execution={result['execution_time']:.1f} s "
              f"planning={result['planning_time']:.3f} s (initial {result['initial_planning_time']:.3f} s, "
              f"{result['replans']} replans, max {result['max_replan_time'] * 1e3:.0f} ms) "
              f"tick p95={result['tick_p95'] * 1e3:.1f} ms visited={' '.join(result['visited'])} "
              f"oscillation={result['oscillation']:.2f}/m state={result['state']} "
              f"(wall {time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
