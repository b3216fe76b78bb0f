"""`softplc verify` timings: seconds per requirement.

    .venv/bin/python tools/bench_verify.py [--stations 9] [--timeout 60] [--quick] [--machines]
        [--program STEM] [--timers]

1. A generated program of 6 rungs per station (9 stations: 54 rungs): start/stop latch
   with an interlock against the neighbour station, an on-delay timer, a counted cycle
   word with 16-bit arithmetic and a limit, a state word. Requirements per station pair:
   interlock (never both), the cycle word stays in range, stop drops the output.
   Goal: each requirement answered within 10 s on this 2-core machine.
2. ladder_programs/drawing_table.il: its phase requirements (drawing_table.req.toml),
   proven or clean to 50 scans. Goal: within 60 s each.
3. A deep counterexample: an interlock broken only once a 5 s on-delay timer (10 ms
   scan) is done, 501 scans from the cold start: seconds to find it (BMC).
4. `--machines`: every shipped requirement file (`--program STEM`: those matching), the
   model's own facts (verify/stateinv.py) timed apart: once per program.
5. `--timers`: ladder_programs/two_hand.req.toml, whose proofs need the relations between
   three timers (verify/invariants.py; a 0.5 s window at 50 ms: k = 11 without them).
Figures go to stdout: requirement, result, method, seconds.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from softplc.plc import PLC  # noqa: E402
from softplc.verify.engines import Limits  # noqa: E402
from softplc.verify.guard import check, isolated  # noqa: E402
from softplc.verify.model import Model  # noqa: E402
from softplc.verify.requirements import load_spec  # noqa: E402
from softplc.verify.stateinv import prove  # noqa: E402


def stations_program(n: int) -> tuple[str, dict, list[str]]:
    """A program of 6 rungs per station, its configuration and requirements."""
    lines, timers, reqs = [], {}, []
    for i in range(n):
        start, stop, q, other = f"%I0.{i}", f"%I0.{12 + i}", f"%Q0.{i}", f"%Q0.{i ^ 1}"
        w, s = f"%MW{10 + i}", f"%MW{40 + i}"
        lines += [f"(*RUNG: station {i}: start/stop latch, interlocked*)",
                  f"LD {start}", f"OR {q}", f"AND {stop}", f"ANDN {other}", f"ST {q}",
                  f"(*RUNG: station {i}: on-delay*)", f"LD {q}", f"IN %TM{i}",
                  f"(*RUNG: station {i}: count cycles*)", f"LD %TM{i}.Q", f"ANDN %M{i}",
                  f"[ {w} := {w} + 1 ]", f"LD %TM{i}.Q", f"ST %M{i}",
                  f"(*RUNG: station {i}: limit*)", f"LD [ {w} >= 1000 ]", f"[ {w} := 0 ]",
                  f"(*RUNG: station {i}: state word*)", "LD 1", f"[ {s} := {w} * 2 ]"]
        timers[f"%TM{i}"] = {"type": "TON", "base": "100ms", "preset": 5 + i}
        if i % 2 == 0:
            reqs.append(f"never {q} AND {other}")
        reqs += [f"always {w} >= 0 AND {w} < 1000", f"{stop} = 0 -> {q} = 0"]
    # two that fail: stations 0 and 2 are not interlocked; a start is not always answered
    reqs += ["never %Q0.0 AND %Q0.2", "%I0.0 rising -> %Q0.0 within 2 scans",
             "always %MW40 <= 1998"]  # a proof that needs the strengthening (k > 1)
    return "\n".join(lines) + "\n", {"scan_period": "10ms", "timers": timers}, reqs


DEEP = "LD %I0.0\nAND %I0.1\nIN %TM0\nLD %TM0.Q\nST %Q0.0\nLD %I0.2\nST %Q0.1\n"


def run(plc: PLC, spec, timeout: float, depth: int,
        devices: dict | None = None) -> list[tuple[str, str, str, float]]:
    free = [r for r, _ in spec.free]  # as the command builds it
    model = Model(plc, spec.reads + free, spec.host + free, spec.periods, held=spec.held,
                  devices=devices)
    t0 = time.perf_counter()
    facts = prove(model, isolated)  # once per model, before its first requirement
    print(f"  the model's own facts (verify/stateinv.py): {len(facts)} proven, "
          f"{time.perf_counter() - t0:.2f} s once", flush=True)
    out, lemmas = [], []
    for req in spec.requirements:
        t0 = time.perf_counter()
        res = check(model, spec, req, lemmas, Limits(depth, 10, timeout), [])  # as the command
        if res.status == "PROVEN" and req.kind == "always":
            lemmas.append(req.cond)  # as softplc verify does
        out.append((req.name, res.status, res.method, time.perf_counter() - t0))
        print(f"  {req.name[:58]:58s} {res.status:8s} {res.method:22s} "
              f"{out[-1][3]:6.2f} s", flush=True)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description="softplc verify: seconds per requirement")
    ap.add_argument("--stations", type=int, default=9, help="6 rungs each, at most 10 "
                    "(default 9)")
    ap.add_argument("--timeout", type=float, default=60.0, help="s per requirement")
    ap.add_argument("--quick", action="store_true", help="2 stations, no drawing table")
    ap.add_argument("--machines", action="store_true",
                    help="only section 4: every shipped requirement file")
    ap.add_argument("--timers", action="store_true", help="only section 5: the two-hand "
                    "control (timer relations; issue 34 item 4)")
    ap.add_argument("--program", default="*", help="with --machines: the requirement "
                    "files STEM.req.toml (a glob, default every one)")
    args = ap.parse_args()
    n = 2 if args.quick else min(10, args.stations)
    print(f"load average at start: {os.getloadavg()[0]:.2f} (2 cores shared)")
    if args.machines or args.timers:
        machines(args.timeout, "two_hand" if args.timers else args.program)
        return 0
    if not args.quick:
        deep()
    text, config, reqs = stations_program(n)
    plc = PLC.from_source(text, config, devices=False, file="stations.il")
    spec = load_spec(None, reqs, plc.profile)
    print(f"generated program: {len(plc.ast.rungs)} rungs, {len(reqs)} requirements "
          f"(goal <= 10 s each)")
    res = run(plc, spec, args.timeout, 30)
    times = [r[3] for r in res]
    print(f"  max {max(times):.2f} s, mean {sum(times) / len(times):.2f} s, "
          f"{sum(r[1] == 'PROVEN' for r in res)} proven, "
          f"{sum(r[1] == 'VIOLATED' for r in res)} violated, of {len(res)}")
    if not args.quick:
        lp = ROOT / "ladder_programs"
        plc = PLC.from_file(lp / "drawing_table.il", lp / "drawing_table.toml", devices=False)
        spec = load_spec(lp / "drawing_table.req.toml", [], plc.profile)
        print("drawing_table.il, drawing_table.req.toml, depth 50 (goal <= 60 s each)")
        res = run(plc, spec, args.timeout, 50)
        print(f"  max {max(r[3] for r in res):.2f} s")
    return 0


def machines(timeout: float, stem: str = "*") -> None:
    """Section 4: every ladder_programs/*.req.toml on its program (`stem`: one), as
    `softplc verify` (the environment with the devices' words). Goals (issue 34): <= 10 s
    per requirement up to 50 rungs (the two-hand control, section 5, included), the
    drawing table <= 20 s, the cutting table and mass tuning <= 60 s."""
    from softplc.verify.environment import device_words
    lp = ROOT / "ladder_programs"
    for req in sorted(lp.glob(f"{stem}.req.toml")):
        stem = req.name.removesuffix(".req.toml")
        program = lp / f"{stem}.il"
        config = lp / f"{stem.removesuffix('_seed')}.toml"
        plc = PLC.from_file(program, config, devices=False)
        spec = load_spec(req, [], plc.symbols)  # as the command: symbols allowed
        print(f"{program.name} ({len(plc.ast.rungs)} rungs), {req.name}")
        run(plc, spec, timeout, 30, device_words(program, config))


def deep() -> None:
    """Section 3, run first: z3's terms of the other sections slow it down (one context)."""
    plc = PLC.from_source(DEEP, {"scan_period": "10ms", "timers": {"%TM0": {
        "type": "TON", "base": "10ms", "preset": 500}}}, devices=False, file="deep.il")
    spec = load_spec(None, ["never %Q0.0 AND %Q0.1"], plc.profile)
    model = Model(plc, spec.reads, spec.host, spec.periods)
    t0 = time.perf_counter()
    res = check(model, spec, spec.requirements[0], [], Limits(600, 10, 300, False), [])
    print(f"deep counterexample (5 s timer, 10 ms scan): {res.status} in {res.depth} "
          f"scans, {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    sys.exit(main())
