"""Analog I/O: the conversion an analog channel does between a physical signal and the
word the program sees in %IWm.c / writes to %QWm.c, and the channel status.

As TwidoSuite configures a channel [manual, from memory: see docs/twido.md#analog-io]:
  * the signal type: 0-10 V, 4-20 mA, +-10 V, a temperature sensor (PT100, thermocouple J/K/T),
    or on the base a potentiometer (position 0..1) or the 0-10 V input;
  * the range: "normal" (0 .. full scale, 4095 on the 12-bit expansion modules; a
    bipolar +-10 V signal -2048..2047),
    "custom" (the signal span mapped linearly onto min .. max, -32768..32767), and for
    temperature sensors "celsius" / "fahrenheit" (tenths of a degree).
A signal outside its span is clamped to the span's end and flagged in the module's status
word %SW8m (m = slot; 4 bits per channel: bit 0 under range, bit 1 over range; our
layout, the real one is unverified). Outputs convert back: the program's %QW word,
clamped to the range, gives the physical signal a device reads.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from softplc.errors import AddressError, ConfigError
from softplc.twido.address import Ref, parse_address

# Physical span of each signal type (V, mA, degrees C, potentiometer fraction) [manual].
SIGNAL_SPAN: dict[str, tuple[float, float]] = {
    "0-10V": (0.0, 10.0), "4-20mA": (4.0, 20.0), "+-10V": (-10.0, 10.0), "pot": (0.0, 1.0),
    "PT100": (-200.0, 600.0), "J": (-200.0, 760.0), "K": (-270.0, 1370.0),
    "T": (-200.0, 400.0),
}
# The unit of each signal type's physical value (a potentiometer: its position, 0..1).
SIGNAL_UNIT: dict[str, str] = {"0-10V": "V", "4-20mA": "mA", "+-10V": "V", "pot": "",
                               "PT100": "°C", "J": "°C", "K": "°C", "T": "°C"}
TEMPERATURE_TYPES = ("PT100", "J", "K", "T")
BIPOLAR_TYPES = ("+-10V",)  # normal range -2048..2047 on a 12-bit channel [issue 11]


def normal_range(signal: str, full_scale: int) -> tuple[int, int]:
    """The words of the signal span in the normal range: 0..4095, or -2048..2047 for a
    bipolar signal, on a 12-bit channel (full_scale 4095)."""
    if signal in BIPOLAR_TYPES:
        return -(full_scale + 1) // 2, full_scale // 2
    return 0, full_scale
SW_ANALOG_STATUS = 80  # %SW80 + slot: status of the analog channels of that slot (our layout)
UNDER_RANGE, OVER_RANGE = 1, 2  # per-channel status bits (our layout)
STATUS_BITS = 4  # status bits per channel


@dataclass
class AnalogChannel:
    """One configured channel: its signal and its range."""

    ref: Ref
    signal: str
    range: str = "normal"
    lo: int = 0  # the word for the bottom of the signal span
    hi: int = 4095  # the word for the top
    full_scale: int = 4095  # of the hardware: 4095 on 12 bits, 1023 on 10
    # False for a module channel [analog] does not mention: its signal type is the module's
    # first one by default, so its words stand for no known physical value
    configured: bool = True

    def _scale(self, x: float) -> float:
        """Physical value -> word (not rounded, not clamped)."""
        if self.range == "celsius":
            return x * 10.0
        if self.range == "fahrenheit":
            return (x * 9.0 / 5.0 + 32.0) * 10.0
        a, b = SIGNAL_SPAN[self.signal]
        return self.lo + (x - a) * (self.hi - self.lo) / (b - a)

    def to_word(self, x: float) -> tuple[int, int]:
        """A physical input -> (word, status bits): clamped to the signal span."""
        a, b = SIGNAL_SPAN[self.signal]
        status = 0
        if x < a:
            x, status = a, UNDER_RANGE
        elif x > b:
            x, status = b, OVER_RANGE
        return round(self._scale(x)), status

    def to_physical(self, word: int) -> float:
        """A word -> the physical signal, the word clamped to the range (an output's signal,
        or the value an input's word stands for)."""
        if self.range == "celsius":
            return word / 10.0
        if self.range == "fahrenheit":
            return (word / 10.0 - 32.0) * 5.0 / 9.0
        a, b = SIGNAL_SPAN[self.signal]
        lo, hi = (self.lo, self.hi) if self.lo <= self.hi else (self.hi, self.lo)
        w = min(max(word, lo), hi)
        return a + (w - self.lo) * (b - a) / (self.hi - self.lo)


class AnalogIO:
    """The configured analog channels of one memory image (`mem.analog`)."""

    def __init__(self, mem: Any, channels: dict[Ref, AnalogChannel]):
        self.mem = mem
        self.channels = channels

    def channel(self, address: str | Ref, kind: str) -> AnalogChannel:
        try:
            ref = address if isinstance(address, Ref) else parse_address(address,
                                                                         self.mem.profile)
        except AddressError as e:
            raise ConfigError(str(e)) from None
        ch = self.channels.get(ref)
        if ch is None or ref.kind != kind:
            what = "input" if kind == "IW" else "output"
            raise ConfigError(f"{address} is not a configured analog {what} (see [analog] "
                              f"and [modules])")
        return ch

    def set_input(self, address: str | Ref, value: float) -> int:
        """Drive an analog input with a physical value (V, mA, degrees C, pot position);
        returns the word the program will read. Out of span: clamped, status set."""
        return self.drive(self.channel(address, "IW"), value)

    def drive(self, ch: AnalogChannel, value: float) -> int:
        """`set_input` on a channel looked up once (a device's, driven every scan: no
        address parsed per scan)."""
        word, status = ch.to_word(float(value))
        self.mem.iw.w[ch.ref.index] = max(-32768, min(32767, word))
        self._status(ch.ref, status)
        return word

    def output(self, address: str | Ref) -> float:
        """The physical value of an analog output (V or mA) from the program's %QW word."""
        return self.signal(self.channel(address, "QW"))

    def signal(self, ch: AnalogChannel) -> float:
        """`output` of a channel looked up once (read by a device every scan)."""
        return ch.to_physical(self.mem.qw.w[ch.ref.index])

    def _status(self, ref: Ref, status: int) -> None:
        if not ref.module:
            return  # the base's inputs have no status word here
        sw = self.mem.sw.uw
        k = SW_ANALOG_STATUS + ref.module
        shift = STATUS_BITS * ref.channel
        sw[k] = (sw[k] & ~(0xF << shift) & 0xFFFF) | (status << shift)
