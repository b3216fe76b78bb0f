"""Word objects in operation blocks: assignments, arithmetic and %S18, word logic, shifts
and rotations with %S17, indexed words and %S20, tables and bit strings, double words.

Semantics from docs/twido.md ([sure]/[m221]/[manual] tags as there).
"""

from __future__ import annotations

import pytest

from softplc import PLC


def calc(plc_from_source, expr: str, target: str = "%MW100", **words: int) -> PLC:
    """One assignment `target := expr` with words preset, after one scan."""
    plc = plc_from_source(f"LD 1\n[ {target} := {expr} ]\n")
    for name, v in words.items():
        plc["%" + name] = v
    plc.scan()
    return plc


# ---- assignments and constants --------------------------------------------------------------
def test_assign_constants_and_words(plc_from_source):
    plc = plc_from_source("""
LD   1
[ %MW0 := 123 ]
[ %MW1 := -5 ]
[ %MW2 := #7FFF ]
[ %MW3 := #FFFF ]
[ %MW4 := %MW0 ]
[ %MD10 := 100000 ]
[ %MD12 := -2 ]
[ %MW20 := %KW3 ]
""", {"constants": {"%KW3": 42}})
    plc.scan()
    assert [plc[f"%MW{i}"] for i in range(5)] == [123, -5, 32767, -1, 123]
    assert plc["%MD10"] == 100000
    assert plc["%MD12"] == -2
    assert plc["%MW20"] == 42


def test_assignment_runs_only_when_accumulator_is_one(plc_from_source):
    """[sure] an operation block runs only when the accumulator is 1."""
    plc = plc_from_source("LD %M0\n[ %MW0 := %MW0 + 1 ]\n")
    plc.scan(3)
    assert plc["%MW0"] == 0
    plc["%M0"] = 1
    plc.scan(3)
    assert plc["%MW0"] == 3


def test_inc_dec(plc_from_source):
    plc = plc_from_source("""
LD 1
[ INC %MW0 ]
[ DEC %MW1 ]
[ INC %MD2 ]
""")
    plc["%MD2"] = 65535
    plc.scan(2)
    assert plc["%MW0"] == 2 and plc["%MW1"] == -2 and plc["%MD2"] == 65537
    assert not plc["%S18"]


def test_inc_overflow_sets_s18(plc_from_source):
    plc = plc_from_source("LD 1\n[ INC %MW0 ]\n")
    plc["%MW0"] = 32767
    plc.scan()
    assert plc["%MW0"] == -32768  # wraps [sure: %S18 on overflow]
    assert plc["%S18"]


# ---- arithmetic and %S18 [sure] -------------------------------------------------------------
@pytest.mark.parametrize("expr,a,b,expected", [
    ("%MW0 + %MW1", 1200, 34, 1234),
    ("%MW0 - %MW1", 5, 9, -4),
    ("%MW0 * %MW1", -120, 100, -12000),
    ("%MW0 / %MW1", 7, 2, 3),
    ("%MW0 / %MW1", -7, 2, -3),  # truncates towards zero [manual]
    ("%MW0 REM %MW1", 7, 3, 1),
    ("%MW0 REM %MW1", -7, 3, -1),  # sign of the dividend [manual]
    ("%MW0 + %MW1 * 2", 1, 3, 7),  # * before +
    ("(%MW0 + %MW1) * 2", 1, 3, 8),
    ("%MW0 - %MW1 - 1", 10, 3, 6),  # left associative
    ("%MW0 / %MW1 * %MW1", 7, 2, 6),
    ("-%MW0 + %MW1", 3, 10, 7),
    ("ABS(%MW0)", -300, 0, 300),
    ("SQRT(%MW0)", 17, 0, 4),
])
def test_word_arithmetic(plc_from_source, expr, a, b, expected):
    plc = calc(plc_from_source, expr, MW0=a, MW1=b)
    assert plc["%MW100"] == expected
    assert not plc["%S18"]


@pytest.mark.parametrize("expr,a,b", [
    ("%MW0 + %MW1", 32767, 1),
    ("%MW0 - %MW1", -32768, 1),
    ("%MW0 * %MW1", 256, 128),
    ("%MW0 / %MW1", 5, 0),
    ("%MW0 REM %MW1", 5, 0),
    ("%MW0 / %MW1", -32768, -1),
    ("SQRT(%MW0)", -4, 0),
    ("ABS(%MW0)", -32768, 0),
])
def test_arithmetic_errors_set_s18(plc_from_source, expr, a, b):
    plc = calc(plc_from_source, expr, MW0=a, MW1=b)
    assert plc["%S18"]


