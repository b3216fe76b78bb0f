"""What the model cannot compute, as sound abstractions: any value within its documented
range, fresh where the engine may change it.

- the function blocks without a model of their own (%FC, %VFC, %PLS, %PWM, %MSG and any
  other the catalog addresses but `objects.MODELLED` lacks): every field is fresh at the
  start and the end of every scan (hooks such as the fast counters' poll, the exchange
  port and the pulse generators run at the scan boundaries) and after each execution of
  the block or write of one of its fields (the engine may clamp what the program wrote)
  [sound: the engine's value is one of them];
- `[ PID n ]`: where it runs, the words it writes are fresh: its output within the
  configured `output_min..output_max` (0..10000 [manual, from memory], `runtime.pid`), the
  diagnostic word and the Kp/Ti/Td words (auto-tuning writes them) any 16-bit value;
- `EXCHi %MWj:n`: the reply lands at a scan boundary: from then on the table's words past
  its two header words are fresh at the start of every scan (the reply's length is in the
  table, a value of the program's), as are the port's status word and %MSGi's fields;
- the outputs a pulse block (%PLS, %PWM) or a PID's PWM drives: fresh after the program
  (their level at the scan's end is a matter of time the model does not follow).

Each abstracted object is named with its line:col (`Abstractions.where`), and its values
in a counterexample are the solver's: `engines` replays the counterexample's real inputs
in the engine, and a counterexample the engine does not confirm is excluded and the
search goes on (counterexample-guided refinement).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import z3

from softplc.il import ast as A
from softplc.twido import catalog
from softplc.twido.address import BLOCK_FIELDS, Ref

WORD_RANGE = (-32768, 32767)  # a 16-bit word: any value
EXCH_HEADER_WORDS = 2  # control and offsets words (runtime/exch.py: the table's layout)
SITE = "~"  # an input key's separator before the site it is fresh at: "%FC0.V~12:3"
ABSTRACT_OUTPUT = "*"  # the input key's prefix of an abstracted output after the program


@dataclass
class Abstractions:
    """The abstracted objects of one model: state key -> (sort, lo, hi), where first."""

    ranges: dict[str, tuple[str, int, int]] = field(default_factory=dict)
    where: dict[str, str] = field(default_factory=dict)  # what -> "line:col"
    scan_start: set[str] = field(default_factory=set)  # keys fresh at each scan's start
    after_program: set[str] = field(default_factory=set)  # %Q driven by pulse blocks
    exch_words: set[str] = field(default_factory=set)  # reply words of EXCH tables

    def note(self, what: str, pos: A.Pos | None) -> None:
        self.where.setdefault(what, f"{what} at {pos.line}:{pos.column}" if pos is not None
                              and pos.line else f"{what} (configured)")

    def is_input(self, key: str) -> bool:
        """An input of the model that stands for an abstracted value (not a real input:
        the replay leaves it to the engine)."""
        return SITE in key or key.startswith(ABSTRACT_OUTPUT) or key in self.ranges


def field_sort(kind: str, name: str) -> tuple[str, int, int]:
    """A block field's sort and range (the catalog's type: a bit, or a 16-bit word)."""
    typ = BLOCK_FIELDS[kind][name][0]
    return ("bool", 0, 1) if typ == "bool" else ("w16", *WORD_RANGE)


class AbstractModel:
    """The mixin `ObjectModel` uses for abstracted objects (`self.abstract`)."""

    st: dict[str, Any]
    inp: dict[str, Any]
    plc: Any
    abstract: Abstractions

    def add_input(self, key: str, sort: str, lo: int = 0, hi: int = 0) -> None: ...
    def mark_written(self, key: str, pos: A.Pos | None) -> None: ...

    def abstract_block(self, ref: Ref, pos: A.Pos | None) -> str:
        """Register block `ref`'s fields as abstracted (fresh at each scan's start)."""
        name = f"%{ref.kind}{ref.index}"
        self.abstract.note(name, pos)
        for f in BLOCK_FIELDS[ref.kind]:
            key = f"{name}.{f}"
            if key not in self.abstract.ranges:
                self.abstract.ranges[key] = field_sort(ref.kind, f)
                self.abstract.scan_start.add(key)
        for key in self.abstract.ranges:
            if key.startswith(name + "."):
                _ = self.st[key]
        return name

    def refresh(self, key: str, g: Any, pos: A.Pos | None) -> None:
        """`key` takes any value of its range where `g` holds (an input of this site)."""
        sort, lo, hi = self.abstract.ranges[key]
        p = pos or A.NOPOS
        site = f"{key}{SITE}{p.line}:{p.column}"
        self.add_input(site, sort, lo, hi)
        self.st[key] = z3.simplify(z3.If(g, self.inp[site], self.st[key]))

    def run_abstract(self, ref: Ref, g: Any, pos: A.Pos | None) -> None:
        """An execution of an abstracted block, or a write of one of its fields."""
        name = self.abstract_block(ref, pos)
        for f in BLOCK_FIELDS[ref.kind]:
            self.refresh(f"{name}.{f}", g, pos)

    def read_abstract(self, ref: Ref) -> Any:
        name = self.abstract_block(ref, None)
        return self.st[f"{name}.{ref.field}"]

    def run_called(self, stmt: A.BlockCall, g: Any) -> bool:
        """`[ KEYWORD n ]` (a PID): the words it writes fresh where it runs; False: not a
        block whose parameters name them."""
        fam = catalog.by_instruction().get(stmt.keyword)
        blk = self.plc.mem.blocks.get(fam.kind, {}).get(stmt.number) if fam else None
        p = getattr(blk, "p", None)
        if p is None or not hasattr(p, "out_max"):
            return False
        what, pos = f"{stmt.keyword} {stmt.number}", stmt.pos
        self.abstract.note(what, pos)
        outs: list[tuple[Ref, tuple[str, int, int]]] = []
        if p.output is not None:
            outs.append((p.output, ("w16", p.out_min, p.out_max)))
        for r in (p.diagnostic, p.kp, p.ti, p.td):
            if isinstance(r, Ref) and r.kind == "MW":
                outs.append((r, ("w16", *WORD_RANGE)))
        for r, rng in outs:
            key = str(r)
            self.abstract.ranges.setdefault(key, rng)
            self.mark_written(key, pos)
            _ = self.st[key]
            self.refresh(key, g, pos)
        if p.pwm_output is not None:
            self.drive_output(p.pwm_output, f"{what}'s PWM output", pos)
        return True

    def run_exch(self, stmt: A.ExchCall, g: Any) -> None:
        """`EXCHi %MWj:n`: the port's reply words and status are fresh from the next scan
        on (`exch_words`); %MSGi's fields too."""
        t = stmt.table
        self.abstract.note(f"EXCH{stmt.port} {t}", stmt.pos)
        self.abstract_block(Ref("MSG", stmt.port), stmt.pos)
        self.run_abstract(Ref("MSG", stmt.port), g, stmt.pos)
        for k in range(EXCH_HEADER_WORDS, t.length or 0):
            key = f"%MW{t.index + k}"
            self.abstract.ranges.setdefault(key, ("w16", *WORD_RANGE))
            self.abstract.exch_words.add(key)
            self.mark_written(key, stmt.pos)
            _ = self.st[key]
        msg = self.plc.mem.blocks.get("MSG", {}).get(stmt.port)
        port = getattr(msg, "port", None)
        if port is not None:
            key = f"%SW{port.status_word}"
            self.abstract.ranges.setdefault(key, ("w16", *WORD_RANGE))
            self.abstract.scan_start.add(key)
            _ = self.st[key]

    def drive_output(self, ref: Ref, what: str, pos: A.Pos | None) -> None:
        key = str(ref)
        self.abstract.note(what, pos)
        self.abstract.ranges.setdefault(key, ("bool", 0, 1))
        self.abstract.after_program.add(key)
        self.mark_written(key, pos)
        _ = self.st[key]

    def pulse_outputs(self) -> None:
        """The %Q outputs the configured pulse blocks drive: fresh after the program."""
        pulses = self.plc.engine.pulses
        for q, name in (pulses.names.items() if pulses is not None else ()):
            # on the base's transistor outputs (`Profile.pulse_outputs`): module 0
            self.drive_output(Ref("Q", q, 0, q), name or f"a pulse output %Q0.{q}", None)

    def abstract_scan_start(self) -> None:
        """Each scan's start: the abstracted fields fresh; the EXCH reply words fresh or
        kept (a reply may or may not land)."""
        for key in sorted(self.abstract.scan_start):
            sort, lo, hi = self.abstract.ranges[key]
            self.add_input(key, sort, lo, hi)
            self.st[key] = self.inp[key]
        if self.abstract.exch_words:
            self.add_input(f"{ABSTRACT_OUTPUT}exch_reply", "bool", 0, 1)
            landed = self.inp[f"{ABSTRACT_OUTPUT}exch_reply"]
            for key in sorted(self.abstract.exch_words):
                sort, lo, hi = self.abstract.ranges[key]
                site = f"{key}{SITE}reply"
                self.add_input(site, sort, lo, hi)
                self.st[key] = z3.If(landed, self.inp[site], self.st[key])

    def abstract_after_program(self) -> None:
        """After the program: the driven outputs, and the abstracted fields (the engine's
        end-of-scan work, the pulse generators', may change them before a requirement
        reads them)."""
        for key in sorted(self.abstract.scan_start):
            sort, lo, hi = self.abstract.ranges[key]
            site = f"{key}{SITE}end"
            self.add_input(site, sort, lo, hi)
            self.st[key] = self.inp[site]
        for key in sorted(self.abstract.after_program):
            self.add_input(f"{ABSTRACT_OUTPUT}{key}", "bool", 0, 1)
            self.st[key] = self.inp[f"{ABSTRACT_OUTPUT}{key}"]
