"""Function blocks: %TM timers (TON/TOF/TP, every time base), %C counters, %DR drums,
%SBR shift registers, %SC step counters, %R FIFO/LIFO; in the BLK ... END_BLK form and in
the short form (`IN %TM0`, `CU %C0`, `LD %TM0.Q`).

Type, time base and preset are configuration [m221]. Semantics from
docs/twido.md ([sure]/[m221]/[manual] tags as there).
"""

from __future__ import annotations

import pytest

from softplc import PLC

BASES_S = {"1ms": 0.001, "10ms": 0.01, "100ms": 0.1, "1s": 1.0, "1min": 60.0}

TIMER_BLK = """
BLK   %TM0
LD    %M0
IN
OUT_BLK
LD    Q
ST    %Q0.0
END_BLK
"""

TIMER_SHORT = """
LD    %M0
IN    %TM0
LD    %TM0.Q
ST    %Q0.0
"""


def timer_plc(make, form: str, type_: str, base: str, preset: int) -> PLC:
    # one scan per time-base tick keeps every base fast
    cfg = {"scan_period": base,
           "timers": {"%TM0": {"type": type_, "base": base, "preset": preset}}}
    return make(TIMER_BLK if form == "blk" else TIMER_SHORT, cfg)


def step(plc: PLC, m0: int, n: int = 1) -> None:
    plc["%M0"] = m0
    plc.scan(n)


# ---- timers [manual] ------------------------------------------------------------------------
@pytest.mark.parametrize("form", ["blk", "short"])
@pytest.mark.parametrize("base", list(BASES_S))
def test_ton_on_delay(plc_from_source, form, base):
    plc = timer_plc(plc_from_source, form, "TON", base, 5)
    step(plc, 0, 3)
    assert not plc["%Q0.0"] and plc["%TM0.V"] == 0
    step(plc, 1, 5)  # elapsed 0..4 ticks
    assert not plc["%Q0.0"] and plc["%TM0.V"] == 4
    step(plc, 1)  # 5 ticks after IN rose: V reaches P
    assert plc["%Q0.0"] and plc["%TM0.V"] == 5
    step(plc, 1, 20)
    assert plc["%Q0.0"] and plc["%TM0.V"] == 5  # V never passes P
    step(plc, 0)  # IN = 0 resets
    assert not plc["%Q0.0"] and plc["%TM0.V"] == 0


@pytest.mark.parametrize("form", ["blk", "short"])
def test_ton_interrupted_restarts(plc_from_source, form):
    plc = timer_plc(plc_from_source, form, "TON", "10ms", 5)
    step(plc, 1, 4)
    step(plc, 0)
    step(plc, 1, 5)
    assert not plc["%Q0.0"]
    step(plc, 1)
    assert plc["%Q0.0"]


@pytest.mark.parametrize("form", ["blk", "short"])
@pytest.mark.parametrize("base", ["1ms", "100ms", "1min"])
def test_tof_off_delay(plc_from_source, form, base):
    plc = timer_plc(plc_from_source, form, "TOF", base, 3)
    step(plc, 0, 2)
    assert not plc["%Q0.0"]
    step(plc, 1)
    assert plc["%Q0.0"] and plc["%TM0.V"] == 0  # Q = 1 while IN = 1
    step(plc, 1, 10)
    assert plc["%Q0.0"]
    step(plc, 0, 3)  # IN fell: V counts 0, 1, 2
    assert plc["%Q0.0"] and plc["%TM0.V"] == 2
    step(plc, 0)
    assert not plc["%Q0.0"] and plc["%TM0.V"] == 3  # Q drops at P
    step(plc, 0, 5)
    assert not plc["%Q0.0"] and plc["%TM0.V"] <= 3


def test_tof_retriggered_while_counting(plc_from_source):
    plc = timer_plc(plc_from_source, "blk", "TOF", "10ms", 3)
    step(plc, 1)
    step(plc, 0, 2)
    step(plc, 1)  # back on before the delay ran out
    assert plc["%Q0.0"] and plc["%TM0.V"] == 0
    step(plc, 0, 3)
    assert plc["%Q0.0"]
    step(plc, 0)
    assert not plc["%Q0.0"]


