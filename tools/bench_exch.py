"""EXCH against a dripping remote (issue 21): does the daemon keep scanning and stop?

The remote reads the request, then sends its reply one byte every `--drip` seconds (an
MBAP header announcing 254 bytes, then zeros, for ever): every read sees a byte in time,
only the exchange's one deadline ends it. The program exchanges again as soon as the
last exchange ended and counts its scans in %MW30. Printed:

- SIGTERM during a drip (`[exch] timeout = "60s"`): seconds until the daemon has exited,
  on the real clock and with `--speed max` (`--runs` each);
- `--speed max` with the default 1 s timeout: scans in `--seconds` of wall time.

    .venv/bin/python tools/bench_exch.py [--drip 0.4] [--runs 3] [--seconds 8]
"""

from __future__ import annotations

import argparse
import signal
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path

from bench_slots import start_daemon

from softplc.modbus.rawclient import RawClient

# EXCH3 %MW0:10 whenever the port is idle: FC03, read 1 word at 0 from remote device 1
PROGRAM = "LD %MSG3.D\nEXCH3 %MW0:10\nLD 1\n[%MW30 := %MW30 + 1]\n" + "".join(
    f"LD 1\n[%MW{k} := {v}]\n" for k, v in enumerate([0x0106, 0x0300, 0x0103, 0, 1]))


class Dripper:
    """A remote on a free loopback port that drips its reply one byte every `interval` s."""

    def __init__(self, interval: float = 0.4):
        self.interval = interval
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen()
        self.port = self.sock.getsockname()[1]
        self.stop = threading.Event()
        self.requests = threading.Event()  # set when a request has come in
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        self.sock.settimeout(0.1)
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            threading.Thread(target=self._drip, args=(conn,), daemon=True).start()

    def _drip(self, conn: socket.socket) -> None:
        with conn:
            try:
                request = conn.recv(300)
                self.requests.set()
                reply = request[:4] + b"\x00\xfe" + request[6:7] + bytes(10_000)
                for b in reply:
                    if self.stop.wait(self.interval):
                        return
                    conn.sendall(bytes([b]))
            except OSError:
                return

    def close(self) -> None:
        self.stop.set()
        self.sock.close()

    def __enter__(self) -> Dripper:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def config(self, timeout: str) -> str:
        """The TOML of a machine whose EXCH remote device 1 is this dripper."""
        return (f'[exch]\ntimeout = "{timeout}"\n[exch.remote.1]\nhost = "127.0.0.1"\n'
                f"port = {self.port}\nunit_id = 1\n")


def sigterm_seconds(drip: float, speed: str | None) -> float:
    with Dripper(drip) as d, tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        (tmp / "m.toml").write_text(d.config("60s"))
        proc, _ = start_daemon(tmp, "--config", str(tmp / "m.toml"),
                               *(["--speed", speed] if speed else []), program=PROGRAM)
        try:
            if not d.requests.wait(10):
                raise RuntimeError("the daemon sent no request")
            time.sleep(0.5)
            t0 = time.monotonic()
            proc.send_signal(signal.SIGTERM)
            proc.wait(120)
            return time.monotonic() - t0
        finally:
            if proc.poll() is None:
                proc.kill()


def scans_at_max_speed(drip: float, seconds: float) -> int:
    with Dripper(drip) as d, tempfile.TemporaryDirectory() as t:
        tmp = Path(t)
        (tmp / "m.toml").write_text(d.config("1s"))
        proc, port = start_daemon(tmp, "--config", str(tmp / "m.toml"), "--speed", "max",
                                  program=PROGRAM)
        try:
            t0 = time.monotonic()
            time.sleep(seconds)
            with RawClient("127.0.0.1", port, timeout=5) as c:
                scans = c.read_registers(30, 1)[0]
            print(f"  (read after {time.monotonic() - t0:.1f} s)")
            return scans
        finally:
            proc.terminate()
            proc.wait(30)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--drip", type=float, default=0.4, help="seconds between bytes (0.4)")
    ap.add_argument("--runs", type=int, default=3, help="SIGTERM runs per clock (3)")
    ap.add_argument("--seconds", type=float, default=8.0,
                    help="wall seconds of the --speed max run (8)")
    args = ap.parse_args(argv)
    for speed in (None, "max"):
        times = [sigterm_seconds(args.drip, speed) for _ in range(args.runs)]
        print(f"SIGTERM during a drip, {speed and '--speed max' or 'real clock'}: "
              + ", ".join(f"{x:.2f}" for x in times) + " s")
    print(f"--speed max, 1 s timeout: {scans_at_max_speed(args.drip, args.seconds)} scans "
          f"in {args.seconds:g} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
