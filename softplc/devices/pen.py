"""The pen lift (the seed's "Y axis": a DC motor that lowers and lifts the pen).

TOML options, table `[devices.NAME]` with `type = "pen"`:

- `output` (required): the `%Q` output that drives it, energised = pen down, e.g.
  `"%Q0.14"`.
- `lower_delay` (float >= 0 seconds, default 0.0): how long the output must have been on
  before the pen touches the paper.
- `lift_delay` (float >= 0 seconds, default 0.0): how long it must have been off before
  the pen leaves the paper.

Attributes: `down` (the pen is on the paper), `moves` (how many times it went down or up).
"""

from __future__ import annotations

from typing import Any

from ..errors import ConfigError
from ..runtime.memory import MemoryImage
from .base import Device, register_device


@register_device("pen")
class Pen(Device):
    STATE = ("down", "moves", "_cmd", "_t_cmd", "_settled")

    def __init__(self, name: str, *, output: Any, lower_delay: Any = 0.0,
                 lift_delay: Any = 0.0):
        super().__init__(name)
        for option, v in (("lower_delay", lower_delay), ("lift_delay", lift_delay)):
            if isinstance(v, bool) or not isinstance(v, int | float) or not v >= 0:
                raise ConfigError(f"device {name!r}: {option} must be a number of seconds "
                                  f">= 0, not {v!r}")
        self.output = output
        self.lower_delay = float(lower_delay)
        self.lift_delay = float(lift_delay)
        self._q: list[int] | None = None
        self._idx = 0
        self.reset()

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._idx = self.io_index(mem, self.output, "Q", "output")
        self._q = mem.q_field

    def reset(self) -> None:
        self.down = False
        self.moves = 0
        self._cmd = 0  # last output value seen
        self._t_cmd = 0.0  # when it last changed
        self._settled = True  # the pen is where the output wants it

    def update(self, t: float, dt: float) -> None:
        c = self._q[self._idx]
        if c == self._cmd and self._settled:
            return
        if c != self._cmd:
            self._cmd = c
            self._t_cmd = t
        want = c != 0
        if want == self.down:
            self._settled = True
            return
        delay = self.lower_delay if want else self.lift_delay
        # a hair of tolerance: t is a float sum of scan periods
        self._settled = t - self._t_cmd >= delay - 1e-9
        if self._settled:
            self.down = want
            self.moves += 1

    def status(self) -> dict[str, Any]:
        return {"down": self.down}
