"""Cutting-table simulation speed: the rounded rectangle (E3, ladder_programs/pieces/
achaflanado.toml) cut by cutting_table.il on its two servo axes (2.26 kHz servo clock) at
1 ms scans, the segments fed in-process through the PLC's words (the Modbus host's
handshake without the network: `softplc.machines.cutting.client.feed_plc`). Homing is done before
the clock starts. Prints simulated seconds per wall second and per CPU second of the
simulating thread (the machine is shared: under load the wall figure falls while the CPU
figure holds), and the servo device: CPU microseconds per `update` of one axis of the
cutting table alone, jogging (2-3 servo cycles a scan) and holding at rest, and of both
axes inside a second run of the piece (each update timed). Target (issue 13): >= 50x
real time.

`--against REV` runs the same figures for a git revision of this repository (exported to
a temporary directory) or a checkout path and this checkout alternately, `--rounds` times
each, each run in its own process, and prints them side by side (best and median of the
rounds; tools/bench_cpu_ab.py).

    python tools/bench_cutting.py [--speed 2] [--against HEAD~3 [--rounds 3]]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import tomllib
from pathlib import Path

import bench_cpu_ab as ab
from peers.common import speed_line

from softplc import PLC
from softplc.machines.cutting import load_piece
from softplc.machines.cutting.client import feed_plc

ROOT = Path(__file__).resolve().parent.parent

TOML = ROOT / "ladder_programs" / "cutting_table.toml"
IL = ROOT / "ladder_programs" / "cutting_table.il"
PIECE = ROOT / "ladder_programs" / "pieces" / "achaflanado.toml"
TARGET = 50.0
READY = 4


def _ready_plc() -> PLC:
    conf = tomllib.loads(TOML.read_text(encoding="utf-8"))
    for a in ("X", "Y"):
        conf["devices"][a]["start"] = 100_000.0  # 1 mm: short homing, not timed
    plc = PLC.from_file(IL, conf)
    if not plc.run_until(lambda p: p["%MW111"] == READY, 30.0):
        raise RuntimeError(f"the cutting table did not get ready: fault {plc['%MW110']}")
    return plc


def run(speed: float = 2.0, piece_file: Path = PIECE) -> dict:
    plc = _ready_plc()
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


def servo_update_us(moving: bool, scans: int = 15_000, repeat: int = 5) -> float:
    """Best-of-`repeat` CPU us per `update` of the cutting table's X axis alone (its TOML
    table; the loop closed), jogging at Ixx22 (10 mm/s, 150 mm each way between 75 and
    225 mm; the reversals not timed) or holding at rest."""
    from softplc.devices.axis import Ctl
    from softplc.devices.axis.rig import Rig

    rig = Rig.from_toml(TOML, "X", start=22_500_000.0)
    best = float("inf")
    for i in range(repeat):
        jog = (Ctl.JOG_MINUS if i % 2 == 0 else Ctl.JOG_PLUS) if moving else 0
        rig.command("X", Ctl.ENABLE | jog)
        rig.run(0.5)  # at cruise speed, or settled
        update = rig.axes["X"].update
        t_us = rig.t_us
        c0 = time.thread_time()
        for _ in range(scans):
            t_us += 1000
            update(t_us / 1e6, 1e-3)
        best = min(best, time.thread_time() - c0)
        rig.t_us = t_us
        if moving and not rig.axes["X"].closed:
            raise RuntimeError("the jogging axis stopped: the figure would be wrong")
    return best / scans * 1e6


def in_run_update_us(speed: float) -> float:
    """CPU us per servo axis `update` inside the whole run (a second run, each update timed
    with the thread's clock: that adds ~0.3 us to each; the run's figures are not kept)."""
    from softplc.devices.axis.servo import ServoAxis

    clock, total, calls = time.thread_time_ns, [0], [0]
    update = ServoAxis.update

    def timed(self: ServoAxis, t: float, dt: float) -> None:
        c0 = clock()
        update(self, t, dt)
        total[0] += clock() - c0
        calls[0] += 1

    ServoAxis.update = timed  # type: ignore[method-assign]
    try:
        plc = _ready_plc()
        piece = load_piece(PIECE, speed=speed, move_speed=speed)
        total[0] = calls[0] = 0  # (homing not counted)
        feed_plc(plc, piece)
        plc.close()
    finally:
        ServoAxis.update = update  # type: ignore[method-assign]
    return total[0] / calls[0] / 1e3


def figures(speed: float) -> dict:
    r = run(speed)
    r["update_moving_us"] = servo_update_us(True)
    r["update_rest_us"] = servo_update_us(False)
    r["update_in_run_us"] = in_run_update_us(speed)
    return r


def report(r: dict) -> str:
    text = (f"Cutting table: {r['piece']} at {r['speed_mm_s']:g} mm/s, {r['segments']} "
            f"segments, 1 ms scans, cutting_table.il + two servo axes + trace "
            f"(tools/bench_cutting.py; load average {r['load_average'][0]:.1f})\n"
            + speed_line(r, TARGET))
    if "update_moving_us" in r:
        text += (f"\n  servo axis alone: {r['update_moving_us']:.2f} us per update jogging, "
                 f"{r['update_rest_us']:.2f} at rest (CPU, best of 5 x 15,000); in the "
                 f"run: {r['update_in_run_us']:.2f} us per update (timed each)")
    return text


def against(rev: str, speed: float, rounds: int) -> str:
    """Side by side: `rev` (before) and this checkout (after), runs alternating."""
    keys = (("speedup_cpu", "x real time (CPU)", True), ("speedup", "x real time (wall)", True),
            ("update_moving_us", "us per update, jogging", False),
            ("update_rest_us", "us per update, at rest", False),
            ("update_in_run_us", "us per update, in the run", False))
    return ab.compare(rev, rounds, ab.script_run(
        __file__, ["--speed", str(speed), "--json", "--root", "{root}"]),
        keys, "Cutting table A/B")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speed", type=float, default=2.0,
                    help="cutting speed, mm/s (default 2: the thesis's v)")
    ab.add_against(ap, rounds=3)
    ap.add_argument("--json", action="store_true", help="print the figures as JSON")
    ap.add_argument("--root", type=Path, help=argparse.SUPPRESS)  # (--against's children)
    a = ap.parse_args(argv)
    if a.against:
        print(against(a.against, a.speed, a.rounds))
        return 0
    if a.root:  # the machine files of that checkout
        global TOML, IL, PIECE
        TOML, IL, PIECE = (a.root / p.relative_to(ROOT) for p in (TOML, IL, PIECE))
    r = figures(a.speed)
    print(json.dumps(r) if a.json else report(r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
