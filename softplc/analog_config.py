"""The `[analog]` configuration section: one entry per analog channel, as TwidoSuite's
module configuration screen sets it (signal type and range of each channel).

    modules = { 1 = "TWDAMM3HT", 2 = "TWDALM3LT" }
    analog."%IW1.0" = { type = "4-20mA", range = "custom", min = 0, max = 1000 }
    analog."%IW1.1" = { type = "0-10V" }                       # normal: 0..4095
    analog."%QW1.0" = { type = "0-10V" }
    analog."%IW2.0" = { type = "PT100", range = "celsius" }    # tenths of a degree
    analog."%IW0.0" = { type = "pot" }                         # the base's potentiometer

Channels of a configured analog module that the section does not name get the module's
first signal type and the normal range; the base's inputs get their profile type.
Pydantic v2 models with `extra="forbid"` (a misspelt key is an error); `parse_analog` turns
a validation error into a `ConfigError` naming the key path.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from .errors import ConfigError
from .runtime.analog import SIGNAL_SPAN, TEMPERATURE_TYPES

Signal = Literal["0-10V", "4-20mA", "pot", "PT100", "J", "K", "T"]


class AnalogChannelConfig(BaseModel):
    """One channel: `type`, `range`, and `min`/`max` for a custom range."""

    model_config = ConfigDict(extra="forbid")

    type: Signal
    range: Literal["normal", "custom", "celsius", "fahrenheit"] = "normal"
    min: int = Field(0, ge=-32768, le=32767)
    max: int = Field(4095, ge=-32768, le=32767)

    @model_validator(mode="after")
    def _consistent(self) -> AnalogChannelConfig:
        if self.range in ("celsius", "fahrenheit") and self.type not in TEMPERATURE_TYPES:
            raise ValueError(f"range {self.range!r} is for temperature sensors "
                             f"({', '.join(TEMPERATURE_TYPES)}), not {self.type}")
        if self.range == "custom" and self.min == self.max:
            raise ValueError("a custom range needs min != max")
        if self.range != "custom" and {"min", "max"} & self.model_fields_set:
            raise ValueError("min/max apply to range = \"custom\" only")
        return self


assert set(SIGNAL_SPAN) == set(Signal.__args__)  # one list of signal types


def parse_analog(section: Any) -> dict[str, AnalogChannelConfig]:
    """Validate the `[analog]` table: address -> channel config."""
    if not isinstance(section, dict):
        raise ConfigError(f"analog must be a table of channels, not {section!r}")
    out = {}
    for addr, table in section.items():
        try:
            out[addr] = AnalogChannelConfig.model_validate(table)
        except ValidationError as e:
            err = e.errors()[0]
            where = ".".join(str(p) for p in err["loc"])
            key = f"analog.{addr}" + (f".{where}" if where else "")
            raise ConfigError(f"{key}: {err['msg']} (got {err.get('input')!r})") from None
    return out
