"""The controller's run state (its own module: the engine and the scan code generator
both use it)."""

from __future__ import annotations

from enum import StrEnum


class RunState(StrEnum):
    """The controller's run state. A str enum: equal to its name ("RUN" == RunState.RUN),
    so JSON answers and saved snapshots keep the plain strings."""

    RUN = "RUN"
    STOP = "STOP"
    HALT = "HALT"  # a fault (watchdog, program error) stopped the scan


RUN, STOP, HALT = RunState.RUN, RunState.STOP, RunState.HALT

# %S9 = 1: the physical outputs at their fallback value 0 while the program runs on (the
# engine's STOP rule, in RUN) [docs/twido.md "Outputs in STOP"; from memory, as the M221's]
S_FALLBACK = 9

__all__ = ["HALT", "RUN", "S_FALLBACK", "STOP", "RunState"]