@pytest.mark.parametrize("form", ["blk", "short"])
@pytest.mark.parametrize("base", ["1ms", "10ms", "1s"])
def test_tp_pulse(plc_from_source, form, base):
    plc = timer_plc(plc_from_source, form, "TP", base, 4)
    step(plc, 0)
    assert not plc["%Q0.0"]
    step(plc, 1)  # rising edge: pulse starts
    assert plc["%Q0.0"]
    step(plc, 0, 3)  # the pulse lasts P whatever IN does
    assert plc["%Q0.0"]
    step(plc, 0)
    assert not plc["%Q0.0"]
    step(plc, 1, 10)  # IN held: one pulse only
    trace = []
    plc2 = timer_plc(plc_from_source, form, "TP", base, 4)
    for _ in range(10):
        step(plc2, 1)
        trace.append(int(plc2["%Q0.0"]))
        assert plc2["%TM0.V"] <= 4
    assert trace == [1, 1, 1, 1, 0, 0, 0, 0, 0, 0]


def test_tp_is_not_retriggered_during_the_pulse(plc_from_source):
    plc = timer_plc(plc_from_source, "blk", "TP", "10ms", 4)
    trace = []
    for m0 in [1, 0, 1, 0, 1, 0, 0, 0]:
        step(plc, m0)
        trace.append(int(plc["%Q0.0"]))
    assert trace == [1, 1, 1, 1, 0, 0, 0, 0]


