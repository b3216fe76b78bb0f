"""The scan cycle and the PLC API: input/output images at scan boundaries, first-scan
bits %S0/%S1/%S13, clocks %S4-%S7, scan times %SW30-%SW32, forcing, RUN/STOP/HALT,
cold and warm start, the deterministic virtual clock, plc[...] access, configuration as a
dict or a TOML file.

Semantics from docs/twido.md ([sure]/[m221]/[manual] tags as there).
"""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.errors import AddressError, ConfigError, SoftPLCError

COPY = """
LD    %I0.0
ST    %Q0.0
"""


# ---- I/O images [manual] --------------------------------------------------------------------
def test_inputs_are_latched_at_the_start_of_a_scan(plc_from_source):
    plc = plc_from_source(COPY)
    plc["%I0.0"] = 1
    assert not plc["%I0.0"]  # the input image changes at the next scan only
    assert not plc.mem.q_field[0]
    plc.scan()
    assert plc["%I0.0"] and plc["%Q0.0"]


def test_input_image_is_stable_during_the_scan(plc_from_source):
    """A device changing a field input during the scan is not seen until the next one."""
    plc = plc_from_source("""
LD    %I0.0
ST    %M0
LD    1
[ INC %MW0 ]
LD    %I0.0
ST    %M1
""")
    plc["%I0.0"] = 1

    class Flip:  # runs after the program, like a simulated device
        def update(self, t, dt):
            plc.mem.i_field[0] = 0

    plc.engine.devices = {"flip": Flip()}
    plc.scan()
    assert plc["%M0"] and plc["%M1"]
    assert plc.mem.i_field[0] == 0 and plc["%I0.0"]  # the image keeps the latched value
    plc.scan()
    assert not plc["%M0"] and not plc["%M1"]


def test_outputs_reach_the_field_at_the_end_of_the_scan(plc_from_source):
    plc = plc_from_source("""
LD    1
ST    %Q0.3
LD    %Q0.3
ST    %M0
""")
    seen = []
    plc.before_scan.append(lambda: seen.append(plc.mem.q_field[3]))
    plc.scan(2)
    assert seen == [0, 1]  # the field got %Q0.3 after the first scan
    assert plc["%M0"]  # the program reads its own output image at once


def test_output_image_is_published_once(plc_from_source):
    """A rung that pulses an output within one scan never shows the pulse on the field."""
    plc = plc_from_source("""
LD    1
ST    %Q0.1
LD    0
ST    %Q0.1
""")
    field = []
    plc.after_scan.append(lambda: field.append(plc.mem.q_field[1]))
    plc.scan(3)
    assert field == [0, 0, 0]


# ---- first-scan bits [manual; %S13 sure] ----------------------------------------------------
FIRST = """
LD    %S0
[ INC %MW0 ]
LD    %S1
[ INC %MW1 ]
LD    %S13
[ INC %MW2 ]
"""


def firsts(plc: PLC) -> tuple[int, int, int]:
    return plc["%MW0"], plc["%MW1"], plc["%MW2"]


def test_cold_start_bits(plc_from_source):
    plc = plc_from_source(FIRST)
    plc.scan(5)
    assert firsts(plc) == (1, 0, 1)  # %S0 and %S13 on the first scan only
    assert not plc["%S0"] and not plc["%S13"]


def test_warm_start_keeps_data_and_sets_s1(plc_from_source):
    plc = plc_from_source(FIRST + "LD 1\nST %M5\n")
    plc.scan(3)
    plc["%MW10"] = 77
    plc.warm_start()
    plc.scan(3)
    assert firsts(plc) == (1, 1, 2)
    assert plc["%MW10"] == 77 and plc["%M5"]


