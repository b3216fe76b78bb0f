"""The `PLC` facade: program + configuration -> a running soft Twido.

    plc = PLC.from_file("ladder_programs/x.il", config="x.toml")
    plc.scan(); plc.run(seconds=1.5); plc["%MW3"] = 120; plc["%Q0.14"]
"""

from __future__ import annotations

import re
import time
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from . import symbols
from .address import BLOCK_FIELDS, IO_KINDS, Ref, parse_address
from .build.blocks import build_blocks
from .compiler import Resolved, compile_program, resolve
from .config import Config, key_path, load_config, symbol_table
from .config_models import parse_analog, parse_exch, parse_rtc, parse_schedules
from .errors import (
    AddressError,
    Code,
    ConfigError,
    Diagnostic,
    ParseError,
    ProgramError,
    SoftPLCError,
)
from .heap import release_free_memory
from .il import ast as A
from .il.parser import parse, parse_file
from .il.rungtree import syntax_follow_ups
from .profile import ANALOG_MODULES, MODULES, PROFILES, AnalogModule, Profile
from .program import CompiledProgram, ProgramState, bind
from .runtime.analog import AnalogChannel, AnalogIO, normal_range
from .runtime.blocks import Message, TimeSource
from .runtime.clock import Clock, VirtualClock, make_clock
from .runtime.engine import DEFAULT_WATCHDOG_S, RUN, Engine
from .runtime.exch import ETHERNET_PORT, ExchPort
from .runtime.grafcet import Grafcet
from .runtime.memory import MemoryImage
from .runtime.rtc import DEFAULT_START, RTC
from .semantics import Ops

# signed or unsigned views of a word / double word
_INT_CONSTANT_RANGE = {"KW": (-(1 << 15), (1 << 16) - 1), "KD": (-(1 << 31), (1 << 32) - 1)}


TRIM_SOURCE = 256 * 1024  # generated source bytes past which compiling is worth a trim


