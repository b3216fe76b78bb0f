"""Issue 11 part A: deviations from the controller, one test (or a few) per point, each
citing its source. Tags and facts as in docs/twido.md (the project's page of the Twido facts
the code relies on).
"""

from __future__ import annotations

import math

import pytest

from softplc import PLC
from softplc.errors import ProgramError

GRAFCET = """
LD    %M10
S     %S21
LD    %M11
S     %S22
LD    %M12
S     %S23
LD    %S21
ST    %M20          (* what the program sees of %S21 in preprocessing *)
=*= 0
LD    %I0.0
# 1
-*- 1
LD    %I0.1
# 2
-*- 2
LD    %I0.2
# 0
=*= POST
LD    %S21
ST    %M21          (* %S21 after preprocessing: reset by the system *)
LD    %S23
ST    %M23
"""


def steps(plc: PLC) -> list[int]:
    return [k for k in range(4) if plc[f"%X{k}"]]


def pulse_in(plc: PLC, addr: str) -> None:
    plc[addr] = 1
    plc.scan()
    plc[addr] = 0


# ---- 1. Grafcet system bits %S21 %S22 %S23 ----------------------------------------------
# Source: TWD USE 10AE system-bit table (%S21 Grafcet initialisation, %S22 re-initialisation,
# %S23 preset and freeze; reset by the system at the end of preprocessing) and the PL7
# reference manual 35015365, "Description of preliminary processing": "The bit %S21 is set
# to 1 by the system before calling up the preliminary processing" on a cold start, the
# Grafcet bits "are used at the beginning of sequential processing". [manual]

def test_s21_set_by_the_system_on_a_cold_start_and_reset_after_preprocessing(plc_from_source):
    plc = plc_from_source(GRAFCET)
    plc.scan()
    assert plc["%M20"], "the first scan's preprocessing sees %S21 = 1"
    assert not plc["%M21"] and not plc["%S21"], "reset at the end of preprocessing"
    assert steps(plc) == [0]
    plc.scan()
    assert not plc["%M20"]


def test_s21_from_the_program_reinitialises_the_chart(plc_from_source):
    plc = plc_from_source(GRAFCET)
    plc.scan()
    pulse_in(plc, "%I0.0")
    assert steps(plc) == [1]
    plc["%M10"] = 1
    plc.scan()
    assert steps(plc) == [0], "every step off, the initial step on"
    assert not plc["%S21"]


def test_s22_deactivates_every_step(plc_from_source):
    plc = plc_from_source(GRAFCET)
    plc.scan()
    pulse_in(plc, "%I0.0")
    plc["%M11"] = 1
    plc.scan()
    assert steps(plc) == [] and not plc["%S22"]
    plc["%M11"] = 0
    plc.scan(3)
    assert steps(plc) == [], "no step is active, so none can fire"


def test_s23_freezes_the_transitions_while_set_in_preprocessing(plc_from_source):
    plc = plc_from_source(GRAFCET)
    plc.scan()
    plc["%M12"] = 1
    plc["%I0.0"] = 1
    plc.scan(3)
    assert steps(plc) == [0], "frozen: the true transition does not fire"
    assert not plc["%M23"], "%S23 is reset at the end of preprocessing"
    plc["%M12"] = 0
    plc.scan()
    assert steps(plc) == [1], "released: the transition fires"


def test_a_program_without_grafcet_sees_s21_on_the_first_scan_only(plc_from_source):
    plc = plc_from_source("LD %S21\nST %M0\n")
    plc.scan()
    assert plc["%M0"]
    plc.scan()
    assert not plc["%M0"] and not plc["%S21"]


# ---- 2. timers keep running when their block is not executed ------------------------------
# Source: TWD USE 10AE, TON/TOF/TP "special cases", "Effect of a program jump": jumping
# over the timer block does not freeze the timer; it goes on counting up to the preset,
# and then its done bit %TMi.Q changes. [manual]

