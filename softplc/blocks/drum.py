"""%DRi drum controllers, every face: the runtime block, `[drums]`, its set-up, its verify
model.

The rule (`drum_rule`) is written once over a value domain: the verifier runs it on solver
terms. `Drum` keeps straight-line code for the engine's speed (the rule through the int
domain took 7 us a run against 0.5 us, measured on the 2-core reference machine);
tests/integration/test_block_rules.py checks the two equal, value for value, outputs
included.

    drums."%DR0" = { steps = [1, 2, 4], outputs = ["%Q0.0", "%Q0.1", "%Q0.2"] }
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Annotated, Any

from pydantic import Field

from softplc.blocks import BIT, WORD, BlockModel, Scan, rising
from softplc.config.fields import DRUM_STEPS, Address, Section
from softplc.errors import AddressError, BlockError, ConfigCode, ConfigError, ConfigIssue
from softplc.runtime.blocks import Block
from softplc.twido.address import Ref, parse_address
from softplc.twido.symbols import SymbolTable

STEP_BITS = 0xFFFF  # a step: 16 control bits [m221]


def drum_rule(D: Any, steps: Sequence[int], s: Mapping[str, Any], R: Any,
              U: Any) -> dict[str, Any]:
    """%DRi [m221]: U advances on a rising edge (wrapping), R (level) goes back to step 0;
    .S the current step, .F on the last step. The step's bits go to the outputs (`s["out"]`,
    their values) only when the step differs from the one they last received (`_written`,
    -1 after a cold start or a reset), so a rung that resets a drum output holds until
    the next step change [m221: recorded simulator runs, issue 11]; while R is held the
    drum is reset at every execution and writes step 0's bits each time [issue 24: a
    user's observation, not found in a manual]."""
    n = len(steps)
    S = s["S"]
    up = rising(D, U, s["_u"])
    S2 = D.ite(R, 0, D.ite(up, D.ite(S == n - 1, 0, S + 1), S))
    changed = S2 != D.ite(R, -1, s["_written"])
    out = [D.ite(changed, D.any_([S2 == j for j, bits in enumerate(steps) if bits >> k & 1]),
                 old) for k, old in enumerate(s.get("out", ()))]
    return {"S": S2, "_written": S2, "_u": D.bit(U), "F": D.bit(S2 == n - 1), "out": out}


class Drum(Block):
    """%DRi drum controller: up to 8 steps of 16 control bits (`drum_rule`, written out
    here for the engine's speed; see the module docstring). The first
    execution after a cold start writes step 0's bits (our choice: the M221 runs start with
    the drum's outputs in step 0's state). The short-form pins (`R %DR0`, `U %DR0`) are the
    generated adapters of `Block`."""

    PINS = ("R", "U")
    FIELDS = ("S", "F", "_u")
    EDGE_PINS = {"U": "_u"}

    def __init__(self, steps: list[int], outputs: list[Any]):
        if not 1 <= len(steps) <= DRUM_STEPS:
            raise BlockError(f"a drum has 1 to {DRUM_STEPS} steps")
        self.steps = [int(s) & STEP_BITS for s in steps]
        self.outputs = outputs  # resolved (buffer, index) pairs
        self.S, self.F, self._u = 0, 0, 0
        self._written = -1  # the step whose bits the outputs last received

    def set_state(self, d: dict[str, Any]) -> None:
        """Cold start or restored state: the next execution writes the step's bits (our
        choice; the outputs were reset or restored meanwhile)."""
        super().set_state(d)
        self._written = -1

    def _apply(self) -> None:
        if self.S != self._written:
            self._written = self.S
            bits = self.steps[self.S]
            for k, (buf, idx) in enumerate(self.outputs):
                buf[idx] = bits >> k & 1 == 1  # a bit image: bools
        self.F = 1 if self.S == len(self.steps) - 1 else 0

    def run(self, R: Any = 0, U: Any = 0) -> None:
        u = 1 if U else 0
        if R:
            self.S = 0
            self._written = -1  # a reset writes step 0's bits, at every scan it is held
        elif u and not self._u:
            self.S = (self.S + 1) % len(self.steps)
        self._u = u
        self._apply()


class DrumConfig(Section):
    """`[drums]`: the steps (16 bits each) and the output bits, addresses or symbols."""

    steps: list[Annotated[int, Field(ge=0, le=STEP_BITS)]] = Field(
        default_factory=lambda: [0], min_length=1, max_length=DRUM_STEPS)
    outputs: list[Address] = Field(default_factory=list)


def drum_outputs(d: DrumConfig, where: str, profile: Any,
                 symbols: SymbolTable | None) -> list[Ref]:
    """The output bits of a `[drums]` entry `d` (at key path `where`), each an address or a
    symbol of `symbols`: %Q or %M bits. The block set-up and the verifier read them here."""
    outs, issues = [], []
    for k, a in enumerate(d.outputs):
        try:
            r = symbols.ref(a) if symbols is not None else parse_address(a, profile)
        except AddressError as e:
            issues.append(ConfigIssue(f"{where}.outputs[{k}]", str(e), ConfigCode.ADDRESS))
            continue
        if r.type != "bool" or r.kind not in ("Q", "M") or r.length:
            issues.append(ConfigIssue(f"{where}.outputs[{k}]", f"%Q or %M bits, not {a!r}",
                                      ConfigCode.ADDRESS))
        outs.append(r)
    if issues:
        raise ConfigError(issues)
    return outs


def setup(ctx: Any, fam: Any, entries: dict[str, DrumConfig]) -> None:
    def make(d: DrumConfig, text: str) -> Drum:
        outs = drum_outputs(d, ctx.where(fam.section, text), ctx.profile, ctx.symbols)
        for r in outs:
            ctx.mem.use_io(r)
        return Drum(d.steps, [(ctx.mem.bits(r.kind), r.index) for r in outs])
    ctx.each(fam, entries, make)


class DrumModel(BlockModel):
    """The state: S, F, the last U and `_written` (the step its outputs hold)."""

    def fields(self, block: Drum, scan: Scan) -> dict[str, int]:
        return {"S": WORD, "F": BIT, "_u": BIT, "_written": WORD}

    def run(self, D: Any, block: Drum, s: Mapping[str, Any], pins: Mapping[str, Any],
            scan: Scan) -> dict[str, Any]:
        return drum_rule(D, block.steps, s, pins["R"], pins["U"])

    def invariants(self, D: Any, block: Drum, s: Mapping[str, Any], scan: Scan) -> list[Any]:
        n = len(block.steps)
        return [s["S"] >= 0, s["S"] < n, s["_written"] >= -1, s["_written"] < n]

    def outputs(self, block: Drum, plc: Any) -> list[Ref]:
        """The configured output bits of `block` (found by its number in `[drums]`)."""
        for text, d in plc.settings.drums.items():  # checked when the PLC was built
            ref = parse_address(text, plc.profile)
            if plc.mem.blocks[ref.kind].get(ref.index) is block:
                return drum_outputs(d, text, plc.profile, plc.symbols)
        return []


MODEL = DrumModel()
