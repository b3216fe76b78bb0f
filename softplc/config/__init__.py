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
    [schedule.0]             # start, schedule blocks: see softplc/config/models.py
    pls."%PLS0" = { base = "10ms", preset = 10, pulses = 200 }   # pulse outputs on %Q0.0/1
    pwm."%PWM1" = { base = "10ms", preset = 100, ratio = 0 }    # (runtime/pulse.py)
    [fast_counters."%FC0"]   # fast counters, [very_fast_counters."%VFC0"]: runtime/fastcount.py
    [exch.remote.1]          # EXCH3's remote devices: host, port, unit_id; [exch] timeout
    [remote_link]            # Remote Link: address (0 master), remotes = { 1 = "peer" }, cycle
    [devices.NAME]           # simulated machine (softplc.devices): type = "...", options
    [modbus]                 # the daemon's server options (softplc run)
    [daemon]                 # the daemon's state file, save and statistics intervals
    [web]                    # the web monitor: allowed_hosts, max_pages (softplc run)

The schema is the pydantic model `Config` below (device options: each device class's
`Options` model, looked up by `type`; field types in `config_fields.py`, section models in
`config_models.py`). Every problem found is reported at once, as `key.path: what is wrong
(got VALUE)`, in one `ConfigError` whose `issues` give each its path and `ConfigCode`.
Durations are strings with a unit ("10ms", "1.5s", "1min", "200us"): a bare number is
refused, since `scan_period = 10` could mean 10 ms or 10 s. Numbered keys (`[schedule.3]`,
`[exch.remote.1]`, module slots) are checked against the profile (`validate_config` passes
it as the validation context). What needs the memory image (whether an address exists in
the profile, a channel a module provides) is checked by the machine builder
(`softplc.assembly`), which collects its problems the same way; `read_toml` is the one reader
of TOML files (machines, pieces, rigs).
"""

from __future__ import annotations

import ipaddress
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
)
from pydantic_core import PydanticCustomError

from softplc.config.fields import (  # noqa: F401  (the field types devices import from here)
    MAX_CLIENTS,
    MAX_DURATION_S,
    MIN_INTERVAL_S,
    MIN_SCAN_PERIOD_S,
    MIN_WATCHDOG_S,
    Address,
    Duration,
    FiniteFloat,
    InfFloat,
    Interval,
    PositiveDuration,
    Section,
    _at_least,
    _parse_duration,
    between,
    check_interval,
    duration,
    exch_timeout_ok,
    frame_timeout_ok,
    idle_timeout_ok,
    numbered,
    profile_of,
)
from softplc.config.models import (
    AnalogChannelConfig,
    ExchConfig,
    RemoteLinkConfig,
    RtcConfig,
    ScheduleConfig,
    ScheduleNumber,
)
from softplc.errors import AddressError, ConfigCode, ConfigError, ConfigIssue
from softplc.limits import MAX_CONFIG_BYTES, BoundsError, check_toml, decode_text, read_bytes
from softplc.twido import catalog
from softplc.twido.address import parse_address
from softplc.twido.profile import ANALOG_MODULES, DEFAULT_PROFILE, MODULES, PROFILES


def _network(text: str) -> str:
    try:
        ipaddress.ip_network(text.strip(), strict=False)
    except ValueError:
        raise ValueError("not an IP address or network (e.g. 192.168.1.0/24, 10.0.0.5, ::1)"
                         ) from None
    return text


def _memory_bit(text: str, info: ValidationInfo) -> str:
    try:
        ref = parse_address(text, profile_of(info))
    except AddressError as e:
        raise ValueError(str(e)) from None
    if ref.kind != "M" or ref.bit is not None or ref.length is not None or ref.offset:
        raise ValueError(f"{text!r} is not a memory bit %Mi")
    return text


def _read_only_entry(text: str, info: ValidationInfo) -> str:
    # imported here: the Modbus package sits above the configuration (numpy, the server)
    from softplc.modbus.regmap import read_only_range

    try:
        read_only_range(text, profile_of(info))
    except ValueError as e:  # AddressError included
        raise PydanticCustomError("address", "{reason}", {"reason": str(e)}) from None
    return text


def _listed(v: Any) -> Any:
    return [v] if isinstance(v, str) else v


ReadOnlyEntry = Annotated[Address, AfterValidator(_read_only_entry)]


class ModbusConfig(Section):
    """`[modbus]`: the daemon's server (softplc run)."""

    host: str = "127.0.0.1"
    port: int = Field(5020, ge=0, le=65535)
    # ranges hosts may not write (softplc.modbus.regmap.read_only_of); one may be a string
    read_only: Annotated[list[ReadOnlyEntry], BeforeValidator(_listed)] = \
        Field(default_factory=list)
    # client addresses/networks (the daemon's --allow)
    allow: list[Annotated[str, AfterValidator(_network)]] | \
        Annotated[str, AfterValidator(_network)] | None = None
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
    host_wait: Annotated[Address, AfterValidator(_memory_bit)] | None = None

    @property
    def host_wait_bit(self) -> int | None:
        """The index i of the `host_wait` bit %Mi (checked against the profile)."""
        return None if self.host_wait is None else parse_address(self.host_wait).index


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


