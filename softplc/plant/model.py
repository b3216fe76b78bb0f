"""The plant file, `plant.toml`: the controllers of a line, the links between them, the
wires and the shared devices; typed with pydantic, every problem reported at once as
`FILE:LINE: key.path: message [code]`.

    name = "bottling line"
    tick = "10ms"                      # the shared devices' step (default: the shortest scan)

    [controllers.master]
    program = "master.il"              # relative to this file
    config = "master.toml"             # optional; its [remote_link] may be left out:
    address = 0                        # the Remote Link address (0: the master)
    host = "10.0.35.1"                 # optional: its own host address (plant up)

    [links.line]                       # a Remote Link: the master polls its peers
    master = "master"
    peers = ["filler", "capper"]       # by controller name; their addresses as above
    cycle = "30ms"                     # optional: the master's link cycle

    [[wires]]                          # a hardwired signal: an output or a device's signal
    from = "master:%Q0.1"              # to one or more inputs
    to = ["filler:%I0.5", "capper:%I0.5"]

    [devices.belt]                     # a shared device (softplc.plant.physics)
    type = "conveyor"
    length = 3.0
    speed = 0.5
    stations = { fill = 1.0, cap = 2.0 }
"""

from __future__ import annotations

import ipaddress
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    model_validator,
)

from softplc.assembly import Loaded
from softplc.config import (
    ModbusConfig,
    PositiveDuration,
    Section,
    error_issues,
    numbered,
    read_toml,
    validate_config,
)
from softplc.config.files import Local
from softplc.devices import device_types
from softplc.errors import AddressError, ConfigCode, ConfigError, ConfigIssue
from softplc.plant.physics import SHARED_DEVICES
from softplc.twido.address import LINK_STATIONS, parse_address

# EXCH remote device indexes: the first byte of the EXCH table (config.models.RemoteIndex)
ExchIndex = numbered(1, 255, "the remote device index is {lo} .. {hi}")
NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,31}$")  # a controller's or a device's name
MAX_CONTROLLERS = 64  # one process; the fleet (issue 35, 7) serves more
MAX_WIRES = 4096
MAX_PLANT_BYTES = 1 << 20  # a plant file of a megabyte is not written by hand
MAX_ENDPOINT = 64  # characters of a wire's end: a 32-character name, ':' and an address


def _name(v: str) -> str:
    if not NAME.match(v):
        raise ValueError("a name is a letter then letters, digits, _ or - (32 at most)")
    return v


def _str_keys(v: Any) -> Any:
    return {str(k): x for k, x in v.items()} if isinstance(v, dict) else v


def _host(v: str) -> str:
    try:
        ipaddress.ip_address(v)
    except ValueError:
        raise ValueError("not an IP address (e.g. 10.0.35.2)") from None
    return v


Name = Annotated[str, AfterValidator(_name)]


class ControllerEntry(Section):
    """`[controllers.NAME]`: one soft Twido of the plant; a remote I/O controller
    (`role = "remote_io"`) has no program."""

    program: str | None = Field(None, min_length=1)
    config: str | None = Field(None, min_length=1)
    address: int | None = Field(None, ge=0, le=LINK_STATIONS - 1)
    role: Literal["peer", "remote_io"] | None = None
    host: Annotated[str, AfterValidator(_host)] | None = None

    @model_validator(mode="after")
    def _program_or_remote_io(self) -> ControllerEntry:
        if (self.program is None) != (self.role == "remote_io"):
            raise ValueError("a controller has a program, a remote I/O controller "
                             "(role = \"remote_io\") none")
        return self


