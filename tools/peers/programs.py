"""The benchmark programs, written once as Twido IL and translated for the peers.

The boolean programs are parsed by softplc's own parser and the AST is translated to
pyrung rungs and to S7 STL (awlsim), so both sides run the same logic by construction.
The timer/counter program is small enough to be written for each side here, next to each
other. `crosscheck_*` functions compare the outputs of both sides after the same scans.
"""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

from softplc.il import ast as A
from softplc.il.parser import parse

ROOT = Path(__file__).resolve().parents[2]  # the repository

# ---- IL programs ------------------------------------------------------------------------------


def chain_program(rungs: int = 250, seed: int = 2) -> str:
    """`rungs` rungs of Q := A AND (B OR C): 5 IL instructions each (1,250 for 250 rungs)."""
    rnd = random.Random(seed)
    out = []
    for k in range(rungs):
        a, b, c = (rnd.randrange(200) for _ in range(3))
        out += [f"LD %M{a}", f"AND( %M{b}", f"OR %M{c}", ")", f"ST %M{200 + k % 56}"]
    return "\n".join(out) + "\n"


def word_program(ops: int = 250, seed: int = 3) -> str:
    """One rung, `LD 1` then `ops` operation blocks `[ %MWa := %MWb + %MWc ]`."""
    rnd = random.Random(seed)
    out = ["LD 1"]
    for _ in range(ops):
        a, b, c = rnd.randrange(100, 200), rnd.randrange(100), rnd.randrange(100)
        out.append(f"[ %MW{a} := %MW{b} + %MW{c} ]")
    return "\n".join(out) + "\n"


def timer_counter_program(n: int = 50) -> tuple[str, dict[str, Any]]:
    """n free-running TON timers (IN = NOT own output, presets 10..50 ms) and n up-counters
    counting the rising edges of a bit toggled every scan, each reset by its own done bit
    of the previous scan (presets 10..10+n-1). Returns (IL text, configuration dict)."""
    lines = ["LDN %M0", "ST %M0"]  # the toggle
    timers: dict[str, Any] = {}
    counters: dict[str, Any] = {}
    for i in range(n):
        timers[f"%TM{i}"] = {"type": "TON", "base": "10ms", "preset": i % 5 + 1}
        counters[f"%C{i}"] = {"preset": 10 + i}
        lines += [f"BLK %TM{i}", f"LDN %M{100 + i}", "IN", "OUT_BLK", "LD Q",
                  f"ST %M{100 + i}", "END_BLK"]
        lines += [f"BLK %C{i}", f"LD %M{200 + i}", "R", "LD %M0", "CU", "OUT_BLK", "LD D",
                  f"ST %M{200 + i}", "END_BLK"]
    return "\n".join(lines) + "\n", {"scan_period": "10ms", "timers": timers,
                                     "counters": counters}


def mixed_program(rungs: int = 40, seed: int = 4) -> tuple[str, dict[str, Any]]:
    """A typical small machine program of `rungs` rungs: boolean interlocks, comparisons,
    word arithmetic, a timer and a counter (the engine's 40-rung target)."""
    rnd = random.Random(seed)
    lines = ["BLK %TM0", "LDN %M99", "IN", "OUT_BLK", "LD Q", "ST %M99", "END_BLK",
             "BLK %C0", "LD %C0.D", "R", "LD %M99", "CU", "OUT_BLK", "LD D", "ST %M98",
             "END_BLK"]
    for k in range(rungs - 2):
        a, b, c = (rnd.randrange(60) for _ in range(3))
        form = k % 4
        if form == 0:
            lines += [f"LD %M{a}", f"ANDN %M{b}", f"OR %I0.{c % 12}", f"ST %Q0.{k % 10}"]
        elif form == 1:
            lines += [f"LD [ %MW{a} > %MW{b} ]", f"AND %M{c}", f"ST %M{60 + k}"]
        elif form == 2:
            lines += [f"LD %M{a}", f"[ %MW{60 + k} := %MW{b} + %MW{c} ]",
                      f"[ %MW{a} := %MW{c} REM 7 ]"]
        else:
            lines += [f"LD %M{a}", "MPS", f"AND %M{b}", f"S %M{60 + k}", "MPP",
                      f"ANDN %M{c}", f"R %M{60 + k}"]
    cfg = {"scan_period": "10ms", "timers": {"%TM0": {"type": "TON", "base": "10ms",
                                                         "preset": 5}},
           "counters": {"%C0": {"preset": 100}}}
    return "\n".join(lines) + "\n", cfg


def bool_index(ref: Any) -> int:
    """%Mi of a boolean benchmark program (the only bits those programs use)."""
    if ref.kind != "M":
        raise ValueError(f"benchmark translator handles %M bits only, not {ref}")
    return ref.index


# ---- translation of the boolean subset --------------------------------------------------------


