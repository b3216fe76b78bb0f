"""Pydantic v2 models of the configuration sections added by issue 11, each with
`extra="forbid"` (a misspelt key is an error). `softplc.config.Config` types its sections
with them, so every problem is reported at once with its key path and code:

- `[analog]` (`AnalogChannelConfig`): one entry per analog channel, as TwidoSuite's module
  configuration screen sets it (signal type and range of each channel);
- `[pid.n]` (`parse_pid`): the PID functions, as TwidoSuite's PID screen sets them;
- `[rtc]` (`RtcConfig`, `rtc_start`): the calendar start of the clock; `[schedule.n]`
  (`ScheduleConfig`, keys 0..15, resolved by `schedules`): the schedule blocks;
- `[exch]` (`ExchConfig`, resolved by `exch_remotes`): EXCH3's timeout and remote devices
  `[exch.remote.<index>]`.

    modules = { 1 = "TWDAMM3HT", 2 = "TWDALM3LT" }
    analog."%IW1.0" = { type = "4-20mA", range = "custom", min = 0, max = 1000 }
    analog."%IW1.1" = { type = "0-10V" }                       # normal: 0..4095
    analog."%QW1.0" = { type = "0-10V" }
    analog."%IW2.0" = { type = "PT100", range = "celsius" }    # tenths of a degree
    analog."%IW0.0" = { type = "pot" }                         # the base's potentiometer

`[analog]`: channels of a configured analog module that the section does not name get the module's
first signal type and the normal range; the base's inputs get their profile type.
"""

from __future__ import annotations

from datetime import date, datetime
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from .address import Ref, parse_address
from .config_fields import Duration, exch_timeout_ok, numbered
from .errors import AddressError, ConfigCode, ConfigError, ConfigIssue
from .runtime.analog import SIGNAL_SPAN, TEMPERATURE_TYPES
from .runtime.exch import Remote
from .runtime.fastcount import MAX_COUNT, N_ZONES, CountingInputs, FastCounter, VeryFastCounter
from .runtime.pid import PidParams
from .runtime.pulse import N_MAX, RATIO_MAX, TIME_BASES_US
from .runtime.rtc import DAYS, SCHEDULE_BLOCKS, Schedule, parse_month_day, parse_time_of_day

Signal = Literal["0-10V", "4-20mA", "+-10V", "pot", "PT100", "J", "K", "T"]


class AnalogChannelConfig(BaseModel):
    """One channel: `type`, `range`, and `min`/`max` for a custom range."""

    model_config = ConfigDict(extra="forbid")

    type: Signal
    range: Literal["normal", "custom", "celsius", "fahrenheit"] = "normal"
    min: int = Field(0, ge=-32768, le=32767)
    max: int = Field(4095, ge=-32768, le=32767)

    @model_validator(mode="after")
    def _consistent(self) -> AnalogChannelConfig:
        if self.range in ("celsius", "fahrenheit") and self.type not in TEMPERATURE_TYPES:
            raise ValueError(f"range {self.range!r} is for temperature sensors "
                             f"({', '.join(TEMPERATURE_TYPES)}), not {self.type}")
        if self.range == "custom" and self.min == self.max:
            raise ValueError("a custom range needs min != max")
        if self.range != "custom" and {"min", "max"} & self.model_fields_set:
            raise ValueError("min/max apply to range = \"custom\" only")
        return self


assert set(SIGNAL_SPAN) == set(Signal.__args__)  # one list of signal types


Word = str  # an address, checked when the PLC resolves it
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
    output_min: int = Field(0, ge=0, le=10000)
    output_max: int = Field(10000, ge=0, le=10000)
    action: Literal["reverse", "direct"] = "reverse"
    manual: Word | None = None
    manual_output: WordOrConst = 0
    pwm_output: Word | None = None
    pwm_period: int = Field(100, ge=1, le=32767)
    diagnostic: Word | None = None
    at_output: int = Field(10000, ge=1, le=10000)
    at_timeout: float = Field(14400.0, gt=0, le=86400)  # seconds
    measure_span: int = Field(10000, ge=1, le=32767)

    @model_validator(mode="after")
    def _limits(self) -> PidConfig:
        if self.output_min > self.output_max:
            raise ValueError("output_min > output_max")
        return self


