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

from typing import Any

from ..config import Address, FiniteFloat, Section
from ..errors import ConfigCode, ConfigError
from ..runtime.memory import MemoryImage
from .base import Device, register_device


@register_device("analog_source")
class AnalogSource(Device):
    STATE = ("value",)

    class Options(Section):
        input: Address
        value: FiniteFloat = 0.0
        profile: list[Any] | None = None  # [time_s, value] pairs, checked below

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.input = options.input
        self.initial = float(options.value)
        self.profile: list[tuple[float, float]] = []
        for k, point in enumerate(options.profile or []):
            if not (isinstance(point, list | tuple) and len(point) == 2 and
                    all(isinstance(x, int | float) and not isinstance(x, bool)
                        for x in point)):
                raise self.problem(f"profile[{k}]", f"points are [time_s, value], not "
                                   f"{point!r}", ConfigCode.TYPE)
            if self.profile and point[0] <= self.profile[-1][0]:
                raise self.problem(f"profile[{k}]", f"times must increase ({point[0]} "
                                   f"after {self.profile[-1][0]})")
            self.profile.append((float(point[0]), float(point[1])))
        self._mem: MemoryImage | None = None
        self.reset()

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._mem = mem
        if mem.analog is None:
            raise self.problem("input", "no analog channels", ConfigCode.MODULE)
        try:
            mem.analog.channel(self.input, "IW")
        except ConfigError as e:
            raise self.problem("input", str(e), ConfigCode.ADDRESS) from None
        self._write(0.0)

    def reset(self) -> None:
        self.value = self.initial

    def at(self, t: float) -> float:
        """The profile's value at time t."""
        pts = self.profile
        if not pts:
            return self.value
        if t <= pts[0][0]:
            return pts[0][1]
        for (t0, v0), (t1, v1) in zip(pts, pts[1:], strict=False):
            if t <= t1:
                return v0 + (v1 - v0) * (t - t0) / (t1 - t0)
        return pts[-1][1]

    def _write(self, t: float) -> None:
        self.value = self.at(t)
        self._mem.analog.set_input(self.input, self.value)

    def update(self, t: float, dt: float) -> None:
        self._write(t)

    def status(self) -> dict[str, Any]:
        return {"value": round(self.value, 4)}
