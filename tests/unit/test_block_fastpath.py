"""The counter's written-out code (issue 26) does what the rule says: `run` as the reference
below (the code before it was written out), and the short-form pins (`CU %C0`, `CD %C0`:
`Counter.cu` / `.cd`) as the generic pin adapter: `run` with that input, R = S = 0, the
other edge input held at its last value."""

from __future__ import annotations

from fuzz_budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from softplc.blocks.counter import Counter
from softplc.runtime.blocks import MAX_VALUE

STATE = st.fixed_dictionaries({
    "P": st.integers(0, MAX_VALUE), "V": st.sampled_from([0, 1, 5, MAX_VALUE - 1, MAX_VALUE]),
    "D": st.integers(0, 1), "E": st.integers(0, 1), "F": st.integers(0, 1),
    "_cu": st.integers(0, 1), "_cd": st.integers(0, 1)})


def reference_run(c: Counter, R: int = 0, S: int = 0, CU: int = 0, CD: int = 0) -> None:
    """%Ci [m221]: R (priority) V := 0; S V := P; CU / CD count on rising edges (both in one
    scan cancel); D = (V = P); F on the 9999 -> 0 wrap, E on 0 -> 9999; E, F clear at a count."""
    cu, cd = (1 if CU else 0), (1 if CD else 0)
    up, down = cu > c._cu, cd > c._cd
    c._cu, c._cd = cu, cd
    if R:
        c.V, c.E, c.F = 0, 0, 0
    elif S:
        c.V = c.P
    elif up != down:
        c.E = c.F = 0
        if up:
            c.V += 1
            if c.V > MAX_VALUE:
                c.V, c.F = 0, 1
        else:
            c.V -= 1
            if c.V < 0:
                c.V, c.E = MAX_VALUE, 1
    c.D = 1 if c.V == c.P else 0


PIN = st.sampled_from([0, 1, True, False, 7])


@settings(max_examples=examples(300), deadline=None)
@given(state=STATE, steps=st.lists(st.tuples(PIN, PIN, PIN, PIN), min_size=1, max_size=12))
def test_run_is_the_rule(state, steps) -> None:
    fast, ref = Counter(), Counter()
    fast.set_state(state)
    ref.set_state(state)
    for pins in steps:
        fast.run(*pins)
        reference_run(ref, *pins)
        assert fast.state() == ref.state(), pins


@settings(max_examples=examples(300), deadline=None)
@given(state=STATE, steps=st.lists(st.tuples(st.sampled_from(["cu", "cd"]),
                                             st.sampled_from([0, 1, True, False, 7])),
                                   min_size=1, max_size=12))
def test_short_form_pins_are_run_with_one_input(state, steps) -> None:
    fast, ref = Counter(), Counter()
    fast.set_state(state)
    ref.set_state(state)
    for pin, v in steps:
        getattr(fast, pin)(v)
        if pin == "cu":
            reference_run(ref, CU=v, CD=ref._cd)
        else:
            reference_run(ref, CD=v, CU=ref._cu)
        assert fast.state() == ref.state(), (pin, v)


def test_counting_up_wraps_and_down_wraps() -> None:
    c = Counter(preset=3)
    for v in (1, 0, 1, 0, 1):
        c.cu(v)
    assert (c.V, c.D) == (3, 1)
    c.set_state({"V": MAX_VALUE, "_cu": 0})
    c.cu(1)
    assert (c.V, c.F, c.E) == (0, 1, 0)
    c.cd(1)
    assert (c.V, c.E, c.F) == (MAX_VALUE, 1, 0)