def _validated(section: str, key: str, model: type[BaseModel], table: Any) -> Any:
    try:
        return model.model_validate(table)
    except ValidationError as e:
        # a `str | int` field reports one error per member: the range one says more
        err = min(e.errors(), key=lambda x: x["type"].endswith("_type"))
        where = ".".join(str(p) for p in err["loc"]
                         if not str(p).startswith(("str", "int", "constrained-")))
        path = ".".join(p for p in (section, key, where) if p)
        msg = err["msg"].removeprefix("Value error, ")
        raise ConfigError(f"{path}: {msg} (got {err.get('input')!r})") from None


def parse_pid(section: Any) -> dict[int, PidConfig]:
    """Validate the `[pid]` table: PID number -> its config."""
    if not isinstance(section, dict):
        raise ConfigError(f"pid must be a table of PID functions, not {section!r}")
    out = {}
    for key, table in section.items():
        try:
            n = int(key)
        except ValueError:
            raise ConfigError(f"pid: {key!r} is not a PID number (pid.0, pid.1 ...)") from None
        out[n] = _validated("pid", str(key), PidConfig, table)
    return out


def _problem(where: str, key: str, message: str,
             code: ConfigCode = ConfigCode.ADDRESS) -> ConfigError:
    return ConfigError(ConfigIssue(f"{where}.{key}", message, code))


def _address(where: str, key: str, text: str, mem: Any) -> Ref:
    try:
        return parse_address(text, mem.profile)
    except AddressError as e:
        raise _problem(where, key, str(e)) from None


def _word(where: str, key: str, v: Any, mem: Any, writable: bool = False) -> Any:
    """A constant stays an int; an address must be a single 16-bit word."""
    if v is None or isinstance(v, int):
        return v
    ref = _address(where, key, v, mem)
    if ref.type != "int16" or ref.length is not None or ref.offset is not None:
        raise _problem(where, key, f"{v!r} is not a word (%MW, %IW, %QW...)")
    if writable and not ref.writable:
        raise _problem(where, key, f"{v!r} cannot be written", ConfigCode.VALUE)
    return ref


def _bit(where: str, key: str, v: Any, mem: Any, kinds: tuple[str, ...]) -> Ref | None:
    if v is None:
        return None
    ref = _address(where, key, v, mem)
    if ref.kind not in kinds or ref.type != "bool" or ref.length is not None:
        raise _problem(where, key, f"{v!r} is not a {'/'.join('%' + k for k in kinds)} bit")
    if ref.kind == "Q":
        mem.use_io(ref)
    return ref


def pid_params(where: str, o: PidConfig, mem: Any, scan_period_s: float) -> PidParams:
    """A validated `[pid.n]` table resolved against the memory image."""
    measure = _word(where, "measure", o.measure, mem)
    return PidParams(
        measure=measure, setpoint=_word(where, "setpoint", o.setpoint, mem),
        output=_word(where, "output", o.output, mem, True),
        kp=_word(where, "kp", o.kp, mem, True), ti=_word(where, "ti", o.ti, mem, True),
        td=_word(where, "td", o.td, mem, True), ts_us=o.ts * 10_000,
        out_min=o.output_min, out_max=o.output_max, action=o.action, mode=o.mode,
        manual=_bit(where, "manual", o.manual, mem, ("M", "I", "Q")),
        manual_output=_word(where, "manual_output", o.manual_output, mem),
        pwm_output=_bit(where, "pwm_output", o.pwm_output, mem, ("Q",)),
        pwm_period_us=o.pwm_period * 10_000,
        diagnostic=_word(where, "diagnostic", o.diagnostic, mem, True),
        at_output=o.at_output, at_timeout_us=round(o.at_timeout * 1e6),
        measure_span=o.measure_span, period_us=round(scan_period_s * 1e6))


class RtcConfig(BaseModel):
    """`[rtc] start`: the calendar date and time at PLC time 0 (a TOML date-time or an
    ISO string); without it, the virtual clock starts on 2000-01-01 00:00:00 and the real
    clock on the host's local time."""

    model_config = ConfigDict(extra="forbid")

    start: datetime | date | None = None


Day = Literal["mon", "tue", "wed", "thu", "fri", "sat", "sun"]


class ScheduleConfig(BaseModel):
    """A schedule block: `output` is 1 from `start` to `stop` ("HH:MM") on `days`, from
    the date `first` to `last` ("MM-DD")."""

    model_config = ConfigDict(extra="forbid")

    output: Word
    start: str
    stop: str
    days: list[Day] = list(DAYS)
    first: str = "01-01"
    last: str = "12-31"

    @field_validator("start", "stop", "first", "last")
    @classmethod
    def _when(cls, v: str, info: Any) -> str:
        parse, form = ((parse_time_of_day, "a time of day \"HH:MM\"")
                       if info.field_name in ("start", "stop")
                       else (parse_month_day, "a date \"MM-DD\""))
        try:
            parse(v)
        except ValueError:
            raise ValueError(f"{form}, not {v!r}") from None
        return v


