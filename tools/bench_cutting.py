"""Cutting-table simulation speed: the rounded rectangle (E3, ladder_programs/pieces/
achaflanado.toml) cut by cutting_table.il on its two servo axes (2.26 kHz servo clock) at
1 ms scans, the segments fed in-process through the PLC's words (the Modbus host's
handshake without the network: `softplc.cutting.client.feed_plc`). Homing is done before
the clock starts. Prints simulated seconds per wall second and per CPU second (the machine
is shared: under load the wall figure falls while the CPU figure holds). Target (issue 13):
>= 50x real time.

    python tools/bench_cutting.py [--speed 2]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tomllib
from pathlib import Path

from peers.common import speed_line

from softplc import PLC
from softplc.cutting import load_piece
from softplc.cutting.client import feed_plc

ROOT = Path(__file__).resolve().parent.parent

TOML = ROOT / "ladder_programs" / "cutting_table.toml"
IL = ROOT / "ladder_programs" / "cutting_table.il"
PIECE = ROOT / "ladder_programs" / "pieces" / "achaflanado.toml"
TARGET = 50.0
READY = 4


def run(speed: float = 2.0, piece_file: Path = PIECE) -> dict:
    conf = tomllib.loads(TOML.read_text(encoding="utf-8"))
    for a in ("X", "Y"):
        conf["devices"][a]["start"] = 100_000.0  # 1 mm: short homing, not timed
    plc = PLC.from_file(IL, conf)
    if not plc.run_until(lambda p: p["%MW111"] == READY, 30.0):
        raise RuntimeError(f"the cutting table did not get ready: fault {plc['%MW110']}")
    piece = load_piece(piece_file, speed=speed, move_speed=speed)
    t_sim0 = plc.time
    w0, c0 = time.perf_counter(), time.thread_time()
    n = feed_plc(plc, piece)
    wall, cpu = time.perf_counter() - w0, time.thread_time() - c0
    sim = plc.time - t_sim0
    plc.close()
    return {"piece": piece_file.name, "speed_mm_s": speed, "segments": n, "simulated_s": sim,
            "wall_s": wall, "cpu_s": cpu, "speedup": sim / wall, "speedup_cpu": sim / cpu,
            "us_per_scan": wall / sim * 1e3, "load_average": os.getloadavg()}


def report(r: dict) -> str:
    return (f"Cutting table: {r['piece']} at {r['speed_mm_s']:g} mm/s, {r['segments']} "
            f"segments, 1 ms scans, cutting_table.il + two servo axes + trace "
            f"(tools/bench_cutting.py; load average {r['load_average'][0]:.1f})\n"
            + speed_line(r, TARGET))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speed", type=float, default=2.0,
                    help="cutting speed, mm/s (default 2: the thesis's v)")
    a = ap.parse_args(argv)
    print(report(run(a.speed)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
