"""Servo simulation speed: simulated seconds per wall (and CPU) second, two servo axes at
the 2.26 kHz PMAC servo clock with 1 ms scans, while both axes run the thesis's S-curve move
back and forth (14,336 counts at 69,632 counts/s, Ixx20/21 = 125/40 ms) with the servo-rate
trace on. Target (issue 12): >= 50x real time.

Two figures: `device` (the two servo_axis devices alone, stepped scan by scan as the engine
does) and `machine` (the whole servo table: servo_table.il on the scan engine with both
axes, started, homed, host moves written into its request block in the same process).
CPU time is printed beside wall time because the benchmark machine is shared: on a loaded
machine the wall figure falls while the CPU figure holds. `calib_ns` is a plain Python
loop's ns per iteration, to compare runs on different machines or loads.

    python tools/bench_servo.py [--seconds 5]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tomllib
from pathlib import Path

from softplc import PLC
from softplc.devices.axis import Ctl, St
from softplc.devices.axis.rig import Rig

ROOT = Path(__file__).resolve().parent.parent

TOML = ROOT / "ladder_programs" / "servo_table.toml"
IL = ROOT / "ladder_programs" / "servo_table.il"
DIST, SPEED = 14336, 69632
TARGET = 50.0


def _calib() -> float:
    t0 = time.thread_time()
    s = 0
    for i in range(200_000):
        s += i * 2
    return (time.thread_time() - t0) / 200_000 * 1e9


def _timed(fn, sim_s: float) -> dict:
    w0, c0 = time.perf_counter(), time.thread_time()
    fn()
    wall, cpu = time.perf_counter() - w0, time.thread_time() - c0
    return {"simulated_s": sim_s, "wall_s": wall, "cpu_s": cpu, "speedup": sim_s / wall,
            "speedup_cpu": sim_s / cpu}


def device(seconds: float) -> dict:
    rig = Rig.from_toml(TOML, "X", "Y", require_home=False, start=-80000.0)  # mid-travel
    for a in "XY":
        rig.command(a, Ctl.ENABLE)
    rig.run(0.05)
    n = round(seconds / 0.5)

    def go() -> None:
        for i in range(n):
            for a in "XY":
                d = DIST if i % 2 == 0 else -DIST
                rig.pulse(a, Ctl.EXECUTE, target=round(rig.axes[a].actual) + d, speed=SPEED,
                          acc_ms=125, scurve_ms=40)
            rig.run(0.499)

    res = _timed(go, n * 0.5)
    res["servo_cycles"] = sum(ax.k for ax in rig.axes.values())
    res["faults"] = sum(1 for ax in rig.axes.values() if ax.error)
    return res


def machine(seconds: float) -> dict:
    conf = tomllib.loads(TOML.read_text())
    for a in ("X", "Y"):
        conf["devices"][a]["start"] = -2500.0  # short homing: the figure is about moving
    plc = PLC.from_file(IL, conf)
    plc["%MW100"] = 5  # remote start: home X then Y
    plc.scan()
    if not plc.run_until(lambda p: p["%MW111"] == 2, 30.0):
        raise RuntimeError(f"the servo table did not get ready: cell state {plc['%MW111']}")
    n = round(seconds / 0.5)
    x0 = {"X": -40000, "Y": -60000}

    def go() -> None:
        for i in range(n):
            for k, a in enumerate("XY"):
                plc["%MW101"], plc["%MD102"], plc["%MD104"] = k, x0[a] + DIST * (i % 2), SPEED
                plc["%MW106"], plc["%MW107"], plc["%MW108"] = 125, 40, 0
                plc["%MW100"] = 1
                plc.scan()
            plc.run(0.498)

    res = _timed(go, n * 0.5 + 2 * n * plc.scan_period)
    st = plc["%MW218"], plc["%MW248"]
    res["faults"] = sum(1 for s in st if s & St.ERROR)
    plc.close()
    return res


def run(seconds: float = 5.0) -> dict:
    return {"calib_ns": _calib(), "device": device(seconds), "machine": machine(seconds),
            "load_average": os.getloadavg()}


def report(r: dict) -> str:
    lines = [f"Servo table: two axes at 2258.65 Hz, 1 ms scans, S-curve moves back and "
             f"forth (tools/bench_servo.py; python loop {r['calib_ns']:.0f} ns/iter, load "
             f"average {r['load_average'][0]:.1f})"]
    for name, what in (("device", "two servo_axis devices"),
                       ("machine", "servo_table.il + both axes on the engine")):
        x = r[name]
        lines.append(f"  {what:42} {x['simulated_s']:.1f} simulated s: "
                     f"{x['speedup']:.0f}x real time (wall), {x['speedup_cpu']:.0f}x "
                     f"(CPU)  target >= {TARGET:.0f}x  "
                     f"{'met' if x['speedup_cpu'] >= TARGET else 'MISSED'} (CPU)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per figure")
    a = ap.parse_args(argv)
    print(report(run(a.seconds)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
