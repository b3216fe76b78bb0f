"""Each basic block family's rule is the one place its behaviour is written
(softplc/blocks/): the engine's straight-line code equals it on Python ints, value for
value, and the solver's reading of the same rule
(`verify.symbolic.Z3State`) equals its reading on ints, for every family, in reachable
states. The programs of tests/integration/test_verify_diff.py check the whole model
against the engine besides."""

from __future__ import annotations

from typing import Any

import z3
from fuzz_budget import examples
from hypothesis import given, settings
from hypothesis import strategies as st

from softplc.blocks import BIT, Scan
from softplc.blocks.counter import MODEL as COUNTER_MODEL
from softplc.blocks.counter import Counter, counter_rule
from softplc.blocks.drum import MODEL as DRUM_MODEL
from softplc.blocks.drum import Drum, drum_rule
from softplc.blocks.register import MODEL as REGISTER_MODEL
from softplc.blocks.register import Register, register_rule, slots
from softplc.blocks.shift import (
    SHIFT_MODEL,
    STEP_MODEL,
    ShiftRegister,
    StepCounter,
    set_bit_rule,
    shift_rule,
    step_rule,
)
from softplc.blocks.timer import MODEL as TIMER_MODEL
from softplc.blocks.timer import TIME_BASES_US, Timer, timer_cap, timer_rule
from softplc.runtime.blocks import MAX_VALUE, TimeSource
from softplc.twido.semantics import IntDomain
from softplc.verify.symbolic import Z3State

bit = st.integers(0, 1)
SMALL_PRESET = 30  # presets and times small enough that timers end within a run


# ---- the engine's straight-line code against the rule, on ints ---------------------------
@settings(max_examples=examples(300), deadline=None)
@given(kind=st.sampled_from(["TON", "TOF", "TP"]), base=st.sampled_from(["1ms", "10ms"]),
       preset=st.integers(0, SMALL_PRESET),
       steps=st.lists(st.tuples(bit, st.integers(0, 25_000), st.none() |
                                st.integers(0, SMALL_PRESET)), min_size=1, max_size=30))
def test_the_timer_runs_its_rule(kind: str, base: str, preset: int,
                                 steps: list[tuple[int, int, int | None]]) -> None:
    clock = TimeSource()
    t = Timer(clock, kind, base, preset)
    s = {"P": preset, "V": 0, "Q": 0, "_in": 0, "_on": 0}
    t0 = 0
    for IN, dt, new_preset in steps:
        clock.now_us += dt
        if new_preset is not None:  # the program stores %TMi.P
            t.P = s["P"] = new_preset
        t.run(IN)
        new = timer_rule(IntDomain, kind, s, IN, clock.now_us - t0, TIME_BASES_US[base])
        t0 = clock.now_us - new.pop("_el")
        s.update(new)
        assert {f: int(getattr(t, f)) for f in s} == {f: int(v) for f, v in s.items()}


@settings(max_examples=examples(300), deadline=None)
@given(preset=st.integers(0, MAX_VALUE), start=st.sampled_from([0, 1, MAX_VALUE - 1, MAX_VALUE]),
       steps=st.lists(st.one_of(st.tuples(st.just("run"), bit, bit, bit, bit),
                                st.tuples(st.sampled_from(["cu", "cd"]), bit)),
                      min_size=1, max_size=30))
def test_the_counter_runs_its_rule(preset: int, start: int, steps: list[tuple]) -> None:
    c = Counter(preset)
    c.V = start
    s = {f: getattr(c, f) for f in Counter.FIELDS}
    for step in steps:
        if step[0] == "run":
            R, S, CU, CD = step[1:]
            c.run(R, S, CU, CD)
        else:  # the short form: R = S = 0, the other edge input held
            R = S = 0
            CU, CD = (step[1], s["_cd"]) if step[0] == "cu" else (s["_cu"], step[1])
            getattr(c, step[0])(step[1])
        s.update(counter_rule(IntDomain, s, R, S, CU, CD))
        assert {f: int(getattr(c, f)) for f in s} == {f: int(v) for f, v in s.items()}


@settings(max_examples=examples(300), deadline=None)
@given(lifo=st.booleans(), depth=st.integers(1, 4),
       steps=st.lists(st.tuples(bit, bit, bit, st.integers(-32768, 32767)), min_size=1,
                      max_size=30))
def test_the_register_runs_its_rule(lifo: bool, depth: int,
                                    steps: list[tuple[int, int, int, int]]) -> None:
    r = Register("LIFO" if lifo else "FIFO", depth)
    s: dict[str, Any] = {"I": 0, "O": 0, "E": 1, "F": 0, "_i": 0, "_o": 0, "_n": 0,
                         **dict.fromkeys(slots(depth), 0)}
    for R, I, O, word in steps:
        r.I = s["I"] = word  # the program stores %Ri.I
        r.run(R, I, O)
        s.update(register_rule(IntDomain, lifo, depth, s, R, I, O))
        assert {f: int(getattr(r, f)) for f in ("I", "O", "E", "F", "_i", "_o")} == \
            {f: int(s[f]) for f in ("I", "O", "E", "F", "_i", "_o")}
        assert r._data == [s[k] for k in slots(depth)][:s["_n"]]


