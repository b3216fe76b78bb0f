"""A realistic TwidoSuite "List" export: SECTION headers, (*SECTTITLE:*) and
(*SECTCOMMENT:*) comments, padded opcodes, trailing comments, subroutines SRn: after END,
labels with backward jumps, and %S17 carry loops like the sample in docs/twido.md
(#instruction-list) [sure].
It parses, keeps its structure, prints back to an equivalent program, and computes.
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.il.parser import parse
from softplc.il.printer import format_program

EXPORT = """\
SECTION     0
(*SECTTITLE:Arranque*)
(*SECTCOMMENT:*)
LD    %S13
[ %MW200 := 0 ]
[ %MD202 := 0 ]
LD    %S13
R     %M10
LDR   %M11                    (* pedido de calculo *)
S     %M10
LD    %M10
SR1
SR2
LD    %M10
[ INC %MW200 ]
R     %M10
SECTION     1
(*SECTTITLE:Salidas*)
LD    [ %MW200 > 0 ]
ST    %Q0.0
LD    [ %MW120 = 0 ]
ST    %Q0.1
END
SR1:
(*SECTTITLE:Producto por desplazamiento*)
LD    1
[ %MD110 := 0 ]
[ %MD112 := 0 ]
[ %MW112 := %MW100 ]
[ %MW104 := %MW101 ]
[ %MW105 := 16 ]
%L26:
LD    1
[ %MW104 := SHR( %MW104, 1 ) ]
LD    %S17                    (* el bit que salio *)
[ %MD110 := %MD110 + %MD112 ]
LD    1
[ %MD112 := SHL( %MD112, 1 ) ]
[ %MW105 := %MW105 - 1 ]
LD    [ %MW105 > 0 ]
JMPC  %L26
RET
SR2:
(*SECTTITLE:Cuenta de bits*)
LD    1
[ %MD990 := %MD984 ]
[ %MW120 := 0 ]
[ %MW993 := 32 ]
%L27:
LD    1
ANDN  %MW991:X15
JMPC  %L28
LD    1
[ INC %MW120 ]
%L28:
LD    1
[ %MD990 := SHL( %MD990, 1 ) ]
[ %MW993 := %MW993 - 1 ]
LD    [ %MW993 > 0 ]
JMPC  %L27
RET
"""


def run_export(text: str, a: int, b: int, d: int) -> PLC:
    plc = PLC.from_source(text, file="export.txt")
    plc["%MW100"], plc["%MW101"], plc["%MD984"] = a, b, d
    plc.scan()
    plc["%M11"] = 1
    plc.scan()
    plc["%M11"] = 0
    plc.scan()
    return plc


def test_structure_of_the_export():
    prog = parse(EXPORT, "export.txt")
    assert prog.section_titles == {0: "Arranque", 1: "Salidas"}
    assert prog.subroutines == [1, 2]
    main = prog.main
    assert {r.section for r in main} == {0, 1}
    assert [r.section for r in main].index(1) == 5  # five rungs in section 0
    assert len(prog.subroutine(1)) == 5 and prog.subroutine(1)[1].label == 26
    assert [r.label for r in prog.subroutine(2) if r.label is not None] == [27, 28]
    assert main[-1].first_line == EXPORT.splitlines().index("LD    [ %MW120 = 0 ]") + 1


@pytest.mark.parametrize("a,b,d", [
    (0, 0, 0), (3, 5, 1), (1234, 21, -1), (32767, 32767, 0x55555555), (255, 256, 1 << 30),
    (40, 1000, -(2**31)),
])
def test_export_computes(a, b, d):
    plc = run_export(EXPORT, a, b, d)
    assert plc.state == "RUN"
    assert plc["%MD110"] == a * b  # shift-and-add product, carry from SHR into %S17
    assert plc["%MW120"] == bin(d & 0xFFFFFFFF).count("1")  # bits of %MD984
    assert plc["%MW200"] == 1  # one request, one computation
    assert plc["%Q0.0"]
    assert plc["%Q0.1"] == (d == 0)
    assert not plc["%M10"]


def test_export_calculation_only_on_request():
    plc = PLC.from_source(EXPORT)
    plc["%MW100"], plc["%MW101"] = 6, 7
    plc.scan(5)
    assert plc["%MD110"] == 0 and plc["%MW200"] == 0 and not plc["%Q0.0"]


def test_printed_export_parses_back_and_computes_the_same():
    prog = parse(EXPORT)
    printed = format_program(prog)
    again = parse(printed)
    assert [r.instructions for r in again.rungs] == [r.instructions for r in prog.rungs]
    assert again.section_titles == prog.section_titles
    assert again.subroutines == prog.subroutines
    for text in (EXPORT, printed):
        plc = run_export(text, 300, 99, 0xF0F0)
        assert plc["%MD110"] == 29700 and plc["%MW120"] == 8


def test_printer_keeps_constants_as_written():
    """#FFFF is the bit pattern -1 in a word; printed as 65535 it would not compile."""
    src = "LD    1\n[ %MW0 := #FFFF AND %MW1 ]\n[ %MF2 := 1.0E3 ]\n"
    printed = format_program(parse(src))
    plc = PLC.from_source(printed)
    plc["%MW1"] = 0x1234
    plc.scan()
    assert plc["%MW0"] == 0x1234 and plc["%MF2"] == 1000.0


def test_export_with_windows_line_ends_and_tabs():
    text = EXPORT.replace("    ", "\t").replace("\n", "\r\n")
    plc = run_export(text, 12, 12, 7)
    assert plc["%MD110"] == 144 and plc["%MW120"] == 3