ScheduleNumber = numbered(0, SCHEDULE_BLOCKS - 1, "schedule blocks are {lo} .. {hi}")


def rtc_start(o: RtcConfig | None) -> datetime | None:
    """The calendar date-time at PLC time 0 that `[rtc]` gives (None: the default)."""
    if o is None:
        return None
    if isinstance(o.start, datetime):
        return o.start.replace(tzinfo=None)
    if isinstance(o.start, date):
        return datetime(o.start.year, o.start.month, o.start.day)
    return None


def schedule(n: int, o: ScheduleConfig, mem: Any) -> Schedule:
    """A validated `[schedule.n]` block with its output bit resolved."""
    ref = _bit(f"schedule.{n}", "output", o.output, mem, ("Q", "M"))
    return Schedule(n, ref, parse_time_of_day(o.start), parse_time_of_day(o.stop),
                    frozenset(DAYS.index(d) for d in o.days),
                    parse_month_day(o.first), parse_month_day(o.last))


# ---- pulse outputs (issue 11 B): [pls] and [pwm] ---------------------------------------------
PulseBase = Literal["0.142ms", "0.57ms", "10ms", "1s"]
assert set(PulseBase.__args__) == set(TIME_BASES_US)  # one list of time bases


class PlsConfig(BaseModel):
    """`pls."%PLSi"`: what TwidoSuite's configuration of %Q0.i as a pulse generator sets:
    the time base, the period preset (%PLSi.P) and the number of pulses (%PLSi.N, 0 = no
    limit) [manual, from memory]. The preset's range depends on the base (checked by the
    block)."""

    model_config = ConfigDict(extra="forbid")

    base: PulseBase = "10ms"
    preset: int = Field(0, ge=0, le=32767)
    pulses: int = Field(0, ge=0, le=N_MAX)


class PwmConfig(BaseModel):
    """`pwm."%PWMi"`: time base, period preset (%PWMi.P), initial ratio (%PWMi.R, %)."""

    model_config = ConfigDict(extra="forbid")

    base: PulseBase = "10ms"
    preset: int = Field(0, ge=0, le=32767)
    ratio: int = Field(0, ge=0, le=RATIO_MAX)


def parse_pulse(kind: str, section: Any) -> dict[str, BaseModel]:
    """Validate `[pls]` or `[pwm]` (kind "PLS" / "PWM"): block address -> its config."""
    name = kind.lower()
    if not isinstance(section, dict):
        raise ConfigError(f"{name} must be a table of %{kind} blocks, not {section!r}")
    model = PlsConfig if kind == "PLS" else PwmConfig
    return {addr: _validated(name, f'"{addr}"', model, table)
            for addr, table in section.items()}
# ---- fast counters %FC / %VFC (runtime/fastcount.py) ---------------------------------------
class FastCounterConfig(BaseModel):
    """`[fast_counters."%FCi"]`, as TwidoSuite's fast counter screen: type and preset."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["up", "down"] = "up"
    preset: int = Field(MAX_COUNT, ge=0, le=MAX_COUNT)


class VeryFastCounterConfig(BaseModel):
    """`[very_fast_counters."%VFCi"]`: mode, preset, thresholds, the optional preset and
    catch inputs, the reflex outputs' state in the zones (V < S0, S0 <= V < S1, V >= S1),
    the frequency meter's time base."""

    model_config = ConfigDict(extra="forbid")

    mode: Literal["up", "down", "up_down", "quadrature", "frequency"] = "up"
    preset: int = Field(0, ge=0, le=MAX_COUNT)
    s0: int = Field(MAX_COUNT, ge=0, le=MAX_COUNT)
    s1: int = Field(MAX_COUNT, ge=0, le=MAX_COUNT)
    preset_input: bool = False
    catch_input: bool = False
    reflex0: list[Literal[0, 1]] | None = Field(None, min_length=N_ZONES, max_length=N_ZONES)
    reflex1: list[Literal[0, 1]] | None = Field(None, min_length=N_ZONES, max_length=N_ZONES)
    time_base: Literal["100ms", "1s"] = "1s"


