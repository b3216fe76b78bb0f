"""The access port's command records and its one bounded queue, applied at the scan
boundary.

Every change a host front-end asks for is a record: `Write`, `Analog`, `Force` (data) and
`Unforce`, `Control`, `Call` (urgent). One queue, two lanes: data changes wait in order,
at most MAX_PENDING: past it a change is refused with `AccessError` (503), so a script
writing faster than the scans take its changes is told at once instead of queuing hours of
them, and what was accepted is never dropped. RUN/STOP/restart, unforce and "call" (a
function run at the boundary: the online program change's swap) go in a short lane applied
first at the next boundary: they never wait behind data changes (an unforce drops the
forcing of its objects still queued: it came after them). The scan thread applies both
(`apply`, a before_scan hook); an input is changed at most once per scan, so a press and
its release queued in the same period are seen in two scans.

Forcing a new object and unforcing recompile the program (`PLC.force`: stores to forced
bits are compiled out), 2-14 ms each for this project's programs, in the scan thread: at
most RECOMPILES_PER_SCAN of them are applied at one boundary (the rest wait for the next
scans, in order), and an unforce of nothing forced is skipped, so a burst of them cannot
stall the scan for seconds. RUN/STOP/restart are never held back.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from softplc.access.errors import AccessError
from softplc.errors import SoftPLCError
from softplc.twido.address import Ref

MAX_PENDING = 256  # data changes (writes, forcing) queued at once; past it: 503
MAX_URGENT = 64  # RUN/STOP/restart and unforce queued at once
RECOMPILES_PER_SCAN = 2  # new forcings and unforcings applied at one scan boundary


class Action(StrEnum):
    """The control commands: RUN, STOP, cold and warm restart."""

    RUN = "run"
    STOP = "stop"
    COLD = "cold"
    WARM = "warm"


ACTIONS = tuple(a.value for a in Action)


@dataclass(frozen=True, slots=True)
class Write:
    """A value for an object (an input: its field value), applied at the boundary."""

    ref: Ref
    value: int | float


@dataclass(frozen=True, slots=True)
class Analog:
    """A physical value (V, mA, degrees C) for an analog input, as a device drives it."""

    ref: Ref
    value: float


@dataclass(frozen=True, slots=True)
class Force:
    ref: Ref
    value: int | float


@dataclass(frozen=True, slots=True)
class Unforce:
    """Release `refs` (None: everything forced)."""

    refs: tuple[Ref, ...] | None


@dataclass(frozen=True, slots=True)
class Control:
    action: Action


@dataclass(frozen=True, slots=True)
class Call:
    """A function run in the scan thread at the boundary; it handles its own errors."""

    fn: Callable[[], None]


Command = Write | Analog | Force | Unforce | Control | Call
URGENT = (Control, Unforce, Call)


class CommandQueue:
    def __init__(self, plc: Any):
        self.plc = plc
        self._data: deque[Command] = deque()
        self._urgent: deque[Command] = deque()
        self._lock = threading.Lock()  # the scan thread pops while `put` filters
        self.applied = 0  # commands applied since start

    def __len__(self) -> int:
        return len(self._data) + len(self._urgent)

    def room(self, n: int, urgent: bool = False) -> None:
        """Refuse (503) `n` more commands the queue has no room for: nothing is queued."""
        q, cap = (self._urgent, MAX_URGENT) if urgent else (self._data, MAX_PENDING)
        if n > cap:
            raise AccessError(f"{n} changes in one request: at most {cap}")
        if len(q) + n > cap:
            what = "control commands" if urgent else "changes"
            raise AccessError(f"{len(q)} {what} are waiting for the next scans already (at "
                              f"most {cap}): try again later", 503)

    def put(self, commands: list[Command]) -> None:
        """Queue `commands` (all of one lane), all or none."""
        if not commands:
            return
        urgent = isinstance(commands[0], URGENT)
        if any(isinstance(c, URGENT) != urgent for c in commands):
            raise ValueError("one put: commands of one lane")  # a caller's bug
        self.room(len(commands), urgent)
        with self._lock:
            for c in commands:
                if isinstance(c, Unforce):
                    self._drop_forcing(None if c.refs is None else {str(r) for r in c.refs})
            (self._urgent if urgent else self._data).extend(commands)

    def _drop_forcing(self, names: set[str] | None) -> None:
        kept = [c for c in self._data
                if not (isinstance(c, Force) and (names is None or str(c.ref) in names))]
        if len(kept) != len(self._data):
            self._data.clear()
            self._data.extend(kept)

    def apply(self) -> None:
        """before_scan hook (scan thread): the urgent lane, then the data in order."""
        if not (self._urgent or self._data):
            return
        with self._lock:
            budget = RECOMPILES_PER_SCAN
            held: list[Command] = []  # unforcings past the budget, for the next scan
            urgent, q = self._urgent, self._data
            while urgent:
                command = urgent.popleft()
                cost = self._recompiles(command)
                if cost and budget <= 0:
                    held.append(command)
                    continue
                budget -= cost
                self._apply_one(command)
            urgent.extend(held)
            inputs: set[int] = set()
            while q:
                command = q[0]
                if isinstance(command, Write) and command.ref.kind == "I":
                    if command.ref.index in inputs:
                        break  # the second change of this input waits for the next scan
                    inputs.add(command.ref.index)
                cost = self._recompiles(command)
                if cost and budget <= 0:
                    break  # the program was recompiled enough for one scan boundary
                budget -= cost
                q.popleft()
                self._apply_one(command)

    def _recompiles(self, command: Command) -> int:
        """How many times applying `command` recompiles the program."""
        forced = self.plc.forced
        if isinstance(command, Force):
            return int(str(command.ref) not in forced)
        if isinstance(command, Unforce):
            if command.refs is None:
                return int(bool(forced))
            return sum(str(r) in forced for r in command.refs)
        return 0

    def _apply_one(self, c: Command) -> None:
        plc = self.plc
        try:
            if isinstance(c, Write):
                plc.mem.write(c.ref, c.value)
            elif isinstance(c, Analog):
                plc.mem.analog.set_input(c.ref, c.value)
            elif isinstance(c, Force):
                plc.force(str(c.ref), c.value)
            elif isinstance(c, Unforce):  # only what is forced: each call recompiles
                forced = plc.forced
                if c.refs is None and forced:
                    plc.unforce(None)
                for r in c.refs or ():
                    if str(r) in forced:
                        plc.unforce(str(r))
            elif isinstance(c, Call):
                c.fn()
            else:
                _CONTROL[c.action](plc)
        except SoftPLCError:  # checked when queued; a block removed since and the like
            pass
        self.applied += 1


_CONTROL: dict[Action, Callable[[Any], None]] = {
    Action.RUN: lambda plc: plc.start(), Action.STOP: lambda plc: plc.stop(),
    Action.COLD: lambda plc: plc.cold_start(), Action.WARM: lambda plc: plc.warm_start()}

__all__ = ["ACTIONS", "MAX_PENDING", "MAX_URGENT", "URGENT", "Action", "Analog", "Call",
           "Command", "CommandQueue", "Control", "Force", "Unforce", "Write"]