def test_overflow_result_wraps_to_16_bits(plc_from_source):
    plc = calc(plc_from_source, "%MW0 + %MW1", MW0=30000, MW1=5000)
    assert plc["%MW100"] == 35000 - 65536
    assert plc["%S18"]


def test_s18_is_reset_only_by_the_program(plc_from_source):
    """[sure] %S18 is set by the system and reset only by the program."""
    plc = plc_from_source("""
LD   %M0
[ %MW0 := %MW1 / %MW2 ]
LD   %M1
R    %S18
""")
    plc["%MW1"], plc["%MW2"] = 10, 0
    plc["%M0"] = 1
    plc.scan()
    assert plc["%S18"]
    plc["%MW2"] = 5
    plc.scan(3)  # correct divisions do not clear it
    assert plc["%MW0"] == 2
    assert plc["%S18"]
    plc["%M1"] = 1
    plc.scan()
    assert not plc["%S18"]


def test_double_word_arithmetic(plc_from_source):
    plc = plc_from_source("""
LD 1
[ %MD0 := %MD2 * %MD4 ]
[ %MD6 := %MD2 + %MW10 ]
[ %MW12 := %MD2 - 99990 ]
""")
    plc["%MD2"], plc["%MD4"], plc["%MW10"] = 100000, 300, -1
    plc.scan()
    assert plc["%MD0"] == 30_000_000
    assert plc["%MD6"] == 99999
    assert plc["%MW12"] == 10
    assert not plc["%S18"]


def test_double_word_overflow_sets_s18(plc_from_source):
    plc = calc(plc_from_source, "%MD0 + 1", target="%MD2")
    assert not plc["%S18"]
    plc = plc_from_source("LD 1\n[ %MD2 := %MD0 + 1 ]\n")
    plc["%MD0"] = 2**31 - 1
    plc.scan()
    assert plc["%MD2"] == -(2**31)
    assert plc["%S18"]


def test_double_word_result_too_big_for_a_word_sets_s18(plc_from_source):
    plc = plc_from_source("LD 1\n[ %MW0 := %MD2 ]\n")
    plc["%MD2"] = 40000
    plc.scan()
    assert plc["%S18"]


# ---- word logic [sure] ----------------------------------------------------------------------
@pytest.mark.parametrize("expr,expected", [
    ("%MW0 AND %MW1", 0x0F00 & 0x3C3C),
    ("%MW0 OR %MW1", 0x0F00 | 0x3C3C),
    ("%MW0 XOR %MW1", 0x0F00 ^ 0x3C3C),
    ("NOT(%MW0)", ~0x0F00),
    ("%MW0 AND #00FF", 0),
    ("%MW1 AND #FF00", 0x3C00),
])
def test_word_logic(plc_from_source, expr, expected):
    plc = calc(plc_from_source, expr, MW0=0x0F00, MW1=0x3C3C)
    assert plc["%MW100"] == expected


def test_word_logic_on_negative_words(plc_from_source):
    plc = calc(plc_from_source, "%MW0 AND #8001", MW0=-1)
    assert plc["%MW100"] == -32767  # 0x8001 as a signed word
    plc = calc(plc_from_source, "NOT(%MW0)", MW0=-1)
    assert plc["%MW100"] == 0


# ---- shifts and rotations, carry into %S17 [sure] -------------------------------------------
@pytest.mark.parametrize("func,value,n,expected,carry", [
    ("SHL", 0x4001, 1, 0x8002, 0),
    ("SHL", 0x8001, 1, 0x0002, 1),
    ("SHL", 0x0001, 4, 0x0010, 0),
    ("SHL", 0x1000, 4, 0x0000, 1),  # the last bit out is bit 12
    ("SHR", 0x0003, 1, 0x0001, 1),
    ("SHR", 0x8000, 1, 0x4000, 0),  # logical: a zero comes in [manual]
    ("SHR", 0x0010, 4, 0x0001, 0),
    ("SHR", 0x0018, 4, 0x0001, 1),
    ("ROL", 0x8001, 1, 0x0003, 1),
    ("ROL", 0x1234, 4, 0x2341, 1),
    ("ROL", 0x4000, 1, 0x8000, 0),
    ("ROR", 0x0001, 1, 0x8000, 1),
    ("ROR", 0x1234, 4, 0x4123, 0),
    ("ROR", 0x0002, 1, 0x0001, 0),
])
def test_shifts_and_rotations(plc_from_source, func, value, n, expected, carry):
    signed = value - 0x10000 if value & 0x8000 else value
    plc = calc(plc_from_source, f"{func}( %MW0, {n} )", MW0=signed)
    assert plc["%MW100"] & 0xFFFF == expected
    assert plc["%S17"] == bool(carry)