def _counter_ref(section: str, key: str, kind: str, mem: Any) -> Ref:
    ref = _address(section, f'"{key}"', key, mem)
    if ref.kind != kind or not ref.is_block:
        raise ConfigError(f'{section}."{key}": {key!r} is not a %{kind} counter (%{kind}0 ..)')
    return ref


def build_counters(fc: Any, vfc: Any, mem: Any) -> CountingInputs | None:
    """Validate `[fast_counters]` and `[very_fast_counters]`, create the blocks in
    `mem.blocks` on the profile's inputs (an input used by two counters is an error) and
    return the `CountingInputs` the sources feed (None: no counter configured)."""
    for name, section in (("fast_counters", fc), ("very_fast_counters", vfc)):
        if not isinstance(section, dict):
            raise ConfigError(f"{name} must be a table of counters, not {section!r}")
    if not fc and not vfc:
        return None
    profile = mem.profile
    hub = CountingInputs(mem.i_field)
    owner: dict[int, str] = {}  # %I0.x channel -> what uses it

    def claim(channel: int, who: str) -> int:
        if channel in owner:
            raise ConfigError(f"{who}: input %I0.{channel} is already {owner[channel]}")
        owner[channel] = who
        return channel  # base inputs: flat index = channel

    for key, table in fc.items():
        ref = _counter_ref("fast_counters", key, "FC", mem)
        o = _validated("fast_counters", key, FastCounterConfig, table)
        wiring = profile.fast_counters[ref.index]
        where = f'fast_counters."{key}"'
        mem.blocks["FC"][ref.index] = FastCounter(o.mode, o.preset, wiring.max_hz)
        hub.attach(mem.blocks["FC"][ref.index], claim(wiring.input, f"{where} (counting)"))
    for key, table in vfc.items():
        ref = _counter_ref("very_fast_counters", key, "VFC", mem)
        o = _validated("very_fast_counters", key, VeryFastCounterConfig, table)
        w = profile.very_fast_counters[ref.index]
        where = f'very_fast_counters."{key}"'
        outputs = tuple(None if z is None else (mem.q, mem.q_field, w.reflex[k])
                        for k, z in enumerate((o.reflex0, o.reflex1)))
        c = VeryFastCounter(o.mode, o.preset, o.s0, o.s1, w.max_hz,
                            100 if o.time_base == "100ms" else 1000,
                            (o.reflex0 and tuple(o.reflex0), o.reflex1 and tuple(o.reflex1)),
                            outputs, hub.events, str(ref))
        mem.blocks["VFC"][ref.index] = c
        two_inputs = o.mode in ("up_down", "quadrature")
        hub.attach(c, claim(w.pulse, f"{where} (pulses / phase A)"),
                   claim(w.direction, f"{where} (direction / phase B)") if two_inputs else None)
        hub.attach_vfc(c, claim(w.preset, f"{where} (preset input)") if o.preset_input else None,
                       claim(w.catch, f"{where} (catch input)") if o.catch_input else None)
    for channel in owner:
        mem.use_io(parse_address(f"%I0.{channel}", profile))
    return hub


# ---- communication (issue 11 B): [exch], the Ethernet port's remote devices ---------------
class ExchRemoteConfig(BaseModel):
    """One row of TwidoSuite's Ethernet remote-device table (`[exch.remote.<index>]`)."""

    model_config = ConfigDict(extra="forbid")

    host: str = Field(min_length=1, max_length=253)  # a DNS name has at most 253 characters
    port: int = Field(502, ge=1, le=65535)
    unit_id: int = Field(255, ge=0, le=255)  # 255: a Twido server's default [manual]


RemoteIndex = numbered(1, lambda p: p.count("EXCH_REMOTES"), "the remote device index is "
                       "{lo} .. {hi} (the first byte of the EXCH table)")


class ExchConfig(BaseModel):
    """`[exch]`: EXCH3 as a Modbus TCP client. `timeout` in seconds (or "500ms")."""

    model_config = ConfigDict(extra="forbid")

    timeout: Annotated[Duration, AfterValidator(exch_timeout_ok)] = 1.0
    remote: dict[RemoteIndex, ExchRemoteConfig] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _some_remote(self) -> ExchConfig:
        if not self.remote:
            raise ValueError("no remote device in exch.remote (e.g. [exch.remote.1] "
                             "host = ...)")
        return self


def exch_remotes(cfg: ExchConfig) -> dict[int, Remote]:
    """The validated `[exch]` remote devices: index -> Remote."""
    return {n: Remote(r.host, r.port, r.unit_id) for n, r in cfg.remote.items()}
