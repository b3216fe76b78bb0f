"""Timers and counters as solver terms: `runtime/blocks.py`'s Timer and Counter, one scan.

The state of a timer is its fields (P, V, Q), its last IN (`_in`), `_on` (TOF/TP timing)
and `_el`, the time since it started in microseconds (`now - _t0` of the engine), which the
model advances by the scan period at the end of every scan and saturates at `cap` (past the
largest preset nothing changes). Every update is guarded: `g` is whether the block runs.
"""

from __future__ import annotations

import math
from typing import Any

import z3

from softplc.runtime.blocks import MAX_VALUE, Counter, Timer
from softplc.verify.symbolic import WIDE, as_bool, wide


def time_unit(t: Timer, period_us: int) -> int:
    """The timer's elapsed time counts in units of gcd(time base, period) microseconds:
    exact, and the divider the solver builds stays small."""
    return math.gcd(t.base_us, period_us)


def timer_cap(t: Timer, period_us: int, longest_us: int = 0) -> int:
    """Elapsed time (in units) past which a timer's outputs no longer change."""
    u = time_unit(t, period_us)
    return (MAX_VALUE * t.base_us + max(period_us, longest_us)) // u


def el_bits(t: Timer, period_us: int, longest_us: int = 0) -> int:
    return (timer_cap(t, period_us, longest_us) * 2).bit_length() + 1


def _set(st: dict[str, Any], key: str, g: Any, value: Any) -> None:
    old = st[key]
    if z3.is_bool(old):
        value = as_bool(value)
        st[key] = z3.If(g, value, old) if not z3.is_true(g) else value
    else:
        v = value if not isinstance(value, int) else z3.BitVecVal(value, old.size())
        if z3.is_bv(v) and v.size() != old.size():
            v = z3.Extract(old.size() - 1, 0, v)
        st[key] = z3.If(g, v, old) if not z3.is_true(g) else v
    st[key] = z3.simplify(st[key])


