"""Scan-engine benchmark (issue 2): ns per boolean instruction, us per scan.

Figures, best of `repeat` timed loops, warm-up excluded:
  * a generated 1,000-instruction boolean program (tools/gen_programs.boolean_program):
    ns per instruction of the compiled main function alone, and of the full `plc.scan()`
    (system bits, input latch, output publish, statistics: the engine's overhead);
  * a generated 40-rung mixed program (booleans, comparisons, words, a timer, a counter);
  * every program in ladder_programs/*.il with its .toml if there is one: us per scan of
    main() alone, plc.scan() without devices, and plc.scan() with the configured simulated
    devices. A program that does not load yet gets an error line instead.

Targets on the 2-core reference machine: <= 10 ns per boolean instruction, <= 20 us per
scan of a 40-rung program; issue 26: <= 3.0 ns per instruction through plc.scan().

    .venv/bin/python tools/bench_engine.py [--quick] [--cpu] [--against REV [--rounds 4]]
                                           [--no-count]

Beside the times, where valgrind exists, the x86 instructions per scan of the 1,000-line
boolean program under callgrind (tools/instr_count.py: the clock calls counted apart), a
figure that does not move with the machine or its load; `--no-count` skips it (it takes
a minute or two: two runs under valgrind).

`--cpu` times CPU time of the thread (`time.thread_time`: steadier on a shared machine)
instead of wall time; `--against REV` runs the main figures (CPU time) for a git revision
(or a checkout path) and this checkout alternating, and prints them side by side
(tools/bench_cpu_ab.py).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import bench_cpu_ab as ab
import instr_count
from gen_programs import boolean_program
from peers.common import best_interleaved, best_per_batch, loop, print_report, progress
from peers.programs import mixed_program

from softplc.errors import SoftPLCError
from softplc.plc import PLC

ROOT = Path(__file__).resolve().parents[1]

TARGET_NS_PER_BOOL = 10.0
TARGET_US_PER_SCAN_40 = 20.0
TARGET_NS_PER_LINE_26 = 3.0  # issue 26, through plc.scan()
CLOCK = time.perf_counter  # --cpu: time.thread_time


def time_plc(plc: PLC, number: int, repeat: int) -> dict[str, float]:
    """us per call of the compiled main() alone and of the full plc.scan() (timed runs
    alternating, so a burst of load from elsewhere hits both alike)."""
    t = best_interleaved({"main": loop(plc.program.main), "scan": plc.scan}, number, repeat,
                         clock=CLOCK)
    return {"main_us": t["main"] * 1e6, "scan_us": t["scan"] * 1e6}


def locals_floor(plc: PLC) -> Callable[[], None]:
    """main() of a program of %M bits only, with each bit a local variable (default
    argument) instead of an item of the memory list: the same bytecode less the memory
    reads and writes, the floor a different memory image could at best reach."""
    src = plc.program.source
    bits = sorted(set(re.findall(r"_M\[(\d+)\]", src)), key=int)
    body = re.sub(r"_M\[(\d+)\]", r"m\1", src.split("\n", 1)[1])
    if src.count("\ndef ") or re.search(r"\b_[A-Z]", body):
        raise ValueError("locals_floor: a single function over %M bits only")
    ns: dict[str, Any] = {}
    exec("def floor(" + ", ".join(f"m{n}=False" for n in bits) + "):\n" + body, ns)
    return ns["floor"]


def _scale(quick: bool, tiny: bool) -> tuple[int, int]:
    if tiny:
        return 20, 2
    return (500, 3) if quick else (5000, 7)


def run(quick: bool = False, tiny: bool = False,
        programs_dir: Path = ROOT / "ladder_programs") -> dict[str, Any]:
    """All engine figures as a dict (see the module docstring). `tiny` is for the smoke
    test: a few calls, a 40-instruction program, structure only."""
    number, repeat = _scale(quick, tiny)
    n_instr = 40 if tiny else 1000
    progress(f"engine: boolean program, {n_instr} instructions, {number} calls x {repeat}")
    plc = PLC.from_source(boolean_program(n_instr), file="<boolean>")
    t = best_interleaved({"main": loop(plc.program.main), "scan": plc.scan,
                          "floor": loop(locals_floor(plc))}, number, repeat, clock=CLOCK)
    boolean = {
        "instructions": plc.program.instruction_count, "rungs": len(plc.rungs),
        "main_us": t["main"] * 1e6, "scan_us": t["scan"] * 1e6,
        "main_ns_per_instr": t["main"] * 1e9 / n_instr,
        "scan_ns_per_instr": t["scan"] * 1e9 / n_instr,
        "floor_ns_per_instr": t["floor"] * 1e9 / n_instr,
    }
    progress("engine: 40-rung mixed program")
    text, cfg = mixed_program(40)
    plc = PLC.from_source(text, cfg, file="<mixed40>")
    mixed = {"instructions": plc.program.instruction_count, "rungs": len(plc.rungs),
             **time_plc(plc, number, repeat)}
    files = []
    for il in sorted(programs_dir.glob("*.il")):
        progress(f"engine: {il.relative_to(ROOT) if il.is_relative_to(ROOT) else il}")
        files.append(_time_file(il, number, repeat))
    return {
        "boolean": boolean, "mixed40": mixed, "programs": files,
        "settings": {"number": number, "repeat": repeat},
        "targets": {"ns_per_bool_instr": TARGET_NS_PER_BOOL,
                    "us_per_scan_40_rungs": TARGET_US_PER_SCAN_40},
    }


def config_for(il: Path) -> Path | None:
    """x.toml for x.il; else the .toml whose name is the longest prefix of the program's
    (drawing_table_seed.il runs with drawing_table.toml, which says it serves both)."""
    exact = il.with_suffix(".toml")
    if exact.exists():
        return exact
    cands = [t for t in il.parent.glob("*.toml") if il.stem.startswith(t.stem + "_")]
    return max(cands, key=lambda t: len(t.stem)) if cands else None


def _time_file(il: Path, number: int, repeat: int) -> dict[str, Any]:
    cfg = config_for(il)
    entry: dict[str, Any] = {"program": il.name, "config": cfg.name if cfg else None}
    try:
        plc = PLC.from_file(il, cfg, devices=False)
        entry.update(instructions=plc.program.instruction_count, rungs=len(plc.rungs),
                     **time_plc(plc, number, repeat))
        if plc.settings.devices:
            with PLC.from_file(il, cfg, devices=True) as dev:
                entry["scan_devices_us"] = best_per_batch(dev.scan, number, repeat,
                                                             clock=CLOCK) * 1e6
    except (SoftPLCError, OSError, ValueError) as e:
        entry["error"] = f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
    return entry


def verdicts(res: dict[str, Any]) -> list[tuple[str, float, str, bool]]:
    """(figure, value, target text, met) for the engine targets."""
    b, m = res["boolean"], res["mixed40"]
    return [
        ("ns/boolean instruction, main()", b["main_ns_per_instr"],
         f"<= {TARGET_NS_PER_BOOL:g}", b["main_ns_per_instr"] <= TARGET_NS_PER_BOOL),
        ("ns/boolean instruction, plc.scan()", b["scan_ns_per_instr"],
         f"<= {TARGET_NS_PER_BOOL:g}", b["scan_ns_per_instr"] <= TARGET_NS_PER_BOOL),
        ("us/scan, 40-rung program, plc.scan()", m["scan_us"],
         f"<= {TARGET_US_PER_SCAN_40:g}", m["scan_us"] <= TARGET_US_PER_SCAN_40),
        ("ns/boolean instruction, plc.scan(), #26", b["scan_ns_per_instr"],
         f"<= {TARGET_NS_PER_LINE_26:g}", b["scan_ns_per_instr"] <= TARGET_NS_PER_LINE_26),
    ]


def report(res: dict[str, Any]) -> str:
    b, m = res["boolean"], res["mixed40"]
    lines = [
        "Scan engine (best of {repeat} x {number} calls, warm-up excluded)".format(
            **res["settings"]),
        f"  boolean program, {b['instructions']} instructions / {b['rungs']} rungs: "
        f"main() {b['main_us']:.2f} us = {b['main_ns_per_instr']:.2f} ns/instr; "
        f"plc.scan() {b['scan_us']:.2f} us = {b['scan_ns_per_instr']:.2f} ns/instr",
        f"    main() with the bits as locals (the floor under it) "
        f"{b['floor_ns_per_instr']:.2f} ns/instr; over the floor: main() "
        f"{b['main_ns_per_instr'] / b['floor_ns_per_instr']:.2f}x, plc.scan() "
        f"{b['scan_ns_per_instr'] / b['floor_ns_per_instr']:.2f}x (the floor moves with "
        f"the machine's speed, the ratios much less)",
        f"  mixed program, {m['rungs']} rungs / {m['instructions']} instructions: "
        f"main() {m['main_us']:.2f} us; plc.scan() {m['scan_us']:.2f} us",
        f"  {'program':28}{'rungs':>6}{'instr':>7}{'main us':>10}{'scan us':>10}"
        f"{'+devices us':>13}",
    ]
    for e in res["programs"]:
        if "error" in e:
            lines.append(f"  {e['program']:28}error: {e['error']}")
            continue
        dev = f"{e['scan_devices_us']:13.2f}" if "scan_devices_us" in e else f"{'-':>13}"
        lines.append(f"  {e['program']:28}{e['rungs']:6}{e['instructions']:7}"
                     f"{e['main_us']:10.2f}{e['scan_us']:10.2f}{dev}")
    lines.append("  targets:")
    for name, v, target, ok in verdicts(res):
        lines.append(f"    {name:40}{v:8.2f}  target {target:8} {'met' if ok else 'MISSED'}")
    return "\n".join(lines)


def profile(il: Path, scans: int = 50_000, top: int = 15) -> str:
    """cProfile of `scans` plc.scan() of a program (its config, no devices): where the
    time of a scan goes, by function, most expensive first."""
    import cProfile
    import io
    import pstats

    plc = PLC.from_file(il, config_for(il), devices=False)
    plc.scan(1000)
    prof = cProfile.Profile()
    prof.runcall(plc.scan, scans)
    buf = io.StringIO()
    pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(top)
    return buf.getvalue()


# the figures an A/B run compares: (key, label, higher is better)
AB_KEYS = (("bool_main_ns", "boolean main(), ns/line", False),
           ("bool_scan_ns", "boolean plc.scan(), ns/line", False),
           ("bool_floor_ns", "boolean floor (locals), ns/line", False),
           ("mixed_scan_us", "mixed 40 rungs plc.scan(), us", False))


COUNT_SCANS = (100, 600)  # the two runs' scans under callgrind: their difference is measured
COUNT_CHILD = r"""
import sys
import instr_count
from gen_programs import boolean_program
from softplc.plc import PLC
plc = PLC.from_source(boolean_program(int(sys.argv[2])), file="<boolean>")
plc.scan()
instr_count.start()
for _ in range(int(sys.argv[1])):
    plc.scan()
