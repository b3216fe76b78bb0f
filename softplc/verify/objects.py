"""Object access for the model: bits, words, double words, function blocks as entries of the
state dict being built (`self.st`, inputs in `self.inp`), every write guarded, %S18 where a
rule faults, and what cannot be modelled reported with its line:col."""

from __future__ import annotations

import re
from typing import Any

import z3

from softplc.blocks import BIT, Scan
from softplc.errors import Code, Diagnostic
from softplc.il import ast as A
from softplc.runtime.blocks import MAX_VALUE
from softplc.runtime.engine import S_CLOCKS
from softplc.twido import catalog
from softplc.twido.address import BLOCK_FIELDS, INT16, INT32, REAL, Ref
from softplc.verify import floats
from softplc.verify.abstract import AbstractModel
from softplc.verify.blocks import apply, view
from softplc.verify.exprs import ExprModel
from softplc.verify.requirements import INDEXED_WORDS
from softplc.verify.symbolic import And, If, Not, Or, Z3State, as_bool, narrow, wide
from softplc.verify.system import AFTER_PROGRAM

MW_ARRAY = INDEXED_WORDS  # the state key of the %MW words when the program indexes them
CLOCK_WRAP_US = 60_000_000  # every %S4-%S7 clock period divides one minute
# the modelled families: those whose catalog entry names a verify model (softplc/blocks/)
MODELLED = {f.kind: f for f in catalog.FAMILIES.values() if f.verify}
BLOCK_KEY = re.compile(rf"%({'|'.join(MODELLED)})(\d+)\.(\w+)$")  # a modelled block's field
# the addressable blocks without a model: sound abstractions (`abstract`)
ABSTRACTED = frozenset(BLOCK_FIELDS) - set(MODELLED)


def abstracted(ref: Ref) -> bool:
    return ref.kind in ABSTRACTED and ref.offset is None


