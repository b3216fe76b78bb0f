"""Numeric literals of an IL program as AST numbers, bounded before conversion.

A run of more than `MAX_NUMBER_DIGITS` digits is refused before `int()` sees it
(Python's own limit is a ValueError at 4,300 digits, and conversion is quadratic in the
digits), and a float literal must be a finite single-precision value: a Twido REAL spans
±3.402823e38 (IEEE-754 single precision [TwidoSuite programming guide, "Floating point
objects", manual from memory]); `1.0E99999` would otherwise become an infinity.
"""

from __future__ import annotations

import re

from lark import Token

from softplc.errors import Code, Diagnostic
from softplc.il import ast as A
from softplc.limits import MAX_NUMBER_DIGITS, position
from softplc.twido.numeric import F32_MAX

INT, HEX, FLOAT = "int", "hex", "float"


def _pos(tok: Token) -> A.Pos:
    return A.Pos(tok.line or 0, tok.column or 0, tok.end_line or 0, tok.end_column or 0)


def number(tok: Token, kind: str, file: str, diags: list[Diagnostic]) -> A.Num:
    """The AST number of an INT, HEX or FLOAT token (its digits already bounded by
    `long_numbers`); a float beyond the REAL range is a diagnostic (and 0.0)."""
    text = str(tok)
    if kind == INT:
        return A.Num(int(text), text, _pos(tok))
    if kind == HEX:
        return A.Num(int(text.split("#", 1)[1], 16), text, _pos(tok))
    value = float(text)
    if abs(value) > F32_MAX:
        diags.append(Diagnostic(f"the REAL constant {text} is beyond the single-precision "
                                f"range", file, tok.line, tok.column, text,
                                f"a value within ±{F32_MAX:.7g}", Code.CONSTANT))
        value = 0.0
    return A.Num(value, text, _pos(tok))


_LONG = re.compile(rf"[0-9A-Fa-f]{{{MAX_NUMBER_DIGITS + 1},}}")


def long_numbers(text: str, file: str, comments: re.Pattern[str]) -> list[Diagnostic]:
    """A diagnostic at each run of more than MAX_NUMBER_DIGITS digits outside comments
    (a constant, a label, a step, an address index...): its line is left out before any
    `int()` sees it."""
    if _LONG.search(text) is None:
        return []
    spans = [m.span() for m in comments.finditer(text)]
    out = []
    for m in _LONG.finditer(text):
        if any(a <= m.start() < b for a, b in spans):
            continue
        line, col = position(text, m.start())
        out.append(Diagnostic(f"a number of {len(m.group())} digits", file, line, col,
                              m.group()[:20] + "...", f"at most {MAX_NUMBER_DIGITS} digits",
                              Code.CONSTANT))
    return out
