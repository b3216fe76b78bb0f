"""Requirements that name floats (issue 34 item 1): %MF, %KF and their symbols compared as
the engine compares floats (doubles, IEEE's NaN), literals bounded and finite; every
counterexample replayed in the scan engine."""

from __future__ import annotations

from pathlib import Path

import pytest
import z3

from softplc.cli import main
from softplc.errors import Code, VerifyError
from softplc.plc import PLC
from softplc.twido.address import Ref
from softplc.verify.checker import Checker
from softplc.verify.engines import Result, verify
from softplc.verify.model import Model
from softplc.verify.replay import first_failure, read_cex, replay
from softplc.verify.requirements import load_spec

# %MF10 is 150.0 while %I0.0 is on, else 50.0; %MF12 follows it
SPEED = ("LD %I0.0\n[ %MF10 := 150.0 ]\nLDN %I0.0\n[ %MF10 := 50.0 ]\n"
         "LD 1\n[ %MF12 := %MF10 ]\n")
SECONDS = 120  # per requirement: the answers below take a few seconds on an idle machine


def run_all(prog: str, checks: list[str], host: tuple[int, ...] = (),
            config: dict | None = None, watch: tuple[str, ...] = ()) -> list[Result]:
    """Each requirement checked on one model of the program (its facts proven once, as
    `softplc verify` does for a requirement file)."""
    plc = PLC.from_source(prog, config, devices=False)
    spec = load_spec(None, checks, plc.symbols)
    model = Model(plc, spec.reads, [Ref("MW", k) for k in host])
    return [verify(Checker(model, spec, req), 4, 4, SECONDS, list(watch), use_spacer=True)
            for req in spec.requirements]


def run(prog: str, check: str, host: tuple[int, ...] = (), config: dict | None = None,
        watch: tuple[str, ...] = ()) -> Result:
    return run_all(prog, [check], host, config, watch)[0]


def replays(prog: str, check: str, res, config: dict | None = None) -> None:
    """The counterexample is the engine's: same values, broken at its last scan."""
    assert res.status == "VIOLATED", res
    assert replay(PLC.from_source(prog, config, devices=False), res.trace) == []
    scans = [r["inputs"] for r in res.trace]
    assert first_failure(PLC.from_source(prog, config, devices=False), check,
                         scans) == res.depth


def test_a_float_limit_proven_and_violated_with_a_replayed_counterexample():
    res, *proven = run_all(SPEED, [
        "never %MF10 > 100.0",
        "always %MF10 <= 150.0 AND %MF10 >= 50",  # an integer literal takes the float's
        "never %MF10 <> %MF12",                   # type, as in an IL comparison
        "always -%MF10 < -49.5 AND %MF10 * 2.0 - 1.0 < 299.5"], watch=("%MF10",))
    replays(SPEED, "never %MF10 > 100.0", res)
    assert res.depth == 1 and res.trace[0]["inputs"] == {"%I0.0": 1}
    assert res.trace[0]["values"] == {"%MF10": 150.0}
    assert [r.status for r in proven] == ["PROVEN"] * 3, proven


@pytest.mark.parametrize(("prog", "check", "floats"), [
    (SPEED, "always %MF10 <= 150.0 AND %MF10 >= 50", True),  # read and written as floats
    (SPEED, "always %MW13 = %MW11", True),  # the words of %MF12, a float copied
    # the high words of 150.0 and 50.0 as singles (0x4316, 0x4248): a constant stored is
    # its bits (folded when the model is built), no float term is left
    (SPEED, "always %MW11 = 17174 OR %MW11 = 16968", False),
    (SPEED + "LD %I0.1\nST %Q0.0\n", "always %Q0.0 = %I0.1", False),  # floats off its cone
    ("LD %I0.0\nST %Q0.0\n", "always %Q0.0 = %I0.0", False)])
def test_the_float_solver_is_for_cones_with_floats(prog, check, floats):
    """A requirement whose cone has float terms gets the bit-blasting solver for floats
    (`Checker.solver`, docs/decisions/verify-float-solver.md), any other the incremental
    one; the verdict is the same either way (the other tests of this file)."""
    plc = PLC.from_source(prog, None, devices=False)
    spec = load_spec(None, [check], plc.symbols)
    ck = Checker(Model(plc, spec.reads), spec, spec.requirements[0])
    assert ck.floats == floats
    assert isinstance(ck.solver(), z3.Solver)
    assert verify(ck, 2, 2, SECONDS, []).status == "PROVEN"


def test_constants_and_symbols_of_floats():
    config = {"constants": {"%KF2": 50.0}, "symbols": {"SPEED": "%MF10", "LOW": "%KF2"}}
    assert run(SPEED, "always SPEED >= LOW", config=config).status == "PROVEN"
    config["constants"]["%KF2"] = 60.0
    res = run(SPEED, "always %MF10 >= %KF2", config=config)
    replays(SPEED, "always %MF10 >= %KF2", res, config)
    assert res.trace[0]["inputs"] == {"%I0.0": 0}


