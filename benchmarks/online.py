"""Online-world benchmark: navigation-function update per added obstacle vs a rebuild (issue 6 item 1).

Run from the repository root::

    python -m benchmarks.online [--quick] [--out benchmarks/results] [--sizes 5 10 20 50 100]

For random forest worlds with 5, 10, 20, 50 and 100 obstacles (``tests.worldgen``, fixed
seeds, trees up to depth 4) and up to 10 obstacles spread over each world's list, it measures

* ``update``: :meth:`navigation.online.OnlineWorld.apply` adding that obstacle to a world that
  holds all the others (the forest memo is warm, as in the running service), followed by
  ``navigation_function(goal)``: the incremental update of paper 001 section 4.2.2;
* ``rebuild``: the same navigation function built from scratch,
  ``NavigationFunction(build_forest(workspace, obstacles), goal)`` with the forest memo cleared.

Medians over the chosen obstacles (``time.perf_counter``); the added obstacle's kind (star,
leaf, joint) is counted. Results go to ``<out>/online.json`` and ``<out>/online.md``; progress to
stderr. ``--quick`` uses two obstacles per world and sizes 5 and 10 (a smoke test).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import statistics
import sys
import time
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from benchmarks._common import log, machine_info, write_results
from navigation import ForestError, NavigationFunction, build_forest
from navigation._argtypes import integer
from navigation.forest import clear_cache
from navigation.online import OnlineWorld
from tests.worldgen import random_forest_world

__all__ = ["main", "run", "render_markdown", "SIZES"]

SIZES = (5, 10, 20, 50, 100)
SEED = 3
MAX_DEPTH = 4


def bench_world(world, picks: int) -> dict:
    obs = list(world.obstacles)
    goal = list(world.regions.values())[0].center
    chosen = sorted(set(np.linspace(0, len(obs) - 1, min(picks, len(obs))).round().astype(int).tolist()))
    updates, rebuilds, kinds = [], [], Counter()
    for k in chosen:
        clear_cache()
        try:
            ow = OnlineWorld(world.workspace, {i: o for i, o in enumerate(obs) if i != k})
        except ForestError:
            continue  # the rest alone is refused (cannot happen for subsets of a forest; kept for safety)
        ow.navigation_function(goal)
        t0 = time.perf_counter()
        change = ow.apply(added={k: obs[k]})
        ow.navigation_function(goal)
        updates.append(time.perf_counter() - t0)
        kinds.update(kind for _, kind in change.kinds)
        clear_cache()
        t0 = time.perf_counter()
        NavigationFunction(build_forest(world.workspace, obs), goal)
        rebuilds.append(time.perf_counter() - t0)
    if not updates:
        raise RuntimeError("no obstacle could be measured")
    return {
        "n_obstacles": len(obs),
        "samples": len(updates),
        "kinds": dict(kinds),
        "update": statistics.median(updates),
        "update_max": max(updates),
        "rebuild": statistics.median(rebuilds),
    }


def run(*, quick: bool = False, sizes: Sequence[int] = SIZES) -> dict:
    rows = []
    for n in sizes:
        log(f"[bench] random{n}: generating (tests.worldgen.random_forest_world({SEED}, n_obstacles={n}))")
        world = random_forest_world(SEED, n_obstacles=n, max_depth=MAX_DEPTH)
        row = {"world": f"random{n}", **bench_world(world, 2 if quick else 10)}
        rows.append(row)
        log(f"[bench] random{n}: update {1e3 * row['update']:.1f} ms, rebuild {1e3 * row['rebuild']:.1f} ms")
    return {
        "benchmark": "online",
        "generated": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "quick": quick,
        "machine": machine_info(),
        "worlds": rows,
    }


def render_markdown(result: dict) -> str:
    lines = [
        "# Online world: update per added obstacle vs rebuild",
        "",
        f"Generated {result['generated']} by `python -m benchmarks.online{' --quick' if result['quick'] else ''}` "
        f"(Python {result['machine']['python']}, {result['machine']['cpus']} CPUs)."
        + (" **Quick mode: a smoke test, not a measurement.**" if result["quick"] else ""),
        "",
        "| world | obstacles | added obstacles (kinds) | update median (ms) | update max (ms) | rebuild median (ms) | speed-up |",
        "|---|---:|---|---:|---:|---:|---:|",
    ]
    for r in result["worlds"]:
        kinds = ", ".join(f"{v} {k}" for k, v in sorted(r["kinds"].items()))
        lines.append(f"| {r['world']} | {r['n_obstacles']} | {r['samples']} ({kinds}) | {1e3 * r['update']:.1f} "
                     f"| {1e3 * r['update_max']:.1f} | {1e3 * r['rebuild']:.1f} | {r['rebuild'] / r['update']:.1f}x |")
    lines += ["", "Update: `OnlineWorld.apply(added=...)` + `navigation_function(goal)` with the forest memo holding "
              "every other obstacle. Rebuild: `NavigationFunction(build_forest(...), goal)` with the memo cleared.", ""]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.online", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two obstacles per world, sizes 5 and 10 (smoke test)")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results"), help="output directory")
    ap.add_argument("--sizes", type=integer(1), nargs="+", default=None, help="obstacle counts (default 5 10 20 50 100)")
    args = ap.parse_args(argv)
    sizes = args.sizes or ((5, 10) if args.quick else SIZES)
    result = run(quick=args.quick, sizes=sizes)
    write_results(args.out, "online", result, render_markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
