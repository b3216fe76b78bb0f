"""Invariants over the program's own state, found from its scan and proven once per model
(Houdini over the whole scan, in a child process: `prove`), then assumed by every
requirement whose cone of influence holds their state (`Checker.facts`).

A Grafcet's safety requirement ("MOVING and FAULT never together", "the torch is off in
FAULT") needs what the chart guarantees by construction: its steps are mutually exclusive
when every transition clears its source and only one fires, a step implies the flags set on
entering it. A stepper's phase requirement needs the range of the word it decodes. Neither
k-induction (at a small k) nor Spacer finds them in time on a program of 100 rungs; stated
as candidates and checked, they make such requirements 1-inductive.

Candidates, read off the scan's terms (an end-of-scan value as a function of the state
before the scan and the inputs):
- a word whose every assignment is a constant (its next value an if-then-else of numerals
  and its own value): it stays in {its cold-start value, those constants} (a state or
  fault word, EJECUTANDO 0/100);
- bits that hold state (their next value reads their own: Grafcet steps, set/reset coils):
  NOT p (never set at the end of a scan: a tag the same scan clears), and for every
  pair p, q: p -> q and p -> NOT q (steps of one chart mutually exclusive, a
  step and its flags); in a program with a Grafcet, p is one of its steps (a program of
  100 rungs has some 40 such bits: every pair would be 3,000 candidates);
- such a bit p (a step, with a Grafcet) against a word w with constant assignments:
  p -> w = c for each constant, and, where w is also computed,
  p -> w in {cold value, its constants} (a count reset to a constant while a flag is set).

Each candidate is checked, never assumed: first on random runs of the scan engine (the
same semantics as the model: `tests/integration/test_verify_diff.py`), where one false in
a reached state is dropped at no solver cost; then it is kept only if it holds at the cold
start and the survivors together are kept by every scan from any state satisfying them (the
greatest such set, Houdini). Their conjunction is then inductive, so true in every reachable
state of the model, and so of the cone of any requirement (the cone's states are the
model's, projected). The environment's `assume` lines are not used: the facts hold in every
run, assumed or not.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import z3

from softplc.verify.model import Model, is_object, sort_of

MAX_BITS = 40  # state-holding bits paired (p -> q): 2 x 40 x 39 = 3,120 candidates at most
MAX_VALUES = 12  # constants per word: more is a computed word, not a table of states
MAX_CANDIDATES = 2500  # the candidates of one model, at most (Houdini asks each)
PROVE_S = 60.0  # s for the whole proof, at most (once per model; then every requirement)
ROUND_S = 5.0  # s per solver call of Houdini, at most
RUNS, SCANS = 24, 120  # random engine runs that sift the candidates, scans each
# word values the random runs try (a handshake's 1, a refusal's -1, small codes and kinds)
# besides any 16-bit value
POOL = (-1, 0, 1, 2, 3, 4, 5, 6, 100, 120)
SIGN = 1 << 15
CHANGE = (0.05, 0.3)  # the chance that an input changes in a scan, by run


@dataclass(frozen=True)
class Fact:
    text: str  # what it says, e.g. "%X5 -> NOT %X9" (also its identity across processes)
    keys: frozenset[str]  # the state it reads
    term: Callable[[dict[str, Any]], Any]  # the fact, over a state
    test: Callable[[dict[str, int]], bool]  # the fact, over an engine's values


def _walk(term: Any, below: Callable[[Any], list[Any]]) -> Iterator[Any]:
    """Each node of `term`'s DAG once, descending into `below(node)`."""
    seen: set[int] = set()
    todo = [term]
    while todo:
        t = todo.pop()
        if t.get_id() in seen:
            continue
        seen.add(t.get_id())
        yield t
        todo.extend(below(t))


def _is_var(t: Any) -> bool:
    return z3.is_const(t) and t.decl().kind() == z3.Z3_OP_UNINTERPRETED


def _names(term: Any) -> set[str]:
    """The names of the constants (variables) in `term`."""
    return {t.decl().name() for t in _walk(term, lambda t: [] if _is_var(t) else t.children())
            if _is_var(t)}


