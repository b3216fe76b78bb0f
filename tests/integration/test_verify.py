"""softplc verify: requirement files, proofs, counterexamples replayed in the engine."""

from __future__ import annotations

import json
import runpy
import subprocess
import sys
from pathlib import Path

import pytest

from softplc.cli import main
from softplc.errors import VerifyError
from softplc.plc import PLC
from softplc.twido.address import Ref
from softplc.verify.checker import Checker
from softplc.verify.clock import Clock
from softplc.verify.engines import bmc, verify
from softplc.verify.model import Model
from softplc.verify.replay import first_failure, replay
from softplc.verify.requirements import check_environment, load_spec

ROOT = Path(__file__).resolve().parents[2]
LP = ROOT / "ladder_programs"
STAR = [str(LP / "star_delta.il"), "--config", str(LP / "star_delta.toml")]


def checker(text: str, check: str, config: dict | None = None, **env) -> Checker:
    plc = PLC.from_source(text, config, devices=False)
    spec = load_spec(None, [check], plc.profile)
    spec.host += env.get("host", [])
    model = Model(plc, spec.reads, spec.host, env.get("periods"))
    return Checker(model, spec, spec.requirements[0])


# no test here expects UNKNOWN from `status`: its time only ends a run gone wrong. 20 s
# of wall time was reached on a loaded machine by a run of 2.4 CPU-s (an UNKNOWN where a
# 4-scan counterexample is); z3's rlimit would not bound the model building, the Python
# side nor Spacer's process, so the budget is a wall one, far above any run's time
STATUS_S = 300.0


def status(text: str, check: str, config: dict | None = None, depth: int = 8,
           **env) -> tuple[str, object]:
    res = verify(checker(text, check, config, **env), depth, 4, STATUS_S, [],
                 use_spacer=True)
    return res.status, res


# ---- results ---------------------------------------------------------------------------------
def test_interlock_proven_and_broken_interlock_found():
    prog = "LD %I0.0\nANDN %Q0.1\nST %Q0.0\nLD %I0.1\nANDN %Q0.0\nST %Q0.1\n"
    assert status(prog, "never %Q0.0 AND %Q0.1")[0] == "PROVEN"
    bad = "LD %I0.0\nST %Q0.0\nLD %I0.1\nANDN %Q0.0\nST %Q0.1\n"  # Q0.1 reads Q0.0: same scan
    st, res = status(bad, "never %Q0.0 AND %Q0.1")
    assert st == "PROVEN"  # the rung order protects it
    bad2 = "LD %I0.1\nANDN %Q0.0\nST %Q0.1\nLD %I0.0\nST %Q0.0\n"  # Q0.0 written after
    st, res = status(bad2, "never %Q0.0 AND %Q0.1")
    assert st == "VIOLATED" and res.depth == 1
    assert res.trace[0]["inputs"] == {"%I0.0": 1, "%I0.1": 1}


def test_counterexample_is_minimal_and_replays_in_engine():
    # %MW0 counts rising edges of %I0.0; it reaches 3 after three presses: 5 scans minimum
    prog = "LDR %I0.0\n[ INC %MW0 ]\n"
    st, res = status(prog, "always %MW0 < 3", depth=10)
    assert st == "VIOLATED" and res.depth == 5
    plc = PLC.from_source(prog, devices=False)
    assert replay(plc, res.trace) == []
    assert [r["values"] for r in res.trace][-1] == {}  # no watch list given here


def test_word_overflow_and_s18():
    prog = "LD 1\n[ %MW1 := %MW0 + 1 ]\n[ %MW0 := %MW1 ]\n"
    # 32767 + 1 wraps to -32768 and sets %S18: reachable only after 32767 scans, so the
    # bounded search does not see it, but a host writing %MW0 does at once
    from softplc.twido.address import Ref
    st, res = status(prog, "never %S18", host=[Ref("MW", 0)])
    assert st == "VIOLATED" and res.depth == 1
    assert res.trace[0]["inputs"]["%MW0"] == 32767
    assert res.trace[0]["objects"]["%MW1"] == -32768


