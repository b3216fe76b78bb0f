"""Requirement files and expressions for `softplc verify`.

A requirement file (TOML) beside the program:

    [environment]
    host = ["%MW0:10"]            # words a host writes: any value at the start of a scan
    held = ["%M0"]                # kept at its cold-start value (default: objects the
                                  # program reads, never writes, a host can write are free)
    assume = ["NOT (%I0.0 AND %I0.1)"]   # what the environment never does

    [[requirement]]
    name = "star and delta never together"
    check = "never %Q0.1 AND %Q0.2"

Forms of `check` (evaluated on the values at the end of every scan):
  `never E`, `always E`, `A -> B` (same scan), `X rising -> Y within N scans` or
  `... within T ms`. Expressions use the IL address syntax, or the configuration's symbols
(`never MOTOR AND JAM`, resolved by softplc.twido.symbols), and operators: NOT AND OR XOR,
  comparisons = <> < <= > >=, + - * / REM on words (exact, no wrap-around), parentheses.
%I bits and configured analog inputs %IW are free (any value in every scan, analog within
the configured span). Errors carry the line:col in the file (`VerifyError`).
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softplc.errors import AddressError, Code, Diagnostic, VerifyError
from softplc.limits import (
    MAX_EXPR_NESTING,
    MAX_NUMBER_DIGITS,
    MAX_REQUIREMENTS_BYTES,
    BoundsError,
    check_toml,
    decode_text,
    read_bytes,
)
from softplc.twido.address import BOOL, REAL, Ref, expand
from softplc.twido.numeric import F32_MAX
from softplc.twido.profile import Profile
from softplc.twido.symbols import SymbolTable

_TOKEN = re.compile(r"""\s*(?:
    (?P<addr>%[A-Za-z]+[0-9][0-9A-Za-z.:\[\]%]*) |
    (?P<real>-?(?:\d+\.\d*(?:[eE][-+]?\d+)?|\d+[eE][-+]?\d+)) |
    (?P<num>-?\d+|16\#[0-9A-Fa-f]+|\#[0-9A-Fa-f]+) |
    (?P<op>->|<=|>=|<>|[-+*/()=<>]) |
    (?P<word>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z]+[0-9]*)?(?::X?[0-9]+)?))""", re.X)
KEYWORDS = {"AND", "OR", "XOR", "NOT", "REM", "NEVER", "ALWAYS", "RISING", "WITHIN",
            "SCANS", "SCAN", "MS", "S"}
#: The keys a requirement file takes, by table (anything else is an unknown key).
TABLES = ("environment", "requirement")
ENVIRONMENT_KEYS = ("host", "free", "held", "assume", "scan_period")
REQUIREMENT_KEYS = ("name", "check")
#: A number in an expression: a value of a 32-bit double word (%MD), or its bit pattern
#: in hex (#FFFFFFFF): whatever a program compares a word with.
NUMBER_RANGE = (-(1 << 31), (1 << 32) - 1)
#: `within N scans`: the response monitor counts scans in a 16-bit word (checker.py).
MAX_WITHIN_SCANS = 32767
#: `within T ms`: a day, far beyond any timer of the program (a %TM counts at most 32767
#: of its 1 s base [manual, from memory]: about 9 hours).
MAX_WITHIN_MS = 86_400_000
#: Depth of an expression's tree, a chain of operators included (`A OR B OR ...` nests to
#: the left): the checker and the replay walk it recursively, a few frames a level, well
#: inside Python's recursion limit (1,000) at this depth.
MAX_EXPR_TREE_DEPTH = 2 * MAX_EXPR_NESTING
#: Words that would be a float's non-finite values (`float("nan")` takes them): refused,
#: as in an IL program (`il/literals.py`), where a REAL constant must be finite.
NOT_FINITE = frozenset({"NAN", "INF", "INFINITY"})
INT, FLOAT = "int", "real"  # a Node's number types (and BOOL)
EXPR_ARG = "--require-expr"
SHOWN = 80  # characters of an expression quoted in an error


@dataclass(frozen=True)
class Node:
    """An expression node: op ("addr", "num", "not", "and", "or", "xor", "cmp:<=",
    "+", "-", "*", "/", "rem", "neg") with its children, type BOOL, INT (a word, exact)
    or FLOAT (a double, as the engine computes a float expression), column."""

    op: str
    args: tuple[Any, ...]
    type: str
    col: int


@dataclass
class Requirement:
    name: str
    kind: str  # "always" | "response"
    cond: Node  # always: the invariant; response: the trigger X (rising)
    target: Node | None = None  # response: Y
    within: int = 0  # response: scans
    text: str = ""
    reads: list[Ref] = field(default_factory=list)


@dataclass
class Spec:
    requirements: list[Requirement]
    assumptions: list[Node]
    host: list[Ref]
    reads: list[Ref]  # every object a requirement or assumption reads
    free: list[tuple[Ref, Diagnostic]] = field(default_factory=list)  # with where declared
    periods: tuple[int, int] | None = None  # (shortest, longest) scan period in us
    held: list[Ref] = field(default_factory=list)  # kept at their cold-start value


class _Where:
    """Locates a string of the TOML file, for line:col in messages."""

    def __init__(self, file: str, text: str):
        self.file, self.lines = file, text.splitlines()

    def find(self, s: str) -> tuple[int, int]:
        for i, ln in enumerate(self.lines):
            for q in ('"', "'"):
                j = ln.find(q + s + q)
                if j >= 0:
                    return i + 1, j + 2
        return 0, 0


def names(table: SymbolTable | Profile) -> SymbolTable:
    """The symbols requirements may use (a bare profile: none)."""
    return table if isinstance(table, SymbolTable) else SymbolTable(profile=table)


class Parser:
    """One expression: tokens with their columns, recursive descent, typed nodes.
    `table`: the configuration's symbols (addresses and names resolve there, the one path
    of softplc.twido.symbols), or a bare profile."""

    def __init__(self, text: str, table: SymbolTable | Profile, err: Any):
        self.text, self.names, self.err = text, names(table), err
        self.toks: list[tuple[str, str, int]] = []
        pos = 0
        while pos < len(text):
            if text[pos:].strip() == "":
                break
            m = _TOKEN.match(text, pos)
            if not m or m.end() == pos:
                col = len(text) - len(text[pos:].lstrip()) + 1
                raise err(f"unexpected {text[col - 1:col + 5]!r}", col)
            kind = m.lastgroup
            val = m[kind]
            self.toks.append((kind, val.upper() if kind == "word" else val, m.start(kind) + 1))
            pos = m.end()
        self.i = 0
        self.depth = 0  # NOT, parentheses and minus signs open now (MAX_EXPR_NESTING)
        self.reads: list[Ref] = []

    def nested(self, parse: Any, col: int) -> Node:
        """`parse()` one level deeper: refused past MAX_EXPR_NESTING levels (the parser
        recurses per level, as does everything that walks the expression later)."""
        self.depth += 1
        try:
            if self.depth > MAX_EXPR_NESTING:
                raise self.err(f"nested more than {MAX_EXPR_NESTING} levels deep (NOT, "
                               "parentheses, minus signs)", col)
            return parse()
        finally:
            self.depth -= 1

    def number(self, val: str, col: int) -> int:
        """The value of a number token, bounded in digits and range."""
        if len(val) > MAX_NUMBER_DIGITS:
            raise self.err(f"a number of {len(val)} characters (at most "
                           f"{MAX_NUMBER_DIGITS})", col)
        v = int(val.replace("16#", "").lstrip("#"), 16) if "#" in val else int(val)
        lo, hi = NUMBER_RANGE
        if not lo <= v <= hi:
            raise self.err(f"{val} is beyond the 32-bit range of a word or double word "
                           f"({lo} .. {hi}, #0 .. #FFFFFFFF)", col)
        return v

    def real(self, val: str, col: int) -> float:
        """The value of a float literal: bounded in digits, finite and within a single's
        range (as an IL REAL constant: `il/literals.py`); a double, as the engine holds
        a literal of a float comparison (`compiler/values.py`: `repr(float(...))`)."""
        if len(val) > MAX_NUMBER_DIGITS:
            raise self.err(f"a number of {len(val)} characters (at most "
                           f"{MAX_NUMBER_DIGITS})", col, Code.CONSTANT)
        v = float(val)  # the token's syntax is a decimal float's: never a ValueError
        if math.isinf(v):  # an exponent too large for a double
            raise self.err(f"the float {val} is not finite", col, Code.CONSTANT)
        if abs(v) > F32_MAX:
            raise self.err(f"the float {val} is beyond the range of a %MF (an IEEE-754 "
                           f"single: at most {F32_MAX:.7g} in magnitude)", col, Code.CONSTANT)
        return v

    def peek(self) -> tuple[str, str, int]:
        return self.toks[self.i] if self.i < len(self.toks) else ("end", "", len(self.text) + 1)

    def take(self, val: str | None = None) -> tuple[str, str, int]:
        t = self.peek()
        if val is not None and t[1] != val:
            raise self.err(f"expected {val!r}, found {t[1] or 'the end'!r}", t[2])
        self.i += 1
        return t

    def at(self, *vals: str) -> bool:
        return self.peek()[1] in vals and self.peek()[0] in ("op", "word")

    def done(self) -> None:
        t = self.peek()
        if t[0] != "end":
            raise self.err(f"unexpected {t[1]!r}", t[2])

    def boolean(self) -> Node:
        n = self.conj()
        while self.at("OR", "XOR"):
            op, col = self.take()[1].lower(), self.peek()[2]
            n = Node(op, (self.need_bool(n), self.need_bool(self.nested(self.conj, col))),
                     BOOL, n.col)
        return n

    def conj(self) -> Node:
        n = self.unary()
        while self.at("AND"):
            col = self.take()[2]
            n = Node("and", (self.need_bool(n), self.need_bool(self.nested(self.unary, col))),
                     BOOL, n.col)
        return n

    def unary(self) -> Node:
        if self.at("NOT"):
            col = self.take()[2]
            return Node("not", (self.need_bool(self.nested(self.unary, col)),), BOOL, col)
        return self.comparison()

    def comparison(self) -> Node:
        n = self.sum()
        if self.at("=", "<>", "<", "<=", ">", ">="):
            _, op, col = self.take()
            m = self.sum()
            if (n.type == BOOL) != (m.type == BOOL):  # a bit compared with 0 / 1
                b, other = (n, m) if n.type == BOOL else (m, n)
                if other.op != "num" or other.args[0] not in (0, 1) or op not in ("=", "<>"):
                    raise self.err("type mismatch: a bit compared with a number", col)
                return Node("cmp:" + op, (b, Node("bool", (other.args[0],), BOOL, other.col)),
                            BOOL, n.col)
            n, m = self.same_type(n, m, col)
            return Node("cmp:" + op, (n, m), BOOL, n.col)
        return n

    def same_type(self, n: Node, m: Node, col: int) -> tuple[Node, Node]:
        """Two numbers of one type: a literal takes the other side's (as
        `ValueCompiler.operand_pair`); a float with a word is refused, as the IL compiler
        refuses it (no implicit conversion)."""
        if n.type == m.type:
            return n, m
        if m.type == INT and _literal(m):
            return n, _as_float(m)
        if n.type == INT and _literal(n):
            return _as_float(n), m
        raise self.err("type mismatch: a float (%MF, %KF) with a word: compare it with a "
                       "float literal (100.0) or a float object", col, Code.TYPE)

    def arith(self, op: str, n: Node, m: Node, col: int) -> Node:
        n, m = self.same_type(self.need_num(n), self.need_num(m), col)
        if n.type == FLOAT and op in ("/", "rem"):  # the engine's `fdiv` faults: not here
            raise self.err(f"{op.upper()} on floats: compare the %MF the program computes",
                           col, Code.TYPE)
        return Node(op, (n, m), n.type, n.col)

    def sum(self) -> Node:
        n = self.term()
        while self.at("+", "-"):
            _, op, col = self.take()
            n = self.arith(op, n, self.nested(self.term, col), col)
        return n

    def term(self) -> Node:
        n = self.factor()
        while self.at("*", "/", "REM"):
            _, op, col = self.take()
            n = self.arith(op.lower(), n, self.nested(self.factor, col), col)
        return n

    def factor(self) -> Node:
        kind, val, col = self.peek()
        if kind == "op" and val == "(":
            self.take()
            n = self.nested(self.boolean, col)
            self.take(")")
            return n
        if kind == "op" and val == "-":
            self.take()
            n = self.need_num(self.nested(self.factor, col))
            return Node("neg", (n,), n.type, col)
        if kind == "num":
            self.take()
            return Node("num", (self.number(val, col),), INT, col)
        if kind == "real":
            self.take()
            return Node("num", (self.real(val, col),), FLOAT, col)
        if kind == "addr" or (kind == "word" and val.split(".")[0] not in KEYWORDS):
            self.take()
            try:
                ref = self.names.ref(val)
            except AddressError as e:
                if val in NOT_FINITE:
                    raise self.err(f"{val}: a float in a requirement must be finite", col,
                                   Code.CONSTANT) from None
                raise self.err(f"unknown address: {e}" if kind == "addr" else str(e),
                               col) from None
            if ref.length is not None or ref.offset is not None or ref.is_block:
                raise self.err(f"{val}: a single bit or word", col)
            self.reads.append(ref)
            typ = BOOL if ref.type == BOOL else FLOAT if ref.type == REAL else INT
            return Node("addr", (ref,), typ, col)
        raise self.err(f"expected a value, found {val or 'the end'!r}", col)

    def need_bool(self, n: Node) -> Node:
        if n.type != BOOL:
            raise self.err("type mismatch: a number where a condition is expected "
                           "(compare it, e.g. %MW10 > 0)", n.col)
        return n

    def need_num(self, n: Node) -> Node:
        if n.type == BOOL:
            raise self.err("type mismatch: a bit where a number is expected", n.col)
        return n


def _literal(n: Node) -> bool:
    """A number written in the expression (a sign and parentheses allowed)."""
    return n.op == "num" or n.op == "neg" and _literal(n.args[0])


def _as_float(n: Node) -> Node:
    """An integer literal taking a float's type: its value as a double (exact: at most
    32 bits)."""
    args = (float(n.args[0]),) if n.op == "num" else (_as_float(n.args[0]),)
    return Node(n.op, args, FLOAT, n.col)


def tree_depth(n: Node) -> tuple[int, Node]:
    """The depth of an expression's tree (iteratively), and its deepest node."""
    deepest, at, stack = 0, n, [(n, 1)]
    while stack:
        node, d = stack.pop()
        if d > deepest:
            deepest, at = d, node
        stack.extend((a, d + 1) for a in node.args if isinstance(a, Node))
    return deepest, at


