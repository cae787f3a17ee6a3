"""Guarantee: the perception benchmark runs and writes its JSON and markdown results.

A smoke test (quick mode: a short drive in ``simple``); timings are not asserted.
"""

from __future__ import annotations

import json

import pytest

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


def test_perception_benchmark_drives_writes_results(tmp_path, capsys):
    """``--drives``: the slow test's drive through one random world, aggregated per noise level."""
    out = tmp_path / "results"
    assert bench.main(["--drives", "0", "--noise", "0.0", "--out", str(out)]) == 0
    data = json.loads((out / "perception_drives.json").read_text())
    assert data["benchmark"] == "perception_drives" and data["seeds"] == [0] and data["spec"] == "0"
    (row,) = data["drives"]
    assert row["world"] == "random0" and row["noise_std"] == 0.0 and row["iou"]
    assert set(row["pass"]) == {"safety", "validity", "stability", "rotation", "iou"}
    (summ,) = data["summary"]
    assert summ["drives"] == 1 and summ["groups"] == len(row["iou"])
    assert summ["iou_mean"] == pytest.approx(sum(row["iou"]) / len(row["iou"]))
    assert summ["all_checks"] == int(all(row["pass"].values()))
    table = (out / "perception_drives.md").read_text()
    assert "--drives 0" in table and "| 0 | 1 |" in table
    assert capsys.readouterr().out.strip() == table.strip()


def test_perception_benchmark_drives_rejects_bad_seeds(capsys):
    with pytest.raises(SystemExit) as err:
        bench.main(["--drives", "a-b"])
    assert err.value.code == 2
    assert "--drives" in capsys.readouterr().err
