"""The scan cycle: read inputs -> execute -> write outputs, on a clock.

One `scan()`:
  1. `before_scan` hooks (the daemon applies queued Modbus writes here)
  2. system objects: %S0/%S1/%S13/%S21 first-scan bits, %S12 (RUN), %S4-%S7 clocks,
     %SW0, %SW11
  3. latch the field inputs into the input image, apply forced values
  4. run the compiled program (a watchdog overrun or fault -> HALT, %S11)
  5. timers the program did not execute keep timing; re-assert forced values, publish the
     output image to the field
  6. simulated devices read field outputs / write field inputs
  7. scan time statistics (%SW30-%SW32), `after_scan` hooks

The code of steps 1-3 and 5-7 is generated for the configuration (runtime/scangen.py) and
regenerated when it changes: whatever sets an attribute below through `_Setting` or a
hook list, or changes the run state, calls `invalidate()`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from types import FunctionType
from typing import Any

from softplc.program import CompiledProgram
from softplc.runtime.clock import Clock
from softplc.runtime.memory import MemoryImage
from softplc.runtime.runstate import HALT, RUN, STOP, RunState
from softplc.runtime.scangen import REBUILD, HookList, build, handover, rebuilder
from softplc.runtime.scangen import S_CLOCKS as S_CLOCKS  # where verify/ and others look for them
from softplc.twido.address import Ref

S_COLD, S_WARM, S_FIRST = 0, 1, 13  # [manual; %S13 sure]
S_RUNNING = 12  # 1 in RUN, 0 in STOP/HALT [manual]; set on each change of state
S_GRAFCET_INIT = 21  # set by the system on a cold start [manual]; see runtime/grafcet.py
S_WATCHDOG, S_OVERRUN = 11, 19
SW_PERIOD, SW_WATCHDOG, SW_LAST, SW_MAX, SW_MIN = 0, 11, 30, 31, 32
# [softplc, not a Twido word] periodic mode's late and skipped scan starts (daemon), counted
# since start-up, held at 32767; the program may reset them
SW_LATE, SW_SKIPPED = 33, 34
DEFAULT_WATCHDOG_S = 0.150  # [manual]


@dataclass(slots=True)  # slots: the generated scan updates it every scan
class ScanStats:
    scans: int = 0
    last: float = 0.0  # seconds, measured wall time of the program execution
    max: float = 0.0
    min: float = 0.0
    total: float = 0.0
    overruns: int = 0
    late_starts: int = 0  # overruns of a scan that started late (see daemon)
    skipped_starts: int = 0  # scheduled starts that passed during overruns


class _Setting:
    """An engine attribute the generated scan depends on: setting it regenerates the scan.
    A dict (`devices`) is read when the scan is generated: replace it, do not change it in
    place."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = "_" + name

    def __get__(self, eng: Any, owner: type) -> Any:
        return getattr(eng, self.slot)

    def __set__(self, eng: Any, value: Any) -> None:
        setattr(eng, self.slot, value)
        eng.invalidate()


class _Hooks(_Setting):
    """A hook list attribute: kept as a `HookList`, which regenerates on each change."""

    def __set__(self, eng: Any, value: Any) -> None:
        super().__set__(eng, HookList(eng.invalidate, value))


