"""The Twido PID function (`[ PID n ]`) and its auto-tuning.

Configured as TwidoSuite's PID screen configures it (`[pid.n]`, `PidConfig` below):
measure, set point, output, Kp (x 0.01), Ti and Td (0.1 s), sampling period Ts (10 ms
units, a multiple of the scan period), output limits, manual / automatic, direct / reverse
action, an optional PWM output, a diagnostic word, and the
operating mode PID, AT (auto-tuning only) or AT+PID [manual, from memory of TWD USE 10AE
and the TwidoSuite PID quick start guide 35011386 ch. 18.3; unverified: the units].

The block runs every time its operation block is executed; it computes a new output once
per Ts. The output is 0..10000 (the output limits narrow it), so an analog output channel
for it gets the custom range 0..10000, as the quick start guide configures it.

The control law is our choice (Twido's is not documented in the sources found): the
velocity form u += Kp (de + Ts/Ti e + Td/Ts d2pv), derivative on the measure (no kick on a
set-point step), the output clamped to its limits (no integral wind-up). Reverse action
(heating) uses e = SP - PV, direct action (cooling) e = PV - SP.

Auto-tuning [manual: Schneider FAQ FA213467, "Auto-tuning requirements for a Twido PID
function": an open-loop stable process, at steady state with a null process input when it
starts, no disturbance during the run, periodic scan with Ts an exact multiple of the scan
period]. Our run: 5 samples with the output at 0 to check the steady state, then an output
step (`at_output`) held until the measure settles; the step response gives a first order
plus dead time model (two-point method, 28.3 % and 63.2 % of the rise: T = 1.5 (t63 -
t28), L = t63 - T, K = rise / step) and the SIMC PI rule (Skogestad 2003, tau_c = L):
Kp = T / (K (tau_c + L)), Ti = min(T, 4 (tau_c + L)), Td = 0. The results go into the
Kp/Ti/Td words when those are %MW words (as Twido writes its AT results), and the mode
AT+PID goes on regulating with them. A failed run leaves the output at 0 until
`start_autotune()` (or a cold start) runs it again.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from softplc.errors import ConfigError
from softplc.twido.address import Ref

OUT_MAX = 10000  # the PID output range 0..10000 [manual, from memory]
# diagnostic word bits (our layout; the Twido's own bits are unverified)
D_PARAM, D_AT_RUNNING, D_AT_DONE, D_AT_FAILED, D_MANUAL, D_LIMITED, D_NOT_STEADY = (
    1, 2, 4, 8, 16, 32, 64)
AT_CHECK_SAMPLES = 5  # samples with the output at 0 that must be steady
AT_STEADY_FRACTION = 0.005  # of the measure's span: "steady" (check and settle)


@dataclass
class PidParams:
    """Resolved configuration: a parameter is a constant (int) or a word (Ref)."""

    measure: Ref
    setpoint: Ref | int
    output: Ref | None
    kp: Ref | int  # x 0.01
    ti: Ref | int  # 0.1 s; 0 = no integral action
    td: Ref | int  # 0.1 s
    ts_us: int
    out_min: int = 0
    out_max: int = OUT_MAX
    action: str = "reverse"
    mode: str = "PID"  # PID | AT | AT+PID
    manual: Ref | None = None  # bit: 1 = manual
    manual_output: Ref | int = 0
    pwm_output: Ref | None = None
    pwm_period_us: int = 0
    diagnostic: Ref | None = None
    at_output: int = OUT_MAX
    at_timeout_us: int = 4 * 3600 * 1_000_000
    measure_span: int = 10000  # for the steady-state test
    period_us: int = 0  # the scan period, for the Ts check
    at_result: dict[str, float] = field(default_factory=dict)


Word = str  # an address, checked when the blocks are set up
WordOrConst = str | Annotated[int, Field(ge=-32768, le=32767)]  # a constant: a word's value


class PidConfig(BaseModel):
    """One PID function (`[pid.n]`, run by `[ PID n ]`). Units as TwidoSuite's PID screen
    [manual, from memory]: kp x 0.01, ti and td in 0.1 s, ts and pwm_period in 10 ms,
    the output 0..10000. A parameter is a constant or a %MW word (read at each sample;
    auto-tuning writes its results into kp/ti/td words)."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["PID", "AT", "AT+PID"] = "PID"
    measure: Word
    setpoint: WordOrConst
    output: Word | None = None
    kp: WordOrConst = 100
    ti: WordOrConst = 0
    td: WordOrConst = 0
    ts: int = Field(100, ge=1, le=32767)
    output_min: int = Field(0, ge=0, le=OUT_MAX)
    output_max: int = Field(OUT_MAX, ge=0, le=OUT_MAX)
    action: Literal["reverse", "direct"] = "reverse"
    manual: Word | None = None
    manual_output: WordOrConst = 0
    pwm_output: Word | None = None
    pwm_period: int = Field(100, ge=1, le=32767)
    diagnostic: Word | None = None
    at_output: int = Field(OUT_MAX, ge=1, le=OUT_MAX)
    at_timeout: float = Field(14400.0, gt=0, le=86400)  # seconds
    measure_span: int = Field(10000, ge=1, le=32767)

    @model_validator(mode="after")
    def _limits(self) -> PidConfig:
        if self.output_min > self.output_max:
            raise ValueError("output_min > output_max")
        return self


