"""Bad input never gets past as a traceback: random programs and random Modbus requests."""

from __future__ import annotations

import struct

from fuzz_budget import examples
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from softplc import PLC, ProgramError
from softplc.modbus.image import ModbusImage
from softplc.modbus.protocol import process_pdu
from softplc.runtime.memory import MemoryImage

# ---- Instruction List ----------------------------------------------------------------------
OPS = ["LD", "LDN", "LDR", "LDF", "AND", "ANDN", "OR", "ORN", "XOR", "ST", "STN", "S", "R",
       "N", "AND(", "OR(N", ")", "MPS", "MRD", "MPP", "JMP", "JMPC", "JMPCN", "SR1", "RET",
       "END", "ENDC", "NOP", "BLK", "OUT_BLK", "END_BLK", "IN", "CU", "CD", "Q", "=*=", "#",
       "INC", "DEC", "SR1:", "%L1:", "%L2:", "SECTION 0"]
OPERANDS = ["%M0", "%M1", "%Q0.0", "%I0.1", "%MW0", "%MW1", "%MD2", "%MF4", "%KW0", "%TM0",
            "%TM0.Q", "%C0", "%C0.D", "%L1", "%L2", "1", "0", "[ %MW0 > 3 ]",
            "[ %MF4 < 1.5 ]", "%S13", "%MW0:X3", "%M300", "%MW9999", "#FF", "1.5E3", ""]
EXPRS = ["%MW0 := %MW1 + 1", "%MF4 := %MF4 * 2.0", "%MW1 := %MW0 / 0", "%MW0 := SHL( %MW0, 3 )",
         "%MF4 := SQRT( %MF4 )", "%MW0 := REAL_TO_INT( %MF4 )", "%MW0 := %MF4",
         "INC %MW5", "%MW0 := ", "%MW2[%MW0] := 7", "%M0:8 := %MW0"]
GARBAGE = st.text(alphabet="%[]():=#*,.;+-/ ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789\t",
                  max_size=20)

line = st.one_of(
    st.builds(lambda o, a: f"{o} {a}".strip(), st.sampled_from(OPS), st.sampled_from(OPERANDS)),
    st.builds(lambda e: f"[ {e} ]", st.sampled_from(EXPRS)),
    st.builds(lambda c: f"(* {c} *)", GARBAGE.filter(lambda t: "*)" not in t)),
    GARBAGE,
)
CONFIG = {"watchdog": "5ms", "timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 3}}}


@settings(max_examples=examples(300), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(line, max_size=25))
def test_random_programs_load_or_fail_cleanly(lines):
    text = "\n".join(lines) + "\n"
    try:
        plc = PLC.from_source(text, CONFIG)
    except ProgramError as e:
        assert e.diagnostics and all(d.line >= 0 and d.message for d in e.diagnostics)
        return
    plc["%M0"], plc["%MW0"], plc["%MF4"] = 1, 5, 2.5
    plc.scan(3)  # runs, or ends in HALT (an endless loop trips the 5 ms watchdog)
    assert plc.state in ("RUN", "HALT")


# ---- Modbus PDUs ---------------------------------------------------------------------------
FCS = [1, 2, 3, 4, 5, 6, 15, 16, 23, 43, 0, 7, 0x5A, 0x83]


def pdus():
    fc = st.sampled_from(FCS)
    raw = st.binary(max_size=40)
    # near-valid: a function code, an address, a quantity, a byte count and data
    shaped = st.builds(
        lambda f, a, q, data: bytes([f]) + struct.pack(">HH", a, q) + bytes([len(data)]) + data,
        fc, st.integers(0, 0xFFFF), st.integers(0, 0xFFFF), st.binary(max_size=30))
    return st.one_of(st.builds(lambda f, r: bytes([f]) + r, fc, raw), shaped, raw)


@settings(max_examples=examples(1500), deadline=None)
@given(pdus())
def test_random_requests_get_a_reply_or_an_exception(pdu):
    mem = MemoryImage()
    img = ModbusImage(mem)
    before_regs, before_coils = bytes(mem.mw.buf), list(mem.m)
    reply = process_pdu(img, pdu)
    assert isinstance(reply, bytes) and reply
    fc = pdu[0] if pdu else 0
    if reply[0] & 0x80:  # an exception reply: function | 0x80, code 01..03, nothing queued
        assert reply[0] == (fc | 0x80) and len(reply) == 2 and reply[1] in (1, 2, 3)
        assert img.pending == 0
    else:
        assert reply[0] == fc and fc in (1, 2, 3, 4, 5, 6, 15, 16, 23, 43)
    img.apply_writes()
    if reply[0] & 0x80 or fc in (1, 2, 3, 4, 43):  # refused or a read: memory untouched
        assert bytes(mem.mw.buf) == before_regs and list(mem.m) == before_coils


BITS = ["%M0", "%M1", "%M2", "%I0.1", "%Q0.0", "%S6", "%MW0:X1", "%TM0.Q", "%C0.D"]
TARGETS = ["%M0", "%M1", "%M2", "%Q0.0", "%Q0.1", "%MW3:X0"]
ASSIGN = ["[ %MW0 := %MW0 + 1 ]", "[ %MW1 := %MW0 * %MW0 ]", "[ %MW2 := %MW1 / %MW0 ]",
          "[ %MF4 := INT_TO_REAL( %MW0 ) / 3.0 ]", "[ %MW5 := REAL_TO_INT( %MF4 ) ]",
          "[ %MW6 := ROL( %MW1, 3 ) ]", "[ %MD8 := %MD8 - 70000 ]", "[ %MW7 := %MW0 REM 4 ]",
          "[ DEC %MW0 ]", "[ %MW10[%MW0] := 1 ]"]

rung = st.builds(
    lambda load, logic, out: [load, *logic, out],
    st.builds(lambda o, b: f"{o} {b}", st.sampled_from(["LD", "LDN", "LDR", "LDF"]),
              st.sampled_from(BITS + ["[ %MW0 > 2 ]", "1"])),
    st.lists(st.builds(lambda o, b: f"{o} {b}",
                       st.sampled_from(["AND", "ANDN", "OR", "ORN", "XOR", "ANDR"]),
                       st.sampled_from(BITS)), max_size=4),
    st.one_of(st.builds(lambda o, t: f"{o} {t}", st.sampled_from(["ST", "STN", "S", "R"]),
                        st.sampled_from(TARGETS)),
              st.sampled_from(ASSIGN), st.just("IN %TM0"), st.just("CU %C0"),
              st.just("JMPC %L1")),
)


@settings(max_examples=examples(150), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(rung, min_size=1, max_size=15), st.integers(0, 14))
def test_generated_valid_programs_compile_and_run(rungs, label_at):
    """Valid rungs (a backward JMPC may loop for ever: the watchdog ends it in HALT)."""
    lines = []
    for k, r in enumerate(rungs):
        if k == min(label_at, len(rungs) - 1):
            lines.append("%L1:")
        lines += r
    if not any(ln == "%L1:" for ln in lines):
        lines.insert(0, "%L1:")
    plc = PLC.from_source("\n".join(lines) + "\n", CONFIG)  # must compile
    plc["%M0"], plc["%MW0"] = 1, 3
    plc.scan(3)
    assert plc.state in ("RUN", "HALT")
    if plc.state == "HALT":
        assert plc["%S11"] and "watchdog" in plc.fault