def test_timer_response_within_scans():
    config = {"scan_period": "10ms", "timers": {"%TM0": {"type": "TON", "base": "10ms",
                                                          "preset": 3}}}
    prog = "BLK %TM0\nLD %I0.0\nIN\nOUT_BLK\nLD Q\nST %Q0.0\nEND_BLK\n"
    assert status(prog, "%I0.0 -> %TM0.V <= 3", config)[0] == "PROVEN"
    # held 3 scans the timer is done: a response within 3 scans needs %I0.0 held
    st, res = status(prog, "%I0.0 rising -> %Q0.0 within 3 scans", config)
    assert st == "VIOLATED"
    assert res.trace[-1]["values"] == {} or True
    plc = PLC.from_source(prog, config, devices=False)
    assert first_failure(plc, "%I0.0 rising -> %Q0.0 within 3 scans",
                         [r["inputs"] for r in res.trace]) == res.depth


def test_variable_scan_period_reaches_long_timers_quickly():
    config = {"scan_period": "10ms", "timers": {"%TM0": {"type": "TON", "base": "1s",
                                                          "preset": 10}}}
    prog = "LD %I0.0\nIN %TM0\nLD %TM0.Q\nST %Q0.0\n"
    fixed = bmc(checker(prog, "never %Q0.0", config), 6, Clock(60), [])
    assert fixed.status == "UNKNOWN"  # 10 s are 1000 scans of 10 ms
    res = bmc(checker(prog, "never %Q0.0", config, periods=(10_000, 5_000_000)), 6,
              Clock(60), [])
    assert res.status == "VIOLATED" and res.depth == 3  # 0, 5 s, 10 s
    assert all("period_ms" in r["inputs"] for r in res.trace)
    plc = PLC.from_source(prog, config, devices=False)
    assert replay(plc, res.trace) == []


def test_grafcet_traffic_light_requirements():
    plc = PLC.from_file(LP / "traffic_light.il", LP / "traffic_light.toml", devices=False)
    spec = load_spec(LP / "traffic_light.req.toml", [], plc.profile)
    model = Model(plc, spec.reads, spec.host, spec.periods)
    by_name = {r.name: r for r in spec.requirements}
    walk = Checker(model, spec, by_name["walk only while cars have red"])
    assert verify(walk, 10, 4, 30, []).status == "PROVEN"
    press = Checker(model, spec, by_name["every press lights the wait lamp at once"])
    res = bmc(press, 30, Clock(60), ["%I0.0", "%Q0.5"])
    assert res.status == "VIOLATED"
    assert res.trace[-1]["values"] == {"%I0.0": 1, "%Q0.5": 0}
    again = PLC.from_file(LP / "traffic_light.il", LP / "traffic_light.toml", devices=False)
    assert replay(again, res.trace) == []


# ---- requirement errors ------------------------------------------------------------------
def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "req.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("check, line, col, words", [
    ('check = "never %Q0.1 AND %Z9"', 3, 26, "malformed"),
    ('check = "never %MW10"', 3, 16, "type mismatch"),
    ('check = "always %MW10 + %Q0.0 > 1"', 3, 25, "type mismatch"),
    ('check = "always %M99999"', 3, 17, "beyond"),
    ('check = "%I0.1 rising -> %Q0.0 within 5"', 3, 40, "'scans' or 'ms'"),
])
def test_requirement_errors_have_line_and_column(tmp_path, check, line, col, words):
    p = write(tmp_path, f'[[requirement]]\nname = "x"\n{check}\n')
    with pytest.raises(VerifyError) as e:
        load_spec(p, [], PLC.from_source("LD 1\nST %Q0.0\n", devices=False).profile)
    d = e.value.diagnostics[0]
    assert (d.line, d.column) == (line, col), str(e.value)
    assert words in d.message


