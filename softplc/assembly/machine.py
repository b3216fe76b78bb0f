"""`Machine`: the assembled parts of one soft Twido, and `assemble`, which builds them from a
configuration (a dict, a TOML file or None)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, NamedTuple

from softplc.assembly import hardware
from softplc.assembly.blocks import BlockSetup
from softplc.config import Config, load_config
from softplc.config.files import FilePolicy, Local
from softplc.config.models import rtc_start
from softplc.errors import ConfigError
from softplc.persist import retain
from softplc.program import ProgramState
from softplc.runtime.blocks import TimeSource
from softplc.runtime.clock import Clock, make_clock
from softplc.runtime.engine import DEFAULT_WATCHDOG_S, RUN, Engine
from softplc.runtime.exch import ExchPort
from softplc.runtime.grafcet import Grafcet
from softplc.runtime.memory import MemoryImage
from softplc.runtime.remotelink import LinkMaster, LinkRemote
from softplc.runtime.rtc import Schedule
from softplc.twido import symbols
from softplc.twido.address import Ref
from softplc.twido.profile import PROFILES, Profile
from softplc.twido.semantics import Ops
from softplc.twido.symbols import SymbolTable


def _no_blocks(ref: Ref) -> str | None:
    return f"{ref.label}: no function blocks on this machine"


@dataclass(eq=False)
class Machine:
    """What the builder returns: the checked configuration and the parts built from it."""

    raw: dict[str, Any]  # the configuration as written
    config_dir: Path | None  # the folder of its file (relative paths), None for a dict
    settings: Config  # the same, checked and typed
    profile: Profile
    symbols: SymbolTable
    mem: MemoryImage
    time_source: TimeSource
    clock: Clock
    modules: hardware.Modules | None  # None: [modules] not given (I/O not checked)
    exch: ExchPort | None
    # the Remote Link station of [remote_link] (runtime/remotelink.py), None without one
    link: LinkMaster | LinkRemote | None
    ops: Ops
    grafcet: Grafcet
    engine: Engine
    program_state: ProgramState  # shared by the fast and the debug build
    rtc_start: datetime | None
    schedules: list[Schedule]
    # what the builder found wrong so far (raised by `equip`, with the blocks' and devices')
    problems: hardware.Problems
    # creates a block the program uses and the configuration does not name, or says what
    # to configure (the block set-up provides it)
    block_factory: Callable[[Ref], str | None] = _no_blocks
    devices: dict[str, Any] = field(default_factory=dict)
    # where the files the configuration names came from, and what they held
    files: FilePolicy = field(default_factory=Local)


class Loaded(NamedTuple):
    """A configuration read and checked by `load`: what `assemble` and `symbol_table` take
    instead of reading it again."""

    raw: dict[str, Any]  # as written
    config_dir: Path | None  # the folder of its file (relative paths), None for a dict
    settings: Config
    file: str | None  # its file, for messages
    # where the files it names may come from (`softplc.config.files`); what was read
    files: FilePolicy


ConfigSource = str | Path | dict[str, Any] | Loaded | None


def load(config: ConfigSource, files: FilePolicy | None = None) -> Loaded:
    """`config` read and checked (`config.load_config`, the devices' options too); a
    `Loaded` is returned as it is. `files`: where the files it names may come from
    (default: anywhere, `Local`; a configuration from the network: `Carried`). Raises
    ConfigError with every problem the schema finds."""
    # the catalog's names: a device type's module is imported only if the config names it
    from softplc.devices import device_types

    if isinstance(config, Loaded):
        return config
    raw, config_dir, settings = load_config(config, device_types())
    return Loaded(raw, config_dir, settings, None if config_dir is None else str(config),
                  Local() if files is None else files.fresh())


def _symbols(c: Loaded) -> SymbolTable:
    return symbols.from_settings(
        c.settings, c.config_dir, PROFILES[c.settings.profile],
        lambda name: c.files.read(name, c.config_dir, "symbols_file", "symbol file"))


def symbol_table(config: ConfigSource) -> SymbolTable:
    """The symbols of `config`, for the parser, which needs them before the machine is
    built: the whole configuration is checked first, so that a wrong one is reported
    before the program's errors (every name of the program would be one without it)."""
    c = load(config)
    try:
        return _symbols(c)
    except ConfigError as e:
        raise e.in_file(c.file) if c.file is not None else e from None


def assemble(config: ConfigSource, clock: str | Clock = "virtual") -> Machine:
    """Load and check `config`, then build the controller's parts (no function blocks, no
    program, no devices yet). Raises ConfigError with every problem the schema finds; the
    builder's are collected in `problems`, which `equip` raises with its own."""
    loaded = load(config)
    raw, config_dir, settings, file, files = loaded
    profile = PROFILES[settings.profile]
    problems = hardware.Problems(file)
    table = SymbolTable(profile=profile)
    with problems.collecting():
        table = _symbols(loaded)
    mem = MemoryImage(profile)
    clk = make_clock(clock)
    discrete, analog_modules = hardware.modules(settings)
    mem.analog = hardware.analog_io(settings.analog, profile, mem, analog_modules, problems)
    hardware.constants(settings.constants, profile, mem, problems)
    found = hardware.schedules(settings, mem, problems)
    time_source = TimeSource()
    watchdog = settings.watchdog if settings.watchdog is not None else DEFAULT_WATCHDOG_S
    grafcet = Grafcet(mem.x, mem.s)
    return Machine(
        raw=raw, config_dir=config_dir, settings=settings, profile=profile, symbols=table,
        mem=mem, time_source=time_source, clock=clk, modules=discrete,
        exch=hardware.exch_port(settings.exch, mem, clk),
        link=hardware.remote_link(settings.remote_link, mem), ops=Ops(mem.s, mem.sw.w),
        grafcet=grafcet,
        engine=Engine(mem, clk, settings.scan_period, watchdog, time_source),
        program_state=ProgramState(grafcet=grafcet), rtc_start=rtc_start(settings.rtc),
        schedules=found, problems=problems, files=files)


def equip(m: Machine, devices: bool = True) -> BlockSetup:
    """Set up the function blocks the configuration names and (`devices`) the simulated
    machine, the devices once the blocks are (a stepper binds to its pulse output). Raises
    one ConfigError with every problem of the build: the hardware's (`assemble`), the
    blocks', the devices'. The `BlockSetup` makes the blocks the program uses."""
    setup = BlockSetup(m.mem, m.profile, m.time_source, m.settings.scan_period, m.engine,
                       m.symbols)
    with m.problems.collecting():
        setup.configure(m.settings)
        if devices:
            attach_devices(m)
    m.problems.raise_any()
    m.block_factory = setup.factory
    return setup


def application_id(m: Machine, program: bytes) -> bytes:
    """What the state file calls the application `program` makes on this machine: a hash
    of the program and of the configuration as written (`retain.application_id`: the
    daemon's, the server's and the devices' sections left out). The one reader of the raw
    table besides online change, which keeps it for this."""
    return retain.application_id(program, m.raw)


def attach_scan_hooks(m: Machine) -> None:
    """The scan-boundary work of the configured functions once the blocks are set up (the
    blocks' own, such as the very fast counters' poll, their catalog `finish` hooks attach):
    the EXCH port. Programs without it pay nothing."""
    if m.exch is not None:
        m.engine.before_scan.append(
            hardware.exch_boundary(m.exch, lambda: m.engine.state, RUN))


def settle_exchange(m: Machine, timeout: float) -> bool:
    """Virtual clock: wait up to `timeout` s for the EXCH exchange in progress (the next
    scan would, up to its deadline); True when the next scan will not wait."""
    port = m.exch
    return port is None or not port.wait or m.engine.state != RUN or port.settle(timeout)


#: Device options that name a file the device writes, placed by the machine's file policy
#: (`FilePolicy.output`): the trace recorder's `csv` (relative to the configuration's
#: folder: True) and a servo axis's `trace_csv` (relative to the working folder, as ever).
FILE_OPTIONS = {"csv": True, "trace_csv": False}


def attach_devices(m: Machine) -> dict[str, Any]:
    """Build the simulated machine of [devices] on the memory image (relative files made
    relative to the config file's folder; a configuration from the network names none)."""
    if not m.settings.devices:
        return {}
    from softplc.devices import build_devices

    config = {}
    for name, section in m.settings.devices.items():
        opts = section.options
        for key, anchored in FILE_OPTIONS.items():
            value = getattr(opts, key, None)
            if isinstance(value, str):
                where = m.files.output(value, m.config_dir if anchored else None,
                                       f"devices.{name}.{key}")
                opts = opts.model_copy(update={key: str(where)})
        config[name] = (section.type, opts)
    m.devices = build_devices(config, m.mem)
    m.engine.devices = m.devices
    return m.devices
