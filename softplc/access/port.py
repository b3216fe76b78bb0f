"""The host access port: the one way host front-ends (the web monitor, `softplc io`
through it, the debugger's data commands) read and change a running controller.

Threads: the scan runs in one thread, a front-end in another (the web monitor in the
daemon's asyncio loop). They meet only at scan boundaries:

- every change (write, force, unforce, RUN/STOP/restart) is checked here, then queued as a
  command record and applied by a `before_scan` hook, after the Modbus writes queued
  before it. %MW/%MD/%MF and %M writes go into the Modbus image's pending image itself
  (`ModbusImage.queue_value`, which coalesces them), so a Modbus host reads back what a
  page wrote exactly as it reads its own writes; the rest go into the one bounded
  `commands.CommandQueue` (control commands first);
- reads are typed (`reading`: bits 0/1, words int, floats float) and sampled by an
  `after_scan` hook: the values of one scan, never a half-finished one. Addresses and
  symbols are checked in `objects.Objects`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

from softplc.access.commands import (
    ACTIONS,
    Action,
    Analog,
    Call,
    CommandQueue,
    Control,
    Force,
    Unforce,
    Write,
)
from softplc.access.errors import AccessError
from softplc.access.machine import MachineInfo
from softplc.access.objects import Objects
from softplc.access.program import ProgramAccess
from softplc.access.reading import Reading
from softplc.access.values import check_value
from softplc.runtime.analog import SIGNAL_SPAN, SIGNAL_UNIT
from softplc.runtime.runstate import RunState
from softplc.twido.address import BLOCK_FIELDS, Ref

CONSTANT_KINDS = ("KW", "KD", "KF")
IMAGE_KINDS = ("MW", "MD", "MF", "M")  # written through the Modbus image when there is one


class WordLane(Protocol):
    """Where %MW/%MD/%MF/%M writes go when the controller is served over Modbus: the
    Modbus image's pending writes (`softplc.modbus.image.ModbusImage`), coalesced and
    applied at the scan boundary before the command queue."""

    @property
    def pending(self) -> int: ...

    def queue_value(self, kind: str, index: int, value: int | float) -> None: ...

    def read_only_object(self, kind: str, index: int, bit: int | None) -> bool: ...


@dataclass(frozen=True)
class Status:
    """The controller as a whole: run state, scans and their times, forcing, queues."""

    state: RunState
    fault: str
    scans: int
    time: float  # s of controller time
    scan_last_ms: float
    scan_min_ms: float
    scan_max_ms: float
    overruns: int
    period_ms: float
    forced: dict[str, int | float] = field(default_factory=dict)
    forced_count: int = 0
    pending: int = 0  # commands and Modbus writes waiting for the next boundary
    applied: int = 0  # commands applied since start

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["state"] = str(self.state)
        out["web_changes_applied"] = out.pop("applied")  # the API's name since it began
        return out


class AccessPort:
    """Typed reads, checked and queued changes, status, over a `PLC` (and its
    `ModbusImage`, the `WordLane`, if it is served over Modbus). `refuse_changes`: a
    front-end's reason to refuse every change (a read-only monitor), "" to allow them.
    `hooks=False`: the caller owns the scan (the debugger, between two instructions) and
    applies the queue itself (`apply_now`); reads are `read_now` only."""

    def __init__(self, plc: Any, image: WordLane | None = None, *,
                 refuse_changes: str = "", hooks: bool = True):
        self.plc = plc
        self.image = image
        self.refuse_changes = refuse_changes
        self.profile = plc.profile
        self.queue = CommandQueue(plc)
        self.objects = Objects(plc)  # addresses and symbols -> objects
        self.reading = Reading(plc)  # typed reads at a scan boundary
        self.machine = MachineInfo(plc)  # I/O layout, analog channels, devices, rungs
        self.program = ProgramAccess(plc, image)  # listing, symbols, map, online change
        # inputs a wire drives ({address: by what}, softplc.access.wires): only forced here
        self.wired: dict[str, str] = {}
        if hooks:
            plc.before_scan.append(self.queue.apply)
            plc.after_scan.append(self.reading.serve)

    def close(self) -> None:
        """Unhook from the controller; pending reads are answered directly."""
        for hooks, fn in ((self.plc.before_scan, self.queue.apply),
                          (self.plc.after_scan, self.reading.serve)):
            if fn in hooks:
                hooks.remove(fn)
        self.reading.serve()

    # -- checks ---------------------------------------------------------------------------
    @staticmethod
    def forceable(ref: Ref) -> bool:
        """Bits (%I %Q %M %S %X) and %MW/%MD/%MF words can be forced (`PLC.force`)."""
        plain = ref.offset is None and ref.field is None and ref.bit is None
        return plain and ref.kind in ("I", "Q", "M", "S", "X", "MW", "MD", "MF")

    def why_not_writable(self, ref: Ref, forcing: bool = False) -> str | None:
        """Why `ref` cannot be written, None if it can. `forcing`: a force (or the
        debugger's set), which overrides the simulated devices and the host read-only
        ranges."""
        if self.refuse_changes:
            return self.refuse_changes
        if ref.kind in CONSTANT_KINDS:
            return (f"{ref.label} is a constant (read-only): set it in the configuration "
                    f"([constants])")
        if ref.kind in BLOCK_FIELDS:
            if ref.is_block:
                return f"{ref.label} is a function block: read or write its fields (.P, .V...)"
            if not ref.writable:
                return f"{ref.label} is read-only (the block computes it)"
        device_io = self.machine.device_io
        if ref.kind == "I" and not forcing and str(ref) in device_io:
            return (f"{ref.label} is driven by the simulated device "
                    f"{device_io[str(ref)]!r}: force it to override")
        if ref.kind == "I" and not forcing and str(ref) in self.wired:
            return (f"{ref.label} is driven by {self.wired[str(ref)]}: force it to "
                    f"override")
        if self.image is not None and ref.kind in IMAGE_KINDS and not forcing \
                and ref.offset is None \
                and self.image.read_only_object(ref.kind, ref.index, ref.bit):
            return f"{ref.label} is read-only ([modbus] read_only in the configuration)"
        return None

    check_value = staticmethod(check_value)

    def _deny(self) -> None:
        if self.refuse_changes:
            raise AccessError(self.refuse_changes, 403)

    # -- changes (queued; applied at the next scan boundary) ------------------------------
    def write_many(self, writes: list[tuple[Any, Any]]) -> list[str]:
        """Check every write (an object or a range, with a list of values or one for all),
        then queue them all: a bad one and nothing is applied."""
        checked = []
        for obj, value in writes:
            refs = self.objects.resolve(obj)
            values = value if isinstance(value, list) else [value] * len(refs)
            if len(values) != len(refs):
                raise AccessError(f"{obj}: {len(refs)} objects but {len(values)} values")
            for ref, v in zip(refs, values, strict=True):
                why = self.why_not_writable(ref)
                if why:
                    raise AccessError(why, 403)
                v = self.check_value(ref, v)
                why = self.machine.write_refusal(ref, v)
                if why:  # the device would refuse it at its next scan: say so now
                    raise AccessError(why)
                checked.append((ref, v))
        self.queue.put([Write(ref, v) for ref, v in checked if not self._to_image(ref)])
        for ref, v in checked:
            if self._to_image(ref):
                assert self.image is not None
                self.image.queue_value(ref.kind, ref.index, v)
        return [str(r) for r, _ in checked]

    def _to_image(self, ref: Ref) -> bool:
        """A write that goes into the Modbus image's pending writes."""
        return self.image is not None and ref.offset is None and ref.bit is None \
            and ref.kind in IMAGE_KINDS

    def write_analog(self, obj: Any, value: Any, force: bool = False) -> dict[str, Any]:
        """Queue a new physical value (V, mA, degrees C, pot position) for an analog input:
        applied at the next scan boundary through `AnalogIO.set_input`, as a device drives
        it. An input a device drives is refused unless `force` (then the word is forced,
        `PLC.force`, and held until unforced), as for %I inputs."""
        ref, ch = self.machine.analog_channel(self.objects.resolve(obj), obj)
        name = str(ref)
        self._deny()
        if ref.kind != "IW":
            raise AccessError(f"{name} is an analog output: the program drives it", 403)
        if not force and name in self.plc.forced:
            raise AccessError(f"{name} is forced: unforce it first, or force a new value",
                              403)
        device_io = self.machine.device_io
        if not force and name in device_io:
            raise AccessError(f"{name} is driven by the simulated device "
                              f"{device_io[name]!r}: force it to override", 403)
        a, b = SIGNAL_SPAN[ch.signal]
        unit = SIGNAL_UNIT[ch.signal]
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value):
            raise AccessError(f"{name}: expected a number ({a:g}..{b:g} {unit}), "
                              f"not {value!r}")
        if not a <= value <= b:
            raise AccessError(f"{name}: {value:g} is out of range {a:g}..{b:g} {unit} "
                              f"({ch.signal})".replace("  ", " "))
        word = ch.to_word(float(value))[0]
        self.queue.put([Force(ref, word) if force else Analog(ref, float(value))])
        return {"queued": name, "value": float(value), "word": word, "forced": force}

    def force(self, obj: Any, value: Any) -> list[str]:
        """Check, then queue the forcing of an object (or each of a range) at `value`."""
        checked = []
        for ref in self.objects.resolve(obj):
            self._deny()
            if not self.forceable(ref):
                raise AccessError(f"{ref.label} cannot be forced: bits (%I %Q %M %S %X) and "
                                  f"%MW/%MD/%MF words can", 403)
            why = self.why_not_writable(ref, forcing=True)
            if why:
                raise AccessError(why, 403)
            checked.append((ref, self.check_value(ref, value)))
        self.queue.put([Force(ref, v) for ref, v in checked])
        return [str(r) for r, _ in checked]

    def unforce(self, obj: Any = None) -> list[str]:
        """Queue the release of `obj` (None, "" or "all": of everything) in the urgent lane;
        a forcing of those objects still queued is dropped (the unforce came after it)."""
        self._deny()
        every = isinstance(obj, str | None) and obj in (None, "", "all")
        refs = None if every else tuple(self.objects.resolve(obj))
        self.queue.put([Unforce(refs)])
        return list(self.plc.forced) if refs is None else [str(r) for r in refs]

    def control(self, action: Any) -> Action:
        """Queue RUN, STOP, a cold or a warm restart (`Action`, or its name)."""
        self._deny()
        if not isinstance(action, str) or action not in ACTIONS:
            raise AccessError(f"action {str(action)[:40]!r}: one of {', '.join(ACTIONS)}")
        act = Action(action)
        self.queue.put([Control(act)])
        return act

    def call(self, fn: Callable[[], None]) -> None:
        """Queue `fn` in the control lane: run in the scan thread at the next boundary (the
        online change's swap); it handles its own errors."""
        self.queue.put([Call(fn)])

    def apply_now(self) -> None:
        """Apply the queued commands at once: for a caller that owns the scan thread and
        stands between two scans or instructions (the debugger)."""
        self.queue.apply()

    @property
    def pending(self) -> int:
        """Commands waiting for the next scan boundary (not the Modbus image's writes)."""
        return len(self.queue)

    # -- reads (typed; sampled at a scan boundary) -----------------------------------------
    async def read(self, objs: Any) -> dict[str, Any]:
        """{name: typed value} of objects, ranges or symbols, of one scan."""
        refs = self.objects.resolve_many(objs)
        return await self.reading.sample(self.reading.values_fn(refs))

    def read_now(self, refs: list[Ref]) -> list[Any]:
        """Typed values of `refs` read at once: for a caller in the scan thread (a hook, a
        debugger between scans)."""
        return self.reading.reader(refs)()

    @property
    def forced(self) -> dict[str, Any]:
        """{address: value} of the forced objects."""
        return self.plc.forced

    def status(self) -> Status:
        plc = self.plc
        st = plc.stats
        forced = {k: (int(v) if isinstance(v, bool) else v) for k, v in plc.forced.items()}
        return Status(state=plc.state, fault=plc.fault, scans=st.scans,
                      time=round(plc.time, 6), scan_last_ms=st.last * 1000,
                      scan_min_ms=st.min * 1000, scan_max_ms=st.max * 1000,
                      overruns=st.overruns, period_ms=round(plc.scan_period * 1000, 3),
                      forced=forced, forced_count=len(forced),
                      pending=self.pending + (self.image.pending if self.image else 0),
                      applied=self.queue.applied)


__all__ = ["AccessPort", "Status", "WordLane"]
