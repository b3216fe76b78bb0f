"""Configuration: a dict or a TOML file with the same keys, checked against one typed schema.

    scan_period = "10ms"     # virtual scan length / periodic-mode period
    watchdog = "150ms"       # %SW11
    profile = "TWDLCAE40DRF"
    timers."%TM0" = { type = "TON", base = "10ms", preset = 50 }
    counters."%C0" = { preset = 10 }
    drums."%DR0" = { steps = [1, 2, 4], outputs = ["%Q0.0", "%Q0.1", "%Q0.2"] }
    registers."%R0" = { type = "FIFO" }
    constants = { "%KW0" = 100, "%KF2" = 1.5 }
    modules = { 1 = "TM2DDO8TT" }    # expansion modules; when given, I/O addresses are checked
    analog."%IW2.0" = { type = "PT100", range = "celsius" }   # analog channels
    [pid.0]                  # PID functions (runtime/pid.py), [rtc] the clock's calendar
    [schedule.0]             # start, schedule blocks: see softplc/config_models.py
    pls."%PLS0" = { base = "10ms", preset = 10, pulses = 200 }   # pulse outputs on %Q0.0/1
    pwm."%PWM1" = { base = "10ms", preset = 100, ratio = 0 }    # (runtime/pulse.py)
    [fast_counters."%FC0"]   # fast counters, [very_fast_counters."%VFC0"]: runtime/fastcount.py
    [exch.remote.1]          # EXCH3's remote devices: host, port, unit_id; [exch] timeout
    [devices.NAME]           # simulated machine (softplc.devices): type = "...", options
    [modbus]                 # the daemon's server options (softplc run)
    [daemon]                 # the daemon's state file, save and statistics intervals
    [web]                    # the web monitor: allowed_hosts, max_pages (softplc run)

The schema is the pydantic model `Config` below (device options: each device class's
`Options` model, looked up by `type`). Every problem found is reported at once, as
`key.path: what is wrong (got VALUE)`, in one `ConfigError`. Durations are strings with a
unit ("10ms", "1.5s", "1min", "200us"): a bare number is refused, since `scan_period = 10`
could mean 10 ms or 10 s. What the schema cannot know (whether an address exists in the
profile, whether a device names another device of the machine) is checked where it is used,
with the same kind of message.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    create_model,
    field_validator,
)

from . import catalog
from .errors import ConfigError, SoftPLCError
from .profile import DEFAULT_PROFILE, PROFILES
from .runtime.blocks import MAX_VALUE, TIME_BASES_US
from .symbols import SymbolTable
from .symbols import from_config as symbols_from_config

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


def _parse_time_base(value: Any) -> str:
    s = _parse_duration(value)
    for name, us in TIME_BASES_US.items():
        if abs(s * 1e6 - us) < 1e-3:
            return name
    raise ValueError(f"one of {', '.join(TIME_BASES_US)}")


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
TimeBase = Annotated[str, BeforeValidator(_parse_time_base)]
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


class TimerConfig(Section):
    type: Literal["TON", "TOF", "TP"] = "TON"
    base: TimeBase = "1s"
    preset: int = Field(0, ge=0, le=MAX_VALUE)


class CounterConfig(Section):
    preset: int = Field(MAX_VALUE, ge=0, le=MAX_VALUE)


class DrumConfig(Section):
    steps: list[Annotated[int, Field(ge=0, le=0xFFFF)]] = Field(
        default_factory=lambda: [0], min_length=1, max_length=DRUM_STEPS)
    outputs: list[Address] = Field(default_factory=list)


class RegisterConfig(Section):
    type: Literal["FIFO", "LIFO"] = "FIFO"


class ModbusConfig(Section):
    """`[modbus]`: the daemon's server (softplc run)."""

    host: str = "127.0.0.1"
    port: int = Field(5020, ge=0, le=65535)
    read_only: list[Address] | Address = Field(default_factory=list)
    allow: list[str] | str | None = None  # client addresses/networks (the daemon's --allow)
    max_clients: int = Field(32, ge=1, le=MAX_CLIENTS)
    frame_timeout: Annotated[Duration, AfterValidator(frame_timeout_ok)] = 2.0
    # seconds without a complete request; 0 = never (softplc.modbus.server)
    idle_timeout: Annotated[Duration, AfterValidator(idle_timeout_ok)] = 60.0


