"""softplc verify's time and failures: every solver call of a requirement (its model's
scans included) on one clock; each requirement in a child process killed at its time
(with its Spacer), a solver that fails or crashes an UNKNOWN, never a traceback."""

from __future__ import annotations

import faulthandler
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import z3

from softplc.cli import main
from softplc.plc import PLC
from softplc.twido.address import Ref
from softplc.verify import guard
from softplc.verify.checker import Checker
from softplc.verify.engines import FOUND, Limits, Result, requirement, verify
from softplc.verify.loops import Loops
from softplc.verify.model import Model
from softplc.verify.requirements import load_spec

# a loop of %MW1 passes (a host word) over a product of host words written through an
# index: deciding whether another pass can run grows to seconds of the solver per pass
HEAVY = """LD 1
[ %MW5 := 0 ]
%L2:
LD 1
[ %MW10[%MW7] := %MW10[%MW7] * %MW2 + %MW3 ]
[ INC %MW5 ]
LD [ %MW5 < %MW1 ]
JMPC %L2
LD [ %MW10 > 5 ]
ST %Q0.0
"""
HEAVY_REQ = ('[environment]\nhost = ["%MW1", "%MW2", "%MW3", "%MW7"]\n\n'
             '[[requirement]]\ncheck = "always %MW6 = 0"\n')


def heavy_verify_args(tmp: Path) -> list[str]:
    """`softplc verify` of HEAVY with its requirement file, both written into `tmp`."""
    (tmp / "heavy.il").write_text(HEAVY)
    (tmp / "heavy.req.toml").write_text(HEAVY_REQ)
    return ["verify", str(tmp / "heavy.il"), "--require", str(tmp / "heavy.req.toml"), "-q"]


def softplc_verify(tmp: Path, *args: str, env: dict | None = None
                   ) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "softplc", *heavy_verify_args(tmp), *args],
        capture_output=True, text=True,
        timeout=120, env={**os.environ, **(env or {})})  # (a guard against hanging only)


def test_a_loop_of_input_dependent_products_ends_unknown_at_its_timeout(tmp_path, capsys):
    """It took 60 s with --timeout 10: the model's loop decisions had no deadline. Now
    the requirement ends UNKNOWN, naming what ran out: the loop's pass being decided.
    (In this process: the command forks the requirement's child all the same.)"""
    code = main([*heavy_verify_args(tmp_path), "--timeout", "1"])
    out, err = capsys.readouterr()
    assert code == 1, out + err
    assert "UNKNOWN   always %MW6 = 0" in out
    assert "the requirement's 1 s ran out: building its model, deciding whether the loop " \
           f"at {tmp_path / 'heavy.il'}:8:1 runs pass" in out
    assert "Traceback" not in err


# z3's memory cap for the test below: HEAVY's loop reaches it in about a second of the
# solver in the requirement's child (40 MB took 10 s); at 16 MB z3 fails already in the
# parent (the model, before any requirement), which is not this test's case
SMALL_CAP_MB = "24"


def test_the_solver_at_a_small_memory_cap_is_an_unknown_not_a_crash(tmp_path):
    """z3 at a small cap on that loop: an exception, an internal assertion or a segfault
    (all seen): the requirement is UNKNOWN saying so, the run goes on. (A process of its
    own: the cap is z3's, global to a process.)"""
    r = softplc_verify(tmp_path, "--timeout", "20", env={"SOFTPLC_Z3_MEMORY_MB": SMALL_CAP_MB})
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stdout + r.stderr
    assert "UNKNOWN   always %MW6 = 0" in r.stdout
    assert "SOFTPLC_Z3_MEMORY_MB" in r.stdout or "ran out" in r.stdout


def test_building_a_model_asks_the_solver_nothing(monkeypatch):
    """Finding the state keys needs one pass of a loop: no solver call (that took 20 s on
    HEAVY, before any requirement's clock)."""
    def never(*_a: object) -> bool:
        raise AssertionError("the solver was asked while discovering the keys")
    monkeypatch.setattr(Loops, "never", never)
    plc = PLC.from_source(HEAVY, {"scan_period": "10ms"}, devices=False)
    spec = load_spec(None, ["always %MW6 = 0"], plc.profile)
    model = Model(plc, spec.reads, spec.host)
    assert model.loops.sites and "%MW[]" in model.vars  # (the %MW words: one array)


