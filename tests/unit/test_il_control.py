"""Program control: JMP/JMPC/JMPCN (forward and backward: loops), labels, subroutine
calls SRi / SRi: / RET(C/CN), END/ENDC/ENDCN, the watchdog on endless loops, Grafcet.

Semantics from docs/twido.md ([sure]/[m221]/[manual] tags as there).
"""

from __future__ import annotations

import time

import pytest

from softplc import PLC


# ---- jumps [sure] ---------------------------------------------------------------------------
def test_jmp_skips_rungs(plc_from_source):
    plc = plc_from_source("""
LD    1
ST    %M0
JMP   %L1
LD    1
ST    %M1
%L1:
LD    1
ST    %M2
""")
    plc.scan()
    assert plc["%M0"] and not plc["%M1"] and plc["%M2"]


@pytest.mark.parametrize("cond", [0, 1])
def test_jmpc_and_jmpcn(plc_from_source, cond):
    plc = plc_from_source("""
LD    %M0
JMPC  %L1
LD    1
ST    %M1
%L1:
LD    %M0
JMPCN %L2
LD    1
ST    %M2
%L2:
LD    1
ST    %M3
""")
    plc["%M0"] = cond
    plc.scan()
    assert plc["%M1"] == (not cond)  # skipped when the accumulator is 1
    assert plc["%M2"] == bool(cond)  # skipped when the accumulator is 0
    assert plc["%M3"]


def test_skipped_rungs_keep_their_outputs(plc_from_source):
    plc = plc_from_source("""
LD    %M0
JMPC  %L3
LD    %M1
ST    %Q0.0
%L3:
LD    1
ST    %M9
""")
    plc["%M1"] = 1
    plc.scan()
    assert plc["%Q0.0"]
    plc["%M0"] = 1
    plc["%M1"] = 0
    plc.scan()
    assert plc["%Q0.0"]  # not executed: keeps its value


def test_backward_jump_loop(plc_from_source):
    """Sum 1..%MW0 with a backward conditional jump [sure: loops in real exports]."""
    plc = plc_from_source("""
LD    1
[ %MW1 := 0 ]
[ %MW2 := %MW0 ]
%L10:
LD    [ %MW2 > 0 ]
[ %MW1 := %MW1 + %MW2 ]
[ DEC %MW2 ]
LD    [ %MW2 > 0 ]
JMPC  %L10
LD    1
[ %MW3 := %MW3 + 1 ]
""")
    plc["%MW0"] = 100
    plc.scan()
    assert plc["%MW1"] == 5050 and plc["%MW2"] == 0 and plc["%MW3"] == 1
    assert plc.state == "RUN"


def test_label_on_a_rung_line_and_at_the_end(plc_from_source):
    plc = plc_from_source("""
LD    %M0
JMPC  %L5
LD    1
ST    %M1
%L5:
""")
    plc["%M0"] = 1
    plc.scan()
    assert not plc["%M1"]
    plc["%M0"] = 0
    plc.scan()
    assert plc["%M1"]


def test_many_loops_in_one_scan_finish(plc_from_source):
    plc = plc_from_source("""
LD    1
[ %MW0 := 0 ]
[ %MW1 := 0 ]
%L1:
LD    1
[ INC %MW0 ]
[ %MW2 := 0 ]
%L2:
LD    1
[ INC %MW2 ]
[ INC %MW1 ]
LD    [ %MW2 < 50 ]
JMPC  %L2
LD    [ %MW0 < 40 ]
JMPC  %L1
""")
    plc.scan()
    assert plc["%MW1"] == 2000


# ---- watchdog [manual] ----------------------------------------------------------------------
def test_endless_loop_halts_with_s11(plc_from_source):
    plc = plc_from_source("""
LD    1
ST    %Q0.0
%L1:
LD    1
JMP   %L1
""", {"watchdog": "20ms"})
    t0 = time.perf_counter()
    plc.scan()
    assert time.perf_counter() - t0 < 5  # ends, does not hang
    assert plc.state == "HALT"
    assert plc["%S11"]
    assert "watchdog" in plc.fault
    assert not plc["%Q0.0"]  # outputs to their fallback 0
    n = plc.scan_count
    plc.scan(3)  # HALT: the program no longer runs
    assert plc.state == "HALT" and not plc["%Q0.0"]
    assert plc.scan_count >= n


def test_endless_loop_in_a_subroutine_halts(plc_from_source):
    plc = plc_from_source("""
LD    1
SR2
END
SR2:
%L7:
LD    1
JMPC  %L7
RET
""", {"watchdog": "20ms"})
    plc.scan()
    assert plc.state == "HALT" and plc["%S11"]


