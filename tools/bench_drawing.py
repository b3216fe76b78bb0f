"""Simulated drawing speed: simulated seconds per wall second for a 100-segment figure.

The drawing-table program and its simulated table (steppers, switches, pen, trace) run on
the virtual clock at a 1 ms scan; a host loop in the same process writes each segment
exactly as the Modbus host does (X, Z, pen, INICIO := 120, then waits for INICIO = 0 and
EJECUTANDO = 0). Target (issue 4): >= 50x real time.

    python tools/bench_drawing.py [--segments 100] [--program ladder_programs/drawing_table.il]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from softplc import PLC

ROOT = Path(__file__).resolve().parent.parent


def figure(n: int, steps_per_cm: float = 111.11) -> list[tuple[int, int, int]]:
    """A closed n-segment figure (a 7-pointed star polygon on a rosette), in steps."""
    pts = []
    for k in range(n):
        a = 2 * math.pi * k * 3 / 7 + k * 0.01
        r = 8.0 + 3.0 * math.cos(5 * a)
        x = 12.5 + r * math.cos(a)
        z = 12.5 + r * math.sin(a)
        pts.append((round(x * steps_per_cm), round(z * steps_per_cm), 1))
    return pts


def run(segments: int = 100, program: str = "ladder_programs/drawing_table.il",
        config: str = "ladder_programs/drawing_table.toml", scan_period: str = "1ms",
        progress: bool = True) -> dict:
    cfg_path = ROOT / config
    import tomllib

    cfg = tomllib.loads(cfg_path.read_text())
    cfg["scan_period"] = scan_period
    plc = PLC.from_file(ROOT / program, cfg)
    plc.run(seconds=0.01)
    homing_until = plc.run_until(lambda p: p["%MW10"] == 0 and p.scan_count > 5, 60)
    if not homing_until:
        raise RuntimeError("homing did not finish")
    pts = figure(segments)
    t_sim0, wall0, scans0 = plc.time, time.perf_counter(), plc.scan_count
    for i, (x, z, pen) in enumerate(pts):
        plc["%MW0"], plc["%MW1"], plc["%MW5"] = x, z, pen
        plc["%MW3"] = 120
        if not plc.run_until(lambda p: p["%MW3"] == 0 and p["%MW10"] == 0, 120):
            raise RuntimeError(f"segment {i} did not finish")
        if progress and (i + 1) % 10 == 0:
            print(f"\r  drawing: {i + 1}/{len(pts)} segments", end="", file=sys.stderr)
    if progress:
        print(file=sys.stderr)
    wall = time.perf_counter() - wall0
    sim = plc.time - t_sim0
    scans = plc.scan_count - scans0
    return {"segments": len(pts), "simulated_s": sim, "wall_s": wall, "scans": scans,
            "speedup": sim / wall, "us_per_scan": wall / scans * 1e6,
            "missed_steps": plc.devices["X"].missed_steps + plc.devices["Z"].missed_steps,
            "trace_samples": len(plc.trace)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--segments", type=int, default=100)
    ap.add_argument("--program", default="ladder_programs/drawing_table.il")
    ap.add_argument("--config", default="ladder_programs/drawing_table.toml")
    args = ap.parse_args(argv)
    r = run(args.segments, args.program, args.config)
    print(f"drawing {r['segments']} segments at 1 ms scan: {r['simulated_s']:.2f} simulated s "
          f"in {r['wall_s']:.2f} wall s = {r['speedup']:.0f}x real time "
          f"({r['us_per_scan']:.2f} us per scan incl. devices and host; "
          f"{r['missed_steps']} missed steps; target >= 50x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