class DaemonConfig(Section):
    """`[daemon]`: state file and intervals (softplc run)."""

    state: str | None = Field(None, min_length=1)
    save_interval: Interval = 5.0
    stats_interval: Interval = 60.0  # = softplc.daemon.DaemonOptions; SIGUSR1: one now
    rt_priority: int = Field(10, ge=0, le=99)
    # a %M bit the program sets while it waits for its host: with --speed the daemon holds
    # the virtual clock meanwhile (deterministic runs; softplc.daemon)
    host_wait: Address | None = None


class WebConfig(Section):
    """`[web]`: the web monitor (softplc run; the command line's --web-* options win)."""

    allowed_hosts: list[str] = Field(default_factory=list)  # Host names besides loopback's
    max_pages: int = Field(32, ge=1, le=1000)  # websocket pages open at once


class DeviceSection(BaseModel):
    """`[devices.NAME]`: `type` picks the device class, whose `Options` model checks the rest
    (see `validate_config`); `options` is that validated model."""

    model_config = ConfigDict(extra="allow", strict=True)
    type: str
    _options: Any = PrivateAttr(None)

    @property
    def options(self) -> Any:
        return self._options


def _str_keys(v: Any) -> Any:
    # TOML keys are strings; a Python dict may say {1: "TM2DDO8TT"}
    return {str(k): x for k, x in v.items()} if isinstance(v, dict) else v


# The function blocks' sections typed by their catalog entries' models ([pid], [pls], [pwm],
# [fast_counters], ...: softplc/catalog.py); addresses are resolved when the blocks are set up.
_BlockSections = create_model(  # type: ignore[call-overload]
    "_BlockSections", __base__=Section,
    **{f.section: (Annotated[dict[str, f.config_model()], BeforeValidator(_str_keys)],
                   Field(default_factory=dict))
       for f in catalog.FAMILIES.values() if f.model})


class Config(_BlockSections):  # type: ignore[misc, valid-type]
    """The whole machine/PLC configuration."""

    name: str = ""
    description: str = ""
    scan_period: Annotated[Duration, _at_least(MIN_SCAN_PERIOD_S, "a scan period")] = 0.010
    # None: the controller's default (engine)
    watchdog: Annotated[Duration, _at_least(MIN_WATCHDOG_S, "the watchdog")] | None = None
    profile: str = DEFAULT_PROFILE.name
    timers: dict[str, TimerConfig] = Field(default_factory=dict)
    counters: dict[str, CounterConfig] = Field(default_factory=dict)
    drums: dict[str, DrumConfig] = Field(default_factory=dict)
    registers: dict[str, RegisterConfig] = Field(default_factory=dict)
    constants: dict[str, int | FiniteFloat] = Field(default_factory=dict)
    modules: Annotated[dict[str, str] | None, BeforeValidator(_str_keys)] = None
    devices: dict[str, DeviceSection] = Field(default_factory=dict)
    modbus: ModbusConfig = Field(default_factory=ModbusConfig)
    daemon: DaemonConfig = Field(default_factory=DaemonConfig)
    web: WebConfig = Field(default_factory=WebConfig)
    # controller functions: checked by their own models in softplc/config_models.py when the
    # PLC builds them (they need the profile and the memory image to resolve addresses)
    analog: dict[str, Any] = Field(default_factory=dict)
    rtc: dict[str, Any] | None = None
    schedule: dict[str, Any] = Field(default_factory=dict)
    exch: dict[str, Any] = Field(default_factory=dict)  # EXCH3 remote devices (issue 11 B)
    # names for addresses: checked by softplc.symbols (the parser needs them first)
    symbols: dict[str, Any] = Field(default_factory=dict)
    symbols_file: str | None = None

    @field_validator("profile")
    @classmethod
    def _known_profile(cls, v: str) -> str:
        if v not in PROFILES:
            raise ValueError(f"unknown profile; known: {', '.join(PROFILES)}")
        return v


# ---- error messages ------------------------------------------------------------------------------
_IDENT = re.compile(r"^[A-Za-z0-9_-]+$")  # a TOML bare key


