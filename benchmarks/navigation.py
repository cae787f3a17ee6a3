"""Navigation-core benchmarks: forest build, construction and evaluation of navigation functions.

Run from the repository root::

    python -m benchmarks.navigation [--quick] [--out benchmarks/results] [--sizes 5 10 20 50]
                                    [--shared office cluttered20]

Worlds: random forest worlds with 5, 10, 20 and 50 obstacles (``tests.worldgen``, fixed seeds,
trees up to depth 4) and the shared ``office`` and ``cluttered20`` worlds; the goal is the centre
of each world's first region. Measured (medians over repeats of :func:`time.perf_counter`
intervals, after one warm-up call):

* ``forest_build``: :func:`navigation.build_forest` on the world's obstacles;
* ``nf_construction``: ``NavigationFunction(forest, goal)`` for an already built forest, the
  first on that forest (the goal-independent parts a forest's functions share,
  ``navigation.potential._SHARED``, are forgotten before every timed call);
* ``construction``: the total, ``NavigationFunction(build_forest(workspace, obstacles), goal)``
  (the issue's construction target counts the forest build);
* ``update``: the same total when one obstacle has just been added to a world whose other
  obstacles the forest memo already holds (``build_forest`` re-uses the memoised per-obstacle
  and pairwise results, paper 001 section 4.2.2), measured by
  :func:`benchmarks.online.bench_world` (``OnlineWorld.apply`` + ``navigation_function``):
  median over up to 7 choices of the added obstacle. This is what a map change costs in the
  running service.

``forest_build`` and ``construction`` are *cold*: the forest memo is cleared
(:func:`navigation.forest.clear_cache`) before every timed call.
* ``one_point``: ``nf.evaluate(q, 2)`` (value, gradient, Hessian) for one point ``q (2,)``,
  median over 200 random free points;
* ``batch_10k``: ``nf.evaluate(Q, 2)`` for 10 000 random free points;
* ``grid_200``: ``nf.evaluate(G, 1)`` (values and gradients) on a 200 x 200 grid over the
  workspace's bounding box (free and non-free points).

Targets (for 20 obstacles): total construction <= 5 ms, one point <= 1 ms, 10k batch <= 0.2 s,
200 x 200 grid <= 0.5 s. Results go to ``<out>/navigation.json`` and ``<out>/navigation.md``
(a table with a PASS/FAIL column per target); the table is also printed to stdout, progress to
stderr. ``--quick`` takes fewer repeats and points (a smoke test, not a measurement).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

import navigation
from navigation._argtypes import integer, world_name
from navigation import NavigationFunction, build_forest
from navigation.forest import clear_cache
from navigation import potential
from benchmarks._common import log, machine_info, verdict, write_results
from benchmarks.online import bench_world as online_update
from tests.worldgen import random_forest_world, random_free_points

__all__ = ["main", "run", "render_markdown", "TARGETS", "SIZES", "SHARED"]

SIZES = (5, 10, 20, 50)  #: obstacle counts of the random worlds
SEEDS = {5: 0, 10: 0, 20: 0, 50: 0}  #: fixed worldgen seeds (each gives a tree of depth 4)
MAX_DEPTH = 4
SHARED = ("office", "cluttered20")
#: metric -> (target in seconds, label); the targets are specified for 20 obstacles
TARGETS = {
    "construction": (5e-3, "total construction (forest build + navigation function) <= 5 ms"),
    "update": (5e-3, "construction after adding one obstacle to a memoised world <= 5 ms"),
    "one_point": (1e-3, "one point <= 1 ms"),
    "batch_10k": (0.2, "10k batch <= 0.2 s"),
    "grid_200": (0.5, "200x200 grid <= 0.5 s"),
}
TARGET_OBSTACLES = 20
#: rows whose obstacle count is at most this are held to the targets (office has 22)
TARGET_APPLIES_UP_TO = 25

FULL = {"forest_repeats": 21, "construction_repeats": 50, "update_picks": 7, "points": 200, "batch_repeats": 7,
        "grid_repeats": 7}
QUICK = {"forest_repeats": 1, "construction_repeats": 3, "update_picks": 2, "points": 10, "batch_repeats": 1,
         "grid_repeats": 1}



def _median_time(fn: Callable[[], object], repeats: int, warmup: int = 1,
                 setup: Callable[[], object] | None = None) -> float:
    for _ in range(warmup):
        fn()
    samples = []
    for _ in range(max(1, repeats)):
        if setup is not None:
            setup()  # untimed
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def _median_cold(fn: Callable[[], object], repeats: int) -> float:
    """Median time of ``fn`` with the forest memo cleared before every call (untimed)."""
    samples = []
    for _ in range(max(1, repeats)):
        clear_cache()
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return statistics.median(samples)


def _grid(workspace, n: int = 200) -> np.ndarray:
    b = workspace.boundary_points(512)
    lo, hi = b.min(axis=0), b.max(axis=0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n), indexing="ij")
    return np.stack((gx.ravel(), gy.ravel()), axis=1)


def _worlds(sizes: Sequence[int], shared: Sequence[str]):
    for n in sizes:
        seed = SEEDS.get(n, 0)
        yield f"random{n}", f"tests.worldgen.random_forest_world({seed}, n_obstacles={n}, max_depth={MAX_DEPTH})", \
            lambda n=n, seed=seed: random_forest_world(seed, n_obstacles=n, max_depth=MAX_DEPTH)
    for name in shared:
        yield name, f"navigation.load_world({name!r})", lambda name=name: navigation.load_world(name)


def bench_world(world, settings: dict, seed: int = 0) -> dict:
    """All measurements for one world (see the module docstring)."""
    rng = np.random.default_rng(seed)
    goal = list(world.regions.values())[0].center
    forest_build = _median_cold(lambda: build_forest(world.workspace, world.obstacles), settings["forest_repeats"])
    forest = world.forest(0.0)
    nf_construction = _median_time(lambda: NavigationFunction(forest, goal), settings["construction_repeats"],
                                   setup=potential._SHARED.clear)
    construction = _median_cold(lambda: NavigationFunction(build_forest(world.workspace, world.obstacles), goal),
                                settings["forest_repeats"])
    update = online_update(world, settings["update_picks"])["update"]
    nf = NavigationFunction(forest, goal)
    pts = random_free_points(world, settings["points"], rng)
    nf.evaluate(pts[0], 2)  # warm-up
    singles = []
    for q in pts:
        t0 = time.perf_counter()
        nf.evaluate(q, 2)
        singles.append(time.perf_counter() - t0)
    batch = random_free_points(world, 10_000, rng)
    batch_10k = _median_time(lambda: nf.evaluate(batch, 2), settings["batch_repeats"])
    grid = _grid(forest.workspace)
    grid_200 = _median_time(lambda: nf.evaluate(grid, 1), settings["grid_repeats"])
    ev = nf.evaluate(grid, 1)
    return {
        "n_obstacles": len(forest.obstacles),
        "n_trees": len(forest.roots),
        "max_depth": forest.max_depth,
        "goal": [float(goal[0]), float(goal[1])],
        "forest_build": forest_build,
        "nf_construction": nf_construction,
        "construction": construction,
        "update": update,
        "one_point": statistics.median(singles),
        "batch_10k": batch_10k,
        "grid_200": grid_200,
        "grid_free_fraction": float(ev.free.mean()),
        "grid_finite": bool(np.isfinite(ev.value).all() and np.isfinite(ev.gradient).all()),
    }


def run(*, quick: bool = False, sizes: Sequence[int] = SIZES, shared: Sequence[str] = SHARED) -> dict:
    """Run the benchmarks and return the JSON-ready result."""
    settings = QUICK if quick else FULL
    rows = []
    for name, source, make in _worlds(sizes, shared):
        log(f"[bench] {name}: generating / loading ({source})")
        t0 = time.perf_counter()
        world = make()
        log(f"[bench] {name}: world ready in {time.perf_counter() - t0:.2f} s; measuring")
        row = {"world": name, "source": source, **bench_world(world, settings)}
        applies = row["n_obstacles"] <= TARGET_APPLIES_UP_TO
        row["target_applies"] = applies
        row["pass"] = {k: bool(row[k] <= limit) for k, (limit, _) in TARGETS.items()}
        rows.append(row)
        log(f"[bench] {name}: forest {1e3 * row['forest_build']:.1f} ms, navigation function "
             f"{1e3 * row['nf_construction']:.2f} ms, total construction {1e3 * row['construction']:.1f} ms, after adding one obstacle "
             f"{1e3 * row['update']:.1f} ms, one point {1e3 * row['one_point']:.3f} ms, "
             f"10k batch {row['batch_10k']:.3f} s, grid {row['grid_200']:.3f} s")
    return {
        "benchmark": "navigation",
        "generated": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "quick": quick,
        "settings": settings,
        "targets": {k: {"seconds": limit, "label": label, "obstacles": TARGET_OBSTACLES}
                    for k, (limit, label) in TARGETS.items()},
        "machine": machine_info(),
        "units": "seconds",
        "worlds": rows,
    }



def render_markdown(result: dict) -> str:
    """The results table (times in ms or s, one PASS/FAIL column per target)."""
    lines = [
        "# Navigation benchmarks",
        "",
        f"Generated {result['generated']} by `python -m benchmarks.navigation"
        f"{' --quick' if result['quick'] else ''}` (Python {result['machine']['python']}, numpy "
        f"{result['machine']['numpy']}, {result['machine']['cpus']} CPUs). Medians of "
        "`time.perf_counter` intervals after a warm-up call."
        + (" **Quick mode: a smoke test, not a measurement.**" if result["quick"] else ""),
        "",
        "| world | obstacles | trees | depth | forest build (ms) | NF construction (ms) "
        "| total construction (ms) | <= 5 ms | after adding one obstacle (ms) | <= 5 ms "
        "| one point (ms) | <= 1 ms | 10k batch (s) | <= 0.2 s | 200x200 grid (s) | <= 0.5 s |",
        "|---|---:|---:|---:|---:|---:|---:|:---:|---:|:---:|---:|:---:|---:|:---:|---:|:---:|",
    ]
    for r in result["worlds"]:
        lines.append(
            f"| {r['world']} | {r['n_obstacles']} | {r['n_trees']} | {r['max_depth']} "
            f"| {1e3 * r['forest_build']:.1f} | {1e3 * r['nf_construction']:.2f} "
            f"| {1e3 * r['construction']:.1f} | {verdict(r, 'construction')} "
            f"| {1e3 * r['update']:.1f} | {verdict(r, 'update')} "
            f"| {1e3 * r['one_point']:.3f} | {verdict(r, 'one_point')} "
            f"| {r['batch_10k']:.3f} | {verdict(r, 'batch_10k')} "
            f"| {r['grid_200']:.3f} | {verdict(r, 'grid_200')} |")
    lines += [
        "",
        f"Targets are specified for {TARGET_OBSTACLES} obstacles and apply to every row with at most "
        f"{TARGET_APPLIES_UP_TO} obstacles; verdicts in parentheses (larger worlds) are informative. "
        "Forest build: `build_forest(workspace, obstacles)`; NF construction: `NavigationFunction(forest, goal)` "
        "on a built forest, the first on it (the parts shared by a forest's functions forgotten); "
        "total construction (the <= 5 ms target): both, "
        "`NavigationFunction(build_forest(workspace, obstacles), goal)`, measured as one call with the forest "
        "memo cleared (cold). After adding one obstacle: the same call when the memo holds every other "
        "obstacle (a map change in the running service; median over up to 7 choices of the added obstacle). "
        "One point: `nf.evaluate(q, 2)` for `q` of shape `(2,)` (median over random free points); "
        "10k batch: `nf.evaluate(Q, 2)`, 10 000 random free points; grid: `nf.evaluate(G, 1)` on "
        "200 x 200 points over the workspace's bounding box (non-free points included).",
        "",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None, *, sizes: Sequence[int] | None = None,
         shared: Sequence[str] | None = None) -> int:
    """Entry point; ``sizes`` / ``shared`` (e.g. ``sizes=(5,), shared=()``) override the command line."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.navigation", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="few repeats and points (smoke test)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks") / "results",
                        help="directory of navigation.json and navigation.md")
    parser.add_argument("--sizes", type=integer(1), nargs="*", default=list(SIZES),
                        help="obstacle counts of the random worlds")
    parser.add_argument("--shared", type=world_name, nargs="*", default=list(SHARED), help="shared worlds to include")
    args = parser.parse_args(argv)
    sizes = tuple(args.sizes if sizes is None else sizes)
    shared = tuple(args.shared if shared is None else shared)
    result = run(quick=args.quick, sizes=sizes, shared=shared)
    write_results(args.out, "navigation", result, render_markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
