"""Instruction List text -> typed AST (`Program` of `Rung`s).

Parsing is line-oriented: a syntax error blanks its line and parsing goes on, so one run
reports every bad line. Rung boundaries are derived the way Twido's list/ladder
reversibility does: a rung starts with a load (or BLK, a label, a Grafcet step) that comes
after the previous rung's outputs.
"""

from __future__ import annotations

import bisect
import dataclasses
import difflib
import heapq
import itertools
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from lark import Lark, Token, Transformer, Tree, v_args
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken

from softplc.errors import AddressError, Code, Diagnostic, ParseError
from softplc.il import ast as A
from softplc.il import fastlines, literals, parsecache
from softplc.il.fastlines import FastLines
from softplc.limits import MAX_PROGRAM_BYTES, BoundsError, read_bytes
from softplc.twido import catalog
from softplc.twido.address import Ref, parse_address
from softplc.twido.profile import DEFAULT_PROFILE
from softplc.twido.symbols import SymbolTable

GRAMMAR = Path(__file__).with_name("twido_il.lark")

# Function aliases accepted as written in real programs.
FUNC_ALIASES = {"INTO_TO_REAL": "INT_TO_REAL"}

# Human names for grammar terminals, for "expected ..." in error messages.
TERMINAL_NAMES = {
    "ADDRESS": "an address (%M0, %MW3, %I0.1...) or a symbol", "INT": "a number",
    "FLOAT": "a number",
    "HEX": "a number", "LABEL": "a label (%Ln)", "CMP_OP": "a comparison (> >= < <= = <>)",
    "ASSIGN": "':='", "RSQB": "']'", "LSQB": "'['", "RPAR": "')'", "LPAR": "'('",
    "_NL": "end of line", "$END": "end of file", "LOAD_KW": "LD/LDN/LDR/LDF",
    "LOGIC_KW": "AND/OR/XOR", "STORE_KW": "ST/STN", "FUNC": "a function",
    "ADD_OP": "an operator", "MUL_OP": "an operator", "REM_KW": "REM", "COMMA": "','",
    "PIN_NAME": "a block output (Q, D, E, F)", "POST_KW": "POST",
    "BLK_KW": "BLK", "OUT_BLK_KW": "OUT_BLK", "END_BLK_KW": "END_BLK", "END_KW": "END",
    "GRAF_INIT": "=*=", "GRAF_STEP": "-*-", "GRAF_JUMP": "#", "JUMP_KW": "JMP",
    "RET_KW": "RET", "NOP_KW": "NOP", "NEG_KW": "N", "STACK_KW": "MPS/MRD/MPP",
    "SETRESET_KW": "S/R", "PIN_KW": "a block input (IN, CU, CD...)", "PAREN_KW": "AND(/OR(",
    "INCDEC_KW": "INC/DEC", "BLOCK_CALL_KW": "/".join(catalog.by_instruction()),
    "SR_CALL": "SRn", "SR_DEF": "SRn:",
    "LABEL_DEF": "%Ln:",
    "SECTION_KW": "SECTION",
}
# Every mnemonic the grammar takes (its *_KW terminals), for "expected" and "did you mean"
INSTRUCTIONS = ("LD LDN LDR LDF AND ANDN ANDR ANDF OR ORN ORR ORF XOR XORN XORR XORF "
                "AND( OR( XOR( ) ST STN S R N MPS MRD MPP [ ] JMP JMPC JMPCN SRn RET RETC "
                "RETCN END ENDC ENDCN NOP BLK OUT_BLK END_BLK IN CU CD U I O EXCHn "
                "=*= -*- # #D POST").split()


def _did_you_mean(word: str) -> str:
    """' (did you mean CU?)' for 'CUU', or '' when no mnemonic is close."""
    close = difflib.get_close_matches(word.upper(), INSTRUCTIONS, n=3, cutoff=0.6)
    if not close:
        return ""
    return f" (did you mean {', '.join(close[:-1]) + ' or ' if close[1:] else ''}{close[-1]}?)"