def test_timer_preset_written_by_the_program(plc_from_source):
    plc = plc_from_source("LD 1\n[ %TM0.P := 2 ]\n" + TIMER_SHORT,
                          {"scan_period": "10ms",
                           "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 50}}})
    step(plc, 1, 2)
    assert not plc["%Q0.0"]
    step(plc, 1)
    assert plc["%Q0.0"] and plc["%TM0.P"] == 2


def test_timer_time_is_virtual_and_independent_of_the_scan_period(plc_from_source):
    """A 100 ms base, preset 10: Q after 1 s of PLC time, with 1 ms or 50 ms scans."""
    for period in ("1ms", "50ms"):
        plc = plc_from_source(TIMER_SHORT, {
            "scan_period": period,
            "timers": {"%TM0": {"type": "TON", "base": "100ms", "preset": 10}}})
        plc["%M0"] = 1
        plc.run(seconds=0.9)
        assert not plc["%Q0.0"], period
        plc.run(seconds=0.2)
        assert plc["%Q0.0"], period


def test_several_timers_run_independently(plc_from_source):
    plc = plc_from_source("""
LD    %M0
IN    %TM0
LD    %TM0.Q
IN    %TM1
LD    %TM1.Q
ST    %Q0.0
""", {"scan_period": "10ms", "timers": {
        "%TM0": {"type": "TON", "base": "10ms", "preset": 3},
        "%TM1": {"type": "TON", "base": "10ms", "preset": 2}}})
    step(plc, 1, 3)
    assert not plc["%TM0.Q"]
    step(plc, 1)
    assert plc["%TM0.Q"] and not plc["%Q0.0"]
    step(plc, 1)  # %TM1 started one tick ago
    assert not plc["%Q0.0"] and plc["%TM1.V"] == 1 and plc["%TM0.V"] == 3
    step(plc, 1)
    assert plc["%Q0.0"]


# ---- counters [m221] ------------------------------------------------------------------------
COUNTER_BLK = """
BLK   %C0
LD    %M0
R
LD    %M1
S
LD    %M2
CU
LD    %M3
CD
OUT_BLK
LD    D
ST    %Q0.0
LD    E
ST    %Q0.1
LD    F
ST    %Q0.2
END_BLK
"""

COUNTER_SHORT = """
LD    %M0
R     %C0
LD    %M1
S     %C0
LD    %M2
CU    %C0
LD    %M3
CD    %C0
LD    %C0.D
ST    %Q0.0
LD    %C0.E
ST    %Q0.1
LD    %C0.F
ST    %Q0.2
"""


def cnt(plc: PLC, r=0, s=0, cu=0, cd=0) -> PLC:
    plc["%M0"], plc["%M1"], plc["%M2"], plc["%M3"] = r, s, cu, cd
    plc.scan()
    return plc


def outs(plc: PLC) -> tuple[int, int, int, int]:
    return plc["%C0.V"], int(plc["%Q0.0"]), int(plc["%Q0.1"]), int(plc["%Q0.2"])


def counter_plc(make, form: str, preset: int = 3) -> PLC:
    return make(COUNTER_BLK if form == "blk" else COUNTER_SHORT,
                {"counters": {"%C0": {"preset": preset}}})


@pytest.mark.parametrize("form", ["blk", "short"])
def test_counter_counts_rising_edges_and_done(plc_from_source, form):
    plc = counter_plc(plc_from_source, form)
    for _ in range(2):
        cnt(plc, cu=1)
        cnt(plc, cu=1)  # held: no count
        cnt(plc)
    assert outs(plc) == (2, 0, 0, 0)
    cnt(plc, cu=1)
    assert outs(plc) == (3, 1, 0, 0)  # D while V = P
    cnt(plc)
    cnt(plc, cu=1)
    assert outs(plc) == (4, 0, 0, 0)
    cnt(plc)
    cnt(plc, cd=1)
    assert outs(plc) == (3, 1, 0, 0)
    cnt(plc)
    cnt(plc, cd=1)
    assert plc["%C0.V"] == 2


@pytest.mark.parametrize("form", ["blk", "short"])
def test_counter_up_and_down_in_one_scan_cancel(plc_from_source, form):
    plc = counter_plc(plc_from_source, form)
    cnt(plc, cu=1)
    cnt(plc)
    cnt(plc, cu=1, cd=1)
    assert plc["%C0.V"] == 1


@pytest.mark.parametrize("form", ["blk", "short"])
def test_counter_reset_and_set(plc_from_source, form):
    plc = counter_plc(plc_from_source, form, preset=7)
    cnt(plc, s=1)
    assert outs(plc) == (7, 1, 0, 0)
    cnt(plc, cu=1)
    cnt(plc, r=1)
    assert outs(plc) == (0, 0, 0, 0)
    cnt(plc, s=1)
    assert outs(plc) == (7, 1, 0, 0)


def test_counter_reset_has_priority_in_the_block_form(plc_from_source):
    """In BLK form all inputs act together: R wins over S and the counts [m221]. (In the
    short form each input acts where it stands in the program.)"""
    plc = counter_plc(plc_from_source, "blk", preset=7)
    cnt(plc, s=1)
    cnt(plc)
    cnt(plc, r=1, s=1, cu=1)
    assert outs(plc) == (0, 0, 0, 0)
    cnt(plc, r=1)
    cnt(plc, r=1, cu=1)  # counting is blocked while R = 1
    assert plc["%C0.V"] == 0


@pytest.mark.parametrize("form", ["blk", "short"])
def test_counter_wraps_with_overflow_bits(plc_from_source, form):
    plc = counter_plc(plc_from_source, form, preset=9999)
    cnt(plc, s=1)
    assert outs(plc) == (9999, 1, 0, 0)
    cnt(plc)
    cnt(plc, cu=1)  # 9999 -> 0 going up: F [m221]
    assert outs(plc) == (0, 0, 0, 1)
    cnt(plc)
    assert plc["%C0.F"]  # stays until the next count
    cnt(plc, cu=1)
    assert outs(plc) == (1, 0, 0, 0)  # cleared at the next count
    cnt(plc, r=1)
    cnt(plc)
    cnt(plc, cd=1)  # 0 -> 9999 going down: E
    assert outs(plc) == (9999, 1, 1, 0)
    cnt(plc)
    cnt(plc, cd=1)
    assert outs(plc) == (9998, 0, 0, 0)


def test_counter_without_configuration_counts_to_9999(plc_from_source):
    plc = plc_from_source("LD %M0\nCU %C5\n")
    for v in (1, 0) * 5:
        plc["%M0"] = v
        plc.scan()
    assert plc["%C5.V"] == 5 and plc["%C5.P"] == 9999 and not plc["%C5.D"]


def test_counter_preset_written_by_the_program(plc_from_source):
    plc = plc_from_source("LD 1\n[ %C0.P := 2 ]\n" + COUNTER_SHORT)
    for v in (1, 0, 1):
        cnt(plc, cu=v)
    assert outs(plc) == (2, 1, 0, 0)


# ---- drums [m221] ---------------------------------------------------------------------------
DRUM_CFG = {"drums": {"%DR0": {"steps": [0b001, 0b010, 0b100, 0b110],
                               "outputs": ["%Q0.0", "%Q0.1", "%Q0.2"]}}}

DRUM_BLK = """
BLK   %DR0
LD    %M0
R
LD    %M1
U
OUT_BLK
LD    F
ST    %Q0.5
END_BLK
"""

DRUM_SHORT = """
LD    %M0
R     %DR0
LD    %M1
U     %DR0
LD    %DR0.F
ST    %Q0.5
"""


def drum(plc: PLC, r=0, u=0) -> tuple[int, list[int], int]:
    plc["%M0"], plc["%M1"] = r, u
    plc.scan()
    return plc["%DR0.S"], [int(plc[f"%Q0.{k}"]) for k in range(3)], int(plc["%Q0.5"])


@pytest.mark.parametrize("form", ["blk", "short"])
def test_drum_steps_wraps_and_resets(plc_from_source, form):
    plc = plc_from_source(DRUM_BLK if form == "blk" else DRUM_SHORT, DRUM_CFG)
    assert drum(plc) == (0, [1, 0, 0], 0)
    assert drum(plc, u=1) == (1, [0, 1, 0], 0)
    assert drum(plc, u=1) == (1, [0, 1, 0], 0)  # level: no step
    drum(plc)
    assert drum(plc, u=1) == (2, [0, 0, 1], 0)
    drum(plc)
    assert drum(plc, u=1) == (3, [0, 1, 1], 1)  # F on the last step
    drum(plc)
    assert drum(plc, u=1) == (0, [1, 0, 0], 0)  # wraps
    drum(plc)
    drum(plc, u=1)
    assert drum(plc, r=1) == (0, [1, 0, 0], 0)  # R back to step 0
    if form == "blk":  # inputs act together: R (a level) blocks U
        assert drum(plc, r=1, u=1) == (0, [1, 0, 0], 0)


# ---- shift register %SBR [manual] -----------------------------------------------------------
SBR_BLK = """
BLK   %SBR0
LD    %M0
R
LD    %M1
CU
LD    %M2
CD
END_BLK
LD    %SBR0.J0
ST    %Q0.0
LD    %SBR0.J1
ST    %Q0.1
"""


def test_shift_register_reset_and_shifts(plc_from_source):
    plc = plc_from_source(SBR_BLK)
    sbr = plc.mem.blocks["SBR"][0]
    sbr.W = 0b1  # load a pattern (the program writes %SBRi.Jk on a real Twido)

    def sc(r=0, cu=0, cd=0):
        plc["%M0"], plc["%M1"], plc["%M2"] = r, cu, cd
        plc.scan()
        return [int(plc[f"%SBR0.J{k}"]) for k in range(4)]

    assert sc() == [1, 0, 0, 0]
    assert plc["%Q0.0"]
    assert sc(cu=1) == [0, 1, 0, 0]  # CU shifts towards the high bits
    assert plc["%Q0.1"] and not plc["%Q0.0"]
    assert sc(cu=1) == [0, 1, 0, 0]  # on edges only
    sc()
    assert sc(cu=1) == [0, 0, 1, 0]
    assert sc(cd=1) == [0, 1, 0, 0]
    assert sc(r=1) == [0, 0, 0, 0]


def test_shift_register_drops_bit_15(plc_from_source):
    plc = plc_from_source(SBR_BLK)
    plc.mem.blocks["SBR"][0].W = 0x8000
    plc["%M1"] = 1
    plc.scan()
    assert not any(plc[f"%SBR0.J{k}"] for k in range(16))


def test_shift_register_bits_are_writable(plc_from_source):
    """%SBRi.Jk can be tested and written by the program [manual]."""
    plc = plc_from_source("LD %M5\nST %SBR0.J0\n" + SBR_BLK)
    plc["%M5"] = 1
    plc.scan()
    assert plc["%SBR0.J0"] and plc["%Q0.0"]
    plc["%M1"] = 1  # the store rung writes J0 = 1 again, then CU shifts it to J1
    plc.scan()
    assert plc["%SBR0.J1"] and not plc["%SBR0.J0"]


# ---- step counter %SC [manual] --------------------------------------------------------------
def test_step_counter(plc_from_source):
    plc = plc_from_source("""
BLK   %SC0
LD    %M0
R
LD    %M1
CU
LD    %M2
CD
END_BLK
LD    %SC0.J2
ST    %Q0.2
""")

    def sc(r=0, cu=0, cd=0):
        plc["%M0"], plc["%M1"], plc["%M2"] = r, cu, cd
        plc.scan()
        return [k for k in range(256) if plc[f"%SC0.J{k}"]]

    assert sc(r=1) == [0]
    assert sc(cu=1) == [1]  # exactly one active step
    sc()
    assert sc(cu=1) == [2]
    assert plc["%Q0.2"]
    sc()
    assert sc(cd=1) == [1]
    sc()
    sc(cd=1)
    sc()
    assert sc(cd=1) == [255]  # wraps downwards
    sc()
    assert sc(cu=1) == [0]


# ---- FIFO / LIFO registers %R [manual] ------------------------------------------------------
REG_BLK = """
BLK   %R0
LD    %M0
R
LD    %M1
I
LD    %M2
O
OUT_BLK
LD    E
ST    %Q0.0
LD    F
ST    %Q0.1
END_BLK
"""

REG_SHORT = """
LD    %M0
R     %R0
LD    %M1
I     %R0
LD    %M2
O     %R0
LD    %R0.E
ST    %Q0.0
LD    %R0.F
ST    %Q0.1
"""


def reg_put(plc: PLC, v: int) -> None:
    plc["%R0.I"] = v
    plc["%M1"] = 1
    plc.scan()
    plc["%M1"] = 0
    plc.scan()


def reg_get(plc: PLC) -> int:
    plc["%M2"] = 1
    plc.scan()
    plc["%M2"] = 0
    plc.scan()
    return plc["%R0.O"]


@pytest.mark.parametrize("form", ["blk", "short"])
@pytest.mark.parametrize("kind", ["FIFO", "LIFO"])
def test_fifo_lifo(plc_from_source, form, kind):
    plc = plc_from_source(REG_BLK if form == "blk" else REG_SHORT,
                          {"registers": {"%R0": {"type": kind}}})
    plc.scan()
    assert plc["%Q0.0"] and not plc["%Q0.1"]  # empty
    for v in (10, 20, 30):
        reg_put(plc, v)
    assert not plc["%Q0.0"]
    got = [reg_get(plc) for _ in range(3)]
    assert got == ([10, 20, 30] if kind == "FIFO" else [30, 20, 10])
    assert plc["%Q0.0"]


@pytest.mark.parametrize("form", ["blk", "short"])
def test_register_full_and_reset(plc_from_source, form):
    plc = plc_from_source(REG_BLK if form == "blk" else REG_SHORT,
                          {"registers": {"%R0": {"type": "FIFO"}}})
    for v in range(17):  # 16 deep: the 17th is refused
        reg_put(plc, v)
    assert plc["%Q0.1"] and not plc["%Q0.0"]
    assert [reg_get(plc) for _ in range(16)] == list(range(16))
    reg_put(plc, 5)
    plc["%M0"] = 1
    plc.scan()
    assert plc["%Q0.0"] and not plc["%Q0.1"]


def test_register_input_word_from_the_program(plc_from_source):
    plc = plc_from_source("""
LD    1
[ %R0.I := %MW0 ]
LD    %M1
I     %R0
LD    %M2
O     %R0
LD    1
[ %MW1 := %R0.O ]
""", {"registers": {"%R0": {"type": "LIFO"}}})
    for v in (7, 8):
        plc["%MW0"] = v
        plc["%M1"] = 1
        plc.scan()
        plc["%M1"] = 0
        plc.scan()
    plc["%M2"] = 1
    plc.scan()
    plc.scan()
    assert plc["%MW1"] == 8
