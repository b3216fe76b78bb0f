"""%TMi timers, every face: the runtime block, `[timers]`, its set-up, its verify model.

TON (on delay), TOF (off delay), TP (pulse) [manual: TWD USE 10AE, timer function block];
type, time base and preset are configuration, never program text [m221]. Values 0..9999.

    timers."%TM0" = { type = "TON", base = "10ms", preset = 50 }

The rule (`timer_rule`) is written once over a value domain: the verifier runs it on solver
terms. `Timer` keeps its own straight-line code: a timer runs in the scan's hot path (a
call or a domain dispatch costs ~20 ns a timer a scan); tests/integration/test_block_rules.py
checks it against the rule, value for value, with `semantics.IntDomain`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field

from softplc.blocks import BIT, WORD, BlockModel, Scan
from softplc.config.fields import Section, _parse_duration
from softplc.errors import BlockError
from softplc.runtime.blocks import MAX_VALUE, TimedBlock, TimeSource

TIME_BASES_US = {"1ms": 1_000, "10ms": 10_000, "100ms": 100_000, "1s": 1_000_000,
                 "1min": 60_000_000}  # [manual]
TYPES = ("TON", "TOF", "TP")


# ---- the rule, over a value domain -------------------------------------------------------
def timer_rule(D: Any, kind: str, s: Mapping[str, Any], IN: Any, el: Any,
               base: Any) -> dict[str, Any]:
    """One execution of a timer of type `kind` with input IN: the new P-relative fields
    V, Q, _on, _in and `_el`, the time since it started (`el` on entry, 0 when this
    execution starts it), in units of which the time base is `base`.

    TON: V counts while IN = 1, Q = 1 once V reaches P, IN = 0 resets V and Q.
    TOF: Q = 1 while IN = 1; when IN falls V counts and Q drops when V reaches P.
    TP: a rising edge of IN gives a pulse of length P; V counts during the pulse."""
    P, V, Q, was_in, on = s["P"], s["V"], s["Q"], s["_in"], s["_on"]
    if kind == "TON":
        start = D.and_(IN, D.not_(was_in))
    elif kind == "TOF":
        start = D.and_(D.not_(IN), was_in)
    else:
        start = D.and_(D.and_(IN, D.not_(was_in)), D.not_(on))
    el2 = D.ite(start, 0, el)
    # V reaches P once el2 >= P x base: the time counted in whole bases, compared without
    # a division (el2 // base >= P <=> el2 >= P * base)
    done = el2 >= D.resize(P, el2) * base
    v = D.ite(done, P, D.resize(D.udiv(el2, base), P))  # below P unless done
    out = {"_el": el2, "_in": D.bit(IN)}
    if kind == "TON":
        out.update(V=D.ite(IN, v, 0), Q=D.bit(D.and_(IN, done)))
        return out
    on1 = D.or_(start, on)
    ended = D.and_(on1, done)
    if kind == "TOF":
        out.update(V=D.ite(IN, 0, D.ite(on1, v, V)),
                   Q=D.bit(D.or_(IN, D.and_(Q, D.not_(ended)))),
                   _on=D.bit(D.and_(D.not_(IN), D.and_(on1, D.not_(done)))))
        return out
    on3 = D.and_(on1, D.not_(done))
    out.update(V=D.ite(D.and_(D.not_(on3), D.not_(IN)), 0, D.ite(on1, v, V)),
               Q=D.bit(D.and_(D.or_(start, Q), D.not_(ended))), _on=D.bit(on3))
    return out


# ---- the runtime block -------------------------------------------------------------------
class Timer(TimedBlock):
    """%TMi: TON, TOF, TP (`timer_rule` says what each does). Straight-line code for the
    engine's speed, checked against `timer_rule` (see the module docstring)."""

    PINS = ("IN",)
    FIELDS = ("P", "V", "Q", "_in", "_t0", "_on")

    def __init__(self, clock: TimeSource, type: str = "TON", base: str = "1s", preset: int = 0):
        type = type.upper()
        if type not in TYPES:
            raise BlockError(f"timer type {type!r}: TON, TOF or TP")
        if base not in TIME_BASES_US:
            raise BlockError(f"time base {base!r}: one of {', '.join(TIME_BASES_US)}")
        if not 0 <= int(preset) <= MAX_VALUE:
            raise BlockError(f"preset {preset}: 0..{MAX_VALUE}")
        self.clock, self.type, self.base = clock, type, base
        self._is_ton = type == "TON"
        self.base_us = TIME_BASES_US[base]
        self.P, self.V, self.Q = int(preset), 0, 0
        self._in, self._t0, self._on = 0, 0, 0  # last IN, start time, timing in progress
        self._seen = -1  # the scan time of the last execution
        self.run = {"TON": self._ton, "TOF": self._tof, "TP": self._tp}[type]

    @property
    def last_in(self) -> int:
        """The IN input at the last execution (what the debugger shows)."""
        return self._in

    @property
    def timing(self) -> bool:
        """Counting towards the preset (V still changes with time)."""
        return bool(self._in and self.V < self.P) if self._is_ton else bool(self._on)

    def listing(self, i: int) -> str:
        """The debugger's line for %TMi."""
        return (f"%TM{i:<3} {self.type:<3} base {self.base:<5} P={self.P:<5} V={self.V:<5} "
                f"Q={int(self.Q)} IN={int(self.last_in)}")

    def set_state(self, d: dict[str, Any]) -> None:
        super().set_state(d)
        if self.timing and self.clock.track:  # a retained timer that was timing goes on
            self.clock.running.add(self)

    def _ton(self, IN: Any) -> None:
        now = self._seen = self.clock.now_us
        if IN:
            if not self._in:
                self._t0 = now
                if self.clock.track:
                    self.clock.running.add(self)
            v = (now - self._t0) // self.base_us
            if v >= self.P:
                self.V, self.Q = self.P, 1
            else:
                self.V, self.Q = v, 0
        else:
            self.V = self.Q = 0
        self._in = 1 if IN else 0

    def _tof(self, IN: Any) -> None:
        now = self._seen = self.clock.now_us
        if IN:
            self.V, self.Q, self._on = 0, 1, 0
        else:
            if self._in:  # falling edge: start counting
                self._start(now)
            if self._on:  # (as in _tp, written out: a call costs ~20 ns a timer a scan)
                v = (now - self._t0) // self.base_us
                if v >= self.P:
                    self.V, self.Q, self._on = self.P, 0, 0
                else:
                    self.V = v
        self._in = 1 if IN else 0

    def _tp(self, IN: Any) -> None:
        now = self._seen = self.clock.now_us
        if IN and not self._in and not self._on:
            self._start(now)
            self.Q = 1
        if self._on:
            v = (now - self._t0) // self.base_us
            if v >= self.P:
                self.V, self.Q, self._on = self.P, 0, 0
            else:
                self.V = v
        if not self._on and not IN:
            self.V = 0
        self._in = 1 if IN else 0

    def _start(self, now: int) -> None:
        """TOF and TP start timing (V follows the time from now until P, then Q drops)."""
        self._t0, self._on = now, 1
        if self.clock.track:
            self.clock.running.add(self)


