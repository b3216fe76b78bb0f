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

__all__ = ["HALT", "RUN", "STOP", "RunState"]
