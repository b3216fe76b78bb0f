"""Bad programs: every problem is a ProgramError (ParseError / CompileError) carrying
file, line, column, the offending text and what was expected, never a Python traceback;
and every problem of a file is reported at once, not only the first.
"""

from __future__ import annotations

import re

import pytest

from softplc import PLC
from softplc.errors import CompileError, ParseError, ProgramError

TIMER_CFG = {"timers": {"%TM0": {"type": "TON", "base": "1s", "preset": 1}}}

# name -> (source, line of the problem, fragment of the offending text, message pattern)
CASES: dict[str, tuple[str, int, str, str]] = {
    "unknown object": ("LD %M0\nST %FOO1\n", 2, "%FOO1", r"malformed|unknown"),
    "unknown object kind in expression": ("LD 1\n[ %MW0 := %ZW3 ]\n", 2, "%ZW3",
                                          r"malformed|unknown"),
    "bit beyond the profile": ("LD %M256\nST %Q0.0\n", 1, "%M256", r"beyond"),
    "word beyond the profile": ("LD 1\n[ %MW3000 := 1 ]\n", 2, "%MW3000", r"beyond"),
    "float beyond the profile": ("LD 1\n[ %MF2999 := 1.0 ]\n", 2, "%MF2999", r"beyond"),
    "input beyond the base": ("LD %I0.24\nST %Q0.0\n", 1, "%I0.24", r"24 inputs"),
    "output beyond the base": ("LD 1\nST %Q0.16\n", 2, "%Q0.16", r"16 outputs"),
    "module beyond the slots": ("LD %I8.0\nST %Q0.0\n", 1, "%I8.0", r"slot|module"),
    "timer beyond the profile": ("LD 1\nIN %TM128\n", 2, "%TM128", r"beyond"),
    "label beyond the profile": ("LD 1\nJMP %L64\n%L64:\nLD 1\nST %M0\n", 3, "%L64",
                                 r"beyond"),
    "write to an input": ("LD 1\nST %I0.1\n", 2, "%I0.1", r"input"),
    "set an input": ("LD 1\nS %I0.1\n", 2, "%I0.1", r"input"),
    "write to a constant word": ("LD 1\n[ %KW1 := 3 ]\n", 2, "%KW1", r"constant"),
    "write to a constant float": ("LD 1\n[ %KF2 := 3.0 ]\n", 2, "%KF2", r"constant"),
    "write to a timer value": ("LD 1\n[ %TM0.V := 3 ]\n", 2, "%TM0.V", r"read-only"),
    "write to a counter value": ("LD 1\n[ %C0.V := 3 ]\n", 2, "%C0.V", r"read-only"),
    "store to a timer output": ("LD 1\nST %TM0.Q\n", 2, "%TM0.Q", r"read-only|cannot"),
    "float into a word": ("LD 1\n[ %MW0 := %MF2 ]\n", 2, "%MW0", r"conversion"),
    "word into a float": ("LD 1\n[ %MF0 := %MW2 ]\n", 2, "%MF0", r"conversion"),
    "float plus word": ("LD 1\n[ %MF0 := %MF2 + INT_TO_REAL(%MW4) * %MW5 ]\n", 2, "%MW5",
                        r"mixes|conversion"),
    "word compared with float": ("LD [ %MW0 > %MF2 ]\nST %M0\n", 1, "%MF2",
                                 r"mixes|conversion"),
    "float function on a word": ("LD 1\n[ %MF0 := SIN( %MW2 ) ]\n", 2, "SIN",
                                 r"takes a float"),
    "REM on floats": ("LD 1\n[ %MF0 := %MF2 REM %MF4 ]\n", 2, "REM", r"REM"),
    "word logic on floats": ("LD 1\n[ %MF0 := %MF2 AND %MF4 ]\n", 2, "AND", r"words"),
    "unknown function": ("LD 1\n[ %MW0 := FOO( %MW1 ) ]\n", 2, "FOO", r"unknown function"),
    "wrong argument count": ("LD 1\n[ %MW0 := SHL( %MW1 ) ]\n", 2, "SHL", r"argument"),
    "constant too big for a word": ("LD 1\n[ %MW0 := 40000 ]\n", 2, "40000",
                                    r"does not fit"),
    "bit used as a word": ("LD 1\n[ %MW0 := %M3 ]\n", 2, "%M3", r"bit"),
    "word used as a bit": ("LD %MW3\nST %M0\n", 1, "%MW3", r"not a bit"),
    "boolean constant other than 0/1": ("LD 2\nST %M0\n", 1, "2", r"0 or 1"),
    "unknown label": ("LD 1\nJMPC %L3\n", 2, "%L3", r"unknown label"),
    "duplicate label": ("%L1:\nLD 1\nST %M0\n%L1:\nLD 1\nST %M1\n", 4, "%L1",
                        r"twice|duplicate"),
    "jump out of a subroutine": ("LD 1\nSR1\n%L2:\nLD 1\nST %M0\nEND\nSR1:\nLD 1\n"
                                 "JMP %L2\nRET\n", 9, "%L2", r"cannot leave|subroutine"),
    "missing subroutine": ("LD 1\nSR4\n", 2, "SR4", r"not defined"),
    "RET in the main program": ("LD 1\nRET\n", 2, "RET", r"outside a subroutine"),
    "unclosed parenthesis": ("LD %M0\nAND( %M1\nST %M2\n", 2, "AND(", r"not closed"),
    "unopened parenthesis": ("LD %M0\n)\nST %M2\n", 2, ")", r"without a matching"),
    "parentheses nested too deep": (
        "LD %M0\n" + "AND( %M1\n" * 9 + ")\n" * 9 + "ST %M2\n", 10, "AND(", r"deeper"),
    "MPP without MPS": ("LD %M0\nMPP\nST %M2\n", 2, "MPP", r"without a preceding MPS"),
    "MRD without MPS": ("LD %M0\nMRD\nST %M2\n", 2, "MRD", r"without a preceding MPS"),
    "stack too deep": ("LD %M0\n" + "MPS\n" * 9 + "ST %M1\n" + "MPP\n" * 9, 10, "MPS",
                       r"deeper"),
    "OUT_BLK outside a block": ("LD %M0\nOUT_BLK\nST %M2\n", 2, "OUT_BLK", r"outside"),
    "END_BLK without BLK": ("LD %M0\nST %M1\nEND_BLK\n", 3, "END_BLK", r"without BLK"),
    "BLK of a word": ("BLK %MW0\nLD 1\nEND_BLK\n", 1, "%MW0", r"function block"),
    "block output outside a block": ("LD Q\nST %M0\n", 1, "Q", r"outside"),
    "wrong input pin": ("BLK %C0\nLD 1\nIN\nEND_BLK\n", 3, "IN", r"no input"),
    "input pin without a block": ("LD 1\nCU\n", 2, "CU", r"outside a BLK"),
    "unconfigured timer": ("LD %M0\nIN %TM0\n", 2, "%TM0", r"not configured"),
    "unconfigured drum": ("LD %M0\nU %DR0\n", 2, "%DR0", r"not configured"),
    "syntax: store without operand": ("LD %M0\nST\n", 2, "ST", r"syntax"),
    "syntax: unknown instruction": ("LDX %M0\n", 1, "LDX", r"unknown instruction|syntax"),
    "syntax: empty assignment": ("LD 1\n[ %MW0 := ]\n", 2, "]", r"syntax"),
    "syntax: unclosed operation block": ("LD 1\n[ %MW0 := 1\n", 2, "%MW0", r"syntax"),
    "syntax: bad comparison": ("LD [ %MW0 >> 1 ]\nST %M0\n", 1, ">", r"syntax"),
}


