"""Building a machine: the CPU time of `PLC.from_file` for each example machine, and of its
first step, `softplc.assembly.assemble` (configuration checked, memory image, modules, analog
channels, constants, EXCH port, engine), best of `--repeat` rounds. Figures only; nothing
is asserted. `--tree` measures another checkout or a git revision (exported by
tools/bench_cpu_ab.py; an older one has no `assemble`: "-").

    .venv/bin/python tools/bench_build.py [--repeat 7] [--tree REV_OR_DIR] [--machines ...]
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import bench_cpu_ab as ab

ROOT = Path(__file__).resolve().parents[1]
MACHINES = ("drawing_table", "cutting_table", "servo_table", "mass_tuning", "star_delta",
            "pid_oven", "remote_io", "fast_counter")


def best_ms(make: Callable[..., Any], *args: Any, repeat: int, inner: int = 5) -> float:
    """Best CPU time of `make(*args)` in ms over `repeat` rounds of `inner` calls."""
    best = float("inf")
    for _ in range(repeat):
        t = time.process_time()
        for _ in range(inner):
            close = getattr(make(*args), "close", None)
            if close:
                close()
        best = min(best, (time.process_time() - t) / inner)
    return best * 1e3


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="CPU time to build each example machine "
                                             "(PLC.from_file and its assemble step).")
    ap.add_argument("--repeat", type=int, default=7, help="rounds; the best counts (7)")
    ap.add_argument("--tree", default=str(ROOT), metavar="REV_OR_DIR",
                    help="the checkout or git revision whose softplc to measure "
                         "(default: this checkout)")
    ap.add_argument("--machines", nargs="+", default=list(MACHINES), metavar="NAME",
                    help="ladder_programs/NAME.il with NAME.toml (default: 8 examples)")
    args = ap.parse_args(argv)
    with ab.sides([args.tree]) as (tree,):
        return measure(tree.root, args.repeat, args.machines)


def measure(tree: Path, repeat: int, machines: list[str]) -> int:
    """The table, softplc imported from `tree`, the machines of this checkout."""
    sys.path.insert(0, str(tree))
    plc_class = importlib.import_module("softplc.plc").PLC
    try:
        assemble = importlib.import_module("softplc.assembly").assemble
    except ImportError:
        assemble = None
    print(f"softplc from {Path(importlib.import_module('softplc').__file__).parent}; "
          f"CPU ms, best of {repeat}")
    print(f"{'machine':16s} {'assemble':>9s} {'from_file':>10s}")
    for name in machines:
        il = ROOT / "ladder_programs" / f"{name}.il"
        toml = il.with_suffix(".toml")
        a = f"{best_ms(assemble, toml, repeat=repeat):9.2f}" if assemble else f"{'-':>9s}"
        f = best_ms(plc_class.from_file, il, toml, repeat=repeat)
        print(f"{name:16s} {a} {f:10.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