def run_timer(st: dict[str, Any], name: str, t: Timer, g: Any, IN: Any,
              period_us: int) -> None:
    """One execution of timer `name` (e.g. "%TM0") with input IN, guarded by g."""
    k = {f: f"{name}.{f}" for f in ("P", "V", "Q", "_in", "_on", "_el")}
    was_in, on, el = st[k["_in"]], st[k["_on"]], st[k["_el"]]
    P = wide(st[k["P"]])
    n = el.size()
    base = z3.BitVecVal(t.base_us // time_unit(t, period_us), n)

    def ticks(e: Any) -> Any:
        return z3.ZeroExt(WIDE - n, z3.UDiv(e, base))

    zero = z3.BitVecVal(0, n)
    if t.type == "TON":
        el2 = z3.If(z3.And(IN, z3.Not(was_in)), zero, el)
        v = ticks(el2)
        done = v >= P
        _set(st, k["_el"], g, el2)
        _set(st, k["V"], g, z3.If(IN, z3.If(done, P, v), wide(0)))
        _set(st, k["Q"], g, z3.And(IN, done))
    elif t.type == "TOF":
        start = z3.And(z3.Not(IN), was_in)
        el2 = z3.If(start, zero, el)
        on2 = z3.Or(start, on)
        v = ticks(el2)
        done = v >= P
        _set(st, k["_el"], g, el2)
        _set(st, k["V"], g, z3.If(IN, wide(0), z3.If(on2, z3.If(done, P, v), wide(st[k["V"]]))))
        _set(st, k["Q"], g, z3.If(IN, True, z3.If(z3.And(on2, done), False, st[k["Q"]])))
        _set(st, k["_on"], g, z3.And(z3.Not(IN), on2, z3.Not(done)))
    else:  # TP
        start = z3.And(IN, z3.Not(was_in), z3.Not(on))
        el2 = z3.If(start, zero, el)
        on2 = z3.Or(start, on)
        q2 = z3.Or(start, st[k["Q"]])
        v = ticks(el2)
        done = v >= P
        v2 = z3.If(on2, z3.If(done, P, v), wide(st[k["V"]]))
        q3 = z3.If(z3.And(on2, done), False, q2)
        on3 = z3.And(on2, z3.Not(done))
        _set(st, k["_el"], g, el2)
        _set(st, k["V"], g, z3.If(z3.And(z3.Not(on3), z3.Not(IN)), wide(0), v2))
        _set(st, k["Q"], g, q3)
        _set(st, k["_on"], g, on3)
    _set(st, k["_in"], g, IN)


def advance_timer(st: dict[str, Any], name: str, t: Timer, period_us: int,
                  periods: Any = None, longest_us: int = 0) -> None:
    """End of scan: the next scan starts one period later (with a variable period: the
    term `periods` times the shortest one, at most `longest_us`)."""
    key = f"{name}._el"
    el = st[key]
    n = el.size()
    step: Any = period_us // time_unit(t, period_us)
    if periods is not None:
        step = z3.ZeroExt(n - periods.size(), periods) * step
    cap = z3.BitVecVal(timer_cap(t, period_us, longest_us), n)
    st[key] = z3.simplify(z3.If(z3.UGE(el, cap - step), cap, el + step))


def run_counter(st: dict[str, Any], name: str, g: Any, R: Any, S: Any, CU: Any,
                CD: Any) -> None:
    """`Counter.run(R, S, CU, CD)` guarded by g."""
    k = {f: f"{name}.{f}" for f in Counter.FIELDS}
    up = z3.And(CU, z3.Not(st[k["_cu"]]))
    down = z3.And(CD, z3.Not(st[k["_cd"]]))
    V, P = wide(st[k["V"]]), wide(st[k["P"]])
    count = z3.And(z3.Not(R), z3.Not(S), up != down)
    over = z3.And(up, V + 1 > MAX_VALUE)
    under = z3.And(down, V - 1 < 0)
    counted = z3.If(up, z3.If(over, wide(0), V + 1), z3.If(under, wide(MAX_VALUE), V - 1))
    V2 = z3.If(R, wide(0), z3.If(S, P, z3.If(count, counted, V)))
    _set(st, k["_cu"], g, CU)
    _set(st, k["_cd"], g, CD)
    _set(st, k["E"], g, z3.If(R, False, z3.If(count, z3.And(z3.Not(up), under), st[k["E"]])))
    _set(st, k["F"], g, z3.If(R, False, z3.If(count, over, st[k["F"]])))
    _set(st, k["V"], g, V2)
    _set(st, k["D"], g, V2 == P)


def run_shift_register(st: dict[str, Any], name: str, g: Any, R: Any, CU: Any,
                       CD: Any) -> None:
    """`ShiftRegister.run(R, CU, CD)` guarded by g: CU shifts left, then CD right."""
    W = st[f"{name}.W"]
    up = z3.And(CU, z3.Not(st[f"{name}._cu"]))
    down = z3.And(CD, z3.Not(st[f"{name}._cd"]))
    w1 = z3.If(up, W << 1, W)
    w2 = z3.If(down, z3.LShR(w1, 1), w1)
    _set(st, f"{name}.W", g, z3.If(R, z3.BitVecVal(0, 16), w2))
    _set(st, f"{name}._cu", g, CU)
    _set(st, f"{name}._cd", g, CD)


def block_invariants(st: dict[str, Any], timers: dict[str, tuple[Timer, int, int]],
                     counters: list[str]) -> list[Any]:
    """Facts true in every reachable state by construction (checked by 1-induction before
    use): value ranges of block fields and elapsed times."""
    out = []
    for name, (t, period, longest) in timers.items():
        out.append(z3.ULE(st[f"{name}._el"], timer_cap(t, period, longest)))  # units
        P, V = st[f"{name}.P"], st[f"{name}.V"]
        out += [P >= 0, P <= MAX_VALUE, V >= 0, V <= MAX_VALUE]
    for name in counters:
        P, V = st[f"{name}.P"], st[f"{name}.V"]
        out += [P >= 0, P <= MAX_VALUE, V >= 0, V <= MAX_VALUE]
    return out


def run_drum(st: dict[str, Any], name: str, steps: list[int], outs: list[str], g: Any,
             R: Any, U: Any) -> None:
    """`Drum.run(R, U)` guarded by g: the step's bits go to the outputs only when the step
    differs from the one last written (`_written`, -1 after a cold start or a reset)."""
    n = len(steps)
    S, W = st[f"{name}.S"], st[f"{name}._written"]
    up = z3.And(U, z3.Not(st[f"{name}._u"]))
    nxt = z3.If(S == n - 1, z3.BitVecVal(0, 16), S + 1)
    S2 = z3.If(R, z3.BitVecVal(0, 16), z3.If(up, nxt, S))
    W1 = z3.If(R, z3.BitVecVal(-1, 16), W)
    changed = z3.And(g, S2 != W1)
    for k, key in enumerate(outs):
        on = z3.Or([S2 == j for j, bits in enumerate(steps) if bits >> k & 1] or [False])
        st[key] = z3.simplify(z3.If(changed, on, st[key]))
    _set(st, f"{name}._written", g, S2)  # after the write, or already equal
    _set(st, f"{name}.S", g, S2)
    _set(st, f"{name}._u", g, U)
    _set(st, f"{name}.F", g, S2 == n - 1)


def run_step_counter(st: dict[str, Any], name: str, g: Any, R: Any, CU: Any,
                     CD: Any) -> None:
    """`StepCounter.run(R, CU, CD)` guarded by g: V the step (0..255), W its 256 bits."""
    V = st[f"{name}.V"]
    up = z3.And(CU, z3.Not(st[f"{name}._cu"]))
    down = z3.And(CD, z3.Not(st[f"{name}._cd"]))
    v1 = z3.If(up, (V + 1) & 255, V)
    v2 = z3.If(R, z3.BitVecVal(0, 16), z3.If(down, (v1 - 1) & 255, v1))
    moved = z3.Or(R, v2 != V)
    _set(st, f"{name}.V", g, v2)
    one = z3.BitVecVal(1, 256) << z3.ZeroExt(240, v2)
    _set(st, f"{name}.W", g, z3.If(moved, one, st[f"{name}.W"]))
    _set(st, f"{name}._cu", g, CU)
    _set(st, f"{name}._cd", g, CD)


def set_step_bit(st: dict[str, Any], name: str, k: int, g: Any, value: Any) -> None:
    """`StepCounter.set_bit(k, value)` guarded by g: setting bit k makes k the step."""
    W = st[f"{name}.W"]
    mask = z3.BitVecVal(1 << k, 256)
    _set(st, f"{name}.W", g, z3.If(value, W | mask, W & ~mask))
    _set(st, f"{name}.V", g, z3.If(value, z3.BitVecVal(k, 16), st[f"{name}.V"]))


def register_fields(depth: int) -> tuple[str, ...]:
    """A %R register's state: its fields, the edge inputs, the count `_n` and the slots
    `_d0`.. (oldest first, as the engine's list; slots past `_n` are never read)."""
    return ("I", "O", "E", "F", "_i", "_o", "_n", *(f"_d{j}" for j in range(depth)))


def run_register(st: dict[str, Any], name: str, lifo: bool, depth: int, g: Any, R: Any,
                 I: Any, O: Any) -> None:
    """`Register.run(R, I, O)` guarded by g: a rising I stores .I unless full, then a
    rising O retrieves the oldest (FIFO) or newest (LIFO) word unless empty."""
    d = [st[f"{name}._d{j}"] for j in range(depth)]
    n = st[f"{name}._n"]
    push = z3.And(z3.Not(R), I, z3.Not(st[f"{name}._i"]), z3.ULT(n, depth))
    d = [z3.If(z3.And(push, n == j), st[f"{name}.I"], d[j]) for j in range(depth)]
    n = z3.If(push, n + 1, n)
    pop = z3.And(z3.Not(R), O, z3.Not(st[f"{name}._o"]), n != 0)
    if lifo:
        top = d[0]
        for j in range(1, depth):
            top = z3.If(n == j + 1, d[j], top)
        _set(st, f"{name}.O", g, z3.If(pop, top, st[f"{name}.O"]))
    else:
        _set(st, f"{name}.O", g, z3.If(pop, d[0], st[f"{name}.O"]))
        d = [z3.If(pop, d[j + 1], d[j]) for j in range(depth - 1)] + [d[-1]]
    n = z3.If(R, z3.BitVecVal(0, 16), z3.If(pop, n - 1, n))
    for j in range(depth):
        _set(st, f"{name}._d{j}", g, d[j])
    _set(st, f"{name}._n", g, n)
    _set(st, f"{name}._i", g, I)
    _set(st, f"{name}._o", g, O)
    _set(st, f"{name}.E", g, n == 0)
    _set(st, f"{name}.F", g, z3.UGE(n, depth))
