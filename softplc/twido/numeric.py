"""Twido number formats: 16/32-bit two's complement wrap and IEEE single rounding.

The one place both the instruction semantics (`semantics.py`) and the memory image
(`runtime/memory.py`) take them from.
"""

from __future__ import annotations

import math

F32_MAX = 3.4028234663852886e38  # largest finite IEEE single


def wrap16(v: int) -> int:
    """`v` as a signed 16-bit word (two's complement wrap)."""
    return ((int(v) + 0x8000) & 0xFFFF) - 0x8000


def wrap32(v: int) -> int:
    """`v` as a signed 32-bit double word (two's complement wrap)."""
    return ((int(v) + 0x80000000) & 0xFFFFFFFF) - 0x80000000


def to_f32(v: float) -> float:
    """Clamp a Python float to what an IEEE single can hold (overflow -> +-inf)."""
    v = float(v)
    if v != v or -F32_MAX <= v <= F32_MAX:
        return v
    return math.copysign(math.inf, v)


def bcd_decode(w: int) -> int | None:
    """A BCD word (16#0000..16#9999) -> its value; None if a nibble is above 9."""
    u, v = w & 0xFFFF, 0
    for shift in (12, 8, 4, 0):
        d = (u >> shift) & 0xF
        if d > 9:
            return None
        v = v * 10 + d
    return v


def bcd_encode(v: int) -> int | None:
    """0..9999 -> its BCD word (signed 16-bit); None out of range."""
    if not 0 <= v <= 9999:
        return None
    return wrap16(int(str(int(v)), 16))  # the decimal digits read as hex digits: 1234 -> 16#1234
