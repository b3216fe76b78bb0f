"""The parser's fast path (issue 26): lines like `LD %M0`, `ST %Q0.1`, `S %M5` and `)` are
parsed without Lark. Whatever the program, the result must be exactly what Lark's path
gives: the same rungs, nodes, positions and diagnostics."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from softplc.errors import ParseError
from softplc.il import ast as A
from softplc.il import parser

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = sorted((ROOT / "ladder_programs").glob("*.il")) + sorted(
    (ROOT / "tests").glob("*.il"))

TRICKY = """\
(* title: LD %M0 in a comment
LD %M1
)
ST %Q0.1 *)
LD %M0
\tand( %I0.1
Orn   %M2 \t
 )
st %Q0.0
LDN %M3 (* trailing comment *)
S %M10
r %M11
LD %MW2:X3
ANDN %I0.1[ %MW5 ]
ST %M20
LD %M9999
ST %M21
%L1: LD %M4
ST %M22
XORN %M5
STN %M23
BLK %TM0
R
IN
OUT_BLK
LD Q
ST %M24
END_BLK
LD [ %MW1 > 3 ]
ST %M25
OR(N %M1
AND(%M2
)
XOR(
LD %M3
)
)
ST %M27
LD %M1 garbage ]]
ST %M26
LD  [ %MW1 >= 3 ]
  [ %MW2 := %MW3+4 ]
ST %M1
andn [%MW1<>%MW2*7]\t
[%MW2:=5]
[ %MW4 := %MW5 - 16#10 ]
[ %MW4 := -3 ]
[ %MW4 := %MW5 + 1 + 2 ]
[ %MW6 := %MW7 REM 3 ]
[ %MW6 := 2.5 ]
[ %MW6 := %MW9999 ]
ST %M2
ORN [ 5 - %MW9 = %MW3 / 2 ]
XOR [ %MW1 > 3 ] (* a comment *)
LDR [ %MW1:X3 < %MW2[%MW3] ]
ST %M3
LD [ %MW1 > 3
ST %M4
"""


def _positions(node: object) -> list[tuple[str, A.Pos]]:
    """Every node's type and position, depth first (equality of nodes ignores them)."""
    out: list[tuple[str, A.Pos]] = []
    if dataclasses.is_dataclass(node) and not isinstance(node, A.Pos):
        for f in dataclasses.fields(node):
            v = getattr(node, f.name)
            if isinstance(v, A.Pos):
                out.append((type(node).__name__, v))
            else:
                out += _positions(v)
    elif isinstance(node, list | tuple):
        for v in node:
            out += _positions(v)
    return out


def _parse(text: str, fast: bool, monkeypatch: pytest.MonkeyPatch
           ) -> tuple[A.Program | None, list]:
    with monkeypatch.context() as m:
        if not fast:
            m.setattr(parser, "_fast_line", lambda: None)
        try:
            return parser.parse(text, "x.il"), []
        except ParseError as e:
            return e.program, e.diagnostics


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.name)
def test_fast_path_gives_lark_ast(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    text = path.read_text(encoding="utf-8-sig")
    fast, slow = _parse(text, True, monkeypatch), _parse(text, False, monkeypatch)
    assert fast == slow
    assert fast[0] is not None and fast[0].rungs
    assert _positions(fast[0].rungs) == _positions(slow[0].rungs)


def test_fast_path_with_comments_errors_and_cases(monkeypatch: pytest.MonkeyPatch) -> None:
    fast, slow = _parse(TRICKY, True, monkeypatch), _parse(TRICKY, False, monkeypatch)
    assert fast == slow
    program, diags = fast
    assert _positions(program.rungs) == _positions(slow[0].rungs)
    # the indexed input, the out-of-range addresses, the garbage line and the unclosed
    # comparison, once each
    assert sorted(d.line for d in diags) == [14, 16, 39, 51, 57]
    instrs = [i for r in program.rungs for i in r.instructions]
    first = instrs[0]  # LD %M0 of line 5: the commented-out lines 1-4 gave nothing
    assert isinstance(first, A.BoolInstr) and first.pos == A.Pos(5, 1, 5, 7)
    assert first.operand.pos == A.Pos(5, 4, 5, 7)
    assert isinstance(instrs[3], A.ParenClose) and instrs[3].pos.line == 8


def test_fast_path_is_used(monkeypatch: pytest.MonkeyPatch) -> None:
    """The simple lines really skip Lark: a chunk of them is never handed to it."""
    calls: list[str] = []
    real = parser._lark()

    class Spy:
        def parse(self, text: str) -> object:
            calls.append(text)
            return real.parse(text)

    monkeypatch.setattr(parser, "_lark", lambda: Spy())
    parser.parse("LD %M0\nAND( %M1\nOR %M2\n)\nST %Q0.0\nS %M3\n")
    assert calls == []
    parser.parse("LD [ %MW1 > %MW2 ]\n[ %MW1 := %MW3 * 2 ]\n[ %MW4 := 7 ]\nST %Q0.0\n")
    assert calls == []
    parser.parse("LD %M0\n[ %MW1 := 2 + 3 * 4 ]\nST %Q0.0\n")
    assert calls == ["\n[ %MW1 := 2 + 3 * 4 ]\n\n"]  # the others blanked: line numbers hold


def test_fast_path_agrees_with_lark_on_random_block_lines(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Comparison and operation blocks made of random pieces, valid or not (spacing,
    case, operands the fast path leaves to Lark): the same AST, positions, diagnostics."""
    import random

    rnd = random.Random(26)
    atoms = ["%MW1", "%MW12", "%MW1:X3", "%MW1[%MW2]", "%KW3", "%MD4", "%MF6", "%M5",
             "%MW9999", "7", "0", "16#1F", "1.5", "-3", "%SW30", "%IW0.1", "x"]
    ops = ["+", "-", "*", "/", "REM", "AND", "+ -"]
    cmps = [">", ">=", "<", "<=", "=", "<>", "=<", "=="]
    sps = ["", " ", "  ", "\t"]

    def expr() -> str:
        e = rnd.choice(atoms)
        if rnd.random() < 0.6:
            e += rnd.choice(sps) + rnd.choice(ops) + rnd.choice(sps) + rnd.choice(atoms)
        return e

    lines = []
    for _ in range(300):
        sp = [rnd.choice(sps) for _ in range(6)]
        if rnd.random() < 0.5:
            kw = rnd.choice(["LD", "ldn", "AND", "ORN", "XOR", "LDR", "OR("])
            lines.append(f"{sp[0]}{kw}{sp[1] or ' '}[{sp[2]}{expr()}{sp[3]}{rnd.choice(cmps)}"
                         f"{sp[4]}{expr()}{sp[5]}]")
        else:
            target = rnd.choice(["%MW3", "%MD8", "%MF10", "%QW0.1", "%MW2:X1", "%M1"])
            lines.append(f"{sp[0]}[{sp[1]}{target}{sp[2]}:={sp[3]}{expr()}{sp[4]}]")
        lines.append("ST %M1")
    text = "\n".join(lines) + "\n"
    fast, slow = _parse(text, True, monkeypatch), _parse(text, False, monkeypatch)
    assert fast == slow
    assert fast[0] is not None
    assert _positions(fast[0].rungs) == _positions(slow[0].rungs)
    taken = sum(1 for ln in lines[::2] if parser._fast_line().pattern.fullmatch(ln))
    assert 30 < taken < 270, taken  # both paths were exercised
