"""Timing and machine-description helpers shared by the benchmarks."""

from __future__ import annotations

import json
import os
import platform
import sys
import time
from collections.abc import Callable
from importlib import metadata
from pathlib import Path
from typing import Any


def progress(msg: str) -> None:
    """Progress goes to stderr so stdout carries only the figures."""
    print(f"[bench] {msg}", file=sys.stderr, flush=True)


def best_per_call(fn: Callable[[], Any], number: int, repeat: int = 5,
                  warmup: int | None = None) -> float:
    """Best-of-`repeat` seconds per call of fn, each repeat timing `number` calls in a tight
    loop. Warm-up calls (default: number // 10, at least 1) run first and are not timed."""
    for _ in range(max(1, number // 10) if warmup is None else warmup):
        fn()
    clock = time.perf_counter
    best = float("inf")
    for _ in range(repeat):
        t0 = clock()
        for _ in range(number):
            fn()
        best = min(best, clock() - t0)
    return best / number


def best_per_batch(batch: Callable[[int], Any], number: int, repeat: int = 5,
                   warmup: int | None = None,
                   clock: Callable[[], float] = time.perf_counter) -> float:
    """Like best_per_call for an API that runs n iterations itself (`plc.scan(n)`);
    `clock` as in best_interleaved."""
    w = max(1, number // 10) if warmup is None else warmup
    if w:
        batch(w)
    best = float("inf")
    for _ in range(repeat):
        t0 = clock()
        batch(number)
        best = min(best, clock() - t0)
    return best / number


def best_interleaved(batches: dict[str, Callable[[int], Any]], number: int, repeat: int = 5,
                     warmup: int | None = None,
                     clock: Callable[[], float] = time.perf_counter) -> dict[str, float]:
    """Best-of seconds per iteration for several contestants, their timed runs alternating
    (A, B, A, B, ...) so that a burst of load from elsewhere hits both sides alike.
    `clock`: wall time by default; `time.thread_time` for CPU time (steadier on a shared
    machine, blind to time lost waiting)."""
    w = max(1, number // 10) if warmup is None else warmup
    for batch in batches.values():
        if w:
            batch(w)
    best = dict.fromkeys(batches, float("inf"))
    for _ in range(repeat):
        for name, batch in batches.items():
            t0 = clock()
            batch(number)
            best[name] = min(best[name], clock() - t0)
    return {name: t / number for name, t in best.items()}


def loop(fn: Callable[[], Any]) -> Callable[[int], None]:
    """fn -> batch(n) calling it n times."""

    def batch(n: int) -> None:
        for _ in range(n):
            fn()

    return batch


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def version_of(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def machine_info() -> dict[str, Any]:
    return {
        "cpus": os.cpu_count(),
        "cpu_model": cpu_model(),
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "softplc": version_of("softplc"),
        "pymodbus": version_of("pymodbus"),
        "numpy": version_of("numpy"),
        "load_average": os.getloadavg(),
    }


def describe_machine(info: dict[str, Any]) -> str:
    return (f"{info['cpus']} CPUs, {info['cpu_model']}, {info['implementation']} "
            f"{info['python']}, {info['platform']}; load average at start "
            f"{info['load_average'][0]:.2f}")


def print_report(text: str, res: dict[str, Any], json_path: Path | None) -> None:
    """A benchmark's figures to stdout, and as JSON to `json_path` if given."""
    print(text)
    if json_path:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps(res, indent=2))


def speed_line(r: dict[str, Any], target: float, us_digits: int = 0, extra: str = "") -> str:
    """'  S simulated s in W wall s: Nx real time (wall), Mx (CPU), U us per scan', `extra`,
    then the target verdict, judged on CPU time (the wall figure depends on the load).

    CPU time is the simulating thread's (`time.thread_time`), not the process's: numpy's
    OpenBLAS worker threads spin on the other core for a while after numpy is imported, and
    `time.process_time` counted that (a 3 s servo run read 50x CPU against 86x wall)."""
    return (f"  {r['simulated_s']:.1f} simulated s in {r['wall_s']:.2f} wall s: "
            f"{r['speedup']:.1f}x real time (wall), {r['speedup_cpu']:.1f}x (CPU), "
            f"{r['us_per_scan']:.{us_digits}f} us per scan{extra}  "
            f"target >= {target:.0f}x  {'met' if r['speedup_cpu'] >= target else 'MISSED'} (CPU)")
