"""Simulator benchmarks: lidar scans, and simulator steps (exact arc + swept collision check).

Run from the repository root::

    python -m benchmarks.sim [--quick] [--out benchmarks/results] [--shared cluttered20 office]
                             [--sizes 20]

Worlds: the shared ``cluttered20`` (20 obstacles, the target world) and ``office`` worlds and
random forest worlds (``tests.worldgen``, seed 0) with the given obstacle counts. Measured
(medians of :func:`time.perf_counter` intervals, each sample timed on its own, after a
warm-up call):

* ``scan_360``: ``Simulator.scan()``, one 360-beam full-circle scan (range of the world file,
  1 m for the shared worlds) at random free poses with random headings;
* ``step_free``: ``Simulator.step((v_max, omega))`` from random free poses at least 0.1 m clear
  (integration, swept check and exact clearance of the new pose);
* ``step_contact``: a step at ``v_max`` from a pose 1-4 cm from the nearest obstacle, heading
  at it, that ends in a contact (the swept check localises it and stops the robot);
* ``arc``: :func:`service.sim.arc_pose` alone.

Targets: one 360-beam scan of a 20-obstacle world <= 2 ms (issue 4); one free step <= 2 ms
(ours: a 50 Hz loop of step + scan fits in its budget). Results go to ``<out>/sim.json`` and
``<out>/sim.md`` (a table with PASS/FAIL columns); the table is also printed to stdout, progress
to stderr. ``--quick`` takes few samples (a smoke test, not a measurement).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import math
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import navigation
from navigation._argtypes import integer, world_name
from service.sim import LidarConfig, Simulator, arc_pose
from benchmarks._common import log, machine_info, verdict, write_results
from tests.worldgen import random_forest_world, random_free_points

__all__ = ["main", "run", "render_markdown", "TARGETS", "SHARED", "SIZES"]

SHARED = ("cluttered20", "office")
SIZES = (20,)
#: metric -> (target in seconds, label)
TARGETS = {
    "scan_360": (2e-3, "360-beam scan <= 2 ms"),
    "step_free": (2e-3, "free step <= 2 ms"),
}
TARGET_APPLIES_UP_TO = 25  #: rows with at most this many obstacles are held to the targets
FULL = {"poses": 300, "steps": 300, "contacts": 150, "arcs": 2000}
QUICK = {"poses": 5, "steps": 5, "contacts": 5, "arcs": 20}



def _timed(fn) -> tuple[float, object]:
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def bench_world(world, settings: dict, seed: int = 0) -> dict:
    """All measurements for one world (see the module docstring)."""
    rng = np.random.default_rng(seed)
    lidar = LidarConfig(world.lidar.range, 2 * math.pi, 360, world.lidar.noise_std, world.lidar.rate_hz)
    sim = Simulator(world, seed=seed, lidar=lidar)
    r = world.robot.radius
    poses = random_free_points(world, settings["poses"], rng, margin=r + 0.01)
    sim.reset((*poses[0], 0.0))
    sim.scan()  # warm-up
    scans, returns = [], []
    for q in poses:
        sim.reset((*q, float(rng.uniform(-math.pi, math.pi))))
        dt_, ranges = _timed(sim.scan)
        scans.append(dt_)
        returns.append(int(np.isfinite(ranges).sum()))
    steps = []
    for q in random_free_points(world, settings["steps"], rng, margin=r + 0.1):
        sim.reset((*q, float(rng.uniform(-math.pi, math.pi))))
        cmd = (world.robot.v_max, float(rng.uniform(-world.robot.omega_max, world.robot.omega_max)))
        steps.append(_timed(lambda: sim.step(cmd))[0])
    contacts, tried = [], 0
    cand = random_free_points(world, 40 * settings["contacts"], rng, margin=r + 0.01)
    c, _ = sim.clearance_at(cand)
    cand = cand[(c > 0.01) & (c < 0.04)]
    h = 1e-5
    for q in cand:
        if len(contacts) >= settings["contacts"]:
            break
        g = np.array([(sim.clearance_at(q + e)[0][0] - sim.clearance_at(q - e)[0][0]) / (2 * h)
                      for e in (np.array([h, 0.0]), np.array([0.0, h]))])
        tried += 1
        sim.reset((*q, math.atan2(-g[1], -g[0])))
        dt_, res = _timed(lambda: sim.step((world.robot.v_max, 0.0)))
        if res.collision is not None:
            contacts.append(dt_)
    pose = (1.0, 2.0, 0.3)
    arcs = []
    for _ in range(settings["arcs"]):
        arcs.append(_timed(lambda: arc_pose(pose, 0.4, 0.7, 0.1))[0])
    return {
        "n_obstacles": len(world.obstacles),
        "lidar_range": world.lidar.range,
        "mean_returns": float(np.mean(returns)),
        "scan_360": statistics.median(scans),
        "scan_360_p90": float(np.percentile(scans, 90)),
        "step_free": statistics.median(steps),
        "step_contact": statistics.median(contacts) if contacts else math.nan,
        "contacts_measured": len(contacts),
        "contacts_tried": tried,
        "arc": statistics.median(arcs),
    }


def _worlds(shared: Sequence[str], sizes: Sequence[int]):
    for name in shared:
        yield name, f"navigation.load_world({name!r})", lambda name=name: navigation.load_world(name)
    for n in sizes:
        yield f"random{n}", f"tests.worldgen.random_forest_world(0, n_obstacles={n})", \
            lambda n=n: random_forest_world(0, n_obstacles=n)


def run(*, quick: bool = False, shared: Sequence[str] = SHARED, sizes: Sequence[int] = SIZES) -> dict:
    """Run the benchmarks and return the JSON-ready result."""
    settings = QUICK if quick else FULL
    rows = []
    for name, source, make in _worlds(shared, sizes):
        log(f"[bench] {name}: loading ({source}) and measuring")
        row = {"world": name, "source": source, **bench_world(make(), settings)}
        row["target_applies"] = row["n_obstacles"] <= TARGET_APPLIES_UP_TO
        row["pass"] = {k: bool(row[k] <= limit) for k, (limit, _) in TARGETS.items()}
        rows.append(row)
        log(f"[bench] {name}: scan {1e3 * row['scan_360']:.3f} ms, free step {1e3 * row['step_free']:.3f} ms, "
             f"contact step {1e3 * row['step_contact']:.3f} ms, arc {1e6 * row['arc']:.2f} us")
    return {
        "benchmark": "sim",
        "generated": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "quick": quick,
        "settings": settings,
        "targets": {k: {"seconds": limit, "label": label} for k, (limit, label) in TARGETS.items()},
        "metrics": ["scan_360", "step_free", "step_contact", "arc"],
        "machine": machine_info(),
        "units": "seconds",
        "worlds": rows,
    }



def render_markdown(result: dict) -> str:
    """The results table (ms / us, one PASS/FAIL column per target)."""
    m = result["machine"]
    lines = [
        "# Simulator benchmarks",
        "",
        f"Generated {result['generated']} by `python -m benchmarks.sim{' --quick' if result['quick'] else ''}` "
        f"(Python {m['python']}, numpy {m['numpy']}, {m['cpus']} CPUs, load average "
        f"{', '.join(f'{x:.2f}' for x in (m['load_average'] or []))}). Medians of `time.perf_counter` "
        "intervals after a warm-up call."
        + (" **Quick mode: a smoke test, not a measurement.**" if result["quick"] else ""),
        "",
        "| world | obstacles | lidar range (m) | returns / scan | 360-beam scan (ms) | <= 2 ms | scan p90 (ms) "
        "| free step (ms) | <= 2 ms | contact step (ms) | arc (us) |",
        "|---|---:|---:|---:|---:|:---:|---:|---:|:---:|---:|---:|",
    ]
    for r in result["worlds"]:
        lines.append(
            f"| {r['world']} | {r['n_obstacles']} | {r['lidar_range']:g} | {r['mean_returns']:.0f} "
            f"| {1e3 * r['scan_360']:.3f} | {verdict(r, 'scan_360')} | {1e3 * r['scan_360_p90']:.3f} "
            f"| {1e3 * r['step_free']:.3f} | {verdict(r, 'step_free')} "
            f"| {1e3 * r['step_contact']:.3f} | {1e6 * r['arc']:.2f} |")
    lines += [
        "",
        "Scan: `Simulator.scan()` (exact ray casting, 360 beams over the full circle) at random free poses. "
        "Free step: `Simulator.step((v_max, omega))` at least 0.1 m from obstacles (exact arc, swept "
        "collision check, exact clearance of the new pose). Contact step: a step at `v_max` from 1-4 cm "
        "in front of an obstacle that ends in a contact. Arc: `arc_pose` alone. The 2 ms scan target is "
        "issue 4's (for 20 obstacles); the 2 ms step target is ours. Verdicts in parentheses (more than "
        f"{TARGET_APPLIES_UP_TO} obstacles) are informative.",
        "",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point (``python -m benchmarks.sim``)."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.sim", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="few samples (smoke test)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks") / "results",
                        help="directory of sim.json and sim.md")
    parser.add_argument("--shared", type=world_name, nargs="*", default=list(SHARED), help="shared worlds to include")
    parser.add_argument("--sizes", type=integer(1), nargs="*", default=list(SIZES),
                        help="obstacle counts of random worlds to include")
    args = parser.parse_args(argv)
    result = run(quick=args.quick, shared=tuple(args.shared), sizes=tuple(args.sizes))
    write_results(args.out, "sim", result, render_markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
