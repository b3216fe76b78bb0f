"""Program -> code on the machine: resolve, allocate blocks and I/O, bind, generate; and the
real-time clock when the program or the configuration needs one."""

from __future__ import annotations

import re
from datetime import datetime, timedelta
from typing import TYPE_CHECKING, Any

from softplc.assembly import hardware
from softplc.assembly.heap import release_free_memory
from softplc.compiler import Resolved, compile_program, resolve
from softplc.errors import Code, Diagnostic
from softplc.il import ast as A
from softplc.program import CompiledProgram, bind
from softplc.runtime.clock import VirtualClock
from softplc.runtime.rtc import DEFAULT_START, RTC
from softplc.twido.address import IO_KINDS, NETWORK_KINDS, Ref

if TYPE_CHECKING:
    from softplc.assembly.machine import Machine

TRIM_SOURCE = 256 * 1024  # generated source bytes past which compiling is worth a trim

# Objects of the real-time clock: %SW49-%SW53, %S50, %S51 (not %SW490, %S500...).
_RTC_OBJECTS = re.compile(r"%SW(49|5[0-3])(?!\d)|%S5[01](?!\d)", re.I)


def forced_bits(forced: dict[Ref, Any]) -> frozenset[Ref]:
    """The forced bits, whose stores the compiled program leaves out (words are re-asserted
    by the engine instead: no code depends on them)."""
    return frozenset(r for r in forced if r.kind in ("I", "Q", "M", "S", "X") and r.offset is None)


def _io_check(m: Machine, ref: Ref) -> str | None:
    """What is wrong with an I/O channel the program uses (None: it exists)."""
    mem, profile = m.mem, m.profile
    if ref.kind in NETWORK_KINDS or ref.station is not None:
        return hardware.link_word_check(m.settings.remote_link, ref)
    if ref.kind in ("IW", "QW"):
        if mem.analog is not None and ref in mem.analog.channels:
            return None
        if ref.module == 0 or m.modules is not None:
            return (f"{ref.label}: no such analog channel (the base has %IW0.0.."
                    f"%IW0.{len(profile.analog_base) - 1}; expansion channels need "
                    f"an analog module in [modules])")
        return None
    if ref.module and m.modules is not None:
        mod = m.modules.get(ref.module)
        n = None if mod is None else (mod[0] if ref.kind == "I" else mod[1])
        if not n:
            what = "inputs" if ref.kind == "I" else "outputs"
            return f"{ref.label}: no module in slot {ref.module} with {what} (see [modules])"
        if ref.channel >= n:
            return f"{ref.label}: the module in slot {ref.module} has {n} channels"
    return None


def _allocate(m: Machine, program: A.Program, resolved: Resolved) -> list[Diagnostic]:
    """Create the blocks and I/O copies the resolve pass found; the problems found."""
    problems = []

    def problem(msg: str, ref: Any, pos: A.Pos, expected: str, code: Code) -> None:
        problems.append(Diagnostic(msg, program.file, pos.line, pos.column, str(ref),
                                   expected, code))

    for ref, pos in resolved.blocks.items():
        msg = m.block_factory(ref)
        if msg:
            problem(msg, ref, pos, "a configured block within the profile", Code.BLOCK)
    for ref, pos in resolved.io.items():
        if ref.kind in IO_KINDS:  # analog words need no scan-boundary copy
            m.mem.use_io(ref)
        msg = _io_check(m, ref)
        if msg:
            problem(msg, ref, pos, "a station of [remote_link]"
                    if ref.kind in NETWORK_KINDS or ref.station is not None
                    else "an I/O channel of a configured module",
                    Code.IO)
    pulses = m.mem.pulses
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
    cold = m.engine.cold_states
    for kind, blocks in m.mem.blocks.items():
        for i, b in blocks.items():
            if (kind, i) not in cold:
                cold[kind, i] = b.state()
    return problems


def compile_onto(m: Machine, program: A.Program, forced: frozenset[Ref] = frozenset(),
                 debug: bool = False) -> CompiledProgram:
    """Resolve, allocate, bind, generate. The program state (edge memory, initial steps)
    changes only once the program compiled. `forced`: bits whose stores are left out."""
    counts = dict(m.profile.counts)
    resolved = resolve(program, counts)
    problems = _allocate(m, program, resolved)
    state = m.program_state
    env = bind(m.mem, m.ops, state, m.engine.watchdog_expired, m.mem.blocks)
    compiled = compile_program(program, resolved, env, state, counts, debug, forced, problems)
    if len(compiled.source) > TRIM_SOURCE:  # compile() left its peak in the C heap
        release_free_memory()
    state.size_edges(resolved.edges)
    state.initial_steps = m.grafcet.initial = resolved.initial_steps
    ts = m.time_source
    ts.track = _conditional_execution(program)
    if not ts.track:
        ts.running.clear()
    return compiled


def attach_rtc(m: Machine, program: A.Program) -> None:
    """The real-time clock costs a little every scan: give the engine one only when the
    program names its words or bits, or the configuration has [rtc] / [schedule]."""
    configured = m.settings.rtc is not None
    if m.engine.rtc is not None or not (
            configured or m.schedules or _RTC_OBJECTS.search(program.source)):
        return
    start = m.rtc_start
    if start is None:
        start = DEFAULT_START if isinstance(m.clock, VirtualClock) else \
            datetime.now().replace(microsecond=0) - timedelta(seconds=m.clock.seconds)
    m.engine.rtc = RTC(m.mem, start, m.schedules)


def load_program(m: Machine, program: A.Program,
                 forced: frozenset[Ref] = frozenset()) -> CompiledProgram:
    """Compile `program` onto the machine and make it the one the engine runs (raises
    CompileError, leaving the running program in place, if it does not compile)."""
    compiled = compile_onto(m, program, forced)
    m.engine.load(compiled)
    attach_rtc(m, program)
    return compiled


def _conditional_execution(program: A.Program) -> bool:
    """Can a block be skipped in a scan (a jump, a subroutine, a Grafcet step, ENDC/ENDCN)?
    Only then do timers need updating when not executed."""
    return any(isinstance(i, (A.Jump, A.SRCall, A.Grafcet))
               or isinstance(i, A.End) and i.op != "END"
               for r in program.rungs for i in r.instructions)
