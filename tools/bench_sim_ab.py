"""A/B comparison of the simulation benchmarks (bench_servo, bench_mass, bench_cutting)
between two versions (git revisions or checkout paths), robust to a loaded machine.

On a shared machine even CPU-time figures swing by 30 % and more (other processes evict
the caches, share the core's pipeline). Here each checkout runs each benchmark `--rounds`
times, alternately; a child process records the CPU time of every chunk of 250 scans (the
runs are deterministic, so chunk i is the same work in every run), and the figure is the
simulated time of the full chunks over the sum of the per-chunk minima: a disturbance has
to hit the same chunk in every round to count.

    .venv/bin/python tools/bench_sim_ab.py A [B]
                           [--benches servo_device,servo_machine,mass,cutting] [--rounds 3]

A and B: a revision or a checkout directory (B: this checkout by default); the runs go
through tools/bench_cpu_ab.py (alternating, progress and ETA, clear errors).
"""

from __future__ import annotations

import argparse
import sys

import bench_cpu_ab as ab

BENCHES = ("servo_device", "servo_machine", "mass", "cutting")
CHUNK = 250  # scans
SCAN_S = 1e-3  # every benchmark runs 1 ms scans

CHILD = r"""
import json, sys, time
root, which, chunk = sys.argv[1], sys.argv[2], int(sys.argv[3])
sys.path[:0] = [root, root + "/tools"]
from softplc.runtime.engine import Engine
from softplc.devices.axis.rig import Rig
marks = []

def counting(fn):
    n = [0]
    def f(self, *a, **k):
        n[0] += 1
        if n[0] % chunk == 0:
            marks.append(time.thread_time())
        return fn(self, *a, **k)
    return f

scans = [0]
def tick():
    scans[0] += 1
    if scans[0] % chunk == 0:
        marks.append(time.thread_time())

# An engine's scan is a generated function it swaps in place (runtime/scangen.py), so the
# scans are counted by a hook every engine gets when it is made.
_init = Engine.__init__
def init(self, *a, **k):
    _init(self, *a, **k)
    self.before_scan.append(tick)
Engine.__init__ = init
step = Rig.step
def rig_step(self, n=1):
    for _ in range(n):
        one(self)
one = counting(lambda self: step(self))
Rig.step = rig_step
import bench_servo, bench_cutting, bench_mass
if which == "servo_device":
    sim = bench_servo.device(6.0)["simulated_s"]
elif which == "servo_machine":
    sim = bench_servo.machine(6.0)["simulated_s"]
elif which == "mass":
    sim = bench_mass.run()["sequence"]["simulated_s"]
else:
    sim = bench_cutting.run()["simulated_s"]
print(json.dumps({"sim": sim, "chunks": [b - a for a, b in zip(marks, marks[1:])]}))
"""


def speed(runs: list[dict]) -> tuple[float, float]:
    """(simulated s of the full chunks, speed-up over the summed per-chunk minima)."""
    n = min(len(r["chunks"]) for r in runs)
    best = sum(min(r["chunks"][i] for r in runs) for i in range(n))
    sim = n * CHUNK * SCAN_S
    return sim, sim / best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a", help="side A: revision (e.g. main) or checkout path")
    ap.add_argument("b", nargs="?", default=str(ab.ROOT),
                    help="side B (default: this checkout)")
    ap.add_argument("--benches", default=",".join(BENCHES),
                    help=f"comma-separated, from {', '.join(BENCHES)}")
    ap.add_argument("--rounds", type=ab.positive, default=3,
                    help="runs per side and benchmark")
    a = ap.parse_args(argv)
    benches = [b for b in a.benches.split(",") if b]
    unknown = set(benches) - set(BENCHES)
    if unknown:
        ap.error(f"unknown benchmark(s) {', '.join(sorted(unknown))}; known: "
                 f"{', '.join(BENCHES)}")
    with ab.sides([a.a, a.b]) as sides:
        print(f"{'benchmark':14} {'side':30} {'chunks':>9} "
              f"{'speed-up (CPU, chunk minima)':>29}")
        for bench in benches:
            runs = ab.alternate(sides, a.rounds, lambda side, bench=bench: ab.child(
                side, ["-c", CHILD, str(side.root), bench, str(CHUNK)]), bench)
            for side, side_runs in zip(sides, runs, strict=True):
                sim, x = speed(side_runs)
                print(f"{bench:14} {side.label:30} {sim:7.1f} s {x:28.1f}x", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