def key_path(loc: tuple[Any, ...]) -> str:
    """('timers', '%TM0', 'preset') -> 'timers."%TM0".preset'; list indexes as [2]."""
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            s = part if _IDENT.match(part) else f'"{part}"'
            out += f".{s}" if out else s
    return out or "(top level)"


def _known_keys(t: Any, loc: tuple[Any, ...]) -> list[str]:
    """The keys the table at `loc` of schema type `t` accepts (walks the schema)."""
    import types
    import typing

    while typing.get_origin(t) is typing.Annotated:
        t = typing.get_args(t)[0]
    if typing.get_origin(t) in (typing.Union, types.UnionType):
        for member in typing.get_args(t):
            if known := _known_keys(member, loc):
                return known
        return []
    is_model = isinstance(t, type) and issubclass(t, BaseModel)
    if not loc:
        return sorted(t.model_fields) if is_model else []
    part, rest = loc[0], loc[1:]
    if is_model:
        f = t.model_fields.get(part) if isinstance(part, str) else None
        return _known_keys(f.annotation, rest) if f is not None else []
    if typing.get_origin(t) is dict:
        return _known_keys(typing.get_args(t)[1], rest)
    if typing.get_origin(t) is list:
        return _known_keys(typing.get_args(t)[0], rest)
    return []


def _tag_positions(t: Any, loc: tuple[Any, ...], disc: str | None = None) -> set[int]:
    """Indexes in `loc` that are the tags pydantic inserts for a discriminated union
    (`Field(discriminator="kind")`): ('op', 0, 'line', 'to') -> {2}. Walks the schema."""
    import types
    import typing

    while typing.get_origin(t) is typing.Annotated:
        t, *meta = typing.get_args(t)
        disc = next((m.discriminator for m in meta if getattr(m, "discriminator", None)), disc)
    if not loc:
        return set()
    if typing.get_origin(t) in (typing.Union, types.UnionType):
        if disc is None:
            return set()
        for member in typing.get_args(t):
            f = getattr(member, "model_fields", {}).get(disc)
            if f is not None and loc[0] in typing.get_args(f.annotation):
                return {0} | {i + 1 for i in _tag_positions(member, loc[1:])}
        return set()
    inner: Any = None
    if isinstance(t, type) and issubclass(t, BaseModel):
        f = t.model_fields.get(loc[0]) if isinstance(loc[0], str) else None
        if f is None:
            return set()
        inner, disc = f.annotation, f.discriminator if isinstance(f.discriminator, str) else None
    elif typing.get_origin(t) is dict:
        inner = typing.get_args(t)[1]
    elif typing.get_origin(t) is list:
        inner = typing.get_args(t)[0]
    if inner is None:
        return set()
    return {i + 1 for i in _tag_positions(inner, loc[1:], disc)}


def _short(value: Any) -> str:
    s = repr(value)
    return s if len(s) <= 60 else s[:57] + "..."


def error_lines(e: ValidationError, model: type[BaseModel],
                prefix: tuple[Any, ...] = ()) -> list[str]:
    """One line per problem: `key.path: message (got VALUE)`."""
    by_path: dict[str, str] = {}
    for err in e.errors(include_url=False):
        loc = tuple(err["loc"])
        # a `X | Y` field reports the loc through the member tried: drop type names
        loc = tuple(p for p in loc if not (isinstance(p, str) and
                                           (p in ("int", "float", "str", "bool")
                                            or p.startswith(("function-", "list[", "dict[",
                                                             "constrained-")))))
        tags = _tag_positions(model, loc)
        loc = tuple(p for i, p in enumerate(loc) if i not in tags)
        path = key_path(prefix + loc)
        kind = err["type"]
        msg = err["msg"]
        if kind == "union_tag_invalid":  # a discriminated union (a piece's op kind)
            ctx = err["ctx"]
            by_path[path] = (f"unknown {ctx['discriminator'].strip(chr(39))} {ctx['tag']!r}; "
                             f"expected {ctx['expected_tags'].replace(chr(39), '')}")
            continue
        if kind == "union_tag_not_found":
            by_path[path] = f"missing {err['ctx']['discriminator']}"
            continue
        if kind == "extra_forbidden":
            known = _known_keys(model, loc[:-1])
            by_path[path] = "unknown key" + (f"; known: {', '.join(known)}" if known else "")
            continue
        if kind == "missing":
            by_path[path] = "required key missing"
            continue
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, "):]
        if msg.startswith("Input should be "):
            msg = "expected " + msg[len("Input should be "):]
        if re.match(r"[A-Z][a-z]+ should ", msg):  # pydantic's "List should ...", not "Ixx30 ..."
            msg = msg[0].lower() + msg[1:]
        if kind in ("dict_type", "model_type"):
            msg = "expected a table"
        elif kind == "list_type":
            msg = "expected a list"
        got = f" (got {_short(err['input'])})"
        if path in by_path:  # a union (`int | float`) reports one problem per member
            by_path[path] = by_path[path][:-len(got)] + " or " + \
                msg.removeprefix("expected ") + got
        else:
            by_path[path] = f"{msg}{got}"
    # a union (`list[str] | str`) that failed inside its list member also says the list is
    # not a string: the deeper problem is the one to show
    return [f"{p}: {m}" for p, m in by_path.items()
            if not any(q.startswith((p + "[", p + ".")) for q in by_path)]


