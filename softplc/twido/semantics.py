"""Instruction semantics: the one place that says what each Twido operation computes.

Compiled rungs call these helpers for anything that can overflow or fault; the helpers set
the system bits the way Twido documents: %S17 carry (last bit shifted out), %S18
arithmetic error (overflow, divide by zero, domain error, bad conversion; set by the
system, reset only by the program), %S20 index overflow. Tags as in the reference:
[sure] seen on a real Twido, [m221] checked on the M221, [manual] documented only.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable
from typing import Any

from softplc.twido.address import INT16, INT32, REAL
from softplc.twido.numeric import F32_MAX, bcd_decode, bcd_encode, wrap16, wrap32

S_CARRY, S_ARITH, S_INDEX = 17, 18, 20  # system bit numbers
# %SW17, the floating-point error word: which kind of fault set %S18; reset by the program
# [manual: TWD USE 10AE system words, quoted from memory: not found in the search corpora]
SW_FLOAT = 17
FLOAT_INVALID, FLOAT_DIV0, FLOAT_OVERFLOW = 1 << 0, 1 << 2, 1 << 3

# Function name -> (argument types, result type). "num" means int16/int32/real, result
# of the same type as the argument; "int" means int16 or int32.
FUNCTIONS: dict[str, tuple[tuple[str, ...], str]] = {
    "SQRT": (("num",), "same"), "ABS": (("num",), "same"),
    "SHL": (("int", INT16), "same"), "SHR": (("int", INT16), "same"),
    "ROL": (("int", INT16), "same"), "ROR": (("int", INT16), "same"),
    "NOT": (("int",), "same"),
    "TRUNC": ((REAL,), REAL),
    "LOG": ((REAL,), REAL), "LN": ((REAL,), REAL), "EXP": ((REAL,), REAL),
    "EXPT": ((REAL, REAL), REAL),
    "SIN": ((REAL,), REAL), "COS": ((REAL,), REAL), "TAN": ((REAL,), REAL),
    "ASIN": ((REAL,), REAL), "ACOS": ((REAL,), REAL), "ATAN": ((REAL,), REAL),
    "DEG_TO_RAD": ((REAL,), REAL), "RAD_TO_DEG": ((REAL,), REAL),
    "INT_TO_REAL": ((INT16,), REAL), "DINT_TO_REAL": ((INT32,), REAL),
    "REAL_TO_INT": ((REAL,), INT16), "REAL_TO_DINT": ((REAL,), INT32),
    "BCD_TO_INT": ((INT16,), INT16), "INT_TO_BCD": ((INT16,), INT16),
    "GRAY_TO_INT": ((INT16,), INT16),
    # TwidoSuite names of the BCD conversions (the M221 names above) [manual]
    "BTI": ((INT16,), INT16), "ITB": ((INT16,), INT16),
    # single / double word conversions [manual]: low word, high word, (low, high) -> %MD
    "LW": ((INT32,), INT16), "HW": ((INT32,), INT16), "CONCATW": ((INT16, INT16), INT32),
    # table functions: one argument, a table %MWi:L, %MDi:L or %MFi:L [manual]
    "SUM": (("table",), "element"), "MAX": (("table",), "element"),
    "MIN": (("table",), "element"), "MEAN": (("table",), REAL),
}


# Comparison blocks [ a OP b ]: the one table of what each operator means, as the Python
# operator compiled code uses and as the function of the same meaning the ladder view and
# the debugger call (the two views below are derived from it).
_COMPARISONS: dict[str, tuple[str, Callable[[object, object], bool]]] = {
    "=": ("==", operator.eq), "<>": ("!=", operator.ne), ">": (">", operator.gt),
    ">=": (">=", operator.ge), "<": ("<", operator.lt), "<=": ("<=", operator.le)}
COMPARE: dict[str, Callable[[object, object], bool]] = {
    op: fn for op, (_py, fn) in _COMPARISONS.items()}
COMPARE_PY: dict[str, str] = {op: py for op, (py, _fn) in _COMPARISONS.items()}


def _tdiv(a: int, b: int) -> int:
    """Integer division truncating towards zero, as the Twido (and C) does [manual]."""
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b >= 0) else -q


class Ops:
    """Helpers bound to one memory image's system bits (`s`)."""

    def __init__(self, s: list[bool], sw: Any = None):
        self.s = s
        self.sw = sw if sw is not None else [0] * (SW_FLOAT + 1)  # system words

    def _float_fault(self, kind: int) -> None:
        """A floating-point fault: %S18 and its kind in %SW17 [manual]."""
        self.s[S_ARITH] = True
        self.sw[SW_FLOAT] |= kind

    @classmethod
    def helper_names(cls) -> tuple[str, ...]:
        """Names of the helpers compiled code may call (bound as `_<name>`)."""
        return tuple(name for name in dir(cls)
                     if not name.startswith("_") and name not in ("table", "helper_names"))

    def table(self) -> dict[str, Callable]:
        """Name -> helper, bound into compiled code's namespace."""
        return {name: getattr(self, name) for name in self.helper_names()}

    # -- overflow bookkeeping ---------------------------------------------------------------
    def _chk16(self, v: int) -> int:
        if -32768 <= v <= 32767:
            return v
        self.s[S_ARITH] = True
        return wrap16(v)

    def _chk32(self, v: int) -> int:
        if -2147483648 <= v <= 2147483647:
            return v
        self.s[S_ARITH] = True
        return wrap32(v)


    # -- 16-bit word arithmetic (%S18 on overflow; the result wraps) [sure: %S18] --------------
    def add16(self, a: int, b: int) -> int:
        return self._chk16(a + b)

    def sub16(self, a: int, b: int) -> int:
        return self._chk16(a - b)

    def mul16(self, a: int, b: int) -> int:
        return self._chk16(a * b)

    def div16(self, a: int, b: int) -> int:
        if b == 0:  # divide by zero: %S18, result 0 [manual: "result not significant"]
            self.s[S_ARITH] = True
            return 0
        return self._chk16(_tdiv(a, b))  # -32768 / -1 overflows

    def rem16(self, a: int, b: int) -> int:
        if b == 0:
            self.s[S_ARITH] = True
            return 0
        return a - _tdiv(a, b) * b  # sign of the dividend

    def neg16(self, a: int) -> int:
        return self._chk16(-a)

    def abs16(self, a: int) -> int:
        return self._chk16(abs(a))

    def sqrt16(self, a: int) -> int:
        if a < 0:
            self.s[S_ARITH] = True
            return 0
        return math.isqrt(a)

    def narrow16(self, a: int) -> int:
        """A 32-bit value stored in a word: %S18 if it does not fit."""
        return self._chk16(a)

    # -- 32-bit ------------------------------------------------------------------------------
    def add32(self, a: int, b: int) -> int:
        return self._chk32(a + b)

    def sub32(self, a: int, b: int) -> int:
        return self._chk32(a - b)

    def mul32(self, a: int, b: int) -> int:
        return self._chk32(a * b)

    def div32(self, a: int, b: int) -> int:
        if b == 0:
            self.s[S_ARITH] = True
            return 0
        return self._chk32(_tdiv(a, b))

    def rem32(self, a: int, b: int) -> int:
        return self.rem16(a, b)

    def neg32(self, a: int) -> int:
        return self._chk32(-a)

    def abs32(self, a: int) -> int:
        return self._chk32(abs(a))

    def sqrt32(self, a: int) -> int:
        return self.sqrt16(a)

    def narrow32(self, a: int) -> int:
        return self._chk32(a)

    # -- shifts and rotations: %S17 = last bit shifted out [sure] ----------------------------
    def _shift(self, a: int, n: int, bits: int, kind: str) -> int:
        mask = (1 << bits) - 1
        u = a & mask
        n = max(0, n)
        if n == 0:
            return a
        if kind == "SHL":
            self.s[S_CARRY] = n <= bits and bool(u >> (bits - n) & 1)
            u = (u << n) & mask
        elif kind == "SHR":  # logical shift: zeros come in on the left [manual]
            self.s[S_CARRY] = n <= bits and bool(u >> (n - 1) & 1)
            u >>= n
        elif kind == "ROL":
            n %= bits
            u = ((u << n) | (u >> (bits - n))) & mask
            self.s[S_CARRY] = bool(u & 1)
        else:  # ROR
            n %= bits
            u = ((u >> n) | (u << (bits - n))) & mask
            self.s[S_CARRY] = bool(u >> (bits - 1) & 1)
        return u - (1 << bits) if u >> (bits - 1) else u

    def shl16(self, a: int, n: int) -> int:
        return self._shift(a, n, 16, "SHL")

    def shr16(self, a: int, n: int) -> int:
        return self._shift(a, n, 16, "SHR")

    def rol16(self, a: int, n: int) -> int:
        return self._shift(a, n, 16, "ROL")

    def ror16(self, a: int, n: int) -> int:
        return self._shift(a, n, 16, "ROR")

    def shl32(self, a: int, n: int) -> int:
        return self._shift(a, n, 32, "SHL")

    def shr32(self, a: int, n: int) -> int:
        return self._shift(a, n, 32, "SHR")

    def rol32(self, a: int, n: int) -> int:
        return self._shift(a, n, 32, "ROL")

    def ror32(self, a: int, n: int) -> int:
        return self._shift(a, n, 32, "ROR")

    # -- floats (IEEE single on store; %S18 on domain errors) [manual] -----------------------
    def fdiv(self, a: float, b: float) -> float:
        if b == 0:
            if a == 0 or a != a:
                self._float_fault(FLOAT_INVALID)
                return math.nan
            self._float_fault(FLOAT_DIV0)
            return math.copysign(math.inf, a) * math.copysign(1.0, b)
        return a / b

    def fmul(self, a: float, b: float) -> float:
        try:
            return a * b
        except OverflowError:  # pragma: no cover - floats give inf, not an error
            self._float_fault(FLOAT_OVERFLOW)
            return math.inf

    def _dom(self, f: Callable[[float], float], x: float) -> float:
        try:
            r = f(x)
        except ValueError:  # outside the domain: sqrt(-1), ln(0)...
            self._float_fault(FLOAT_INVALID)
            return math.nan
        except OverflowError:  # exp(1000)
            self._float_fault(FLOAT_OVERFLOW)
            return math.inf
        return r

    def fsqrt(self, x: float) -> float:
        return self._dom(math.sqrt, x)

    def fabs(self, x: float) -> float:
        return abs(x)

    def ftrunc(self, x: float) -> float:
        return float(math.trunc(x)) if math.isfinite(x) else x

    def flog(self, x: float) -> float:
        return self._dom(math.log10, x)

    def fln(self, x: float) -> float:
        return self._dom(math.log, x)

    def fexp(self, x: float) -> float:
        return self._dom(math.exp, x)

    def fexpt(self, x: float, y: float) -> float:
        try:
            r = x ** y
        except ZeroDivisionError:  # 0 ** negative
            self._float_fault(FLOAT_DIV0)
            return math.nan
        except OverflowError:
            self._float_fault(FLOAT_OVERFLOW)
            return math.nan
        if isinstance(r, complex):
            self._float_fault(FLOAT_INVALID)
            return math.nan
        return r

    def fsin(self, x: float) -> float:
        return self._dom(math.sin, x)

    def fcos(self, x: float) -> float:
        return self._dom(math.cos, x)

    def ftan(self, x: float) -> float:
        return self._dom(math.tan, x)

    def fasin(self, x: float) -> float:
        return self._dom(math.asin, x)

    def facos(self, x: float) -> float:
        return self._dom(math.acos, x)

    def fatan(self, x: float) -> float:
        return self._dom(math.atan, x)

    def fdeg_to_rad(self, x: float) -> float:
        return math.radians(x)

    def frad_to_deg(self, x: float) -> float:
        return math.degrees(x)

    # -- conversions -------------------------------------------------------------------------
    def _round(self, x: float, lo: int, hi: int) -> int:
        """REAL_TO_INT/DINT round to nearest, halves away from zero [manual]; %S18 out of range."""
        if not math.isfinite(x):
            self.s[S_ARITH] = True
            return 0
        r = int(math.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)
        if lo <= r <= hi:
            return r
        self.s[S_ARITH] = True
        return 0

    def real_to_int(self, x: float) -> int:
        return self._round(x, -32768, 32767)

    def real_to_dint(self, x: float) -> int:
        return self._round(x, -2147483648, 2147483647)

    # -- BCD and Gray codes [manual] -------------------------------------------------------
    def bcd_to_int(self, w: int) -> int:
        """A BCD word (#0000..#9999) to its value; a nibble above 9 is %S18, result 0."""
        v = bcd_decode(w)
        if v is None:
            self.s[S_ARITH] = True
            return 0
        return v

    def int_to_bcd(self, v: int) -> int:
        """0..9999 to a BCD word; out of range is %S18, result 0."""
        u = bcd_encode(v)
        if u is None:
            self.s[S_ARITH] = True
            return 0
        return u

    bti = bcd_to_int  # TwidoSuite's name [manual]
    itb = int_to_bcd

    # -- single / double words [manual] ------------------------------------------------------
    @staticmethod
    def lw(d: int) -> int:
        """Low word of a double word."""
        return wrap16(d)

    @staticmethod
    def hw(d: int) -> int:
        """High word of a double word."""
        return wrap16(d >> 16)

    @staticmethod
    def concatw(low: int, high: int) -> int:
        """Two words into a double word: the first argument is the low word [manual, from
        memory: unverified]."""
        return wrap32(((high & 0xFFFF) << 16) | (low & 0xFFFF))

    def gray_to_int(self, w: int) -> int:
        u = w & 0xFFFF
        v = u
        while u:
            u >>= 1
            v ^= u
        return wrap16(v)

    # -- table functions: SUM MAX MIN over a table, MEAN of a float table [manual] ----------
    def tsum16(self, values: list[int]) -> int:
        return self._chk16(sum(values))

    def tsum32(self, values: list[int]) -> int:
        return self._chk32(sum(values))

    def tsumf(self, values: list[float]) -> float:
        return float(sum(values))

    def tmax(self, values: list) -> int | float:
        return max(values)

    def tmin(self, values: list) -> int | float:
        return min(values)

    def tmean(self, values: list[float]) -> float:
        return float(sum(values)) / len(values)

    # -- bit strings -------------------------------------------------------------------------
    @staticmethod
    def _bits_value(bits: list[bool], start: int, n: int) -> int:
        """%Mi:L as a number: bit i is bit 0 [manual]."""
        v = 0
        for k in range(n):
            if bits[start + k]:
                v |= 1 << k
        return v

    def bitstr16(self, bits: list[bool], start: int, n: int) -> int:
        return wrap16(self._bits_value(bits, start, n))

    def bitstr32(self, bits: list[bool], start: int, n: int) -> int:
        return wrap32(self._bits_value(bits, start, n))

    # -- stores ------------------------------------------------------------------------------
    def stf(self, view: memoryview, k: int, v: float) -> None:
        """Store a float in an IEEE single: a finite value out of range -> +-inf, %S18 and
        %SW17 overflow (an infinity already computed was reported where it arose)."""
        if v != v or -F32_MAX <= v <= F32_MAX or math.isinf(v):
            view[k] = v
        else:
            self._float_fault(FLOAT_OVERFLOW)
            view[k] = math.copysign(math.inf, v)

    def ix(self, base: int, offset: int, count: int) -> int:
        """Indexed address base[offset]: outside the object range -> %S20 and the object is
        processed as if the index were 0 [manual]."""
        i = base + offset
        if 0 <= i < count:
            return i
        self.s[S_INDEX] = True
        return base


