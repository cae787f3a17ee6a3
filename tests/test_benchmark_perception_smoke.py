"""Guarantee: the perception benchmark runs and writes its JSON and markdown results.

A smoke test (quick mode: a short drive in ``simple``); timings are not asserted.
"""

from __future__ import annotations

import json

from benchmarks import perception as bench


def test_perception_benchmark_quick_writes_results(tmp_path, capsys):
    out = tmp_path / "results"
    assert bench.main(["--quick", "--out", str(out)]) == 0
    data = json.loads((out / "perception.json").read_text())
    assert data["benchmark"] == "perception" and data["quick"] is True
    assert {"median", "p95", "safety", "iou", "rotation"} <= set(data["targets"])
    assert {"python", "numpy", "platform", "cpus"} <= set(data["machine"])
    (row,) = data["worlds"]
    assert row["world"] == "simple" and row["noise_std"] == 0.0 and row["scans"] > 10
    for key in ("median", "p95", "max", "mean"):
        assert isinstance(row[key], float) and row[key] > 0.0
    assert 0.0 <= row["safety"] <= 1.0 and 0.0 <= row["changed"] <= 1.0
    assert all(isinstance(v, bool) for v in row["pass"].values())
    table = (out / "perception.md").read_text()
    assert "| world |" in table and "| simple | 0 |" in table
    assert table.count("PASS") + table.count("FAIL") >= 5
    printed = capsys.readouterr()
    assert printed.out.strip() == table.strip()
    assert "[bench]" in printed.err
