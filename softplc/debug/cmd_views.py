"""Debugger commands: views of the PLC and the program (timers, counters, pid, pulses,
analog, link, status, where, rung, rungs, reload, help, quit)."""

from __future__ import annotations

import difflib
import textwrap
from typing import TYPE_CHECKING, Any

from softplc import ladder
from softplc.debug.registry import command, first_sentence
from softplc.debug.report import position_text, reload_text
from softplc.debug.stepper import BreakKind, DebugError, resolve_rung
from softplc.il import ast as A
from softplc.il.parser import parse_file
from softplc.twido import catalog
from softplc.twido.address import LINK_WORDS

if TYPE_CHECKING:
    from softplc.debug.session import Session


@command("timers")
def cmd_timers(s: Session, arg: str) -> str:
    """timers: every timer with its type, base, preset, value and output."""
    return "\n".join(_listing(s, "timers")) or "no timers"


@command("counters")
def cmd_counters(s: Session, arg: str) -> str:
    """counters: every counter with its preset, value and outputs (D done, E/F
    underflow/overflow); the fast counters %FC / %VFC with their mode (_en: IN, lost:
    pulses above the input's frequency)."""
    return "\n".join(_listing(s, "counters")) or "no counters"


def _listing(s: Session, command: str) -> list[str]:
    """The lines of the blocks of the families `command` lists (catalog order): a block's
    own `listing(i)`, or its mode and its summary of the ladder's box."""
    lines = []
    for fam in catalog.listed_in(command):
        for i, b in sorted(s.plc.mem.blocks.get(fam.kind, {}).items()):
            lines.append(b.listing(i) if hasattr(b, "listing") else
                         f"{f'%{fam.kind}{i}':<6} {b.mode:<10} {ladder.block_summary(b)}")
    return lines


@command("pid")
def cmd_instruction_blocks(s: Session, arg: str) -> str:
    """pid: every PID function with its mode, set point, measure, output, Kp/Ti/Td,
    diagnostic word and auto-tuning state."""
    lines = []
    for fam in catalog.by_instruction().values():  # the blocks `[ PID n ]` runs
        blocks = s.plc.mem.blocks.get(fam.kind, {})
        lines += [b.listing(i) for i, b in sorted(blocks.items())] or [f"no {fam.title}s"]
    return "\n".join(lines)


@command("pulses")
def cmd_pulses(s: Session, arg: str) -> str:
    """pulses: every pulse output (%PLS, %PWM) with its period, frequency, fields, the
    pulses sent so far and the duty cycle."""
    pulses = s.plc.mem.pulses
    if pulses is None:
        return "no pulse outputs"
    now = s.plc.engine.clock.now_us
    return "\n".join(f"{pulses.names[i]:<16} {g.summary(now)}"
                     for i, g in sorted(pulses.by_output.items()))


@command("analog")
def cmd_analog(s: Session, arg: str) -> str:
    """analog: every analog channel with its signal, range, word and physical value."""
    analog = s.plc.mem.analog
    if analog is None or not analog.channels:
        return "no analog channels"
    lines = []
    for ref, ch in sorted(analog.channels.items(), key=lambda kv: (kv[0].kind, kv[0].index)):
        word = s.plc.mem.read(ref)
        rng = f"{ch.range} {ch.lo}..{ch.hi}" if ch.range in ("normal", "custom") else ch.range
        extra = f"  = {analog.output(ref):.3f}" if ref.kind == "QW" else ""
        lines.append(f"{str(ref):<8} {ch.signal:<6} {rng:<18} {word}{extra}")
    return "\n".join(lines)


@command("link")
def cmd_link(s: Session, arg: str) -> str:
    """link: the Remote Link station (master or peer), each station's presence, the
    status words %SW111-%SW113 and the network words %INW / %QNW."""
    link = s.plc.machine.link
    if link is None:
        return "no Remote Link ([remote_link] not configured)"
    st = link.status()
    lines = [f"address {link.address} ({s.plc.settings.remote_link.kind})   %SW111="
             f"16#{st['status']:04X} %SW112={st['error']} %SW113=16#{st['config']:04X}"]
    stations = getattr(link, "remotes", None) or {0: "peer"}
    for a, role in stations.items():
        here = "present" if st["status"] >> ((a or link.address) - 1) & 1 else "ABSENT"
        if role != "peer":  # a remote I/O controller: its channels are the master's %Ia.0.z
            lines.append(f"station {a}: {here:7s} remote I/O (%I{a}.0.z, %Q{a}.0.z)")
            continue
        words = " ".join(f"{s.plc.mem.read(f'%INW{a}.{j}'):6d}" for j in range(LINK_WORDS))
        sent = " ".join(f"{s.plc.mem.read(f'%QNW{a}.{j}'):6d}" for j in range(LINK_WORDS))
        lines.append(f"station {a}: {here:7s} %INW{a}.0-3 {words}   %QNW{a}.0-3 {sent}")
    return "\n".join(lines)


