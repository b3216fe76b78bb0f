"""softplc verify's sound abstractions (issue 34 item 2): every shipped program without
floats loads; an abstraction's range always holds the engine's value; a counterexample
through an abstraction is reported only when the engine confirms it (CEGAR)."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from softplc.cli import main
from softplc.plc import PLC
from softplc.verify.model import Model
from softplc.verify.replay import set_inputs

ROOT = Path(__file__).resolve().parents[2]
LP = ROOT / "ladder_programs"
ABSTRACTED = ["fast_counter", "pid_oven", "pulse_axis", "pwm_heater", "remote_io"]
SCANS = 60


@pytest.mark.parametrize("name", ABSTRACTED)
def test_abstracted_programs_load_and_name_what_is_abstracted(name):
    plc = PLC.from_file(LP / f"{name}.il", LP / f"{name}.toml", devices=False)
    model = Model(plc)
    assert model.abstract.ranges and model.abstract.where
    assert all(" at " in w or "(configured)" in w for w in model.abstract.where.values())


@pytest.mark.parametrize("name", ABSTRACTED)
def test_abstraction_ranges_hold_the_engines_values(name):
    """Random inputs, with the machine's devices: after every scan each abstracted
    object's engine value is within the abstraction's range."""
    r = random.Random(name)
    with PLC.from_file(LP / f"{name}.il", LP / f"{name}.toml", devices=False) as bare:
        ranges = Model(bare).abstract.ranges
    inputs = [k for k in ("%I0.0", "%I0.1", "%I0.2", "%I0.3")]
    with PLC.from_file(LP / f"{name}.il", LP / f"{name}.toml") as plc:
        for n in range(SCANS):
            set_inputs(plc, {k: r.randrange(2) for k in inputs})
            plc.scan()
            for key, (_sort, lo, hi) in ranges.items():
                if not key.startswith("%") or "~" in key:
                    continue  # an abstracted float function: tested on its own
                v = int(plc[key])
                assert lo <= v <= hi, f"{name} scan {n + 1}: {key} = {v} not in {lo}..{hi}"


def test_pid_output_limits_proven_through_the_abstraction(capsys):
    args = ["verify", str(LP / "pid_oven.il"), "--config", str(LP / "pid_oven.toml"),
            "--require-expr", "always %QW2.0 >= 0 AND %QW2.0 <= 10000", "-q"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "abstracted (any value of its documented range" in out and "PID 0 at 17:3" in out
    assert "PROVEN" in out


def _pulse_generator(tmp_path: Path, enable: str) -> tuple[Path, Path]:
    """A program whose %Q0.4 copies %PLS0.Q, the generator run by `enable`, and its
    configuration (base 0.57 ms, preset 4, pulses = 0)."""
    prog = tmp_path / "p.il"
    prog.write_text(f"LD {enable}\nIN %PLS0\nLD %PLS0.Q\nST %Q0.4\n")
    cfg = tmp_path / "p.toml"
    cfg.write_text('scan_period = "10ms"\n[pls."%PLS0"]\nbase = "0.57ms"\npreset = 4\n'
                   "pulses = 0\n")
    return prog, cfg


def test_spurious_counterexample_refined_until_the_engine_confirms(tmp_path, capsys):
    """%PLS0.Q is free in the model; with %I0.0 = 0 the engine never sets it, so such a
    counterexample is excluded; the one reported has the generator running and replays."""
    prog, cfg = _pulse_generator(tmp_path, "%I0.0")
    args = ["verify", str(prog), "--config", str(cfg), "--require-expr", "never %Q0.4",
            "-q", "--timeout", "60"]
    assert main(args) == 2
    out = capsys.readouterr().out
    assert "replayed in the scan engine: same values in every scan" in out
    table = out.split("VIOLATED")[1]
    assert "%I0.0 | %Q0.4" in table and "1     1 |     1" in table


def test_unconfirmed_counterexamples_never_violated(tmp_path, capsys):
    """Without the generator's input the engine never pulses: the abstraction's
    counterexamples are all excluded and the answer is not VIOLATED."""
    prog, cfg = _pulse_generator(tmp_path, "0")
    args = ["verify", str(prog), "--config", str(cfg), "--require-expr", "never %Q0.4",
            "-q", "--timeout", "8", "--depth", "3", "--no-spacer"]
    assert main(args) == 1
    out = capsys.readouterr().out
    assert "VIOLATED" not in out and "UNKNOWN" in out


@pytest.mark.parametrize("src", [
    "LD 1\n[ %MF4 := %MF0[%MW1] + 1.0 ]\n", "LD [ %MF0[%MW1] < 1.0 ]\nST %Q0.0\n",
    "LD 1\n[ %MF4 := SIN(%MF0[%MW1]) ]\n", "LD 1\n[ %MW4 := REAL_TO_INT(%MF0[%MW1]) ]\n",
    "LD 1\n[ %MF0 := MEAN(%MF2:3) ]\n"])
def test_float_beside_an_unmodelled_construct_is_a_located_error(src):
    from softplc.errors import VerifyError
    plc = PLC.from_source(src, devices=False)
    with pytest.raises(VerifyError) as e:
        Model(plc)
    assert all(d.line == (1 if src.startswith("LD [") else 2) for d in e.value.diagnostics)
