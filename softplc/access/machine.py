"""What the access port tells of the machine around the program: the I/O layout (base
and expansion modules), the analog channels, the simulated devices as a typed listing
(which I/O each one drives or reads), the rungs and the program's version."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from softplc.access.errors import AccessError
from softplc.errors import AddressError
from softplc.runtime.analog import SIGNAL_SPAN, SIGNAL_UNIT
from softplc.twido.address import Ref, parse_address
from softplc.twido.profile import MODULES

IO_PREFIXES = ("%I", "%Q")  # %I/%Q bits and %IW/%QW analog words
DEVICE_WORD_KINDS = ("MW", "MD", "MF")  # the words a device's `word_check` may check


@dataclass(frozen=True)
class DeviceEntry:
    """One simulated device: its name in the configuration, its registered type
    (`register_device`), the device itself and the %I/%Q objects its options name."""

    name: str
    kind: str
    device: Any
    io: tuple[str, ...]


def device_entry(name: str, dev: Any, profile: Any) -> DeviceEntry:
    """The entry of a device; its I/O is found from the address strings (and lists of
    them) among its attributes, the options it copied from its configuration. Its options
    model would name more (an encoder's inputs, a servo's E-stop button), but they do not
    say whether the device drives an input or only reads it (a user presses the E-stop):
    an input listed here refuses writes."""
    io: dict[str, None] = {}
    for value in vars(dev).values():
        for item in value if isinstance(value, list | tuple) else [value]:
            if isinstance(item, str) and item[:2].upper() in IO_PREFIXES:
                try:
                    io[str(parse_address(item, profile))] = None
                except AddressError:
                    pass
    return DeviceEntry(name, str(dev.type_name), dev, tuple(io))


class MachineInfo:
    def __init__(self, plc: Any):
        self.plc = plc
        self.profile = plc.profile
        self._io_refs: list[tuple[str, Ref]] | None = None
        self.devices = [device_entry(n, d, self.profile) for n, d in plc.devices.items()]
        # which %I/%Q each device reads or drives: {address: device}
        self.device_io = {a: d.name for d in self.devices for a in d.io}
        # I/O the program, configuration and devices name (before any write adds more)
        self.io_in_use = {kind: plc.mem.io_used(kind) for kind in ("I", "Q")}

    def write_refusal(self, ref: Ref, value: int | float) -> str | None:
        """Why a simulated device refuses `value` in a word it checks (its `word_check`,
        e.g. a servo axis's I-variable ranges), None if none does."""
        if ref.kind not in DEVICE_WORD_KINDS or ref.offset is not None or ref.bit is not None:
            return None
        for entry in self.devices:
            check = entry.device.word_check
            why = check.refusal(ref.kind, ref.index, value) if check is not None else None
            if why:
                return f"{ref} := {value:g} refused: {why}"
        return None

    # -- program --------------------------------------------------------------------------
    @property
    def rungs(self) -> list[Any]:
        return self.plc.rungs

    @property
    def code_version(self) -> int:
        """Bumped by every rebuild of the running code (forcing, online change): what the
        views' caches of the running code key on (the program's own version is the
        program port's)."""
        return self.plc.code_version

    @property
    def time(self) -> float:
        """Controller time, s."""
        return self.plc.time

    @property
    def trace(self) -> list[Any]:
        """The trace recorder's samples (appended to by the scan)."""
        return self.plc.trace

    @property
    def scan_period(self) -> float:
        return self.plc.scan_period

    # -- I/O ------------------------------------------------------------------------------
    def io_layout(self) -> list[dict[str, Any]]:
        """The base and the configured expansion modules with their I/O channels."""
        prof = self.profile
        mods = [{"slot": 0, "name": prof.name, "inputs": prof.inputs_base,
                 "outputs": prof.outputs_base}]
        for slot, name in sorted((self.plc.settings.modules or {}).items()):
            n_in, n_out = MODULES.get(name, (0, 0))  # an analog module: no %I/%Q
            mods.append({"slot": slot, "name": name, "inputs": n_in, "outputs": n_out})
        return mods

    def io_refs(self) -> list[tuple[str, Ref]]:
        """Every %I/%Q channel of the layout: (address, object)."""
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

    def io_used(self) -> list[str]:
        """The channels the program, configuration and devices name."""
        return [name for name, ref in self.io_refs()
                if ref.index in self.io_in_use[ref.kind]]

    # -- analog ---------------------------------------------------------------------------
    def analog_channel(self, refs: list[Ref], obj: Any) -> tuple[Ref, Any]:
        """The one configured analog channel `refs` (resolved from `obj`) names."""
        analog = self.plc.mem.analog
        if len(refs) != 1 or analog is None or refs[0] not in analog.channels:
            raise AccessError(f"{obj!r} is not a configured analog channel (see [analog] "
                              f"and [modules] in the configuration)")
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


__all__ = ["DeviceEntry", "MachineInfo", "device_entry"]
