"""The parser's fast path: the commonest IL lines without Lark.

Lines like `LD %M0`, `ANDN %I0.3`, `ST %Q0.1`, `S %M5`, `AND( %M1`, `)`, and the simple
comparison and operation blocks (`LD [ %MW1 > 3 ]`, `[ %MW2 := %MW3 + 4 ]`: operands
`%` addresses or decimal integers, at most one `+ - * /` a side) make up most of a
program. Lark's lexer and tree builder cost ~50 us a line (~85 for a block); a regex
match and building the nodes a few. The regex is assembled from the grammar's terminals,
so what it matches the grammar's rules accept; references and the nodes of rules with
logic of their own come from the transformer (`SHARED`); any other line (comments,
other expressions, labels, symbols, errors) goes to Lark. tests/unit/test_il_fastpath.py
checks that both paths give the same AST, positions and diagnostics.
"""

from __future__ import annotations

import re
import sys
from typing import Any

from lark import Lark

from softplc.il import ast as A

# regex group -> its keyword terminals: `KEYWORD ADDRESS` lines (bool_instr, store,
# set_reset)
KEYWORDS = {"b": ("LOAD_KW", "LOGIC_KW"), "s": ("STORE_KW",), "r": ("SETRESET_KW",)}
TERMINALS = ("ADDRESS", "RPAR", "PAREN_KW", "CMP_OP", "ASSIGN", "ADD_OP", "MUL_OP", "INT",
             "LSQB", "RSQB")
# what the transformer shares with the fast path: references (cached, with their
# diagnostics) and the nodes built from text by rules with logic of their own
SHARED = ("ref_at", "bool_instr_node", "paren_open_node", "set_reset_node")
Pos = A.Pos


class FastLines:
    """The matcher (`pattern.fullmatch(line)`) and the node builder of the fast path.

    The nodes are built here, as the transformer's methods build them from Lark's tokens
    (positions: a token's columns, a rule's from its first token to its last, 1-based),
    without the tokens: building those and calling the methods cost twice as much."""

    def __init__(self, pattern: re.Pattern[str]):
        self.pattern = pattern

    def item(self, tx: Any, m: re.Match[str], line: int) -> A.Instruction:
        """The node of a matched line (1-based `line`), built with transformer `tx`."""
        b, s, r, o, p, c, x = m.group("b", "s", "r", "o", "p", "c", "x")
        if b is not None or s is not None or r is not None:  # KEYWORD %address
            kw = b or s or r
            start = m.start("b" if b is not None else "s" if s is not None else "r") + 1
            col, end = m.span("a")
            text = m.group("a")
            ref = tx.ref_at(text, line, col + 1)
            pos = Pos(line, start, line, end + 1)
            if b is not None:
                return tx.bool_instr_node(kw, A.Operand(ref, Pos(line, col + 1, line, end + 1)),
                                          pos)
            if s is not None:
                return A.Store(sys.intern(kw.upper()), ref, pos)  # one string for all
            return tx.set_reset_node(kw, ref, pos)
        if p is not None:
            return A.ParenClose(self._span(m, "p", "p", line))
        if o is not None:  # AND( / OR( / XOR(, with or without its operand
            if m.group("oa") is None:
                return tx.paren_open_node(o, None, self._span(m, "o", "o", line))
            col, end = m.span("oa")
            operand = A.Operand(tx.ref_at(m.group("oa"), line, col + 1),
                                Pos(line, col + 1, line, end + 1))
            return tx.paren_open_node(o, operand, self._span(m, "o", "oa", line))
        if x is not None:  # [ %MW2 := expr ]
            expr = self._expr(tx, m, "3", line)
            col = m.start("t") + 1
            stmt = A.Assign(tx.ref_at(m.group("t"), line, col), expr,
                            Pos(line, col, line, expr.pos.end_column))
            return A.OpBlock(stmt, self._span(m, "x", "xe", line))
        # KEYWORD [ expr CMP expr ]
        cmp = A.Compare(m.group("cmp"), self._expr(tx, m, "1", line),
                        self._expr(tx, m, "2", line), self._span(m, "cb", "ce", line))
        return tx.bool_instr_node(c, cmp, self._span(m, "c", "ce", line))

    @staticmethod
    def _span(m: re.Match[str], first: str, last: str, line: int) -> A.Pos:
        """From group `first`'s start to group `last`'s end (a rule's meta)."""
        return Pos(line, m.start(first) + 1, line, m.end(last) + 1)

    def _expr(self, tx: Any, m: re.Match[str], n: str, line: int) -> A.Expr:
        """Expression `n` of the line: an atom, or `atom op atom`."""
        left = self._atom(tx, m, "l" + n, line)
        op = m.group("o" + n)
        if op is None:
            return left
        right = self._atom(tx, m, "r" + n, line)
        return A.BinOp(op, left, right, Pos(line, left.pos.column, line, right.pos.end_column))

    @staticmethod
    def _atom(tx: Any, m: re.Match[str], group: str, line: int) -> A.Expr:
        text = m.group(group)
        col, end = m.span(group)
        pos = Pos(line, col + 1, line, end + 1)
        if text[0] == "%":
            return A.Addr(tx.ref_at(text, line, col + 1), pos)
        return A.Num(int(text), text, pos)


def build(lark: Lark, transformer: type) -> FastLines | None:
    """The fast path for this grammar and transformer class; None (every line through
    Lark) if the grammar lacks a terminal or the transformer what the fast path shares."""
    if not all(callable(getattr(transformer, name, None)) for name in SHARED):
        return None
    try:
        rx = {t: lark.get_terminal(t).pattern.to_regexp()
              for t in (*TERMINALS, *(t for terms in KEYWORDS.values() for t in terms))}
    except KeyError:
        return None
    kws = "|".join(f"(?P<{g}>{'|'.join(rx[t] for t in terms)})"
                   for g, terms in KEYWORDS.items())
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
    return FastLines(pattern)