def _leaves(term: Any, own: str) -> tuple[set[int], bool]:
    """The numerals at the leaves of `term`'s if-then-else tree (as signed 16-bit values),
    and whether every leaf is a numeral or the variable named `own` (the word kept)."""
    vals: set[int] = set()
    exact = True
    def branches(t: Any) -> list[Any]:  # an if-then-else's two values, not its condition
        return t.children()[1:] if z3.is_app_of(t, z3.Z3_OP_ITE) else []
    for t in _walk(term, branches):
        if z3.is_app_of(t, z3.Z3_OP_ITE):
            continue
        if z3.is_bv_value(t):
            vals.add(t.as_signed_long())
        elif not (z3.is_const(t) and t.decl().name() == own):
            exact = False
    return vals, exact


def _floating(term: Any) -> bool:
    """`term` computes with floating-point values (a float's bits stored in a word)."""
    return any(t.sort().kind() in (z3.Z3_FLOATING_POINT_SORT, z3.Z3_ROUNDING_MODE_SORT)
               for t in _walk(term, lambda t: t.children()))


def _word(v: int) -> Any:
    return z3.BitVecVal(v, 16)


def _signed(v: int) -> int:
    """A word's value as a signed 16-bit number (the engine may give either form)."""
    v &= 2 * SIGN - 1
    return v - 2 * SIGN if v >= SIGN else v


def sift(model: Model, facts: list[Fact], runs: int = RUNS, scans: int = SCANS,
         seed: int = 0) -> list[Fact]:
    """The facts no state of `runs` random engine runs of `scans` scans breaks (inputs,
    host words and free objects random each scan; abstracted values the engine's own)."""
    import random

    from softplc.plc import PLC
    from softplc.verify.replay import set_inputs
    rnd = random.Random(seed)
    keys = sorted({k for f in facts for k in f.keys})
    inputs = [(k, sort, lo, hi) for k, (sort, lo, hi) in sorted(model.inputs.items())
              if not model.abstract.is_input(k) and k != "_dt"]

    def value(sort: str, lo: int, hi: int) -> int:
        if sort == "bool":
            return rnd.randint(0, 1)
        if lo < hi and (lo, hi) != (-SIGN, SIGN - 1):  # an analog input's span
            return rnd.randint(lo, hi)
        return rnd.choice(POOL) if rnd.random() < 0.8 else rnd.randint(-SIGN, SIGN - 1)

    from softplc.errors import SoftPLCError
    try:  # the engine from the model's program and configuration, as the replay builds it
        plc = PLC(model.plc.ast, model.plc.config, devices=False)
    except SoftPLCError:  # e.g. a symbol file named relative to another directory
        return facts  # not sifted: Houdini alone decides (sifting only saves it time)
    alive = list(facts)
    seen: set[tuple[int, ...]] = set()
    with plc:
        # each run from the cold start: the engine put back as built (`Engine.restore`,
        # as the trace player goes back) rather than built again (most of the sift's time)
        cold = plc.engine.snapshot()
        from softplc.access.reading import Reading
        read = Reading(plc).reader([plc.symbols.ref(k) for k in keys])  # from the arrays
        for run in range(runs):
            # inputs held for stretches (a run of all-random bits would fault at once: an
            # E-stop released half the time); half the runs change them more often
            change = CHANGE[run % len(CHANGE)]
            now = {k: value(sort, lo, hi) for k, sort, lo, hi in inputs}
            if run:
                plc.engine.restore(cold)
            for _ in range(scans):
                now = {k: value(sort, lo, hi) if rnd.random() < change else now[k]
                       for k, sort, lo, hi in inputs}
                set_inputs(plc, now)
                plc.scan()
                v = dict(zip(keys, read(), strict=True))
                seen_before = tuple(v.values())
                if seen_before not in seen:  # a state seen already breaks nothing new
                    seen.add(seen_before)
                    alive = [f for f in alive if f.test(v)]
    return alive


def _scan(model: Model) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """The model's scan from variables (state `k@si`, inputs): read by `candidates`, then
    checked by `houdini`: built once per model, kept on it."""
    made = getattr(model, "_state_scan", None)
    if made is None:
        pre = {k: z3.Const(f"{k}@si", sort_of(v.sort)) for k, v in model.vars.items()}
        _, inp = model.fresh("si")
        made = model._state_scan = (pre, inp, model.scan(dict(pre), inp))  # type: ignore[attr-defined]
    return made


