"""The counter's written-out short-form pins (`CU %C0`, `CD %C0`: `Counter.cu` / `.cd`, issue
26) do what the generic pin adapter does: `run` with that input, R = S = 0, the other edge
input held at its last value."""

from __future__ import annotations

from fuzz_budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from softplc.runtime.blocks import MAX_VALUE, Counter

STATE = st.fixed_dictionaries({
    "P": st.integers(0, MAX_VALUE), "V": st.sampled_from([0, 1, 5, MAX_VALUE - 1, MAX_VALUE]),
    "D": st.integers(0, 1), "E": st.integers(0, 1), "F": st.integers(0, 1),
    "_cu": st.integers(0, 1), "_cd": st.integers(0, 1)})


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
            ref.run(CU=v, CD=ref._cd)
        else:
            ref.run(CD=v, CU=ref._cu)
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
