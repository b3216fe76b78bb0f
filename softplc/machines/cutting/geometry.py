"""Path geometry of the cutting table: lines, arcs, fillets, Newton curves, in mm.

The corrected algorithms of docs/machines/cutting-table.md ("Path library"; the thesis's defects
are reproduced separately in `seed.py`). Every shape is a frozen dataclass that knows its
start, end and length and turns itself into chord end points (`chords`), each chord a line
move of the table. Arcs use the drawing host's chord count (`softplc.machines.gcode.arcs`):
n = ceil(|sweep| / (2·acos(1 - ε/R))), the same rule the spec asks for.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from softplc.errors import SoftPLCError
from softplc.machines.gcode.arcs import TAU, ArcGeometryError, segments_needed

Point = tuple[float, float]

#: Default chord tolerance (largest distance of a chord from the true curve), mm [choice].
DEFAULT_TOLERANCE = 0.01
#: Default number of chords of a Newton curve (the thesis's 60 equal x steps).
NEWTON_SAMPLES = 60
#: Node counts the thesis's Newton code handles (Matlab 6, CPU 5; 2 is a straight line).
NEWTON_NODES = (2, 6)
#: Relative slack when deciding that nodes are equidistant / two points coincide.
REL_EPS = 1e-9
#: Points closer than this are the same point (mm): far below the 1 µm setpoint resolution.
SAME_POINT = 1e-9


class CuttingError(SoftPLCError):
    """Base of the cutting table's errors (geometry, piece files, streaming)."""


class GeometryError(CuttingError, ValueError):
    """A shape cannot be built from the values given."""


class CoincidentPointsError(GeometryError):
    """Two points that must differ are the same (zero-length direction, repeated node)."""


class ZeroRadiusError(GeometryError):
    """An arc or fillet has radius 0 (or a negative one)."""


class FilletError(GeometryError):
    """A fillet does not fit its corner (radius too large for the lines, or a U-turn)."""


class NewtonError(GeometryError):
    """The nodes of a Newton curve are unusable (count, order, repeated x)."""


def _fmt(p: Point) -> str:
    return f"({p[0]:g}, {p[1]:g})"


def distance(a: Point, b: Point) -> float:
    return math.hypot(b[0] - a[0], b[1] - a[1])


def unit(a: Point, b: Point, what: str = "direction") -> Point:
    """Unit vector from a to b; CoincidentPointsError if they are the same point."""
    d = distance(a, b)
    if d <= SAME_POINT:
        raise CoincidentPointsError(f"{what}: the points {_fmt(a)} and {_fmt(b)} coincide")
    return ((b[0] - a[0]) / d, (b[1] - a[1]) / d)


def cross(u: Point, v: Point) -> float:
    return u[0] * v[1] - u[1] * v[0]


def dot(u: Point, v: Point) -> float:
    return u[0] * v[0] + u[1] * v[1]


