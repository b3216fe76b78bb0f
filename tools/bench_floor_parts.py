"""Where the per-scan floor goes (issue 26): the fixed engine cost of the generated scan
with one part of it removed at a time (a removal experiment, not a working scan).

The two-instruction program of bench_floor.py on the virtual clock (default period, so
%S4-%S7 come from the ring). Each variant rewrites the generated text before it is
compiled; all run interleaved, best of `repeat` loops of `number` calls, thread CPU time.

    .venv/bin/python tools/bench_floor_parts.py [--number N] [--repeat R]
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from bench_floor import SOURCE
from peers.common import best_interleaved, loop

from softplc.plc import PLC
from softplc.runtime import scangen

# part -> (text in the generated scan, what replaces it)
PARTS: dict[str, list[tuple[str, str]]] = {
    "%S4-%S7 (ring)": [("if now is not exp:\n            node = clock_ring(P, now)", "pass"),
                       ("s[4], s[5], s[6], s[7], node = node", "pass")],
    "both perf_counter() calls": [("t0 = perf_counter()", "t0 = 0.0"),
                                  ("dt = perf_counter() - t0", "dt = 0.0001")],
    "stats (scans, last, total)": [("st.scans += 1", "pass"), ("st.last = dt", "pass"),
                                   ("st.total += dt", "pass")],
    "%SW30-%SW32 stores": [("sw[30] = ms = 0", "ms = 0"), ("sw[31] = ms", "pass"),
                           ("sw[32] = ms", "pass")],
    "clock step (now + P)": [("clock.now_us = exp = now + P", "pass"),
                             ("if now is not exp:", "if node is None:")],
    "timers' time (ts.now_us)": [("ts.now_us = now", "pass")],
    "latch and publish": [("i[0] = i_field[0]", "pass"), ("q_field[0] = q[0]", "pass")],
    "watchdog test (dt > W)": [("if dt > W:", "if 0:")],
}


def _plc(edits: list[tuple[str, str]], applied: list[str]) -> PLC:
    """A PLC whose steady scan is generated with `edits` (the first scan's is not)."""
    make = scangen._make

    def edited(*args: Any, **kwargs: Any) -> str:
        text = make(*args, **kwargs)
        for old, new in edits:
            if old in text:
                applied.append(old)
            text = text.replace(old, new)
        return text

    scangen._make = edited
    try:
        plc = PLC.from_source(SOURCE)
        plc.scan(100)
    finally:
        scangen._make = make
    return plc


def run(number: int, repeat: int) -> dict[str, float]:
    """{"main", "full", part...}: ns per call of main(), of the whole scan's fixed cost and
    of the fixed cost without each part."""
    plcs, missing = {"full": _plc([], [])}, []
    for name, edits in PARTS.items():
        applied: list[str] = []
        plcs[name] = _plc(edits, applied)
        missing += [f"{name}: {old!r}" for old, _ in edits if old not in applied]
    if missing:  # the generated scan changed: the experiment would measure nothing
        raise SystemExit("not in the generated scan: " + "; ".join(missing))
    batches = {name: loop(p.engine.scan) for name, p in plcs.items()}
    batches["main"] = loop(plcs["full"].program.main)
    t = best_interleaved(batches, number, repeat, clock=time.thread_time)
    main_ns = t.pop("main") * 1e9
    return {"main": main_ns, **{name: v * 1e9 - main_ns for name, v in t.items()}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--number", type=int, default=50_000, help="calls per timed loop")
    ap.add_argument("--repeat", type=int, default=15, help="timed loops; the best counts")
    a = ap.parse_args(argv)
    res = run(a.number, a.repeat)
    full = res["full"]
    print(f"fixed engine cost {full:.0f} ns (main() {res['main']:.0f} ns), best of "
          f"{a.repeat} x {a.number:,} calls, thread CPU time")
    for name in PARTS:
        print(f"  without {name:28}{res[name]:6.0f} ns   the part: {full - res[name]:4.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