def test_free_input_written_by_the_program_is_an_error(tmp_path):
    p = write(tmp_path, '[environment]\nfree = ["%M3"]\n\n[[requirement]]\n'
                        'check = "never %Q0.0"\n')
    plc = PLC.from_source("LD %I0.0\nST %M3\nLD %M3\nST %Q0.0\n", devices=False)
    spec = load_spec(p, [], plc.profile)
    model = Model(plc, spec.reads, [r for r, _ in spec.free])
    with pytest.raises(VerifyError) as e:
        check_environment(spec, model.written, "prog.il")
    d = e.value.diagnostics[0]
    assert (d.line, d.column) == (2, 10) and "prog.il:2:" in d.message


def test_unsupported_constructs_are_reported_with_position():
    plc = PLC.from_source("LD 1\n[ %MF0 := MEAN(%MF2:3) ]\nLD %M10[%MW2]\nST %Q0.0\n",
                          devices=False)
    with pytest.raises(VerifyError) as e:
        Model(plc)
    lines = sorted({d.line for d in e.value.diagnostics})
    assert lines == [2, 3]
    assert "cannot model" in str(e.value)


DRUM_PROG = """LD %I0.0
U %DR0
LD %I0.1
R %DR0
LDR %I0.2
[ %R0.I := SHL(%MW4, 1) ]
LD %I0.2
I %R0
LD %I0.0
O %R0
LD %I0.1
CU %SC0
LD %SC0.2
ST %M3
"""
DRUM_CFG = {"scan_period": "10ms",
            "drums": {"%DR0": {"steps": [1, 2, 4, 2], "outputs": ["%Q0.0", "%Q0.1", "%Q0.2"]}},
            "registers": {"%R0": {"type": "LIFO"}}}


def test_drum_interlock_proven_and_register_counterexample_replays():
    """A drum whose steps never energise %Q0.0 and %Q0.2 together is proven so (its range
    invariants hold: they are checked inductive); a step-counter bit reached, and a word
    retrieved from a LIFO, are counterexamples the engine reproduces."""
    from softplc.verify.engines import invariants_inductive
    ck = checker(DRUM_PROG, "never %Q0.0 AND %Q0.2", DRUM_CFG, host=[Ref("MW", 4)])
    assert invariants_inductive(ck, Clock(60))
    assert status(DRUM_PROG, "never %Q0.0 AND %Q0.2", DRUM_CFG)[0] == "PROVEN"
    st, res = status(DRUM_PROG, "never %M3", DRUM_CFG)
    assert st == "VIOLATED" and res.depth == 3  # two rising edges of %I0.1: 1, 0, 1
    plc = PLC.from_source(DRUM_PROG, DRUM_CFG, devices=False)
    assert replay(plc, res.trace) == []
    st, res = status(DRUM_PROG, "always %R0.O <> 6", DRUM_CFG, host=[Ref("MW", 4)])
    # one scan: %I0.2 stores SHL(%MW4, 1) = 6 (its top bit is shifted out), %I0.0 gets it
    assert st == "VIOLATED" and res.depth == 1 and res.trace[0]["inputs"]["%MW4"] in (3, -32765)
    plc = PLC.from_source(DRUM_PROG, DRUM_CFG, devices=False)
    assert replay(plc, res.trace) == []


