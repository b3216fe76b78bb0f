"""A position-controlled servo axis: PMAC-style controller, drive and mechanics in one device.

Options and word map: `options.py`; the law: `law.py`; the plant: `plant.py`; the
trajectories: `trajectory.py`; the device's jobs: `motion.py`, `runner.py` (with the
generated loop, `loop.py`), `ivars.py`, `status.py`. Per scan, `update(t, dt)`:

1. reads the command words once and acts on their edges (a command seen at update(t)
   acts from the next servo tick), then the I-variables changed since (`ivars.py`);
2. runs every servo loop cycle k with k T_loop in (t - dt, t]: the number of cycles due
   by time t is floor(t * f_loop) computed from the scan's time in whole microseconds, so
   a scan period that is not a multiple of the servo period gets 2 or 3 cycles and the
   remainder carries over: the long-run rate is exact and the same run is the same
   sequence of cycles every time;
3. writes the status words (never the command words).

Timing inside cycle k (time k T_loop): first the plant is integrated exactly over the last
period, ((k-1) T, k T], with the DAC holding the output computed at tick k-1 (zero-order
hold, no extra delay [choice]); then, at the tick, the encoder is read, the trajectory gives
the commanded position and the law computes the output held until tick k+1. So after the
cycles of a scan the carriage, the encoder count, the commanded position and the following
error all belong to the last tick k <= t (none is a tick ahead of another).

The common case of the loop is inlined for speed (about 0.5 us per cycle); the drive's
special states (E-stop braking, a limit switch, a hard stop, a jammed carriage) go
through the slower `LoopRunner.special` path. A whole scan in its common cases (the loop
closed and moving, or held at a fixed point) is one generated function (`loop._SCAN`:
the checks, the cycles, the status words); `update` does the rest.
"""

from __future__ import annotations

import math
from math import floor
from pathlib import Path
from typing import Any

from softplc.devices.axis import ivars as iv
from softplc.devices.axis.law import Coefficients
from softplc.devices.axis.motion import Motion
from softplc.devices.axis.options import Err, ServoAxisOptions, Word
from softplc.devices.axis.plant import ZOH
from softplc.devices.axis.runner import LoopRunner
from softplc.devices.axis.state import guard
from softplc.devices.axis.status import StatusWords
from softplc.devices.base import AxisDevice, Device, finite_or_none, register_device
from softplc.errors import AddressError, ConfigError
from softplc.runtime.memory import MemoryImage
from softplc.twido.address import parse_address

TRACE_HEADER = "t,commanded,actual,fe,output"
FE_ENVELOPE_ROWS = 20000  # servo-rate rows an FE envelope scans at most (a page's first)