@lru_cache(maxsize=1)
def _lark() -> Lark:
    text = GRAMMAR.read_text().replace("@BLOCK_CALLS@", "|".join(catalog.by_instruction()))
    return Lark(text, parser="lalr", lexer="contextual",
                propagate_positions=True, maybe_placeholders=False, cache=parsecache.grammar_file())


@lru_cache(maxsize=1)
def _fast_line() -> FastLines | None:
    """The fast path for the commonest lines (il/fastlines.py); None: Lark for all."""
    return fastlines.build(_lark(), _ToAST)


def prepare() -> None:
    """Build the grammar and the fast line table now, not at the first parse: for a
    process that forks parsers (`plant up`, the test zygote), so that each child does not."""
    _fast_line()


def _pos(tok: Token | object) -> A.Pos:
    return A.Pos(getattr(tok, "line", 0) or 0, getattr(tok, "column", 0) or 0,
                 getattr(tok, "end_line", 0) or 0, getattr(tok, "end_column", 0) or 0)


_LOGIC_OP = re.compile(r"AND|OR|XOR")
_BOOL_WORDS: dict[str, tuple[str, str]] = {}  # LD, andn, ... as written -> (op, modifier)


@dataclass(frozen=True)
class _Section:
    number: int
    pos: A.Pos


@dataclass(frozen=True)
class _SRDef:
    number: int
    pos: A.Pos