def point_to_segment(p: Point, a: Point, b: Point) -> float:
    """Distance from p to the segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    L2 = dx * dx + dy * dy
    if L2 == 0.0:
        return distance(p, a)
    s = max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / L2))
    return distance(p, (a[0] + s * dx, a[1] + s * dy))


@dataclass(frozen=True)
class Line:
    """A straight move from start to end; `cut` False is a positioning move (torch off)."""

    start: Point
    end: Point
    cut: bool = True

    @property
    def length(self) -> float:
        return distance(self.start, self.end)

    def chords(self, tolerance: float = DEFAULT_TOLERANCE) -> list[Point]:
        """End points of the moves (one; none for a zero-length line: a no-op)."""
        return [] if self.length <= SAME_POINT else [self.end]

    def sample(self, n: int = 2) -> list[Point]:
        return [self.start, self.end]


@dataclass(frozen=True)
class Arc:
    """A circular arc: centre, start point (the current point) and signed sweep (rad, CCW > 0).

    A sweep of ±2π is a full circle that ends where it started.
    """

    centre: Point
    start: Point
    sweep: float
    #: The exact end when the arc was given by its end point (`through`), else computed.
    given_end: Point | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if self.radius <= SAME_POINT:
            raise ZeroRadiusError(f"arc about {_fmt(self.centre)} starts at its centre "
                                  "(radius 0)")
        if not math.isfinite(self.sweep) or self.sweep == 0.0 or abs(self.sweep) > TAU + 1e-12:
            raise GeometryError(f"arc sweep {math.degrees(self.sweep):g} degrees: expected a "
                                "nonzero angle within ±360")

    @classmethod
    def through(cls, centre: Point, start: Point, end: Point, ccw: bool,
                radius_tolerance: float = 0.001) -> Arc:
        """The arc from start to end about centre in the given direction (end = start: full
        circle). The end must lie on the circle within `radius_tolerance` mm."""
        r0, r1 = distance(centre, start), distance(centre, end)
        if r0 <= SAME_POINT:
            raise ZeroRadiusError(f"arc about {_fmt(centre)} starts at its centre (radius 0)")
        if abs(r1 - r0) > radius_tolerance:
            raise GeometryError(f"arc end {_fmt(end)} is {r1:g} mm from the centre "
                                f"{_fmt(centre)} but the start is {r0:g} mm "
                                f"(allowed difference {radius_tolerance:g} mm)")
        a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
        a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
        if distance(start, end) <= SAME_POINT:
            return cls(centre, start, TAU if ccw else -TAU)
        sweep = (a1 - a0) % TAU  # the CCW sweep; CW goes the other way round
        return cls(centre, start, sweep if ccw else sweep - TAU, end)

    @cached_property
    def radius(self) -> float:
        return distance(self.centre, self.start)

    @cached_property
    def start_angle(self) -> float:
        """β = atan2 of the start vector (the thesis's quadrant code is defect B5)."""
        return math.atan2(self.start[1] - self.centre[1], self.start[0] - self.centre[0])

    @property
    def full_circle(self) -> bool:
        return abs(abs(self.sweep) - TAU) <= 1e-12

    @cached_property
    def end(self) -> Point:
        if self.full_circle:
            return self.start
        if self.given_end is not None:
            return self.given_end
        return self.point_at(self.sweep)

    @property
    def length(self) -> float:
        return self.radius * abs(self.sweep)

    @property
    def ccw(self) -> bool:
        return self.sweep > 0

    def point_at(self, angle: float) -> Point:
        """The point `angle` rad along the arc from its start (signed like the sweep)."""
        a = self.start_angle + angle
        return (self.centre[0] + self.radius * math.cos(a),
                self.centre[1] + self.radius * math.sin(a))

    def tangent_at(self, angle: float) -> Point:
        """Unit direction of travel at `angle` from the start."""
        a = self.start_angle + angle
        s = 1.0 if self.sweep > 0 else -1.0
        return (-s * math.sin(a), s * math.cos(a))

    def chord_count(self, tolerance: float = DEFAULT_TOLERANCE,
                    max_chord: float | None = None) -> int:
        """n = ceil(|θ| / α_max), α_max from the sagitta tolerance (and a chord limit)."""
        try:
            n = segments_needed(self.radius, self.sweep, tolerance)
        except ArcGeometryError as e:
            raise GeometryError(str(e)) from None
        if max_chord is not None:
            if max_chord <= 0:
                raise GeometryError(f"chord limit {max_chord:g} mm must be positive")
            if max_chord < 2 * self.radius:
                step = 2.0 * math.asin(max_chord / (2.0 * self.radius))
                n = max(n, math.ceil(abs(self.sweep) / step - 1e-12))
        return n

    def chords(self, tolerance: float = DEFAULT_TOLERANCE,
               max_chord: float | None = None) -> list[Point]:
        """P_1..P_n, α = θ/n; P_n is exactly the arc's end (count-based end, not a box)."""
        n = self.chord_count(tolerance, max_chord)
        alpha = self.sweep / n
        return [self.point_at(i * alpha) for i in range(1, n)] + [self.end]

    def sagitta(self, n: int) -> float:
        """Largest distance between the arc and its chords when cut in n equal chords."""
        return self.radius * (1.0 - math.cos(self.sweep / n / 2.0))

    def polyline_length(self, n: int) -> float:
        return n * 2.0 * self.radius * math.sin(abs(self.sweep) / n / 2.0)

    def sample(self, n: int = 200) -> list[Point]:
        return [self.point_at(self.sweep * i / n) for i in range(n + 1)]


@dataclass(frozen=True)
class Fillet:
    """A tangent arc of radius ρ rounding the corner between two lines (§2.3)."""

    t1: Point  # tangent point on the incoming line
    t2: Point  # tangent point on the outgoing line
    arc: Arc
    setback: float  # tangent distance t = ρ·tan(|φ|/2) from the corner


def fillet(a: Point, corner: Point, b: Point, radius: float) -> Fillet | None:
    """Round the corner a -> corner -> b with radius ρ; None if the lines are collinear.

    FilletError if the setback exceeds either line or the path turns back on itself.
    """
    if not radius > 0 or not math.isfinite(radius):
        raise ZeroRadiusError(f"fillet radius {radius:g} at corner {_fmt(corner)}: expected "
                              "a positive radius")
    u1 = unit(a, corner, f"line into the corner {_fmt(corner)}")
    u2 = unit(corner, b, f"line out of the corner {_fmt(corner)}")
    phi = math.atan2(cross(u1, u2), dot(u1, u2))
    if abs(phi) <= 1e-12:
        return None
    if abs(phi) >= math.pi - 1e-9:
        raise FilletError(f"corner {_fmt(corner)}: the path turns back on itself (180 "
                          "degrees), no fillet fits")
    t = radius * math.tan(abs(phi) / 2.0)
    for name, p in (("incoming", a), ("outgoing", b)):
        if t > distance(p, corner) * (1 + REL_EPS):
            raise FilletError(f"fillet radius {radius:g} at corner {_fmt(corner)} needs "
                              f"{t:.6g} mm of the {name} line, which is only "
                              f"{distance(p, corner):.6g} mm long")
    t1 = (corner[0] - t * u1[0], corner[1] - t * u1[1])
    t2 = (corner[0] + t * u2[0], corner[1] + t * u2[1])
    n1 = (-u1[1], u1[0]) if phi > 0 else (u1[1], -u1[0])
    centre = (t1[0] + radius * n1[0], t1[1] + radius * n1[1])
    return Fillet(t1, t2, Arc(centre, t1, phi), t)


def is_tangent_join(incoming: Point, outgoing: Point, tol: float = 1e-9) -> bool:
    """True when two unit directions are the same (a smooth join)."""
    return abs(cross(incoming, outgoing)) <= tol and dot(incoming, outgoing) > 0


def equidistant(xs: Sequence[float]) -> bool:
    """|x_j - x0 - j·h| <= 1e-9·|h| for h = (x_n - x0)/n (§2.4)."""
    n = len(xs) - 1
    h = (xs[-1] - xs[0]) / n
    return all(abs(xs[j] - xs[0] - j * h) <= REL_EPS * abs(h) for j in range(n + 1))


def divided_differences(xs: Sequence[float], ys: Sequence[float]) -> list[float]:
    """Newton coefficients f[x0], f[x0,x1], ..., f[x0..xn] (in place, as FIGURA 18)."""
    c = list(map(float, ys))
    n = len(xs) - 1
    for k in range(1, n + 1):
        for j in range(n, k - 1, -1):
            c[j] = (c[j] - c[j - 1]) / (xs[j] - xs[j - k])
    return c


def forward_coefficients(ys: Sequence[float]) -> list[float]:
    """c_k = Δ^k y0 / k! of the equidistant form p = Σ c_k·t(t-1)…(t-k+1) (FIGURA 19)."""
    d = list(map(float, ys))
    n = len(d) - 1
    for i in range(1, n + 1):
        for j in range(n, i - 1, -1):
            d[j] -= d[j - 1]
    return [d[k] / math.factorial(k) for k in range(n + 1)]


def check_nodes(xs: Sequence[float], ys: Sequence[float]) -> None:
    lo, hi = NEWTON_NODES
    if len(xs) != len(ys):
        raise NewtonError(f"Newton curve: {len(xs)} x values but {len(ys)} y values")
    if not lo <= len(xs) <= hi:
        raise NewtonError(f"Newton curve: {len(xs)} nodes; expected {lo} to {hi}")
    if not all(math.isfinite(v) for v in (*xs, *ys)):
        raise NewtonError("Newton curve: every node must be a finite number")
    steps = [b - a for a, b in zip(xs, xs[1:], strict=False)]
    for j, s in enumerate(steps):
        if abs(s) <= SAME_POINT:
            raise NewtonError(f"Newton curve: nodes {j} and {j + 1} have the same x "
                              f"({xs[j]:g}); y = p(x) needs distinct x")
    if not (all(s > 0 for s in steps) or all(s < 0 for s in steps)):
        raise NewtonError(f"Newton curve: x = {list(xs)} must be increasing or decreasing "
                          "(the curve is the graph y = p(x))")


@dataclass(frozen=True)
class NewtonCurve:
    """The interpolation polynomial through 2..6 nodes, drawn as y = p(x) from x0 to x_n.

    All n+1 terms are evaluated (the thesis drops the last one, B13); nodes need not be
    equidistant (divided differences; the thesis assumes h = x1 - x0, B12).
    """

    xs: tuple[float, ...]
    ys: tuple[float, ...]

    def __post_init__(self) -> None:
        check_nodes(self.xs, self.ys)

    @cached_property
    def coefficients(self) -> list[float]:
        """Divided differences f[x0..xk]."""
        return divided_differences(self.xs, self.ys)

    @property
    def equidistant(self) -> bool:
        return equidistant(self.xs)

    def __call__(self, x: float) -> float:
        """p(x) by Horner's rule on the Newton form."""
        c, xs = self.coefficients, self.xs
        q = c[-1]
        for k in range(len(c) - 2, -1, -1):
            q = q * (x - xs[k]) + c[k]
        return q

    @property
    def start(self) -> Point:
        return (self.xs[0], self.ys[0])

    @property
    def end(self) -> Point:
        return (self.xs[-1], self.ys[-1])

    def sample_x(self, samples: int) -> list[float]:
        x0, xn = self.xs[0], self.xs[-1]
        return [x0 + i * (xn - x0) / samples for i in range(samples + 1)]

    def points(self, samples: int = NEWTON_SAMPLES) -> list[Point]:
        """x_i = x0 + i·(x_n - x0)/N, i = 0..N; the last point is exactly the last node."""
        if samples < 1:
            raise NewtonError(f"Newton curve: {samples} samples; expected at least 1")
        pts = [(x, self(x)) for x in self.sample_x(samples)]
        pts[0], pts[-1] = self.start, self.end
        return pts

    def chords(self, tolerance: float | None = None, samples: int = NEWTON_SAMPLES
               ) -> list[Point]:
        """Chord end points: N = `samples`, or the least N whose chords stay within
        `tolerance` of the curve (doubling, then bisection)."""
        if tolerance is not None:
            samples = self.samples_for(tolerance)
        return self.points(samples)[1:]

    def chord_deviation(self, samples: int) -> tuple[float, float]:
        """(largest distance of the curve from its N-chord polyline, x where it occurs)."""
        pts = self.points(samples)
        worst, at = 0.0, self.xs[0]
        for a, b in zip(pts, pts[1:], strict=False):
            d, x = _max_on_chord(self, a, b)
            if d > worst:
                worst, at = d, x
        return worst, at

    def samples_for(self, tolerance: float, limit: int = 1 << 16) -> int:
        if not tolerance > 0:
            raise GeometryError(f"chord tolerance {tolerance:g} mm must be positive")
        hi = 1
        while self.chord_deviation(hi)[0] > tolerance:
            hi *= 2
            if hi > limit:
                raise NewtonError(f"Newton curve: more than {limit} chords needed for a "
                                  f"tolerance of {tolerance:g} mm")
        lo = hi // 2
        while hi - lo > 1:  # lo fails (or is 0), hi passes
            mid = (lo + hi) // 2
            if self.chord_deviation(mid)[0] > tolerance:
                lo = mid
            else:
                hi = mid
        return hi

    def arc_length(self, n: int = 20000) -> float:
        """Length of the curve (a fine polyline: converges as 1/n²)."""
        pts = self.points(n)
        return sum(distance(a, b) for a, b in zip(pts, pts[1:], strict=False))

    def sample(self, n: int = 400) -> list[Point]:
        return self.points(n)

    @cached_property
    def dense(self) -> tuple[np.ndarray, np.ndarray]:
        """256 equal x steps of the curve (x, y arrays), for nearest-point searches."""
        xs = np.array(self.sample_x(256))
        return xs, np.array([self(x) for x in xs])


def _max_on_chord(curve: NewtonCurve, a: Point, b: Point) -> tuple[float, float]:
    """Largest distance from the curve between a and b to the chord a-b (golden search
    after a coarse scan: the deviation is unimodal on one short chord)."""
    def f(x: float) -> float:
        return point_to_segment((x, curve(x)), a, b)

    xs = [a[0] + (b[0] - a[0]) * i / 16 for i in range(17)]
    i = max(range(17), key=lambda k: f(xs[k]))
    lo, hi = xs[max(i - 1, 0)], xs[min(i + 1, 16)]
    x = _golden_min(lambda x: -f(x), min(lo, hi), max(lo, hi), 60)
    return f(x), x


def _pick(left: bool, a: float, b: float) -> float:
    """np.where on one pair of floats, without numpy's cost per call (the same values)."""
    return a if left else b


def _golden_min(f, lo, hi, iterations: int = 80):
    """x in [lo, hi] minimising a unimodal f; lo and hi may be arrays (one search per
    element, f evaluated on arrays)."""
    g = (math.sqrt(5) - 1) / 2
    pick = _pick if np.ndim(lo) == 0 and np.ndim(hi) == 0 else np.where
    for _ in range(iterations):
        m1, m2 = hi - g * (hi - lo), lo + g * (hi - lo)
        left = f(m1) < f(m2)
        hi, lo = pick(left, m2, hi), pick(left, lo, m1)
    x = (lo + hi) / 2
    return float(x) if np.ndim(x) == 0 else x


def distance_to(shape: Line | Arc | NewtonCurve, p: Point) -> float:
    """Distance from p to the ideal shape (not its chords)."""
    return float(distances_to(shape, np.array([p[0]], float), np.array([p[1]], float))[0])


#: points per block in `distances_to` (bounds the nearest-point matrix of a Newton curve)
_BLOCK = 4096


def distances_to(shape: Line | Arc | NewtonCurve, px: np.ndarray,
                 py: np.ndarray) -> np.ndarray:
    """Distances from the points (px, py) to the ideal shape (not its chords), all at
    once: a trace check measures tens of thousands of samples."""
    if isinstance(shape, Line):
        (ax, ay), (bx, by) = shape.start, shape.end
        dx, dy = bx - ax, by - ay
        L2 = dx * dx + dy * dy
        s = (np.clip(((px - ax) * dx + (py - ay) * dy) / L2, 0.0, 1.0) if L2 > 0.0
             else np.zeros_like(px))
        return np.hypot(px - ax - s * dx, py - ay - s * dy)
    if isinstance(shape, Arc):
        (ox, oy), (sx, sy), (ex, ey) = shape.centre, shape.start, shape.end
        d = np.hypot(px - ox, py - oy)
        phi = np.arctan2(py - oy, px - ox) - shape.start_angle
        along = np.mod(phi, TAU) if shape.sweep > 0 else -np.mod(-phi, TAU)
        inside = shape.full_circle | (np.abs(along) <= abs(shape.sweep))
        ends = np.minimum(np.hypot(px - sx, py - sy), np.hypot(px - ex, py - ey))
        return np.where(inside, np.abs(d - shape.radius), ends)
    if len(px) > _BLOCK:
        return np.concatenate([distances_to(shape, px[i:i + _BLOCK], py[i:i + _BLOCK])
                               for i in range(0, len(px), _BLOCK)])
    # y = p(x): the nearest dense sample brackets the nearest point; golden-section search
    # on the distance (unimodal inside one bracket), every point at once
    xs, ys = shape.dense
    i = np.argmin(np.hypot(xs[None, :] - px[:, None], ys[None, :] - py[:, None]), axis=1)
    a, b = xs[np.maximum(i - 1, 0)], xs[np.minimum(i + 1, len(xs) - 1)]

    def f(x: np.ndarray) -> np.ndarray:
        return np.hypot(px - x, py - shape(x))

    return f(_golden_min(f, np.minimum(a, b), np.maximum(a, b), 50))


def green_term(shape: Line | Arc) -> float:
    """∮(x dy - y dx) along a line or arc: half the sum over a closed path is its area."""
    if isinstance(shape, Line):
        (x0, y0), (x1, y1) = shape.start, shape.end
        return x0 * y1 - x1 * y0
    (ox, oy), R = shape.centre, shape.radius
    a0 = shape.start_angle
    a1 = a0 + shape.sweep
    return (R * ox * (math.sin(a1) - math.sin(a0)) - R * oy * (math.cos(a1) - math.cos(a0))
            + R * R * shape.sweep)


def polyline_length(points: Sequence[Point]) -> float:
    return sum(distance(a, b) for a, b in zip(points, points[1:], strict=False))


def polygon_area(points: Sequence[Point]) -> float:
    """Signed shoelace area of a closed polyline (CCW > 0)."""
    s = 0.0
    for (x0, y0), (x1, y1) in zip(points, [*points[1:], points[0]], strict=True):
        s += x0 * y1 - x1 * y0
    return s / 2.0
