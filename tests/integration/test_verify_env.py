"""softplc verify's environment (issue 34 item 0): no vacuous proof by default, the
environment printed, proofs resting on held objects flagged, UNKNOWNs that say what to try."""

from __future__ import annotations

from pathlib import Path

from softplc.cli import main
from softplc.plc import PLC
from softplc.verify.environment import compact
from softplc.verify.model import Model

ROOT = Path(__file__).resolve().parents[2]
LP = ROOT / "ladder_programs"
# a conveyor: %M0 / %M1 are a SCADA's start / stop coils, read and never written
CONVEYOR = "LD %M0\nOR %Q0.0\nANDN %M1\nANDN %I0.1\nST %Q0.0\n"


def write(tmp_path: Path, name: str, text: str) -> str:
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_host_coils_are_free_by_default(tmp_path, capsys):
    """The issue's case: `never %M0 OR %M1` was PROVEN with the coils held at 0."""
    prog = write(tmp_path, "conveyor.il", CONVEYOR)
    assert main(["verify", prog, "--require-expr", "never %M0 OR %M1", "-q"]) == 2
    out = capsys.readouterr().out
    assert "environment assumed in every scan:" in out
    assert "free, written by a Modbus host" in out and "%M0..%M1" in out
    assert "VIOLATED  never %M0 OR %M1: counterexample of 1 scan(s)" in out


def test_held_objects_flag_a_vacuous_proof(tmp_path, capsys):
    prog = write(tmp_path, "conveyor.il", CONVEYOR)
    req = write(tmp_path, "req.toml", '[environment]\nheld = ["%M0:2"]\n\n'
                '[[requirement]]\ncheck = "never %Q0.0"\n\n'
                '[[requirement]]\ncheck = "never %Q0.0 AND %I0.1"\n')
    assert main(["verify", prog, "--require", req, "-q"]) == 0
    out = capsys.readouterr().out
    assert "held at the cold-start value: %M0 (declared held), %M1 (declared held)" in out
    first, second = out.split("PROVEN")[1:3]
    assert "! VACUOUS: holds only because %M0, %M1 never change" in first
    assert "fails after 1 scan(s)" in first
    assert "VACUOUS" not in second  # true whatever %M0 / %M1 do


def test_an_object_only_the_requirement_reads_is_free_too(tmp_path, capsys):
    """A word and a coil the program never reads, a host may still write: free, so `never
    %MW5 = 7` is VIOLATED (it was PROVEN, %MW5 held at 0 without a word)."""
    prog = write(tmp_path, "p.il", "LD 1\nST %Q0.0\n")
    assert main(["verify", prog, "--require-expr", "never %MW5 = 7",
                 "--require-expr", "never %M3"]) == 2
    out = capsys.readouterr().out
    assert "written by a Modbus host (read, never written by the program): %M3 %MW5" in out
    assert out.count("VIOLATED") == 2 and "PROVEN" not in out


def test_read_only_range_is_held_and_program_words_stay_the_programs():
    prog = ("LD %M5\nST %Q0.0\nLD [ %MW3 > 0 ]\nST %Q0.1\n"
            "LD %I0.0\n[ %MW4 := %MW4 + 1 ]\n")
    plc = PLC.from_source(prog, {"modbus": {"read_only": ["%M5", "%MW3"]}}, devices=False)
    env = Model(plc).env
    assert env.held == {"%M5": "nothing else writes it", "%MW3": "nothing else writes it"}
    assert env.free == {}  # %MW4 is read and written by the program: not free


def test_device_status_words_are_free():
    """The servo cell reads its drives' status words: the drives write them, so they are
    free (the simulated devices are not part of the model)."""
    plc = PLC.from_file(LP / "servo_table.il", LP / "servo_table.toml", devices=False)
    words = {"X": [(210, 228)], "Y": [(240, 258)]}
    env = Model(plc, devices=words).env
    assert env.free and set(env.free.values()) <= {"device X", "device Y",
                                                    "a Modbus host"}
    assert any(v == "device X" for v in env.free.values())
    model = Model(plc, devices=words)
    assert all(k in model.inputs for k in env.free)


def test_unknown_says_what_to_try(tmp_path, capsys):
    """A 3 s timer at 10 ms scans: UNKNOWN within 30 scans names a depth and a scan
    period range; with the range, the counterexample comes."""
    prog = write(tmp_path, "t.il", "LD %I0.0\nIN %TM0\nLD %TM0.Q\nST %Q0.0\n")
    cfg = write(tmp_path, "t.toml", 'scan_period = "10ms"\n[timers."%TM0"]\ntype = "TON"\n'
                'base = "10ms"\npreset = 300\n')
    args = ["verify", prog, "--config", cfg, "--require-expr", "never %Q0.0", "-q",
            "--no-spacer", "--max-k", "2", "--timeout", "30"]
    assert main(args) == 1
    out = capsys.readouterr().out
    assert "try: %TM0 needs 300 scans of 10ms" in out
    assert "--depth 302" in out and 'scan_period = ["10ms", "3s"]' in out
    assert main([*args, "--scan-period", "10ms:3s"]) == 2


def test_compact_ranges():
    assert compact(["%M1", "%M0", "%MW3", "%MW5", "%MW4", "%S19"]) == \
        "%M0..%M1 %MW3..%MW5 %S19"


