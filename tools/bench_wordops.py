"""Word arithmetic and block calls in generated code (issue 26): ns per line of `main()`.

Each case is a generated one-rung program of `--lines` lines of one kind (operands spread
over many addresses, all values in range so no %S18); the figure is the best-of time of
the compiled `main()` divided by the number of lines, and a plain Python loop's cost is
printed beside it so that the figures can be scaled to another machine. Goals of issue 26:
a %MW word line <= 50 ns, a timer or counter call <= 100 ns.

    .venv/bin/python tools/bench_wordops.py [--lines 200] [--number 2000] [--repeat 7]
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from peers.common import best_interleaved, best_per_call, loop, progress

from softplc.plc import PLC

GOALS_NS = {"word": 50.0, "block": 100.0}


def _lines(kind: str, n: int) -> tuple[list[str], dict[str, Any]]:
    """IL lines of one case (after `LD 1`) and the configuration it needs."""
    if kind == "add16":
        return [f"[ %MW{200 + k} := %MW{k % 100} + %MW{(k * 7) % 100} ]" for k in range(n)], {}
    if kind == "inc16":
        return [f"[ INC %MW{k} ]" for k in range(n)], {}
    if kind == "sub32":
        return [f"[ %MD{200 + 2 * k} := %MD{2 * (k % 50)} - %MD{2 * ((k * 3) % 50)} ]"
                for k in range(n)], {}
    if kind == "div32s":  # a single division of plain reads
        return [f"[ %MD{200 + 2 * k} := %MD{2 * (k % 50)} / %KD{2 * (k % 8)} ]"
                for k in range(n)], {"constants": {f"%KD{2 * i}": 7 + i for i in range(8)}}
    if kind == "div32":
        return [f"[ %MD{200 + 2 * k} := ( %MD{2 * (k % 50)} - %MD100 ) / %KD{2 * (k % 8)} ]"
                for k in range(n)], {"constants": {f"%KD{2 * i}": 7 + i for i in range(8)}}
    if kind == "timer":
        timers = {f"%TM{k}": {"type": "TON", "base": "10ms", "preset": 5} for k in range(64)}
        return [s for k in range(n) for s in (f"BLK %TM{k % 64}", f"LD %M{k % 64}", "IN",
                                                "END_BLK")], \
            {"timers": timers}
    if kind == "counter":
        counters = {f"%C{k}": {"preset": 9999} for k in range(64)}
        return [s for k in range(n) for s in (f"LD %M{k % 64}", f"CU %C{k % 64}")], \
            {"counters": counters}
    if kind == "counter_blk":
        counters = {f"%C{k}": {"preset": 9999} for k in range(64)}
        return [s for k in range(n) for s in (f"BLK %C{k % 64}", f"LD %M{64 + k % 64}", "R",
                                                f"LD %M{k % 64}", "CU", "END_BLK")], \
            {"counters": counters}
    raise ValueError(kind)


CASES = ("add16", "inc16", "sub32", "div32s", "div32", "timer", "counter", "counter_blk")


def _floor_main(lines: int) -> Any:
    """The add16 case's lines with no overflow check at all, over a word memoryview like
    the PLC's: what any checked form costs at least (reads, int objects, the store)."""
    src = "def f(_MW=_MW):\n" + "".join(
        f"    _MW[{200 + k}] = _MW[{k % 100}] + _MW[{(k * 7) % 100}]\n" for k in range(lines))
    mw = memoryview(bytearray(2 * 512)).cast("h")
    for k in range(100):
        mw[k] = (k * 37) % 1000 - 400
    ns: dict[str, Any] = {"_MW": mw}
    exec(src, ns)
    return ns["f"]


def _list_main(lines: int) -> Any:
    """The add16 case's lines over words held in a Python list, each sum checked against
    the 16-bit range in the code (the memoryview does that check now): what a list-held
    word image would cost, checked (a way in for issue 26, not how the memory is held)."""
    src = "def f(_L=_L, _wrap=_wrap):\n" + "".join(
        f"    _v = _L[{k % 100}] + _L[{(k * 7) % 100}]\n"
        f"    _L[{200 + k}] = _v if -32768 <= _v <= 32767 else _wrap(_v)\n"
        for k in range(lines))
    ns: dict[str, Any] = {"_L": [(k * 37) % 1000 - 400 for k in range(512)],
                          "_wrap": lambda v: (v + 32768) % 65536 - 32768}
    exec(src, ns)
    return ns["f"]


def build(kind: str, n: int) -> PLC:
    lines, cfg = _lines(kind, n)
    plc = PLC.from_source("LD 1\n" + "\n".join(lines) + "\n", cfg or None, file=f"<{kind}>")
    for k in range(100):  # non-zero operands, the words within range
        plc.mem.words("MW").w[k] = (k * 37) % 1000 - 400
    return plc


def run(lines: int, number: int, repeat: int) -> dict[str, Any]:
    plcs = {}
    for kind in CASES:
        progress(f"wordops: {kind}, {lines} lines")
        plcs[kind] = build(kind, lines)
        for k in range(0, 64, 2):  # the timers/counters: raise half the inputs
            plcs[kind].mem.bits("M")[k] = 1
    mains = {k: loop(p.program.main) for k, p in plcs.items()}
    mains["add16 floor"] = loop(_floor_main(lines))
    mains["add16 list"] = loop(_list_main(lines))
    t = best_interleaved(mains, number, repeat)
    x = 0

    def plain() -> None:  # a plain Python loop iteration, for scaling
        nonlocal x
        for i in range(1000):
            x = i
    base_ns = best_per_call(plain, 200, repeat) * 1e9 / 1000
    return {"lines": lines, "loop_ns": base_ns,
            "ns_per_line": {k: v * 1e9 / lines for k, v in t.items()}}


def report(res: dict[str, Any]) -> str:
    out = [f"plain Python loop: {res['loop_ns']:.1f} ns per iteration",
           f"{'case':<10}{'ns/line':>10}  goal"]
    for k, v in res["ns_per_line"].items():
        goal = GOALS_NS["block" if k.startswith(("timer", "counter")) else "word"]
        out.append(f"{k:<10}{v:>10.1f}  <= {goal:.0f}: {'met' if v <= goal else 'not met'}")
    out.append("(add16 floor: the same lines unchecked, a plain function over a memoryview;")
    out.append(" add16 list: checked in the code, over words held in a Python list)")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="ns per word line and per block call of "
                                 "compiled main() (issue 26)")
    ap.add_argument("--lines", type=int, default=200, help="lines per case (200)")
    ap.add_argument("--number", type=int, default=2000, help="main() calls per timing (2000)")
    ap.add_argument("--repeat", type=int, default=7, help="timings, best kept (7)")
    a = ap.parse_args(argv)
    print(report(run(a.lines, a.number, a.repeat)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
