"""Soak run of the executive: a patrol mission for a long simulated time (issue 6; the service is
long-running, so nothing may grow with the time it has run).

Run from the repository root::

    python -m benchmarks.soak [--world office] [--task "G F p1 & G F d1 & G F d3"]
                              [--duration 3600] [--window 300] [--out DIR] [--quick]

The world's obstacles are unknown (as in :func:`tamp.run.run_mission`); the executive is ticked
in the simulator at the lidar rate for ``--duration`` simulated seconds, whatever its state (a
recurrent mission never ends; a co-safe one leaves the robot idle once done). Every ``--window``
simulated seconds a row: the memory Python has allocated since the executive's construction
began and still holds (``tracemalloc``, after a garbage collection: the executive, perception,
forests, trees, caches), the process's resident set
size, the per-tick compute (median and 95th percentile over the window; ``tracemalloc`` slows
Python down, so compare the windows with each other, not with ``benchmarks.executive``),
re-plans, distance, arrivals at the accepting state, collisions and commands that were not
finite or out of limits. The summary gives the growth of traced memory from the end of the
first window (caches filled) to the end of the run, per simulated hour. ``--quick``: ``simple``,
``G F a & G F b``, 120 s in 30 s windows (the CI smoke test).

Output in ``--out`` (default ``benchmarks/results``): ``soak.json``, ``soak.md`` (also
printed). Progress on stderr, one line per window.
"""

from __future__ import annotations

import argparse
import gc
import math
import time
import tracemalloc
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import navigation
from navigation._argtypes import positive, world_name
from benchmarks._common import log, machine_info, write_results

__all__ = ["main", "run", "render_markdown"]

DEFAULT_TASK = {"office": "G F p1 & G F d1 & G F d3", "simple": "G F a & G F b"}


