"""The one-process plant's speed (issue 35): 8 controllers of 50 rungs (a master and its 7
peers on one Remote Link, wires between them) on one virtual clock, 10 ms scans. Prints
the real-time factor: plant time / CPU time of this thread (time.thread_time: one core,
blind to the time other processes hold it); the goal is >= 50x.

    .venv/bin/python tools/bench_plant.py [--controllers 8] [--rungs 50] [--seconds 60]
                                          [--rounds 3]

The controllers' programs are generated (`program`): per rung, boolean logic on inputs and
memory bits, a word operation, a timer, the link words; the plant file (`plant_file`)
wires each peer's %Q0.0 to the master's %I0.k and the master's %Q0.0 to every peer.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from softplc.plant import Plant  # noqa: E402
from softplc.twido.address import LINK_STATIONS  # noqa: E402

GOAL = 50.0  # x real time (issue 35, "Numbers")
SCAN_PERIOD = "10ms"
LINK_CYCLE = "70ms"  # seven slots of about 9 ms (softplc.runtime.remotelink.SLOT_US)


def program(rungs: int, station: int, stations: int) -> str:
    """A program of `rungs` rungs for Remote Link station `station` (0: the master of
    `stations` - 1 peers)."""
    out = [f"(* generated for tools/bench_plant.py: station {station} *)"]
    peers = (range(1, stations) or [1]) if station == 0 else [0]
    for r in range(rungs):
        kind = r % 10
        out.append(f"(*RUNG: {r}*)")
        if kind == 0:
            out += [f"LD %I0.{r % 8}", f"AND %M{r}", "IN %TM0", "LD %TM0.Q", f"ST %M{r + 1}"]
        elif kind == 1:
            p = peers[r % len(peers)]
            out += ["LD 1", f"[ %MW{r} := %INW{p}.{r % 4} + %MW{r + 1} ]",
                    f"[ %QNW{p}.{r % 4} := %MW{r} ]"]
        elif kind == 2:
            out += [f"LD [ %MW{r - 1} > 100 ]", f"ANDN %M{r}", f"ST %Q0.{r % 8}"]
        elif kind == 3:
            out += [f"LDR %I0.{r % 8}", f"[ INC %MW{r} ]"]
        else:
            out += [f"LD %M{r - 1}", f"AND( %I0.{r % 8}", f"ORN %M{r + 2}", ")",
                    f"OR %M{r + 3}", f"ST %M{r}"]
    return "\n".join(out) + "\n"


def plant_file(n: int) -> str:
    peers = [f"peer{k}" for k in range(1, n)]
    lines = ['name = "bench"', "", "[controllers.master]", 'program = "station0.il"',
             'config = "station.toml"', "address = 0"]
    for k, name in enumerate(peers, 1):
        lines += ["", f"[controllers.{name}]", f'program = "station{k}.il"',
                  'config = "station.toml"', f"address = {k}"]
    if peers:
        lines += ["", "[links.line]", 'master = "master"',
                  "peers = [" + ", ".join(f'"{p}"' for p in peers) + "]",
                  f'cycle = "{LINK_CYCLE}"']
    for k, name in enumerate(peers, 1):
        lines += ["", "[[wires]]", f'from = "{name}:%Q0.0"', f'to = "master:%I1.{k % 8}"']
    if peers:
        lines += ["", "[[wires]]", 'from = "master:%Q0.1"',
                  "to = [" + ", ".join(f'"{p}:%I1.0"' for p in peers) + "]"]
    return "\n".join(lines) + "\n"


CONFIG = f"""scan_period = "{SCAN_PERIOD}"
modules = {{ 1 = "TM2DDI8DT" }}

[timers."%TM0"]
type = "TON"
base = "10ms"
preset = 20
"""


def build(folder: Path, n: int, rungs: int) -> Path:
    for k in range(n):
        (folder / f"station{k}.il").write_text(program(rungs, k, n))
    (folder / "station.toml").write_text(CONFIG)
    f = folder / "plant.toml"
    f.write_text(plant_file(n))
    return f


def measure(path: Path, seconds: float) -> tuple[float, float, int]:
    """(plant seconds per CPU second, per wall second, scans) of one run."""
    plant = Plant.from_file(path)
    plant.run(1.0)  # warm up: the scans are generated on the first one
    scans0 = sum(c.plc.scan_count for c in plant.controllers.values())
    cpu0, wall0 = time.thread_time(), time.perf_counter()
    plant.run(seconds)
    cpu, wall = time.thread_time() - cpu0, time.perf_counter() - wall0
    scans = sum(c.plc.scan_count for c in plant.controllers.values()) - scans0
    plant.close()
    return seconds / cpu, seconds / wall, scans


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--controllers", type=int, default=8, choices=range(2, LINK_STATIONS + 1),
                    metavar="N", help="a master and N-1 peers (2 .. 8; default 8)")
    ap.add_argument("--rungs", type=int, default=50, help="rungs per program (default 50)")
    ap.add_argument("--seconds", type=float, default=60.0, help="plant time per round")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    if args.rungs < 10 or args.seconds <= 0 or args.rounds < 1:
        ap.error("--rungs >= 10, --seconds > 0, --rounds >= 1")
    with tempfile.TemporaryDirectory() as tmp:
        path = build(Path(tmp), args.controllers, args.rungs)
        runs = [measure(path, args.seconds) for _ in range(args.rounds)]
    cpu = [r[0] for r in runs]
    wall = [r[1] for r in runs]
    scans = runs[0][2]
    best = max(cpu)
    print(f"{args.controllers} controllers x {args.rungs} rungs, {SCAN_PERIOD} scans, link "
          f"cycle {LINK_CYCLE}, {args.seconds:g} s of plant time x {args.rounds} rounds")
    print(f"  scans per round      {scans}")
    print(f"  real-time factor     best {best:.1f}x  median {statistics.median(cpu):.1f}x "
          f"(plant time / CPU time of one core)")
    print(f"  wall-clock factor    best {max(wall):.1f}x  median {statistics.median(wall):.1f}x")
    print(f"  CPU per scan         {args.seconds / best / scans * 1e6:.1f} us (best round)")
    print(f"  goal >= {GOAL:g}x: {'met' if best >= GOAL else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
