"""Proof and search engines over a `Checker`: bounded model checking (BMC) for a minimal
counterexample, k-induction for a proof, and z3's Spacer (IC3/PDR on constrained Horn
clauses) for a proof without a k.

BMC unrolls from the cold-start state one scan at a time, with fresh variables per scan
tied by equalities, and asks at each depth whether the requirement can fail there first:
the first depth that is satisfiable gives a shortest counterexample.
k-induction: from any state satisfying the range invariants (`Checker.invariants`, first
checked inductive themselves), k scans in which the requirement (and the requirements
already proven, `Checker.lemmas`) holds force it in the next one; with BMC clean to
depth k that proves it for every run.
`verify` advances the two in turn, one depth each (BMC at scan d, then the induction step
at k = d): a short counterexample is found before the induction goes deep, a proof comes
as soon as the step holds with BMC clean to its k.
"""

from __future__ import annotations

import random
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import z3

from softplc.verify.cegar import confirmed, engine_run, exclusion, given_inputs, real_inputs
from softplc.verify.checker import Checker
from softplc.verify.clock import Clock, TimeUp
from softplc.verify.defaults import DEPTH, MAX_K, TIMEOUT_S
from softplc.verify.model import Model, run_concrete, sort_of
from softplc.verify.requirements import Node, Requirement, Spec
from softplc.verify.stateinv import prove
from softplc.verify.symbolic import value_of

Progress = Callable[[str, int, float], None]
FOUND = "counterexample"  # progress: BMC found one at that depth (its trace comes next)
Stop = Callable[[], bool]  # polled between solver calls: a proof came from elsewhere
INDUCTION_SHARE = 0.5  # of a requirement's time, at most, in k-induction's own steps


@dataclass
class Result:
    status: str  # PROVEN | VIOLATED | UNKNOWN
    method: str = ""  # "k-induction (k=3)", "Spacer", "BMC"
    depth: int = 0  # scans searched (VIOLATED: the counterexample's length)
    seconds: float = 0.0
    trace: list[dict[str, dict[str, int]]] = field(default_factory=list)  # per scan
    note: str = ""  # why UNKNOWN, when it is not the time


class _Unroll:
    """A path of scans: states as variables, each tied to the scan before."""

    def __init__(self, ck: Checker, solver: z3.Solver, start: dict[str, Any] | None,
                 tag: str):
        self.ck, self.s, self.tag = ck, solver, tag
        self.keys = ck.state_keys()
        if start is None:
            start = self.fresh_state(0)
            solver.add(*ck.invariants(start))
        self.states = [start]
        self.inputs: list[dict[str, Any]] = []
        self.posts: list[dict[str, Any]] = []

    def fresh_state(self, i: int) -> dict[str, Any]:
        return {k: z3.Const(f"{k}@{self.tag}{i}", sort_of(s)) for k, s in self.keys.items()}

    def extend(self) -> dict[str, Any]:
        i = len(self.inputs)
        _, inp = self.ck.model.fresh(f"{self.tag}{i}")
        post = self.ck.step(self.states[-1], inp)
        nxt = self.fresh_state(i + 1)
        self.s.add(*[nxt[k] == post[k] for k in self.keys])
        self.s.add(*self.ck.assumed(post, inp))
        view = dict(post)
        view.update(nxt)  # read the state through its variables (smaller terms)
        self.states.append(nxt)
        self.inputs.append(inp)
        self.posts.append(view)
        return view


