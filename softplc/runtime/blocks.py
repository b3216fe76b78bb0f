"""Twido function blocks: %TM timers, %C counters, %DR drums, %SBR shift registers,
%SC step counters, %R FIFO/LIFO registers.

Type, time base and preset are configuration, never program text [m221]. Each block
exposes its fields as attributes named like the Twido fields (`.Q`, `.V`, `.P` ...), one
method per input pin for the short form (`CU %C0` -> `cu`; a timer's one pin is `run`), and
`run(...)` taking all input pins at once for the `BLK ... END_BLK` form. Values are 0..9999
as on Twido [manual].
"""

from __future__ import annotations

from typing import Any

from softplc.errors import BlockError

MAX_VALUE = 9999  # %TMi.P/.V, %Ci.P/.V range [manual]

TIME_BASES_US = {"1ms": 1_000, "10ms": 10_000, "100ms": 100_000, "1s": 1_000_000,
                 "1min": 60_000_000}


class TimeSource:
    """Shared with the engine: the current scan's start time, and the timers in the middle
    of timing (so that the engine can update those the program did not execute)."""

    def __init__(self) -> None:
        self.now_us = 0
        self.running: set[Timer] = set()
        # False when every timer block runs in every scan (no jump, subroutine, Grafcet
        # step or conditional end in the program): then nothing needs tracking
        self.track = True

    def update_running(self) -> None:
        """End of the scan: a timer keeps timing when its block is not executed (jumped
        over, in an uncalled subroutine or an inactive step): %TMi.V counts on and %TMi.Q
        changes at the preset [manual: TWD USE 10AE, timer "special cases", "effect of a
        program jump"]; those the program executed in this scan are up to date."""
        done = []
        now = self.now_us
        for t in self.running:
            if t._seen != now:
                t.run(t._in)
            if not (t._on if t._is_ton is False else t._in and t.V < t.P):  # t.timing
                done.append(t)
        for t in done:
            self.running.discard(t)


class Block:
    PINS: tuple[str, ...] = ()
    FIELDS: tuple[str, ...] = ()
    EDGE_PINS: dict[str, str] = {}  # rising-edge inputs -> attribute with their last value

    def __init_subclass__(cls, **kw: Any) -> None:
        """The short form (`CU %C0`, `R %R0`): one method per input pin (`cu`, `r`...) that
        runs the block with that input, holding the edge inputs at their last value (no
        edge) and the level inputs at 0. Generated, so each is one plain call to `run`.
        A class may still define a pin method itself (`run` serves a timer's IN)."""
        super().__init_subclass__(**kw)
        for pin in cls.PINS:
            name = pin.lower()
            if pin == "IN" or name in cls.__dict__:
                continue
            held = "".join(f", {p}=self.{a}" for p, a in cls.EDGE_PINS.items() if p != pin)
            ns: dict[str, Any] = {}
            exec(f"def {name}(self, v):\n    self.run({pin}=v{held})\n", ns)
            setattr(cls, name, ns[name])

    def state(self) -> dict[str, Any]:
        return {f: getattr(self, f) for f in self.FIELDS}

    def set_state(self, d: dict[str, Any]) -> None:
        for k, v in d.items():
            setattr(self, k, v)


class TimedBlock(Block):
    """A block with a start time `_t0` on `self.clock` (a TimeSource): its state holds the
    time elapsed since (`_elapsed_us`), valid whatever clock the state is restored under
    (a restart's starts again at 0). Timers, pulse outputs (runtime/pulse.py)."""

    clock: TimeSource

    def state(self) -> dict[str, Any]:
        st = super().state()
        st["_elapsed_us"] = self.clock.now_us - st.pop("_t0")
        return st

    def set_state(self, d: dict[str, Any]) -> None:
        d = dict(d)
        if "_elapsed_us" in d:
            d["_t0"] = self.clock.now_us - d.pop("_elapsed_us")
        super().set_state(d)


class Timer(TimedBlock):
    """%TMi: TON (on delay), TOF (off delay), TP (pulse) [manual].

    TON: V counts while IN = 1, Q = 1 once V reaches P, IN = 0 resets V and Q.
    TOF: Q = 1 while IN = 1; when IN falls V counts and Q drops when V reaches P.
    TP: a rising edge of IN gives a pulse of length P; V counts during the pulse."""

    PINS = ("IN",)
    FIELDS = ("P", "V", "Q", "_in", "_t0", "_on")

    def __init__(self, clock: TimeSource, type: str = "TON", base: str = "1s", preset: int = 0):
        type = type.upper()
        if type not in ("TON", "TOF", "TP"):
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


