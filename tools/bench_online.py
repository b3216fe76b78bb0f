"""Online program change through the web API: how long `POST /api/program` takes for
programs of growing size (check + compile in a worker thread, swap at a scan boundary), and
how late the 10 ms scans start meanwhile (the compile shares the GIL with the scan
thread), and how long the swap itself holds the scan thread (`online.apply` compiles the
new program there again, measured apart on an idle PLC). Figures only; nothing is asserted.

    .venv/bin/python tools/bench_online.py [--instructions 1000 20000 100000] [--period 10]
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

sys.path.insert(0, str(Path(__file__).resolve().parent))
from gen_programs import boolean_program  # noqa: E402 (tools/, the script's folder)

from softplc import online  # noqa: E402
from softplc.access import AccessPort  # noqa: E402
from softplc.commands.io import Client  # noqa: E402
from softplc.modbus import ModbusImage, ServerThread  # noqa: E402
from softplc.plc import PLC  # noqa: E402
from softplc.web import WebOptions, attach  # noqa: E402


class Running:
    """A PLC scanned every `period` s by a thread, served by Modbus and the web monitor;
    records how late each scan starts."""

    def __init__(self, program: str, period: float):
        self.plc = PLC.from_source(program)
        self.image = ModbusImage(self.plc.mem)
        self.plc.before_scan.append(self.image.apply_writes)
        self.plc.after_scan.append(self.image.take_snapshot)
        self.modbus = ServerThread(self.image, "127.0.0.1", 0).start()
        daemon = SimpleNamespace(plc=self.plc, program_name="bench.il", overruns=0,
                                 late_starts=0, skipped_starts=0, jitter_max=0.0)
        self.web = attach(daemon, self.modbus, AccessPort(self.plc, self.image),
                          WebOptions(port=0))
        self.period = period
        self.late: list[float] = []
        self._stop = False
        self.thread = threading.Thread(target=self._scan, daemon=True)
        self.thread.start()

    def _scan(self) -> None:
        t = time.perf_counter()
        while not self._stop:
            t += self.period
            delay = t - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            self.late.append(max(0.0, time.perf_counter() - t))
            self.plc.scan()
            if time.perf_counter() > t + self.period:
                t = time.perf_counter()  # overrun: start again from now

    def close(self) -> None:
        self._stop = True
        self.thread.join(2)
        self.web.stop()
        self.modbus.stop()


def swap_ms(old: str, new: str) -> float:
    """How long `online.apply` holds the scan thread (it compiles the new program there)."""
    plc = PLC.from_source(old)
    change = online.plan(plc, new)
    t0 = time.perf_counter()
    online.apply(plc, change)
    return (time.perf_counter() - t0) * 1000


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--instructions", type=int, nargs="+", default=[1000, 20000, 100000],
                    help="program sizes in IL instructions (default 1000 20000 100000)")
    ap.add_argument("--period", type=float, default=10.0, help="scan period, ms (10)")
    args = ap.parse_args()
    print(f"{'instructions':>12} {'bytes':>9} {'POST s':>8} {'late p50 ms':>12} "
          f"{'late max ms':>12} {'scans during':>13} {'swap ms':>8}")
    for n in args.instructions:
        old, new = boolean_program(n, seed=1), boolean_program(n, seed=2)
        run = Running(old, args.period / 1000)
        try:
            time.sleep(0.3)
            client = Client("127.0.0.1", run.web.server.port, timeout=600)
            first = len(run.late)
            t0 = time.perf_counter()
            answer = client.request("program", {"program": new, "file": "new.il"})
            took = time.perf_counter() - t0
            late = sorted(run.late[first:]) or [0.0]
            assert answer["applied"], answer
            print(f"{n:>12} {len(new.encode()):>9} {took:>8.2f} "
                  f"{late[len(late) // 2] * 1000:>12.2f} {late[-1] * 1000:>12.2f} "
                  f"{len(late):>13} {swap_ms(old, new):>8.1f}")
        finally:
            run.close()


if __name__ == "__main__":
    main()