# ---- configuration and set-up ------------------------------------------------------------
def _time_base(value: Any) -> str:
    """"10ms", "0.1s", "1min"... -> the name of a timer time base."""
    s = _parse_duration(value)
    for name, us in TIME_BASES_US.items():
        if abs(s * 1e6 - us) < 1e-3:
            return name
    raise ValueError(f"one of {', '.join(TIME_BASES_US)}")


TimeBase = Annotated[str, BeforeValidator(_time_base)]


class TimerConfig(Section):
    """`[timers]`: one entry per timer, as TwidoSuite's timer screen sets it."""

    type: Literal["TON", "TOF", "TP"] = "TON"
    base: TimeBase = "1s"
    preset: int = Field(0, ge=0, le=MAX_VALUE)


def setup(ctx: Any, fam: Any, entries: dict[str, TimerConfig]) -> None:
    ctx.each(fam, entries, lambda t, _: Timer(ctx.time_source, t.type, t.base, t.preset))


# ---- the verify model --------------------------------------------------------------------
def time_unit(t: Timer, period_us: int) -> int:
    """The model counts a timer's elapsed time in units of gcd(time base, period)
    microseconds: exact, and the numbers the solver handles stay small."""
    return math.gcd(t.base_us, period_us)


def timer_cap(t: Timer, scan: Scan) -> int:
    """Elapsed time (in units) past which a timer's outputs no longer change."""
    return (MAX_VALUE * t.base_us + max(scan.period_us, scan.longest_us)) \
        // time_unit(t, scan.period_us)


class TimerModel(BlockModel):
    """The state: P, V, Q, the last IN (`_in`), `_on` (TOF/TP timing) and `_el`, the time
    since the timer started in units (`now - _t0` of the engine), which advances by the
    scan period after every scan and saturates at `timer_cap` (past the largest preset
    nothing changes)."""

    def fields(self, block: Timer, scan: Scan) -> dict[str, int]:
        el = (timer_cap(block, scan) * 2).bit_length() + 1  # room for cap + a step, signed
        return {"P": WORD, "V": WORD, "Q": BIT, "_in": BIT, "_on": BIT, "_el": el}

    def init(self, block: Timer, field: str) -> int:
        return 0 if field == "_el" else int(getattr(block, field))

    def run(self, D: Any, block: Timer, s: Mapping[str, Any], pins: Mapping[str, Any],
            scan: Scan) -> dict[str, Any]:
        base = block.base_us // time_unit(block, scan.period_us)
        return timer_rule(D, block.type, s, pins["IN"], s["_el"], base)

    def held(self, s: Mapping[str, Any]) -> dict[str, Any]:
        return {"IN": s["_in"]}  # not executed: it keeps timing [manual: "program jump"]

    def after_scan(self, D: Any, block: Timer, s: Mapping[str, Any],
                   scan: Scan) -> dict[str, Any]:
        """The next scan starts one period later (a variable period: `dt` times the
        shortest one)."""
        el = s["_el"]
        step: Any = scan.period_us // time_unit(block, scan.period_us)
        if scan.dt is not None:
            step = D.resize(scan.dt, el) * step
        cap = timer_cap(block, scan)
        return {"_el": D.ite(el >= cap - step, cap, el + step)}

    def invariants(self, D: Any, block: Timer, s: Mapping[str, Any],
                   scan: Scan) -> list[Any]:
        el, P, V = s["_el"], s["P"], s["V"]
        return [el >= 0, el <= timer_cap(block, scan), P >= 0, P <= MAX_VALUE,
                V >= 0, V <= MAX_VALUE]


MODEL = TimerModel()