def validate_config(raw: Any, device_types: Mapping[str, Any] | None = None) -> Config:
    """Check a whole configuration. `device_types` maps a device `type` to its class (with an
    `Options` model); given, every `[devices.NAME]` table is checked against it too."""
    lines: list[str] = []
    try:
        cfg = Config.model_validate(raw)
    except ValidationError as e:
        lines = error_lines(e, Config)
        cfg = None
    if device_types is not None:
        devices = raw.get("devices") if isinstance(raw, dict) else None
        for name, section in (devices.items() if isinstance(devices, dict) else ()):
            if not isinstance(section, dict) or not isinstance(section.get("type"), str):
                continue  # reported by the schema above
            cls = device_types.get(section["type"])
            where = ("devices", name)
            if cls is None:
                lines.append(f"{key_path(where + ('type',))}: unknown device type "
                             f"{section['type']!r}; known: {', '.join(sorted(device_types))}")
                continue
            opts = {k: v for k, v in section.items() if k != "type"}
            try:
                model = cls.Options.model_validate(opts)
            except ValidationError as e:
                lines += error_lines(e, cls.Options, where)
                continue
            if cfg is not None:
                cfg.devices[name]._options = model
    if lines:
        raise ConfigError("\n".join(lines))
    assert cfg is not None
    return cfg


def read_config(config: str | Path | dict[str, Any] | None) -> tuple[dict[str, Any], Path | None]:
    """The raw configuration (TOML parsed) and the folder of its file for relative paths."""
    if config is None:
        return {}, None
    if isinstance(config, dict):
        return dict(config), None
    p = Path(config)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{p}: no such file") from None
    except OSError as e:
        raise ConfigError(f"cannot read config {p}: {e.strerror}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{p}: not a UTF-8 text file") from None
    try:
        return tomllib.loads(text), p.parent
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{p}: {e}") from None


def load_config(config: str | Path | dict[str, Any] | None,
                device_types: Mapping[str, Any] | None = None,
                ) -> tuple[dict[str, Any], Path | None, Config]:
    """(raw dict, folder of the config file, validated `Config`). Raises ConfigError naming
    the file and every wrong key."""
    raw, base = read_config(config)
    try:
        cfg = validate_config(raw, device_types)
    except ConfigError as e:
        if base is not None:
            raise ConfigError(f"{config}:\n  " + str(e).replace("\n", "\n  ")) from None
        raise
    return raw, base, cfg


def symbol_table(config: str | Path | dict[str, Any] | None) -> SymbolTable | None:
    """The configuration's symbols, for the parser (which runs before the PLC is built);
    None if the configuration cannot be read (the PLC reports that after the program's own
    errors). A wrong symbol declaration is a ConfigError naming the file: reported first,
    since every name of the program would be an error without it."""
    try:
        raw, base = read_config(config)
    except SoftPLCError:
        return None
    profile = PROFILES.get(str(raw.get("profile", DEFAULT_PROFILE.name)), DEFAULT_PROFILE)
    try:
        return symbols_from_config(raw, base, profile)
    except ConfigError as e:
        raise ConfigError(f"{config}: {e}" if isinstance(config, (str, Path)) else str(e)
                          ) from None