JUMPED = """
LD    %M0
JMPC  %L1
BLK   %TM0
LD    %M1
IN
END_BLK
%L1:
LD    %TM0.Q
ST    %Q0.0
"""


@pytest.mark.parametrize("kind", ["TON", "TOF", "TP"])
def test_jumped_over_timer_keeps_timing(plc_from_source, kind):
    cfg = {"scan_period": "10ms",
           "timers": {"%TM0": {"type": kind, "base": "10ms", "preset": 10}}}
    plc = plc_from_source(JUMPED, cfg)
    plc["%M1"] = 1
    plc.scan(2)                       # TON/TP start timing; TOF holds Q = 1
    if kind == "TOF":
        plc["%M1"] = 0
        plc.scan()                    # falling edge: the off-delay starts
    plc["%M0"] = 1                    # from now on the block is jumped over
    plc.scan(3)
    v = plc["%TM0.V"]
    assert 0 < v < 10
    plc.scan(3)
    assert plc["%TM0.V"] > v, "%TMi.V goes on counting"
    plc.run(0.2)
    assert plc["%TM0.V"] in (0, 10)
    assert plc["%TM0.Q"] == (kind == "TON"), "%TMi.Q changes at the preset"
    assert plc["%Q0.0"] == (kind == "TON")


def test_timer_in_an_uncalled_subroutine_and_an_inactive_step(plc_from_source):
    src = """
LD    %M0
SR0
LD    %TM0.Q
ST    %Q0.0
=*= 0
LD    %M2
# 1
-*- 1
LD    1
IN    %TM1
LD    %M3
# 0
END
SR0:
LD    1
IN    %TM0
RET
"""
    cfg = {"scan_period": "100ms", "timers": {
        "%TM0": {"type": "TON", "base": "100ms", "preset": 5},
        "%TM1": {"type": "TON", "base": "100ms", "preset": 5}}}
    plc = plc_from_source(src, cfg)
    plc["%M0"] = 1
    plc["%M2"] = 1
    plc.scan(3)                        # SR0 called: %TM0 starts; step 1 active: %TM1 starts
    plc["%M0"] = plc["%M2"] = 0
    plc["%M3"] = 1
    plc.scan()                         # back to step 0: %TM1's step is inactive
    assert 0 < plc["%TM1.V"] < 5
    plc.run(1.0)
    assert plc["%TM0.Q"] and plc["%Q0.0"] and plc["%TM0.V"] == 5
    assert plc["%TM1.Q"] and plc["%TM1.V"] == 5


