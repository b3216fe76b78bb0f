"""The machines' requirement files (issue 34 item 3): counterexamples `softplc verify`
found in the shipped programs, kept as tests once the program was fixed, and the quick
proofs of the servo cell (the slow ones: tools/bench_verify.py --machines)."""

from __future__ import annotations

from pathlib import Path

from softplc.cli import main
from softplc.plc import PLC
from softplc.verify.replay import first_failure

ROOT = Path(__file__).resolve().parents[2]
LP = ROOT / "ladder_programs"


def test_mass_tuning_amber_lamp_off_in_fault():
    """VIOLATED before the fix, in 2 scans: the softkey in automatic mode starts the
    measurement, automatic mode lost in the next scan sends it to FAULT (step 40), and the
    amber lamp, computed from the scan's first steps, stayed lit in that scan."""
    scans = [{"%I0.0": 1, "%I0.1": 1}, {"%I0.0": 0, "%I0.1": 0}]
    with PLC.from_file(LP / "mass_tuning.il", LP / "mass_tuning.toml", devices=False) as plc:
        assert first_failure(plc, "never %X40 AND %Q0.2", scans) is None
        assert plc["%X40"] == 1  # the fault did happen: the lamp is what changed


def test_servo_cell_requirements_proven(capsys):
    args = ["verify", str(LP / "servo_table.il"), "--config", str(LP / "servo_table.toml"),
            "--require", str(LP / "servo_table.req.toml"), "-q"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.count("PROVEN") == 3
    assert "free, written by device X" in out  # the drives' status words
