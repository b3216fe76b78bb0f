"""Table functions (SUM MAX MIN MEAN) and BCD / Gray conversions [manual]."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softplc import PLC, CompileError


def run(src: str, **values) -> PLC:
    return run_on(PLC.from_source("LD 1\n" + src), **values)


def run_on(plc: PLC, **values) -> PLC:
    for addr, v in values.items():
        plc["%" + addr] = v
    plc.scan()
    return plc


def test_sum_max_min_of_a_word_table():
    plc = run("[ %MW20 := SUM( %MW0:4 ) ]\n[ %MW21 := MAX( %MW0:4 ) ]\n"
              "[ %MW22 := MIN( %MW0:4 ) ]\n", MW0=5, MW1=-3, MW2=40, MW3=7)
    assert (plc["%MW20"], plc["%MW21"], plc["%MW22"]) == (49, 40, -3)
    assert not plc["%S18"]


def test_sum_of_words_overflows_into_s18():
    plc = run("[ %MW20 := SUM( %MW0:2 ) ]\n", MW0=30000, MW1=30000)
    assert plc["%S18"] and plc["%MW20"] == 60000 - 65536


def test_float_and_double_tables():
    plc = run("[ %MF30 := MEAN( %MF10:3 ) ]\n[ %MF32 := SUM( %MF10:3 ) ]\n"
              "[ %MD26 := SUM( %MD40:2 ) ]\n[ %MF34 := MAX( %MF10:3 ) ]\n",
              MF10=1.5, MF12=2.5, MF14=5.0, MD40=100000, MD42=23)
    assert (plc["%MF30"], plc["%MF32"], plc["%MD26"], plc["%MF34"]) == (3.0, 9.0, 100023, 5.0)


@pytest.mark.parametrize("src, message", [
    ("[ %MW0 := SUM( %MW1 ) ]", "SUM takes a table"),
    ("[ %MF0 := MEAN( %MW0:3 ) ]", "MEAN takes a float table"),
    ("[ %MW0 := MAX( %MF0:3 ) ]", "needs a conversion"),
    ("[ %MW0 := SUM( %MW0:3, %MW4:3 ) ]", "takes 1 argument"),
])
def test_table_function_misuse(src, message):
    with pytest.raises(CompileError, match=message):
        PLC.from_source("LD 1\n" + src + "\n")


@pytest.fixture(scope="module")
def bcd_plc() -> Iterator[PLC]:
    """One PLC for all of a property's examples (building one per example was most of the
    test's time): each example writes every input the program reads, %S18 included."""
    plc = PLC.from_source("LD 1\n[ %MW1 := INT_TO_BCD( %MW0 ) ]\n"
                          "[ %MW2 := BCD_TO_INT( %MW1 ) ]\n")
    yield plc
    plc.close()


@pytest.fixture(scope="module")
def gray_plc() -> Iterator[PLC]:
    plc = PLC.from_source("LD 1\n[ %MW1 := GRAY_TO_INT( %MW0 ) ]\n")
    yield plc
    plc.close()


def rescan(plc: PLC, **values) -> PLC:
    """`plc` scanned once with these inputs and %S18 (which stays set until reset) at 0."""
    return run_on(plc, S18=0, **values)


@settings(max_examples=200, deadline=None)
@given(n=st.integers(0, 9999))
def test_bcd_round_trip(bcd_plc, n):
    plc = rescan(bcd_plc, MW0=n)
    assert plc["%MW2"] == n and not plc["%S18"]
    assert f"{plc['%MW1'] & 0xFFFF:04x}" == f"{n:04d}"  # each nibble is a decimal digit


def test_bad_bcd_and_out_of_range():
    assert run("[ %MW0 := BCD_TO_INT( #12A4 ) ]\n")["%S18"]
    assert run("[ %MW0 := INT_TO_BCD( %MW1 ) ]\n", MW1=10000)["%S18"]
    assert run("[ %MW0 := INT_TO_BCD( %MW1 ) ]\n", MW1=-1)["%S18"]


@settings(max_examples=200, deadline=None)
@given(n=st.integers(0, 0xFFFF))
def test_gray_decode_inverts_gray_encode(gray_plc, n):
    gray = n ^ (n >> 1)
    plc = rescan(gray_plc, MW0=gray - 0x10000 if gray > 0x7FFF else gray)
    assert plc["%MW1"] & 0xFFFF == n
