"""Twido pulse outputs: the pulse generator `%PLSi` and the pulse width modulator `%PWMi`.

What the Twido documents [manual: Twido hardware guide as quoted in seed thesis 003 (the
TWDLCAE40DRF has 14 relay outputs and 2 transistor outputs, and offers "PWM" and "PLS");
the rest from memory of TWD USE 10AE "Pulse generator output function block (%PLS)" /
"Pulse width modulation function block (%PWM)", not found in the search corpora]:

- two blocks of each, on the base's transistor outputs: `%PLS0`/`%PWM0` drive `%Q0.0`,
  `%PLS1`/`%PWM1` drive `%Q0.1` (`Profile.pulse_outputs`); an output is configured as one
  of them (or as a plain output), never both;
- the time base is configuration: 0.142 ms, 0.57 ms, 10 ms or 1 s; the period preset
  `.P` is 1..255 with the fast bases, 1..32767 with the slow ones; 0 = not in use;
- `%PLSi`: a square wave (50 % duty) of period P x base; `.N` pulses (0 = no limit,
  0..32767); input IN (1: generate, 0: the output is 0), input R (1: `.Q` and `.D` to 0,
  the pulse count to 0); output `.Q` (generation in progress), `.D` (done: the N pulses
  are out; cleared by R);
- `%PWMi`: a fixed period P x base with the ratio `.R` (0..100 %) high; input IN.

Our choices (no source found): IN = 0 pauses a %PLS train, IN = 1 resumes it with the
pulses still due (only R restarts the count); with `.D` = 1 nothing is generated until R;
a new `.P` applies from the next pulse; a value out of range written to `.P`/`.N`/`.R`
is clamped to it.

Pulses at kHz cannot be sampled by a scan, so the generators do not toggle `%Q` bits: a
generator is a function of time (`_t0`, period), and the engine's `PulseOutputs.end_of_scan`
only writes the output's level at the scan time into `%Q` (what a person or the debugger
sees). Devices read the generator through `mem.pulses` (the device -> runtime direction):

    gen = mem.pulses.source(q_index)   # the generator driving that %Q, or None
    gen.pulses_at(t_us)   # rising edges since the cold start: monotonic, the device keeps
                          # the last count and takes the difference once per update
    gen.duty()            # the fraction of time the output is high now (mean power)

A generator keeps running when its block is not executed (it is hardware, as on Twido).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from softplc.errors import BlockError, ConfigError
from softplc.runtime.blocks import TimedBlock
from softplc.twido.address import parse_address

# Time bases of %PLS / %PWM [manual, from memory] (microseconds: 0.142 ms = 142 us).
TIME_BASES_US = {"0.142ms": 142, "0.57ms": 570, "10ms": 10_000, "1s": 1_000_000}
FAST_BASES = ("0.142ms", "0.57ms")  # .P at most 255 with these [manual, from memory]
P_MAX_FAST, P_MAX = 255, 32767
N_MAX = 32767  # %PLSi.N; 0 = no limit
RATIO_MAX = 100  # %PWMi.R, per cent
PulseBase = Literal["0.142ms", "0.57ms", "10ms", "1s"]
assert set(PulseBase.__args__) == set(TIME_BASES_US)  # one list of time bases


class _Clamped:
    """A field the program may write (`.P`, `.N`, `.R`), kept within 0..limit [our choice:
    clamped]; `limit` is a number or the name of the block attribute holding it."""

    def __init__(self, limit: int | str):
        self.limit = limit

    def __set_name__(self, owner: type, name: str) -> None:
        self.attr = "_" + name

    def __get__(self, obj: Any, cls: type | None = None) -> Any:
        return self if obj is None else getattr(obj, self.attr)

    def __set__(self, obj: Any, v: Any) -> None:
        hi = self.limit if isinstance(self.limit, int) else getattr(obj, self.limit)
        v = int(v)
        setattr(obj, self.attr, 0 if v < 0 else hi if v > hi else v)


class PulseOutput(TimedBlock):
    """What %PLS and %PWM share: the owned output, the time base, the period `.P`; the
    state keeps the run's start relative to the clock (a retained generator goes on at
    the same phase after a warm restart)."""

    def __init__(self, clock: Any, base: str = "10ms", preset: int = 0):
        if base not in TIME_BASES_US:
            raise BlockError(f"time base {base!r}: one of {', '.join(TIME_BASES_US)}")
        self.clock, self.base = clock, base
        self.base_us = TIME_BASES_US[base]
        self.p_max = P_MAX_FAST if base in FAST_BASES else P_MAX
        if not 0 <= int(preset) <= self.p_max:
            raise BlockError(f"preset {preset}: 0..{self.p_max} with the {base} time base")
        self._P = int(preset)
        self._on = 0  # generating
        self._t0 = 0  # start of the current run of pulses (us)

    P = _Clamped("p_max")

    @property
    def period_us(self) -> int:
        return self._P * self.base_us

    def level(self, t_us: int) -> bool:
        """The output's level at time t (what %Q shows at the end of a scan: a bool, as
        the bit images hold)."""
        period = self._run_period()
        if not self._on or period == 0 or t_us < self._t0:
            return False
        return (t_us - self._t0) % period < period * self.duty()

    def _run_period(self) -> int:
        """The period the running output has (a new .P may wait for the next pulse)."""
        return self.period_us

    def update(self, now_us: int) -> None:
        """End of a scan: the hardware went on generating (see PulseOutputs)."""

    def duty(self) -> float:
        raise NotImplementedError

    def pulses_at(self, t_us: int) -> int:
        raise NotImplementedError

    def summary(self, now_us: int) -> str:
        """One line for the debugger: period, frequency, fields, pulses so far, duty."""
        per = self.period_us
        freq = f"{1e6 / per:.4g} Hz" if per else "not in use"
        fields = " ".join(f"{f}={int(getattr(self, f))}" for f in ("N", "R", "Q", "D")
                          if f in self.FIELDS)
        return (f"base {self.base} P={self.P} ({per / 1000:g} ms, {freq}) {fields} "
                f"{'on' if self._on else 'off'} pulses={self.pulses_at(now_us)} "
                f"duty={self.duty():.2f}")


class PlsConfig(BaseModel):
    """`pls."%PLSi"`: what TwidoSuite's configuration of %Q0.i as a pulse generator sets:
    the time base, the period preset (%PLSi.P) and the number of pulses (%PLSi.N, 0 = no
    limit) [manual, from memory]. The preset's range depends on the base (checked by the
    block)."""

    model_config = ConfigDict(extra="forbid")

    base: PulseBase = "10ms"
    preset: int = Field(0, ge=0, le=32767)
    pulses: int = Field(0, ge=0, le=N_MAX)


class PulseGenerator(PulseOutput):
    """%PLSi: N pulses (or an endless train) of period P x base, 50 % duty."""

    PINS = ("IN", "R")
    FIELDS = ("P", "N", "Q", "D", "_on", "_t0", "_T", "_base", "_offset")
    SUMMARY = ("Q", "P", "N", "D")  # the debugger's one-line summary

    def __init__(self, clock: Any, base: str = "10ms", preset: int = 0, pulses: int = 0):
        super().__init__(clock, base, preset)
        if not 0 <= int(pulses) <= N_MAX:
            raise BlockError(f"pulses {pulses}: 0..{N_MAX} (0 = no limit)")
        self._N = int(pulses)
        self.Q = self.D = 0
        self._T = 0  # the period of the current run (us): a new .P applies at a pulse
        self._base = 0  # pulses out before the current run (since the last R)
        self._offset = 0  # pulses out before the last R (the devices' count is monotonic)

    @classmethod
    def configured(cls, clock: Any, o: PlsConfig) -> PulseGenerator:
        return cls(clock, o.base, o.preset, o.pulses)

    N = _Clamped(N_MAX)

    # -- time: pulses are rising edges, pulse k of a run at _t0 + k * _T -----------------------
    def _started(self, t_us: int) -> int:
        """Pulses of the current run started by time t (limited by N)."""
        if not self._on or t_us < self._t0:
            return 0
        k = (t_us - self._t0) // self._T + 1
        if self._N:
            k = min(k, max(0, self._N - self._base))
        return k

    def pulses_at(self, t_us: int) -> int:
        return self._offset + self._base + self._started(t_us)

    def _run_period(self) -> int:
        return self._T

    def duty(self) -> float:
        return 0.5 if self._on else 0.0

    def _stop(self, now_us: int) -> None:
        self._base += self._started(now_us)
        self._on = self.Q = 0

    def _start(self, now_us: int) -> None:
        self._on, self._t0, self._T, self.Q = 1, now_us, self.period_us, 1

    def update(self, now_us: int) -> None:
        """Done once the N-th pulse has ended (its low half included)."""
        if self._on and self._N and self._base + self._started(now_us) >= self._N \
                and now_us >= self._t0 + (self._N - self._base) * self._T:
            self._base = self._N
            self._on = self.Q = 0
            self.D = 1

    # -- the instruction ---------------------------------------------------------------------
    def run(self, IN: Any = 0, R: Any = 0) -> None:
        now = self.clock.now_us
        if R:
            self.r(1)
            return
        self.update(now)
        if IN and not self.D and self._P:
            if not self._on:
                self._start(now)
            elif self._T != self.period_us:  # a new period from the next pulse on
                k = self._started(now)
                self._base += k
                self._t0 += k * self._T
                self._T = self.period_us
        elif self._on:
            self._stop(now)

    def r(self, v: Any) -> None:
        """Input R (the short form `R %PLSi`): Q, D and the pulse count to 0."""
        if v:
            now = self.clock.now_us
            self._offset += self._base + self._started(now)
            self._base = 0
            self._on = self.Q = self.D = 0


class PwmConfig(BaseModel):
    """`pwm."%PWMi"`: time base, period preset (%PWMi.P), initial ratio (%PWMi.R, %)."""

    model_config = ConfigDict(extra="forbid")

    base: PulseBase = "10ms"
    preset: int = Field(0, ge=0, le=32767)
    ratio: int = Field(0, ge=0, le=RATIO_MAX)


class PwmOutput(PulseOutput):
    """%PWMi: period P x base, the ratio .R (per cent) high, while IN = 1."""

    PINS = ("IN",)
    FIELDS = ("P", "R", "_on", "_t0", "_count_before")
    SUMMARY = ("P", "R")

    def __init__(self, clock: Any, base: str = "10ms", preset: int = 0, ratio: int = 0):
        super().__init__(clock, base, preset)
        if not 0 <= int(ratio) <= RATIO_MAX:
            raise BlockError(f"ratio {ratio}: 0..{RATIO_MAX} %")
        self._R = int(ratio)
        self._count_before = 0  # periods of the runs before the current one

    @classmethod
    def configured(cls, clock: Any, o: PwmConfig) -> PwmOutput:
        return cls(clock, o.base, o.preset, o.ratio)

    R = _Clamped(RATIO_MAX)

    def duty(self) -> float:
        return self._R / RATIO_MAX if self._on and self._P else 0.0

    def pulses_at(self, t_us: int) -> int:
        """Periods started in the current run (a device counting pulses sees one a period
        while the ratio is above 0)."""
        if not self._on or not self._R or not self._P or t_us < self._t0:
            return self._count_before
        return self._count_before + (t_us - self._t0) // self.period_us + 1

    def run(self, IN: Any = 0) -> None:
        now = self.clock.now_us
        if IN and not self._on:
            self._on, self._t0 = 1, now
        elif not IN and self._on:
            self._count_before = self.pulses_at(now)
            self._on = 0


class PulseOutputs:
    """The configured pulse outputs of a PLC, by flat %Q index: the engine calls
    `end_of_scan` (generators advance, their level goes into the output image), devices
    call `source` (see the module docstring)."""

    def __init__(self, q: list[bool]):
        self._q = q
        self.by_output: dict[int, PulseOutput] = {}
        self.names: dict[int, str] = {}  # q index -> "%PLS0 on %Q0.0"

    def add(self, q_index: int, gen: PulseOutput, name: str = "") -> None:
        self.by_output[q_index] = gen
        self.names[q_index] = name

    def source(self, q_index: int) -> PulseOutput | None:
        return self.by_output.get(q_index)

    def end_of_scan(self, now_us: int) -> None:
        q = self._q
        for i, g in self.by_output.items():
            g.update(now_us)
            q[i] = g.level(now_us)


# ---- set-up (the catalog's hooks, run by softplc.assembly.blocks) --------------------------------
def setup_pulses(ctx: Any, family: Any, entries: dict[str, Any]) -> None:
    """A pulse family's configured blocks on the profile's transistor outputs (an output is
    one pulse block or none: `ctx.outputs` holds who has each)."""
    pulses = ctx.shared.setdefault("pulses", PulseOutputs(ctx.mem.q))
    outputs = ctx.profile.pulse_outputs
    for text, o in entries.items():
        ref, where = ctx.block_ref(text, family), ctx.where(family.section, text)
        if ref.index >= len(outputs):
            raise ConfigError(f"{where}: {ctx.profile.name} has no output for {text}")
        q = outputs[ref.index]
        if q in ctx.outputs:
            raise ConfigError(f"{where}: %Q0.{q} is already the output of "
                              f"{ctx.outputs[q]} (an output is one pulse block or none)")
        ctx.outputs[q] = str(ref)
        try:
            gen = family.block_class.configured(ctx.time_source, o)
        except ValueError as e:
            raise ConfigError(f"{where}: {e}") from None
        ctx.mem.blocks[family.kind][ref.index] = gen
        out = parse_address(f"%Q0.{q}", ctx.profile)
        ctx.mem.use_io(out)
        pulses.add(out.index, gen, f"{ref} on {out}")


def finish_pulses(ctx: Any) -> None:
    """The engine updates the pulse outputs only when there are some."""
    pulses = ctx.shared.get("pulses")
    if pulses is not None and pulses.by_output:
        ctx.mem.pulses = ctx.engine.pulses = pulses
