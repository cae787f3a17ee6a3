"""Evaluation suite: paper 001 Table 1 reproduced on our worlds, all methods side by side (issue 8).

Run from the repository root::

    python -m benchmarks.evaluation [--quick] [--out DIR] [--random N]
                                    [--methods HT HT-fields OHPF NF RRT* RRT*-buffer oracle]
                                    [--jobs N] [--max-time S] [--rrt-seed N] [--rrt-draws K]

Scenarios: the shared worlds ``office`` (its mission and its urgent ``u1`` event at 60 s) and
``cluttered20`` (visit ``d1 .. d4``), and the random forest worlds
``tests.worldgen.random_forest_world(seed, gap=0.3)`` for seeds ``0 .. N-1`` (visit-all missions
over their 4 regions). Obstacles are unknown except the world file's ``known_obstacles``; the
simulator is seeded with 0. ``--quick`` runs two small random worlds (8 obstacles, seeds 0
and 1) and a reduced timing sweep: the CI smoke test.

Methods (:mod:`benchmarks.methods`): ``HT``, ``HT-fields`` (HT with the paper's execution, a
field per waypoint), ``OHPF``, ``NF``, ``RRT*`` and ``RRT*-buffer`` (RRT* keeping HT's 0.15 m
clearance instead of 5 cm; both skipped, with the reason in the report, when OMPL's Python
bindings do not work) and ``oracle``. RRT* is randomised: each RRT* method runs ``--rrt-draws``
(3) times per scenario with OMPL seeds ``--rrt-seed`` (1), 2, ... (every draw reproducible) and
the scenario keeps the draw with the median distance (:func:`median_draw`), listing them all.

Every method's run on every scenario is a process of its own, forked from the prepared parent
(:func:`benchmarks._common.isolated_map`): no run is timed with the memos (forest results, LTL
translation) that another method's run on the same scenario filled. ``--jobs N`` runs N at a
time.

Metrics per method and scenario: completed, collisions, planning time (initial and total, wall
s), execution time (simulated s), travel distance and its ratio to the oracle (and to the
tour keeping the method's own clearance, :data:`benchmarks.methods.CLEARANCE`: what is left of
the distance once its safety margin is paid for), replans,
oscillation (sign changes of the commanded turn rate per metre, ``tamp.run``), chatter
(sign flips of the executed turn rate between consecutive control periods per metre;
*oscillation flagged* when above ``CHATTER_FLAG``), minimum clearance. Over the random set:
success rate, and median and 90th percentile of every metric over the completed runs.

Output in ``--out`` (default ``benchmarks/results/evaluation``, ``.../evaluation_quick`` with
``--quick``): ``evaluation.json``, ``evaluation.md`` (also printed), ``traj_<scenario>.png``
(trajectories of all methods) and ``potential_time.png`` (potential construction from scratch
vs incremental update against the number of obstacles). Progress on stderr.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from benchmarks._common import isolated_map, log, machine_info, markdown_table, write_results
from benchmarks.methods import ADAPTATION, CLEARANCE, METHODS, ompl_status, oracle_tour, run_method
from navigation._argtypes import integer, positive, world_name

__all__ = ["main", "run", "scenario", "render_markdown", "chatter_table", "targets", "CHATTER_FLAG", "SHARED"]

SHARED = ("office", "cluttered20")
CHATTER_FLAG = 1.0  #: chatter (flips per metre) above which a run's oscillation is flagged
QUICK_OBSTACLES = 8
#: the clearances (m beyond the robot radius) whose tours the shared worlds' report lists, besides
#: those of the methods run (:data:`benchmarks.methods.CLEARANCE`)
SHARED_CLEARANCES = (0.0, 0.03, 0.05, 0.10, 0.15)
RANDOM_KEYS = ("distance", "ratio", "own_ratio", "execution_time", "planning_time", "initial_planning_time",
               "max_replan_time", "replans", "oscillation", "chatter", "min_clearance")
_VISIT_ALL = re.compile(r"^\s*F\s*\w+(\s*&\s*F\s*\w+)*\s*$")


# ------------------------------------------------------------------------------- scenarios
def scenario(name: str, quick: bool = False):
    """``(world, task or None)`` of a scenario name: a built-in world or ``random<seed>``."""
    import navigation

    if name.startswith("random"):
        from tests.worldgen import random_forest_world

        kw = {"n_obstacles": QUICK_OBSTACLES} if quick else {}
        w = random_forest_world(int(name[len("random"):]), gap=0.3, **kw)
        return w, " & ".join(f"F {r}" for r in w.regions)
    return navigation.load_world(name), None


def _run_one(args) -> dict:
    """One method on one scenario (in a child process of its own, :func:`benchmarks._common.isolated_map`)."""
    name, m, quick, max_time, rrt_seed = args
    world, task = scenario(name, quick)
    t0 = time.perf_counter()
    try:
        r = run_method(m, world, task, max_time=max_time, rrt_seed=rrt_seed)
    except Exception as err:  # noqa: BLE001 - a crashing baseline is a result, not the end of the suite
        r = {"error": f"{type(err).__name__}: {err}", "completed": False}
    r["wall"] = time.perf_counter() - t0
    return r


def _log_run(args, r: dict) -> None:
    name, m, seed = args[0], args[1], args[4]
    log(f"[eval] {name} {m}{'' if seed is None else f' (seed {seed})'}: " + (f"error {r['error']}" if "error" in r else
                                  f"completed={r['completed']} collisions={r['collisions']} "
                                  f"distance={r['distance']:.2f} planning={r['planning_time']:.2f} s "
                                  f"chatter={r['chatter']:.2f}/m (wall {r['wall']:.0f} s)"))


def _scenario_result(name: str, methods: Sequence[str], quick: bool, runs: dict) -> dict:
    """A scenario's runs (method -> result) with the oracle's tour added (it needs HT's order
    when the mission is not visit-all) and every run's ratio to it."""
    world, task = scenario(name, quick)
    out = {"scenario": name, "world": world.name, "task": task or world.task, "n_obstacles": len(world.obstacles),
           "runs": {m: runs[m] for m in methods if m in runs}}
    if "oracle" in methods:
        visit_all = bool(_VISIT_ALL.match(out["task"])) and not world.events
        ref = out["runs"].get("HT", {}).get("visited") or list(world.regions)
        t0 = time.perf_counter()
        d, order = oracle_tour(world, ref, visit_all=visit_all)
        out["runs"]["oracle"] = {"distance": d, "visited": order, "completed": d is not None,
                                 "orders": "all orders" if visit_all else "HT's order", "wall": time.perf_counter() - t0}
        # the tour at each method's own clearance (and, on the shared worlds, at a few more):
        # how much of a method's distance is its clearance, how much its execution
        wanted = {CLEARANCE.get(m) for m in out["runs"]} | (set(SHARED_CLEARANCES) if name in SHARED else set())
        bounds = {0.0: d}
        for b in sorted(c for c in wanted if c):
            try:
                bounds[b] = oracle_tour(world, ref, visit_all=visit_all, buffer=b)[0]
            except ValueError:  # the start itself closer than b to an obstacle
                bounds[b] = None
        out["clearance_tours"] = {f"{b:g}": v for b, v in sorted(bounds.items())}
        for m, r in out["runs"].items():
            if "distance" in r and d:
                r["ratio"] = r["distance"] / d
            own = bounds.get(CLEARANCE.get(m)) if m != "oracle" else None
            if r.get("distance") is not None and own:
                r["own_ratio"] = r["distance"] / own
    return out


