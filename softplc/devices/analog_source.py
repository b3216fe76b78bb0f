"""A signal source for an analog input: a constant, or a piecewise-linear profile over
time (a level sensor filling, a pressure ramp...), in the channel's physical unit.

TOML options, table `[devices.NAME]` with `type = "analog_source"`:

- `input` (required): the analog input it drives, e.g. `"%IW1.0"` (configured in
  `[analog]`, or one of the base's inputs).
- `value` (number, default 0.0): the signal when there is no profile (V, mA, degrees C,
  or 0..1 for a potentiometer).
- `profile` (list of `[time_s, value]` pairs, times increasing): the signal follows the
  straight lines between the points, holds the first value before the first point and
  the last one after the last.

Attribute: `value` (the signal now). Tests may set `value` between scans.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Field, field_validator

from softplc.config import Address, FiniteFloat, Section
from softplc.devices.base import Device, interp, register_device
from softplc.errors import ConfigCode, ConfigError
from softplc.runtime.memory import MemoryImage

Point = Annotated[list[FiniteFloat], Field(min_length=2, max_length=2)]  # [time_s, value]


@register_device("analog_source")
class AnalogSource(Device):
    STATE = ("value",)

    class Options(Section):
        input: Address
        value: FiniteFloat = 0.0
        profile: list[Point] | None = None  # [time_s, value] pairs

        @field_validator("profile")
        @classmethod
        def _increasing(cls, v: list[list[float]] | None) -> list[list[float]] | None:
            times = [p[0] for p in v or []]
            for k in range(1, len(times)):
                if not times[k] > times[k - 1]:
                    raise ValueError(f"times must increase ({times[k]:g} s after "
                                     f"{times[k - 1]:g} s)")
            return v

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.input = options.input
        self.initial = float(options.value)
        self.profile = [(t, x) for t, x in options.profile or []]
        self._mem: MemoryImage | None = None
        self.reset()

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._mem = mem
        if mem.analog is None:
            raise self.problem("input", "no analog channels", ConfigCode.MODULE)
        try:  # (looked up once: the source writes it every scan)
            self._ch = mem.analog.channel(self.input, "IW")
        except ConfigError as e:
            raise self.problem("input", str(e), ConfigCode.ADDRESS) from None
        self._write(0.0)

    def reset(self) -> None:
        self.value = self.initial

    def at(self, t: float) -> float:
        """The profile's value at time t."""
        return interp(self.profile, t) if self.profile else self.value

    def _write(self, t: float) -> None:
        self.value = self.at(t)
        self._mem.analog.drive(self._ch, self.value)

    def update(self, t: float, dt: float) -> None:
        self._write(t)

    def status(self) -> dict[str, Any]:
        return {"value": round(self.value, 4)}
