"""Symbols: names for addresses (START_PB for %I0.0), as TwidoSuite programs are read.

Declared in the configuration, inline or in a CSV file beside it:

    symbols_file = "motor_symbols.csv"          # relative to the configuration's folder
    [symbols]
    START_PB = "%I0.0"
    MOTOR_K1 = { address = "%Q0.0", comment = "main contactor" }

The CSV has one symbol a line: address, symbol, comment (TwidoSuite's symbol export
columns [unsure: the layout is from memory, no export was at hand], so symbol, address,
comment is read too); the separator is `,`, `;` or a tab, whichever the file uses, and a
header line is skipped. A name is a letter or
`_` then letters, digits and `_` (at most 32 characters), is not an IL keyword, and is
matched whatever its case. One name per address and one address per name.

A symbol stands wherever an address does: in the program (`LD START_PB`, `TIMER1.Q` for a
field of a block named TIMER1), `plc["START_PB"]`, the REPL, `softplc io`. This module
reads no program and imports neither numpy nor the parser.
"""

from __future__ import annotations

import csv
import difflib
import io
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from softplc.errors import AddressError, ConfigCode, ConfigError, ConfigIssue
from softplc.limits import MAX_SYMBOLS_BYTES, BoundsError, decode_text, read_bytes
from softplc.twido import catalog
from softplc.twido.address import Ref, parse_address
from softplc.twido.profile import DEFAULT_PROFILE, Profile

NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,31}$")
# Words the IL grammar reads as keywords where an address may stand (softplc/il/
# twido_il.lark): a symbol spelled so could not be told from the keyword.
RESERVED = frozenset("""
    LD LDN LDR LDF AND ANDN ANDR ANDF OR ORN ORR ORF XOR XORN XORR XORF ST STN S R N
    MPS MRD MPP INC DEC JMP JMPC JMPCN RET RETC RETCN END ENDC ENDCN NOP BLK OUT_BLK
    END_BLK IN CU CD U I O Q D E F POST REM SECTION
""".split()) | set(catalog.by_instruction())  # and the block instructions (`[ PID n ]`)
_NUMBERED_KEYWORD = re.compile(r"^(SR|EXCH)\d+$", re.I)
# A name and what may follow it where an address stands: .FIELD, :Xk, :N, [INDEX]
# (the suffixes of an address, softplc.twido.address). The index is bounded like a name.
_NAMED = re.compile(r"""(?P<name>[A-Za-z_][A-Za-z0-9_]{0,31})
    (?P<suffix>(?P<pre>(?:\.[A-Za-z]{1,3}\d{0,3})?(?::X?\d{1,5})?)
               (?:\[(?P<index>%?[A-Za-z_][A-Za-z0-9_]{0,31})\])?)$""", re.X)
CSV_HEADER = ("Address", "Symbol", "Comment")
#: Symbols one CSV declares: more than the objects of the largest Twido one would name
#: (3,000 %MW, 256 %M, 128 timers, 128 counters... [manual, from memory]).
MAX_SYMBOLS = 10_000


@dataclass(frozen=True)
class Symbol:
    name: str
    address: str  # canonical text (str of the parsed Ref)
    comment: str = ""


