"""Pydantic v2 models of the configuration sections added by issue 11, each with
`extra="forbid"` (a misspelt key is an error). `softplc.config.Config` types its sections
with them, so every problem is reported at once with its key path and code:

- `[analog]` (`AnalogChannelConfig`): one entry per analog channel, as TwidoSuite's module
  configuration screen sets it (signal type and range of each channel);
- `[rtc]` (`RtcConfig`, `rtc_start`): the calendar start of the clock; `[schedule.n]`
  (`ScheduleConfig`, keys 0..15, resolved by `schedules`): the schedule blocks;
- `[exch]` (`ExchConfig`, resolved by `exch_remotes`): EXCH3's timeout and remote devices
  `[exch.remote.<index>]`;
- `[remote_link]` (`RemoteLinkConfig`): this controller on the Twido Remote Link, its
  address (0: the master) and role (a peer or a remote I/O controller) and, on the master,
  the remotes it polls (`remotes = { 1 = "peer", 3 = "remote_io" }`) and its link cycle.

The function blocks' sections (`[pid.n]`, `[pls]`, `[pwm]`, `[fast_counters]`,
`[very_fast_counters]`) have their models in their runtime modules, named by their catalog
entries (`softplc/twido/catalog.py`), and `softplc/assembly/blocks.py` sets them up.

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

from softplc.config.fields import Duration, PositiveDuration, exch_timeout_ok, numbered
from softplc.errors import AddressError, ConfigCode, ConfigError, ConfigIssue
from softplc.runtime.analog import SIGNAL_SPAN, TEMPERATURE_TYPES
from softplc.runtime.exch import Remote
from softplc.runtime.remotelink import MASTER, PEER
from softplc.runtime.rtc import DAYS, SCHEDULE_BLOCKS, Schedule, parse_month_day, parse_time_of_day
from softplc.twido.address import LINK_STATIONS, Ref, parse_address

Word = str  # an address, checked when it is resolved
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


# ---- the Twido Remote Link (issue 35) -----------------------------------------------------
RemoteAddress = numbered(1, LINK_STATIONS - 1, "a remote's address is {lo} .. {hi}")
# a peer (its own program, 4 words each way) or a remote I/O controller (no program: the
# master's %Ix.0.z / %Qx.0.z are its base I/O) [remote-link.md A1, A2]
RemoteType = Literal["peer", "remote_io"]


class RemoteLinkConfig(BaseModel):
    """`[remote_link]`: this controller on the Remote Link. `address` 0 is the master
    [remote-link.md A1]; it declares its `remotes` by address and type, as TwidoSuite's
    master configuration does [A6, from memory]; `cycle`: the master's link cycle (default
    one slot per remote, softplc.runtime.remotelink.default_cycle_us)."""

    model_config = ConfigDict(extra="forbid")

    address: int = Field(ge=0, le=LINK_STATIONS - 1)
    role: Literal["master", "peer", "remote_io"] | None = None  # implied by the address
    remotes: dict[RemoteAddress, RemoteType] = Field(default_factory=dict)
    cycle: PositiveDuration | None = None

    @model_validator(mode="after")
    def _consistent(self) -> RemoteLinkConfig:
        master = self.address == MASTER
        if self.role is not None and (self.role == "master") != master:
            raise ValueError(f"role {self.role!r} does not go with address {self.address} "
                             f"(the master is address 0, remotes 1 .. {LINK_STATIONS - 1})")
        if master and not self.remotes:
            raise ValueError("the master declares its remotes, e.g. remotes = { 1 = \"peer\" }")
        if not master and (self.remotes or self.cycle is not None):
            raise ValueError("remotes and cycle are the master's (address 0) settings")
        return self

    @property
    def kind(self) -> str:
        """"master" or the remote's type."""
        return "master" if self.address == MASTER else (self.role or PEER)
