"""A/B comparison of the simulation benchmarks (bench_servo, bench_mass, bench_cutting)
between two checkouts, robust to a loaded machine.

On a shared machine even CPU-time figures swing by 30 % and more (other processes evict
the caches, share the core's pipeline). Here each checkout runs each benchmark `--rounds`
times, alternately; a child process records the CPU time of every chunk of 250 scans (the
runs are deterministic, so chunk i is the same work in every run), and the figure is the
simulated time of the full chunks over the sum of the per-chunk minima: a disturbance has
to hit the same chunk in every round to count.

    .venv/bin/python tools/bench_sim_ab.py /path/to/checkout_a /path/to/checkout_b
                                          [--benches servo_device,servo_machine,mass,cutting]
                                          [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

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


def run_child(root: Path, bench: str) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(root), bench, str(CHUNK)],
                         capture_output=True, text=True, check=False)
    if out.returncode:
        raise SystemExit(f"{root} {bench}: the benchmark failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def speed(runs: list[dict]) -> tuple[float, float]:
    """(simulated s of the full chunks, speed-up over the summed per-chunk minima)."""
    n = min(len(r["chunks"]) for r in runs)
    best = sum(min(r["chunks"][i] for r in runs) for i in range(n))
    sim = n * CHUNK * SCAN_S
    return sim, sim / best


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a", type=Path, help="first checkout (e.g. /work/main)")
    ap.add_argument("b", type=Path, help="second checkout")
    ap.add_argument("--benches", default=",".join(BENCHES),
                    help=f"comma-separated, from {', '.join(BENCHES)}")
    ap.add_argument("--rounds", type=int, default=3, help="runs per checkout and benchmark")
    a = ap.parse_args(argv)
    benches = [b for b in a.benches.split(",") if b]
    unknown = set(benches) - set(BENCHES)
    if unknown:
        ap.error(f"unknown benchmark(s) {', '.join(sorted(unknown))}; known: "
                 f"{', '.join(BENCHES)}")
    print(f"{'benchmark':14} {'checkout':30} {'chunks':>9} {'speed-up (CPU, chunk minima)':>29}")
    t0 = time.monotonic()
    total = len(benches) * a.rounds * 2
    done = 0
    for bench in benches:
        runs: dict[Path, list[dict]] = {a.a: [], a.b: []}
        for _ in range(a.rounds):
            for root in (a.a, a.b):
                runs[root].append(run_child(root, bench))
                done += 1
                eta = (time.monotonic() - t0) / done * (total - done)
                print(f"  ... {done}/{total} runs, ETA {eta:.0f} s", file=sys.stderr)
        for root in (a.a, a.b):
            sim, x = speed(runs[root])
            print(f"{bench:14} {str(root):30} {sim:7.1f} s {x:28.1f}x", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
