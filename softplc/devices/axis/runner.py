"""The servo axis's loop job: the constants of its generated servo loop (`loop.py`), running
the cycles due in a scan, the exact fast path at a fixed point of the loop, what interrupts
the cycles (events) and the drive's exceptional states. Like `Motion`, it acts on the
state of its `ServoAxis` and holds none that a snapshot needs."""

from __future__ import annotations

import math
import struct
from itertools import repeat
from typing import TYPE_CHECKING, Any

from softplc.devices.axis import loop, status
from softplc.devices.axis.options import Err
from softplc.devices.axis.plant import ZOH, step
from softplc.devices.base import interp as _interp

if TYPE_CHECKING:
    from softplc.devices.axis.state import ServoState


class LoopRunner:
    def __init__(self, axis: ServoState):
        self.a = axis

    def build(self) -> None:
        """The plant terms that depend on the moving mass, and the loop's constants (after
        a change of the mass, the load or an I-variable)."""
        a = self.a
        o, p, g = a.opt, a.opt.plant, a.opt.geometry
        a.K = p.K / (1 + a.load_mass_ratio)
        a.a = p.a / (1 + a.load_mass_ratio)
        a.zoh = z = ZOH.of(a.a, a.T)
        gn = a.gains
        c = a.coef
        inf = math.inf
        table = p.load_table
        load = p.load + a.disturbance
        # Everything the servo loop reads but never changes: literals of its generated code
        # (loop.py), with the flags that drop the branches this configuration never takes.
        fatal = gn.fatal_fe / 16 if gn.fatal_fe else inf
        warn = gn.warn_fe / 16 if gn.warn_fe else inf
        ilim = gn.int_limit / 16 if gn.int_limit else inf
        values = dict(
            cfe=c.fe, ccv=c.cv, cca=c.ca, cie=c.ie, cav=c.av, ilim=ilim, nilim=-ilim,
            ff=gn.friction_ff, off=gn.offset, lim=gn.output_limit, nlim=-gn.output_limit,
            fatal=fatal, warn_lim=warn, check=min(warn, fatal), q=a._dac_q, K=a.K,
            a=a.a, fc=p.coulomb, nfc=-p.coulomb, uoff=p.amp_offset, up=a.u_peak,
            nup=-a.u_peak, load=load, phi=z.phi, g1=z.g1, g2=z.g2, T=a.T,
            enc0=o.start if a._ideal else a._enc0, lo=a._lo, hi=a._hi,
            hlo=g.home_switch[0], hhi=g.home_switch[1], iper=g.index_period,
            ioff=g.index_offset)
        values["law"], no_neg_zero = loop.law(c, gn.offset)
        if len(table) == 2:
            (x0, y0), (x1, y1) = table
            values.update(t_x0=x0, t_y0=y0, t_x1=x1, t_y1=y1, t_dy=y1 - y0, t_dx=x1 - x0)
        self._values = values
        self._flags = dict(
            ideal=a._ideal, int_always=gn.int_mode == 0, ilim=ilim != inf,
            check=min(warn, fatal) != inf, warn_on=warn != inf, fatal_on=fatal != inf,
            dac=bool(a._dac_q), trace=a._rec is not None, gather=a.gather is not None,
            up=a.u_peak != inf, load=load != 0, phi1=z.phi == 1.0, table2=len(table) == 2,
            table=len(table) not in (0, 2), fc0=p.coulomb == 0,
            w_is_u=p.amp_offset == 0 and (no_neg_zero or math.copysign(1, p.amp_offset) < 0),
            ff0=gn.friction_ff == 0 and no_neg_zero,
            ca=" ca" in values["law"], av=" av" in values["law"])
        self._loops: dict[tuple[bool, ...], Any] = {}
        a._warn_lim = warn
        a._in_pos = gn.in_position / 16
        a._fixed = False
        a._scan = self.scan_function()

    def scan_function(self) -> Any:
        """The generated scan of the common case (`loop._SCAN`), or None where it does not
        apply: before bind, a variant's own cycles (feed_axis), a gather."""
        a = self.a
        if (getattr(a, "_mem", None) is None or type(self).cycles is not LoopRunner.cycles
                or a.gather is not None):
            return None
        values = dict(self._values, ctl_i=a._ctl_i, hz_us=a._hz_us, trim_at=a._trim_at,
                      estop_idx=a._estop_idx, power_idx=a._power_idx,
                      mass_word=a._mass_word,
                      plim_lo=a._plo, plim_hi=a._phi, in_pos=a._in_pos, lp=a._lp, lm=a._lm,
                      cur_scale=a._cur_scale, status_at=a._status_at,
                      ticks_at=a._status_at + status.TICKS_AT,
                      status_end=a._status_at + status.END_AT)
        flags = dict(self._flags, closed=True, open_loop=False, killed=False, search=False,
                     special=False, ready=True, capture=False, use_ca=self._flags["ca"],
                     use_av=self._flags["av"], estop=a._estop_idx is not None,
                     power=a._power_idx is not None, wired=a._wired,
                     mass=a._mass_word is not None)  # (cycles' key of the case)
        return loop.generated(values, flags, _interp, step, loop.scan_source(), "scan")

    def run(self, due: int) -> None:
        """The servo cycles due by the scan's time (the cycle count `due`). (The device's
        update runs the common case itself, a closed loop moving: no fixed point.)"""
        a = self.a
        n = due - a.k
        if n <= 0:
            return
        if a._fixed:
            n = self._repeat(n)  # (a creep may end within the scan: the rest computed)
        elif not a.closed_ and self._at_rest_open():
            n, a.k = 0, due  # killed and stuck: nothing moves, nothing to record
        elif a.v_ == 0.0 and self._fixed_candidate():
            # (with FE != 0 and no clamp the integrator moves: a creep, not a fixed point)
            if a.fe_ == 0.0 or a._clamped_:
                n = self._probe_fixed(n)
            else:
                a._creep = self._creep_ticks()
                a._fixed = a._creep > 0
            if a._fixed:
                n = self._repeat(n)
        while n > 0:
            n = self.cycles(n)
        if a._rec is not None and len(a.trace) >= a._trim_at:
            self.trim()

    def trim(self) -> None:
        """Keep the trace's last trace_max rows (called once it holds twice that)."""
        a = self.a
        rec = a.trace
        cut = len(rec) - a.opt.trace_max
        del rec[:cut]
        a._trace_dropped += cut

    def _at_rest_open(self) -> bool:
        """Loop open, carriage still and held by friction against the drive's offset and
        the load: the cycles would change nothing."""
        a = self.a
        if a.closed_ or a.open_loop_ or a.v_ != 0.0 or a.fault_ != "none":
            return False
        p = a.opt.plant
        w = (p.amp_offset if a.amp_ready() else 0.0) - p.load - a.disturbance
        return not p.load_table and abs(w) <= p.coulomb and a._lm < a.x_ < a._lp

    # -- the fixed point ----------------------------------------------------------------------
    # A servo cycle maps the loop state L = (x, v, CP, CP', CV', AP', IE, clamped, u) to the
    # next one; with the loop closed, no trajectory left (CP constant), no tail velocity, the
    # drive ready, no fault, no homing search and the carriage inside the limits, the map
    # depends on nothing else (not on the cycle number). So if one cycle leaves L bit for bit
    # as it was, every later cycle does too and computes the same u, w, FE: the cycles can
    # be skipped, their trace rows written in one go, until a command, a fault, the drive's
    # READY, the moving mass, the load or an I-variable changes (Motion.commands, set_fault,
    # build clear the flag). The test is on the packed bytes (-0.0 and 0.0 differ), so it is
    # exact, not approximate. `_fixed` with `_creep` > 0: a creep (below) for that many
    # cycles.
    _PACK = struct.Struct("<9d").pack

    def _loop_state(self) -> bytes:
        a = self.a
        return self._PACK(a.x_, a.v_, a._cp_, a._cpp_, a._cvp_, a._app_, a._ie_, a._clamped_, a.u_)

    def _fixed_candidate(self) -> bool:
        """The conditions under which the cycle map is the same for every cycle."""
        a = self.a
        return (a.closed_ and not a.open_loop_ and not a._tail_v_
                and a.k + 1 - a._k0 >= len(a._traj_) and a.homing_ != 1
                and a._ready_ and a.fault_ == "none" and a._lo < a.x_ < a._hi)

    def _probe_fixed(self, n: int) -> int:
        """Run one of the n due cycles; note a fixed point. Returns the cycles left."""
        before = self._loop_state()
        left = self.cycles(1)
        a = self.a
        a._fixed, a._creep = self._fixed_candidate() and self._loop_state() == before, 0
        return n - 1 + left

    def _repeat(self, n: int) -> int:
        """n cycles at the fixed point (only the cycle count and the records move on), or
        up to n of a creep's (the integrator moves too). Returns the cycles left."""
        a = self.a
        k = a.k
        o = a.origin_
        if a._creep:
            n, left = min(n, a._creep), n - min(n, a._creep)
            ie, fe = a._ie_, a.fe_
            for _ in range(n):  # the loop's own additions, in its order: bit for bit
                ie += fe
            # (the fields: a creep is the fixed point's own advance, run only by the
            # device's generic update, which then writes the status words in full)
            a._ie_ = ie
            a._creep -= n
            a._fixed = a._creep > 0
            c = self._values  # the drive's command over the last period: the held output's
            a.w_ = max(c["nup"], min(c["up"], a.u_ + c["uoff"]))
        else:
            left = 0
        if a._rec is not None:
            a.trace.extend(zip(range(k + 1, k + n + 1), repeat(a._cp_ - o),
                               repeat(a._app_ - o), repeat(a.u_), strict=False))
        if a.gather is not None:
            a.gather.extend(zip(range(k + 1, k + n + 1), repeat(a._cp_ - o),
                                repeat(a._app_ - o), repeat(a.u_),
                                repeat(self._values["cie"] * a._ie_), strict=False))
        a.k = k + n
        return left

    # A creep: at rest with FE != 0 (the carriage stuck by friction a few counts off), each
    # cycle adds FE to the integrator and changes nothing else while the output stays in
    # its 12-bit DAC step: hundreds of cycles at a time at the servo table's Ki. Then the
    # cycles can be skipped but for that addition, until the step's edge comes near.
    def _creep_ticks(self) -> int:
        """Cycles that are certainly a creep from now (0: none). Called at rest (v = 0)
        under `_fixed_candidate`."""
        a = self.a
        fe, q = a.fe_, a._dac_q
        if (a._clamped_ or not q or a.gather is not None or a._cp_ != a._cpp_
                or a._cvp_ != 0.0 or a.opt.plant.load_table):
            return 0
        c = self._values
        if abs(fe) > c["check"]:
            return 0
        w = a.u_ + c["uoff"]  # the drive's command the output gives, then stiction?
        w = max(-c["up"], min(c["up"], w)) - c["load"]
        if not -c["fc"] <= w <= c["fc"]:
            return 0
        # the law's output as the loop computes it (CV = CA = AV = 0), in the DAC step of u
        u = c["cfe"] * fe + c["ccv"] * 0.0 + c["cca"] * 0.0 + c["cie"] * a._ie_ \
            - c["cav"] * 0 + c["off"]
        lo = q * math.floor(u / q)
        if lo != a.u_ or not -c["lim"] <= lo < lo + q <= c["lim"]:
            return 0
        d = c["cie"] * fe  # the output's change per cycle
        if d == 0.0:
            return 0
        m = math.floor((lo + q - u) / d if d > 0 else (u - lo) / -d) - 2  # (2: a margin)
        if c["ilim"] != math.inf:
            m = min(m, math.floor((c["ilim"] - abs(a._ie_)) / abs(fe)) - 2)
        return max(m, 0)
    def cycles(self, n: int, capture: bool = False) -> int:
        """Run up to n loop cycles; returns how many are left when an event interrupts.
        `capture`: also keep the last cycle's CA and AV (`_ca`, `_av`; IVarTable.apply)."""
        a = self.a
        closed, open_loop = a.closed_, a.open_loop_
        ready = a._ready_
        key = (closed, open_loop, a.homing_ == 1, ready, a.fault_ != "none", capture)
        fn = self._loops.get(key)
        if fn is None:
            flags = dict(self._flags, closed=closed, open_loop=open_loop,
                         killed=not (closed or open_loop), search=key[2],
                         special=not ready or key[4], ready=ready, capture=capture,
                         use_ca=self._flags["ca"] or capture,
                         use_av=self._flags["av"] or capture)
            fn = self._loops[key] = loop.generated(self._values, flags, _interp, step)
        return fn(a, n)

    def on_event(self, event: Any) -> None:
        """What interrupted the cycles (called by the loop with its state written back)."""
        a = self.a
        if event == "fatal":
            x = a.x_
            a.motion.kill(Err.LIMIT if x >= a._lp or x <= a._lm else Err.FATAL_FE)
        elif event == "open loop end":  # output 0: the carriage coasts to a stop
            a._ol_u = 0.0
            a._ol_end = 0
            a._coast = True
        else:
            a.motion.home_trigger(event[1])

    def special(self, x: float, v: float, w: float) -> tuple[float, float]:
        """The drive's and the mechanics' exceptional states, one cycle."""
        a = self.a
        p = a.opt.plant
        if a.fault_ == "jammed":
            return x, 0.0
        brake = a.u_peak if math.isfinite(a.u_peak) else 32767.0
        if a.estop_active():
            # The drive brakes at its current limit and lets go once the carriage is at
            # rest (`hold`: the tick ends where the velocity reaches 0, never beyond: a
            # braking that reversed would carry it back against its travel).
            w = -brake if v > 0 else (brake if v < 0 else 0.0)
            return step(x, v, w, a.K, a.a, p.coulomb, a.T, a.zoh, hold=True)
        stopping = False
        if not a._pmac_lim and (x >= a._lp and w > 0 or x <= a._lm and w < 0):
            # END switch: no torque further that way; quick stop if still moving that way
            stopping = v > 0 if x >= a._lp else v < 0
            w = (-brake if v > 0 else brake) if stopping else 0.0
        # (a quick stop ends at standstill, never reverses: `hold`)
        x1, v1 = step(x, v, w, a.K, a.a, p.coulomb, a.T, a.zoh, hold=stopping)
        if x1 > a._hp:
            return a._hp, 0.0
        if x1 < a._hm:
            return a._hm, 0.0
        return x1, v1
