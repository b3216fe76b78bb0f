"""The Modbus map of one program: an HMI/SCADA tag list.

`regmap` says what the server exposes in general (%MWn = register n, %Mn = coil n). This
module applies it to a program: every %M/%MW/%MD/%MF object the program uses becomes a tag
with its Modbus table, address, function codes and access (read-only ranges of the
configuration and the devices' status words refused to writes), and every object it uses
that no host can reach (%I, %Q, timers, system words...) is listed apart, with the way to
expose it. `softplc map` prints it and writes it as CSV; the web monitor shows it.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from softplc.compiler.resolve import object_uses
from softplc.il import ast as A
from softplc.modbus.regmap import COILS, FUNCTIONS, REGISTERS, ReadOnly, read_only_of, span
from softplc.twido.address import BLOCK_FIELDS, Ref

#: The function codes that read / write each table (from the one map, regmap.FUNCTIONS);
#: 32-bit objects span two registers, so only the multi-register writes reach them whole.
READ_FCS = {space: tuple(f.code for f in FUNCTIONS.values()
                         if f.space == space and "read" in f.access)
            for space in (COILS, REGISTERS)}
WRITE_FCS = {space: tuple(f.code for f in FUNCTIONS.values()
                          if f.space == space and "write" in f.access)
             for space in (COILS, REGISTERS)}
MULTI_REGISTER_WRITES = tuple(c for c in WRITE_FCS[REGISTERS] if FUNCTIONS[c].max_quantity > 1)
#: Modicon-style references (what many HMI tag importers want): coil n is 00001 + n,
#: holding register n is 40001 + n.
REFERENCE_BASE = {COILS: 1, REGISTERS: 40001}
TYPES = {"M": "BOOL", "MW": "INT16", "MD": "INT32", "MF": "REAL"}
#: Why an object is not on the map, and how a program shows it to a host: the copy's target
#: is a bit ("M"), a word ("MW"), a double word ("MD") or a float ("MF"), chosen free.
HIDDEN_WHY = {
    "I": ("inputs have no Modbus address", "M"),
    "Q": ("outputs have no Modbus address", "M"),
    "IW": ("analog inputs have no Modbus address", "MW"),
    "QW": ("analog outputs have no Modbus address", "MW"),
    # the Modbus map is %M / %MW only [manual, TWD USE 10AE]: the Remote Link words too
    "INW": ("Remote Link words received have no Modbus address", "MW"),
    "QNW": ("Remote Link words sent have no Modbus address", "MW"),
    "S": ("system bits have no Modbus address", "M"),
    "SW": ("system words have no Modbus address", "MW"),
    "KW": ("constants have no Modbus address", "MW"),
    "KD": ("constants have no Modbus address", "MD"),
    "KF": ("constants have no Modbus address", "MF"),
    "X": ("Grafcet steps have no Modbus address", "M"),
}


class FreeTargets:
    """%M bits and %MW words the program does not use, handed out in order: each hidden
    object's hint copies it to its own free target (two rows never suggest the same)."""

    def __init__(self, used_coils: set[int], used_registers: set[int]):
        self._coils, self._regs = used_coils, used_registers
        self._next_coil = self._next_reg = 0

    def bit(self) -> int:
        while self._next_coil in self._coils:
            self._next_coil += 1
        self._coils.add(self._next_coil)
        return self._next_coil

    def words(self, n: int) -> int:
        """The first of `n` free registers in a row (even for a double word, as TwidoSuite
        aligns %MD/%MF)."""
        i = self._next_reg + (self._next_reg % n if n > 1 else 0)
        while any(i + k in self._regs for k in range(n)):
            i += n
        self._regs.update(range(i, i + n))
        if n == 1:
            self._next_reg = i + 1
        return i

    def copy(self, address: str, target: str) -> str:
        """The IL that shows `address` to a host through a free `target` kind."""
        if target == "M":
            return f"LD {address} / ST %M{self.bit()}"
        n = 2 if target in ("MD", "MF") else 1
        return f"[ %{target}{self.words(n)} := {address} ]"