def params(where: str, o: PidConfig, ctx: Any) -> PidParams:
    """A validated `[pid.n]` table resolved against the memory image (`ctx`: the block
    set-up, `softplc.assembly.blocks.BlockSetup`)."""
    word = ctx.word
    return PidParams(
        measure=word(where, "measure", o.measure), setpoint=word(where, "setpoint", o.setpoint),
        output=word(where, "output", o.output, True),
        kp=word(where, "kp", o.kp, True), ti=word(where, "ti", o.ti, True),
        td=word(where, "td", o.td, True), ts_us=o.ts * 10_000,
        out_min=o.output_min, out_max=o.output_max, action=o.action, mode=o.mode,
        manual=ctx.bit(where, "manual", o.manual, ("M", "I", "Q")),
        manual_output=word(where, "manual_output", o.manual_output),
        pwm_output=ctx.bit(where, "pwm_output", o.pwm_output, ("Q",)),
        pwm_period_us=o.pwm_period * 10_000,
        diagnostic=word(where, "diagnostic", o.diagnostic, True),
        at_output=o.at_output, at_timeout_us=round(o.at_timeout * 1e6),
        measure_span=o.measure_span, period_us=round(ctx.scan_period * 1e6))


def setup(ctx: Any, family: Any, entries: dict[str, PidConfig]) -> None:
    """The PID functions of `[pid]`, addresses resolved and checked once; a PWM output may
    not be a pulse block's output (`ctx.outputs`, claimed by those before)."""
    count = ctx.profile.count(family.kind)
    for key, o in entries.items():
        try:
            n = int(key)
        except ValueError:
            raise ConfigError(f"{family.section}: {key!r} is not a PID number "
                              f"({family.section}.0, {family.section}.1 ...)") from None
        if not 0 <= n < count:
            raise ConfigError(f"{family.section}.{n}: PID 0 .. PID {count - 1}")
        where = f"{family.section}.{n}"
        p = params(where, o, ctx)
        out = p.pwm_output  # the PID's PWM writes its output too
        if out is not None and out.kind == "Q" and out.module == 0 \
                and out.channel in ctx.outputs:
            raise ConfigError(f"{where}.pwm_output: %Q0.{out.channel} is the output of "
                              f"{ctx.outputs[out.channel]}")
        ctx.mem.blocks[family.kind][n] = Pid(ctx.mem, ctx.time_source, p)


