"""Object access for the model: bits, words, double words, %TM/%C blocks as entries of the
state dict being built (`self.st`, inputs in `self.inp`), every write guarded, %S18 where a
rule faults, and what cannot be modelled reported with its line:col."""

from __future__ import annotations

import re
from typing import Any

import z3

from softplc.assembly.blocks import drum_outputs
from softplc.errors import Code, Diagnostic
from softplc.il import ast as A
from softplc.runtime.blocks import (
    MAX_VALUE,
    Counter,
    Drum,
    Register,
    ShiftRegister,
    StepCounter,
    Timer,
)
from softplc.runtime.engine import S_CLOCKS
from softplc.twido import catalog
from softplc.twido.address import BLOCK_FIELDS, INT16, INT32, REAL, Ref, parse_address
from softplc.verify import floats
from softplc.verify.abstract import AbstractModel
from softplc.verify.blocks import (
    register_fields,
    run_counter,
    run_drum,
    run_register,
    run_shift_register,
    run_step_counter,
    run_timer,
    set_step_bit,
)
from softplc.verify.exprs import ExprModel
from softplc.verify.requirements import INDEXED_WORDS
from softplc.verify.symbolic import as_bool, narrow, wide
from softplc.verify.system import AFTER_PROGRAM

MW_ARRAY = INDEXED_WORDS  # the state key of the %MW words when the program indexes them
CLOCK_WRAP_US = 60_000_000  # every %S4-%S7 clock period divides one minute
# the modelled families, named by their runtime class (their kinds are the catalog's)
TM, C, DR, SBR, SC, R = map(catalog.of_class, (Timer, Counter, Drum, ShiftRegister,
                                               StepCounter, Register))
# the state kept per modelled block kind (a drum's `_written`: the step its outputs hold)
MODELLED = {TM: ("P", "V", "Q", "_in", "_on", "_el"), C: Counter.FIELDS,
            SBR: ShiftRegister.FIELDS, DR: ("S", "F", "_u", "_written"),
            SC: StepCounter.FIELDS, R: ()}  # %R: `register_fields`
BLOCK_KEY = re.compile(rf"%({'|'.join(MODELLED)})(\d+)\.(\w+)$")  # a modelled block's field
# the addressable blocks without a model: sound abstractions (`abstract`)
ABSTRACTED = frozenset(BLOCK_FIELDS) - set(MODELLED)


def abstracted(ref: Ref) -> bool:
    return ref.kind in ABSTRACTED and ref.offset is None


