"""A position-controlled servo axis: PMAC-style controller, drive and mechanics in one device.

Options and word map: `options.py`; the law: `law.py`; the plant: `plant.py`; the
trajectories: `trajectory.py`. Per scan, `update(t, dt)`:

1. reads the command words once and acts on their edges (a command seen at update(t)
   acts from the next servo tick);
2. runs every servo loop cycle k with k T_loop in (t - dt, t]: the number of cycles due
   by time t is floor(t * f_loop) computed from the scan's time in whole microseconds, so
   a scan period that is not a multiple of the servo period gets 2 or 3 cycles and the
   remainder carries over: the long-run rate is exact and the same run is the same
   sequence of cycles every time;
3. writes the status words (never the command words).

Timing inside a cycle: the encoder is read, the law computes u, the DAC holds u for the
next T_loop (zero-order hold, no extra delay [choice]), the plant integrates exactly over
it. The common case of the loop is inlined for speed (about 1 us per cycle); the drive's
special states (E-stop braking, a limit switch, a hard stop, a jammed carriage) go
through the slower `_special` path.
"""

from __future__ import annotations

import math
import struct
from itertools import repeat
from math import floor
from pathlib import Path
from typing import Any

from ...address import parse_address
from ...errors import AddressError, ConfigError
from ...runtime.memory import MemoryImage
from ..base import AxisDevice, Device, register_device
from . import loop
from . import trajectory as tj
from .law import Coefficients
from .options import Ctl, Err, Mode, ServoAxisOptions, St, Word
from .plant import ZOH, step

TRACE_HEADER = "t,commanded,actual,fe,output"
# The status words in word order, (offset, struct code): one `pack_into` writes them all.
_STATUS_WORDS = ((Word.ACTUAL, "i"), (Word.COMMANDED, "i"), (Word.FE, "f"), (Word.FE_MAX, "f"),
                 (Word.STATUS, "H"), (Word.ERROR, "H"), (Word.TICKS, "i"), (Word.OUTPUT, "f"),
                 (Word.CURRENT, "f"), (Word.VELOCITY, "f"))
