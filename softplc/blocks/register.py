"""%Ri FIFO / LIFO registers, every face: the runtime block, `[registers]`, its set-up, its
verify model.

    registers."%R0" = { type = "FIFO" }

The rule (`register_rule`) is written once over a value domain, on the register's words as
slots `_d0`.. and a count `_n`: the verifier runs it on solver terms. `Register` keeps its
words in a list (`_data`, oldest first: the state file's form, and one append or pop per
edge); tests/integration/test_block_rules.py checks it against the rule, value for value.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

from softplc.blocks import BIT, WORD, BlockModel, Scan, rising
from softplc.config.fields import Section
from softplc.errors import BlockError
from softplc.runtime.blocks import Block

TYPES = ("FIFO", "LIFO")


def slots(depth: int) -> list[str]:
    """The state fields of a register's stored words, oldest first."""
    return [f"_d{j}" for j in range(depth)]


def register_rule(D: Any, lifo: bool, depth: int, s: Mapping[str, Any], R: Any, I: Any,
                  O: Any) -> dict[str, Any]:
    """%Ri [manual]: a rising I stores .I unless full, then a rising O retrieves the
    oldest (FIFO) or newest (LIFO) word into .O unless empty; R empties; .E empty, .F
    full. Slots past the count `_n` are never read."""
    d = [s[k] for k in slots(depth)]
    n = s["_n"]
    push = D.and_(D.and_(D.not_(R), rising(D, I, s["_i"])), n < depth)
    d = [D.ite(D.and_(push, n == j), s["I"], d[j]) for j in range(depth)]
    n = D.ite(push, n + 1, n)
    pop = D.and_(D.and_(D.not_(R), rising(D, O, s["_o"])), n != 0)
    if lifo:
        top = d[0]
        for j in range(1, depth):
            top = D.ite(n == j + 1, d[j], top)
    else:
        top = d[0]
        d = [D.ite(pop, d[j + 1], d[j]) for j in range(depth - 1)] + [d[-1]]
    n = D.ite(R, 0, D.ite(pop, n - 1, n))
    return {"O": D.ite(pop, top, s["O"]), "_n": n, **dict(zip(slots(depth), d, strict=False)),
            "_i": D.bit(I), "_o": D.bit(O), "E": D.bit(n == 0), "F": D.bit(n >= depth)}


class Register(Block):
    """%Ri FIFO or LIFO of `depth` words (`register_rule`; the profile's FIFO_DEPTH, 16 on
    Twido [manual])."""

    PINS = ("R", "I", "O")
    FIELDS = ("I", "O", "E", "F", "_i", "_o", "_data")
    EDGE_PINS = {"I": "_i", "O": "_o"}

    def __init__(self, type: str = "FIFO", depth: int = 16):
        type = type.upper()
        if type not in TYPES:
            raise BlockError(f"register type {type!r}: FIFO or LIFO")
        self.type, self.depth = type, depth
        self.I = self.O = 0
        self.E, self.F = 1, 0
        self._i = self._o = 0
        self._data: list[int] = []

    def state(self) -> dict[str, Any]:
        d = super().state()
        d["_data"] = list(self._data)
        return d

    def run(self, R: Any = 0, I: Any = 0, O: Any = 0) -> None:
        i, o = (1 if I else 0), (1 if O else 0)
        if R:
            self._data.clear()
        else:
            if i > self._i and len(self._data) < self.depth:
                self._data.append(self.I)
            if o > self._o and self._data:
                self.O = self._data.pop(0 if self.type == "FIFO" else -1)
        self._i, self._o = i, o
        self.E = 0 if self._data else 1
        self.F = 1 if len(self._data) >= self.depth else 0


class RegisterConfig(Section):
    """`[registers]`: one entry per register, FIFO or LIFO."""

    type: Literal["FIFO", "LIFO"] = "FIFO"


def setup(ctx: Any, fam: Any, entries: dict[str, RegisterConfig]) -> None:
    ctx.each(fam, entries, lambda g, _: Register(g.type, ctx.profile.count("FIFO_DEPTH")))


def default(profile: Any) -> Register:
    """A register the configuration does not name: FIFO, the profile's depth."""
    return Register("FIFO", profile.count("FIFO_DEPTH"))


class RegisterModel(BlockModel):
    """The state: the fields, the last I / O inputs, the count `_n` and the slots."""

    def fields(self, block: Register, scan: Scan) -> dict[str, int]:
        return {"I": WORD, "O": WORD, "E": BIT, "F": BIT, "_i": BIT, "_o": BIT, "_n": WORD,
                **dict.fromkeys(slots(block.depth), WORD)}

    def init(self, block: Register, field: str) -> int:
        if field == "_n":
            return len(block._data)
        if field.startswith("_d"):
            return (block._data + [0] * block.depth)[int(field[2:])]
        return int(getattr(block, field))

    def run(self, D: Any, block: Register, s: Mapping[str, Any], pins: Mapping[str, Any],
            scan: Scan) -> dict[str, Any]:
        return register_rule(D, block.type == "LIFO", block.depth, s, pins["R"], pins["I"],
                             pins["O"])

    def invariants(self, D: Any, block: Register, s: Mapping[str, Any],
                   scan: Scan) -> list[Any]:
        return [s["_n"] >= 0, s["_n"] <= block.depth]


MODEL = RegisterModel()
