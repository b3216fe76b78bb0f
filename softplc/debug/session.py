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

import dataclasses
import difflib
import struct
from pathlib import Path
from typing import Any

from softplc.debug.registry import COMMANDS
from softplc.debug.stepper import HISTORY, DebugError, Stepper
from softplc.errors import SoftPLCError
from softplc.plc import PLC
from softplc.twido import catalog
from softplc.twido.address import IO_KINDS, Ref, expand
from softplc.twido.display import format_value

CONTINUE_LIMIT = 100_000  # scans `continue` runs before giving up
WORDS = ("MW", "KW", "SW")
DWORDS = ("MD", "KD")
FLOATS = ("MF", "KF")


class Session:
    """A debugging session over one PLC: the command and format layer over a `Stepper`
    (`self.ctl`, which the web monitor can drive the same way). `execute(line)`
    runs a command from the table `COMMANDS` (filled when the package `softplc.debug` is
    imported) and returns its text."""

    def __init__(self, plc: PLC, program_path: str | Path | None = None,
                 history: int = HISTORY):
        self.plc = plc
        self.ctl = Stepper(plc, history)
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
                if catalog.family(kind).addressable:  # `PID n` is no address
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

    def count(self, arg: str, default: int) -> int:
        """A command's count argument (`step 5`), `default` when none is given."""
        if not arg:
            return default
        try:
            n = int(arg)
        except ValueError:
            raise DebugError(f"{arg!r} is not a count") from None
        if n < 0:
            raise DebugError("the count must be >= 0")
        return n

    def close_trace(self) -> None:
        if self.trace_file is not None:
            self.trace_file.close()
        self.trace_file = self.trace_writer = None
        self.trace_refs = []

    def close(self) -> None:
        self.close_trace()
        self.ctl.close()


__all__ = ["Session"]