def _rss_mb() -> float | None:
    """Resident set size (MB) from ``/proc/self/status``; ``None`` where there is none."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def run(world_name: str, task: str, duration: float, window: float) -> dict:
    """The soak run (module doc); returns the rows and the summary."""
    from service.sim import Simulator
    from tamp.executive import Executive
    from tamp.run import command_ok, drive, prepare

    if not (math.isfinite(duration) and duration > 0 and math.isfinite(window) and 0 < window <= duration):
        raise ValueError(f"need 0 < window <= duration, got window {window!r}, duration {duration!r}")
    world = navigation.load_world(world_name)
    prepare()
    tracemalloc.start()  # the executive from its construction on, not the kernels prepare() loaded
    ex = Executive(world, task)
    sim = Simulator(world, seed=0)
    mark = window
    ticks: list[float] = []
    bad, replans0, rows = 0, ex.replans, []
    wall0 = time.perf_counter()

    def row() -> None:
        """The window that ended with the last step."""
        nonlocal ticks, replans0, mark
        gc.collect()
        traced, _peak = tracemalloc.get_traced_memory()
        t = np.asarray(ticks)
        m = sim.metrics
        r = {"sim_time": round(float(sim.time), 3), "wall": time.perf_counter() - wall0,
             "traced_mb": traced / 1e6, "rss_mb": _rss_mb(),
             "tick_median_ms": 1e3 * float(np.median(t)), "tick_p95_ms": 1e3 * float(np.percentile(t, 95)),
             "replans": ex.replans - replans0, "distance": float(m.distance),
             "accepting_visits": int(ex.accepting_visits), "visits": len(ex.visited),
             "collisions": len(m.collisions), "bad_commands": bad, "state": ex.state.value,
             "obstacles": len(ex.obstacles)}
        rows.append(r)
        log(f"[soak] {r['sim_time']:7.0f} s sim, {r['wall']:6.0f} s wall: traced {r['traced_mb']:.1f} MB, "
            f"tick p95 {r['tick_p95_ms']:.1f} ms, {r['accepting_visits']} accepting visits, "
            f"{r['collisions']} collisions, {r['state']}")
        ticks, replans0, mark = [], ex.replans, mark + window

    try:
        for res, _cpu in drive(ex, sim, duration):
            if sim.time >= mark - 1e-9:  # this tick starts the next window
                row()
            ticks.append(res.compute)
            bad += not command_ok(res, ex.control)
        row()  # the last window, up to ``duration``
    finally:
        tracemalloc.stop()
    first, last = rows[0], rows[-1]
    hours = (last["sim_time"] - first["sim_time"]) / 3600.0
    summary = {"sim_time": last["sim_time"], "wall": last["wall"], "distance": last["distance"],
               "accepting_visits": last["accepting_visits"], "collisions": last["collisions"],
               "bad_commands": last["bad_commands"], "state": last["state"],
               "traced_first_mb": first["traced_mb"], "traced_last_mb": last["traced_mb"],
               "traced_max_mb": max(r["traced_mb"] for r in rows),
               "growth_mb_per_hour": (last["traced_mb"] - first["traced_mb"]) / hours if hours > 0 else None,
               "tick_p95_first_ms": first["tick_p95_ms"], "tick_p95_last_ms": last["tick_p95_ms"]}
    return {"world": world.name, "task": task, "duration": duration, "window": window, "rows": rows,
            "summary": summary}


def render_markdown(result: dict, command: str) -> str:
    s = result["summary"]
    lines = [f"# Soak run: `{result['world']}`, `{result['task']}`, {result['duration']:g} simulated s", "",
             f"Command: `{command}`", "",
             "| sim s | wall s | traced MB | RSS MB | tick median ms | tick p95 ms | re-plans | distance m "
             "| accepting visits | collisions | bad commands | state |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in result["rows"]:
        rss = f"{r['rss_mb']:.0f}" if r["rss_mb"] is not None else "-"
        lines.append(f"| {r['sim_time']:.0f} | {r['wall']:.0f} | {r['traced_mb']:.1f} | {rss} | "
                     f"{r['tick_median_ms']:.2f} | {r['tick_p95_ms']:.2f} | {r['replans']} | {r['distance']:.1f} | "
                     f"{r['accepting_visits']} | {r['collisions']} | {r['bad_commands']} | {r['state']} |")
    growth = s["growth_mb_per_hour"]
    lines += ["", f"Traced memory {s['traced_first_mb']:.1f} MB after the first window, {s['traced_last_mb']:.1f} MB at "
              f"the end (largest {s['traced_max_mb']:.1f} MB)"
              + (f": {growth:+.1f} MB per simulated hour" if growth is not None else "")
              + f". Tick p95 {s['tick_p95_first_ms']:.1f} ms in the first window, {s['tick_p95_last_ms']:.1f} ms in the "
              f"last (under tracemalloc). {s['accepting_visits']} arrivals at the accepting state, "
              f"{s['distance']:.1f} m, {s['collisions']} collisions, {s['bad_commands']} bad commands.", "",
              f"Machine: {machine_info()}", ""]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.soak", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--world", type=world_name, default="office", help="world file or built-in name")
    parser.add_argument("--task", default=None, help="LTL mission (default: a patrol of the world's regions)")
    parser.add_argument("--duration", type=positive, default=3600.0, help="simulated seconds")
    parser.add_argument("--window", type=positive, default=300.0, help="simulated seconds per row")
    parser.add_argument("--out", type=Path, default=Path("benchmarks") / "results", help="output directory")
    parser.add_argument("--quick", action="store_true", help="simple world, 120 s (smoke test)")
    a = parser.parse_args(argv)
    if a.quick:
        a.world, a.duration, a.window = "simple", 120.0, 30.0
    task = a.task
    if task is None:
        if a.world in DEFAULT_TASK:
            task = DEFAULT_TASK[a.world]
        else:
            regions = list(navigation.load_world(a.world).regions)
            task = " & ".join(f"G F {r}" for r in regions)
    try:
        result = run(a.world, task, a.duration, a.window)
    except (ValueError, navigation.HarmonicTampError) as err:
        raise SystemExit(f"python -m benchmarks.soak: {err}") from None
    command = "python -m benchmarks.soak" + (" --quick" if a.quick else
                                             f" --world {a.world} --duration {a.duration:g} --window {a.window:g}")
    if a.task is not None:
        command += f" --task {a.task!r}"
    result["machine"] = machine_info()
    result["benchmark"] = "soak"
    write_results(a.out, "soak", result, render_markdown(result, command))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
