"""A/B comparison of `plc.scan()` cost between two checkouts, in CPU time.

On a loaded machine wall-clock figures swing by 2x from run to run; the CPU time of the
main thread (`time.thread_time`) does not count the time other processes hold the core, so
it compares two versions of the engine much more steadily.

    .venv/bin/python tools/bench_cpu_ab.py /path/to/checkout_a /path/to/checkout_b
                                          [--rounds 3] [--scans 5000]

Each round runs one child process per checkout (alternating), each timing the 40-rung
mixed program and the ladder_programs examples (without devices); the table shows the
best of all rounds in us of CPU per scan.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

CHILD = r"""
import json, sys, time, timeit
root, scans = sys.argv[1], int(sys.argv[2])
sys.path[:0] = [root, root + "/tools"]
from softplc.plc import PLC
from peers.programs import mixed_program
res = {}
def t(name, plc):
    plc.scan(100)
    best = min(timeit.repeat(plc.scan, number=scans, repeat=5, timer=time.thread_time))
    res[name] = best / scans * 1e6
src, cfg = mixed_program()
t("mixed program (40 rungs)", PLC.from_source(src, cfg))
for name in ("drawing_table", "traffic_light", "star_delta"):
    lp = root + "/ladder_programs/" + name
    t(name + ".il", PLC.from_file(lp + ".il", lp + ".toml", devices=False))
print(json.dumps(res))
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a", type=Path, help="first checkout (e.g. main)")
    ap.add_argument("b", type=Path, help="second checkout (e.g. your branch)")
    ap.add_argument("--rounds", type=int, default=3, help="alternating rounds (default 3)")
    ap.add_argument("--scans", type=int, default=5000, help="scans per timing (default 5000)")
    args = ap.parse_args(argv)
    best: dict[str, dict[str, float]] = {}
    for r in range(args.rounds):
        for side in (args.a, args.b):
            print(f"\r  round {r + 1}/{args.rounds}: {side}", end="", file=sys.stderr,
                  flush=True)
            out = subprocess.run([sys.executable, "-c", CHILD, str(side.resolve()),
                                  str(args.scans)], capture_output=True, text=True,
                                 check=True).stdout
            for prog, us in json.loads(out).items():
                d = best.setdefault(prog, {})
                d[str(side)] = min(d.get(str(side), float("inf")), us)
    print(file=sys.stderr)
    print(f"{'program':<28}{'A us':>9}{'B us':>9}{'B/A':>8}   (CPU per scan, best of "
          f"{args.rounds} rounds)")
    for prog, d in best.items():
        a, b = d[str(args.a)], d[str(args.b)]
        print(f"{prog:<28}{a:>9.2f}{b:>9.2f}{b / a:>8.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
