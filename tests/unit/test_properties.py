"""Property tests (hypothesis): word arithmetic against a 16-bit model with %S18, the
%MF/%MD over %MW overlays, timer and counter invariants against models, the
parse -> print -> parse round trip of softplc.il.printer, and that no input text ever
gives anything but a ProgramError.
"""

from __future__ import annotations

import math
import struct
from functools import lru_cache

from fuzz_budget import examples
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from softplc import PLC
from softplc.errors import ProgramError
from softplc.il.parser import parse
from softplc.il.printer import format_program

SETTINGS = settings(max_examples=examples(150), deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
int16 = st.integers(-32768, 32767)


def wrap16(v: int) -> int:
    return ((v + 0x8000) & 0xFFFF) - 0x8000


def tdiv(a: int, b: int) -> int:
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b >= 0) else -q


# ---- word arithmetic vs a 16-bit model [sure: %S18] -----------------------------------------
OPS = ["+", "-", "*", "/", "REM"]


@lru_cache(maxsize=1)
def arith_plc() -> PLC:
    rungs = "".join(f"LD [ %MW9 = {k} ]\n[ %MW2 := %MW0 {op} %MW1 ]\n"
                    for k, op in enumerate(OPS))
    return PLC.from_source(rungs)


def model(op: str, a: int, b: int) -> tuple[int | None, bool]:
    """(result or None when not significant, %S18)."""
    if op in ("/", "REM") and b == 0:
        return None, True
    r = {"+": a + b, "-": a - b, "*": a * b, "/": tdiv(a, b) if b else 0,
         "REM": a - tdiv(a, b) * b if b else 0}[op]
    return wrap16(r), not -32768 <= r <= 32767


@SETTINGS
@given(op=st.sampled_from(OPS), a=int16, b=int16)
def test_word_arithmetic_matches_a_16_bit_model(op, a, b):
    plc = arith_plc()
    plc["%MW0"], plc["%MW1"], plc["%MW9"], plc["%MW2"] = a, b, OPS.index(op), 12345
    plc["%S18"] = 0
    plc.scan()
    expected, s18 = model(op, a, b)
    if expected is not None:
        assert plc["%MW2"] == expected
    assert plc["%S18"] == s18


@SETTINGS
@given(func=st.sampled_from(["SHL", "SHR", "ROL", "ROR"]), a=int16, n=st.integers(1, 15))
def test_shifts_match_a_model(func, a, n):
    plc = shift_plc(func)
    plc["%MW0"], plc["%MW1"] = a, n
    plc["%S17"] = 0
    plc.scan()
    u = a & 0xFFFF
    if func == "SHL":
        r, c = (u << n) & 0xFFFF, (u >> (16 - n)) & 1
    elif func == "SHR":
        r, c = u >> n, (u >> (n - 1)) & 1
    elif func == "ROL":
        r = ((u << n) | (u >> (16 - n))) & 0xFFFF
        c = r & 1
    else:
        r = ((u >> n) | (u << (16 - n))) & 0xFFFF
        c = r >> 15
    assert plc["%MW2"] & 0xFFFF == r
    assert plc["%S17"] == bool(c)


@lru_cache(maxsize=4)
def shift_plc(func: str) -> PLC:
    return PLC.from_source(f"LD 1\n[ %MW2 := {func}( %MW0, %MW1 ) ]\n")


# ---- overlays [sure; odd indices manual] ----------------------------------------------------
floats32 = st.floats(width=32, allow_nan=False)


@lru_cache(maxsize=1)
def overlay_plc() -> PLC:
    return PLC.from_source("""
LD 1
[ %MF2990 := %MF0[%MW2994] ]
[ %MD2996 := %MD0[%MW2994] ]
""")


@SETTINGS
@given(i=st.integers(0, 2988), f=floats32)
def test_float_overlay_round_trip(i, f):
    plc = overlay_plc()
    plc[f"%MF{i}"] = f
    raw = struct.unpack("<I", struct.pack("<f", f))[0]
    assert plc[f"%MW{i}"] & 0xFFFF == raw & 0xFFFF  # low word first
    assert plc[f"%MW{i + 1}"] & 0xFFFF == raw >> 16
    assert plc[f"%MF{i}"] == f
    plc["%MW2994"] = i  # the program reads it back through an indexed %MF
    plc.scan()
    assert plc["%MF2990"] == f


