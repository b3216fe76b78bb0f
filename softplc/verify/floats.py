"""Floats as the engine computes them, as z3 floating-point terms.

The engine (`compiler/values.py`, `twido/semantics.Ops`) computes float expressions in
Python floats, IEEE-754 double precision rounded to nearest-even, and stores them in %MF
as IEEE singles (`Ops.stf`: rounded to nearest-even; a finite value beyond the largest
single is +-inf with %S18 and %SW17's overflow bit). A %MF or %KF read is the single
widened exactly to a double. So: expressions are Float64 terms, `+ - *` z3's RNE
operations, `/` with `Ops.fdiv`'s rules, comparisons IEEE's (NaN unordered), stores
rounded to Float32 and put in the two %MW words, low word first [manual: %MDi / %MFi
overlay %MWi and %MWi+1]. The conversions follow `Ops._round` (REAL_TO_INT: floor(|x| +
0.5) in double, the sign of x; %S18 and 0 out of range or not finite), INT_TO_REAL is
exact. A NaN's bit pattern in the words is left to the solver (IEEE leaves it open):
any NaN, a sound over-approximation.

SIN, COS, TAN, ASIN, ACOS, ATAN, EXP, LN, LOG and EXPT have no solver theory: their value
is an abstraction (`abstract`), fresh where they run, within the function's true range
(|SIN| <= 1, 0 <= ACOS <= pi...; NaN in, NaN out), and %S18 where the engine's domain
errors may set it. Besides (`anchor_facts`, `monotone_facts`):
- the exact values C's math library gives at its anchor points [ISO/IEC 9899:1999
  Annex F.9 (IEC 60559 floating point): exp(+-0) = 1, log(1) = log10(1) = +0,
  sin/tan/asin/atan(+-0) = +-0, cos(+-0) = 1, acos(1) = +0]: CPython's `math` calls the
  C library for these (`Ops._dom`);
- monotony: EXP, LN, LOG, ATAN, ASIN non-decreasing and ACOS non-increasing on their
  domains, as the engine computes them (glibc's double functions, faithfully rounded:
  monotony is not promised by C, so it is checked on the engine, on adjacent doubles
  too: `tests/integration/test_verify_diff.py`): with the anchor, one application's
  value is on the anchor's side of its argument's (x >= 0 -> EXP(x) >= 1, LN(x) < 0 for
  0 < x < 1 ...), and two applications of one function in a scan are in the order of
  their arguments (x1 <= x2 -> f(x1) <= f(x2)).
"""

from __future__ import annotations

import math
from typing import Any

import z3

from softplc.twido.numeric import F32_MAX
from softplc.twido.semantics import FLOAT_DIV0, FLOAT_INVALID, FLOAT_OVERFLOW, SW_FLOAT
from softplc.verify.symbolic import WIDE

F64 = z3.Float64()
F32 = z3.Float32()
RNE = z3.RNE()
HALF_PI = math.pi / 2  # math.atan(inf), math.asin(1)
# the result ranges of the abstracted functions for a finite argument in their domain
BOUNDS = {"SIN": (-1.0, 1.0), "COS": (-1.0, 1.0), "ATAN": (-HALF_PI, HALF_PI),
          "ASIN": (-HALF_PI, HALF_PI), "ACOS": (0.0, math.pi), "EXP": (0.0, math.inf)}
ABSTRACTED = frozenset({"SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN", "EXP", "LN", "LOG",
                        "EXPT"})
#: f -> (a, f(a)), exact [C99 Annex F.9]; a zero argument gives the zero of its sign
#: where the value is a zero (sin, tan, asin, atan).
ANCHORS = {"EXP": (0.0, 1.0), "LN": (1.0, 0.0), "LOG": (1.0, 0.0), "COS": (0.0, 1.0),
           "ACOS": (1.0, 0.0), "SIN": (0.0, 0.0), "TAN": (0.0, 0.0), "ASIN": (0.0, 0.0),
           "ATAN": (0.0, 0.0)}
ODD_AT_ZERO = frozenset({"SIN", "TAN", "ASIN", "ATAN"})
#: f -> +1 (non-decreasing) or -1 (non-increasing) on its domain (`in_domain`)
MONOTONE = {"EXP": 1, "LN": 1, "LOG": 1, "ATAN": 1, "ASIN": 1, "ACOS": -1}
INT_RANGES = {16: (-32768, 32767), 32: (-2147483648, 2147483647)}