def _bool_rungs(program: A.Program) -> list[tuple[list[tuple[str, str, int]], int | None]]:
    """Boolean rungs as ([(op, modifier, %M index)|('(',op,mod)|(')',..)], %M target)."""
    out = []
    for rung in program.rungs:
        seq: list[tuple[str, str, int]] = []
        target = None
        for ins in rung.instructions:
            if isinstance(ins, A.BoolInstr) and isinstance(ins.operand, A.Operand):
                seq.append((ins.op, ins.modifier, bool_index(ins.operand.ref)))
            elif isinstance(ins, A.ParenOpen) and isinstance(ins.operand, A.Operand):
                seq.append(("(" + ins.op, ins.modifier, bool_index(ins.operand.ref)))
            elif isinstance(ins, A.ParenClose):
                seq.append((")", "", -1))
            elif isinstance(ins, A.Store) and ins.op == "ST" and target is None:
                target = bool_index(ins.target)
            else:
                raise ValueError(f"not in the translated subset: {ins}")
        out.append((seq, target))  # target None: a dangling load (no output)
    return out


def to_stl(il: str) -> tuple[str, int]:
    """Boolean IL -> an S7 OB1 in STL; returns (source, STL instruction count)."""
    stl_op = {("LD", ""): "U", ("LD", "N"): "UN", ("AND", ""): "U", ("AND", "N"): "UN",
              ("OR", ""): "O", ("OR", "N"): "ON"}
    body: list[str] = []
    for seq, target in _bool_rungs(parse(il)):
        for op, mod, i in seq:
            if op == ")":
                body.append(")")
            elif op.startswith("("):
                body += [stl_op[(op[1:], "")][0] + ("N(" if mod == "N" else "("),
                         f"U M {i // 8}.{i % 8}"]
            else:
                body.append(f"{stl_op[(op, mod)]} M {i // 8}.{i % 8}")
        if target is not None:
            body.append(f"= M {target // 8}.{target % 8}")
    return _ob1(body), len(body)


def word_to_stl(il: str) -> tuple[str, int]:
    """The word program -> STL (L MW b, L MW c, +I, T MW a); %MWn is S7 MW 2n."""
    body: list[str] = []
    for rung in parse(il).rungs:
        for ins in rung.instructions:
            if isinstance(ins, A.OpBlock):
                st = ins.stmt
                e = st.expr
                body += [f"L MW {2 * e.left.ref.index}", f"L MW {2 * e.right.ref.index}", "+I",
                         f"T MW {2 * st.target.index}"]
    return _ob1(body), len(body)


def _ob1(body: list[str]) -> str:
    return "ORGANIZATION_BLOCK OB 1\nBEGIN\n" + "".join(f"\t{b}\n" for b in body) + \
        "END_ORGANIZATION_BLOCK\n"


def to_pyrung(il: str) -> tuple[Any, dict[int, Any]]:
    """Boolean IL -> (pyrung Program, {%M index: Bool tag})."""
    from pyrung import Bool, Or, Program, out, rung

    tags: dict[int, Any] = {}

    def tag(i: int) -> Any:
        if i not in tags:
            tags[i] = Bool(f"M{i}")
        return tags[i]

    def term(mod: str, i: int) -> Any:
        return ~tag(i) if mod == "N" else tag(i)

    def cond(terms: list[Any]) -> Any:
        from pyrung import And
        return terms[0] if len(terms) == 1 else And(*terms)

    rungs = _bool_rungs(parse(il))
    with Program(strict=False) as logic:
        for seq, target in rungs:
            # accumulator: a list of AND-ed terms; OR folds it into one Or(...) term
            stack: list[tuple[str, list[Any]]] = []
            acc: list[Any] = []
            for op, mod, i in seq:
                if op == "LD":
                    acc = [term(mod, i)]
                elif op == "AND":
                    acc.append(term(mod, i))
                elif op == "OR":
                    acc = [Or(cond(acc), term(mod, i))]
                elif op.startswith("("):
                    stack.append((op[1:], acc))
                    acc = [term(mod, i)]
                else:  # ')'
                    kind, outer = stack.pop()
                    acc = outer + [cond(acc)] if kind == "AND" else [Or(cond(outer), cond(acc))]
            if target is not None:
                with rung(*acc):
                    out(tag(target))
    return logic, tags


def timer_counter_pyrung(n: int = 50) -> tuple[Any, dict[str, Any]]:
    """The pyrung twin of timer_counter_program(n) (presets in ms: base 10 ms x preset)."""
    from pyrung import Bool, Counter, Program, Timer, count_up, on_delay, out, rise, rung

    tog = Bool("Toggle")
    tq = [Bool(f"TQ{i}") for i in range(n)]
    cd = [Bool(f"CD{i}") for i in range(n)]
    tm = Timer.clone("TM", count=n)
    ct = Counter.clone("CT", count=n)
    with Program(strict=False) as logic:
        with rung(~tog):
            out(tog)
        for i in range(n):
            with rung(~tq[i]):
                on_delay(tm[i + 1], preset=10 * (i % 5 + 1))
            with rung(tm[i + 1].Done):
                out(tq[i])
            with rung(rise(tog)):
                count_up(ct[i + 1], preset=10 + i).reset(cd[i])
            with rung(ct[i + 1].Done):
                out(cd[i])
    return logic, {"toggle": tog, "tq": tq, "cd": cd, "counters": ct, "timers": tm}