def check_depth(n: Node, err: Any) -> Node:
    """`n`, or the error `err(message, col)` if its tree is deeper than
    MAX_EXPR_TREE_DEPTH."""
    depth, at = tree_depth(n)
    if depth > MAX_EXPR_TREE_DEPTH:
        raise err(f"an expression {depth} operators deep (at most {MAX_EXPR_TREE_DEPTH}): "
                  "split it over several requirements or assumptions", at.col)
    return n


def parse_check(text: str, name: str, profile: SymbolTable | Profile, err: Any
                ) -> Requirement:
    """One requirement's text (`never E`, `always E`, `A -> B`, `X rising -> Y within N
    scans|ms`); `err(message, col)` makes the error to raise."""
    p = Parser(text, profile, err)
    if p.at("NEVER", "ALWAYS"):
        kw = p.take()[1]
        e = check_depth(p.need_bool(p.boolean()), err)
        p.done()
        cond = Node("not", (e,), BOOL, e.col) if kw == "NEVER" else e
        return Requirement(name, "always", cond, text=text, reads=p.reads)
    a = check_depth(p.need_bool(p.boolean()), err)
    if p.at("RISING"):
        p.take()
        p.take("->")
        b = check_depth(p.need_bool(p.boolean()), err)
        p.take("WITHIN")
        kind, val, col = p.peek()
        if kind != "num":
            raise err("expected a number of scans or milliseconds after 'within'", col)
        p.take()
        unit = p.take()[1] if p.peek()[0] == "word" else ""
        if unit not in ("SCANS", "SCAN", "MS"):
            raise err("expected 'scans' or 'ms' after the number", p.peek()[2])
        p.done()
        n = p.number(val, col)
        top = MAX_WITHIN_MS if unit == "MS" else MAX_WITHIN_SCANS
        if not 0 <= n <= top:  # 0: in the same scan
            raise err(f"within {val} {unit.lower()}: from 0 to {top}", col)
        return Requirement(name, "response", a, b, n if unit != "MS" else -n, text, p.reads)
    if not p.at("->"):
        p.done()
        return Requirement(name, "always", a, text=text, reads=p.reads)
    p.take("->")
    b = check_depth(p.need_bool(p.boolean()), err)
    p.done()
    return Requirement(name, "always", Node("or", (Node("not", (a,), BOOL, a.col), b),
                                            BOOL, a.col), text=text, reads=p.reads)


