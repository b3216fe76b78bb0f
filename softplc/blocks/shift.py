"""%SBRi shift registers and %SCi step counters, every face: the runtime blocks and their
verify models (neither is configured).

One rule per family is written over a value domain (`shift_rule`, `step_rule`,
`set_bit_rule`): the verifier runs it on solver terms. The blocks keep straight-line code
for the engine's speed (the rules through the int domain took 2.2 us a run against
0.4 us); tests/integration/test_block_rules.py checks them equal, value for value.

Both take R / CU / CD, CU and CD counted on rising edges; the short-form pins feed `run`
one input at a time, holding the others at their last value (`Block`'s generated pins).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from softplc.blocks import BIT, WORD, BlockModel, Scan, rising
from softplc.runtime.blocks import Block

SBR_BITS = 16  # %SBRi.J0..J15 [manual]
SBR_MASK = (1 << SBR_BITS) - 1
SC_STEPS = 256  # %SCi.0..255 [manual]


def shift_rule(D: Any, s: Mapping[str, Any], R: Any, CU: Any, CD: Any) -> dict[str, Any]:
    """%SBRi [manual]: R clears; a rising CU shifts left (bit k -> k+1), then a rising CD
    shifts right."""
    W = s["W"]
    w1 = D.ite(rising(D, CU, s["_cu"]), (W << 1) & SBR_MASK, W)
    w2 = D.ite(rising(D, CD, s["_cd"]), D.lshr(w1, 1), w1)
    return {"W": D.ite(R, 0, w2), "_cu": D.bit(CU), "_cd": D.bit(CD)}


def step_rule(D: Any, s: Mapping[str, Any], R: Any, CU: Any, CD: Any) -> dict[str, Any]:
    """%SCi [manual]: one active step of 256 (V, its bit in W); a rising CU steps up, then
    a rising CD down (wrapping), R back to step 0. W is rewritten when the step moves or R
    holds (the program's writes to the bits stay until then)."""
    V, W = s["V"], s["W"]
    top = SC_STEPS - 1
    v1 = D.ite(rising(D, CU, s["_cu"]), (V + 1) & top, V)
    v2 = D.ite(R, 0, D.ite(rising(D, CD, s["_cd"]), (v1 - 1) & top, v1))
    moved = D.or_(R, v2 != V)
    return {"V": v2, "W": D.ite(moved, 1 << D.resize(v2, W), W), "_cu": D.bit(CU),
            "_cd": D.bit(CD)}


def set_bit_rule(D: Any, s: Mapping[str, Any], k: int, v: Any, step: bool) -> dict[str, Any]:
    """The program writes bit object k. Of a step counter (`step`): setting bit k makes k
    the current step for CU/CD, clearing it leaves the step alone (our reading: the manual
    only says the bits can be written), so several bits can be 1 until the next CU/CD/R."""
    W = s["W"]
    out = {"W": D.ite(v, W | (1 << k), W & ~(1 << k))}
    if step:
        out["V"] = D.ite(v, k, s["V"])
    return out


class _Shifting(Block):
    PINS = ("R", "CU", "CD")
    EDGE_PINS = {"CU": "_cu", "CD": "_cd"}
    W = 0

    def bit(self, k: int) -> bool:  # read as a bit: a bool, as the bit images hold
        return self.W >> k & 1 == 1


class ShiftRegister(_Shifting):
    """%SBRi 16-bit shift register (`shift_rule`, written out). Bits %SBRi.J0..J15."""

    FIELDS = ("W", "_cu", "_cd")

    def __init__(self) -> None:
        self.W, self._cu, self._cd = 0, 0, 0

    def set_bit(self, k: int, v: Any) -> None:
        self.W = (self.W | (1 << k)) if v else (self.W & ~(1 << k))

    def run(self, R: Any = 0, CU: Any = 0, CD: Any = 0) -> None:
        cu, cd = (1 if CU else 0), (1 if CD else 0)
        if R:
            self.W = 0
        else:
            if cu > self._cu:
                self.W = (self.W << 1) & SBR_MASK
            if cd > self._cd:
                self.W >>= 1
        self._cu, self._cd = cu, cd


class StepCounter(_Shifting):
    """%SCi step counter (`step_rule`, `set_bit_rule`, written out): 256 bits
    %SCi.0-255, one active."""

    FIELDS = ("V", "W", "_cu", "_cd")

    def __init__(self) -> None:
        self.V, self.W, self._cu, self._cd = 0, 1, 0, 0

    def set_bit(self, k: int, v: Any) -> None:
        if v:
            self.W |= 1 << k
            self.V = k
        else:
            self.W &= ~(1 << k)

    def run(self, R: Any = 0, CU: Any = 0, CD: Any = 0) -> None:
        cu, cd = (1 if CU else 0), (1 if CD else 0)
        v = self.V
        if R:
            v = 0
        else:
            if cu > self._cu:
                v = (v + 1) % SC_STEPS
            if cd > self._cd:
                v = (v - 1) % SC_STEPS
        if v != self.V or R:
            self.V, self.W = v, 1 << v
        self._cu, self._cd = cu, cd


class _ShiftingModel(BlockModel):
    def __init__(self, rule: Any, words: dict[str, int], step: bool):
        self.rule, self.words, self.step = rule, words, step

    def fields(self, block: Any, scan: Scan) -> dict[str, int]:
        return {**self.words, "_cu": BIT, "_cd": BIT}

    def run(self, D: Any, block: Any, s: Mapping[str, Any], pins: Mapping[str, Any],
            scan: Scan) -> dict[str, Any]:
        return self.rule(D, s, pins["R"], pins["CU"], pins["CD"])

    def bit(self, D: Any, s: Mapping[str, Any], k: int) -> Any:
        return D.lshr(s["W"], k) & 1 == 1

    def set_bit(self, D: Any, s: Mapping[str, Any], k: int, v: Any) -> dict[str, Any]:
        return set_bit_rule(D, s, k, v, self.step)

    def invariants(self, D: Any, block: Any, s: Mapping[str, Any], scan: Scan) -> list[Any]:
        return [s["V"] >= 0, s["V"] < SC_STEPS] if self.step else []


SHIFT_MODEL = _ShiftingModel(shift_rule, {"W": SBR_BITS}, step=False)
STEP_MODEL = _ShiftingModel(step_rule, {"V": WORD, "W": SC_STEPS}, step=True)
