"""Client slots under attack (issue 21): is a legitimate Modbus client still answered?

Starts `softplc run --max-clients 8` with every other setting at its default, then for
each attack keeps 8 hostile connections open (reopening each one the server closes):

- idle: connect and send nothing;
- slowloris: a valid request dripped one byte per second;
- never-reading: pipelined requests as fast as the socket takes them, no reply read.

After the attackers have had `--settle` seconds to take the slots, a legitimate client
connects and reads %MW0; printed: the seconds until its first answer (the target is
30 s), then how many of its polls (one every 0.5 s for `--poll` seconds, reconnecting
when dropped) were answered, and what the server did to the attackers.

    .venv/bin/python tools/bench_slots.py [--settle 3] [--poll 10]
"""

from __future__ import annotations

import argparse
import re
import select
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from softplc.modbus.rawclient import RawClient
from softplc.modbus_codec import frame as mbap_frame

ROOT = Path(__file__).resolve().parents[1]
REQUEST = mbap_frame(1, 1, struct.pack(">BHH", 3, 0, 125))  # 12 bytes in, 259 bytes out
KINDS = ("idle", "slowloris", "never-reading")


class Attack(threading.Thread):
    """`n` hostile connections of one kind to 127.0.0.1:`port`, each reopened when the
    server closes it (`reconnect`). `drip`: seconds between slowloris bytes."""

    def __init__(self, kind: str, port: int, n: int = 8, drip: float = 1.0,
                 reconnect: bool = True):
        super().__init__(name=f"attack-{kind}", daemon=True)
        if kind not in KINDS:
            raise ValueError(f"unknown attack {kind!r}: one of {', '.join(KINDS)}")
        self.kind, self.port, self.n, self.drip, self.reconnect = kind, port, n, drip, reconnect
        self.stop_event = threading.Event()
        self.connects = 0  # connections opened
        self.closed = 0  # connections the server closed or reset
        self.held = threading.Event()  # set once all n are open at the same time
        self._socks: list[socket.socket | None] = [None] * n
        self._opened = [False] * n
        self._sent = [0] * n  # slowloris: bytes of the current request sent

    def stop(self) -> None:
        self.stop_event.set()
        self.join(5)
        for s in self._socks:
            if s is not None:
                s.close()

    def __enter__(self) -> Attack:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _open(self, i: int) -> None:
        try:
            s = socket.create_connection(("127.0.0.1", self.port), timeout=1)
        except OSError:
            return
        s.setblocking(False)
        self._socks[i], self._sent[i], self._opened[i] = s, 0, True
        self.connects += 1

    def _lost(self, i: int) -> None:
        s = self._socks[i]
        if s is not None:
            s.close()
        self._socks[i] = None
        self.closed += 1

    def _step(self, i: int, s: socket.socket) -> None:
        try:
            if self.kind == "never-reading":
                try:
                    s.send(REQUEST * 1000)
                except BlockingIOError:
                    pass
            elif self.kind == "slowloris":
                s.send(REQUEST[self._sent[i]:self._sent[i] + 1])
                self._sent[i] = (self._sent[i] + 1) % len(REQUEST)
            if self.kind != "never-reading":  # the server never writes to these: a
                r, _, _ = select.select([s], [], [], 0)  # readable socket is a closed one
                if r and not s.recv(4096):
                    self._lost(i)
        except OSError:
            self._lost(i)

    def run(self) -> None:
        period = self.drip if self.kind == "slowloris" else 0.02
        while not self.stop_event.is_set():
            for i in range(self.n):
                if self._socks[i] is None and (self.reconnect or not self._opened[i]):
                    self._open(i)
            if all(s is not None for s in self._socks):
                self.held.set()
            for i, s in enumerate(self._socks):
                if s is not None:
                    self._step(i, s)
            self.stop_event.wait(period)


def first_answer(port: int, limit: float = 30.0) -> tuple[float, RawClient] | None:
    """A new client reads %MW0, reconnecting after each refusal or drop: the seconds
    until the first answer and its connection (None: no answer within `limit` s)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit:
        c = None
        try:
            c = RawClient("127.0.0.1", port, timeout=min(5.0, limit))
            c.read_registers(0, 1)
            return time.monotonic() - t0, c
        except (OSError, ConnectionError):
            if c is not None:
                c.close()
            time.sleep(0.1)
    return None


def time_to_answer(port: int, limit: float = 30.0) -> float | None:
    """Seconds until a new client's first read of %MW0 is answered (see first_answer)."""
    got = first_answer(port, limit)
    if got is None:
        return None
    got[1].close()
    return got[0]


def poll(port: int, seconds: float, interval: float = 0.5) -> tuple[int, int]:
    """A client polling %MW0 every `interval` s: (answered, failed) polls."""
    ok = failed = 0
    client: RawClient | None = None
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            if client is None:
                client = RawClient("127.0.0.1", port, timeout=2)
            client.read_registers(0, 1)
            ok += 1
        except (OSError, ConnectionError):
            failed += 1
            if client is not None:
                client.close()
            client = None
        time.sleep(interval)
    if client is not None:
        client.close()
    return ok, failed


COUNTER = "LD 1\n[ %MW1 := %MW1 + 1 ]\nEND\n"


def start_daemon(tmp: Path, *args: str, program: str = COUNTER) -> tuple[subprocess.Popen, int]:
    """`softplc run` on a free port with `args` (normal priority, no statistics, no web
    monitor): the process and its Modbus port."""
    prog = tmp / "p.il"
    prog.write_text(program)
    proc = subprocess.Popen(
        [sys.executable, "-m", "softplc", "run", str(prog), "--port", "0", *args,
         "--stats-interval", "0", "--rt-priority", "0", "--web", "off"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=tmp)
    for line in proc.stdout:  # type: ignore[union-attr]
        m = re.search(r"listening on [\d.]+:(\d+)", line)
        if m:
            threading.Thread(target=proc.stdout.read, daemon=True).start()  # type: ignore
            return proc, int(m[1])
    raise RuntimeError("the daemon did not start")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--settle", type=float, default=3.0,
                    help="seconds the attackers get before the client comes (3)")
    ap.add_argument("--poll", type=float, default=10.0,
                    help="seconds the client then polls, every 0.5 s (10)")
    ap.add_argument("--attack", choices=KINDS, action="append",
                    help="run only this attack (repeatable; default: all three)")
    args = ap.parse_args(argv)
    print(f"{'attack (8 connections)':24} {'first answer':>12} {'polls answered':>15} "
          f"{'attacker connects':>17}")
    with tempfile.TemporaryDirectory() as d:
        proc, port = start_daemon(Path(d), "--max-clients", "8")
        try:
            for kind in args.attack or KINDS:
                with Attack(kind, port) as atk:
                    atk.held.wait(args.settle)
                    time.sleep(args.settle)
                    first = time_to_answer(port)
                    ok, failed = poll(port, args.poll)
                shown = "none in 30 s" if first is None else f"{first * 1000:.0f} ms"
                print(f"{kind:24} {shown:>12} {ok:>8}/{ok + failed:<6} {atk.connects:>17}")
        finally:
            proc.terminate()
            proc.wait(10)
    return 0


if __name__ == "__main__":
    sys.exit(main())
