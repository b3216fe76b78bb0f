"""Properties of the path library on random shapes (hypothesis)."""

from __future__ import annotations

import math

from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from softplc.machines.cutting import Arc, NewtonCurve, fillet, split_line
from softplc.machines.cutting.geometry import cross, distance, forward_coefficients, unit

coord = st.floats(-200, 200, allow_nan=False)
point = st.tuples(coord, coord)
FEW = settings(max_examples=60, deadline=None)


@FEW
@given(centre=point, r=st.floats(0.5, 100), a0=st.floats(-math.pi, math.pi),
       sweep=st.floats(0.01, 2 * math.pi).flatmap(lambda s: st.sampled_from([s, -s])),
       tol=st.floats(0.001, 1.0))
def test_arc_chords_stay_within_tolerance_and_end_exactly(centre, r, a0, sweep, tol):
    start = (centre[0] + r * math.cos(a0), centre[1] + r * math.sin(a0))
    arc = Arc(centre, start, sweep)
    pts = [start, *arc.chords(tol)]
    assert pts[-1] == arc.end
    n = len(pts) - 1
    assert n == arc.chord_count(tol)
    assert arc.sagitta(n) <= tol + 1e-12
    for a, b in zip(pts, pts[1:], strict=False):
        assert abs(distance(b, centre) - r) <= 1e-9 * max(1.0, r + abs(centre[0]) + abs(
            centre[1]))
        mid = ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2)
        assert r - distance(mid, centre) <= tol + 1e-9
        if abs(sweep) / n < math.pi - 1e-6:  # every chord turns the way the sweep does
            turn = cross((a[0] - centre[0], a[1] - centre[1]),
                         (b[0] - centre[0], b[1] - centre[1]))
            assert math.copysign(1, turn) == math.copysign(1, sweep)


@FEW
@given(corner=point, a_in=st.floats(-math.pi, math.pi), turn=st.floats(0.05, math.pi - 0.05),
       left=st.booleans(), rho=st.floats(0.1, 20))
def test_fillet_is_tangent_to_both_lines(corner, a_in, turn, left, rho):
    u1 = (math.cos(a_in), math.sin(a_in))
    a_out = a_in + (turn if left else -turn)
    u2 = (math.cos(a_out), math.sin(a_out))
    t = rho * math.tan(turn / 2)
    a = (corner[0] - (t + 5) * u1[0], corner[1] - (t + 5) * u1[1])
    b = (corner[0] + (t + 5) * u2[0], corner[1] + (t + 5) * u2[1])
    f = fillet(a, corner, b, rho)
    assert f is not None
    arc = f.arc
    assert abs(arc.radius - rho) < 1e-9 * max(1, rho)
    assert distance(arc.end, f.t2) < 1e-9 * (1 + abs(corner[0]) + abs(corner[1]))
    assert distance(arc.tangent_at(0), unit(a, corner)) < 1e-9
    assert distance(arc.tangent_at(arc.sweep), unit(corner, b)) < 1e-9
    assert (arc.sweep > 0) == left


@FEW
@given(x0=st.floats(-100, 100), gaps=st.lists(st.floats(0.5, 30), min_size=1, max_size=5),
       data=st.data())
def test_newton_curve_passes_through_every_node(x0, gaps, data):
    xs = [x0]
    for g in gaps:
        xs.append(xs[-1] + g)
    ys = data.draw(st.lists(st.floats(-50, 50), min_size=len(xs), max_size=len(xs)))
    c = NewtonCurve(tuple(xs), tuple(ys))
    scale = 1 + max(abs(y) for y in ys)
    for x, y in zip(xs, ys, strict=True):
        assert abs(c(x) - y) <= 1e-7 * scale
    pts = c.points(60)
    assert pts[0] == (xs[0], ys[0]) and pts[-1] == (xs[-1], ys[-1])


@FEW
@given(x0=st.floats(-100, 100), h=st.floats(0.5, 30), ys=st.lists(st.floats(-50, 50),
                                                                  min_size=2, max_size=6))
def test_equidistant_forward_form_is_the_same_polynomial(x0, h, ys):
    xs = tuple(x0 + j * h for j in range(len(ys)))
    c = NewtonCurve(xs, tuple(ys))
    coef = forward_coefficients(ys)
    for x in (x0 + 0.37 * h, x0 + (len(ys) - 1.2) * h):
        t = (x - x0) / h
        q, term = 0.0, 1.0
        for k, ck in enumerate(coef):
            q += ck * term
            term *= t - k
        assert abs(q - c(x)) <= 1e-7 * (1 + max(abs(y) for y in ys)) * 2 ** len(ys)


@FEW
@given(a=point, b=point, v=st.floats(0.5, 200), acc=st.floats(10, 5000))
# An axis with a vanishing share of the line: v_i*v_i underflowed to 0 and its profile
# was taken as a trapezoid (arrival 17 ms late) before Trapezoid compared ratios.
@example(a=(0.0, 0.0), b=(1.0, 2.6707883194420036e-258), v=4.0, acc=10.0)
# A subnormal share (found by CI): its profile's ratios lost precision, arrival 1e-7 s early.
@example(a=(0.0, 0.0), b=(105.88309459413672, 2.2250738585e-313), v=1.0, acc=10.0)
def test_split_line_axes_arrive_together_on_the_line(a, b, v, acc):
    assume(distance(a, b) > 1e-3)
    s = split_line(a, b, v, acc)
    assert s.arrival_gap <= 1e-9 * max(1.0, s.duration)
    assert s.cross_track(samples_per_phase=20)[0] <= 1e-9 * (1 + distance(a, b))
    assert distance(s.position(s.duration), b) < 1e-9 * (1 + abs(b[0]) + abs(b[1]))