def errors_of(src: str, config=None) -> ProgramError:
    with pytest.raises(ProgramError) as info:
        PLC.from_source(src, config, file="prog.il")
    return info.value


@pytest.mark.parametrize("name", list(CASES))
def test_error_has_file_line_column_and_text(name):
    src, line, fragment, pattern = CASES[name]
    err = errors_of(src)
    assert isinstance(err, (ParseError, CompileError))
    d = next((d for d in err.diagnostics if d.line == line), None)
    assert d is not None, [str(d) for d in err.diagnostics]
    assert d.file == "prog.il"
    assert d.column >= 1
    assert fragment.lower() in d.text.lower(), d
    assert re.search(pattern, d.message, re.I), d.message
    assert str(d).startswith(f"prog.il:{line}:{d.column}: ")
    # the first-problem accessors of the exception
    first = err.diagnostics[0]
    assert (err.file, err.line, err.column, err.text, err.expected) == (
        first.file, first.line, first.column, first.text, first.expected)


@pytest.mark.parametrize("name", [n for n in CASES if n.startswith("syntax")])
def test_syntax_errors_say_what_was_expected(name):
    src, line, _, _ = CASES[name]
    err = errors_of(src)
    assert isinstance(err, ParseError)
    d = next(d for d in err.diagnostics if d.line == line)
    assert d.expected, d


