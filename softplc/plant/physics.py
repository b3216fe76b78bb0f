"""Shared devices of a plant: physical models that several controllers see or drive.

A controller's own devices (`[devices]` of its configuration, softplc.devices) sit on its
memory image. A shared device has named signals instead, which the plant's wires connect
to controllers' inputs and outputs: `INPUTS` are what it is driven by (a motor contactor,
a stop gate), `OUTPUTS` what it shows (a photo-eye). The plant calls `update(t, dt)` every
device tick, after copying the wires into the device and before copying its outputs out.

A new shared device: a subclass with its `Options` (a pydantic `Section`), `INPUTS` /
`OUTPUTS` (`signals()` when they depend on the options), `update`, `state`/`set_state`,
registered in `SHARED_DEVICES`.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import Field, ValidationInfo, field_validator

from softplc.config import FiniteFloat, PositiveDuration, Section

MAX_LENGTH_M = 1_000.0  # a conveyor longer than a kilometre is a typing error
MAX_STATIONS = 16  # stations or sensors on one conveyor (bounds the signal table)


class SharedDevice:
    """A physical model with named boolean signals."""

    type_name: ClassVar[str] = "device"

    class Options(Section):
        """No options."""

    def __init__(self, name: str, options: Any):
        self.name = name
        self.options = options
        ins, outs = self.signals()
        self.inputs: dict[str, bool] = dict.fromkeys(ins, False)
        self.outputs: dict[str, bool] = dict.fromkeys(outs, False)

    def signals(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(input signals, output signals) of this device."""
        return (), ()

    def update(self, t: float, dt: float) -> None:
        """Read `inputs`, move the physics on by dt seconds to time t, write `outputs`."""

    def state(self) -> dict[str, Any]:
        return {}

    def set_state(self, st: dict[str, Any]) -> None:
        """Back to a `state()`."""

    def status(self) -> dict[str, Any]:
        return {}


class Conveyor(SharedDevice):
    """A belt carrying boxes from position 0 to `length` (metres) at `speed` (m/s) while
    its `run` input is on. A new box is put on at the start every `feed_every` seconds when
    there is room. Each station `S` has a stop gate (input `hold_S`: a box reaching the
    station stops there while it is on) and a photo-eye (output `at_S`: a box covers the
    station point); each sensor `N` is a photo-eye (output `N`). Boxes queue behind each
    other `gap` apart (so a photo-eye sees each one go); `delivered` counts the boxes that
    left the end."""

    type_name = "conveyor"

    class Options(Section):
        length: FiniteFloat = Field(gt=0, le=MAX_LENGTH_M)
        speed: FiniteFloat = Field(gt=0, le=MAX_LENGTH_M)
        box: FiniteFloat = Field(0.2, gt=0, le=MAX_LENGTH_M)
        gap: FiniteFloat = Field(0.1, ge=0, le=MAX_LENGTH_M)
        feed_every: PositiveDuration = 2.0
        stations: dict[str, FiniteFloat] = Field(default_factory=dict, max_length=MAX_STATIONS)
        sensors: dict[str, FiniteFloat] = Field(default_factory=dict, max_length=MAX_STATIONS)

        @field_validator("stations", "sensors")
        @classmethod
        def _on_the_belt(cls, v: dict[str, float], info: ValidationInfo) -> dict[str, float]:
            length = info.data.get("length")
            for key, pos in v.items():
                if length is not None and not 0 <= pos <= length:
                    raise ValueError(f"{key} at {pos} m is off the belt (0 .. {length} m)")
            if set(v) & set(info.data.get("stations", {})):
                raise ValueError("a name is either a station or a sensor")
            return v

    def __init__(self, name: str, options: Options):
        super().__init__(name, options)
        self.boxes: tuple[float, ...] = ()  # box fronts, leading box first
        self.fed = 0
        self.delivered = 0
        self.next_feed = 0.0

    def signals(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        o = self.options
        return (("run", *(f"hold_{s}" for s in o.stations)),
                (*(f"at_{s}" for s in o.stations), *o.sensors))

    def update(self, t: float, dt: float) -> None:
        o = self.options
        boxes = list(self.boxes)
        if self.inputs["run"]:
            gates = [p for s, p in o.stations.items() if self.inputs[f"hold_{s}"]]
            moved: list[float] = []
            for front in boxes:
                new = front + o.speed * dt
                for p in gates:  # a raised gate stops the box front at its point
                    if front <= p < new:
                        new = p
                if moved:  # queued boxes keep `gap` between them
                    new = min(new, moved[-1] - o.box - o.gap)
                moved.append(max(front, new))
            boxes = moved
        kept = [f for f in boxes if f - o.box < o.length]
        self.delivered += len(boxes) - len(kept)
        boxes = kept
        if t >= self.next_feed:
            if not boxes or boxes[-1] - o.box >= o.box + o.gap:  # room for one at the start
                boxes.append(o.box)
                self.fed += 1
                self.next_feed = t + o.feed_every
        self.boxes = tuple(boxes)
        for s, p in o.stations.items():
            self.outputs[f"at_{s}"] = self._covered(p)
        for s, p in o.sensors.items():
            self.outputs[s] = self._covered(p)

    def _covered(self, p: float) -> bool:
        box = self.options.box
        return any(f - box <= p <= f for f in self.boxes)

    def state(self) -> dict[str, Any]:
        return {"boxes": self.boxes, "fed": self.fed, "delivered": self.delivered,
                "next_feed": self.next_feed}

    def set_state(self, st: dict[str, Any]) -> None:
        self.boxes, self.fed = st["boxes"], st["fed"]
        self.delivered, self.next_feed = st["delivered"], st["next_feed"]

    def status(self) -> dict[str, Any]:
        return {"boxes": len(self.boxes), "fed": self.fed, "delivered": self.delivered}


SHARED_DEVICES: dict[str, type[SharedDevice]] = {c.type_name: c for c in (Conveyor,)}
