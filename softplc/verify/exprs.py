"""Operands, `[ ... ]` expressions and operation blocks as solver terms.

The typing follows `compiler/values.py` (literals take the other side's type, a word
operation on a double word is 32-bit, a 32-bit value stored in a word is narrowed with
%S18) and every arithmetic rule is `semantics.arith` over `symbolic.Z3Domain`.
"""

from __future__ import annotations

from typing import Any

import z3

from softplc.errors import Diagnostic
from softplc.il import ast as A
from softplc.twido.address import INT16, INT32, REAL, Ref
from softplc.twido.semantics import (
    ARITH_OPS,
    FUNCTIONS,
    absolute,
    arith,
    bcd_to_int,
    checked,
    concat_words,
    gray_to_int,
    high_word,
    int_sqrt,
    int_to_bcd,
    low_word,
    negate,
    shift,
)
from softplc.verify import floats
from softplc.verify.abstract import SITE
from softplc.verify.symbolic import And, If, Z3Domain, wide

# the integer functions modelled exactly (each a rule in `semantics`)
INT_FUNCS = frozenset({"ABS", "SQRT", "NOT", "SHL", "SHR", "ROL", "ROR", "BCD_TO_INT", "BTI",
                       "INT_TO_BCD", "ITB", "GRAY_TO_INT", "LW", "HW", "CONCATW"})
CMP = {"=": lambda a, b: a == b, "<>": lambda a, b: a != b, ">": lambda a, b: a > b,
       ">=": lambda a, b: a >= b, "<": lambda a, b: a < b, "<=": lambda a, b: a <= b}