"""


def count_line(n_instr: int = 1000) -> str:
    """Instructions per plc.scan() of the n-instruction boolean program, or why not."""
    if not instr_count.available():
        return instr_count.MISSING
    c = instr_count.count(COUNT_CHILD, *COUNT_SCANS, str(n_instr))
    return (c.line(f"plc.scan() of the {n_instr:,}-instruction boolean program")
            + f" ({c.without_clock / n_instr:.1f} per IL instruction)")


def ab_figures(res: dict[str, Any]) -> dict[str, float]:
    b = res["boolean"]
    return {"bool_main_ns": b["main_ns_per_instr"], "bool_scan_ns": b["scan_ns_per_instr"],
            "bool_floor_ns": b["floor_ns_per_instr"], "mixed_scan_us": res["mixed40"]["scan_us"]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer calls and repeats")
    ap.add_argument("--json", type=Path, help="also write the figures as JSON here")
    ap.add_argument("--cpu", action="store_true",
                    help="time CPU time of the thread, not wall time")
    ab.add_against(ap, rounds=4, note=", CPU time")
    ap.add_argument("--ab-child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--profile", type=Path, metavar="PROGRAM.il",
                    help="instead: cProfile plc.scan() of this program, top functions")
    ap.add_argument("--no-count", action="store_true",
                    help="skip the instruction count under valgrind (callgrind)")
    a = ap.parse_args(argv)
    if a.cpu or a.against or a.ab_child:
        global CLOCK
        CLOCK = time.thread_time
    if a.against:
        args = ["--ab-child"] + (["--quick"] if a.quick else [])
        print(ab.compare(a.against, a.rounds, ab.script_run(__file__, args), AB_KEYS,
                         "Scan engine A/B (CPU time)"))
        return 0
    if a.ab_child:  # the boolean and mixed figures only, as one line of JSON
        import softplc  # the side's tree (PYTHONPATH), which is the working directory

        if not Path(softplc.__file__).resolve().is_relative_to(Path.cwd().resolve()):
            raise SystemExit(f"softplc imported from {softplc.__file__}, not {Path.cwd()}")
        print(json.dumps(ab_figures(run(quick=a.quick, programs_dir=Path("no-programs")))))
        return 0
    if a.profile:
        print(profile(a.profile))
        return 0
    res = run(quick=a.quick)
    print_report(report(res), res, a.json)
    if not a.no_count:
        print(count_line())
    return 0


if __name__ == "__main__":
    sys.exit(main())