# -- the integer rules over any value domain ---------------------------------------------------
# What a word operation computes, written once over a value domain `D` (`IntDomain`: Python
# ints; the verifier's `verify.symbolic.Z3Domain`: solver terms on wide bit-vectors): the
# exact result, then the Twido rule (%S18 and wrap-around out of range; divide by zero gives
# 0 and %S18; truncation towards zero; the remainder takes the dividend's sign) [manual].
# `Ops` keeps its own straight-line int code for the engine's speed;
# tests/integration/test_verify_diff.py checks `Ops` against these rules value for value.
WORD_RANGE = {16: (-32768, 32767), 32: (-2147483648, 2147483647)}


class IntDomain:
    """Concrete values: Python ints and bools."""

    @staticmethod
    def ite(c: Any, a: Any, b: Any) -> Any:
        return a if c else b

    @staticmethod
    def and_(a: Any, b: Any) -> Any:
        return a and b

    @staticmethod
    def or_(a: Any, b: Any) -> Any:
        return a or b

    @staticmethod
    def not_(a: Any) -> Any:
        return not a

    @staticmethod
    def wrap(v: int, bits: int) -> int:
        return wrap16(v) if bits == 16 else wrap32(v)

    @staticmethod
    def tdiv(a: int, b: int) -> int:
        return _tdiv(a, b)

    # -- what the function blocks' rules add (softplc/blocks/): non-negative fields of
    # their own widths (16-bit words, a timer's elapsed time), 0/1 bits
    @staticmethod
    def bit(a: Any) -> int:
        """A bit as a block stores it."""
        return 1 if a else 0

    @staticmethod
    def ne(a: Any, b: Any) -> bool:
        return bool(a) != bool(b)

    @staticmethod
    def any_(terms: list[Any]) -> bool:
        return any(terms)

    @staticmethod
    def resize(v: int, like: Any) -> int:
        """`v` in the width of `like` (an int has every width)."""
        return v

    @staticmethod
    def udiv(a: int, b: int) -> int:
        return a // b

    @staticmethod
    def lshr(a: int, n: int) -> int:
        return a >> n