class Counter(Block):
    """%Ci up/down counter [m221]: R (priority) V := 0; S V := P; CU / CD count on rising
    edges (both in one scan cancel); D = (V = P); F set on the 9999 -> 0 wrap going up,
    E on the 0 -> 9999 wrap going down; E and F clear at the next count."""

    PINS = ("R", "S", "CU", "CD")
    FIELDS = ("P", "V", "D", "E", "F", "_cu", "_cd")
    EDGE_PINS = {"CU": "_cu", "CD": "_cd"}

    def __init__(self, preset: int = MAX_VALUE):
        if not 0 <= int(preset) <= MAX_VALUE:
            raise BlockError(f"preset {preset}: 0..{MAX_VALUE}")
        self.P, self.V, self.D, self.E, self.F = int(preset), 0, 0, 0, 0
        self._cu = self._cd = 0

    def run(self, R: Any = 0, S: Any = 0, CU: Any = 0, CD: Any = 0) -> None:
        up, down = CU and not self._cu, CD and not self._cd  # rising edges
        self._cu, self._cd = (1 if CU else 0), (1 if CD else 0)
        if R:
            self.V, self.E, self.F = 0, 0, 0
        elif S:
            self.V = self.P
        elif up:
            if not down:  # both in one scan cancel
                self.E = 0
                if self.V < MAX_VALUE:
                    self.V, self.F = self.V + 1, 0
                else:
                    self.V, self.F = 0, 1
        elif down:
            self.F = 0
            if self.V > 0:
                self.V, self.E = self.V - 1, 0
            else:
                self.V, self.E = MAX_VALUE, 1
        self.D = 1 if self.V == self.P else 0

    # The short form (`CU %C0`, `CD %C0`): `run` with that input, R = S = 0 and the other
    # edge input held (no edge), written out: one call instead of three, the rising edge
    # the only branch that counts (tests/unit/test_block_fastpath.py checks them against `run`).
    def cu(self, v: Any) -> None:
        if v and not self._cu:
            self._cu, self.E, self.F = 1, 0, 0
            if self.V < MAX_VALUE:
                self.V += 1
            else:
                self.V, self.F = 0, 1
        else:
            self._cu = 1 if v else 0
        self.D = 1 if self.V == self.P else 0

    def cd(self, v: Any) -> None:
        if v and not self._cd:
            self._cd, self.E, self.F = 1, 0, 0
            if self.V > 0:
                self.V -= 1
            else:
                self.V, self.E = MAX_VALUE, 1
        else:
            self._cd = 1 if v else 0
        self.D = 1 if self.V == self.P else 0


class Drum(Block):
    """%DRi drum controller [m221]: up to 8 steps of 16 control bits; U advances on a rising
    edge (wrapping), R (level) goes back to step 0; .S current step, .F on the last step.

    The step's bits are written to the configured bit objects only when the step changes
    [m221: recorded simulator runs, issue 11], so a rung that resets a drum output holds
    until the next step change; except while R is held: the drum is reset at every
    execution and writes step 0's bits each time, so a rung after the drum that changes
    one of its outputs is overwritten at the next scan [issue 24: a user's observation,
    not found in a manual]. The first execution after a cold start writes step 0's bits
    (our choice: the M221 runs start with the drum's outputs in step 0's state).
    The short-form pins (`R %DR0`, `U %DR0`) are the generated adapters of `Block`."""

    PINS = ("R", "U")
    FIELDS = ("S", "F", "_u")
    EDGE_PINS = {"U": "_u"}

    def __init__(self, steps: list[int], outputs: list[Any]):
        if not 1 <= len(steps) <= 8:
            raise BlockError("a drum has 1 to 8 steps")
        self.steps = [int(s) & 0xFFFF for s in steps]
        self.outputs = outputs  # resolved (buffer, index) pairs
        self.S, self.F, self._u = 0, 0, 0
        self._written = -1  # the step whose bits the outputs last received

    def set_state(self, d: dict[str, Any]) -> None:
        """Cold start or restored state: the next execution writes the step's bits (our
        choice; the outputs were reset or restored meanwhile)."""
        super().set_state(d)
        self._written = -1

    def _apply(self) -> None:
        if self.S != self._written:
            self._written = self.S
            bits = self.steps[self.S]
            for k, (buf, idx) in enumerate(self.outputs):
                buf[idx] = bits >> k & 1 == 1  # a bit image: bools
        self.F = 1 if self.S == len(self.steps) - 1 else 0

    def run(self, R: Any = 0, U: Any = 0) -> None:
        u = 1 if U else 0
        if R:
            self.S = 0
            self._written = -1  # a reset writes step 0's bits, at every scan it is held
        elif u and not self._u:
            self.S = (self.S + 1) % len(self.steps)
        self._u = u
        self._apply()


class _UpDownBlock(Block):
    """Blocks with R / CU / CD inputs counted on rising edges: the short-form pins feed
    `run` one input at a time, holding the others at their last value."""

    PINS = ("R", "CU", "CD")
    EDGE_PINS = {"CU": "_cu", "CD": "_cd"}
    _cu = _cd = 0

    def run(self, R: Any = 0, CU: Any = 0, CD: Any = 0) -> None:  # pragma: no cover
        raise NotImplementedError