class _ToAST(Transformer):
    """Parse tree -> AST nodes. Address errors are collected, not raised."""

    def __init__(self, file: str, lines: list[str], symbols: SymbolTable | None = None):
        super().__init__()
        self.file = file
        self.lines = lines
        self.diags: list[Diagnostic] = []
        self.symbols = symbols
        self._refs: dict[str, Ref] = {}  # a program names the same addresses again and again

    def _ref(self, tok: Token) -> Ref:
        return self.ref_at(str(tok), tok.line, tok.column)

    def ref_at(self, text: str, line: int, column: int) -> Ref:
        """The reference `text` (an address, or a symbol) at line:column (1-based), or a
        placeholder with a diagnostic."""
        ref = self._refs.get(text)
        if ref is not None:
            return ref
        try:
            if self.symbols is not None:  # a name, or an address: its symbol attached
                ref = self.symbols.ref(text)
            elif not text.startswith("%"):
                raise AddressError(f"unknown symbol {text!r} (no symbol table: declare "
                                   f"[symbols] in the configuration)")
            else:
                ref = parse_address(text)
            self._refs[text] = ref
            return ref
        except AddressError as e:
            symbol = not text.startswith("%")
            self.diags.append(Diagnostic(
                str(e), self.file, line, column, text,
                "a declared symbol or an address" if symbol else
                f"an address within the {DEFAULT_PROFILE.name} profile",
                Code.SYMBOL if symbol else Code.ADDRESS))
            return Ref("M", 0)  # placeholder; the program is rejected anyway

    # Nodes built from plain text, shared with the fast path (il/fastlines.py)
    @staticmethod
    def bool_instr_node(kw: str, operand: A.BoolOperand, pos: A.Pos) -> A.BoolInstr:
        split = _BOOL_WORDS.get(kw)
        if split is None:  # op and modifier strings shared by every node (memory)
            word = kw.upper()
            op = "LD" if word.startswith("LD") else _LOGIC_OP.match(word).group(0)
            split = _BOOL_WORDS[kw] = sys.intern(op), sys.intern(word[len(op):])
        return A.BoolInstr(*split, operand, pos)

    @staticmethod
    def paren_open_node(kw: str, operand: A.BoolOperand | None, pos: A.Pos) -> A.ParenOpen:
        op, mod = kw.upper().replace(" ", "").replace("\t", "").split("(")
        return A.ParenOpen(sys.intern(op), mod, operand, pos)

    @staticmethod
    def set_reset_node(kw: str, ref: Ref | None, pos: A.Pos) -> A.Instruction:
        kw = kw.upper()
        if ref is None or ref.is_block:  # a bare R / S inside BLK, or R %C0: a block input
            return A.Pin(kw, ref, pos)
        return A.Store(kw, ref, pos)

    # -- operands --
    def address(self, items):
        (tok,) = items
        return A.Operand(self._ref(tok), _pos(tok))

    def bool_const(self, items):
        (tok,) = items
        if str(tok) not in ("0", "1"):
            self.diags.append(Diagnostic("a boolean operand constant is 0 or 1", self.file,
                                         tok.line, tok.column, str(tok), "0 or 1",
                                         Code.CONSTANT))
        return A.Const(int(str(tok) == "1"), _pos(tok))

    def block_output(self, items):
        (tok,) = items
        return A.BlockOutput(str(tok).upper(), _pos(tok))

    @v_args(meta=True)
    def compare(self, meta, items):
        left, op, right = items
        return A.Compare(str(op), left, right, _pos(meta))

    # -- expressions --
    def ref(self, items):
        (tok,) = items
        return A.Addr(self._ref(tok), _pos(tok))

    def int_lit(self, items):
        return literals.number(items[0], literals.INT, self.file, self.diags)

    def hex_lit(self, items):
        return literals.number(items[0], literals.HEX, self.file, self.diags)

    def float_lit(self, items):
        return literals.number(items[0], literals.FLOAT, self.file, self.diags)

    @v_args(meta=True)
    def binop(self, meta, items):
        left, op, right = items
        return A.BinOp(str(op).upper(), left, right, _pos(meta))

    @v_args(meta=True)
    def neg(self, meta, items):
        op, operand = items
        if str(op) == "+":
            return operand
        if isinstance(operand, A.Num):  # fold: -5 is a constant
            return A.Num(-operand.value, "-" + (operand.text or str(operand.value)),
                         operand.pos)
        return A.Neg(operand, _pos(meta))

    @v_args(meta=True)
    def call(self, meta, items):
        name, *args = items
        func = str(name).upper()
        return A.Call(FUNC_ALIASES.get(func, func), tuple(a for a in args if a is not None),
                      _pos(meta))

    @v_args(meta=True)
    def assign(self, meta, items):
        target, _, expr = items
        return A.Assign(self._ref(target), expr, _pos(meta))

    @v_args(meta=True)
    def incdec(self, meta, items):
        op, target = items
        return A.IncDec(str(op).upper(), self._ref(target), _pos(meta))

    @v_args(meta=True)
    def block_call(self, meta, items):
        return A.BlockCall(str(items[0]).upper(), int(items[1]), _pos(meta))

    # -- instructions --
    @v_args(meta=True)
    def bool_instr(self, meta, items):
        kw, operand = items
        return self.bool_instr_node(str(kw), operand, _pos(meta))

    @v_args(meta=True)
    def paren_open(self, meta, items):
        return self.paren_open_node(str(items[0]), items[1] if len(items) > 1 else None,
                                    _pos(meta))

    @v_args(meta=True)
    def paren_close(self, meta, items):
        return A.ParenClose(_pos(meta))

    @v_args(meta=True)
    def store(self, meta, items):
        kw, target = items
        return A.Store(sys.intern(str(kw).upper()), self._ref(target), _pos(meta))

    @v_args(meta=True)
    def set_reset(self, meta, items):
        return self.set_reset_node(str(items[0]), self._ref(items[1]) if len(items) > 1
                                   else None, _pos(meta))

    @v_args(meta=True)
    def negate(self, meta, items):
        return A.Negate(_pos(meta))

    @v_args(meta=True)
    def stack(self, meta, items):
        return A.Stack(str(items[0]).upper(), _pos(meta))

    @v_args(meta=True)
    def op_block(self, meta, items):
        return A.OpBlock(items[0], _pos(meta))

    @v_args(meta=True)
    def exch(self, meta, items):
        kw, table = items
        return A.OpBlock(A.ExchCall(int(str(kw)[4:]), self._ref(table), _pos(meta)), _pos(meta))

    @v_args(meta=True)
    def jump(self, meta, items):
        kw, label = items
        return A.Jump(str(kw).upper(), int(str(label)[2:]), _pos(meta))

    @v_args(meta=True)
    def sr_call(self, meta, items):
        return A.SRCall(int(str(items[0])[2:]), _pos(meta))

    @v_args(meta=True)
    def ret(self, meta, items):
        return A.Return(str(items[0]).upper(), _pos(meta))

    @v_args(meta=True)
    def end(self, meta, items):
        return A.End(str(items[0]).upper(), _pos(meta))

    @v_args(meta=True)
    def nop(self, meta, items):
        return A.Nop(_pos(meta))

    @v_args(meta=True)
    def blk(self, meta, items):
        return A.Blk(self._ref(items[1]), _pos(meta))

    @v_args(meta=True)
    def out_blk(self, meta, items):
        return A.OutBlk(_pos(meta))

    @v_args(meta=True)
    def end_blk(self, meta, items):
        return A.EndBlk(_pos(meta))

    @v_args(meta=True)
    def pin(self, meta, items):
        name = str(items[0]).upper()
        return A.Pin(name, self._ref(items[1]) if len(items) > 1 else None, _pos(meta))

    @v_args(meta=True)
    def grafcet(self, meta, items):
        kw = str(items[0]).upper()
        arg = str(items[1]).upper() if len(items) > 1 else None
        if kw == "=*=" and arg == "POST":
            return A.Grafcet("POST", None, _pos(meta))
        return A.Grafcet(kw, int(arg) if arg is not None else None, _pos(meta))

    # -- structure --
    @v_args(meta=True)
    def section(self, meta, items):
        return _Section(int(str(items[1])), _pos(meta))

    @v_args(meta=True)
    def sr_def(self, meta, items):
        return _SRDef(int(re.match(r"SR(\d+)", str(items[0]), re.I).group(1)), _pos(meta))

    @v_args(meta=True)
    def label_def(self, meta, items):
        return A.Label(int(re.match(r"%L(\d+)", str(items[0]), re.I).group(1)), _pos(meta))

    def start(self, items):
        return items