def test_cold_start_resets_data(plc_from_source):
    plc = plc_from_source(FIRST + """
LD    1
ST    %M5
ST    %Q0.0
LD    %M6
CU    %C0
LD    %M6
IN    %TM0
""", {"scan_period": "10ms",
      "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 100}}})
    plc["%M6"] = 1
    plc.scan(3)
    assert plc["%C0.V"] == 1 and plc["%TM0.V"] == 2
    plc["%MW10"] = 77
    plc["%M6"] = 0
    plc.cold_start()
    assert plc["%MW10"] == 0 and not plc["%M5"] and not plc["%Q0.0"]
    assert plc["%C0.V"] == 0 and plc["%TM0.V"] == 0
    plc.scan()
    assert firsts(plc) == (1, 0, 1)  # %MW0..2 were reset too, then counted once


def test_stop_and_start(plc_from_source):
    plc = plc_from_source(FIRST + "LD 1\n[ INC %MW5 ]\n")
    plc.scan(2)
    plc.stop()
    assert plc.state == "STOP"
    plc.scan(3)
    assert plc["%MW5"] == 2  # the program does not run in STOP
    plc.start()
    assert plc.state == "RUN"
    plc.scan(2)
    assert plc["%MW5"] == 4
    assert firsts(plc) == (1, 0, 2)  # %S13 again on the first scan after going to RUN


# ---- clocks %S4-%S7 [manual] ----------------------------------------------------------------
@pytest.mark.parametrize("bit,period_s", [(4, 0.01), (5, 0.1), (6, 1.0)])
def test_system_clocks_are_50_percent_square_waves(plc_from_source, bit, period_s):
    plc = plc_from_source(f"""
LDR   %S{bit}
[ INC %MW0 ]
LD    %S{bit}
[ INC %MW1 ]
""", {"scan_period": "1ms"})
    n = round(10 * period_s / 0.001)  # ten periods
    plc.scan(n)
    assert plc["%MW0"] in (9, 10)  # rising edges
    assert abs(plc["%MW1"] - n // 2) <= 1  # high half of the time


def test_minute_clock(plc_from_source):
    plc = plc_from_source("LD %S7\n[ INC %MW1 ]\nLDR %S7\n[ INC %MW0 ]\n",
                          {"scan_period": "1s"})
    plc.run(seconds=180)
    assert plc["%MW0"] in (2, 3)
    assert abs(plc["%MW1"] - 90) <= 1


# ---- system words [manual] ------------------------------------------------------------------
def test_sw0_and_sw11_show_period_and_watchdog(plc_from_source):
    plc = plc_from_source(COPY, {"scan_period": "20ms", "watchdog": "100ms"})
    assert plc["%SW0"] == 20
    assert plc["%SW11"] == 100
    plc = plc_from_source(COPY)
    assert plc["%SW11"] == 150  # the documented default


def test_scan_time_words(plc_from_source):
    plc = plc_from_source("""
LD    %M0
[ %MW1 := 0 ]
%L1:
LD    %M0
[ INC %MW1 ]
LD    [ %MW1 < 30000 ]
AND   %M0
JMPC  %L1
""")
    plc.scan(3)
    assert plc["%SW30"] >= 0 and plc["%SW31"] >= plc["%SW30"] >= plc["%SW32"] >= 0
    plc["%M0"] = 1
    plc.scan()  # a heavy scan: a loop of 30000 turns takes at least a few ms
    assert plc["%SW31"] == plc["%SW30"] >= 1
    plc["%M0"] = 0
    plc.scan()
    assert plc["%SW31"] >= 1 and plc["%SW32"] <= plc["%SW30"] <= plc["%SW31"]


def test_overrun_sets_s19(plc_from_source):
    plc = plc_from_source(COPY)
    plc.engine.note_overrun()
    assert plc["%S19"] and plc.state == "RUN"


# ---- forcing --------------------------------------------------------------------------------
def test_forced_output_wins_over_the_program(plc_from_source):
    plc = plc_from_source(COPY + "LD %Q0.0\nST %M0\n")
    plc.force("%Q0.0", 1)
    plc.scan()
    assert plc["%Q0.0"] and plc.mem.q_field[0] == 1
    assert plc.forced == {"%Q0.0": 1}
    plc.unforce("%Q0.0")
    plc.scan()
    assert not plc["%Q0.0"] and plc.mem.q_field[0] == 0


def test_forced_input_wins_over_the_field(plc_from_source):
    plc = plc_from_source(COPY)
    plc.force("%I0.0", 1)
    plc.scan()
    assert plc["%Q0.0"]
    plc["%I0.0"] = 0
    plc.scan()
    assert plc["%Q0.0"]
    plc.force("%I0.0", 0)
    plc["%I0.0"] = 1
    plc.scan()
    assert not plc["%Q0.0"]
    plc.unforce()
    plc.scan()
    assert plc["%Q0.0"] and plc.forced == {}


def test_forced_word_and_internal_bit(plc_from_source):
    plc = plc_from_source("LD 1\n[ %MW0 := 5 ]\nLD 1\nR %M0\nLD %M0\nST %Q0.0\n")
    plc.force("%MW0", 42)
    plc.force("%M0", 1)
    plc.scan()
    assert plc["%MW0"] == 42 and plc["%M0"]


def test_forcing_recompiles_only_when_the_forced_bits_change(plc_from_source):
    """Stores to forced bits are compiled out; words are re-asserted by the engine, so
    forcing a word, re-forcing a bit or releasing nothing costs no recompilation."""
    plc = plc_from_source("LD 1\n[ %MW0 := 5 ]\nLD 1\nST %Q0.0\n")
    v = plc.code_version
    plc.force("%MW0", 42)
    plc.unforce("%MW1")  # not forced
    assert plc.code_version == v
    plc.force("%Q0.0", 0)
    assert plc.code_version == v + 1
    plc.force("%Q0.0", 1)  # the same bit, another value
    plc.unforce("%MW0")
    assert plc.code_version == v + 1
    plc.scan()
    assert plc["%Q0.0"] == 1 and plc["%MW0"] == 5
    plc.unforce()
    assert plc.code_version == v + 2 and plc.forced == {}


# ---- HALT -----------------------------------------------------------------------------------
def test_halt_outputs_to_zero_and_cold_start_recovers(plc_from_source):
    plc = plc_from_source("""
LD    1
ST    %Q0.0
%L1:
LD    %M0
JMPC  %L1
""", {"watchdog": "10ms"})
    plc.scan()
    assert plc.mem.q_field[0] == 1
    plc["%M0"] = 1
    plc.scan()
    assert plc.state == "HALT" and plc["%S11"]
    assert plc.mem.q_field[0] == 0 and not plc["%Q0.0"]
    plc.cold_start()
    plc.scan()
    assert plc.state == "RUN" and not plc["%S11"] and plc.mem.q_field[0] == 1


# ---- virtual clock --------------------------------------------------------------------------
def test_virtual_time_and_scan_count(plc_from_source):
    plc = plc_from_source(COPY, {"scan_period": "10ms"})
    assert plc.time == 0 and plc.scan_count == 0
    plc.scan(7)
    assert plc.scan_count == 7
    assert plc.time == pytest.approx(0.07)
    plc.run(seconds=1.5)
    assert plc.scan_count == 157
    assert plc.time == pytest.approx(1.57)


def test_virtual_runs_are_repeatable(plc_from_source):
    src = """
LD    %S5
AND   %I0.0
IN    %TM0
LD    %TM0.Q
CU    %C0
LDR   %S6
[ %MW0 := %MW0 * 3 + %C0.V ]
"""
    cfg = {"scan_period": "3ms",
           "timers": {"%TM0": {"type": "TP", "base": "10ms", "preset": 2}}}
    snaps = []
    for _ in range(2):
        plc = plc_from_source(src, cfg)
        for k in range(700):
            plc["%I0.0"] = (k // 7) % 2
            plc.scan()
        snaps.append((plc["%MW0"], plc["%C0.V"], plc.time, bytes(plc.mem.mw.buf)))
    assert snaps[0] == snaps[1]
    assert snaps[0][1] > 0


def test_run_until(plc_from_source):
    plc = plc_from_source("LD 1\n[ INC %MW0 ]\n")
    assert plc.run_until(lambda p: p["%MW0"] >= 5, timeout=1)
    assert plc["%MW0"] == 5
    assert not plc.run_until(lambda p: p["%MW0"] < 0, timeout=0.05)


# ---- plc[...] access ------------------------------------------------------------------------
def test_reads_and_writes_of_every_kind(plc_from_source):
    plc = plc_from_source("LD 1\n[ %MW100 := %MW3 + 1 ]\n",
                          {"constants": {"%KW0": 5, "%KF2": 2.5},
                           "counters": {"%C1": {"preset": 9}}})
    plc["%MW3"] = 120
    plc["%M10"] = True
    plc["%MD20"] = -100000
    plc["%MF40"] = 0.5
    plc["%MW50:X4"] = 1
    plc["%MW60:3"] = [1, 2, 3]
    plc["%C1.P"] = 4
    plc.scan()
    assert plc["%MW100"] == 121
    assert plc["%M10"] is True
    assert plc["%MD20"] == -100000
    assert plc["%MF40"] == 0.5
    assert plc["%MW50"] == 16 and plc["%MW50:X4"] is True
    assert plc["%MW60:3"] == [1, 2, 3]
    assert plc["%KW0"] == 5 and plc["%KF2"] == 2.5
    assert plc["%C1.P"] == 4
    assert plc["%Q0.0"] is False
    assert isinstance(plc["%MW3"], int) and isinstance(plc["%MF40"], float)


def test_word_write_wraps_to_16_bits(plc_from_source):
    plc = plc_from_source(COPY)
    plc["%MW0"] = 65535
    assert plc["%MW0"] == -1


@pytest.mark.parametrize("address,value", [
    ("%KW0", 1), ("%TM0.V", 3), ("%C0.V", 1), ("%C0.D", 1), ("%MW3000", 1),
    ("%I0.24", 1), ("%Q0.16", 1), ("%M256", 1), ("%XYZ", 1), ("%MF2999", 1.0),
])
def test_bad_writes_raise_a_softplc_error(plc_from_source, address, value):
    plc = plc_from_source("LD %M0\nCU %C0\n",
                          {"timers": {"%TM0": {"type": "TON", "base": "1s", "preset": 1}}})
    with pytest.raises(SoftPLCError):
        plc[address] = value


@pytest.mark.parametrize("address", ["%MW3000", "%I8.0", "%FOO1", "%TM0.X", "%C200.V"])
def test_bad_reads_raise_an_address_error(plc_from_source, address):
    plc = plc_from_source(COPY)
    with pytest.raises(AddressError):
        plc[address]


def test_unconfigured_block_read_is_a_clear_error(plc_from_source):
    plc = plc_from_source(COPY)
    with pytest.raises(AddressError, match="not configured"):
        plc["%TM5.Q"]


# ---- configuration --------------------------------------------------------------------------
TOML = """
scan_period = "5ms"
watchdog = "80ms"

[timers."%TM0"]
type = "TON"
base = "10ms"
preset = 4

[counters."%C0"]
preset = 3

[constants]
"%KW0" = 1234
"%KF2" = 0.25
"""

CFG_PROGRAM = """
LD    %M0
IN    %TM0
LD    %TM0.Q
ST    %Q0.0
LD    1
[ %MW0 := %KW0 ]
[ %MF2 := %KF2 ]
LD    %M1
CU    %C0
LD    %C0.D
ST    %Q0.1
"""


def check_config(plc: PLC) -> None:
    assert plc.scan_period == 0.005 and plc["%SW11"] == 80
    plc["%M0"] = 1
    plc.scan(8)  # 35 ms of timing
    assert not plc["%Q0.0"]
    plc.scan()
    assert plc["%Q0.0"]
    assert plc["%MW0"] == 1234 and plc["%MF2"] == 0.25
    for v in (1, 0) * 3:
        plc["%M1"] = v
        plc.scan()
    assert plc["%Q0.1"]


def test_config_as_dict(plc_from_source):
    cfg = {"scan_period": "5ms", "watchdog": "80ms",
           "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 4}},
           "counters": {"%C0": {"preset": 3}},
           "constants": {"%KW0": 1234, "%KF2": 0.25}}
    check_config(plc_from_source(CFG_PROGRAM, cfg))


def test_config_as_toml_file(plc_from_source, tmp_path):
    path = tmp_path / "machine.toml"
    path.write_text(TOML)
    check_config(plc_from_source(CFG_PROGRAM, path))
    check_config(plc_from_source(CFG_PROGRAM, str(path)))


def test_program_and_config_from_files(tmp_path):
    (tmp_path / "p.il").write_text(CFG_PROGRAM)
    (tmp_path / "p.toml").write_text(TOML)
    with PLC.from_file(tmp_path / "p.il", tmp_path / "p.toml") as plc:
        check_config(plc)


@pytest.mark.parametrize("cfg", [
    {"scan_period": "fast"},
    {"scan_period": 0},
    {"timers": {"%TM0": {"type": "TUN", "base": "1s", "preset": 1}}},
    {"timers": {"%TM0": {"type": "TON", "base": "2s", "preset": 1}}},
    {"timers": {"%TM0": {"type": "TON", "base": "1s", "preset": 10000}}},
    {"timers": {"%C0": {"type": "TON", "base": "1s", "preset": 1}}},
    {"counters": {"%C0": {"preset": -1}}},
    {"constants": {"%MW0": 1}},
    {"constants": {"%KW0": 70000}},
    {"modules": {"9": "TM2DDO8TT"}},
    {"modules": {"1": "NOPE"}},
    {"profile": "TWDXYZ"},
    {"unknown_key": 1},
])
def test_bad_configuration_is_a_config_error(plc_from_source, cfg):
    with pytest.raises(ConfigError):
        plc_from_source(COPY, cfg)


def test_bad_toml_is_a_config_error(plc_from_source, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("scan_period = = 3\n")
    with pytest.raises(ConfigError):
        plc_from_source(COPY, path)
    with pytest.raises(ConfigError):
        plc_from_source(COPY, tmp_path / "missing.toml")


def test_cold_start_after_forcing_resets_blocks(plc_from_source):
    """Forcing recompiles the program; the blocks' cold-start state must not move with it."""
    plc = plc_from_source("LD %I0.0\nCU %C0\n")
    for v in (1, 0, 1):
        plc["%I0.0"] = v
        plc.scan()
    assert plc["%C0.V"] == 2
    plc.force("%M5", True)
    plc.cold_start()
    assert plc["%C0.V"] == 0


# ---- outputs in STOP and %S9 [docs/twido.md "Outputs in STOP", from memory] -----------------
def test_stop_puts_the_physical_outputs_at_0_and_keeps_the_image(plc_from_source):
    plc = plc_from_source(COPY)
    plc["%I0.0"] = 1
    plc.scan(2)
    assert plc["%Q0.0"] and plc.mem.q_field[0]
    plc.stop()
    plc.scan(3)
    assert plc["%Q0.0"]  # the %Q image is kept...
    assert not plc.mem.q_field[0]  # ...the output itself is at its fallback value 0
    plc.start()
    plc.scan()
    assert plc.mem.q_field[0]  # back in RUN the image is written to the outputs again


def test_s9_holds_the_outputs_at_0_while_the_program_runs(plc_from_source):
    plc = plc_from_source(COPY + "LD %I0.1\nST %S9\n")
    plc["%I0.0"] = 1
    plc["%I0.1"] = 1
    plc.scan(2)
    assert plc["%Q0.0"] and not plc.mem.q_field[0]  # the program runs; the output is 0
    plc["%I0.1"] = 0
    plc.scan()
    assert plc.mem.q_field[0]


def test_forcing_a_bit_rebuilds_the_code_but_is_not_a_new_program_version(plc_from_source):
    plc = plc_from_source(COPY)
    version, code = plc.program_version, plc.code_version
    plc.force("%Q0.0", 1)  # a forced bit: the program's stores to it compiled out
    assert plc.code_version == code + 1
    assert plc.program_version == version  # what the Program tab shows does not move
    plc.unforce()
    assert plc.program_version == version