def test_expected_of_a_missing_operand_names_an_address():
    d = errors_of("LD %M0\nST\n").diagnostics[0]
    assert "address" in d.expected


def test_semantic_errors_say_what_was_expected():
    missing = []
    for name, (src, line, _, _) in CASES.items():
        if name.startswith("syntax"):
            continue
        d = next(d for d in errors_of(src).diagnostics if d.line == line)
        if not d.expected:
            missing.append(name)
    assert not missing, missing


def test_one_problem_is_one_diagnostic():
    """No follow-up noise: an address beyond the profile is reported once."""
    for src in ("LD 1\n[ %MW3000 := 1 ]\n", "LD %M256\nST %Q0.0\n", "LD 1\nST %I0.1\n",
                "LD 1\nJMPC %L3\n", "LD %M0\nMPP\nST %M2\n",
                "LD 1\n[ %MF0 := %MF2 + %MW4 ]\n", "LD 1\n[ %MF0 := FOO( %MF2 ) ]\n",
                "LD 1\n[ %MF0 := %MF2 AND %MF4 ]\n", "%L1:\nLD 1\nST %M0\n%L1:\nLD 1\n"):
        assert len(errors_of(src).diagnostics) == 1, src


def test_every_error_of_a_file_is_reported():
    src = """
LD    %M0
ST    %I0.0
LD    %M999
ST    %Q0.0
LD    1
[ %MW0 := %MF2 ]
LDX   %M1
JMP   %L9
LD    %M0
AND(  %M1
ST    %M2
LD    1
[ %KW0 := 1 ]
LD    1
SR7
LD    1
[ %MW1 := %MW2 + ]
LD    %M0
MPP
ST    %M3
LD    %M0
IN    %TM3
"""
    err = errors_of(src)
    lines = [d.line for d in err.diagnostics]
    assert lines == sorted(lines)
    for expected_line in (3, 4, 7, 8, 9, 11, 14, 16, 18, 20, 23):
        assert expected_line in lines, (expected_line, [str(d) for d in err.diagnostics])
    # all of them in the message too, one a line
    assert len(str(err).splitlines()) == len(err.diagnostics)


def test_every_syntax_error_is_reported():
    src = "LD %M0\nST\nLD 1\n[ %MW0 := ]\nFOO BAR\nLD %M1\nST %Q0.0\nAND(\n"
    err = errors_of(src)
    assert isinstance(err, ParseError)
    assert {2, 4, 5} <= {d.line for d in err.diagnostics}


def test_errors_name_the_file(tmp_path):
    path = tmp_path / "bad.il"
    path.write_text("LD %M0\nST %I0.0\n")
    with pytest.raises(CompileError) as info:
        PLC.from_file(path)
    assert info.value.file == str(path) and info.value.line == 2


def test_missing_program_file_is_a_program_error(tmp_path):
    with pytest.raises(ProgramError, match="cannot read"):
        PLC.from_file(tmp_path / "nope.il")


