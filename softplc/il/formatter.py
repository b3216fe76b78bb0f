"""`softplc check --format`: a program re-laid out line by line, comments kept.

Each line that holds instructions is rewritten in TwidoSuite export layout (opcode padded to
six columns, one space inside brackets, canonical case); comment lines, comments at the end
of a line and multi-line comments are kept as written, runs of blank lines become one. The
instructions keep their order and their comments, so the formatted program parses to the
same rungs with the same titles.
"""

from __future__ import annotations

import bisect
import itertools
import re
from collections import defaultdict

from softplc.errors import ParseError
from softplc.il import ast as A
from softplc.il.parser import _COMMENT, _Section, _SRDef, parse_lines
from softplc.il.printer import format_instruction
from softplc.twido.address import Ref
from softplc.twido.symbols import SymbolTable

_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


class _AnyName(SymbolTable):
    """Without the configuration, any name stands for an object: the formatter only lays
    the text out and writes each name back as it was written."""

    def ref(self, text: str) -> Ref:
        if text.startswith("%") or self.get(text.partition(".")[0]) is not None:
            return super().ref(text)
        return Ref("M", 0).with_symbol(text)


def _item_text(it: object, line: str) -> str:
    if isinstance(it, _Section):
        return f"SECTION     {it.number}"
    if isinstance(it, _SRDef):
        return f"SR{it.number}:"
    if isinstance(it, A.Label):
        return f"%L{it.number}:"
    written = {w.upper() for w in _WORD.findall(line)}

    def name(ref: Ref) -> str:  # a symbol where the line has one, else the address
        sym = ref.symbol
        return sym if sym and sym.partition(".")[0].upper() in written else str(ref)

    return format_instruction(it, name)  # type: ignore[arg-type]


def format_source(text: str, file: str = "<string>", symbols: SymbolTable | None = None
                  ) -> str:
    """`text` formatted; a ParseError (every syntax problem) if it does not parse.
    `symbols`: the configuration's (names then take their declared spelling)."""
    table = _AnyName(symbols, symbols.profile) if symbols is not None else _AnyName()
    items, _comments, diags = parse_lines(text, file, table)
    if diags:
        raise ParseError(diags)
    lines = text.splitlines()
    by_line: dict[int, list[object]] = defaultdict(list)
    for it in items:
        by_line[it.pos.line].append(it)
    # comments by the line they start on (text from "(*" to the end of that line), and the
    # lines that start inside a multi-line comment (kept verbatim)
    starts = list(itertools.accumulate((len(ln) + 1 for ln in lines), initial=0))
    flat = "\n".join(lines) + "\n"
    trailing: dict[int, list[str]] = defaultdict(list)
    column: dict[int, int] = {}  # where the line's first comment started: kept if it can
    inside: set[int] = set()
    for m in _COMMENT.finditer(flat):
        first = bisect.bisect_right(starts, m.start())
        last = bisect.bisect_right(starts, m.end() - 1)
        end = m.end() if first == last else starts[first] - 1
        trailing[first].append(flat[m.start():end])
        column.setdefault(first, m.start() - starts[first - 1])
        inside.update(range(first + 1, last + 1))
    out: list[str] = []
    for n, line in enumerate(lines, 1):
        if n in by_line and n not in inside:
            code = " ".join(_item_text(it, _COMMENT.sub("", line)) for it in by_line[n])
            if n in trailing:
                code = code.ljust(max(len(code) + 2, column[n])) + "  ".join(trailing[n])
            out.append(code)
        elif n in inside or line.strip():
            out.append(line.rstrip())
        elif out and out[-1]:  # one blank line between blocks, none at the top
            out.append("")
    while out and not out[-1]:
        out.pop()
    return "\n".join(out) + "\n"