@register_device("servo_axis")
@guard  # (the state the generated scan's caches are made from: properties, state.guard)
class ServoAxis(AxisDevice):
    """One motor: PMAC servo loop + amplifier + table axis. Positions in encoder counts.

    The device holds the state (snapshots, the generated loop read it here); its jobs are
    collaborators acting on it: `motion` (commands, trajectories, homing), `runner` (the
    servo loop's constants and cycles, the fixed point, events), `ivars` (I-variables
    read and written while running, their word table), `words` (the status words)."""

    Options = ServoAxisOptions
    # set by the runner's build() and the generated loop (the jobs' ServoState names them)
    K: float
    a: float
    zoh: ZOH
    _ca: float
    _av: float
    _in_pos: float
    _warn_lim: float
    MOTION: type[Motion] = Motion  # the jobs, replaceable by a variant (devices/feed_axis.py)
    RUNNER: type[LoopRunner] = LoopRunner
    # Everything a scan changes (Device.state); K, a and the loop constants follow from
    # load_mass_ratio, gains and disturbance and are rebuilt by set_state. The trace is a
    # record: see state(). (_fixed, _creep, _rest_words, _st_slow: what the generated scan
    # kept, listed after the properties whose setters drop them, so set_state restores
    # them last; the memory image is restored with the state.)
    STATE = ("x", "v", "k", "origin", "fault", "closed", "open_loop", "_ol_u", "_ol_end",
             "_coast", "latched", "error", "homed", "homing", "done", "warn", "fe", "fe_max",
             "u", "w", "_cp", "_cpp", "_cvp", "_app", "_ie", "_clamped",
             "_traj", "_active", "_k0", "_tail_v", "_ctl_prev", "_vel", "_x_prev_scan",
             "_ready", "_mass_f", "load_mass_ratio", "gains", "disturbance", "_fixed",
             "_creep", "_limit_stop", "_rest_words", "_st_slow")

    def __init__(self, name: str, options: ServoAxisOptions):
        super().__init__(name, options)
        self.opt = o = options
        self.gains = o.ivars
        g = o.geometry
        self.loop_hz = o.servo_clock_hz / (self.gains.servo_ext + 1)
        self.T = 1.0 / self.loop_hz
        self._hz_us = self.loop_hz / 1e6  # cycles per microsecond
        p = o.plant
        self.load_mass_ratio = p.load_mass_ratio
        self.disturbance = 0.0  # a step of load torque applied at run time, DAC bits
        self.coef = Coefficients.of(self.gains)
        self._dac_q = 2.0 ** (16 - p.dac_bits) if p.dac_bits else 0.0
        self.u_peak = p.u_peak or math.inf
        self._cur_scale = 100 / p.u_peak if p.u_peak else 1.0  # CURRENT: % of the limit
        self._lp = g.limit_plus if g.limit_plus is not None else math.inf
        self._lm = g.limit_minus if g.limit_minus is not None else -math.inf
        self._hp = g.hard_stop_plus if g.hard_stop_plus is not None else math.inf
        self._hm = g.hard_stop_minus if g.hard_stop_minus is not None else -math.inf
        # The fast path of the loop runs inside (_lo, _hi): the drive acts at its END
        # switches when they are wired to it, at the hard stops only when they go to the
        # PMAC, which checks them once per scan instead (`_plo`, `_phi`: Motion.limit_stop).
        self._pmac_lim = g.limit_wiring == "pmac"
        if self._pmac_lim:
            self._lo, self._hi = self._hm, self._hp
            self._plo, self._phi = self._lm, self._lp
        else:
            self._lo, self._hi = max(self._lm, self._hm), min(self._lp, self._hp)
            self._plo, self._phi = -math.inf, math.inf
        if not self._hm <= o.start <= self._hp:
            raise ConfigError(f"{self.where('start')}: {o.start} is beyond the hard stops")
        self._enc0 = math.floor(o.start)
        self._start = o.start
        self._ideal = p.encoder == "ideal"
        self._ready = True  # the drive's READY, evaluated once per scan in update()
        self._mass_word: int | None = None
        self._mass_f = 0.0  # the load mass word's value last seen
        # The servo-rate trace: a list trimmed to the last `trace_max` rows once it holds
        # twice that many (cheaper than a ring per row); `_trace_dropped` rows were cut.
        self.trace: list[tuple[int, float, float, float]] = []
        self._trace_dropped = 0
        self._rec = self.trace.append if o.trace else None
        self._trim_at = 2 * o.trace_max
        # A tuning gather (`start_gather`): (k, CP, AP, output, integrator term) per tick.
        self.gather: list[tuple[int, float, float, float, float]] | None = None
        self.motion = self.MOTION(self)
        self.runner = self.RUNNER(self)
        self.ivars = iv.IVarTable(self)
        self.words = StatusWords(self)
        # (bound once: used every scan)
        self._run, self._cycles, self._write = self.runner.run, self.runner.cycles, \
            self.words.write
        self._watch = False  # an I-variable table bound, or changes waiting
        self._ivars_clean: Any = bool  # (IVarTable keeps it: False once there is work)
        self._scan: Any = None  # the generated scan of the common case (runner.build)
        self._rest_words: bytes | None = None  # its status words at a fixed point
        self._st_slow = -1  # the status bits of the last write but the tick's (-1: none)
        self._mem: MemoryImage | None = None
        self.runner.build()
        self._base = 0
        self._estop_idx: int | None = None
        self._wired = False  # the drive's READY depends on an input or an output
        self._power_idx: int | None = None
        self._i: list[bool] = []
        self._q: list[bool] = []
        self.reset()

    def set_load_mass_ratio(self, ratio: float) -> None:
        """Change the moving mass at run time (a workpiece loaded or removed): `ratio` is
        the extra mass over the configured one (`plant.load_mass_ratio`'s meaning); K and
        a scale by 1 / (1 + ratio) from the next servo cycle, the state is kept."""
        if not math.isfinite(ratio) or ratio < 0:
            raise ConfigError(f"device {self.name!r}: load mass ratio {ratio!r}: expected "
                              "a finite number >= 0")
        if ratio != self.load_mass_ratio:
            self.load_mass_ratio = ratio
            self.runner.build()

    def set_disturbance(self, bits: float) -> None:
        """A step of load torque (DAC bits, added to `plant.load`) from the next servo
        cycle: what the integrator has to take up (0 removes it)."""
        why = iv.disturbance_refusal(bits)
        if why:
            raise iv.IVarError(f"device {self.name!r}: {why}")
        if bits != self.disturbance:
            self.disturbance = float(bits)
            self.runner.build()

    def start_gather(self) -> list[tuple[int, float, float, float, float]]:
        """Gather every servo tick from now (PMAC's data gathering): the list it fills."""
        self.gather = []
        self.runner.build()
        return self.gather

    def set_gains(self, gains: Any) -> None:
        """A whole new set of I-variables (a validated `law.Gains`, same Ixx60) from the
        next cycle: the machining centre's retune, made at standstill. A change while
        moving goes through `ivars.set` (checked, bumpless, at a servo tick)."""
        self.gains, self.coef = gains, Coefficients.of(gains)
        self.runner.build()
        self.ivars.write_words()

    # -- contract --------------------------------------------------------------------------
    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        self._mem = mem
        self._base = b = _word_block(self, mem, self.opt.words, Word.SIZE, "words")
        self._w = mem.mw.uw
        self._ctl_i = b + Word.CONTROL
        self._buf = mem.mw.buf
        self._status_at = 2 * (b + Word.ACTUAL)  # byte offset of the status words
        self._i, self._q = mem.i_field, mem.q_field
        if self.opt.load_mass_word is not None:
            self._mass_word = _float_word(self, mem, self.opt.load_mass_word, "load_mass_word")
            self._mass_get = mem.mw.get_f  # (read by the generated scan every scan)
        if self.opt.estop_input is not None:
            self._estop_idx = self.io_index(mem, self.opt.estop_input, "I", "estop_input")
        if self.opt.power_output is not None:
            self._power_idx = self.io_index(mem, self.opt.power_output, "Q", "power_output")
        self._wired = self._estop_idx is not None or self._power_idx is not None
        if self.opt.ivar_words is not None:
            self.ivars.bind(_word_block(self, mem, self.opt.ivar_words, iv.SIZE, "ivar_words"))
            self.word_check = self.ivars  # a host's refused value is refused when written
            # Device.cold_start: the table written again (the values in force) as soon as
            # the image is cleared, so a host's write landing before the next poll is the
            # only change the poll sees (not every I-variable "written" 0)
            self.cold_start = self.ivars.write_words  # type: ignore[method-assign]
        self.words.write()
        self._scan = self.runner.scan_function()

    def read_only_words(self) -> list[tuple[int, int]]:
        """%MW ranges [start, stop) a Modbus host may read but not write (status words)."""
        b = self._base + Word.COMMAND_WORDS
        at = self.ivars._at
        flags = [] if at is None else [(at + iv.REFUSED, at + iv.DISTURBANCE)]
        return [(b, self._base + Word.SIZE), *flags]

    def reset(self) -> None:
        o = self.opt
        self.x = float(o.start)  # true position, counts from the home index mark
        self.v = 0.0  # counts/s
        self.k = 0  # servo loop cycles run
        self.origin = 0  # raw encoder count of user position 0 (set by homing)
        self.fault = o.fault
        self.closed = False  # loop closed
        self.open_loop = False
        self._ol_u = 0.0
        self._ol_end = 0  # cycle at which an open-loop output ends (0: until STOP)
        self._coast = False  # open-loop output over, waiting for the carriage to stop
        self.latched = False  # fatal error latched until RESET
        self.error = Err.NONE
        self.homed = False
        self.homing = 0  # 0 no, 1 searching, 2 stopping after the trigger, 3 returning
        self.done = False
        self.warn = False
        self.fe = 0.0
        self.fe_max = 0.0
        self.u = 0.0  # DAC output
        self.w = 0.0  # drive command after offset and current limit (torque signal)
        ap = self._raw()
        self._cp = float(ap)  # commanded position (raw counts)
        self._cpp = self._cvp = 0.0
        self._app = ap
        self._ie = 0.0
        self._clamped = False
        self._traj: tuple[float, ...] = ()
        self._active = False  # a trajectory was started and has not been seen to end
        self._k0 = 1
        self._tail_v = 0.0  # counts per cycle after the trajectory's end
        self._ctl_prev = 0
        self._vel = 0.0
        self._x_prev_scan = self.x_
        self._fixed = False  # the loop's state is a fixed point: see LoopRunner
        self._creep = 0  # ... or a creep for that many cycles
        self._limit_stop = False  # the trajectory is a "pmac" limit's abort
        self.trace.clear()
        self._trace_dropped = 0
        self._rest_words, self._st_slow = None, -1

    def set_fault(self, fault: str) -> None:
        """Inject a fault at run time: "jammed" (the carriage is frozen), "estop" (the
        drive's E-stop), "amp_fault" (the drive drops READY), "none"."""
        if fault not in ("none", "jammed", "estop", "amp_fault"):
            raise ConfigError(f"device {self.name!r}: unknown fault {fault!r}")
        self.fault = fault
        self._fixed = False

    # -- positions (the interface limit switches and tools use) ----------------------------
    def _raw(self) -> float:
        if self._ideal:
            return self.x_ - self._start
        return floor(self.x_) - self._enc0

    @property
    def position(self) -> float:
        """True carriage position, counts from the home index mark."""
        return self.x_

    def axis_position(self) -> float:
        return self.x_

    def axis_end(self) -> float:
        return self._lp

    @property
    def actual(self) -> float:
        """Actual position as the controller sees it (encoder, user coordinates)."""
        return self._raw() - self.origin_

    @property
    def commanded(self) -> float:
        return self._cp_ - self.origin_

    # -- per scan ---------------------------------------------------------------------------
    def update(self, t: float, dt: float) -> None:
        scan = self._scan  # the common case, generated (loop.py): False if it does not hold
        if scan is not None and scan(self, t, dt):
            return
        if self._mass_word is not None:
            r = self._mem.mw.get_f(self._mass_word)  # type: ignore[union-attr]
            if r != self._mass_f:  # a change of the ratio from the configured one
                self._mass_f = r
                r += self.opt.plant.load_mass_ratio
                self.set_load_mass_ratio(r if math.isfinite(r) and r >= 0 else 0.0)
        fault = self.fault_  # (the fields: _finish writes the status words in full)
        # (amp_ready() inlined for the common case: no fault, drive not wired to inputs)
        self._ready_ = ready = True if fault == "none" and not self._wired else self.amp_ready()
        if self._w[self._ctl_i] != self._ctl_prev or not self.closed_ or fault != "none" or \
                not ready:
            self.motion.commands()
        due = floor(round(t * 1e6) * self._hz_us + 1e-9)
        if self._watch and not self._ivars_clean():  # a host wrote the table, or a change
            self.ivars.poll(due)
        n = due - self.k
        if n > 0:
            if self._fixed or self.v_ == 0.0 or not self.closed_:
                self._run(due)  # at rest, at a fixed point or open: the runner decides
            else:  # (the common case inline: moving, loop closed, no fixed point)
                cycles = self._cycles
                while n > 0:
                    n = cycles(n)
                if self._rec is not None and len(self.trace) >= self._trim_at:
                    self.runner.trim()
        self._finish(dt)

    def _finish(self, dt: float) -> None:
        """The scan after its servo cycles: limits wired to the PMAC, the velocity word,
        the sequencing at a trajectory's end, the status words."""
        self._rest_words = None
        x = self.x_
        if not self._plo < x < self._phi:  # on a limit wired to the PMAC
            self.motion.limit_stop()
        if dt > 0:
            self._vel_ = (x - self._x_prev_scan) / dt  # (the field: written in full below)
        self._x_prev_scan = x
        if self._active and not self._tail_v_ and self.k - self._k0 + 1 >= len(self._traj_):
            self.motion.after_ticks()  # (it does nothing before the trajectory's end)
        if self._coast_ and self.v_ == 0.0:  # after an open-loop output: close the loop here
            self._coast = False
            if self.open_loop:
                self.motion.close_loop()
                self.done = True
        self._write()

    # -- drive state ------------------------------------------------------------------------
    def amp_ready(self) -> bool:
        if self.fault_ in ("estop", "amp_fault"):
            return False
        if self._estop_idx is not None and self._i[self._estop_idx]:
            return False
        return self._power_idx is None or bool(self._q[self._power_idx])

    def estop_active(self) -> bool:
        return self.fault_ == "estop" or (self._estop_idx is not None
                                         and bool(self._i[self._estop_idx]))

    # -- status -----------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        # drive_homed: the drive's own home search (MODE home) ran; a program that homes
        # the axis itself (on its switches, as cutting_table.il) keeps its own bit
        return {"pos": round(self.actual), "fe": round(self.fe_, 2), "drive_homed": self.homed_,
                "error": Err.TEXT[self.error_]}

    # -- snapshots --------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        st = super().state()
        st["trace"] = self._trace_dropped + len(self.trace)  # rows recorded so far
        return st

    def set_state(self, st: dict[str, Any]) -> None:
        ratio = self.load_mass_ratio
        fixed = st["_fixed"]
        built = (ratio, self.gains, self.disturbance)
        super().set_state(st)
        if (self.load_mass_ratio, self.gains, self.disturbance) != built:
            self.coef = Coefficients.of(self.gains)
            self.runner.build()
            self._fixed = fixed
            self.ivars.write_words()
        keep = st["trace"] - self._trace_dropped
        del self.trace[max(keep, 0):]
        if keep < 0:  # the rows back to there were trimmed: the trace restarts at the cut
            self._trace_dropped = st["trace"]

    # -- trace ------------------------------------------------------------------------------
    def samples(self) -> list[tuple[float, float, float, float, float]]:
        """The servo-rate trace: (t s, commanded, actual, following error, output bits),
        positions in counts (user coordinates of the time)."""
        T = self.T
        return [(k * T, cp, ap, cp - ap, u)
                for k, cp, ap, u in self.trace[-self.opt.trace_max:]]

    def close(self) -> None:
        if self.opt.trace_csv:
            write_trace_csv(self.samples(), self.opt.trace_csv)

    def view(self, since_t: float) -> dict[str, Any] | None:
        """The axis in its true frame (counts from the home index mark, as the trace
        recorder and the limit switches use): position, commanded position, travel, FE and
        its envelope over the servo-rate trace since `since_t` (machine time)."""
        g = self.opt.geometry
        lo = g.limit_minus if g.limit_minus is not None else g.hard_stop_minus
        hi = g.limit_plus if g.limit_plus is not None else g.hard_stop_plus
        x = float(self.axis_position())
        fe = float(self.fe) if self.closed else 0.0
        fe_lo = fe_hi = fe
        trace = self.trace
        if trace:  # rows (tick, commanded, actual, output); ticks of self.T seconds
            first = math.ceil(since_t / self.T)
            n = 0
            for k, cp, ap, _u in reversed(trace):
                if k < first or n >= FE_ENVELOPE_ROWS:
                    break
                e = cp - ap
                fe_lo, fe_hi = min(fe_lo, e), max(fe_hi, e)
                n += 1
        return {"counts_per_mm": self.opt.counts_per_mm, "x": x, "cmd": x + fe,
                "lo": finite_or_none(lo),
                "hi": finite_or_none(hi),
                "fe": fe, "fe_lo": fe_lo, "fe_hi": fe_hi, "fe_max": float(self.fe_max),
                "v": float(self.v), "enabled": bool(self.closed),
                "load_mass_ratio": float(self.load_mass_ratio)}


