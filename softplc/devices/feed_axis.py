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

from .axis.options import Err
from .axis.servo import ServoAxis, _interp
from .base import register_device


@register_device("feed_axis")
class FeedAxis(ServoAxis):
    """A servo axis whose loop is perfect: actual = commanded, torque = inverse dynamics."""

    def _start_home(self) -> None:
        self.error = Err.BAD_COMMAND

    def _cycles(self, n: int) -> int:
        if not self.closed or self.open_loop or not self._ready or self.fault != "none":
            return super()._cycles(n)
        p = self.opt.plant
        K, a, fc, table = self.K, self.a, p.coulomb, p.load_table
        hz = self.loop_hz
        x0 = self._start if self._ideal else self._enc0  # true position of raw count 0
        traj, k0, tail_v = self._traj, self._k0, self._tail_v
        cp, cpp, cvp = self._cp, self._cpp, self._cvp
        rec, origin = self._rec, self.origin
        w = self.w
        for k in range(self.k + 1, self.k + n + 1):
            if traj:
                j = k - k0
                cp = traj[j] if j < len(traj) else traj[-1] + tail_v * (j - len(traj) + 1)
            elif tail_v:
                cp += tail_v
            cv = cp - cpp
            ca = cv - cvp
            x, v = cp + x0, cv * hz
            w = ca * hz * hz / K + a / K * v + p.load \
                + (fc if v > 0 else -fc if v < 0 else 0.0) + (_interp(table, x) if table else 0.0)
            cpp, cvp = cp, cv
            if rec is not None:
                rec((k, cp - origin, cp - origin, w - p.amp_offset))
        self.k += n
        self.x, self.v = cp + x0, cvp * hz
        self._cp, self._cpp, self._cvp, self._app = cp, cpp, cvp, cp
        self.w, self.u = w, w - p.amp_offset
        self.fe = 0.0
        return 0
