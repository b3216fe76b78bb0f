"""The servo axis's motion job: the command words' edges, the trajectories they start
(move, step, parabolic, open loop, jog, stop, homing), killing the motor, and the
sequencing once a trajectory has ended. It acts on its axis's state (`ServoAxis`, where the
snapshots and the generated servo loop find it); it holds none itself."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from softplc.devices.axis import trajectory as tj
from softplc.devices.axis.options import Ctl, Err, Mode, Word

if TYPE_CHECKING:
    from softplc.devices.axis.state import ServoState


class Motion:
    def __init__(self, axis: ServoState):
        self.a = axis

    def kill(self, error: int, latch: bool = True) -> None:
        a = self.a
        a.closed = a.open_loop = a._coast = False
        a.u = 0.0
        a._traj = ()
        a._tail_v = 0.0
        a.homing = 0
        if latch:
            a.latched = True
        if error:
            a.error = error

    def commands(self) -> None:
        """The control word's edges and levels, once per scan (see `Ctl`)."""
        a = self.a
        a._fixed = False  # whatever the commands change, the fixed point is re-proved
        mw = a._mem.mw  # type: ignore[union-attr]
        b = a._base
        ctl = mw.uw[b + Word.CONTROL]
        rise = ctl & ~a._ctl_prev
        fall = a._ctl_prev & ~ctl
        a._ctl_prev = ctl
        ready = a.amp_ready()
        if (a.closed or a.open_loop) and not ready:
            self.kill(Err.AMP_FAULT)
        if rise & Ctl.RESET:
            a.latched = False
            a.error = Err.NONE
        if ctl & Ctl.KILL or not ctl & Ctl.ENABLE:
            if a.closed or a.open_loop:
                self.kill(Err.NONE, latch=False)
            return
        if not (a.closed or a.open_loop):
            if a.latched or not ready:
                return
            self.close_loop()
        if rise & Ctl.HOME:
            self.start_home()
        elif rise & Ctl.EXECUTE:
            self.execute(mw, b)
        elif rise & Ctl.STOP:
            self.stop()
        jog = ctl & (Ctl.JOG_PLUS | Ctl.JOG_MINUS)
        if rise & jog and jog != Ctl.JOG_PLUS | Ctl.JOG_MINUS:
            self.jog(1 if jog == Ctl.JOG_PLUS else -1)
        elif fall & (Ctl.JOG_PLUS | Ctl.JOG_MINUS) or (rise & jog and jog != rise & jog):
            self.stop()

    # -- limits wired to the PMAC (geometry.limit_wiring = "pmac"; Ixx24 bit 17 = 0) --------
    # [manual: Turbo PMAC User Manual, "Making your Application Safe", hardware overtravel
    # limits] On a made limit the PMAC brings the commanded trajectory to a stop at the
    # Ixx15 rate (as an abort), the loop stays closed and holds; the limit is direction
    # sensitive: the + limit stops positive moves only, so moving away is allowed. It is
    # checked here once per scan (<= 1 ms late) [choice]; the servo output is not clamped
    # (holding needs both signs) [choice]. Error code LIMIT, not latched, no DONE.
    def limit_stop(self) -> None:
        """The carriage is on a limit: abort a commanded motion going into it."""
        a = self.a
        if a._limit_stop or not a.closed:
            return
        into = 1.0 if a.x >= a._lp else -1.0
        cv = a._cvp * a.loop_hz  # commanded velocity of the last tick, counts/s
        if cv * into <= 0 and a._tail_v * into <= 0:
            return
        if a.homing == 1:
            a.homing = 0
        decel = a.opt.geometry.limit_decel * 1e6  # counts/ms^2 -> counts/s^2
        self.follow(tj.velocity_change(a._cp, cv, 0.0, tj.RampRule(abs(cv) / decel, 0.0)))
        a._limit_stop = True
        a.error = Err.LIMIT

    def _into_limit(self, direction: float) -> bool:
        """A command moving `direction` (its sign) into a made "pmac" limit: refused."""
        a = self.a
        if a._pmac_lim and (direction > 0 and a.x >= a._lp or direction < 0 and a.x <= a._lm):
            a.error = Err.LIMIT
            return True
        return False

    def close_loop(self) -> None:
        """PMAC `J/`: close the loop holding the present actual position."""
        a = self.a
        ap = a._raw()
        a.closed, a.open_loop, a._coast = True, False, False
        a._cp = a._cpp = float(ap)
        a._cvp = 0.0
        a._app = ap
        a._ie = 0.0
        a._traj, a._tail_v = (), 0.0
        a._limit_stop = False

    def rule(self, acc_ms: int = 0, s_ms: int = 0, trapezoid: bool = False) -> tj.RampRule:
        g = self.a.gains
        ta = (acc_ms or g.accel_time) / 1000
        ts = 0.0 if trapezoid else (s_ms or g.scurve_time) / 1000
        return tj.RampRule(ta, ts, g.max_accel * 1e6)

    def busy(self) -> bool:
        a = self.a
        return a.homing != 0 or bool(a._traj) or a._tail_v != 0.0 or a._coast or a.open_loop

    def _refuse_unhomed(self) -> bool:
        if self.a.opt.require_home and not self.a.homed:
            self.kill(Err.NOT_HOMED)
            return True
        return False

    def execute(self, mw: Any, b: int) -> None:
        a = self.a
        mode = mw.w[b + Word.MODE]
        if self.busy() or not Mode.SCURVE <= mode <= Mode.OPEN_LOOP:
            a.error = Err.BAD_COMMAND
            return
        if self._refuse_unhomed():
            return
        acc_ms, s_ms = mw.uw[b + Word.ACC_TIME], mw.uw[b + Word.SCURVE_TIME]
        a.done = False
        a.fe_max = 0.0
        if mode == Mode.OPEN_LOOP:
            if self._into_limit(mw.w[b + Word.OPEN_LOOP]):
                return
            a.closed, a.open_loop = False, True
            a._ol_u = mw.w[b + Word.OPEN_LOOP] / 10000 * a.gains.output_limit
            a._ol_end = a.k + math.ceil(acc_ms / 1000 * a.loop_hz) if acc_ms else 0
            return
        target = mw.get_d(b + Word.TARGET) + a.origin
        speed = mw.get_d(b + Word.SPEED) or a.gains.jog_speed * 1000
        if speed <= 0:
            a.error = Err.BAD_COMMAND
            return
        if self._into_limit(target - a._cp):
            return
        if mode == Mode.STEP:  # the commanded position jumps at the next cycle
            self.follow(tj.Profile(float(target), 0.0), end=float(target))
            return
        if mode == Mode.PARABOLIC:
            if not acc_ms:
                a.error = Err.BAD_COMMAND
                return
            prof = tj.parabolic(a._cp, target, acc_ms / 1000)
        else:
            prof = tj.move(a._cp, target, float(speed),
                           self.rule(acc_ms, s_ms, mode == Mode.TRAPEZOID))
        self.follow(prof, end=float(target))

    def follow(self, prof: tj.Profile, end: float | None = None, v_end: float = 0.0) -> None:
        """Start a trajectory at the next cycle; `end` is the exact final position, `v_end`
        the velocity (counts/s) that continues after the profile (a jog's)."""
        a = self.a
        if not prof.duration <= tj.MAX_SAMPLES * a.T:  # refused, held (nan too)
            a.error = Err.BAD_COMMAND
            prof, end, v_end = tj.Profile(a._cp, 0.0), a._cp, 0.0
        traj = tj.sample(prof, a.T)
        a._limit_stop = False
        a._tail_v = v_end * a.T
        a._active = True
        if traj and end is not None:
            traj[-1] = end
        elif not traj and not a._tail_v:
            a._cp = end if end is not None else a._cp
        a._traj = tuple(traj)  # immutable: a state() shares it
        a._k0 = a.k + 1

    def _velocity_change(self, v1: float) -> tj.Profile:
        """From the commanded velocity of the last tick (counts/s) to v1."""
        a = self.a
        return tj.velocity_change(a._cp, a._cvp * a.loop_hz, v1, self.rule())

    def stop(self) -> None:
        a = self.a
        if a.open_loop:  # output 0, coast to a stop, then the loop closes
            a._ol_u, a._ol_end, a._coast = 0.0, 0, True
            return
        if not self.busy():
            return
        a.homing = 0 if a.homing == 1 else a.homing
        self.follow(self._velocity_change(0.0))

    def jog(self, sign: int) -> None:
        a = self.a
        if self._refuse_unhomed() or a.homing or self._into_limit(sign):
            return
        a.done = False
        v1 = sign * a.gains.jog_speed * 1000
        self.follow(self._velocity_change(v1), v_end=v1)

    def start_home(self) -> None:
        a = self.a
        if self.busy():
            a.error = Err.BAD_COMMAND
            return
        if self._into_limit(a.gains.home_speed):
            return
        a.homed = a.done = False
        a.fe_max = 0.0
        a.homing = 1
        v = a.gains.home_speed * 1000
        self.follow(tj.velocity_change(a._cp, 0.0, v, self.rule()), v_end=v)

    def home_trigger(self, capture: float) -> None:
        """The index pulse after the home flag: new origin, decelerate."""
        a = self.a
        a.origin = round(capture + a.gains.home_offset / 16)
        a.homed = True
        a.homing = 2
        self.follow(self._velocity_change(0.0))

    def after_ticks(self) -> None:
        """Scan-level sequencing once the trajectory has ended."""
        a = self.a
        if a._traj and a.k - a._k0 + 1 >= len(a._traj) and not a._tail_v:
            a._traj = ()  # a finished move holds its end exactly
        if a._traj or a._tail_v:
            return
        a._active = False
        if a.homing == 2:
            a.homing = 3
            speed = abs(a.gains.home_speed) * 1000
            self.follow(tj.move(a._cp, float(a.origin), speed, self.rule()),
                        end=float(a.origin))
        elif a.homing == 3:
            a.homing = 0
            a.done = True
        elif a.closed and not a._limit_stop:
            a.done = True