class ObjectModel(AbstractModel, ExprModel):
    """What `Model` reads and writes; `Model` supplies the state and the scan."""

    st: dict[str, Any]
    inp: dict[str, Any]
    timers: dict[str, Timer]
    counters: list[str]
    drums: dict[str, list[str]]  # drum -> its output keys
    written: dict[str, A.Pos]
    executed: dict[str, Any]
    period_us: int
    mw_array: bool = False  # the %MW words as one array (`word`, `put_word`)
    mw_named: set[int]  # with it, the words named: compared with the engine

    def add_input(self, key: str, sort: str, lo: int = 0, hi: int = 0) -> None: ...

    # ---- blocks ---------------------------------------------------------------------------
    def block(self, name: str) -> Any:
        m = BLOCK_KEY.match(name + ".x")
        return self.plc.mem.blocks[m[1]][int(m[2])]

    def use_block(self, ref: Ref, pos: A.Pos | None) -> str | None:
        name = f"%{ref.kind}{ref.index}"
        if ref.kind not in MODELLED:
            self.unsupported(f"the %{ref.kind} function block", pos, str(ref))
            return None
        if ref.index not in self.plc.mem.blocks.get(ref.kind, {}):
            self.unsupported(f"{name}: not used by the program nor configured", pos, name)
            return None
        if ref.kind == TM:
            self.timers.setdefault(name, self.plc.mem.blocks[TM][ref.index])
        elif ref.kind == C and name not in self.counters:
            self.counters.append(name)
        elif ref.kind == DR and name not in self.drums:
            self.drums[name] = self.drum_outputs(ref, pos)
        fields = register_fields(self.block(name).depth) if ref.kind == R else \
            MODELLED[ref.kind]
        for f in fields:
            _ = self.st[f"{name}.{f}"]
        return name

    def drum_outputs(self, ref: Ref, pos: A.Pos | None) -> list[str]:
        """The state keys of a drum's configured output bits, in bit order."""
        plc = self.plc
        for text, d in plc.settings.drums.items():  # checked when the PLC was built
            if parse_address(text, plc.profile).index != ref.index:
                continue
            outs = drum_outputs(d, text, plc.profile, plc.symbols)  # addresses or symbols
            keys = [self.key_for(r) for r in outs]
            for k in keys:
                self.mark_written(k, pos)
            return keys
        self.unsupported(f"{ref}: its outputs are not found in the configuration", pos,
                         str(ref))
        return []

    def run_block(self, ref: Ref, g: Any, pins: dict[str, Any], pos: A.Pos | None) -> None:
        if abstracted(ref):
            self.run_abstract(ref, g, pos)
            return
        name = self.use_block(ref, pos)
        if name is None:
            return
        p = {k: pins.get(k, z3.BoolVal(False))
             for k in ("IN", "R", "S", "CU", "CD", "U", "I", "O")}
        st = self.st
        if ref.kind == TM:
            self.mark_written(f"{name}.V", pos)
            self.executed[name] = z3.Or(self.executed.get(name, False), g)
            run_timer(st, name, self.timers[name], g, p["IN"], self.period_us)
        elif ref.kind == SBR:
            run_shift_register(st, name, g, p["R"], p["CU"], p["CD"])
        elif ref.kind == SC:
            run_step_counter(st, name, g, p["R"], p["CU"], p["CD"])
        elif ref.kind == R:
            b = self.block(name)
            run_register(st, name, b.type == "LIFO", b.depth, g, p["R"], p["I"], p["O"])
        elif ref.kind == DR:
            run_drum(st, name, self.block(name).steps, self.drums[name], g, p["R"], p["U"])
        else:
            self.mark_written(f"{name}.V", pos)
            run_counter(st, name, g, p["R"], p["S"], p["CU"], p["CD"])

    def run_pin(self, ref: Ref, pin: str, g: Any, v: Any, pos: A.Pos | None) -> None:
        """The short form (`CU %C0`, `U %DR0`): as `Block`'s generated pin methods, the
        edge inputs held at their last value, the level inputs at 0."""
        if abstracted(ref):
            self.run_abstract(ref, g, pos)
            return
        name = self.use_block(ref, pos)
        if name is None:
            return
        held = {p: self.st[f"{name}.{a}"] for p, a in
                catalog.family(ref.kind).block_class.EDGE_PINS.items()} if ref.kind != TM else {}
        held[pin] = v
        self.run_block(ref, g, held, pos)

    # ---- objects --------------------------------------------------------------------------
    def key_for(self, ref: Ref) -> str:
        """The state key of a bit or word (inputs registered as inputs)."""
        if ref.kind == "I":
            self.add_input(str(ref), "bool")
            return str(ref)
        if ref.kind == "IW":
            ch = self.plc.mem.analog.channels.get(ref) if self.plc.mem.analog else None
            lo, hi = (min(ch.lo, ch.hi), max(ch.lo, ch.hi)) if ch else (-32768, 32767)
            self.add_input(str(ref), "w16", lo, hi)
            return str(ref)
        if ref.kind == "INW":  # the Remote Link's words arrive on its own cycle: free
            self.add_input(str(ref), "w16", -32768, 32767)
            return str(ref)
        if ref.kind in MODELLED and ref.field is not None:
            if self.use_block(Ref(ref.kind, ref.index), None) is None:
                return "_none"
            return f"%{ref.kind}{ref.index}.{ref.field}"
        key = str(Ref(ref.kind, ref.index, ref.module, ref.channel, station=ref.station))
        if ref.kind == "S" and ref.index in S_CLOCKS:
            if CLOCK_WRAP_US % self.period_us:
                self.unsupported(f"{ref} with a scan period that does not divide 1 min",
                                 None, str(ref))
            _ = self.st["_tmod"]
        _ = self.st[key]
        return key

    def mark_written(self, key: str, pos: A.Pos | None) -> None:
        self.written.setdefault(key, pos or A.NOPOS)

    def read_bit(self, ref: Ref, pos: A.Pos | None) -> Any:
        if ref.offset is not None or ref.length is not None:
            self.unsupported("an indexed object or a bit string", pos, str(ref))
            return z3.BoolVal(False)
        if ref.kind in ("I", "Q", "M", "S", "X"):
            key = self.key_for(ref)
            return self.inp[key] if ref.kind == "I" else self.st[key]
        if ref.bit is not None and ref.kind in ("MW", "SW"):
            w = self.word(Ref(ref.kind, ref.index))
            return z3.Extract(ref.bit, ref.bit, w) == 1
        if ref.bit is not None and ref.kind == "KW":
            return z3.BoolVal(bool(self.plc.mem.kw.uw[ref.index] >> ref.bit & 1))
        if ref.kind in (TM, C, DR, R) and ref.field in ("Q", "D", "E", "F"):
            return self.st[self.key_for(ref)]
        if abstracted(ref) and ref.field is not None and ref.bit is None:
            return self.read_abstract(ref)
        if ref.kind in (SBR, SC) and ref.field == "J":
            w = self.st[self.key_for(Ref(ref.kind, ref.index, field="W"))]
            return z3.Extract(ref.bit, ref.bit, w) == 1
        self.unsupported(f"reading {ref}", pos, str(ref))
        return z3.BoolVal(False)

    def write_bit(self, ref: Ref, g: Any, value: Any, pos: A.Pos | None) -> None:
        value = as_bool(value)
        if ref.kind in ("Q", "M", "S", "X") and ref.offset is None:
            key = self.key_for(ref)
            self.mark_written(key, pos)
            self.st[key] = z3.simplify(z3.If(g, value, self.st[key]))
        elif ref.kind in ("MW", "SW", SBR) and ref.bit is not None and ref.offset is None:
            word = Ref(ref.kind, ref.index) if ref.kind != SBR else \
                Ref(SBR, ref.index, field="W")
            w = self.word(word)
            mask = z3.BitVecVal(1 << ref.bit, 16)
            self.put_word(word, g, z3.If(value, w | mask, w & ~mask), pos)
        elif abstracted(ref) and ref.field is not None:
            self.run_abstract(Ref(ref.kind, ref.index), g, pos)
        elif ref.kind == SC and ref.bit is not None and ref.offset is None:
            name = self.use_block(Ref(SC, ref.index), pos)
            if name is not None:
                self.mark_written(f"{name}.W", pos)
                set_step_bit(self.st, name, ref.bit, g, value)
        else:
            self.unsupported(f"writing {ref}", pos, str(ref))

    def read_word(self, ref: Ref, pos: A.Pos | None, g: Any = None) -> tuple[Any, str]:
        """(wide term, type); `g`: where the read runs (an index out of range: %S20)."""
        k = ref.kind
        if self.mw_array and k in ("MW", "MD") and ref.offset is not None \
                and ref.length is None and ref.bit is None:
            i = self.mw_index(ref, g)
            if k == "MW":
                return wide(z3.Select(self.st[MW_ARRAY], i)), INT16
            return wide(z3.Concat(z3.Select(self.st[MW_ARRAY], i + 1),
                                  z3.Select(self.st[MW_ARRAY], i))), INT32
        if k == "M" and ref.length is not None and ref.offset is None and ref.length <= 32:
            bits = [self.read_bit(Ref("M", ref.index + i), pos) for i in range(ref.length)]
            width = 16 if ref.length <= 16 else 32  # %Mi:L as a number, bit i is bit 0
            v = z3.Concat(*[z3.If(b, z3.BitVecVal(1, 1), z3.BitVecVal(0, 1))
                            for b in reversed(bits)]) if len(bits) > 1 else \
                z3.If(bits[0], z3.BitVecVal(1, 1), z3.BitVecVal(0, 1))
            return wide(z3.ZeroExt(width - ref.length, v)), INT16 if width == 16 else INT32
        if ref.offset is not None or ref.length is not None or ref.bit is not None:
            self.unsupported("an indexed object, table or bit string", pos, str(ref))
            return wide(0), INT16
        if k == "KW":
            return wide(int(self.plc.mem.kw.w[ref.index])), INT16
        if k == "KD":
            return wide(int(self.plc.mem.read(ref))), INT32
        if k in ("MW", "QW", "SW", "QNW"):
            return wide(self.word(ref)), INT16
        if k in ("IW", "INW"):
            return wide(self.inp[self.key_for(ref)]), INT16
        if k == "MD":
            lo = self.word(Ref("MW", ref.index))
            hi = self.word(Ref("MW", ref.index + 1))
            return wide(z3.Concat(hi, lo)), INT32
        if k in (TM, C) and ref.field in ("V", "P") or k == DR and ref.field == "S" \
                or k == R and ref.field in ("I", "O"):
            return wide(self.st[self.key_for(ref)]), INT16
        if abstracted(ref) and ref.field is not None and ref.type != REAL:
            return wide(self.read_abstract(ref)), INT16
        if k == "MF":
            return floats.from_words(self.word(Ref("MW", ref.index)),
                                     self.word(Ref("MW", ref.index + 1))), REAL
        if k == "KF":
            return floats.const(float(self.plc.mem.read(ref))), REAL
        if ref.type == REAL:
            self.unsupported("floating-point values", pos, str(ref))
        else:
            self.unsupported(f"reading {ref}", pos, str(ref))
        return wide(0), INT16

    def store_word(self, ref: Ref, g: Any, v: Any, t: str, pos: A.Pos | None) -> None:
        k = ref.kind
        if self.mw_array and k in ("MW", "MD") and ref.offset is not None \
                and ref.length is None:
            i = self.mw_index(ref, g)
            v = narrow(v, 16 if k == "MW" else 32)
            parts = [(i, v)] if k == "MW" else [(i, z3.Extract(15, 0, v)),
                                                 (i + 1, z3.Extract(31, 16, v))]
            for at, x in parts:
                arr = self.st[MW_ARRAY]
                self.st[MW_ARRAY] = z3.If(g, z3.Store(arr, at, x), arr)
            self.mark_written(MW_ARRAY, pos)
            return
        if ref.offset is not None or ref.length is not None:
            self.unsupported("an indexed object or table", pos, str(ref))
        elif k in ("MW", "QW", "SW", "QNW"):
            self.put_word(ref, g, narrow(v, 16), pos)
        elif k == "MD":
            v32 = narrow(v, 32)
            self.put_word(Ref("MW", ref.index), g, z3.Extract(15, 0, v32), pos)
            self.put_word(Ref("MW", ref.index + 1), g, z3.Extract(31, 16, v32), pos)
        elif k in (TM, C) and ref.field == "P":
            clamped = z3.If(v < 0, wide(0), z3.If(v > MAX_VALUE, wide(MAX_VALUE), v))
            self._put(self.key_for(ref), g, narrow(clamped, 16), pos)
        elif k == R and ref.field in ("I", "O"):
            self._put(self.key_for(ref), g, narrow(v, 16), pos)
        elif abstracted(ref) and ref.field is not None:
            self.run_abstract(Ref(k, ref.index), g, pos)
        else:
            self.unsupported(f"writing {ref}", pos, str(ref))

    # ---- words: one state key each, or with indexed objects the %MW words as one array --
    def word(self, ref: Ref) -> Any:
        """The 16-bit term of a word (%MW, %QW, %SW) or a block's word field."""
        if self.mw_array and ref.kind == "MW":
            self.mw_named.add(ref.index)
            return z3.Select(self.st[MW_ARRAY], z3.BitVecVal(ref.index, 16))
        return self.st[self.key_for(ref)]

    def put_word(self, ref: Ref, g: Any, v: Any, pos: A.Pos | None) -> None:
        if self.mw_array and ref.kind == "MW":
            self.mw_named.add(ref.index)
            self.mark_written(f"%MW{ref.index}", pos)
            arr = self.st[MW_ARRAY]
            new = z3.Store(arr, z3.BitVecVal(ref.index, 16), v)
            self.st[MW_ARRAY] = new if z3.is_true(g) else z3.If(g, new, arr)
            return
        self._put(self.key_for(ref), g, v, pos)

    def mw_index(self, ref: Ref, g: Any) -> Any:
        """The word number of `%MWi[%MWj]` / `%MDi[%MWj]` (16-bit), as `Ops.ix`: out of the
        family's range, %S20 and the object is processed as if the index were 0."""
        assert ref.offset is not None
        count = self.plc.profile.counts["MW"] - (1 if ref.kind == "MD" else 0)
        at = z3.BitVecVal(ref.index, 16)
        i = wide(ref.index) + wide(self.word(ref.offset))
        ok = z3.And(i >= 0, i < count)
        if g is not None:
            key = self.key_for(Ref("S", 20))
            self.mark_written(key, None)
            self.st[key] = z3.simplify(z3.Or(self.st[key], z3.And(g, z3.Not(ok))))
        return z3.If(ok, z3.Extract(15, 0, i), at)

    def _put(self, key: str, g: Any, v: Any, pos: A.Pos | None) -> None:
        if key in AFTER_PROGRAM:
            self.unsupported(f"writing {key}, which the system rewrites after the program",
                             pos, key)
        self.mark_written(key, pos)
        self.st[key] = z3.simplify(z3.If(g, v, self.st[key]))

    def fault(self, g: Any, f: Any) -> None:
        """%S18 set where a rule faulted (set by the system, reset only by the program)."""
        f = z3.simplify(z3.And(g, as_bool(f)))
        if z3.is_false(f):
            return
        self.st["%S18"] = z3.simplify(z3.Or(self.st["%S18"], f))

    def carry(self, g: Any, c: Any) -> None:
        """%S17 := the bit a shift or rotation moved out, where g holds."""
        key = self.key_for(Ref("S", 17))
        self.mark_written(key, None)
        self.st[key] = z3.simplify(z3.If(g, as_bool(c), self.st[key]))

    def unsupported(self, what: str, pos: A.Pos | None, text: str) -> None:
        p = pos or A.NOPOS
        self.problems.append(Diagnostic(
            f"verify cannot model {what}", self.plc.ast.file, p.line, p.column, text,
            "booleans, edges, 16/32-bit words, comparisons, "
            + ", ".join(f"%{k}" for k in MODELLED) + ", SR, JMP, Grafcet",
            Code.OTHER))