class LinkEntry(Section):
    """`[links.NAME]`: a Remote Link (`type = "remote_link"`, the default: its `master`
    and `peers`, by controller name), or EXCH (`type = "exch"`: the `client` controller's
    EXCH3 remote devices, `remotes = { 1 = "filler" }`, named by controller)."""

    type: Literal["remote_link", "exch"] = "remote_link"
    master: Name | None = None
    peers: list[Name] = Field(default_factory=list, max_length=LINK_STATIONS - 1)
    cycle: PositiveDuration | None = None
    client: Name | None = None
    remotes: Annotated[dict[ExchIndex, Name], BeforeValidator(_str_keys)] = \
        Field(default_factory=dict)

    @model_validator(mode="after")
    def _of_its_type(self) -> LinkEntry:
        if self.type == "remote_link":
            if self.master is None or not self.peers:
                raise ValueError("a Remote Link names its master and its peers")
            if self.client is not None or self.remotes:
                raise ValueError("client and remotes are an EXCH link's (type = \"exch\")")
        else:
            if self.client is None or not self.remotes:
                raise ValueError("an EXCH link names its client and its remotes, e.g. "
                                 "remotes = { 1 = \"filler\" }")
            if self.master is not None or self.peers or self.cycle is not None:
                raise ValueError("master, peers and cycle are a Remote Link's")
        return self


class WireEntry(Section):
    """`[[wires]]`: `from` one output (`ctl:%Qm.c`, `device:signal`) to inputs
    (`ctl:%Im.c`, `device:signal`)."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True,
                              populate_by_name=True)
    source: str = Field(alias="from", min_length=3, max_length=MAX_ENDPOINT)
    to: list[Annotated[str, Field(max_length=MAX_ENDPOINT)]] | \
        Annotated[str, Field(max_length=MAX_ENDPOINT)] = Field(min_length=1)
    name: str = ""

    @property
    def targets(self) -> list[str]:
        return [self.to] if isinstance(self.to, str) else list(self.to)


class DeviceEntry(BaseModel):
    """`[devices.NAME]`: `type` picks the shared device, whose `Options` check the rest."""

    model_config = ConfigDict(extra="allow", strict=True)
    type: str


class PlantFile(Section):
    """The whole plant file."""

    name: str = ""
    description: str = ""
    tick: PositiveDuration | None = None
    controllers: dict[Name, ControllerEntry] = Field(min_length=1, max_length=MAX_CONTROLLERS)
    links: dict[Name, LinkEntry] = Field(default_factory=dict)
    wires: list[WireEntry] = Field(default_factory=list, max_length=MAX_WIRES)
    devices: dict[Name, DeviceEntry] = Field(default_factory=dict)


# ---- errors with their line ------------------------------------------------------------------
@dataclass(frozen=True)
class PlantIssue:
    """One problem of a plant file, where it is."""

    file: str
    line: int
    path: str
    message: str
    code: ConfigCode

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: {self.path}: {self.message} [{self.code}]"


class PlantError(ConfigError):
    """A plant file is wrong: every problem, each `FILE:LINE: path: message [code]`."""

    def __init__(self, issues: list[PlantIssue]):
        super().__init__([ConfigIssue(i.path, i.message, i.code) for i in issues],
                         issues[0].file if issues else None)
        self.plant_issues = issues
        self.args = ("\n".join(str(i) for i in issues),)

    def __str__(self) -> str:
        return self.args[0]


_HEADER = re.compile(r"^\s*\[(\[?)\s*([^\]]+?)\s*\]\]?\s*(?:#.*)?$")
_KEY = re.compile(r"""^\s*("[^"]*"|'[^']*'|[A-Za-z0-9_.-]+(?:\s*\.\s*[A-Za-z0-9_-]+)*)\s*=""")


def _parts(dotted: str) -> list[str]:
    return [p.strip().strip("\"'") for p in re.findall(r"""("[^"]*"|'[^']*'|[^.]+)""", dotted)]


