"""System bits and words as the model sees them, from a cold start in RUN (the system
objects of docs/twido.md#system-bits-and-words, in the engine's scan order:
runtime/engine.py, runtime/rtc.py, runtime/analog.py).

Definite (modelled exactly):
- %S0 %S13 %S21: 1 in the first scan, then 0 (`FIRST_SCAN_BITS`); %S1 0 (a cold start,
  never a warm restart); %S11 0 (a watchdog trip halts the controller: no scan follows);
  %S12 1 (RUN); %S4-%S7 the clocks of the model's time; %S17 %S18 %S20 from the
  instructions; %S22 %S23 %S50 and every bit the system does not write: as the program
  leaves them;
- every %SW the system does not rewrite while running keeps its cold-start value from the
  loaded configuration (%SW0 the scan period, %SW11 the watchdog, %SW114 the schedule
  enables...) unless the program writes it.

Free (the system sets them from what the model does not know: wall time, the calendar,
analog signals): any value at the start of every scan, stated as such by `softplc verify`
and set so by the replay: %S19 (a scan overrun), %SW30-%SW32 (scan times, rewritten after
the program, which may not write them), %SW0 with a variable scan period; with a real-time
clock %S51, %SW49-%SW53 and the outputs of its schedule blocks; with analog modules their
status words %SW80+slot; with the Remote Link its status and error words %SW111-%SW112
(the link words %INW are free inputs, verify/objects.py).
"""

from __future__ import annotations

from typing import Any

from softplc.runtime.analog import SW_ANALOG_STATUS
from softplc.runtime.engine import SW_LAST, SW_MAX, SW_MIN, SW_PERIOD
from softplc.runtime.remotelink import SW_LINK_ERROR, SW_LINK_STATUS
from softplc.runtime.rtc import S_RTC_UNSET, SW_CCYY, SW_DOW
from softplc.twido.address import Ref

FIRST_SCAN_BITS = (0, 13, 21)  # %S0 cold start, %S13 first scan, %S21 Grafcet init
FIXED_BITS = {1: 0, 11: 0, 12: 1}  # warm restart, watchdog trip: 0; %S12 RUN: 1
S_OVERRUN = 19
# words the engine rewrites after the program every scan: the program must not write them
AFTER_PROGRAM = frozenset(f"%SW{k}" for k in (SW_LAST, SW_MAX, SW_MIN))


def free_objects(plc: Any, variable_period: bool) -> dict[str, str]:
    """The system objects the model leaves free, for `plc`: key -> why (for the output)."""
    out = {"%S19": "set by a scan overrun (wall time)"}
    for k in AFTER_PROGRAM:
        out[k] = "a scan time (wall time)"
    if variable_period:
        out[f"%SW{SW_PERIOD}"] = "the scan period, any in the range"
    rtc = plc.engine.rtc
    if rtc is not None:
        out[f"%S{S_RTC_UNSET}"] = "cleared by the real-time clock"
        for k in range(SW_DOW, SW_CCYY + 1):
            out[f"%SW{k}"] = "the real-time clock"
        for sch in rtc.schedules:
            out[str(sch.output)] = "written by a real-time clock schedule block"
    if plc.machine.link is not None:  # the link runs on its own cycle
        out[f"%SW{SW_LINK_STATUS}"] = "the Remote Link's stations present"
        out[f"%SW{SW_LINK_ERROR}"] = "the Remote Link's error code"
    analog = plc.mem.analog
    for ref in analog.channels if analog else ():
        if ref.kind == "IW" and ref.module:
            out[f"%SW{SW_ANALOG_STATUS + ref.module}"] = "an analog module's channel status"
    return out


def cold_value(plc: Any, key: str) -> int:
    """A system word's or bit's value after a cold start, in RUN."""
    if key.startswith("%SW"):
        return int(plc.mem.sw.w[int(key[3:])])
    return FIXED_BITS.get(int(key[2:]), 0)


def is_system(ref: Ref) -> bool:
    return ref.kind in ("S", "SW")
