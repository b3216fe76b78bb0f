"""Solver terms for the verifier: the value domain `semantics` rules are written over.

Words live in the model state as 16-bit bit-vectors (32-bit for %MD halves joined), and are
computed on `WIDE`-bit signed bit-vectors so that the exact result of + - * on two 32-bit
values exists before the Twido rule (`semantics.checked`) wraps it. Bits are z3 Booleans.
"""

from __future__ import annotations

import math
import struct
from typing import Any

import z3
from z3 import z3core
from z3.z3 import _to_expr_ref

WIDE = 72  # > 2 * 32 bits + sign: any product of two double words is exact


# ---- the model's constructors ------------------------------------------------------------
# z3.And / Or / Not / If first coerce their arguments (a sort asked of each, casts, checks:
# some ten API calls each); the model builds tens of thousands of terms per requirement
# from arguments that are already terms of the right sort. These make the same call to
# the C API (the same term: z3 shares equal terms) without that, about five times faster;
# anything else (a Python int, a probe, differing sorts) goes to z3's own function.


def _asts(args: tuple[Any, ...], keep: list[Any]) -> Any:
    """The C array of Boolean `args` (Python bools made terms, kept alive in `keep`), or
    None if one is neither or belongs to another context than z3's main one (the C API
    does not check: z3's own function says why)."""
    arr = (z3.Ast * len(args))()
    ctx = z3.main_ctx()
    for i, a in enumerate(args):
        if isinstance(a, bool):
            a = z3.BoolVal(a)
            keep.append(a)
        elif not isinstance(a, z3.BoolRef) or a.ctx is not ctx:
            return None
        arr[i] = a.ast
    return arr


def _nary(mk: Any, theirs: Any, args: tuple[Any, ...]) -> Any:
    """z3.And or z3.Or (`theirs`) of `args` (also of one list) by the C API's `mk`."""
    if len(args) == 1 and isinstance(args[0], (list, tuple)):
        args = tuple(args[0])
    keep: list[Any] = []
    arr = _asts(args, keep) if args else None
    if arr is None:
        return theirs(*args)
    ctx = z3.main_ctx()
    return z3.BoolRef(mk(ctx.ref(), len(args), arr), ctx)


def And(*args: Any) -> Any:
    """z3.And (also of one list)."""
    return _nary(z3core.Z3_mk_and, z3.And, args)


def Or(*args: Any) -> Any:
    """z3.Or (also of one list)."""
    return _nary(z3core.Z3_mk_or, z3.Or, args)


def Not(a: Any) -> Any:
    """z3.Not."""
    if not isinstance(a, z3.BoolRef):
        return z3.Not(a)
    return z3.BoolRef(z3core.Z3_mk_not(a.ctx.ref(), a.ast), a.ctx)


def If(c: Any, a: Any, b: Any) -> Any:
    """z3.If: for a Boolean term `c` and two terms of one sort, straight to the C API
    (which checks the sorts: differing ones go to z3.If, which says why)."""
    if not (isinstance(c, z3.BoolRef) and isinstance(a, z3.ExprRef)
            and isinstance(b, z3.ExprRef) and a.ctx is c.ctx and b.ctx is c.ctx):
        return z3.If(c, a, b)
    ctx = c.ctx
    try:
        t = z3core.Z3_mk_ite(ctx.ref(), c.ast, a.ast, b.ast)
    except z3.Z3Exception:
        return z3.If(c, a, b)
    return z3.BoolRef(t, ctx) if isinstance(a, z3.BoolRef) else _to_expr_ref(t, ctx)


class Z3Domain:
    """`semantics.IntDomain`'s operations on z3 terms."""

    @staticmethod
    def ite(c: Any, a: Any, b: Any) -> Any:
        c = as_bool(c)
        if z3.is_true(c):
            return wide(a)
        if z3.is_false(c):
            return wide(b)
        return If(c, wide(a), wide(b))

    @staticmethod
    def and_(a: Any, b: Any) -> Any:
        return And(as_bool(a), as_bool(b))

    @staticmethod
    def or_(a: Any, b: Any) -> Any:
        return Or(as_bool(a), as_bool(b))

    @staticmethod
    def not_(a: Any) -> Any:
        return Not(as_bool(a))

    @staticmethod
    def wrap(v: Any, bits: int) -> Any:
        return z3.SignExt(WIDE - bits, z3.Extract(bits - 1, 0, v))

    @staticmethod
    def tdiv(a: Any, b: Any) -> Any:
        return a / b  # bvsdiv truncates towards zero, as the Twido does