@SETTINGS
@given(i=st.integers(0, 2988), lo=int16, hi=int16)
def test_words_to_float_and_double_word(i, lo, hi):
    plc = overlay_plc()
    plc[f"%MW{i}"], plc[f"%MW{i + 1}"] = lo, hi
    raw = (lo & 0xFFFF) | (hi & 0xFFFF) << 16
    d = raw - (1 << 32) if raw >> 31 else raw
    assert plc[f"%MD{i}"] == d
    f = struct.unpack("<f", struct.pack("<I", raw))[0]
    got = plc[f"%MF{i}"]
    assert got == f or (math.isnan(f) and math.isnan(got))
    plc["%MW2994"] = i
    plc.scan()
    assert plc["%MD2996"] == d


@SETTINGS
@given(i=st.integers(0, 2998), d=st.integers(-(2**31), 2**31 - 1))
def test_double_word_round_trip(i, d):
    plc = overlay_plc()
    plc[f"%MD{i}"] = d
    assert plc[f"%MD{i}"] == d
    assert plc[f"%MW{i}"] & 0xFFFF == d & 0xFFFF
    assert plc[f"%MW{i + 1}"] & 0xFFFF == (d >> 16) & 0xFFFF


# ---- timers [manual] ------------------------------------------------------------------------
PERIODS_MS = [1, 3, 10, 25]


@lru_cache(maxsize=12)
def timer_plc(type_: str, period_ms: int) -> PLC:
    return PLC.from_source("""
LD 1
[ %TM0.P := %MW0 ]
LD %M0
IN %TM0
""", {"scan_period": f"{period_ms}ms",
      "timers": {"%TM0": {"type": type_, "base": "10ms", "preset": 0}}})


@SETTINGS
@given(period=st.sampled_from(PERIODS_MS), preset=st.integers(0, 12),
       ins=st.lists(st.booleans(), min_size=1, max_size=80))
