"""The `PLC` facade: program + configuration -> a running soft Twido.

    plc = PLC.from_file("ladder_programs/x.il", config="x.toml")
    plc.scan(); plc.run(seconds=1.5); plc["%MW3"] = 120; plc["%Q0.14"]

The machine builder (`softplc.assembly`) assembles the parts; the facade keeps run control and
item access, and gives the parts' usual names (`plc.mem`, `plc.engine`, `plc.settings`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from operator import attrgetter
from pathlib import Path
from typing import Any

from softplc import assembly as build
from softplc.errors import (
    AddressError,
    ConfigError,
    ParseError,
    ProgramError,
    SoftPLCError,
)
from softplc.il import ast as A
from softplc.il.parser import parse, parse_file
from softplc.il.rungtree import syntax_follow_ups
from softplc.program import CompiledProgram
from softplc.runtime.clock import Clock
from softplc.runtime.engine import Engine
from softplc.twido.address import BLOCK_FIELDS, Ref


def _engine(name: str) -> Callable[..., Any]:
    """A PLC method that is the engine's (run control the facade passes on unchanged)."""
    def call(self: PLC, *args: Any, **kw: Any) -> Any:
        return getattr(self.engine, name)(*args, **kw)
    call.__name__ = call.__qualname__ = name
    call.__doc__ = getattr(Engine, name).__doc__
    return call


def _machine_value(name: str, doc: str) -> property:
    """A PLC attribute that is the machine's (online change replaces it: one copy only)."""
    def set_value(self: PLC, value: Any) -> None:
        setattr(self.machine, name, value)
    return property(attrgetter(f"machine.{name}"), set_value, doc=doc)


def _engine_value(name: str, doc: str) -> property:
    """A read-only PLC attribute that is the engine's."""
    return property(attrgetter(f"engine.{name}"), doc=doc)


