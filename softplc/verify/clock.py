"""A requirement's time. Every solver call of a requirement (the model's scans included:
deciding a loop's passes is one) gets what is left of it, so that the requirement ends at
its deadline, UNKNOWN, with a message saying what was running (`TimeUp`)."""

from __future__ import annotations

import time
from typing import Any

import z3


class TimeUp(Exception):
    """The requirement's time ran out; the message says during what. Caught by the engines
    (`engines.verify`, `engines.requirement`): a user sees an UNKNOWN with it."""


class Clock:
    """The deadline of one requirement, `seconds` from now."""

    def __init__(self, seconds: float):
        self.seconds = seconds
        self.start = time.monotonic()
        self.end = self.start + seconds
        self.doing = "building its model"  # what runs now, named when the time runs out
        self.clean = 0  # scans BMC searched with no counterexample

    def left(self) -> float:
        return self.end - time.monotonic()

    def elapsed(self) -> float:
        return time.monotonic() - self.start

    def ms(self, what: str, cap: float | None = None) -> int:
        """A solver timeout in ms: the time left, at most `cap` s; TimeUp if none is left."""
        left = self.left()
        if left <= 0:
            raise self.up(what)
        return max(1, int(1000 * (left if cap is None else min(cap, left))))

    def check(self, s: z3.Solver, *assumptions: Any, what: str,
              cap: float | None = None) -> z3.CheckSatResult:
        """`s.check(*assumptions)` within the time left (and `cap` s); TimeUp if the answer
        is unknown because the requirement's time ran out."""
        s.set("timeout", self.ms(what, cap))
        r = s.check(*assumptions)
        if r == z3.unknown and self.left() <= 0:
            raise self.up(what)
        return r

    def up(self, what: str = "") -> TimeUp:
        return TimeUp(f"the requirement's {self.seconds:g} s ran out: {self.doing}"
                      + (f", {what}" if what else ""))