def test_shift_by_a_word_and_carry_loop(plc_from_source):
    """Count the bits of a word with a loop on %S17, like the real exports [sure]."""
    plc = plc_from_source("""
LD    1
[ %MW1 := %MW0 ]
[ %MW2 := 0 ]
[ %MW3 := 16 ]
%L1:
LD    1
[ %MW1 := SHL( %MW1, %MW4 ) ]
LD    %S17
[ INC %MW2 ]
LD    1
[ DEC %MW3 ]
LD    [ %MW3 > 0 ]
JMPC  %L1
""")
    plc["%MW0"] = 0b1011_0000_0110_0001
    plc["%MW4"] = 1
    plc.scan()
    assert plc["%MW2"] == 6
    assert plc["%MW1"] == 0


def test_shift_of_a_double_word(plc_from_source):
    plc = plc_from_source("LD 1\n[ %MD0 := SHL( %MD2, 1 ) ]\n")
    plc["%MD2"] = 0x40000001
    plc.scan()
    assert plc["%MD0"] == -(2**31) + 2
    assert not plc["%S17"]


# ---- indexed words, %S20 [manual] -----------------------------------------------------------
def test_indexed_read_and_write(plc_from_source):
    plc = plc_from_source("""
LD 1
[ %MW0 := %MW10[%MW5] ]
[ %MW20[%MW5] := 77 ]
""")
    for i in range(10, 15):
        plc[f"%MW{i}"] = i * 100
    for k in range(5):
        plc["%MW5"] = k
        plc.scan()
        assert plc["%MW0"] == (10 + k) * 100
        assert plc[f"%MW{20 + k}"] == 77
    assert not plc["%S20"]


def test_indexed_double_word_and_float(plc_from_source):
    plc = plc_from_source("""
LD 1
[ %MD100 := %MD10[%MW0] ]
[ %MF102 := %MF20[%MW0] ]
""")
    plc["%MW0"] = 4
    plc["%MD14"] = 123456
    plc["%MF24"] = 2.5
    plc.scan()
    assert plc["%MD100"] == 123456
    assert plc["%MF102"] == 2.5


def test_index_overflow_sets_s20_and_uses_the_base(plc_from_source):
    plc = plc_from_source("""
LD 1
[ %MW0 := %MW2990[%MW5] ]
[ %MW2995[%MW5] := 5 ]
""")
    plc["%MW2990"] = 11
    plc["%MW5"] = 100  # %MW3090 is beyond %MW2999
    plc.scan()
    assert plc["%S20"]
    assert plc["%MW0"] == 11  # processed as if the index were 0 [manual]
    assert plc["%MW2995"] == 5


def test_negative_index_out_of_range_sets_s20(plc_from_source):
    plc = plc_from_source("LD 1\n[ %MW0 := %MW3[%MW5] ]\n")
    plc["%MW5"] = -10
    plc.scan()
    assert plc["%S20"]


# ---- tables and bit strings [manual] --------------------------------------------------------
def test_table_copy_and_fill(plc_from_source):
    plc = plc_from_source("""
LD 1
[ %MW0:4 := %MW10:4 ]
[ %MW20:3 := 9 ]
""")
    for k in range(4):
        plc[f"%MW{10 + k}"] = k + 1
    plc.scan()
    assert [plc[f"%MW{k}"] for k in range(5)] == [1, 2, 3, 4, 0]
    assert [plc[f"%MW{k}"] for k in range(19, 24)] == [0, 9, 9, 9, 0]
    assert plc["%MW0:4"] == [1, 2, 3, 4]


def test_bit_string_from_a_word(plc_from_source):
    plc = plc_from_source("LD 1\n[ %M8:8 := %MW0 ]\n")
    plc["%MW0"] = 0b1010_0101
    plc.scan()
    assert [int(plc[f"%M{8 + k}"]) for k in range(8)] == [1, 0, 1, 0, 0, 1, 0, 1]
    assert not plc["%M7"] and not plc["%M16"]


def test_word_from_a_bit_string(plc_from_source):
    plc = plc_from_source("LD 1\n[ %MW0 := %M8:8 ]\n")
    plc["%M8"] = 1
    plc["%M10"] = 1
    plc.scan()
    assert plc["%MW0"] == 0b101


def test_timer_and_counter_fields_in_expressions(plc_from_source):
    plc = plc_from_source("""
LD   %M0
CU   %C3
LD   1
[ %MW0 := %C3.V * 10 ]
[ %C3.P := 5 ]
LD   [ %C3.P = 5 ]
ST   %M1
""")
    for v in (1, 0, 1, 0):
        plc["%M0"] = v
        plc.scan()
    assert plc["%MW0"] == 20
    assert plc["%C3.P"] == 5 and plc["%M1"]