# --------------------------------------------------------------------------------- timing
def _timing(quick: bool) -> dict:
    """Potential construction vs number of obstacles: ``benchmarks.online.bench_world``
    (incremental update per added obstacle with the forest memo warm, as HT and OHPF do it;
    from scratch with the memo cleared, as a nominal NF implementation does it)."""
    from benchmarks.online import MAX_DEPTH, SEED, bench_world
    from tests.worldgen import random_forest_world

    sizes, picks = ((5, 10), 1) if quick else ((5, 10, 20, 30, 40), 5)
    rows = []
    for n in sizes:
        row = {"n_obstacles": n, **bench_world(random_forest_world(SEED, n_obstacles=n, max_depth=MAX_DEPTH), picks)}
        rows.append(row)
        log(f"[eval] timing {n} obstacles: update {row['update'] * 1e3:.1f} ms, from scratch {row['rebuild'] * 1e3:.1f} ms")
    return {"rows": rows}


# -------------------------------------------------------------------------------- figures
_COLOURS = {"HT": (0, 0, 220), "HT-fields": (200, 0, 200), "OHPF": (0, 150, 0), "NF": (220, 60, 0),
            "RRT*": (0, 140, 255), "RRT*-buffer": (40, 90, 150)}  # BGR, as Fig. 14 (HT-fields: magenta)


