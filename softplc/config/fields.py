"""Field types of the configuration schema, shared by `softplc.config`, the section models of
`softplc.config.models` and the devices' `Options`: durations with a unit, bounded numbers,
numbered table keys, and `Section` (a strict table: unknown keys refused)."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, ValidationInfo

from softplc.errors import ConfigError
from softplc.twido.profile import DEFAULT_PROFILE, Profile

_DUR = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(us|ms|s|min)?\s*$", re.I)
_UNIT_S = {"us": 1e-6, "ms": 1e-3, "s": 1.0, "min": 60.0}
MAX_DURATION_S = 86400.0  # a day: longer is a typo, and keeps every duration finite in code


def _parse_duration(value: Any) -> float:
    """'10ms', '1.5s', '1min', '200us' -> seconds (ValueError with a hint otherwise)."""
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise ValueError("expected a duration string with a unit, like \"10ms\" or \"1s\"")
    m = _DUR.match(str(value))
    if m and not m.group(2):
        raise ValueError(f"a bare number is ambiguous: write the unit, e.g. \"{value}ms\" or "
                         f"\"{value}s\"")
    if not m:
        raise ValueError("not a duration like \"10ms\", \"1s\", \"1min\"")
    secs = float(m.group(1)) * _UNIT_S[m.group(2).lower()]
    if not secs <= MAX_DURATION_S:
        raise ValueError(f"longer than {MAX_DURATION_S / 3600:g} h")
    return secs


def duration(value: Any, what: str = "duration") -> float:
    """'10ms', '1.5s', '1min' -> seconds, as a ConfigError naming `what` when wrong."""
    try:
        return _parse_duration(value)
    except ValueError as e:
        raise ConfigError(f"{what}: {e} (got {value!r})") from None


def _positive(v: float) -> float:
    if not v > 0:
        raise ValueError("must be longer than 0")
    return v


def between(lo: float, hi: float, never: bool = False) -> Callable[[float], float]:
    """A check that a duration in seconds is within lo..hi (or 0, meaning never)."""
    def check(v: float) -> float:
        if not (lo <= v <= hi or (never and v == 0)):
            raise ValueError(f"must be from {lo:g} s to {hi:g} s" + (" (0: never)" if never
                                                                    else ""))
        return v
    return check


# ---- bounds of the Modbus server's and EXCH's numbers (issue 21) ---------------------------------
MAX_CLIENTS = 1000  # each client holds a file descriptor; a process gets 1024 by default
# a frame is at most 260 bytes: 60 s is ample; without a deadline a client may drip forever
frame_timeout_ok = between(0.1, 60.0)
idle_timeout_ok = between(1.0, MAX_DURATION_S, never=True)
exch_timeout_ok = between(0.01, 60.0)  # [our choice]: a LAN reply takes ms


# Bounds of the numeric settings that have no Twido range: what makes sense, so that a typo
# (a period of 1 ns, a statistics line every microsecond) is an error, not a hang or a flood.
MIN_SCAN_PERIOD_S = 1e-6  # the engine counts PLC time in whole microseconds
MIN_WATCHDOG_S = 0.001
MIN_INTERVAL_S = 0.010  # save and statistics intervals (0 = off)
DRUM_STEPS = 8  # [m221] a drum has 1 to 8 steps of 16 control bits


def _at_least(low: float, what: str) -> Any:
    def check(v: float) -> float:
        if not v >= low:
            raise ValueError(f"{what} is at least " + (f"{low * 1e6:g} us" if low < 1e-3
                                                         else f"{low * 1000:g} ms"))
        return v
    return AfterValidator(check)


def check_interval(v: float) -> float:
    """A save or statistics interval: 0 (off) or from MIN_INTERVAL_S on."""
    if v != 0 and not v >= MIN_INTERVAL_S:
        raise ValueError(f"0 (off) or at least {MIN_INTERVAL_S * 1000:g} ms")
    return v


# ---- field types shared by the schema and the devices' Options ---------------------------------
Duration = Annotated[float, BeforeValidator(_parse_duration)]
"""Seconds, written with a unit ("10ms"); bare numbers refused."""
PositiveDuration = Annotated[Duration, AfterValidator(_positive)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
Interval = Annotated[Duration, AfterValidator(check_interval)]
"""Seconds between two periodic actions: 0 (never) or at least 10 ms."""
Address = Annotated[str, Field(min_length=1)]


def _no_nan(v: float) -> float:
    if math.isnan(v):
        raise ValueError("nan is not a number here")
    return v


InfFloat = Annotated[float, AfterValidator(_no_nan)]
"""A float where `inf` means "no limit" (nan still refused)."""


class Section(BaseModel):
    """A config table: unknown keys are errors, no silent type conversion (a string is not a
    number, a number is not a bool)."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


def profile_of(info: ValidationInfo) -> Profile:
    """The controller profile a validation runs for (`validate_config` passes it as context)."""
    return (info.context or {}).get("profile", DEFAULT_PROFILE)


def numbered(lo: int, hi: int | Callable[[Profile], int], message: str) -> Any:
    """A table key that is a number (TOML keys are text: `[schedule.3]`, `modules = { 1 = ..}`)
    from `lo` to `hi` (a number, or what the profile allows); `message` says what is wrong,
    with `{key}`, `{lo}` and `{hi}` filled in. The one place numbered keys are read."""
    def check(v: Any, info: ValidationInfo) -> int:
        top = hi(profile_of(info)) if callable(hi) else hi
        s = str(v).strip()
        if isinstance(v, bool) or not s.isdigit() or not lo <= int(s) <= top:
            raise ValueError(message.format(key=v, lo=lo, hi=top))
        return int(s)
    return Annotated[int, BeforeValidator(check)]