class ExprModel:
    """Expressions over the state being built (`self.st`); the model supplies object
    access (`read_bit`, `read_word`, `store_word`), `fault` and `unsupported`."""

    def __init__(self, plc: Any):
        self.plc = plc
        self.problems: list[Diagnostic] = []

    # provided by Model
    def read_bit(self, ref: Ref, pos: A.Pos | None) -> Any: ...
    def read_word(self, ref: Ref, pos: A.Pos | None, g: Any = None) -> tuple[Any, str]: ...
    def store_word(self, ref: Ref, g: Any, v: Any, t: str, pos: A.Pos | None) -> None: ...
    def fault(self, g: Any, f: Any) -> None: ...
    def carry(self, g: Any, c: Any) -> None: ...
    def unsupported(self, what: str, pos: A.Pos | None, text: str) -> None: ...
    def key_for(self, ref: Ref) -> str: ...
    def write_bit(self, ref: Ref, g: Any, value: Any, pos: A.Pos | None) -> None: ...
    def run_exch(self, stmt: A.ExchCall, g: Any) -> None: ...
    def put_word(self, ref: Ref, g: Any, v: Any, pos: A.Pos | None) -> None: ...
    def add_input(self, key: str, sort: str, lo: int = 0, hi: int = 0) -> None: ...
    def mark_written(self, key: str, pos: A.Pos | None) -> None: ...
    facts: list[Any]
    applied: dict[str, list[tuple[Any, Any]]]  # this scan's abstracted calls: f -> (x, r)
    st: dict[str, Any]
    inp: dict[str, Any]
    def run_called(self, stmt: A.BlockCall, g: Any) -> bool: ...

    def operand(self, op: Any, blk: Ref | None, g: Any) -> Any:
        if op is None:
            return z3.BoolVal(True)
        if isinstance(op, A.Const):
            return z3.BoolVal(bool(op.value))
        if isinstance(op, A.Operand):
            return self.read_bit(op.ref, op.pos)
        if isinstance(op, A.BlockOutput):
            if blk is None:
                return z3.BoolVal(False)
            return self.read_bit(Ref(blk.kind, blk.index, field=op.name), op.pos)
        if isinstance(op, A.Compare):
            (a, ta), (b, tb) = self.pair(op.left, op.right, None, g)
            if REAL in (ta, tb):  # one side not a float: already reported
                return floats.compare(op.op, a, b) if ta == tb else z3.BoolVal(False)
            return CMP[op.op](a, b)
        self.unsupported("this operand", getattr(op, "pos", None), "")
        return z3.BoolVal(False)

    def expr(self, e: A.Expr, want: str | None, g: Any) -> tuple[Any, str]:
        """(wide term, type) of an expression; faults set %S18 where g holds."""
        if isinstance(e, A.Num):
            if e.is_float or want == REAL:
                return floats.const(float(e.value)), REAL
            v = int(e.value)
            if e.text.startswith(("#", "16#")) and want != INT32 and 0x8000 <= v <= 0xFFFF:
                v -= 0x10000  # hex word constants are bit patterns
            t = INT32 if want == INT32 or not -32768 <= v <= 32767 else INT16
            return wide(v), t
        if isinstance(e, A.Addr):
            return self.read_word(e.ref, e.pos, g)
        if isinstance(e, A.Neg):
            v, t = self.expr(e.operand, want, g)
            if t == REAL:
                return z3.fpNeg(v), REAL
            r, f = negate(Z3Domain, v, 16 if t == INT16 else 32)
            self.fault(g, f)
            return r, t
        if isinstance(e, A.BinOp):
            (a, ta), (b, tb) = self.pair(e.left, e.right, want, g)
            t = ta if ta == tb else INT32
            if REAL in (ta, tb) and ta != tb:  # a side already reported
                return floats.const(0.0), REAL
            if REAL in (ta, tb):
                r, faults = floats.binop(e.op, a, b)
                for c, kind in faults:
                    self.float_fault(g, c, kind)
                return r, REAL
            if e.op in ("AND", "OR", "XOR"):
                return (a & b if e.op == "AND" else a | b if e.op == "OR" else a ^ b), t
            r, f = arith(Z3Domain, ARITH_OPS[e.op], a, b, 16 if t == INT16 else 32)
            self.fault(g, f)
            return r, t
        if isinstance(e, A.Call):
            return self.call(e, want, g)
        self.unsupported("this expression", getattr(e, "pos", None), "")
        return wide(0), INT16

    def pair(self, left: A.Expr, right: A.Expr, want: str | None, g: Any
             ) -> tuple[tuple[Any, str], tuple[Any, str]]:
        """Literals take the type of the other side (as `ValueCompiler.operand_pair`)."""
        lhint = None if isinstance(left, A.Num) else want
        a = self.expr(left, lhint if not isinstance(right, A.Num) else want, g)
        b = self.expr(right, a[1] if isinstance(right, A.Num) else want, g)
        if isinstance(left, A.Num) and not isinstance(right, A.Num):
            a = self.expr(left, b[1], g)
        return a, b

    def call(self, e: A.Call, want: str | None, g: Any) -> tuple[Any, str]:
        """The integer functions with a bit-vector rule in `semantics`, typed as
        `ValueCompiler.call` (argument hints from `FUNCTIONS`, "same" result type)."""
        f = e.func
        if f in FUNCTIONS and len(e.args) == len(FUNCTIONS[f][0]) and (
                REAL in FUNCTIONS[f][0] or FUNCTIONS[f][1] == REAL or want == REAL
                and f in ("ABS", "SQRT")):
            return self.real_call(e, want, g)
        if f not in INT_FUNCS or f not in FUNCTIONS or len(e.args) != len(FUNCTIONS[f][0]):
            self.unsupported(f"the function {f}", e.pos, f)
            return wide(0), want or INT16
        params, result = FUNCTIONS[f]
        args = [self.expr(a, p if p in (INT16, INT32, REAL) else want, g)
                for p, a in zip(params, e.args, strict=True)]
        if any(t == REAL for _, t in args):
            return self.real_call(e, want, g)
        (v, t), bits = args[0], 16 if args[0][1] == INT16 else 32
        rtype = t if result == "same" else result
        D = Z3Domain
        if f == "NOT":
            return ~v, t
        if f == "ABS":
            r, fault = absolute(D, v, bits)
        elif f == "SQRT":
            r, fault = int_sqrt(D, v, bits)
        elif f in ("SHL", "SHR", "ROL", "ROR"):
            r, carry, moved = shift(D, f, v, args[1][0], bits)
            self.carry(And(g, moved), carry)
            return r, rtype
        elif f in ("BCD_TO_INT", "BTI"):
            r, fault = bcd_to_int(D, v)
        elif f in ("INT_TO_BCD", "ITB"):
            r, fault = int_to_bcd(D, v)
        elif f == "GRAY_TO_INT":
            return gray_to_int(D, v), rtype
        elif f == "CONCATW":
            return concat_words(D, v, args[1][0]), rtype
        else:
            return (low_word if f == "LW" else high_word)(D, v), rtype
        self.fault(g, fault)
        return r, rtype

    def statement(self, stmt: A.Statement, g: Any) -> None:
        """An operation block, run where g holds."""
        if isinstance(stmt, A.IncDec):
            v, t = self.read_word(stmt.target, stmt.pos, g)
            r, f = arith(Z3Domain, "add" if stmt.op == "INC" else "sub", v, wide(1),
                         16 if t == INT16 else 32)
            self.fault(g, f)
            self.store_word(stmt.target, g, r, t, stmt.pos)
            return
        if isinstance(stmt, A.ExchCall):
            self.run_exch(stmt, g)
            return
        if isinstance(stmt, A.BlockCall) and self.run_called(stmt, g):
            return
        if not isinstance(stmt, A.Assign):
            what = stmt.keyword if isinstance(stmt, A.BlockCall) else "EXCH"
            self.unsupported(f"{what} (its effect is outside the program)", stmt.pos, what)
            return
        ref = stmt.target
        if ref.length is not None and ref.offset is None:
            self.table_assign(ref, stmt.expr, g, stmt.pos)
            return
        if ref.type == REAL and ref.length is None and ref.offset is None \
                and ref.kind == "MF":
            v, t = self.expr(stmt.expr, REAL, g)
            if t == REAL:  # else a part was reported
                self.store_real(ref, g, v, stmt.pos)
            return
        if ref.length is not None or ref.type == REAL:
            self.unsupported("floating-point values" if ref.type == REAL else
                             "an indexed table", stmt.pos, str(ref))
            return
        tt = INT32 if ref.kind in ("MD", "KD") else INT16
        v, t = self.expr(stmt.expr, tt, g)
        if tt == INT16 and t == INT32:
            v, f = checked(Z3Domain, v, 16)  # `narrow16`
            self.fault(g, f)
        self.store_word(ref, g, v, tt, stmt.pos)

    def table_assign(self, ref: Ref, e: A.Expr, g: Any, pos: A.Pos | None) -> None:
        """As `ValueCompiler.table_assign`: `%MWi:n := %MWj:n` (all read, then all
        written), `%MWi:n := value` (each word), `%Mi:n := value` (bit k of the value)."""
        n = ref.length or 0
        if isinstance(e, A.Addr) and e.ref.length is not None:
            src = e.ref
            if src.kind == ref.kind and src.length == n and src.offset is None \
                    and ref.kind in ("MW", "M"):
                get = (lambda r: self.read_bit(r, pos)) if ref.kind == "M" else \
                    (lambda r: self.read_word(r, pos)[0])
                vals = [get(Ref(src.kind, src.index + k)) for k in range(n)]
                for k, v in enumerate(vals):
                    self.put_element(Ref(ref.kind, ref.index + k), g, v, pos)
                return
        elif ref.kind in ("MW", "M"):
            v, t = self.expr(e, INT16, g)
            if t == INT16:  # bit k of the value: of its sign extension beyond 16
                vals = [wide(v) if ref.kind == "MW" else z3.Extract(k, k, wide(v)) == 1
                        for k in range(n)]
                for k, x in enumerate(vals):
                    self.put_element(Ref(ref.kind, ref.index + k), g, x, pos)
                return
        self.unsupported("this table assignment", pos, str(ref))

    def put_element(self, ref: Ref, g: Any, v: Any, pos: A.Pos | None) -> None:
        if ref.kind == "M":
            self.write_bit(ref, g, v, pos)
        else:
            self.store_word(ref, g, v, INT16, pos)

    # ---- floats (`floats`) --------------------------------------------------------------
    def real_call(self, e: A.Call, want: str | None, g: Any) -> tuple[Any, str]:
        """A function on or to floats: exact where `floats` has a rule, else abstracted."""
        f = e.func
        params, result = FUNCTIONS[f]
        args = [self.expr(a, p if p in (INT16, INT32, REAL) else want, g)
                for p, a in zip(params, e.args, strict=True)]
        (x, t) = args[0]
        if f in ("INT_TO_REAL", "DINT_TO_REAL"):
            return floats.from_int(x), REAL
        if f in ("REAL_TO_INT", "REAL_TO_DINT"):
            if t != REAL:  # the argument was reported
                return wide(0), result
            bits = 16 if result == INT16 else 32
            v, fault = floats.to_int(x, bits)
            self.fault(g, fault)
            return v, result
        if t != REAL or any(ta != REAL for _, ta in args):
            self.unsupported(f"the function {f} on these types", e.pos, f)
            return (floats.const(0.0), REAL) if result == REAL else (wide(0), want or INT16)
        exact = floats.exact_function(f, x)
        if exact is not None:
            r, faults = exact
        else:  # abstracted: fresh, within what is known of the function
            key = f"{f}{SITE}{e.pos.line}:{e.pos.column}"
            self.abstract.ranges.setdefault(key, ("f64", 0, 0))
            self.abstract.note(f, e.pos)
            self.add_input(key, "f64")
            self.add_input(key + "!", "bool")
            r, fault = self.inp[key], self.inp[key + "!"]
            self.abstract.ranges.setdefault(key + "!", ("bool", 0, 1))
            self.facts += floats.abstract_function(f, [a for a, _ in args], r, fault)
            self.facts += floats.anchor_facts(f, x, r)
            for x0, r0 in self.applied.setdefault(f, []):  # earlier ones of this scan
                self.facts += floats.monotone_facts(f, x0, r0, x, r)
            self.applied[f].append((x, r))
            faults = [(fault, floats.FLOAT_INVALID)]
        for c, kind in faults:
            self.float_fault(g, c, kind)
        return r, REAL

    def store_real(self, ref: Ref, g: Any, v: Any, pos: A.Pos | None) -> None:
        """`%MFi := v`: rounded to a single in %MWi (low half) and %MWi+1 (`Ops.stf`)."""
        bits, over = floats.to_single(v)
        self.float_fault(g, over, floats.FLOAT_OVERFLOW)
        self.put_word(Ref("MW", ref.index), g, z3.Extract(15, 0, bits), pos)
        self.put_word(Ref("MW", ref.index + 1), g, z3.Extract(31, 16, bits), pos)

    def float_fault(self, g: Any, c: Any, kind: int) -> None:
        """%S18 and %SW17's bit `kind` where a float rule faulted (`Ops._float_fault`)."""
        self.fault(g, c)
        key = self.key_for(Ref("SW", floats.SW_FLOAT))
        self.mark_written(key, None)
        w = self.st[key]
        self.st[key] = z3.simplify(If(And(g, c), w | kind, w))