def _trace(ck: Checker, u: _Unroll, model: z3.ModelRef, watch: list[str]) -> list[dict]:
    """The counterexample's rows: inputs, the values the requirement reads, and every
    object the model has, from the whole model run on the inputs (the solver saw only the
    requirement's cone of influence)."""
    from softplc.twido.address import parse_address
    given = given_inputs(u.inputs, model)
    every = run_concrete(ck.model, given)
    if ck.model.abstract.ranges:  # the values are the engine's (it confirmed the run)
        every = engine_run(ck.model, ck.req.text,
                           [real_inputs(ck.model, g) for g in given])[1]
    from softplc.verify.replay import shown
    rows = []
    for raw, post, objects in zip(given, u.posts, every, strict=True):
        rd = ck.read(post)
        values = {}
        for a in watch:
            ref = parse_address(a, ck.model.plc.profile)
            values[a] = shown(value_of(model, rd(ref)))
        ins = real_inputs(ck.model, raw)
        if ck.model.abstract.ranges:
            values = {a: objects.get(a, values[a]) for a in values}
        rows.append({"inputs": ins, "values": values, "objects": objects})
    return rows


def _loop_hit(s: z3.Solver, post: dict[str, Any]) -> bool:
    """The solver's run has a loop past the passes unrolled (not a counterexample)."""
    return "_loop" in post and z3.is_true(s.model().eval(post["_loop"],
                                                         model_completion=True))


class BaseCase:
    """BMC one scan at a time (`step`): from the cold-start state, is there a run whose
    first failure is at the next scan? The first scan that has one gives a shortest
    counterexample. Abstractions are refined at each scan: a counterexample the engine
    does not confirm is excluded (at that scan only: a longer run may still fail)."""

    def __init__(self, ck: Checker, clock: Clock, watch: list[str],
                 progress: Progress | None = None):
        self.ck, self.clock, self.watch, self.progress = ck, clock, watch, progress
        self.t0 = time.monotonic()
        self.s = ck.solver()
        self.u = _Unroll(ck, self.s, ck.init(), "b")
        self.spurious = 0
        self.clean = 0  # scans searched with no counterexample

    def unknown(self, note: str = "") -> Result:
        return Result("UNKNOWN", "BMC", self.clean, time.monotonic() - self.t0, note=note)

    def step(self) -> Result | None:
        """Search scan `clean + 1`: None when no run fails first there (clean to it), else
        VIOLATED (a shortest counterexample, with its trace) or UNKNOWN with a note (a
        run needs more passes of a loop than unrolled; the solver gave up). TimeUp when
        the clock runs out (`clock.clean`: the scans searched clean)."""
        ck, s, clock, d = self.ck, self.s, self.clock, self.clean
        clock.doing = f"BMC at scan {d + 1}"
        post = self.u.extend()
        bad = z3.Not(ck.holds(post))
        abstract = bool(ck.model.abstract.ranges)
        if abstract:  # exclusions hold at this depth only: a longer run may still fail
            s.push()
        r = clock.check(s, bad, what="")
        while r == z3.sat and abstract and not _loop_hit(s, post) \
                and not confirmed(ck.model, ck.req.text, given_inputs(self.u.inputs, s.model())):
            self.spurious += 1  # the abstraction allowed it, the engine does not: refine
            s.add(exclusion(ck.model, self.u.inputs, s.model()))
            clock.doing = (f"BMC at scan {d + 1}, refining the abstractions "
                           f"({self.spurious} counterexample(s) the engine did not confirm "
                           "excluded)")
            r = clock.check(s, bad, what="")
        m = s.model() if r == z3.sat else None
        if abstract:
            s.pop()
        if m is not None:
            if "_loop" in post and z3.is_true(m.eval(post["_loop"], model_completion=True)):
                return self.unknown(ck.model.loops.note(d + 1))
            if self.progress:  # the verdict is in (`guard` waits for its trace, off the clock)
                self.progress(FOUND, d + 1, time.monotonic() - self.t0)
            ck.model.loops.clock = None  # the trace's scans are concrete: no time out
            return Result("VIOLATED", "BMC", d + 1, time.monotonic() - self.t0,
                          _trace(ck, self.u, m, self.watch))
        if r == z3.unknown:
            return self.unknown(f"the solver gave up at scan {d + 1}: {s.reason_unknown()}")
        s.add(ck.holds(post))  # the first failure is at a later scan
        self.clean = clock.clean = d + 1
        if self.progress:
            self.progress("BMC", d + 1, time.monotonic() - self.t0)
        return None


