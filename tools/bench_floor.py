"""Per-scan floor benchmark (issue 26): the engine's fixed cost per scan.

A two-instruction program (`LD %I0.0 / ST %Q0.0`) on the virtual clock, best of `repeat`
timed loops of `number` calls each, warm-up excluded, figures in ns per call:
  * `main()`: the compiled program alone;
  * `engine.scan()`: one scan (system bits, latch, program, publish, statistics);
  * `plc.scan()`: the same through the PLC facade;
  * fixed engine cost = engine.scan() - main().
Then the same with a before_scan and an after_scan hook, a device, a forced bit, and the
real clock, to show what each configuration adds. Target: fixed cost <= 300 ns. Timed
in the thread's CPU time (steady on a shared machine; `--wall` for wall time).

    .venv/bin/python tools/bench_floor.py [--number N] [--repeat R] [--wall]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from typing import Any

from peers.common import best_interleaved, loop

from softplc.plc import PLC

TARGET_NS = 300.0
SOURCE = "LD %I0.0\nST %Q0.0\n"


class _NullDevice:
    def update(self, t: float, dt: float) -> None:
        pass

    def state(self) -> dict[str, Any]:
        return {}


def _variants() -> dict[str, Callable[[PLC], None]]:
    def hooks(plc: PLC) -> None:
        plc.before_scan.append(lambda: None)
        plc.after_scan.append(lambda: None)

    def device(plc: PLC) -> None:
        plc.engine.devices = {"null": _NullDevice()}

    def forced(plc: PLC) -> None:
        plc.force("%M5", 1)

    return {"bare": lambda plc: None, "2 hooks": hooks, "1 device": device,
            "1 forced bit": forced}


def measure(setup: Callable[[PLC], None], clock: str, number: int, repeat: int,
            wall: bool = False) -> dict[str, float]:
    """ns per call of main(), engine.scan() and plc.scan() for one configuration."""
    plc = PLC.from_source(SOURCE, clock=clock)
    setup(plc)
    plc.scan(100)
    t = best_interleaved({"main": loop(plc.program.main), "engine": loop(plc.engine.scan),
                          "plc": plc.scan}, number, repeat,
                         clock=time.perf_counter if wall else time.thread_time)
    return {k: v * 1e9 for k, v in t.items()}


def run(number: int, repeat: int, wall: bool = False) -> dict[str, dict[str, float]]:
    """{"clock, configuration": {"main", "engine", "plc", "fixed"} in ns per call}."""
    res = {}
    for clock in ("virtual", "real"):
        for name, setup in _variants().items():
            r = measure(setup, clock, number, repeat, wall)
            res[f"{clock}, {name}"] = {**r, "fixed": r["engine"] - r["main"]}
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--number", type=int, default=50_000, help="calls per timed loop")
    ap.add_argument("--repeat", type=int, default=15, help="timed loops; the best counts")
    ap.add_argument("--wall", action="store_true", help="wall time instead of CPU time")
    a = ap.parse_args(argv)
    print(f"per-scan floor, ns per call (best of {a.repeat} x {a.number:,} calls, "
          f"{'wall' if a.wall else 'thread CPU'} time)")
    print(f"  {'configuration':24}{'main()':>9}{'engine':>9}{'plc':>9}{'fixed':>9}")
    for name, r in run(a.number, a.repeat, a.wall).items():
        print(f"  {name:24}{r['main']:9.0f}{r['engine']:9.0f}{r['plc']:9.0f}{r['fixed']:9.0f}")
    print(f"  target: fixed engine cost <= {TARGET_NS:.0f} ns (virtual clock, bare)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