def checked(D: Any, v: Any, bits: int) -> tuple[Any, Any]:
    """(value, fault): `v` stored in `bits` bits, wrapped with %S18 when it does not fit."""
    lo, hi = WORD_RANGE[bits]
    ok = D.and_(v >= lo, v <= hi)
    return D.ite(ok, v, D.wrap(v, bits)), D.not_(ok)


# IL operator -> the operation names `arith` and `Ops` use (compiler and verifier read it)
ARITH_OPS = {"+": "add", "-": "sub", "*": "mul", "/": "div", "REM": "rem"}


def arith(D: Any, op: str, a: Any, b: Any, bits: int) -> tuple[Any, Any]:
    """(value, fault) of `a op b` (op: add sub mul div rem) on `bits`-bit words."""
    if op in ("add", "sub", "mul"):
        exact = a + b if op == "add" else a - b if op == "sub" else a * b
        return checked(D, exact, bits)
    zero = b == 0
    q = D.tdiv(a, D.ite(zero, 1, b))
    if op == "div":
        v, fault = checked(D, q, bits)  # -32768 / -1 overflows
    else:
        v, fault = a - q * b, False  # the sign of the dividend
    return D.ite(zero, 0, v), D.or_(zero, fault)


def negate(D: Any, a: Any, bits: int) -> tuple[Any, Any]:
    return checked(D, -a, bits)