def write_trace_csv(samples: list[tuple[float, float, float, float, float]],
                    path: str | Path) -> None:
    """A servo axis's `samples()` as the CSV of its `trace_csv` option."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(TRACE_HEADER + "\n")
        for r in samples:
            f.write(f"{r[0]:.7f},{r[1]:.4f},{r[2]:.4f},{r[3]:.4f},{r[4]:.2f}\n")


def _word_block(dev: Device, mem: MemoryImage, address: str, size: int, option: str) -> int:
    try:
        ref = parse_address(address, mem.profile)
    except AddressError as e:
        raise ConfigError(f"{dev.where(option)}: {e}") from None
    if ref.kind != "MW" or ref.bit is not None or ref.length or ref.offset is not None:
        raise ConfigError(f"{dev.where(option)}: expected a %MW address "
                          f"(got {address!r})")
    if ref.index + size > mem.mw.n:
        raise ConfigError(f"{dev.where(option)}: {address} + {size} "
                          f"words run past %MW{mem.mw.n - 1}")
    return ref.index

def _float_word(dev: Device, mem: MemoryImage, address: str, option: str) -> int:
    try:
        ref = parse_address(address, mem.profile)
    except AddressError as e:
        raise ConfigError(f"device {dev.name!r}: {option}: {e}") from None
    if ref.kind != "MF" or ref.length or ref.index + 1 >= mem.mw.n:
        raise ConfigError(f"device {dev.name!r}: {option} must be a %MF address, "
                          f"not {address!r}")
    return ref.index
