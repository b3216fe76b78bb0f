"""The parser's fast path: the commonest IL lines without Lark.

Lines like `LD %M0`, `ANDN %I0.3`, `ST %Q0.1`, `S %M5`, `AND( %M1` and `)` make up most
of a program. Lark's lexer and tree builder cost ~50 us a line; a regex match and the
transformer's own methods ~6 (tools/bench_compile.py). The regex is assembled from the
grammar's terminals, so what it matches the grammar's rules accept, and the nodes come
from the same transformer methods Lark's path calls, with the same tokens and positions;
any other line (comments, expressions, labels, symbols, errors) goes to Lark.
tests/test_il_fastpath.py checks that both paths give the same AST and diagnostics.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

from lark import Lark, Token

from . import ast as A

# regex group -> (rule, its keyword terminals): `KEYWORD ADDRESS` lines
RULES = {"b": ("bool_instr", "LOAD_KW", "LOGIC_KW"), "s": ("store", "STORE_KW"),
         "r": ("set_reset", "SETRESET_KW")}
PAREN_RULES = ("paren_open", "paren_close")


def _token(kind: str, m: re.Match[str], group: str, line: int) -> Token:
    return Token(kind, m.group(group), m.start(group), line, m.start(group) + 1, line,
                 m.end(group) + 1, m.end(group))


class FastLines:
    """The matcher (`pattern.fullmatch(line)`) and the node builder of the fast path."""

    def __init__(self, pattern: re.Pattern[str], funcs: dict[str, Callable[..., Any]]):
        self.pattern = pattern
        self.funcs = funcs

    def item(self, tx: Any, m: re.Match[str], line: int) -> A.Instruction:
        """The node of a matched line (1-based `line`), built by transformer `tx`."""
        f = self.funcs
        if m.group("p") is not None:
            t = _token("RPAR", m, "p", line)
            return f["paren_close"](tx, A.Pos(line, t.column, line, t.end_column), [])
        if m.group("o") is not None:  # AND( / OR( / XOR(, with or without its operand
            kw = _token("PAREN_KW", m, "o", line)
            if m.group("oa") is None:
                return f["paren_open"](tx, A.Pos(line, kw.column, line, kw.end_column), [kw])
            addr = _token("ADDRESS", m, "oa", line)
            return f["paren_open"](tx, A.Pos(line, kw.column, line, addr.end_column),
                                   [kw, tx.address([addr])])
        group = next(g for g in RULES if m.group(g) is not None)
        rule, *terms = RULES[group]
        kind = terms[0] if len(terms) == 1 or m.group(group)[:2].upper() == "LD" else terms[1]
        kw, addr = _token(kind, m, group, line), _token("ADDRESS", m, "a", line)
        operand = tx.address([addr]) if rule == "bool_instr" else addr
        return f[rule](tx, A.Pos(line, kw.column, line, addr.end_column), [kw, operand])


def build(lark: Lark, transformer: type) -> FastLines | None:
    """The fast path for this grammar and transformer class; None (every line through
    Lark) if the grammar lacks a terminal or a rule's method is not a `v_args(meta=True)`
    method any more."""
    # The methods' plain functions: getting a `v_args` method from the class or an
    # instance builds a new wrapper every time (functools.update_wrapper, ~3 us).
    funcs = {rule: getattr(vars(transformer).get(rule), "base_func", None)
             for rule in (*PAREN_RULES, *(r for r, *_t in RULES.values()))}
    if None in funcs.values():
        return None
    try:
        rx = {t: lark.get_terminal(t).pattern.to_regexp()
              for _rule, *terms in RULES.values()
              for t in (*terms, "ADDRESS", "RPAR", "PAREN_KW")}
    except KeyError:
        return None
    kws = "|".join(f"(?P<{g}>{'|'.join(rx[t] for t in terms)})"
                   for g, (_rule, *terms) in RULES.items())
    # `%` addresses only: a name (a symbol, or a pin such as `LD Q` inside BLK, which the
    # contextual lexer takes by priority) goes to Lark
    pattern = re.compile(rf"[ \t]*(?:(?:{kws})[ \t]+(?P<a>(?=%)(?:{rx['ADDRESS']}))"
                         rf"|(?P<o>{rx['PAREN_KW']})(?:[ \t]*(?P<oa>(?=%)(?:{rx['ADDRESS']})))?"
                         rf"|(?P<p>{rx['RPAR']}))[ \t]*")
    return FastLines(pattern, funcs)
