"""The parser's fast path: the commonest IL lines without Lark.

Lines like `LD %M0`, `ANDN %I0.3`, `ST %Q0.1`, `S %M5`, `AND( %M1`, `)`, and the simple
comparison and operation blocks (`LD [ %MW1 > 3 ]`, `[ %MW2 := %MW3 + 4 ]`: operands
`%` addresses or decimal integers, at most one `+ - * /` a side) make up most of a
program. Lark's lexer and tree builder cost ~50 us a line (~85 for a block); a regex
match and the transformer's own methods a few. The regex is assembled from the grammar's
terminals, so what it matches the grammar's rules accept, and the nodes come from the
same transformer methods Lark's path calls, with the same tokens and positions; any other
line (comments, other expressions, labels, symbols, errors) goes to Lark.
tests/test_il_fastpath.py checks that both paths give the same AST, positions and
diagnostics.
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
# the other rules whose methods the fast path calls (`v_args(meta=True)` methods)
META_RULES = ("paren_open", "paren_close", "compare", "op_block", "assign", "binop")
TERMINALS = ("ADDRESS", "RPAR", "PAREN_KW", "CMP_OP", "ASSIGN", "ADD_OP", "MUL_OP", "INT",
             "LSQB", "RSQB")


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
        if m.group("x") is not None:  # [ %MW2 := expr ]
            target = _token("ADDRESS", m, "t", line)
            expr = self._expr(tx, m, "3", line)
            stmt = f["assign"](tx, A.Pos(line, target.column, line, expr.pos.end_column),
                               [target, _token("ASSIGN", m, "as", line), expr])
            return f["op_block"](tx, self._span(m, "x", "xe", line), [stmt])
        group = next(g for g in (*RULES, "c") if m.group(g) is not None)
        rule, *terms = RULES["b" if group == "c" else group]
        kind = terms[0] if len(terms) == 1 or m.group(group)[:2].upper() == "LD" else terms[1]
        kw = _token(kind, m, group, line)
        if group == "c":  # LD [ expr CMP expr ]
            left, right = self._expr(tx, m, "1", line), self._expr(tx, m, "2", line)
            cmp = f["compare"](tx, self._span(m, "cb", "ce", line),
                               [left, _token("CMP_OP", m, "cmp", line), right])
            return f[rule](tx, A.Pos(line, kw.column, line, cmp.pos.end_column), [kw, cmp])
        addr = _token("ADDRESS", m, "a", line)
        operand = tx.address([addr]) if rule == "bool_instr" else addr
        return f[rule](tx, A.Pos(line, kw.column, line, addr.end_column), [kw, operand])

    @staticmethod
    def _span(m: re.Match[str], first: str, last: str, line: int) -> A.Pos:
        """From group `first`'s start to group `last`'s end (a rule's meta)."""
        return A.Pos(line, m.start(first) + 1, line, m.end(last) + 1)

    def _expr(self, tx: Any, m: re.Match[str], n: str, line: int) -> A.Expr:
        """Expression `n` of the line: an atom, or `atom op atom`."""
        left = self._atom(tx, m, "l" + n, line)
        if m.group("o" + n) is None:
            return left
        op = _token("ADD_OP" if m.group("o" + n) in "+-" else "MUL_OP", m, "o" + n, line)
        right = self._atom(tx, m, "r" + n, line)
        return self.funcs["binop"](tx, A.Pos(line, left.pos.column, line, right.pos.end_column),
                                   [left, op, right])

    @staticmethod
    def _atom(tx: Any, m: re.Match[str], group: str, line: int) -> A.Expr:
        if m.group(group)[0] == "%":
            return tx.ref([_token("ADDRESS", m, group, line)])
        return tx.int_lit([_token("INT", m, group, line)])


def build(lark: Lark, transformer: type) -> FastLines | None:
    """The fast path for this grammar and transformer class; None (every line through
    Lark) if the grammar lacks a terminal or a rule's method is not a `v_args(meta=True)`
    method any more."""
    # The methods' plain functions: getting a `v_args` method from the class or an
    # instance builds a new wrapper every time (functools.update_wrapper, ~3 us).
    funcs = {rule: getattr(vars(transformer).get(rule), "base_func", None)
             for rule in (*META_RULES, *(r for r, *_t in RULES.values()))}
    if None in funcs.values() or not all(callable(getattr(transformer, r, None))
                                         for r in ("address", "ref", "int_lit")):
        return None
    try:
        rx = {t: lark.get_terminal(t).pattern.to_regexp()
              for t in (*TERMINALS, *(t for _r, *terms in RULES.values() for t in terms))}
    except KeyError:
        return None
    kws = "|".join(f"(?P<{g}>{'|'.join(rx[t] for t in terms)})"
                   for g, (_rule, *terms) in RULES.items())
    # `%` addresses only: a name (a symbol, or a pin such as `LD Q` inside BLK, which the
    # contextual lexer takes by priority) goes to Lark
    addr = rf"(?=%)(?:{rx['ADDRESS']})"
    sp = "[ \t]*"

    def expr(n: str) -> str:  # atom, or atom (+ - * /) atom: no precedence to mind
        atom = f"{addr}|{rx['INT']}"
        return (rf"(?P<l{n}>{atom})(?:{sp}(?P<o{n}>{rx['ADD_OP']}|{rx['MUL_OP']}){sp}"
                rf"(?P<r{n}>{atom}))?")

    pattern = re.compile(
        rf"{sp}(?:(?:{kws})[ \t]+(?P<a>{addr})"
        rf"|(?P<o>{rx['PAREN_KW']})(?:{sp}(?P<oa>{addr}))?"
        rf"|(?P<p>{rx['RPAR']})"
        rf"|(?P<c>{rx['LOAD_KW']}|{rx['LOGIC_KW']}){sp}(?P<cb>{rx['LSQB']}){sp}{expr('1')}"
        rf"{sp}(?P<cmp>{rx['CMP_OP']}){sp}{expr('2')}{sp}(?P<ce>{rx['RSQB']})"
        rf"|(?P<x>{rx['LSQB']}){sp}(?P<t>{addr}){sp}(?P<as>{rx['ASSIGN']}){sp}{expr('3')}"
        rf"{sp}(?P<xe>{rx['RSQB']})"
        rf"){sp}")
    return FastLines(pattern, funcs)
