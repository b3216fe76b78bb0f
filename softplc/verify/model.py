"""One scan of a program as solver terms: the transition relation the engines unroll.

Built from the same rung structure as the compiler (`il.rungtree.build`: what each `)`,
MRD/MPP and OUT_BLK refers to) and the same instruction rules (`semantics.arith` over
`symbolic.Z3Domain`), in the engine's scan order: first-scan system bits and clocks,
latched inputs, the program (jumps, subroutines and Grafcet steps as guards on every
update), timers the program did not execute, then time advances by the scan period.

A state is a dict: object key (`"%M3"`, `"%MW10"`, `"%TM0.V"`, `"%TM0._el"`, `"edge2"`)
-> term. Only what the program or the requirements read or write is modelled. What the
solver cannot model exactly (floats, tables, indexed objects, shifts...) is reported with
its line:col (`VerifyError`), never approximated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import z3

from softplc.errors import VerifyError
from softplc.il import ast as A
from softplc.il import rungtree
from softplc.runtime.engine import S_CLOCKS
from softplc.twido.address import BOOL, Ref
from softplc.verify import environment
from softplc.verify.abstract import Abstractions
from softplc.verify.blocks import apply, sort_name
from softplc.verify.defaults import LOOP_BOUND
from softplc.verify.loops import Loops
from softplc.verify.objects import BLOCK_KEY, CLOCK_WRAP_US, MODELLED, MW_ARRAY, ObjectModel
from softplc.verify.symbolic import And, If, Not, Or, Z3State, substitute_all
from softplc.verify.system import AFTER_PROGRAM, FIRST_SCAN_BITS, cold_value, free_objects


@dataclass
class Var:
    key: str
    sort: str  # "bool" | "w16" | "t" | "bvN" (a timer's elapsed time)
    init: int


def sort_of(sort: str) -> Any:
    if sort == "arr":  # the %MW words, by word number
        return z3.ArraySort(z3.BitVecSort(16), z3.BitVecSort(16))
    if sort == "f64":  # an abstracted float function's value (`floats`)
        return z3.Float64()
    if sort.startswith("bv"):
        return z3.BitVecSort(int(sort[2:]))
    return {"bool": z3.BoolSort(), "w16": z3.BitVecSort(16), "t": z3.BitVecSort(32)}[sort]


class _Lazy(dict):
    """The pre-state of the discovery pass: creates a variable for any key first read."""

    def __init__(self, model: Model):
        super().__init__()
        self.model = model

    def __missing__(self, key: str) -> Any:
        v = self.model.declare(key)
        self[key] = v
        return v


class _LazyInputs(dict):
    """The inputs of the discovery pass: a variable for any input first read."""

    def __init__(self, model: Model):
        super().__init__()
        self.model = model

    def __missing__(self, key: str) -> Any:
        v = self[key] = self.model.input_var(key, "")
        return v


class Model(ObjectModel):
    """The transition relation of `plc`'s program (a loaded `PLC`, cold-started)."""

    def __init__(self, plc: Any, reads: list[Ref] = (), host: list[Ref] = (),
                 periods: tuple[int, int] | None = None, loop_bound: int = LOOP_BOUND,
                 held: list[Ref] = (), devices: dict[str, list[tuple[int, int]]] | None = None):
        """`reads`: objects requirements read (modelled even if the program does not use
        them); `host`: objects the environment sets at the start of every scan;
        `periods`: (shortest, longest) scan period in us when any period in between (a
        multiple of the shortest) may occur in each scan, as in cyclic mode;
        `loop_bound`: passes of a backward jump (a loop) unrolled in one scan (beyond it
        the key `_loop` is true after the scan: checkers treat it as unknown);
        `held`: objects kept at their cold-start value although a host may write them;
        `devices`: the %MW ranges each simulated device writes (`Device.read_only_words`;
        None: those of `plc`'s devices). Objects the program reads and never writes that a
        host or a device may write are free in every scan (`environment`: `self.env`)."""
        super().__init__(plc)
        self.loops = Loops(loop_bound, plc.ast.file)
        self.edge_keys: dict[int, str] = {}  # id of an edge instruction -> its key
        self.period_us = round(plc.scan_period * 1e6) if periods is None else periods[0]
        self.longest_us = self.period_us if periods is None else periods[1]
        self.variable = periods is not None and periods[1] > periods[0]
        self.clock_wrap = max(1, CLOCK_WRAP_US // self.period_us)  # scans in a minute
        self.vars: dict[str, Var] = {}
        self.inputs: dict[str, tuple[str, int, int]] = {}  # key -> (sort, lo, hi)
        self.host = {str(r) for r in host}
        # system objects set from what is not modelled (wall time, the calendar): free
        self.sys_free = free_objects(plc, self.variable)
        if self.variable:  # the input "_dt": this scan lasts _dt x the shortest period
            self.add_input("_dt", "w16", 1, self.longest_us // self.period_us)
        self.used: dict[str, tuple[Any, Any]] = {}  # the blocks modelled
        self.outs: dict[str, list[str]] = {}
        self.abstract = Abstractions()
        self.written: dict[str, A.Pos] = {}  # keys the program writes, where first
        self.grafcet = any(isinstance(i, A.Grafcet) for r in plc.ast.rungs
                           for i in r.instructions)
        self.conditional = any(isinstance(i, (A.Jump, A.SRCall, A.Grafcet))
                               or isinstance(i, A.End) and i.op != "END"
                               for r in plc.ast.rungs for i in r.instructions)
        self.initial_steps = tuple(plc.grafcet.initial)
        self.mw_array = any(r.offset is not None and r.kind in ("MW", "MD")
                            for r in _refs(plc.ast.rungs))
        self.mw_named: set[int] = set()
        # discovery: run the scan on lazily created variables until no new key appears,
        # then again with the objects the environment writes as inputs (`environment`)
        self.discovering = True
        who = environment.of_plc(plc, devices)
        held_keys, declared = {str(r) for r in held}, set(self.host)
        required = {k for r in reads if r.offset is None for k in environment.keys_of(r)}
        while True:
            self._discover(plc, reads)
            self.env = environment.decide(plc.ast, self.written, who, held_keys, declared,
                                          required)
            extra = set(self.env.free) - self.host
            if not extra:
                break
            self.host |= extra
            for k in self.host:  # as the scan's start will (the same order): the next
                _free_input(self, k)  # pass adds nothing unless something else is new
        self.discovering = False

    def _discover(self, plc: Any, reads: list[Ref]) -> None:
        n = -1
        while n != len(self.vars) + len(self.inputs):
            n = len(self.vars) + len(self.inputs)
            pre = _Lazy(self)
            for k in list(self.vars):
                pre[k] = self.declare(k)
            self.st, self.inp = pre, _LazyInputs(self)
            for ref in reads:  # as a requirement reads it (%MD: two words, %Mi:L: bits)
                if ref.type == BOOL:
                    self.read_bit(ref, None)
                else:
                    self.read_word(ref, None)
            self.scan(pre, self.inp)
            if self.problems:
                raise VerifyError(sorted(set(self.problems), key=lambda d: (d.line, d.column)))

    # ---- variables ----------------------------------------------------------------------
    def declare(self, key: str, suffix: str = "") -> Any:
        """The variable of state key `key` (registered on first use), named `key@suffix`."""
        if key not in self.vars:
            self.vars[key] = Var(key, self._sort(key), self._init(key))
        return z3.Const(f"{key}@{suffix}" if suffix else key, sort_of(self.vars[key].sort))

    def _sort(self, key: str) -> str:
        if key == MW_ARRAY:
            return "arr"
        blk = BLOCK_KEY.match(key)
        if blk:
            return sort_name(self.block_fields(key.split(".")[0])[blk[3]])
        if key == "_tmod":
            return "t"
        if key in self.abstract.ranges:
            return self.abstract.ranges[key][0]
        if key.startswith("edge") or key == "_first" or self.is_bit_key(key):
            return "bool"
        return "w16"

    def is_bit_key(self, key: str) -> bool:
        blk = BLOCK_KEY.match(key)
        if blk:
            return self._sort(key) == "bool"
        return key.startswith(("%M", "%Q", "%S", "%X", "%I")) and not key.startswith(
            ("%MW", "%QW", "%SW", "%MD", "%QNW", "%INW"))

    def _init(self, key: str) -> int:
        """The value after a cold start."""
        if key == "_first":
            return 1
        blk = BLOCK_KEY.match(key)
        if blk:
            model, b = self.used[key.split(".")[0]]
            return model.init(b, blk[3])
        if key.startswith("%S"):
            return cold_value(self.plc, key)
        if key.startswith("%X"):  # the initial steps are active from the cold start
            return 1 if int(key[2:]) in self.initial_steps else 0
        return 0

    def input_var(self, key: str, suffix: str) -> Any:
        sort = self.inputs[key][0]
        return z3.Const(f"{key}#in@{suffix}" if suffix else f"{key}#in", sort_of(sort))

    def add_input(self, key: str, sort: str, lo: int = 0, hi: int = 0) -> None:
        self.inputs.setdefault(key, (sort, lo, hi))

    def input_constraints(self, inp: dict[str, Any]) -> list[Any]:
        """Analog inputs within their configured span."""
        return [And(inp[k] >= lo, inp[k] <= hi) for k, (s, lo, hi) in self.inputs.items()
                if s == "w16" and (lo, hi) != (-32768, 32767)]

    def fresh(self, suffix: str) -> tuple[dict[str, Any], dict[str, Any]]:
        """New variables for a state and the inputs of the scan after it."""
        return ({k: z3.Const(f"{k}@{suffix}", sort_of(v.sort)) for k, v in self.vars.items()},
                {k: self.input_var(k, suffix) for k in self.inputs})

    def init_state(self) -> dict[str, Any]:
        return {k: self.const(v.sort, v.init) for k, v in self.vars.items()}

    @staticmethod
    def const(sort: str, v: int) -> Any:
        if sort == "arr":  # every word 0 after a cold start
            return z3.K(z3.BitVecSort(16), z3.BitVecVal(v, 16))
        if sort == "f64":
            return z3.FPVal(float(v), z3.Float64())
        return z3.BoolVal(bool(v)) if sort == "bool" else \
            z3.BitVecVal(int(v), sort_of(sort).size())

    def invariants(self, st: dict[str, Any]) -> list[Any]:
        """Range facts true by construction in every reachable state (see `blocks`)."""
        out = []
        for name, (model, b) in self.used.items():
            s = {f: st[f"{name}.{f}"] for f in self.block_fields(name)}
            out += model.invariants(Z3State, b, s, self.scan_info())
        if "_tmod" in st:
            out.append(z3.ULT(st["_tmod"], self.clock_wrap))
        return out

    # ---- the scan -----------------------------------------------------------------------
    def scan(self, pre: dict[str, Any], inp: dict[str, Any]) -> dict[str, Any]:
        """The state after one scan from `pre` with inputs `inp`; the result also holds
        the inputs of the scan under their own keys (what requirements read)."""
        st = pre if self.discovering else dict(pre)
        self.st, self.inp = st, inp
        first = st["_first"] if "_first" in self.vars or self.discovering else None
        for b in FIRST_SCAN_BITS:
            if f"%S{b}" in self.vars or (b == 21 and self.grafcet):
                st[f"%S{b}"] = first if first is not None else st["_first"]
        if any(f"%S{b}" in self.vars for b in S_CLOCKS):
            now = st["_tmod"] * self.period_us  # _tmod counts scans, modulo one minute
            for b, p in S_CLOCKS.items():
                if f"%S{b}" in self.vars:
                    st[f"%S{b}"] = z3.ULT(z3.URem(now, p), p // 2)
        free = [k for k in self.sys_free if k in self.vars and k not in self.host]
        for k in [*self.host, *free]:  # words a host writes between scans, free bits
            if self.discovering:
                _free_input(self, k)
            if self.mw_array and k.startswith("%MW"):
                self.mw_named.add(int(k[3:]))
                st[MW_ARRAY] = z3.Store(st[MW_ARRAY], z3.BitVecVal(int(k[3:]), 16), inp[k])
                continue
            if self.discovering:
                _ = st[k]
            st[k] = inp[k]
        if self.discovering:
            self.pulse_outputs()
        self.abstract_scan_start()
        self.live: Any = z3.BoolVal(True)
        self.executed: dict[str, Any] = {}
        self.ga: dict[int, Any] = {}
        self.gd: dict[int, Any] = {}
        self.steps_at_start: dict[int, Any] = {}
        self.frozen: Any = z3.BoolVal(False)
        self.calls: list[int] = []
        self.overflow: Any = z3.BoolVal(False)
        self.facts: list[Any] = []  # what is known of abstracted float functions' values
        self.applied: dict[str, list[tuple[Any, Any]]] = {}  # their (argument, value)
        self.post_done = False
        self.function(self.plc.ast.main, main=True)
        if self.grafcet and not self.post_done:
            self.post(self.live)
        self.abstract_after_program()
        if self.conditional:  # blocks not executed that go on (timers keep timing)
            for name, (model, _b) in self.used.items():
                held = model.held(self.block_view(name))
                if held is not None:
                    self.step_block(name, Not(self.executed.get(name, z3.BoolVal(False))),
                                    held)
        for b in FIRST_SCAN_BITS:
            if f"%S{b}" in st:
                st[f"%S{b}"] = z3.BoolVal(False)
        dt = z3.Extract(15, 0, inp["_dt"]) if self.variable else None
        for name, (model, b) in self.used.items():  # time goes on (timers' elapsed time)
            apply(st, name, z3.BoolVal(True),
                  model.after_scan(Z3State, b, self.block_view(name), self.scan_info(dt)))
        if "_tmod" in self.vars or "_tmod" in st:
            t = st["_tmod"]
            t = t + (z3.ZeroExt(16, dt) if dt is not None else 1)
            st["_tmod"] = z3.simplify(If(z3.UGE(t, self.clock_wrap), t - self.clock_wrap, t))
        if "_first" in st:
            st["_first"] = z3.BoolVal(False)
        out = dict(st)
        if self.facts:
            out["_facts"] = z3.simplify(And(self.facts))
        if self.loops.sites:  # a loop ran past the unrolled passes in this scan
            out["_loop"] = z3.simplify(self.overflow)
        out.update({k: v for k, v in inp.items() if k not in st})  # %I, %IW: as latched
        return out

    # ---- program structure ----------------------------------------------------------------
    def function(self, rungs: list[A.Rung], main: bool) -> None:
        """The rungs of main or a subroutine. A backward jump (a loop, as the engine's
        `_pc` dispatch runs it) starts another pass over the rungs, entered only at the
        labels jumped to, while the solver cannot rule one out (`Loops.after_pass`); a
        loop still running after the passes unrolled sets `overflow`."""
        back: dict[int, Any] = {}  # label -> a backward jump to it was taken
        end_live: Any = z3.BoolVal(False)
        spent = 0.0  # s the solver took deciding whether another pass can run
        for n in range(self.loops.bound + 1):
            nxt: dict[int, Any] = {}
            self.one_pass(rungs, main, back, nxt)
            end_live = Or(end_live, self.live)
            if self.discovering:  # no solver: one more pass, from any state, reads and
                if n or not nxt:  # writes what any later pass does (values a first pass
                    break  # has concrete may skip a key: INC's %S18)
                back = {k: z3.Bool(f"back{k}@discovery") for k in nxt}
                for k in list(self.st):
                    self.st[k] = self.declare(k)
                self.live = z3.BoolVal(False)
                continue
            back, past, spent = self.loops.after_pass(n, nxt, spent)
            if past is not None:
                self.overflow = Or(self.overflow, past)
            if not back or past is not None:
                break
            self.live = z3.BoolVal(False)
        self.live = z3.simplify(end_live)

    def one_pass(self, rungs: list[A.Rung], main: bool, back: dict[int, Any],
                 nxt: dict[int, Any]) -> None:
        """One pass over `rungs`: entered at the top (the first pass: `self.live`) and at
        the labels of `back`; backward jumps taken go to `nxt`."""
        pending: dict[int, Any] = {}
        seen: set[int] = set()
        step: int | None = None
        for r in rungs:
            if r.label is not None:
                seen.add(r.label)
                self.live = z3.simplify(Or(self.live, pending.pop(r.label, False),
                                              back.get(r.label, False)))
            marker = next((i for i in r.instructions if isinstance(i, A.Grafcet)
                           and i.op in ("=*=", "-*-", "POST")), None)
            if marker is not None:
                if marker.op == "POST" or step is None and main:
                    if step is None and not self.steps_at_start:
                        self.grafcet_pre()
                if marker.op == "POST":
                    self.post(self.live)
                    step = None
                else:
                    step = marker.step
                continue
            if self.unreached(r):
                continue
            self.rung(r, step, (pending, seen, nxt), main)

    def unreached(self, r: A.Rung) -> bool:
        """The rung cannot run (jumped over, after a return, before the label a loop's
        later pass enters at): every effect of it is guarded by `live`, so it is left
        out. Not while discovering (that pass reads and writes what any pass does), nor
        a Grafcet END (it ends the sequential part, run or not)."""
        return (not self.discovering and z3.is_false(self.live)
                and not (self.grafcet and any(isinstance(i, A.End) for i in r.instructions)))

    def grafcet_pre(self) -> None:
        """End of preprocessing: %S21 (initial steps on), %S22 (all off), %S23 (freeze)."""
        st = self.st
        init = st["%S21"] if "%S21" in st else z3.BoolVal(False)
        reset = st["%S22"] if "%S22" in st or "%S22" in self.vars else z3.BoolVal(False)
        g = And(self.live, Or(init, reset))
        for k in self.steps():
            key = f"%X{k}"
            st[key] = z3.simplify(If(g, And(init, k in self.initial_steps), st[key]))
        if "%S23" in st or "%S23" in self.vars:
            self.frozen = And(self.live, st["%S23"])
        for b in (21, 22, 23):
            key = f"%S{b}"
            if key in st or key in self.vars:
                st[key] = If(self.live, False, st[key])
        self.steps_at_start = {k: st[f"%X{k}"] for k in self.steps()}

    def steps(self) -> list[int]:
        used: set[int] = set()
        for r in self.plc.ast.rungs:
            for i in r.instructions:
                if isinstance(i, A.Grafcet) and i.step is not None:
                    used.add(i.step)
        used |= set(self.initial_steps)
        used |= {int(k[2:]) for k in self.vars if k.startswith("%X")}
        return sorted(used)

    def post(self, g: Any) -> None:
        """End of the sequential part: the transitions of the scan, unless frozen."""
        self.post_done = True
        st = self.st
        g = And(g, Not(self.frozen))
        for k in self.steps():
            key = f"%X{k}"
            new = Or(self.ga.get(k, False), And(st[key], Not(self.gd.get(k, False))))
            st[key] = z3.simplify(If(g, new, st[key]))

    # ---- one rung -------------------------------------------------------------------------
    def rung(self, rung: A.Rung, step: int | None,
             flow: tuple[dict[int, Any], set[int], dict[int, Any]], main: bool) -> None:
        """`flow`: the forward jumps pending per label, the labels passed, the backward
        jumps taken per label (see `function`)."""
        pending, seen, back = flow
        counts = self.plc.profile.counts
        tree = rungtree.build(rung, counts["PAREN"], counts["STACK"])
        guard0 = self.steps_at_start.get(step, z3.BoolVal(False)) if step is not None \
            else z3.BoolVal(True)
        acc: Any = None
        saved: dict[int, Any] = {}
        pins: dict[str, Any] = {}

        made: list[Any] = [None, None]  # (live, g): g made again only when live changes

        def g() -> Any:  # the rung runs: not jumped over, in its active step
            if made[0] is not self.live:
                made[:] = [self.live, And(self.live, guard0)]
            return made[1]

        for s in tree.steps:
            ins, blk = s.instr, s.block
            if not s.ok:
                continue
            if isinstance(ins, A.BoolInstr):
                v = self.modified(self.operand(ins.operand, blk, g()), ins, g())
                acc = v if ins.op == "LD" else self.combine(ins.op, acc, v)
            elif isinstance(ins, A.ParenOpen):
                saved[s.k] = acc
                acc = self.modified(self.operand(ins.operand, blk, g()) if ins.operand
                                    else z3.BoolVal(False), ins, g())
            elif isinstance(ins, A.ParenClose):
                acc = self.combine(tree.steps[s.opener].instr.op, saved[s.opener], acc)
            elif isinstance(ins, A.Negate):
                acc = Not(acc)
            elif isinstance(ins, A.Stack):
                if ins.op == "MPS":
                    saved[s.k] = acc
                elif s.opener is not None:
                    acc = saved[s.opener]
            elif isinstance(ins, A.Store):
                value = {"ST": acc, "STN": Not(acc), "S": True, "R": False}[ins.op]
                cond = g() if ins.op in ("ST", "STN") else And(g(), acc)
                self.write_bit(ins.target, cond, value, ins.pos)
            elif isinstance(ins, A.OpBlock):
                self.statement(ins.stmt, And(g(), acc))
            elif isinstance(ins, A.Jump):
                c = z3.BoolVal(True) if ins.op == "JMP" else acc if ins.op == "JMPC" \
                    else Not(acc)
                take = And(self.live, guard0, c)
                if ins.label in seen:  # backward: a loop (see `function`)
                    if self.grafcet:
                        self.unsupported("a backward jump in a Grafcet program", ins.pos,
                                         f"{ins.op} %L{ins.label}")
                        continue
                    self.loops.sites.setdefault(ins.label, ins.pos)
                    back[ins.label] = Or(back.get(ins.label, False), take)
                else:
                    pending[ins.label] = Or(pending.get(ins.label, False), take)
                self.live = z3.simplify(And(self.live, Not(take)))
            elif isinstance(ins, A.SRCall):
                self.call_sr(ins, And(g(), acc))
            elif isinstance(ins, (A.Return, A.End)):
                c = z3.BoolVal(True) if ins.op in ("RET", "END") else \
                    acc if ins.op in ("RETC", "ENDC") else Not(acc)
                stop = And(self.live, guard0, c)
                if isinstance(ins, A.End) and self.grafcet and not self.post_done:
                    self.post(stop)
                self.live = z3.simplify(And(self.live, Not(stop)))
            elif isinstance(ins, A.Blk):
                pins = {}
                acc = None
            elif isinstance(ins, (A.OutBlk, A.EndBlk)):
                if blk is not None and s.phase == "in":
                    self.run_block(blk, g(), pins, ins.pos)
                acc = None
            elif isinstance(ins, A.Pin):
                if ins.block is None:
                    pins[ins.name] = acc
                else:
                    self.run_pin(ins.block, ins.name, g(), acc, ins.pos)
            elif isinstance(ins, A.Grafcet):
                self.transition(ins, step, And(g(), acc if acc is not None else True))
            elif not isinstance(ins, A.Nop):
                self.unsupported(f"instruction {rungtree.describe(ins)}", s.pos, "")

    @staticmethod
    def combine(op: str, a: Any, b: Any) -> Any:
        a = a if a is not None else z3.BoolVal(False)
        return And(a, b) if op == "AND" else Or(a, b) if op == "OR" else z3.Xor(a, b)

    def modified(self, v: Any, ins: Any, g: Any) -> Any:
        mod = ins.modifier
        if mod == "N":
            return Not(v)
        if mod in ("R", "F"):  # one memory per instruction, as the compiler's edge slots
            key = self.edge_keys.setdefault(id(ins), f"edge{len(self.edge_keys)}")
            old = self.st[key]
            r = And(v, Not(old)) if mod == "R" else And(Not(v), old)
            self.st[key] = z3.simplify(If(g, v, old))
            return r
        return v

    def call_sr(self, ins: A.SRCall, g: Any) -> None:
        n = ins.number
        if n in self.calls:
            self.unsupported("a recursive subroutine call", ins.pos, f"SR{n}")
            return
        if n not in self.plc.ast.subroutines:
            return
        saved = self.live
        self.live = And(self.live, g)
        self.calls.append(n)
        self.function(self.plc.ast.subroutine(n), main=False)
        self.calls.pop()
        self.live = saved

    def transition(self, ins: A.Grafcet, step: int | None, g: Any) -> None:
        if ins.op in ("=*=", "-*-", "POST") or step is None:
            return
        self.gd[step] = Or(self.gd.get(step, False), g)
        if ins.op == "#":
            if ins.step is not None:
                self.ga[ins.step] = Or(self.ga.get(ins.step, False), g)
        else:
            self.gd[ins.step] = Or(self.gd.get(ins.step, False), g)


__all__ = ["Model", "Var", "is_object", "run_concrete"]


def is_object(key: str) -> bool:
    """A state key that is an object address (not a block's internal state)."""
    blk = BLOCK_KEY.match(key)
    if blk:  # a field of the block's address (a step counter's step has none)
        return blk[3] in (MODELLED[blk[1]].fields or {})
    # scan times are rewritten after the program
    return key.startswith("%") and not key.endswith("[]") and key not in AFTER_PROGRAM


def run_concrete(model: Model, scans: list[dict[str, int]]) -> list[dict[str, int]]:
    """The model's values scan by scan for concrete inputs (missing inputs are 0): every
    object it models after each scan, for comparison with the engine; it stops before a
    scan in which a loop ran past the passes modelled (that scan is not modelled).

    Without a loop the scan is built once on variables (the transition relation the
    engines unroll) and each scan substitutes the state's and inputs' values into it: one
    solver call per object instead of thousands of term constructions per scan. A loop's
    passes are decided on the state's values, so a program with one is run scan by scan."""
    from softplc.verify.symbolic import value_of
    st = model.init_state()
    step = _Substituted(model) if not model.loops.sites else None
    out = []
    m = z3.Solver()
    m.check()
    empty = m.model()  # no constraint: the values are those of the constant terms
    for given in scans:
        # an object the environment may write and did not: it keeps its value
        inp = {k: model.const(sort, given.get(k, lo if sort == "w16" else 0))
               if k in given or k not in model.env.free else _current(model, st, k)
               for k, (sort, lo, _hi) in model.inputs.items()}
        if step is not None:
            post = step(st, inp)
        else:
            post = {k: z3.simplify(v) for k, v in model.scan(st, inp).items()}
        if z3.is_true(post.get("_loop", False)):
            break
        st = {k: post[k] for k in model.vars}
        values = {k: value_of(empty, v) for k, v in post.items() if is_object(k)}
        if model.mw_array:  # the words named, read from the array
            for i in sorted(model.mw_named):
                values[f"%MW{i}"] = value_of(empty, z3.Select(post[MW_ARRAY], i))
        out.append(values)
    return out


class _Substituted:
    """One scan of `model` as terms over the pre-state's and inputs' variables; called
    with values, the post-state's values (`substitute_all`: one substitution and one
    simplification per term, each a single solver call)."""

    def __init__(self, model: Model):
        self.pre, self.inp = model.fresh("concrete")
        self.post = model.scan(self.pre, self.inp)

    def __call__(self, st: dict[str, Any], inp: dict[str, Any]) -> dict[str, Any]:
        return substitute_all(self.post, [(v, st[k]) for k, v in self.pre.items()]
                              + [(v, inp[k]) for k, v in self.inp.items()])


def _free_input(model: Model, key: str) -> None:
    """An object a host writes between scans (or the system, unmodelled): an input."""
    model.add_input(key, "bool" if model.is_bit_key(key) else "w16", -32768, 32767)


def _current(model: Model, st: dict[str, Any], key: str) -> Any:
    """A state key's value in `st` (a %MW word: in the array when the program indexes)."""
    if key in st:
        return st[key]
    return z3.Select(st[MW_ARRAY], z3.BitVecVal(int(key[3:]), 16))


def _refs(node: Any) -> list[Ref]:
    """Every address in an AST node (instructions, expressions, their offsets)."""
    if isinstance(node, Ref):
        return [node] + (_refs(node.offset) if node.offset is not None else [])
    if isinstance(node, (list, tuple)):
        return [r for x in node for r in _refs(x)]
    if hasattr(node, "__dataclass_fields__"):
        return [r for f in node.__dataclass_fields__ for r in _refs(getattr(node, f))]
    return []