def test_ton_invariants(period, preset, ins):
    plc = timer_plc("TON", period)
    plc.cold_start()
    plc["%MW0"] = preset
    rise = None
    for v in ins:
        t = plc.clock.now_us
        plc["%M0"] = v
        plc.scan()
        V, Q = plc["%TM0.V"], plc["%TM0.Q"]
        assert 0 <= V <= preset
        if v:
            rise = t if rise is None else rise
            assert V == min(preset, (t - rise) // 10_000)
            assert Q == (V == preset)  # Q iff V = P while IN = 1
        else:
            rise = None
            assert V == 0 and not Q


@SETTINGS
@given(type_=st.sampled_from(["TOF", "TP"]), period=st.sampled_from(PERIODS_MS),
       preset=st.integers(1, 12), ins=st.lists(st.booleans(), min_size=1, max_size=80))
def test_tof_tp_invariants(type_, period, preset, ins):
    plc = timer_plc(type_, period)
    plc.cold_start()
    plc["%MW0"] = preset
    q_prev, in_prev = False, False
    for v in ins:
        plc["%M0"] = v
        plc.scan()
        V, Q = plc["%TM0.V"], plc["%TM0.Q"]
        assert 0 <= V <= preset
        if type_ == "TOF":
            if v:
                assert Q and V == 0  # Q = 1 while IN = 1
            elif not in_prev and not q_prev:
                assert not Q  # once off, stays off until IN rises
        else:
            if v and not in_prev and not q_prev:
                assert Q  # a rising edge outside a pulse starts one
            if Q:
                assert V < preset
        q_prev, in_prev = Q, v


# ---- counters [m221] ------------------------------------------------------------------------
@lru_cache(maxsize=1)
def counter_plc() -> PLC:
    return PLC.from_source("""
BLK %C0
LD %M0
R
LD %M1
S
LD %M2
CU
LD %M3
CD
END_BLK
""", {"counters": {"%C0": {"preset": 5}}})


rare = st.sampled_from([0, 0, 0, 1])  # R and S seldom, so that counts accumulate
counter_inputs = st.tuples(rare, rare, st.integers(0, 1), st.integers(0, 1))


@SETTINGS
@given(start=st.sampled_from([0, 5, 9998, 9999]),
       seq=st.lists(counter_inputs, max_size=60))
def test_counter_matches_a_model(start, seq):
    plc = counter_plc()
    plc.cold_start()
    blk = plc.mem.blocks["C"][0]
    blk.V = start
    V, E, F, pcu, pcd = start, 0, 0, 0, 0
    for r, s, cu, cd in seq:
        plc["%M0"], plc["%M1"], plc["%M2"], plc["%M3"] = r, s, cu, cd
        plc.scan()
        up, down = cu and not pcu, cd and not pcd
        pcu, pcd = cu, cd
        if r:
            V, E, F = 0, 0, 0
        elif s:
            V = 5
        elif up != down:
            E = F = 0
            V += 1 if up else -1
            if V > 9999:
                V, F = 0, 1
            elif V < 0:
                V, E = 9999, 1
        assert (plc["%C0.V"], plc["%C0.D"], plc["%C0.E"], plc["%C0.F"]) == (
            V, V == 5, bool(E), bool(F))
        assert 0 <= plc["%C0.V"] <= 9999


# ---- parse -> print -> parse ----------------------------------------------------------------
bits = st.one_of(
    st.integers(0, 255).map(lambda i: f"%M{i}"),
    st.integers(0, 23).map(lambda i: f"%I0.{i}"),
    st.integers(0, 15).map(lambda i: f"%Q0.{i}"),
    st.tuples(st.integers(0, 2999), st.integers(0, 15)).map(lambda t: f"%MW{t[0]}:X{t[1]}"),
    st.sampled_from(["%S13", "%S18", "%X3", "%TM0.Q", "%C1.D", "0", "1"]),
)
out_bits = st.one_of(st.integers(0, 255).map(lambda i: f"%M{i}"),
                     st.integers(0, 15).map(lambda i: f"%Q0.{i}"))
word_atoms = st.one_of(
    st.integers(0, 2999).map(lambda i: f"%MW{i}"),
    st.integers(-32768, 32767).map(str),
    st.integers(0, 0xFFFF).map(lambda v: f"#{v:X}"),
    st.sampled_from(["%KW3", "%TM0.V", "%C1.P", "%MW5[%MW7]", "%SW30"]),
)
words = st.recursive(
    word_atoms,
    lambda sub: st.one_of(
        st.tuples(sub, st.sampled_from(["+", "-", "*", "/", "REM", "AND", "OR", "XOR"]), sub)
        .map(lambda t: f"{t[0]} {t[1]} {t[2]}"),
        sub.map(lambda e: f"( {e} )"),
        sub.map(lambda e: f"-( {e} )"),
        st.tuples(st.sampled_from(["SHL", "SHR", "ROL", "ROR"]), sub, st.integers(1, 15))
        .map(lambda t: f"{t[0]}( {t[1]}, {t[2]} )"),
        sub.map(lambda e: f"ABS( {e} )"),
    ),
    max_leaves=6,
)
float_atoms = st.one_of(
    st.integers(0, 2998).map(lambda i: f"%MF{i}"),
    st.floats(0, 1e6, allow_nan=False).map(repr),
    st.sampled_from(["1.0E3", "2.5e-3", "%KF4"]),
    st.integers(0, 2999).map(lambda i: f"INT_TO_REAL( %MW{i} )"),
)
floats = st.recursive(
    float_atoms,
    lambda sub: st.one_of(
        st.tuples(sub, st.sampled_from(["+", "-", "*", "/"]), sub)
        .map(lambda t: f"{t[0]} {t[1]} {t[2]}"),
        st.tuples(st.sampled_from(["SIN", "SQRT", "LN", "TRUNC", "ABS", "EXP"]), sub)
        .map(lambda t: f"{t[0]}( {t[1]} )"),
        st.tuples(sub, sub).map(lambda t: f"EXPT( {t[0]}, {t[1]} )"),
    ),
    max_leaves=5,
)
compare = st.one_of(
    st.tuples(words, st.sampled_from([">", ">=", "<", "<=", "=", "<>"]), words),
    st.tuples(floats, st.sampled_from([">", "<", "<>"]), floats),
).map(lambda t: f"[ {t[0]} {t[1]} {t[2]} ]")
operand = st.one_of(bits, bits, compare)
logic = st.tuples(st.sampled_from(["AND", "ANDN", "ANDR", "ANDF", "OR", "ORN", "ORR", "ORF",
                                   "XOR", "XORN", "XORR", "XORF"]), operand) \
    .map(lambda t: [f"{t[0]}   {t[1]}"])
paren = st.tuples(st.sampled_from(["AND(", "OR(", "XOR(", "AND(N", "OR(R"]), operand,
                  st.lists(logic, max_size=2)) \
    .map(lambda t: [f"{t[0]} {t[1]}"] + [x for ls in t[2] for x in ls] + [")"])
output = st.one_of(
    st.tuples(st.sampled_from(["ST", "STN", "S", "R"]), out_bits).map(lambda t: f"{t[0]} {t[1]}"),
    st.tuples(st.integers(0, 2999), words).map(lambda t: f"[ %MW{t[0]} := {t[1]} ]"),
    st.tuples(st.integers(0, 2998), floats).map(lambda t: f"[ %MF{t[0]} := {t[1]} ]"),
    st.integers(0, 2999).map(lambda i: f"[ INC %MW{i} ]"),
)
rung = st.tuples(st.sampled_from(["LD", "LDN", "LDR", "LDF"]), operand,
                 st.lists(st.one_of(logic, paren), max_size=4),
                 st.lists(output, min_size=1, max_size=3)) \
    .map(lambda t: [f"{t[0]}    {t[1]}"] + [x for ls in t[2] for x in ls] + t[3])


@settings(max_examples=examples(150), deadline=None)
@given(rungs=st.lists(rung, min_size=1, max_size=8), noise=st.booleans())
def test_parse_print_parse_round_trip(rungs, noise):
    lines = []
    for k, r in enumerate(rungs):
        if noise:  # comments, blank lines and case do not matter
            lines += [f"(* rung {k} *)", ""]
            r = [r[0].lower()] + r[1:]
        lines += r
    text = "\n".join(lines) + "\n"
    prog = parse(text)
    # the generated program has exactly the rungs and instructions generated
    assert [len(r.instructions) for r in prog.rungs] == [len(r) for r in rungs]
    printed = format_program(prog)
    again = parse(printed)
    assert [r.instructions for r in again.rungs] == [r.instructions for r in prog.rungs]
    assert format_program(again) == printed


@settings(max_examples=examples(40), deadline=None)
@given(rungs=st.lists(rung, min_size=1, max_size=4))
def test_printed_program_behaves_like_the_original(rungs):
    text = "\n".join(x for r in rungs for x in r) + "\n"
    cfg = {"timers": {"%TM0": {"type": "TON", "base": "10ms", "preset": 3}},
           "constants": {"%KW3": 7, "%KF4": 0.5}}
    try:
        a = PLC.from_source(text, cfg)
    except ProgramError:
        assume(False)
    b = PLC.from_source(format_program(a.ast), cfg)
    for k in range(4):
        for p in (a, b):
            p["%MW5"], p["%M7"], p["%I0.3"] = k, k % 2, k // 2 % 2
            p.scan()
    assert bytes(a.mem.mw.buf) == bytes(b.mem.mw.buf)
    assert a.mem.m == b.mem.m and a.mem.q == b.mem.q and a.mem.s == b.mem.s


# ---- robustness -----------------------------------------------------------------------------
TOKENS = ["LD", "ST", "AND(", ")", "[", "]", ":=", "%MW3", "%M1", "%Q0.0", "%L1:", "JMP",
          "%L1", "SR1", "SR1:", "RET", "END", "BLK", "%TM0", "%C0", "OUT_BLK", "END_BLK",
          "IN", "CU", "Q", "1", "0", "-", "+", "1.5", "#FF", "(*", "*)", "MPS", "MPP",
          "SHL(", ",", "=*=", "#", "-*-", "\n", "\n", "\n", " ", "%MF1", "INT_TO_REAL(",
          "\n=*= 0\n", "\n-*- 1\n", "\n# 1\n", "\n=*= POST\n", "\nLD %M0\n", "\nST %M1\n"]


@settings(max_examples=examples(200), deadline=None)
@given(st.lists(st.sampled_from(TOKENS), max_size=40).map(" ".join))
def test_any_text_gives_a_program_or_a_program_error(text):
    try:
        plc = PLC.from_source(text, {"timers": {"%TM0": {"type": "TON", "base": "1s",
                                                         "preset": 1}}, "watchdog": "20ms"})
    except ProgramError as e:
        assert e.diagnostics
        for d in e.diagnostics:
            assert d.file == "<string>" and d.message
    else:
        plc.scan(2)
