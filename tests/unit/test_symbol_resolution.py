"""One resolver for symbols (issue 33): a name stands wherever an address does, with what
may follow an address (`.Q`, `:4`, `:X3`, `[INDEX]`), in `plc[...]`, the REPL, the PLC's
repr and the messages that name an object (softplc.twido.symbols.SymbolTable.address_of)."""

from __future__ import annotations

import pytest

from softplc import PLC
from softplc.debug.session import Session
from softplc.errors import AddressError

BIN = """\
(*RUNG: count the parts*)
LD    PART_SENSOR
AND   MOTOR
ANDN  JAM
CU    PART_COUNTER
(*RUNG: the bin is nearly full*)
LD    [PART_COUNT >= 8]
ST    NEARLY_FULL
(*RUNG: motor*)
LD    START_PB
OR    MOTOR
ANDN  JAM
ST    MOTOR
"""
CONFIG = {"counters": {"%C0": {"preset": 10}},
          "symbols": {"START_PB": "%I0.0", "PART_SENSOR": "%I0.1", "MOTOR": "%Q0.0",
                      "NEARLY_FULL": "%Q0.4", "JAM": "%M10", "PART_COUNTER": "%C0",
                      "PART_COUNT": "%MW3", "SPARE": "%MW4", "LIMIT": "%KW0"}}


@pytest.fixture
def plc() -> PLC:
    return PLC.from_source(BIN, CONFIG, file="bin.il")


@pytest.mark.parametrize("text, address", [
    ("PART_COUNT", "%MW3"), ("part_count:2", "%MW3:2"), ("PART_COUNT:X3", "%MW3:X3"),
    ("PART_COUNTER.V", "%C0.V"), ("MOTOR:4", "%Q0.0:4"), ("PART_COUNT[SPARE]", "%MW3[%MW4]"),
    ("PART_COUNT[%MW7]", "%MW3[%MW7]"), ("%MW9", "%MW9"),
])
def test_a_name_takes_what_follows_an_address(plc, text, address):
    assert plc.symbols.address_of(text) == address


@pytest.mark.parametrize("text, message", [
    ("PART_CONT:2", "unknown symbol 'PART_CONT' (did you mean PART_COUNT?)"),
    ("MW3", "did you mean %MW3?"),
    ("PART_COUNT;2", "nor a symbol (a name, with .FIELD, :N, :Xk or [INDEX] after it)"),
    ("PART_COUNT[SPAR]", "unknown symbol 'SPAR' (did you mean SPARE?)"),
    ("PART_COUNT:99999", "beyond the controller profile"),
])
def test_bad_names_are_clear_errors(plc, text, message):
    with pytest.raises(AddressError) as e:
        plc[text]
    assert message in str(e.value)


def test_plc_items_by_symbol_range_and_field(plc):
    plc["PART_COUNT:2"] = [5, 6]
    assert plc["%MW3"] == 5 and plc["SPARE"] == 6
    assert plc["PART_COUNT:2"] == [5, 6]
    plc["PART_COUNT:X1"] = 1
    assert plc["%MW3"] == 7
    assert plc["PART_COUNT[SPARE]"] == 0  # %MW3[%MW4] = %MW9
    assert plc["part_counter.p"] == 10


def test_repr_and_errors_name_the_symbol_beside_the_address(plc):
    assert repr(plc).endswith("on: none>")
    plc["START_PB"] = 1
    plc["%MW3"] = 8
    plc.scan()
    assert repr(plc).endswith("on: START_PB(%I0.0) MOTOR(%Q0.0) NEARLY_FULL(%Q0.4)>")
    with pytest.raises(AddressError, match=r"^LIMIT\(%KW0\) is a constant"):
        plc["LIMIT"] = 3
    with pytest.raises(AddressError, match=r"^PART_COUNTER\.E\(%C0\.E\) is read-only"):
        plc["PART_COUNTER.E"] = 1


def test_repl_prints_a_symbol_range_and_finds_a_rung_by_symbol(plc):
    s = Session(plc)
    plc["%MW3"], plc["%MW4"] = 4, 2
    assert s.execute("print PART_COUNT:3").splitlines() == [
        "%MW3:          4      2      0", "  symbols: %MW3 PART_COUNT, %MW4 SPARE"]
    # a symbol the rung writes, then one it only reads, then an address, then the title
    assert s.execute("rung NEARLY_FULL").startswith("rung 1  the bin is nearly full")
    assert s.execute("rung JAM").startswith("rung 0  count the parts")
    assert s.execute("rung %C0.V").startswith("rung 0")  # the block's field: CU %C0
    assert s.execute("rung motor").startswith("rung 2  motor")  # the title, first
    assert s.execute("rung MOTOR").startswith("rung 2  motor")
    assert "no rung uses SPARE(%MW4)" in s.execute("rung SPARE")
    assert "(did you mean NEARLY_FULL?)" in s.execute("rung NERALY_FULL")
    assert s.execute("break NEARLY_FULL") == "breakpoint #1 at rung 1 (the bin is nearly full)"
