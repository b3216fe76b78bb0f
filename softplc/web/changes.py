"""The web API's queue of changes for the scan boundary: one bounded queue, two lanes.

Data changes (inputs and other objects the Modbus queue does not take, forcing, analog
values) wait in order, at most MAX_PENDING: past it a change is refused with 503, so a
script writing faster than the scans take its changes is told at once instead of queuing
hours of them. RUN/STOP/restart and unforce go in a short lane applied first at the next
boundary (and "call": a function run there, the online program change's swap): they
never wait behind data changes (an unforce drops the forcing of its objects
still queued: it came after them). The scan thread applies both (`apply`, a before_scan
hook); an input is changed at most once per scan, so a press and its release queued in the
same period are seen in two scans.

Forcing a new object and unforcing recompile the program (`PLC.force`: stores to forced
bits are compiled out), 2-14 ms each for this project's programs, in the scan thread: at
most RECOMPILES_PER_SCAN of them are applied at one boundary (the rest wait for the next
scans, in order), and an unforce of nothing forced is skipped, so a burst of them cannot
stall the scan for seconds. RUN/STOP/restart are never held back.
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Any

from ..errors import SoftPLCError
from .errors import ApiError

MAX_PENDING = 256  # data changes (writes, forcing) queued at once; past it: 503
MAX_URGENT = 64  # RUN/STOP/restart and unforce queued at once
URGENT = ("control", "unforce", "call")
RECOMPILES_PER_SCAN = 2  # new forcings and unforcings applied at one scan boundary

Change = tuple[str, Any, Any]  # (operation, object or action, value)


class ChangeQueue:
    def __init__(self, plc: Any):
        self.plc = plc
        self._data: deque[Change] = deque()
        self._urgent: deque[Change] = deque()
        self._lock = threading.Lock()  # the scan thread pops while `put` filters
        self.applied = 0  # changes applied since start

    def __len__(self) -> int:
        return len(self._data) + len(self._urgent)

    def room(self, n: int, urgent: bool = False) -> None:
        """Refuse (503) `n` more changes the queue has no room for: nothing is queued."""
        q, cap = (self._urgent, MAX_URGENT) if urgent else (self._data, MAX_PENDING)
        if n > cap:
            raise ApiError(f"{n} changes in one request: at most {cap}")
        if len(q) + n > cap:
            what = "control commands" if urgent else "changes"
            raise ApiError(f"{len(q)} {what} are waiting for the next scans already (at most "
                           f"{cap}): try again later", 503)

    def put(self, changes: list[Change]) -> None:
        """Queue `changes` (all of one lane), all or none."""
        if not changes:
            return
        urgent = changes[0][0] in URGENT
        self.room(len(changes), urgent)
        with self._lock:
            for op, refs, _ in changes:
                if op == "unforce":
                    self._drop_forcing(None if refs is None else {str(r) for r in refs})
            (self._urgent if urgent else self._data).extend(changes)

    def _drop_forcing(self, names: set[str] | None) -> None:
        kept = [c for c in self._data
                if not (c[0] == "force" and (names is None or str(c[1]) in names))]
        if len(kept) != len(self._data):
            self._data.clear()
            self._data.extend(kept)

    def apply(self) -> None:
        """before_scan hook (scan thread): the urgent lane, then the data in order."""
        if not (self._urgent or self._data):
            return
        with self._lock:
            budget = RECOMPILES_PER_SCAN
            held: list[Change] = []  # unforcings past the budget, for the next scan
            urgent, q = self._urgent, self._data
            while urgent:
                change = urgent.popleft()
                cost = self._recompiles(change)
                if cost and budget <= 0:
                    held.append(change)
                    continue
                budget -= cost
                self._apply_one(*change)
            urgent.extend(held)
            inputs: set[int] = set()
            while q:
                op, ref, value = q[0]
                if op == "write" and ref.kind == "I":
                    if ref.index in inputs:
                        break  # the second change of this input waits for the next scan
                    inputs.add(ref.index)
                cost = self._recompiles(q[0])
                if cost and budget <= 0:
                    break  # the program was recompiled enough for one scan boundary
                budget -= cost
                q.popleft()
                self._apply_one(op, ref, value)

    def _recompiles(self, change: Change) -> int:
        """How many times applying `change` recompiles the program."""
        op, ref, _ = change
        if op == "force":
            return int(str(ref) not in self.plc.forced)
        if op == "unforce":
            forced = self.plc.forced
            return int(bool(forced)) if ref is None else sum(str(r) in forced for r in ref)
        return 0

    def _apply_one(self, op: str, ref: Any, value: Any) -> None:
        plc = self.plc
        try:
            if op == "write":
                plc.mem.write(ref, value)
            elif op == "analog":
                plc.mem.analog.set_input(ref, value)
            elif op == "force":
                plc.force(str(ref), value)
            elif op == "unforce":  # only what is forced: each call recompiles
                forced = plc.forced
                if ref is None and forced:
                    plc.unforce(None)
                for r in ref or ():
                    if str(r) in forced:
                        plc.unforce(str(r))
            elif op == "call":  # handles its own errors (online program change)
                ref()
            elif ref == "run":
                plc.start()
            elif ref == "stop":
                plc.stop()
            elif ref == "cold":
                plc.cold_start()
            elif ref == "warm":
                plc.warm_start()
        except SoftPLCError:  # checked when queued; a block removed since and the like
            pass
        self.applied += 1


__all__ = ["MAX_PENDING", "MAX_URGENT", "ChangeQueue"]
