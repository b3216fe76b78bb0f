"""The operating API of a running soft-PLC, without HTTP: what the web page, `softplc io`
and scripts can read and do, and the one place that checks their requests.

Threads: the scan runs in one thread, the web server in the daemon's asyncio loop (the
Modbus thread). They meet only at scan boundaries:

- every change (write, force, unforce, RUN/STOP/restart) is checked here, then queued and
  applied by a `before_scan` hook, after the Modbus writes queued before it. %MW/%MD/%MF
  and %M writes go into the Modbus queue itself (`ModbusImage.queue_*`, which coalesces
  them), so a Modbus host reads back what the page wrote exactly as it reads its own
  writes; the rest go into `changes.ChangeQueue` (bounded; control commands first);
- reads are sampled by an `after_scan` hook (`reading.Reading.sample`): the values of one
  scan, never a half-finished one. Addresses are checked in `objects.Objects`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from ..address import BLOCK_FIELDS, WIDTH, Ref, parse_address
from ..errors import AddressError
from ..il.printer import format_instruction
from ..modbus.image import ModbusImage, words_to_wire
from ..modbus.regmap import COILS, REGISTERS
from ..numeric import F32_MAX, wrap16
from ..profile import MODULES
from ..runtime.analog import SIGNAL_SPAN, SIGNAL_UNIT
from ..runtime.memory import WordFamily
from .changes import ChangeQueue
from .errors import ApiError
from .objects import Objects
from .reading import Reading

# Value ranges the API accepts, per value type.
INT16_RANGE = (-32768, 65535)  # unsigned 16-bit too, as a Modbus host or hex entry gives it
INT32_RANGE = (-(2 ** 31), 2 ** 32 - 1)
MAX_PAGES = 32  # websocket pages open at once (--web-max-pages; [web] max_pages default)
ACTIONS = ("run", "stop", "cold", "warm")
CONSTANT_KINDS = ("KW", "KD", "KF")


def _device_io(devices: dict[str, Any], profile: Any) -> dict[str, str]:
    """Which %I/%Q addresses each simulated device reads or drives: {address: device}.
    Found from the devices' configured address options (strings and lists of strings)."""
    out: dict[str, str] = {}
    for name, dev in devices.items():
        for value in vars(dev).values():
            items = value if isinstance(value, list | tuple) else [value]
            for item in items:
                if isinstance(item, str) and item[:2].upper() in ("%I", "%Q"):
                    try:
                        out[str(parse_address(item, profile))] = name
                    except AddressError:
                        pass
    return out