class ObjectModel(AbstractModel, ExprModel):
    """What `Model` reads and writes; `Model` supplies the state and the scan."""

    st: dict[str, Any]
    inp: dict[str, Any]
    used: dict[str, tuple[Any, Any]]  # block name -> (its family's model, the block)
    outs: dict[str, list[str]]  # block name -> the keys of the output bits it writes
    written: dict[str, A.Pos]
    executed: dict[str, Any]
    period_us: int
    longest_us: int
    mw_array: bool = False  # the %MW words as one array (`word`, `put_word`)
    mw_named: set[int]  # with it, the words named: compared with the engine

    def add_input(self, key: str, sort: str, lo: int = 0, hi: int = 0) -> None: ...

    # ---- blocks: each family's model (softplc/blocks/), dispatched by the catalog ----------
    def block(self, name: str) -> Any:
        m = BLOCK_KEY.match(name + ".x")
        return self.plc.mem.blocks[m[1]][int(m[2])]

    def scan_info(self, dt: Any = None) -> Scan:
        return Scan(self.period_us, self.longest_us, dt)

    def block_fields(self, name: str) -> dict[str, int]:
        """Block `name`'s state: field -> width (BIT for a bit)."""
        model, blk = self.used[name]
        return model.fields(blk, self.scan_info())

    @property
    def timers(self) -> dict[str, Any]:
        """The modelled blocks that count time (a time base), by name: what the timer
        lemmas (`lemmas`) and the advice on depths read."""
        return {n: b for n, (_m, b) in self.used.items() if hasattr(b, "base_us")}

    def block_view(self, name: str) -> dict[str, Any]:
        return view(self.st, name, self.block_fields(name), self.outs.get(name, ()))

    def use_block(self, ref: Ref, pos: A.Pos | None) -> str | None:
        name = f"%{ref.kind}{ref.index}"
        if ref.kind not in MODELLED:
            self.unsupported(f"the %{ref.kind} function block", pos, str(ref))
            return None
        if ref.index not in self.plc.mem.blocks.get(ref.kind, {}):
            self.unsupported(f"{name}: not used by the program nor configured", pos, name)
            return None
        if name not in self.used:
            model, blk = MODELLED[ref.kind].verify_model(), self.block(name)
            self.used[name] = (model, blk)
            outs = model.outputs(blk, self.plc)
            if outs:
                self.outs[name] = [self.key_for(r) for r in outs]
        for k in self.outs.get(name, ()):
            self.mark_written(k, pos)
        for f in self.block_fields(name):
            _ = self.st[f"{name}.{f}"]
        return name

    def run_block(self, ref: Ref, g: Any, pins: dict[str, Any], pos: A.Pos | None) -> None:
        if abstracted(ref):
            self.run_abstract(ref, g, pos)
            return
        name = self.use_block(ref, pos)
        if name is None:
            return
        model, blk = self.used[name]
        self.executed[name] = Or(self.executed.get(name, False), g)
        self.step_block(name, g, {k: pins.get(k, z3.BoolVal(False)) for k in blk.PINS}, pos)

    def step_block(self, name: str, g: Any, pins: dict[str, Any],
                   pos: A.Pos | None = None) -> None:
        """One execution of block `name` with inputs `pins`, where g holds; the fields the
        program can read that it changes are written by the program."""
        model, blk = self.used[name]
        new = model.run(Z3State, blk, self.block_view(name), pins, self.scan_info())
        readable = catalog.family(BLOCK_KEY.match(name + ".x")[1]).fields or {}
        for f in new:
            if f in readable:
                self.mark_written(f"{name}.{f}", pos)
        apply(self.st, name, g, new, self.outs.get(name, ()))

    def run_pin(self, ref: Ref, pin: str, g: Any, v: Any, pos: A.Pos | None) -> None:
        """The short form (`CU %C0`, `U %DR0`): as `Block`'s generated pin methods, the
        edge inputs held at their last value, the level inputs at 0."""
        if abstracted(ref):
            self.run_abstract(ref, g, pos)
            return
        name = self.use_block(ref, pos)
        if name is None:
            return
        held = {p: self.st[f"{name}.{a}"] for p, a in self.used[name][1].EDGE_PINS.items()}
        held[pin] = v
        self.run_block(ref, g, held, pos)

    def block_field(self, ref: Ref, width: int | None, writable: bool = False) -> str | None:
        """The state key of a block's field the program reads or writes (an address field
        of its family that its model keeps, of that width; None: any width; `writable`:
        one the program may write, %TMi.P, %Ri.I...)."""
        fam = MODELLED.get(ref.kind)
        if fam is None or ref.field not in (fam.fields or {}) or ref.offset is not None \
                or writable and not (fam.fields or {})[ref.field][1]:
            return None
        name = self.use_block(Ref(ref.kind, ref.index), None)
        if name is None:
            return "_none"
        w = self.block_fields(name).get(ref.field)
        return None if w is None or width is not None and w != width else \
            f"{name}.{ref.field}"

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
        key = self.block_field(ref, BIT)
        if key is not None:
            return self.st[key] if key != "_none" else z3.BoolVal(False)
        name = self.bit_object(ref, pos)
        if name is not None:
            return self.used[name][0].bit(Z3State, self.block_view(name), ref.bit)
        if abstracted(ref) and ref.field is not None and ref.bit is None:
            return self.read_abstract(ref)
        self.unsupported(f"reading {ref}", pos, str(ref))
        return z3.BoolVal(False)

    def write_bit(self, ref: Ref, g: Any, value: Any, pos: A.Pos | None) -> None:
        value = as_bool(value)
        if ref.kind in ("Q", "M", "S", "X") and ref.offset is None:
            key = self.key_for(ref)
            self.mark_written(key, pos)
            self.st[key] = z3.simplify(If(g, value, self.st[key]))
        elif ref.kind in ("MW", "SW") and ref.bit is not None and ref.offset is None:
            word = Ref(ref.kind, ref.index)
            w = self.word(word)
            mask = z3.BitVecVal(1 << ref.bit, 16)
            self.put_word(word, g, If(value, w | mask, w & ~mask), pos)
        elif (name := self.bit_object(ref, pos)) is not None:
            new = self.used[name][0].set_bit(Z3State, self.block_view(name), ref.bit, value)
            for f in new:
                self.mark_written(f"{name}.{f}", pos)
            apply(self.st, name, g, new)
        elif abstracted(ref) and ref.field is not None:
            self.run_abstract(Ref(ref.kind, ref.index), g, pos)
        else:
            self.unsupported(f"writing {ref}", pos, str(ref))

    def bit_object(self, ref: Ref, pos: A.Pos | None) -> str | None:
        """The block of a bit object (%SBRi.Jk, %SCi.k: a family with `bits`), None if
        `ref` is not one."""
        fam = MODELLED.get(ref.kind)
        if fam is None or not fam.bits or ref.bit is None or ref.offset is not None:
            return None
        return self.use_block(Ref(ref.kind, ref.index), pos)

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
            v = z3.Concat(*[If(b, z3.BitVecVal(1, 1), z3.BitVecVal(0, 1))
                            for b in reversed(bits)]) if len(bits) > 1 else \
                If(bits[0], z3.BitVecVal(1, 1), z3.BitVecVal(0, 1))
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
        key = self.block_field(ref, 16)
        if key is not None:
            return (wide(self.st[key]) if key != "_none" else wide(0)), INT16
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
                self.st[MW_ARRAY] = If(g, z3.Store(arr, at, x), arr)
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
        elif (key := self.block_field(ref, 16, writable=True)) is not None:
            if catalog.family(k).clamp_preset and ref.field == "P":
                v = If(v < 0, wide(0), If(v > MAX_VALUE, wide(MAX_VALUE), v))
            if key != "_none":
                self._put(key, g, narrow(v, 16), pos)
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
            self.st[MW_ARRAY] = new if z3.is_true(g) else If(g, new, arr)
            return
        self._put(self.key_for(ref), g, v, pos)

    def mw_index(self, ref: Ref, g: Any) -> Any:
        """The word number of `%MWi[%MWj]` / `%MDi[%MWj]` (16-bit), as `Ops.ix`: out of the
        family's range, %S20 and the object is processed as if the index were 0."""
        assert ref.offset is not None
        count = self.plc.profile.counts["MW"] - (1 if ref.kind == "MD" else 0)
        at = z3.BitVecVal(ref.index, 16)
        i = wide(ref.index) + wide(self.word(ref.offset))
        ok = And(i >= 0, i < count)
        if g is not None:
            key = self.key_for(Ref("S", 20))
            self.mark_written(key, None)
            self.st[key] = z3.simplify(Or(self.st[key], And(g, Not(ok))))
        return If(ok, z3.Extract(15, 0, i), at)

    def _put(self, key: str, g: Any, v: Any, pos: A.Pos | None) -> None:
        if key in AFTER_PROGRAM:
            self.unsupported(f"writing {key}, which the system rewrites after the program",
                             pos, key)
        self.mark_written(key, pos)
        self.st[key] = z3.simplify(If(g, v, self.st[key]))

    def fault(self, g: Any, f: Any) -> None:
        """%S18 set where a rule faulted (set by the system, reset only by the program)."""
        f = z3.simplify(And(g, as_bool(f)))
        if z3.is_false(f):
            return
        self.st["%S18"] = z3.simplify(Or(self.st["%S18"], f))

    def carry(self, g: Any, c: Any) -> None:
        """%S17 := the bit a shift or rotation moved out, where g holds."""
        key = self.key_for(Ref("S", 17))
        self.mark_written(key, None)
        self.st[key] = z3.simplify(If(g, as_bool(c), self.st[key]))

    def unsupported(self, what: str, pos: A.Pos | None, text: str) -> None:
        p = pos or A.NOPOS
        self.problems.append(Diagnostic(
            f"verify cannot model {what}", self.plc.ast.file, p.line, p.column, text,
            "booleans, edges, 16/32-bit words, comparisons, "
            + ", ".join(f"%{k}" for k in MODELLED) + ", SR, JMP, Grafcet",
            Code.OTHER))