def _module_name(name: str) -> str:
    name = name.upper()
    if name not in MODULES and name not in ANALOG_MODULES:
        raise ValueError(f"unknown module {name!r}; known: "
                         f"{', '.join(sorted(MODULES | ANALOG_MODULES))}")
    return name


Slot = numbered(1, lambda p: p.expansion_slots, "slot {key} outside {lo}..{hi}")
ModuleName = Annotated[str, AfterValidator(_module_name)]


class SymbolEntry(Section):
    """`symbols.NAME = { address = "%I0.0", comment = "..." }` (or just the address)."""

    address: Address
    comment: str = ""


def _symbol_entry(v: Any) -> Any:
    if isinstance(v, str):
        return {"address": v}
    if not isinstance(v, dict):
        raise ValueError('"ADDRESS" or { address = "ADDRESS", comment = "..." }')
    return v


def _none_if_empty(v: Any) -> Any:
    return None if v == {} else v  # `exch = {}`: no EXCH, as if absent


# The function blocks' sections typed by their catalog entries' models ([timers], [counters],
# [drums], [registers], [pid], [pls], [pwm], [fast_counters], ...: softplc/twido/catalog.py);
# addresses are resolved when the blocks are set up.
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
    constants: dict[str, int | FiniteFloat] = Field(default_factory=dict)
    # expansion modules by slot; None: not configured (I/O addresses are not checked)
    modules: Annotated[dict[Slot, ModuleName] | None, BeforeValidator(_str_keys)] = None
    devices: dict[str, DeviceSection] = Field(default_factory=dict)
    modbus: ModbusConfig = Field(default_factory=ModbusConfig)
    daemon: DaemonConfig = Field(default_factory=DaemonConfig)
    web: WebConfig = Field(default_factory=WebConfig)
    # controller functions (softplc/config/models.py; the function blocks' sections come
    # from the catalog: _BlockSections); what needs the profile's addresses
    # and the memory image is resolved by the machine builder (softplc.assembly)
    analog: dict[str, AnalogChannelConfig] = Field(default_factory=dict)
    rtc: RtcConfig | None = None
    schedule: Annotated[dict[ScheduleNumber, ScheduleConfig], BeforeValidator(_str_keys)] = \
        Field(default_factory=dict)
    # EXCH3 remote devices (issue 11 B)
    exch: Annotated[ExchConfig | None, BeforeValidator(_none_if_empty)] = None
    # the Twido Remote Link (issue 35): this controller's address and, on the master, remotes
    remote_link: RemoteLinkConfig | None = None
    # names for addresses: softplc.twido.symbols resolves them (the parser needs them first)
    symbols: dict[str, Annotated[SymbolEntry, BeforeValidator(_symbol_entry)]] = \
        Field(default_factory=dict)
    symbols_file: str | None = Field(None, min_length=1)

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
            part = str(part)
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


def _code(kind: str) -> ConfigCode:
    """The issue code of a pydantic error type."""
    if kind == "extra_forbidden":
        return ConfigCode.UNKNOWN_KEY
    if kind == "address":  # a validator's PydanticCustomError("address", ...)
        return ConfigCode.ADDRESS
    if kind in ("missing", "union_tag_not_found"):
        return ConfigCode.MISSING_KEY
    if kind.endswith("_type") or kind in ("is_instance_of", "model_attributes_type"):
        return ConfigCode.TYPE
    return ConfigCode.VALUE


def error_issues(e: ValidationError, model: type[BaseModel],
                 prefix: tuple[Any, ...] = ()) -> list[ConfigIssue]:
    """One issue per problem: its key path, `message (got VALUE)` and code."""
    by_path: dict[str, tuple[str, ConfigCode]] = {}
    keys = set()  # paths whose table key is wrong: shown with what is wrong inside
    for err in e.errors(include_url=False):
        loc = tuple(err["loc"])
        if loc and loc[-1] == "[key]":
            keys.add(key_path(prefix + loc[:-1]))
        # a `X | Y` field reports the loc through the member tried: drop type names; a
        # dict key's own error adds "[key]"
        loc = tuple(p for p in loc if not (isinstance(p, str) and
                                           (p in ("int", "float", "str", "bool", "[key]")
                                            or p.startswith(("function-", "list[", "dict[",
                                                             "constrained-")))))
        tags = _tag_positions(model, loc)
        loc = tuple(p for i, p in enumerate(loc) if i not in tags)
        path = key_path(prefix + loc)
        kind = err["type"]
        code = _code(kind)
        msg = err["msg"]
        if kind == "union_tag_invalid":  # a discriminated union (a piece's op kind)
            ctx = err["ctx"]
            by_path[path] = (f"unknown {ctx['discriminator'].strip(chr(39))} {ctx['tag']!r}; "
                             f"expected {ctx['expected_tags'].replace(chr(39), '')}", code)
            continue
        if kind == "union_tag_not_found":
            by_path[path] = f"missing {err['ctx']['discriminator']}", code
            continue
        if kind == "extra_forbidden":
            known = _known_keys(model, loc[:-1])
            by_path[path] = ("unknown key" + (f"; known: {', '.join(known)}" if known else ""),
                             code)
            continue
        if kind == "missing":
            by_path[path] = "required key missing", code
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
            before = by_path[path][0]
            by_path[path] = (before[:-len(got)] + " or " + msg.removeprefix("expected ") + got,
                             code)
        else:
            by_path[path] = f"{msg}{got}", code
    # a union (`list[str] | str`) that failed inside its list member also says the list is
    # not a string: the deeper problem is the one to show
    return [ConfigIssue(p, m, c) for p, (m, c) in by_path.items()
            if p in keys or not any(q.startswith((p + "[", p + ".")) for q in by_path)]