class ShiftRegister(_UpDownBlock):
    """%SBRi 16-bit shift register [manual]: R clears, CU shifts left (bit k -> k+1),
    CD shifts right, both on rising edges. Bits %SBRi.J0..J15."""

    FIELDS = ("W", "_cu", "_cd")

    def __init__(self) -> None:
        self.W, self._cu, self._cd = 0, 0, 0

    def bit(self, k: int) -> bool:  # read as a bit: a bool, as the bit images hold
        return self.W >> k & 1 == 1

    def set_bit(self, k: int, v: Any) -> None:
        self.W = (self.W | (1 << k)) if v else (self.W & ~(1 << k))

    def run(self, R: Any = 0, CU: Any = 0, CD: Any = 0) -> None:
        cu, cd = (1 if CU else 0), (1 if CD else 0)
        if R:
            self.W = 0
        else:
            if cu > self._cu:
                self.W = (self.W << 1) & 0xFFFF
            if cd > self._cd:
                self.W >>= 1
        self._cu, self._cd = cu, cd


class StepCounter(_UpDownBlock):
    """%SCi step counter [manual]: 256 bits %SCi.0-255, one active; CU steps up, CD down
    (rising edges, wrapping), R back to step 0. The program may also write the bits
    (`ST %SC0.5`) [manual]: setting bit j makes j the current step for CU/CD, clearing it
    leaves the current step alone (our reading: the manual only says the bits can be
    written), so several bits can be 1 until the next CU/CD/R."""

    FIELDS = ("V", "W", "_cu", "_cd")

    def __init__(self) -> None:
        self.V, self.W, self._cu, self._cd = 0, 1, 0, 0

    def bit(self, k: int) -> bool:  # read as a bit: a bool, as the bit images hold
        return self.W >> k & 1 == 1

    def set_bit(self, k: int, v: Any) -> None:
        if v:
            self.W |= 1 << k
            self.V = k
        else:
            self.W &= ~(1 << k)

    def run(self, R: Any = 0, CU: Any = 0, CD: Any = 0) -> None:
        cu, cd = (1 if CU else 0), (1 if CD else 0)
        v = self.V
        if R:
            v = 0
        else:
            if cu > self._cu:
                v = (v + 1) % 256
            if cd > self._cd:
                v = (v - 1) % 256
        if v != self.V or R:
            self.V, self.W = v, 1 << v
        self._cu, self._cd = cu, cd


class Register(Block):
    """%Ri FIFO or LIFO of 16 words [manual]: a rising edge on I stores .I, on O retrieves
    into .O; R empties; .E empty, .F full."""

    PINS = ("R", "I", "O")
    FIELDS = ("I", "O", "E", "F", "_i", "_o", "_data")
    EDGE_PINS = {"I": "_i", "O": "_o"}

    def __init__(self, type: str = "FIFO", depth: int = 16):
        type = type.upper()
        if type not in ("FIFO", "LIFO"):
            raise BlockError(f"register type {type!r}: FIFO or LIFO")
        self.type, self.depth = type, depth
        self.I = self.O = 0
        self.E, self.F = 1, 0
        self._i = self._o = 0
        self._data: list[int] = []

    def state(self) -> dict[str, Any]:
        d = super().state()
        d["_data"] = list(self._data)
        return d

    def run(self, R: Any = 0, I: Any = 0, O: Any = 0) -> None:
        i, o = (1 if I else 0), (1 if O else 0)
        if R:
            self._data.clear()
        else:
            if i > self._i and len(self._data) < self.depth:
                self._data.append(self.I)
            if o > self._o and self._data:
                self.O = self._data.pop(0 if self.type == "FIFO" else -1)
        self._i, self._o = i, o
        self.E = 0 if self._data else 1
        self.F = 1 if len(self._data) >= self.depth else 0



# ---- communication (issue 11 B: EXCH / %MSG, runtime/exch.py) ----------------------------
class Message(Block):
    """%MSGi: the state of the exchanges of port i [manual]: D = 1 done (no exchange in
    progress), E = 1 the last exchange failed (code in the port's status word). R resets:
    the exchange in progress is dropped, D = 1, E = 0. `port` is the `runtime.exch.ExchPort`
    the configuration gives (None: the port is not configured)."""

    PINS = ("R",)
    FIELDS = ("D", "E")

    def __init__(self) -> None:
        self.D, self.E = 1, 0
        self.port: Any = None

    def run(self, R: Any = 0) -> None:
        if R:
            if self.port is not None:
                self.port.reset()
            self.D, self.E = 1, 0

    def exch(self, start: int, n: int) -> None:
        """`EXCHi %MW<start>:<n>` (the compiler checked that the port is configured)."""
        self.port.start(start, n)
