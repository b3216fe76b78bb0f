"""How the two axes run one straight segment: the speed/acceleration split (§2.1).

A Twido has no interpolated multi-axis motion: each axis runs its own trapezoidal profile to
an absolute target. The carriage stays on the straight line only if both trapezoids are the
same shape scaled by |u_i|, i.e. v_i = v·|u_i| AND a_i = a·|u_i|; the thesis splits the speed
only (equal accelerations, defect B3, in `seed.thesis_split`). The PLC program computes this
split in float IL; this module is the host's reference for it (tests, ETA, seed comparison)
and the Matlab stepping the thesis plots with.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Protocol

from softplc.machines.cutting.geometry import GeometryError, Point, distance

#: The thesis's acceleration (FB_TrazarLinea positiveAccel 100), mm/s², and path speed
#: (Matlab v = 2) [choice D3], and the Matlab cycle T = 0.025 s.
DEFAULT_ACCEL = 100.0
DEFAULT_SPEED = 2.0
MATLAB_CYCLE = 0.025
#: Relative slack of the Matlab step count (so 4/0.05 gives 80 full steps, not 79 + 1).
STEP_SLACK = 1e-9


class SegmentLike(Protocol):
    """What `simulate` needs of a segment (`piece.Segment` has it)."""

    start: Point
    end: Point
    speed: float
    cut: bool


@dataclass(frozen=True)
class Trapezoid:
    """A symmetric trapezoidal (or triangular) profile over `length` >= 0 mm."""

    length: float
    speed: float
    accel: float

    @property
    def triangular(self) -> bool:
        return self.length / self.speed < self.speed / self.accel  # ratios: no underflow

    @property
    def accel_time(self) -> float:
        if self.triangular:
            return math.sqrt(self.length / self.accel)
        return self.speed / self.accel

    @property
    def duration(self) -> float:
        """L/v + v/a, or 2·sqrt(L/a) when the cruise speed is never reached."""
        if self.length == 0.0:
            return 0.0
        if self.triangular:
            return 2.0 * math.sqrt(self.length / self.accel)
        return self.length / self.speed + self.speed / self.accel

    def position(self, t: float) -> float:
        """Distance covered at time t (0 before, `length` after the move)."""
        T, ta = self.duration, self.accel_time
        if t <= 0.0 or self.length == 0.0:
            return 0.0
        if t >= T:
            return self.length
        peak = self.accel * ta
        if t < ta:
            return 0.5 * self.accel * t * t
        if t <= T - ta:
            return 0.5 * self.accel * ta * ta + peak * (t - ta)
        rest = T - t
        return self.length - 0.5 * self.accel * rest * rest


@dataclass(frozen=True)
class AxisMove:
    """One axis's command for a segment: absolute target, speed and acceleration."""

    target: float
    speed: float
    accel: float
    profile: Trapezoid
    direction: float  # +1 / -1 (0: the axis does not move)


@dataclass(frozen=True)
class LineSplit:
    """Both axes' commands for the straight move start -> end."""

    start: Point
    end: Point
    x: AxisMove
    y: AxisMove

    @property
    def duration(self) -> float:
        return max(self.x.profile.duration, self.y.profile.duration)

    @property
    def arrival_gap(self) -> float:
        """|t_x - t_y| for the moving axes: 0 when both arrive together."""
        times = [a.profile.duration for a in (self.x, self.y) if a.direction]
        return max(times) - min(times) if times else 0.0

    def position(self, t: float) -> Point:
        return (self.start[0] + self.x.direction * self.x.profile.position(t),
                self.start[1] + self.y.direction * self.y.profile.position(t))

    def cross_track(self, samples_per_phase: int = 200) -> tuple[float, float]:
        """(largest distance of the carriage from the straight line, time it occurs),
        sampled on every phase of both profiles (constant during the common cruise)."""
        L = distance(self.start, self.end)
        if L == 0.0:
            return 0.0, 0.0
        ux, uy = (self.end[0] - self.start[0]) / L, (self.end[1] - self.start[1]) / L
        marks = {0.0, self.duration}
        for a in (self.x, self.y):
            p = a.profile
            marks |= {p.accel_time, p.duration - p.accel_time, p.duration}
        marks = sorted(m for m in marks if 0.0 <= m <= self.duration)
        worst, at = 0.0, 0.0
        for t0, t1 in zip(marks, marks[1:], strict=False):
            for i in range(samples_per_phase + 1):
                t = t0 + (t1 - t0) * i / samples_per_phase
                px, py = self.position(t)
                d = abs((px - self.start[0]) * uy - (py - self.start[1]) * ux)
                if d > worst:
                    worst, at = d, t
        return worst, at