def error_lines(e: ValidationError, model: type[BaseModel],
                prefix: tuple[Any, ...] = ()) -> list[str]:
    """One line per problem: `key.path: message (got VALUE)`."""
    return [str(i) for i in error_issues(e, model, prefix)]


def validate_config(raw: Any, device_types: Mapping[str, Any] | None = None) -> Config:
    """Check a whole configuration, collecting every problem. `device_types` maps a device
    `type` to its class (with an `Options` model); given, every `[devices.NAME]` table is
    checked against it too."""
    issues: list[ConfigIssue] = []
    name = raw.get("profile") if isinstance(raw, dict) else None
    context = {"profile": PROFILES.get(name, DEFAULT_PROFILE) if isinstance(name, str)
               else DEFAULT_PROFILE}
    try:
        cfg = Config.model_validate(raw, context=context)
    except ValidationError as e:
        issues = error_issues(e, Config)
        cfg = None
    if device_types is not None:
        devices = raw.get("devices") if isinstance(raw, dict) else None
        for name, section in (devices.items() if isinstance(devices, dict) else ()):
            if not isinstance(section, dict) or not isinstance(section.get("type"), str):
                continue  # reported by the schema above
            cls = device_types.get(section["type"])
            where = ("devices", name)
            if cls is None:
                issues.append(ConfigIssue(
                    key_path(where + ("type",)), f"unknown device type {section['type']!r}; "
                    f"known: {', '.join(sorted(device_types))}", ConfigCode.DEVICE))
                continue
            opts = {k: v for k, v in section.items() if k != "type"}
            try:
                model = cls.Options.model_validate(opts)
            except ValidationError as e:
                issues += error_issues(e, cls.Options, where)
                continue
            if cfg is not None:
                cfg.devices[name]._options = model
    if issues:
        raise ConfigError(_in_file_order(issues, raw))
    assert cfg is not None
    return cfg


def _in_file_order(issues: list[ConfigIssue], raw: Any) -> list[ConfigIssue]:
    """The issues in the order their top-level keys stand in the file (the schema's own
    order otherwise: the block sections come from the catalog), one key's in the order
    found."""
    order = {key_path((k,)): i for i, k in enumerate(raw)} if isinstance(raw, dict) else {}

    def rank(issue: ConfigIssue) -> int:
        top = re.match(r'"[^"]*"|[^.\[]+', issue.path)
        return order.get(top.group(0) if top else "", len(order))

    return sorted(issues, key=rank)


def read_toml(path: str | Path) -> dict[str, Any]:
    """A TOML file's tables: the one reader of configuration files (machines, pieces, rigs).
    ConfigError (code `file`) naming the file when it cannot be read or is not TOML."""
    p = Path(path)

    def fail(what: str) -> ConfigError:
        return ConfigError(ConfigIssue("", f"{p}: {what}", ConfigCode.FILE))
    try:
        text = decode_text(read_bytes(p, MAX_CONFIG_BYTES, "the file"), "the file")
    except FileNotFoundError:
        raise fail("no such file") from None
    except OSError as e:
        raise fail(f"cannot read the file: {e.strerror or e}") from None
    except BoundsError as e:
        raise fail(str(e)) from None
    return parse_toml(text, str(p))


def parse_toml(text: str, where: str = "") -> dict[str, Any]:
    """A configuration's TOML text parsed, its depth and numbers bounded first
    (softplc.limits.check_toml): ConfigError (code `file`) at line:col otherwise. `where`:
    the file or origin named in the message."""
    prefix = f"{where}: " if where else ""
    try:
        check_toml(text)
        return tomllib.loads(text)
    except BoundsError as e:
        raise ConfigError(ConfigIssue("", f"{prefix}{e}", ConfigCode.FILE)) from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(ConfigIssue("", f"{prefix}not valid TOML: {e}",
                                      ConfigCode.FILE)) from None


def read_config(config: str | Path | dict[str, Any] | None) -> tuple[dict[str, Any], Path | None]:
    """The raw configuration (TOML parsed) and the folder of its file for relative paths."""
    if config is None:
        return {}, None
    if isinstance(config, dict):
        return dict(config), None
    return read_toml(config), Path(config).parent


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
            raise e.in_file(str(config)) from None
        raise
    return raw, base, cfg