def test_a_loop_scan_is_built_once_per_requirement(monkeypatch):
    """With a loop the solver decides each pass: the cone's scan is substituted into for
    every engine (k-induction, BMC, the invariants, Spacer), never built again."""
    calls = []
    scan = Model.scan
    monkeypatch.setattr(Model, "scan", lambda self, *a: calls.append(1) or scan(self, *a))
    plc = PLC.from_source("LD 1\n[ %MW5 := 0 ]\n%L2:\nLD 1\n[ INC %MW5 ]\n"
                          "LD [ %MW5 < %MW0 ]\nJMPC %L2\n", devices=False)
    spec = load_spec(None, ["always %MW5 <= 8"], plc.profile)
    spec.host.append(Ref("MW", 0))
    spec.assumptions += load_spec(None, ["always %MW0 <= 8"], plc.profile).requirements[0] \
        .cond,
    model = Model(plc, spec.reads, spec.host, loop_bound=8)
    calls.clear()
    ck = Checker(model, spec, spec.requirements[0])
    assert verify(ck, 6, 4, 20, []).status == "PROVEN" and len(calls) == 1


def test_a_requirement_in_process_ends_unknown_at_its_time():
    """Without the child process too (as the API's tests call it): the clock ends it."""
    plc = PLC.from_source(HEAVY, {"scan_period": "10ms"}, devices=False)
    spec = load_spec(None, ["always %MW6 = 0"], plc.profile)
    spec.host += [Ref("MW", i) for i in (1, 2, 3, 7)]
    model = Model(plc, spec.reads, spec.host)
    res = requirement(model, spec, spec.requirements[0], [], Limits(10, 4, 0.5), [])
    assert res.status == "UNKNOWN" and res.note.startswith(
        "the requirement's 0.5 s ran out: building its model, deciding whether the loop at "
        "<string>:8:1 runs pass")


def test_a_child_that_overruns_is_killed_with_its_own_children(tmp_path, monkeypatch):
    """A z3 call deaf to its timeout: the child (and what it started, as Spacer) is
    killed MARGIN_S after the requirement's time, naming the last progress reported; its
    temporary files are removed."""
    monkeypatch.setattr(guard, "MARGIN_S", 0.3)
    pid_file = tmp_path / "pid"

    def work(report):
        p = subprocess.Popen(["sleep", "60"])
        with tempfile.NamedTemporaryFile(delete=False) as f:  # as Spacer's clauses
            pid_file.write_text(f"{p.pid} {f.name}")
        report("BMC", 3, 0.1)
        time.sleep(60)
    seen = []
    res = guard.isolated(work, 0.2, lambda *a: seen.append(a))
    assert res.status == "UNKNOWN" and seen == [("BMC", 3, 0.1)]
    assert res.note == ("the solver did not stop at the requirement's 0.2 s (after BMC "
                        "reached depth 3): its process was killed 0.3 s later")
    pid, left = pid_file.read_text().split()
    assert gone(int(pid)) and not Path(left).exists()


def gone(pid: int) -> bool:
    """The process ended (a zombie until its new parent reaps it counts as ended)."""
    for _ in range(100):
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except FileNotFoundError:
            return True
        if state == "Z":
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("how", ["segfault", "z3 exception", "bug"])
def test_a_child_that_crashes_or_fails(how):
    """A segfault after z3's last words, and a z3 exception, are UNKNOWN with what
    happened; any other exception is a bug, raised here with the child's traceback."""
    def work(report):
        if how == "segfault":
            faulthandler.disable()  # (pytest's: its dump would go to the terminal)
            os.write(2, b"UNEXPECTED CODE WAS REACHED.\n")
            os.kill(os.getpid(), signal.SIGSEGV)
        if how == "z3 exception":
            raise z3.Z3Exception(b"out of memory")
        raise KeyError("oops")
    if how == "bug":
        with pytest.raises(RuntimeError, match="KeyError: 'oops'"):
            guard.isolated(work, 5)
        return
    res = guard.isolated(work, 5)
    assert res.status == "UNKNOWN"
    if how == "segfault":
        assert "ended without an answer (SIGSEGV) before any progress" in res.note
        assert "z3 said: UNEXPECTED CODE WAS REACHED." in res.note
    else:
        assert res.note.startswith("the solver failed (out of memory; its memory cap:")


def test_a_child_answers_with_its_result():
    res = guard.isolated(lambda report: Result("PROVEN", "k-induction (k=1)", 1, 0.1), 5)
    assert res == Result("PROVEN", "k-induction (k=1)", 1, 0.1)


def test_a_counterexample_found_in_time_is_waited_for(monkeypatch):
    """Once BMC reports one, its trace (concrete scans of the model) is off the clock: the
    parent waits for it past the requirement's time."""
    monkeypatch.setattr(guard, "MARGIN_S", 0.1)

    def work(report):
        report(FOUND, 5, 0.1)
        time.sleep(0.6)
        return Result("VIOLATED", "BMC", 5, 0.7)
    assert guard.isolated(work, 0.1).status == "VIOLATED"