def const(v: float) -> Any:
    return z3.FPVal(v, F64)


def from_words(lo: Any, hi: Any) -> Any:
    """A %MF's value from its two 16-bit words (the single widened exactly)."""
    return z3.fpToFP(RNE, z3.fpBVToFP(z3.Concat(hi, lo), F32), F64)


def finite(x: Any) -> Any:
    return z3.Not(z3.Or(z3.fpIsNaN(x), z3.fpIsInf(x)))


def to_single(x: Any) -> tuple[Any, Any]:
    """`Ops.stf`: (the 32 bits stored, the overflow fault)."""
    over = z3.And(finite(x), z3.fpGT(z3.fpAbs(x), const(F32_MAX)))
    inf = z3.If(z3.fpIsNegative(x), z3.fpMinusInfinity(F32), z3.fpPlusInfinity(F32))
    return z3.fpToIEEEBV(z3.If(over, inf, z3.fpToFP(RNE, x, F32))), over


def compare(op: str, a: Any, b: Any) -> Any:
    return {"=": z3.fpEQ, "<>": lambda x, y: z3.Not(z3.fpEQ(x, y)), "<": z3.fpLT,
            "<=": z3.fpLEQ, ">": z3.fpGT, ">=": z3.fpGEQ}[op](a, b)


def binop(op: str, a: Any, b: Any) -> tuple[Any, list[tuple[Any, int]]]:
    """`a op b` in double; the faults (condition, %SW17 bit) `Ops.fdiv` raises."""
    if op == "+":
        return z3.fpAdd(RNE, a, b), []
    if op == "-":
        return z3.fpSub(RNE, a, b), []
    if op == "*":
        return z3.fpMul(RNE, a, b), []
    zero = z3.fpIsZero(b)
    invalid = z3.And(zero, z3.Or(z3.fpIsZero(a), z3.fpIsNaN(a)))
    div0 = z3.And(zero, z3.Not(invalid))
    neg = z3.Xor(z3.fpIsNegative(a), z3.fpIsNegative(b))
    inf = z3.If(neg, z3.fpMinusInfinity(F64), z3.fpPlusInfinity(F64))
    r = z3.If(invalid, z3.fpNaN(F64), z3.If(div0, inf, z3.fpDiv(RNE, a, b)))
    return r, [(invalid, FLOAT_INVALID), (div0, FLOAT_DIV0)]


def to_int(x: Any, bits: int) -> tuple[Any, Any]:
    """REAL_TO_INT / REAL_TO_DINT (`Ops._round`): (the WIDE-bit value, the fault)."""
    lo, hi = INT_RANGES[bits]
    mag = z3.fpRoundToIntegral(z3.RTN(), z3.fpAdd(RNE, z3.fpAbs(x), const(0.5)))
    r = z3.If(z3.fpLT(x, const(0.0)), z3.fpNeg(mag), mag)
    ok = z3.And(finite(x), z3.fpGEQ(r, const(float(lo))), z3.fpLEQ(r, const(float(hi))))
    v = z3.If(ok, z3.fpToSBV(z3.RTZ(), r, z3.BitVecSort(WIDE)), z3.BitVecVal(0, WIDE))
    return v, z3.Not(ok)


def from_int(v: Any) -> Any:
    """INT_TO_REAL / DINT_TO_REAL: exact (a double holds any 32-bit integer)."""
    return z3.fpSignedToFP(RNE, v, F64)


def exact_function(f: str, x: Any) -> tuple[Any, list[tuple[Any, int]]] | None:
    """The float functions with an exact rule (None: abstracted)."""
    if f == "ABS":
        return z3.fpAbs(x), []
    if f == "SQRT":  # math.sqrt: a ValueError below zero (not at -0.0)
        bad = z3.fpLT(x, const(0.0))
        return z3.If(bad, z3.fpNaN(F64), z3.fpSqrt(RNE, x)), [(bad, FLOAT_INVALID)]
    if f == "TRUNC":  # float(math.trunc(x)): a zero is +0.0
        t = z3.fpRoundToIntegral(z3.RTZ(), x)
        return z3.If(finite(x), z3.If(z3.fpIsZero(t), const(0.0), t), x), []
    if f == "DEG_TO_RAD":  # math.radians: x * (pi / 180), one rounding
        return z3.fpMul(RNE, x, const(math.pi / 180.0)), []
    if f == "RAD_TO_DEG":
        return z3.fpMul(RNE, x, const(180.0 / math.pi)), []
    return None