class Engine:
    time_source = _Setting()
    clock = _Setting()
    period_us = _Setting()
    watchdog_s = _Setting()
    main = _Setting()
    devices = _Setting()
    rtc = _Setting()
    pulses = _Setting()
    forced = _Setting()
    before_scan = _Hooks()
    after_scan = _Hooks()

    def __init__(self, mem: MemoryImage, clock: Clock, period_s: float, watchdog_s: float,
                 time_source: Any = None):
        self.version = 0  # +1 on each change the generated scan depends on
        # the generated scan (a copy held by a caller after a change hands over to the new
        # one: scangen.handover)
        self.scan: Callable[[], None] = rebuilder(self)
        self.mem = mem
        self.time_source = time_source  # timers read the scan's start time from it
        self.clock = clock
        self.period_us = max(1, round(period_s * 1e6))
        self.watchdog_s = watchdog_s
        self.program: CompiledProgram | None = None
        self.main: Callable[[], Any] | None = None
        self.state: RunState = RUN
        self.fault = ""
        self.stats = ScanStats()
        self.before_scan: list[Callable[[], None]] = []
        self.after_scan: list[Callable[[], None]] = []
        self.devices: dict[str, Any] = {}
        self.cold_states: dict[tuple[str, int], dict[str, Any]] = {}  # (kind, i) -> state
        self.rtc: Any = None  # runtime.rtc.RTC when the program or the config uses it
        self.pulses: Any = None  # runtime.pulse.PulseOutputs when %PLS/%PWM are configured
        self.forced: dict[Ref, Any] = {}
        self._forced_bits: list[tuple[list[bool], int, bool]] = []
        self._forced_inputs: list[tuple[list[bool], int, bool]] = []
        self._forced_other: list[tuple[Ref, Any]] = []
        self._first = {S_COLD: True, S_FIRST: True, S_GRAFCET_INIT: True}  # to raise
        self._deadline = 0.0
        self._cpu0: float | None = None  # thread CPU time at the scan's start, when measured
        self._suspect = False  # the last scan was late on the wall clock: measure CPU time
        mem.on_copiers = self.invalidate
        mem.s[S_RUNNING] = True
        mem.sw.w[SW_PERIOD] = min(32767, round(period_s * 1000))
        mem.sw.w[SW_WATCHDOG] = min(32767, round(watchdog_s * 1000))

    # -- lifecycle ----------------------------------------------------------------------------
    def load(self, program: CompiledProgram) -> None:
        self.program = program
        self.main = program.main

    # -- the generated scan -------------------------------------------------------------------
    def invalidate(self) -> None:
        """The configuration changed: regenerate the scan before the next one runs. Safe
        from another thread: the version is bumped first, so a scan being generated
        meanwhile is dropped (see `_rebuild`)."""
        self.version += 1
        stale, self.scan = self.scan, rebuilder(self)
        if isinstance(stale, FunctionType):
            handover(stale)

    def _rebuild(self) -> None:
        """Generate the scan for the configuration as it is now, and run it (called by
        the `rebuilder` in `self.scan`, which then hands over to the new scan)."""
        caller = self.scan
        while True:
            v = self.version
            scan = build(self)[0]
            self.scan = scan
            if self.version == v:
                break
            self.scan = rebuilder(self)
            handover(scan)  # type: ignore[arg-type]
        if isinstance(caller, FunctionType) and caller.__code__ is REBUILD:
            handover(caller)
        scan()

    def _resume(self, part: int) -> Any:
        """A before_scan hook changed the configuration: the rest of this scan (0) or of
        this `begin` (1) with the new one."""
        self.scan = rebuilder(self)
        return build(self, before=False)[part]()

    def watchdog_expired(self) -> bool:
        return time.perf_counter() > self._deadline and self._overran_in_loop()

    # The watchdog is a limit on the controller's own execution time [manual]. On a shared
    # host the wall clock also counts the time the OS did not run this process, and a
    # loaded machine must not halt a healthy program, so the cheap wall-clock deadline only
    # raises a suspicion that the thread's CPU time confirms or not (thread_time costs a
    # system call, ~0.7 us here, so it is read only once a scan is suspect).
    def _overran_in_loop(self) -> bool:
        """A loop passed the wall-clock deadline: trip once the scan has used the watchdog's
        time in CPU (counted from the scan's start when measured, else from now)."""
        if self.watchdog_s == -math.inf:  # interrupt()
            return True
        cpu = time.thread_time()
        if self._cpu0 is None:
            self._cpu0 = cpu
        used = cpu - self._cpu0
        if used > self.watchdog_s:
            return True
        self._deadline = time.perf_counter() + self.watchdog_s - used
        return False

    def _overran(self, dt: float) -> None:
        """A finished scan took longer than the watchdog on the wall clock: trip when its
        CPU time confirms it; without a CPU measurement, measure the next scans."""
        if self.state == RUN:
            if self.watchdog_s == -math.inf or (
                    self._cpu0 is not None and time.thread_time() - self._cpu0 > self.watchdog_s):
                self._watchdog_trip(dt)
            else:
                self._suspect = True
                self.invalidate()
        self._cpu0 = None

    def interrupt(self) -> None:
        """End the running scan at its next watchdog check, and any later scan at once, as
        a watchdog trip (HALT): for a daemon told to stop while a program loops. Safe from
        a signal handler."""
        self.watchdog_s = -math.inf
        self._deadline = -math.inf

    def cold_start(self) -> None:
        """Reset %M, %MW, %Q, timers, counters, Grafcet; %S0 and %S13 on the next scan."""
        m = self.mem
        for buf in (m.m, m.q, m.q_field, m.x):
            buf[:] = [False] * len(buf)
        m.mw.buf[:] = bytes(len(m.mw.buf))
        for dev in self.devices.values():  # their own words, before a host's write lands
            rewrite = getattr(dev, "cold_start", None)  # (optional: Device.cold_start)
            if rewrite is not None:
                rewrite()
        for (kind, i), st in self.cold_states.items():
            m.blocks[kind][i].set_state(st)
        if self.program is not None:
            self.program.state.cold_start(m.x)
        self._first = {S_COLD: True, S_FIRST: True, S_GRAFCET_INIT: True}
        if self.rtc is not None:
            self.rtc.cold_start()
        self.state, self.fault = RUN, ""
        self.mem.s[S_WATCHDOG] = False
        self.mem.s[S_RUNNING] = True
        self.invalidate()

    def warm_start(self) -> None:
        """Keep data; %S1 and %S13 on the next scan."""
        self._first = {S_WARM: True, S_FIRST: True}
        self.state, self.fault = RUN, ""
        self.mem.s[S_WATCHDOG] = False
        self.mem.s[S_RUNNING] = True
        self.invalidate()

    def stop(self) -> None:
        """RUN -> STOP: the program no longer runs and the physical outputs take their
        fallback value 0, the %Q image kept (a Twido has no "maintain outputs in STOP"
        option for its discrete outputs [docs/twido.md "Outputs in STOP", from memory]; on START the
        image is written to the outputs again)."""
        self.state = STOP
        self.mem.s[S_RUNNING] = False
        self.mem.q_field[:] = [False] * len(self.mem.q_field)
        self.invalidate()

    def start(self) -> None:
        """STOP -> RUN (%S13 on the first scan). A HALT needs cold_start/warm_start."""
        if self.state == STOP:
            self.state = RUN
            self._first = {S_FIRST: True}
            self.mem.s[S_RUNNING] = True
            self.invalidate()

    def halt(self, reason: str) -> None:
        self.state, self.fault = HALT, reason
        self.mem.s[S_RUNNING] = False
        self.stop_outputs()
        self.invalidate()

    def stop_outputs(self) -> None:
        """Outputs to their fallback value 0, image and field."""
        self.mem.q[:] = [False] * len(self.mem.q)
        self.mem.q_field[:] = [False] * len(self.mem.q_field)

    # -- snapshots ----------------------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        """Everything a scan changes, at a scan boundary: memory and blocks, the program's
        state, the clock, first-scan flags, run state, statistics, and the devices. One
        mechanism for the debugger's `back`, its history and retained state."""
        program = self.program
        return {"mem": self.mem.snapshot(), "now_us": self.clock.now_us,
                "scan_start_us": getattr(self.time_source, "now_us", 0),
                "stats": dataclasses.replace(self.stats), "first": dict(self._first),
                "state": (self.state, self.fault),
                "program": program.state.snapshot() if program is not None else None,
                "devices": {name: dev.state() for name, dev in self.devices.items()}}

    def restore(self, snap: dict[str, Any]) -> None:
        """Back to a `snapshot()` (of this engine, with the same program and devices)."""
        self.clock.now_us = snap["now_us"]
        if self.time_source is not None:  # before the blocks: timers keep elapsed times
            self.time_source.now_us = snap["scan_start_us"]
        self.mem.restore(snap["mem"])
        self.stats = dataclasses.replace(snap["stats"])
        self._first = dict(snap["first"])
        self.state, self.fault = snap["state"]
        if self.program is not None and snap["program"] is not None:
            self.program.state.restore(snap["program"])
            self.program.state.clear_transitions()  # those of an abandoned scan
        for name, st in snap["devices"].items():
            self.devices[name].set_state(st)
        self.invalidate()  # the run state, first-scan bits, the clock bits' interval

    # -- forcing ------------------------------------------------------------------------------
    def set_forced(self, forced: dict[Ref, Any]) -> None:
        self._forced_bits, self._forced_inputs, self._forced_other = [], [], []
        for ref, v in forced.items():
            if ref.kind in ("I", "Q", "M", "S", "X") and ref.offset is None:
                entry = (self.mem.bits(ref.kind), ref.index, bool(v))
                (self._forced_inputs if ref.kind == "I" else self._forced_bits).append(entry)
            else:
                self._forced_other.append((ref, v))
        self.forced = forced  # regenerates the scan

    def _apply_forced_other(self) -> None:
        """Forced words and other non-bit objects (the generated scan stores forced bits
        itself)."""
        for ref, v in self._forced_other:
            self.mem.write(ref, v, field_inputs=False)

    # -- the scan -----------------------------------------------------------------------------
    def scan_stepwise(self, debug_main: Callable[[], Iterator[tuple[int, int]]]
                      ) -> Iterator[tuple[int, int]]:
        """One scan of a debug build, yielding (rung, instruction) before each instruction.
        The watchdog is off (a person is stepping); the scan completes when exhausted."""
        _, begin, finish = build(self)
        version = self.version
        if not begin():
            return
        if self.version != version:  # a before_scan hook changed the configuration
            finish = build(self, before=False)[2]
        self._deadline = float("inf")
        busy = 0.0  # execution time only: time stopped at a yield (a breakpoint) is not scan
        t0 = time.perf_counter()
        try:
            for pos in debug_main():
                busy += time.perf_counter() - t0
                yield pos
                t0 = time.perf_counter()
        except Exception as e:  # as scan()
            self._fault(e)
        finish(busy + time.perf_counter() - t0)

    def _fault(self, e: Exception) -> None:
        """An exception inside the program: HALT with the fault recorded, as a Twido
        halts on a system error; the daemon goes on serving Modbus."""
        if isinstance(e, RecursionError):
            self.halt("subroutine calls nested too deep (recursion)")
        else:
            self.halt(f"runtime fault: {type(e).__name__}: {e}")

    def _watchdog_trip(self, dt: float) -> None:
        self.mem.s[S_WATCHDOG] = True
        self.halt(f"watchdog: scan took {dt * 1000:.1f} ms > {self.watchdog_s * 1000:.0f} ms")

    def note_overrun(self, late: bool = False, skipped: int = 0) -> None:
        """Periodic mode: the cycle did not finish within its period (%S19) [manual]; `late`:
        because the scan started late; `skipped`: scheduled starts that passed meanwhile."""
        st = self.stats
        st.overruns += 1
        st.late_starts += late
        st.skipped_starts += skipped
        self.mem.s[S_OVERRUN] = True
        sw = self.mem.sw.w
        sw[SW_LATE] = min(32767, sw[SW_LATE] + late)
        sw[SW_SKIPPED] = min(32767, sw[SW_SKIPPED] + skipped)

