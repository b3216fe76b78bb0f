"""Issue 11 B: the pulse generator %PLS on the TWDLCAE40DRF's transistor outputs %Q0.0 /
%Q0.1, the step/direction stepper that reads it and the example
ladder_programs/pulse_axis.il (%PWM: tests/unit/test_pwm.py).

Sources: the TWDLCAE40DRF has 14 relay and 2 transistor outputs and offers PLS and PWM
[manual: Twido hardware guide, quoted in seed thesis 003]; the blocks' fields, inputs,
time bases and ranges [manual, from memory of TWD USE 10AE: see
docs/twido.md#pulse-outputs]; pause/resume on IN, a new period from the next pulse [our choice].
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.cli import main as softplc
from softplc.debug.session import Session
from softplc.errors import ConfigError, ProgramError
from softplc.persist import retain

PLS = "LD %M0\nIN %PLS0\nLD %M1\nR %PLS0\nLD %PLS0.D\nST %M2\nLD %PLS0.Q\nST %M3\n"


def pls(preset: int = 2, pulses: int = 5, base: str = "10ms", src: str = PLS,
        **cfg) -> PLC:
    return PLC.from_source(src, {"scan_period": "10ms", **cfg, "pls": {
        "%PLS0": {"base": base, "preset": preset, "pulses": pulses}}})


def count(plc: PLC, q: int = 0) -> int:
    return plc.mem.pulses.source(q).pulses_at(round(plc.time * 1e6))


def test_pls_sends_n_pulses_then_sets_done():
    # [manual] N pulses of period P x base; Q while generating; D once the N are out
    plc = pls(preset=2, pulses=5)  # period 20 ms
    plc["%M0"] = 1
    levels = []
    for _ in range(10):
        plc.scan()
        levels.append(plc["%Q0.0"])
        assert plc["%M3"] and not plc["%M2"]
    assert levels == [1, 0] * 5  # %Q shows the level (50 % duty) at each scan time
    assert count(plc) == 5
    plc.scan()  # the 5th pulse ended at 100 ms
    assert plc["%M2"] and not plc["%M3"] and not plc["%Q0.0"]
    plc.run(1.0)
    assert count(plc) == 5 and plc["%M2"]  # done holds while IN stays 1, no more pulses


def test_pls_with_n_zero_runs_on_and_counts_at_khz():
    # [manual] N = 0: no limit. 0.142 ms x 7 = 994 us: about 1 kHz, 10 pulses a scan
    plc = pls(preset=7, pulses=0, base="0.142ms")
    plc["%M0"] = 1
    plc.run(1.0)
    assert count(plc) == 1_000_000 // 994 + 1
    assert plc["%M3"] and not plc["%M2"]


def test_in_pauses_and_r_resets_the_count():
    plc = pls(preset=2, pulses=5)
    plc["%M0"] = 1
    plc.scan(4)  # t = 40 ms: the pulses at 0, 20 and 40 ms have started
    assert count(plc) == 3
    plc["%M0"] = 0  # [manual] IN = 0: the output is 0; [our choice] the train pauses
    plc.run(0.5)
    assert count(plc) == 3 and not plc["%Q0.0"] and not plc["%M3"]
    plc["%M0"] = 1  # resumes with the pulses still due
    plc.run(0.2)
    assert count(plc) == 5 and plc["%M2"]
    plc["%M1"] = 1  # [manual] R: Q and D to 0, the count to 0; a new train of N
    plc.scan()
    assert not plc["%M2"]
    plc["%M1"] = 0
    plc.run(0.2)
    assert plc["%M2"] and count(plc) == 10  # devices see a monotonic total


def test_a_new_period_applies_from_the_next_pulse():
    src = PLS + "LD %M5\n[ %PLS0.P := 10 ]\n"
    plc = pls(preset=2, pulses=0, src=src)
    plc["%M0"] = 1
    plc.scan(5)  # pulses at 0, 20, 40 ms
    plc["%M5"] = 1  # .P := 10 at 50 ms; the block sees it at 60 ms (that pulse is out)
    plc.run(0.2)  # the next pulse, at 80 ms, has the new period: 80, 180 ms
    assert plc["%PLS0.P"] == 10 and count(plc) == 6


def test_generator_runs_on_when_its_block_is_skipped():
    # the pulse output is hardware: jumping over the block does not stop it
    src = "LD %M7\nJMPCN %L1\nLD %M0\nIN %PLS0\n%L1:\nLD %PLS0.D\nST %M2\n"
    plc = pls(preset=1, pulses=3, src=src)
    plc["%M0"] = plc["%M7"] = 1
    plc.scan()
    plc["%M7"] = 0
    plc.scan(6)
    assert count(plc) == 3 and plc["%M2"]


def test_blk_form_with_in_r_and_the_done_output():
    src = "BLK %PLS0\nLD %M0\nIN\nLD %M1\nR\nOUT_BLK\nLD D\nST %Q0.3\nLD Q\nST %Q0.4\nEND_BLK\n"
    plc = pls(preset=1, pulses=2, src=src)
    plc["%M0"] = 1
    plc.scan()
    assert plc["%Q0.4"] and not plc["%Q0.3"]
    plc.scan(4)
    assert plc["%Q0.3"] and not plc["%Q0.4"] and count(plc) == 2
    plc["%M1"] = 1
    plc.scan()
    assert not plc["%Q0.3"]


def test_pls_objects_in_the_repl():
    plc = pls(preset=3, pulses=7)
    s = Session(plc, "<string>")
    out = s.execute("print %PLS0")
    assert "P=3" in out and "N=7" in out and "D=0" in out
    assert s.execute("print %PLS0.N").strip().endswith("7")
    plc["%M0"] = 1
    s.execute("run 100ms")
    out = s.execute("pulses")
    assert out.startswith("%PLS0 on %Q0.0") and "P=3 (30 ms, 33.33 Hz) N=7" in out
    assert "pulses=4 duty=0.50" in out


@pytest.mark.parametrize(("src", "cfg", "message"), [
    ("LD 1\nIN %PLS1\n", {}, "%PLS1 is used but not configured: %Q0.1 must be configured"),
    ("LD 1\nIN %PLS2\n", {}, "beyond the controller profile"),
    ("LD 1\nST %PLS0.D\n", {"pls": {"%PLS0": {}}}, "cannot write %PLS0.D"),
    ("LD 1\nCU %PLS0\n", {"pls": {"%PLS0": {}}}, "%PLS has no input CU"),
])
def test_misuse_is_a_clear_program_error(src, cfg, message):
    with pytest.raises(ProgramError) as e:
        PLC.from_source(src, cfg)
    assert message in str(e.value)


@pytest.mark.parametrize(("cfg", "message"), [
    ({"pls": {"%PLS0": {"base": "0.142ms", "preset": 300}}}, "0..255 with the 0.142ms"),
    ({"pls": {"%PLS0": {"base": "2ms"}}}, "pls.\"%PLS0\".base"),
    ({"pls": {"%PLS0": {"pulse": 3}}}, "pulse"),
    ({"pls": {"%TM0": {}}}, "is not a %PLS object"),
])
def test_bad_configuration_is_a_clear_config_error(cfg, message):
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %Q0.5\n", cfg)
    assert message in str(e.value)


def test_a_retained_generator_goes_on_at_the_same_point(tmp_path):
    # its run's start is saved relative to the clock (as a timer's), which restarts at 0
    plc = pls(preset=2, pulses=10)
    plc["%M0"] = 1
    plc.run(0.05)  # pulses at 0, 20, 40 ms
    retain.save(tmp_path / "s", retain.capture(plc.mem))
    new = pls(preset=2, pulses=10)
    retain.apply(new.mem, retain.load(tmp_path / "s"))
    new["%M0"] = 1
    new.run(0.15)  # the 40 ms pulse is at 0 on the new clock: 7 due at 20 .. 140 ms
    assert count(new) == 10 and not new["%M2"]
    new.scan(2)  # the 10th ends at 160 ms
    assert new["%M2"]


def test_the_debugger_back_restores_the_generator():
    plc = pls(preset=2, pulses=0)
    plc["%M0"] = 1
    plc.scan(3)
    snap = plc.engine.snapshot()
    plc.scan(10)
    plc.engine.restore(snap)
    assert count(plc) == 2  # pulses at 0 and 20 ms, as at t = 30 ms
    plc.scan(10)
    assert count(plc) == 7


def test_programs_without_pulse_outputs_pay_nothing():
    plc = PLC.from_source("LD %I0.0\nST %Q0.0\n")
    assert plc.engine.pulses is None and plc.mem.pulses is None


# ---- devices -------------------------------------------------------------------------------
def stepper_plc(rate: float = 1000.0, preset: int = 4, **dev) -> PLC:
    src = "LD %M0\nIN %PLS0\nLD %M1\nST %Q0.2\n"
    return PLC.from_source(src, {"scan_period": "10ms", "pls": {
        "%PLS0": {"base": "0.57ms", "preset": preset, "pulses": 0}}, "devices": {"x": {
            "type": "stepper", "step": "%Q0.0", "direction": "%Q0.2",
            "max_step_rate": rate, "travel": 50.0, "steps_per_unit": 100.0, **dev}}})


def test_stepper_takes_one_step_per_pulse_in_the_direction_output():
    plc = stepper_plc()  # 2.28 ms: 438.6 pulses/s
    x = plc.devices["x"]
    plc["%M0"] = plc["%M1"] = 1
    plc.run(1.0)
    assert x.position == count(plc) == 1_000_000 // 2280 + 1 and x.missed_steps == 0
    assert x.status() == {"pos": 439, "units": 4.39, "missed": 0, "pulses": 439}
    plc["%M1"] = 0  # direction output 0: - steps
    plc.run(0.5)
    assert x.position == 2 * 439 - count(plc)


def test_stepper_misses_pulses_faster_than_it_can_follow():
    plc = stepper_plc(rate=200.0)  # 438.6 pulses/s into a 200 steps/s motor
    x = plc.devices["x"]
    plc["%M0"] = plc["%M1"] = 1
    plc.run(1.0)
    assert x.position == 200 and x.missed_steps == count(plc) - 200


def test_stepper_pulses_into_the_hard_stop_are_missed():
    plc = stepper_plc(travel=1.0, hard_stop_margin=0.5)  # the stop at 1.5 units: 150 steps
    x = plc.devices["x"]
    plc["%M0"] = plc["%M1"] = 1
    plc.run(1.0)
    assert x.position == 150 and x.missed_steps == count(plc) - 150


@pytest.mark.parametrize(("dev", "message"), [
    ({"step": "%Q0.3"}, "%Q0.3 is not driven by a configured %PLS"),
    ({"phases": ["%Q1.0", "%Q1.1", "%Q1.2", "%Q1.3"]}, "phases"),
])
def test_stepper_step_source_errors(dev, message):
    with pytest.raises(ConfigError) as e:
        stepper_plc(**dev)
    assert message in str(e.value)


# ---- examples ------------------------------------------------------------------------------
AXIS = ("ladder_programs/pulse_axis.il", "ladder_programs/pulse_axis.toml")


def move(plc: PLC, target: int) -> None:
    plc["%I0.0"] = 0
    plc["%MW10"] = target
    plc.scan()
    plc["%I0.0"] = 1
    plc.scan()
    assert plc["%M0"] and plc["%Q0.4"] and not plc["%Q0.3"]
    assert plc.run_until(lambda p: p["%Q0.3"], 10.0)


def test_pulse_axis_example_positions_the_stepper():
    plc = PLC.from_file(*AXIS)
    x = plc.devices["x"]
    move(plc, 1000)
    assert x.position == 1000 and plc["%MW12"] == 1000 and not plc["%M0"]
    assert plc.time == pytest.approx(1000 * 2.28e-3, abs=0.03)  # 439 Hz
    move(plc, 250)  # back: direction output 0, 750 pulses
    assert x.position == 250 and plc["%MW12"] == 250 and x.missed_steps == 0


@pytest.mark.parametrize("example", [AXIS])
def test_check_accepts_the_examples(example, capsys):
    assert softplc(["check", example[0], "--config", example[1]]) == 0