def abstract_function(f: str, args: list[Any], r: Any, fault: Any) -> list[Any]:
    """What is known of `f(args)` = `r` with the fault bit `fault` (both fresh): NaN in,
    NaN out; the true range on the domain; the domain errors math raises (ValueError,
    OverflowError: `Ops._dom`) the only faults."""
    x = args[0]
    nan_in = z3.Or(*[z3.fpIsNaN(a) for a in args])
    facts = [z3.Implies(nan_in, z3.And(z3.fpIsNaN(r), z3.Not(fault)))]
    if f in ("SIN", "COS", "TAN"):  # an infinite argument: ValueError
        facts.append(fault == z3.And(z3.fpIsInf(x), z3.Not(nan_in)))
        facts.append(z3.Implies(fault, z3.fpIsNaN(r)))
        facts.append(z3.Implies(finite(x), z3.Not(z3.fpIsNaN(r))))
    elif f in ("ASIN", "ACOS"):  # beyond [-1, 1]: ValueError
        bad = z3.fpGT(z3.fpAbs(x), const(1.0))
        facts += [fault == bad, z3.Implies(bad, z3.fpIsNaN(r))]
    elif f == "ATAN":
        facts.append(z3.Not(fault))
    elif f in ("LN", "LOG"):  # zero and below: ValueError; +inf -> +inf
        bad = z3.fpLEQ(x, const(0.0))
        facts += [fault == bad, z3.Implies(bad, z3.fpIsNaN(r)),
                  z3.Implies(z3.fpIsInf(x), z3.Not(bad) == z3.fpIsInf(r))]
    elif f == "EXP":  # overflow: OverflowError, +inf
        facts += [z3.Implies(fault, z3.fpIsInf(r)),
                  z3.Implies(z3.Not(nan_in), z3.Not(z3.fpIsNaN(r)))]
    if f in BOUNDS:
        lo, hi = BOUNDS[f]
        facts.append(z3.Implies(z3.And(finite(x), z3.Not(fault)),
                                z3.And(z3.fpGEQ(r, const(lo)), z3.fpLEQ(r, const(hi)))))
    return facts


def in_domain(f: str, x: Any) -> Any:
    """x is in the domain on which `MONOTONE[f]` holds (not NaN; LN, LOG: above 0; ASIN,
    ACOS: within [-1, 1])."""
    if f in ("LN", "LOG"):
        return z3.fpGT(x, const(0.0))
    if f in ("ASIN", "ACOS"):
        return z3.fpLEQ(z3.fpAbs(x), const(1.0))
    return z3.Not(z3.fpIsNaN(x))


def _ordered(sign: int, x1: Any, r1: Any, x2: Any, r2: Any) -> Any:
    """x1 <= x2 -> r1 <= r2 (sign +1) or r1 >= r2 (sign -1)."""
    return z3.Implies(z3.fpLEQ(x1, x2), z3.fpLEQ(r1, r2) if sign > 0 else z3.fpGEQ(r1, r2))


def anchor_facts(f: str, x: Any, r: Any) -> list[Any]:
    """One application `r` = f(x): its exact value at the anchor, and, for a monotone f,
    its value on the anchor's side."""
    if f not in ANCHORS:
        return []
    a, b = ANCHORS[f]
    at = z3.fpIsZero(x) if a == 0.0 else z3.fpEQ(x, const(a))
    exact = r == x if f in ODD_AT_ZERO else r == const(b)  # `==`: the same zero's sign
    facts = [z3.Implies(at, exact)]
    if f in MONOTONE:
        ok = in_domain(f, x)
        facts += [z3.Implies(ok, _ordered(MONOTONE[f], x, r, const(a), const(b))),
                  z3.Implies(ok, _ordered(MONOTONE[f], const(a), const(b), x, r))]
    return facts


def monotone_facts(f: str, x1: Any, r1: Any, x2: Any, r2: Any) -> list[Any]:
    """Two applications of a monotone f (in one scan): in the order of their arguments,
    both ways."""
    if f not in MONOTONE:
        return []
    both = z3.And(in_domain(f, x1), in_domain(f, x2))
    return [z3.Implies(both, _ordered(MONOTONE[f], x1, r1, x2, r2)),
            z3.Implies(both, _ordered(MONOTONE[f], x2, r2, x1, r1))]


FAULT_KINDS = (FLOAT_INVALID, FLOAT_DIV0, FLOAT_OVERFLOW)
SW17 = f"%SW{SW_FLOAT}"