@command("status", "info")
def cmd_status(s: Session, arg: str) -> str:
    """status: PLC state, scan count, virtual time, scan times, position, forced."""
    st = s.plc.stats
    n = max(1, st.scans)
    lines = [f"state    {s.plc.state}" + (f" ({s.plc.fault})" if s.plc.fault
                                              else ""),
             f"scans    {st.scans}   time {s.plc.time:.3f} s   period "
             f"{s.plc.scan_period * 1000:g} ms",
             f"scan     last {st.last * 1e6:.0f} us  min {st.min * 1e6:.0f} us  max "
             f"{st.max * 1e6:.0f} us  mean {st.total / n * 1e6:.0f} us (execution, wall)",
             f"position {position_text(s.ctl.position(), s.plc.ast)}",
             f"history  {len(s.ctl.ring)} scans (back)",
             f"forced   {', '.join(f'{k}={v}' for k, v in s.plc.forced.items()) or '-'}"]
    if s.ctl.pending:
        lines.append("pending  " + ", ".join(f"{r} := {v}" for r, v in s.ctl.pending))
    if s.ctl.breaks:
        lines.append(f"breaks   {len(s.ctl.breaks)}")
    if s.trace_writer is not None:
        lines.append(f"trace    {', '.join(map(str, s.trace_refs))} -> "
                     f"{s.trace_file.name}")
    for name, dev in s.plc.devices.items():
        info = dev.status()
        if info:
            lines.append(f"device   {name}: " + " ".join(f"{k}={v}" for k, v in info.items()))
    return "\n".join(lines)


@command("where", "bt")
def cmd_where(s: Session, arg: str) -> str:
    """where: the current position (the next instruction to run)."""
    return position_text(s.ctl.position(), s.plc.ast)


@command("rung")
def cmd_rung(s: Session, arg: str) -> str:
    """rung [N | TITLE | SYMBOL]: the rung as a ladder with live power flow (double lines) and
    values (F = forced); > marks the next instruction. Default: the current rung."""
    r = resolve_rung(s.plc.ast, arg, s.plc.symbols) if arg else s.plc.ast.rungs[s.ctl.last_rung]
    live = ladder.Live(s.read, s.ctl.dbg.log[r.index] if r.index < len(s.ctl.dbg.log)
                       else None, set(s.plc.forced))
    marker = s.ctl.pos[1] if s.ctl.pos and s.ctl.pos[0] == r.index else None
    text = ladder.render_text(r, live, marker=marker)
    if s.ctl.pos is not None and (r.index > s.ctl.pos[0] or marker is not None):
        text += "(power flow of the previous scan where this scan has not run yet)\n"
    return text.rstrip("\n")


@command("rungs", "l")
def cmd_rungs(s: Session, arg: str) -> str:
    """rungs: list the rungs (* breakpoint, > current)."""
    bp = {b.rung for b in s.ctl.breaks if b.kind == BreakKind.RUNG and b.enabled}
    lines = []
    for r in s.plc.ast.rungs:
        mark = (">" if s.ctl.pos and s.ctl.pos[0] == r.index else " ") + \
            ("*" if r.index in bp else " ")
        where = f"SR{r.subroutine} " if r.subroutine is not None else ""
        lbl = f"%L{r.label}: " if r.label is not None else ""
        lines.append(f"{mark}{r.index:>4}  {where}{lbl}{r.title or '(no title)'}")
    return "\n".join(lines)


@command("reload")
def cmd_reload(s: Session, arg: str) -> str:
    """reload: re-read the program file, keep memory, report the rungs added, removed,
    modified. A scan in progress is finished first."""
    if s.path is None:
        raise DebugError("the program was not loaded from a file")
    new = parse_file(s.path)
    old = s.plc.ast
    done = s.ctl.reload(new)
    pre = "finished the scan in progress\n" if done.finished else ""
    report = diff_programs(old, new) + reload_text(done)
    return pre + (f"reloaded {s.path}: " + ("; ".join(report) if report else
                                               "no change"))


@command("help")
def cmd_help(s: Session, arg: str) -> str:
    """help [COMMAND]: list the commands, or explain one."""
    if arg:
        name = s.aliases.get(arg, arg)
        if name not in s.commands:
            raise DebugError(f"no command {arg!r}")
        return s.commands[name].doc
    lines = ["commands (help NAME for details):"]
    for name, doc in sorted((c.name, c.doc) for c in s.commands.values()):
        lines += textwrap.wrap(first_sentence(doc) if doc else name,
                               max(40, s.width - 1), initial_indent="  ",
                               subsequent_indent="      ",
                               break_on_hyphens=False)  # "auto-tuning" stays whole
    lines += textwrap.wrap("aliases: " + ", ".join(f"{a}={n}" for a, n in
                                                   sorted(s.aliases.items())),
                           max(40, s.width - 1), subsequent_indent="  ")
    return "\n".join(lines)


@command("quit", "q", "exit")
def cmd_quit(s: Session, arg: str) -> str:
    """quit: leave the debugger."""
    s.close()
    s.done = True
    return "bye"


def diff_programs(old: A.Program, new: A.Program) -> list[str]:
    """What changed between two versions of a program, rung by rung."""
    def sig(r: A.Rung) -> tuple[Any, ...]:
        return (r.title, r.label, r.subroutine, tuple(r.instructions))

    a, b = [sig(r) for r in old.rungs], [sig(r) for r in new.rungs]
    added, removed, modified = [], [], []
    sm = difflib.SequenceMatcher(None, a, b, autojunk=False)
    for op, i1, i2, j1, j2 in sm.get_opcodes():
        if op == "equal":
            continue
        olds, news = old.rungs[i1:i2], new.rungs[j1:j2]
        paired = min(len(olds), len(news)) if op == "replace" else 0
        modified += [n.name for n in news[:paired]]
        removed += [o.name for o in olds[paired:]]
        added += [n.name for n in news[paired:]]
    out = []
    for what, names in (("added", added), ("removed", removed), ("modified", modified)):
        if names:
            out.append(f"{what}: " + ", ".join(names))
    return out