def test_junit_report(tmp_path, capsys):
    """`--junit`: one test case per requirement, VIOLATED a failure with its table,
    UNKNOWN a failure with its reasons, skipped when --bounded accepts it."""
    import xml.etree.ElementTree as ET
    prog = write(tmp_path, "conveyor.il", CONVEYOR)
    report = tmp_path / "report.xml"
    assert main(["verify", prog, "--require-expr", "never %M0 OR %M1", "--require-expr",
                 "never %Q0.0 AND %I0.1", "-q", "--junit", str(report)]) == 2
    suite = ET.parse(report).getroot()
    assert (suite.get("tests"), suite.get("failures")) == ("2", "1")
    violated, proven = suite.findall("testcase")
    assert violated.get("name") == "never %M0 OR %M1"
    assert violated.find("failure").get("type") == "VIOLATED"
    assert "%M0 %M1" in violated.find("failure").text
    assert proven.find("failure") is None and proven.find("skipped") is None
    t = write(tmp_path, "t.il", "LD %I0.0\nIN %TM0\nLD %TM0.Q\nST %Q0.0\n")
    cfg = write(tmp_path, "t.toml", 'scan_period = "10ms"\n[timers."%TM0"]\ntype = "TON"\n'
                'base = "10ms"\npreset = 300\n')
    assert main(["verify", t, "--config", cfg, "--require-expr", "never %Q0.0", "-q",
                 "--no-spacer", "--max-k", "2", "--depth", "5", "--bounded",
                 "--junit", str(report)]) == 0
    case = ET.parse(report).getroot().find("testcase")
    assert case.find("skipped").get("type") == "UNKNOWN"
    assert "--depth" in case.find("skipped").text


def test_assumption_pinning_an_input_is_flagged(tmp_path, capsys):
    """`assume = ["NOT %I0.1"]` holds the stop button released forever: said so."""
    prog = write(tmp_path, "conveyor.il", CONVEYOR)
    req = write(tmp_path, "req.toml", '[environment]\nassume = ["NOT %I0.1"]\n\n'
                '[[requirement]]\ncheck = "never %Q0.0 AND %I0.1"\n')
    assert main(["verify", prog, "--require", req, "-q"]) == 0
    out = capsys.readouterr().out
    assert "! the assumptions hold %I0.1=0 in every scan" in out
    free = write(tmp_path, "free.toml", '[environment]\nassume = ["NOT (%I0.1 AND %M0)"]\n\n'
                 '[[requirement]]\ncheck = "never %Q0.0 AND %I0.1"\n')
    assert main(["verify", prog, "--require", free, "-q"]) == 0
    assert "the assumptions hold" not in capsys.readouterr().out  # both values possible


TWO_HAND = ("LD %I0.0\nIN %TM0\nLD %I0.1\nIN %TM1\nLD %I0.0\nAND %I0.1\nANDN %TM0.Q\n"
            "ANDN %TM1.Q\nOR %Q0.0\nAND %I0.0\nAND %I0.1\nST %Q0.0\n")
TWO_HAND_CFG = ('scan_period = "50ms"\n' + "".join(
    f'[timers."%TM{k}"]\ntype = "TON"\nbase = "10ms"\npreset = 50\n' for k in (0, 1)))


def test_two_hand_window_proven_by_induction(tmp_path, capsys):
    """Two-hand control, 0.5 s windows at 50 ms scans: the output starts only inside both
    windows. The timers' candidate invariants (the monitor's last trigger, the presets the
    program never writes), kept once inductive, make it k-inductive at a small k."""
    prog = write(tmp_path, "two_hand.il", TWO_HAND)
    cfg = write(tmp_path, "two_hand.toml", TWO_HAND_CFG)
    args = ["verify", prog, "--config", cfg, "-q", "--no-spacer", "--require-expr",
            "%Q0.0 rising -> %TM0.V < 50 AND %TM1.V < 50 within 0 scans"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "PROVEN" in out and "k-induction (k=" in out


def test_houdini_drops_a_candidate_the_program_breaks():
    """A preset the program writes is not taken for a constant; the one it never writes
    is, once checked inductive."""
    from softplc.verify.checker import Checker
    from softplc.verify.clock import Clock
    from softplc.verify.lemmas import houdini
    from softplc.verify.requirements import load_spec
    src = TWO_HAND + "LD %I0.2\n[ %TM0.P := 7 ]\n"
    config = {"scan_period": "50ms", "timers": {
        f"%TM{k}": {"type": "TON", "base": "10ms", "preset": 50} for k in (0, 1)}}
    plc = PLC.from_source(src, config, devices=False)
    spec = load_spec(None, ["%Q0.0 rising -> %TM0.V < 50 AND %TM1.V < 50 within 0 scans"],
                     plc.profile)
    ck = Checker(Model(plc, spec.reads), spec, spec.requirements[0])
    kept = houdini(ck, Clock(30))
    texts = [str(c) for c in ck.candidates(ck.pre)]
    assert any("%TM1.P" in texts[i] for i in kept) and any("_prev" in texts[i] for i in kept)
    # the two hands' timers have their own inputs: no relation between them is kept
    assert not any("%TM0._in" in texts[i] and "%TM1._in" in texts[i] for i in kept)
    assert not any("%TM0.P" in t for t in texts)  # written by the program: no candidate
