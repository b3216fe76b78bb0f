"""Compiling object access: the shared state of one compilation (diagnostics, emission of
code lines), and reading and writing Twido objects (bits, words, double words, floats, block
fields and pins) as Python over the memory buffers, with the checks that go with them
(read-only objects, forced bits, what a block field is). `values.ValueCompiler` adds the
expressions and statements on top; the function-block tables come from the catalog.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from typing import Any

from softplc.errors import Code, Diagnostic
from softplc.il import ast as A
from softplc.program import Names
from softplc.runtime.blocks import MAX_VALUE
from softplc.twido import catalog
from softplc.twido.address import BOOL, INT16, INT32, REAL, Ref
from softplc.twido.semantics import INLINE_EXACT, INLINE_QUOTIENT, inline_checked

BIT_BUFFERS, WORD_BUFFERS, PAIR_VIEWS, FAMILY = Names.BIT, Names.WORD, Names.PAIR, Names.FAMILY
# Short form (`CU %C0`): the block method of each input pin (see blocks.Block: `run` for a
# timer's IN, else the pin's name in lower case).
BLOCK_PIN_METHODS = {pin: "run" if pin == "IN" else pin.lower()
                     for f in catalog.addressable() for pin in f.pins}
# A block's input pins (as its class declares them) and its bit outputs (its read-only bit
# fields; the writable %VFCi.R / %VFCi.S are enable bits, not outputs).
BLOCK_KIND_PINS = {f.kind: f.pins for f in catalog.addressable()}
BLOCK_OUTPUTS = {f.kind: f.outputs for f in catalog.addressable() if f.fields}
# blocks whose preset a store clamps to 0 .. MAX_VALUE (the others clamp it themselves or
# take any word)
CLAMPED_PRESET = frozenset(f.kind for f in catalog.FAMILIES.values() if f.clamp_preset)
# word objects indexed by (module or station, channel), never by a %MW: analog I/O words and
# the Remote Link's network words
DIRECT_WORDS = frozenset(("IW", "QW", "INW", "QNW"))
# Operand code without side effects (a buffer read, a literal): may be evaluated out of order
_PURE = re.compile(r"-?[\w\[\]]+")


@dataclass
class _Acc:
    code: str
    kind: str = "atom"  # atom | and | or
    # this value is `(not X)`: X, so that `(not A) and (not B)` can be written
    # `not (A or B)` (De Morgan: one negation fewer per ANDN; a chain of them, one in all)
    neg: str | None = None

    @property
    def simple(self) -> bool:  # safe to evaluate again after memory changed
        return self.code in ("0", "1", "True", "False") or (
            self.code.startswith("_t") and self.code[2:].isdigit())


class _Fn:
    """Code of one function being generated."""

    def __init__(self, name: str):
        self.name = name
        self.lines: list[str] = []
        self.names: set[str] = set()
        self.blocks: list[int] = []  # rung index starting each dispatcher block


class ObjectCompiler:
    """Shared state of one compilation, diagnostics, emission, object access."""

    def __init__(self, program: A.Program, profile_counts: dict[str, int],
                 debug: bool = False, forced: frozenset[Ref] = frozenset()):
        self.program = program
        self.forced = forced  # bits the program may not change (forced from outside)
        self.counts = profile_counts
        self.debug = debug
        self.diags: list[Diagnostic] = []
        self.tmp = itertools.count()
        self.edge = itertools.count()
        self.fn: _Fn
        self.indent = 1
        self.ninstr = 0
        self.env: dict[str, Any] = {}  # the bound names (`program.bind`): configured PIDs
        # inline operation code -> (op, bits, a, b): what `store_value` may store unchecked
        self.inline_parts: dict[str, tuple[str, int, str, str]] = {}

    # ---- diagnostics ----------------------------------------------------------------------
    def err(self, msg: str, pos: A.Pos | None, text: str = "", expected: str = "",
            code: Code = Code.OTHER) -> None:
        p = pos or A.NOPOS
        if not text and p.line:
            lines = self.program.source.splitlines()
            text = lines[p.line - 1].strip() if p.line <= len(lines) else ""
        self.diags.append(Diagnostic(msg, self.program.file, p.line, p.column, text, expected,
                                     code))

    # ---- emission helpers -----------------------------------------------------------------
    def use(self, *names: str) -> None:
        self.fn.names.update(names)

    def helper(self, name: str) -> str:
        """The bound name of the instruction helper `semantics.Ops.<name>`, used."""
        bound = Names.helper(name)
        self.use(bound)
        return bound

    def emit(self, line: str) -> None:
        self.fn.lines.append("    " * self.indent + line)

    def new_local(self) -> str:
        """A fresh local for an inline operation's value (not an accumulator: see _Acc)."""
        return f"_v{next(self.tmp)}"

    def new_tmp(self) -> str:
        return f"_t{next(self.tmp)}"

    def checked(self, op: str, t: str, a: str, b: str = "") -> str:
        """Code of the checked word operation `op` (add sub mul div neg narrow) of type `t`,
        inline (`semantics.inline_checked`)."""
        bits = 16 if t == INT16 else 32
        narrow = self.helper(f"narrow{bits}")
        if op != "div":
            code = inline_checked(op, bits, a, b, v=self.new_local(), narrow=narrow)
        else:
            code = inline_checked(op, bits, a, b, v=self.new_local(), narrow=narrow,
                                  div=self.helper(f"div{bits}"), d=self.new_local(),
                                  n="" if _PURE.fullmatch(a) else self.new_local())
        self.inline_parts[code] = (op, bits, a, b)
        return code

    def materialize(self, acc: _Acc) -> _Acc:
        if acc.simple:
            return acc
        t = self.new_tmp()
        self.emit(f"{t} = {acc.code}")
        return _Acc(t)

    # ---- object access --------------------------------------------------------------------
    def block_name(self, ref: Ref) -> str:
        """The bound name of a block (the resolve pass collected it, the PLC allocated it)."""
        name = Names.block(ref.kind, ref.index)
        self.use(name)
        return name

    def index_code(self, ref: Ref, count: int) -> str:
        """Index expression for a possibly indexed object."""
        if ref.offset is None:
            return str(ref.index)
        ix, mw = self.helper("ix"), WORD_BUFFERS["MW"]
        self.use(mw)
        return f"{ix}({ref.index}, {mw}[{ref.offset.index}], {count})"

    def read_bit(self, ref: Ref, pos: A.Pos | None) -> str:
        k = ref.kind
        if k in BIT_BUFFERS:
            buf = BIT_BUFFERS[k]
            self.use(buf)
            if k in ("I", "Q"):
                return f"{buf}[{ref.index}]"
            return f"{buf}[{self.index_code(ref, self.counts[k])}]"
        if ref.bit is not None and ref.kind in WORD_BUFFERS:
            buf = WORD_BUFFERS[k]
            self.use(buf)
            return f"({buf}[{ref.index}] & {1 << ref.bit} != 0)"  # a bool, as bits are
        if ref.type == BOOL and ref.kind in BLOCK_OUTPUTS or ref.field == "J":
            b = self.block_name(Ref(ref.kind, ref.index))
            if ref.field == "J":
                return f"{b}.bit({ref.bit})"
            # a block holds its outputs as 0/1: compared, they store bools in the images
            return f"({b}.{ref.field} == 1)"
        self.err(f"{ref.label} is a {self.tname(ref.type)}, not a bit", pos, str(ref),
                 f"a bit (%I, %Q, %M, %S, %MWi:Xk, block output) or a comparison block "
                 f"such as [ {ref} <> 0 ]", code=Code.BLOCK)
        return "0"

    def read_word(self, ref: Ref, pos: A.Pos | None) -> tuple[str, str]:
        """(code, type) of a word/dword/float object."""
        k = ref.kind
        if ref.length is not None and k in BIT_BUFFERS and ref.offset is None:
            if ref.length > 32:  # a bit string read as a word (<= 16) or double word
                self.err(f"{ref.label}: a bit string of {ref.length} bits", pos, str(ref),
                         "at most 16 bits for a word, 32 for a double word", code=Code.TYPE)
                return "0", INT16
            h = self.helper("bitstr16" if ref.length <= 16 else "bitstr32")
            self.use(BIT_BUFFERS[k])
            return f"{h}({BIT_BUFFERS[k]}, {ref.index}, {ref.length})", \
                INT16 if ref.length <= 16 else INT32
        if ref.length is not None:
            self.err(f"{ref.label}: a word table cannot be used in an expression", pos, str(ref),
                     "a single word, double word or float, or a bit string %Mi:L", code=Code.TYPE)
            return "0", INT16
        if ref.bit is not None or ref.type == BOOL:
            self.err(f"{ref.label} is a bit, not a number", pos, str(ref),
                     "a word, double word or float (%MW, %MD, %MF, %KW, %SW, block field)",
                     code=Code.TYPE)
            return "0", INT16
        if k in WORD_BUFFERS:
            buf = WORD_BUFFERS[k]
            self.use(buf)
            if k in DIRECT_WORDS:  # the resolve pass checked the module (PLC._allocate)
                return f"{buf}[{ref.index}]", INT16
            return f"{buf}[{self.index_code(ref, self.counts[k])}]", INT16
        if k in PAIR_VIEWS:
            typ = REAL if k in ("MF", "KF") else INT32
            if ref.offset is not None:
                fam = FAMILY[k]
                self.use(fam)
                idx = self.index_code(ref, self.counts[k[0] + "W"] - 1)  # of the word family
                return f"{fam}.get_{'f' if typ == REAL else 'd'}({idx})", typ
            view = PAIR_VIEWS[k][ref.index & 1]
            self.use(view)
            return f"{view}[{ref.index >> 1}]", typ
        if k in BLOCK_OUTPUTS:
            if ref.field is None:
                self.err(f"{ref.label} is a function block, not a value", pos, str(ref),
                         f"a field of it, such as {ref}.V or {ref}.P", code=Code.TYPE)
                return "0", INT16
            b = self.block_name(Ref(ref.kind, ref.index))
            return f"{b}.{ref.field}", INT16
        self.err(f"{ref.label} cannot be used in an expression", pos, str(ref),
                 "a word, double word or float", code=Code.TYPE)
        return "0", INT16

    def check_writable(self, ref: Ref, pos: A.Pos | None) -> bool:
        if not ref.writable:
            what = {"I": "an input: the program cannot write inputs",
                    "IW": "an analog input: the program cannot write inputs",
                    "INW": "a Remote Link word received: the program writes %QNW",
                    "KW": "a constant", "KD": "a constant", "KF": "a constant"}.get(
                ref.kind, "read-only")
            self.err(f"cannot write {ref}: it is {what}", pos, str(ref),
                     "a writable object (%Q, %M, %MW, %MD, %MF, %TMi.P, %Ci.P...)",
                     code=Code.READ_ONLY)
            return False
        return True

    def write_bit(self, ref: Ref, value: str, pos: A.Pos | None) -> None:
        """Emit `ref := value` for a bit target."""
        if not self.check_writable(ref, pos):
            return
        if ref in self.forced:  # a forced bit keeps its value all through the scan
            self.emit(f"pass  # {ref} is forced")
            return
        k = ref.kind
        if k in BIT_BUFFERS:
            buf = BIT_BUFFERS[k]
            self.use(buf)
            idx = str(ref.index) if k in ("I", "Q") else self.index_code(ref, self.counts[k])
            self.emit(f"{buf}[{idx}] = {value}")
        elif ref.field == "J":  # %SBRi.j, %SCi.j
            b = self.block_name(Ref(k, ref.index))
            self.emit(f"{b}.set_bit({ref.bit}, {value})")
        elif ref.kind in BLOCK_OUTPUTS and ref.field is not None:  # %VFCi.R / .S enables
            self.emit(f"{self.block_name(Ref(k, ref.index))}.{ref.field} = {value}")
        elif ref.bit is not None and k in WORD_BUFFERS:
            u = Names.UWORD[k]
            self.use(u)
            mask = 1 << ref.bit
            self.emit(f"{u}[{ref.index}] = ({u}[{ref.index}] | {mask}) if {value} else "
                      f"({u}[{ref.index}] & {0xFFFF ^ mask})")
        else:
            self.err(f"{ref.label} is not a bit that can be stored to", pos, str(ref),
                     "%Q, %M, %S, %X or %MWi:Xk", code=Code.TYPE)

    @staticmethod
    def tname(t: str) -> str:
        return {INT16: "word", INT32: "double word", REAL: "float", BOOL: "bit"}.get(t, t)

    def store_value(self, ref: Ref, code: str, t: str, pos: A.Pos | None) -> None:
        k = ref.kind
        if self.store_unchecked(ref, code, t):
            return
        if k in DIRECT_WORDS:
            self.use(WORD_BUFFERS[k])
            self.emit(f"{WORD_BUFFERS[k]}[{ref.index}] = {code}")
        elif k in WORD_BUFFERS:
            buf = WORD_BUFFERS[k]
            self.use(buf)
            self.emit(f"{buf}[{self.index_code(ref, self.counts[k])}] = {code}")
        elif k in PAIR_VIEWS:
            if ref.offset is not None:
                fam = FAMILY[k]
                self.use(fam)
                idx = self.index_code(ref, self.counts[k[0] + "W"] - 1)  # of the word family
                self.emit(f"{fam}.set_{'f' if t == REAL else 'd'}({idx}, {code})")
                return
            view = PAIR_VIEWS[k][ref.index & 1]
            self.use(view)
            if t == REAL:
                self.emit(f"{self.helper('stf')}({view}, {ref.index >> 1}, {code})")
            else:
                self.emit(f"{view}[{ref.index >> 1}] = {code}")
        elif k in BLOCK_OUTPUTS:
            b = self.block_name(Ref(ref.kind, ref.index))
            if ref.field == "P" and k in CLAMPED_PRESET:
                self.emit(f"{b}.P = min(max({code}, 0), {MAX_VALUE})")
            else:
                self.emit(f"{b}.{ref.field} = {code}")
        else:
            self.err(f"cannot assign to {ref}", pos, str(ref),
                     "a word, double word, float or block preset", code=Code.TYPE)

    def store_unchecked(self, ref: Ref, code: str, t: str) -> bool:
        """`%MW5 := %MW3 + %MW7` (one add/sub/mul/div/neg/narrow of plain reads into a
        plain word or double word): the memoryview store itself refuses a value out of its
        range (ValueError), a zero divisor raises ZeroDivisionError, so the common path
        makes no check at all; the rare path recomputes with the `Ops` helper (%S18, wrap,
        0 for a division by zero). Operands without side effects may be read twice."""
        parts = self.inline_parts.get(code)
        if parts is None or ref.offset is not None or t == REAL:
            return False
        op, bits, a, b = parts
        if not (_PURE.fullmatch(a) and (op in ("neg", "narrow") or _PURE.fullmatch(b))):
            return False
        # the store's range must be the operation's: a word sum stored in a %MD checks 16 bits
        if ref.kind in WORD_BUFFERS and bits == 16:
            target = f"{WORD_BUFFERS[ref.kind]}[{ref.index}]"
        elif ref.kind in PAIR_VIEWS and bits == 32:
            target = f"{PAIR_VIEWS[ref.kind][ref.index & 1]}[{ref.index >> 1}]"
        else:
            return False
        self.use(target.split("[")[0])
        if op == "div":
            exact, errors = INLINE_QUOTIENT.format(n=a, d=b), "(ValueError, ZeroDivisionError)"
        else:
            exact, errors = INLINE_EXACT[op].format(a=a, b=b), "ValueError"
        args = a if op in ("neg", "narrow") else f"{a}, {b}"
        self.emit("try:")
        self.emit(f"    {target} = {exact}")
        self.emit(f"except {errors}:  # out of the word's range, or / 0: %S18")
        self.emit(f"    {target} = {self.helper(f'{op}{bits}')}({args})")
        return True