def test_a_timer_reset_by_its_block_leaves_the_running_set(plc_from_source):
    cfg = {"timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 100}}}
    plc = plc_from_source("LD %M9\nJMPC %L1\nLD %M1\nIN %TM0\n%L1:\nLD 1\n", cfg)
    plc["%M1"] = 1
    plc.scan(2)
    assert plc.time_source.running
    plc["%M1"] = 0
    plc.scan(2)
    assert not plc.time_source.running and plc["%TM0.V"] == 0


def test_nothing_tracked_when_every_block_runs_every_scan(plc_from_source):
    cfg = {"timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 100}}}
    plc = plc_from_source("LD %M1\nIN %TM0\n", cfg)
    plc["%M1"] = 1
    plc.scan(2)
    assert not plc.time_source.running and plc["%TM0.V"] > 0


# ---- 3. drums write their outputs only when the step changes ------------------------------
# Source: recorded M221 simulator runs (issue 11) [m221]; while R is held the drum rewrites
# step 0's bits at every scan (issue 24, a user's observation; no manual found saying so).

def test_drum_outputs_written_on_step_change_only(plc_from_source):
    src = """
BLK   %DR0
LD    %M9
R
LD    %M0
U
END_BLK
LD    %M5
R     %Q0.0
"""
    cfg = {"drums": {"%DR0": {"steps": [1, 3, 0], "outputs": ["%Q0.0", "%Q0.1"]}}}
    plc = plc_from_source(src, cfg)
    plc.scan()
    assert plc["%Q0.0"] and not plc["%Q0.1"], "step 0 written at the first execution"
    plc["%M5"] = 1
    plc.scan()
    plc["%M5"] = 0
    plc.scan(3)
    assert not plc["%Q0.0"], "the reset by another rung stands: no rewrite every scan"
    pulse_in(plc, "%M0")
    assert plc["%Q0.0"] and plc["%Q0.1"], "a step change writes the outputs"
    plc["%M9"] = 1                     # R held: back to step 0
    plc.scan()
    assert plc["%Q0.0"] and not plc["%Q0.1"]
    plc["%M5"] = 1
    plc.scan()
    assert not plc["%Q0.0"], "the rung after the drum resets the output in this scan"
    plc["%M5"] = 0
    plc.scan()
    assert plc["%Q0.0"], "R held: the next scan writes step 0's bits again"
    plc["%M9"] = 0                     # R released: written once more, then left alone
    plc["%M5"] = 1
    plc.scan()
    plc["%M5"] = 0
    plc.scan(2)
    assert not plc["%Q0.0"], "R released at step 0: no rewrite"
    plc.cold_start()
    plc["%M9"] = 0
    plc.scan()
    assert plc["%Q0.0"], "after a cold start the first execution writes step 0 again"


# ---- 4. %S12 = 1 in RUN, 0 in STOP ------------------------------------------------------
# Source: TWD USE 10AE system bits, %S12 "PLC in RUN mode" [manual]; the Control Expert
# simulator's table gives %S12 PLCRUNNING the same meaning.

def test_s12_follows_the_run_state(plc_from_source):
    plc = plc_from_source("LD %S12\nST %M0\n")
    plc.scan()
    assert plc["%S12"] and plc["%M0"]
    plc.stop()
    plc.scan()
    assert not plc["%S12"]
    plc.start()
    plc.scan()
    assert plc["%S12"]


# ---- 5. syntax: %SBRi.j / %SCi.j, BTI/ITB, LW/HW/CONCATW, %SW17 ---------------------------
# Source: TWD USE 10AE, shift register bits %SBRi.j (j = 0..15) and step counter bits
# %SCi.j (j = 0..255), "tested by Load instructions and written by Assignment" [manual].

def test_block_bits_in_twidosuite_spelling(plc_from_source):
    src = """
LD    %M0
ST    %SBR0.3
LD    %SBR0.3
ST    %Q0.0
LD    %M1
ST    %SC1.7
LD    %SC1.7
ST    %Q0.1
BLK   %SC1
LD    %M2
CU
END_BLK
LD    %SC1.8
ST    %Q0.2
"""
    plc = plc_from_source(src)
    plc["%M0"] = plc["%M1"] = 1
    plc.scan()
    assert plc["%Q0.0"] and plc["%Q0.1"] and plc["%SBR0.J3"]
    plc["%M1"] = 0
    plc.scan()
    assert not plc["%Q0.1"]
    plc["%M1"] = 1
    plc.scan()
    plc["%M1"] = 0
    plc["%M2"] = 1                     # CU from step 7 (set by the program) -> step 8
    plc.scan()
    assert plc["%Q0.2"] and not plc["%SC1.7"]


@pytest.mark.parametrize("src, what", [
    ("LD %SBR0.16\nST %Q0.0\n", "bit 16 out of range"),
    ("LD %SC0.256\nST %Q0.0\n", "bit 256 out of range"),
    ("LD %SBR8.0\nST %Q0.0\n", "beyond the controller profile"),
])
def test_block_bits_out_of_range_are_clear_errors(src, what):
    with pytest.raises(ProgramError) as e:
        PLC.from_source(src)
    assert what in str(e.value)


# BTI/ITB: TwidoSuite names of BCD_TO_INT/INT_TO_BCD, %S18 on a non-BCD operand [manual].
def test_bti_itb(plc_from_source):
    plc = plc_from_source("LD 1\n[ %MW1 := BTI( %MW0 ) ]\n[ %MW2 := ITB( %MW1 ) ]\n")
    plc["%MW0"] = 0x1234
    plc.scan()
    assert plc["%MW1"] == 1234 and plc["%MW2"] == 0x1234 and not plc["%S18"]
    plc["%MW0"] = 0x12A4               # A is no BCD digit
    plc.scan()
    assert plc["%S18"]


# LW, HW, CONCATW on %MD [manual]: CONCATW( low, high ).
def test_lw_hw_concatw(plc_from_source):
    src = ("LD 1\n[ %MW10 := LW( %MD0 ) ]\n[ %MW11 := HW( %MD0 ) ]\n"
           "[ %MD20 := CONCATW( %MW11, %MW10 ) ]\n")
    plc = plc_from_source(src)
    plc["%MD0"] = 0x12345678
    plc.scan()
    assert plc["%MW10"] == 0x5678 and plc["%MW11"] == 0x1234
    assert plc["%MD20"] == 0x56781234
    plc["%MD0"] = -2
    plc.scan()
    assert plc["%MW10"] == -2 and plc["%MW11"] == -1


def test_lw_of_a_float_is_a_compile_error():
    with pytest.raises(ProgramError) as e:
        PLC.from_source("LD 1\n[ %MW1 := LW( %MF0 ) ]\n")
    assert "LW takes a double word" in str(e.value)


# %SW17: kind of floating-point fault (bit 0 invalid, bit 2 divide by 0, bit 3 overflow),
# with %S18 [manual, from memory].
@pytest.mark.parametrize("expr, bit", [
    ("SQRT( %MF0 )", 0), ("%MF2 / %MF4", 2), ("EXP( %MF6 )", 3), ("%MF6 * %MF8", 3)])
def test_sw17_records_the_float_fault(plc_from_source, expr, bit):
    plc = plc_from_source(f"LD 1\n[ %MF20 := {expr} ]\n")
    plc["%MF0"], plc["%MF2"], plc["%MF4"], plc["%MF6"], plc["%MF8"] = -1.0, 1.0, 0.0, 1e3, 1e38
    plc.scan()
    assert plc["%S18"] and plc["%SW17"] == 1 << bit
    assert math.isnan(plc["%MF20"]) or math.isinf(plc["%MF20"])


# ---- every instruction of the reference's tables compiles ----------------------------------
# Source: the instruction lists of docs/twido.md#instruction-list, one line
# each; a syntax or compile error names the one missing.
EVERY_INSTRUCTION = """
LD %I0.0
LDN %I0.1
LDR %I0.2
LDF %I0.3
AND %M0
ANDN %M1
ANDR %M2
ANDF %M3
OR %M4
ORN %M5
ORR %M6
ORF %M7
XOR %M8
XORN %M9
XORR %M10
XORF %M11
AND( %M12
OR( %M13
XOR( %M14
)
)
)
AND(N %M15
)
AND(R %M16
)
AND(F %M17
)
AND([ %MW0 > 100 ]
)
OR [ %MF2 <= 1.5 ]
MPS
ST %Q0.0
MRD
STN %Q0.1
MPP
N
S %M20
R %M21
LD 1
[ %MW1 := %MW2 + %MW3 - %MW4 * %MW5 / 7 REM 3 ]
[ INC %MW6 ]
[ DEC %MW7 ]
[ %MW8 := SQRT( %MW9 ) ]
[ %MW8 := ABS( %MW9 ) ]
[ %MW8 := %MW9 AND %MW10 OR %MW11 XOR NOT( %MW12 ) ]
[ %MW8 := SHL( %MW9, 2 ) ]
[ %MW8 := SHR( %MW9, 2 ) ]
[ %MW8 := ROL( %MW9, 2 ) ]
[ %MW8 := ROR( %MW9, 2 ) ]
[ %MF20 := SQRT( %MF22 ) + ABS( %MF22 ) + TRUNC( %MF22 ) + LOG( %MF22 ) + LN( %MF22 ) ]
[ %MF20 := EXP( %MF22 ) + EXPT( %MF22, %MF24 ) + SIN( %MF22 ) + COS( %MF22 ) ]
[ %MF20 := TAN( %MF22 ) + ASIN( %MF22 ) + ACOS( %MF22 ) + ATAN( %MF22 ) ]
[ %MF20 := DEG_TO_RAD( %MF22 ) + RAD_TO_DEG( %MF22 ) ]
[ %MF20 := INT_TO_REAL( %MW9 ) + DINT_TO_REAL( %MD30 ) + INTO_TO_REAL( %MW9 ) ]
[ %MW8 := REAL_TO_INT( %MF22 ) ]
[ %MD30 := REAL_TO_DINT( %MF22 ) ]
[ %MW40:5 := %MW50:5 ]
LD %M30
JMPC %L1
JMPCN %L1
SR0
%L1:
LD %M31
ENDC
LD %M31
ENDCN
BLK %TM0
LD %M32
IN
OUT_BLK
LD Q
ST %Q0.3
END_BLK
BLK %C0
LD %M33
R
LD %M34
S
LD %M35
CU
LD %M36
CD
OUT_BLK
LD D
ST %M40
LD E
ST %M41
LD F
ST %M42
END_BLK
BLK %DR0
LD %M37
R
LD %M38
U
END_BLK
BLK %SBR0
LD %M39
R
LD %M43
CU
LD %M44
CD
END_BLK
BLK %R0
LD %M45
R
LD %M46
I
LD %M47
O
END_BLK
LD %M48
IN %TM0
CU %C0
LD %TM0.Q
ST %Q0.4
NOP
=*= 0
LD %M50
# 1
-*- 1
LD %M51
#D 0
LD %M52
#
=*= POST
LD %X1
ST %Q0.5
END
SR0:
LD 1
RET
"""


def test_every_instruction_of_the_reference_compiles():
    cfg = {"timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 5}},
           "drums": {"%DR0": {"steps": [1, 2], "outputs": ["%Q0.6", "%Q0.7"]}}}
    plc = PLC.from_source(EVERY_INSTRUCTION, cfg)
    plc.scan(3)
    assert plc.state == "RUN" and plc["%X0"]


# ---- `softplc check` and the ladder view --------------------------------------------------

def test_check_accepts_the_new_syntax_and_reports_misuse(tmp_path, capsys):
    from softplc.cli import main as softplc

    good = tmp_path / "good.il"
    good.write_text("LD %SBR0.3\nANDN %SC1.7\nST %SC1.8\nLD 1\n[ %MW1 := BTI( %MW0 ) ]\n"
                    "[ %MW10 := LW( %MD2 ) ]\n[ %MD20 := CONCATW( %MW11, %MW10 ) ]\n")
    assert softplc(["check", str(good)]) == 0
    assert "OK - 2 rungs" in capsys.readouterr().out
    bad = tmp_path / "bad.il"
    bad.write_text("LD %SBR0.16\nST %SC9.1\nLD 1\n[ %MW1 := LW( %MF0 ) ]\n"
                   "[ %MW1 := CONCATW( %MD0 ) ]\n")
    assert softplc(["check", str(bad)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith(f"{bad}:1:4: '%SBR0.16': bit 16 out of range")
    assert err[1].startswith(f"{bad}:2:4: '%SC9.1' is beyond the controller profile")
    assert err[2].startswith(f"{bad}:4:11: LW takes a double word, got a float")
    assert err[3].startswith(f"{bad}:5:11: CONCATW takes 2 argument(s), got 1")


def test_ladder_view_shows_block_bits_in_twido_spelling():
    from softplc.il.parser import parse
    from softplc.ladder import render_text

    text = render_text(parse("LD %SBR0.J3\nANDN %SC1.7\nST %SC1.8\n").rungs[0])
    assert "%SBR0.3" in text and "%SC1.7" in text and "%SC1.8" in text