class SymbolTable:
    """Names <-> addresses, checked once; lookups ignore the case of names."""

    def __init__(self, symbols: Iterable[Symbol] = (), profile: Profile = DEFAULT_PROFILE,
                 paths: Mapping[str, str] | None = None):
        """Every wrong declaration is reported (one ConfigError), each at `paths[name]`,
        its key path in the configuration, or as `symbol NAME`."""
        self.profile = profile
        self._by_name: dict[str, Symbol] = {}
        self._by_address: dict[str, Symbol] = {}
        issues: list[ConfigIssue] = []
        for s in symbols:
            problem = self._add(s)
            if problem is not None:
                where = (paths or {}).get(s.name, f"symbol {s.name}")
                issues.append(ConfigIssue(where, *problem))
        if issues:
            raise ConfigError(issues)

    def _add(self, s: Symbol) -> tuple[str, ConfigCode] | None:
        """Declare `s`; what is wrong with it (message, code), if anything."""
        if not NAME.match(s.name):
            return (f"{s.name!r}: a letter or _ then letters, digits and _, at most 32 "
                    f"characters", ConfigCode.VALUE)
        if s.name.upper() in RESERVED or _NUMBERED_KEYWORD.match(s.name):
            return (f"{s.name!r} is an Instruction List keyword: choose another name",
                    ConfigCode.VALUE)
        try:
            ref = parse_address(s.address, self.profile)
        except AddressError as e:
            return str(e), ConfigCode.ADDRESS
        if ref.length is not None or ref.offset is not None:
            return (f"{s.address!r} is a range or an indexed word: a symbol names one "
                    f"object", ConfigCode.ADDRESS)
        s = Symbol(s.name, str(ref), s.comment)
        old = self._by_name.get(s.name.upper())
        if old is not None:
            return f"{s.name} declared twice ({old.address} and {s.address})", \
                ConfigCode.CONFLICT
        other = self._by_address.get(s.address)
        if other is not None:
            return f"{s.address} has two symbols: {other.name} and {s.name}", \
                ConfigCode.CONFLICT
        self._by_name[s.name.upper()] = s
        self._by_address[s.address] = s
        return None

    def __len__(self) -> int:
        return len(self._by_name)

    def key(self) -> tuple:
        """What decides how the table resolves names (its profile and symbols), hashable:
        two tables with equal keys give every program text the same references."""
        return repr(self.profile), tuple(self._by_name.values())

    def __iter__(self):
        return iter(sorted(self._by_name.values(), key=lambda s: _address_key(s.address)))

    def get(self, name: str) -> Symbol | None:
        return self._by_name.get(name.upper())

    def suggest(self, name: str) -> str:
        """' (did you mean START_PB?)' for a name close to a declared one, else ''."""
        close = difflib.get_close_matches(name.upper(), list(self._by_name), n=1, cutoff=0.6)
        return f" (did you mean {self._by_name[close[0]].name}?)" if close else ""

    def address_of(self, text: str) -> str:
        """The address text a name stands for, with what follows it: `STAR_TIME.Q` (a block's
        field), `STATE:X3` (a bit of a word), `STARTS:4` (a range from the symbol's object),
        `TABLE[INDEX]` (indexed, the index a symbol or an address). Text starting with % is
        returned as is. The one resolver of names: the parser, `plc[...]`, the REPL,
        `softplc io`, the access port and the verifier all come here. AddressError naming
        the closest symbol if a name is unknown."""
        text = text.strip()
        if text.startswith("%"):
            return text
        m = _NAMED.match(text)
        s = self.get(m["name"]) if m is not None else None
        if s is None:
            try:  # `I0.0`, `MW3`: an address without its %
                parse_address("%" + text, self.profile)
            except AddressError:
                pass
            else:
                raise AddressError(f"{text!r} is no address (they start with %) and no "
                                   f"declared symbol: did you mean %{text}?")
        if m is None:
            raise AddressError(f"{text!r} is neither an address (they start with %: %MW3, "
                               f"%I0.0...) nor a symbol (a name, with .FIELD, :N, :Xk or "
                               f"[INDEX] after it)")
        name, suffix = m["name"], m["suffix"]
        if s is None:
            if self:
                raise AddressError(f"unknown symbol {name!r}{self.suggest(name)}")
            raise AddressError(f"{text!r} is neither an address (addresses start with %: "
                               f"%MW3, %I0.0...) nor a symbol (none is declared: [symbols] "
                               f"in the configuration)")
        if m["index"] is not None:  # TABLE[INDEX]: the index may be a symbol too
            suffix = f"{m['pre'] or ''}[{self.address_of(m['index'])}]"
        return s.address + suffix

    def label(self, ref: Ref | str) -> str:
        """`MOTOR(%Q0.0)` for an object with a symbol, else its address (`Ref.label` with
        this table's name attached): how messages, test output and tables name it."""
        if isinstance(ref, str):
            try:
                ref = parse_address(ref, self.profile)
            except AddressError:
                return ref
        return self.attach(ref).label

    def ref(self, text: str) -> Ref:
        """The object named by an address or a symbol, its symbol attached."""
        return self.attach(parse_address(self.address_of(text), self.profile))

    def name_of(self, ref: Ref) -> str | None:
        """The symbol of an object: its own, its block's with the field (TIMER1.Q), or its
        word's with the bit (STATE:X3)."""
        s = self._by_address.get(str(ref))
        if s is not None:
            return s.name
        if ref.field is not None and ref.bit is None:
            base = self._by_address.get(str(Ref(ref.kind, ref.index)))
            if base is not None:
                return f"{base.name}.{ref.field}"
        if ref.bit is not None and ref.field is None:  # STATE:X3, a bit of a named word
            base = self._by_address.get(str(Ref(ref.kind, ref.index)))
            if base is not None:
                return f"{base.name}:X{ref.bit}"
        return None

    def comment_of(self, ref: Ref) -> str:
        s = self._by_address.get(str(ref))
        return s.comment if s is not None else ""

    def attach(self, ref: Ref) -> Ref:
        """`ref` with its symbol's name in `ref.symbol` (for the views), if it has one."""
        if not self._by_name:
            return ref
        name = self.name_of(ref)
        return ref if name is None else ref.with_symbol(name)

    # ---- files ---------------------------------------------------------------------------
    def to_csv(self, delimiter: str = ",") -> str:
        """The table in the CSV layout `read_csv` reads (a header line first)."""
        out = io.StringIO()
        w = csv.writer(out, delimiter=delimiter, lineterminator="\r\n")
        w.writerow(CSV_HEADER)
        for s in self:
            w.writerow((s.address, s.name, s.comment))
        return out.getvalue()

    def to_toml(self) -> str:
        """The table as a `[symbols]` section of a configuration."""
        lines = ["[symbols]"]
        for s in self:
            if s.comment:
                lines.append(f"{s.name} = {{ address = {_toml_str(s.address)}, "
                             f"comment = {_toml_str(s.comment)} }}")
            else:
                lines.append(f"{s.name} = {_toml_str(s.address)}")
        return "\n".join(lines) + "\n"