class PLC:
    def __init__(self, program: A.Program, config: str | Path | dict[str, Any] | None = None,
                 *, clock: str | Clock = "virtual", devices: bool = True):
        from .devices import DEVICE_TYPES

        cfg, self.config_dir, settings = load_config(config, DEVICE_TYPES)
        self.config = cfg  # as written; `settings` is the same, checked and typed
        self.settings: Config = settings
        self.profile: Profile = PROFILES[settings.profile]
        self.symbols = symbols.from_config(cfg, self.config_dir, self.profile)
        self.ast = program
        self._refs: dict[str, Ref] = {}
        self.mem = MemoryImage(self.profile)
        self.time_source = TimeSource()
        self.scan_period = settings.scan_period
        watchdog = settings.watchdog if settings.watchdog is not None else DEFAULT_WATCHDOG_S
        self._clock = make_clock(clock)
        self._analog_modules: dict[int, AnalogModule] = {}
        self._modules = self._load_modules(settings.modules)
        self.mem.analog = self._configure_analog(settings.analog)
        self._configure_constants(settings.constants)
        self._exch = self._configure_exch(settings.exch)
        self.ops = Ops(self.mem.s, self.mem.sw.w)
        self.grafcet = Grafcet(self.mem.x, self.mem.s)
        self.engine = Engine(self.mem, self._clock, self.scan_period, watchdog, self.time_source)
        self.block_setup = build_blocks(self.mem, self.profile, self.time_source,
                                        self.scan_period, self.engine, settings)
        if self._exch is not None:  # only then: programs without EXCH pay nothing
            self.engine.before_scan.append(self._exch_boundary)
        self.program_state = ProgramState(grafcet=self.grafcet)  # fast and debug build share it
        self.program: CompiledProgram = self._compile(program)
        self.engine.load(self.program)
        self._rtc_start = parse_rtc(cfg.get("rtc"))
        self._schedules = parse_schedules(cfg.get("schedule", {}), self.mem)
        self._attach_rtc(program, "rtc" in cfg)
        self.program_version = 0  # bumped when the running code is rebuilt
        self.program_loaded_at = time.time()  # wall time of the last load (online change)
        self.devices: dict[str, Any] = {}
        if devices and settings.devices:
            from .devices import build_devices

            self.devices = build_devices(self._device_config(settings), self.mem)
            self.engine.devices = self.devices
        self._forced: dict[Ref, Any] = {}
        self.engine.cold_start()

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def from_file(cls, path: str | Path, config: str | Path | dict[str, Any] | None = None,
                  **kw: Any) -> PLC:
        table = symbol_table(config)
        return cls._checked(lambda: parse_file(path, table), config, kw)

    @classmethod
    def from_source(cls, text: str, config: str | Path | dict[str, Any] | None = None,
                    *, file: str = "<string>", **kw: Any) -> PLC:
        table = symbol_table(config)
        return cls._checked(lambda: parse(text, file, table), config, kw)

    @classmethod
    def _checked(cls, parser: Any, config: Any, kw: dict[str, Any]) -> PLC:
        """Parse; on syntax errors still run the semantic checks on the lines that parsed,
        so one run reports every problem of the file."""
        try:
            program = parser()
        except ParseError as e:
            partial = getattr(e, "program", None)
            if partial is not None:
                try:
                    cls(partial, config, **{**kw, "devices": False})
                except ProgramError as more:
                    follow_ups = syntax_follow_ups(partial, e.diagnostics, more.diagnostics)
                    diags = sorted(e.diagnostics + [d for d in more.diagnostics
                                                    if d not in follow_ups],
                                   key=lambda d: (d.line, d.column))
                    raise ParseError(diags) from None
                except SoftPLCError:
                    pass
            raise
        return cls(program, config, **kw)

    def _device_config(self, settings: Config) -> dict[str, tuple[str, Any]]:
        """Device name -> (type, validated options), relative files made relative to the
        config file's folder."""
        out = {}
        for name, section in settings.devices.items():
            opts = section.options
            csv = getattr(opts, "csv", None)
            if self.config_dir is not None and isinstance(csv, str) \
                    and not Path(csv).is_absolute():
                opts = opts.model_copy(update={"csv": str(self.config_dir / csv)})
            out[name] = (section.type, opts)
        return out

    def _load_modules(self, mods: dict[str, str] | None) -> dict[int, tuple[int, int]] | None:
        if mods is None:
            return None
        out = {}
        for k, name in mods.items():
            try:
                slot = int(k)
            except ValueError:
                raise ConfigError(f"modules.{k}: slot {k!r} is not a number") from None
            if not 1 <= slot <= self.profile.expansion_slots:
                raise ConfigError(f"modules.{k}: slot {slot} outside "
                                  f"1..{self.profile.expansion_slots}")
            name = str(name).upper()
            if name in ANALOG_MODULES:
                self._analog_modules[slot] = ANALOG_MODULES[name]
                out[slot] = (0, 0)
                continue
            if name not in MODULES:
                raise ConfigError(f"modules.{k}: unknown module {name!r}; known: "
                                  f"{', '.join(sorted(MODULES | ANALOG_MODULES))}")
            out[slot] = MODULES[name]
        return out

    def _configure_analog(self, section: Any) -> AnalogIO:
        """The analog channels: the base's inputs, those of the analog modules in
        [modules], with the signal type and range [analog] gives them."""
        chans: dict[Ref, AnalogChannel] = {}
        allowed: dict[Ref, tuple[str, ...]] = {}
        for c, (sig, full) in enumerate(self.profile.analog_base):
            ref = Ref("IW", c, 0, c)
            chans[ref] = AnalogChannel(ref, sig, "normal", *normal_range(sig, full), full)
            allowed[ref] = (sig,)
        for slot, mod in self._analog_modules.items():
            for kind, n, types in (("IW", mod.inputs, mod.input_types),
                                   ("QW", mod.outputs, mod.output_types)):
                for c in range(n):
                    ref = parse_address(f"%{kind}{slot}.{c}", self.profile)
                    chans[ref] = AnalogChannel(ref, types[0], "normal",
                                               *normal_range(types[0], mod.full_scale),
                                               mod.full_scale, configured=False)
                    allowed[ref] = types
        for text, o in parse_analog(section).items():
            try:
                ref = parse_address(text, self.profile)
            except AddressError as e:
                raise ConfigError(f"analog: {e}") from None
            ch = chans.get(ref)
            if ch is None:
                raise ConfigError(f"analog.{text}: no such analog channel: configure an "
                                  f"analog module in its slot ([modules])")
            if o.type not in allowed[ref]:
                raise ConfigError(f"analog.{text}: type {o.type!r} not available on this "
                                  f"channel; one of {', '.join(allowed[ref])}")
            ch.signal, ch.range, ch.configured = o.type, o.range, True
            ch.lo, ch.hi = (o.min, o.max) if o.range == "custom" else \
                normal_range(o.type, ch.full_scale)
        return AnalogIO(self.mem, chans)

    # ---- communication (issue 11 B) ----
    def _configure_exch(self, section: Any) -> ExchPort | None:
        """[exch]: the Ethernet port's remote devices; %MSG3 drives the port."""
        parsed = parse_exch(section, self.profile.count("EXCH_REMOTES"))
        if parsed is None:
            return None
        timeout, remotes = parsed
        port = ExchPort(self.mem, lambda: round(self._clock.seconds * 1e6), remotes,
                        timeout, wait_at_boundary=isinstance(self._clock, VirtualClock))
        port.msg = msg = self.mem.blocks["MSG"].setdefault(ETHERNET_PORT, Message())
        msg.port = port
        return port

    def settle_exchange(self, timeout: float) -> bool:
        """Virtual clock: wait up to `timeout` s for the EXCH exchange in progress (the next
        scan would, up to its deadline); True when the next scan will not wait."""
        port = self._exch
        return port is None or not port.wait or self.engine.state != RUN or port.settle(timeout)

    def _exch_boundary(self) -> None:
        """Scan boundary: a finished exchange lands; leaving RUN ends the one in progress."""
        if self.engine.state == RUN:
            self._exch.poll()
        else:
            self._exch.stop()

    def _configure_constants(self, consts: dict[str, int | float]) -> None:
        for text, v in consts.items():
            try:
                ref = parse_address(text, self.profile)
            except AddressError as e:
                raise ConfigError(f"{key_path(('constants', text))}: {e}") from None
            if ref.kind not in ("KW", "KD", "KF") or ref.length is not None \
                    or ref.bit is not None:
                raise ConfigError(f"{key_path(('constants', text))}: {text!r} is not a "
                                  f"%KW/%KD/%KF constant")
            if ref.kind != "KF":
                lo, hi = _INT_CONSTANT_RANGE[ref.kind]
                if not isinstance(v, int) or not lo <= v <= hi:
                    raise ConfigError(f"{key_path(('constants', text))}: expected an integer "
                                      f"{lo}..{hi} (got {v!r})")
            self.mem.write(ref, v)

    def _io_check(self, ref: Ref) -> str | None:
        if ref.kind in ("IW", "QW"):
            if self.mem.analog is not None and ref in self.mem.analog.channels:
                return None
            if ref.module == 0 or self._modules is not None:
                return (f"{ref}: no such analog channel (the base has %IW0.0.."
                        f"%IW0.{len(self.profile.analog_base) - 1}; expansion channels need "
                        f"an analog module in [modules])")
            return None
        if ref.module and self._modules is not None:
            mod = self._modules.get(ref.module)
            n = None if mod is None else (mod[0] if ref.kind == "I" else mod[1])
            if not n:
                what = "inputs" if ref.kind == "I" else "outputs"
                return f"{ref}: no module in slot {ref.module} with {what} (see [modules])"
            if ref.channel >= n:
                return f"{ref}: the module in slot {ref.module} has {n} channels"
        return None

    def _allocate(self, program: A.Program, resolved: Resolved) -> list[Diagnostic]:
        """Create the blocks and I/O copies the resolve pass found; the problems found."""
        problems = []

        def problem(msg: str, ref: Any, pos: A.Pos, expected: str, code: Code) -> None:
            problems.append(Diagnostic(msg, program.file, pos.line, pos.column, str(ref),
                                       expected, code))

        for ref, pos in resolved.blocks.items():
            msg = self.block_setup.factory(ref)
            if msg:
                problem(msg, ref, pos, "a configured block within the profile", Code.BLOCK)
        for ref, pos in resolved.io.items():
            if ref.kind in IO_KINDS:  # analog words need no scan-boundary copy
                self.mem.use_io(ref)
            msg = self._io_check(ref)
            if msg:
                problem(msg, ref, pos, "an I/O channel of a configured module", Code.IO)
        pulses = self.mem.pulses
        if pulses is not None:  # [our choice] a pulse block owns its output: no coil on it
            for rung in program.rungs:
                for ins in rung.instructions:
                    if isinstance(ins, A.Store) and ins.target.kind == "Q" \
                            and ins.target.length is None and ins.target.index in pulses.names:
                        problem(f"{ins.op} {ins.target}: the output is driven by "
                                f"{pulses.names[ins.target.index].split()[0]}",
                                ins.target, ins.pos, "another output (or no pulse block on it)",
                                Code.IO)
        # cold start puts a block back to its state when first allocated (a later build,
        # e.g. after forcing, keeps that one)
        cold = self.engine.cold_states
        for kind, blocks in self.mem.blocks.items():
            for i, b in blocks.items():
                if (kind, i) not in cold:
                    cold[kind, i] = b.state()
        return problems

    def _compile(self, program: A.Program, debug: bool = False) -> CompiledProgram:
        """Resolve, allocate, bind, generate. The program state (edge memory, initial
        steps) changes only once the program compiled."""
        counts = dict(self.profile.counts)
        resolved = resolve(program, counts)
        problems = self._allocate(program, resolved)
        state = self.program_state
        env = bind(self.mem, self.ops, state, self.engine.watchdog_expired, self.mem.blocks)
        forced = self._forced_bits()
        compiled = compile_program(program, resolved, env, state, counts, debug, forced,
                                   problems)
        if len(compiled.source) > TRIM_SOURCE:  # compile() left its peak in the C heap
            release_free_memory()
        state.size_edges(resolved.edges)
        state.initial_steps = self.grafcet.initial = resolved.initial_steps
        ts = self.time_source
        ts.track = _conditional_execution(program)
        if not ts.track:
            ts.running.clear()
        return compiled

    def _attach_rtc(self, program: A.Program, configured: bool = False) -> None:
        """The real-time clock costs a little every scan: give the engine one only when the
        program names its words or bits, or the configuration has [rtc] / [schedule]."""
        if self.engine.rtc is not None or not (
                configured or self._schedules or _RTC_OBJECTS.search(program.source)):
            return
        start = self._rtc_start
        if start is None:
            start = DEFAULT_START if isinstance(self._clock, VirtualClock) else \
                datetime.now().replace(microsecond=0) - timedelta(seconds=self.time)
        self.engine.rtc = RTC(self.mem, start, self._schedules)

    def compile_debug(self) -> CompiledProgram:
        """The debug build: `main()` is a generator yielding (rung, instruction) before each
        instruction; `log[rung][k]` holds the accumulator after instruction k."""
        return self._compile(self.ast, debug=True)

    def replace_program(self, program: A.Program) -> None:
        """Run `program` from the next scan on, keeping memory (the debugger's reload).
        Raises CompileError, leaving the running program in place, if it does not compile."""
        compiled = self._compile(program)
        self.ast, self.program = program, compiled
        self.engine.load(compiled)
        self._attach_rtc(program)
        self.program_version += 1
        self.program_loaded_at = time.time()

    # -- running --------------------------------------------------------------------------------
    def scan(self, n: int = 1) -> None:
        """Run n scans (on the virtual clock each advances time by scan_period)."""
        scan = self.engine.scan
        for _ in range(n):
            scan()

    def run(self, seconds: float) -> None:
        """Run for `seconds` of virtual time (whole scans)."""
        n = max(0, round(seconds / self.scan_period))
        self.scan(n)

    def run_until(self, condition: Any, timeout: float = 10.0) -> bool:
        """Scan until condition(plc) is true or `timeout` seconds of PLC time pass."""
        limit = max(1, round(timeout / self.scan_period))
        for _ in range(limit):
            if condition(self):
                return True
            self.scan()
        return bool(condition(self))

    # -- memory access --------------------------------------------------------------------------
    def __getitem__(self, address: str) -> Any:
        return self.mem.read(self._ref(address))

    def __setitem__(self, address: str, value: Any) -> None:
        ref = self._ref(address)
        if ref.kind in ("KW", "KD", "KF"):
            raise AddressError(f"{address} is a constant: set it in the configuration "
                               f"([constants])")
        if ref.kind in BLOCK_FIELDS and (ref.field is None or
                                         not BLOCK_FIELDS[ref.kind].get(ref.field, ("", 0))[1]):
            raise AddressError(f"{address} is read-only")
        self.mem.write(ref, value)

    def _ref(self, address: str | Ref) -> Ref:
        if isinstance(address, Ref):
            return address
        ref = self._refs.get(address)
        if ref is None:  # parsed once per address string: hosts poll the same words
            ref = self._refs[address] = (parse_address(address, self.profile)
                                         if address.startswith("%")
                                         else self.symbols.ref(address))  # plc["START_PB"]
        return ref

    def force(self, address: str, value: Any) -> None:
        """Hold an object at a value, whatever the program or the field does. A forced bit
        keeps its value all through the scan (the program's stores to it are compiled out);
        a forced word is re-asserted at the start and end of every scan."""
        ref = self._ref(address)
        bits = self._forced_bits()
        self._forced[ref] = value
        self.engine.set_forced(dict(self._forced))
        self.mem.write(ref, value, field_inputs=False)
        self._forced_changed(bits)

    def unforce(self, address: str | None = None) -> None:
        """Release one forced object, or all of them."""
        bits = self._forced_bits()
        if address is None:
            self._forced.clear()
        else:
            self._forced.pop(self._ref(address), None)
        self.engine.set_forced(dict(self._forced))
        self._forced_changed(bits)

    def _forced_bits(self) -> frozenset[Ref]:
        """The forced bits, whose stores the compiled program leaves out (words are
        re-asserted by the engine instead: no code depends on them)."""
        return frozenset(r for r in getattr(self, "_forced", {})
                         if r.kind in ("I", "Q", "M", "S", "X") and r.offset is None)

    def _forced_changed(self, before: frozenset[Ref]) -> None:
        """Recompile when the set of forced bits changed (2-14 ms for a machine program),
        so that stores to them are left out (or back in); not for words or a no-op."""
        if self._forced_bits() != before:
            self.replace_program(self.ast)

    @property
    def forced(self) -> dict[str, Any]:
        return {str(r): v for r, v in self._forced.items()}

    # -- state ----------------------------------------------------------------------------------
    def __repr__(self) -> str:
        """State, PLC time, scan count and the I/O that is on (what a failing test shows)."""
        stride, shown = self.mem.stride, 16
        on = [f"%{kind}{i // stride}.{i % stride}" for kind, bits in
              (("I", self.mem.i), ("Q", self.mem.q)) for i, v in enumerate(bits) if v]
        io = " ".join(on[:shown]) + (f" (+{len(on) - shown} more)" if len(on) > shown else "")
        return (f"<PLC {Path(self.ast.file).name} {self.state} t={self.time:.3f}s "
                f"scans={self.scan_count} on: {io or 'none'}>")

    @property
    def time(self) -> float:
        """PLC time in seconds (virtual: scans x scan_period)."""
        return self._clock.seconds

    @property
    def clock(self) -> Clock:
        return self._clock

    @property
    def scan_count(self) -> int:
        return self.engine.stats.scans

    @property
    def state(self) -> str:
        return self.engine.state

    @property
    def fault(self) -> str:
        return self.engine.fault

    @property
    def stats(self) -> Any:
        return self.engine.stats

    @property
    def before_scan(self) -> list:
        return self.engine.before_scan

    @property
    def after_scan(self) -> list:
        return self.engine.after_scan

    @property
    def rungs(self) -> list[A.Rung]:
        return self.ast.rungs

    @property
    def trace(self) -> list:
        """Samples of the machine's trace recorder (empty without one)."""
        for dev in self.devices.values():
            if getattr(dev, "type_name", "") == "trace":
                return dev.samples
        return []

    def cold_start(self) -> None:
        self.engine.cold_start()

    def warm_start(self) -> None:
        self.engine.warm_start()

    def stop(self) -> None:
        self.engine.stop()

    def start(self) -> None:
        self.engine.start()

    def stop_outputs(self) -> None:
        self.engine.stop_outputs()

    def set_scan_period(self, seconds: float) -> None:
        """Change the scan period (the virtual clock's step, %SW0)."""
        if seconds <= 0:
            raise ConfigError("scan period must be > 0")
        self.scan_period = seconds
        self.engine.period_us = max(1, round(seconds * 1e6))
        self.mem.sw.w[0] = min(32767, round(seconds * 1000))

    def note_overrun(self, late: bool = False, skipped: int = 0) -> None:
        self.engine.note_overrun(late, skipped)

    def close(self) -> None:
        """Flush and close devices (trace files) and the EXCH port's connections."""
        if self._exch is not None:
            self._exch.close()
        for dev in self.devices.values():
            close = getattr(dev, "close", None)
            if close:
                close()

    def __enter__(self) -> PLC:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _conditional_execution(program: A.Program) -> bool:
    """Can a block be skipped in a scan (a jump, a subroutine, a Grafcet step, ENDC/ENDCN)?
    Only then do timers need updating when not executed."""
    return any(isinstance(i, (A.Jump, A.SRCall, A.Grafcet))
               or isinstance(i, A.End) and i.op != "END"
               for r in program.rungs for i in r.instructions)


# Objects of the real-time clock: %SW49-%SW53, %S50, %S51 (not %SW490, %S500...).
_RTC_OBJECTS = re.compile(r"%SW(49|5[0-3])(?!\d)|%S5[01](?!\d)", re.I)

__all__ = ["PLC", "SoftPLCError"]
