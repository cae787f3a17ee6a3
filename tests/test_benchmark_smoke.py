"""Guarantee: the navigation benchmark runs and writes its JSON and markdown results.

A smoke test (quick mode, the 5-obstacle world only); timings are not asserted.
"""

from __future__ import annotations

import json

from benchmarks import navigation as bench

METRICS = ("forest_build", "construction", "update", "one_point", "batch_10k", "grid_200")


def test_benchmark_quick_writes_results(tmp_path, capsys):
    out = tmp_path / "results"
    assert bench.main(["--quick", "--out", str(out)], sizes=(5,), shared=()) == 0
    data = json.loads((out / "navigation.json").read_text())
    assert data["benchmark"] == "navigation" and data["quick"] is True
    assert set(data["targets"]) == {"construction", "update", "one_point", "batch_10k", "grid_200"}
    assert {"python", "numpy", "platform", "cpus", "speed"} <= set(data["machine"])
    speed = data["machine"]["speed"]
    assert set(speed) == {"python_ms", "numpy_small_ms"} and all(v > 0 for v in speed.values())
    (row,) = data["worlds"]
    assert row["world"] == "random5" and row["n_obstacles"] == 5 and row["max_depth"] == 4
    for key in METRICS:
        assert isinstance(row[key], float) and row[key] > 0.0
    assert set(row["pass"]) == set(data["targets"]) and all(isinstance(v, bool) for v in row["pass"].values())
    assert row["grid_finite"] is True and 0.0 < row["grid_free_fraction"] < 1.0
    table = (out / "navigation.md").read_text()
    assert "| world |" in table and "| random5 | 5 |" in table
    assert table.count("PASS") + table.count("FAIL") >= 4
    printed = capsys.readouterr()
    assert printed.out.strip() == table.strip()
    assert "[bench]" in printed.err


def test_ltl_benchmark_quick_writes_results(tmp_path, capsys):
    from benchmarks import ltl as ltl_bench

    out = tmp_path / "results"
    assert ltl_bench.main(["--quick", "--out", str(out)]) == 0
    data = json.loads((out / "ltl.json").read_text())
    assert data["benchmark"] == "ltl" and data["quick"] is True
    assert len(data["targets"]) == 3 and set(data["pass"]) == set(data["targets"])
    assert all(isinstance(v, bool) for v in data["pass"].values())
    table = (out / "ltl.md").read_text()
    assert "| office mission |" in table
    assert table.count("PASS") + table.count("FAIL") >= 3
    assert capsys.readouterr().out.strip() == table.strip()


def test_control_benchmark_quick_writes_results(tmp_path, capsys):
    from benchmarks import control as control_bench

    out = tmp_path / "results"
    assert control_bench.main(["--quick", "--out", str(out)]) == 0
    data = json.loads((out / "control.json").read_text())
    assert data["benchmark"] == "control" and data["quick"] is True
    row, total = data["worlds"]
    assert row["world"] == "simple" and row["runs"] == 2 and row["collisions"] == 0
    assert 0.0 <= row["success_rate"] <= 1.0 and row["step_median"] > 0.0
    assert total["world"] == "all" and total["runs"] == 2 and total["reached"] == row["reached"]
    table = (out / "control.md").read_text()
    assert "| simple | 4 |" in table and "| all | - |" in table
    assert capsys.readouterr().out.strip() == table.strip()


