"""Compiling values: expressions and operation blocks.

`ValueCompiler` turns `[ ... ]` expressions into Python expressions over the memory
buffers, with their Twido type (word, double word, float, bit), and checks the rules:
word/float mixing, function signatures; object access (reading, writing, the checks of
read-only objects) is `objects.ObjectCompiler`'s. The rung compiler (`codegen.Compiler`)
builds on it for the boolean accumulator and program control.
"""

from __future__ import annotations

from softplc.compiler.objects import (  # noqa: F401  (the compiler's tables, also read by the ladder view)
    BLOCK_KIND_PINS,
    BLOCK_OUTPUTS,
    BLOCK_PIN_METHODS,
    ObjectCompiler,
    _Acc,
    _Fn,
)
from softplc.errors import Code
from softplc.il import ast as A
from softplc.program import Names
from softplc.runtime.exch import ETHERNET_PORT, SERIAL_PORTS
from softplc.twido import catalog
from softplc.twido.address import BOOL, INT16, INT32, REAL, Ref
from softplc.twido.semantics import ARITH_OPS, FUNCTIONS

# Float functions: the helper is "f" + the function name in lower case (semantics.Ops.fsqrt)
FLOAT_FUNCS = frozenset({"SQRT", "ABS", "TRUNC", "LOG", "LN", "EXP", "EXPT", "SIN", "COS",
                         "TAN", "ASIN", "ACOS", "ATAN", "DEG_TO_RAD", "RAD_TO_DEG"})
# IL keyword -> the block family its instruction runs (`[ PID n ]`)
BLOCK_INSTRUCTIONS = catalog.by_instruction()


class ValueCompiler(ObjectCompiler):
    """Expressions, assignments and operation blocks over `ObjectCompiler`'s objects."""

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
        if e.op not in ARITH_OPS:
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
        return self.checked(ARITH_OPS[e.op], t, a[0], b[0]), t

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

    # ---- operation blocks -----------------------------------------------------------------
    def statement(self, st: A.Statement) -> None:
        if isinstance(st, A.BlockCall):
            fam = BLOCK_INSTRUCTIONS[st.keyword]
            name = Names.block(fam.kind, st.number)
            if self.env.get(name) is None:
                n, kw = self.counts[fam.kind], f"{fam.instruction} "
                self.err(f"{kw}{st.number} is used but not configured" if st.number < n
                         else f"{kw}{st.number} beyond {kw}0 .. {kw}{n - 1}", st.pos,
                         f"{kw}{st.number}", f"a [{fam.section}.{st.number}] table in the "
                         "configuration" if st.number < n else f"{kw}0 .. {kw}{n - 1}",
                         code=Code.BLOCK)
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