def load_spec(path: Path | None, exprs: list[str], profile: SymbolTable | Profile) -> Spec:
    """The requirements of a file and of `--require-expr` texts; `profile`: the
    configuration's symbol table (names and addresses), or a bare profile."""
    table = names(profile)
    problems: list[Diagnostic] = []
    reqs: list[Requirement] = []
    assumptions: list[Node] = []
    host: list[Ref] = []
    reads: list[Ref] = []
    data: dict[str, Any] = {}
    where = _Where("", "")
    if path is not None:
        try:
            text = decode_text(read_bytes(path, MAX_REQUIREMENTS_BYTES, "the file"),
                               "the file")
            check_toml(text)
        except OSError as e:
            raise VerifyError(Diagnostic(f"cannot read the requirements: {e.strerror}",
                                         str(path), code=Code.CANNOT_READ)) from None
        except BoundsError as e:
            raise VerifyError(Diagnostic(e.message, str(path), e.line, e.col,
                                         code=Code.SYNTAX)) from None
        if not text.strip():
            raise VerifyError(Diagnostic("the file is empty: no [[requirement]]", str(path),
                                         expected='[[requirement]] with check = "..."',
                                         code=Code.SYNTAX))
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            m = re.search(r"line (\d+), column (\d+)", str(e))
            ln, col = (int(m[1]), int(m[2])) if m else (0, 0)
            raise VerifyError(Diagnostic(f"not valid TOML: {e}", str(path), ln, col,
                                         code=Code.SYNTAX)) from None
        where = _Where(str(path), text)
    file = str(path) if path is not None else "--require-expr"

    def parse_one(s: Any, what: str, fn: Any) -> Any:
        if not isinstance(s, str):
            problems.append(Diagnostic(f"{what}: a string expected, got {s!r}"[:200], file,
                                       *_key(where, what.rsplit(".", 1)[-1]),
                                       code=Code.TYPE))
            return None
        # an expression of the command line is line 1 of its own
        src, (line, col0) = (what, (1, 1)) if what == EXPR_ARG else (file, where.find(s))
        shown = s if len(s) <= SHOWN else s[:SHOWN] + "..."

        def err(msg: str, col: int, code: Code | None = None) -> VerifyError:
            code = code or (Code.ADDRESS if "address" in msg else Code.SYMBOL if "symbol"
                            in msg else Code.TYPE if "mismatch" in msg else Code.SYNTAX)
            return VerifyError(Diagnostic(msg, src, line, col0 + col - 1 if line else col,
                                          shown, "", code))
        try:
            return fn(s, err)
        except VerifyError as e:
            problems.extend(e.diagnostics)
            return None

    unknown = set(data) - set(TABLES)
    for k in sorted(unknown):
        problems.append(Diagnostic(f"unknown table [{k}]", file, *_key(where, k),
                                   expected="[environment], [[requirement]]", code=Code.SYNTAX))
    env = data.get("environment", {})
    if not isinstance(env, dict):
        problems.append(Diagnostic("environment: a table expected, got "
                                   f"{type(env).__name__} {env!r}"[:200], file,
                                   *_key(where, "environment"),
                                   expected="[environment] with host, free, assume",
                                   code=Code.TYPE))
        env = {}
    for k in sorted(set(env) - set(ENVIRONMENT_KEYS)):
        problems.append(Diagnostic(f"unknown key environment.{k}", file, *_key(where, k),
                                   expected=", ".join(ENVIRONMENT_KEYS), code=Code.SYNTAX))
    for k in ("host", "free", "held", "assume"):
        if k in env and not isinstance(env[k], list):
            problems.append(Diagnostic(f"environment.{k}: a list of strings expected, got "
                                       f"{type(env[k]).__name__} {env[k]!r}"[:200], file,
                                       *_key(where, k), expected=f'{k} = ["..."]',
                                       code=Code.TYPE))
            env = {**env, k: []}
    periods = None
    if "scan_period" in env:
        try:
            periods = parse_periods(env["scan_period"])
        except ValueError as e:
            problems.append(Diagnostic(f"environment.scan_period: {e}", file,
                                       *_key(where, "scan_period"), code=Code.TYPE))
    free: list[tuple[Ref, Diagnostic]] = []
    held: list[Ref] = []
    for key in ("host", "free", "held"):
        for s in env.get(key, []):
            def env_refs(s: str, err: Any, key: str = key) -> list[Ref]:
                try:
                    refs = expand(table.address_of(s), table.profile)
                except AddressError as e:
                    raise err(f"unknown address: {e}", 1) from None
                kinds = {"host": ("MW", "MD"), "held": ("MW", "MD", "M")}.get(
                    key, ("MW", "MD", "M", "Q", "I"))
                if any(r.kind not in kinds for r in refs):
                    raise err(f"{s}: {key} objects are " + {
                        "host": "%MW / %MD words", "held": "%M, %MW, %MD"}.get(
                        key, "%M, %MW, %MD (%I are free anyway)"), 1)
                return [Ref("MW", r.index + k) if r.kind in ("MW", "MD") else r
                        for r in refs for k in range(2 if r.kind == "MD" else 1)]
            refs = parse_one(s, f"environment.{key}", env_refs) or []
            if key == "host":
                host += refs
            elif key == "held":
                held += refs
            else:
                line, col = where.find(s)
                free += [(r, Diagnostic(f"free input {r} is written by the program", file,
                                        line, col, s, "'host' for words both a host and "
                                        "the program write (a handshake)", Code.READ_ONLY))
                         for r in refs]
    for s in env.get("assume", []):
        def assumption(s: str, err: Any) -> Node:
            p = Parser(s, profile, err)
            n = check_depth(p.need_bool(p.boolean()), err)
            p.done()
            reads.extend(p.reads)
            return n
        n = parse_one(s, "environment.assume", assumption)
        if n is not None:
            assumptions.append(n)
    items = data.get("requirement", [])
    if not isinstance(items, list):
        problems.append(Diagnostic("requirement: an array of tables expected ([[requirement]])"
                                   f", got {type(items).__name__}", file,
                                   *_key(where, "requirement"), code=Code.TYPE))
        items = []
    for i, item in enumerate(items):
        if not isinstance(item, dict) or "check" not in item:
            problems.append(Diagnostic(f"requirement {i + 1}: no 'check' key", file,
                                       *_nth_table(where, i), code=Code.SYNTAX))
            continue
        for k in sorted(set(item) - set(REQUIREMENT_KEYS)):
            problems.append(Diagnostic(f"requirement {i + 1}: unknown key {k}", file,
                                       *_key(where, k), expected=", ".join(REQUIREMENT_KEYS),
                                       code=Code.SYNTAX))
        if not isinstance(item.get("name", ""), str):
            problems.append(Diagnostic(f"requirement {i + 1}: name must be a string", file,
                                       *_key(where, "name"), code=Code.TYPE))
        name = str(item.get("name", item["check"]))
        r = parse_one(item["check"], "check", lambda s, err, n=name: parse_check(
            s, n, profile, err))
        if r is not None:
            reqs.append(r)
    for s in exprs:
        r = parse_one(s, EXPR_ARG, lambda s, err: parse_check(s, s, profile, err))
        if r is not None:
            reqs.append(r)
    if not reqs and not problems:
        problems.append(Diagnostic("no requirement to check", file,
                                   expected='[[requirement]] with check = "..."',
                                   code=Code.SYNTAX))
    if problems:
        raise VerifyError(problems)
    for r in reqs:
        reads += r.reads
    if periods is not None:
        for r in reqs:
            if r.kind == "response" and r.within < 0:
                problems.append(Diagnostic(
                    f"{r.name}: 'within ... ms' needs a fixed scan period", file,
                    *where.find(r.text), expected="'within N scans'", code=Code.TYPE))
    if problems:
        raise VerifyError(problems)
    return Spec(reqs, assumptions, host, reads, free, periods, held)