def test_halt_until_reinitialised(plc_from_source):
    plc = plc_from_source("""
LD    1
ST    %Q0.0
%L1:
LD    %M0
JMPC  %L1
""", {"watchdog": "20ms"})
    plc["%M0"] = 1
    plc.scan()
    assert plc.state == "HALT"
    plc["%M0"] = 0
    plc.start()  # start() does not leave HALT
    plc.scan()
    assert plc.state == "HALT"
    plc.cold_start()
    plc.scan()
    assert plc.state == "RUN" and not plc["%S11"] and plc["%Q0.0"]


def test_recursive_subroutine_halts_instead_of_crashing(plc_from_source):
    plc = plc_from_source("""
LD    1
SR1
END
SR1:
LD    1
SR1
RET
""")
    plc.scan()
    assert plc.state == "HALT"


# ---- subroutines [sure] ---------------------------------------------------------------------
def test_subroutine_call_and_return(plc_from_source):
    plc = plc_from_source("""
LD    %M0
SR3
LD    1
[ %MW1 := %MW0 ]
END
SR3:
LD    1
[ %MW0 := %MW0 + 10 ]
RET
""")
    plc.scan()
    assert plc["%MW0"] == 0  # not called: accumulator 0
    plc["%M0"] = 1
    plc.scan(2)
    assert plc["%MW0"] == 20 and plc["%MW1"] == 20  # runs before the next rung


def test_conditional_returns(plc_from_source):
    plc = plc_from_source("""
LD    1
SR0
END
SR0:
LD    1
[ %MW0 := 1 ]
LD    %M0
RETC
LD    1
[ %MW1 := 1 ]
LD    %M1
RETCN
LD    1
[ %MW2 := 1 ]
RET
""")
    plc["%M0"] = 1
    plc.scan()
    assert (plc["%MW0"], plc["%MW1"], plc["%MW2"]) == (1, 0, 0)
    plc["%M0"] = 0
    plc.scan()
    assert (plc["%MW1"], plc["%MW2"]) == (1, 0)
    plc["%M1"] = 1
    plc.scan()
    assert plc["%MW2"] == 1


def test_nested_subroutines_and_jumps_inside(plc_from_source):
    plc = plc_from_source("""
LD    1
SR1
END
SR1:
LD    1
[ %MW0 := 0 ]
%L1:
LD    1
SR2
LD    [ %MW0 < 5 ]
JMPC  %L1
RET
SR2:
LD    1
[ INC %MW0 ]
[ INC %MW1 ]
RET
""")
    plc.scan(2)
    assert plc["%MW0"] == 5 and plc["%MW1"] == 10


def test_same_label_number_in_main_and_subroutine(plc_from_source):
    """Labels are local to the main program or a subroutine."""
    plc = plc_from_source("""
LD    1
JMP   %L1
LD    1
ST    %M0
%L1:
LD    1
SR1
END
SR1:
LD    1
JMP   %L1
LD    1
ST    %M1
%L1:
LD    1
ST    %M2
RET
""")
    plc.scan()
    assert not plc["%M0"] and not plc["%M1"] and plc["%M2"]


# ---- END / ENDC / ENDCN [sure] --------------------------------------------------------------
def test_end_variants(plc_from_source):
    plc = plc_from_source("""
LD    1
[ INC %MW0 ]
LD    %M0
ENDC
LD    1
[ INC %MW1 ]
LD    %M1
ENDCN
LD    1
[ INC %MW2 ]
END
""")
    plc["%M0"], plc["%M1"] = 1, 1
    plc.scan()
    assert (plc["%MW0"], plc["%MW1"], plc["%MW2"]) == (1, 0, 0)
    plc["%M0"] = 0
    plc.scan()
    assert (plc["%MW0"], plc["%MW1"], plc["%MW2"]) == (2, 1, 1)
    plc["%M1"] = 0
    plc.scan()
    assert (plc["%MW0"], plc["%MW1"], plc["%MW2"]) == (3, 2, 1)


def test_end_still_publishes_outputs(plc_from_source):
    plc = plc_from_source("LD 1\nST %Q0.0\nLD 1\nENDC\nLD 1\nST %Q0.1\n")
    plc.scan()
    assert plc["%Q0.0"] and not plc["%Q0.1"]


def test_nop(plc_from_source):
    plc = plc_from_source("LD 1\nNOP\nST %M0\n")
    plc.scan()
    assert plc["%M0"]