def draw_trajectories(world, runs: dict, size: int = 720) -> np.ndarray:
    """Every method's trajectory on one picture (paper Fig. 14): true obstacles grey, regions,
    start, a legend with each method's outcome. Uses ``navigation.render``'s canvas."""
    from navigation.render import _Canvas

    cv = _Canvas(world.workspace, size)
    img = np.full((cv.h, cv.w, 3), 255, np.uint8)
    aa, t = cv2.LINE_AA, cv.thick
    for o in world.obstacles:
        pts = cv.px(o.boundary_points(256))
        cv2.fillPoly(img, [pts], (200, 200, 200), aa)
        cv2.polylines(img, [pts], True, (90, 90, 90), t, aa)
    cv2.polylines(img, [cv.px(world.workspace.boundary_points(512))], True, (0, 0, 0), 2 * t, aa)
    for name, reg in world.regions.items():
        c = tuple(int(v) for v in cv.px(reg.center)[0])
        cv2.circle(img, c, cv.length(reg.radius), (120, 0, 120), t, aa)
        cv2.putText(img, name, (c[0] + cv.length(reg.radius) + 2, c[1] - 2), cv2.FONT_HERSHEY_SIMPLEX, cv.font,
                    (120, 0, 120), 1, aa)
    y = 18
    for m, r in runs.items():
        if m not in _COLOURS:
            continue
        col = _COLOURS[m]
        if r.get("trajectory"):
            cv2.polylines(img, [cv.px(np.asarray(r["trajectory"])[:, :2])], False, col, 2 * t, aa)
            label = (f"{m}: {r['distance']:.1f} m" + ("" if r["completed"] else " (not completed)")
                     + (f", {r['collisions']} coll." if r["collisions"] else ""))
        else:
            label = f"{m}: {r.get('error', 'no run')}"[:60]
        cv2.line(img, (8, y - 4), (28, y - 4), col, 3, aa)
        cv2.putText(img, label, (34, y), cv2.FONT_HERSHEY_SIMPLEX, cv.font, (0, 0, 0), 1, aa)
        y += 18
    if "oracle" in runs and runs["oracle"].get("distance"):
        cv2.putText(img, f"oracle (lower bound): {runs['oracle']['distance']:.1f} m (not drawn)", (8, y),
                    cv2.FONT_HERSHEY_SIMPLEX, cv.font, (0, 0, 0), 1, aa)
    s = tuple(int(v) for v in cv.px(world.robot.start[:2])[0])
    cv2.drawMarker(img, s, (0, 0, 0), cv2.MARKER_STAR, 14, 2, aa)
    return img


