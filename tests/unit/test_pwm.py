"""Issue 11 B: the pulse width modulator %PWM on the TWDLCAE40DRF's transistor outputs
%Q0.0 / %Q0.1 (sharing them with %PLS: tests/unit/test_pulse.py), a PWM-heated oven and the
example ladder_programs/pwm_heater.il.

Sources: the TWDLCAE40DRF offers PLS and PWM on its 2 transistor outputs [manual: Twido
hardware guide, quoted in seed thesis 003]; the block's fields, input, time bases and
ranges [manual, from memory of TWD USE 10AE: see docs/twido.md#pulse-outputs].
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.cli import main as softplc
from softplc.errors import ConfigError, ProgramError


def test_pwm_duty_and_level():
    # [manual] period P x base, the ratio .R per cent high, while IN = 1
    src = "LD %M0\nIN %PWM1\nLD 1\n[ %PWM1.R := %MW0 ]\n"
    plc = PLC.from_source(src, {"scan_period": "10ms", "pwm": {
        "%PWM1": {"base": "10ms", "preset": 10, "ratio": 0}}})
    gen = plc.mem.pulses.source(1)
    plc["%MW0"] = 30
    plc.scan()
    assert gen.duty() == 0.0 and not plc["%Q0.1"]  # IN = 0: output 0
    plc["%M0"] = 1
    levels = []
    for _ in range(20):
        plc.scan()
        levels.append(plc["%Q0.1"])
    assert gen.duty() == 0.3 and levels == ([1] * 3 + [0] * 7) * 2
    plc["%MW0"] = 250  # [our choice] out of range: clamped to 0..100
    plc.scan()
    assert plc["%PWM1.R"] == 100 and gen.duty() == 1.0


@pytest.mark.parametrize(("src", "cfg", "message"), [
    ("LD 1\nIN %PWM0\n", {}, "pwm.\"%PWM0\""),
    ("LD %PWM0.R\nST %Q0.5\n", {"pwm": {"%PWM0": {}}}, "not a bit"),
    ("LD 1\nST %Q0.1\n", {"pwm": {"%PWM1": {}}}, "ST %Q0.1: the output is driven by %PWM1"),
])
def test_misuse_is_a_clear_program_error(src, cfg, message):
    with pytest.raises(ProgramError) as e:
        PLC.from_source(src, cfg)
    assert message in str(e.value)


@pytest.mark.parametrize(("cfg", "message"), [
    ({"pls": {"%PLS0": {}}, "pwm": {"%PWM0": {}}}, "%Q0.0 is already the output of %PLS0"),
    ({"pwm": {"%PWM0": {"ratio": 101}}}, "pwm.\"%PWM0\".ratio"),
    ({"pwm": {"%PWM0": {}}, "pid": {"0": {"measure": "%MW0", "setpoint": 5,
                                         "pwm_output": "%Q0.0"}}},
     "pid.0.pwm_output: %Q0.0 is the output of %PWM0"),
])
def test_bad_configuration_is_a_clear_config_error(cfg, message):
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %Q0.5\n", cfg)
    assert message in str(e.value)


def test_a_stepper_names_pwm_as_a_step_source():
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %Q0.5\n", {"devices": {"x": {
            "type": "stepper", "step": "%Q0.3", "direction": "%Q0.4", "steps_per_unit": 1.0}}})
    assert "is not driven by a configured %PLS or %PWM" in str(e.value)


def test_oven_heater_on_a_pwm_output_gets_the_duty_cycle():
    src = "LD 1\nIN %PWM0\n[ %PWM0.R := 25 ]\n"
    plc = PLC.from_source(src, {
        "scan_period": "100ms", "modules": {"2": "TWDALM3LT"},
        "analog": {"%IW2.0": {"type": "PT100", "range": "celsius"}},
        "pwm": {"%PWM0": {"base": "10ms", "preset": 100}},
        "devices": {"oven": {"type": "oven", "sensor": "%IW2.0", "heater_bit": "%Q0.0",
                             "gain": 200.0, "tau": 10.0, "dead_time": 0.0}}})
    plc.run(120.0)
    oven = plc.devices["oven"]
    assert oven.power == 0.25 and oven.temperature == pytest.approx(70.0, abs=0.01)


# ---- the example ----------------------------------------------------------------------------
HEATER = ("ladder_programs/pwm_heater.il", "ladder_programs/pwm_heater.toml")


def test_pwm_heater_example_holds_the_set_point():
    plc = PLC.from_file(*HEATER)
    plc["%I0.0"] = 1
    plc.run(300.0)
    oven = plc.devices["oven"]
    assert oven.temperature == pytest.approx(80.0, abs=0.2) and plc["%Q0.2"]
    assert oven.power == plc["%PWM1.R"] / 100
    plc["%I0.0"] = 0  # heating off: the oven cools
    plc.run(60.0)
    assert oven.power == 0.0 and oven.temperature < 50.0


def test_check_accepts_the_example(capsys):
    assert softplc(["check", HEATER[0], "--config", HEATER[1]]) == 0
