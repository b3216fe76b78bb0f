"""Relations between timers the model states itself: candidates added to
`Checker.candidates`, kept where inductive by `lemmas.houdini`, then given to k-induction
(assumed in every state of its step) and to Spacer (in its clauses' body).

A proof that needs the relation between timers (a two-hand control: both hands within the
window of a third timer) is k-inductive only at a k as long as the timer's window in scans
(0.5 s at 50 ms: k = 11), each step with every timer's divider: too slow. Stated as
invariants, the same proof is k-inductive at k = 1 or 2.

Candidates, over the state at the end of a scan (`_in` a timer's last IN,
`_el` its elapsed time in units, advanced by the period at the end of the scan:
`softplc/blocks/timer.py`):
(presets and a TON's Q/V against its last IN are `lemmas.timer_candidates`')
- per timer V <= P; per on-delay timer (TON; Twido: the current
  value counts up from 0 while IN is 1, Q is 1 once it reaches the preset [TwidoSuite
  Programming Guide, "Timer function block", TON, manual, from memory]) with a
  fixed period: IN on -> V is the elapsed time before the scan's advance, in time bases,
  clamped at P;
- per pair of on-delay timers a, b counting in the same unit: IN_a -> IN_b (b's input is
  on whenever a's is) and, both on, el_a <= el_b (b started no later); both directions
  together: timers that share an input have equal elapsed times (only pairs whose
  inputs, as one scan computes them, imply each other: `related_pairs`);
- with a response requirement's monitor (`checker.response_step`: scans since the
  unanswered rising edge, `_mon`), per on-delay timer: an unanswered edge means the timer
  runs and has run at least since that edge (its elapsed time at least `_mon` periods),
  so the deadline is reached through the timer, for every scan.
- per counter: D = (V = P); E -> V = 9999; F -> V = 0 (its status bits against its
  value). A counter's value against the count of its input's edges is not stated (the
  edges are the program's expressions, not state the model keeps).
- per off-delay (TOF) and pulse (TP) timer (`_pulse_candidates`): its Q against its last
  IN and `_on` (timing), V = 0 when neither times nor holds it, V < P while timing and
  (fixed period) V its elapsed time;
- per counter (`_counter_bounds`): V <= P and V < P (a counter counted up to its preset,
  or reset in the scan it gets there).

A candidate is kept only if it holds at the cold start and is kept by every scan from any
state satisfying the range invariants and the kept candidates (a greatest fixpoint,
Houdini): their conjunction is then inductive, true in every reachable state, and a proof
that assumes it stays sound.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import z3

from softplc.blocks import counter
from softplc.blocks.timer import time_unit, timer_cap
from softplc.runtime.blocks import MAX_VALUE

WIDE_EL = 64  # bits for elapsed-time arithmetic: an elapsed time times a 16-bit count
WORD_BITS = 16  # a Twido word: a preset, a value, the response monitor's count
MONITOR_OFFSETS = (-1, 0)  # periods between the timer's start and the edge's scan
PAIR_CHECK_MS = 2000  # ms per pair: IN_a -> IN_b over one scan (small terms: the inputs)


@dataclass(frozen=True)
class Candidate:
    text: str  # for the output: what it says
    keys: frozenset[str]  # the state it reads (all within the requirement's cone)
    term: Callable[[dict[str, Any]], Any]  # the fact, over a state


def _ew(x: Any) -> Any:
    """A bit-vector widened (unsigned) to WIDE_EL bits."""
    return z3.ZeroExt(WIDE_EL - x.size(), x)


def _timer_candidates(ck: Any, name: str) -> list[Candidate]:
    m = ck.model
    t = m.timers[name]
    k = {f: f"{name}.{f}" for f in ("P", "V", "Q", "_in", "_el")}
    out = [Candidate(f"{name}.V <= {name}.P", frozenset({k["P"], k["V"]}),
                     lambda s: s[k["V"]] <= s[k["P"]])]
    if t.type == "TON" and not m.variable:
        u = time_unit(t, m.period_us)
        base, step = t.base_us // u, m.period_us // u
        out.append(Candidate(f"{name} IN on -> {name}.V = its elapsed time (clamped at P)",
                             frozenset({k["_in"], k["_el"], k["P"], k["V"]}),
                             lambda s: _counted(s, k, "_in", base, step)))
    return out


def _counted(s: dict[str, Any], k: dict[str, str], running: str, base: int, step: int
             ) -> Any:
    """`running` on -> V is the elapsed time before the scan's advance, in time bases,
    clamped at P (`timer_rule`: V = el // base below P)."""
    el, P, V = _ew(s[k["_el"]]), _ew(s[k["P"]]), _ew(s[k["V"]])
    e = el - step
    return z3.Implies(s[k[running]], z3.And(
        z3.UGE(el, step), V == z3.If(z3.UGE(e, P * base), P, z3.UDiv(e, base))))


def _pulse_candidates(ck: Any, name: str) -> list[Candidate]:
    """An off-delay (TOF) or pulse (TP) timer's outputs against its last IN and `_on`
    (timing), as `timer_rule` leaves them after every execution [TWD USE 10AE, "Timer
    function block": TOF, Q is 1 while IN is 1 and until V reaches P after IN falls; TP,
    a rising edge gives a pulse of length P; manual, from memory; twido.md]:
    TOF: Q = (IN or timing); IN -> V = 0 and not timing; neither -> V = 0 or P (timed
    out);
    TP: Q = timing; neither timing nor IN -> V = 0;
    both, timing: V below P, and (fixed period) V is the elapsed time in time bases."""
    m = ck.model
    t = m.timers[name]
    k = {f: f"{name}.{f}" for f in ("P", "V", "Q", "_in", "_on", "_el")}
    Q, i, on, V, P = (k[f] for f in ("Q", "_in", "_on", "V", "P"))
    if t.type == "TOF":
        out = [Candidate(f"{name}.Q = (IN or timing)", frozenset({Q, i, on}),
                         lambda s: s[Q] == z3.Or(s[i], s[on])),
               Candidate(f"{name} IN on -> V = 0, not timing", frozenset({i, on, V}),
                         lambda s: z3.Implies(s[i], z3.And(s[V] == 0, z3.Not(s[on]))))]
        out.append(Candidate(f"{name} neither timing nor IN -> V = 0 or V = P",
                             frozenset({i, on, V, P}),
                             lambda s: z3.Implies(z3.Not(z3.Or(s[i], s[on])),
                                                  z3.Or(s[V] == 0, s[V] == s[P]))))
    else:
        out = [Candidate(f"{name}.Q = timing", frozenset({Q, on}),
                         lambda s: s[Q] == s[on]),
               Candidate(f"{name} neither timing nor IN -> V = 0", frozenset({i, on, V}),
                         lambda s: z3.Implies(z3.Not(z3.Or(s[i], s[on])), s[V] == 0))]
    out.append(Candidate(f"{name} timing -> V < P", frozenset({on, V, P}),
                         lambda s: z3.Implies(s[on], s[V] < s[P])))
    if not m.variable:
        u = time_unit(t, m.period_us)
        base, step = t.base_us // u, m.period_us // u
        out.append(Candidate(f"{name} timing -> {name}.V = its elapsed time",
                             frozenset({on, k["_el"], P, V}),
                             lambda s: _counted(s, k, "_on", base, step)))
    return out


def _counter_bounds(name: str) -> list[Candidate]:
    """A counter's value against its preset (`softplc/blocks/counter.py`): V <= P where
    nothing counts it past its preset (counted only up to it, or reset when it gets
    there: then V < P at every scan's end, the scan's reset included). Its value changes
    only on an edge of CU or CD, by one (or to 0 / P on R / S): that is the model's
    transition itself, exact, not a fact to add."""
    v, p = f"{name}.V", f"{name}.P"
    return [Candidate(f"{name}.V <= {name}.P", frozenset({v, p}),
                      lambda s: s[v] <= s[p]),
            Candidate(f"{name}.V < {name}.P", frozenset({v, p}),
                      lambda s: s[v] < s[p])]


def _pair_candidates(ck: Any, a: str, b: str) -> list[Candidate]:
    """b's input on whenever a's is, and then b's elapsed time at least a's."""
    ia, ib, ea, eb = (f"{a}._in", f"{b}._in", f"{a}._el", f"{b}._el")
    return [Candidate(f"{a} IN on -> {b} IN on", frozenset({ia, ib}),
                      lambda s: z3.Implies(s[ia], s[ib])),
            Candidate(f"{a} and {b} IN on -> {a} elapsed <= {b} elapsed",
                      frozenset({ia, ib, ea, eb}),
                      lambda s: z3.Implies(z3.And(s[ia], s[ib]),
                                           z3.ULE(_ew(s[ea]), _ew(s[eb]))))]


def _monitor_candidates(ck: Any, name: str) -> list[Candidate]:
    """An unanswered rising edge (`_mon` > 0 scans) and timer `name` running since."""
    m = ck.model
    t = m.timers[name]
    step = m.period_us // time_unit(t, m.period_us)
    cap = timer_cap(t, m.scan_info())
    i, e = f"{name}._in", f"{name}._el"
    out = []
    for off in MONITOR_OFFSETS:
        def since(s: dict[str, Any], off: int = off) -> Any:
            scans = _ew(s["_mon"]) + off if off >= 0 else _ew(s["_mon"]) - (-off)
            el = z3.If(z3.UGE(scans * step, cap), z3.BitVecVal(cap, WIDE_EL), scans * step)
            return z3.Implies(z3.UGT(s["_mon"], 0), z3.And(s[i], z3.UGE(_ew(s[e]), el)))
        out.append(Candidate(f"an unanswered edge -> {name} running, at least its scans"
                             f"{off:+d}", frozenset({"_mon", i, e}), since))
    return out


def _counter_candidates(name: str) -> list[Candidate]:
    """A counter's status bits against its value (`softplc/blocks/counter.py`): D is
    V = P after every execution; E (an underflow wrapped V to 9999) and F (an overflow
    wrapped it to 0) stay set only until the next count or reset [TWD USE 10AE, "Up/down
    counter function block", manual, from memory]."""
    k = {f: f"{name}.{f}" for f in ("P", "V", "D", "E", "F")}
    return [Candidate(f"{name}.D = ({name}.V = {name}.P)", frozenset({k["D"], k["V"], k["P"]}),
                      lambda s: s[k["D"]] == (s[k["V"]] == s[k["P"]])),
            Candidate(f"{name}.E -> {name}.V = {MAX_VALUE}", frozenset({k["E"], k["V"]}),
                      lambda s: z3.Implies(s[k["E"]], s[k["V"]] == MAX_VALUE)),
            Candidate(f"{name}.F -> {name}.V = 0", frozenset({k["F"], k["V"]}),
                      lambda s: z3.Implies(s[k["F"]], s[k["V"]] == 0))]


def related_pairs(ck: Any, ton: list[str]) -> list[tuple[str, str]]:
    """The ordered pairs (a, b) of on-delay timers counting in the same unit whose inputs,
    as one scan computes them from any state, satisfy IN_a -> IN_b: only those get the
    pair candidates (a filter, for time: Houdini would drop the others one round each)."""
    m = ck.model
    post = ck.step(dict(ck.pre), ck.inp)
    s = z3.Solver()
    s.set("timeout", PAIR_CHECK_MS)
    out = []
    for a in ton:
        for b in ton:
            ta, tb = m.timers[a], m.timers[b]
            if a != b and time_unit(ta, m.period_us) == time_unit(tb, m.period_us) and \
                    timer_cap(ta, m.scan_info()) == \
                    timer_cap(tb, m.scan_info()) and \
                    s.check(post[f"{a}._in"], z3.Not(post[f"{b}._in"])) == z3.unsat:
                out.append((a, b))
    return out


def timer_relations(ck: Any, st: dict[str, Any]) -> list[Any]:
    """The candidates over state `st`, for `Checker.candidates` (kept by `lemmas.houdini`
    where inductive); the same list, in the same order, for every state of `ck`."""
    m, keys = ck.model, ck.state_keys()
    # a product of an elapsed time and a 16-bit count must fit in WIDE_EL bits
    names = sorted(n for n in m.timers if f"{n}._in" in keys and f"{n}._el" in keys
                   and m.block_fields(n)["_el"] <= WIDE_EL - WORD_BITS)
    out = [c for n in names for c in _timer_candidates(ck, n)]
    ton = [n for n in names if m.timers[n].type == "TON"]
    if ck.timer_pairs is None:
        ck.timer_pairs = related_pairs(ck, ton)
    for a, b in ck.timer_pairs:
        out += _pair_candidates(ck, a, b)
    out += [c for n in sorted(m.used) if m.used[n][0] is counter.MODEL
            for c in _counter_candidates(n)]
    out += [c for n in names if m.timers[n].type in ("TOF", "TP")
            for c in _pulse_candidates(ck, n)]
    out += [c for n in sorted(m.used) if m.used[n][0] is counter.MODEL
            for c in _counter_bounds(n)]
    if ck.monitor and not m.variable and "_mon" in keys:
        out += [c for n in ton for c in _monitor_candidates(ck, n)]
    return [c.term(st) for c in out if c.keys <= set(keys)]
