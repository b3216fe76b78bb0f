"""The function-block classes by address kind: `%TM0` is a `Timer`, `%VFC0` a
`VeryFastCounter`... Each block's module defines its class (and its input pins, `PINS`,
once); this module gathers them, so imports point one way: catalog -> blocks, fastcount,
pulse -> the base classes in blocks."""

from __future__ import annotations

from .blocks import Block, Counter, Drum, Message, Register, ShiftRegister, StepCounter, Timer
from .fastcount import FastCounter, VeryFastCounter
from .pulse import PulseGenerator, PwmOutput

BLOCK_CLASSES: dict[str, type[Block]] = {
    "TM": Timer, "C": Counter, "DR": Drum, "SBR": ShiftRegister, "SC": StepCounter,
    "R": Register, "MSG": Message,
    "FC": FastCounter, "VFC": VeryFastCounter,  # fast counters (runtime/fastcount.py)
    "PLS": PulseGenerator, "PWM": PwmOutput,  # pulse outputs (runtime/pulse.py)
}
