"""The catalog of Twido object families: one data-only entry per function-block family
(%TM, %C, %DR, ... %VFC, and the PID functions), read by every layer that must know a
family: the address syntax (`address.py`: fields and the regex of kinds), the bindings
table (`program.py`), the profile counts (`profile.py`), the compiler (`compiler/values.py`:
pins and outputs), the block set-up (`assembly/blocks.py`: configuration section, model,
set-up hooks), the symbol table, the rung structure, online change, the verifier (each
family's model, dispatched by kind) and the debugger's listings.

The catalog is the bottom of the package: it imports nothing of softplc, so `address.py`
(which the runtime imports) may read it. What lives above it is named by a
"module:attribute" string and imported on first use (`Family.block_class`,
`Family.config_model`, `Family.verify_model`, `resolve`): the runtime class, the
configuration model, the set-up hooks and the verify model of a family live in its one
module (`softplc/blocks/` for the basic ones), and a string keeps the catalog below them
without a registration step that would depend on import order.

A new function block: its module (the block class with its `PINS`, its configuration model,
set-up function and verify model) and one `Family` entry below; see CONTRIBUTING.md,
"Adding a function block".
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from functools import cache
from typing import Any

BOOL, INT16 = "bool", "int16"  # the value types of `address.py`


@dataclass(frozen=True)
class Family:
    """One family of Twido objects (`%VFC0`, `%VFC1`... are one family)."""

    kind: str  # the address prefix: "VFC" in %VFC0
    title: str  # what users call one: "very fast counter" (messages, the ladder's label)
    runtime: str  # "module:Class" of the runtime block class (its `PINS` are its pins)
    count: int  # how many on the TWDLCAE40DRF (the profile's count of `kind`) [manual]
    # address fields -> (value type, writable by the program); None: not an address
    # (`PID n` is an instruction, not an object)
    fields: Mapping[str, tuple[str, bool]] | None = field(default_factory=dict)
    bits: int = 0  # bit objects %SBRi.j: how many per block
    instruction: str = ""  # an IL instruction `[ KEYWORD n ]` runs block n (PID)
    # configuration: its table (section name), the pydantic model of one entry
    # ("module:Class", None: typed by `config.Config` itself), the set-up function
    # `setup(ctx, family, entries)` creating the configured blocks, and `finish(ctx)`,
    # called once after every set-up, which attaches the scan-time hooks (the engine's
    # before-scan poll, the pulse outputs' update)
    section: str = ""
    model: str | None = None
    setup: str | None = None
    finish: str | None = None
    online: bool = False  # an online change may alter its section (block by block)
    # used by the program but not configured: the hint saying what to configure (a
    # str.format template of `ref`, `section`, `title`, `q`: its pulse output channel), or, if
    # empty, the default block: `default(profile)` ("module:function") or the class's own
    default: str | None = None
    unconfigured: str = ""
    pulse_output: bool = False  # drives one of the profile's `pulse_outputs` (%Q0.i)
    clamp_preset: bool = False  # a store to .P is clamped to 0 .. MAX_VALUE (%TM, %C)
    in_blk_hint: bool = False  # named in the hint of what BLK takes
    listing: str = ""  # the debugger command listing it ("timers", "counters")
    # its model for `softplc verify` ("module:attribute" of a `softplc.blocks.BlockModel`:
    # its state and its rule over a value domain); None: the verifier does not model it
    verify: str | None = None

    @property
    def addressable(self) -> bool:
        return self.fields is not None

    @property
    def block_class(self) -> Any:
        return resolve(self.runtime)

    @property
    def pins(self) -> tuple[str, ...]:
        """Input pins, as the runtime class declares them (its pin methods follow them)."""
        return tuple(getattr(self.block_class, "PINS", ()))

    @property
    def outputs(self) -> tuple[str, ...]:
        """Bit outputs: the read-only bit fields (the writable %VFCi.R / .S are enables)."""
        return tuple(f for f, (t, w) in (self.fields or {}).items() if t == BOOL and not w)

    def config_model(self) -> Any:
        return resolve(self.model) if self.model else None

    def verify_model(self) -> Any:
        return resolve(self.verify) if self.verify else None


@cache
def resolve(target: str) -> Any:
    """"package.module:attribute" -> the attribute (imported on first use)."""
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


_RT, _FC, _PL = "softplc.runtime", "softplc.runtime.fastcount", "softplc.runtime.pulse"
_B = "softplc.blocks"  # the basic blocks, one module each
_RW, _RO, _BW = (INT16, True), (INT16, False), (BOOL, False)
_COUNTER_HINT = ('counter {ref} is used but not configured: add [{section}."{ref}"] with its '
                 "mode (TwidoSuite's counter screen)")
# TwidoSuite configures the output as one
_PULSE_HINT = ('{ref} is used but not configured: %Q0.{q} must be configured as a {title}, '
               'e.g. {section}."{ref}" = {{base = "10ms", preset = 100}}')

# The families (this order: the memory image's, hence the state file's). Counts and fields
# [manual] unless said otherwise.
FAMILIES: dict[str, Family] = {f.kind: f for f in (
    Family("TM", "timer", f"{_B}.timer:Timer", 128, {"Q": _BW, "V": _RO, "P": _RW},
           section="timers", model=f"{_B}.timer:TimerConfig", setup=f"{_B}.timer:setup",
           verify=f"{_B}.timer:MODEL", online=True, clamp_preset=True, in_blk_hint=True,
           listing="timers",
           unconfigured='timer {ref} is used but not configured: give its type, time base '
                        'and preset, e.g. timers = {{"{ref}" = {{type = "TON", '
                        'base = "100ms", preset = 10}}}}'),
    Family("C", "counter", f"{_B}.counter:Counter", 128,
           {"V": _RO, "P": _RW, "D": _BW, "E": _BW, "F": _BW},
           section="counters", model=f"{_B}.counter:CounterConfig",
           setup=f"{_B}.counter:setup", verify=f"{_B}.counter:MODEL", online=True,
           clamp_preset=True, in_blk_hint=True, listing="counters"),
    Family("DR", "drum", f"{_B}.drum:Drum", 8, {"S": _RO, "F": _BW},
           section="drums", model=f"{_B}.drum:DrumConfig", setup=f"{_B}.drum:setup",
           verify=f"{_B}.drum:MODEL", online=True, in_blk_hint=True,
           unconfigured='drum {ref} is used but not configured ({section}."{ref}".steps)'),
    Family("SBR", "shift register", f"{_B}.shift:ShiftRegister", 8, bits=16,
           verify=f"{_B}.shift:SHIFT_MODEL", in_blk_hint=True),
    Family("SC", "step counter", f"{_B}.shift:StepCounter", 8, bits=256,
           verify=f"{_B}.shift:STEP_MODEL", in_blk_hint=True),
    Family("R", "register", f"{_B}.register:Register", 4,
           {"I": _RW, "O": _RW, "E": _BW, "F": _BW},
           section="registers", model=f"{_B}.register:RegisterConfig",
           setup=f"{_B}.register:setup", verify=f"{_B}.register:MODEL", online=True,
           in_blk_hint=True, default=f"{_B}.register:default"),
    # pulse outputs (issue 11 B, runtime/pulse.py) on the profile's transistor outputs
    Family("PLS", "pulse generator", f"{_PL}:PulseGenerator", 2,
           {"Q": _BW, "D": _BW, "P": _RW, "N": _RW},
           section="pls", model=f"{_PL}:PlsConfig", setup=f"{_PL}:setup_pulses",
           finish=f"{_PL}:finish_pulses", pulse_output=True,
           unconfigured=_PULSE_HINT),
    Family("PWM", "PWM output", f"{_PL}:PwmOutput", 2, {"P": _RW, "R": _RW},
           section="pwm", model=f"{_PL}:PwmConfig", setup=f"{_PL}:setup_pulses",
           finish=f"{_PL}:finish_pulses", pulse_output=True,
           unconfigured=_PULSE_HINT),
    # fast counters (runtime/fastcount.py) [manual, from memory of TWD USE 10AE]
    Family("FC", "fast counter", f"{_FC}:FastCounter", 4,
           {"V": _RO, "P": _RW, "D": _BW},
           section="fast_counters", model=f"{_FC}:FastCounterConfig",
           setup=f"{_FC}:setup_counters", finish=f"{_FC}:finish_counters",
           listing="counters",
           unconfigured=_COUNTER_HINT),
    Family("VFC", "very fast counter", f"{_FC}:VeryFastCounter", 2,
           {"V": _RO, "P": _RW, "U": _BW, "C": _RO, "S0": _RW, "S1": _RW, "F": _BW,
            "TH0": _BW, "TH1": _BW, "R": (BOOL, True), "S": (BOOL, True), "T": _RW},
           section="very_fast_counters", model=f"{_FC}:VeryFastCounterConfig",
           setup=f"{_FC}:setup_counters", finish=f"{_FC}:finish_counters",
           listing="counters",
           unconfigured=_COUNTER_HINT),
    # communication (issue 11 B, runtime/exch.py): %MSG1..%MSG3 (index 0 unused)
    Family("MSG", "exchange block", f"{_RT}.exch:Message", 4, {"D": _BW, "E": _BW}),
    # PID functions PID 0 .. PID 13 [manual, from memory]
    Family("PID", "PID function", "softplc.runtime.pid:Pid", 14, None, instruction="PID",
           section="pid", model="softplc.runtime.pid:PidConfig",
           setup="softplc.runtime.pid:setup"),
)}


def family(kind: str) -> Family:
    return FAMILIES[kind]


def addressable() -> Iterator[Family]:
    """The families that are objects of the address syntax (%TM0.Q, %VFC1.S0...)."""
    return (f for f in FAMILIES.values() if f.addressable)


def by_instruction() -> dict[str, Family]:
    """IL keyword -> the family its instruction runs (`PID` -> the PID functions)."""
    return {f.instruction: f for f in FAMILIES.values() if f.instruction}


def listed_in(command: str) -> list[Family]:
    return [f for f in FAMILIES.values() if f.listing == command]
