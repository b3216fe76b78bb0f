"""Seed mode: the thesis's setpoint algorithms with their documented defects (§2.6).

Each function here computes what the thesis's Matlab or SIMOTION code computes, so tests and
users can put it next to the corrected algorithm (`geometry.py`, `motion.py`) and see the
difference. Nothing here is used to cut a piece unless the user asks for seed mode.

- `thesis_line_steps`: ConsignaLinea, B1 (speeds always >= 0, last step from atan) and B2
  (n = round, the last step can be negative).
- `thesis_split`: FB_TrazarLinea, B3 (equal accelerations bend the line).
- `thesis_arc_points`: TrazarArco2 / FB_TrazarCirculo, B6 (3·v·T or 0.03 rad step), B7
  (round overshoots the arc end; CW impossible in the Matlab, while the CPU's step carries
  the sign of θ), B9 (TRUNC to 0.001 on the CPU).
- `thesis_beta`: the start angle from atan(|y/x|) plus quadrant offsets, B5 (Matlab wrong in
  the 2nd quadrant; the CPU right only on the +x ray and, by chance, at 135°).
- `thesis_cpu_arc`: the CPU's circle loop, B8 (next point when within 0.005, the arc ends
  when both axes are within 0.1 of Pf: a full circle ends at once, an arc that misses the
  box goes round again), with B5 and B9 optional.
- `ThesisNewton`: ClcDifPolNwt + TrazarPolinomio, B12 (h = x1 - x0 assumed), B13 (the last
  term dropped: wrong value at the last node), B16 (sampling stops at the penultimate node).
- `run_trigger_chain`: the piece programs' trigger chains, B19 (end tests not gated by
  their trigger: the shield piece is cut forever), bounded and detected.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from softplc.machines.cutting.geometry import (
    TAU,
    GeometryError,
    NewtonCurve,
    Point,
    distance,
    forward_coefficients,
)
from softplc.machines.cutting.motion import (
    DEFAULT_ACCEL,
    DEFAULT_SPEED,
    MATLAB_CYCLE,
    LineSplit,
    axis_move,
)
from softplc.machines.gcode.parser import steps_of

#: The CPU's fixed arc step (F_ClcCirculo), rad, and its setpoint truncation (0.001).
CPU_ARC_STEP = 0.03
CPU_SETPOINT_STEP = 0.001
#: The Matlab TrazarArco2 step is 2·asin(ARC_STEP_FACTOR·v·T / 2R) (the text says 1).
ARC_STEP_FACTOR = 3.0


def _matlab_round(x: float) -> int:
    """Matlab's round: halves away from zero (Python's round() rounds halves to even)."""
    return steps_of(x, 1.0)


@dataclass(frozen=True)
class ThesisSteps:
    """The Matlab ConsignaLinea output: points after each step."""

    points: list[Point]
    steps: int
    last_step: float  # r = L - n·v·T (negative: the line overshoots and comes back, B2)


def thesis_line_steps(start: Point, end: Point, speed: float = DEFAULT_SPEED,
                      cycle: float = MATLAB_CYCLE) -> ThesisSteps:
    """ConsignaLinea as printed: α = atan(dy/dx), steps (|v·cos α|, |v·sin α|)·T for
    n = round(L/(v·T)) cycles (B2), then r·(cos α, sin α) (B1: wrong for dx < 0, and the
    printed code has no sign: every step goes up and right). L = 0 gives NaN, as in Matlab."""
    dx, dy = end[0] - start[0], end[1] - start[1]
    L = math.hypot(dx, dy)
    if dx == 0.0:
        alpha = math.nan if dy == 0.0 else math.copysign(math.pi / 2, dy)
    else:
        alpha = math.atan(dy / dx)
    vx, vy = abs(speed * math.cos(alpha)), abs(speed * math.sin(alpha))
    n = _matlab_round(L / (speed * cycle))
    x, y = start
    pts: list[Point] = []
    for _ in range(n):
        x, y = x + vx * cycle, y + vy * cycle
        pts.append((x, y))
    r = L - n * speed * cycle
    pts.append((x + r * math.cos(alpha), y + r * math.sin(alpha)))
    return ThesisSteps(pts, n, r)


def thesis_split(start: Point, end: Point, speed: float = DEFAULT_SPEED,
                 accel: float = DEFAULT_ACCEL) -> LineSplit:
    """FB_TrazarLinea: v_i = v·|u_i| (a zero speed replaced by v), the SAME acceleration on
    both axes (B3): the axes arrive v·(|ux| - |uy|)/a apart and, while one still accelerates,
    the carriage leaves the line (cruise offset (v²/2a)·|ux·uy·(uy - ux)|)."""
    L = distance(start, end)
    moves = []
    for i in (0, 1):
        v_i = speed * abs(end[i] - start[i]) / L if L > 0 else 0.0
        moves.append(axis_move(start[i], end[i], v_i or speed, accel))
    return LineSplit(start, end, moves[0], moves[1])


def thesis_arc_step(radius: float, speed: float = DEFAULT_SPEED,
                    cycle: float = MATLAB_CYCLE, cpu: bool = False, sweep: float = 1.0) -> float:
    """The step angle: Matlab 2·asin(3·v·T/(2R)) (B6, always > 0: its loop runs no step
    for a negative sweep, B7); the CPU a fixed 0.03 rad with the sign of `sweep`
    (reference §2.2: F_ClcCirculo steps clockwise arcs clockwise)."""
    if cpu:
        return math.copysign(CPU_ARC_STEP, sweep)
    s = ARC_STEP_FACTOR * speed * cycle / (2.0 * radius)
    if s > 1.0:
        raise GeometryError(f"thesis arc step: asin({s:g}) is undefined (3·v·T = "
                            f"{3 * speed * cycle:g} > 2R = {2 * radius:g}), defect B6")
    return 2.0 * math.asin(s)


@dataclass(frozen=True)
class ThesisArc:
    points: list[Point]  # P_1..P_k, then the closing line's end Pf
    alpha: float  # signed step (the Matlab's is always > 0)
    steps: int  # k
    overshoot: float  # angle by which P_k passes Pf (rad, > 0: beyond the arc end, B7)


#: Seed-mode variants of the arc: the Matlab TrazarArco2 or the CPU's F_ClcCirculo step.
SEED_VARIANTS = ("matlab", "cpu")


def seed_variant(seed: bool | str) -> str | None:
    """None (the corrected path), "matlab" (seed=True) or "cpu"."""
    if seed is False or seed is None:
        return None
    if seed is True:
        return SEED_VARIANTS[0]
    if seed not in SEED_VARIANTS:
        raise ValueError(f"seed variant {seed!r}: one of {', '.join(SEED_VARIANTS)}")
    return seed


def thesis_arc_points(centre: Point, start: Point, sweep: float, speed: float = DEFAULT_SPEED,
                      cycle: float = MATLAB_CYCLE, count: str | None = None,
                      cpu: bool = False) -> ThesisArc:
    """TrazarArco2: P_i = O + R·(cos(β + iα), sin(β + iα)), i = 1..k, then a line to Pf.

    Matlab (cpu=False, count "round" by default) is the thesis: k = round(θ/α) overshoots by
    up to α/2 and cuts back (B7), and a negative sweep runs no step, so a CW arc becomes one
    chord (B7, kept: it is the thesis's own defect). The CPU (cpu=True) steps 0.03 rad with
    the sign of θ, k = floor(|θ|/0.03) by default (reference §2.2), and truncates each point
    to 0.001 (B9). "floor" stops short of Pf instead of passing it. β comes from atan2 here:
    the thesis's own quadrant code (B5) is right only on the +x ray from the centre.
    """
    count = count or ("floor" if cpu else "round")
    if count not in ("round", "floor"):
        raise ValueError(f"count must be 'round' or 'floor', not {count!r}")
    R = distance(centre, start)
    alpha = thesis_arc_step(R, speed, cycle, cpu, sweep)
    # the CPU counts |θ|/|α| (its step carries the sign); the Matlab θ/α is < 0 for CW
    ratio = abs(sweep / alpha) if cpu else sweep / alpha
    k = _matlab_round(ratio) if count == "round" else math.floor(ratio)
    k = max(k, 0)  # Matlab's 1:k is empty for k <= 0
    beta = math.atan2(start[1] - centre[1], start[0] - centre[0])

    def at(a: float) -> Point:
        p = (centre[0] + R * math.cos(a), centre[1] + R * math.sin(a))
        if cpu:
            p = (math.trunc(p[0] / CPU_SETPOINT_STEP) * CPU_SETPOINT_STEP,
                 math.trunc(p[1] / CPU_SETPOINT_STEP) * CPU_SETPOINT_STEP)
        return p

    pts = [at(beta + i * alpha) for i in range(1, k + 1)]
    pts.append(at(beta + sweep))
    return ThesisArc(pts, alpha, k, k * abs(alpha) - abs(sweep) if k else 0.0)


def thesis_beta(vector: Point, cpu: bool = False) -> float:
    """β of TrazarArco2 (Matlab) or F_ClcCirculo (CPU), as printed (B5), in [0, 2π) terms.

    Both take atan(|y/x|) (x = 0 gives π/2) and add a quadrant offset. Matlab: 2nd +π/2
    (should be π - β), 3rd +π, 4th 2π - β (its conditions name `vectOP1`, read here as the
    variable `vctOP1`). CPU: +π/2 in the 2nd and 3rd quadrants and for x >= 0, y > 0 (the
    1st, labelled "4th"); the 4th quadrant gets no offset."""
    x, y = vector
    beta = math.pi / 2 if x == 0 else math.atan(abs(y / x))
    if cpu:
        if (x < 0 and y > 0) or (x < 0 and y <= 0) or (x >= 0 and y > 0):
            beta += math.pi / 2
        return beta
    if x < 0 and y > 0:
        beta += math.pi / 2
    if x < 0 and y <= 0:
        beta += math.pi
    if x >= 0 and y < 0:
        beta = 2 * math.pi - beta
    return beta


#: The CPU circle loop's windows: next point within NEXT_WINDOW, arc end within END_BOX.
NEXT_WINDOW = 0.005
END_BOX = 0.1


@dataclass(frozen=True)
class CpuArcRun:
    points: list[Point]  # where the axes went: the arc points, the box entry, then Pf
    ended: bool  # False: the end box was never met within max_points (it would go on)
    turns: float  # how far the generated points went round, in full turns


def _box_entry(a: Point, b: Point, centre: Point, half: float) -> float | None:
    """Fraction of the way from a to b where the segment enters the square centre ± half
    (Liang-Barsky clipping); None if it misses."""
    t0, t1 = 0.0, 1.0
    for i in (0, 1):
        d = b[i] - a[i]
        lo, hi = centre[i] - half - a[i], centre[i] + half - a[i]
        if d == 0.0:
            if lo > 0.0 or hi < 0.0:
                return None
            continue
        e0, e1 = sorted((lo / d, hi / d))
        t0, t1 = max(t0, e0), min(t1, e1)
        if t0 > t1:
            return None
    return t0


def thesis_cpu_arc(centre: Point, start: Point, sweep: float, quadrant_bug: bool = False,
                   truncate: bool = True, max_points: int = 100_000) -> CpuArcRun:
    """The CPU's circle (FB_TrazarCirculo + F_ClcCirculo): points O + R·(cos(β + k·α),
    sin(β + k·α)), α = ±0.03, k = 1, 2, ..., each sent when the axes reach the previous one;
    the end test "both axes within 0.1 of Pf" runs every cycle (B8), so the arc ends where
    the carriage enters that box, then the next operation goes to Pf. The axes follow the
    chords exactly and the test is taken as continuous (a fast CPU cycle). Counting with its
    own counter (the printed code increments PosX_0, B11). Pf is the true end point."""
    R = distance(centre, start)
    vec = (start[0] - centre[0], start[1] - centre[1])
    true_beta = math.atan2(vec[1], vec[0])
    beta = thesis_beta(vec, cpu=True) if quadrant_bug else true_beta
    pf = (centre[0] + R * math.cos(true_beta + sweep), centre[1] + R * math.sin(true_beta + sweep))
    alpha = math.copysign(CPU_ARC_STEP, sweep)
    pos, pts, k = start, [], 0
    while _box_entry(pos, pos, pf, END_BOX) is None:
        if k >= max_points:
            return CpuArcRun(pts, False, k * CPU_ARC_STEP / TAU)
        k += 1
        a = beta + k * alpha
        p = (centre[0] + R * math.cos(a), centre[1] + R * math.sin(a))
        if truncate:
            p = (math.trunc(p[0] / CPU_SETPOINT_STEP) * CPU_SETPOINT_STEP,
                 math.trunc(p[1] / CPU_SETPOINT_STEP) * CPU_SETPOINT_STEP)
        t = _box_entry(pos, p, pf, END_BOX)
        if t is not None:  # the carriage enters the box on the way: the arc ends there
            p = (pos[0] + t * (p[0] - pos[0]), pos[1] + t * (p[1] - pos[1]))
        pts.append(p)
        pos = p
    pts.append(pf)
    return CpuArcRun(pts, True, k * CPU_ARC_STEP / TAU)


@dataclass(frozen=True)
class ThesisNewton:
    """ClcDifPolNwt + TrazarPolinomio: forward differences with h = x1 - x0 whatever the
    other x are (B12), the highest-degree term dropped (B13), sampled to x_{n-1} (B16)."""

    xs: tuple[float, ...]
    ys: tuple[float, ...]
    samples: int = 60

    def __post_init__(self) -> None:
        NewtonCurve(self.xs, self.ys)  # same node checks as the corrected curve

    @property
    def coefficients(self) -> list[float]:
        return forward_coefficients(self.ys)

    def __call__(self, x: float) -> float:
        c = self.coefficients
        t = (x - self.xs[0]) / (self.xs[1] - self.xs[0])
        total, term = 0.0, 1.0
        for k in range(len(c) - 1):  # k = 0..n-1: the last term is lost (B13)
            total += c[k] * term
            term *= t - k
        return total

    def points(self) -> list[Point]:
        x0, x_end = self.xs[0], self.xs[-2]  # B16
        return [(x, self(x)) for x in (x0 + i * (x_end - x0) / self.samples
                                       for i in range(self.samples + 1))]


@dataclass
class ChainRun:
    """What a trigger-chain piece program did, pass by pass (bounded)."""

    moves: list[tuple[int, Point, Point]] = field(default_factory=list)  # (op, from, to)
    passes: int = 0
    finished: bool = False  # every trigger off: the piece ended
    cycle_moves: int = 0  # moves in the repeating cycle (0: none found)

    @property
    def ops(self) -> list[int]:
        """The operations the axes ran, 1-based, in order."""
        return [op for op, _, _ in self.moves]

    @property
    def runs_forever(self) -> bool:
        """The state came back after moving: the program would cut the cycle forever."""
        return self.cycle_moves > 0


def run_trigger_chain(ends: Sequence[Point], start: Point = (0.0, 0.0), gated: bool = False,
                      max_passes: int = 10_000) -> ChainRun:
    """Run a piece program written as a trigger chain (§3.3): operation i moves to ends[i].

    Every pass, for each i in order: `IF Di THEN start op i`; `IF axes = ends[i] THEN
    Di := FALSE; Di+1 := TRUE`. The thesis (gated=False) tests the end point whatever Di is
    (B19); gated=True nests the test inside `IF Di` (the "Intersecciones" fix). The axes are
    ideal: they stand exactly on the last target issued one pass later (SIMOSIM, so the exact
    equality of B18 holds). Stops when no trigger is set (finished), when a (position,
    triggers) state comes back (a cycle: it would run forever), or after `max_passes`.
    """
    n = len(ends)
    d = [bool(n)] + [False] * (n - 1)
    pos = start
    run = ChainRun()
    seen: dict[tuple[Point, tuple[bool, ...]], int] = {}
    while run.passes < max_passes:
        state = (pos, tuple(d))
        if state in seen:
            run.cycle_moves = len(run.moves) - seen[state]
            return run
        seen[state] = len(run.moves)
        if not any(d):
            run.finished = True
            return run
        run.passes += 1
        target, op = pos, 0
        for i in range(n):
            if d[i]:
                target, op = ends[i], i + 1
            if (d[i] or not gated) and pos == ends[i]:
                d[i] = False
                if i + 1 < n:
                    d[i + 1] = True
        if target != pos:
            run.moves.append((op, pos, target))
        pos = target
    return run
