"""Scan jitter of `softplc run` with web monitor pages open, under the Modbus benchmark load.

Each case starts a fresh daemon (10 ms period, tools/bench_modbus.py's program and Modbus
load generator), opens N websocket "pages" in a separate process (each subscribes as the
monitor page does: all I/O, an animation table of 20 objects, two live rungs, and receives
the 10 updates/s the server sends), and reads the daemon's scan-start jitter from its
statistics lines while the Modbus clients run. `--stalled K` also opens K pages that
never read a byte (raw sockets with a small receive buffer) beside them. Targets: jitter
p99 <= 1 ms at a 10 ms period with 5 pages and the Modbus load (issue 15), and with 100
pages (issue 21; the daemon is started with --web-max-pages to let them in), normal pages
still at 10 updates/s beside stalled ones. Figures only; nothing is asserted.

    .venv/bin/python tools/bench_web.py [--pages 0 5 100] [--clients 1 8] [--duration 3]
                                        [--stalled 0 20] [--rt-priority N]
    .venv/bin/python tools/bench_web.py --attacks   # issue 21's attacks, one line each
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


def _rss_mb(pid: int) -> float:
    """Resident memory of process `pid` (Linux), MB; NaN elsewhere."""
    try:
        with open(f"/proc/{pid}/status") as f:
            kb = next(int(line.split()[1]) for line in f if line.startswith("VmRSS:"))
    except (OSError, StopIteration):
        return float("nan")
    return kb / 1024


def _stalled_page(port: int) -> socket.socket:
    """A websocket page that subscribes to everything and then never reads."""
    import base64
    import os

    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET /api/ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                  f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                  f"Sec-WebSocket-Version: 13\r\n\r\n").encode())
    payload = json.dumps({"subscribe": {"objects": TABLE, "io": True,
                                        "rungs": [0, 1]}}).encode()
    mask = os.urandom(4)
    body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    sock.sendall(bytes([0x81, 0x80 | 126]) + len(payload).to_bytes(2, "big") + mask + body)
    return sock


def _pages(port: int, n: int, start_at: float, duration: float, out: mp.Queue,
           stalled: int = 0) -> None:
    """n websocket pages in one process (and `stalled` pages that never read); puts the
    updates each normal page received per second."""
    import aiohttp

    held = [_stalled_page(port) for _ in range(stalled)]  # open until this process ends

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
    del held


def run(pages: tuple[int, ...] = (0, 5), clients: tuple[int, ...] = (1, 8),
        duration: float = 3.0, period_ms: int = 10, stalled: tuple[int, ...] = (0,),
        rt_priority: int | None = None) -> list[dict[str, float]]:
    rows = []
    ctx = mp.get_context("fork")
    max_pages = str(max(32, max(pages) + max(stalled)))
    cases = [(p, c, k) for p in pages for c in clients for k in stalled if p or not k]
    with tempfile.TemporaryDirectory() as tmp:
        program = Path(tmp) / "bench.il"
        program.write_text(bench_modbus.DEFAULT_PROGRAM)
        for n_pages, n_clients, n_stalled in cases:
            web = _free_port()
            rt = () if rt_priority is None else ("--rt-priority", str(rt_priority))
            daemon = bench_modbus.DaemonProcess(program, period_ms, (
                "--web", str(web), "--web-max-pages", max_pages, *rt))
            try:
                time.sleep(1.0)
                q: mp.Queue = ctx.Queue()
                proc = None
                if n_pages:  # pages open before the load and until after it
                    proc = ctx.Process(target=_pages, args=(
                        web, n_pages, time.time() + 0.5, duration + 1.5, q, n_stalled))
                    proc.start()
                res = bench_modbus._load(daemon, n_clients, duration)
                res["rss_mb"] = _rss_mb(daemon.proc.pid)  # pages still open
                rates = q.get(timeout=duration + 30) if proc else []
                if proc:
                    proc.join()
                res.update(pages=n_pages, stalled=n_stalled,
                           updates_per_s_per_page=min(rates, default=0.0))
                rows.append(res)
            finally:
                daemon.stop()
    return rows


async def _attack_figures(port: int, pid: int) -> list[tuple[str, str]]:
    """Issue 21's attacks on the web monitor, each with what it gets now."""
    import aiohttp

    base, out = f"http://127.0.0.1:{port}", []
    evil = {"Host": f"evil.example:{port}", "Origin": f"http://evil.example:{port}"}
    async with aiohttp.ClientSession(connector=aiohttp.TCPConnector(limit=0)) as http:
        async def post(path: str, body: bytes, headers: dict | None = None) -> int:
            async with http.post(base + path, data=body, headers={
                    "Content-Type": "application/json", **(headers or {})}) as r:
                await r.read()
                return r.status

        codes = {await post("/api/write", b'{"object": "%MW3", "value": 5}', evil),
                 await post("/api/force", b'{"object": "%Q0.0", "value": 1}', evil)}
        try:
            await http.ws_connect(base + "/api/ws", headers=evil)
            ws_code = 101
        except aiohttp.WSServerHandshakeError as e:
            ws_code = e.status
        out.append(("DNS rebinding (Host and Origin evil.example), write and force",
                    f"HTTP {sorted(codes)}, websocket upgrade HTTP {ws_code}"))

        rss0 = _rss_mb(pid)
        msg = json.dumps({"subscribe": {"objects": [f"%MW{i}:2000" for i in range(4000)]}})
        async with http.ws_connect(base + "/api/ws") as ws:
            times = []
            for _ in range(20):
                t0 = time.perf_counter()
                await ws.send_str(msg)
                while json.loads((await ws.receive(timeout=10)).data)["type"] != "error":
                    pass
                times.append(time.perf_counter() - t0)
            await ws.send_str("x" * 1_000_000)
            while (await ws.receive(timeout=10)).type not in (aiohttp.WSMsgType.CLOSE,
                                                                aiohttp.WSMsgType.CLOSED):
                pass
            big = ws.close_code
        out.append((f"subscribe of 8,000,000 objects ({len(msg):,} B), 20 times",
                    f"error frame in {sorted(times)[10] * 1000:.1f} ms (median), daemon RSS "
                    f"{_rss_mb(pid) - rss0:+.1f} MB; a 1 MB message: closed with {big}"))

        t0 = time.perf_counter()
        pages, codes = [], {}
        for _ in range(1000):
            ws = await http.ws_connect(base + "/api/ws")
            pages.append(ws)
        for ws in pages:
            msg = await ws.receive(timeout=10)
            key = "update" if msg.type == aiohttp.WSMsgType.TEXT else f"closed {ws.close_code}"
            codes[key] = codes.get(key, 0) + 1
        out.append(("1,000 websocket pages", f"{codes} in {time.perf_counter() - t0:.1f} s"))
        for ws in pages:
            await ws.close()

        statuses: dict[int, int] = {}
        for k in range(2000):
            st = await post("/api/write", json.dumps({"object": "%I0.0", "value": k % 2})
                            .encode())
            statuses[st] = statuses.get(st, 0) + 1
        t0 = time.perf_counter()
        await post("/api/control", b'{"action": "stop"}')
        while True:
            async with http.get(base + "/api/status") as r:
                st = await r.json()
            if st["state"] == "STOP":
                break
        out.append(("2,000 writes of %I0.0, then STOP",
                    f"HTTP {statuses}; STOP in {(time.perf_counter() - t0) * 1000:.0f} ms with "
                    f"{st['pending']} changes still queued"))
        await post("/api/control", b'{"action": "run"}')

        deep = await post("/api/write", b"[" * 20000 + b"]" * 20000)
        async with http.ws_connect(base + "/api/ws") as ws:
            await ws.send_str("[" * 20000 + "]" * 20000)
            while (m := json.loads((await ws.receive(timeout=10)).data))["type"] == "update":
                pass
            alive = not ws.closed
        out.append(("JSON nested 20,000 deep (POST, websocket)",
                    f"HTTP {deep}; websocket: {m['type']} frame, still open: {alive}"))
    return out