class Pid:
    """One PID function; `mem` for its words, `clock` (TimeSource) for the scan time."""

    FIELDS = ("u", "_last", "_e1", "_pv1", "_pv2", "_at", "_at_t0", "_samples", "diag")

    def __init__(self, mem: Any, clock: Any, p: PidParams):
        self.mem, self.clock, self.p = mem, clock, p
        self.u = 0.0  # the output, 0..10000
        self._last: int | None = None  # time of the last sample
        self._e1 = 0.0
        self._pv1: float | None = None
        self._pv2: float | None = None
        self._at = "check" if "AT" in p.mode else ""  # "" | check | step | done | failed
        self._at_t0 = 0
        self._samples: list[tuple[float, float]] = []
        self.diag = 0
        if p.period_us and p.ts_us % p.period_us:
            self.diag |= D_PARAM  # Ts must be a multiple of the scan period [manual]
        self._initial = self.state()

    # -- state (cold start, retained data) ----------------------------------------------------
    def state(self) -> dict[str, Any]:
        return {f: (list(v) if isinstance(v, list) else v)
                for f, v in ((f, getattr(self, f)) for f in self.FIELDS)}

    def set_state(self, d: dict[str, Any]) -> None:
        for k, v in d.items():
            setattr(self, k, list(v) if isinstance(v, list) else v)
        self._last = None  # an absolute time of another clock: sample at the next run

    def start_autotune(self) -> None:
        """Run the auto-tuning again (the process must be back at steady state, output 0)."""
        self._at, self._samples, self._last = "check", [], None
        self.diag &= ~(D_AT_DONE | D_AT_FAILED | D_NOT_STEADY)

    # -- what views show (the debugger's `pid`) ---------------------------------------------------
    def listing(self, i: int) -> str:
        """PID function `i` in one line (the debugger's `pid` command)."""
        p, get = self.p, self.value
        return (f"PID {i:<2} {p.mode:<6} {p.action:<7} SP={get(p.setpoint):<6} "
                f"PV={get(p.measure):<6} OUT={round(self.u):<5} Kp={get(p.kp)}/100 "
                f"Ti={get(p.ti)}/10s Td={get(p.td)}/10s diag={self.diag:#06x} "
                f"AT={self.autotune_state or '-'}")

    def value(self, v: Ref | int) -> int:
        """A parameter's value now: the constant, or the word it names."""
        return self._get(v)

    @property
    def autotune_state(self) -> str:
        """The auto-tuning's state: "" (none), check, step, done or failed."""
        return self._at

    # -- the instruction ------------------------------------------------------------------------
    def _get(self, v: Ref | int) -> int:
        return v if isinstance(v, int) else int(self.mem.read(v))

    def run(self) -> None:
        now = self.clock.now_us
        p = self.p
        if self._last is None or now - self._last >= p.ts_us:
            dt = p.ts_us / 1e6
            self._last = now
            self._sample(now, dt)
        if p.pwm_output is not None:  # duty cycle = output / 10000 over the PWM period
            phase = now % p.pwm_period_us
            self.mem.write(p.pwm_output, phase < self.u / OUT_MAX * p.pwm_period_us)

    def _sample(self, now: int, dt: float) -> None:
        p = self.p
        pv = float(self._get(p.measure))
        manual = p.manual is not None and self.mem.read(p.manual)
        self.diag = (self.diag & ~(D_MANUAL | D_LIMITED | D_AT_RUNNING)) | \
            (D_MANUAL if manual else 0)
        if manual:  # bumpless: the regulator restarts from the manual output
            self.u = float(self._get(p.manual_output))
            self._pv1 = self._pv2 = pv
            self._e1 = self._error(pv)
        elif self._at in ("check", "step"):
            self.diag |= D_AT_RUNNING
            self._autotune(now, pv)
        elif p.mode == "AT" or self._at == "failed":
            self.u = 0.0  # AT only, or a failed AT (our choice): the output stays at 0
        else:
            self._regulate(pv, dt)
        self._write_output()

    def _error(self, pv: float) -> float:
        sp = float(self._get(self.p.setpoint))
        return sp - pv if self.p.action == "reverse" else pv - sp

    def _regulate(self, pv: float, dt: float) -> None:
        p = self.p
        kp = self._get(p.kp) / 100.0
        ti = self._get(p.ti) / 10.0
        td = self._get(p.td) / 10.0
        e = self._error(pv)
        sign = 1.0 if p.action == "reverse" else -1.0  # derivative acts on the measure
        pv1 = pv if self._pv1 is None else self._pv1
        pv2 = pv1 if self._pv2 is None else self._pv2
        du = kp * ((e - self._e1) + (dt / ti * e if ti > 0 else 0.0)
                   - sign * (td / dt) * (pv - 2 * pv1 + pv2))
        self.u += du
        self._e1, self._pv2, self._pv1 = e, pv1, pv

    def _write_output(self) -> None:
        p = self.p
        lo, hi = max(0, p.out_min), min(OUT_MAX, p.out_max)
        if self.u < lo or self.u > hi:
            self.u = min(max(self.u, lo), hi)
            self.diag |= D_LIMITED
        if p.output is not None:
            self.mem.write(p.output, round(self.u))
        if p.diagnostic is not None:
            self.mem.write(p.diagnostic, self.diag)

    # -- auto-tuning ----------------------------------------------------------------------------
    def _autotune(self, now: int, pv: float) -> None:
        p = self.p
        tol = AT_STEADY_FRACTION * p.measure_span
        if self._at == "check":
            self.u = 0.0
            self._samples.append((now / 1e6, pv))
            if len(self._samples) >= AT_CHECK_SAMPLES:
                values = [v for _, v in self._samples]
                if max(values) - min(values) > tol:
                    self._fail(D_NOT_STEADY)  # not at steady state: precondition [manual]
                    return
                self._at, self._at_t0, self._samples = "step", now, [(now / 1e6, pv)]
                self.u = float(min(p.at_output, p.out_max))
            return
        self._samples.append((now / 1e6, pv))
        self.u = float(min(p.at_output, p.out_max))
        if now - self._at_t0 > p.at_timeout_us:
            self._fail(0)
            return
        n = len(self._samples)
        window = max(10, n // 5)
        if n < 2 * window:
            return
        pv0 = self._samples[0][1]
        rise = pv - pv0
        recent = pv - self._samples[-window][1]
        if abs(rise) > 10 * tol and abs(recent) < AT_STEADY_FRACTION * abs(rise) * 4:
            self._identify(pv0, rise)

    def _identify(self, pv0: float, rise: float) -> None:
        t0 = self._samples[0][0]

        def crossing(frac: float) -> float:
            level = pv0 + frac * rise
            prev_t, prev_v = self._samples[0]
            for t, v in self._samples[1:]:
                if (v - level) * (1 if rise > 0 else -1) >= 0:
                    return prev_t + (t - prev_t) * ((level - prev_v) / (v - prev_v)
                                                    if v != prev_v else 1.0) - t0
                prev_t, prev_v = t, v
            return self._samples[-1][0] - t0

        t28, t63 = crossing(0.283), crossing(0.632)
        tau = 1.5 * (t63 - t28)
        dead = max(t63 - tau, self.p.ts_us / 1e6)
        gain = rise / self.u
        if self.p.action == "direct":
            gain = -gain
        if tau <= 0 or gain <= 0:
            self._fail(0)
            return
        tc = dead  # SIMC tuning, tau_c = L
        kp = tau / (gain * (tc + dead))
        ti = min(tau, 4 * (tc + dead))
        self.p.at_result.update(K=gain, T=tau, L=dead, Kp=kp, Ti=ti, Td=0.0)
        for name, value in (("kp", round(kp * 100)), ("ti", round(ti * 10)), ("td", 0)):
            ref = getattr(self.p, name)
            if isinstance(ref, Ref):
                self.mem.write(ref, max(0, min(32767, value)))
            else:
                setattr(self.p, name, max(0, min(32767, value)))
        self._at = "done"
        self.diag = (self.diag | D_AT_DONE) & ~D_AT_RUNNING
        self._e1 = self._error(self._samples[-1][1])
        self._pv1 = self._pv2 = self._samples[-1][1]

    def _fail(self, why: int) -> None:
        self._at = "failed"
        self.u = 0.0
        self.diag = (self.diag | D_AT_FAILED | why) & ~D_AT_RUNNING