def line_of(text: str, path: tuple[Any, ...]) -> int:
    """The line of the key `path` (('controllers', 'filler', 'program'), ('wires', 2,
    'to')) in TOML `text`: the deepest part of it found; 1 when nothing is."""
    want = [str(p) for p in path]
    best, best_depth = 1, 0
    table: list[str] = []
    counts: dict[str, int] = {}
    for n, line in enumerate(text.splitlines(), 1):
        h = _HEADER.match(line)
        if h:
            table = _parts(h[2])
            if h[1]:  # [[array]]: the k-th element
                key = ".".join(table)
                counts[key] = counts.get(key, -1) + 1
                table = [*table, str(counts[key])]
            here = table
        else:
            k = _KEY.match(line)
            if not k:
                continue
            here = table + _parts(k[1])
        depth = 0
        for a, b in zip(here, want, strict=False):
            if a != b:
                break
            depth += 1
        if depth > best_depth or (depth == best_depth == len(here) and depth and best == 1):
            best, best_depth = n, depth
    return best


def _raise(file: str, text: str, issues: list[tuple[tuple[Any, ...], str, ConfigCode]]) -> None:
    if issues:
        raise PlantError([PlantIssue(file, line_of(text, p), ".".join(map(str, p)) or
                                     "(top level)", m, c) for p, m, c in issues])


# ---- loading ---------------------------------------------------------------------------------
@dataclass
class Endpoint:
    """One end of a wire: a controller's I/O bit or a device's signal."""

    owner: str
    what: str  # the address or the signal name
    device: bool


@dataclass
class PlantSpec:
    """A checked plant file with its controllers' configurations loaded."""

    file: Path
    data: PlantFile
    configs: dict[str, Loaded]  # controller -> its configuration, with the link's section
    programs: dict[str, Path]  # a remote I/O controller has none
    device_options: dict[str, Any]  # device -> its validated Options
    wires: list[tuple[str, Endpoint, list[Endpoint]]]  # (name, source, targets)


def _validate(file: str, text: str, raw: dict[str, Any]) -> PlantFile:
    try:
        return PlantFile.model_validate(raw)
    except ValidationError as e:
        found = []
        for issue in error_issues(e, PlantFile):
            parts = tuple(int(p) if p.isdigit() else p
                          for p in _parts(issue.path.replace("[", ".").replace("]", "")))
            found.append((parts, issue.message, issue.code))
        _raise(file, text, found)
        raise  # not reached


def load_plant(path: str | Path) -> PlantSpec:
    """Read and check a plant file and its controllers' configurations. Raises PlantError
    (every problem, with its line), or the controllers' own ConfigError (their file)."""
    p = Path(path)
    file = str(p)
    try:
        size = p.stat().st_size
    except OSError:
        size = 0  # read_toml says what is wrong with the file
    if size > MAX_PLANT_BYTES:
        raise PlantError([PlantIssue(file, 1, "(file)", f"{size} bytes: a plant file has at "
                                     f"most {MAX_PLANT_BYTES}", ConfigCode.FILE)])
    raw = read_toml(p)
    text = p.read_text(encoding="utf-8")
    data = _validate(file, text, raw)
    issues: list[tuple[tuple[Any, ...], str, ConfigCode]] = []
    here = p.parent

    def problem(where: tuple[Any, ...], message: str,
                code: ConfigCode = ConfigCode.VALUE) -> None:
        issues.append((where, message, code))

    for name in set(data.controllers) & set(data.devices):
        problem(("devices", name), f"{name!r} is also a controller's name", ConfigCode.CONFLICT)
    programs: dict[str, Path] = {}
    raws: dict[str, tuple[dict[str, Any], Path | None, str | None]] = {}
    for name, c in data.controllers.items():
        if c.program is not None:
            prog = here / c.program
            if not prog.is_file():
                problem(("controllers", name, "program"), f"no such file {prog}",
                        ConfigCode.FILE)
            programs[name] = prog
        if c.config is None:
            raws[name] = ({}, None, None)
            continue
        cfg = here / c.config
        try:
            raws[name] = (read_toml(cfg), cfg.parent, str(cfg))
        except ConfigError as e:
            problem(("controllers", name, "config"), str(e), ConfigCode.FILE)
    _link_sections(data, raws, problem)
    options = _devices(data, problem)
    wires = _wires(data, options, problem)
    _raise(file, text, issues)
    configs = {}
    for name, (cfg_raw, base, cfg_file) in raws.items():
        try:
            settings = validate_config(cfg_raw, device_types())
        except ConfigError as e:
            raise (e.in_file(cfg_file) if cfg_file else e) from None
        configs[name] = Loaded(cfg_raw, base, settings, cfg_file, Local())
    return PlantSpec(p, data, configs, programs, options, wires)


