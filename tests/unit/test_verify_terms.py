"""The model's term constructors (`softplc.verify.symbolic.And/Or/Not/If`): the same terms
as z3's own functions (what the solver sees is unchanged), and z3's coercions and messages
for what they do not take themselves."""

from __future__ import annotations

import pytest
import z3

from softplc.verify.symbolic import And, If, Not, Or


def test_the_same_terms_as_z3s():
    a, b, c = z3.Bools("a b c")
    x, y = z3.BitVecs("x y", 16)
    arr = z3.Array("m", z3.BitVecSort(16), z3.BitVecSort(16))
    pairs = [(And(a, b, c), z3.And(a, b, c)), (And([a, b]), z3.And([a, b])),
             (And(a, True), z3.And(a, True)), (Or(a, False, c), z3.Or(a, False, c)),
             (Or([b]), z3.Or([b])), (Not(a), z3.Not(a)), (If(a, b, c), z3.If(a, b, c)),
             (If(a, x, y), z3.If(a, x, y)), (If(a, arr, z3.Store(arr, x, y)),
                                             z3.If(a, arr, z3.Store(arr, x, y)))]
    for ours, theirs in pairs:
        assert ours.get_id() == theirs.get_id() and type(ours) is type(theirs)


def test_what_they_do_not_take_goes_to_z3():
    a = z3.Bool("a")
    x = z3.BitVec("x", 16)
    assert If(a, x, 3).get_id() == z3.If(a, x, 3).get_id()  # an int takes x's sort
    assert And().get_id() == z3.And().get_id() and Or().get_id() == z3.Or().get_id()
    assert Not(True).get_id() == z3.Not(True).get_id()
    with pytest.raises(z3.Z3Exception):  # differing sorts: z3's error, not a bad term
        If(a, x, z3.BitVec("y", 8))
    with pytest.raises(z3.Z3Exception):
        And(a, x)


def test_terms_of_another_context_go_to_z3():
    """The C API does not check that its arguments share a context: terms of another
    context than z3's main one are left to z3's functions, which make them there or say
    why not."""
    other = z3.Context()
    p, q = z3.Bool("p", other), z3.Bool("q", other)
    x, y = z3.BitVec("x", 8, other), z3.BitVec("y", 8, other)
    for ours, theirs in [(And(p, q), z3.And(p, q)), (Or(p, q), z3.Or(p, q)),
                         (If(p, x, y), z3.If(p, x, y))]:
        assert ours.ctx is other and ours.get_id() == theirs.get_id()
    a = z3.Bool("a")
    with pytest.raises(z3.Z3Exception):  # a main-context term with one of `other`
        And(a, p)
    with pytest.raises(z3.Z3Exception):
        If(a, x, y)
