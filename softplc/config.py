"""Configuration: a dict or a TOML file with the same keys.

    scan_period = "10ms"     # virtual scan length / periodic-mode period
    watchdog = "150ms"       # %SW11
    profile = "TWDLCAE40DRF"
    timers."%TM0" = { type = "TON", base = "10ms", preset = 50 }
    counters."%C0" = { preset = 10 }
    drums."%DR0" = { steps = [1, 2, 4], outputs = ["%Q0.0", "%Q0.1", "%Q0.2"] }
    registers."%R0" = { type = "FIFO" }
    constants = { "%KW0" = 100, "%KF2" = 1.5 }
    modules = { 1 = "TM2DDO8TT" }    # expansion modules; when given, I/O addresses are checked
    analog."%IW2.0" = { type = "PT100", range = "celsius" }   # analog channels
    [pid.0]                  # PID functions, [rtc] the clock's calendar start,
    [schedule.0]             # schedule blocks: see softplc/config_models.py
    [devices.NAME]           # simulated machine (softplc.devices): type = "...", options
    [modbus]                 # the daemon's server options (softplc run)
    [daemon]                 # the daemon's state file, save and statistics intervals
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path
from typing import Any

from .errors import ConfigError

KNOWN_KEYS = {"scan_period", "watchdog", "profile", "timers", "counters", "drums", "registers",
              "constants", "modules", "devices", "modbus", "daemon", "name", "description",
              "analog", "pid", "rtc", "schedule"}

_DUR = re.compile(r"^\s*([0-9]*\.?[0-9]+)\s*(us|ms|s|min)?\s*$", re.I)
_UNIT_S = {"us": 1e-6, "ms": 1e-3, "s": 1.0, "min": 60.0, None: 1.0}


def check_keys(section: str, table: Any, allowed: tuple[str, ...]) -> dict[str, Any]:
    """A config table with only known keys: a typo is an error, not a silent default."""
    if not isinstance(table, dict):
        raise ConfigError(f"{section} must be a table, not {table!r}")
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise ConfigError(f"{section}: unknown key(s) {', '.join(unknown)}; known: "
                          f"{', '.join(allowed)}")
    return table


def duration(value: Any, what: str = "duration") -> float:
    """'10ms', '1.5s', '1min', 0.01 -> seconds."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if value < 0:
            raise ConfigError(f"{what}: negative duration {value}")
        return float(value)
    m = _DUR.match(str(value))
    if not m:
        raise ConfigError(f"{what}: {value!r} is not a duration like '10ms', '1s', '1min'")
    unit = m.group(2).lower() if m.group(2) else None
    return float(m.group(1)) * _UNIT_S[unit]


def time_base(value: Any) -> str:
    """Normalise a timer time base to '1ms' | '10ms' | '100ms' | '1s' | '1min'."""
    s = duration(value, "time base")
    for name, sec in (("1ms", 1e-3), ("10ms", 1e-2), ("100ms", 0.1), ("1s", 1.0),
                      ("1min", 60.0)):
        if abs(s - sec) < 1e-9:
            return name
    raise ConfigError(f"time base {value!r}: one of 1ms, 10ms, 100ms, 1s, 1min")


def load_config(config: str | Path | dict[str, Any] | None) -> tuple[dict[str, Any], Path | None]:
    """Returns (config dict, folder of the config file for relative paths)."""
    if config is None:
        return {}, None
    if isinstance(config, dict):
        cfg, base = dict(config), None
    else:
        p = Path(config)
        try:
            cfg = tomllib.loads(p.read_text(encoding="utf-8"))
        except OSError as e:
            raise ConfigError(f"cannot read config {p}: {e.strerror}") from None
        except tomllib.TOMLDecodeError as e:
            raise ConfigError(f"{p}: {e}") from None
        base = p.parent
    unknown = set(cfg) - KNOWN_KEYS
    if unknown:
        raise ConfigError(f"unknown configuration key(s) {', '.join(sorted(unknown))}; "
                          f"known: {', '.join(sorted(KNOWN_KEYS))}")
    return cfg, base
