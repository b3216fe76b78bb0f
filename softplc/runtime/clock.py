"""Clocks. Time is kept in integer microseconds so virtual runs are exactly repeatable.

The engine calls `start_scan(period_us)` at the start of a scan (it returns the scan's
start time, which timers use) and `end_scan(period_us)` after it.
"""

from __future__ import annotations

import time


class Clock:
    virtual = True
    now_us: int = 0

    def start_scan(self, period_us: int) -> int:
        return self.now_us

    def end_scan(self, period_us: int) -> None:
        pass

    @property
    def seconds(self) -> float:
        return self.now_us / 1e6


class VirtualClock(Clock):
    """Each scan lasts exactly one period: fully deterministic."""

    def __init__(self, start_us: int = 0):
        self.now_us = start_us

    def end_scan(self, period_us: int) -> None:
        self.now_us += period_us


class RealClock(Clock):
    """Monotonic wall time since the clock was made."""

    virtual = False

    def __init__(self) -> None:
        self._t0 = time.perf_counter_ns()

    def start_scan(self, period_us: int) -> int:
        self.now_us = (time.perf_counter_ns() - self._t0) // 1000
        return self.now_us

    @property
    def seconds(self) -> float:
        return (time.perf_counter_ns() - self._t0) / 1e9


def make_clock(kind: str | Clock) -> Clock:
    if isinstance(kind, Clock):
        return kind
    if kind == "virtual":
        return VirtualClock()
    if kind == "real":
        return RealClock()
    raise ValueError(f"clock {kind!r}: 'virtual' or 'real'")
