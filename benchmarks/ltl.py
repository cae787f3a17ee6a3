"""Mission-layer benchmarks: LTL translation, product size, lasso planning and re-planning.

Run from the repository root::

    python -m benchmarks.ltl [--quick] [--out benchmarks/results] [--world office]

Measured (medians of :func:`time.perf_counter` intervals; the first call of each measurement
is reported separately as ``first``, since the translator and the BDD package keep process-wide
caches):

* ``translate``: ``to_buchi(parse(f))`` for the pattern suite (visit, sequenced, ordered,
  patrolling, avoidance, response, until), the four size-target formulas of issue 3 and the
  office mission, with the automaton's states and edges; ``first`` is measured in a fresh
  interpreter for each formula (cold caches);
* ``plan``: for the office world (6 regions x 8 orientations + the start pose): building the
  navigation map, the product and the optimal lasso, i.e. ``MissionPlanner(world, buchi)``
  with the already translated automaton (``plan_with_translation`` includes translation);
  the size of the product part reachable from the start;
* ``replan``: after one random edge-cost change (fixed seed; a random region pair gets a new
  cost, a fresh change each repeat), :meth:`MissionPlanner.replan` from the start state.
* ``scaling``: missions over ``n`` regions, visiting all of them (``F r0 & ... & F r{n-1}``,
  whose minimal automaton has ``2^n`` states) and patrolling all of them (``G F r0 & ...``):
  the translation the planner runs (``exclusive=True``: one region at a time, ``n + 1``
  letters), the full-alphabet translation (``2^n`` letters; up to ``n = 8``, it took about a
  minute at 10), and ``MissionPlanner`` with its first plan on an obstacle-free world with the
  ``n`` regions on a grid. One run each, fresh proposition names (no memo reused).

Targets (issue 3): office mission translation <= 50 ms; product plus lasso plan for the office
map <= 100 ms; re-planning after a cost change <= 20 ms. Results go to ``<out>/ltl.json`` and
``<out>/ltl.md`` (a table with a PASS/FAIL column per target); the table is also printed to
stdout, progress to stderr. ``--quick`` takes fewer repeats (a smoke test, not a measurement).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import random
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import navigation
from navigation._argtypes import world_name
from benchmarks._common import log, machine_info, write_results
from tamp import MissionPlanner
from tamp.ltl import parse, to_buchi

__all__ = ["main", "run", "render_markdown", "TARGETS", "PATTERNS"]

#: name -> (formula, state-count target or None)
PATTERNS = {
    "visit": ("F a", None),
    "sequenced visit": ("F(a & F(b & F c))", None),
    "ordered visit": ("(!b U a) & (!c U b) & F c", None),
    "patrolling": ("G F a & G F b & G F c", None),
    "avoidance": ("F a & F b & G !c", None),
    "response": ("G(a -> F b)", None),
    "until": ("!b U a", None),
    "size: sequence of 6": ("F(a & F(b & F(c & F(d & F(e & F f)))))", 7),
    "size: 4 recurrences": ("G F a & G F b & G F c & G F d", 5),
    "size: response + avoid": ("G(a -> F b) & G !c", 3),
}
OFFICE_TARGET_STATES = 12
TARGETS = {
    "translate": (50e-3, "office mission translation <= 50 ms"),
    "plan": (100e-3, "product + lasso plan (office) <= 100 ms"),
    "replan": (20e-3, "re-plan after a cost change <= 20 ms"),
}
FULL = {"translate_repeats": 20, "plan_repeats": 20, "replan_repeats": 50}
QUICK = {"translate_repeats": 2, "plan_repeats": 2, "replan_repeats": 5}



def _times(fn: Callable[[], object], repeats: int) -> tuple[float, float]:
    """(first call, median of ``repeats`` further calls)."""
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    samples = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - t0)
    return first, statistics.median(samples)


def _cold_translation(formula: str) -> float | None:
    """Seconds of one ``to_buchi(parse(formula))`` in a fresh interpreter (imports excluded)."""
    code = ("import time, sys; from tamp.ltl import parse, to_buchi; t = time.perf_counter(); "
            "to_buchi(parse(sys.argv[1])); print(time.perf_counter() - t)")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path.cwd()), os.environ.get("PYTHONPATH", "")]))
    try:
        out = subprocess.run([sys.executable, "-c", code, formula], capture_output=True, text=True,
                             timeout=120, env=env, check=True)
        return float(out.stdout.strip())
    except (subprocess.SubprocessError, ValueError, OSError):  # pragma: no cover - reported as null
        return None


def bench_translation(settings: dict, office_task: str) -> list[dict]:
    rows = []
    suite = dict(PATTERNS)
    suite["office mission"] = (office_task, OFFICE_TARGET_STATES)
    for name, (formula, size_target) in suite.items():
        f = parse(formula)
        cold = _cold_translation(formula)
        _, median = _times(lambda: to_buchi(parse(formula)), settings["translate_repeats"])
        b = to_buchi(f)
        rows.append({"pattern": name, "formula": str(f), "states": b.num_states, "edges": b.num_edges,
                     "accepting": len(b.accepting), "size_target": size_target,
                     "size_pass": None if size_target is None else b.num_states <= size_target,
                     "first": cold, "median": median})
        log(f"[bench] translate {name}: {b.num_states} states, {b.num_edges} edges, "
             f"median {1e3 * median:.2f} ms, cold {1e3 * (cold or 0):.1f} ms")
    return rows


def bench_planning(settings: dict, world_name: str, seed: int = 0) -> dict:
    world = navigation.load_world(world_name)
    buchi = to_buchi(parse(world.task))
    first, plan_t = _times(lambda: MissionPlanner(world, buchi), settings["plan_repeats"])
    _, with_tr = _times(lambda: MissionPlanner(world, world.task), settings["plan_repeats"])
    p = MissionPlanner(world, buchi)
    plan = p.plan()
    prod = p.product
    sources = [prod.encode(n, q) for n, q in p.current]
    n_states, n_edges = prod.reachable(sources)
    rng = random.Random(seed)
    names = list(world.regions)
    replans, reused, computed = [], 0, 0
    p.replan()
    for _ in range(settings["replan_repeats"]):
        u, v = rng.sample(names, 2)
        p.set_cost(u, v, rng.uniform(0.5, 8.0))
        t0 = time.perf_counter()
        p.replan()
        replans.append(time.perf_counter() - t0)
        reused += p.last_stats["cycles_reused"]
        computed += p.last_stats["cycles_computed"]
    res = {
        "world": world_name, "regions": len(world.regions), "n_orient": p.navmap.n_orient,
        "map_nodes": p.navmap.num_nodes, "map_edges": p.navmap.num_edges,
        "automaton_states": buchi.num_states, "automaton_edges": buchi.num_edges,
        "product_states": n_states, "product_edges": n_edges,
        "product_potential_states": prod.N * prod.Q,
        "plan_first": first, "plan": plan_t, "plan_with_translation": with_tr,
        "replan": statistics.median(replans), "replan_max": max(replans),
        "replan_cycles_reused": reused, "replan_cycles_computed": computed,
        "initial_plan": plan.to_dict(),
    }
    log(f"[bench] {world_name}: product {n_states} states / {n_edges} edges, plan "
         f"{1e3 * plan_t:.2f} ms, replan {1e3 * res['replan']:.2f} ms")
    return res


SCALING_SIZES = (4, 6, 8, 10, 12)
SCALING_FULL_MAX = 8  # the full alphabet beyond: 59 s at n = 10 before the exclusive one


def _grid_world(names: Sequence[str], task: str):
    regions = {r: {"center": [0.8 + 1.2 * (i % 6), 0.8 + 1.5 * (i // 6)], "radius": 0.2}
               for i, r in enumerate(names)}
    return navigation.World.from_dict({
        "name": "grid", "workspace": {"center": [4.0, 2.5], "width": 8.0, "height": 5.0, "theta": 0.0, "s": 0.99},
        "obstacles": [], "regions": regions,
        "robot": {"radius": 0.1, "start": [0.3, 0.3, 0.0], "v_max": 0.5, "omega_max": 1.5},
        "lidar": {"range": 1.0, "fov": 6.283185, "beams": 360, "noise_std": 0.0, "rate_hz": 10}, "task": task})


def bench_scaling(sizes: Sequence[int] = SCALING_SIZES) -> list[dict]:
    rows = []
    for n in sizes:
        for kind, op in (("visit all", "F"), ("patrol all", "G F")):
            def mission(tag: str) -> tuple[list[str], str]:
                names = [f"{tag}{n}r{i}" for i in range(n)]
                return names, " & ".join(f"{op} {r}" for r in names)

            names, text = mission("x")
            t0 = time.perf_counter()
            b = to_buchi(parse(text), exclusive=True)
            t_excl = time.perf_counter() - t0
            t_full = full_states = None
            if n <= SCALING_FULL_MAX:
                _, text_f = mission("f")
                t0 = time.perf_counter()
                full_states = to_buchi(parse(text_f)).num_states
                t_full = time.perf_counter() - t0
            names_p, text_p = mission("p")
            world = _grid_world(names_p, text_p)
            t0 = time.perf_counter()
            MissionPlanner(world, world.task).plan()
            t_plan = time.perf_counter() - t0
            rows.append({"mission": kind, "regions": n, "states": b.num_states, "edges": b.num_edges,
                         "translate_exclusive": t_excl, "translate_full": t_full, "full_states": full_states,
                         "planner": t_plan})
            log(f"[bench] scaling {kind} n={n}: {b.num_states} states, exclusive {1e3 * t_excl:.1f} ms, "
                f"full {'-' if t_full is None else f'{1e3 * t_full:.1f} ms'}, planner {1e3 * t_plan:.1f} ms")
    return rows


def run(*, quick: bool = False, world: str = "office") -> dict:
    """Run the benchmarks and return the JSON-ready result."""
    settings = QUICK if quick else FULL
    office_task = navigation.load_world(world).task
    translation = bench_translation(settings, office_task)
    planning = bench_planning(settings, world)
    scaling = bench_scaling(SCALING_SIZES[:3] if quick else SCALING_SIZES)
    office_row = translation[-1]
    measured = {"translate": office_row["median"], "plan": planning["plan"], "replan": planning["replan"]}
    return {
        "benchmark": "ltl",
        "generated": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "quick": quick,
        "settings": settings,
        "targets": {k: {"seconds": limit, "label": label} for k, (limit, label) in TARGETS.items()},
        "measured": measured,
        "pass": {k: bool(measured[k] <= TARGETS[k][0]) for k in TARGETS},
        "machine": machine_info(),
        "units": "seconds",
        "translation": translation,
        "planning": planning,
        "scaling": scaling,
    }


def _ms(x) -> str:
    return "n/a" if x is None else f"{1e3 * x:.2f}"


def render_markdown(result: dict) -> str:
    """The results tables (times in ms, PASS/FAIL per target)."""
    pl = result["planning"]
    lines = [
        "# Mission-layer (LTL) benchmarks",
        "",
        f"Generated {result['generated']} by `python -m benchmarks.ltl"
        f"{' --quick' if result['quick'] else ''}` (Python {result['machine']['python']}, "
        f"{result['machine']['cpus']} CPUs). Medians of `time.perf_counter` intervals."
        + (" **Quick mode: a smoke test, not a measurement.**" if result["quick"] else ""),
        "",
        "## Targets",
        "",
        "| target | measured (ms) | limit (ms) | verdict |",
        "|---|---:|---:|:---:|",
    ]
    for k, (limit, label) in TARGETS.items():
        lines.append(f"| {label} | {_ms(result['measured'][k])} | {1e3 * limit:.0f} "
                     f"| {'PASS' if result['pass'][k] else 'FAIL'} |")
    lines += [
        "",
        "## Translation",
        "",
        "| pattern | formula | states | edges | size target | median (ms) | cold (ms) |",
        "|---|---|---:|---:|:---:|---:|---:|",
    ]
    for r in result["translation"]:
        tgt = "" if r["size_target"] is None else \
            f"<= {r['size_target']} {'PASS' if r['size_pass'] else 'FAIL'}"
        lines.append(f"| {r['pattern']} | `{r['formula']}` | {r['states']} | {r['edges']} | {tgt} "
                     f"| {_ms(r['median'])} | {_ms(r['first'])} |")
    lines += [
        "",
        f"## Product and planning ({pl['world']})",
        "",
        f"Navigation map: {pl['regions']} regions x {pl['n_orient']} orientations + start = "
        f"{pl['map_nodes']} nodes, {pl['map_edges']} edges. Automaton: {pl['automaton_states']} states, "
        f"{pl['automaton_edges']} edges. Product reachable from the start: {pl['product_states']} "
        f"states, {pl['product_edges']} edges (of {pl['product_potential_states']} potential states).",
        "",
        "| measurement | ms |",
        "|---|---:|",
        f"| map + product + lasso plan (automaton given), median | {_ms(pl['plan'])} |",
        f"| same, first call | {_ms(pl['plan_first'])} |",
        f"| same, including translation, median | {_ms(pl['plan_with_translation'])} |",
        f"| re-plan after one cost change, median | {_ms(pl['replan'])} |",
        f"| re-plan after one cost change, max | {_ms(pl['replan_max'])} |",
        "",
        f"Re-planning reused {pl['replan_cycles_reused']} cached cycle searches and ran "
        f"{pl['replan_cycles_computed']} over {result['settings']['replan_repeats']} changes. "
        f"Initial plan: prefix {' '.join(pl['initial_plan']['prefix'])}, suffix "
        f"{' '.join(pl['initial_plan']['suffix'])}, cost {pl['initial_plan']['cost']:.3f}.",
        "",
    ]
    if result.get("scaling"):
        lines += [
            "## Missions over n regions",
            "",
            "One run each. *exclusive*: the translation the planner runs (one region at a time, "
            "n + 1 letters); *full*: every one of the 2^n letters (not run beyond "
            f"{SCALING_FULL_MAX} regions); *planner*: `MissionPlanner(world, task).plan()` on an "
            "obstacle-free world with the regions on a grid, translation included.",
            "",
            "| mission | regions | states | edges | exclusive (ms) | full (ms) | planner (ms) |",
            "|---|---:|---:|---:|---:|---:|---:|",
        ]
        for r in result["scaling"]:
            lines.append(f"| {r['mission']} | {r['regions']} | {r['states']} | {r['edges']} "
                         f"| {_ms(r['translate_exclusive'])} | {_ms(r['translate_full'])} | {_ms(r['planner'])} |")
        lines.append("")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.ltl", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="few repeats (smoke test)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks") / "results",
                        help="directory of ltl.json and ltl.md")
    parser.add_argument("--world", type=world_name, default="office", help="world whose mission and regions are planned")
    args = parser.parse_args(argv)
    result = run(quick=args.quick, world=args.world)
    write_results(args.out, "ltl", result, render_markdown(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
