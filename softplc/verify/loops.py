"""Loops (backward jumps) in the model: each scan unrolls a loop pass by pass, as the
engine's `_pc` dispatch runs it, while the solver cannot rule out another pass, up to
`bound` passes; past them a run is not modelled (`Model.scan`'s key `_loop`)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import z3

from softplc.il import ast as A
from softplc.verify.clock import Clock

# s the solver may spend, over a loop's passes, deciding whether another pass can run;
# past it the remaining passes are not unrolled and the scans needing them are UNKNOWN
LOOP_SOLVER_BUDGET_S = 10.0
PASS_CHECK_S = 2.0  # s for one such decision (an undecided pass is unrolled)


class Loops:
    """The loops of one program's model and what unrolling them cost."""

    def __init__(self, bound: int, file: str):
        self.bound = bound
        self.cut = bound + 1  # passes unrolled when the solver's budget ran out
        self.sites: dict[int, A.Pos] = {}  # label -> its first backward jump
        self.file = file
        self.clock: Clock | None = None  # the requirement's, while one is checked

    @contextmanager
    def timed(self, clock: Clock) -> Iterator[None]:
        """Decide passes on the requirement's `clock` within this block."""
        self.clock = clock
        try:
            yield
        finally:
            self.clock = None

    def where(self) -> str:
        return ", ".join(f"{self.file}:{p.line}:{p.column}" for p in self.sites.values())

    def after_pass(self, n: int, nxt: dict[int, Any], spent: float
                   ) -> tuple[dict[int, Any], Any | None, float]:
        """After pass `n` (from 0) took the backward jumps `nxt` (label -> condition): the
        ones another pass may take, the condition of a run past the passes unrolled
        (None: unroll on), and the solver's time spent over this loop's passes."""
        t0 = time.perf_counter()
        back = {k: c for k, c in nxt.items() if not self.never(c, n + 2)}
        spent += time.perf_counter() - t0
        if back and (n == self.bound or spent > LOOP_SOLVER_BUDGET_S):
            # past the bound, or the passes' terms have outgrown the solver (a pass count
            # that depends on inputs, products of them: time and memory grow each pass)
            if n < self.bound:
                self.cut = min(self.cut, n + 1)
            return back, z3.Or(*back.values()), spent
        return back, None, spent

    def never(self, c: Any, n: int) -> bool:
        """`c` (a jump back to run pass `n`) is false in every state: the state's terms
        are in `c`, so a plain simplification does not see that a loop counter reached its
        end. Within the requirement's clock (TimeUp when it runs out)."""
        c = z3.simplify(c)
        if z3.is_false(c) or z3.is_true(c):
            return z3.is_false(c)
        s = z3.Solver()
        if self.clock is None:
            s.set("timeout", int(PASS_CHECK_S * 1000))
            return s.check(c) == z3.unsat
        what = f"deciding whether the loop at {self.where()} runs pass {n}"
        return self.clock.check(s, c, what=what, cap=PASS_CHECK_S) == z3.unsat

    def note(self, scan: int) -> str:
        """Why a run is not modelled past `scan`: a loop ran more passes than unrolled."""
        if self.cut <= self.bound:
            return (f"a loop (backward jump at {self.where()}) can run more than {self.cut} "
                    f"passes in scan {scan}, and deciding whether each pass runs outgrew "
                    f"{LOOP_SOLVER_BUDGET_S:g} s of the solver at pass {self.cut}: "
                    "verify cannot model it past there (its pass count depends on inputs)")
        return (f"a loop (backward jump at {self.where()}) can run more than {self.bound} "
                f"passes in scan {scan}: verify cannot model it past there (raise "
                f"--loop-bound)")
