"""softplc's Modbus TCP server against libmodbus (C), both driven by a C load generator.

    .venv/bin/python tools/bench_modbus_c.py [--duration 2] [--rounds 3] [--clients 8]

Servers (subprocesses on 127.0.0.1, ports picked free by the servers): `softplc run` on
tools/bench_modbus.py's program scanning every 10 ms, with the event loop it uses by
default (uvloop when installed) and with plain asyncio (SOFTPLC_EVENT_LOOP=asyncio), and
peers/libmodbus_server.c. Load: peers/modbus_load.c, CLIENTS closed-loop connections in
one C process (a Python client saturates before the server does). Cases: FC 3 reading 10
registers, FC 16 writing 100. The servers take turns each round; the best round is kept.
Printed per case: requests/s, server CPU per request (us, from /proc: the whole process,
the scan thread included) and softplc's ratio to libmodbus (goals: FC 3 >= 1.0x,
FC 16 >= 0.9x, issue 26). `--baseline REV_OR_PATH` adds a server run from a git revision
or another checkout (before/after in one run; the side resolved by tools/bench_cpu_ab.py).
Needs gcc and libmodbus-dev.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import bench_cpu_ab as ab
from peers.libmodbus_peer import LibmodbusServer
from peers.modbus_peer import ServerProcess

HERE = Path(__file__).resolve().parent
CASES = {"FC 3 x 10": (3, 10, 0), "FC 16 x 100": (16, 100, 100)}
GOALS = {"FC 3 x 10": 1.0, "FC 16 x 100": 0.9}
TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process, all threads."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def build_load(folder: Path) -> Path:
    exe = folder / "modbus_load"
    r = subprocess.run(["gcc", "-O2", str(HERE / "peers" / "modbus_load.c"), "-o", str(exe)],
                       capture_output=True, text=True)
    if r.returncode:
        raise SystemExit(f"gcc failed: {r.stderr.strip()}")
    return exe


def softplc(program: Path, loop: str, checkout: Path | None = None) -> ServerProcess:
    """`softplc run` of this checkout, or of another one (its softplc imported first)."""
    os.environ["SOFTPLC_EVENT_LOOP"] = loop
    start = ["-m", "softplc"] if checkout is None else [
        "-c", f"import sys; sys.path.insert(0, {str(checkout)!r}); from softplc.cli import "
        "main; sys.exit(main())"]
    try:
        return ServerProcess([sys.executable, *start, "run", str(program), "--period",
                              "10ms", "--port", "0", "--stats-interval", "0"],
                             r"listening on [\d.]+:(\d+)")
    finally:
        os.environ.pop("SOFTPLC_EVENT_LOOP", None)


def load(exe: Path, srv: ServerProcess, clients: int, seconds: float, case: str
         ) -> tuple[float, float]:
    """(requests/s, server CPU us per request) of one run."""
    fc, qty, addr = CASES[case]
    c0 = cpu_seconds(srv.proc.pid)
    r = subprocess.run([str(exe), str(srv.port), str(clients), str(seconds), str(fc),
                        str(qty), str(addr)], capture_output=True, text=True, timeout=seconds + 30)
    c1 = cpu_seconds(srv.proc.pid)
    words = r.stdout.split()
    if r.returncode or len(words) != 6:
        raise SystemExit(f"load generator failed: {r.stderr.strip() or r.stdout.strip()}")
    replies, errors, wall = int(words[1]), int(words[3]), float(words[5])
    if errors:
        raise SystemExit(f"{case}: {errors} errors from the server on port {srv.port}")
    return replies / wall, (c1 - c0) / replies * 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=2.0, help="seconds per run (2)")
    ap.add_argument("--rounds", type=int, default=3, help="turns per server, best kept (3)")
    ap.add_argument("--clients", type=int, default=8, help="connections (8)")
    ap.add_argument("--baseline", metavar="REV_OR_PATH",
                    help="also serve from this git revision or checkout (e.g. main)")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp, \
            ab.sides([a.baseline] if a.baseline else []) as baseline:
        exe = build_load(Path(tmp))
        program = Path(tmp) / "bench.il"
        # imported here: it loads the daemon (0.7 s of CPU); a bad --baseline is refused
        # before that
        from bench_modbus import DEFAULT_PROGRAM

        program.write_text(DEFAULT_PROGRAM)
        servers = {"softplc": softplc(program, "default"),
                   "softplc asyncio": softplc(program, "asyncio"),
                   "libmodbus": LibmodbusServer()}
        if baseline:
            servers["baseline"] = softplc(program, "default", baseline[0].root)
        best: dict[tuple[str, str], tuple[float, float]] = {}
        try:
            time.sleep(1.0)
            for case in CASES:
                for srv in servers.values():
                    load(exe, srv, a.clients, 0.3, case)  # warm-up
                for _ in range(a.rounds):
                    for name, srv in servers.items():
                        rate, cpu = load(exe, srv, a.clients, a.duration, case)
                        if rate > best.get((name, case), (0.0, 0.0))[0]:
                            best[name, case] = (rate, cpu)
        finally:
            for srv in servers.values():
                srv.stop()
    print(f"{a.clients} clients, C load generator, best of {a.rounds} x {a.duration:g} s, "
          f"{os.cpu_count()} CPUs; req/s (server CPU us/request)")
    print(f"{'case':14}" + "".join(f"{n:>22}" for n in servers) + "   softplc/libmodbus")
    for case in CASES:
        cells = "".join(f"{best[n, case][0]:>12,.0f} ({best[n, case][1]:5.1f})"
                        for n in servers)
        ratio = best["softplc", case][0] / best["libmodbus", case][0]
        others = ", ".join(f"{n} {best[n, case][0] / best['libmodbus', case][0]:.2f}x"
                           for n in servers if n not in ("softplc", "libmodbus"))
        print(f"{case:14}{cells}   {ratio:.2f}x ({others}), goal >= {GOALS[case]:g}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