class Controller:
    """The API core over a `PLC` (and its `ModbusImage`, if it is served over Modbus)."""

    def __init__(self, plc: Any, image: ModbusImage | None = None, *,
                 read_only: bool = False, program_name: str = "",
                 status_extra: Callable[[], dict[str, Any]] | None = None):
        self.plc = plc
        self.image = image
        self.read_only = read_only
        self.program_name = program_name
        self.status_extra = status_extra or (lambda: {})
        self.profile = plc.profile
        self.changes = ChangeQueue(plc)
        self.objects = Objects(plc)  # addresses -> objects
        self.reading = Reading(plc)  # reads at a scan boundary
        self._io_refs: list[tuple[str, Ref]] | None = None
        self.device_io = _device_io(plc.devices, self.profile)
        # I/O the program, configuration and devices name (before any API write adds more)
        self.io_in_use = {kind: plc.mem.io_used(kind) for kind in ("I", "Q")}
        plc.before_scan.append(self.changes.apply)
        plc.after_scan.append(self.reading.serve)

    def close(self) -> None:
        """Unhook from the PLC; pending reads are answered directly."""
        for hooks, fn in ((self.plc.before_scan, self.changes.apply),
                          (self.plc.after_scan, self.reading.serve)):
            if fn in hooks:
                hooks.remove(fn)
        self.reading.serve()

    # -- objects ------------------------------------------------------------------------------
    @staticmethod
    def forceable(ref: Ref) -> bool:
        """Bits (%I %Q %M %S %X) and %MW/%MD/%MF words can be forced (`PLC.force`)."""
        plain = ref.offset is None and ref.field is None and ref.bit is None
        return plain and ref.kind in ("I", "Q", "M", "S", "X", "MW", "MD", "MF")

    def _why_not_writable(self, ref: Ref, forcing: bool = False) -> str | None:
        if self.read_only:
            return "the web monitor is read-only (--web-read-only)"
        if ref.kind in CONSTANT_KINDS:
            return f"{ref} is a constant: set it in the configuration ([constants])"
        if ref.kind in BLOCK_FIELDS:
            if ref.is_block:
                return f"{ref} is a function block: read or write its fields (.P, .V...)"
            if not ref.writable:
                return f"{ref} is read-only (the block computes it)"
        if ref.kind == "I" and not forcing and str(ref) in self.device_io:
            return (f"{ref} is driven by the simulated device "
                    f"{self.device_io[str(ref)]!r}: force it to override")
        if self.image is not None and ref.kind in ("MW", "MD", "MF", "M") and not forcing:
            space = COILS if ref.kind == "M" else REGISTERS
            n = 1 if ref.kind == "M" or ref.bit is not None else WIDTH[ref.kind]
            if ref.offset is None and self.image.read_only.blocks(space, ref.index, n):
                return f"{ref} is read-only ([modbus] read_only in the configuration)"
        return None

    @staticmethod
    def check_value(ref: Ref, value: Any) -> int | float:
        """A value for `ref`, or an ApiError saying what fits."""
        if isinstance(value, str):
            try:
                value = float(value) if ref.type == "real" else int(value, 0)
            except ValueError:
                raise ApiError(f"{ref}: {value!r} is not a number") from None
        if ref.type == "bool":
            if value in (0, 1) and not isinstance(value, float):
                return int(value)
            raise ApiError(f"{ref} is a bit: value 0 or 1, not {value!r}")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ApiError(f"{ref}: expected a number, not {value!r}")
        if ref.type == "real":
            if not (math.isfinite(value) and abs(value) <= F32_MAX):
                raise ApiError(f"{ref}: {value!r} does not fit a 32-bit float")
            return float(value)
        if isinstance(value, float):
            if not value.is_integer():
                raise ApiError(f"{ref} is an integer object: {value!r} is not whole")
            value = int(value)
        lo, hi = INT32_RANGE if ref.type == "int32" else INT16_RANGE
        if ref.kind in BLOCK_FIELDS:
            lo, hi = 0, 32767  # presets and register words [manual]
        if not lo <= value <= hi:
            raise ApiError(f"{ref}: {value} is out of range {lo}..{hi}")
        return value

    # -- changes (queued; applied at the next scan boundary) -----------------------------------
    def write(self, obj: Any, value: Any) -> list[str]:
        """Queue a write of one object or a range (a list of values, or one for all)."""
        return self.write_many([(obj, value)])

    def write_many(self, writes: list[tuple[Any, Any]]) -> list[str]:
        """Check every write, then queue them all: a bad one and nothing is applied."""
        checked = []
        for obj, value in writes:
            refs = self.objects.resolve(obj)
            values = value if isinstance(value, list) else [value] * len(refs)
            if len(values) != len(refs):
                raise ApiError(f"{obj}: {len(refs)} objects but {len(values)} values")
            for ref, v in zip(refs, values, strict=True):
                why = self._why_not_writable(ref)
                if why:
                    raise ApiError(why, 403)
                checked.append((ref, self.check_value(ref, v)))
        self.changes.put([("write", ref, v) for ref, v in checked
                          if not self._to_image(ref)])
        for ref, v in checked:
            if self._to_image(ref):
                self._queue_write(ref, v)
        return [str(r) for r, _ in checked]

    def _to_image(self, ref: Ref) -> bool:
        """A write that goes into the Modbus write queue (`_queue_write`)."""
        return self.image is not None and ref.offset is None and ref.bit is None \
            and ref.kind in ("MW", "MD", "MF", "M")

    def _queue_write(self, ref: Ref, value: int | float) -> None:
        """A write into the Modbus write queue (one that `_to_image` sends there)."""
        img = self.image
        assert img is not None
        if ref.kind == "M":
            img.queue_coils(ref.index, bytes([1 if value else 0]))
            return
        fam = WordFamily(WIDTH[ref.kind])  # encoded by the memory's own conversions
        if ref.kind == "MW":
            fam.w[0] = wrap16(int(value))
        elif ref.kind == "MD":
            fam.set_d(0, int(value))
        else:
            fam.set_f(0, float(value))
        img.queue_registers(ref.index, words_to_wire(fam.buf))

    def write_analog(self, obj: Any, value: Any, force: bool = False) -> dict[str, Any]:
        """Queue a new physical value (V, mA, degrees C, pot position) for an analog input:
        applied at the next scan boundary through `AnalogIO.set_input`, as a device drives
        it. An input a device drives is refused unless `force` (then the word is forced,
        `PLC.force`, and held until unforced), as for %I inputs."""
        ref, ch = self._analog_channel(obj)
        name = str(ref)
        if self.read_only:
            raise ApiError("the web monitor is read-only (--web-read-only)", 403)
        if ref.kind != "IW":
            raise ApiError(f"{name} is an analog output: the program drives it", 403)
        if not force and name in self.plc.forced:
            raise ApiError(f"{name} is forced: unforce it first, or force a new value", 403)
        if not force and name in self.device_io:
            raise ApiError(f"{name} is driven by the simulated device "
                           f"{self.device_io[name]!r}: force it to override", 403)
        a, b = SIGNAL_SPAN[ch.signal]
        unit = SIGNAL_UNIT[ch.signal]
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not math.isfinite(value):
            raise ApiError(f"{name}: expected a number ({a:g}..{b:g} {unit}), not {value!r}")
        if not a <= value <= b:
            raise ApiError(f"{name}: {value:g} is out of range {a:g}..{b:g} {unit} "
                           f"({ch.signal})".replace("  ", " "))
        word = ch.to_word(float(value))[0]
        self.changes.put([("force", ref, word) if force else ("analog", ref, float(value))])
        return {"queued": name, "value": float(value), "word": word, "forced": force}

    def _analog_channel(self, obj: Any) -> tuple[Ref, Any]:
        analog = self.plc.mem.analog
        refs = self.objects.resolve(obj)
        if len(refs) != 1 or analog is None or refs[0] not in analog.channels:
            raise ApiError(f"{obj!r} is not a configured analog channel (see [analog] and "
                           f"[modules] in the configuration)")
        return refs[0], analog.channels[refs[0]]

    def analog_channels(self) -> list[dict[str, Any]]:
        """The configured analog channels: address, direction, signal, its span in the
        signal's unit, the words of that span, the device driving or reading it."""
        analog = self.plc.mem.analog
        out: list[dict[str, Any]] = []
        if analog is None:
            return out
        for ref, ch in sorted(analog.channels.items(),
                              key=lambda kv: (kv[0].kind, kv[0].index)):
            a, b = SIGNAL_SPAN[ch.signal]
            out.append({"address": str(ref), "input": ref.kind == "IW", "signal": ch.signal,
                        "range": ch.range, "unit": SIGNAL_UNIT[ch.signal], "min": a, "max": b,
                        "word_min": ch.to_word(a)[0], "word_max": ch.to_word(b)[0],
                        "driven_by": self.device_io.get(str(ref), ""),
                        "configured": ch.configured})
        return out

    def analog_values_fn(self) -> Callable[[], dict[str, dict[str, float]]]:
        """A function (for the scan thread) giving each analog channel's word and the
        physical value it stands for: {address: {"word": w, "value": x}}; the value is
        None for a channel [analog] does not configure (word 0 of a PT100 would read
        -200 °C, like a sensor fault)."""
        analog = self.plc.mem.analog
        if analog is None:
            return dict
        plc, mem = self.plc, self.plc.mem
        chans = [(str(ref), (mem.iw if ref.kind == "IW" else mem.qw).w, ref.index, ch)
                 for ref, ch in analog.channels.items()]

        def values() -> dict[str, dict[str, float]]:
            # a forced input: the value the program reads (a device rewrites the word after
            # the scan; the force is re-asserted before the next one)
            forced = plc.forced if plc.engine.forced else {}
            out = {}
            for name, words, i, ch in chans:
                w = int(forced.get(name, words[i]))
                out[name] = {"word": w, "value": round(ch.to_physical(w), 4)
                             if ch.configured else None}
            return out
        return values

    def force(self, obj: Any, value: Any) -> list[str]:
        refs = self.objects.resolve(obj)
        checked = []
        for ref in refs:
            if self.read_only:
                raise ApiError(self._why_not_writable(ref) or "", 403)
            if not self.forceable(ref):
                raise ApiError(f"{ref} cannot be forced: bits (%I %Q %M %S %X) and "
                               f"%MW/%MD/%MF words can", 403)
            why = self._why_not_writable(ref, forcing=True)
            if why:
                raise ApiError(why, 403)
            checked.append((ref, self.check_value(ref, value)))
        self.changes.put([("force", ref, v) for ref, v in checked])
        return [str(r) for r, _ in checked]

    def unforce(self, obj: Any = None) -> list[str]:
        """Queue the release of `obj` (None, "" or "all": of everything) in the urgent lane;
        a forcing of those objects still queued is dropped (the unforce came after it)."""
        if self.read_only:
            raise ApiError("the web monitor is read-only (--web-read-only)", 403)
        every = isinstance(obj, str | None) and obj in (None, "", "all")
        refs = None if every else self.objects.resolve(obj)
        self.changes.put([("unforce", refs, None)])
        return list(self.plc.forced) if refs is None else [str(r) for r in refs]

    def control(self, action: Any) -> str:
        if self.read_only:
            raise ApiError("the web monitor is read-only (--web-read-only)", 403)
        if not isinstance(action, str) or action not in ACTIONS:
            raise ApiError(f"action {str(action)[:40]!r}: one of {', '.join(ACTIONS)}")
        self.changes.put([("control", action, None)])
        return action

    @property
    def pending(self) -> int:
        return len(self.changes)

    # -- reads (sampled at a scan boundary) ----------------------------------------------------
    async def read(self, objs: Any) -> dict[str, Any]:
        refs = self.objects.resolve_many(objs)
        return await self.reading.sample(self.reading.values_fn(refs))

    # -- the controller as a whole ------------------------------------------------------------
    def io_layout(self) -> list[dict[str, Any]]:
        """The base and the configured expansion modules with their I/O channels."""
        prof = self.profile
        mods = [{"slot": 0, "name": prof.name, "inputs": prof.inputs_base,
                 "outputs": prof.outputs_base}]
        for slot, name in sorted((int(k), str(v).upper())
                                 for k, v in (self.plc.config.get("modules") or {}).items()):
            n_in, n_out = MODULES.get(name, (0, 0))
            mods.append({"slot": slot, "name": name, "inputs": n_in, "outputs": n_out})
        return mods

    def io_refs(self) -> list[tuple[str, Ref]]:
        if self._io_refs is not None:
            return self._io_refs
        out = []
        for m in self.io_layout():
            for kind, n in (("I", m["inputs"]), ("Q", m["outputs"])):
                for ch in range(n):
                    text = f"%{kind}{m['slot']}.{ch}"
                    out.append((text, parse_address(text, self.profile)))
        self._io_refs = out
        return out

    def info(self) -> dict[str, Any]:
        plc = self.plc
        rungs = [{"index": r.index, "title": r.title or "", "section": r.section,
                  "subroutine": r.subroutine, "label": r.label,
                  "il": "\n".join(format_instruction(i) for i in r.instructions)}
                 for r in plc.rungs]
        devices = {name: getattr(d, "type_name", "device") for name, d in plc.devices.items()}
        used = [name for name, ref in self.io_refs() if ref.index in self.io_in_use[ref.kind]]
        return {"program": self.program_name, "profile": self.profile.name, "io_used": used,
                "period_ms": round(plc.scan_period * 1000, 3), "modules": self.io_layout(),
                "device_io": self.device_io, "devices": devices, "rungs": rungs,
                "read_only": self.read_only, "actions": list(ACTIONS),
                "analog": self.analog_channels()}

    def status(self) -> dict[str, Any]:
        plc = self.plc
        st = plc.stats
        out = {"state": plc.state, "fault": plc.fault, "scans": st.scans,
               "time": round(plc.time, 6), "scan_last_ms": st.last * 1000,
               "scan_min_ms": st.min * 1000, "scan_max_ms": st.max * 1000,
               "overruns": st.overruns, "period_ms": round(plc.scan_period * 1000, 3),
               "forced": {k: (int(v) if isinstance(v, bool) else v)
                          for k, v in plc.forced.items()},
               "pending": self.pending + (self.image.pending if self.image else 0),
               "web_changes_applied": self.changes.applied}
        out.update(self.status_extra())
        return out


__all__ = ["ACTIONS", "ApiError", "Controller"]
