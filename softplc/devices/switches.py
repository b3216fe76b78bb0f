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
from typing import Any

from ..errors import ConfigError
from ..runtime.memory import MemoryImage
from .base import AxisDevice, Device, register_device

FAULTS = ("none", "stuck_open", "stuck_closed")


@register_device("limit_switch")
class LimitSwitch(Device):
    STATE = ("fault", "_sign", "_thr")

    def __init__(self, name: str, *, axis: Any, input: Any, at: Any = "home",
                 normally_closed: Any = False, fault: Any = "none"):
        super().__init__(name)
        if at not in ("home", "end"):
            raise ConfigError(f"device {name!r}: at must be \"home\" or \"end\", not {at!r}")
        if not isinstance(normally_closed, bool):
            raise ConfigError(f"device {name!r}: normally_closed must be true or false")
        self.axis_name = axis
        self.input = input
        self.at = at
        self.normally_closed = normally_closed
        self.fault = "none"
        self._fault0 = fault
        self._axis: AxisDevice | None = None
        self._i: list[int] | None = None
        self._idx = 0
        self._check_fault(fault)

    def _check_fault(self, fault: Any) -> None:
        if fault not in FAULTS:
            raise ConfigError(f"device {self.name!r}: fault must be one of "
                              f"{', '.join(FAULTS)}, not {fault!r}")

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
        elif self.at == "home":
            self._sign, self._thr = -1, 0
        else:
            assert self._axis is not None
            self._sign, self._thr = 1, self._axis.axis_end()

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._axis = self.peer(devices, self.axis_name, AxisDevice, "axis")
        self._pos = self._axis.axis_position
        self._idx = self.io_index(mem, self.input, "I", "input")
        self._i = mem.i_field
        self.set_fault(self._fault0)
        self.update(0.0, 0.0)

    def reset(self) -> None:
        if self._axis is not None:
            self.set_fault(self._fault0)
            self.update(0.0, 0.0)

    def update(self, t: float, dt: float) -> None:
        self._i[self._idx] = (self._sign * self._pos() >= self._thr) ^ self.normally_closed

    @property
    def made(self) -> bool:
        return self._sign * self._pos() >= self._thr

    def status(self) -> dict[str, Any]:
        return {"made": self.made}
