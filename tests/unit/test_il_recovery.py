"""Syntax error recovery, diagnostic codes, deep nesting, and a program mutation fuzzer.

Recovery must not re-parse the whole file per bad line: the tests count grammar runs (the
time itself is measured by `tools/bench.py --sections parse`)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
from fuzz_budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from input_fuzz import mutate_tokens

from softplc import PLC
from softplc.errors import Code, ParseError, ProgramError, SoftPLCError
from softplc.il import parser as P
from softplc.il.parser import MAX_EXPR_DEPTH, parse

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = {p.name: p.read_text() for p in sorted((ROOT / "ladder_programs").glob("*.il"))}
# each program's configuration: the .toml of the same name (the seed runs on the table's)
CONFIGS = {name: name.replace("_seed", "").replace(".il", ".toml") for name in PROGRAMS}


class CountingLark:
    """Wraps the grammar to count how often it runs."""

    def __init__(self, lark):
        self.lark, self.parses = lark, 0

    def parse(self, text):
        self.parses += 1
        return self.lark.parse(text)

    def __getattr__(self, name):  # the rest of Lark's interface (e.g. get_terminal) as is
        return getattr(self.lark, name)


@pytest.fixture
def counted(monkeypatch):
    counter = CountingLark(P._lark())
    monkeypatch.setattr(P, "_lark", lambda: counter)
    return counter


def big_program(rungs: int) -> list[str]:
    lines = []
    for k in range(rungs):
        lines += [f"(* rung {k} *)", f"LD %M{k % 200}", f"AND %I0.{k % 12}", f"ST %Q0.{k % 10}"]
    return lines


def test_recovery_costs_a_bounded_number_of_parses(counted):
    lines = big_program(750)  # 3,000 lines (tools/bench_parse.py times 6,000)
    clean = "\n".join(lines) + "\n"
    parse(clean)
    clean_parses, counted.parses = counted.parses, 0
    rnd = random.Random(7)
    bad_lines = sorted(rnd.sample(range(len(lines)), 60))
    for n in bad_lines:
        lines[n] = "LD %M1 garbage ]]"
    with pytest.raises(ParseError) as e:
        parse("\n".join(lines) + "\n")
    assert [d.line for d in e.value.diagnostics] == [n + 1 for n in bad_lines]
    assert all(d.code == Code.SYNTAX for d in e.value.diagnostics)
    # each bad line: the failing run plus one run of the lines before it in its chunk
    assert counted.parses <= clean_parses + 2 * len(bad_lines)
    # what parsed is kept: every good instruction is in the partial program
    partial = e.value.program
    n_instr = sum(len(r.instructions) for r in partial.rungs)
    n_good = sum(1 for k, ln in enumerate(lines) if not ln.startswith("(*")
                 and k not in bad_lines)
    assert n_instr == n_good


def test_a_comment_spanning_many_lines_crosses_chunk_boundaries():
    body = "\n".join(f"   line {k} of the comment" for k in range(3 * P.CHUNK_LINES))
    text = f"LD %M0\nST %Q0.0\n(* Long title\n{body}\n*)\nLD %M1\nST %Q0.1\nBAD LINE\nLD %M2\n"
    with pytest.raises(ParseError) as e:
        parse(text)
    (d,) = e.value.diagnostics
    assert d.line == text.splitlines().index("BAD LINE") + 1
    rungs = e.value.program.rungs
    assert rungs[1].title.startswith("Long title") and rungs[1].first_line == d.line - 2


def test_messages_do_not_decide_which_errors_are_shown():
    """A syntax error on an opening line hides the structural errors it causes; the
    filter goes by diagnostic codes."""
    src = "LD %M0\nAND( %M1 %%bad\nOR %M2\n)\nST %Q0.0\n"
    with pytest.raises(ProgramError) as e:
        PLC.from_source(src)
    assert [(d.line, d.code) for d in e.value.diagnostics] == [(2, Code.SYNTAX)]


@pytest.mark.parametrize("src, code", [
    ("ST %Q0.0\n", Code.NEEDS_LOAD),
    ("LD %M0\n)\nST %Q0.0\n", Code.UNMATCHED_CLOSE),
    ("LD %M0\nMPP\nST %Q0.0\n", Code.NO_MPS),
    ("LD %M0\nAND( %M1\nST %Q0.0\n", Code.NOT_CLOSED),
    ("LD %M0\nJMP %L3\n", Code.LABEL),
    ("LD %M0\nSR4\n", Code.SUBROUTINE),
    ("LD %M0\nST %I0.0\n", Code.READ_ONLY),
    ("LD 1\n[ %MW0 := %MF2 ]\n", Code.TYPE),
    ("LD %M999\nST %Q0.0\n", Code.ADDRESS),
    ("FOO %M0\n", Code.UNKNOWN_INSTRUCTION),
    ("LD %TM0.Q\nST %Q0.0\n", Code.BLOCK),
])
def test_each_kind_of_problem_has_its_code(src, code):
    with pytest.raises(ProgramError) as e:
        PLC.from_source(src)
    assert code in {d.code for d in e.value.diagnostics}, e.value


# ---- deep nesting (issue 9, point 8) ----------------------------------------------------------
def nested_sum(depth: int) -> str:
    return "(" * depth + "%MW1" + " + 1)" * depth


@pytest.mark.parametrize("expr", [
    lambda n: nested_sum(n),
    lambda n: "%MW1" + " + 1" * n,
    lambda n: "ABS( " * n + "%MW1" + " )" * n,
    lambda n: "- " * (n - 1) + "%MW1",
])
def test_nesting_up_to_the_limit_runs(expr):
    plc = PLC.from_source(f"LD 1\n[ %MW0 := {expr(MAX_EXPR_DEPTH)} ]\n")
    plc["%MW1"] = 3
    plc.scan()
    assert plc.state == "RUN"


@pytest.mark.parametrize("depth", [MAX_EXPR_DEPTH + 1, 300, 3000])
def test_deeper_nesting_is_a_clear_error_with_the_line(depth):
    src = f"LD 1\n[ %MW2 := 1 ]\n[ %MW0 := {nested_sum(depth)} ]\nST %Q0.0\n"
    with pytest.raises(ParseError) as e:
        PLC.from_source(src)
    (d,) = e.value.diagnostics
    assert d.line == 3 and d.code == Code.NESTING and f"at most {MAX_EXPR_DEPTH}" in str(d)


def test_deep_nesting_in_a_comparison_is_a_clear_error():
    with pytest.raises(ParseError) as e:
        PLC.from_source(f"LD [ {nested_sum(500)} > 0 ]\nST %Q0.0\n")
    assert e.value.diagnostics[0].code == Code.NESTING


def test_nested_sum_value():
    plc = PLC.from_source(f"LD 1\n[ %MW0 := {nested_sum(MAX_EXPR_DEPTH)} ]\n")
    plc["%MW1"] = 3
    plc.scan()
    assert plc["%MW0"] == 3 + MAX_EXPR_DEPTH


# ---- program mutation fuzzer --------------------------------------------------------------------
REPLACEMENTS = ["(", ")", "[", "]", ":=", "%MW0", "%MF2", "%M0", "%TM0", "%Q0.0", "%I0.1", "%X3",
                "%L1", "LD", "AND(", "ST", "BLK", "END_BLK", "OUT_BLK", "JMPC", "SR9", "=*=",
                "#", "65536", "-1", "1.5E40", "#FFFF", "SQRT(", "+", "/", "", "((((((((", "%C99",
                "%MW99999", "(*", "*)", ";", "%S", "\t"]


def mutate(text: str, data) -> str:
    return mutate_tokens(text, data, REPLACEMENTS)


@settings(max_examples=examples(40), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(sorted(PROGRAMS)), st.data())
def test_mutated_programs_compile_or_fail_clearly(name, data):
    text = mutate(PROGRAMS[name], data)
    config = ROOT / "ladder_programs" / CONFIGS[name]
    try:
        plc = PLC.from_source(text, config, file=name, devices=False)
    except SoftPLCError as e:
        assert str(e)  # a clear message, not another exception
        if isinstance(e, ProgramError):
            assert e.diagnostics and all(d.message and d.line >= 0 for d in e.diagnostics)
        return
    plc.scan(2)
    assert plc.state in ("RUN", "STOP", "HALT")