def bmc(ck: Checker, depth: int, clock: Clock, watch: list[str],
        progress: Progress | None = None, stop: Stop | None = None) -> Result:
    """A shortest counterexample within `depth` scans, or UNKNOWN (clean to that depth;
    also when `stop()` says a proof came from elsewhere). TimeUp when `clock` runs out
    (`clock.clean`: the scans searched clean)."""
    base = BaseCase(ck, clock, watch, progress)
    while base.clean < depth and not (stop is not None and stop()):
        res = base.step()
        if res is not None:
            return res
    return base.unknown()


def invariants_inductive(ck: Checker, clock: Clock) -> bool:
    """The range invariants hold initially and are kept by every scan."""
    clock.doing = "checking the range invariants"
    s = ck.solver()
    init = ck.init()
    if clock.check(s, z3.Not(z3.And(*ck.invariants(init))), what="at the cold start",
                   cap=20) != z3.unsat:
        return False
    u = _Unroll(ck, s, None, "i")
    u.extend()
    return clock.check(s, z3.Not(z3.And(*ck.invariants(u.states[-1]))),
                       what="after a scan", cap=20) == z3.unsat


class Induction:
    """k-induction one k at a time (`step`): from any state satisfying the range
    invariants, k scans in which the requirement (and the lemmas, the model's facts) holds
    force it in the next one. `k` is the smallest such k once found; `over` once no
    larger k will be tried (a proof, `max_k`, its `budget` of seconds spent in its own
    steps, the solver gave up). The caller checks the base case (BMC clean to depth k)."""

    def __init__(self, ck: Checker, clock: Clock, max_k: int, budget: float,
                 progress: Progress | None = None):
        self.ck, self.clock, self.max_k, self.budget = ck, clock, max_k, budget
        self.progress = progress
        self.spent = 0.0  # s in its steps (BMC's, in between, are not its time)
        self.s: z3.Solver | None = ck.solver()
        self.u: _Unroll | None = _Unroll(ck, self.s, None, "k")
        self.tried = 0  # the largest k tried
        self.k: int | None = None
        self.over = max_k < 1

    def _end(self, k: int | None = None) -> None:
        self.k, self.over = k, True
        self.s = self.u = None  # its terms: freed for the other engines

    def step(self) -> None:
        """Try k = `tried + 1`. TimeUp when the clock (not the budget) runs out."""
        t0 = time.monotonic()
        try:
            self._try(self.tried + 1, t0)
        finally:
            self.spent += time.monotonic() - t0

    def _try(self, k: int, t0: float) -> None:
        assert self.s is not None and self.u is not None and not self.over
        ck, s, clock = self.ck, self.s, self.clock
        self.tried = k
        clock.doing = f"k-induction at k={k}"
        post = self.u.extend()
        s.add(*ck.lemma_terms(post), *ck.facts(post))  # proven invariants: every scan
        left = self.budget - self.spent - (time.monotonic() - t0)
        if left <= 0:
            return self._end()
        r = clock.check(s, z3.Not(ck.holds(post)), what="", cap=left)
        if r == z3.unsat:
            return self._end(k)
        if r == z3.unknown:
            return self._end()
        s.add(ck.holds(post))
        if self.progress:
            self.progress("k-induction", k, self.spent + time.monotonic() - t0)
        if k >= self.max_k:
            self._end()