def test_executive_benchmark_quick_with_jitter_and_overrides(tmp_path, capsys):
    """``python -m benchmarks.executive --quick --jitter 2 --set ...``: the main row, two runs
    from jittered start poses (different from the nominal one, clear of the obstacles), the
    overrides recorded; a bad override is a one-line error."""
    import pytest

    from benchmarks import executive as exe_bench

    out = tmp_path / "results"
    assert exe_bench.main(["--quick", "--repeat", "2", "--jitter", "2", "--set", "align_angle=0", "--set",
                           "seen_share=0.8", "--out", str(out)]) == 0
    data = json.loads((out / "executive_quick.json").read_text())
    assert data["config"] == {"align_angle": 0, "seen_share": 0.8}
    (row,) = data["rows"]
    assert row["world"] == "simple" and row["completed"] and row["collisions"] == 0
    # two timed runs of the same (deterministic) mission: one route, the median of their timings
    assert data["repeat"] == 2 and row["repeats"] == 2 and not row["route_differs"]
    assert len(row["tick_cpu_p95_runs"]) == 2
    assert row["tick_cpu_p95"] == pytest.approx(sum(row["tick_cpu_p95_runs"]) / 2, rel=1e-12)
    jit = data["jitter"]
    assert [(r["world"], r["k"]) for r in jit] == [("simple", 1), ("simple", 2)]
    assert all(r["completed"] and r["collisions"] == 0 and r["ratio"] > 0.9 for r in jit)
    table = (out / "executive_quick.md").read_text()
    assert "Jittered runs within 1.25 x their tour: " in table and '"align_angle": 0' in table
    assert capsys.readouterr().out.strip() == table.strip()
    world, _ = exe_bench._world("simple")
    moved = exe_bench.jittered_start(world, 1).robot.start
    assert moved != tuple(world.robot.start) and abs(moved[0] - world.robot.start[0]) < 0.05
    with pytest.raises(SystemExit, match="NAME=VALUE"):
        exe_bench.main(["--quick", "--set", "no_such_field=1", "--out", str(out)])
    with pytest.raises(SystemExit):
        exe_bench.main(["--quick", "--repeat", "0", "--out", str(out)])
    with pytest.raises(SystemExit, match="align_angle"):
        exe_bench.main(["--quick", "--set", "align_angle=2.0", "--out", str(out)])


def test_executive_benchmark_controller_override():
    """``--set controller={...}`` changes the named ``ControllerConfig`` fields of the
    executive's default controller; ``null`` selects the rotated gradient; an unknown field is
    a one-line error."""
    import pytest

    from benchmarks import executive as exe_bench
    from navigation.control import RATE_LIMITED
    from tamp.executive import ExecutiveConfig

    over = exe_bench._overrides(['controller={"accel_max": 1.0, "alpha_max": 6.0, "brake_share": 0.5}'])
    ctl = over["controller"]
    base = ExecutiveConfig().controller
    assert ctl.push_forward == base.push_forward and ctl.k_v == base.k_v
    assert {k: getattr(ctl, k) for k in RATE_LIMITED} == dict(RATE_LIMITED)
    assert exe_bench._overrides(["controller=null"]) == {"controller": None}
    with pytest.raises(SystemExit, match="no_such_gain"):
        exe_bench._overrides(['controller={"no_such_gain": 1}'])
    with pytest.raises(SystemExit, match="accel_max"):
        exe_bench._overrides(['controller={"accel_max": -1}'])


def test_executive_benchmark_crawl_guard_override():
    """``--set crawl_guard={...}`` turns the executive's crawl guard on with the named
    ``navigation.CrawlConfig`` fields changed (``{}``: its defaults); ``null`` leaves it off;
    a bad field is a one-line error."""
    import pytest

    from benchmarks import executive as exe_bench
    from navigation import CrawlConfig

    assert exe_bench._overrides(["crawl_guard={}"]) == {"crawl_guard": CrawlConfig()}
    assert exe_bench._overrides(['crawl_guard={"pull": 0.0}'])["crawl_guard"] == CrawlConfig(pull=0.0)
    assert exe_bench._overrides(["crawl_guard=null"]) == {"crawl_guard": None}
    with pytest.raises(SystemExit, match="crawl_guard"):
        exe_bench._overrides(['crawl_guard={"reach": 0.5}'])
    with pytest.raises(SystemExit, match="crawl_guard"):
        exe_bench._overrides(['crawl_guard={"no_such_field": 1}'])