def test_configured_timer_is_not_an_error():
    plc = PLC.from_source("LD %M0\nIN %TM0\n", TIMER_CFG)
    plc.scan()
    assert plc.state == "RUN"


@pytest.mark.parametrize("src", [
    "", "\n\n", "(* only a comment *)\n", "END\n",
])
def test_empty_programs_are_valid(src):
    plc = PLC.from_source(src)
    plc.scan()
    assert plc.scan_count == 1


@pytest.mark.parametrize("garbage", [
    "%", "[", "]", "(*", "LD [", "LD [ %MW0 >", "[ %MW0 := SHL( ]", "#", "=*=", "-*- x",
    "LD %MW0:X16", "LD %MW0[%M1]", "ST %I0.0.1", "BLK", "SR", "SR99999:", "%L:",
    "LD 1\nJMP %L99999", "LD\tÄ", "LD 1\n[ %MW0 := 1.0E99999 ]", "LD 1\n[ %MD0 := 99999999999 ]",
    "LD 1\n[ %MW0 := #FFFFF ]", "\x00", "LD 1 2 3",
])
def test_garbage_never_gives_a_traceback(garbage):
    try:
        plc = PLC.from_source(garbage + "\n")
    except ProgramError as e:
        assert e.diagnostics and all(d.line >= 0 for d in e.diagnostics)
    else:
        plc.scan()


@pytest.mark.parametrize("src,fragment", [
    ("LD 1\nST %Q2.0\n", "%Q2.0"),  # no module in slot 2
    ("LD 1\nST %Q1.8\n", "%Q1.8"),  # the TM2DDO8TT has 8 outputs
    ("LD %I1.0\nST %Q0.0\n", "%I1.0"),  # it has no inputs
])
def test_io_beyond_the_configured_modules(src, fragment):
    with pytest.raises(CompileError) as info:
        PLC.from_source(src, {"modules": {"1": "TM2DDO8TT"}}, file="prog.il")
    d = info.value.diagnostics[0]
    assert d.text == fragment and d.line >= 1 and d.column >= 1


def test_configured_module_outputs_are_accepted():
    plc = PLC.from_source("LD 1\nST %Q1.7\n", {"modules": {"1": "TM2DDO8TT"}})
    plc.scan()
    assert plc["%Q1.7"]


@pytest.mark.parametrize("src, lines", [
    ("LDX   %M0\nST    %Q0.0\n", [1]),                      # the bad line was the load
    ("LD    %M1\nAND(  %M2\n)x\nST    %Q0.1\n", [3]),         # the bad line was the ')'
    ("LD    1\n[ %MW1 := ]\nLD    %M0\nMPP\nST    %M3\n", [2, 4]),  # MPP error is real
])
def test_a_skipped_line_causes_no_follow_up_errors(src, lines):
    assert [d.line for d in errors_of(src).diagnostics] == lines


@pytest.mark.parametrize("source, suggestion", [
    ("CUU %C0\n", "(did you mean CU?)"),
    ("LDD %I0.0\nST %Q0.0\n", "(did you mean LD, "),
    ("ld %I0.0\nstt %Q0.0\n", "(did you mean ST or STN?)"),
])
def test_unknown_mnemonic_gets_a_did_you_mean(source: str, suggestion: str):
    with pytest.raises(ParseError) as e:
        PLC.from_source(source)
    (d,) = e.value.diagnostics
    assert suggestion in d.message
    # the list of what is expected is whole: it names the last mnemonics of the grammar
    assert d.expected.startswith("an instruction: LD LDN") and d.expected.endswith("#D POST")
    assert "EXCHn" in d.expected and "RETCN" in d.expected and not d.expected.endswith(")")


def test_unknown_word_far_from_every_mnemonic_gets_no_guess():
    with pytest.raises(ParseError) as e:
        PLC.from_source("WHATEVER %M0\n")
    assert "did you mean" not in e.value.diagnostics[0].message
