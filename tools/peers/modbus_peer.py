"""Modbus TCP server overhead: FC 3 and FC 16 (10 registers) against several servers.

Servers (each a subprocess on 127.0.0.1, port chosen free by the server itself):
  * pymodbus: a bare pymodbus TCP server with a plain datastore (peers/pymodbus_server.py)
  * softplc: `python -m softplc run drawing_table.il --config drawing_table.toml --period
    10ms` (the program scanning, the simulated table running)
  * libmodbus (optional, the C ceiling): peers/libmodbus_server.c compiled with gcc.

Load: closed-loop clients on raw sockets with pre-built frames, multiplexed with
`selectors` over up to 2 processes (the machine has 2 cores; more processes would only
steal CPU from the server). Each client sends, waits for the whole reply, records the
latency, sends again, until `duration` seconds or `max_requests` replies. FC 3 reads
registers 0-9; FC 16 writes registers 100-109 (unused by the drawing-table program).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import re
import selectors
import socket
import subprocess
import sys
import time
from array import array
from pathlib import Path
from struct import pack
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
UNIT = 1
FC3 = pack(">HHHBBHH", 1, 0, 6, UNIT, 3, 0, 10)
FC3_REPLY = 9 + 20
FC16 = pack(">HHHBBHHB", 1, 0, 7 + 20, UNIT, 16, 100, 10, 20) + bytes(range(20))
FC16_REPLY = 12
REQUESTS = {"fc3": (FC3, FC3_REPLY), "fc16": (FC16, FC16_REPLY)}


def percentile(sorted_values: list[float], p: float) -> float:
    if not sorted_values:
        return float("nan")
    k = min(len(sorted_values) - 1, max(0, round(p / 100 * (len(sorted_values) - 1))))
    return sorted_values[k]


class ServerProcess:
    """A server subprocess; `port` is parsed from the first stdout line matching `pattern`."""

    def __init__(self, argv: list[str], pattern: str, timeout: float = 30.0):
        self.argv = argv
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, cwd=ROOT, env=dict(os.environ,
                                     PYTHONPATH=str(ROOT)))
        self.port = 0
        deadline = time.monotonic() + timeout
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            m = re.search(pattern, line)
            if m:
                self.port = int(m[1])
                break
            if time.monotonic() > deadline:
                break
        if not self.port:
            err = self.proc.stderr.read() if self.proc.stderr else ""
            self.stop()
            raise RuntimeError(f"{' '.join(argv[:4])}... did not start: "
                               f"{err.strip().splitlines()[-1] if err.strip() else 'no port'}")
        # keep draining stdout so a chatty server never blocks on a full pipe
        import threading

        threading.Thread(target=self._drain, daemon=True).start()

    def _drain(self) -> None:
        assert self.proc.stdout is not None
        for _ in self.proc.stdout:
            pass

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)

    def __enter__(self) -> ServerProcess:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()


def _client_proc(port: int, n_sockets: int, frame: bytes, reply: int, start_at: float,
                 duration: float, max_requests: int, out: Any) -> None:
    sel = selectors.DefaultSelector()
    socks = []
    for _ in range(n_sockets):
        s = socket.create_connection(("127.0.0.1", port))
        s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        socks.append(s)
    lat = array("d")
    errors = 0
    now = time.perf_counter
    while time.time() < start_at:
        time.sleep(0.0005)
    end = now() + duration
    t_start = now()
    sent: dict[socket.socket, float] = {}
    bufs: dict[socket.socket, bytearray] = {}
    for s in socks:
        sel.register(s, selectors.EVENT_READ)
        bufs[s] = bytearray()
        sent[s] = now()
        s.sendall(frame)
    active = len(socks)
    fc = frame[7]
    while active:
        for key, _ in sel.select(timeout=5.0) or [(None, None)]:
            if key is None:  # a server that stopped answering: give up
                active = 0
                errors += 1
                break
            s = key.fileobj
            data = s.recv(4096)
            if not data:
                sel.unregister(s)
                active -= 1
                errors += 1
                continue
            b = bufs[s]
            b += data
            if len(b) >= 9 and b[7] & 0x80:  # exception reply (9 bytes)
                errors += 1
                del b[:9]
            elif len(b) < reply:
                continue
            else:
                if b[7] != fc:
                    errors += 1
                del b[:reply]
            t = now()
            lat.append(t - sent[s])
            if t >= end or len(lat) + n_sockets > max_requests:
                sel.unregister(s)
                active -= 1
                continue
            sent[s] = t
            s.sendall(frame)
    elapsed = now() - t_start
    for s in socks:
        s.close()
    out.put((lat.tobytes(), errors, elapsed))


def load(port: int, request: str, clients: int, duration: float,
         max_requests: int = 200_000) -> dict[str, Any]:
    """Closed-loop load; returns requests/s and latency percentiles (ms)."""
    frame, reply = REQUESTS[request]
    procs_n = min(clients, 2)
    split = [clients // procs_n + (1 if i < clients % procs_n else 0) for i in range(procs_n)]
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    start_at = time.time() + 0.3
    procs = [ctx.Process(target=_client_proc, args=(port, k, frame, reply, start_at, duration,
                                                     max_requests // procs_n, q))
             for k in split]
    for p in procs:
        p.start()
    lats = array("d")
    errors = 0
    wall = 0.0
    for _ in procs:
        raw, err, elapsed = q.get(timeout=duration + 60)
        lats.frombytes(raw)
        errors += err
        wall = max(wall, elapsed)
    for p in procs:
        p.join(10)
    values = sorted(lats)
    return {"requests": len(values), "errors": errors, "seconds": wall,
            "requests_per_s": len(values) / wall if wall else 0.0,
            "p50_ms": percentile(values, 50) * 1e3, "p99_ms": percentile(values, 99) * 1e3}


def pymodbus_server() -> ServerProcess:
    return ServerProcess([sys.executable, str(Path(__file__).with_name("pymodbus_server.py")),
                          "0"], r"^listening (\d+)")


def softplc_server(program: Path, config: Path | None, period: str = "10ms") -> ServerProcess:
    argv = [sys.executable, "-m", "softplc", "run", str(program), "--period", period,
            "--port", "0", "--stats-interval", "0"]
    if config is not None:
        argv[5:5] = ["--config", str(config)]
    return ServerProcess(argv, r"listening on [\d.]+:(\d+)")


def run(servers: dict[str, Any], clients: tuple[int, ...] = (1, 8),
        duration: float = 2.0, max_requests: int = 200_000, rounds: int = 1) -> dict[str, Any]:
    """servers: name -> a zero-argument factory returning a started ServerProcess (or raising
    an error whose text is reported). All servers run at once (idle but one); for every case
    the servers take turns, `rounds` times, and the best round (most requests/s) is kept, so
    that a burst of load from elsewhere does not favour one server.
    Returns {name: {"fc3": {"1": {...}, ...}, ...}}."""
    from .common import progress

    results: dict[str, Any] = {}
    running: dict[str, ServerProcess] = {}
    try:
        for name, factory in servers.items():
            try:
                running[name] = factory()
            except Exception as e:  # a server that does not start is a result, not a crash
                results[name] = {"unavailable": str(e)}
        for name, srv in running.items():
            results[name] = {req: {} for req in REQUESTS}
            for req in REQUESTS:
                load(srv.port, req, 1, 0.2, 200)  # warm-up, not recorded
        for req in REQUESTS:
            for n in clients:
                progress(f"modbus: {req} x {n} client(s), {duration:g} s x {rounds} round(s) "
                         f"on {', '.join(running)}")
                for _ in range(rounds):
                    for name, srv in running.items():
                        r = load(srv.port, req, n, duration, max_requests)
                        best = results[name][req].get(str(n))
                        if best is None or r["requests_per_s"] > best["requests_per_s"]:
                            results[name][req][str(n)] = r
    finally:
        for srv in running.values():
            srv.stop()
    return results
