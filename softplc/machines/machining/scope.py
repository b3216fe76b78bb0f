"""The recorder (the iTNC oscilloscope of seed 000, mass-estimation.md §1/§6): samples a
servo axis's position, velocity, acceleration and motor torque every `sampling_us` after
START, up to `max_count` samples, and on STORE writes `IMCal_.dta` (JOB 1) or `IMMea_.dta`
(JOB 2) through `softplc.machines.machining.recording` (the one writer of the format).

    [devices.scope]
    type = "scope"
    axis = "X"                  # a servo_axis device of this machine
    words = "%MW320"            # command and status words (below)
    directory = "."             # where STORE writes (relative to the daemon's directory)
    sampling_us = 3000          # the thesis's SAMPLING (3 ms); up to 1 s
    max_count = 8192            # the thesis's COUNT; TRUNCATED when the buffer is full;
                                # up to 1,000,000
    torque_per_bit = 0.01       # motor torque, Nm per drive-command bit (the axis's w)
    noise = [1e-6, 2e-4, 0.02, 0.5]   # sd of x m, v m/s, a m/s², torque Nm (seeded), >= 0
    seed = 0                    # 0 .. 2**32 - 1

Sample i (i = 1..COUNT) is the axis state at the end of the scan whose time reaches
t_START + i x SAMPLING: exact when the scan period divides SAMPLING (1 ms scans, 3 ms
samples), otherwise up to one scan late [choice]. Position = the axis's actual position
(user coordinates), velocity = its velocity at the last servo cycle, acceleration = the
velocity change over the last scan / the scan period, torque = drive command x
`torque_per_bit`. Noise is drawn at STORE from numpy's generator seeded with (seed, JOB):
the same run gives the same file.

Words (offsets from `words`): +0 CONTROL: X0 START, X1 STOP, X2 STORE (rising edges);
+1 JOB (1 calibration, 2 measurement). Status (read-only for Modbus): +2 STATUS: X0
RECORDING, X1 STORED, X2 TRUNCATED, X3 ERROR; +3 COUNT; +4 ERROR: 0 none, 1 bad JOB,
2 nothing recorded, 3 file not written.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import ConfigDict, Field

from softplc.config import Section
from softplc.devices.axis.servo import ServoAxis
from softplc.devices.base import Device, register_device
from softplc.errors import AddressError, ConfigCode, SoftPLCError
from softplc.machines.machining import handshake
from softplc.machines.machining.recording import (
    THESIS_CHANNELS,
    Recording,
    quantise,
    write_recording,
)
from softplc.machines.machining.synth import CAL_JOB, MEAS_JOB
from softplc.machines.machining.tuning import CAL_FILE, MEAS_FILE
from softplc.runtime.memory import MemoryImage
from softplc.twido.address import parse_address

FILES = {CAL_JOB: CAL_FILE, MEAS_JOB: MEAS_FILE}
NonNegative = Annotated[float, Field(ge=0)]


class ScopeOptions(Section):  # strict: "0.01" is not a number
    model_config = ConfigDict(allow_inf_nan=False)
    axis: str
    words: str = "%MW320"
    directory: str = "."
    sampling_us: int = Field(3000, gt=0, le=1_000_000)
    max_count: int = Field(8192, gt=0, le=1_000_000)
    torque_per_bit: float = Field(gt=0)
    # standard deviations (numpy refuses negative ones, and seeds, at STORE)
    noise: Annotated[list[NonNegative], Field(min_length=4, max_length=4)] = [0.0, 0.0, 0.0, 0.0]
    seed: int = Field(0, ge=0, le=2**32 - 1)
    axis_label: str = "A"  # AXISn in the files (the thesis's files say "A")


class SW:
    """Word offsets and bits."""

    CONTROL, JOB, STATUS, COUNT, ERROR, SIZE = 0, 1, 2, 3, 4, 5
    START, STOP, STORE = 1, 2, 4
    RECORDING, STORED, TRUNCATED, FAULT = 1, 2, 4, 8
    BAD_JOB, EMPTY, WRITE_FAILED = 1, 2, 3


@register_device("scope")
class Scope(Device):
    """The oscilloscope: four channels of one servo axis (thesis IDs 2, 6, 19, 29)."""

    Options = ScopeOptions
    STATE = ("recording", "stored", "truncated", "error", "_next_us", "_ctl_prev", "_v_prev",
             "last_file")
    RECORDS = ("rows",)  # START begins a new list: a restored state gets its own back

    def __init__(self, name: str, options: ScopeOptions):
        super().__init__(name, options)
        self.options: ScopeOptions = options
        self.channels = tuple(c.__class__(c.id, c.name, c.dim, c.factor, self.options.axis_label)
                              for c in THESIS_CHANNELS)
        self.axis: ServoAxis | None = None
        self._w: Any = None
        self._mem: MemoryImage | None = None
        self._base = 0
        self.reset()

    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self.axis = self.peer(devices, self.options.axis, ServoAxis, "axis")
        try:
            ref = parse_address(self.options.words, mem.profile)
        except AddressError as e:
            raise self.problem("words", str(e), ConfigCode.ADDRESS) from None
        if ref.kind != "MW" or ref.bit is not None or ref.length or \
                ref.index + SW.SIZE > mem.mw.n:
            raise self.problem("words", f"a %MW address with {SW.SIZE} words after it, "
                               f"not {self.options.words!r}", ConfigCode.ADDRESS)
        self._w, self._base = mem.mw.w, ref.index
        self._mem = mem
        self._v_prev = self.axis.v
        self._write_status()

    def read_only_words(self) -> list[tuple[int, int]]:
        return [(self._base + SW.STATUS, self._base + SW.SIZE)]

    def reset(self) -> None:
        self.recording = False
        self.stored = False
        self.truncated = False
        self.error = 0
        self.rows: list[tuple[float, float, float, float]] = []
        self._next_us = 0
        self._ctl_prev = 0
        self._v_prev = self.axis.v if self.axis is not None else 0.0
        self.last_file: Path | None = None

    # -- per scan ---------------------------------------------------------------------------
    def update(self, t: float, dt: float) -> None:
        ax = self.axis
        assert ax is not None
        v, v_prev = ax.v, self._v_prev
        self._v_prev = v
        ctl = self._w[self._base + SW.CONTROL] & 0xFFFF
        rise = ctl & ~self._ctl_prev
        self._ctl_prev = ctl
        if rise & SW.START:
            self.rows = []
            self.recording, self.stored, self.truncated, self.error = True, False, False, 0
            self._next_us = round(t * 1e6) + self.options.sampling_us
        elif self.recording and (t_us := round(t * 1e6)) >= self._next_us:
            # the hot path samples only here: every scan costs a velocity copy and a rise test
            acc = (v - v_prev) / dt if dt > 0 else 0.0
            state = (ax.actual, v, acc, ax.w)
            while t_us >= self._next_us and self.recording:
                self.rows.append(state)
                self._next_us += self.options.sampling_us
                if len(self.rows) >= self.options.max_count:
                    self.recording, self.truncated = False, True
        if rise & SW.STOP:
            self.recording = False
        if rise & SW.STORE:
            self.store(self._w[self._base + SW.JOB])
        self._write_status()

    def _write_status(self) -> None:
        w, b = self._w, self._base
        w[b + SW.STATUS] = (SW.RECORDING if self.recording else 0) \
            | (SW.STORED if self.stored else 0) | (SW.TRUNCATED if self.truncated else 0) \
            | (SW.FAULT if self.error else 0)
        w[b + SW.COUNT] = len(self.rows)
        w[b + SW.ERROR] = self.error

    # -- the files --------------------------------------------------------------------------
    def to_recording(self, job: int) -> Recording:
        """The samples so far as a recording of JOB (noise seeded by (seed, job))."""
        ax = self.axis
        assert ax is not None
        cpm = ax.opt.counts_per_mm
        data = np.array(self.rows, dtype=float).reshape(-1, 4)
        n = len(data)
        # device units -> SI (m, m/s, m/s², Nm), noise in SI, then the channels' DIM
        si = (data[:, 0] / cpm / 1e3, data[:, 1] / cpm / 1e3, data[:, 2] / cpm / 1e3,
              data[:, 3] * self.options.torque_per_bit)
        to_dim = (1e3, 6e4, 1.0, 1.0)  # mm, mm/min, m/(s*s), Nm
        rng = np.random.default_rng([self.options.seed, job])
        cols = [quantise((val + rng.normal(0.0, sd, n)) * k, ch.factor)
                for val, sd, k, ch in zip(si, self.options.noise, to_dim, self.channels,
                                          strict=True)]
        return Recording(self.channels, self.options.sampling_us,
                         np.column_stack(cols) if n else np.zeros((0, 4), np.int64),
                         FILES.get(job, "?"))

    def store(self, job: int) -> Path | None:
        """STORE: write the recording of JOB into `directory`; errors set the ERROR word."""
        if job not in FILES:
            self.error = SW.BAD_JOB
            return None
        if not self.rows:
            self.error = SW.EMPTY
            return None
        path = Path(self.options.directory) / FILES[job]
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_recording(self.to_recording(job), path)
        except (OSError, SoftPLCError):
            self.error = SW.WRITE_FAILED
            return None
        self.stored, self.last_file = True, path
        return path

    def panels(self) -> dict[str, Any]:
        """The mass estimator's handshake words (handshake.py is their one place), beside
        the recorder: the Machine tab's "Mass estimate" panel."""
        return {"estimate": handshake.words(self._mem)} if self._mem is not None else {}

    def status(self) -> dict[str, Any]:
        return {"recording": self.recording, "count": len(self.rows), "error": self.error}
