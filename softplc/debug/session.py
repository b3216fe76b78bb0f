"""The debugger's command API, independent of the terminal.

    s = Session(plc, program_path="x.il")
    print(s.execute("break 13"))      # every command returns the text to show
    print(s.execute("continue"))

Execution: one scan in progress at most, kept as a generator over the debug build
(`plc.engine.scan_stepwise(dbg.main)`), which stops *before* each instruction. `stepi` /
`step` advance it by one instruction / to the start of the next rung; `scan`, `run` and
`continue` finish it and run whole scans, with the fast build when no rung breakpoint needs
the debug build (watches and conditions are then checked once per scan). The last scan of
a batch always runs the debug build so that `rung N` shows this scan's power flow.

History: a bounded ring of snapshots taken at the start of every scan (memory, clock, scan
statistics, edge memory, device state); `back N` restores one.
"""

from __future__ import annotations

import csv
import dataclasses
import difflib
import math
import re
import struct
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..address import IO_KINDS, Ref, expand
from ..config import duration
from ..display import format_value
from ..errors import ConfigError, SoftPLCError
from ..il import ast as A
from ..il.parser import parse_file
from ..plc import PLC
from ..semantics import COMPARE, COMPARE_PY
from . import ladder
from .controller import (
    HISTORY,
    STOPS_A_COMMAND,
    Breakpoint,
    Controller,
    DebugError,
    Ran,
    StopKind,
)

CONTINUE_LIMIT = 100_000  # scans `continue` runs before giving up
WORDS = ("MW", "KW", "SW")
DWORDS = ("MD", "KD")
FLOATS = ("MF", "KF")
# the Twido operators and their Python spellings (== !=), as users also type them
CMP_OPS = {**COMPARE, **{COMPARE_PY[op]: fn for op, fn in COMPARE.items()}}
_COND = re.compile(r"^\s*(\S+)\s*(==|=|<>|!=|<=|>=|<|>)\s*(\S+)\s*$")


def parse_value(text: str) -> int | float:
    """A number as the user types it: 12, -3, 16#FF, 0xFF, 2#1010, 1.5, true/false."""
    t = text.strip().lower().replace("_", "")
    if t in ("true", "on"):
        return 1
    if t in ("false", "off"):
        return 0
    try:
        if t.startswith("16#"):
            return int(t[3:], 16)
        if t.startswith("2#"):
            return int(t[2:], 2)
        if t.startswith(("0x", "-0x")):
            return int(t, 16)
        return int(t)
    except ValueError:
        pass
    try:
        v = float(t)
    except ValueError:
        raise DebugError(f"bad value {text!r}: a number (12, -3, 16#FF, 2#1010, 1.5)") from None
    if not math.isfinite(v):
        raise DebugError(f"bad value {text!r}")
    return v


@dataclasses.dataclass(frozen=True)
class Command:
    """One debugger command: the method that runs it, its help text, its other names and
    whether it takes a /FORMAT (print/x)."""

    name: str
    fn: Callable[..., str]
    doc: str
    aliases: tuple[str, ...] = ()
    formats: bool = False


# The command table: every command, filled by `@command` on the methods of `Session`.
COMMANDS: dict[str, Command] = {}


def command(name: str, *aliases: str, formats: bool = False
            ) -> Callable[[Callable[..., str]], Callable[..., str]]:
    """Register a `Session` method as the command `name` (and its aliases)."""
    def register(fn: Callable[..., str]) -> Callable[..., str]:
        COMMANDS[name] = Command(name, fn, (fn.__doc__ or "").strip(), aliases, formats)
        return fn
    return register


