"""Scan jitter of `softplc run` with web monitor pages open, under the Modbus benchmark load.

Each case starts a fresh daemon (10 ms period, tools/bench_modbus.py's program and Modbus
load generator), opens N websocket "pages" in a separate process (each subscribes as the
monitor page does: all I/O, an animation table of 20 objects, two live rungs, and receives
the 10 updates/s the server sends), and reads the daemon's scan-start jitter from its
statistics lines while the Modbus clients run. Target (issue 15): jitter p99 <= 1 ms at a
10 ms period with 5 pages and the Modbus load. Figures only; nothing is asserted.

    .venv/bin/python tools/bench_web.py [--pages 0 5] [--clients 1 8] [--duration 3]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import multiprocessing as mp
import socket
import sys
import tempfile
import time
from pathlib import Path

import bench_modbus  # tools/, the script's folder

TABLE = ["%MW0:10", "%MW20", "%MF10", "%M1", "%M4", "%Q0.0", "%Q0.1", "%S6", "%MW1", "%MW2",
         "%I0.0"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _pages(port: int, n: int, start_at: float, duration: float, out: mp.Queue) -> None:
    """n websocket pages in one process; puts the updates each received per second."""
    import aiohttp

    async def page(session: aiohttp.ClientSession) -> int:
        async with session.ws_connect(f"http://127.0.0.1:{port}/api/ws") as ws:
            await ws.send_str(json.dumps({"subscribe": {"objects": TABLE, "io": True,
                                                        "rungs": [0, 1]}}))
            while time.time() < start_at:
                await ws.receive(timeout=5)
            end, got = time.time() + duration, 0
            while time.time() < end:
                msg = await ws.receive(timeout=5)
                got += json.loads(msg.data).get("type") == "update"
            return got

    async def main() -> list[int]:
        async with aiohttp.ClientSession() as session:
            return list(await asyncio.gather(*(page(session) for _ in range(n))))

    out.put([g / duration for g in asyncio.run(main())])


def run(pages: tuple[int, ...] = (0, 5), clients: tuple[int, ...] = (1, 8),
        duration: float = 3.0, period_ms: int = 10) -> list[dict[str, float]]:
    rows = []
    ctx = mp.get_context("fork")
    with tempfile.TemporaryDirectory() as tmp:
        program = Path(tmp) / "bench.il"
        program.write_text(bench_modbus.DEFAULT_PROGRAM)
        for n_pages in pages:
            for n_clients in clients:
                web = _free_port()
                daemon = bench_modbus.DaemonProcess(program, period_ms, ("--web", str(web)))
                try:
                    time.sleep(1.0)
                    q: mp.Queue = ctx.Queue()
                    proc = None
                    if n_pages:  # pages open before the load and until after it
                        proc = ctx.Process(target=_pages, args=(
                            web, n_pages, time.time() + 0.5, duration + 1.5, q))
                        proc.start()
                    res = bench_modbus._load(daemon, n_clients, duration)
                    rates = q.get(timeout=duration + 30) if proc else []
                    if proc:
                        proc.join()
                    res.update(pages=n_pages, updates_per_s_per_page=min(rates, default=0.0))
                    rows.append(res)
                finally:
                    daemon.stop()
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pages", type=int, nargs="+", default=[0, 5])
    ap.add_argument("--clients", type=int, nargs="+", default=[1, 8])
    ap.add_argument("--duration", type=float, default=3.0, help="seconds of load per case")
    ap.add_argument("--period", type=int, default=10, help="scan period, ms")
    a = ap.parse_args(argv)
    print(f"{'pages':>5} {'Modbus clients':>14} {'req/s':>8} {'updates/s/page':>14} "
          f"{'jitter p50':>10} {'p99':>7} {'max':>7} {'scan max':>8} {'overruns':>8}")
    for r in run(tuple(a.pages), tuple(a.clients), a.duration, a.period):
        print(f"{r['pages']:>5} {r['clients']:>14} {r['requests_per_s']:>8.0f} "
              f"{r['updates_per_s_per_page']:>14.1f} {r['jitter_p50_ms']:>8.3f}ms "
              f"{r['jitter_p99_ms']:>5.3f}ms {r['jitter_max_ms']:>5.3f}ms "
              f"{r['scan_max_ms']:>6.3f}ms {r['overruns']:>8}")
    print("target: jitter p99 <= 1 ms at a 10 ms period with 5 pages and the Modbus load "
          "(figures vary with the machine's load: this machine's 2 cores are shared)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
