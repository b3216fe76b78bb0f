"""The drive's machine-parameter interface (seed 000's macro 2: FN 17 writes the speed
controller's MPs, only at standstill): when the PLC applies a new set of the 22 MPs, the
servo axis is retuned from them (`softplc.machines.machining.retune`) at the next scan that finds it
at rest (loop closed, in position, not busy); until then the set waits.

    [devices.drive]
    type = "drive_tuning"
    axis = "X"                  # a servo_axis (or feed_axis) device of this machine
    mps = "%MF500"              # the 22 active MPs (float32, macro order: MP2500, MP2510, ...)
    trigger = "%MW498"          # the PLC's count of applications: a change = a new set
    applied = "%MW499"          # status: sets applied to the axis (read-only for Modbus)
    error = "%MW497"            # status: 0 ok, 1 set refused (the gains are left as they were)
    reference = { MP2500 = 3350.0, MP2510 = 43.5 }   # the MPs of the configured I-variables

The trigger's value at power-up is taken as seen: only later changes retune.
"""

from __future__ import annotations

from typing import Any

from pydantic import ConfigDict, Field, field_validator

from softplc.config import Section
from softplc.devices.axis.options import St
from softplc.devices.axis.servo import ServoAxis
from softplc.devices.base import Device, register_device
from softplc.errors import AddressError, ConfigCode, ConfigError
from softplc.machines.machining.params import MP_NAMES
from softplc.machines.machining.retune import DRIVE_MPS, REFERENCE, mp_dict, retuned
from softplc.runtime.memory import MemoryImage
from softplc.twido.address import parse_address


class DriveTuningOptions(Section):  # strict: "0.01" is not a number
    model_config = ConfigDict(allow_inf_nan=False)
    axis: str
    mps: str = "%MF500"
    trigger: str = "%MW498"
    applied: str = "%MW499"
    error: str = "%MW497"
    reference: dict[str, float] = Field(default_factory=lambda: dict(REFERENCE))

    @field_validator("reference")
    @classmethod
    def _known_mps(cls, v: dict[str, float]) -> dict[str, float]:
        unknown = sorted(set(v) - set(MP_NAMES))
        if unknown:
            raise ValueError(f"unknown parameter {unknown[0]!r}")
        missing = [mp for mp in DRIVE_MPS if not v.get(mp, 0.0) > 0]
        if missing:
            raise ValueError(f"{', '.join(missing)} must be given, > 0")
        return v


REFUSED = 1


@register_device("drive_tuning")
class DriveTuning(Device):
    """Applies the PLC's active MPs to a servo axis's gains at standstill."""

    Options = DriveTuningOptions
    STATE = ("seen", "pending", "applied", "error")

    def __init__(self, name: str, options: DriveTuningOptions):
        super().__init__(name, options)
        self.options: DriveTuningOptions = options
        self.axis: ServoAxis | None = None
        self.commissioned: Any = None  # the axis's configured I-variables
        self._mw: Any = None
        self.reset()

    def _word(self, mem: MemoryImage, option: str, kind: str, size: int) -> int:
        address = getattr(self.options, option)
        try:
            ref = parse_address(address, mem.profile)
        except AddressError as e:
            raise self.problem(option, str(e), ConfigCode.ADDRESS) from None
        if ref.kind != kind or ref.bit is not None or ref.length or \
                ref.index + size > mem.mw.n:
            raise self.problem(option, f"expected a %{kind} address with room for {size} "
                               f"words (got {address!r})", ConfigCode.ADDRESS)
        return ref.index

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self.axis = self.peer(devices, self.options.axis, ServoAxis, "axis")
        self.commissioned = self.axis.gains
        self.mps_at = self._word(mem, "mps", "MF", 2 * len(MP_NAMES))
        self.trigger_at = self._word(mem, "trigger", "MW", 1)
        self._applied = self._word(mem, "applied", "MW", 1)
        self._error = self._word(mem, "error", "MW", 1)
        self._mw = mem.mw
        self.seen = mem.mw.w[self.trigger_at]
        self._write_status()

    def read_only_words(self) -> list[tuple[int, int]]:
        return [(self._applied, self._applied + 1), (self._error, self._error + 1)]

    def reset(self) -> None:
        self.seen = self._mw.w[self.trigger_at] if self._mw is not None else 0
        self.pending: tuple[float, ...] = ()  # a set waiting for standstill
        self.applied = 0
        self.error = 0
        if self._mw is not None:
            self._write_status()

    def update(self, t: float, dt: float) -> None:
        mw = self._mw
        trig = mw.w[self.trigger_at]
        if trig != self.seen:  # (the common case is one word compared per scan)
            self.seen = trig
            self.pending = tuple(mw.get_f(self.mps_at + 2 * i) for i in range(len(MP_NAMES)))
        if self.pending and self._at_rest():
            self.apply(self.pending)
            self.pending = ()
            self._write_status()

    def _at_rest(self) -> bool:
        ax = self.axis
        assert ax is not None
        bits = ax.words.bits()
        return bits & (St.ENABLED | St.BUSY | St.IN_POSITION) == \
            St.ENABLED | St.IN_POSITION

    def apply(self, mps: tuple[float, ...] | list[float]) -> None:
        """Retune the axis from the commissioned gains for this MP set (no wait for rest);
        a refused set leaves the gains and sets the error word."""
        assert self.axis is not None
        try:
            gains = retuned(self.commissioned, mp_dict(mps), self.options.reference)
        except ConfigError:
            self.error = REFUSED
            return
        self.axis.set_gains(gains)
        self.applied += 1
        self.error = 0

    def _write_status(self) -> None:
        w = self._mw.w
        w[self._applied] = self.applied & 0x7FFF
        w[self._error] = self.error

    def status(self) -> dict[str, Any]:
        ax = self.axis
        scale = ax.gains.kp / self.commissioned.kp if ax and self.commissioned.kp else 1.0
        return {"applied": self.applied, "pending": bool(self.pending), "kp_scale":
                round(scale, 4), "error": self.error}