def hidden_why(kind: str, address: str, free: FreeTargets) -> str:
    """Why `address` (of kind `kind`) is not on the map, and its own copy to a free target."""
    why, target = HIDDEN_WHY[kind]
    return f"{why}: copy it ({free.copy(address, target)})"


def block_why(name: str, kind: str, free: FreeTargets | None = None) -> str:
    """How a program shows block `name` (%C0) to a host: its own word field, copied to a
    free word (%MW100 when no program is given)."""
    words = [f for f, (typ, _) in BLOCK_FIELDS[kind].items() if typ != "bool"]
    if not words:
        return "function block: copy its bits to %M bits"
    target = f"%MW{free.words(1)}" if free is not None else "%MW100"
    return f"function block: copy its fields to %M/%MW ([ {target} := {name}.{words[0]} ])"


@dataclass(frozen=True)
class Tag:
    """One object a host can reach."""

    address: str  # %MW10, %MD20, %M5:8, %MW3:X2
    type: str  # BOOL, INT16, INT32, REAL (tables: the element type)
    space: str  # COILS or REGISTERS
    start: int  # first coil or register (0-based, as on the wire)
    count: int  # coils or registers spanned
    access: str  # "read/write", or "read" (a read-only range)
    program: str  # how the program uses it: read, write, read/write
    line: int  # where the program first uses it
    symbol: str = ""
    comment: str = ""
    note: str = ""

    @property
    def read_fcs(self) -> tuple[int, ...]:
        return READ_FCS[self.space]

    @property
    def write_fcs(self) -> tuple[int, ...]:
        if self.access == "read":
            return ()
        if self.space == REGISTERS and (self.count > 1 or self.type in ("INT32", "REAL")):
            return MULTI_REGISTER_WRITES
        return WRITE_FCS[self.space]

    @property
    def reference(self) -> int:
        return REFERENCE_BASE[self.space] + self.start


@dataclass(frozen=True)
class Hidden:
    """An object the program uses that no Modbus host can reach."""

    address: str
    program: str
    line: int
    why: str
    symbol: str = ""
    comment: str = ""


@dataclass(frozen=True)
class ProgramMap:
    tags: list[Tag]
    hidden: list[Hidden]


def _block_name(ref: Ref) -> str:
    return f"%{ref.kind}{ref.index}"


def _free_targets(uses: Mapping[Any, Any]) -> FreeTargets:
    """The %M bits and registers the program's own objects take (hints suggest others)."""
    coils: set[int] = set()
    regs: set[int] = set()
    for ref in uses:
        where = span(ref)
        if where is not None:
            space, start, count = where
            (coils if space == COILS else regs).update(range(start, start + count))
    return FreeTargets(coils, regs)


def build(program: A.Program, read_only: ReadOnly | None = None,
          device_words: Mapping[str, Iterable[tuple[int, int]]] | None = None,
          symbols: Mapping[str, tuple[str, str]] | None = None,
          limits: Mapping[str, int] | None = None) -> ProgramMap:
    """The map of `program`. `read_only`: the configured read-only ranges; `device_words`:
    device name -> the %MW ranges [start, stop) it writes (read-only for hosts); `symbols`:
    address text -> (symbol, comment); `limits`: the image size per table (objects beyond
    it are listed as hidden)."""
    read_only = read_only or ReadOnly()
    symbols = symbols or {}
    owners = [(a, b, name) for name, ranges in (device_words or {}).items() for a, b in ranges]
    tags: list[Tag] = []
    hidden: list[Hidden] = []
    seen_blocks: set[str] = set()
    uses = object_uses(program)
    free = _free_targets(uses)
    for ref, (role, pos) in uses.items():
        text = str(ref)
        sym, comment = symbols.get(text, ("", ""))
        where = span(ref)
        if where is None:
            if ref.kind in BLOCK_FIELDS:  # one line per block, not per field
                name = _block_name(ref)
                if name in seen_blocks:
                    continue
                seen_blocks.add(name)
                sym, comment = symbols.get(name, (sym, comment))
                hidden.append(Hidden(name, "uses", pos.line, block_why(name, ref.kind, free),
                                     sym, comment))
            elif ref.kind in HIDDEN_WHY:
                hidden.append(Hidden(text, role, pos.line, hidden_why(ref.kind, text, free),
                                     sym, comment))
            continue
        space, start, count = where
        if limits is not None and start + count > limits.get(space, start + count):
            hidden.append(Hidden(text, role, pos.line,
                                 f"beyond the {space} of the image", sym, comment))
            continue
        access, note = "read/write", ""
        if read_only.blocks(space, start, count):
            access, note = "read", "read-only range ([modbus] read_only)"
        if space == REGISTERS:
            for a, b, name in owners:
                if start < b and a < start + count:
                    access, note = "read", f"status word of device {name}"
        if ref.offset is not None:
            note = (note + "; " if note else "") + f"indexed: register {start} + {ref.offset}"
        if ref.bit is not None and access != "read":
            note = (note + "; " if note else "") + (
                f"bit {ref.bit} of register {start}: a host writes the whole word")
        tags.append(Tag(text, "BOOL" if ref.bit is not None else TYPES[ref.kind], space,
                        start, count, access, role, pos.line, sym, comment, note))
    tags.sort(key=lambda t: (t.space, t.start, t.address))
    hidden.sort(key=lambda h: (h.line, h.address))
    return ProgramMap(tags, hidden)


