"""%Ci up/down counters, every face: the runtime block, `[counters]`, its set-up, its verify
model.

    counters."%C0" = { preset = 10 }

The rule (`counter_rule`) is written once over a value domain: the verifier runs it on
solver terms. `Counter` keeps straight-line code (`run`, and the short forms `cu`, `cd`
written out: one call instead of three, the scan's hot path);
tests/integration/test_block_rules.py checks each against the rule, value for value.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pydantic import Field

from softplc.blocks import BIT, WORD, BlockModel, Scan, rising
from softplc.config.fields import Section
from softplc.errors import BlockError
from softplc.runtime.blocks import MAX_VALUE, Block


def counter_rule(D: Any, s: Mapping[str, Any], R: Any, S: Any, CU: Any,
                 CD: Any) -> dict[str, Any]:
    """%Ci [m221]: R (priority) V := 0; S V := P; CU / CD count on rising edges (both in
    one scan cancel); D = (V = P); F set on the 9999 -> 0 wrap going up, E on the
    0 -> 9999 wrap going down; E and F clear at the next count."""
    V, P = s["V"], s["P"]
    up, down = rising(D, CU, s["_cu"]), rising(D, CD, s["_cd"])
    count = D.and_(D.and_(D.not_(R), D.not_(S)), D.ne(up, down))
    over = D.and_(up, V >= MAX_VALUE)
    under = D.and_(down, V <= 0)
    counted = D.ite(up, D.ite(over, 0, V + 1), D.ite(under, MAX_VALUE, V - 1))
    V2 = D.ite(R, 0, D.ite(S, P, D.ite(count, counted, V)))
    return {"_cu": D.bit(CU), "_cd": D.bit(CD), "V": V2, "D": D.bit(V2 == P),
            "E": D.bit(D.and_(D.not_(R), D.ite(count, D.and_(D.not_(up), under),
                                                  s["E"]))),
            "F": D.bit(D.and_(D.not_(R), D.ite(count, over, s["F"])))}


class Counter(Block):
    """%Ci up/down counter (`counter_rule` says what it does). Straight-line code for the
    engine's speed, checked against `counter_rule` (see the module docstring)."""

    PINS = ("R", "S", "CU", "CD")
    FIELDS = ("P", "V", "D", "E", "F", "_cu", "_cd")
    EDGE_PINS = {"CU": "_cu", "CD": "_cd"}

    def __init__(self, preset: int = MAX_VALUE):
        if not 0 <= int(preset) <= MAX_VALUE:
            raise BlockError(f"preset {preset}: 0..{MAX_VALUE}")
        self.P, self.V, self.D, self.E, self.F = int(preset), 0, 0, 0, 0
        self._cu = self._cd = 0

    def listing(self, i: int) -> str:
        """The debugger's line for %Ci."""
        return f"%C{i:<3} P={self.P:<5} V={self.V:<5} D={int(self.D)} E={int(self.E)} " \
               f"F={int(self.F)}"

    def run(self, R: Any = 0, S: Any = 0, CU: Any = 0, CD: Any = 0) -> None:
        up, down = CU and not self._cu, CD and not self._cd  # rising edges
        self._cu, self._cd = (1 if CU else 0), (1 if CD else 0)
        if R:
            self.V, self.E, self.F = 0, 0, 0
        elif S:
            self.V = self.P
        elif up:
            if not down:  # both in one scan cancel
                self.E = 0
                if self.V < MAX_VALUE:
                    self.V, self.F = self.V + 1, 0
                else:
                    self.V, self.F = 0, 1
        elif down:
            self.F = 0
            if self.V > 0:
                self.V, self.E = self.V - 1, 0
            else:
                self.V, self.E = MAX_VALUE, 1
        self.D = 1 if self.V == self.P else 0

    # The short form (`CU %C0`, `CD %C0`): `run` with that input, R = S = 0 and the other
    # edge input held (no edge), written out: one call instead of three, the rising edge
    # the only branch that counts.
    def cu(self, v: Any) -> None:
        if v and not self._cu:
            self._cu, self.E, self.F = 1, 0, 0
            if self.V < MAX_VALUE:
                self.V += 1
            else:
                self.V, self.F = 0, 1
        else:
            self._cu = 1 if v else 0
        self.D = 1 if self.V == self.P else 0

    def cd(self, v: Any) -> None:
        if v and not self._cd:
            self._cd, self.E, self.F = 1, 0, 0
            if self.V > 0:
                self.V -= 1
            else:
                self.V, self.E = MAX_VALUE, 1
        else:
            self._cd = 1 if v else 0
        self.D = 1 if self.V == self.P else 0


class CounterConfig(Section):
    """`[counters]`: one entry per counter, its preset."""

    preset: int = Field(MAX_VALUE, ge=0, le=MAX_VALUE)


def setup(ctx: Any, fam: Any, entries: dict[str, CounterConfig]) -> None:
    ctx.each(fam, entries, lambda c, _: Counter(c.preset))


class CounterModel(BlockModel):
    """The state: the fields and the last CU / CD inputs."""

    def fields(self, block: Counter, scan: Scan) -> dict[str, int]:
        return {"P": WORD, "V": WORD, "D": BIT, "E": BIT, "F": BIT, "_cu": BIT, "_cd": BIT}

    def run(self, D: Any, block: Counter, s: Mapping[str, Any], pins: Mapping[str, Any],
            scan: Scan) -> dict[str, Any]:
        return counter_rule(D, s, pins["R"], pins["S"], pins["CU"], pins["CD"])

    def invariants(self, D: Any, block: Counter, s: Mapping[str, Any],
                   scan: Scan) -> list[Any]:
        P, V = s["P"], s["V"]
        return [P >= 0, P <= MAX_VALUE, V >= 0, V <= MAX_VALUE]


MODEL = CounterModel()
