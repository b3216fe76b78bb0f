"""Parse time of a large program, clean and with syntax errors (error recovery's cost).

    .venv/bin/python tools/bench_parse.py [--lines 6000] [--bad 100] [--repeat 3]

Prints the best-of-N parse CPU time of a generated program of LINES lines, clean and with BAD
lines replaced by garbage, and their ratio (target < 2: recovery must not re-parse the
whole file per bad line). Absolute times vary with the machine's load; compare the ratio.
"""

from __future__ import annotations

import argparse
import gc
import random
import time

from softplc.errors import ParseError
from softplc.il.parser import parse


def program(lines: int) -> list[str]:
    out: list[str] = []
    for k in range(lines // 4 + 1):
        out += [f"(* rung {k} *)", f"LD %M{k % 200}", f"AND %I0.{k % 12}", f"ST %Q0.{k % 10}"]
    return out[:lines]


def best(text: str, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        gc.collect()
        t0 = time.thread_time()  # CPU time: the machine may be shared
        try:
            parse(text)
        except ParseError:
            pass
        times.append(time.thread_time() - t0)
    return min(times)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lines", type=int, default=6000, help="program size (default 6000)")
    ap.add_argument("--bad", type=int, default=100, help="bad lines (default 100)")
    ap.add_argument("--repeat", type=int, default=3, help="best of N runs (default 3)")
    a = ap.parse_args()
    lines = program(a.lines)
    clean = "\n".join(lines) + "\n"
    for n in random.Random(1).sample(range(len(lines)), min(a.bad, len(lines))):
        lines[n] = "LD %M1 garbage ]]"
    bad = "\n".join(lines) + "\n"
    parse("LD %M0\n")  # build the grammar once, outside the timing
    tc, tb = best(clean, a.repeat), best(bad, a.repeat)
    print(f"parse {a.lines} lines: clean {tc:.3f} s, with {a.bad} bad lines {tb:.3f} s, "
          f"ratio {tb / tc:.2f} (target < 2)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
