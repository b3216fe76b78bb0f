"""The pen lift (the seed's "Y axis": a DC motor that lowers and lifts the pen).

TOML options, table `[devices.NAME]` with `type = "pen"`:

- `output` (required): the `%Q` output that drives it, energised = pen down, e.g.
  `"%Q0.14"`.
- `lower_delay` (duration, default "0ms"): how long the output must have been on
  before the pen touches the paper, e.g. `"50ms"`.
- `lift_delay` (duration, default "0ms"): how long it must have been off before
  the pen leaves the paper.

Attributes: `down` (the pen is on the paper), `moves` (how many times it went down or up).
"""

from __future__ import annotations

from typing import Any

from softplc.config import Address, Duration, Section
from softplc.devices.base import Device, register_device
from softplc.runtime.memory import MemoryImage


@register_device("pen")
class Pen(Device):
    STATE = ("down", "moves", "_cmd", "_t_cmd", "_settled")

    class Options(Section):
        output: Address
        lower_delay: Duration = 0.0
        lift_delay: Duration = 0.0

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.output = options.output
        self.lower_delay = options.lower_delay
        self.lift_delay = options.lift_delay
        self._q: list[bool] | None = None
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


@register_device("torch")
class Torch(Pen):
    """The cutting torch: the pen device under the cutting table's names. Options `output`
    (energised = cutting), `ignition_delay` (duration before the flame cuts, default
    "0ms") and `extinction_delay` (duration before it stops cutting, default "0ms");
    attribute `lit` (= `down`)."""

    class Options(Section):  # type: ignore[assignment]
        output: Address
        ignition_delay: Duration = 0.0
        extinction_delay: Duration = 0.0

    def __init__(self, name: str, options: Options):  # type: ignore[override]
        super().__init__(name, Pen.Options.model_construct(output=options.output,
                                           lower_delay=options.ignition_delay,
                                           lift_delay=options.extinction_delay))
        self.options = options

    @property
    def lit(self) -> bool:
        return self.down

    def status(self) -> dict[str, Any]:
        return {"lit": self.down}