# ---- Grafcet [manual] -----------------------------------------------------------------------
GRAFCET = """
=*=   0
LD    %M0
#     1
-*-   1
LD    %M1
#     2
-*-   2
LD    %M2
#     0
LD    %M3
#
=*=   POST
LD    %X0
ST    %Q0.0
LD    %X1
ST    %Q0.1
LD    %X2
ST    %Q0.2
"""


def steps(plc: PLC) -> list[int]:
    return [k for k in range(4) if plc[f"%X{k}"]]


def gstep(plc: PLC, **bits: int) -> list[int]:
    for k in range(4):
        plc[f"%M{k}"] = bits.get(f"M{k}", 0)
    plc.scan()
    return steps(plc)


def test_grafcet_sequence(plc_from_source):
    plc = plc_from_source(GRAFCET)
    assert steps(plc) == [0]  # the initial step after a cold start
    assert gstep(plc) == [0]
    assert plc["%Q0.0"]
    assert gstep(plc, M1=1) == [0]  # not the active step's transition
    assert gstep(plc, M0=1) == [1]
    assert plc["%Q0.1"] and not plc["%Q0.0"]  # post-processing sees the new step
    assert gstep(plc, M0=1, M1=1) == [2]  # one transition per scan
    assert gstep(plc, M2=1) == [0]
    plc.cold_start()
    assert gstep(plc, M0=1) == [1]


def test_grafcet_transitions_use_the_step_state_at_the_start(plc_from_source):
    """All M bits on: each scan moves one step (evolution at the end of the sequential
    part), never 0 -> 1 -> 2 in one scan."""
    plc = plc_from_source(GRAFCET)
    seen = [gstep(plc, M0=1, M1=1, M2=1) for _ in range(4)]
    assert seen == [[1], [2], [0], [1]]


def test_grafcet_deactivate_current_step(plc_from_source):
    plc = plc_from_source(GRAFCET)
    gstep(plc, M0=1)
    gstep(plc, M1=1)
    assert gstep(plc, M3=1) == []  # '#' alone deactivates step 2
    assert gstep(plc, M0=1, M1=1, M2=1) == []


def test_grafcet_cold_start_resets_steps(plc_from_source):
    plc = plc_from_source(GRAFCET)
    gstep(plc, M0=1)
    assert steps(plc) == [1]
    plc.cold_start()
    assert steps(plc) == [0]


def test_endless_loop_with_the_default_watchdog(plc_from_source):
    plc = plc_from_source("%L1:\nLD 1\nJMP %L1\n")
    t0 = time.perf_counter()
    plc.scan()
    assert time.perf_counter() - t0 < 5  # 150 ms watchdog [manual], not a hang
    assert plc.state == "HALT" and plc["%S11"]


class _StalledWallClock:
    """The engine's `time` with a wall clock that jumps 100 ms per reading, as when a
    loaded host does not run the process; CPU time stays real."""

    thread_time = staticmethod(time.thread_time)

    def __init__(self) -> None:
        # from the real reading: the scan's own start (its deadline's base) is one, and a
        # clock from 0 would stay 10^5 readings behind it (seconds of CPU to catch up)
        self.t = time.perf_counter()

    def perf_counter(self) -> float:
        self.t += 0.1
        return self.t


def test_host_load_alone_does_not_trip_the_watchdog(plc_from_source, monkeypatch):
    # The watchdog limits the controller's own execution time [manual: docs/twido.md#scan-cycle]:
    # wall time the OS gave to other processes is not the program's
    # (docs/decisions/watchdog-cpu-time.md)
    from softplc.runtime import engine

    plc = plc_from_source("LD %I0.0\nST %Q0.0\n", {"watchdog": "20ms"})
    monkeypatch.setattr(engine, "time", _StalledWallClock())
    for k in range(5):
        plc["%I0.0"] = k % 2
        plc.scan()
        assert plc.state == "RUN" and plc["%Q0.0"] == k % 2
    assert not plc["%S11"]


def test_endless_loop_halts_under_host_load_too(plc_from_source, monkeypatch):
    from softplc.runtime import engine

    plc = plc_from_source("%L1:\nLD 1\nJMP %L1\n", {"watchdog": "20ms"})
    monkeypatch.setattr(engine, "time", _StalledWallClock())
    plc.scan()
    assert plc.state == "HALT" and plc["%S11"] and "watchdog" in plc.fault


def test_grafcet_step_with_a_rung_without_output(plc_from_source):
    """A step whose rung only loads compiles (it does nothing)."""
    plc = plc_from_source("=*= 0\nLD %M0\n-*- 1\nLD %M1\n# 0\n")
    plc.scan()
    assert steps(plc) == [0]