_STATUS_PACK = struct.Struct("=" + "".join(c for _, c in _STATUS_WORDS)).pack_into
assert [o for o, _ in _STATUS_WORDS] == [  # contiguous, from ACTUAL to the block's end
    Word.ACTUAL + sum(struct.calcsize(c) // 2 for _, c in _STATUS_WORDS[:i])
    for i in range(len(_STATUS_WORDS))] and Word.VELOCITY + 2 == Word.SIZE


@register_device("servo_axis")
class ServoAxis(AxisDevice):
    """One motor: PMAC servo loop + amplifier + table axis. Positions in encoder counts."""

    Options = ServoAxisOptions
    # Everything a scan changes (Device.state); K, a and the loop constants follow from
    # load_mass_ratio and are rebuilt by set_state. The trace is a record: see state().
    STATE = ("x", "v", "k", "origin", "fault", "closed", "open_loop", "_ol_u", "_ol_end",
             "_coast", "latched", "error", "homed", "homing", "done", "warn", "fe", "fe_max",
             "u", "w", "_cp", "_cpp", "_cvp", "_app", "_ie", "_clamped", "_traj", "_active",
             "_k0", "_tail_v", "_ctl_prev", "_vel", "_x_prev_scan", "_ready", "_mass_f",
             "load_mass_ratio", "_fixed", "gains")

    def __init__(self, name: str, options: ServoAxisOptions):
        super().__init__(name, options)
        self.opt = o = options
        self.gains = o.ivars
        g = o.geometry
        self.loop_hz = o.servo_clock_hz / (self.gains.servo_ext + 1)
        self.T = 1.0 / self.loop_hz
        p = o.plant
        self.load_mass_ratio = p.load_mass_ratio
        self._dac_q = 2.0 ** (16 - p.dac_bits) if p.dac_bits else 0.0
        self.u_peak = p.u_peak or math.inf
        self._cur_scale = 100 / p.u_peak if p.u_peak else 1.0  # CURRENT: % of the limit
        self._lp = g.limit_plus if g.limit_plus is not None else math.inf
        self._lm = g.limit_minus if g.limit_minus is not None else -math.inf
        self._hp = g.hard_stop_plus if g.hard_stop_plus is not None else math.inf
        self._hm = g.hard_stop_minus if g.hard_stop_minus is not None else -math.inf
        self._lo, self._hi = max(self._lm, self._hm), min(self._lp, self._hp)
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
        self._build_consts()
        self._mem: MemoryImage | None = None
        self._base = 0
        self._estop_idx: int | None = None
        self._wired = False  # the drive's READY depends on an input or an output
        self._power_idx: int | None = None
        self._i: list[int] = []
        self._q: list[int] = []
        self.reset()

    def _build_consts(self) -> None:
        """The plant terms that depend on the moving mass, and the loop's constants."""
        o, p, g = self.opt, self.opt.plant, self.opt.geometry
        self.K = p.K / (1 + self.load_mass_ratio)
        self.a = p.a / (1 + self.load_mass_ratio)
        self.zoh = ZOH.of(self.a, self.T)
        gn = self.gains
        c = self.coef = Coefficients.of(gn)
        inf = math.inf
        table = p.load_table
        # Everything the servo loop reads but never changes: literals of its generated code
        # (loop.py), with the flags that drop the branches this configuration never takes.
        fatal = gn.fatal_fe / 16 if gn.fatal_fe else inf
        warn = gn.warn_fe / 16 if gn.warn_fe else inf
        ilim = gn.int_limit / 16 if gn.int_limit else inf
        z = self.zoh
        self._loop_values = dict(
            cfe=c.fe, ccv=c.cv, cca=c.ca, cie=c.ie, cav=c.av, ilim=ilim, nilim=-ilim,
            ff=gn.friction_ff, off=gn.offset, lim=gn.output_limit, nlim=-gn.output_limit,
            fatal=fatal, warn_lim=warn, check=min(warn, fatal), q=self._dac_q, K=self.K,
            a=self.a, fc=p.coulomb, nfc=-p.coulomb, uoff=p.amp_offset, up=self.u_peak,
            nup=-self.u_peak, load=p.load, phi=z.phi, g1=z.g1, g2=z.g2, T=self.T,
            enc0=o.start if self._ideal else self._enc0, lo=self._lo, hi=self._hi,
            hlo=g.home_switch[0], hhi=g.home_switch[1], iper=g.index_period,
            ioff=g.index_offset)
        if len(table) == 2:
            (x0, y0), (x1, y1) = table
            self._loop_values.update(t_x0=x0, t_y0=y0, t_x1=x1, t_y1=y1, t_dy=y1 - y0,
                                     t_dx=x1 - x0)
        self._loop_flags = dict(
            ideal=self._ideal, int_always=gn.int_mode == 0, ilim=ilim != inf,
            check=min(warn, fatal) != inf, warn_on=warn != inf, fatal_on=fatal != inf,
            dac=bool(self._dac_q), trace=self._rec is not None, up=self.u_peak != inf,
            load=p.load != 0, table2=len(table) == 2, table=len(table) not in (0, 2))
        self._loops: dict[tuple[bool, ...], Any] = {}
        self._warn_lim, self._in_pos = warn, gn.in_position / 16
        self._fixed = False

    def set_load_mass_ratio(self, ratio: float) -> None:
        """Change the moving mass at run time (a workpiece loaded or removed): `ratio` is
        the extra mass over the configured one (`plant.load_mass_ratio`'s meaning); K and
        a scale by 1 / (1 + ratio) from the next servo cycle, the state is kept."""
        if not math.isfinite(ratio) or ratio < 0:
            raise ConfigError(f"device {self.name!r}: load mass ratio {ratio!r}: expected "
                              "a finite number >= 0")
        if ratio != self.load_mass_ratio:
            self.load_mass_ratio = ratio
            self._build_consts()

    def set_gains(self, gains: Any) -> None:
        """New I-variables (a validated `law.Gains`, same Ixx60) from the next cycle."""
        self.gains = gains
        self._build_consts()

    # -- contract --------------------------------------------------------------------------
    def bind(self, mem: MemoryImage, devices: dict[str, Device]) -> None:
        try:
            ref = parse_address(self.opt.words, mem.profile)
        except AddressError as e:
            raise ConfigError(f"{self.where('words')}: {e}") from None
        if ref.kind != "MW" or ref.bit is not None or ref.length or ref.offset is not None:
            raise ConfigError(f"{self.where('words')}: expected a %MW address "
                              f"(got {self.opt.words!r})")
        if ref.index + Word.SIZE > mem.mw.n:
            raise ConfigError(f"{self.where('words')}: {self.opt.words} + {Word.SIZE} "
                              f"words run past %MW{mem.mw.n - 1}")
        self._mem = mem
        self._base = b = ref.index
        self._w = mem.mw.uw
        self._ctl_i = b + Word.CONTROL
        self._buf = mem.mw.buf
        self._status_at = 2 * (b + Word.ACTUAL)  # byte offset of the status words
        self._i, self._q = mem.i_field, mem.q_field
        if self.opt.load_mass_word is not None:
            self._mass_word = self._float_word(mem, self.opt.load_mass_word, "load_mass_word")
        if self.opt.estop_input is not None:
            self._estop_idx = self.io_index(mem, self.opt.estop_input, "I", "estop_input")
        if self.opt.power_output is not None:
            self._power_idx = self.io_index(mem, self.opt.power_output, "Q", "power_output")
        self._wired = self._estop_idx is not None or self._power_idx is not None
        self._write_status()

    def _float_word(self, mem: MemoryImage, address: str, option: str) -> int:
        try:
            ref = parse_address(address, mem.profile)
        except AddressError as e:
            raise ConfigError(f"device {self.name!r}: {option}: {e}") from None
        if ref.kind != "MF" or ref.length or ref.index + 1 >= mem.mw.n:
            raise ConfigError(f"device {self.name!r}: {option} must be a %MF address, "
                              f"not {address!r}")
        return ref.index

    def read_only_words(self) -> list[tuple[int, int]]:
        """%MW ranges [start, stop) a Modbus host may read but not write (status words)."""
        b = self._base + Word.COMMAND_WORDS
        return [(b, self._base + Word.SIZE)]

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
        self._x_prev_scan = self.x
        self._fixed = False  # the loop's state is a fixed point: see _probe_fixed
        self.trace.clear()
        self._trace_dropped = 0

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
            return self.x - self._start
        return floor(self.x) - self._enc0

    @property
    def position(self) -> float:
        """True carriage position, counts from the home index mark."""
        return self.x

    def axis_position(self) -> float:
        return self.x

    def axis_end(self) -> float:
        return self._lp

    @property
    def actual(self) -> float:
        """Actual position as the controller sees it (encoder, user coordinates)."""
        return self._raw() - self.origin

    @property
    def commanded(self) -> float:
        return self._cp - self.origin

    # -- per scan ---------------------------------------------------------------------------
    def update(self, t: float, dt: float) -> None:
        if self._mass_word is not None:
            r = self._mem.mw.get_f(self._mass_word)  # type: ignore[union-attr]
            if r != self._mass_f:  # a change of the ratio from the configured one
                self._mass_f = r
                r += self.opt.plant.load_mass_ratio
                self.set_load_mass_ratio(r if math.isfinite(r) and r >= 0 else 0.0)
        fault = self.fault
        # (amp_ready() inlined for the common case: no fault, drive not wired to inputs)
        self._ready = ready = True if fault == "none" and not self._wired else self.amp_ready()
        closed = self.closed
        if self._w[self._ctl_i] != self._ctl_prev or not closed or fault != "none" or \
                not ready:
            self._commands()
            closed = self.closed
        due = floor(round(t * 1e6) * self.loop_hz / 1e6 + 1e-9)
        n = due - self.k
        if n > 0:
            if self._fixed:
                self._repeat(n)
            elif not closed and self._at_rest_open():
                self.k = due  # killed and stuck: nothing moves, nothing to record
            else:
                # (a pre-filter: with FE != 0 and no clamp the integrator moves: no probe)
                if self.v == 0.0 and (self.fe == 0.0 or self._clamped) and \
                        self._fixed_candidate():
                    n = self._probe_fixed(n)
                    if self._fixed:
                        self._repeat(n)
                        n = 0
                while n > 0:
                    n = self._cycles(n)
            if self._rec is not None and len(self.trace) >= self._trim_at:
                rec = self.trace  # keep the last trace_max rows
                cut = len(rec) - self.opt.trace_max
                del rec[:cut]
                self._trace_dropped += cut
        x = self.x
        if dt > 0:
            self._vel = (x - self._x_prev_scan) / dt
        self._x_prev_scan = x
        if self._active and not self._tail_v and self.k - self._k0 + 1 >= len(self._traj):
            self._after_ticks()  # (it does nothing before the trajectory's end)
        if self._coast and self.v == 0.0:  # after an open-loop output: close the loop here
            self._coast = False
            if self.open_loop:
                self._close_loop()
                self.done = True
        self._write_status()

    # -- drive state ------------------------------------------------------------------------
    def amp_ready(self) -> bool:
        if self.fault in ("estop", "amp_fault"):
            return False
        if self._estop_idx is not None and self._i[self._estop_idx]:
            return False
        return self._power_idx is None or bool(self._q[self._power_idx])

    def _at_rest_open(self) -> bool:
        """Loop open, carriage still and held by friction against the drive's offset and
        the load: the cycles would change nothing."""
        if self.closed or self.open_loop or self.v != 0.0 or self.fault != "none":
            return False
        p = self.opt.plant
        w = (p.amp_offset if self.amp_ready() else 0.0) - p.load
        return not p.load_table and abs(w) <= p.coulomb and self._lm < self.x < self._lp

    def estop_active(self) -> bool:
        return self.fault == "estop" or (self._estop_idx is not None
                                         and bool(self._i[self._estop_idx]))

    def _kill(self, error: int, latch: bool = True) -> None:
        self.closed = False
        self.open_loop = False
        self._coast = False
        self.u = 0.0
        self._traj = ()
        self._tail_v = 0.0
        self.homing = 0
        if latch:
            self.latched = True
        if error:
            self.error = error

    # -- commands ---------------------------------------------------------------------------
    def _commands(self) -> None:
        self._fixed = False  # whatever the commands change, the fixed point is re-proved
        mw = self._mem.mw  # type: ignore[union-attr]
        b = self._base
        ctl = mw.uw[b + Word.CONTROL]
        rise = ctl & ~self._ctl_prev
        fall = self._ctl_prev & ~ctl
        self._ctl_prev = ctl
        ready = self.amp_ready()
        if (self.closed or self.open_loop) and not ready:
            self._kill(Err.AMP_FAULT)
        if rise & Ctl.RESET:
            self.latched = False
            self.error = Err.NONE
        if ctl & Ctl.KILL or not ctl & Ctl.ENABLE:
            if self.closed or self.open_loop:
                self._kill(Err.NONE, latch=False)
            return
        if not (self.closed or self.open_loop):
            if self.latched or not ready:
                return
            self._close_loop()
        if rise & Ctl.HOME:
            self._start_home()
        elif rise & Ctl.EXECUTE:
            self._execute(mw, b)
        elif rise & Ctl.STOP:
            self._stop()
        jog = ctl & (Ctl.JOG_PLUS | Ctl.JOG_MINUS)
        if rise & jog and jog != Ctl.JOG_PLUS | Ctl.JOG_MINUS:
            self._jog(1 if jog == Ctl.JOG_PLUS else -1)
        elif fall & (Ctl.JOG_PLUS | Ctl.JOG_MINUS) or (rise & jog and jog != rise & jog):
            self._stop()

    def _close_loop(self) -> None:
        """PMAC `J/`: close the loop holding the present actual position."""
        ap = self._raw()
        self.closed, self.open_loop = True, False
        self._coast = False
        self._cp = self._cpp = float(ap)
        self._cvp = 0.0
        self._app = ap
        self._ie = 0.0
        self._traj, self._tail_v = (), 0.0

    def _rule(self, acc_ms: int = 0, s_ms: int = 0, trapezoid: bool = False) -> tj.RampRule:
        g = self.gains
        ta = (acc_ms or g.accel_time) / 1000
        ts = 0.0 if trapezoid else (s_ms or g.scurve_time) / 1000
        return tj.RampRule(ta, ts, g.max_accel * 1e6)

    def _busy(self) -> bool:
        return self.homing != 0 or bool(self._traj) or self._tail_v != 0.0 or self._coast \
            or self.open_loop

    def _refuse_unhomed(self) -> bool:
        if self.opt.require_home and not self.homed:
            self._kill(Err.NOT_HOMED)
            return True
        return False

    def _execute(self, mw: Any, b: int) -> None:
        mode = mw.w[b + Word.MODE]
        if self._busy() or not Mode.SCURVE <= mode <= Mode.OPEN_LOOP:
            self.error = Err.BAD_COMMAND
            return
        if self._refuse_unhomed():
            return
        acc_ms, s_ms = mw.uw[b + Word.ACC_TIME], mw.uw[b + Word.SCURVE_TIME]
        self.done = False
        self.fe_max = 0.0
        if mode == Mode.OPEN_LOOP:
            self.closed, self.open_loop = False, True
            self._ol_u = mw.w[b + Word.OPEN_LOOP] / 10000 * self.gains.output_limit
            self._ol_end = self.k + math.ceil(acc_ms / 1000 * self.loop_hz) if acc_ms else 0
            return
        target = mw.get_d(b + Word.TARGET) + self.origin
        speed = mw.get_d(b + Word.SPEED) or self.gains.jog_speed * 1000
        if speed <= 0:
            self.error = Err.BAD_COMMAND
            return
        if mode == Mode.STEP:  # the commanded position jumps at the next cycle
            self._follow(tj.Profile(float(target), 0.0), end=float(target))
            return
        if mode == Mode.PARABOLIC:
            if not acc_ms:
                self.error = Err.BAD_COMMAND
                return
            prof = tj.parabolic(self._cp, target, acc_ms / 1000)
        else:
            prof = tj.move(self._cp, target, float(speed),
                           self._rule(acc_ms, s_ms, mode == Mode.TRAPEZOID))
        self._follow(prof, end=float(target))

    def _follow(self, prof: tj.Profile, end: float | None = None, v_end: float = 0.0) -> None:
        """Start a trajectory at the next cycle; `end` is the exact final position, `v_end`
        the velocity (counts/s) that continues after the profile (a jog's)."""
        traj = tj.sample(prof, self.T)
        self._tail_v = v_end * self.T
        self._active = True
        if traj and end is not None:
            traj[-1] = end
        elif not traj and not self._tail_v:
            self._cp = end if end is not None else self._cp
        self._traj = tuple(traj)  # immutable: a state() shares it
        self._k0 = self.k + 1

    def _cmd_velocity(self) -> float:
        """Commanded velocity now, counts/s."""
        return self._cvp * self.loop_hz

    def _stop(self) -> None:
        if self.open_loop:  # output 0, coast to a stop, then the loop closes
            self._ol_u, self._ol_end, self._coast = 0.0, 0, True
            return
        if not self._busy():
            return
        self.homing = 0 if self.homing == 1 else self.homing
        self._follow(tj.velocity_change(self._cp, self._cmd_velocity(), 0.0, self._rule()))

    def _jog(self, sign: int) -> None:
        if self._refuse_unhomed() or self.homing:
            return
        self.done = False
        v1 = sign * self.gains.jog_speed * 1000
        self._follow(tj.velocity_change(self._cp, self._cmd_velocity(), v1, self._rule()),
                     v_end=v1)

    def _start_home(self) -> None:
        if self._busy():
            self.error = Err.BAD_COMMAND
            return
        self.homed = False
        self.done = False
        self.fe_max = 0.0
        self.homing = 1
        v = self.gains.home_speed * 1000
        self._follow(tj.velocity_change(self._cp, 0.0, v, self._rule()), v_end=v)

    def _home_trigger(self, capture: float) -> None:
        """The index pulse after the home flag: new origin, decelerate."""
        self.origin = round(capture + self.gains.home_offset / 16)
        self.homed = True
        self.homing = 2
        self._follow(tj.velocity_change(self._cp, self._cmd_velocity(), 0.0, self._rule()))

    def _after_ticks(self) -> None:
        """Scan-level sequencing once the trajectory has ended."""
        if self._traj and self.k - self._k0 + 1 >= len(self._traj) and not self._tail_v:
            self._traj = ()  # a finished move holds its end exactly
        if self._traj or self._tail_v:
            return
        self._active = False
        if self.homing == 2:
            self.homing = 3
            speed = abs(self.gains.home_speed) * 1000
            self._follow(tj.move(self._cp, float(self.origin), speed, self._rule()),
                         end=float(self.origin))
        elif self.homing == 3:
            self.homing = 0
            self.done = True
        elif self.closed:
            self.done = True

    # -- the fixed point ----------------------------------------------------------------------
    # A servo cycle maps the loop state L = (x, v, CP, CP', CV', AP', IE, clamped) to the next
    # one; with the loop closed, no trajectory left (CP constant), no tail velocity, the drive
    # ready, no fault, no homing search and the carriage inside the limits, the map depends
    # on nothing else (not on the cycle number). So if one cycle leaves L bit for bit as it
    # was, every later cycle does too and computes the same u, w, FE: the cycles can be
    # skipped, their trace rows written in one go, until a command, a fault, the drive's
    # READY or the moving mass changes (_commands, set_fault, _build_consts clear the flag).
    # The test is on the packed bytes (-0.0 and 0.0 differ), so it is exact, not approximate.
    _PACK = struct.Struct("<8d").pack

    def _loop_state(self) -> bytes:
        return self._PACK(self.x, self.v, self._cp, self._cpp, self._cvp, self._app,
                          self._ie, self._clamped)

    def _fixed_candidate(self) -> bool:
        """The conditions under which the cycle map is the same for every cycle."""
        return (self.closed and not self.open_loop and not self._tail_v
                and self.k + 1 - self._k0 >= len(self._traj) and self.homing != 1
                and self._ready and self.fault == "none" and self._lo < self.x < self._hi)

    def _probe_fixed(self, n: int) -> int:
        """Run one of the n due cycles; note a fixed point. Returns the cycles left."""
        before = self._loop_state()
        left = self._cycles(1)
        self._fixed = self._fixed_candidate() and self._loop_state() == before
        return n - 1 + left

    def _repeat(self, n: int) -> None:
        """n cycles at the fixed point: only the cycle count and the trace move on."""
        k = self.k
        if self._rec is not None:
            o = self.origin
            self.trace.extend(zip(range(k + 1, k + n + 1), repeat(self._cp - o),
                                  repeat(self._app - o), repeat(self.u)))
        self.k = k + n

    # -- the servo loop ---------------------------------------------------------------------
    def _cycles(self, n: int) -> int:
        """Run up to n loop cycles; returns how many are left when an event interrupts."""
        closed, open_loop = self.closed, self.open_loop
        ready = self._ready
        key = (closed, open_loop, self.homing == 1, ready, self.fault != "none")
        fn = self._loops.get(key)
        if fn is None:
            flags = dict(self._loop_flags, closed=closed, open_loop=open_loop,
                         killed=not (closed or open_loop), search=key[2],
                         special=not ready or key[4], ready=ready)
            fn = self._loops[key] = loop.compile_cycles(
                loop.render(self._loop_values, flags), _interp, step)
        return fn(self, n)

    def _on_event(self, event: Any) -> None:
        """What interrupted the cycles (called by the loop with its state written back)."""
        if event == "fatal":
            x = self.x
            self._kill(Err.LIMIT if x >= self._lp or x <= self._lm else Err.FATAL_FE)
        elif event == "open loop end":  # output 0: the carriage coasts to a stop
            self._ol_u = 0.0
            self._ol_end = 0
            self._coast = True
        else:
            self._home_trigger(event[1])

    def _special(self, x: float, v: float, w: float) -> tuple[float, float]:
        """The drive's and the mechanics' exceptional states, one cycle."""
        p = self.opt.plant
        T = self.T
        if self.fault == "jammed":
            return x, 0.0
        if self.estop_active():  # the drive brakes at its current limit, then lets go
            brake = self.u_peak if math.isfinite(self.u_peak) else 32767.0
            w = -brake if v > 0 else (brake if v < 0 else 0.0)
            x1, v1 = step(x, v, w, self.K, self.a, p.coulomb, T, self.zoh)
            return x1, (0.0 if v1 * v <= 0 else v1)
        if x >= self._lp and w > 0 or x <= self._lm and w < 0:
            # END switch: no torque further that way; quick stop if still moving that way
            brake = self.u_peak if math.isfinite(self.u_peak) else 32767.0
            moving_on = v > 0 if x >= self._lp else v < 0
            w = (-brake if v > 0 else brake) if moving_on else 0.0
        x1, v1 = step(x, v, w, self.K, self.a, p.coulomb, T, self.zoh)
        if x1 > self._hp:
            return self._hp, 0.0
        if x1 < self._hm:
            return self._hm, 0.0
        return x1, v1

    # -- status -----------------------------------------------------------------------------
    def status_bits(self) -> int:
        busy = self.homing != 0 or bool(self._traj) or self._tail_v != 0.0 or self._coast \
            or self.open_loop
        closed = self.closed
        s = (St.ENABLED if closed else 0) | (St.BUSY if busy else 0) \
            | (St.DONE if self.done else 0) | (St.HOMED if self.homed else 0) \
            | (St.FE_WARNING if self.warn else 0) | (St.HOMING if self.homing else 0) \
            | (St.OPEN_LOOP if self.open_loop else 0)
        if closed and not busy and abs(self.fe) <= self._in_pos:
            s |= St.IN_POSITION
        err = self.error
        if err:
            s |= St.ERROR
            if self.latched and err in (Err.FATAL_FE, Err.LIMIT, Err.NOT_HOMED):
                s |= St.FE_FATAL
        if err == Err.AMP_FAULT or not self._ready:
            s |= St.AMP_FAULT
            if self.estop_active():
                s |= St.ESTOP
        x = self.x
        if x >= self._lp:
            s |= St.LIMIT_PLUS
        elif x <= self._lm:
            s |= St.LIMIT_MINUS
        return s

    def _write_status(self) -> None:
        # The status words are one contiguous run: one pack_into (its 'f' rounds to single
        # precision as the memory image's %MF casts do; native order as theirs).
        origin = self.origin
        x = self.x
        _STATUS_PACK(self._buf, self._status_at,
                     round((x - self._start if self._ideal else floor(x) - self._enc0)
                           - origin),  # _raw() inlined
                     round(self._cp - origin), self.fe if self.closed else 0.0, self.fe_max,
                     self.status_bits(), self.error, self.k & 0x7FFFFFFF, self.u,
                     self.w * self._cur_scale, self._vel)

    def status(self) -> dict[str, Any]:
        return {"pos": round(self.actual), "fe": round(self.fe, 2), "homed": self.homed,
                "error": Err.TEXT[self.error]}

    # -- snapshots --------------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        st = super().state()
        st["trace"] = self._trace_dropped + len(self.trace)  # rows recorded so far
        return st

    def set_state(self, st: dict[str, Any]) -> None:
        ratio, gains = self.load_mass_ratio, self.gains
        fixed = st["_fixed"]
        super().set_state(st)
        if self.load_mass_ratio != ratio or self.gains is not gains:
            self._build_consts()
            self._fixed = fixed
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

    def trace_to_csv(self, path: str | Path) -> None:
        with open(path, "w", encoding="utf-8") as f:
            f.write(TRACE_HEADER + "\n")
            for r in self.samples():
                f.write(f"{r[0]:.7f},{r[1]:.4f},{r[2]:.4f},{r[3]:.4f},{r[4]:.2f}\n")

    def close(self) -> None:
        if self.opt.trace_csv:
            self.trace_to_csv(self.opt.trace_csv)


def _interp(table: list[tuple[float, float]], x: float) -> float:
    """Piecewise-linear load at x, constant beyond the table's ends."""
    if x <= table[0][0]:
        return table[0][1]
    for (x0, y0), (x1, y1) in zip(table, table[1:], strict=False):
        if x <= x1:
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0)
    return table[-1][1]
