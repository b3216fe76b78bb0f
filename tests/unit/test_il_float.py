"""Floats: %MF arithmetic, float functions, conversions (with the INTO_TO_REAL alias of
the seed document), %S18 on domain errors, and the %MF/%MD over %MW overlay.

Semantics from docs/twido.md ([sure]/[m221]/[manual] tags as there).
"""

from __future__ import annotations

import math
import struct

import pytest

from softplc import PLC


def f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def fcalc(plc_from_source, expr: str, target: str = "%MF100", **objs) -> PLC:
    plc = plc_from_source(f"LD 1\n[ {target} := {expr} ]\n")
    for name, v in objs.items():
        plc["%" + name] = v
    plc.scan()
    return plc


# ---- arithmetic -----------------------------------------------------------------------------
@pytest.mark.parametrize("expr,a,b,expected", [
    ("%MF0 + %MF2", 1.5, 2.25, 3.75),
    ("%MF0 - %MF2", 1.5, 2.25, -0.75),
    ("%MF0 * %MF2", -1.5, 4.0, -6.0),
    ("%MF0 / %MF2", 1.0, 4.0, 0.25),
    ("%MF0 * 2.0 + 1.0E3", 0.5, 0.0, 1001.0),
    ("-%MF0", 0.5, 0.0, -0.5),
    ("%MF0 + 1", 0.5, 0.0, 1.5),  # an integer literal in a float context
])
def test_float_arithmetic(plc_from_source, expr, a, b, expected):
    plc = fcalc(plc_from_source, expr, MF0=a, MF2=b)
    assert plc["%MF100"] == pytest.approx(expected)
    assert not plc["%S18"]


def test_float_results_are_single_precision(plc_from_source):
    plc = fcalc(plc_from_source, "%MF0 / 3.0", MF0=1.0)
    assert plc["%MF100"] == f32(1.0 / 3.0)
    assert plc["%MF100"] != 1.0 / 3.0


def test_float_divide_by_zero_sets_s18(plc_from_source):
    plc = fcalc(plc_from_source, "%MF0 / %MF2", MF0=1.0, MF2=0.0)
    assert plc["%S18"]


def test_float_overflow_sets_s18(plc_from_source):
    plc = fcalc(plc_from_source, "%MF0 * %MF0", MF0=1e30)
    assert plc["%S18"]
    assert math.isinf(plc["%MF100"])


# ---- float functions [manual] ---------------------------------------------------------------
@pytest.mark.parametrize("func,x,expected", [
    ("SQRT", 2.0, math.sqrt(2.0)),
    ("ABS", -3.5, 3.5),
    ("TRUNC", 2.7, 2.0),
    ("TRUNC", -2.7, -2.0),
    ("LOG", 1000.0, 3.0),
    ("LN", math.e, 1.0),
    ("EXP", 1.0, math.e),
    ("SIN", math.pi / 2, 1.0),
    ("COS", 0.0, 1.0),
    ("TAN", math.pi / 4, 1.0),
    ("ASIN", 1.0, math.pi / 2),
    ("ACOS", 1.0, 0.0),
    ("ATAN", 1.0, math.pi / 4),
    ("DEG_TO_RAD", 180.0, math.pi),
    ("RAD_TO_DEG", math.pi, 180.0),
])
def test_float_functions(plc_from_source, func, x, expected):
    plc = fcalc(plc_from_source, f"{func}( %MF0 )", MF0=x)
    assert plc["%MF100"] == pytest.approx(expected, rel=1e-6, abs=1e-6)
    assert not plc["%S18"]


def test_expt(plc_from_source):
    plc = fcalc(plc_from_source, "EXPT( %MF0, %MF2 )", MF0=2.0, MF2=10.0)
    assert plc["%MF100"] == 1024.0


@pytest.mark.parametrize("expr,x", [
    ("SQRT( %MF0 )", -1.0),
    ("LN( %MF0 )", 0.0),
    ("LOG( %MF0 )", -5.0),
    ("ASIN( %MF0 )", 2.0),
    ("ACOS( %MF0 )", -1.5),
    ("EXPT( %MF0, 0.5 )", -4.0),
])
def test_float_domain_errors_set_s18(plc_from_source, expr, x):
    plc = fcalc(plc_from_source, expr, MF0=x)
    assert plc["%S18"]


