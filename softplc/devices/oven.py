"""An electric oven: a first-order-plus-dead-time thermal process driven by an analog
output (heater power) or a digital output (heater on/off, e.g. PID's PWM), measured by an
analog input (a temperature sensor channel).

    dT/dt = (ambient + gain * u(t - dead_time) - T) / tau,   u = heater power 0..1

TOML options, table `[devices.NAME]` with `type = "oven"`:

- `sensor` (required): the analog input the temperature drives, e.g. `"%IW2.0"` (its
  `[analog]` entry sets how degrees become a word: PT100 in celsius = tenths of a degree).
- `heater` (an analog output such as `"%QW1.0"`: power = its signal over the signal's
  span, 0-10 V -> 0..1) or `heater_bit` (a `%Q` output: power 1 while on; on an output
  driven by a `%PWM`/`%PLS` the power is its duty cycle, read through the runtime's pulse
  interface, `softplc/runtime/pulse.py`); one of them.
- `gain` (degrees C at full power above ambient, -1e6..1e6, default 200.0), `tau` (time
  constant, seconds, up to 1e6, default 60.0), `dead_time` (seconds, 0..600, default
  5.0), `ambient` (degrees C, -273..1e4, default 20.0), `start` (initial temperature,
  default ambient).

Attributes: `temperature` (degrees C), `power` (the heater power now, 0..1).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

from pydantic import Field, model_validator

from softplc.config import Address, FiniteFloat, Section
from softplc.devices.base import Device, register_device
from softplc.errors import AddressError, ConfigCode
from softplc.runtime.analog import SIGNAL_SPAN, AnalogChannel
from softplc.runtime.memory import MemoryImage
from softplc.twido.address import parse_address

MAX_DEAD_TIME_S = 600.0  # ten minutes: 600,000 values at a 1 ms scan


@register_device("oven")
class Oven(Device):
    # not the heater's dead-time queue `_delay` (mutable): `back` leaves it as it is
    STATE = ("temperature", "power")

    # physical constants in plain units (degrees C, seconds), as in the process model above
    class Options(Section):
        sensor: Address
        heater: Address | None = None
        heater_bit: Address | None = None
        gain: FiniteFloat = Field(200.0, ge=-1e6, le=1e6)
        tau: FiniteFloat = Field(60.0, ge=1e-6, le=1e6)
        # the heater's history is kept for the dead time, one value a scan: bounded
        dead_time: FiniteFloat = Field(5.0, ge=0.0, le=MAX_DEAD_TIME_S)
        ambient: FiniteFloat = Field(20.0, ge=-273.0, le=1e4)
        start: FiniteFloat | None = Field(None, ge=-273.0, le=1e4)

        @model_validator(mode="after")
        def _one_heater(self) -> Any:
            if (self.heater is None) == (self.heater_bit is None):
                raise ValueError("give one of heater (a %QW) or heater_bit (a %Q)")
            return self

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        o = options
        self.sensor, self.heater, self.heater_bit = o.sensor, o.heater, o.heater_bit
        self.gain, self.tau, self.dead_time = o.gain, o.tau, o.dead_time
        self.ambient = o.ambient
        self.start = self.ambient if o.start is None else o.start
        self._mem: MemoryImage | None = None
        self.reset()

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._mem = mem
        analog = mem.analog
        # the channels looked up once, not per scan (an address parsed per scan was most
        # of the oven's cost)
        chans: dict[str, AnalogChannel] = {}
        for option, addr, kind in (("sensor", self.sensor, "IW"), ("heater", self.heater, "QW")):
            if addr is None:
                continue
            try:
                ref = parse_address(str(addr), mem.profile)
            except AddressError as e:
                raise self.problem(option, str(e), ConfigCode.ADDRESS) from None
            if analog is None or ref not in analog.channels or ref.kind != kind:
                raise self.problem(option, f"{addr!r} is not a configured analog "
                                   f"{'input' if kind == 'IW' else 'output'}",
                                   ConfigCode.MODULE)
            chans[option] = analog.channels[ref]
        self._sensor_ch = chans["sensor"]
        self._heater_ch = chans.get("heater")
        if self._heater_ch is not None:
            self._span = SIGNAL_SPAN[self._heater_ch.signal]
        self._pulse = None
        if self.heater_bit is not None:
            self._bit = self.io_index(mem, self.heater_bit, "Q", "heater_bit")
            if mem.pulses is not None:  # a PWM heater: mean power = duty cycle
                self._pulse = mem.pulses.source(self._bit)
        self._write_sensor()

    def reset(self) -> None:
        self.temperature = self.start
        self.power = 0.0
        self._delay: deque[float] = deque()

    def _heater_power(self) -> float:
        mem = self._mem
        if self._pulse is not None:
            return self._pulse.duty()
        if self.heater_bit is not None:
            return 1.0 if mem.q_field[self._bit] else 0.0
        a, b = self._span
        return (mem.analog.signal(self._heater_ch) - a) / (b - a)

    def _write_sensor(self) -> None:
        self._mem.analog.drive(self._sensor_ch, self.temperature)

    def update(self, t: float, dt: float) -> None:
        self.power = self._heater_power()
        self._delay.append(self.power)
        n = max(1, round(self.dead_time / dt)) if self.dead_time > 0 else 0
        u = self._delay.popleft() if len(self._delay) > n else 0.0
        # exact discretisation of the first-order lag over dt (stable for any dt)
        target = self.ambient + self.gain * u
        k = dt / self.tau
        self.temperature = target + (self.temperature - target) * math.exp(-k)
        self._write_sensor()

    def status(self) -> dict[str, Any]:
        return {"temperature": round(self.temperature, 2), "power": round(self.power, 3)}