class Z3State:
    """The value domain of the function blocks' rules (softplc/blocks/) on solver terms in
    the state's own sorts: words as 16-bit bit-vectors, a timer's elapsed time in its
    width, bits as Booleans; a Python int takes the sort of the term it meets."""

    @staticmethod
    def ite(c: Any, a: Any, b: Any) -> Any:
        c = as_bool(c)
        if z3.is_true(c):
            return a
        if z3.is_false(c):
            return b
        return If(c, a, b)

    and_, or_, not_ = Z3Domain.and_, Z3Domain.or_, Z3Domain.not_

    @staticmethod
    def bit(a: Any) -> Any:
        return as_bool(a)

    @staticmethod
    def ne(a: Any, b: Any) -> Any:
        return as_bool(a) != as_bool(b)

    @staticmethod
    def any_(terms: list[Any]) -> Any:
        return Or([as_bool(t) for t in terms]) if terms else z3.BoolVal(False)

    @staticmethod
    def resize(v: Any, like: Any) -> Any:
        """`v` (non-negative) zero-extended or cut to the width of `like`."""
        if isinstance(v, int) or not z3.is_bv(like):
            return v
        n, m = v.size(), like.size()
        return v if n == m else z3.ZeroExt(m - n, v) if m > n else z3.Extract(m - 1, 0, v)

    @staticmethod
    def udiv(a: Any, b: Any) -> Any:
        return z3.UDiv(a, b)

    @staticmethod
    def lshr(a: Any, n: Any) -> Any:
        return z3.LShR(a, n)


def as_bool(v: Any) -> Any:
    if isinstance(v, bool):
        return z3.BoolVal(v)
    if isinstance(v, int):
        return z3.BoolVal(v != 0)
    if z3.is_bv(v):
        return v != 0
    return v


def wide(v: Any) -> Any:
    """A value as a WIDE-bit signed bit-vector."""
    if isinstance(v, (int, bool)):
        return z3.BitVecVal(int(v), WIDE)
    if z3.is_bool(v):
        return If(v, z3.BitVecVal(1, WIDE), z3.BitVecVal(0, WIDE))
    n = v.size()
    return v if n == WIDE else z3.SignExt(WIDE - n, v)


def narrow(v: Any, bits: int) -> Any:
    """The low `bits` bits of a wide value (the caller checked it fits, or wants the wrap)."""
    return z3.simplify(z3.Extract(bits - 1, 0, wide(v)))


def value_of(model: z3.ModelRef, term: Any) -> int | float:
    """A term's value in a solver model: 0/1 for bits, signed ints for words, a float
    for a float term (a NaN as NaN: its IEEE bits are left open by z3)."""
    v = model.eval(term, model_completion=True)
    if z3.is_bool(v):
        return 1 if z3.is_true(v) else 0
    if z3.is_bv_value(v):
        return v.as_signed_long()
    if z3.is_fp_value(v) and v.isNaN():
        return math.nan
    if z3.is_fp(v):  # a float (%MF read, an abstracted function's value): its double
        v = z3.fpToFP(z3.RNE(), v, z3.Float64())  # exact: a single widened
        bits = model.eval(z3.fpToIEEEBV(v), model_completion=True).as_long()
        return struct.unpack("<d", bits.to_bytes(8, "little"))[0]
    return int(str(v))


def substitute_all(terms: dict[str, Any], pairs: list[tuple[Any, Any]]) -> dict[str, Any]:
    """`terms` with each pair's variable replaced by its term, in one substitution (what
    the terms share is done once: they are the arguments of one application of a function
    symbol); simplified where a value, not a variable, went in."""
    keys = list(terms)
    pack = z3.Function("scan@", *[terms[k].sort() for k in keys], z3.BoolSort())
    out = z3.substitute(pack(*[terms[k] for k in keys]), *pairs)
    if not all(z3.is_const(t) and t.decl().kind() == z3.Z3_OP_UNINTERPRETED
               for _, t in pairs):
        out = z3.simplify(out)  # the arguments, in one call
    return dict(zip(keys, out.children(), strict=True))