# ---- conversions [manual] -------------------------------------------------------------------
def test_int_to_real_and_the_seed_alias(plc_from_source):
    plc = plc_from_source("""
LD 1
[ %MF10 := INT_TO_REAL( %MW0 ) ]
[ %MF12 := INTO_TO_REAL( %MW0 ) ]
[ %MF14 := DINT_TO_REAL( %MD2 ) ]
[ %MF16 := INT_TO_REAL( %MW0 ) * 0.5 ]
""")
    plc["%MW0"] = -1234
    plc["%MD2"] = 1_000_000
    plc.scan()
    assert plc["%MF10"] == -1234.0
    assert plc["%MF12"] == -1234.0  # INTO_TO_REAL is accepted as INT_TO_REAL
    assert plc["%MF14"] == 1_000_000.0
    assert plc["%MF16"] == -617.0


@pytest.mark.parametrize("x,expected", [
    (2.4, 2), (2.5, 3), (2.6, 3), (-2.4, -2), (-2.5, -3), (32767.0, 32767),
    (-32768.0, -32768),
])
def test_real_to_int_rounds_to_nearest(plc_from_source, x, expected):
    plc = fcalc(plc_from_source, "REAL_TO_INT( %MF0 )", target="%MW100", MF0=x)
    assert plc["%MW100"] == expected
    assert not plc["%S18"]


def test_real_to_dint(plc_from_source):
    plc = fcalc(plc_from_source, "REAL_TO_DINT( %MF0 )", target="%MD100", MF0=-123456.0)
    assert plc["%MD100"] == -123456
    assert not plc["%S18"]


@pytest.mark.parametrize("x", [32768.0, -40000.0, 1e20, float("inf"), float("nan")])
def test_bad_conversion_sets_s18(plc_from_source, x):
    plc = fcalc(plc_from_source, "REAL_TO_INT( %MF0 )", target="%MW100", MF0=x)
    assert plc["%S18"]


def test_float_comparisons_in_rungs(plc_from_source):
    plc = plc_from_source("""
LD   [ %MF0 > 0.5 ]
AND  [ %MF0 <= 1.0E1 ]
ST   %M0
""")
    for x, exp in ((0.5, False), (0.51, True), (10.0, True), (10.5, False)):
        plc["%MF0"] = x
        plc.scan()
        assert plc["%M0"] == exp, x


# ---- %MF / %MD over %MW [sure; odd indices manual] ------------------------------------------
def words(plc: PLC, i: int) -> tuple[int, int]:
    return plc[f"%MW{i}"] & 0xFFFF, plc[f"%MW{i + 1}"] & 0xFFFF


@pytest.mark.parametrize("i", [0, 1, 40, 41, 2998])
def test_float_overlays_two_words_low_word_first(plc_from_source, i):
    plc = plc_from_source(f"LD 1\n[ %MF{i} := 1.5 ]\n")
    plc.scan()
    raw = struct.unpack("<I", struct.pack("<f", 1.5))[0]
    assert words(plc, i) == (raw & 0xFFFF, raw >> 16)  # CDAB: low word in %MWi


@pytest.mark.parametrize("i", [0, 7])
def test_double_word_overlays_two_words_low_word_first(plc_from_source, i):
    plc = plc_from_source(f"LD 1\n[ %MD{i} := 70000 ]\n")
    plc.scan()
    assert words(plc, i) == (70000 & 0xFFFF, 70000 >> 16)


def test_words_written_by_the_program_read_as_float(plc_from_source):
    raw = struct.unpack("<I", struct.pack("<f", -2.75))[0]
    lo, hi = raw & 0xFFFF, raw >> 16
    sgn = lambda w: w - 0x10000 if w & 0x8000 else w  # noqa: E731
    plc = plc_from_source(f"""
LD 1
[ %MW41 := {sgn(lo)} ]
[ %MW42 := {sgn(hi)} ]
[ %MF50 := %MF41 * 2.0 ]
""")
    plc.scan()
    assert plc["%MF41"] == -2.75
    assert plc["%MF50"] == -5.5


def test_overlapping_floats_share_words(plc_from_source):
    """%MF0 and %MF1 overlap on %MW1 [manual: overlaps allowed]."""
    plc = plc_from_source("LD 1\n[ %MF1 := 0.0 ]\n")
    plc["%MF0"] = 1.5
    hi_before = plc["%MW1"]
    assert hi_before != 0
    plc.scan()
    assert plc["%MW1"] == 0 and plc["%MW2"] == 0
    assert plc["%MF0"] != 1.5  # its high word was overwritten


def test_constant_floats_from_configuration(plc_from_source):
    plc = plc_from_source("LD 1\n[ %MF0 := %KF4 * 2.0 ]\n[ %MD2 := %KD6 ]\n",
                          {"constants": {"%KF4": 1.25, "%KD6": -70000}})
    plc.scan()
    assert plc["%MF0"] == 2.5
    assert plc["%MD2"] == -70000