def _toml_str(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _address_key(address: str) -> tuple[Any, ...]:
    """%I before %Q before %M..., then by number: the order of TwidoSuite's table."""
    order = ["I", "Q", "IW", "QW", "INW", "QNW", "M", "MW", "MD", "MF", "KW", "KD", "KF", "S", "SW"]
    order += [f.kind for f in catalog.FAMILIES.values() if f.online]  # %TM %C %DR %R
    m = re.match(r"%([A-Z]+)(\d+)(?:\.(\d+))?", address)
    if not m:
        return (len(order) + 1, address)
    kind = m[1]
    return (order.index(kind) if kind in order else len(order), kind, int(m[2]),
            int(m[3] or 0), address)


def read_csv(text: str, source: str = "<csv>") -> list[Symbol]:
    """Symbols of a CSV export: address, symbol, comment a line (`,` `;` or tab)."""
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        return []
    if len(lines) > MAX_SYMBOLS + 1:  # and a header line
        raise ConfigError(ConfigIssue("", f"{source}: {len(lines)} lines, at most "
                                      f"{MAX_SYMBOLS} symbols", ConfigCode.FILE))
    delimiter = max((",", ";", "\t"), key=lambda d: lines[0].count(d))
    out = []
    rows = csv.reader(lines, delimiter=delimiter)
    for n in range(1, len(lines) + 1):
        try:
            row = next(rows)
        except (csv.Error, StopIteration) as e:  # a field over csv's size limit, a NUL
            raise ConfigError(ConfigIssue("", f"{source}:{n}: not a symbol line: {e}",
                                          ConfigCode.FILE)) from None
        cells = [c.strip() for c in row]
        if n == 1 and not any(c.startswith("%") for c in cells[:2]):
            continue  # the header line
        if len(cells) >= 2 and cells[1].startswith("%") and not cells[0].startswith("%"):
            cells[0], cells[1] = cells[1], cells[0]  # symbol first: take it as well
        if len(cells) < 2 or not cells[0] or not cells[1]:
            # the line is not quoted: the file may be one the reader may not show
            raise ConfigError(f"{source}:{n}: expected ADDRESS{delimiter}SYMBOL"
                              f"[{delimiter}COMMENT], got {len(cells)} cell(s)")
        out.append(Symbol(cells[1], cells[0], cells[2] if len(cells) > 2 else ""))
    return out


def decode_csv(data: bytes, source: str) -> str:
    """A symbol file's text: UTF-8 (with or without a BOM), else Windows-1252, which
    TwidoSuite on Windows writes; ConfigError at the line:col of the first byte that is
    neither (a binary file)."""
    try:
        return decode_text(data, "the symbol file", fallback="cp1252")
    except BoundsError as e:
        raise ConfigError(ConfigIssue("", f"{source}:{e}", ConfigCode.FILE)) from None


def read_csv_file(path: str | Path) -> list[Symbol]:
    p = Path(path)
    try:
        data = read_bytes(p, MAX_SYMBOLS_BYTES, "the symbol file")
    except FileNotFoundError:
        raise ConfigError(f"{p}: no such symbol file") from None
    except OSError as e:
        raise ConfigError(f"cannot read symbol file {p}: {e.strerror}") from None
    except BoundsError as e:
        raise ConfigError(ConfigIssue("", f"{p}: {e}", ConfigCode.FILE)) from None
    return read_csv(decode_csv(data, str(p)), str(p))


def from_settings(settings: Any, base: Path | None, profile: Profile = DEFAULT_PROFILE,
                  read: Callable[[str], bytes] | None = None) -> SymbolTable:
    """The table of a checked configuration (`softplc.config.Config`: its `symbols` and
    `symbols_file`; `base`: the folder of its file, for `symbols_file`). `read` gives the
    bytes of the file the configuration names (the machine builder passes its file policy,
    `softplc.config.files`); None reads it from disk. An empty table when it declares
    none; every wrong declaration at its key path (`symbols.NAME`)."""
    symbols: list[Symbol] = []
    if settings.symbols_file is not None:
        if read is not None:
            name = settings.symbols_file
            symbols += read_csv(decode_csv(read(name), name), name)
        else:
            path = Path(settings.symbols_file)
            if base is not None and not path.is_absolute():
                path = base / path
            symbols += read_csv_file(path)
    symbols += [Symbol(name, v.address, v.comment) for name, v in settings.symbols.items()]
    return SymbolTable(symbols, profile, {n: f"symbols.{n}" for n in settings.symbols})