def parse_periods(value: Any) -> tuple[int, int]:
    """["10ms", "1s"] (or "10ms:1s") -> (10000, 1000000) us: any period from the shortest
    to the longest, in steps of the shortest, may occur in each scan."""
    from softplc.config import _parse_duration
    if isinstance(value, str):
        value = value.split(":")
    if not isinstance(value, list) or len(value) != 2:
        raise ValueError('expected ["SHORTEST", "LONGEST"], e.g. ["10ms", "1s"]')
    lo, hi = (round(_parse_duration(v) * 1e6) for v in value)
    if not 0 < lo <= hi <= 60_000_000 or hi % lo:
        raise ValueError("0 < shortest <= longest <= 1min, the longest a multiple of the "
                         "shortest")
    return lo, hi


def _nth_table(where: _Where, i: int) -> tuple[int, int]:
    """line:col of the `i`-th [[requirement]] header."""
    headers = [n for n, ln in enumerate(where.lines, 1) if ln.strip().startswith(
        "[[requirement]]")]
    return (headers[i], 1) if i < len(headers) else (0, 0)


def _key(where: _Where, key: str) -> tuple[int, int]:
    for i, ln in enumerate(where.lines):
        j = ln.find(key)
        if j >= 0 and "=" in ln[j:]:
            return i + 1, j + 1
    return 0, 0


INDEXED_WORDS = "%MW[]"  # the model's key of the %MW words when the program indexes them


def check_environment(spec: Spec, written: dict[str, Any], program_file: str) -> None:
    """A free input the program writes is an error (with where the program writes it)."""
    bad = []
    indexed = written.get(INDEXED_WORDS)  # `%MWi[%MWj] := ...`: any word may be the one
    for ref, d in spec.free:
        pos = written.get(str(ref))
        if pos is None and indexed is not None and ref.kind in ("MW", "MD"):
            pos = indexed
            d = Diagnostic(f"{d.message}: the program writes %MW words through an index, "
                           "which may reach it", d.file, d.line, d.column, d.text,
                           d.expected, d.code)
        if pos is not None:
            bad.append(Diagnostic(f"{d.message} (at {program_file}:{pos.line}:{pos.column})",
                                  d.file, d.line, d.column, d.text, d.expected, d.code))
    if bad:
        raise VerifyError(bad)