def host_read_only(plc: Any) -> tuple[ReadOnly, dict[str, list[tuple[int, int]]]]:
    """What hosts may not write on `plc`'s map: the configured `[modbus] read_only` ranges,
    and each device's status words (device name -> %MW ranges)."""
    devices = {name: list(d.read_only_words()) for name, d in plc.devices.items()}
    ro = read_only_of(plc.settings.modbus.read_only, plc.mem.profile)
    return ro, {n: r for n, r in devices.items() if r}


def of_plc(plc: Any) -> ProgramMap:
    """The map of a loaded PLC's program with its configuration and devices."""
    ro, device_words = host_read_only(plc)
    limits = {REGISTERS: plc.mem.profile.count("MW"), COILS: plc.mem.profile.count("M")}
    names = {s.address: (s.name, s.comment) for s in plc.symbols}
    return build(plc.ast, ro, device_words, names, limits)


CSV_COLUMNS = ("tag", "address", "type", "table", "modbus_address", "reference", "count",
               "read_fc", "write_fc", "access", "program", "comment", "note")


def to_csv(pmap: ProgramMap) -> str:
    """The tags as CSV, one row per object, for an HMI or SCADA tag import: `tag` is the
    symbol (or the address), `modbus_address` 0-based as on the wire, `reference` the
    Modicon 00001/40001-based number."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for t in pmap.tags:
        w.writerow([t.symbol or t.address, t.address, t.type,
                    "coil" if t.space == COILS else "holding register", t.start, t.reference,
                    t.count, " ".join(map(str, t.read_fcs)), " ".join(map(str, t.write_fcs)),
                    t.access, t.program, t.comment, t.note])
    return out.getvalue()


def to_text(pmap: ProgramMap) -> str:
    """The map as aligned text: the tags, then what the program uses that is not exposed."""
    rows = [("address", "symbol", "type", "table", "modbus", "FC read", "FC write", "access",
             "program", "note")]
    for t in pmap.tags:
        last = t.start + t.count - 1
        where = f"{t.start}" if t.count == 1 else f"{t.start}..{last}"
        rows.append((t.address, t.symbol, t.type, "coil" if t.space == COILS else "register",
                     where, ",".join(map(str, t.read_fcs)),
                     ",".join(map(str, t.write_fcs)) or "-", t.access, t.program,
                     t.note or t.comment))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
             for r in rows]
    if len(rows) == 1:
        lines.append("(the program uses no %M, %MW, %MD or %MF object)")
    if pmap.hidden:
        lines += ["", "Used by the program but not on the Modbus map:"]
        width = max(len(h.address) for h in pmap.hidden)
        names = max(len(h.symbol) for h in pmap.hidden)
        for h in pmap.hidden:
            name = f"{h.symbol.ljust(names)}  " if names else ""
            lines.append(f"  {h.address.ljust(width)}  {name}line {h.line}: {h.why}")
    return "\n".join(lines) + "\n"
