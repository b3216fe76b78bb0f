"""Benchmark `softplc fleet` (issue 35): N controllers at 10 ms scans in one process, one
Modbus client per controller polling 10 times a second from this (other) process.

    .venv/bin/python tools/bench_fleet.py                 # 100 controllers, 20 s
    .venv/bin/python tools/bench_fleet.py --count 20 --seconds 5

Prints the fleet's scan-start lateness (p50/p99/max, from its own summary line: every scan
on time within 2 ms at p99 is the goal) and the clients' request latency (send to the last
byte of the reply, p50/p99/max: p99 <= 20 ms is the goal). The clients run on asyncio in
this process; the fleet in a `softplc fleet` subprocess. On a shared machine the figures
depend on what else runs: the load average is printed with them.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import re
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
from softplc.modbus.server import new_event_loop  # noqa: E402  (uvloop when installed)

PROGRAM = ROOT / "ladder_programs" / "plant" / "station.il"
CONFIG = ROOT / "ladder_programs" / "plant" / "filler.toml"
SCAN_GOAL_MS, REQUEST_GOAL_MS = 2.0, 20.0  # issue 35's numbers
POLLS_PER_S = 10  # each client
READ_COUNT = 10  # holding registers per poll (function 3)
START_TIMEOUT_S = 120.0
CLIENT_PRIORITY = 5  # SCHED_FIFO, below the fleet's scan (10) and Modbus (9) threads


def _pct(samples: list[float], p: float) -> float:
    s = sorted(samples)
    return s[min(len(s) - 1, max(0, -(-len(s) * p // 100) - 1))] if s else 0.0


async def _client(port: int, seconds: float, lat: list[float], errors: list[str]) -> None:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    period = 1 / POLLS_PER_S
    loop = asyncio.get_running_loop()
    # each client starts at its own phase in the poll period: not all at once
    due = loop.time() + period * (port % 97) / 97
    end = loop.time() + seconds
    tid = 0
    try:
        while due < end:
            await asyncio.sleep(max(0.0, due - loop.time()))
            tid = (tid + 1) & 0xFFFF
            req = struct.pack(">HHHBBHH", tid, 0, 6, 1, 3, 0, READ_COUNT)
            t0 = time.perf_counter()
            writer.write(req)
            head = await reader.readexactly(7)
            body = await reader.readexactly(struct.unpack(">H", head[4:6])[0] - 1)
            lat.append(time.perf_counter() - t0)
            if body[0] != 3:
                errors.append(f"port {port}: exception {body!r}")
            due += period
    finally:
        writer.close()


async def _clients(ports: list[int], seconds: float) -> tuple[list[float], list[str]]:
    lat: list[float] = []
    errors: list[str] = []
    await asyncio.gather(*(_client(p, seconds, lat, errors) for p in ports))
    return lat, errors


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=100)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--period", default="10ms")
    ap.add_argument("--client-rt-priority", type=int, default=CLIENT_PRIORITY,
                    help="SCHED_FIFO priority of the clients (below the fleet's threads; "
                         "0 = normal): the clients stand for other machines, so that the "
                         "figures measure the fleet, not this process' wake-ups on a busy "
                         "machine")
    args = ap.parse_args()
    if args.client_rt_priority:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(args.client_rt_priority))
        except (AttributeError, OSError) as e:
            print(f"clients at normal priority ({e})")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    fleet = subprocess.Popen(
        [sys.executable, "-m", "softplc", "fleet", f"{PROGRAM},{CONFIG}", "--count",
         str(args.count), "--base-port", "0", "--period", args.period],
        stdout=subprocess.PIPE, text=True, env=env)
    ports: list[int] = []
    assert fleet.stdout is not None
    end = time.monotonic() + START_TIMEOUT_S
    for line in fleet.stdout:
        m = re.match(r"\s+plc\d+ .* on [\d.]+:(\d+)$", line)
        if m:
            ports.append(int(m[1]))
        if line.startswith("softplc fleet:"):
            print(line.strip())
            break
        if time.monotonic() > end:
            break
    if len(ports) != args.count:
        fleet.kill()
        print(f"the fleet did not start ({len(ports)} ports seen)")
        return 1
    try:
        loop = new_event_loop()
        try:
            lat, errors = loop.run_until_complete(_clients(ports, args.seconds))
        finally:
            loop.close()
    finally:
        fleet.send_signal(signal.SIGINT)
        out, _ = fleet.communicate(timeout=60)
    summary = next((ln for ln in out.splitlines() if ln.startswith("fleet stats")), "")
    print(summary)
    late = {k: float(v) for k, v in re.findall(r"late_(p50|p99|max)=([\d.]+)ms", summary)}
    ms = [x * 1000 for x in lat]
    print(f"modbus requests={len(ms)} errors={len(errors)} p50={_pct(ms, 50):.3f}ms "
          f"p99={_pct(ms, 99):.3f}ms max={max(ms, default=0):.3f}ms "
          f"({args.count} clients x {POLLS_PER_S}/s, function 3, {READ_COUNT} registers)")
    print(f"load average: {open('/proc/loadavg').read().split()[:3]} on "
          f"{os.cpu_count()} CPUs")
    ok_scan = late.get("p99", 1e9) <= SCAN_GOAL_MS
    ok_req = _pct(ms, 99) <= REQUEST_GOAL_MS and not errors
    print(f"scan p99 <= {SCAN_GOAL_MS} ms: {'yes' if ok_scan else 'NO'}; "
          f"request p99 <= {REQUEST_GOAL_MS} ms: {'yes' if ok_req else 'NO'}")
    for e in errors[:5]:
        print(e)
    return 0 if ok_scan and ok_req else 1


if __name__ == "__main__":
    sys.exit(main())
