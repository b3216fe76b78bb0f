"""What value an object takes from a host or a test: one check for every way in (the
access port's front-ends and `plc[...] = value`). Below the PLC facade and the port."""

from __future__ import annotations

import math
from typing import Any

from softplc.access.errors import AccessError
from softplc.runtime.blocks import MAX_VALUE
from softplc.twido import catalog
from softplc.twido.address import BLOCK_FIELDS, Ref
from softplc.twido.numeric import F32_MAX

# Value ranges accepted, per value type.
INT16_RANGE = (-32768, 65535)  # unsigned 16-bit too, as a Modbus host or hex entry gives it
INT32_RANGE = (-(2 ** 31), 2 ** 32 - 1)
# %TMi.P / %Ci.P: what the program's store clamps to (docs/twido.md#function-blocks: presets
# 0-9999), so a host cannot write a preset the program could never hold.
PRESET_RANGE = (0, MAX_VALUE)


def check_value(ref: Ref, value: Any) -> int | float:
    """A value for `ref` of its type, or an AccessError saying what fits."""
    if isinstance(value, str):
        try:
            value = float(value) if ref.type == "real" else int(value, 0)
        except ValueError:
            raise AccessError(f"{ref.label}: {value!r} is not a number") from None
    if ref.type == "bool":
        if value in (0, 1) and not isinstance(value, float):
            return int(value)
        raise AccessError(f"{ref.label} is a bit: value 0 or 1, not {value!r}")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise AccessError(f"{ref.label}: expected a number, not {value!r}")
    if ref.type == "real":
        if not (math.isfinite(value) and abs(value) <= F32_MAX):
            raise AccessError(f"{ref.label}: {value!r} does not fit a 32-bit float")
        return float(value)
    if isinstance(value, float):
        if not value.is_integer():
            raise AccessError(f"{ref.label} is an integer object: {value!r} is not whole")
        value = int(value)
    # other block words are plain words (%VFCi.S0 up to 65535)
    preset = ref.kind in BLOCK_FIELDS and ref.field == "P" \
        and catalog.family(ref.kind).clamp_preset
    lo, hi = PRESET_RANGE if preset else INT32_RANGE if ref.type == "int32" else INT16_RANGE
    if not lo <= value <= hi:
        why = "a preset the program can hold" if preset else "does not fit"
        raise AccessError(f"{ref.label}: {value} is out of range {lo}..{hi} ({why})")
    return value