def draw_line_chart(series: dict, xlabel: str, ylabel: str, title: str, size=(640, 420)) -> np.ndarray:
    """Minimal log-y line chart: ``series`` maps a label to ``(xs, ys, bgr)``."""
    W, H = size
    L, R, T, B = 70, 20, 40, 50
    img = np.full((H, W, 3), 255, np.uint8)
    xs = np.concatenate([np.asarray(s[0], float) for s in series.values()])
    ys = np.concatenate([np.asarray(s[1], float) for s in series.values()])
    x0, x1 = 0.0, float(xs.max()) * 1.05
    ly0, ly1 = math.floor(math.log10(ys.min())), math.ceil(math.log10(ys.max()))
    if ly1 == ly0:
        ly1 += 1

    def px(x, y):
        u = L + (x - x0) / (x1 - x0) * (W - L - R)
        v = H - B - (math.log10(y) - ly0) / (ly1 - ly0) * (H - T - B)
        return int(round(u)), int(round(v))

    f, aa = cv2.FONT_HERSHEY_SIMPLEX, cv2.LINE_AA
    cv2.rectangle(img, (L, T), (W - R, H - B), (0, 0, 0), 1)
    for e in range(ly0, ly1 + 1):
        _, v = px(x0, 10.0 ** e)
        cv2.line(img, (L, v), (W - R, v), (220, 220, 220), 1)
        cv2.putText(img, f"{10.0 ** e * 1e3:g} ms", (4, v + 4), f, 0.4, (0, 0, 0), 1, aa)
    for xt in np.unique(xs):
        u, _ = px(xt, 10.0 ** ly0)
        cv2.line(img, (u, H - B), (u, H - B + 4), (0, 0, 0), 1)
        cv2.putText(img, f"{xt:g}", (u - 8, H - B + 18), f, 0.4, (0, 0, 0), 1, aa)
    cv2.putText(img, xlabel, (W // 2 - 60, H - 12), f, 0.45, (0, 0, 0), 1, aa)
    cv2.putText(img, title, (L, T - 22), f, 0.5, (0, 0, 0), 1, aa)
    cv2.putText(img, ylabel, (L, T - 6), f, 0.4, (0, 0, 0), 1, aa)
    for k, (label, (sx, sy, col)) in enumerate(series.items()):
        pts = np.array([px(a, b) for a, b in zip(sx, sy)], np.int32)
        cv2.polylines(img, [pts], False, col, 2, aa)
        for p in pts:
            cv2.circle(img, tuple(int(v) for v in p), 3, col, -1, aa)
        cv2.putText(img, label, (L + 8, T + 16 + 16 * k), f, 0.42, col, 1, aa)
    return img


# ------------------------------------------------------------------------------------ run
def run(names: Sequence[str], methods: Sequence[str], *, quick: bool = False, jobs: int = 1,
        max_time: float = 300.0, timing: bool = True, rrt_seed: int = 1, rrt_draws: int = 3) -> dict:
    """Every method on every scenario (RRT* methods ``rrt_draws`` times, OMPL seeds ``rrt_seed``,
    ``rrt_seed + 1``, ...; the scenario keeps the median draw, :func:`median_draw`), the oracle
    and the clearance tours, the random set's aggregates, the targets and, with ``timing``, the
    potential construction sweep."""
    if rrt_draws < 1:
        raise ValueError(f"rrt_draws must be at least 1, got {rrt_draws!r}")
    methods = list(methods)
    ompl = ompl_status()
    skipped = {}
    for m in [m for m in methods if m.startswith("RRT*")]:
        if not ompl[0]:
            methods.remove(m)
            skipped[m] = ompl[1]
            log(f"[eval] {m} skipped: {ompl[1]}")
    seeds = list(range(rrt_seed, rrt_seed + rrt_draws))
    tasks = [(n, m, quick, max_time, k) for n in names for m in methods if m != "oracle"
             for k in (seeds if m.startswith("RRT*") else [None])]
    t0 = time.perf_counter()
    results = isolated_map(_run_one, tasks, jobs, _log_run)
    draws: dict[tuple, list] = {}
    for (n, m, _, _, k), r in zip(tasks, results):
        draws.setdefault((n, m), []).append((k, r))
    runs: dict[str, dict] = {n: {} for n in names}
    for (n, m), rs in draws.items():
        runs[n][m] = rs[0][1] if rs[0][0] is None else median_draw(rs)
    scenarios = [_scenario_result(n, methods, quick, runs[n]) for n in names]
    result = {"command": None, "quick": quick, "methods": methods, "skipped": skipped, "ompl": ompl[1],
              "rrt_seeds": seeds, "max_time": max_time,
              "chatter_flag": CHATTER_FLAG, "scenarios": scenarios, "wall": time.perf_counter() - t0,
              "machine": machine_info()}
    result["aggregates"] = aggregate([s for s in scenarios if s["scenario"].startswith("random")], methods)
    result["targets"] = targets(result)
    if timing:
        result["timing"] = _timing(quick)
    return result


def median_draw(draws: Sequence[tuple]) -> dict:
    """The run that stands for a randomised method on a scenario: of its ``draws`` (``(seed,
    run)`` pairs), the one with the median distance, an unfinished run counting as longer than
    every finished one (the lower median for an even count), with ``seed`` and ``draws`` (every
    draw's seed, distance, completed, collisions) added."""
    def key(item):
        _, r = item
        done = bool(r.get("completed")) and "error" not in r
        return (not done, r.get("distance") if r.get("distance") is not None else math.inf)

    order = sorted(draws, key=key)
    seed, run = order[(len(order) - 1) // 2]
    run = dict(run)
    run["seed"] = seed
    run["draws"] = [{"seed": k, "distance": r.get("distance"), "completed": bool(r.get("completed")),
                     "collisions": r.get("collisions"), "error": r.get("error")} for k, r in draws]
    return run


def aggregate(scenarios: Sequence[dict], methods: Sequence[str]) -> dict:
    """Per method: runs, success rate, collisions, ``planning_sum`` (planning time summed over
    every run: OHPF plans HT's trees, so where both drive one plan their planning times are
    equal by construction and only the sum shows the re-plans each execution causes) and,
    over completed runs, median / p90 of :data:`RANDOM_KEYS`."""
    agg = {}
    for m in methods:
        runs = [s["runs"][m] for s in scenarios if m in s["runs"]]
        done = [r for r in runs if r.get("completed")]
        row = {"runs": len(runs), "completed": len(done), "success_rate": len(done) / len(runs) if runs else None,
               "collisions": sum(r.get("collisions", 0) for r in runs),
               "draw_collisions": (sum(d.get("collisions") or 0 for r in runs for d in r["draws"])
                                   if any(r.get("draws") for r in runs) else None),
               "flagged": sum(r.get("chatter", 0.0) > CHATTER_FLAG for r in runs),
               "planning_sum": (sum(float(r["planning_time"]) for r in runs if r.get("planning_time") is not None)
                                if runs and m != "oracle" else None)}
        for k in RANDOM_KEYS:
            vals = [float(r[k]) for r in done if r.get(k) is not None]
            row[k] = {"median": float(np.median(vals)), "p90": float(np.percentile(vals, 90))} if vals else None
        agg[m] = row
    return agg


# --------------------------------------------------------------------------------- targets
_SET_LABELS = ("random set",)  # target details that name a set of scenarios, not one


def targets(result: dict) -> list[dict]:
    """Issue 8's targets checked on this run: one ``{"target", "met", "detail"}`` per target,
    ``met`` ``True`` / ``False``, or ``None`` where the run does not measure it (no shared world,
    HT, OHPF or RRT* not run). Only completed runs have a tour to compare; the shortest other
    method's contact steps are named beside its distance."""
    scen = result["scenarios"]
    shared = [s for s in scen if s["scenario"] in SHARED]
    rand = [s for s in scen if s["scenario"].startswith("random")]

    def ht(s):
        r = s["runs"].get("HT")
        return r if r and "error" not in r else None

    out = []
    runs = [(s["scenario"], ht(s)) for s in scen if "HT" in s["runs"]]
    bad = [n for n, r in runs if r is None or not r.get("completed") or r.get("collisions")]
    out.append({"target": "HT completes every mission with zero collisions",
                "met": (not bad) if runs else None,
                "detail": (f"{len(runs) - len(bad)}/{len(runs)} scenarios"
                           + (f"; not: {', '.join(bad)}" if bad else "")) if runs else "HT not run"})
    short, within = [], []
    for s in shared:
        r = ht(s)
        if r is None or not r.get("completed"):
            short.append((s["scenario"], False, "HT did not complete"))
            within.append((s["scenario"], False, "HT did not complete"))
            continue
        others = [(o["distance"], m, o.get("collisions", 0)) for m, o in s["runs"].items()
                  if m not in ("HT", "oracle") and "error" not in o and o.get("completed")]
        best = min(others, default=None)
        if best is None:
            short.append((s["scenario"], None, f"HT {r['distance']:.2f} m, no other method completed"))
        else:
            d, m, c = best
            spread = [x["distance"] for x in s["runs"][m].get("draws") or () if x.get("distance") is not None]
            short.append((s["scenario"], r["distance"] <= d,
                          f"HT {r['distance']:.2f} m, shortest other {m} {d:.2f} m"
                          + (f" ({c} contact steps)" if c else "")
                          + (f" (median of {len(spread)} draws, {min(spread):.2f}-{max(spread):.2f} m)"
                             if len(spread) > 1 else "")))
        ratio = r.get("ratio")
        detail = "no oracle" if ratio is None else f"{ratio:.2f} x"
        tours = s.get("clearance_tours") or {}
        d0, dh = tours.get("0"), tours.get(f"{CLEARANCE['HT']:g}")
        if ratio is not None and d0 and dh:
            detail += f" (the tour keeping HT's {CLEARANCE['HT']:g} m buffer: {dh:.2f} m, {dh / d0:.2f} x)"
        within.append((s["scenario"], None if ratio is None else ratio <= 1.25, detail))

    def fold(name, items, what):
        met = [m for _, m, _ in items]
        return {"target": name,
                "met": None if not items or None in met else all(met),
                "detail": "; ".join(f"{n if n in _SET_LABELS else f'`{n}`'} {d}" for n, _, d in items)
                if items else f"no {what} in this run"}

    out.append(fold("HT's distance the smallest of the non-oracle methods on the shared worlds", short,
                    "shared world"))
    out.append(fold("HT within 1.25 x the oracle on the shared worlds", within, "shared world"))

    def planning(other, factor, name):
        why = result.get("skipped", {}).get(other)
        if why is not None:
            return {"target": name, "met": None, "detail": f"{other} skipped: {why}"}
        items = []
        for s in shared:
            r, o = ht(s), s["runs"].get(other)
            if r is None or o is None or "error" in o:
                continue
            items.append((s["scenario"], r["planning_time"] * factor < o["planning_time"],
                          f"{r['planning_time']:.3f} s against {o['planning_time']:.3f} s"))
        pairs = [(ht(s), s["runs"].get(other)) for s in rand]
        pairs = [(r, o) for r, o in pairs if r is not None and o is not None and "error" not in o]
        if pairs:
            a, b = sum(r["planning_time"] for r, _ in pairs), sum(o["planning_time"] for _, o in pairs)
            k = sum(r["planning_time"] * factor < o["planning_time"] for r, o in pairs)
            items.append(("random set", a * factor < b,
                          f"sum over {len(pairs)} worlds {a:.2f} s against {b:.2f} s ({k}/{len(pairs)} worlds each)"))
        return fold(name, items, f"HT and {other} pair")

    out.append(planning("OHPF", 1.0, "HT's planning time below OHPF's total"))
    out.append(planning("RRT*", 10.0, "HT's planning time at least 10 x below RRT*'s"))
    flagged = [n for n, r in runs if r is not None and r.get("chatter", 0.0) > CHATTER_FLAG]
    out.append({"target": "no oscillation flagged for HT", "met": (not flagged) if runs else None,
                "detail": (f"{len(flagged)} of {len(runs)} flagged" + (f": {', '.join(flagged)}" if flagged else ""))
                if runs else "HT not run"})
    return out


def targets_table(result: dict) -> list[str]:
    status = {True: "met", False: "**not met**", None: "not measured"}
    return ["## Issue 8 targets (this run)", "",
            "| target | status | detail |", "|---|---|---|",
            *(f"| {t['target']} | {status[t['met']]} | {t['detail']} |" for t in result["targets"]), ""]


# ---------------------------------------------------------------------------------- report
def _f(x, fmt="{:.2f}"):
    return "-" if x is None else fmt.format(x)


def _yes(r):
    if "error" in r:
        return "ERROR"
    return "yes" if r.get("completed") else f"NO ({r.get('state', '?')})"


def _clearances(methods) -> str:
    """``"HT 0.15 m, RRT* 0.05 m, ..."``: the nominal clearance of each of ``methods`` that has one."""
    return ", ".join(f"{m} {c:g} m" for m, c in CLEARANCE.items() if c is not None and m in methods)


#: The columns of a scenario's table: (title, alignment).
SCENARIO_COLUMNS = [("method", "l"), ("completed", "l"), ("collisions", "r"), ("planning initial / total s", "r"),
                    ("execution s", "r"), ("distance m", "r"), ("/ oracle", "r"), ("/ own clearance", "r"),
                    ("replans", "r"), ("oscillation /m", "r"), ("chatter /m", "r"), ("oscillation flagged", "l"),
                    ("min clearance m", "r"), ("adaptation", "l"), ("visited", "l")]


#: The columns of the random set's aggregate table.
RANDOM_COLUMNS = [("method", "l"), ("success", "l"), ("collisions", "r"), ("flagged", "r"), ("distance m", "r"),
                  ("/ oracle", "r"), ("/ own clearance", "r"), ("execution s", "r"), ("planning total s", "r"),
                  ("planning sum s", "r"), ("planning initial s", "r"), ("max replan s", "r"), ("replans", "r"),
                  ("oscillation /m", "r"), ("chatter /m", "r"), ("min clearance m", "r")]


def scenario_table(s: dict) -> list[str]:
    rows = []
    for m, r in s["runs"].items():
        adapt = {True: "yes", False: "no", None: "-"}[ADAPTATION.get(m)]
        if m == "oracle":
            rows.append(["oracle", "-", "-", "-", "-", _f(r["distance"]), "1.00", "-", "-", "-", "-", "-", "-", "-",
                         f"{' '.join(r['visited'])} ({r['orders']})"])
        elif "error" in r:
            rows.append([m, f"ERROR: {r['error']}"])
        else:
            rows.append([m, _yes(r), r["collisions"], f"{r['initial_planning_time']:.3f} / {r['planning_time']:.3f}",
                         f"{r['execution_time']:.1f}", f"{r['distance']:.2f}", _f(r.get("ratio")),
                         _f(r.get("own_ratio")), r["replans"], f"{r['oscillation']:.2f}", f"{r['chatter']:.2f}",
                         "yes" if r["chatter"] > CHATTER_FLAG else "no", f"{r['min_clearance']:.3f}", adapt,
                         " ".join(r["visited"])])
    lines = [f"### {s['scenario']} ({s['n_obstacles']} obstacles; task `{s['task']}`)", "",
             *markdown_table(SCENARIO_COLUMNS, rows)]
    for m, r in s["runs"].items():
        if r.get("draws") and len(r["draws"]) > 1:
            lines += ["", f"{m}'s draws (the row is the median one, seed {r['seed']}): " + ", ".join(
                f"seed {d['seed']} " + ("error" if d.get("error") else f"{_f(d['distance'])} m"
                                        + ("" if d["completed"] else " not completed")
                                        + (f", {d['collisions']} contact steps" if d.get("collisions") else ""))
                for d in r["draws"]) + "."]
    tours = s.get("clearance_tours")
    if tours:
        lines += ["", "Tour with every obstacle known, keeping a clearance beyond the robot radius (the oracle at "
                  "0; `/ own clearance` divides by the tour at the method's own: " + _clearances(s["runs"]) + "): " + ", ".join(f"{c} m: {_f(v)} m" for c, v in tours.items()) + "."]
    return lines + [""]


def chatter_table(result: dict) -> list[str]:
    """Where each method's chatter comes from, over every scenario
    (:func:`benchmarks.methods.chatter_sources`): flips per metre on the ticks of a re-plan, of a
    waypoint hand-over, and while tracking one waypoint."""
    rows = []
    for m in result["methods"]:
        runs = [s["runs"][m] for s in result["scenarios"] if "chatter_sources" in s["runs"].get(m, {})]
        if not runs:
            continue
        dist = sum(r["distance"] for r in runs)
        n = {k: sum(r["chatter_sources"][k] for r in runs) for k in ("handover", "replan", "tracking")}
        per = {k: (v / dist if dist > 1e-9 else 0.0) for k, v in n.items()}
        rows.append(f"| {m} | {len(runs)} | {dist:.1f} | {sum(n.values())} | {n['handover']} ({per['handover']:.2f}) | "
                    f"{n['replan']} ({per['replan']:.2f}) | {n['tracking']} ({per['tracking']:.2f}) |")
    if not rows:
        return []
    return ["## Where the chatter comes from", "",
            "Flips of the executed turn rate over every scenario, by what changed on the tick of the second "
            "period: the executive re-planned, the tracked waypoint changed without a re-plan (hand-over to the "
            "next waypoint's field), or neither (tracking one field). Count (per metre).", "",
            "| method | runs | distance m | flips | at hand-overs | at re-plans | while tracking |",
            "|---|---:|---:|---:|---:|---:|---:|", *rows, ""]


def render_markdown(result: dict) -> str:
    out = ["# Evaluation: paper 001 Table 1 on our worlds", "",
           f"Command: `{result.get('command') or 'python -m benchmarks.evaluation'}`; wall {result['wall']:.0f} s; "
           f"at most {result['max_time']:.0f} simulated s per mission; RRT*: "
           + (f"skipped ({result['skipped']['RRT*']})" if "RRT*" in result["skipped"] else
              f"{result['ompl']}; the median of {len(result.get('rrt_seeds', [1]))} draws (OMPL seeds "
              f"{', '.join(str(k) for k in result.get('rrt_seeds', [1]))}) per scenario") + ".",
           "",
           "Planning time: wall s (initial synthesis, and total with every re-plan). Execution time: simulated s. "
           "Oscillation: sign changes of the commanded turn rate per metre (`tamp.run`). Chatter: sign flips of "
           "the executed turn rate between consecutive 0.1 s periods per metre; *flagged* above "
           f"{result['chatter_flag']:g}/m. Oracle: a lower bound on the travel distance with every obstacle known "
           "(the shortest tour touching the region discs in order; docs/evaluation.md).", ""]
    if "targets" in result:
        out += targets_table(result)
    shared = [s for s in result["scenarios"] if not s["scenario"].startswith("random")]
    rand = [s for s in result["scenarios"] if s["scenario"].startswith("random")]
    if shared:
        out += ["## Shared worlds", ""]
        for s in shared:
            out += scenario_table(s)
    if rand:
        methods = [m for m in result["methods"]]
        out += [f"## Random forest worlds ({len(rand)})", "",
                "Success rate, collisions and the planning sum (planning total over every run) over all runs; "
                "median / p90 over the completed runs. OHPF plans HT's trees (only its execution differs): "
                "where both drive one plan their planning times are equal by construction, and the sum shows "
                "the re-plans each execution causes. `/ own clearance`: the distance over the tour keeping the "
                "method's own clearance (" + _clearances(methods) + "; HT and OHPF pass narrow passages at the fallback buffer, so theirs can fall below 1).", ""]
        rows = []
        for m in methods:
            a = result["aggregates"][m]
            if m == "oracle":
                d = a["distance"]
                rows.append(["oracle", f"{a['completed']}/{a['runs']}", "-", "-",
                             f"{_f(d and d['median'])} / {_f(d and d['p90'])}"])
                continue

            def mp(k, fmt="{:.2f}"):
                v = a[k]
                return "-" if v is None else f"{fmt.format(v['median'])} / {fmt.format(v['p90'])}"

            rows.append([m, f"{a['completed']}/{a['runs']}", a["collisions"], a["flagged"], mp("distance"), mp("ratio"),
                         mp("own_ratio"), mp("execution_time", "{:.1f}"), mp("planning_time", "{:.3f}"),
                         _f(a.get("planning_sum"), "{:.2f}"), mp("initial_planning_time", "{:.3f}"),
                         mp("max_replan_time", "{:.3f}"), mp("replans", "{:.0f}"), mp("oscillation"), mp("chatter"),
                         mp("min_clearance", "{:.3f}")])
        out += markdown_table(RANDOM_COLUMNS, rows)
        for m in methods:
            a = result["aggregates"][m]
            if a.get("draw_collisions") is not None:
                out += ["", f"{m}: every scenario's median draw above; contact steps over all its draws: "
                            f"{a['draw_collisions']} (median draws: {a['collisions']})."]
        out += ["", "Per world (distance m; `x` = not completed, `!` = collision):", "",
                "| world | " + " | ".join(methods) + " |", "|---|" + "---:|" * len(methods)]
        for s in rand:
            cells = []
            for m in methods:
                r = s["runs"].get(m, {})
                if r.get("distance") is None:
                    cells.append("-")
                    continue
                mark = ("" if r.get("completed") else " x") + ("!" if r.get("collisions") else "")
                cells.append(f"{r['distance']:.2f}{mark}")
            out.append(f"| {s['scenario']} | " + " | ".join(cells) + " |")
        out.append("")
    out += chatter_table(result)
    if "timing" in result:
        out += ["## Potential construction vs obstacles", "",
                "`benchmarks.online.bench_world`: median per added obstacle; *update* = incremental forest + "
                "navigation function (HT, OHPF), *from scratch* = forest memo cleared (nominal NF). RRT* has "
                "no potential. Figure: `potential_time.png`.", "",
                "| obstacles | update ms (median / max) | from scratch ms |", "|---:|---:|---:|"]
        for r in result["timing"]["rows"]:
            out.append(f"| {r['n_obstacles']} | {r['update'] * 1e3:.1f} / {r['update_max'] * 1e3:.1f} | "
                       f"{r['rebuild'] * 1e3:.1f} |")
        out.append("")
    out += [f"Machine: {result['machine']}", ""]
    return "\n".join(out)


def _write_figures(out: Path, result: dict) -> list[str]:
    files = []
    for s in result["scenarios"]:
        world, _ = scenario(s["scenario"], result["quick"])
        p = out / f"traj_{s['scenario']}.png"
        cv2.imwrite(str(p), draw_trajectories(world, s["runs"]))
        files.append(p.name)
    if "timing" in result:
        rows = result["timing"]["rows"]
        n = [r["n_obstacles"] for r in rows]
        img = draw_line_chart({"incremental update (HT, OHPF)": (n, [r["update"] for r in rows], (0, 0, 220)),
                               "from scratch (NF)": (n, [r["rebuild"] for r in rows], (220, 60, 0))},
                              "number of obstacles", "forest + navigation function, median per added obstacle",
                              "Potential construction time")
        p = out / "potential_time.png"
        cv2.imwrite(str(p), img)
        files.append(p.name)
    return files


def _strip(result: dict) -> dict:
    """JSON copy without trajectories (they go into the figures) and the executive's notes."""
    import copy

    r = copy.deepcopy(result)
    for s in r["scenarios"]:
        for run in s["runs"].values():
            for key in ("trajectory", "waypoints", "replanned"):
                run.pop(key, None)
    return r


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.evaluation", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="two small random worlds, reduced timing sweep (CI smoke)")
    parser.add_argument("--random", type=integer(0), default=20, help="random forest worlds (seeds 0 .. N-1)")
    parser.add_argument("--shared", type=world_name, nargs="*", default=list(SHARED), help="shared worlds to run")
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS), help="methods to run")
    parser.add_argument("--jobs", type=integer(1), default=1, help="runs (one method on one scenario, a process each) at a time")
    parser.add_argument("--max-time", type=positive, default=300.0, help="simulated seconds per mission")
    parser.add_argument("--rrt-seed", type=integer(1), default=1,
                        help="OMPL's first random seed for the RRT* methods (at least 1): runs are reproducible")
    parser.add_argument("--rrt-draws", type=integer(1), default=3,
                        help="runs of each RRT* method per scenario, seeds --rrt-seed, --rrt-seed + 1, ...; the "
                             "report keeps the median draw and lists them all")
    parser.add_argument("--no-timing", action="store_true", help="skip the potential-construction timing sweep")
    parser.add_argument("--out", type=Path, default=None,
                        help="output directory (default benchmarks/results/evaluation[_quick])")
    args = parser.parse_args(argv)
    names = ["random0", "random1"] if args.quick else list(args.shared) + [f"random{s}" for s in range(args.random)]
    out = args.out or Path("benchmarks") / "results" / ("evaluation_quick" if args.quick else "evaluation")
    result = run(names, args.methods, quick=args.quick, jobs=args.jobs, max_time=args.max_time,
                 timing=not args.no_timing, rrt_seed=args.rrt_seed, rrt_draws=args.rrt_draws)
    result["command"] = "python -m benchmarks.evaluation" + ("" if argv is None and len(sys.argv) <= 1 else " " + " ".join(
        sys.argv[1:] if argv is None else argv))
    out.mkdir(parents=True, exist_ok=True)
    result["figures"] = _write_figures(out, result)
    write_results(out, "evaluation", _strip(result), render_markdown(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