def absolute(D: Any, a: Any, bits: int) -> tuple[Any, Any]:
    return checked(D, D.ite(a < 0, -a, a), bits)


# -- inline forms for compiled code -------------------------------------------------------------
# The checked word arithmetic of `Ops` (add16 .. narrow32, div16/div32) as one Python
# expression, so that a word line makes no call on its common path (issue 26): the exact
# value goes into a fresh local `v` of the generated function and is kept when it lies in
# WORD_RANGE; else the rare path calls `Ops.narrow16/narrow32` (%S18 and wrap, as every
# checked helper). A zero divisor calls `Ops.div16/div32(0, 0)` (%S18, result 0).
# `int(a / b)` truncates towards zero exactly: for |a|, |b| <= 2**31 the float quotient
# (correctly rounded, 53 bits) never rounds across an integer, since a non-integer quotient
# is at least 1/|b| from one, a relative gap of at least 2**-31. The operands are evaluated
# in order, a then b (their helpers may set %S17). tests/unit/test_inline_arith.py checks each
# form against the `Ops` helper value for value, %S18 included.
INLINE_QUOTIENT = "int({n} / {d})"
INLINE_EXACT = {"add": "{a} + {b}", "sub": "{a} - {b}", "mul": "{a} * {b}", "neg": "-{a}",
                "narrow": "{a}",
                # n, d: locals holding the dividend (when its code is not a plain read) and
                # the divisor; `(n := a) is None` is never true, it only evaluates a first
                "div": f"({INLINE_QUOTIENT} if ({{first}}({{d}} := {{b}})) else {{div}}(0, 0))"}