def candidates(model: Model) -> list[Fact]:
    """The model's candidate facts, in an order that depends on the model only."""
    _, _, post = _scan(model)
    init = model.init_state()
    state = sorted(k for k, v in model.vars.items()
                   if is_object(k) and k not in model.host and k in post
                   and v.sort in ("bool", "w16") and not k.startswith(("%S", "%I")))
    bits = [k for k in state if model.vars[k].sort == "bool"
            and f"{k}@si" in _names(post[k])]
    bits = sorted(bits, key=lambda k: (not k.startswith("%X"), k))[:MAX_BITS]
    tables: dict[str, tuple[list[int], bool]] = {}
    for k in state:
        if model.vars[k].sort != "w16":
            continue
        if _floating(post[k]):  # a half of a float: no table of states, and its
            continue            # terms would make every solver call of Houdini slow
        vals, exact = _leaves(post[k], f"{k}@si")
        vals.add(z3.simplify(init[k]).as_signed_long())
        if len(vals) <= MAX_VALUES:
            tables[k] = (sorted(vals), exact)
    out: list[Fact] = []

    def among(w: str, vals: list[int]) -> Callable[[dict[str, Any]], Any]:
        return lambda s: z3.Or(*[s[w] == _word(c) for c in vals])

    for w, (vals, exact) in tables.items():
        if exact:
            out.append(Fact(f"{w} in {vals}", frozenset({w}), among(w, vals),
                            lambda v, w=w, vals=vals: _signed(v[w]) in vals))
    for p in bits:  # a bit that holds state and is never set (a tag the program clears)
        out.append(Fact(f"NOT {p}", frozenset({p}), lambda s, p=p: z3.Not(s[p]),
                        lambda v, p=p: not v[p]))
    # a Grafcet's steps are the antecedents (its facts are the step's), else every bit
    heads = [k for k in bits if k.startswith("%X")] or bits
    for p in heads:  # exclusions first (cut last when there are too many)
        for q in bits:
            if p != q and not (q in heads and q < p):  # p -> NOT q is q -> NOT p
                out.append(Fact(f"{p} -> NOT {q}", frozenset({p, q}),
                                lambda s, p=p, q=q: z3.Implies(s[p], z3.Not(s[q])),
                                lambda v, p=p, q=q: not (v[p] and v[q])))
    for p in heads:
        for q in bits:
            if p != q and not (p.startswith("%X") and q.startswith("%X")):  # a step
                out.append(Fact(f"{p} -> {q}", frozenset({p, q}),  # needs no other
                                lambda s, p=p, q=q: z3.Implies(s[p], s[q]),
                                lambda v, p=p, q=q: not v[p] or bool(v[q])))
    for p in heads:
        for w, (vals, exact) in tables.items():
            keys = frozenset({p, w})
            if not exact:
                out.append(Fact(f"{p} -> {w} in {vals}", keys,
                                lambda s, p=p, w=w, vals=vals: z3.Implies(
                                    s[p], among(w, vals)(s)),
                                lambda v, p=p, w=w, vals=vals:
                                not v[p] or _signed(v[w]) in vals))
            for c in vals if exact and len(vals) > 1 else ():
                out.append(Fact(f"{p} -> {w} = {c}", keys, lambda s, p=p, w=w, c=c:
                                z3.Implies(s[p], s[w] == _word(c)),
                                lambda v, p=p, w=w, c=c: not v[p] or _signed(v[w]) == c))
    return out[:MAX_CANDIDATES]


def houdini(model: Model, facts: list[Fact], seconds: float = PROVE_S) -> list[str]:
    """The texts of the facts that hold at the cold start and together are inductive
    ([] when the time runs out first: nothing is assumed then). The facts alive are
    asserted before the scan (in a scope, re-asserted when some are dropped: assumption
    literals for each, tried first, made one query of the mass tuning take a minute), and
    each is asked after the scan on its own (a disjunction of hundreds is far slower than
    hundreds of small queries); a model that breaks one drops every fact it breaks.
    Passes until one drops nothing."""
    return _houdini(model, facts, seconds)[0]


