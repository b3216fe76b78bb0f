"""A test rig: servo axes on a bare memory image, commanded through their words with no PLC
program (for tests, the benchmark and experiments). Time advances in whole scans.

    rig = Rig.from_toml("ladder_programs/servo_table.toml", "X", "Y")
    rig.command("X", Ctl.ENABLE)
    rig.run(0.1)
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

from softplc.config import read_toml
from softplc.devices.axis.options import Ctl, Mode, Word
from softplc.devices.axis.servo import ServoAxis
from softplc.devices.base import build_devices
from softplc.errors import ConfigError
from softplc.runtime.memory import MemoryImage


def load_axes(path: str | Path, *names: str) -> dict[str, dict[str, Any]]:
    """The `[devices.NAME]` tables of a machine TOML, as written (deep copies, to override
    freely; `Rig` checks them with the devices' Options). Read by the configuration loader:
    ConfigError naming the file if it cannot be read, or a name it lacks."""
    devs = read_toml(path).get("devices", {})
    missing = [n for n in names if n not in devs]
    if missing:
        raise ConfigError(f"{path}: no [devices.{missing[0]}]; devices: "
                          f"{', '.join(devs) or 'none'}")
    return {n: copy.deepcopy(devs[n]) for n in (names or devs)}


class Rig:
    def __init__(self, config: dict[str, dict[str, Any]], scan: float = 1e-3):
        self.mem = MemoryImage()
        self.devices = build_devices(config, self.mem)
        self.axes: dict[str, ServoAxis] = {n: d for n, d in self.devices.items()
                                           if isinstance(d, ServoAxis)}
        self.scan_us = round(scan * 1e6)
        self.t_us = 0

    @classmethod
    def from_toml(cls, path: str | Path, *names: str, wired: bool = False,
                  **overrides: Any) -> Rig:
        """Axes of a machine TOML; unless `wired`, without their contactor and E-stop
        bindings (drives always powered). overrides: {"plant.coulomb": 0, ...}."""
        cfg = load_axes(path, *names)
        for opts in cfg.values():
            if not wired:
                opts.pop("power_output", None)
                opts.pop("estop_input", None)
            for key, value in overrides.items():
                section, _, leaf = key.rpartition(".")
                (opts.setdefault(section, {}) if section else opts)[leaf] = value
        return cls(cfg)

    @property
    def t(self) -> float:
        return self.t_us / 1e6

    def base(self, axis: str) -> int:
        return self.axes[axis]._base

    def command(self, axis: str, control: int, *, target: int | None = None,
                speed: int | None = None, mode: int = Mode.SCURVE, acc_ms: int = 0,
                scurve_ms: int = 0, open_loop: int = 0) -> None:
        mw, b = self.mem.mw, self.base(axis)
        if target is not None:
            mw.set_d(b + Word.TARGET, target)
        if speed is not None:
            mw.set_d(b + Word.SPEED, speed)
        mw.w[b + Word.MODE] = mode
        mw.w[b + Word.ACC_TIME] = acc_ms
        mw.w[b + Word.SCURVE_TIME] = scurve_ms
        mw.w[b + Word.OPEN_LOOP] = open_loop
        mw.uw[b + Word.CONTROL] = control

    def pulse(self, axis: str, bit: int, **kw: Any) -> None:
        """Raise `bit` (keeping ENABLE) for one scan, then drop it."""
        self.command(axis, Ctl.ENABLE | bit, **kw)
        self.step()
        self.mem.mw.uw[self.base(axis) + Word.CONTROL] = Ctl.ENABLE

    def word(self, axis: str, offset: int, kind: str = "w") -> Any:
        # read once per simulated scan by a waiting caller (run_until): no closures built
        mw, i = self.mem.mw, self.base(axis) + offset
        if kind == "w":
            return mw.w[i]
        if kind == "d":
            return mw.get_d(i)
        if kind == "f":
            return mw.get_f(i)
        raise KeyError(kind)

    def step(self, n: int = 1) -> None:
        # (locals: a waiting caller steps one scan at a time, ~10^5 times a sequence)
        devices, scan_us = tuple(self.devices.values()), self.scan_us
        dt = scan_us / 1e6
        for _ in range(n):
            self.t_us = t_us = self.t_us + scan_us
            t = t_us / 1e6
            for d in devices:
                d.update(t, dt)

    def run(self, seconds: float) -> None:
        self.step(round(seconds * 1e6 / self.scan_us))

    def run_until(self, cond: Any, timeout: float) -> bool:
        end = self.t_us + round(timeout * 1e6)
        while self.t_us < end:
            if cond():
                return True
            self.step()
        return bool(cond())