def inline_checked(op: str, bits: int, a: str, b: str = "", *, v: str, narrow: str,
                   div: str = "", d: str = "", n: str = "") -> str:
    """Python expression of `op` (a key of INLINE_EXACT) on `bits`-bit words: operand codes
    `a`, `b`; `v` a fresh local for the value; `narrow`, `div` the bound names of
    `Ops.narrow<bits>` and `Ops.div<bits>`; for "div", `d` a fresh local for the divisor and
    `n` one for the dividend, or "" when `a` has no side effect (a plain read, a literal)."""
    lo, hi = WORD_RANGE[bits]
    first = f"({n} := {a}) is None or " if n else ""
    exact = INLINE_EXACT[op].format(a=a, b=b, d=d, n=n or a, first=first, div=div)
    return f"({v} if {lo} <= ({v} := {exact}) <= {hi} else {narrow}({v}))"


# Word functions over a value domain (`Ops` keeps its own int code; the hypothesis test in
# tests/integration/test_verify_diff.py checks these against it value for value).
def shift(D: Any, kind: str, a: Any, n: Any, bits: int) -> tuple[Any, Any, Any]:
    """(value, carry, moved) of SHL SHR ROL ROR `a` by `n` on `bits`-bit words: carry is
    the new %S17 (the last bit shifted out; for a rotation the bit that went round), moved
    whether anything happens (n <= 0 keeps `a` and %S17). Every shift count used is
    within 0..bits, so the rule is safe for any `n` in both domains."""
    mask = (1 << bits) - 1
    u = a & mask
    moved = n > 0
    if kind in ("SHL", "SHR"):
        big = n > bits  # everything shifted out, the carry too
        k = D.ite(D.or_(big, D.not_(moved)), 1, n)
        if kind == "SHL":
            carry, r = (u >> (bits - k)) & 1, (u << k) & mask
        else:  # logical: zeros come in on the left [manual]
            carry, r = (u >> (k - 1)) & 1, u >> k
        carry, r = D.ite(big, 0, carry), D.ite(big, 0, r)
    else:
        k = D.ite(moved, n % bits, 0)
        if kind == "ROL":
            r = ((u << k) | (u >> (bits - k))) & mask
            carry = r & 1
        else:
            r = ((u >> k) | (u << (bits - k))) & mask
            carry = (r >> (bits - 1)) & 1
    return D.ite(moved, D.wrap(r, bits), a), carry, moved