def horn_clauses(ck: Checker, shuffle: int = 0) -> str:
    """The system as constrained Horn clauses (SMT-LIB): an inductive `Inv` exists (sat)
    exactly when the requirement holds in every reachable state. `shuffle` > 0: `Inv`'s
    arguments in another order (Spacer's time depends much on the order of the text)."""
    keys = ck.state_keys()
    names = list(keys)
    if shuffle:
        random.Random(shuffle).shuffle(names)
    sorts = [sort_of(keys[k]) for k in names]
    inv = z3.Function("Inv", *sorts, z3.BoolSort())
    cur = {k: z3.Const(f"{k}@h", sort_of(keys[k])) for k in names}
    _, inp = ck.model.fresh("h")
    post = ck.step(cur, inp)
    init = ck.init()
    xs = [cur[k] for k in names] + list(inp.values())
    s = z3.SolverFor("HORN")
    s.add(inv(*[init[k] for k in names]))
    # the range invariants (checked inductive) and the proven lemmas hold in every
    # reachable state: given, Spacer need not find them
    body = z3.And(inv(*[cur[k] for k in names]), *ck.invariants(cur), *ck.assumed(post, inp),
                  *ck.lemma_terms(post), *ck.facts(post))
    s.add(z3.ForAll(xs, z3.Implies(body, inv(*[post[k] for k in names]))))
    s.add(z3.ForAll(xs, z3.Implies(z3.And(body, z3.Not(ck.holds(post))), False)))
    return s.sexpr()


_CHILD = ("import sys, z3\n"
          "s = z3.SolverFor('HORN')\n"
          "s.from_file(sys.argv[1])\n"
          "print(s.check())\n")


class Spacer:
    """Spacer on a requirement in a child process, so that it runs beside k-induction and
    BMC: it honours neither z3's timeout nor an interrupt promptly, so it is killed at the
    deadline (`kill`). Its time depends much on the order of the clauses' text (on the
    drawing table, one order answers in 0.6 s, another not in 20 s): an attempt that
    outlives its budget is restarted on another order (`horn_clauses`' shuffle), each
    budget twice the last."""

    FIRST = 4.0  # s, the first attempt's budget

    def __init__(self, ck: Checker):
        self.ck = ck
        self.attempt = 0
        self.result: str | None = None
        self._start()

    def _start(self) -> None:
        with tempfile.NamedTemporaryFile("w", suffix=".smt2", delete=False) as f:
            f.write(horn_clauses(self.ck, self.attempt))
        self.path = Path(f.name)
        self.proc = subprocess.Popen([sys.executable, "-c", _CHILD, f.name],
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                                     text=True)
        self.until = time.monotonic() + self.FIRST * 2 ** self.attempt

    def _stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        if self.proc.stdout:
            self.proc.stdout.close()
        self.path.unlink(missing_ok=True)

    def _restart(self) -> None:
        self._stop()
        self.attempt += 1
        self._start()

    def done(self) -> str | None:
        """The answer if there is one, else None (never blocks; restarts when due)."""
        if self.result is None and self.proc.poll() is not None:
            out = self.proc.stdout.read().strip() if self.proc.stdout else ""
            self.result = {"sat": "PROVEN", "unsat": "VIOLATED"}.get(out, "UNKNOWN")
        elif self.result is None and time.monotonic() > self.until:
            self._restart()
        return self.result

    def proven(self) -> bool:
        return self.done() == "PROVEN"

    def wait(self, seconds: float) -> str:
        end = time.monotonic() + max(0.0, seconds)
        while self.done() is None:
            try:
                self.proc.wait(timeout=max(0.01, min(end, self.until) - time.monotonic()))
            except subprocess.TimeoutExpired:
                if time.monotonic() >= end:
                    self.kill()
                    return "UNKNOWN"
        return self.result or "UNKNOWN"

    def kill(self) -> None:
        self._stop()


@dataclass
class Limits:
    """How far `requirement` searches: scans, k, seconds (the whole requirement), Spacer."""

    depth: int = DEPTH
    max_k: int = MAX_K
    seconds: float = TIMEOUT_S
    spacer: bool = True


def requirement(model: Model, spec: Spec, req: Requirement, lemmas: list[Node],
                limits: Limits, watch: list[str], progress: Progress | None = None
                ) -> Result:
    """`req` checked from start to end on one clock of `limits.seconds`: its cone of
    influence (`Checker`: a scan of the model, loops decided by the solver) and `verify`."""
    clock = Clock(limits.seconds)
    try:
        with model.loops.timed(clock):
            ck = Checker(model, spec, req, lemmas)
    except TimeUp as e:
        return Result("UNKNOWN", "", 0, clock.elapsed(), note=str(e))
    return verify(ck, limits.depth, limits.max_k, clock, watch, limits.spacer, progress)


