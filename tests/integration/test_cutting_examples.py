"""Worked examples E1-E7 and E10 of cutting-table.md §4: the host generator's values.

Closed-form values are checked to 1e-9 mm; the figures the reference prints (5-6 digits)
to their printed precision. E8 (homing) and E9 (limit stop) need the servo axis device and
the PLC program: they come with the device round.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from softplc.machines.cutting import Arc, NewtonCurve, load_piece, matlab_steps, split_line
from softplc.machines.cutting.geometry import distance, forward_coefficients, is_tangent_join
from softplc.machines.cutting.seed import ThesisNewton, run_trigger_chain, thesis_arc_points

PIECES = Path(__file__).resolve().parents[2] / "ladder_programs" / "pieces"
EXACT = 1e-9


def printed(value: float, digits: int) -> pytest.approx:
    """A value printed with `digits` decimals in the reference."""
    return pytest.approx(value, abs=0.5 * 10 ** -digits + 1e-12)


def cut_lengths(piece) -> list[float]:
    return [s.length for s in piece.segments() if s.cut]


# -- E1 Cuadrado ---------------------------------------------------------------------------

def test_e1_square():
    p = load_piece(PIECES / "cuadrado.toml")
    segs = p.segments()
    assert [s.kind for s in segs] == ["cut"] * 4
    assert [s.end for s in segs] == [(15, 0), (15, 15), (0, 15), (0, 0)]
    assert p.length() == pytest.approx(60.0, abs=EXACT)
    assert p.area() == pytest.approx(225.0, abs=EXACT)
    assert p.end == (0.0, 0.0)


# -- E2 Escudo -----------------------------------------------------------------------------

SHIELD = [(5, 5), (7, 8), (7, 12), (6, 13), (4, 13), (3, 12), (3, 8), (5, 5)]


def test_e2_shield_geometry():
    p = load_piece(PIECES / "escudo.toml")
    s13, s2 = math.sqrt(13), math.sqrt(2)
    assert cut_lengths(p) == pytest.approx([s13, 4, s2, 2, s2, 4, s13], abs=EXACT)
    assert p.length() == printed(20.03953, 5)
    assert p.length() == pytest.approx(2 * s13 + 10 + 2 * s2, abs=EXACT)
    assert p.length("move") == printed(7.07107, 5)
    assert p.area() == pytest.approx(25.0, abs=EXACT)
    ends = [s.end for s in p.segments()]
    assert {(10 - x, y) for x, y in ends} == set(ends)  # symmetric about x = 5


def test_e2_matlab_steps_per_line():
    full, last = [], []
    for a, b in zip(SHIELD, SHIELD[1:], strict=False):
        st = matlab_steps(a, b, 2.0, 0.025)
        full.append(st.full_steps)
        last.append(st.last_step)
        assert st.points[-1] == b
        steps = [distance(p, q) for p, q in zip([a, *st.points], st.points, strict=False)]
        assert max(steps) <= 0.05 + EXACT  # never more than v·T, never backwards
    assert full == [72, 80, 28, 40, 28, 80, 72]
    assert last == [printed(v, 5) for v in (0.00555, 0, 0.01421, 0, 0.01421, 0, 0.00555)]
    pos = matlab_steps((0, 0), (5, 5), 2.0, 0.025)
    assert (pos.full_steps, pos.last_step) == (141, printed(0.02107, 5))


def test_e2_shield_runs_once_with_gated_triggers():
    run = run_trigger_chain(SHIELD, start=(0, 0), gated=True)
    assert run.finished and not run.runs_forever
    assert run.ops == [1, 2, 3, 4, 5, 6, 7, 8]


# -- E3 rounded rectangle ------------------------------------------------------------------

def test_e3_rounded_rectangle_ideal_shape():
    p = load_piece(PIECES / "achaflanado.toml")
    shapes = [e.shape for e in p.elements if e.cut]
    assert sum(s.length for s in shapes) == pytest.approx(80 + 20 * math.pi, abs=EXACT)
    assert sum(s.length for s in shapes) == printed(142.83185, 5)
    assert p.area() == printed(1514.15927, 5)
    assert p.end == (20.0, 10.0)
    # every joint tangent: the outgoing direction of one shape is the incoming of the next
    for a, b in zip(shapes, shapes[1:] + shapes[:1], strict=True):
        out_dir = a.tangent_at(a.sweep) if isinstance(a, Arc) else _dir(a)
        in_dir = b.tangent_at(0.0) if isinstance(b, Arc) else _dir(b)
        assert is_tangent_join(out_dir, in_dir)


def _dir(line):
    d = distance(line.start, line.end)
    return ((line.end[0] - line.start[0]) / d, (line.end[1] - line.start[1]) / d)


def test_e3_chords_within_tolerance():
    arc = Arc((40, 20), (40, 10), math.pi / 2)
    n = arc.chord_count(0.01)
    assert n == 18
    assert arc.sweep / n == pytest.approx(math.radians(5), abs=1e-15)
    assert arc.sagitta(n) == printed(0.009518, 6)
    assert arc.sagitta(n) <= 0.01
    assert arc.chords(0.01)[-1] == (50.0, 20.0)
    p = load_piece(PIECES / "achaflanado.toml")
    assert p.length() == printed(142.81192, 5)
    assert p.length() == pytest.approx(80 + 4 * 18 * 20 * math.sin(math.pi / 72), abs=EXACT)
    assert sum(1 for s in p.segments() if s.cut) == 4 + 4 * 18


def test_e3_same_piece_from_contour_fillets_and_from_gcode():
    from softplc.machines.cutting import piece_from_dict

    contour = piece_from_dict({"op": [{"kind": "contour", "radius": 10, "closed": True,
                                       "points": [[10, 10], [50, 10], [50, 50], [10, 50]]}]})
    arcs = [e.shape for e in contour.elements if isinstance(e.shape, Arc)]
    assert [a.centre for a in arcs] == [
        pytest.approx(c, abs=EXACT) for c in [(40, 20), (40, 40), (20, 40), (20, 20)]]
    assert [a.start for a in arcs] == [
        pytest.approx(c, abs=EXACT) for c in [(40, 10), (50, 40), (20, 50), (10, 20)]]
    ref = load_piece(PIECES / "achaflanado.toml")
    gcode = load_piece(PIECES / "rounded_rectangle.gcode")
    want = [s.end for s in ref.segments() if s.cut]
    for other in (contour, gcode):
        got = [s.end for s in other.segments() if s.cut]
        assert len(got) == len(want)
        assert max(distance(a, b) for a, b in zip(got, want, strict=True)) < 1e-9


def test_e3_seed_arc_overshoots():
    s = thesis_arc_points((40, 20), (40, 10), math.pi / 2, 2.0, 0.025)
    assert s.alpha == printed(0.0150001, 7)
    assert 2 * 10 * math.sin(s.alpha / 2) == pytest.approx(0.15, abs=EXACT)
    assert 10 * (1 - math.cos(s.alpha / 2)) == pytest.approx(2.81e-4, abs=5e-7)
    assert s.steps == 105
    assert s.points[104] == (printed(49.99991, 5), printed(20.04218, 5))
    floor = thesis_arc_points((40, 20), (40, 10), math.pi / 2, 2.0, 0.025, count="floor")
    assert floor.steps == 104
    assert distance(floor.points[-2], floor.points[-1]) == printed(0.10782, 5)


# -- E4 arc step of the CPU ----------------------------------------------------------------

def test_e4_cpu_arc_step():
    arc = Arc((0, 0), (10, 0), 0.03)
    assert arc.polyline_length(1) == printed(0.29999, 5)
    assert arc.sagitta(1) == printed(0.001125, 6)
    assert (math.pi / 2) / 0.03 == printed(52.36, 2)


# -- E5, E6 Newton curves ------------------------------------------------------------------

def test_e5_figura20_divided_differences():
    c = NewtonCurve((10, 40, 60, 90), (11, 22, 20, 5))
    assert not c.equidistant
    assert c.coefficients == pytest.approx([11, 11 / 30, -0.0093333333, 1 / 60000], abs=1e-9)
    for x, y in zip(c.xs, c.ys, strict=True):
        assert c(x) == pytest.approx(y, abs=EXACT)
    # the maximum 22.1615 at x = 44.23: p'(x) = 0 there
    x_max = _argmax(c, 10, 90)
    assert (x_max, c(x_max)) == (printed(44.23, 2), printed(22.1615, 4))
    dev, _ = c.chord_deviation(60)
    assert dev == printed(0.00415, 5)
    thesis = ThesisNewton((10, 40, 60, 90), (11, 22, 20, 5))
    assert thesis.coefficients == [11, 11, -6.5, 0]
    assert [thesis(x) for x in (25, 60, 90)] == [
        printed(18.125, 6), printed(22.111, 3), printed(11.444, 3)]


def test_e6_equidistant_five_nodes():
    c = NewtonCurve((0, 10, 20, 30, 40), (0, 5, 3, 8, 2))
    assert c.equidistant
    assert forward_coefficients(c.ys) == pytest.approx([0, 5, -3.5, 7 / 3, -4 / 3], abs=EXACT)
    assert [c(x) for x in (5, 15, 25, 35)] == pytest.approx([5.5, 3.25, 5.0, 8.75], abs=EXACT)
    x_max = _argmax(c, 30, 40)
    assert (x_max, c(x_max)) == (printed(33.472, 3), printed(9.03503, 5))
    dev, at = c.chord_deviation(60)
    assert dev == printed(0.015602, 6) and at == printed(35.67, 2)
    pts = c.points(60)
    assert sum(distance(a, b) for a, b in zip(pts, pts[1:], strict=False)) == printed(
        48.17690, 5)
    assert c.arc_length() == printed(48.19093, 5)
    assert c(40) == pytest.approx(2.0, abs=EXACT) and pts[-1] == (40, 2)
    p = load_piece(PIECES / "newton5.toml")
    assert [s.end for s in p.segments()] == pts[1:]


def test_newton_chord_count_from_tolerance():
    c = NewtonCurve((0, 10, 20, 30, 40), (0, 5, 3, 8, 2))
    n = c.samples_for(0.01)
    assert c.chord_deviation(n)[0] <= 0.01 < c.chord_deviation(n - 1)[0]


def _argmax(c: NewtonCurve, lo: float, hi: float) -> float:
    for _ in range(200):  # golden search on the unimodal maximum
        m1, m2 = lo + (hi - lo) * 0.382, lo + (hi - lo) * 0.618
        lo, hi = (lo, m2) if c(m1) > c(m2) else (m1, hi)
    return (lo + hi) / 2


# -- E7 the line split ---------------------------------------------------------------------

@pytest.mark.parametrize("v, t", [(2.0, 50.02), (50.0, 2.5)])
def test_e7_corrected_split_keeps_the_line(v, t):
    s = split_line((0, 0), (80, 60), v, 100.0)
    assert (s.x.speed, s.y.speed) == pytest.approx((0.8 * v, 0.6 * v), abs=EXACT)
    assert (s.x.accel, s.y.accel) == pytest.approx((80.0, 60.0), abs=EXACT)
    assert s.x.profile.duration == pytest.approx(t, abs=EXACT)
    assert s.arrival_gap == pytest.approx(0.0, abs=EXACT)
    assert s.cross_track()[0] < 1e-9
    assert s.position(t) == (80.0, 60.0)


def test_split_triangle_axis_at_rest_and_zero_length():
    s = split_line((0, 0), (0.1, 0), 50.0, 100.0)  # L < v²/a: triangular profile
    assert s.x.profile.triangular and s.duration == pytest.approx(2 * math.sqrt(0.001))
    assert s.y.direction == 0 and s.y.speed == 50.0  # the PLC never gets a zero speed
    assert split_line((3, 4), (3, 4)).duration == 0.0


# -- E10 Arandela --------------------------------------------------------------------------

def test_e10_washer_full_circles():
    p = load_piece(PIECES / "arandela.toml")
    circles = [e.shape for e in p.elements if isinstance(e.shape, Arc)]
    assert [c.radius for c in circles] == [6, 15]
    expected = {6: (55, 0.009785, 37.67862), 15: (87, 0.009779, 94.22730)}
    for c in circles:
        n, sag, length = expected[c.radius]
        assert c.chord_count(0.01) == n
        assert c.sagitta(n) == printed(sag, 6)
        assert c.polyline_length(n) == printed(length, 5)
        assert c.chords(0.01)[-1] == c.start  # ends exactly at its start
    kinds = [s.kind for s in p.segments()]
    assert kinds == ["move"] + ["cut"] * 55 + ["move"] + ["cut"] * 87
