"""Trajectories of the servo axis: jog-type S-curve / trapezoid moves, velocity ramps (jog,
stop), steps and parabolic moves, sampled at the servo ticks.

A profile is a list of constant-jerk segments from a start state; `sample(profile, T, n)`
gives the commanded positions at t = T, 2T, ... nT after its start (numpy, once per
move), and the device steps through that list at the servo rate, continuing at the
profile's final velocity after its end (a jog's cruise) or holding the end position.

S-curve rules (PMAC Ixx19-Ixx21 [manual]; the spec `servo-table.md` section 3.3):
TA = max(Ixx20, 2 Ixx21), TS = Ixx21: jerk phases TS at both ends of each ramp, constant
acceleration for TA - 2 TS in between, peak acceleration A = dV / (TA - TS); TS = 0 is a
trapezoid (A = dV / TA). If A exceeds Ixx19, TA and TS are stretched by A / Ixx19. A move
shorter than V TA runs at V = D / TA with no cruise [choice]. A stop or a jog change ramps
from the current commanded velocity with the same rules [choice].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Profile:
    """Constant-jerk segments (duration s, jerk, acceleration at the segment's start)."""

    p0: float
    v0: float
    segments: list[tuple[float, float, float]] = field(default_factory=list)

    @property
    def duration(self) -> float:
        return sum(d for d, _, _ in self.segments)

    def end(self) -> tuple[float, float]:
        """(position, velocity) at the end of the last segment."""
        p, v = self.p0, self.v0
        for d, j, a in self.segments:
            p += v * d + a * d * d / 2 + j * d ** 3 / 6
            v += a * d + j * d * d / 2
        return p, v


@dataclass(frozen=True)
class RampRule:
    """Ixx19 (max acceleration, counts/s^2; 0 = no limit), Ixx20, Ixx21 (seconds)."""

    accel_time: float
    scurve_time: float
    max_accel: float = 0.0

    def ramp(self, dv: float) -> list[tuple[float, float, float]]:
        """Segments that change the velocity by dv from zero acceleration to zero."""
        if dv == 0:
            return []
        ta = max(self.accel_time, 2 * self.scurve_time)
        ts = self.scurve_time
        if ta <= 0:
            return []  # callers make the velocity change instantaneous
        peak = abs(dv) / (ta - ts)
        if self.max_accel > 0 and peak > self.max_accel:
            f = peak / self.max_accel
            ta, ts = ta * f, ts * f
            peak = abs(dv) / (ta - ts)
        acc = math.copysign(peak, dv)
        if ts <= 0:
            return [(ta, 0.0, acc)]
        jerk = acc / ts
        segs = [(ts, jerk, 0.0)]
        if ta - 2 * ts > 0:
            segs.append((ta - 2 * ts, 0.0, acc))
        segs.append((ts, -jerk, acc))
        return segs

    @property
    def ramp_time(self) -> float:
        return max(self.accel_time, 2 * self.scurve_time)


def move(p0: float, target: float, speed: float, rule: RampRule) -> Profile:
    """A jog-type point-to-point move from rest: ramp up, cruise, ramp down."""
    dist = target - p0
    if dist == 0 or speed <= 0:
        return Profile(p0, 0.0)
    d = abs(dist)
    sign = 1.0 if dist > 0 else -1.0
    if rule.ramp_time <= 0:  # no ramps: constant velocity (the trapezoid's limit)
        return _constant_velocity(p0, sign * speed, d / speed)

    def ramp_time(v: float) -> float:
        return sum(s[0] for s in rule.ramp(v))

    v = speed
    if d < v * ramp_time(v):  # too short to reach the speed: the fastest v that fits
        lo, hi = 0.0, speed
        for _ in range(60):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if d >= mid * ramp_time(mid) else (lo, mid)
        v = lo
    cruise = d / v - ramp_time(v)
    segs = rule.ramp(sign * v) + ([(cruise, 0.0, 0.0)] if cruise > 0 else [])
    return Profile(p0, 0.0, segs + rule.ramp(-sign * v))


def _constant_velocity(p0: float, v: float, t: float) -> Profile:
    """Velocity v for t seconds from rest to rest (infinite acceleration at both ends)."""
    return Profile(p0, v, [(t, 0.0, 0.0)]) if t > 0 else Profile(p0, 0.0)


def velocity_change(p0: float, v0: float, v1: float, rule: RampRule) -> Profile:
    """From velocity v0 to v1 (a jog start, a jog speed change, or a stop with v1 = 0);
    the profile's final velocity v1 then continues."""
    if rule.ramp_time <= 0:
        return Profile(p0, v1)
    return Profile(p0, v0, rule.ramp(v1 - v0))


def parabolic(p0: float, target: float, duration: float) -> Profile:
    """PMAC tuning 'parabolic velocity' move: v(t) = 6 D t (T - t) / T^3 (one jerk segment
    with a negative jerk), from rest to rest in `duration` seconds."""
    if duration <= 0 or target == p0:
        return Profile(p0, 0.0)
    d = target - p0
    a0 = 6 * d / duration ** 2
    return Profile(p0, 0.0, [(duration, -2 * a0 / duration, a0)])


# The longest trajectory an axis plans (its positions are sampled in advance): about
# 15 minutes at 2.26 kHz, 70 MB; a longer one (a crawl speed, an absurd ramp) is refused.
MAX_SAMPLES = 1 << 21


def sample(prof: Profile, T: float, n: int | None = None) -> list[float]:
    """Commanded positions at T, 2T, ... after the profile's start, until its end (or n)."""
    segs = prof.segments
    dur = prof.duration
    count = math.ceil(dur / T - 1e-9) if n is None else n
    if count <= 0:
        return []
    t = np.arange(1, count + 1, dtype=float) * T
    starts = np.zeros(len(segs) + 1)
    p = np.zeros(len(segs) + 1)
    v = np.zeros(len(segs) + 1)
    p[0], v[0] = prof.p0, prof.v0
    for i, (d, j, a) in enumerate(segs):
        starts[i + 1] = starts[i] + d
        p[i + 1] = p[i] + v[i] * d + a * d * d / 2 + j * d ** 3 / 6
        v[i + 1] = v[i] + a * d + j * d * d / 2
    jerk = np.array([s[1] for s in segs] + [0.0])
    acc = np.array([s[2] for s in segs] + [0.0])
    k = np.searchsorted(starts, t, side="right") - 1
    k = np.minimum(k, len(segs))
    tau = t - starts[k]
    out = p[k] + v[k] * tau + acc[k] * tau * tau / 2 + jerk[k] * tau ** 3 / 6
    return out.tolist()