def attacks(period_ms: int = 1000) -> list[tuple[str, str]]:
    """A fresh daemon (1 s period by default: slow scans make a queue grow), attacked."""
    with tempfile.TemporaryDirectory() as tmp:
        program = Path(tmp) / "bench.il"
        program.write_text(bench_modbus.DEFAULT_PROGRAM)
        web = _free_port()
        daemon = bench_modbus.DaemonProcess(program, period_ms, ("--web", str(web)))
        try:
            time.sleep(1.0)
            return asyncio.run(_attack_figures(web, daemon.proc.pid))
        finally:
            daemon.stop()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pages", type=int, nargs="+", default=[0, 5])
    ap.add_argument("--clients", type=int, nargs="+", default=[1, 8])
    ap.add_argument("--duration", type=float, default=3.0, help="seconds of load per case")
    ap.add_argument("--period", type=int, default=10, help="scan period, ms")
    ap.add_argument("--stalled", type=int, nargs="+", default=[0],
                    help="pages that never read, beside the others (default 0)")
    ap.add_argument("--rt-priority", type=int, default=None,
                    help="the daemon's --rt-priority (0 = normal scheduling)")
    ap.add_argument("--attacks", action="store_true",
                    help="instead: issue 21's attacks on a daemon at a 1 s period, and what "
                         "each gets")
    a = ap.parse_args(argv)
    if a.attacks:
        for what, result in attacks():
            print(f"{what}: {result}")
        return 0
    print(f"{'pages':>5} {'stalled':>7} {'Modbus clients':>14} {'req/s':>8} {'Modbus p99':>10} "
          f"{'updates/s/page':>14} "
          f"{'jitter p50':>10} {'p99':>7} {'max':>7} {'scan max':>8} {'overruns':>8} "
          f"{'RSS':>6}")
    for r in run(tuple(a.pages), tuple(a.clients), a.duration, a.period, tuple(a.stalled),
                 a.rt_priority):
        print(f"{r['pages']:>5} {r['stalled']:>7} {r['clients']:>14} "
              f"{r['requests_per_s']:>8.0f} {r['latency_p99_ms']:>8.3f}ms "
              f"{r['updates_per_s_per_page']:>14.1f} {r['jitter_p50_ms']:>8.3f}ms "
              f"{r['jitter_p99_ms']:>5.3f}ms {r['jitter_max_ms']:>5.3f}ms "
              f"{r['scan_max_ms']:>6.3f}ms {r['overruns']:>8} {r['rss_mb']:>4.0f}MB")
    print("target: jitter p99 <= 1 ms at a 10 ms period with 5 and with 100 pages and the "
          "Modbus load (figures vary with the machine's load: its cores may be shared)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
