"""Grafcet housekeeping: the system bits %S21-%S23 and the transitions of one scan.

A Twido Grafcet program has three parts: preprocessing (the rungs before the first step),
the sequential part (the steps) and post-processing (after `=*= POST`). The compiled code
calls `pre()` at the end of preprocessing and `post()` at the end of the sequential part.

%S21, %S22, %S23 [manual: TWD USE 10AE system-bit table; PL7 reference manual 35015365,
"Description of preliminary processing", for the order and the moment they act]:
  %S21 Grafcet initialisation: every step off, the initial steps (`=*=`) on. Set by the
       system on a cold start, or by the program in preprocessing.
  %S22 Grafcet re-initialisation: every step off.
  %S23 preset and freeze: while 1, no transition fires (the chart keeps its state).
All three are acted on at the end of preprocessing and reset there by the system, so a
program holds the chart frozen by setting %S23 in every scan's preprocessing.
If several are set, %S21 wins over %S22 (PL7: in ascending order); %S23 freezes the
transitions of the same scan in either case (our reading; unverified on hardware).
"""

from __future__ import annotations

S_GRAFCET_INIT, S_GRAFCET_RESET, S_GRAFCET_FREEZE = 21, 22, 23  # [manual]
GRAFCET_BITS = (S_GRAFCET_INIT, S_GRAFCET_RESET, S_GRAFCET_FREEZE)


class Grafcet:
    """Step bits `x`, system bits `s`; `ga`/`gd` collect the steps a scan's transitions
    activate / deactivate, applied together by `post()`."""

    def __init__(self, x: list[bool], s: list[bool]):
        self.x, self.s = x, s
        self.ga: list[int] = []
        self.gd: list[int] = []
        self.initial: tuple[int, ...] = ()  # the `=*= i` steps, set by the compiler's user
        self.frozen = 0

    def pre(self) -> None:
        """End of preprocessing: act on %S21/%S22/%S23, then reset them [manual]."""
        s = self.s
        if s[S_GRAFCET_INIT] or s[S_GRAFCET_RESET]:
            x = self.x
            x[:] = [False] * len(x)
            if s[S_GRAFCET_INIT]:
                for k in self.initial:
                    x[k] = True
        self.frozen = s[S_GRAFCET_FREEZE]
        s[S_GRAFCET_INIT] = s[S_GRAFCET_RESET] = s[S_GRAFCET_FREEZE] = False

    def post(self) -> None:
        """End of the sequential part: apply the transitions (none while frozen)."""
        if not (self.ga or self.gd or self.frozen):
            return  # most scans: no transition fired
        if self.frozen:
            self.frozen = 0
        else:
            x = self.x
            for k in self.gd:
                x[k] = False
            for k in self.ga:
                x[k] = True
        self.ga.clear()
        self.gd.clear()
