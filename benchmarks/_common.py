"""Pieces every benchmark command shares: progress lines, machine facts, verdicts, output files."""

from __future__ import annotations

import functools
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

__all__ = ["isolated_map", "load_average", "log", "machine_info", "machine_speed", "markdown_table", "verdict",
           "write_results"]


def log(msg: str) -> None:
    """A progress line on stderr (stdout carries the results table)."""
    print(msg, file=sys.stderr, flush=True)


def machine_info() -> dict:
    """Python, numpy, platform, CPU count, load average (where the OS reports it) and the
    machine's speed on two fixed workloads (:func:`machine_speed`)."""
    return {"python": platform.python_version(), "numpy": np.__version__, "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "load_average": load_average(), "speed": machine_speed()}


def load_average() -> list | None:
    """The OS's 1, 5 and 15 minute load averages, or ``None`` where it does not report them."""
    return list(os.getloadavg()) if hasattr(os, "getloadavg") else None


@functools.cache
def machine_speed() -> dict:
    """Milliseconds this machine takes for two fixed workloads (median of 5), so that times
    measured on different machines can be compared: ``python_ms``, interpreted Python (dict
    and list work); ``numpy_small_ms``, 4000 numpy calls on arrays of 64 points (the size of
    the executive's per-tick work, whose cost is mostly per-call overhead). Measured once per
    process, when first asked (on a machine busy with other work it reads slow)."""

    def python_work():
        d = {}
        for i in range(60_000):
            d[i % 997] = d.get(i % 997, 0) + i
        return sorted(d.values())[-1]

    pts = np.random.default_rng(0).random((64, 2))

    def numpy_work():
        acc = 0.0
        for _ in range(1000):
            r = np.hypot(pts[:, 0], pts[:, 1])
            acc += float(r.min()) + float(np.sum(pts * pts))
        return acc

    def median_ms(fn):
        times = []
        for _ in range(5):
            t = time.perf_counter()
            fn()
            times.append(1e3 * (time.perf_counter() - t))
        return round(statistics.median(times), 2)

    return {"python_ms": median_ms(python_work), "numpy_small_ms": median_ms(numpy_work)}


def verdict(row: dict, key: str) -> str:
    """``PASS``/``FAIL`` of ``row["pass"][key]``, in parentheses when the target does not apply."""
    v = "PASS" if row["pass"][key] else "FAIL"
    return v if row["target_applies"] else f"({v})"


def markdown_table(columns, rows, *, fill: str = "-") -> list[str]:
    """Lines of a markdown table. ``columns``: ``(title, align)`` pairs, align ``"l"`` or ``"r"``;
    ``rows``: sequences of cells, a row shorter than the header padded with ``fill`` (rows that
    give only their first cells, as an oracle's or a failed run's); a longer one is an error."""
    columns = list(columns)
    out = ["| " + " | ".join(t for t, _ in columns) + " |",
           "|" + "".join("---:|" if a == "r" else "---|" for _, a in columns)]
    for row in rows:
        cells = [str(c) for c in row]
        if len(cells) > len(columns):
            raise ValueError(f"row of {len(cells)} cells in a table of {len(columns)} columns: {cells}")
        out.append("| " + " | ".join(cells + [fill] * (len(columns) - len(cells))) + " |")
    return out


def write_results(out: Path, name: str, result: dict, table: str) -> None:
    """Write ``<out>/<name>.json`` and ``<out>/<name>.md``, say so on stderr, print the table."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / f"{name}.md").write_text(table)
    log(f"[bench] wrote {out / f'{name}.json'} and {out / f'{name}.md'}")
    print(table, end="" if table.endswith("\n") else "\n")


def _prepare() -> None:
    """Compile or load the kernels and freeze the start-up heap (:func:`tamp.run.prepare`), so
    that no run times their loading: in the parent before it forks, or in a spawned child."""
    from tamp.run import prepare

    prepare()


def _indexed(job):
    fn, i, task = job
    return i, fn(task)


def isolated_map(fn, tasks, jobs: int = 1, done=None) -> list:
    """``[fn(t) for t in tasks]``, each call in a fresh child process (``jobs`` at a time);
    ``done(task, result)`` is called in this process as each finishes (progress lines: a
    child's own output does not reach a caller that captures ``sys.stderr``).

    Every run starts from the same state: this process's after :func:`tamp.run.prepare`
    (kernels compiled, heap frozen; done here), forked for each task (``maxtasksperchild=1``). Runs in one
    process would share the process-wide memos (the forest's pairwise results, the
    per-squircle tables, the LTL translation's caches), so a run would be timed faster for
    the runs before it on the same world or mission: in the evaluation suite OHPF, run after
    HT on each scenario, found HT's translation and forest results cached (office: initial
    planning 0.024 s against HT's 0.093 s with the same planner). Where ``fork`` is not
    available the children are spawned and prepare themselves before their task.
    """
    import multiprocessing as mp

    tasks = list(tasks)
    if not tasks:
        return []
    if "fork" in mp.get_all_start_methods():
        _prepare()
        ctx, init = mp.get_context("fork"), None
    else:
        ctx, init = mp.get_context("spawn"), _prepare
    out = [None] * len(tasks)
    with ctx.Pool(processes=max(1, min(jobs, len(tasks))), initializer=init, maxtasksperchild=1) as pool:
        for i, result in pool.imap_unordered(_indexed, [(fn, i, t) for i, t in enumerate(tasks)], chunksize=1):
            out[i] = result
            if done is not None:
                done(tasks[i], result)
    return out
