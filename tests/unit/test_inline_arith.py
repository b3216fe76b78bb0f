"""The inline word arithmetic of generated code (`semantics.inline_checked`, issue 26) computes
what the `semantics.Ops` helpers compute: the value, %S18, and the order of the operands'
own flags (%S17 from shifts)."""

from __future__ import annotations

import pytest
from fuzz_budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from softplc.plc import PLC
from softplc.twido.semantics import WORD_RANGE, Ops

OPS = {"add": "+", "sub": "-", "mul": "*", "div": "/"}
W = {16: ("%MW0", "%MW1", "%MW5"), 32: ("%MD0", "%MD2", "%MD6")}  # a, b, result
PLCS: dict[str, PLC] = {}


def plc_for(line: str) -> PLC:
    """A program of the one line (each its own, so that %S18 is that line's)."""
    if line not in PLCS:
        PLCS[line] = PLC.from_source(f"LD 1\n{line}\n", file="<inline>")
    return PLCS[line]


def one(plc: PLC, setup: dict[str, int], target: str) -> tuple[int, int]:
    """(target value, %S18) after one run of main() from `setup`, %S18 cleared first."""
    for k, v in setup.items():
        plc[k] = v
    plc.mem.s[18] = 0
    plc.program.main()
    return int(plc[target]), plc.mem.s[18]


def helper(name: str, *args: int) -> tuple[int, int]:
    ops = Ops([0] * 32)
    return getattr(ops, name)(*args), ops.s[18]


def test_the_generated_code_is_inline() -> None:
    """A plain store is left to the memoryview's own range check; a nested operation is
    inline; a division too."""
    src = plc_for("[ %MW5 := %MW0 + %MW1 ]").program.source
    assert "    _MW[5] = _MW[0] + _MW[1]\n" in src and "except ValueError:" in src
    src = plc_for("[ %MW5 := ( %MW0 + %MW1 ) * %MW2 ]").program.source
    assert "_add16" not in src and "_mul16" not in src and "(_v0 := _MW[0] + _MW[1])" in src
    src = plc_for("[ %MD6 := %MD0 / %MD2 ]").program.source
    assert "    _MDE[3] = int(_MDE[0] / _MDE[1])\n" in src and "ZeroDivisionError" in src
    src = plc_for("[ %MD6 := ( %MD0 + 0 ) / %MD2 ]").program.source
    assert "_div32(0, 0)" in src and "_div32(_" not in src and "int(_v" in src


@settings(max_examples=examples(300), deadline=None)
@given(bits=st.sampled_from([16, 32]), op=st.sampled_from(sorted(OPS)),
       a=st.integers(-2**31, 2**31 - 1), b=st.integers(-2**31, 2**31 - 1))
def test_inline_binary_operations_are_the_helpers(bits: int, op: str, a: int, b: int) -> None:
    lo, hi = WORD_RANGE[bits]
    a, b = min(max(a, lo), hi), min(max(b, lo), hi)
    x, y, r = W[bits]
    want = helper(f"{op}{bits}", a, b)
    assert one(plc_for(f"[ {r} := {x} {OPS[op]} {y} ]"), {x: a, y: b}, r) == want
    # the same operation nested (the inline expression form, not the store's check)
    assert one(plc_for(f"[ {r} := ( {x} {OPS[op]} {y} ) + 0 ]"), {x: a, y: b}, r) == want


@pytest.mark.parametrize("bits", [16, 32])
@pytest.mark.parametrize("a,b", [(-1, 0), (5, 0), (-7, 2), (7, -2), (-2**31, -1), (-32768, -1),
                                 (2**31 - 1, 1), (-2**31, 1), (2**31 - 1, 2**31 - 1),
                                 (-2**31 + 1, 3), (2**31 - 2, -(2**31 - 1))])
def test_division_edges(bits: int, a: int, b: int) -> None:
    lo, hi = WORD_RANGE[bits]
    a, b = min(max(a, lo), hi), min(max(b, lo), hi)
    x, y, r = W[bits]
    got = one(plc_for(f"[ {r} := {x} / {y} ]"), {x: a, y: b}, r)
    assert got == helper(f"div{bits}", a, b)
    # a dividend with an operation in it (its code is not a plain read: evaluated first)
    got = one(plc_for(f"[ {r} := ( {x} + 0 ) / {y} ]"), {x: a, y: b}, r)
    assert got == helper(f"div{bits}", a, b)


@settings(max_examples=examples(200), deadline=None)
@given(bits=st.sampled_from([16, 32]), a=st.integers(-2**31, 2**31 - 1))
def test_inline_negation_increment_and_narrowing(bits: int, a: int) -> None:
    lo, hi = WORD_RANGE[bits]
    w = min(max(a, lo), hi)
    x, _, r = W[bits]
    assert one(plc_for(f"[ {r} := -{x} ]"), {x: w}, r) == helper(f"neg{bits}", w)
    assert one(plc_for(f"[ INC {r} ]"), {r: w}, r) == helper(f"add{bits}", w, 1)
    assert one(plc_for(f"[ DEC {r} ]"), {r: w}, r) == helper(f"sub{bits}", w, 1)
    if bits == 16:
        assert one(plc_for("[ %MW5 := %MD0 ]"), {"%MD0": a}, "%MW5") == helper("narrow16", a)
        # a word sum stored in a double word: checked on 16 bits, not by the store's range
        got = one(plc_for("[ %MD6 := %MW0 + %MW1 ]"), {"%MW0": w, "%MW1": w}, "%MD6")
        assert got == helper("add16", w, w)


@pytest.mark.parametrize("b", [0, 6])
def test_operands_evaluate_in_order(b: int) -> None:
    """The dividend's flags come before the divisor's (both shifts set %S17), also when the
    divisor is zero; then %S18."""
    plc = PLC.from_source("LD 1\n[ %MW5 := SHL( %MW0, 1 ) / SHR( %MW1, %MW2 ) ]\n", file="<o>")
    # SHL(-32768, 1) carries 1; SHR(d, 1) carries 1 and SHR(d, 2) carries 0 (d = 1 or 13):
    # with a shift of 2, %S17 = 0 says the divisor was evaluated last
    a, d = -32768, 1 if b == 0 else 13
    for shift in (1, 2):
        plc["%MW0"], plc["%MW1"], plc["%MW2"] = a, d, shift
        plc.mem.s[17] = plc.mem.s[18] = 0
        plc.program.main()
        ops = Ops([0] * 32)
        want = ops.div16(ops.shl16(a, 1), ops.shr16(d, shift))
        assert (plc["%MW5"], plc.mem.s[17], plc.mem.s[18]) == (want, ops.s[17], ops.s[18])
