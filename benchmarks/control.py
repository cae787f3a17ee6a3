"""Closed-loop benchmark of the oriented field + unicycle controller in the simulator (issue 4).

Run from the repository root::

    python -m benchmarks.control [--quick] [--out benchmarks/results] [--starts 10] [--goals 2] [--random 5] [--jobs 1]
                                 [--push-forward] [--standoff D] [--no-crawl-guard] [--no-route] [--unlimited]

For each world (``simple``, ``office`` with all obstacles known, and random forest worlds from
``tests.worldgen`` with ``gap=0.3`` so that they stay forests in the robot's configuration
space) and each random goal pose, the robot starts from random free poses and is driven by
:class:`navigation.Tracker` (the controller of :func:`navigation.track` with the crawl guard,
as the executive drives the robot, and the route rescue: on every loop or crawl engagement
the harmonic tree from the robot to the goal pose, :class:`tamp.routes.TreeRoutes`;
``--no-route``: the guard alone; ``--no-crawl-guard``: :func:`navigation.track` alone) on an
:class:`navigation.OrientedField` built on the obstacles grown by the robot radius, in
:class:`service.sim.Simulator` (dt = 0.1 s, noise-free), for at most 120 simulated seconds. A run *reaches* the goal pose when it is within 0.05 m and 0.1 rad.

Reported per world: success rate, collisions, minimum clearance (exact, robot disc to the true
obstacles), mean path length and time to goal of the successful runs, and two oscillation
measures: sign changes of the commanded turn rate per metre travelled (|omega| > 0.05 rad/s)
integrated absolute curvature ``sum |omega| dt`` over moving steps (rad), and the evaluation
suite's chatter (:func:`benchmarks.methods.chatter`: sign flips of the executed turn rate between
consecutive periods, both above 0.05 rad/s, per metre; a run is *flagged* above 1/m) with the
count of flagged runs; the longest time to goal of a successful run; *rate-limit jumps*: steps
whose command changed by more than 0.1 m/s in ``v`` or 0.6 rad/s in ``omega`` (the rate-limited
mode's bound, ``DV_BOUND`` / ``DOMEGA_BOUND``; 0 expected unless ``--unlimited``). ``--push-forward`` runs the controller with
``ControllerConfig(push_forward=True)`` and ``--standoff D`` with ``ControllerConfig(standoff=D)``
(``--standoff 0``: the controller without the stand-off; docs/control.md), ``--unlimited``
without the rate-limited mode (``navigation.control.UNLIMITED``; the rate limit is the
controller's default since the twenty-seventh session, ``--rate-limited`` is accepted and
changes nothing); the crawl guard
then engages ``standoff=0.03`` only while the robot crawls. Also the median
time of one controller step (field, Jacobian, command) with its target <= 2 ms, and the longest
step (a route's planning and the first field of its waypoints fall on one step). The
kernels are compiled (or loaded from numba's cache) before any run (:func:`tamp.run.prepare`),
so that a first run on a fresh checkout does not time their compilation as a step (about 1.2
s in each worker's first step otherwise).
Results: ``<out>/control.json`` and ``<out>/control.md`` (also printed); progress on stderr.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import navigation
from navigation._argtypes import integer, number
from navigation.control import RATE_LIMITED, UNLIMITED, ControllerConfig, track
from navigation.tracker import CrawlConfig, Tracker
from navigation.oriented import OrientedField, wrap_angle
from service.sim import Simulator
from tamp.routes import TreeRoutes
from tamp.run import prepare
from benchmarks._common import log, machine_info, write_results
from benchmarks.methods import chatter
from tests.worldgen import random_forest_world, random_free_points

__all__ = ["main", "run", "render_markdown", "STEP_TARGET"]

STEP_TARGET = 2e-3
POS_TOL, HEADING_TOL, MAX_TIME = 0.05, 0.1, 120.0
#: the issue's bounded change per 0.1 s step (the rate-limited mode's limits), counted in every mode
DV_BOUND, DOMEGA_BOUND = 0.1 * RATE_LIMITED["accel_max"], 0.1 * RATE_LIMITED["alpha_max"]
CHATTER_FLAG = 1.0  #: chatter per metre above which a run is flagged (as in benchmarks.evaluation)



def _episode(world, field, start, cfg, guard: bool = True, routes: TreeRoutes | None = None) -> dict:
    sim = Simulator(world, seed=0, pose=start)
    tracker = Tracker(cfg, CrawlConfig(), route=routes) if guard else None
    omegas, step_times, poses = [], [], []
    reached, jumps = False, 0
    for _ in range(int(MAX_TIME / sim.dt)):
        x, y, th = sim.pose
        if math.hypot(x - field.goal[0], y - field.goal[1]) < POS_TOL and abs(wrap_angle(th - field.heading)) < HEADING_TOL:
            reached = True
            break
        t0 = time.perf_counter()
        cmd = tracker.command(sim.time, (x, y, th), field) if guard else track((x, y, th), field, cfg)
        step_times.append(time.perf_counter() - t0)
        poses.append((x, y, th))
        result = sim.step((cmd.v, cmd.omega))
        pv, pw = omegas[-1] if omegas else (0.0, 0.0)
        if abs(cmd.v - pv) > DV_BOUND + 1e-9 or abs(cmd.omega - pw) > DOMEGA_BOUND + 1e-9:
            jumps += 1
        omegas.append((cmd.v, cmd.omega))
        if result.collision is not None:
            break
    m = sim.metrics
    signs = [np.sign(w) for v, w in omegas if abs(w) > 0.05]
    flips = sum(1 for a, b in zip(signs, signs[1:]) if a != b)
    curvature = sum(abs(w) * sim.dt for v, w in omegas if v > 1e-3)
    poses.append(tuple(sim.pose))
    return {"reached": reached, "collisions": len(m.collisions), "min_clearance": float(m.min_clearance),
            "distance": float(m.distance), "time": float(sim.time), "flips_per_m": flips / max(m.distance, 1e-9),
            "curvature": float(curvature), "chatter": chatter(poses, sim.dt), "step_times": step_times,
            "engagements": tracker.guard.engagements if guard else 0, "loops": tracker.guard.loops if guard else 0,
            "routes": tracker.routes if guard else 0,
            "jumps": jumps}


def _worlds(n_random: int):
    yield "simple", navigation.load_world("simple")
    yield "office", navigation.load_world("office")
    for seed in range(n_random):
        yield f"random12_seed{seed}", random_forest_world(seed, gap=0.3)


def _world_row(job) -> dict:
    """Closed-loop runs of one world: ``job = (name, world, starts, goals, push_forward, standoff,
    guard, unlimited, relax, route)`` (``standoff``, ``relax`` ``None``: the :class:`ControllerConfig`
    default; ``guard``: the crawl guard; ``route``: its route rescue)."""
    name, world, starts, goals, push_forward, standoff, guard, unlimited, relax, route = job
    routes = TreeRoutes(world) if guard and route else None
    rng = np.random.default_rng(0)
    r = world.robot.radius
    extra = {} if standoff is None else {"standoff": standoff}
    if relax is not None:
        extra["relax"] = relax
    if unlimited:
        extra.update(UNLIMITED)
    cfg = ControllerConfig.from_robot(world.robot, push_forward=push_forward, **extra)
    eps, times = [], []
    for g in range(goals):
        goal = random_free_points(world, 1, rng, margin=r + 0.2)[0]
        field = OrientedField(navigation.NavigationFunction(world, goal=goal, inflation=r),
                              heading=rng.uniform(-math.pi, math.pi))
        for s in random_free_points(world, starts, rng, margin=r + 0.05):
            e = _episode(world, field, (s[0], s[1], rng.uniform(-math.pi, math.pi)), cfg, guard, routes)
            times += e.pop("step_times")
            eps.append(e)
    ok = [e for e in eps if e["reached"]]
    row = {
        "world": name, "n_obstacles": len(world.obstacles), "runs": len(eps), "reached": len(ok),
        "success_rate": len(ok) / len(eps), "collisions": sum(e["collisions"] for e in eps),
        "min_clearance": min(e["min_clearance"] for e in eps),
        "mean_distance": statistics.fmean(e["distance"] for e in ok) if ok else None,
        "mean_time": statistics.fmean(e["time"] for e in ok) if ok else None,
        "flips_per_m": statistics.fmean(e["flips_per_m"] for e in eps),
        "curvature": statistics.fmean(e["curvature"] for e in eps),
        "chatter": statistics.fmean(e["chatter"] for e in eps),
        "flagged": sum(e["chatter"] > CHATTER_FLAG for e in eps),
        "engaged_runs": sum(e["engagements"] > 0 for e in eps),
        "loop_runs": sum(e["loops"] > 0 for e in eps),
        "route_runs": sum(e["routes"] > 0 for e in eps),
        "jumps": sum(e["jumps"] for e in eps),
        "max_time": max(e["time"] for e in ok) if ok else None,
        "step_median": statistics.median(times), "step_pass": statistics.median(times) <= STEP_TARGET,
        "step_max": max(times),
    }
    log(f"[bench] {name}: {row['reached']}/{row['runs']} reached, {row['collisions']} collisions")
    return row


def _total(rows: list[dict]) -> dict:
    runs = sum(r["runs"] for r in rows)
    ok = sum(r["reached"] for r in rows)

    def mean(key, weight):
        pairs = [(r[key], r[weight]) for r in rows if r[key] is not None and r[weight]]
        w = sum(n for _, n in pairs)
        return sum(x * n for x, n in pairs) / w if w else None

    return {"world": "all", "n_obstacles": None, "runs": runs, "reached": ok, "success_rate": ok / runs if runs else 0.0,
            "collisions": sum(r["collisions"] for r in rows), "min_clearance": min(r["min_clearance"] for r in rows),
            "mean_distance": mean("mean_distance", "reached"), "mean_time": mean("mean_time", "reached"),
            "flips_per_m": mean("flips_per_m", "runs"), "curvature": mean("curvature", "runs"),
            "chatter": mean("chatter", "runs"), "flagged": sum(r["flagged"] for r in rows),
            "engaged_runs": sum(r.get("engaged_runs", 0) for r in rows),
            "loop_runs": sum(r.get("loop_runs", 0) for r in rows),
            "route_runs": sum(r.get("route_runs", 0) for r in rows),
            "jumps": sum(r["jumps"] for r in rows),
            "max_time": max((r["max_time"] for r in rows if r["max_time"] is not None), default=None),
            "step_median": statistics.median(r["step_median"] for r in rows),
            "step_pass": all(r["step_pass"] for r in rows),
            "step_max": max((r["step_max"] for r in rows if r.get("step_max") is not None), default=None)}


def run(*, quick: bool = False, starts: int = 10, goals: int = 2, n_random: int = 5, jobs: int = 1,
        push_forward: bool = False, standoff: float | None = None, crawl_guard: bool = True,
        unlimited: bool = False, relax: float | None = None, route: bool = True) -> dict:
    if quick:
        starts, goals, n_random = 2, 1, 0
    work = [(name, world, starts, goals, push_forward, standoff, crawl_guard, unlimited, relax, route)
            for name, world in _worlds(n_random)
            if not quick or name == "simple"]
    prepare()  # kernels compiled before any step is timed (forked workers inherit them)
    if jobs > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            rows = list(pool.map(_world_row, work))
    else:
        rows = [_world_row(job) for job in work]
    rows.append(_total(rows))
    return {"benchmark": "control", "quick": quick,
            "settings": {"starts": starts, "goals": goals, "random": n_random, "push_forward": push_forward,
                         "standoff": standoff,
                         "crawl_guard": crawl_guard, "route": route, "unlimited": unlimited, "relax": relax},
            "tolerances": {"position": POS_TOL, "heading": HEADING_TOL, "max_time": MAX_TIME},
            "step_target": STEP_TARGET, "worlds": rows,
            "machine": machine_info()}


def _f(x, fmt: str) -> str:
    return "-" if x is None else format(x, fmt)


def render_markdown(result: dict) -> str:
    st = result["settings"]
    cmd = ("python -m benchmarks.control" + (" --quick" if result["quick"] else
                                             f" --starts {st['starts']} --goals {st['goals']} --random {st['random']}")
           + (" --push-forward" if st.get("push_forward") else "")
           + (f" --standoff {st['standoff']:g}" if st.get("standoff") is not None else "")
           + ("" if st.get("crawl_guard", True) else " --no-crawl-guard")
           + ("" if st.get("route", True) or not st.get("crawl_guard", True) else " --no-route")
           + (" --unlimited" if st.get("unlimited") else "")
           + (f" --relax {st['relax']:g}" if st.get("relax") is not None else ""))
    lines = ["# Closed-loop controller benchmark", "",
             f"`{cmd}` "
             f"(Python {result['machine']['python']}, {result['machine']['cpus']} CPUs). Goal pose reached: "
             f"within {POS_TOL} m and {HEADING_TOL} rad; dt = 0.1 s; obstacles grown by the robot radius; "
             + (("crawl guard on (navigation.Tracker)" + (", with the route rescue (tamp.routes.TreeRoutes)."
                                                          if st.get("route", True) else ", no route rescue."))
                if st.get("crawl_guard", True) else "plain controller (navigation.track, no crawl guard).")
             + " Guard: runs in which a crawl engaged the stand-off; loops: runs in which it detected a loop; "
               "routes: runs that planned a route; longest step: the slowest controller step (a route's "
               "planning and first field).", "",
             "| world | obstacles | reached | collisions | min clearance (m) | mean path (m) | mean time (s) "
             "| longest time (s) | turn-sign flips / m | integrated abs curvature (rad) | chatter / m "
             "| flagged (> 1/m) | guard | loops | routes | rate-limit jumps | controller step (ms) | <= 2 ms "
             "| longest step (ms) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---:|---:|"]
    for r in result["worlds"]:
        lines.append(f"| {r['world']} | {_f(r['n_obstacles'], 'd')} | {r['reached']}/{r['runs']} | {r['collisions']} | "
                     f"{r['min_clearance']:.4f} | {_f(r['mean_distance'], '.2f')} | {_f(r['mean_time'], '.1f')} | "
                     f"{_f(r.get('max_time'), '.1f')} | "
                     f"{r['flips_per_m']:.2f} | {r['curvature']:.2f} | {r['chatter']:.2f} | {r['flagged']}/{r['runs']} | "
                     f"{r.get('engaged_runs', 0)}/{r['runs']} | {r.get('loop_runs', 0)}/{r['runs']} | "
                     f"{r.get('route_runs', 0)}/{r['runs']} | "
                     f"{r.get('jumps', 0)} | "
                     f"{r['step_median'] * 1e3:.2f} | "
                     f"{'PASS' if r['step_pass'] else 'FAIL'} | "
                     f"{_f(None if r.get('step_max') is None else r['step_max'] * 1e3, '.1f')} |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.control", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="simple world, two runs (smoke test)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks") / "results", help="directory of control.{json,md}")
    parser.add_argument("--starts", type=integer(1), default=10, help="start poses per goal")
    parser.add_argument("--goals", type=integer(1), default=2, help="goal poses per world")
    parser.add_argument("--random", type=integer(0), default=5, help="random worlds (seeds 0..N-1)")
    parser.add_argument("--jobs", type=integer(1), default=1, help="worker processes (one world per task)")
    parser.add_argument("--push-forward", action="store_true",
                        help="track the push-forward direction (ControllerConfig(push_forward=True))")
    parser.add_argument("--unlimited", action="store_true",
                        help="without the controller's rate-limited mode, its default (accel_max 0, alpha_max 0, "
                             "brake_share 1: navigation.control.UNLIMITED)")
    parser.add_argument("--rate-limited", action="store_true",
                        help="the controller's default rate-limited mode (kept for old command lines; no effect)")
    parser.add_argument("--standoff", type=number(0.0), default=None,
                        help="ControllerConfig.standoff in m (0 turns the stand-off off; default: the config's)")
    parser.add_argument("--relax", type=number(0.0), default=None,
                        help="ControllerConfig.relax (0: track Upsilon itself; default: the config's)")
    parser.add_argument("--no-crawl-guard", action="store_true",
                        help="drive with navigation.track alone (no crawl guard, navigation.tracker)")
    parser.add_argument("--no-route", action="store_true",
                        help="the crawl guard without its route rescue (tamp.routes.TreeRoutes)")
    args = parser.parse_args(argv)
    result = run(quick=args.quick, starts=args.starts, goals=args.goals, n_random=args.random, jobs=args.jobs,
                 push_forward=args.push_forward, standoff=args.standoff, crawl_guard=not args.no_crawl_guard,
                 unlimited=args.unlimited, relax=args.relax, route=not args.no_route)
    write_results(args.out, "control", result, render_markdown(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
