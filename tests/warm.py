"""A machine brought once per test process to a state many tests start from (homed, say),
then handed to each of them as a new PLC restored to that state with the engine's
snapshots (`Engine.snapshot`/`restore`, the debugger's `back`): the homing's thousands of
scans are paid once, not once per test. Each test gets its own PLC and its own copy of the
snapshot, so what one test does never reaches another; that a restored machine runs on
exactly as one brought there by its own scans is checked in each module that uses it
(`simulated` equal after the same work).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Hashable
from typing import Any

from softplc.devices.axis.servo import ServoAxis
from softplc.plc import PLC
from softplc.runtime.engine import SW_LAST, SW_MIN

_SNAPSHOTS: dict[Hashable, dict[str, Any]] = {}


def warm(key: Hashable, build: Callable[[], PLC], prepare: Callable[[PLC], None]) -> PLC:
    """A new `build()` in the state `prepare` brings such a machine to (`prepare` runs on
    the first call for `key` only; its asserts are the state's checks)."""
    snap = _SNAPSHOTS.get(key)
    if snap is None:
        first = build()
        prepare(first)
        snap = _SNAPSHOTS[key] = copy.deepcopy(first.engine.snapshot())
        first.close()
    plc = build()
    plc.engine.restore(copy.deepcopy(snap))  # (records included: this test's own lists)
    return plc


def simulated(plc: PLC) -> tuple[Any, ...]:
    """The engine's snapshot but for what measures the host's wall time (the scan time
    words %SW30-%SW32, the statistics) and the servo axes' trace row counts (a snapshot
    does not carry their rows, ServoAxis.state: a restored axis's trace starts empty;
    compare the rows since with `servo_rows`): equal for two machines that ran the same."""
    snap = plc.engine.snapshot()
    mem = dict(snap["mem"])
    sw = bytearray(mem["sw"])
    sw[2 * SW_LAST:2 * (SW_MIN + 1)] = bytes(2 * (SW_MIN + 1 - SW_LAST))
    mem["sw"] = bytes(sw)
    devices = {name: {k: v for k, v in st.items() if not (k == "trace" and isinstance(v, int))}
               for name, st in snap["devices"].items()}
    return mem, devices, snap["program"], snap["now_us"], snap["state"]


def servo_rows(plc: PLC, since: int) -> dict[str, list[Any]]:
    """Each servo axis's trace rows after its servo cycle `since`."""
    return {name: [row for row in dev.trace if row[0] > since]
            for name, dev in plc.devices.items() if isinstance(dev, ServoAxis)}
