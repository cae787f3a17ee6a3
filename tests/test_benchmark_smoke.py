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
    assert {"python", "numpy", "platform", "cpus"} <= set(data["machine"])
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