def _syntax_diag(e: UnexpectedInput, file: str, lines: list[str]) -> Diagnostic:
    line = getattr(e, "line", 0) or len(lines)
    col = getattr(e, "column", 0) or 1
    src = lines[line - 1] if 0 < line <= len(lines) else ""
    if isinstance(e, UnexpectedToken):
        tok = e.token
        text = str(tok) if tok.type != "$END" else ""
        what = "unexpected end of line" if tok.type == "_NL" else (
            "unexpected end of file" if tok.type == "$END" else f"unexpected {text.strip()!r}")
        expected = sorted({TERMINAL_NAMES.get(t, t.strip("_").replace("_KW", "").lower())
                           for t in e.expected})
    elif isinstance(e, UnexpectedCharacters):
        text = src[col - 1:].split()[0] if src[col - 1:].split() else src[col - 1:col]
        what = f"unexpected {text!r}"
        expected = sorted({TERMINAL_NAMES.get(t, t.strip("_").replace("_KW", "").lower())
                           for t in (e.allowed or ())})
    else:  # UnexpectedEOF
        text, what, expected = "", "unexpected end of file", []
    exp = ", ".join(expected[:12]) + (" ..." if len(expected) > 12 else "")
    stripped = src.lstrip()
    if src and col == len(src) - len(stripped) + 1 and text and not text.startswith(("%", "(")):
        word = stripped.split()[0]
        return Diagnostic(f"unknown instruction {word!r}{_did_you_mean(word)}", file, line,
                          col, src.strip(), f"an instruction: {' '.join(INSTRUCTIONS)}",
                          Code.UNKNOWN_INSTRUCTION)
    return Diagnostic(f"syntax error: {what}", file, line, col, src.strip(), exp, Code.SYNTAX)


# Nesting of an expression (operators and function calls inside each other) the parser
# takes. Twido limits IL parentheses (AND( OR( XOR() to 8 levels [manual]; the depth of an
# operation block's expression is not documented, and a TwidoSuite operation block holds
# far fewer than this. Deeper expressions would overflow Python's recursion and nesting
# limits in the later stages, so they are refused here with their line.
MAX_EXPR_DEPTH = 64
_COMMENT = re.compile(r"\(\*(.|\n)*?\*\)")  # as the grammar's COMMENT terminal
_NESTING_NODES = frozenset({"binop", "neg", "call"})