def test_executive_benchmark_sweep_reports_every_world_and_refuses_a_bad_range(tmp_path, capsys):
    """``python -m benchmarks.executive --sweep A:B``: one row per seed (nominal start poses),
    the summary in the table; a malformed or empty range is a one-line error."""
    import pytest

    from benchmarks import executive as exe_bench

    out = tmp_path / "results"
    assert exe_bench.main(["--sweep", "3:5", "--jobs", "2", "--out", str(out)]) == 0
    data = json.loads((out / "executive_sweep.json").read_text())
    assert data["seeds"] == [3, 5] and [r["world"] for r in data["rows"]] == ["random3", "random4"]
    assert all(r["completed"] and r["collisions"] == 0 and r["ratio"] > 0.9 for r in data["rows"])
    table = (out / "executive_sweep.md").read_text()
    assert "--sweep 3:5" in table and "Completed 2/2, collisions 0" in table
    assert all(r["tick_cpu_p95"] > 0 and r["max_replan_cpu"] >= 0 and r["deferred_plans"] >= 0 for r in data["rows"])
    assert "Tick CPU p95 (one run each)" in table and "Re-plans deferred a tick:" in table
    assert capsys.readouterr().out.strip() == table.strip()
    for bad in ("5:3", "x:4", "4"):
        with pytest.raises(SystemExit):
            exe_bench.main(["--sweep", bad, "--out", str(out)])
    # --patrol: recurrent missions, each going round every region (once more after the prefix)
    assert exe_bench.main(["--sweep", "3:5", "--patrol", "--jobs", "2", "--out", str(out)]) == 0
    data = json.loads((out / "executive_sweep.json").read_text())
    assert data["patrol"] is True
    assert all(r["completed"] and r["collisions"] == 0 and r["every_region_twice"] for r in data["rows"])
    table = (out / "executive_sweep.md").read_text()
    assert "--sweep 3:5 --patrol" in table and "Every region visited at least twice: 2/2" in table
    with pytest.raises(SystemExit):
        exe_bench.main(["--patrol", "--out", str(out)])  # only with --sweep
    # --noise: every mission's lidar noisy (the worlds' own is noise-free), said in the table
    assert exe_bench.main(["--sweep", "3:4", "--noise", "0.01", "--out", str(out)]) == 0
    data = json.loads((out / "executive_sweep.json").read_text())
    assert data["noise"] == 0.01 and data["rows"][0]["completed"] and data["rows"][0]["collisions"] == 0
    assert "--sweep 3:4 --noise 0.01" in (out / "executive_sweep.md").read_text()
    world, _ = exe_bench._world("random3", noise=0.01)
    assert world.lidar.noise_std == 0.01 and exe_bench._world("random3")[0].lidar.noise_std == 0.0
    for bad in ("-0.01", "nan", "1"):
        with pytest.raises(SystemExit):
            exe_bench.main(["--sweep", "3:4", "--noise", bad, "--out", str(out)])


def test_soak_benchmark_quick_patrols_and_reports_every_window(tmp_path, capsys):
    """``python -m benchmarks.soak --quick``: four 30 s windows of the patrol of ``simple``, the
    robot keeps arriving at the accepting state without a collision or a bad command; a bad
    window is a one-line error."""
    import pytest

    from benchmarks import soak

    out = tmp_path / "results"
    assert soak.main(["--quick", "--out", str(out)]) == 0
    data = json.loads((out / "soak.json").read_text())
    assert data["benchmark"] == "soak" and data["task"] == "G F a & G F b"
    rows = data["rows"]
    assert [r["sim_time"] for r in rows] == [30.0, 60.0, 90.0, 120.0]
    assert all(r["collisions"] == 0 and r["bad_commands"] == 0 for r in rows)
    visits = [r["accepting_visits"] for r in rows]
    assert visits == sorted(visits) and visits[-1] >= 3  # still patrolling in the last window
    assert all(r["traced_mb"] > 0 and r["tick_p95_ms"] > 0 for r in rows)
    s = data["summary"]
    assert s["traced_last_mb"] == rows[-1]["traced_mb"] and s["growth_mb_per_hour"] is not None
    table = (out / "soak.md").read_text()
    assert "python -m benchmarks.soak --quick" in table and table.count("\n| ") == 1 + len(rows)
    assert capsys.readouterr().out.strip() == table.strip()
    with pytest.raises(SystemExit, match="window"):
        soak.main(["--world", "simple", "--duration", "10", "--window", "20", "--out", str(out)])


def test_executive_benchmark_repeats_report_median_timings_and_flag_differing_routes():
    """``--repeat N``: a world's row keeps its first run's route and counts, every timing field
    is the median over the runs (each run's tick p95 listed), and the targets are judged on the
    medians; runs that took different routes are flagged."""
    from benchmarks import executive as exe_bench

    def run(p95, distance=10.0):
        r = {k: 0.001 for k in exe_bench._TIMED}
        r.update(world="w", distance=distance, visited=["a", "b"], ratio=1.1, tick_p95=p95, tick_cpu_p95=p95,
                 replans=3)
        return r

    row = exe_bench._merge_repeats([run(0.019), run(0.026), run(0.020)])
    assert row["tick_cpu_p95"] == 0.020 and row["tick_p95"] == 0.020 and row["repeats"] == 3
    assert row["tick_cpu_p95_runs"] == [0.019, 0.026, 0.020] and not row["route_differs"]
    assert row["pass"]["tick_cpu"] and row["pass"]["distance"] and row["replans"] == 3
    row = exe_bench._merge_repeats([run(0.019), run(0.021), run(0.026, distance=11.0)])
    assert row["route_differs"] and row["distance"] == 10.0 and not row["pass"]["tick_cpu"]