def gray_to_int(D: Any, w: Any) -> Any:
    """A Gray-coded word to its value: the XOR of every right shift of it."""
    u = w & 0xFFFF
    v = u
    for s in range(1, 16):
        v = v ^ (u >> s)
    return D.wrap(v, 16)


def bcd_to_int(D: Any, w: Any) -> tuple[Any, Any]:
    """(value, fault) of a BCD word: a nibble above 9 faults, value 0."""
    u = w & 0xFFFF
    digits = [(u >> s) & 0xF for s in (12, 8, 4, 0)]
    bad = False
    v: Any = 0
    for d in digits:
        bad = D.or_(bad, d > 9)
        v = v * 10 + d
    return D.ite(bad, 0, v), bad


def int_to_bcd(D: Any, v: Any) -> tuple[Any, Any]:
    """(value, fault) of 0..9999 as a BCD word (signed 16-bit): out of range faults, 0."""
    ok = D.and_(v >= 0, v <= 9999)
    x = D.ite(ok, v, 0)
    u: Any = 0
    for s in (12, 8, 4, 0):
        p = 10 ** (s // 4)
        u = u | ((D.tdiv(x, p) - D.tdiv(x, p * 10) * 10) << s)
    return D.ite(ok, D.wrap(u, 16), 0), D.not_(ok)


def low_word(D: Any, d: Any) -> Any:
    return D.wrap(d, 16)


def high_word(D: Any, d: Any) -> Any:
    return D.wrap(d >> 16, 16)


def concat_words(D: Any, low: Any, high: Any) -> Any:
    """Two words into a double word, the first argument the low word (as `Ops.concatw`)."""
    return D.wrap(((high & 0xFFFF) << 16) | (low & 0xFFFF), 32)


def int_sqrt(D: Any, a: Any, bits: int) -> tuple[Any, Any]:
    """(value, fault) of the integer SQRT: the root rounded down, bit by bit from the top
    (exact: each square fits twice the word's width); a negative argument faults, 0."""
    r: Any = 0
    for b in reversed(range(bits // 2)):
        cand = r | (1 << b)
        r = D.ite(cand * cand <= a, cand, r)
    neg = a < 0
    return D.ite(neg, 0, r), neg
