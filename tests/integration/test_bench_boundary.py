"""Smoke test of tools/bench_boundary.py: it runs and returns well-formed figures (never a
time threshold: tests check behaviour, not speed)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

TOOLS = Path(__file__).resolve().parents[2] / "tools"
sys.path.insert(0, str(TOOLS))

import bench_boundary  # noqa: E402


def test_boundary_benchmark_tiny() -> None:
    r = bench_boundary.figures(bench_boundary.ROOT, segments=1, repeat=1, number=5)
    us = [k for k in r if k.endswith("_us") and k != "overhead_us"]
    assert set(us) == {key for key, _, _ in bench_boundary.KEYS} - {"overhead_us"}
    assert all(isinstance(r[k], float) and math.isfinite(r[k]) and r[k] > 0 for k in us)
    assert r["overhead_us"] == r["scan_daemon_us"] - r["scan_bare_us"]
    assert r["scans"] > 100  # a segment drawn: the host's writes reached the program
    assert "overhead per scan" in bench_boundary.report(r)