def _expr_depth(tree: Tree) -> tuple[int, Tree]:
    """Deepest nesting of operators/calls in a line's tree (iteratively), and that node."""
    deepest, node = 0, tree
    stack = [(tree, 0)]
    while stack:
        t, d = stack.pop()
        if t.data in _NESTING_NODES:
            d += 1
            if d > deepest:
                deepest, node = d, t
        stack.extend((c, d) for c in t.children if isinstance(c, Tree))
    return deepest, node


def _shift_lines(tree: Tree, offset: int) -> None:
    """Add `offset` to the line numbers of a tree parsed from a chunk of the file."""
    if not offset:
        return
    seen: set[int] = set()
    for t in tree.iter_subtrees():
        meta = t.meta
        if not meta.empty and id(meta) not in seen:
            seen.add(id(meta))
            meta.line += offset
            meta.end_line += offset
        for c in t.children:
            if isinstance(c, Token) and id(c) not in seen and c.line is not None:
                seen.add(id(c))
                c.line += offset
                c.end_line += offset


class _LineParser:
    """Parse a program, skipping bad lines. On a syntax error at line L, the lines before
    it are parsed once more on their own and parsing resumes after L, so a file with many
    bad lines costs about two parses, not one per bad line."""

    def __init__(self, text: str, file: str, symbols: SymbolTable | None = None):
        self.file = file
        self.symbols = symbols
        self.lines = text.splitlines()
        self.inside: bytearray | None = None  # 1: line starts inside a comment (parse_lines)
        self.fast = _fast_line()
        self.tx = _ToAST(file, self.lines, symbols)
        self.done: dict[int, A.Instruction] = {}  # fast_items' nodes by 0-based line
        self.diags: list[Diagnostic] = []
        self.bad: set[int] = set()  # 1-based numbers of the lines left out
        self.parses = 0  # grammar runs (the recovery's cost)
        self.lost = False  # an error that could not be pinned to a line: give up

    def parse_range(self, start: int, end: int) -> list:
        """Items of lines start+1 .. end (1-based), bad lines left out."""
        items: list = []
        pos = start
        while pos < end and not self.lost:
            chunk = self.lines[pos:end]
            fast = self.fast_items(pos, chunk)
            self.parses += 1
            try:
                # lines parsed without Lark stay as blank lines: line numbers hold
                rest = [("" if k in fast else ln) for k, ln in enumerate(chunk)] if fast \
                    else chunk
                tree = _lark().parse("\n".join(rest) + "\n") if len(fast) < len(chunk) \
                    else None
            except UnexpectedInput as e:
                d = _syntax_diag(e, self.file, chunk)
                d = dataclasses.replace(d, line=d.line + pos)
                self.diags.append(d)
                line = d.line
                if not (pos < line <= end) or not self.lines[line - 1].strip():
                    self.lost = True
                    break
                self.bad.add(line)
                items += self.parse_range(pos, line - 1)
                pos = line
                continue
            if tree is not None:
                _shift_lines(tree, pos)
                slow = self.transform(tree)
                items += heapq.merge(slow, fast.values(), key=lambda it: it.pos.line) \
                    if fast else slow
            else:
                items += fast.values()
            break
        return items

    def fast_items(self, pos: int, chunk: list[str]) -> dict[int, A.Instruction]:
        """Nodes of the chunk's lines that `_fast_line` matches, by index in the chunk
        (in line order), leaving out lines that start inside a comment."""
        out: dict[int, A.Instruction] = {}
        if self.fast is None:
            return out
        match, inside, done = self.fast.pattern.fullmatch, self.inside, self.done
        for k, text in enumerate(chunk):
            item = done.get(pos + k)  # after a syntax error: built once (its diagnostics)
            if item is None:
                m = match(text)
                if m is None or inside and inside[pos + k]:
                    continue
                item = done[pos + k] = self.fast.item(self.tx, m, pos + k + 1)
            out[k] = item
        return out

    def transform(self, tree: Tree) -> list:
        tx = self.tx
        items = []
        for child in tree.children:  # one line item each (start's children)
            if not isinstance(child, Tree):
                continue
            depth, node = _expr_depth(child)
            if depth > MAX_EXPR_DEPTH:
                line = getattr(node.meta, "line", 0)
                src = self.lines[line - 1].strip() if 0 < line <= len(self.lines) else ""
                self.diags.append(Diagnostic(
                    f"expression nested {depth} levels deep", self.file, line,
                    getattr(node.meta, "column", 0), src,
                    f"at most {MAX_EXPR_DEPTH} levels of operators and functions inside each "
                    f"other: split it over several operation blocks", Code.NESTING))
                self.bad.add(line)
                continue
            items.append(tx.transform(child))
        return items