# ---- the command -------------------------------------------------------------------------
def test_command_proves_star_delta(capsys):
    code = main(["verify", *STAR, "--require", str(LP / "star_delta.req.toml"), "-q",
                 "--depth", "5"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert out.count("PROVEN") == 5


def test_command_finds_defect_writes_cex_and_test(tmp_path, capsys):
    cex, test = tmp_path / "cex.json", tmp_path / "test_cex.py"
    code = main(["verify", str(LP / "star_delta_defect.il"), "--config",
                 str(LP / "star_delta.toml"), "--require-expr",
                 "%I0.2 = 0 -> NOT (%Q0.0 OR %Q0.1 OR %Q0.2)", "-q", "--depth", "5",
                 "--cex", str(cex), "--emit-test", str(test)])
    out = capsys.readouterr().out
    assert code == 2, out
    assert "VIOLATED" in out and "same values in every scan" in out
    data = json.loads(cex.read_text())
    assert len(data["counterexamples"][0]["scans"]) == 1
    r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                        str(test)], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 1 and "broken at scan 1" in r.stdout


def test_command_bounded_exit_and_bad_file(tmp_path, capsys):
    req = write(tmp_path, '[[requirement]]\ncheck = "never %Q0.0 AND %Q0.1 AND %MW3 = 7"\n'
                          '[[requirement]]\ncheck = "never %MW10"\n')
    assert main(["verify", *STAR, "--require", str(req)]) == 1
    err = capsys.readouterr().err
    assert "req.toml:4:16" in err and "type mismatch" in err


def test_repl_replays_a_counterexample(tmp_path, capsys):
    cex = tmp_path / "cex.json"
    main(["verify", str(LP / "star_delta_defect.il"), "--config", str(LP / "star_delta.toml"),
          "--require-expr", "%I0.2 = 0 -> %Q0.0 = 0", "-q", "--depth", "3", "--cex", str(cex)])
    capsys.readouterr()
    main(["repl", str(LP / "star_delta_defect.il"), "--config", str(LP / "star_delta.toml"),
          "--replay", str(cex), "-x", "scan 1", "-x", "print %Q0.0", "-x", "print %I0.2",
          "-x", "quit"])
    out = capsys.readouterr().out
    # (the configuration names them: KM1_MAIN, OVERLOAD_OK)
    assert "%Q0.0 KM1_MAIN = 1" in out and "%I0.2 OVERLOAD_OK = 0" in out, out


def test_the_docs_requirement_example_loads(tmp_path):
    from docs_util import fenced, page

    toml = fenced(page("docs/verify.md"), "## Requirement files", "toml")
    plc = PLC.from_source("LD %I0.0\nANDN %Q0.2\nST %Q0.1\n", devices=False)
    spec = load_spec(write(tmp_path, toml), [], plc.profile)
    assert spec.periods == (10_000, 1_000_000) and len(spec.host) == 10
    assert [r.kind for r in spec.requirements] == ["always"]


def test_proven_requirements_strengthen_the_induction():
    prog = ("LD %I0.0\n[ %MW10 := %MW10 + 1 ]\nLD [ %MW10 >= 1000 ]\n[ %MW10 := 0 ]\n"
            "LD 1\n[ %MW40 := %MW10 * 2 ]\n")
    plc = PLC.from_source(prog, devices=False)
    spec = load_spec(None, ["always %MW10 >= 0 AND %MW10 < 1000", "always %MW40 <= 1998"],
                     plc.profile)
    model = Model(plc, spec.reads)
    lemma, target = spec.requirements
    alone = verify(Checker(model, spec, target), 5, 4, 20, [], use_spacer=False)
    assert alone.status == "UNKNOWN"  # a negative %MW10 is not reachable, but inductive
    first = verify(Checker(model, spec, lemma), 5, 4, 20, [], use_spacer=False)
    assert first.status == "PROVEN"
    helped = verify(Checker(model, spec, target, [lemma.cond]), 5, 4, 20, [],
                    use_spacer=False)
    assert helped.status == "PROVEN" and helped.method == "k-induction (k=1)"


def test_assumptions_and_analog_spans(tmp_path):
    prog = "LD %I0.0\nAND %I0.1\nST %Q0.0\nLD [ %IW0.0 > 1000 ]\nST %Q0.1\n"
    config = {"analog": {"%IW0.0": {"type": "pot"}}}  # the potentiometer: 0..1023
    plc = PLC.from_source(prog, config, devices=False)
    spec = load_spec(None, ["never %Q0.0", "never %Q0.1", "always %IW0.0 <= 1023"],
                     plc.profile)
    model = Model(plc, spec.reads)
    both, pot, span = (Checker(model, spec, r) for r in spec.requirements)
    assert verify(both, 3, 2, 20, []).status == "VIOLATED"
    res = verify(pot, 3, 2, 20, ["%IW0.0"])
    assert res.status == "VIOLATED" and 1000 < res.trace[0]["values"]["%IW0.0"] <= 1023
    assert verify(span, 3, 2, 20, []).status == "PROVEN"
    req = write(tmp_path, '[environment]\nassume = ["NOT (%I0.0 AND %I0.1)"]\n\n'
                          '[[requirement]]\ncheck = "never %Q0.0"\n')
    spec = load_spec(req, [], plc.profile)
    assert verify(Checker(model, spec, spec.requirements[0]), 3, 2, 20, []).status == "PROVEN"


# ---- loops (backward jumps) and system objects -----------------------------------------------
LOOP_PROG = """LD 1
[ %MW5 := 0 ]
%L2:
LD 1
[ INC %MW5 ]
LDR %I0.0
[ INC %MW6 ]
LD [ %MW5 < %MW0 ]
JMPC %L2
LD [ %MW5 > 5 ]
ST %Q0.0
"""


def loop_checker(tmp: Path, check: str, assume: str | None, bound: int) -> Checker:
    plc = PLC.from_source(LOOP_PROG, {"scan_period": "10ms"}, devices=False)
    req = tmp / "loop.req.toml"
    req.write_text(f'[environment]\nhost = ["%MW0"]\nassume = {[assume] if assume else []}\n'
                   f'[[requirement]]\ncheck = "{check}"\n')
    spec = load_spec(req, [], plc.profile)
    model = Model(plc, spec.reads, spec.host, None, loop_bound=bound)
    return Checker(model, spec, spec.requirements[0])


def test_backward_jump_unrolled_within_its_bound_and_unknown_beyond(tmp_path):
    """A loop runs %MW0 passes in a scan (the engine's `_pc` dispatch): modelled exactly
    up to the bound (its edge instruction updated on every pass, as the engine's one slot),
    a run needing more passes is UNKNOWN with the jump's line:col, never a violation."""
    ck = loop_checker(tmp_path, "always %MW5 <= 8", "%MW0 <= 8", 8)
    assert verify(ck, 6, 4, 20, [], use_spacer=False).status == "PROVEN"
    res = verify(loop_checker(tmp_path, "never %Q0.0", "%MW0 <= 8", 8), 6, 4, 20, ["%Q0.0"])
    assert res.status == "VIOLATED" and res.depth == 1
    plc = PLC.from_source(LOOP_PROG, {"scan_period": "10ms"}, devices=False)
    assert replay(plc, res.trace) == []
    assert plc["%MW5"] == res.trace[0]["inputs"]["%MW0"] > 5
    ck = loop_checker(tmp_path, "always %MW6 <= 1", None, 3)
    res = verify(ck, 4, 2, 20, [], use_spacer=False)
    assert res.status == "UNKNOWN" and "<string>:9:1" in res.note and "3 passes" in res.note


def test_backward_jump_in_a_grafcet_program_is_refused():
    plc = PLC.from_source("=*= 0\n%L1:\nLD %I0.0\nJMPC %L1\nLD %I0.1\n# 1\n-*- 1\n",
                          devices=False)
    with pytest.raises(VerifyError, match="backward jump in a Grafcet"):
        Model(plc)


def test_system_words_definite_or_free_and_replayed(capsys):
    """%S1/%S11 0 and %S12 1 after a cold start, %SW0 the configured period: proven; the
    analog status word and the real-time clock's words are free, named in the output, and
    their counterexamples replay (the clock held at the counterexample's values)."""
    prog = "LD %I0.0\nST %Q0.0\n"
    assert status(prog, "always %S12 AND NOT %S1 AND NOT %S11 AND %SW0 = 10",
                  {"scan_period": "10ms"})[0] == "PROVEN"
    therm = [str(LP / "analog_thermostat.il"), "--config", str(LP / "analog_thermostat.toml")]
    assert main(["verify", *therm, "--require-expr", "never %Q0.0 AND %Q0.1",
                 "--require-expr", "never %Q0.1", "-q"]) == 2
    out = capsys.readouterr().out
    assert "free system objects" in out and "%SW82 (an analog module" in out
    assert "PROVEN    never %Q0.0 AND %Q0.1" in out and "same values in every scan" in out
    rtc = [str(LP / "rtc_schedule.il"), "--config", str(LP / "rtc_schedule.toml")]
    assert main(["verify", *rtc, "--require-expr", "never %Q0.1", "-q"]) == 2
    out = capsys.readouterr().out
    assert "%SW51 (the real-time clock)" in out and "same values in every scan" in out
    plc = PLC.from_source("LD 1\n[ %SW30 := 0 ]\n", devices=False)
    with pytest.raises(VerifyError, match="rewrites after the program"):
        Model(plc)


def test_tables_and_bit_strings_modelled_and_replayed():
    """`%MWi:n := %MWj:n`, `%MWi:n := value`, `%Mi:n := value` and `%Mi:L` read as a
    number: a counterexample through them replays; a requirement on a double word reads
    its two words (no separate variable)."""
    prog = ("LD %I0.0\n[ %MW0:3 := %MW10:3 ]\nLD %I0.1\n[ %MW10:3 := %MW0 + 1 ]\n"
            "LD %I0.2\n[ %M0:20 := %MW1 ]\nLD 1\n[ %MD30 := %M0:20 ]\n"
            "LD [ %M0:4 > 2 ]\nST %Q0.0\n")
    st, res = status(prog, "never %Q0.0", depth=12)
    assert st == "VIOLATED" and res.depth == 4  # %MW10 and %MW1 climb 1, 2, 3 together
    plc = PLC.from_source(prog, devices=False)
    assert replay(plc, res.trace) == [] and plc["%MD30"] == 3
    model = checker(prog, "always %MD30 >= 0").model
    assert "%MD30" not in model.vars and {"%MW30", "%MW31"} <= set(model.vars)


def test_spacer_restarts_on_another_order_of_its_clauses(monkeypatch):
    """Two counters kept equal: not k-inductive (any state may have them differ), Spacer
    proves it; with a tiny first budget it is restarted on shuffled clauses and still
    answers, each restart a new order of `Inv`'s arguments. The first attempt gets no time
    (it is restarted at the first poll, before its interpreter has even loaded z3), the
    next the usual budget: one restart, not one per doubling of a tiny budget (each
    restart a new interpreter)."""
    from softplc.verify.engines import Spacer, horn_clauses
    prog = ("LDR %I0.0\n[ INC %MW0 ]\n[ INC %MW1 ]\nLD [ %MW0 >= 5 ]\n[ %MW0 := 0 ]\n"
            "[ %MW1 := 0 ]\n")
    ck = checker(prog, "always %MW1 < 5")
    assert horn_clauses(ck, 1) != horn_clauses(ck, 0)
    usual = Spacer.FIRST
    monkeypatch.setattr(Spacer, "FIRST", 0.0)
    child = Spacer(ck)
    monkeypatch.setattr(Spacer, "FIRST", usual)
    try:
        assert child.wait(30) == "PROVEN" and child.attempt >= 1
    finally:
        child.kill()
    res = verify(ck, 5, 3, 30, [])
    assert res.status == "PROVEN" and res.method.startswith("Spacer")


def test_indexed_words_as_an_array_with_s20_out_of_range():
    """`%MW10[%MW0] := ...` and `... := %MW10[%MW2]` with host-written indexes: the %MW
    words become one solver array; an index out of range sets %S20 and uses the word
    itself, as the engine (`Ops.ix`): both counterexamples replay."""
    prog = ("LD 1\n[ %MW10[%MW0] := %MW1 ]\nLD [ %MW12 = 7 ]\nST %Q0.0\nLD %S20\nST %Q0.1\n"
            "LD 1\n[ %MW3 := %MW10[%MW2] ]\n")
    host = [Ref("MW", 0), Ref("MW", 1), Ref("MW", 2)]
    st, res = status(prog, "never %Q0.0", host=host)
    assert st == "VIOLATED" and res.trace[0]["inputs"]["%MW0"] == 2
    assert replay(PLC.from_source(prog, devices=False), res.trace) == []
    st, res = status(prog, "never %Q0.1", host=host)
    ins = res.trace[0]["inputs"]
    assert st == "VIOLATED" and not (0 <= 10 + ins["%MW0"] < 3000 and 0 <= 10 + ins["%MW2"] < 3000)
    assert replay(PLC.from_source(prog, devices=False), res.trace) == []
    # what %MW0 selects is written with %MW1 in the same scan: read back through %MW2
    assert status(prog, "always %MW3 <> 5", host=host)[0] == "VIOLATED"


def test_a_free_word_the_program_may_write_through_an_index_is_an_error(tmp_path):
    """The index is the program's: any %MW word may be the one written, a free one too."""
    p = write(tmp_path, '[environment]\nfree = ["%MW3"]\n\n[[requirement]]\n'
                        'check = "never %Q0.0"\n')
    plc = PLC.from_source("LD 1\n[ %MW10[%MW0] := 5 ]\nLD [%MW3 > 2]\nST %Q0.0\n",
                          devices=False)
    spec = load_spec(p, [], plc.profile)
    model = Model(plc, spec.reads, [r for r, _ in spec.free])
    with pytest.raises(VerifyError, match="through an index") as e:
        check_environment(spec, model.written, "prog.il")
    assert "prog.il:2:" in e.value.diagnostics[0].message



def test_a_loop_the_solver_cannot_decide_is_cut_and_unknown(tmp_path, monkeypatch):
    """Deciding whether a loop's next pass can run has a time budget over its passes (a
    pass count that depends on inputs, products of them, grew the solver's memory until
    z3 crashed): past it the passes are not unrolled, and a run that needs them is
    UNKNOWN with the jump and the reason, never a violation."""
    import softplc.verify.loops as L

    monkeypatch.setattr(L, "LOOP_SOLVER_BUDGET_S", 0.0)  # cut at the first pass
    ck = loop_checker(tmp_path, "always %MW6 <= 1", None, 8)
    res = verify(ck, 4, 2, 20, [], use_spacer=False)
    assert res.status == "UNKNOWN" and "<string>:9:1" in res.note
    assert "more than 1 passes" in res.note and "outgrew 0 s of the solver" in res.note


# ---- symbols (issue 33) ----------------------------------------------------------------------
def test_requirements_name_objects_by_symbol_and_the_results_show_them(tmp_path, capsys):
    """`check` and --require-expr take the configuration's symbols (star_delta_symbols.csv)
    like addresses; the counterexample table and the emitted test name them too."""
    req = write(tmp_path, '[[requirement]]\ncheck = "never KM2_STAR AND KM3_DELTA"\n')
    test = tmp_path / "test_cex.py"
    code = main(["verify", str(LP / "star_delta_defect.il"), "--config",
                 str(LP / "star_delta_defect.toml"), "--require", str(req), "--require-expr",
                 "overload_ok = 0 -> NOT (KM1_MAIN OR STAR_TIME.Q)", "-q", "--depth", "5",
                 "--emit-test", str(test)])
    out = capsys.readouterr().out
    assert code == 2, out
    assert "PROVEN    never KM2_STAR AND KM3_DELTA" in out
    names, head = [ln.split() for ln in out.splitlines() if ("%I0.0" in ln or
                   "START_PB" in ln) and "free inputs" not in ln][:2]  # not the environment
    assert names[:4] == ["START_PB", "STOP_PB", "OVERLOAD_OK", "FAULT_RESET"], out
    assert head[:5] == ["scan", "%I0.0", "%I0.1", "%I0.2", "%I0.3"], out
    assert "KM1_MAIN" in names and "STAR_TIME.Q" in names, out
    emitted = test.read_text()
    assert "# inputs: " in emitted and "OVERLOAD_OK(%I0.2)" in emitted
    # the emitted test fails at the counterexample's scan (run here: that pytest runs an
    # emitted file is test_command_finds_defect_writes_cex_and_test's point)
    tests = runpy.run_path(str(test))
    with pytest.raises(AssertionError, match="broken at scan 1"):
        tests["test_requirement_0"]()


def test_an_unknown_symbol_in_a_requirement_is_located_with_a_guess(tmp_path, capsys):
    req = write(tmp_path, '[[requirement]]\ncheck = "never KM2_STAR AND KM3_DELTTA"\n')
    assert main(["verify", *STAR, "--require", str(req)]) == 1
    err = capsys.readouterr().err
    assert "req.toml:2:29: unknown symbol 'KM3_DELTTA' (did you mean KM3_DELTA?)" in err, err
