"""Guarantee: the evaluation suite (issue 8) runs end to end in quick mode, writes its JSON,
markdown report and figures, and HT completes its missions without collision; a missing or
broken OMPL skips RRT* with the reason in the report instead of failing the suite.

CI-sized: two 8-obstacle random worlds, HT, NF and the oracle (RRT* is exercised only through
its skip path, so the test passes whether or not ``ompl`` is installed).
"""

from __future__ import annotations

import json

import cv2

from benchmarks import evaluation


def test_quick_run_writes_report_and_ht_completes(tmp_path, capsys):
    out = tmp_path / "eval"
    assert evaluation.main(["--quick", "--methods", "HT", "NF", "oracle", "--out", str(out)]) == 0
    data = json.loads((out / "evaluation.json").read_text())
    assert [s["scenario"] for s in data["scenarios"]] == ["random0", "random1"]
    for s in data["scenarios"]:
        ht = s["runs"]["HT"]
        assert ht["completed"] and ht["collisions"] == 0 and ht["bad_commands"] == 0
        assert s["runs"]["oracle"]["distance"] > 0 and ht["ratio"] > 0
        assert "trajectory" not in ht  # trajectories go to the figures, not the JSON
    assert data["aggregates"]["HT"]["success_rate"] == 1.0
    assert {"median", "p90"} == set(data["aggregates"]["HT"]["distance"])
    report = (out / "evaluation.md").read_text()
    assert "## Random forest worlds (2)" in report and "| HT | 2/2 |" in report
    for name in ("traj_random0.png", "traj_random1.png", "potential_time.png"):
        img = cv2.imread(str(out / name))
        assert img is not None and img.shape[0] > 100 and img.shape[1] > 100
    printed = capsys.readouterr()
    assert printed.out.strip() == report.strip()
    assert "[eval] random0 HT" in printed.err


def test_rrt_star_skipped_with_reason_without_ompl(tmp_path, monkeypatch):
    monkeypatch.setattr(evaluation, "ompl_status", lambda: (False, "import ompl failed: test"))
    out = tmp_path / "eval"
    assert evaluation.main(["--quick", "--methods", "RRT*", "oracle", "--no-timing", "--out", str(out)]) == 0
    data = json.loads((out / "evaluation.json").read_text())
    assert data["skipped"] == {"RRT*": "import ompl failed: test"}
    assert all("RRT*" not in s["runs"] for s in data["scenarios"])
    assert "skipped (import ompl failed: test)" in (out / "evaluation.md").read_text()