def _check(speed: float, accel: float) -> None:
    for name, v in (("speed", speed), ("acceleration", accel)):
        if not (math.isfinite(v) and v > 0):
            raise GeometryError(f"line {name} {v:g} must be a positive number")


def axis_move(start: float, target: float, speed: float, accel: float) -> AxisMove:
    d = target - start
    return AxisMove(target, speed, accel, Trapezoid(abs(d), speed, accel),
                    (d > 0) - (d < 0))


def split_line(start: Point, end: Point, speed: float = DEFAULT_SPEED,
               accel: float = DEFAULT_ACCEL) -> LineSplit:
    """The corrected split: v_i = v·|u_i|, a_i = a·|u_i|; both axes take L/v + v/a (or the
    triangle 2·sqrt(L/a)) and the carriage stays on the line. An axis with u_i = 0 gets the
    path values (it does not move anyway, and the PLC refuses a zero speed); L = 0 is a
    no-op (both axes already there)."""
    _check(speed, accel)
    L = distance(start, end)
    moves = []
    for i in (0, 1):
        d = abs(end[i] - start[i])
        u = d / L if L > 0 else 0.0
        if min(d, u, speed * u, accel * u) >= sys.float_info.min:
            moves.append(axis_move(start[i], end[i], speed * u, accel * u))
        else:
            # No share of the line, or one so small that it or its speed is a subnormal
            # double (a 1e-313 mm offset): the axis does not move. A direction with a zero-
            # speed profile would arrive at t=0, and subnormals have too few significant
            # bits for the profile's ratios (the arrival came 1e-7 s early).
            moves.append(AxisMove(end[i], speed, accel, Trapezoid(0.0, speed, accel), 0))
    return LineSplit(start, end, moves[0], moves[1])


@dataclass(frozen=True)
class SteppedLine:
    """A line as the Matlab plots step it: full steps of v·T, then one shorter last step."""

    points: list[Point]  # after each step, ending at the line's end
    full_steps: int
    last_step: float  # length of the short last step (0: none)


def matlab_steps(start: Point, end: Point, speed: float = DEFAULT_SPEED,
                 cycle: float = MATLAB_CYCLE) -> SteppedLine:
    """Corrected ConsignaLinea: n = floor(L/(v·T)) steps of u·v·T, then r = L - n·v·T in
    [0, v·T) if r > 1e-9·L. Every step is <= v·T and none goes backwards (B1, B2 fixed)."""
    _check(speed, cycle)
    L = distance(start, end)
    if L == 0.0:
        return SteppedLine([], 0, 0.0)
    step = speed * cycle
    n = math.floor(L / step * (1 + STEP_SLACK))
    r = L - n * step
    if r <= STEP_SLACK * L:
        r = 0.0
    ux, uy = (end[0] - start[0]) / L, (end[1] - start[1]) / L
    pts = [(start[0] + ux * step * k, start[1] + uy * step * k) for k in range(1, n + 1)]
    if r > 0.0:
        pts.append(end)
    elif pts:
        pts[-1] = end
    return SteppedLine(pts, n, r)


@dataclass(frozen=True)
class Sample:
    """One point of a simulated run: time (s), position (mm), torch on."""

    t: float
    x: float
    y: float
    torch: bool


def simulate(segments: Iterable[SegmentLike], accel: float = DEFAULT_ACCEL,
             dt: float = 0.01, split: Callable[..., LineSplit] = split_line) -> list[Sample]:
    """The carriage's path with ideal axes: each segment's two profiles from `split` (the
    corrected one, or `seed.thesis_split`), run one after the other with no handshake time,
    sampled every `dt` seconds of each segment plus its end. No PLC, no device: a reference
    for the device round's traces and a way to see B3 on a whole piece."""
    if not (math.isfinite(dt) and dt > 0):
        raise GeometryError(f"simulation step {dt:g} s must be positive")
    out: list[Sample] = []
    t0 = 0.0
    for seg in segments:
        s = split(seg.start, seg.end, seg.speed, accel)
        n = math.floor(s.duration / dt)
        for k in range(n + 1):
            x, y = s.position(k * dt)
            out.append(Sample(t0 + k * dt, x, y, seg.cut))
        if n * dt < s.duration:
            out.append(Sample(t0 + s.duration, *s.position(s.duration), seg.cut))
        t0 += s.duration + getattr(seg, "dwell", 0.0)  # a dwell stands still
    return out
