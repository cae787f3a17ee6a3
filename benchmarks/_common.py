"""Pieces every benchmark command shares: progress lines, machine facts, verdicts, output files."""

from __future__ import annotations

import json
import os
import platform
import sys
from pathlib import Path

import numpy as np

__all__ = ["log", "machine_info", "verdict", "write_results"]


def log(msg: str) -> None:
    """A progress line on stderr (stdout carries the results table)."""
    print(msg, file=sys.stderr, flush=True)


def machine_info() -> dict:
    """Python, numpy, platform, CPU count and load average (where the OS reports it)."""
    return {"python": platform.python_version(), "numpy": np.__version__, "platform": platform.platform(),
            "cpus": os.cpu_count(),
            "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None}


def verdict(row: dict, key: str) -> str:
    """``PASS``/``FAIL`` of ``row["pass"][key]``, in parentheses when the target does not apply."""
    v = "PASS" if row["pass"][key] else "FAIL"
    return v if row["target_applies"] else f"({v})"


def write_results(out: Path, name: str, result: dict, table: str) -> None:
    """Write ``<out>/<name>.json`` and ``<out>/<name>.md``, say so on stderr, print the table."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n")
    (out / f"{name}.md").write_text(table)
    log(f"[bench] wrote {out / f'{name}.json'} and {out / f'{name}.md'}")
    print(table, end="" if table.endswith("\n") else "\n")