def verify(ck: Checker, depth: int, max_k: int, seconds: float | Clock, watch: list[str],
           use_spacer: bool = True, progress: Progress | None = None) -> Result:
    """BMC for a counterexample and k-induction for a proof, in turn one depth each, with
    Spacer beside them for a proof without a k, within `seconds`
    (or what is left of a requirement's clock): every solver call, the model's included,
    gets the time left; when it runs out, UNKNOWN saying what was running."""
    clock = seconds if isinstance(seconds, Clock) else Clock(seconds)
    try:
        with ck.model.loops.timed(clock):
            return _verify(ck, depth, max_k, clock, watch, use_spacer, progress)
    except TimeUp as e:
        return Result("UNKNOWN", "BMC", clock.clean, clock.elapsed(), note=str(e))


def _verify(ck: Checker, depth: int, max_k: int, clock: Clock, watch: list[str],
            use_spacer: bool, progress: Progress | None) -> Result:
    if not invariants_inductive(ck, clock):  # pragma: no cover - a modelling bug
        ck.invariants = lambda st: []  # type: ignore[method-assign]  # prove without them
    # the model's facts (proven once, `stateinv`), after the check: a subset of an
    # inductive set need not be inductive on its own, but each is true in every state
    ck.use_facts(prove(ck.model, seconds=max(0.0, clock.left() / 2)))
    if ck.candidates(ck.init()):  # the timers' facts, kept where inductive
        from softplc.verify.lemmas import houdini
        ck.lemma_ids = houdini(ck, clock)
    # the base case and the induction step advance in turn, one depth each: BMC at scan
    # d, then k-induction at k = d. A counterexample is reported as soon as BMC finds it
    # (the shortest: every shorter depth was clean), a proof as soon as the step holds at
    # k with BMC clean to k. Spacer runs beside them (the time of the slower, not of the
    # sum), started once 1-induction has failed: most simple requirements end there
    base = BaseCase(ck, clock, watch, progress)
    step = Induction(ck, clock, max_k, clock.seconds * INDUCTION_SHARE, progress)
    spacer: Spacer | None = None
    try:
        while True:
            if step.k is not None and base.clean >= step.k:
                return Result("PROVEN", f"k-induction (k={step.k})", base.clean,
                              clock.elapsed())
            if use_spacer and spacer is None and step.k is None and (step.tried or step.over):
                spacer = Spacer(ck)
            if spacer is not None and spacer.proven():
                return Result("PROVEN", "Spacer (IC3/PDR)", base.clean, clock.elapsed())
            if base.clean < max(depth, step.k or 0):  # a proof at k needs BMC to k
                res = base.step()
                if res is not None:
                    res.seconds = clock.elapsed()
                    return res
            elif step.over:
                break
            if not step.over:
                step.step()
        if spacer is None:  # (no Spacer asked)
            return Result("UNKNOWN", "BMC", base.clean, clock.elapsed())
        clock.doing = f"waiting for Spacer, BMC clean to {base.clean} scans"
        if progress and spacer.done() is None:
            progress("Spacer", base.clean, clock.elapsed())
        found = spacer.wait(clock.left())
    finally:
        if spacer is not None:
            spacer.kill()
    if found == "PROVEN":
        return Result("PROVEN", "Spacer (IC3/PDR)", base.clean, clock.elapsed())
    if found == "VIOLATED":  # no trace from Spacer: say so, keep it unconfirmed
        return Result("UNKNOWN", "Spacer: fails after more scans than searched",
                      base.clean, clock.elapsed())
    note = str(clock.up()) if clock.left() <= 0 else "Spacer gave up (unknown)"
    return Result("UNKNOWN", "BMC", base.clean, clock.elapsed(), note=note)
