"""Candidate invariants the model states itself, kept when they are inductive (Houdini).

An on-delay timer's outputs follow from its last input and elapsed value: `Q` is set
exactly when the last IN was 1 and `V` reached `P`, and `V` is 0 while the last IN was 0
(`blocks/timer.timer_rule`). That holds after every execution;
a program that writes the preset between two executions breaks it, which is why each
candidate is only kept once checked: dropped if false at the cold start, then the ones a
scan can break from a state satisfying all of them are dropped until the rest is
inductive. The survivors strengthen k-induction (start states) and Spacer (its clauses):
a two-hand control's timer windows become 1-inductive instead of needing a deep k.
"""

from __future__ import annotations

from typing import Any

import z3

from softplc.verify.clock import Clock
from softplc.verify.model import sort_of

CHECK_S = 10.0  # s per Houdini round, at most (within the requirement's clock)


def timer_candidates(st: dict[str, Any], timers: dict[str, Any]) -> list[Any]:
    """The on-delay timers' output facts over state `st`."""
    out = []
    for name, t in sorted(timers.items()):
        if t.type != "TON":
            continue
        q, v, p, last = (st[f"{name}.{f}"] for f in ("Q", "V", "P", "_in"))
        out += [q == z3.And(last, v >= p), z3.Implies(z3.Not(last), v == 0)]
    return out


def houdini(ck: Any, clock: Clock) -> list[int]:
    """The indices of `ck.candidates`' terms that hold at the cold start and together are
    inductive (with the range invariants); [] when the clock or the solver gives up."""
    init = ck.candidates(ck.init())
    s = z3.Solver()
    alive = [i for i, c in enumerate(init) if z3.is_true(z3.simplify(c))
             or s.check(z3.Not(c)) == z3.unsat]
    if not alive:
        return []
    # one scan from variables for every round (each round's query on the same terms)
    pre = {k: z3.Const(f"{k}@houdini", sort_of(v)) for k, v in ck.state_keys().items()}
    _, inp = ck.model.fresh("houdini")
    post = ck.step(pre, inp)
    cands, after = ck.candidates(pre), ck.candidates(post)
    while alive:
        s = z3.Solver()
        s.add(*ck.invariants(pre), *ck.assumed(post, inp))
        s.add(*[cands[i] for i in alive])
        bad = z3.Or(*[z3.Not(after[i]) for i in alive])
        clock.doing = "checking the timers' candidate invariants"
        r = clock.check(s, bad, what="", cap=CHECK_S)
        if r == z3.unsat:
            return alive
        if r != z3.sat:
            return []
        m = s.model()
        keep = [i for i in alive if z3.is_true(m.eval(after[i], model_completion=True))]
        if len(keep) == len(alive):  # pragma: no cover - the model refutes one of them
            return []
        alive = keep
    return []
