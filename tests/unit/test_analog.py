"""Issue 11 B: analog I/O (%IWm.c, %QWm.c), channel configuration, status words, the oven
device, and the analog thermostat example (ladder_programs/analog_thermostat.il).

Sources: TwidoSuite's analog module configuration (signal type; range normal 0-4095,
custom min..max, celsius/fahrenheit in tenths for temperature sensors) [manual, from
memory, see docs/twido.md#analog-io]; the status-word layout is our choice.
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.errors import ConfigError, ProgramError

MODS = {"modules": {1: "TWDAMM3HT", 2: "TWDALM3LT", 3: "TWDAMO1HT"}}


def plc_with(analog: dict, src: str = "LD 1\n[ %MW0 := %IW1.0 ]\n", **kw) -> PLC:
    return PLC.from_source(src, {**MODS, "analog": analog}, **kw)


@pytest.mark.parametrize("cfg, value, word", [
    ({"type": "0-10V"}, 5.0, 2048),                               # normal 0..4095
    ({"type": "0-10V"}, 10.0, 4095),
    ({"type": "4-20mA"}, 4.0, 0),
    ({"type": "4-20mA"}, 20.0, 4095),
    ({"type": "4-20mA", "range": "custom", "min": 0, "max": 1000}, 12.0, 500),
    ({"type": "0-10V", "range": "custom", "min": -100, "max": 100}, 2.5, -50),
])
def test_input_conversion(cfg, value, word):
    plc = plc_with({"%IW1.0": cfg})
    assert plc.mem.analog.set_input("%IW1.0", value) == word
    plc.scan()
    assert plc["%MW0"] == word and plc["%SW81"] == 0


@pytest.mark.parametrize("rng, temp, word", [("celsius", 123.4, 1234),
                                             ("fahrenheit", 100.0, 2120)])
def test_temperature_ranges_in_tenths(rng, temp, word):
    plc = plc_with({"%IW2.1": {"type": "PT100", "range": rng}})
    assert plc.mem.analog.set_input("%IW2.1", temp) == word


def test_out_of_span_is_clamped_and_flagged_in_the_status_word():
    plc = plc_with({"%IW1.1": {"type": "4-20mA"}})
    assert plc.mem.analog.set_input("%IW1.1", 2.0) == 0        # under range (broken wire)
    assert plc["%SW81"] == 1 << 4                               # channel 1: bits 4-7
    assert plc.mem.analog.set_input("%IW1.1", 25.0) == 4095
    assert plc["%SW81"] == 2 << 4
    plc.mem.analog.set_input("%IW1.1", 10.0)
    assert plc["%SW81"] == 0


def test_outputs_convert_back_clamped():
    src = "LD 1\n[ %QW1.0 := %MW0 ]\n[ %QW3.0 := %MW1 ]\n"
    plc = plc_with({"%QW3.0": {"type": "4-20mA", "range": "custom", "min": 0, "max": 100}},
                   src)
    plc["%MW0"], plc["%MW1"] = 4095, 50
    plc.scan()
    assert plc.mem.analog.output("%QW1.0") == pytest.approx(10.0)
    assert plc.mem.analog.output("%QW3.0") == pytest.approx(12.0)
    plc["%MW0"], plc["%MW1"] = 9000, -5
    plc.scan()
    assert plc.mem.analog.output("%QW1.0") == pytest.approx(10.0)
    assert plc.mem.analog.output("%QW3.0") == pytest.approx(4.0)


def test_base_potentiometer_and_voltage_input():
    plc = PLC.from_source("LD 1\n[ %MW0 := %IW0.0 ]\n[ %MW1 := %IW0.2 ]\n")
    plc.mem.analog.set_input("%IW0.0", 0.5)
    plc.mem.analog.set_input("%IW0.2", 10.0)
    plc.scan()
    assert plc["%MW0"] == 512 and plc["%MW1"] == 1023


@pytest.mark.parametrize("cfg, message", [
    ({"modules": {1: "TWDAMI2HT"}, "analog": {"%IW1.0": {"type": "PT100"}}},
     "type 'PT100' not available on this channel"),
    ({"modules": {1: "TWDAMI2HT"}, "analog": {"%IW1.0": {"type": "0-10V", "rnage": "x"}}},
     "analog.\"%IW1.0\".rnage: unknown key; known: max, min, range, type"),
    ({"modules": {1: "TWDAMI2HT"}, "analog": {"%IW1.0": {"type": "0-10V",
                                                           "range": "celsius"}}},
     "is for temperature sensors"),
    ({"modules": {1: "TWDAMI2HT"}, "analog": {"%IW1.0": {"type": "0-10V", "min": 5}}},
     "min/max apply to range = \"custom\" only"),
    ({"analog": {"%IW4.0": {"type": "0-10V"}}}, "no such analog channel"),
    ({"modules": {1: "TWDAMO1HT"}, "analog": {"%IW1.0": {"type": "0-10V"}}},
     "no such analog channel"),
    ({"modules": {1: "TWDAMX9"}}, "unknown module"),
])
def test_config_errors_name_the_key(cfg, message):
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %M0\n", cfg)
    assert message in str(e.value)


@pytest.mark.parametrize("src, message", [
    ("LD 1\n[ %IW1.0 := 5 ]\n", "cannot write %IW1.0: it is an analog input"),
    ("LD 1\n[ %MW0 := %IW1.2 ]\n", "no such analog channel"),
    ("LD 1\n[ %QW0.0 := 1 ]\n", "no such analog channel"),
    ("LD 1\n[ %MW0 := %IW1.9 ]\n", "analog channel 9 beyond 7"),
    ("LD %IW1.0\nST %M0\n", "not a bit"),
])
def test_program_errors(src, message):
    with pytest.raises(ProgramError) as e:
        PLC.from_source(src, MODS)
    assert message in str(e.value)


def test_oven_first_order_plus_dead_time():
    cfg = {**MODS, "analog": {"%IW2.0": {"type": "PT100", "range": "celsius"}},
           "scan_period": "100ms",
           "devices": {"oven": {"type": "oven", "sensor": "%IW2.0", "heater": "%QW1.0",
                                "gain": 100.0, "tau": 10.0, "dead_time": 2.0}}}
    plc = PLC.from_source("LD %M0\n[ %QW1.0 := 4095 ]\n", cfg)
    plc["%M0"] = 1
    plc.run(1.9)
    assert plc.devices["oven"].temperature == pytest.approx(20.0), "dead time: no reaction"
    plc.run(10.0)                      # one time constant after the dead time: 63 %
    assert plc.devices["oven"].temperature == pytest.approx(20 + 100 * 0.632, abs=1.5)
    plc.run(100)
    assert plc["%IW2.0"] == pytest.approx(1200, abs=2), "the sensor word, in tenths"


def test_oven_config_errors():
    cfg = {**MODS, "devices": {"oven": {"type": "oven", "sensor": "%IW1.0"}}}
    with pytest.raises(ConfigError, match="give one of heater"):
        PLC.from_source("LD 1\nST %M0\n", cfg)
    cfg["devices"]["oven"]["heater"] = "%QW2.1"
    with pytest.raises(ConfigError, match="not a configured analog output"):
        PLC.from_source("LD 1\nST %M0\n", cfg)


# ---- the example program ------------------------------------------------------------------
THERMOSTAT = ("ladder_programs/analog_thermostat.il", "ladder_programs/analog_thermostat.toml")


@pytest.mark.plc_program(*THERMOSTAT[:1], config=THERMOSTAT[1])
def test_thermostat_holds_the_set_point(plc):
    plc.mem.analog.set_input("%IW0.0", 0.4)          # the pot at 40 %: 409 -> 102 degrees
    plc.run(600)
    temps, heating = [], []
    for _ in range(600):
        plc.run(1)
        temps.append(plc.devices["oven"].temperature)
        heating.append(plc["%Q0.0"])
    assert plc["%MW0"] == 102
    assert 102 - 25 < min(temps) and max(temps) < 102 + 25, "a limit cycle round the set point"
    assert any(heating) and not all(heating)
    assert not plc["%Q0.1"]


def test_thermostat_sensor_fault_stops_heating():
    plc = PLC.from_file(*THERMOSTAT, devices=False)
    plc.mem.analog.set_input("%IW0.0", 0.4)
    plc.mem.analog.set_input("%IW2.0", 20.0)
    plc.scan()
    assert plc["%Q0.0"] and plc["%QW2.0"] == 4095
    plc.mem.analog.set_input("%IW2.0", 900.0)        # a PT100 with a broken wire
    plc.scan()
    assert plc["%Q0.1"] and not plc["%Q0.0"] and plc["%QW2.0"] == 0


def test_analog_source_follows_its_profile():
    cfg = {**MODS, "analog": {"%IW1.0": {"type": "4-20mA", "range": "custom", "min": 0,
                                         "max": 1000}},
           "scan_period": "1s",
           "devices": {"level": {"type": "analog_source", "input": "%IW1.0",
                                 "profile": [[0, 4.0], [10, 20.0], [20, 20.0], [30, 2.0]]}}}
    plc = PLC.from_source("LD 1\n[ %MW0 := %IW1.0 ]\n", cfg)
    plc.run(5)                            # the device runs after each scan: t = 1..5 s
    assert plc["%IW1.0"] == 500 and plc.devices["level"].value == pytest.approx(12.0)
    plc.run(10)
    assert plc["%IW1.0"] == 1000
    plc.run(15)                           # t = 30: 2 mA, under range (a broken wire)
    assert plc["%IW1.0"] == 0 and plc["%SW81"] == 1


@pytest.mark.parametrize("dev, message", [
    ({"input": "%IW1.1", "profile": [[0, 1], [0, 2]]}, "devices.s.profile: times must increase"),
    ({"input": "%IW1.1", "profile": [[0]]}, "devices.s.profile[0]: list should have at least 2"),
    ({"input": "%QW1.0"}, "input: %QW1.0 is not a configured analog input"),
])
def test_analog_source_config_errors(dev, message):
    cfg = {**MODS, "devices": {"s": {"type": "analog_source", **dev}}}
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %M0\n", cfg)
    assert message in str(e.value)


def test_bipolar_output_normal_range():
    # +-10 V on a 12-bit channel: -2048..2047 (the "-2048..2047" range)
    plc = PLC.from_source("LD 1\n[ %QW4.1 := %MW0 ]\n", {"modules": {4: "TWDAVO2HT"}})
    for word, volts in ((-2048, -10.0), (2047, 10.0), (0, 0.0024)):
        plc["%MW0"] = word
        plc.scan()
        assert plc.mem.analog.output("%QW4.1") == pytest.approx(volts, abs=0.003)
