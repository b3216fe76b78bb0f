"""Scan-start jitter at normal priority, with and without `gc.freeze()` after start-up.

Each run starts a fresh `softplc run` (10 ms period, tools/bench_modbus.py's program) at
normal scheduling (`--rt-priority 0`) with the web monitor, opens one web page (a websocket
subscribed as the monitor page does: tools/bench_web.py), drives 8 closed-loop Modbus
clients (FC 3) for `--duration` seconds and reads the daemon's jitter (scan-start lateness)
from its statistics lines. "before" runs with `--no-gc-freeze`, "after" with the default
(the objects made at start-up frozen: the collector no longer walks them). The two
alternate, `--rounds` times, so that the machine's load weighs on both alike. Target
(issue 21): jitter p99 <= 1 ms. Figures only; nothing is asserted.

First, what a full collection costs in a process holding what the daemon holds (the
drawing-table program and machine, the web monitor's modules): the time the collector
keeps the GIL, hence the longest scan-start delay it can cause, before and after freezing.

    .venv/bin/python tools/bench_gc.py [--rounds 3] [--duration 5] [--clients 8]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import bench_modbus  # tools/, the script's folder
import bench_web

CASES = {"before (no gc.freeze)": ("--no-gc-freeze",), "after (gc.freeze)": ()}


def one(program: Path, extra: tuple[str, ...], clients: int, duration: float,
        period_ms: int) -> dict[str, float]:
    web = bench_web._free_port()
    daemon = bench_modbus.DaemonProcess(
        program, period_ms, ("--rt-priority", "0", "--web", str(web), *extra))
    ctx = mp.get_context("fork")
    try:
        time.sleep(1.0)
        q: mp.Queue = ctx.Queue()
        page = ctx.Process(target=bench_web._pages,
                           args=(web, 1, time.time() + 0.5, duration + 1.5, q))
        page.start()
        res = bench_modbus._load(daemon, clients, duration)
        res["updates_per_s"] = min(q.get(timeout=duration + 30), default=0.0)
        page.join()
        return res
    finally:
        daemon.stop()


def full_collections(n: int = 5) -> dict[str, list[float]]:
    """ms per `gc.collect()` with the daemon's objects, before and after `gc.freeze()`."""
    import gc

    import softplc.web.server  # noqa: F401  (the web monitor's modules: aiohttp...)
    from softplc.plc import PLC

    table = Path(__file__).resolve().parents[1] / "ladder_programs"
    plc = PLC.from_file(table / "drawing_table.il", config=table / "drawing_table.toml")
    out: dict[str, list[float]] = {}
    for case in ("before", "after"):
        if case == "after":
            gc.collect()
            gc.freeze()
        times = []
        for _ in range(n):
            t0 = time.perf_counter()
            gc.collect()
            times.append((time.perf_counter() - t0) * 1000)
        out[case] = times
    gc.unfreeze()
    del plc
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3,
                    help="before/after pairs (3; 0: the collection costs only)")
    ap.add_argument("--duration", type=float, default=5.0, help="seconds of load per run (5)")
    ap.add_argument("--clients", type=int, default=8, help="Modbus clients (8)")
    ap.add_argument("--period", type=int, default=10, help="scan period, ms (10)")
    a = ap.parse_args(argv)
    rows: dict[str, list[dict[str, float]]] = {k: [] for k in CASES}
    for case, times in full_collections().items():
        print(f"full gc.collect() {case} gc.freeze: " + " ".join(f"{t:.3f}" for t in times)
              + " ms")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'case':<22} {'round':>5} {'req/s':>7} {'updates/s':>9} {'jitter p50':>10} "
          f"{'p99':>8} {'max':>8} {'overruns':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        program = Path(tmp) / "bench.il"
        program.write_text(bench_modbus.DEFAULT_PROGRAM)
        for r in range(a.rounds):
            for name, extra in CASES.items():
                res = one(program, extra, a.clients, a.duration, a.period)
                rows[name].append(res)
                print(f"{name:<22} {r + 1:>5} {res['requests_per_s']:>7.0f} "
                      f"{res['updates_per_s']:>9.1f} {res['jitter_p50_ms']:>8.3f}ms "
                      f"{res['jitter_p99_ms']:>6.3f}ms {res['jitter_max_ms']:>6.3f}ms "
                      f"{res['overruns']:>8}", flush=True)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    for name, rs in rows.items():
        if not rs:
            continue
        p99 = [x["jitter_p99_ms"] for x in rs]
        print(f"{name}: jitter p99 median {statistics.median(p99):.3f} ms, "
              f"range {min(p99):.3f}-{max(p99):.3f} ms over {len(rs)} runs "
              f"(target <= 1 ms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
