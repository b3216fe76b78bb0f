"""Compiling values: object access, expressions and operation blocks.

`ValueCompiler` turns addresses and `[ ... ]` expressions into Python expressions over the
memory buffers, with their Twido type (word, double word, float, bit), and checks the
rules: read-only objects, word/float mixing, function signatures. The rung compiler
(`codegen.Compiler`) builds on it for the boolean accumulator and program control.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from typing import Any

from ..address import BLOCK_FIELDS, BOOL, INT16, INT32, REAL, Ref
from ..errors import Code, Diagnostic
from ..il import ast as A
from ..program import Names
from ..runtime.blocks import MAX_VALUE
from ..runtime.catalog import BLOCK_CLASSES
from ..runtime.exch import ETHERNET_PORT, SERIAL_PORTS
from ..semantics import FUNCTIONS, INLINE_EXACT, INLINE_QUOTIENT, inline_checked

ARITH = {"+": "add", "-": "sub", "*": "mul", "/": "div", "REM": "rem"}
BIT_BUFFERS, WORD_BUFFERS, PAIR_VIEWS, FAMILY = Names.BIT, Names.WORD, Names.PAIR, Names.FAMILY
# Float functions: the helper is "f" + the function name in lower case (semantics.Ops.fsqrt)
FLOAT_FUNCS = frozenset({"SQRT", "ABS", "TRUNC", "LOG", "LN", "EXP", "EXPT", "SIN", "COS",
                         "TAN", "ASIN", "ACOS", "ATAN", "DEG_TO_RAD", "RAD_TO_DEG"})
# Short form (`CU %C0`): the block method of each input pin (see blocks.Block: `run` for a
# timer's IN, else the pin's name in lower case).
BLOCK_PIN_METHODS = {pin: "run" if pin == "IN" else pin.lower()
                     for cls in BLOCK_CLASSES.values() for pin in cls.PINS}
# A block's input pins (as its class declares them) and its bit outputs (its read-only bit
# fields; the writable %VFCi.R / %VFCi.S are enable bits, not outputs).
BLOCK_KIND_PINS = {kind: cls.PINS for kind, cls in BLOCK_CLASSES.items()}
# Operand code without side effects (a buffer read, a literal): may be evaluated out of order
_PURE = re.compile(r"-?[\w\[\]]+")
BLOCK_OUTPUTS = {kind: tuple(f for f, (t, w) in fields.items() if t == BOOL and not w)
                 for kind, fields in BLOCK_FIELDS.items() if fields}


@dataclass
class _Acc:
    code: str
    kind: str = "atom"  # atom | and | or

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


class ValueCompiler:
    """Shared state of one compilation, diagnostics, emission, object access, expressions."""

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
            return f"({buf}[{ref.index}] >> {ref.bit} & 1)"
        if ref.type == BOOL and ref.kind in BLOCK_OUTPUTS or ref.field == "J":
            b = self.block_name(Ref(ref.kind, ref.index))
            if ref.field == "J":
                return f"{b}.bit({ref.bit})"
            return f"{b}.{ref.field}"
        self.err(f"{ref} is a {self.tname(ref.type)}, not a bit", pos, str(ref),
                 f"a bit (%I, %Q, %M, %S, %MWi:Xk, block output) or a comparison block "
                 f"such as [ {ref} <> 0 ]", code=Code.BLOCK)
        return "0"

    def read_word(self, ref: Ref, pos: A.Pos | None) -> tuple[str, str]:
        """(code, type) of a word/dword/float object."""
        k = ref.kind
        if ref.length is not None and k in BIT_BUFFERS and ref.offset is None:
            if ref.length > 32:  # a bit string read as a word (<= 16) or double word
                self.err(f"{ref}: a bit string of {ref.length} bits", pos, str(ref),
                         "at most 16 bits for a word, 32 for a double word", code=Code.TYPE)
                return "0", INT16
            h = self.helper("bitstr16" if ref.length <= 16 else "bitstr32")
            self.use(BIT_BUFFERS[k])
            return f"{h}({BIT_BUFFERS[k]}, {ref.index}, {ref.length})", \
                INT16 if ref.length <= 16 else INT32
        if ref.length is not None:
            self.err(f"{ref}: a word table cannot be used in an expression", pos, str(ref),
                     "a single word, double word or float, or a bit string %Mi:L", code=Code.TYPE)
            return "0", INT16
        if ref.bit is not None or ref.type == BOOL:
            self.err(f"{ref} is a bit, not a number", pos, str(ref),
                     "a word, double word or float (%MW, %MD, %MF, %KW, %SW, block field)",
                     code=Code.TYPE)
            return "0", INT16
        if k in WORD_BUFFERS:
            buf = WORD_BUFFERS[k]
            self.use(buf)
            if k in ("IW", "QW"):  # the resolve pass checked the module (PLC._allocate)
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
        if k in BLOCK_OUTPUTS or k in ("TM", "C", "DR", "R"):
            if ref.field is None:
                self.err(f"{ref} is a function block, not a value", pos, str(ref),
                         f"a field of it, such as {ref}.V or {ref}.P", code=Code.TYPE)
                return "0", INT16
            b = self.block_name(Ref(ref.kind, ref.index))
            return f"{b}.{ref.field}", INT16
        self.err(f"{ref} cannot be used in an expression", pos, str(ref),
                 "a word, double word or float", code=Code.TYPE)
        return "0", INT16

    def check_writable(self, ref: Ref, pos: A.Pos | None) -> bool:
        if not ref.writable:
            what = {"I": "an input: the program cannot write inputs",
                    "IW": "an analog input: the program cannot write inputs",
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
            self.err(f"{ref} is not a bit that can be stored to", pos, str(ref),
                     "%Q, %M, %S, %X or %MWi:Xk", code=Code.TYPE)

    # ---- expressions ----------------------------------------------------------------------
    def expr(self, e: A.Expr, want: str | None = None) -> tuple[str, str]:
        """(code, type). `want` adapts integer literals to the context's type."""
        if isinstance(e, A.Num):
            if e.is_float:
                return repr(float(e.value)), REAL
            v = int(e.value)
            if want == REAL:
                return repr(float(v)), REAL
            if e.text.startswith(("#", "16#")) and want != INT32 and 0x8000 <= v <= 0xFFFF:
                v -= 0x10000  # hex word constants are bit patterns
            if want == INT32 or not -32768 <= v <= 32767:
                if not -2147483648 <= v <= 2147483647:
                    self.err(f"constant {e.text or v} does not fit 32 bits", e.pos,
                             e.text or str(v), "-2147483648 .. 2147483647", code=Code.CONSTANT)
                return str(v), INT32
            return str(v), INT16
        if isinstance(e, A.Addr):
            return self.read_word(e.ref, e.pos)
        if isinstance(e, A.Neg):
            code, t = self.expr(e.operand, want)
            if t == REAL:
                return f"(-{code})", REAL
            return self.checked("neg", t, code), t
        if isinstance(e, A.BinOp):
            return self.binop(e, want)
        if isinstance(e, A.Call):
            return self.call(e, want)
        self.err("unsupported expression", getattr(e, "pos", None), "",
                 "a number, an object, an operator or a function", code=Code.OTHER)
        return "0", INT16

    def unify(self, a: tuple[str, str], b: tuple[str, str], pos: A.Pos | None,
              what: str) -> str | None:
        ta, tb = a[1], b[1]
        if ta == tb:
            return ta
        if REAL in (ta, tb):
            self.err(f"{what} mixes a float with a {'word' if INT16 in (ta, tb) else 'double word'}"
                     f" without conversion", pos, "",
                     "operands of one type: convert with INT_TO_REAL, DINT_TO_REAL, "
                     "REAL_TO_INT or REAL_TO_DINT", code=Code.TYPE)
            return None
        return INT32

    def operand_pair(self, left: A.Expr, right: A.Expr, want: str | None
                     ) -> tuple[tuple[str, str], tuple[str, str]]:
        # Literals take the type of the other side.
        lhint = None if isinstance(left, A.Num) else want
        a = self.expr(left, lhint if not isinstance(right, A.Num) else want)
        b = self.expr(right, a[1] if isinstance(right, A.Num) else want)
        if isinstance(left, A.Num) and not isinstance(right, A.Num):
            a = self.expr(left, b[1])
        return a, b

    def binop(self, e: A.BinOp, want: str | None) -> tuple[str, str]:
        a, b = self.operand_pair(e.left, e.right, want)
        t = self.unify(a, b, e.pos, f"'{e.op}'")
        if t is None:
            return self.poison(want)
        if e.op in ("AND", "OR", "XOR"):
            if t == REAL:
                self.err(f"word logic {e.op} needs words, not floats", e.pos, e.op,
                         "words or double words", code=Code.TYPE)
                return self.poison(want)
            py = {"AND": "&", "OR": "|", "XOR": "^"}[e.op]
            return f"({a[0]} {py} {b[0]})", t
        if e.op not in ARITH:
            self.err(f"unknown operator {e.op}", e.pos, e.op, "+ - * / REM AND OR XOR",
                     code=Code.FUNCTION)
            return "0", t
        if t == REAL:
            if e.op == "REM":
                self.err("REM on floats", e.pos, "REM", "words or double words", code=Code.TYPE)
                return "0", REAL
            if e.op == "/":
                return f"{self.helper('fdiv')}({a[0]}, {b[0]})", REAL
            return f"({a[0]} {e.op} {b[0]})", REAL
        if e.op == "REM":
            return f"{self.helper(f'rem{16 if t == INT16 else 32}')}({a[0]}, {b[0]})", t
        return self.checked(ARITH[e.op], t, a[0], b[0]), t

    @staticmethod
    def poison(want: str | None) -> tuple[str, str]:
        """Stand-in for an expression already reported: of the type the context wants, so
        one mistake gives one diagnostic, not a cascade."""
        return ("0.0", REAL) if want == REAL else ("0", want or INT16)

    def call(self, e: A.Call, want: str | None) -> tuple[str, str]:
        if e.func not in FUNCTIONS:
            self.err(f"unknown function {e.func}", e.pos, e.func,
                     ", ".join(sorted(FUNCTIONS)), code=Code.FUNCTION)
            return self.poison(want)
        params, result = FUNCTIONS[e.func]
        if len(e.args) != len(params):
            self.err(f"{e.func} takes {len(params)} argument(s), got {len(e.args)}", e.pos,
                     e.func, f"{len(params)} argument(s)", code=Code.FUNCTION)
            return self.poison(want)
        if params == ("table",):
            return self.table_function(e, want)
        args = []
        for p, arg in zip(params, e.args, strict=True):
            hint = p if p in (INT16, INT32, REAL) else (want if p in ("num", "int") else None)
            code, t = self.expr(arg, hint)
            if p in (INT16, INT32, REAL) and t != p and not (p == INT32 and t == INT16) and \
                    not (p == INT16 and isinstance(arg, A.Num) and t == INT16):
                if {t, p} & {REAL} or p == INT16:
                    self.err(f"{e.func} takes a {self.tname(p)}, got a {self.tname(t)}",
                             e.pos, e.func, f"a {self.tname(p)} argument", code=Code.TYPE)
            if p == "int" and t == REAL:
                self.err(f"{e.func} on a float", e.pos, e.func, "a word or double word",
                         code=Code.TYPE)
            args.append((code, t))
        t0 = args[0][1]
        f = e.func
        if f in ("SHL", "SHR", "ROL", "ROR"):
            h = self.helper(f"{f.lower()}{16 if t0 == INT16 else 32}")
        elif f == "NOT":
            return f"(~{args[0][0]})", t0
        elif f in ("SQRT", "ABS") and t0 != REAL:
            h = self.helper(f"{f.lower()}{16 if t0 == INT16 else 32}")
        elif f in FLOAT_FUNCS:
            h = self.helper("f" + f.lower())
        elif f in ("INT_TO_REAL", "DINT_TO_REAL"):
            return f"float({args[0][0]})", REAL
        else:  # REAL_TO_INT / REAL_TO_DINT, BCD and Gray conversions
            h = self.helper(f.lower())
        rtype = t0 if result == "same" else result
        return f"{h}({', '.join(c for c, _ in args)})", rtype

    def table_function(self, e: A.Call, want: str | None) -> tuple[str, str]:
        """SUM / MAX / MIN / MEAN over a table %MWi:L, %MDi:L, %MFi:L (or %KW...)."""
        arg = e.args[0]
        kinds = ("MW", "MD", "MF", "KW", "KD", "KF")
        if not (isinstance(arg, A.Addr) and arg.ref.length and arg.ref.kind in kinds
                and arg.ref.offset is None):
            self.err(f"{e.func} takes a table", e.pos, e.func,
                     "a table such as %MW0:10, %MD0:5 or %MF0:5", code=Code.FUNCTION)
            return self.poison(want)
        ref = arg.ref
        t = {"MW": INT16, "KW": INT16, "MD": INT32, "KD": INT32}.get(ref.kind, REAL)
        if e.func == "MEAN" and t != REAL:
            self.err("MEAN takes a float table", e.pos, str(ref), "a table such as %MF0:5",
                     code=Code.TYPE)
            return self.poison(want)
        self.use(Names.MEM)
        values = f"{Names.MEM}.read({str(ref)!r})"
        if e.func == "SUM":
            h = self.helper({INT16: "tsum16", INT32: "tsum32", REAL: "tsumf"}[t])
        else:
            h = self.helper("t" + e.func.lower())
        return f"{h}({values})", t

    @staticmethod
    def tname(t: str) -> str:
        return {INT16: "word", INT32: "double word", REAL: "float", BOOL: "bit"}.get(t, t)

    # ---- operation blocks -----------------------------------------------------------------
    def statement(self, st: A.Statement) -> None:
        if isinstance(st, A.PidCall):
            name = Names.block("PID", st.number)
            if self.env.get(name) is None:
                n = self.counts["PID"]
                self.err(f"PID {st.number} is used but not configured" if st.number < n
                         else f"PID {st.number} beyond PID 0 .. PID {n - 1}", st.pos,
                         f"PID {st.number}", f"a [pid.{st.number}] table in the configuration"
                         if st.number < n else f"PID 0 .. PID {n - 1}", code=Code.BLOCK)
                return
            self.use(name)
            self.emit(f"{name}.run()")
            return
        if isinstance(st, A.ExchCall):
            self.exch(st)
            return
        if isinstance(st, A.IncDec):
            ref = st.target
            if not self.check_writable(ref, st.pos):
                return
            code, t = self.read_word(ref, st.pos)
            if t == REAL:
                self.err(f"{st.op} of a float", st.pos, str(ref), "a word or double word",
                         code=Code.TYPE)
                return
            self.store_value(ref, self.checked("add" if st.op == "INC" else "sub", t, code, "1"),
                             t, st.pos)
            return
        ref, e = st.target, st.expr
        if not self.check_writable(ref, st.pos):
            return
        if ref.length is not None:
            self.table_assign(ref, e, st.pos)
            return
        if ref.type == BOOL or ref.is_block:
            self.err(f"cannot assign to {ref} with :=", st.pos, str(ref),
                     "a word, double word or float target (use ST / S / R for bits)",
                     code=Code.TYPE)
            return
        _, tt = self.read_word(ref, st.pos)
        code, t = self.expr(e, tt)
        if tt == REAL and t != REAL or tt != REAL and t == REAL:
            self.err(f"assignment of a {self.tname(t)} to the {self.tname(tt)} {ref} needs a "
                     f"conversion", st.pos, str(ref),
                     f"a {self.tname(tt)} value: INT_TO_REAL, DINT_TO_REAL, REAL_TO_INT, "
                     f"REAL_TO_DINT convert", code=Code.TYPE)
            return
        if tt == INT16 and t == INT32:
            if isinstance(e, A.Num):
                self.err(f"constant {e.text or e.value} does not fit the word {ref}", st.pos,
                         e.text or str(e.value), "-32768 .. 32767 (or #0000 .. #FFFF)",
                         code=Code.CONSTANT)
                return
            code = self.checked("narrow", INT16, code)
        self.store_value(ref, code, tt, st.pos)

    def exch(self, st: A.ExchCall) -> None:
        """`EXCHi %MWj:n` (communication, issue 11 B; runtime/exch.py): the port's %MSG
        block starts the exchange; only the Ethernet port 3 is emulated."""
        t, n = st.table, self.counts["MSG"]
        text = f"EXCH{st.port} {t}"
        if not 1 <= st.port < n:
            self.err(f"EXCH{st.port}: no such port", st.pos, text,
                     f"EXCH1 .. EXCH{n - 1}", code=Code.BLOCK)
        elif t.kind != "MW" or t.length is None or t.offset is not None:
            self.err(f"EXCH{st.port}: {t} is not a word table", st.pos, text,
                     "a %MW table such as %MW0:10", code=Code.TYPE)
        elif st.port in SERIAL_PORTS:
            self.err(f"EXCH{st.port}: the serial port {st.port} is not emulated", st.pos,
                     text, f"EXCH{ETHERNET_PORT} (the Ethernet port, configured in [exch])",
                     code=Code.BLOCK)
        elif getattr(self.env.get(Names.block("MSG", st.port)), "port", None) is None:
            self.err(f"EXCH{st.port} is used but the port is not configured", st.pos, text,
                     "an [exch] table in the configuration (the remote devices of the "
                     "Ethernet port, e.g. [exch.remote.1] host = ...)",
                     code=Code.BLOCK)
        else:
            self.emit(f"{self.block_name(Ref('MSG', st.port))}.exch({t.index}, {t.length})")

    def store_value(self, ref: Ref, code: str, t: str, pos: A.Pos | None) -> None:
        k = ref.kind
        if self.store_unchecked(ref, code, t):
            return
        if k in ("IW", "QW"):
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
        elif k in BLOCK_OUTPUTS or k in ("TM", "C", "R"):
            b = self.block_name(Ref(ref.kind, ref.index))
            if ref.field == "P" and k in ("TM", "C"):  # %PLS/%PWM clamp; %FC/%VFC: any word
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

    def table_assign(self, ref: Ref, e: A.Expr, pos: A.Pos | None) -> None:
        """Tables and bit strings: %MW0:5 := %MW10:5, %MW0:5 := 0, %M0:16 := %MW3,
        %MW3 := %M0:16 is handled by the caller as an expression error (rare)."""
        mem = Names.MEM
        self.use(mem)
        if isinstance(e, A.Addr) and e.ref.length is not None:
            src = e.ref
            if src.length != ref.length:
                self.err(f"table lengths differ: {ref} := {src}", pos, str(src),
                         f"a table of {ref.length}", code=Code.TYPE)
                return
            self.emit(f"{mem}.write({str(ref)!r}, {mem}.read({str(src)!r}))")
            return
        if ref.kind == "M":
            code, t = self.expr(e, INT16)
            if t == REAL:
                self.err("a bit string from a float", pos, str(ref), "a word value", code=Code.TYPE)
                return
            self.emit(f"{mem}.write({str(ref)!r}, [({code}) >> _k & 1 for _k in "
                      f"range({ref.length})])")
            return
        _, tt = self.read_word(Ref(ref.kind, ref.index), pos)
        code, t = self.expr(e, tt)
        if (t == REAL) != (tt == REAL):
            self.err(f"table {ref} and value types differ", pos, str(ref),
                     f"a {self.tname(tt)} value", code=Code.TYPE)
            return
        self.emit(f"{mem}.write({str(ref)!r}, [{code}] * {ref.length})")