@settings(max_examples=examples(300), deadline=None)
@given(steps=st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=8),
       moves=st.lists(st.tuples(bit, bit, st.none() | st.integers(0, 2)), min_size=1,
                      max_size=30))
def test_the_drum_runs_its_rule(steps: list[int], moves: list[tuple]) -> None:
    out = [False] * 3
    d = Drum(steps, [(out, k) for k in range(3)])
    s: dict[str, Any] = {"S": 0, "F": 0, "_u": 0, "_written": -1, "out": list(out)}
    for R, U, reset in moves:
        if reset is not None:  # a rung after the drum resets one of its outputs
            out[reset] = s["out"][reset] = False
        d.run(R, U)
        s.update(drum_rule(IntDomain, d.steps, s, R, U))
        assert (d.S, int(d.F), d._u, d._written) == (s["S"], int(s["F"]), s["_u"],
                                                     s["_written"])
        assert out == [bool(x) for x in s["out"]]


@settings(max_examples=examples(300), deadline=None)
@given(step=st.booleans(),
       moves=st.lists(st.one_of(st.tuples(st.just("run"), bit, bit, bit),
                                st.tuples(st.just("bit"), st.integers(0, 15), bit)),
                      min_size=1, max_size=30))
def test_the_shift_register_and_step_counter_run_their_rules(step: bool,
                                                              moves: list[tuple]) -> None:
    b = StepCounter() if step else ShiftRegister()
    rule = step_rule if step else shift_rule
    s = b.state()
    for move in moves:
        if move[0] == "run":
            b.run(*move[1:])
            s.update(rule(IntDomain, s, *move[1:]))
        else:
            b.set_bit(*move[1:])
            s.update(set_bit_rule(IntDomain, s, *move[1:], step))
        assert b.state() == {f: int(v) for f, v in s.items()}
        assert [b.bit(k) for k in range(16)] == \
            [bool(SHIFT_MODEL.bit(IntDomain, s, k)) for k in range(16)]


# ---- the solver's reading of each rule against the ints' ---------------------------------
SCAN = Scan(10_000, 30_000)  # a 10 ms scan, up to 30 ms when the period varies
ints = st.integers(0, MAX_VALUE)


def _z3_value(v: Any, width: int) -> Any:
    if width == BIT:
        return z3.BoolVal(bool(v))
    return z3.BitVecVal(v, width)


def _same(ints_result: dict[str, Any], z3_result: dict[str, Any],
          widths: dict[str, int]) -> None:
    assert set(ints_result) == set(z3_result)
    for f, v in ints_result.items():
        if f == "out":
            assert [bool(x) for x in v] == [z3.is_true(z3.simplify(x)) for x in z3_result[f]]
            continue
        term = z3.simplify(z3_result[f]) if z3.is_expr(z3_result[f]) else z3_result[f]
        if widths[f] == BIT:
            assert bool(v) == z3.is_true(term), f
        else:
            got = term.as_long() if z3.is_expr(term) else term
            assert int(v) % (1 << widths[f]) == got % (1 << widths[f]), f


def _both(model: Any, block: Any, state: dict[str, int], pins: dict[str, int],
          outs: list[int] = ()) -> None:
    widths = model.fields(block, SCAN)
    s_int: dict[str, Any] = dict(state)
    s_z3: dict[str, Any] = {f: _z3_value(v, widths[f]) for f, v in state.items()}
    if outs:
        s_int["out"], s_z3["out"] = list(outs), [z3.BoolVal(bool(x)) for x in outs]
    p_z3 = {k: z3.BoolVal(bool(v)) for k, v in pins.items()}
    _same(model.run(IntDomain, block, s_int, pins, SCAN),
          model.run(Z3State, block, s_z3, p_z3, SCAN), widths)
    _same(model.after_scan(IntDomain, block, s_int, SCAN),
          model.after_scan(Z3State, block, s_z3, SCAN), widths)
    for inv in model.invariants(Z3State, block, s_z3, SCAN):
        assert z3.is_true(z3.simplify(inv))  # the states drawn are reachable ones


@settings(max_examples=examples(300), deadline=None)
@given(kind=st.sampled_from(["TON", "TOF", "TP"]), base=st.sampled_from(list(TIME_BASES_US)),
       P=ints, V=ints, Q=bit, was_in=bit, on=bit, IN=bit, el=st.floats(0, 1))
