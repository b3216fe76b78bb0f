"""Limit switches on an axis (a stepper or a servo axis: any `AxisDevice`).

TOML options, table `[devices.NAME]` with `type = "limit_switch"`:

- `axis` (required): name of the axis device the switch watches (`stepper` or
  `servo_axis`), e.g. `"X"`.
- `input` (required): the `%I` input the switch is wired to, e.g. `"%I0.12"`.
- `at` (default `"home"`): `"home"` is made while the axis position <= 0; `"end"` is made
  while the position >= the axis's end: a stepper's travel * steps_per_unit (e.g. 25.0 *
  111.11 = 2777.75, so from step 2778 on), a servo axis's `geometry.limit_plus` (counts).
- `normally_closed` (bool, default false): the input is on while the switch is NOT made.
- `fault` (default `"none"`): `"stuck_open"` (never made: a broken wire) or
  `"stuck_closed"` (always made), to test what a program does with a broken switch.

A switch stops nothing by itself: the program must. The mechanical hard stops a little
beyond each end are the stepper's (`hard_stop_margin`). The switch writes its input in
`bind` (so the first scan already sees it) and after every scan. Attribute: `made`.
"""

from __future__ import annotations

import math
from typing import Any, Literal, get_args

from pydantic import Field

from softplc.config import Address, Section
from softplc.devices.base import AxisDevice, Device, register_device
from softplc.runtime.memory import MemoryImage

Fault = Literal["none", "stuck_open", "stuck_closed"]
FAULTS: tuple[str, ...] = get_args(Fault)


@register_device("limit_switch")
class LimitSwitch(Device):
    STATE = ("fault", "_sign", "_thr")

    class Options(Section):
        axis: str = Field(min_length=1)
        input: Address
        at: Literal["home", "end"] = "home"
        normally_closed: bool = False
        fault: Fault = "none"

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.input = options.input  # the web monitor finds the wiring by this attribute
        self.normally_closed = options.normally_closed
        self.fault = "none"
        self._axis: AxisDevice | None = None
        self._i: list[bool] | None = None
        self._idx = 0

    def _check_fault(self, fault: Any) -> None:
        if fault not in FAULTS:
            raise self.problem("fault", f"expected one of {', '.join(FAULTS)} (got "
                               f"{fault!r})")

    def set_fault(self, fault: str) -> None:
        """Break (or repair, with "none") the switch at run time."""
        self._check_fault(fault)
        self.fault = fault
        # made <=> sign * position >= thr; a stuck switch is a
        # threshold nothing (or everything) reaches, so update stays one comparison.
        if fault == "stuck_open":
            self._sign, self._thr = 1, math.inf
        elif fault == "stuck_closed":
            self._sign, self._thr = 1, -math.inf
        elif self.options.at == "home":
            self._sign, self._thr = -1, 0
        else:
            assert self._axis is not None
            self._sign, self._thr = 1, self._axis.axis_end()

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._axis = self.peer(devices, self.options.axis, AxisDevice, "axis")
        self._pos = self._axis.axis_position
        self._idx = self.io_index(mem, self.input, "I", "input")
        self._i = mem.i_field
        self.set_fault(self.options.fault)
        self.update(0.0, 0.0)

    def reset(self) -> None:
        if self._axis is not None:
            self.set_fault(self.options.fault)
            self.update(0.0, 0.0)

    def update(self, t: float, dt: float) -> None:
        self._i[self._idx] = (self._sign * self._pos() >= self._thr) ^ self.normally_closed

    @property
    def made(self) -> bool:
        return self._sign * self._pos() >= self._thr

    def status(self) -> dict[str, Any]:
        return {"made": self.made}


@register_device("push_button")
class PushButton(Device):
    """A push button or E-stop on an `%I` input. Options: `input` (required),
    `normally_closed` (default false: the input is on while pressed; an E-stop is
    normally closed, so its input is on while released and a broken wire reads as
    pressed), `pressed` (default false: the state at power-up). `press()` / `release()`
    operate it at run time (tests, the debugger)."""

    STATE = ("pressed",)

    class Options(Section):
        input: Address
        normally_closed: bool = False
        pressed: bool = False

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.input = options.input
        self.normally_closed = options.normally_closed
        self.pressed = options.pressed
        self._i: list[bool] | None = None
        self._idx = 0

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._idx = self.io_index(mem, self.input, "I", "input")
        self._i = mem.i_field
        self.update(0.0, 0.0)

    def reset(self) -> None:
        self.pressed = self.options.pressed
        if self._i is not None:
            self.update(0.0, 0.0)

    def press(self) -> None:
        self.pressed = True

    def release(self) -> None:
        self.pressed = False

    def update(self, t: float, dt: float) -> None:
        self._i[self._idx] = bool(self.pressed ^ self.normally_closed)  # type: ignore[index]

    def status(self) -> dict[str, Any]:
        return {"pressed": self.pressed}
