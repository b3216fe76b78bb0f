"""Arc linearisation properties (hypothesis): chords within tolerance, endpoints on the arc."""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from softplc.machines.gcode import GCodeConfig, parse_gcode
from softplc.machines.gcode.arcs import centre_from_radius, linearise_arc, sweep_angle

coord = st.floats(min_value=0.0, max_value=25.0, allow_nan=False)
tolerance = st.sampled_from([0.001, 0.01, 0.05, 0.2])


def check_chords(start, pts, centre, radius, tol):
    """Every point on the circle; every chord's bulge (sagitta) within tol."""
    prev = start
    for p in pts:
        assert math.dist(p, centre) == pytest.approx(radius, rel=1e-9, abs=1e-9)
        mid = ((prev[0] + p[0]) / 2, (prev[1] + p[1]) / 2)
        assert radius - math.dist(mid, centre) <= tol + 1e-9
        prev = p


@settings(max_examples=200, deadline=None)
@given(x0=coord, z0=coord, x1=coord, z1=coord, extra=st.floats(0.0, 20.0),
       long=st.booleans(), cw=st.booleans(), tol=tolerance)
def test_radius_arcs_stay_within_chord_tolerance(x0, z0, x1, z1, extra, long, cw, tol):
    d = math.dist((x0, z0), (x1, z1))
    assume(d > 1e-3)
    r = (d / 2 + extra) * (-1 if long else 1)
    centre = centre_from_radius((x0, z0), (x1, z1), r, cw)
    # Both ends are at distance |r| from the centre.
    assert math.dist(centre, (x0, z0)) == pytest.approx(abs(r), rel=1e-9, abs=1e-9)
    assert math.dist(centre, (x1, z1)) == pytest.approx(abs(r), rel=1e-9, abs=1e-9)
    sweep = sweep_angle((x0, z0), (x1, z1), centre, cw, full_if_closed=False)
    assert (sweep < 0) == cw
    if extra > 1e-6:  # exact half circles are both short and long
        assert (abs(sweep) > math.pi) == long
    pts = linearise_arc((x0, z0), (x1, z1), centre, sweep, tol)
    assert pts[-1] == (x1, z1)
    check_chords((x0, z0), pts, centre, abs(r), tol)


@settings(max_examples=150, deadline=None)
@given(cx=st.floats(5.0, 20.0), cz=st.floats(5.0, 20.0), r=st.floats(0.05, 5.0),
       a0=st.floats(-math.pi, math.pi), a1=st.floats(-math.pi, math.pi),
       cw=st.booleans(), tol=tolerance)
# tangent to the table's edge X = 0: a chord point lands 4.7e-7 cm past it after the
# centre's 6-decimal rounding (refused before the edge tolerance)
@example(cx=5.0, cz=5.0, r=5.0, a0=0.0, a1=2.26679884513333, cw=True, tol=0.001)
def test_offset_arcs_through_the_parser(cx, cz, r, a0, a1, cw, tol):
    x0, z0 = cx + r * math.cos(a0), cz + r * math.sin(a0)
    x1, z1 = cx + r * math.cos(a1), cz + r * math.sin(a1)
    text = (f"G01 X{x0:.6f} Z{z0:.6f}\n"
            f"G0{2 if cw else 3} X{x1:.6f} Z{z1:.6f} I{cx - x0:.6f} K{cz - z0:.6f}")
    prog = parse_gcode(text, GCodeConfig(chord_tolerance=tol))
    arc = [s for s in prog.segments if s.kind == "arc"]
    assert arc and arc[-1].end == pytest.approx((x1, z1), abs=1e-6)
    start = arc[0].start
    centre = (start[0] + round(cx - x0, 6), start[1] + round(cz - z0, 6))
    rad = math.dist(start, centre)
    for s in arc:  # each segment's ends lie on the arc (rounding to 6 decimals aside)
        assert math.dist(s.end, centre) == pytest.approx(rad, abs=1e-5)
        mid = ((s.start[0] + s.end[0]) / 2, (s.start[1] + s.end[1]) / 2)
        assert rad - math.dist(mid, centre) <= tol + 1e-5
    # Chords are contiguous.
    for a, b in zip(arc, arc[1:], strict=False):
        assert a.end == b.start


@settings(max_examples=50, deadline=None)
@given(cx=st.floats(6.0, 19.0), cz=st.floats(6.0, 19.0), r=st.floats(0.1, 5.0),
       a0=st.floats(-math.pi, math.pi), cw=st.booleans(), tol=tolerance)
def test_full_circles_turn_once(cx, cz, r, a0, cw, tol):
    x0, z0 = cx + r * math.cos(a0), cz + r * math.sin(a0)
    centre = (cx, cz)
    sweep = sweep_angle((x0, z0), (x0, z0), centre, cw, full_if_closed=True)
    assert sweep == pytest.approx(-2 * math.pi if cw else 2 * math.pi)
    pts = linearise_arc((x0, z0), (x0, z0), centre, sweep, tol)
    assert len(pts) >= 3 and pts[-1] == (x0, z0)
    check_chords((x0, z0), pts, centre, math.dist((x0, z0), centre), tol)
