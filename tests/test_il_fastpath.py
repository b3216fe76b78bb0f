"""The parser's fast path (issue 26): lines like `LD %M0`, `ST %Q0.1`, `S %M5` and `)` are
parsed without Lark. Whatever the program, the result must be exactly what Lark's path
gives: the same rungs, nodes, positions and diagnostics."""

from __future__ import annotations

from pathlib import Path

import pytest

from softplc.errors import ParseError
from softplc.il import ast as A
from softplc.il import parser

ROOT = Path(__file__).resolve().parents[1]
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
"""


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


def test_fast_path_with_comments_errors_and_cases(monkeypatch: pytest.MonkeyPatch) -> None:
    fast, slow = _parse(TRICKY, True, monkeypatch), _parse(TRICKY, False, monkeypatch)
    assert fast == slow
    program, diags = fast
    # the indexed input, the out-of-range address and the garbage line, once each
    assert sorted(d.line for d in diags) == [14, 16, 39]
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
    parser.parse("LD %M0\n[ %MW1 := 2 ]\nST %Q0.0\n")
    assert calls == ["\n[ %MW1 := 2 ]\n\n"]  # the others blanked: line numbers hold
