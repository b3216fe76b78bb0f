"""Circular arcs in the drawing plane: centre from R or from centre offsets, linearisation.

Coordinates are (u, v): the first and second axis of the drawing plane (X, Z on the seed
table). Clockwise (G02) is clockwise as the drawing is seen with u to the right and v up,
whatever the plane. The centre from R uses only vector algebra (no slope, no atan of a
slope), so vertical chords work; this fixes the seed's VB arc code (defect 6).
"""

from __future__ import annotations

import math

from softplc.errors import SoftPLCError

Point = tuple[float, float]

TAU = 2.0 * math.pi
#: Chords one arc may become. An arc of the largest table (a 240 mm radius) cut at a 1 nm
#: tolerance needs about 34,000; more means a tolerance below any machine's resolution
#: (the cutting table's setpoints are in µm, %MD100) and memory without bound (a 1e-12 mm
#: tolerance asked 2.7 GB).
MAX_ARC_SEGMENTS = 65_536


class ArcGeometryError(SoftPLCError, ValueError):
    """An arc cannot be built from its words (the parser turns it into a diagnostic)."""


def centre_from_radius(start: Point, end: Point, r: float, clockwise: bool) -> Point:
    """Centre of the arc from `start` to `end` with signed radius `r`.

    r > 0 selects the short arc (sweep <= 180 degrees), r < 0 the long one (> 180).
    """
    (x0, y0), (x1, y1) = start, end
    dx, dy = x1 - x0, y1 - y0
    d = math.hypot(dx, dy)
    if d == 0.0:
        raise ArcGeometryError("arc with R needs distinct start and end points "
                               "(use I/J/K centre offsets for a full circle)")
    if r == 0.0:
        raise ArcGeometryError("arc radius R must not be 0")
    half = d / 2.0
    rad = abs(r)
    if rad < half:
        # Accept tiny rounding in programs that mean a half circle.
        if half - rad > 1e-6 * max(1.0, half):
            raise ArcGeometryError(f"radius {rad:g} is smaller than half the chord "
                                   f"({half:g}): no arc joins these points")
        rad = half
    h = math.sqrt(max(rad * rad - half * half, 0.0))
    # Unit normal to the left of the chord direction.
    nx, ny = -dy / d, dx / d
    # A counter-clockwise short arc has its centre on the left of the chord.
    left = (not clockwise) == (r > 0)
    s = h if left else -h
    return (x0 + dx / 2.0 + s * nx, y0 + dy / 2.0 + s * ny)


def sweep_angle(start: Point, end: Point, centre: Point, clockwise: bool,
                full_if_closed: bool) -> float:
    """Signed sweep in radians (negative clockwise) from start to end around centre."""
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    if full_if_closed and math.isclose(start[0], end[0], abs_tol=1e-9) \
            and math.isclose(start[1], end[1], abs_tol=1e-9):
        return -TAU if clockwise else TAU
    if clockwise:
        sweep = -((a0 - a1) % TAU)
    else:
        sweep = (a1 - a0) % TAU
    return sweep


def segments_needed(radius: float, sweep: float, tolerance: float) -> int:
    """Number of chords so that no chord strays more than `tolerance` from the arc;
    ArcGeometryError if a value is not finite or more than MAX_ARC_SEGMENTS are needed."""
    if not (math.isfinite(radius) and math.isfinite(sweep) and math.isfinite(tolerance)
            and tolerance > 0.0):
        raise ArcGeometryError(f"arc of radius {radius:g}, sweep {sweep:g} rad, chord "
                               f"tolerance {tolerance:g}: finite numbers (a tolerance > 0) "
                               "expected")
    if radius <= 0.0:
        return 1
    if tolerance >= radius:
        max_step = math.pi
    else:
        max_step = 2.0 * math.acos(1.0 - tolerance / radius)
    if max_step <= 0.0 or abs(sweep) / max_step > MAX_ARC_SEGMENTS:
        raise ArcGeometryError(f"an arc of radius {radius:g} would be more than "
                               f"{MAX_ARC_SEGMENTS} chords at a chord tolerance of "
                               f"{tolerance:g}: use a larger tolerance")
    n = max(1, math.ceil(abs(sweep) / max_step - 1e-12))
    if abs(sweep) >= TAU - 1e-12:
        n = max(n, 3)  # a full circle needs at least a triangle
    return n


def linearise_arc(start: Point, end: Point, centre: Point, sweep: float,
                  tolerance: float) -> list[Point]:
    """Points of the chords approximating the arc, from start (excluded) to end (included).

    The radius is interpolated from the start radius to the end radius, so the last point is
    exactly `end` even when the program's centre is slightly off (I/J/K rounding).
    """
    cx, cy = centre
    r0 = math.hypot(start[0] - cx, start[1] - cy)
    r1 = math.hypot(end[0] - cx, end[1] - cy)
    a0 = math.atan2(start[1] - cy, start[0] - cx)
    n = segments_needed(max(r0, r1), sweep, tolerance)
    pts: list[Point] = []
    for k in range(1, n):
        f = k / n
        a = a0 + sweep * f
        r = r0 + (r1 - r0) * f
        pts.append((cx + r * math.cos(a), cy + r * math.sin(a)))
    pts.append((float(end[0]), float(end[1])))
    return pts
