"""A/B runs of a benchmark: a git revision of this repository against this checkout, in
child processes alternating (A, B, A, B, ...) so a burst of load from elsewhere hits both
sides alike. The script is this checkout's; `PYTHONPATH` makes each child import softplc
from its side's tree."""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]

# (key of a child's JSON figures, label, higher is better)
Key = tuple[str, str, bool]


def export(rev: str, into: Path) -> Path:
    """`rev` of this repository as a plain tree (git archive)."""
    arch = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev],
                          capture_output=True, check=False)
    if arch.returncode:
        raise SystemExit(f"git archive {rev}: {arch.stderr.decode(errors='replace').strip()}")
    subprocess.run(["tar", "-x", "-C", str(into)], input=arch.stdout, check=True)
    return into


def child(script: str, root: Path, args: Sequence[str]) -> dict[str, Any]:
    """`script args` in a process importing softplc from `root` (its working directory):
    the JSON object of its last line of output."""
    env = dict(os.environ, PYTHONPATH=str(root))
    out = subprocess.run([sys.executable, script, *args], capture_output=True, text=True,
                         env=env, cwd=root, check=False)
    if out.returncode:
        raise SystemExit(f"{root}: the benchmark failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def against(rev: str, rounds: int, run: Callable[[Path], dict[str, Any]], keys: Sequence[Key],
            title: str) -> str:
    """`run(root)` for `rev` (before) and this checkout (after), `rounds` times each,
    alternating; a table of each key's best / median and the ratio of the bests (> 1:
    this checkout is better)."""
    with tempfile.TemporaryDirectory(prefix="bench_ab_") as tmp:
        sides = {rev: export(rev, Path(tmp)), "this checkout": ROOT}
        runs: dict[str, list[dict[str, Any]]] = {name: [] for name in sides}
        for i in range(rounds):
            for name, root in sides.items():
                print(f"[bench] round {i + 1}/{rounds}: {name}", file=sys.stderr, flush=True)
                runs[name].append(run(root))
    lines = [f"{title}, {rounds} alternating runs each (best / median), load "
             f"average {os.getloadavg()[0]:.1f}:",
             f"  {'figure':30} {rev[:20]:>22} {'this checkout':>22} {'ratio':>7}"]
    for key, label, higher in keys:
        cells, best = [], []
        for name in sides:
            vals = [r[key] for r in runs[name]]
            b = max(vals) if higher else min(vals)
            best.append(b)
            cells.append(f"{b:9.2f} / {statistics.median(vals):9.2f}")
        ratio = best[1] / best[0] if higher else best[0] / best[1]
        lines.append(f"  {label:30} {cells[0]:>22} {cells[1]:>22} {ratio:6.2f}x")
    return "\n".join(lines)
