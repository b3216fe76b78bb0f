"""The debugger's command API (softplc.debug.session), driven as the REPL drives it."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest

from softplc.debug.cmd_views import diff_programs
from softplc.debug.registry import parse_value
from softplc.debug.session import Session
from softplc.il.parser import parse
from softplc.plc import PLC

HERE = Path(__file__).parents[1]  # tests/
SAMPLE = HERE / "debug_sample.il"
CONFIG = {"scan_period": "10ms", "modules": {"1": "TM2DDO8TT"},
          "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 5}}}
TABLE = HERE.parent / "ladder_programs" / "drawing_table.il"
TABLE_CFG = TABLE.with_suffix(".toml")


@pytest.fixture
def s() -> Session:
    return Session(PLC.from_file(SAMPLE, config=CONFIG), SAMPLE)


def test_stepi_enters_the_scan_then_runs_one_instruction(s: Session) -> None:
    out = s.execute("stepi")
    assert s.pos == (0, 0) and "before rung 0" in out and "LDR" in out
    s.execute("stepi")
    assert s.pos == (0, 1)
    out = s.execute("step")
    assert s.pos == (1, 0) and "threshold" in out
    out = s.execute("scan")  # finishes the scan in progress only
    assert s.pos is None and s.plc.scan_count == 1 and "scan boundary" in out


def test_break_on_rung_number_title_and_label(s: Session) -> None:
    assert "breakpoint #1 at rung 3 (stack)" in s.execute("break 3")
    out = s.execute("continue")
    assert "breakpoint #1" in out and s.pos == (3, 0)
    assert s.execute("break timer").startswith("breakpoint #2 at rung 6 (timer)")
    assert s.execute("break %L1").startswith("breakpoint #3 at rung 6")
    s.execute("disable 1")
    s.execute("continue")
    assert s.pos == (6, 0)
    assert "(disabled)" in s.execute("breakpoints")
    s.execute("delete 2 3")
    s.execute("enable 1")
    s.execute("continue")
    assert s.pos == (3, 0) and s.plc.scan_count == 1  # the next scan, same rung


def test_jumped_over_rung_does_not_stop(s: Session) -> None:
    s.continue_limit = 50
    s.execute("force %M8 1")
    s.execute("break 5")
    out = s.execute("continue")
    assert "no breakpoint hit in 50 scans" in out and s.pos is None
    s.execute("unforce %M8")
    s.execute("set %M8 0")
    s.execute("continue")
    assert s.pos == (5, 0)


def test_watch_stops_where_the_value_changes_and_keeps_history(s: Session) -> None:
    assert "now 0" in s.execute("watch %MW0")
    s.execute("set %I0.0 1")
    out = s.execute("continue")
    assert "watch #1 %MW0: 0 -> 1 (in rung 0 instr 1)" in out
    assert s.pos == (1, 0)
    s.execute("set %I0.0 0")
    s.execute("scan 2")
    s.execute("set %I0.0 1")
    s.execute("continue")
    hist = s.execute("history %MW0")
    assert "2 change(s)" in hist and "0 -> 1" in hist and "1 -> 2" in hist


def test_condition_breakpoints(s: Session) -> None:
    s.execute("break when %MW0 = 2")
    s.execute("break when %M5 rises")
    for _ in range(3):
        s.execute("set %I0.0 1")
        s.execute("scan")
        s.execute("set %I0.0 0")
        out = s.execute("scan")
    # the %MW0 = 2 breakpoint stopped one of those scans
    assert "#1" in s.execute("breakpoints") and "hits 1" in s.execute("breakpoints")
    out = s.execute("set %I0.0 1") + s.execute("continue")
    assert "breakpoint #2 when %M5 rises" in out and s.plc["%M5"]
    assert "error" in s.execute("break when %MW0 ~ 3")


def test_print_formats_and_ranges(s: Session) -> None:
    s.plc["%MW0"] = 120
    s.plc["%MW1"] = -1
    assert s.execute("print %MW0") == "%MW0 = 120"
    assert s.execute("p/x %MW0") == "%MW0 = 16#0078"
    assert s.execute("print/b %MW0") == "%MW0 = 2#0000_0000_0111_1000"
    assert s.execute("print/u %MW1") == "%MW1 = 65535"
    s.plc["%MF40"] = 2.5
    assert s.execute("print %MF40") == "%MF40 = 2.5"
    assert s.execute("print/f %MW40") == "%MW40 = 2.5"
    out = s.execute("print %MW0:10")
    assert out.splitlines()[0].split()[:3] == ["%MW0:", "120", "-1"]
    assert out.splitlines()[1].startswith("%MW8:")
    s.plc.mem.write("%Q1.2", 1)
    assert s.execute("print %Q1.0:4").split()[1:] == ["0", "0", "1", "0"]
    assert "P=5" in s.execute("print %TM0") and "Q=0" in s.execute("print %TM0")
    assert "V=0" in s.execute("print %C0")
    assert s.execute("print/z %MW0").startswith("error: unknown format")


def test_set_is_applied_at_the_next_scan_boundary(s: Session) -> None:
    s.execute("stepi")  # mid-scan
    assert "queued" in s.execute("set %MW0 2")
    assert s.plc["%MW0"] == 0
    s.execute("scan")  # finishes the scan in progress: not yet
    assert s.plc["%MW0"] == 0
    s.execute("scan")
    assert s.plc["%MW0"] == 2
    assert "error" in s.execute("set %KW0 1") and "read-only" in s.execute("set %KW0 1")
    assert "does not fit" in s.execute("set %MW0 70000")
    assert "0 or 1" in s.execute("set %M0 2")
    assert "value(s)" in s.execute("set %MW0:2 1")
    s.execute("set %MW4:3 1 2 16#10")
    s.execute("scan")
    assert s.plc["%MW4:3"] == [1, 2, 16]


def test_force_is_held_and_marked(s: Session) -> None:
    assert s.execute("force %M5 1") == "%M5 forced to 1"
    s.execute("scan 3")  # rung 1 writes %M5 := %MW0 >= 3 (false) every scan
    assert s.plc["%M5"] is True
    assert s.execute("print %M5") == "%M5 = 1  [forced]"
    assert "1F" in s.execute("rung 1")
    assert "%M5=1" in s.execute("status") and "%M5 = 1" in s.execute("force")
    s.execute("unforce %M5")
    s.execute("scan")
    assert s.plc["%M5"] is False
    assert "not forced" in s.execute("unforce %M5")


def test_rung_view_shows_power_flow_and_the_next_instruction(s: Session) -> None:
    s.execute("force %M5 1")
    s.execute("force %M7 1")
    s.execute("scan")
    view = s.execute("rung branches")
    assert view.splitlines()[0] == "rung 2  branches"
    assert "═" in view and "( )" in view and "(/)" in view
    s.execute("break 2")
    s.execute("continue")
    s.execute("stepi")
    assert ">%M" in s.execute("rung")  # the marker before the next element
    assert "error: no rung" in s.execute("rung 99")
    rungs = s.execute("rungs")
    assert ">*   2  branches" in rungs and "%L1: timer" in rungs


def test_back_restores_memory_clock_and_scan_count(s: Session) -> None:
    s.execute("run 5")
    assert s.plc.scan_count == 5
    s.plc["%MW3"] = 7
    s.execute("set %I0.0 1")
    s.execute("run 3")
    assert s.plc["%MW0"] == 1
    out = s.execute("back 3")
    assert s.plc.scan_count == 5 and abs(s.plc.time - 0.05) < 1e-9 and "scan 5" in out
    assert s.plc["%MW0"] == 0 and s.plc["%MW3"] == 7
    s.execute("stepi")
    s.execute("back")  # abandons the scan in progress
    assert s.pos is None and s.plc.scan_count == 5
    assert "only 5 scans of history" in s.execute("back 6")


def test_back_restores_edge_memory_and_devices() -> None:
    if not TABLE.exists():
        pytest.skip("drawing table program not there")
    s = Session(PLC.from_file(TABLE, config=TABLE_CFG), TABLE)
    s.execute("run 300")
    x = s.plc.devices["X"].position
    samples = len(s.plc.trace)
    s.execute("run 200")
    assert s.plc.devices["X"].position != x
    s.execute("back 200")
    assert s.plc.devices["X"].position == x and len(s.plc.trace) == samples
    s.execute("run 200")  # the same future again: deterministic
    assert s.plc.scan_count == 500


def test_run_by_time_and_status(s: Session) -> None:
    s.execute("run 2s")
    assert s.plc.scan_count == 200
    st = s.execute("status")
    assert "state    RUN" in st and "scans    200" in st and "time 2.000 s" in st
    assert "error" in s.execute("run 2 parsecs")
    assert "error" in s.execute("run")


def test_timers_and_counters(s: Session) -> None:
    s.execute("set %MW0 3")
    s.execute("run 10")
    tm = s.execute("timers")
    assert tm.startswith("%TM0") and "TON" in tm and "Q=1" in tm and "V=5" in tm
    assert "%C0" in s.execute("counters") and "V=1" in s.execute("counters")


def test_trace_to_csv(s: Session, tmp_path: Path) -> None:
    f = tmp_path / "t.csv"
    assert "tracing" in s.execute(f"trace %MW0 %M5 %MW0:2 to {f}")
    s.execute("set %MW0 4")
    s.execute("run 3")
    s.execute("trace off")
    rows = list(csv.reader(f.open()))
    assert rows[0] == ["scan", "t", "%MW0", "%M5", "%MW0", "%MW1"]
    assert [r[0] for r in rows[1:]] == ["1", "2", "3"]
    assert rows[1][2:4] == ["4", "1"]


def test_reload_keeps_memory_and_reports_changes(tmp_path: Path) -> None:
    prog = tmp_path / "p.il"
    shutil.copy(SAMPLE, prog)
    s = Session(PLC.from_file(prog, config=CONFIG), prog)
    s.execute("break timer")
    s.plc["%MW1"] = 42
    text = prog.read_text()
    text = text.replace("LD    [ %MW0 >= 3 ]", "LD    [ %MW0 >= 4 ]")
    text = text.replace("(*RUNG: float*)", "(*RUNG: new one*)\nLD %M1\nST %M2\n\n(*RUNG: float*)")
    prog.write_text(text)
    out = s.execute("reload")
    assert "added: rung 8 (new one)" in out and "modified: rung 1 (threshold)" in out
    assert s.plc["%MW1"] == 42
    s.execute("continue")
    assert s.pos == (6, 0)
    prog.write_text("LD %M0\nST %ZZ9\n")
    assert s.execute("reload").startswith("error")
    assert s.execute("scan")  # the old program still runs


def test_mistakes_never_end_the_session(s: Session) -> None:
    for bad in ("print %MW99999", "print MW0", "bogus", "step x", "delete 9", "watch",
                "break nosuchtitle", "force %MW0:3 1", "print %I0.99", "history %MW0",
                "trace %MW0", "continue", "scan -1", "print/ %MW0"):
        out = s.execute(bad)
        assert out.startswith("error:"), (bad, out)
    assert "did you mean 'print'" in s.execute("prnt %MW0")
    assert "scan 1" in s.execute("scan")
    assert "stepi" in s.execute("help") and "one instruction" in s.execute("help stepi")
    assert s.execute("quit") == "bye" and s.done


def test_parse_value_and_diff() -> None:
    assert parse_value("16#FF") == 255 and parse_value("2#101") == 5
    assert parse_value("-3") == -3 and parse_value("1.5") == 1.5 and parse_value("true") == 1
    a = parse("(*RUNG: a*)\nLD %M0\nST %M1\n(*RUNG: b*)\nLD %M2\nST %M3\n")
    b = parse("(*RUNG: b*)\nLD %M2\nST %M3\n")
    assert diff_programs(a, b) == ["removed: rung 0 (a)"]


def test_drawing_table_homing_with_a_forced_switch() -> None:
    if not TABLE.exists():
        pytest.skip("drawing table program not there")
    s = Session(PLC.from_file(TABLE, config=TABLE_CFG), TABLE)
    out = s.execute("break X home switch")
    assert out.startswith("breakpoint #1 at rung")
    s.execute("continue")
    s.execute("step")
    s.execute("watch %MW32")
    s.execute("force %I0.12 1")
    out = s.execute("continue")  # next scan: stops at the rung breakpoint first
    assert "breakpoint #1" in out
    out = s.execute("step")
    assert "watch #2 %MW32 TRAYEX: 32000 -> 0" in out  # with its symbol (drawing_table.toml)
    assert "1F" in s.execute("rung X home switch")
    s.execute("back")
    assert s.plc["%MW32"] == 32000


def test_interrupt_stops_a_long_run(s: Session) -> None:
    """What Ctrl-C does in the REPL: the run stops at the next scan, state consistent."""
    s.plc.before_scan.append(lambda: s.plc.scan_count == 7 and s.interrupt())
    out = s.execute("run 1000")
    assert "interrupted" in out and s.plc.scan_count == 8 and s.pos is None
    assert "scan 9" in s.execute("scan")


def test_subroutine_rungs_and_where() -> None:
    plc = PLC.from_source("LD %M0\nSR1\nEND\nSR1:\n(*RUNG: inside*)\nLD 1\n[ INC %MW0 ]\nRET\n")
    s = Session(plc)
    s.execute("set %M0 1")
    s.execute("break inside")
    s.execute("continue")
    assert "before rung 1 (inside)" in s.execute("where")
    assert "rung 1 SR1  inside" in s.execute("rung")
    assert "not loaded from a file" in s.execute("reload")


def test_step_count_is_not_cut_by_rung_titles_that_read_like_stops() -> None:
    """The stepper stops on typed reasons, not on words in its own output."""
    src = ("(* watch the pump *)\nLD %I0.0\nST %Q0.0\n(* breakpoint zone *)\nLD %I0.1\n"
           "ST %Q0.1\n(* third *)\nLD %I0.2\nST %Q0.2\n(* fourth *)\nLD %I0.3\nST %Q0.3\n")
    ses = Session(PLC.from_source(src))
    ses.execute("stepi")  # into the scan, before rung 0
    out = ses.execute("step 3")
    assert ses.pos == (3, 0), out
    ses.execute("back 1")
    ses.execute("break 2")
    out = ses.execute("step 3")  # a real breakpoint still ends the count early
    assert ses.pos == (2, 0) and "breakpoint #1" in out


@pytest.mark.parametrize("width", [60, 100])
def test_help_lists_whole_first_sentences_wrapped(s: Session, width: int) -> None:
    from softplc.debug.registry import first_sentence

    s.width = width
    out = s.execute("help")
    assert all(len(line) < width for line in out.splitlines())
    flat = " ".join(out.split())
    for name, doc in ((c.name, c.doc) for c in s.commands.values()):
        sentence = first_sentence(doc)
        assert sentence.endswith("."), name  # whole, not cut mid-sentence
        assert " ".join(sentence.split()) in flat, name
    assert first_sentence("a: b, e.g. c. More.") == "a: b, e.g. c."


def test_the_stepper_runs_without_the_command_layer() -> None:
    """What the web monitor will drive: typed results, no terminal, no command parsing."""
    from softplc.debug.stepper import Stepper, StopKind

    plc = PLC.from_file(SAMPLE, config=CONFIG)
    ctl = Stepper(plc)
    ran = ctl.step_instruction()
    assert ran.reason == StopKind.DONE and ctl.pos == (0, 0)
    ran = ctl.run_scans(3)
    # the scan in progress is finished first, then 3 whole scans
    assert ran.reason == StopKind.DONE and plc.scan_count == 4 and ctl.pos is None
    ctl.back(2)
    assert plc.scan_count == 2 and len(ctl.ring) == 2
    ctl.close()
    assert ctl._apply_pending not in plc.before_scan


def test_the_stepper_returns_typed_stop_reasons() -> None:
    """Each run's result is data: the reason, the hits with their ids, rungs and raw values,
    where it stands; the REPL formats it (debug/report.py)."""
    from softplc.debug.stepper import (
        BreakKind,
        CondHit,
        Executed,
        Position,
        RungHit,
        Stepper,
        StopKind,
        WatchHit,
    )

    plc = PLC.from_file(SAMPLE, config=CONFIG)
    ctl = Stepper(plc)
    ran = ctl.step()  # enters the scan: stops before rung 0
    assert ran.reason == StopKind.DONE and ran.position == Position(0, plc.time, 0, 0)
    assert ran.running and ran.state == "RUN" and not ran.hits
    for _ in range(len(plc.rungs)):
        ran = ctl.step()
    assert ran.reason == StopKind.SCAN_END and ran.position.rung is None
    b = ctl.breakpoints.add(kind=BreakKind.RUNG, text="rung 3 (stack)", rung=3, key="3")
    ran = ctl.run_scans(5)
    assert ran.reason == StopKind.BREAKPOINT and ran.hits == (RungHit(b.id, 3, b.text),)
    ctl.breakpoints.delete([b])
    w = ctl.breakpoints.add(kind=BreakKind.WATCH, text="%MW0", test=lambda: plc["%MW0"])
    plc["%I0.0"] = 1
    ran = ctl.run_scans(5)
    assert ran.reason == StopKind.WATCH
    assert ran.hits == (WatchHit(w.id, "%MW0", 0, 1, Executed(0, 1)),)
    assert isinstance(ran.hits[0].new, int)  # the value, not its text
    ctl.breakpoints.delete([w])
    c = ctl.breakpoints.add(kind=BreakKind.COND, text="%M5 rises", test=lambda: plc["%M5"],
                            mode="rises")
    assert ctl.run_until_hit(3).reason == StopKind.SCAN_LIMIT  # %M5 stays 0
    plc["%MW0"] = 3
    ran = ctl.run_until_hit(3)
    assert ran.reason == StopKind.BREAKPOINT and ran.hits == (CondHit(c.id, c.text,
                                                                      Executed(1, 1)),)
    ctl.close()


def test_a_fault_stops_a_run() -> None:
    """The PLC leaving RUN ends `run` and `continue` at that scan, with the reason FAULT
    (they used to run their scans on in HALT: continue, 100000 of them)."""
    from softplc.debug.stepper import Stepper, StopKind

    plc = PLC.from_source("LD %M0\nJMPC %L1\n%L1:\nLD 1\n[ INC %MW0 ]\nLD %M1\n"
                          "JMPC %L1\n", {"watchdog": "5ms", "scan_period": "10ms"})
    ctl = Stepper(plc)
    assert ctl.run_scans(3).reason == StopKind.DONE and plc.scan_count == 3
    plc["%M1"] = 1  # rung 1 jumps back to itself for ever: the watchdog halts the PLC
    ran = ctl.run_scans(50)
    assert ran.reason == StopKind.FAULT and not ran.running and "watchdog" in ran.fault
    assert plc.scan_count == 4
    s = Session(PLC.from_source("LD 1\n[ INC %MW0 ]\nLD [ %MW0 > 2 ]\nJMPC %L1\n"
                                "%L1:\nLD [ %MW0 > 2 ]\nJMPC %L1\n", {"watchdog": "5ms"}))
    s.execute("break when %MW5 = 1")
    out = s.execute("continue")
    assert s.plc.scan_count == 3 and "no breakpoint hit" not in out
    assert out.splitlines()[0].startswith("PLC in HALT: watchdog")
    assert "a fault stops it" in " ".join(s.execute("help continue").split())


def test_the_stepper_builds_no_text() -> None:
    """No printing or text building in the stepper: f-strings only in its errors."""
    import ast

    import softplc.debug.stepper as mod

    tree = ast.parse(Path(mod.__file__).read_text(encoding="utf-8"))
    in_raise = {id(n) for r in ast.walk(tree) if isinstance(r, ast.Raise)
                for n in ast.walk(r)}
    built = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.JoinedStr)
             and id(n) not in in_raise]
    assert not built, f"text built at lines {built}"
    calls = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call)
             and isinstance(n.func, ast.Name)}
    assert not calls & {"print", "format_value", "format_instruction"}


def test_one_command_table() -> None:
    """Every command comes from the table: a help text, aliases that name no other command
    and are not given twice, and only print takes a /FORMAT."""
    from softplc.debug.registry import COMMANDS

    aliases = [a for c in COMMANDS.values() for a in c.aliases]
    assert len(aliases) == len(set(aliases)) and not set(aliases) & set(COMMANDS)
    assert all(c.doc for c in COMMANDS.values())
    assert [c.name for c in COMMANDS.values() if c.formats] == ["print"]
    s = Session(PLC.from_file(SAMPLE, config=CONFIG))
    assert s.execute("si") == s.execute("where")  # an alias runs its command
    assert "takes no /format" in s.execute("where/x")