CHUNK_LINES = 40  # lines parsed at once: a syntax error costs a re-parse of at most this


def _inside_comments(text: str, lines: list[str]) -> bytearray:
    """1 at the 0-based index of each line that starts inside a comment (comments may
    span lines)."""
    inside = bytearray(len(lines) + 1)
    if "(*" not in text:
        return inside
    starts = list(itertools.accumulate((len(ln) + 1 for ln in lines), initial=0))
    for m in _COMMENT.finditer(text):
        first = bisect.bisect_right(starts, m.start())  # 1-based line of "(*"
        last = bisect.bisect_right(starts, m.end() - 1)
        for k in range(first, last):  # lines first+1 .. last start inside: 0-based k
            inside[k] = 1
    return inside


def _chunks(lines: list[str], inside: bytearray) -> Iterator[tuple[int, int]]:
    """Line ranges [start, end) of about CHUNK_LINES lines, cut only where a line does not
    start inside a comment, so each parses on its own."""
    pos = 0
    while pos < len(lines):
        end = min(pos + CHUNK_LINES, len(lines))
        while end < len(lines) and inside[end]:
            end += 1
        yield pos, end
        pos = end


def parse_lines(text: str, file: str = "<string>", symbols: SymbolTable | None = None
                ) -> tuple[list, list, list[Diagnostic]]:
    """Parse to a flat list of line items (instructions, sections, SR defs, labels).

    Returns (items, comments, diagnostics); comments are (line, column, text)."""
    lp = _LineParser(text, file, symbols)
    lp.inside = _inside_comments(text, lp.lines)
    for d in literals.long_numbers(text, file, _COMMENT):  # left out before int() sees them
        lp.lines[d.line - 1] = ""
        lp.bad.add(d.line)
        lp.diags.append(d)
    items = []
    for start, end in _chunks(lp.lines, lp.inside):
        items += lp.parse_range(start, end)
        lp.done.clear()  # a chunk's recovery never goes back to an earlier chunk
        if lp.lost:
            break
    diags = sorted(lp.diags + lp.tx.diags, key=lambda d: (d.line, d.column))
    if lp.lost:
        return [], [], diags
    if "(*" not in text:
        return items, [], diags
    work = [("" if n + 1 in lp.bad else ln) for n, ln in enumerate(lp.lines)]
    src = "\n".join(work) + "\n"
    starts = list(itertools.accumulate((len(ln) + 1 for ln in work), initial=0))
    comments: list[tuple[int, int, str]] = []  # re-scanned: the lexer ignores them
    for m in _COMMENT.finditer(src):
        ln = bisect.bisect_right(starts, m.start())  # 1-based line of the comment
        comments.append((ln, m.start() - starts[ln - 1] + 1, m.group(0)[2:-2].strip()))
    return items, comments, diags


# Instructions that end a rung: after one of these, the next load starts a new rung.
_OUTPUTS = (A.Store, A.OpBlock, A.Jump, A.SRCall, A.Return, A.End, A.EndBlk, A.Pin, A.Nop,
            A.Grafcet)
_STEP_MARKERS = ("=*=", "-*-", "POST")
_TITLE_PREFIX = re.compile(r"^(RUNG|RUNGTITLE|RUNGCOMMENT|TITLE|COMMENT)\s*:\s*", re.I)


def _is_start(instr: A.Instruction) -> bool:
    return (isinstance(instr, A.BoolInstr) and instr.is_load) or isinstance(instr, A.Blk)


