"""The controller's configured hardware: expansion modules, analog channels, constants, the
EXCH port and the schedule blocks, from the typed configuration. Each function reports the
problems the schema cannot see (an address outside the profile, a channel no module has)
to a `Problems` collector, so that one run names them all."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from softplc.config import Config, key_path
from softplc.config.models import (
    AnalogChannelConfig,
    ExchConfig,
    RemoteLinkConfig,
    exch_remotes,
    schedule,
)
from softplc.errors import AddressError, ConfigCode, ConfigError, ConfigIssue
from softplc.runtime.analog import AnalogChannel, AnalogIO, normal_range
from softplc.runtime.clock import Clock, VirtualClock
from softplc.runtime.exch import ETHERNET_PORT, ExchPort, Message
from softplc.runtime.memory import MemoryImage
from softplc.runtime.remotelink import LinkMaster, LinkRemote, default_cycle_us
from softplc.runtime.rtc import Schedule
from softplc.twido.address import Ref, parse_address
from softplc.twido.profile import ANALOG_MODULES, MODULES, AnalogModule, Profile

# signed or unsigned views of a word / double word
_INT_CONSTANT_RANGE = {"KW": (-(1 << 15), (1 << 16) - 1), "KD": (-(1 << 31), (1 << 32) - 1)}


class Problems:
    """The configuration problems found while building, raised together at the end;
    `file`: the configuration file they are in (None for a dict)."""

    def __init__(self, file: str | None = None) -> None:
        self.issues: list[ConfigIssue] = []
        self.file = file

    def add(self, path: tuple[Any, ...], message: str, code: ConfigCode) -> None:
        self.issues.append(ConfigIssue(key_path(path), message, code))

    def address(self, path: tuple[Any, ...], text: str, profile: Profile) -> Ref | None:
        """The address `text` at key `path`, or None with the problem noted."""
        try:
            return parse_address(text, profile)
        except AddressError as e:
            self.add(path, str(e), ConfigCode.ADDRESS)
            return None

    @contextmanager
    def collecting(self) -> Iterator[None]:
        """Run a step that raises ConfigError at its first problem; keep its issues."""
        try:
            yield
        except ConfigError as e:
            self.issues += e.issues

    def raise_any(self) -> None:
        if self.issues:
            raise ConfigError(self.issues, self.file)


Modules = dict[int, tuple[int, int]]  # slot -> (inputs, outputs) of a discrete module


def modules(settings: Config) -> tuple[Modules | None, dict[int, AnalogModule]]:
    """The discrete modules by slot (None: [modules] not given, I/O not checked) and the
    analog ones (names and slots checked by the schema)."""
    if settings.modules is None:
        return None, {}
    discrete: Modules = {}
    analog: dict[int, AnalogModule] = {}
    for slot, name in settings.modules.items():
        if name in ANALOG_MODULES:
            analog[slot] = ANALOG_MODULES[name]
            discrete[slot] = (0, 0)
        else:
            discrete[slot] = MODULES[name]
    return discrete, analog


def analog_io(section: dict[str, AnalogChannelConfig], profile: Profile, mem: MemoryImage,
              analog_modules: dict[int, AnalogModule], problems: Problems) -> AnalogIO:
    """The analog channels: the base's inputs, those of the analog modules in [modules],
    with the signal type and range [analog] gives them."""
    chans: dict[Ref, AnalogChannel] = {}
    allowed: dict[Ref, tuple[str, ...]] = {}
    for c, (sig, full) in enumerate(profile.analog_base):
        ref = Ref("IW", c, 0, c)
        chans[ref] = AnalogChannel(ref, sig, "normal", *normal_range(sig, full), full)
        allowed[ref] = (sig,)
    for slot, mod in analog_modules.items():
        for kind, n, types in (("IW", mod.inputs, mod.input_types),
                               ("QW", mod.outputs, mod.output_types)):
            for c in range(n):
                ref = parse_address(f"%{kind}{slot}.{c}", profile)
                chans[ref] = AnalogChannel(ref, types[0], "normal",
                                           *normal_range(types[0], mod.full_scale),
                                           mod.full_scale, configured=False)
                allowed[ref] = types
    for text, o in section.items():
        where = ("analog", text)
        ref = problems.address(where, text, profile)
        if ref is None:
            continue
        ch = chans.get(ref)
        if ch is None:
            problems.add(where, "no such analog channel: configure an analog module in its "
                         "slot ([modules])", ConfigCode.MODULE)
            continue
        if o.type not in allowed[ref]:
            problems.add(where + ("type",), f"type {o.type!r} not available on this channel; "
                         f"one of {', '.join(allowed[ref])}", ConfigCode.VALUE)
            continue
        ch.signal, ch.range, ch.configured = o.type, o.range, True
        ch.lo, ch.hi = (o.min, o.max) if o.range == "custom" else \
            normal_range(o.type, ch.full_scale)
    return AnalogIO(mem, chans)


def constants(consts: dict[str, int | float], profile: Profile, mem: MemoryImage,
              problems: Problems) -> None:
    """Write [constants] into %KW/%KD/%KF."""
    for text, v in consts.items():
        where = ("constants", text)
        ref = problems.address(where, text, profile)
        if ref is None:
            continue
        if ref.kind not in ("KW", "KD", "KF") or ref.length is not None or ref.bit is not None:
            problems.add(where, f"{text!r} is not a %KW/%KD/%KF constant", ConfigCode.ADDRESS)
            continue
        if ref.kind != "KF":
            lo, hi = _INT_CONSTANT_RANGE[ref.kind]
            if not isinstance(v, int) or not lo <= v <= hi:
                problems.add(where, f"expected an integer {lo}..{hi} (got {v!r})",
                             ConfigCode.VALUE)
                continue
        mem.write(ref, v)


def exch_port(cfg: ExchConfig | None, mem: MemoryImage, clock: Clock) -> ExchPort | None:
    """[exch]: the Ethernet port's remote devices; %MSG3 drives the port."""
    if cfg is None:
        return None
    port = ExchPort(mem, lambda: round(clock.seconds * 1e6), exch_remotes(cfg), cfg.timeout,
                    wait_at_boundary=isinstance(clock, VirtualClock))
    port.msg = msg = mem.blocks["MSG"].setdefault(ETHERNET_PORT, Message())
    msg.port = port
    return port


