"""The basic Twido function blocks, one module per family with all its faces: %TM timers
(`timer.py`), %C counters (`counter.py`), %DR drums (`drum.py`), %R FIFO/LIFO registers
(`register.py`), %SBR shift registers and %SC step counters (`shift.py`).

Each module holds the family's runtime class (a `runtime.blocks.Block`), its configuration
model (the catalog's `model`, a strict table as `config.fields.Section`), its set-up hook
(the catalog's `setup`, called with an `assembly.blocks.BlockSetup`) and its model for
`softplc verify` (the catalog's `verify`, a `BlockModel`): the block's rule written once
over a value domain `D`, as `twido.semantics.arith` is (`semantics.IntDomain`: Python ints
and bools; `verify.symbolic.Z3State`: solver terms in the state's own sorts). The runtime
classes keep straight-line code for the engine's speed (through the int domain a block's
run took 5 to 14 times as long: a drum 7 us against 0.5 us), as `semantics.Ops` does
for arithmetic; tests/integration/test_block_rules.py checks each class against its rule,
value for value, and the solver's reading of each rule against its reading on ints.

The package sits in the layers above the configuration (its models are `Section`s with the
configuration's field types) and below the machine builder, which calls the set-up hooks;
the runtime reaches the classes through the catalog's "module:attribute" strings only.
See docs/decisions/one-module-per-block.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

BIT = 0  # the width of a state field that is a bit (a bool; a Boolean term in verify)
WORD = 16  # a 16-bit word field


@dataclass(frozen=True)
class Scan:
    """What a block's verify model knows of the scan: the shortest and longest period in
    microseconds and, when the period varies, the term `dt` (this scan lasts `dt` times
    the shortest period)."""

    period_us: int
    longest_us: int
    dt: Any = None


class BlockModel:
    """A family's face for `softplc verify`: its state (field -> width) and one execution
    of a block as new field values, written over a value domain `D`. `s` maps each state
    field to its value (a drum's also maps "out" to the values of its output bits); the
    verifier guards what `run` returns by where the block runs."""

    def fields(self, block: Any, scan: Scan) -> dict[str, int]:
        """The block's state in the model: field -> BIT or a width in bits."""
        raise NotImplementedError

    def init(self, block: Any, field: str) -> int:
        """A field's value after a cold start (as the engine's block holds it)."""
        return int(getattr(block, field))

    def run(self, D: Any, block: Any, s: Mapping[str, Any], pins: Mapping[str, Any],
            scan: Scan) -> dict[str, Any]:
        """The fields one execution with inputs `pins` changes."""
        raise NotImplementedError

    def held(self, s: Mapping[str, Any]) -> dict[str, Any] | None:
        """The inputs a block the program did not execute runs with at the end of the scan
        (a timer keeps timing), None: it does not run."""
        return None

    def after_scan(self, D: Any, block: Any, s: Mapping[str, Any],
                   scan: Scan) -> dict[str, Any]:
        """What changes between two scans (a timer's elapsed time)."""
        return {}

    def invariants(self, D: Any, block: Any, s: Mapping[str, Any], scan: Scan) -> list[Any]:
        """Facts true in every reachable state by construction (value ranges)."""
        return []

    def outputs(self, block: Any, plc: Any) -> list[Any]:
        """The bit objects (Refs) an execution writes besides the block's own fields."""
        return []

    def bit(self, D: Any, s: Mapping[str, Any], k: int) -> Any:
        """Bit object k (%SBRi.Jk, %SCi.k) of a block with bit objects."""
        raise NotImplementedError

    def set_bit(self, D: Any, s: Mapping[str, Any], k: int, v: Any) -> dict[str, Any]:
        """The fields a program's write of bit object k changes."""
        raise NotImplementedError


def rising(D: Any, pin: Any, last: Any) -> Any:
    """A rising edge: the input is 1 and was 0 at the block's last execution."""
    return D.and_(pin, D.not_(last))



# The configuration first: its `Config` types each block section by the model in the
# family's module (named by the catalog), and those models are built on its field types
# (`config.fields`). A family module imported first would be asked for its model while
# half-built; importing the configuration here, once this package's names exist, makes
# `softplc.config` resolve the family modules, whoever is imported first.
import softplc.config  # noqa: E402, F401