def _houdini(model: Model, facts: list[Fact], seconds: float) -> tuple[list[str], bool]:
    """`houdini`'s texts, and whether the solver decided every question in its time (else
    what it kept depends on the machine's speed: not kept for another model, `prove`)."""
    import time

    from softplc.verify.symbolic import value_of
    end = time.monotonic() + seconds
    # a fact read on values (`Fact.test`, as the sift reads the engine's) is the fact's
    # term evaluated on them: the cold start's, then a refuting model's post-state
    cold = {k: v.init for k, v in model.vars.items()}
    alive = {i for i, f in enumerate(facts) if f.test(cold)}
    pre, inp, post = _scan(model)
    s = z3.Solver()
    s.add(*model.invariants(pre), *model.input_constraints(inp))
    if "_facts" in post:
        s.add(post["_facts"])
    before = {i: facts[i].term(pre) for i in alive}
    after = {i: facts[i].term(post) for i in alive}
    changed, decided = True, True
    while changed and alive:
        changed = False
        s.push()
        s.add(*[before[i] for i in sorted(alive)])
        for i in sorted(alive):
            if i not in alive:
                continue
            left = end - time.monotonic()
            if left <= 0:
                return [], False
            s.set("timeout", int(1000 * min(left, ROUND_S)))
            r = s.check(z3.Not(after[i]))
            if r == z3.unsat:
                continue
            changed = True
            if r != z3.sat:  # undecided in its time: not assumed
                alive.discard(i)
                decided = False
            else:
                m = s.model()
                now = {k: value_of(m, post[k]) for k in {k for j in alive
                                                         for k in facts[j].keys}}
                alive -= {j for j in alive if not facts[j].test(now)}
            s.pop()  # the facts dropped were asserted: assert those alive again
            s.push()
            s.add(*[before[j] for j in sorted(alive)])
        s.pop()
    return [facts[i].text for i in sorted(alive)], decided


# Facts proven for a model, kept in this process for another model of the same system (a
# program verified again: the REPL, a test session, the benchmark), the least recently
# used dropped first. The key is the system itself: the ids of its terms (the scan from
# variables, the cold start, the range invariants, the input spans), which z3 shares
# between equal terms; the entry holds those terms, so no other term can take their ids.
CACHE_MODELS = 8
_proven: OrderedDict[tuple[Any, ...], tuple[list[Fact], list[Any]]] = OrderedDict()


def _system(model: Model) -> tuple[tuple[Any, ...], list[Any]]:
    """The key of `model`'s transition system in `_proven`, and the terms it names."""
    pre, inp, post = _scan(model)
    terms = [*post.values(), *model.init_state().values(), *model.invariants(pre),
             *model.input_constraints(inp)]
    return (tuple(post), tuple((k, v.sort) for k, v in model.vars.items()),
            tuple(sorted(model.host)), tuple(t.get_id() for t in terms)), terms


def prove(model: Model, run: Callable[..., Any] | None = None,
          seconds: float = PROVE_S) -> list[Fact]:
    """The model's proven facts, computed once and kept on the model (and for another
    model of the same system: `_proven`). `run(work, seconds)`: where the proof runs
    (`guard.isolated`: a child process, so that a solver overrunning its timeout cannot
    hold the run, and whose answer every requirement's child inherits); None: here,
    within `seconds`."""
    cached = getattr(model, "_state_facts", None)
    if cached is not None:
        return cached
    out: list[Fact] = []
    if not model.loops.sites:  # a loop's passes are the solver's: no scan term to read
        key, terms = _system(model)
        if key in _proven:
            _proven.move_to_end(key)
            out = _proven[key][0]
        else:
            out = _proven_here(model, run, seconds, key, terms)
    model._state_facts = out  # type: ignore[attr-defined]
    return out


def _proven_here(model: Model, run: Callable[..., Any] | None, seconds: float,
                 key: tuple[Any, ...], terms: list[Any]) -> list[Fact]:
    facts = candidates(model)

    def work(_report: Any = None) -> tuple[list[str], bool]:
        return _houdini(model, sift(model, facts), seconds)
    got = ([], True) if not facts else work() if run is None else run(work, seconds)
    if not isinstance(got, tuple):  # an UNKNOWN Result: the time or the solver
        return []
    texts, decided = got
    kept = set(texts)
    out = [f for f in facts if f.text in kept]
    if decided:  # (else a faster run may keep more)
        _proven[key] = (out, terms)
        while len(_proven) > CACHE_MODELS:
            _proven.popitem(last=False)
    return out
