"""Issue 11 B: the fast counter %FCi and the very fast counter %VFCi, counted between scans
from a simulated encoder, and the example ladder_programs/fast_counter.il.

Sources: TWD USE 10AE (Twido software reference), the %FC and %VFC function blocks, and
the TWDLCAE40DRF wiring (inputs %I0.2-%I0.5 for %FC0-3 at 5 kHz; %VFC0 on %I0.1/%I0.0
with preset %I0.2, catch %I0.3 and reflex outputs %Q0.2/%Q0.3, 20 kHz), all from memory:
not found in the search corpora (see docs/twido.md#fast-counters). Counting between
scans, the reflex outputs at the encoder's tick and losing pulses above the input's
frequency are our model of the hardware (softplc/runtime/fastcount.py).
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.debug.session import Session
from softplc.errors import ConfigError, ProgramError

EXAMPLE = ("ladder_programs/fast_counter.il", "ladder_programs/fast_counter.toml")

FC_BLOCK = "BLK %FC0\nLD %M0\nIN\nLD %M1\nS\nOUT_BLK\nLD D\nST %Q0.5\nEND_BLK\n"
VFC_BLOCK = "BLK %VFC0\nLD %M2\nIN\nLD %M3\nS\nEND_BLK\nLD %M4\nST %VFC0.R\n"


def fc_plc(fc: dict | None = None, encoder: dict | None = None, period: str = "10ms",
           src: str = FC_BLOCK) -> PLC:
    cfg = {"scan_period": period, "fast_counters": {"%FC0": fc or {}},
           "devices": {"enc": {"type": "encoder", "a": "%I0.2", "frequency": 1000.0,
                               **(encoder or {})}}}
    plc = PLC.from_source(src, cfg)
    plc["%M0"] = 1
    return plc


def vfc_plc(vfc: dict, encoder: dict | None = None, devices: dict | None = None,
            period: str = "10ms") -> PLC:
    cfg = {"scan_period": period, "very_fast_counters": {"%VFC0": vfc},
           # other devices first: their inputs change before the encoder's pulses
           "devices": {**(devices or {}), "enc": {"type": "encoder", "a": "%I0.1",
                                                  "b": "%I0.0", "frequency": 1000.0,
                                                  **(encoder or {})}}}
    plc = PLC.from_source(VFC_BLOCK, cfg)
    plc["%M2"] = plc["%M4"] = 1
    return plc


# ---- %FC ------------------------------------------------------------------------------------
def test_fc_counts_every_pulse_the_scan_would_miss():
    # 1 kHz on %I0.2 with a 10 ms scan: 10 edges a scan. The input image, sampled once a
    # scan, sees the same level every time (the pulse phase at a scan end never changes).
    plc = fc_plc()
    levels = set()
    for _ in range(100):
        plc.scan()
        levels.add(plc["%I0.2"])
    assert plc["%FC0.V"] == 1000  # 1 s at 1 kHz: every edge
    assert levels == {True}


def test_fc_up_done_at_preset_and_restarts_from_zero():
    # [manual, from memory] up counting: V reaches P -> D = 1, V starts again from 0;
    # D stays until the S input
    plc = fc_plc({"preset": 250})
    plc.scan(27)  # 270 edges counted
    assert plc["%FC0.D"] and plc["%Q0.5"] and plc["%FC0.V"] == 20
    plc["%M1"] = 1
    plc.scan()
    assert not plc["%FC0.D"] and plc["%FC0.V"] == 10  # S: 0, then this scan's pulses
    plc["%M1"] = 0
    plc.scan()
    assert plc["%FC0.V"] == 20


def test_fc_down_counts_from_the_preset_to_zero():
    plc = fc_plc({"mode": "down", "preset": 100})
    plc.scan(6)
    assert plc["%FC0.V"] == 40 and not plc["%FC0.D"]
    plc.scan(4)
    assert plc["%FC0.D"] and plc["%FC0.V"] == 100  # reached 0: D, the preset again


def test_fc_in_at_zero_freezes_the_count():
    plc = fc_plc()
    plc.scan(5)
    plc["%M0"] = 0
    plc.scan(5)
    assert plc["%FC0.V"] == 50


def test_fc_above_the_input_frequency_loses_pulses():
    # our choice: beyond 5 kHz (the %FC inputs' limit [manual, from memory]) the excess
    # edges are lost and counted in .lost
    plc = fc_plc(encoder={"frequency": 8000.0})
    plc.scan(11)
    fc = plc.mem.blocks["FC"][0]
    assert plc["%FC0.V"] == 550  # 0.11 s at 5 kHz
    assert fc.lost == 880 - 550


def test_fc_values_are_unsigned_words():
    # [manual, from memory] 16-bit values 0..65535: the program reads and writes them as
    # words (16#9C40 = 40000 reads as -25536, as a %MW would), the counter counts them
    # unsigned
    plc = fc_plc({"preset": 40010}, src=FC_BLOCK + "LD 1\n[ %MW0 := %FC0.V ]\n")
    fc = plc.mem.blocks["FC"][0]
    fc.V = 39980 - 65536
    plc.scan(2)  # 20 pulses; the program copied V before the second scan's pulses
    assert plc["%FC0.V"] == 40000 - 65536 and plc["%MW0"] == 39990 - 65536
    assert not plc["%FC0.D"]
    plc.scan()
    assert plc["%FC0.D"] and plc["%FC0.V"] == 0  # the preset 40010 reached


def test_fc_program_writes_the_preset():
    plc = fc_plc({"preset": 100}, src=FC_BLOCK + "LD %M9\n[ %FC0.P := 16#9C40 ]\n")
    plc["%M9"] = 1
    plc.scan()
    assert plc["%FC0.P"] == 40000 - 65536 and plc.mem.blocks["FC"][0].P & 0xFFFF == 40000


# ---- %VFC -----------------------------------------------------------------------------------
def test_vfc_quadrature_follows_an_axis_both_ways():
    stepper = {"type": "stepper", "phases": ["%Q0.6", "%Q0.7", "%Q0.8", "%Q0.9"]}
    plc = PLC.from_source(VFC_BLOCK, {
        "scan_period": "10ms",
        "very_fast_counters": {"%VFC0": {"mode": "quadrature", "preset": 1000}},
        "devices": {"X": stepper, "enc": {"type": "encoder", "a": "%I0.1", "b": "%I0.0",
                                          "axis": "X", "pulses_per_unit": 1.0}}})
    plc["%M2"] = plc["%M3"] = 1
    plc.scan()
    plc["%M3"] = 0
    assert plc["%VFC0.V"] == 1000  # S loads the preset
    axis = plc.devices["X"]
    enc = plc.devices["enc"]
    for target, up in ((40.0, True), (15.0, False)):
        while abs(axis.axis_position() - target) > 0.5:
            axis.position = axis.position + (1 if up else -1) * 1.0
            plc.scan()
        assert plc["%VFC0.V"] == 1000 + enc.pulses and plc["%VFC0.U"] == up
    assert plc["%VFC0.V"] == 1015


def test_vfc_down_below_zero_wraps_and_sets_f():
    plc = vfc_plc({"mode": "down", "preset": 5})
    assert plc["%VFC0.V"] == 5  # down counting starts from the preset
    plc.scan()
    assert plc["%VFC0.V"] == -5 and plc["%VFC0.F"]  # 5 - 10 wraps to 65531, overflow


def test_vfc_up_down_reads_its_direction_input():
    # up/down mode with the pulses on %I0.1 and the direction level on %I0.0 from another
    # device (a switch): 1 counts up, 0 down [our reading of TWD USE 10AE]
    plc = vfc_plc({"mode": "up_down"}, encoder={"b": None},
                  devices={"dir": {"type": "push_button", "input": "%I0.0"}})
    plc.devices["dir"].press()
    plc.scan(11)
    assert plc["%VFC0.V"] == 110
    plc.devices["dir"].release()
    plc.scan(4)
    assert plc["%VFC0.V"] == 70 and not plc["%VFC0.U"]


def test_reflex_output_switches_between_scans_at_the_threshold():
    # 1 kHz, 10 ms scans, 1 ms encoder tick: V reaches S0 = 55 at t = 55 ms, inside a
    # scan; the reflex output (zone table [0, 1, 0]) switches then, not at a scan
    # boundary, and goes off at S1 = 85 (t = 85 ms)
    plc = vfc_plc({"s0": 55, "s1": 85, "reflex0": [0, 1, 0]})
    plc.scan(6)
    events = list(plc.mem.counting.events)
    assert events == [(pytest.approx(0.055), "%VFC0", 0, 1)]
    assert plc.mem.q_field[2] == 1 and plc["%VFC0.TH0"] and not plc["%VFC0.TH1"]
    plc.scan(3)
    assert list(plc.mem.counting.events)[-1] == (pytest.approx(0.085), "%VFC0", 0, 0)
    assert plc.mem.q_field[2] == 0 and plc["%VFC0.TH1"]


def test_reflex_output_needs_its_enable_bit():
    plc = vfc_plc({"s0": 5, "reflex0": [0, 1, 1]})
    plc["%M4"] = 0  # %VFC0.R = 0: the counter leaves %Q0.2 alone
    plc.scan(3)
    assert plc["%VFC0.TH0"] and plc.mem.q_field[2] == 0
    plc["%M4"] = 1
    plc.scan(2)
    assert plc.mem.q_field[2] == 1


def test_catch_input_captures_the_value():
    plc = vfc_plc({"catch_input": True},
                  devices={"eye": {"type": "push_button", "input": "%I0.3"}})
    plc.scan(5)
    plc.devices["eye"].press()
    plc.scan(3)
    assert plc["%VFC0.C"] == 50  # the value when %I0.3 rose (seen at the next feed)
    assert plc["%VFC0.V"] == 80


def test_preset_input_loads_the_preset():
    plc = vfc_plc({"mode": "up_down", "preset": 500, "preset_input": True},
                  devices={"home": {"type": "push_button", "input": "%I0.2"}})
    plc.scan(5)
    plc.devices["home"].press()
    plc.scan()
    assert plc["%VFC0.V"] == 510  # loaded at the edge, then 10 pulses counted up


def test_frequency_meter():
    plc = vfc_plc({"mode": "frequency", "time_base": "100ms"}, encoder={"frequency": 1234.0})
    plc.scan(12)
    assert plc["%VFC0.V"] == pytest.approx(1234, abs=10)


def test_cold_start_restores_the_counters():
    plc = vfc_plc({"s0": 5, "s1": 8})
    plc.scan(3)
    assert plc["%VFC0.V"] == 30
    plc.engine.cold_start()
    assert plc["%VFC0.V"] == 0 and plc["%VFC0.S0"] == 5


# ---- checks: program and configuration ------------------------------------------------------
@pytest.mark.parametrize(("src", "message"), [
    ("LD %FC1.D\nST %Q0.5\n", "%FC1 is used but not configured"),
    ("LD %FC4.D\nST %Q0.5\n", "beyond the controller profile"),
    ("LD %VFC0.TH2\nST %Q0.5\n", "%VFC has fields"),
    ("LD 1\n[ %FC0.V := 3 ]\n", "cannot write %FC0.V"),
    ("LD %FC0.V\nST %Q0.5\n", "not a bit"),
    ("LD 1\nST %FC0.D\n", "cannot write %FC0.D"),
    ("BLK %FC0\nLD 1\nCU\nEND_BLK\n", "CU"),
])
def test_misuse_is_reported(src, message):
    with pytest.raises(ProgramError) as e:
        PLC.from_source(src, {"fast_counters": {"%FC0": {}}})
    assert message in str(e.value)


@pytest.mark.parametrize(("cfg", "message"), [
    ({"fast_counters": {"%FC0": {}}, "very_fast_counters": {"%VFC0": {"preset_input": True}}},
     "input %I0.2 is already"),
    ({"fast_counters": {"%FC0": {"mode": "sideways"}}}, 'fast_counters."%FC0".mode'),
    ({"very_fast_counters": {"%VFC0": {"reflex0": [0, 1]}}}, "reflex0"),
    ({"very_fast_counters": {"%VFC2": {}}}, "beyond the controller profile"),
    ({"fast_counters": {"%C0": {}}}, "is not a %FC counter"),
    ({"very_fast_counters": {"%VFC0": {"s0": 70000}}}, "s0"),
])
def test_configuration_errors(cfg, message):
    with pytest.raises(ConfigError) as e:
        PLC.from_source("LD 1\nST %Q0.5\n", cfg)
    assert message in str(e.value)


def test_encoder_options_are_checked():
    with pytest.raises(ConfigError) as e:
        fc_plc(encoder={"axis": "X"})
    assert "either axis" in str(e.value)


# ---- the example and the debugger ------------------------------------------------------------
def test_example_marks_the_belt_and_counts_a_batch():
    plc = PLC.from_file(*EXAMPLE)
    plc.devices["start"].press()
    plc.scan()
    plc.devices["start"].release()
    plc.run(2.9)
    # marks at 1000, 2200 pulses: 1000 pulses/s from t = 0.01 s; a part every 0.5 s
    marks = [e for e in plc.mem.counting.events if e[3] == 1]
    assert [round(e[0], 3) for e in marks] == [1.01, 2.21]
    assert plc["%MW0"] == 2 and plc["%MW1"] == 5
    plc.run(2.5)
    assert plc["%Q0.4"] and not plc["%Q0.0"]  # 10 parts: batch complete, belt stopped
    stopped_at = plc["%MW2"]
    plc.run(0.5)
    assert plc["%MW2"] == stopped_at  # no pulse while the belt stands
    plc.devices["reset"].press()
    plc.scan(2)  # the button's input is latched by the next scan
    assert plc["%MW1"] == 0 and plc["%MW0"] == 0 and not plc["%Q0.4"]


def test_repl_shows_the_counters():
    s = Session(PLC.from_file(*EXAMPLE), EXAMPLE[0])
    s.plc.devices["start"].press()
    s.execute("scan 120")
    out = s.execute("print %VFC0")
    assert "V=1190" in out and "S0=2200" in out and "TH0=0" in out
    assert s.execute("print %FC0.V") == "%FC0.V PART_COUNTER.V = 2"  # fast_counter.toml names it
    s.execute("set %VFC0.S0 40000")  # a word: the unsigned threshold 40000
    s.execute("scan")
    assert s.plc.mem.blocks["VFC"][0].S0 & 0xFFFF == 40000 and s.plc.engine.state == "RUN"
    assert s.execute("print/u %VFC0.S0") == "%VFC0.S0 BELT_ENCODER.S0 = 40000"
    counters = s.execute("counters")
    rows = {line.split()[0]: line.split()[1] for line in counters.splitlines()}
    assert rows == {"%FC0": "up", "%VFC0": "quadrature"}