@pytest.mark.parametrize("check", ["always %MF0 = %MF0", "never %MF0 <> %MF0",
                                   "always %MF0 < 1.0 OR %MF0 >= 1.0"])
def test_nan_is_unordered_as_in_the_engine(check):
    """A host's words may hold a NaN: `=` and every order fail on it, `<>` holds (Python's
    float comparisons, which the compiled program uses); only a NaN breaks these."""
    res = run("LD 1\n", check, host=(0, 1), watch=("%MF0",))
    replays("LD 1\n", check, res)
    assert res.trace[0]["values"] == {"%MF0": "nan"}  # JSON has no NaN


def test_command_line_float_counterexample_round_trips(tmp_path, capsys):
    """The program reads %MF0 (a Modbus host may write its words: free by default)."""
    prog = tmp_path / "p.il"
    prog.write_text("LD [ %MF0 > 0.0 ]\nST %Q0.0\n")
    cfg = tmp_path / "p.toml"
    cfg.write_text('[symbols]\nSETPOINT = "%MF0"\n')
    cex = tmp_path / "cex.json"
    code = main(["verify", str(prog), "--config", str(cfg), "--require-expr",
                 "always SETPOINT = SETPOINT", "--depth", "2", "--timeout", str(SECONDS),
                 "--cex", str(cex)])
    out = capsys.readouterr().out
    assert code == 2, out
    assert "replayed in the scan engine: same values in every scan" in out, out
    data = read_cex(cex)
    assert data["counterexamples"][0]["scans"][0]["values"] == {"%MF0": "nan"}


def spec_error(tmp_path: Path, check: str) -> tuple[int, int, str, Code]:
    p = tmp_path / "req.toml"
    p.write_text(f'[[requirement]]\ncheck = "{check}"\n')
    with pytest.raises(VerifyError) as e:
        load_spec(p, [], PLC.from_source("LD 1\n", devices=False).profile)
    d = e.value.diagnostics[0]
    return d.line, d.column, d.message, d.code


@pytest.mark.parametrize("check, col, words, code", [
    ("never %MF10 > 1.0e400", 24, "not finite", Code.CONSTANT),
    ("never %MF10 > -1e999", 24, "not finite", Code.CONSTANT),
    ("never %MF10 > 3.5e38", 24, "beyond the range of a %MF", Code.CONSTANT),
    ("never %MF10 > NAN", 24, "must be finite", Code.CONSTANT),
    ("never %MF10 < INF", 24, "must be finite", Code.CONSTANT),
    ("never %MF10 > 1." + "0" * 120, 24, "characters (at most 100)", Code.CONSTANT),
    ("never %MF10 > %MW0", 22, "a float (%MF, %KF) with a word", Code.TYPE),
    ("never %MW0 + %MF10 > 1.0", 21, "a float (%MF, %KF) with a word", Code.TYPE),
    ("never %MF10 / 2.0 > 1.0", 22, "/ on floats", Code.TYPE),
    ("never %MF10", 16, "type mismatch", Code.TYPE),
])
def test_bad_float_requirements_have_a_code_and_line_col(tmp_path, check, col, words, code):
    line, column, message, got = spec_error(tmp_path, check)
    assert (line, column) == (2, col), message  # the literal or the operator
    assert words in message and got == code, message


def test_bad_float_in_require_expr_is_located_on_its_own_line():
    with pytest.raises(VerifyError) as e:
        load_spec(None, ["never %MF10 >= 1e39"],
                  PLC.from_source("LD 1\n", devices=False).profile)
    d = e.value.diagnostics[0]
    assert (d.file, d.line, d.column, d.code) == ("--require-expr", 1, 16, Code.CONSTANT)


# ---- functions without a solver theory: anchors and monotony (issue 34 item 1) -----------
@pytest.mark.parametrize("prog, check", [
    # EXP(0) = 1 and EXP non-decreasing: EXP(x) >= 1 for x >= 0 (overflow: inf, %S18)
    ("LD 1\n[ %MF10 := EXP(%MF0) ]\n", "%MF0 >= 0.0 -> %MF10 >= 1.0"),
    # two applications in one scan: in the order of their arguments
    ("LD [ LN(%MF0) > LN(%MF2) ]\nST %Q0.0\n", "%MF0 > 0.0 AND %MF0 <= %MF2 -> NOT %Q0.0"),
    ("LD [ ATAN(%MF0) > ATAN(%MF2) ]\nST %Q0.0\n", "%MF0 <= %MF2 -> NOT %Q0.0"),
])
def test_monotone_facts_prove_what_bounds_alone_cannot(prog, check):
    """With the range facts only, each ended UNKNOWN (the refinement excluded hundreds of
    counterexamples the engine did not confirm, one input at a time)."""
    res = run(prog, check, host=(0, 1, 2, 3))
    assert res.status == "PROVEN", res
