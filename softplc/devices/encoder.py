"""An incremental encoder (or any pulse source) wired to the fast counting inputs.

TOML options, table `[devices.NAME]` with `type = "encoder"`:

- `a` (required): the `%I` input of phase A (the pulses), e.g. `"%I0.1"` for %VFC0.
- `b`: the `%I` input of phase B (quadrature, 90 degrees behind A when moving up) or, with
  `signal = "pulse_direction"`, the direction level (1 while moving up). Omitted: A only.
- `signal` (default `"quadrature"`): `"quadrature"` or `"pulse_direction"`.
- The motion, one of:
  - `axis`: a `stepper` or `servo_axis` device, and `pulses_per_unit` (pulses, i.e. A
    periods, per unit of that axis's position: motor steps or encoder counts);
  - `frequency` (Hz, default 0): a fixed pulse rate, negative to move down; with `run`
    (an `%Q` output, e.g. the conveyor motor), pulses only while that output is on.
- `tick` (duration, default `"1ms"`): the time step at which the encoder reports pulses to
  the counters inside one scan; the very fast counter's reflex outputs switch with this
  resolution, independent of the scan period.

Counting between scans: after each scan the engine calls `update`, which splits the scan's
time into ticks and, for each, tells the counter listening on `a` how many rising edges of
A occurred (`mem.counting.feed`, runtime/fastcount.py) instead of toggling %I many times
per scan; the %I inputs show the A/B levels at the end of the scan. Attributes: `pulses`
(the signed count of A periods so far), `position` (the same in fractional periods).
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import Field, model_validator

from softplc.config import Address, Duration, FiniteFloat, Section
from softplc.devices.base import AxisDevice, Device, register_device
from softplc.runtime.memory import MemoryImage


@register_device("encoder")
class Encoder(Device):
    STATE = ("position", "_axis_pos")

    class Options(Section):
        a: Address
        b: Address | None = None
        signal: Literal["quadrature", "pulse_direction"] = "quadrature"
        axis: str | None = Field(None, min_length=1)
        pulses_per_unit: FiniteFloat = 1.0
        frequency: FiniteFloat = 0.0
        run: Address | None = None
        tick: Duration = 0.001

        @model_validator(mode="after")
        def _one_motion(self) -> Encoder.Options:
            if self.axis is not None and (self.frequency or self.run is not None):
                raise ValueError("give either axis (with pulses_per_unit) or frequency "
                                 "(with run), not both")
            if self.tick <= 0:
                raise ValueError("tick must be > 0")
            return self

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.position = 0.0  # in A periods; a rising edge of A at each integer
        self._axis_pos = 0.0
        self._axis: AxisDevice | None = None
        self._counting: Any = None

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        o = self.options
        self._i = mem.i_field
        self._a = self.io_index(mem, o.a, "I", "a")
        self._b = None if o.b is None else self.io_index(mem, o.b, "I", "b")
        self._run = None if o.run is None else self.io_index(mem, o.run, "Q", "run")
        self._q = mem.q_field
        if o.axis is not None:
            self._axis = self.peer(devices, o.axis, AxisDevice, "axis")
            self._axis_pos = self._axis.axis_position()
            self.position = self._axis_pos * o.pulses_per_unit
        counting = mem.counting
        self._counting = counting if counting is not None and counting.listens(self._a) \
            else None
        self._levels(1)

    def reset(self) -> None:
        self.position = 0.0
        if self._axis is not None:
            self._axis_pos = self._axis.axis_position()
            self.position = self._axis_pos * self.options.pulses_per_unit

    @property
    def pulses(self) -> int:
        return math.floor(self.position)

    def _levels(self, direction: int) -> None:
        frac = self.position - math.floor(self.position)
        self._i[self._a] = frac < 0.5
        if self._b is not None:
            if self.options.signal == "quadrature":  # B a quarter period behind A going up
                self._i[self._b] = (frac - 0.25) % 1.0 < 0.5
            else:
                self._i[self._b] = direction > 0

    def update(self, t: float, dt: float) -> None:
        o = self.options
        if self._axis is not None:
            new = self._axis.axis_position()
            start, rate = self.position, (new - self._axis_pos) * o.pulses_per_unit
            self._axis_pos = new
        else:
            running = self._run is None or self._q[self._run]
            start, rate = self.position, (o.frequency * dt if running else 0.0)
        if not rate:
            return
        direction = 1 if rate > 0 else -1
        steps = max(1, math.ceil(dt / o.tick - 1e-9))
        sub = dt / steps
        t0 = t - dt
        prev = math.floor(start)
        counting = self._counting
        for k in range(1, steps + 1):
            self.position = start + rate * k / steps
            now = math.floor(self.position)
            if now != prev and counting is not None:
                # rising edges of A crossed in this tick (A rises at each integer position)
                # (no B wired: the counter reads its own direction input)
                counting.feed(self._a, abs(now - prev), direction if self._b is not None
                              else None, t0 + k * sub, sub)
            prev = now
        self._levels(direction)

    def status(self) -> dict[str, Any]:
        return {"pulses": self.pulses}