def exch_boundary(port: ExchPort, state: Callable[[], str], running: str) -> Callable[[], None]:
    """The scan-boundary hook of the EXCH port: a finished exchange lands; leaving RUN ends
    the one in progress."""
    def boundary() -> None:
        if state() == running:
            port.poll()
        else:
            port.stop()
    return boundary


def schedules(settings: Config, mem: MemoryImage, problems: Problems) -> list[Schedule]:
    """The [schedule] blocks, their output bits resolved."""
    out = []
    for n, o in settings.schedule.items():
        with problems.collecting():
            out.append(schedule(n, o, mem))
    return out


def remote_link(cfg: RemoteLinkConfig | None, mem: MemoryImage) -> LinkMaster | LinkRemote | None:
    """This controller's Remote Link station (`[remote_link]`), its status words set; the
    transport is attached by whoever runs the link (softplc.plant)."""
    if cfg is None:
        return None
    if cfg.kind == "master":
        cycle = round(cfg.cycle * 1e6) if cfg.cycle is not None else \
            default_cycle_us(len(cfg.remotes))
        return LinkMaster(mem, cfg.remotes, cycle)
    return LinkRemote(mem, cfg.address, cfg.kind)


def link_word_check(cfg: RemoteLinkConfig | None, ref: Ref) -> str | None:
    """What is wrong with a %INWi.j / %QNWi.j or a remote I/O channel %Ix.0.z the program
    uses (None: the link has it): a master reaches the peers' words and the remote I/O
    controllers' channels it declares, a peer only the master's words (station 0)."""
    if cfg is None:
        return f"{ref}: the Remote Link is not configured ([remote_link] address = ...)"
    remote_io = ref.station is not None
    station = ref.station if remote_io else ref.module
    want = "remote_io" if remote_io else "peer"
    if cfg.kind == "master":
        if cfg.remotes.get(station) != want:
            declared = ", ".join(str(a) for a, t in cfg.remotes.items() if t == want)
            what = "remote I/O" if remote_io else "peer"
            return (f"{ref}: station {station} is not a {what} of this master "
                    f"([remote_link] remotes: {declared or 'none'})")
        return None
    if remote_io:
        return f"{ref}: only the master reaches a remote I/O controller's channels"
    if station != 0:
        return (f"{ref}: a peer exchanges words with the master only "
                f"(%{ref.kind}0.0 .. %{ref.kind}0.3)")
    return None