def test_the_solver_reads_the_timer_rule_as_the_engine(kind: str, base: str, P: int, V: int,
                                                        Q: int, was_in: int, on: int, IN: int,
                                                        el: float) -> None:
    t = Timer(TimeSource(), kind, base, P)
    state = {"P": P, "V": V, "Q": Q, "_in": was_in, "_on": on,
             "_el": int(el * timer_cap(t, SCAN))}
    _both(TIMER_MODEL, t, state, {"IN": IN})


@settings(max_examples=examples(300), deadline=None)
@given(P=ints, V=ints, flags=st.lists(bit, min_size=5, max_size=5),
       pins=st.fixed_dictionaries({p: bit for p in Counter.PINS}))
def test_the_solver_reads_the_counter_rule_as_the_engine(P: int, V: int, flags: list[int],
                                                          pins: dict[str, int]) -> None:
    state = {"P": P, "V": V, **dict(zip(("D", "E", "F", "_cu", "_cd"), flags, strict=True))}
    _both(COUNTER_MODEL, Counter(P), state, pins)


@settings(max_examples=examples(300), deadline=None)
@given(data=st.data(), lifo=st.booleans(), depth=st.integers(1, 16),
       pins=st.fixed_dictionaries({p: bit for p in Register.PINS}))
def test_the_solver_reads_the_register_rule_as_the_engine(data: Any, lifo: bool, depth: int,
                                                           pins: dict[str, int]) -> None:
    words = st.integers(0, 0xFFFF)
    n = data.draw(st.integers(0, depth))
    state = {"I": data.draw(words), "O": data.draw(words), "E": int(n == 0),
             "F": int(n >= depth), "_i": data.draw(bit), "_o": data.draw(bit), "_n": n,
             **{k: data.draw(words) for k in slots(depth)}}
    _both(REGISTER_MODEL, Register("LIFO" if lifo else "FIFO", depth), state, pins)


@settings(max_examples=examples(300), deadline=None)
@given(data=st.data(), n=st.integers(1, 8), pins=st.fixed_dictionaries({"R": bit, "U": bit}))
def test_the_solver_reads_the_drum_rule_as_the_engine(data: Any, n: int,
                                                       pins: dict[str, int]) -> None:
    steps = data.draw(st.lists(st.integers(0, 0xFFFF), min_size=n, max_size=n))
    outs = data.draw(st.lists(bit, min_size=0, max_size=16))
    S = data.draw(st.integers(0, n - 1))
    state = {"S": S, "F": int(S == n - 1), "_u": data.draw(bit),
             "_written": data.draw(st.integers(-1, n - 1))}
    _both(DRUM_MODEL, Drum(steps, []), state, pins, outs)


@settings(max_examples=examples(300), deadline=None)
@given(data=st.data(), step=st.booleans(), k=st.integers(0, 15), v=bit,
       pins=st.fixed_dictionaries({p: bit for p in ShiftRegister.PINS}))
def test_the_solver_reads_the_shift_rules_as_the_engine(data: Any, step: bool, k: int, v: int,
                                                         pins: dict[str, int]) -> None:
    model, block = (STEP_MODEL, StepCounter()) if step else (SHIFT_MODEL, ShiftRegister())
    widths = model.fields(block, SCAN)
    state = {f: data.draw(bit if w == BIT else st.integers(0, (1 << w) - 1))
             for f, w in widths.items()}
    if step:
        state["V"] = data.draw(st.integers(0, 255))
    _both(model, block, state, pins)
    s_z3 = {f: _z3_value(x, widths[f]) for f, x in state.items()}
    _same(model.set_bit(IntDomain, state, k, v),
          model.set_bit(Z3State, s_z3, k, z3.BoolVal(bool(v))), widths)
    assert bool(model.bit(IntDomain, state, k)) == \
        z3.is_true(z3.simplify(model.bit(Z3State, s_z3, k)))


def test_shift_register_step_counter_and_drum_by_the_manual():
    """One step of each, as the manual says (the rules are checked against these)."""
    sbr = ShiftRegister()
    sbr.set_bit(0, 1)
    sbr.run(CU=1)
    assert sbr.W == 0b10 and sbr.bit(1)
    sbr.run(CU=0, CD=1)
    assert sbr.W == 0b01
    sc = StepCounter()
    sc.run(CD=1)  # from step 0 down: wraps to 255
    assert (sc.V, sc.W) == (255, 1 << 255)
    sc.set_bit(7, 1)
    assert sc.V == 7 and sc.bit(7) and sc.bit(255)
    out = [False, False]
    dr = Drum([0b01, 0b10], [(out, 0), (out, 1)])
    dr.run()
    assert out == [True, False] and (dr.S, dr.F) == (0, 0)
    out[0] = False  # a rung resets an output: it holds until the step changes
    dr.run()
    assert out == [False, False]
    dr.run(U=1)
    assert out == [False, True] and (dr.S, dr.F) == (1, 1)