class PLC:
    """A soft Twido: the machine `softplc.assembly` assembles (`self.machine`), run (`scan`,
    `run`, `start`/`stop`...) and read or written by address (`plc["%MW3"]`, `force`)."""

    def __init__(self, program: A.Program, config: build.ConfigSource = None,
                 *, clock: str | Clock = "virtual", devices: bool = True):
        m = self.machine = build.assemble(config, clock)
        self.config_dir = m.config_dir
        self.profile, self.symbols, self.mem = m.profile, m.symbols, m.mem
        self.time_source, self._clock, self.engine = m.time_source, m.clock, m.engine
        self.ops, self.grafcet, self.program_state = m.ops, m.grafcet, m.program_state
        self.scan_period = m.settings.scan_period
        self._refs: dict[str, Ref] = {}
        self._forced: dict[Ref, Any] = {}
        # the function blocks, family by family from the catalog (softplc/assembly/blocks.py),
        # and the devices: every configuration problem the build finds is raised here
        self.block_setup = build.equip(m, devices)
        self.devices: dict[str, Any] = m.devices
        build.attach_scan_hooks(m)
        self.ast = program
        self.program: CompiledProgram = build.load_program(m, program)
        self.program_version = 0  # bumped by each new program (online change, reload)
        self.code_version = 0  # bumped whenever the running code is rebuilt (forcing too)
        self.program_loaded_at = time.time()  # wall time of the last load (online change)
        self.engine.cold_start()

    config = _machine_value("raw", "The configuration as written (a dict).")
    settings = _machine_value("settings", "The configuration, checked and typed (Config).")

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def from_file(cls, path: str | Path, config: build.ConfigSource = None,
                  **kw: Any) -> PLC:
        config = build.load(config)  # checked first, once: the parser needs its symbols
        table = build.symbol_table(config)
        return _checked(cls, lambda: parse_file(path, table), config, kw)

    @classmethod
    def from_source(cls, text: str, config: build.ConfigSource = None,
                    *, file: str = "<string>", **kw: Any) -> PLC:
        config = build.load(config)
        table = build.symbol_table(config)
        return _checked(cls, lambda: parse(text, file, table), config, kw)


    def compile_debug(self) -> CompiledProgram:
        """The debug build: `main()` is a generator yielding (rung, instruction) before each
        instruction; `log[rung][k]` holds the accumulator after instruction k."""
        return build.compile_onto(self.machine, self.ast, build.forced_bits(self._forced),
                                  debug=True)

    def replace_program(self, program: A.Program, *, new_program: bool = True) -> None:
        """Run `program` from the next scan on, keeping memory (the debugger's reload).
        Raises CompileError, leaving the running program in place, if it does not compile.
        `new_program` False: the same program rebuilt (a bit forced or released): the
        program's version, which the user sees, stays; only `code_version` moves."""
        self.program = build.load_program(self.machine, program,
                                          build.forced_bits(self._forced))
        self.ast = program
        self.code_version += 1
        if new_program:
            self.program_version += 1
            self.program_loaded_at = time.time()

    # -- running --------------------------------------------------------------------------------
    def scan(self, n: int = 1) -> None:
        """Run n scans (on the virtual clock each advances time by scan_period)."""
        eng = self.engine  # eng.scan each time: a change in a scan replaces it
        if n == 1:  # the common call: no range object (80 ns of a 3.1 us scan)
            eng.scan()
            return
        for _ in range(n):
            eng.scan()

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
            raise AddressError(f"{ref.label} is a constant: set it in the configuration "
                               f"([constants])")
        if ref.kind in BLOCK_FIELDS and (ref.field is None or
                                         not BLOCK_FIELDS[ref.kind].get(ref.field, ("", 0))[1]):
            raise AddressError(f"{ref.label} is read-only")
        self.mem.write(ref, value)

    def _ref(self, address: str | Ref) -> Ref:
        if isinstance(address, Ref):
            return address
        ref = self._refs.get(address)
        if ref is None:  # parsed once per address string: hosts poll the same words
            # an address, a symbol, a symbol's range or field (plc["STARTS:4"]): one
            # resolver (softplc.twido.symbols), the symbol attached for the messages
            ref = self._refs[address] = self.symbols.ref(address)
        return ref

    def force(self, address: str, value: Any) -> None:
        """Hold an object at a value, whatever the program or the field does. A forced bit
        keeps its value all through the scan (the program's stores to it are compiled out);
        a forced word is re-asserted at the start and end of every scan."""
        ref = self._ref(address)
        before = build.forced_bits(self._forced)
        self._forced[ref] = value
        self.engine.set_forced(dict(self._forced))
        self.mem.write(ref, value, field_inputs=False)
        self._forced_changed(before)

    def unforce(self, address: str | None = None) -> None:
        """Release one forced object, or all of them."""
        before = build.forced_bits(self._forced)
        if address is None:
            self._forced.clear()
        else:
            self._forced.pop(self._ref(address), None)
        self.engine.set_forced(dict(self._forced))
        self._forced_changed(before)

    def _forced_changed(self, before: frozenset[Ref]) -> None:
        """Recompile when the set of forced bits changed (2-14 ms for a machine program),
        so that stores to them are left out (or back in); not for words or a no-op."""
        if build.forced_bits(self._forced) != before:
            self.replace_program(self.ast, new_program=False)

    @property
    def forced(self) -> dict[str, Any]:
        return {str(r): v for r, v in self._forced.items()}

    # -- state ----------------------------------------------------------------------------------
    def __repr__(self) -> str:
        """State, PLC time, scan count and the I/O that is on, by symbol and address
        (`on: MOTOR(%Q0.0) %Q0.4`): what a failing test shows."""
        stride, shown = self.mem.stride, 16
        slots = self.profile.expansion_slots  # beyond: the remote I/O's (%Ix.0.z)
        on = [self.symbols.label(f"%{kind}{i // stride}.{i % stride}" if i // stride <= slots
                                 else f"%{kind}{i // stride - slots}.0.{i % stride}")
              for kind, bits in
              (("I", self.mem.i), ("Q", self.mem.q)) for i, v in enumerate(bits) if v]
        io = " ".join(on[:shown]) + (f" (+{len(on) - shown} more)" if len(on) > shown else "")
        return (f"<PLC {Path(self.ast.file).name} {self.state} t={self.time:.3f}s "
                f"scans={self.scan_count} on: {io or 'none'}>")

    time = property(attrgetter("_clock.seconds"),
                    doc="PLC time in seconds (virtual: scans x scan_period).")
    clock = property(attrgetter("_clock"))
    scan_count = _engine_value("stats.scans", "Scans run since the PLC was built.")
    state = _engine_value("state", "RUN, STOP, HALT (softplc.runtime.engine).")
    fault = _engine_value("fault", "Why the engine halted ('' when it did not).")
    stats = _engine_value("stats", "The engine's scan statistics.")
    before_scan = _engine_value("before_scan", "Hooks run before each scan.")
    after_scan = _engine_value("after_scan", "Hooks run after each scan.")
    rungs = property(attrgetter("ast.rungs"), doc="The program's rungs.")
    cold_start = _engine("cold_start")
    warm_start = _engine("warm_start")
    stop = _engine("stop")
    start = _engine("start")

    @property
    def trace(self) -> list:
        """Samples of the machine's trace recorder (empty without one)."""
        for dev in self.devices.values():
            if getattr(dev, "type_name", "") == "trace":
                return dev.samples
        return []

    def set_scan_period(self, seconds: float) -> None:
        """Change the scan period (the virtual clock's step, %SW0)."""
        if seconds <= 0:
            raise ConfigError("scan period must be > 0")
        self.scan_period = seconds
        self.engine.period_us = max(1, round(seconds * 1e6))
        self.mem.sw.w[0] = min(32767, round(seconds * 1000))

    def close(self) -> None:
        """Flush and close devices (trace files) and the EXCH port's connections."""
        if self.machine.exch is not None:
            self.machine.exch.close()
        for dev in self.devices.values():
            close = getattr(dev, "close", None)
            if close:
                close()

    def __enter__(self) -> PLC:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _checked(cls: type[PLC], parser: Any, config: Any, kw: dict[str, Any]) -> PLC:
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


__all__ = ["PLC", "SoftPLCError"]