def _link_sections(data: PlantFile, raws: dict[str, Any], problem: Any) -> None:
    """Give each linked controller its `[remote_link]` section (or check the one it has)."""
    member: dict[str, str] = {}
    for lname, link in data.links.items():
        where = ("links", lname)
        if link.type == "exch":
            _exch_section(data, raws, lname, link, problem)
            continue
        assert link.master is not None
        addresses: dict[int, str] = {}
        kinds: dict[int, str] = {}  # address -> "peer" or "remote_io"
        complete = True  # every member resolved: only then compare the master's remotes
        for role, name in [("master", link.master)] + [("peers", n) for n in link.peers]:
            complete = complete and name in data.controllers
            if name not in data.controllers:
                problem((*where, role), f"{name!r} is not a controller of this plant",
                        ConfigCode.MISSING_KEY)
                continue
            if name in member:
                problem((*where, role), f"{name!r} is already on link {member[name]!r}",
                        ConfigCode.CONFLICT)
                continue
            member[name] = lname
            if name not in raws:
                continue
            own = raws[name][0].get("remote_link")
            plant_addr = data.controllers[name].address
            addr = plant_addr if plant_addr is not None else \
                (own.get("address") if isinstance(own, dict) else None)
            if role == "master":
                addr = 0 if addr is None else addr
                if data.controllers[name].role is not None:
                    problem(("controllers", name, "role"), f"{name!r} is the master of link "
                            f"{lname!r}: it has no remote's role", ConfigCode.CONFLICT)
                    continue
            if not isinstance(addr, int) or (addr == 0) != (role == "master"):
                problem(("controllers", name, "address"),
                        f"{name!r} needs a Remote Link address: 0 for the master, 1 .. "
                        f"{LINK_STATIONS - 1} for a peer (here or in its [remote_link])",
                        ConfigCode.MISSING_KEY)
                continue
            if isinstance(own, dict) and own.get("address", addr) != addr:
                problem(("controllers", name, "address"),
                        f"address {addr} but its configuration's [remote_link] says "
                        f"{own.get('address')}", ConfigCode.CONFLICT)
                continue
            if role == "peers":
                if addr in addresses:
                    problem((*where, "peers"), f"{name!r} and {addresses[addr]!r} both have "
                            f"address {addr}", ConfigCode.CONFLICT)
                addresses[addr] = name
                kind = data.controllers[name].role or (
                    own.get("role") if isinstance(own, dict) else None) or "peer"
                kinds[addr] = kind
                if own is None:
                    raws[name][0]["remote_link"] = {"address": addr, "role": kind}
        master = raws.get(link.master)
        if master is not None and link.master in data.controllers:
            own = master[0].get("remote_link")
            want = {str(a): kinds[a] for a in sorted(addresses)}
            if own is None:
                section: dict[str, Any] = {"address": 0, "remotes": want}
                if link.cycle is not None:
                    section["cycle"] = f"{link.cycle * 1e6:.0f}us"
                master[0]["remote_link"] = section
            elif complete and isinstance(own, dict) and {str(k): v for k, v in
                                            own.get("remotes", {}).items()} != want:
                problem((*where, "peers"), f"the master's [remote_link] remotes "
                        f"{own.get('remotes')} are not this link's peers {want}",
                        ConfigCode.CONFLICT)


DEFAULT_MODBUS_HOST = "127.0.0.1"  # a remote controller without its own `host`


