"""An ideal feed axis (mass-estimation.md §6: actual = commanded): the servo axis's words,
options and plant, without the loop's lag. Every servo cycle the carriage is exactly at
the commanded position, and the drive gives exactly the torque the plant needs for it
(inverse dynamics of `plant`):

    w = x'' / K + (a / K) x' + coulomb sgn(x') + load(x)          (DAC bits)

with x', x'' the commanded velocity and acceleration over the cycle (backward differences
of the commanded positions, counts/s, counts/s²) and K, a those of the moving mass (the
load mass word included). So the same machine runs with `type = "feed_axis"` instead of
`"servo_axis"` and nothing else changed, and the estimator sees the mass without the
closed loop's following error. The following error is 0; the I-variables only shape the
moves (Ixx19-Ixx22); HOME is refused (BAD_COMMAND: an ideal axis has no index search);
with the loop open (disabled, killed, open-loop output) it is the servo axis's plant.
"""

from __future__ import annotations

from softplc.devices.axis.motion import Motion
from softplc.devices.axis.options import Err
from softplc.devices.axis.runner import LoopRunner, _interp
from softplc.devices.axis.servo import ServoAxis
from softplc.devices.base import register_device


class _IdealMotion(Motion):
    def start_home(self) -> None:
        self.a.error = Err.BAD_COMMAND  # an ideal axis has no index search


class _IdealRunner(LoopRunner):
    """Cycles of a perfect loop while it is closed; the servo axis's own otherwise."""

    def run(self, due: int) -> None:
        n = due - self.a.k
        while n > 0:  # (no fixed point to look for: nothing lags, nothing creeps)
            n = self.cycles(n)
        if self.a._rec is not None and len(self.a.trace) >= self.a._trim_at:
            self.trim()

    def build(self) -> None:
        super().build()
        a, p = self.a, self.a.opt.plant
        # the plant's terms of a cycle, once per mass (`acc / K`: the cycle's own first
        # product, the same value)
        self._plant = (a.K, a.a / a.K, p.coulomb, p.load_table, p.load, p.amp_offset,
                       a.loop_hz, a._start if a._ideal else a._enc0)

    def cycles(self, n: int, capture: bool = False) -> int:
        a = self.a  # (the state's fields, not its properties: read once a scan)
        if not a.closed_ or a.open_loop_ or not a._ready_ or a.fault_ != "none":
            return super().cycles(n, capture)
        # x0: the true position of raw count 0
        K, acc_k, fc, table, load, uoff, hz, x0 = self._plant
        traj, k0, tail_v = a._traj_, a._k0, a._tail_v_
        ntraj = len(traj)
        cp, cpp, cvp = a._cp_, a._cpp_, a._cvp_
        rec, origin = a._rec, a.origin_
        w = a.w_
        for k in range(a.k + 1, a.k + n + 1):
            if ntraj:
                j = k - k0
                cp = traj[j] if j < ntraj else traj[-1] + tail_v * (j - ntraj + 1)
            elif tail_v:
                cp += tail_v
            cv = cp - cpp
            ca = cv - cvp
            x, v = cp + x0, cv * hz
            w = ca * hz * hz / K + acc_k * v + load \
                + (fc if v > 0 else -fc if v < 0 else 0.0) + (_interp(table, x) if table else 0.0)
            cpp, cvp = cp, cv
            if rec is not None:
                rec((k, cp - origin, cp - origin, w - uoff))
        a.k += n
        # (the fields, then the caches made from them dropped once: what the properties'
        # setters do, state.guard, without their cost eight times a scan)
        a.x_, a.v_ = cp + x0, cvp * hz
        a._cp_, a._cpp_, a._cvp_, a._app_ = cp, cpp, cvp, cp
        a.w_, a.u_ = w, w - uoff
        a.fe_ = 0.0
        a._rest_words, a._st_slow, a._fixed = None, -1, False
        return 0


@register_device("feed_axis")
class FeedAxis(ServoAxis):
    """A servo axis whose loop is perfect: actual = commanded, torque = inverse dynamics."""

    MOTION = _IdealMotion
    RUNNER = _IdealRunner
