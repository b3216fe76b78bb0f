"""What the scan generator (scangen.py) reads and calls on the engine it writes a scan for.

A `Protocol`, so that scangen.py sits below engine.py (the engine imports the generator,
never the reverse). `Engine` satisfies it; the underscored members are the engine's own
state that the generated scan reads and updates.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from softplc.program import CompiledProgram
from softplc.runtime.blocks import TimeSource
from softplc.runtime.clock import Clock
from softplc.runtime.memory import MemoryImage
from softplc.runtime.pulse import PulseOutputs
from softplc.runtime.rtc import RTC
from softplc.runtime.runstate import RunState
from softplc.twido.address import Ref


class ScanCounters(Protocol):
    """The scan statistics the generated scan updates (engine.ScanStats)."""

    scans: int
    last: float
    max: float
    min: float
    total: float


class ScanHost(Protocol):
    """The engine as the scan generator sees it."""

    # the configuration a generated scan is written for (a change calls invalidate())
    mem: MemoryImage
    clock: Clock
    period_us: int
    watchdog_s: float
    version: int
    program: CompiledProgram | None
    main: Callable[[], Any] | None
    state: RunState
    time_source: TimeSource | None  # the scan's start time, for the timers
    rtc: RTC | None
    pulses: PulseOutputs | None  # %PLS/%PWM, when configured
    devices: dict[str, Any]
    forced: dict[Ref, Any]
    before_scan: list[Callable[[], None]]
    after_scan: list[Callable[[], None]]
    scan: Callable[[], None]
    # the engine's scan state, read and set by the generated code
    _forced_bits: list[tuple[list[bool], int, bool]]
    _forced_inputs: list[tuple[list[bool], int, bool]]
    _forced_other: list[tuple[Ref, Any]]
    _first: dict[int, int]
    _deadline: float
    _cpu0: float | None
    _suspect: bool

    @property
    def stats(self) -> ScanCounters: ...  # read-only here: the engine's own ScanStats

    def invalidate(self) -> None: ...

    def _resume(self, part: int) -> Any: ...

    def _apply_forced_other(self) -> None: ...

    def _fault(self, e: Exception) -> None: ...

    def _watchdog_trip(self, dt: float) -> None: ...

    def _overran(self, dt: float) -> None: ...
