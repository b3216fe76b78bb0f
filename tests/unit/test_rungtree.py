"""The rung structure (`il.rungtree`): what each `)`, MRD, MPP and block instruction refers
to, and the structure errors with their codes and positions."""

from __future__ import annotations

from softplc.errors import Code
from softplc.il import ast as A
from softplc.il import rungtree
from softplc.il.parser import parse


def tree(src: str, **limits: int) -> rungtree.Structure:
    return rungtree.build(parse(src).rungs[0], **limits)


def test_parentheses_and_mps_link_to_their_openers() -> None:
    s = tree("LD %I0.0\nAND( %M0\nOR( %M1\nAND %M2\n)\n)\nMPS\nST %Q0.0\nMRD\nST %Q0.1\n"
             "MPP\nST %Q0.2\n")
    ops = [(st.k, st.opener) for st in s.steps if st.opener is not None]
    assert ops == [(4, 2), (5, 1), (8, 6), (10, 6)]
    assert not s.problems and s.open_block is None
    assert [st.has_acc for st in s.steps][:2] == [False, True]


def test_block_sides_and_accumulator_reuse() -> None:
    s = tree("BLK %C0\nLD %I0.0\nCU\nOUT_BLK\nLD D\nST %Q0.0\nOR %M1\nST %Q0.1\nEND_BLK\n")
    by_k = {st.k: st for st in s.steps}
    assert [by_k[k].phase for k in (1, 2, 3, 4, 8)] == ["in", "in", "in", "out", "out"]
    assert by_k[2].block is not None and str(by_k[2].block) == "%C0" and by_k[2].block_k == 0
    # ST %Q0.0 is followed by OR: the accumulator it leaves is read again; ST %Q0.1 is not
    assert by_k[5].used_later and not by_k[7].used_later


def test_structure_errors_carry_codes_and_positions() -> None:
    s = tree("AND %M0\n)\nMRD\nLD %M0\nOR( %M1\nOUT_BLK\nEND_BLK\n")
    got = sorted(((p.code, p.pos.line) for p in s.problems), key=lambda c: c[1])
    assert got == [(Code.NEEDS_LOAD, 1), (Code.UNMATCHED_CLOSE, 2), (Code.NO_MPS, 3),
                   (Code.NOT_CLOSED, 5), (Code.OUTSIDE_BLK, 6), (Code.OUTSIDE_BLK, 7)]
    skipped = [type(st.instr) for st in s.steps if not st.ok]
    assert skipped == [A.ParenClose, A.OutBlk, A.EndBlk]


def test_profile_limits_and_an_open_block() -> None:
    s = tree("LD %M0\nMPS\nMPS\nAND( %M1\nAND( %M2\n)\n)\nBLK %TM0\nLD 1\nIN\n",
             max_parens=1, max_stack=1)
    assert sorted(p.code for p in s.problems) == [Code.NOT_CLOSED, Code.STRUCTURE,
                                                  Code.STRUCTURE]
    assert s.open_block == 7