def _exch_section(data: PlantFile, raws: dict[str, Any], lname: str, link: LinkEntry,
                  problem: Any) -> None:
    """Give the client's `[exch]` the remote devices the link names (the controller's
    host and Modbus port, for the plant across processes; in one process the plant serves
    them in memory), or check the ones it has."""
    where = ("links", lname)
    for role, name in [("client", link.client)] + [("remotes", n)
                                                    for n in link.remotes.values()]:
        if name not in data.controllers:
            problem((*where, role), f"{name!r} is not a controller of this plant",
                    ConfigCode.MISSING_KEY)
    if link.client not in raws or any(n not in data.controllers for n in link.remotes.values()):
        return
    exch = raws[link.client][0].setdefault("exch", {})
    if not isinstance(exch, dict):
        return  # the client's configuration reports it
    table = exch.setdefault("remote", {})
    for index, name in link.remotes.items():
        if name == link.client:
            problem((*where, "remotes"), f"{name!r} cannot be its own remote device",
                    ConfigCode.CONFLICT)
            continue
        server = raws.get(name, ({}, None, None))[0].get("modbus", {})
        port = server.get("port", ModbusConfig.model_fields["port"].default) \
            if isinstance(server, dict) else None
        table.setdefault(str(index), {"host": data.controllers[name].host
                                      or DEFAULT_MODBUS_HOST, "port": port})


def _devices(data: PlantFile, problem: Any) -> dict[str, Any]:
    out = {}
    for name, dev in data.devices.items():
        cls = SHARED_DEVICES.get(dev.type)
        if cls is None:
            problem(("devices", name, "type"), f"unknown shared device type {dev.type!r}; "
                    f"known: {', '.join(SHARED_DEVICES)}", ConfigCode.DEVICE)
            continue
        try:
            out[name] = cls.Options.model_validate(dev.model_extra or {})
        except ValidationError as e:
            for issue in error_issues(e, cls.Options, ("devices", name)):
                problem(tuple(_parts(issue.path)), issue.message, issue.code)
    return out


def _wires(data: PlantFile, options: dict[str, Any], problem: Any,
           ) -> list[tuple[str, Endpoint, list[Endpoint]]]:
    def end(text: str, where: tuple[Any, ...], output: bool) -> Endpoint | None:
        owner, sep, what = text.partition(":")
        if not sep:
            problem(where, f"{text!r}: write CONTROLLER:%ADDRESS or DEVICE:SIGNAL",
                    ConfigCode.ADDRESS)
            return None
        if owner in data.controllers:
            kind = "Q" if output else "I"
            try:
                ref = parse_address(what)
            except AddressError as e:
                problem(where, f"{text!r}: {e}", ConfigCode.ADDRESS)
                return None
            if ref.kind != kind or ref.length is not None:
                problem(where, f"{text!r}: a wire goes from an output %Q to an input %I bit",
                        ConfigCode.ADDRESS)
                return None
            return Endpoint(owner, str(ref), False)
        if owner in data.devices:
            if owner not in options:
                return None  # its own problem is reported
            probe = SHARED_DEVICES[data.devices[owner].type]("_", options[owner])
            names = probe.outputs if output else probe.inputs
            if what not in names:
                problem(where, f"{text!r}: {owner} has {'output' if output else 'input'} "
                        f"signals {', '.join(names) or 'none'}", ConfigCode.ADDRESS)
                return None
            return Endpoint(owner, what, True)
        problem(where, f"{text!r}: no controller or device {owner!r}", ConfigCode.ADDRESS)
        return None

    out = []
    driven: dict[tuple[str, str], int] = {}
    for k, w in enumerate(data.wires):
        src = end(w.source, ("wires", k, "from"), True)
        targets = []
        for t in w.targets:
            e = end(t, ("wires", k, "to"), False)
            if e is None:
                continue
            if (e.owner, e.what) in driven:
                problem(("wires", k, "to"), f"{t!r} is already driven by wire "
                        f"{driven[e.owner, e.what]}", ConfigCode.CONFLICT)
                continue
            driven[e.owner, e.what] = k
            targets.append(e)
        if src is not None and targets:
            out.append((w.name or w.source, src, targets))
    return out