class Session:
    """A debugging session over one PLC: the command and format layer over a stepping
    controller (`self.ctl`, which the web monitor can drive the same way). `execute(line)`
    runs a command from the table `COMMANDS` and returns its text."""

    def __init__(self, plc: PLC, program_path: str | Path | None = None,
                 history: int = HISTORY):
        self.plc = plc
        self.ctl = Controller(plc, history)
        self.path = Path(program_path) if program_path else None
        self.width = 80  # of the text `help` wraps to (the REPL sets the terminal's)
        self.trace_file: Any = None
        self.trace_writer: Any = None
        self.trace_refs: list[Ref] = []
        self.done = False
        self.continue_limit = CONTINUE_LIMIT
        self.ctl.scan_end_hooks.append(self._scan_done)
        self.commands = COMMANDS
        self.aliases = {a: c.name for c in COMMANDS.values() for a in c.aliases}

    @property
    def pos(self) -> tuple[int, int] | None:
        """The next instruction (rung, k), None at the scan boundary."""
        return self.ctl.pos

    # ---- the command line -------------------------------------------------------------------
    def execute(self, line: str) -> str:
        """Run one command line. Errors come back as text: the session never dies of one."""
        line = line.strip()
        if not line or line.startswith("#"):
            return ""
        word, _, rest = line.partition(" ")
        fmt = ""
        if "/" in word and not word.startswith("%"):
            word, _, fmt = word.partition("/")
            if not fmt:
                return "error: a format after / (d u x b f), e.g. print/x %MW0"
        name = self.aliases.get(word.lower(), word.lower())
        if name not in self.commands:
            close = difflib.get_close_matches(name, list(self.commands), 1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            return f"error: unknown command {word!r}{hint}; 'help' lists the commands"
        cmd = self.commands[name]
        try:
            if cmd.formats:
                return cmd.fn(self, rest, fmt)
            if fmt:
                raise DebugError(f"{name} takes no /format")
            return cmd.fn(self, rest.strip())
        except (SoftPLCError, ValueError, KeyError, IndexError, TypeError, OSError) as e:
            msg = e.args[0] if isinstance(e, KeyError) and e.args else e
            return f"error: {msg}"

    def complete_words(self) -> list[str]:
        """Command names (for tab completion)."""
        return sorted(self.commands)

    def addresses(self) -> list[str]:
        """Every object the program names, for tab completion."""
        found: set[str] = set()

        def walk(x: Any) -> None:
            if isinstance(x, Ref):
                found.add(str(x))
                if x.field is not None or x.bit is not None:
                    found.add(str(Ref(x.kind, x.index, x.module, x.channel)))
                if x.offset is not None:
                    walk(x.offset)
            elif dataclasses.is_dataclass(x) and not isinstance(x, type):
                for f in dataclasses.fields(x):
                    walk(getattr(x, f.name))
            elif isinstance(x, (list, tuple)):
                for y in x:
                    walk(y)

        for r in self.plc.ast.rungs:
            walk(r.instructions)
        found.update(s.name for s in self.plc.symbols)
        for kind, blocks in self.plc.mem.blocks.items():
            for i in blocks:
                if kind != "PID":  # PID n is no address
                    found.add(f"%{kind}{i}")
        return sorted(found)

    def interrupt(self) -> None:
        """Ask a running `run`/`continue` to stop at the next scan or instruction (Ctrl-C)."""
        self.ctl.interrupt()

    # ---- objects -------------------------------------------------------------------------
    def parse_obj(self, text: str) -> list[Ref]:
        """An address, a range (`%MW0:15`: 15 words, `%Q1.0:8`: 8 bits from %Q1.0) or a
        symbol (`START_PB`, `TIMER1.Q`), each object with its symbol attached."""
        table = self.plc.symbols
        return [table.attach(r) for r in expand(table.address_of(text), self.plc.profile)]

    def title(self, ref: Ref) -> str:
        """`%I0.0 START_PB`: an object and its symbol, if it has one."""
        return f"{ref} {ref.symbol}" if ref.symbol else str(ref)

    def read(self, ref: Ref) -> Any:
        return self.plc.mem.read(ref)

    def fmt(self, ref: Ref, v: Any, f: str = "") -> str:
        """One value in a format: d (default), u, x, b, f."""
        if ref.is_block or ref.type == "bool" or f in ("", "d"):
            return format_value(v, ref)  # as `softplc io` and the ladder show it
        bits = 32 if ref.kind in DWORDS + FLOATS else 16
        if isinstance(v, float):
            raw = int.from_bytes(struct.pack("<f", v), "little")
        else:
            raw = int(v) & ((1 << bits) - 1)
        if f == "u":
            return str(raw)
        if f == "x":
            return f"16#{raw:0{bits // 4}X}"
        if f == "b":
            s = f"{raw:0{bits}b}"
            return "2#" + "_".join(s[i:i + 4] for i in range(0, bits, 4))
        if f == "f":
            if isinstance(v, float):
                return f"{v:.7g}"
            if ref.kind in WORDS and ref.bit is None:
                fam = self.plc.mem.words(ref.kind)
                if ref.index + 1 >= fam.n:
                    raise DebugError(f"{ref} is the last word: no float there")
                return f"{fam.get_f(ref.index):.7g}"
            return f"{struct.unpack('<f', raw.to_bytes(4, 'little'))[0]:.7g}"
        raise DebugError(f"unknown format /{f}: use /d /u /x /b /f")

    def show(self, ref: Ref, f: str = "") -> str:
        v = self.read(ref)
        s = self.fmt(ref, v, f)
        if str(ref) in self.plc.forced:
            s += "  [forced]"
        if ref.kind in IO_KINDS:
            fld = (self.plc.mem.i_field if ref.kind == "I" else self.plc.mem.q_field)[ref.index]
            if bool(fld) != bool(v):
                s += f"  (field {int(fld)})"
        return s

    # ---- snapshots ----------------------------------------------------------------------------
    def _scan_done(self) -> None:
        if self.trace_writer is not None:
            self.trace_writer.writerow([self.plc.scan_count, f"{self.plc.time:.6f}"] +
                                       [self._trace_value(r) for r in self.trace_refs])

    def _trace_value(self, ref: Ref) -> Any:
        v = self.read(ref)
        return int(v) if isinstance(v, bool) else v

    # ---- commands: execution -----------------------------------------------------------------
    @command("scan")
    def cmd_scan(self, arg: str) -> str:
        """scan [N]: finish the scan in progress, then run N more scans (default 1; 0 when a
        scan is in progress). Stops at breakpoints."""
        n = self._count(arg, 0 if self.ctl.in_scan else 1)
        return self.ctl.run_scans(n).text

    @command("step", "s")
    def cmd_step(self, arg: str) -> str:
        """step [N]: run to the start of the next rung (entering a scan if at the boundary)."""
        ran = Ran(StopKind.DONE, "")
        for _ in range(self._count(arg, 1)):
            ran = self.ctl.step()
            if ran.reason in STOPS_A_COMMAND:
                break
        return ran.text

    @command("stepi", "si")
    def cmd_stepi(self, arg: str) -> str:
        """stepi [N]: run one instruction (entering a scan if at the boundary)."""
        ran = Ran(StopKind.DONE, "")
        for _ in range(self._count(arg, 1)):
            ran = self.ctl.step_instruction()
            if ran.reason in STOPS_A_COMMAND:
                break
        return ran.text

    @command("run", "r")
    def cmd_run(self, arg: str) -> str:
        """run N | run Ts: run N scans (run 100) or T seconds of PLC time (run 2s, run 500ms).
        Stops at breakpoints."""
        a = arg.strip()
        if not a:
            raise DebugError("run N (scans) or run T (seconds, e.g. 2s, 500ms)")
        if re.fullmatch(r"\d+", a):
            n = int(a)
        else:
            try:
                secs = duration(a, "run")
            except ConfigError as e:
                raise DebugError(str(e)) from None
            n = max(1, round(secs / self.plc.scan_period))
        if self.ctl.in_scan:
            n = max(0, n - 1)  # the scan in progress counts as one
        return self.ctl.run_scans(n).text

    @command("continue", "c", "cont")
    def cmd_continue(self, arg: str) -> str:
        """continue: run until a breakpoint or watch stops it (at most 100000 scans;
        Ctrl-C stops it)."""
        if not self.ctl.breaks or not any(b.enabled for b in self.ctl.breaks):
            raise DebugError("no breakpoint is enabled: continue would never stop "
                             "(use 'run N' or set one with 'break')")
        ran = self.ctl.run_scans(self.continue_limit)
        if ran.reason not in STOPS_A_COMMAND:
            return f"no breakpoint hit in {self.continue_limit} scans\n" + ran.text
        return ran.text

    def _count(self, arg: str, default: int) -> int:
        if not arg:
            return default
        try:
            n = int(arg)
        except ValueError:
            raise DebugError(f"{arg!r} is not a count") from None
        if n < 0:
            raise DebugError("the count must be >= 0")
        return n

    @command("back")
    def cmd_back(self, arg: str) -> str:
        """back [N]: go back N scans (default 1; a scan in progress counts as one)."""
        n = self._count(arg, 1)
        if n == 0:
            return self.ctl.position()
        self.ctl.back(n)
        return self.ctl.position()

    # ---- commands: breakpoints -----------------------------------------------------------------
    @command("break", "b")
    def cmd_break(self, arg: str) -> str:
        """break RUNG | break %Li | break when COND: stop before a rung (number or title), at a
        label, or when a condition becomes true: `break when %MW32 = 100` (= <> < <= > >=, a
        value or an address on the right), `break when %M33 rises` (falls, changes).
        Without argument: list the breakpoints."""
        if not arg:
            return self.cmd_breakpoints("")
        m = re.match(r"when\s+(.*)$", arg, re.I)
        if m:
            return self._break_when(m[1])
        r = self.ctl.resolve_rung(arg)
        b = self.ctl.add_breakpoint(kind="rung", text=r.name, rung=r.index, key=arg)
        return f"breakpoint #{b.id} at {r.name}"

    def _break_when(self, text: str) -> str:
        parts = text.split()
        if len(parts) == 2 and parts[1].lower() in ("rises", "falls", "changes"):
            refs = self.parse_obj(parts[0])
            if len(refs) != 1:
                raise DebugError("a condition names one object, not a range")
            ref = refs[0]
            b = self.ctl.add_breakpoint(kind="cond", text=f"{ref} {parts[1].lower()}",
                          test=lambda: self.read(ref), mode=parts[1].lower())
            return f"breakpoint #{b.id} when {b.text}"
        m = _COND.match(text)
        if not m:
            raise DebugError("condition: ADDR OP VALUE (e.g. %MW32 = 100) or ADDR rises / "
                             "falls / changes")
        left = self.parse_obj(m[1])
        if len(left) != 1:
            raise DebugError("a condition names one object, not a range")
        lref, op = left[0], CMP_OPS[m[2]]
        if m[3].startswith("%"):
            rref = self.parse_obj(m[3])[0]

            def right() -> Any:
                return self.read(rref)
        else:
            val = parse_value(m[3])

            def right() -> Any:
                return val
        b = self.ctl.add_breakpoint(kind="cond", text=f"{lref} {m[2]} {m[3]}",
                      test=lambda: bool(op(self.read(lref), right())))
        return f"breakpoint #{b.id} when {b.text}" + (" (true now: stops when it becomes "
                                                      "true again)" if b.last else "")

    @command("watch")
    def cmd_watch(self, arg: str) -> str:
        """watch ADDR: stop when the object changes (a data breakpoint); its changes are
        kept for `history`."""
        refs = self.parse_obj(arg) if arg else []
        if len(refs) != 1:
            raise DebugError("watch one object, e.g. watch %MW32")
        ref = refs[0]
        b = self.ctl.add_breakpoint(kind="watch", text=self.title(ref),
                                    test=lambda: self.read(ref))
        return f"watch #{b.id} {self.title(ref)} (now {self.fmt(ref, b.last)})"

    @command("breakpoints", "breaks", "tb")
    def cmd_breakpoints(self, arg: str) -> str:
        """breakpoints: list breakpoints and watches."""
        if not self.ctl.breaks:
            return "no breakpoints"
        lines = []
        for b in self.ctl.breaks:
            what = {"rung": "at", "cond": "when", "watch": "watch"}[b.kind]
            lines.append(f"#{b.id:<3} {what} {b.text}{'' if b.enabled else '  (disabled)'}"
                         f"  hits {b.hits}")
        return "\n".join(lines)

    def _ids(self, arg: str) -> list[Breakpoint]:
        if not arg or arg == "all":
            return self.ctl.find_breakpoints(None)
        ids = []
        for t in arg.replace(",", " ").split():
            try:
                ids.append(int(t.lstrip("#")))
            except ValueError:
                raise DebugError(f"{t!r} is not a breakpoint number") from None
        return self.ctl.find_breakpoints(ids)

    @command("delete", "d")
    def cmd_delete(self, arg: str) -> str:
        """delete [ID...]: delete breakpoints/watches (all without argument)."""
        gone = self._ids(arg)
        self.ctl.delete_breakpoints(gone)
        return f"deleted {len(gone)} breakpoint(s)"

    @command("disable")
    def cmd_disable(self, arg: str) -> str:
        """disable [ID...]: disable breakpoints (all without argument)."""
        for b in self._ids(arg):
            b.enabled = False
        return self.cmd_breakpoints("")

    @command("enable")
    def cmd_enable(self, arg: str) -> str:
        """enable [ID...]: enable breakpoints (all without argument)."""
        for b in self._ids(arg):
            b.enabled = True
        return self.cmd_breakpoints("")

    @command("history")
    def cmd_history(self, arg: str) -> str:
        """history [ADDR]: the recorded changes of watched objects (watch them first)."""
        keys = [str(self.parse_obj(arg)[0])] if arg else list(self.ctl.changes)
        if not keys:
            return "nothing watched: 'watch ADDR' records the changes of an object"
        lines = []
        for key in keys:
            if key not in self.ctl.changes:
                raise DebugError(f"{key} is not watched: 'watch {key}' first")
            hist = self.ctl.changes[key]
            lines.append(f"{key}: {len(hist)} change(s)")
            for c in hist:
                lines.append(f"  scan {c.scan:>6}  t={c.time:9.3f} s  {c.where:<18} "
                             f"{format_value(c.old)} -> {format_value(c.new)}")
        return "\n".join(lines)

    # ---- commands: data -----------------------------------------------------------------------
    @command("print", "p", formats=True)
    def cmd_print(self, arg: str, fmt: str = "") -> str:
        """print[/FMT] ADDR...: show objects or ranges: %MW0:15 (15 words from %MW0),
        %Q1.0:8 (8 bits), %MF40, %TM0, %C0. FMT: d decimal, u unsigned, x hex, b binary,
        f float (a word pair as %MF). Forced values are marked [forced]."""
        if not arg.strip():
            raise DebugError("print what? e.g. print %MW0, print/x %MW0:8")
        fmt = fmt.lower()
        if fmt not in ("", "d", "u", "x", "b", "f"):
            raise DebugError(f"unknown format /{fmt}: use /d /u /x /b /f")
        lines = []
        for a in arg.split():
            refs = self.parse_obj(a)
            if len(refs) == 1:
                lines.append(f"{self.title(refs[0])} = {self.show(refs[0], fmt)}")
                continue
            per = 8 if fmt in ("", "d", "u", "f") else 4
            for i in range(0, len(refs), per):
                chunk = refs[i:i + per]
                vals = []
                for r in chunk:
                    s = self.fmt(r, self.read(r), fmt)
                    vals.append(s + ("F" if str(r) in self.plc.forced else ""))
                lines.append(f"{str(chunk[0]) + ':':<9} " + " ".join(f"{v:>6}" for v in vals))
        return "\n".join(lines)

    def _check_set(self, refs: list[Ref], values: list[str]) -> list[tuple[Ref, Any]]:
        if len(values) != len(refs):
            raise DebugError(f"{len(refs)} object(s) but {len(values)} value(s)")
        out = []
        for ref, t in zip(refs, values, strict=True):
            if not (ref.writable or ref.kind == "I"):
                raise DebugError(f"{ref} is read-only" + (" (a constant: set it in the "
                                                          "configuration)" if ref.kind in
                                                          ("KW", "KD", "KF") else ""))
            v = parse_value(t)
            if ref.type == "bool":
                if v not in (0, 1):
                    raise DebugError(f"{ref} is a bit: 0 or 1, not {t}")
            elif ref.type == "int16" and not -32768 <= v <= 65535:
                raise DebugError(f"{t} does not fit the word {ref}")
            elif ref.type == "int32" and not -2**31 <= v < 2**32:
                raise DebugError(f"{t} does not fit the double word {ref}")
            if ref.type != "real" and isinstance(v, float):
                if v != int(v):
                    raise DebugError(f"{ref} holds integers, not {t}")
                v = int(v)
            out.append((ref, v))
        return out

    @command("set")
    def cmd_set(self, arg: str) -> str:
        """set ADDR VALUE...: write an object at the start of the next scan (a range takes
        one value per object: set %MW0:3 1 2 3). %I writes go to the field input."""
        parts = arg.split()
        if len(parts) < 2:
            raise DebugError("set ADDR VALUE, e.g. set %MW3 120")
        items = self._check_set(self.parse_obj(parts[0]), parts[1:])
        self.ctl.queue(items)
        return "queued for the next scan: " + ", ".join(f"{r} := {v}" for r, v in items)

    @command("force")
    def cmd_force(self, arg: str) -> str:
        """force ADDR VALUE: hold an object at a value every scan (force alone lists)."""
        parts = arg.split()
        if not parts:
            f = self.plc.forced
            return "\n".join(f"{k} = {v}" for k, v in f.items()) if f else "nothing forced"
        refs = self.parse_obj(parts[0])
        if len(refs) != 1:
            raise DebugError("force one object at a time")
        (ref, v), = self._check_set(refs, parts[1:])
        if ref.offset is not None:
            raise DebugError("an indexed object cannot be forced")
        self.plc.force(str(ref), v)
        return f"{ref} forced to {v}"

    @command("unforce")
    def cmd_unforce(self, arg: str) -> str:
        """unforce [ADDR | all]: release a forced object (all without argument)."""
        if not arg or arg == "all":
            n = len(self.plc.forced)
            self.plc.unforce()
            return f"released {n} forced object(s)"
        ref = self.parse_obj(arg)[0]
        if str(ref) not in self.plc.forced:
            raise DebugError(f"{ref} is not forced")
        self.plc.unforce(str(ref))
        return f"{ref} released"

    @command("timers")
    def cmd_timers(self, arg: str) -> str:
        """timers: every timer with its type, base, preset, value and output."""
        tms = self.plc.mem.blocks.get("TM", {})
        if not tms:
            return "no timers"
        lines = []
        for i, t in sorted(tms.items()):
            lines.append(f"%TM{i:<3} {t.type:<3} base {t.base:<5} P={t.P:<5} V={t.V:<5} "
                         f"Q={int(t.Q)} IN={int(t.last_in)}")
        return "\n".join(lines)

    @command("counters")
    def cmd_counters(self, arg: str) -> str:
        """counters: every counter with its preset, value and outputs (D done, E/F
        underflow/overflow); the fast counters %FC / %VFC with their mode (_en: IN, lost:
        pulses above the input's frequency)."""
        cs = self.plc.mem.blocks.get("C", {})
        lines = [f"%C{i:<3} P={c.P:<5} V={c.V:<5} D={int(c.D)} E={int(c.E)} F={int(c.F)}"
                 for i, c in sorted(cs.items())]
        for kind in ("FC", "VFC"):  # fast counters (runtime/fastcount.py)
            lines += [f"{f'%{kind}{i}':<6} {c.mode:<10} {ladder.block_summary(c)}"
                      for i, c in sorted(self.plc.mem.blocks.get(kind, {}).items())]
        return "\n".join(lines) or "no counters"

    @command("pid")
    def cmd_pid(self, arg: str) -> str:
        """pid: every PID function with its mode, set point, measure, output, Kp/Ti/Td,
        diagnostic word and auto-tuning state."""
        pids = self.plc.mem.blocks.get("PID", {})
        if not pids:
            return "no PID functions"
        lines = []
        for i, pid in sorted(pids.items()):
            p, get = pid.p, pid._get
            at = pid._at or "-"
            lines.append(f"PID {i:<2} {p.mode:<6} {p.action:<7} SP={get(p.setpoint):<6} "
                         f"PV={get(p.measure):<6} OUT={round(pid.u):<5} Kp={get(p.kp)}/100 "
                         f"Ti={get(p.ti)}/10s Td={get(p.td)}/10s diag={pid.diag:#06x} AT={at}")
        return "\n".join(lines)

    @command("pulses")
    def cmd_pulses(self, arg: str) -> str:
        """pulses: every pulse output (%PLS, %PWM) with its period, frequency, fields, the
        pulses sent so far and the duty cycle."""
        pulses = self.plc.mem.pulses
        if pulses is None:
            return "no pulse outputs"
        now = self.plc.engine.clock.now_us
        return "\n".join(f"{pulses.names[i]:<16} {g.summary(now)}"
                         for i, g in sorted(pulses.by_output.items()))

    @command("analog")
    def cmd_analog(self, arg: str) -> str:
        """analog: every analog channel with its signal, range, word and physical value."""
        analog = self.plc.mem.analog
        if analog is None or not analog.channels:
            return "no analog channels"
        lines = []
        for ref, ch in sorted(analog.channels.items(), key=lambda kv: (kv[0].kind, kv[0].index)):
            word = self.plc.mem.read(ref)
            rng = f"{ch.range} {ch.lo}..{ch.hi}" if ch.range in ("normal", "custom") else ch.range
            extra = f"  = {analog.output(ref):.3f}" if ref.kind == "QW" else ""
            lines.append(f"{str(ref):<8} {ch.signal:<6} {rng:<18} {word}{extra}")
        return "\n".join(lines)

    @command("status", "info")
    def cmd_status(self, arg: str) -> str:
        """status: PLC state, scan count, virtual time, scan times, position, forced."""
        st = self.plc.stats
        n = max(1, st.scans)
        lines = [f"state    {self.plc.state}" + (f" ({self.plc.fault})" if self.plc.fault
                                                  else ""),
                 f"scans    {st.scans}   time {self.plc.time:.3f} s   period "
                 f"{self.plc.scan_period * 1000:g} ms",
                 f"scan     last {st.last * 1e6:.0f} us  min {st.min * 1e6:.0f} us  max "
                 f"{st.max * 1e6:.0f} us  mean {st.total / n * 1e6:.0f} us (execution, wall)",
                 f"position {self.ctl.position()}",
                 f"history  {len(self.ctl.ring)} scans (back)",
                 f"forced   {', '.join(f'{k}={v}' for k, v in self.plc.forced.items()) or '-'}"]
        if self.ctl.pending:
            lines.append("pending  " + ", ".join(f"{r} := {v}" for r, v in self.ctl.pending))
        if self.ctl.breaks:
            lines.append(f"breaks   {len(self.ctl.breaks)}")
        if self.trace_writer is not None:
            lines.append(f"trace    {', '.join(map(str, self.trace_refs))} -> "
                         f"{self.trace_file.name}")
        for name, dev in self.plc.devices.items():
            info = dev.status()
            if info:
                lines.append(f"device   {name}: " + " ".join(f"{k}={v}" for k, v in info.items()))
        return "\n".join(lines)

    @command("where", "bt")
    def cmd_where(self, arg: str) -> str:
        """where: the current position (the next instruction to run)."""
        return self.ctl.position()

    @command("trace")
    def cmd_trace(self, arg: str) -> str:
        """trace ADDR... to FILE.csv: record these objects at the end of every scan from now
        on (trace off: stop)."""
        if arg.strip().lower() in ("off", "stop"):
            if self.trace_file is None:
                return "no trace running"
            name = self.trace_file.name
            self._close_trace()
            return f"trace to {name} stopped"
        m = re.match(r"(.+?)\s+to\s+(\S+)$", arg)
        if not m:
            raise DebugError("trace ADDR... to FILE.csv")
        refs = [r for a in m[1].split() for r in self.parse_obj(a)]
        self._close_trace()
        try:
            self.trace_file = open(m[2], "w", newline="", encoding="utf-8")  # noqa: SIM115
        except OSError as e:
            raise DebugError(f"cannot write {m[2]}: {_why(e, m[2])}") from None
        self.trace_writer = csv.writer(self.trace_file)
        self.trace_refs = refs
        self.trace_writer.writerow(["scan", "t"] + [str(r) for r in refs])
        return f"tracing {', '.join(map(str, refs))} to {m[2]} every scan"

    def _close_trace(self) -> None:
        if self.trace_file is not None:
            self.trace_file.close()
        self.trace_file = self.trace_writer = None
        self.trace_refs = []

    # ---- commands: program --------------------------------------------------------------------
    @command("rung")
    def cmd_rung(self, arg: str) -> str:
        """rung [N | TITLE]: the rung as a ladder with live power flow (double lines) and
        values (F = forced); > marks the next instruction. Default: the current rung."""
        r = self.ctl.resolve_rung(arg) if arg else self.plc.ast.rungs[self.ctl.last_rung]
        live = ladder.Live(self.read, self.ctl.dbg.log[r.index] if r.index < len(self.ctl.dbg.log)
                           else None, set(self.plc.forced))
        marker = self.ctl.pos[1] if self.ctl.pos and self.ctl.pos[0] == r.index else None
        text = ladder.render_text(r, live, marker=marker)
        if self.ctl.pos is not None and (r.index > self.ctl.pos[0] or marker is not None):
            text += "(power flow of the previous scan where this scan has not run yet)\n"
        return text.rstrip("\n")

    @command("rungs", "l")
    def cmd_rungs(self, arg: str) -> str:
        """rungs: list the rungs (* breakpoint, > current)."""
        bp = {b.rung for b in self.ctl.breaks if b.kind == "rung" and b.enabled}
        lines = []
        for r in self.plc.ast.rungs:
            mark = (">" if self.ctl.pos and self.ctl.pos[0] == r.index else " ") + \
                ("*" if r.index in bp else " ")
            where = f"SR{r.subroutine} " if r.subroutine is not None else ""
            lbl = f"%L{r.label}: " if r.label is not None else ""
            lines.append(f"{mark}{r.index:>4}  {where}{lbl}{r.title or '(no title)'}")
        return "\n".join(lines)

    @command("reload")
    def cmd_reload(self, arg: str) -> str:
        """reload: re-read the program file, keep memory, report the rungs added, removed,
        modified. A scan in progress is finished first."""
        if self.path is None:
            raise DebugError("the program was not loaded from a file")
        new = parse_file(self.path)
        old = self.plc.ast
        finished, lost = self.ctl.reload(new)
        pre = "finished the scan in progress\n" if finished else ""
        report = diff_programs(old, new) + lost
        return pre + (f"reloaded {self.path}: " + ("; ".join(report) if report else
                                                   "no change"))

    @command("help")
    def cmd_help(self, arg: str) -> str:
        """help [COMMAND]: list the commands, or explain one."""
        if arg:
            name = self.aliases.get(arg, arg)
            if name not in self.commands:
                raise DebugError(f"no command {arg!r}")
            return self.commands[name].doc
        lines = ["commands (help NAME for details):"]
        for name, doc in sorted((c.name, c.doc) for c in self.commands.values()):
            lines += textwrap.wrap(first_sentence(doc) if doc else name,
                                   max(40, self.width - 1), initial_indent="  ",
                                   subsequent_indent="      ",
                                   break_on_hyphens=False)  # "auto-tuning" stays whole
        lines += textwrap.wrap("aliases: " + ", ".join(f"{a}={n}" for a, n in
                                                       sorted(self.aliases.items())),
                               max(40, self.width - 1), subsequent_indent="  ")
        return "\n".join(lines)

    @command("quit", "q", "exit")
    def cmd_quit(self, arg: str) -> str:
        """quit: leave the debugger."""
        self.close()
        self.done = True
        return "bye"

    def close(self) -> None:
        self._close_trace()
        self.ctl.close()


def first_sentence(doc: str) -> str:
    """The first sentence of a docstring, whole, on one line ("e.g.", "i.e.", an ellipsis
    and decimal points do not end it)."""
    text = " ".join(doc.split("\n\n")[0].split())
    m = re.search(r"(?<!\be\.g)(?<!\bi\.e)(?<!\.)\.(?=\s|$)", text)
    return text[: m.end()] if m else text


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


def _why(e: OSError, path: str) -> str:
    """An OSError as words, e.g. "the folder /x does not exist"."""
    import errno
    import os

    folder = os.path.dirname(path) or "."
    if e.errno == errno.ENOENT:
        return f"the folder {folder} does not exist"
    if e.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if e.errno == errno.EISDIR:
        return "it is a folder"
    return e.strerror or str(e)