def segment(items: list, comments: list[tuple[int, int, str]], file: str, source: str
            ) -> A.Program:
    """Group a flat item list into rungs."""
    instr_lines = {getattr(it, "pos", A.NOPOS).line for it in items}
    # own-line comments (not SECTTITLE) become the title of the rung that follows them
    own: dict[int, str] = {}
    section_titles: dict[int, str] = {}
    pending_titles: list[tuple[int, str]] = []
    for ln, _col, text in comments:
        if text.upper().startswith("SECTTITLE:"):
            pending_titles.append((ln, text.split(":", 1)[1].strip()))
        elif text.upper().startswith("SECTCOMMENT:"):
            continue
        elif ln not in instr_lines and text:
            own[ln] = _TITLE_PREFIX.sub("", text)

    rungs: list[A.Rung] = []
    section: int | None = None
    sr: int | None = None
    cur: A.Rung | None = None
    in_blk = False
    label: int | None = None
    label_line = 0
    last_line = 0

    def title_before(line: int) -> str:
        # the nearest own-line comment between the previous instruction and this line
        for ln in range(line - 1, last_line, -1):
            if ln in own:
                return own[ln]
        return ""

    def new_rung(first_line: int) -> A.Rung:
        nonlocal cur, label
        cur = A.Rung(len(rungs), [], title_before(first_line), section, sr, label,
                     first_line, first_line, label_line if label is not None else 0)
        label = None
        rungs.append(cur)
        return cur

    for it in items:
        if isinstance(it, _Section):
            section, sr, cur = it.number, None, None
            for ln, t in pending_titles:
                if ln > it.pos.line and section not in section_titles:
                    section_titles[section] = t
            last_line = it.pos.line
            continue
        if isinstance(it, _SRDef):
            sr, cur = it.number, None
            last_line = it.pos.line
            continue
        if isinstance(it, A.Label):
            label, label_line, cur = it.number, it.pos.line, None
            last_line = it.pos.line
            continue
        # a step marker starts a rung; '# i' is an output of its transition rung
        starts = (cur is None or (isinstance(it, A.Grafcet) and it.op in _STEP_MARKERS) or
                  (not in_blk and _is_start(it) and cur.instructions
                   and isinstance(cur.instructions[-1], _OUTPUTS)))
        if starts:
            new_rung(it.pos.line)
        cur.instructions.append(it)
        cur.last_line = it.pos.line
        last_line = it.pos.line
        if isinstance(it, A.Blk):
            in_blk = True
        elif isinstance(it, A.EndBlk):
            in_blk = False
        if isinstance(it, A.Grafcet) and it.op in _STEP_MARKERS:
            cur = None  # a step marker is a rung of its own
    if label is not None:  # a label at the very end: an empty rung to jump to
        rungs.append(A.Rung(len(rungs), [], "", section, sr, label, last_line, last_line,
                            label_line))
    # section titles that came before any SECTION line
    for _ln, t in pending_titles:
        section_titles.setdefault(section if section is not None else 0, t)
    return A.Program(file, source, rungs, section_titles)


def parse(text: str, file: str = "<string>", symbols: SymbolTable | None = None
          ) -> A.Program:
    """Parse a whole program (a text parsed before: a copy, il/parsecache.py). Raises
    ParseError listing every syntax problem; the error's `program` holds what parsed (bad
    lines left out) so later checks can still run. `symbols`: the names the program may use
    for addresses (softplc.twido.symbols)."""
    key = (text, file, None if symbols is None else symbols.key())
    return parsecache.parsed(key, text, lambda: _parse(text, file, symbols))


def _parse(text: str, file: str, symbols: SymbolTable | None) -> A.Program:
    items, comments, diags = parse_lines(text, file, symbols)
    if diags:
        err = ParseError(diags)
        err.program = segment(items, comments, file, text) if items else None
        raise err
    return segment(items, comments, file, text)


def parse_file(path: str | Path, symbols: SymbolTable | None = None) -> A.Program:
    p = Path(path)
    try:
        text = read_bytes(p, MAX_PROGRAM_BYTES, "the program").decode("utf-8-sig", "replace")
    except (OSError, BoundsError) as e:
        why = getattr(e, "strerror", None) or e
        raise ParseError(Diagnostic(f"cannot read program: {why}", str(p),
                                    code=Code.CANNOT_READ)) from None
    return parse(text, str(p), symbols)
