"""Seed mode: each defect of the thesis (cutting-table.md §2.6) shown next to its correction."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from softplc.machines.cutting import Arc, NewtonCurve, load_piece, matlab_steps, split_line
from softplc.machines.cutting.geometry import distance, dot
from softplc.machines.cutting.regmap import to_um
from softplc.machines.cutting.seed import (
    ThesisNewton,
    run_trigger_chain,
    thesis_arc_points,
    thesis_arc_step,
    thesis_beta,
    thesis_cpu_arc,
    thesis_line_steps,
    thesis_split,
)

PIECES = Path(__file__).resolve().parents[2] / "ladder_programs" / "pieces"
SHIELD = [(5, 5), (7, 8), (7, 12), (6, 13), (4, 13), (3, 12), (3, 8), (5, 5)]


def test_b1_thesis_line_steps_always_go_up_and_right():
    # Escudo P4 -> P5 goes left; the printed ConsignaLinea has no sign and goes right.
    seed = thesis_line_steps((7, 12), (6, 13))
    assert seed.points[-1][0] == pytest.approx(8.0, abs=1e-9)
    assert distance(seed.points[-1], (6, 13)) > 1.9
    assert matlab_steps((7, 12), (6, 13)).points[-1] == (6, 13)
    # L = 0: the thesis divides 0 by 0 (NaN); the corrected line is a no-op.
    assert math.isnan(thesis_line_steps((1, 1), (1, 1)).points[-1][0])
    assert matlab_steps((1, 1), (1, 1)).points == []


def test_b2_round_makes_the_last_step_go_back():
    # L/(v·T) = 1.6: round gives 2 full steps (past the end) and a step of -0.02 back.
    seed = thesis_line_steps((0, 0), (0.08, 0), 2.0, 0.025)
    assert seed.steps == 2 and seed.last_step == pytest.approx(-0.02)
    assert max(p[0] for p in seed.points) == pytest.approx(0.1)  # 0.02 beyond the end
    fixed = matlab_steps((0, 0), (0.08, 0), 2.0, 0.025)
    assert (fixed.full_steps, fixed.last_step) == (1, pytest.approx(0.03))
    assert max(p[0] for p in fixed.points) == 0.08


@pytest.mark.parametrize("v, offset, gap, tx, ty", [
    (2.0, 0.00192, 0.004, 50.016, 50.012), (50.0, 1.200, 0.1, 2.4, 2.3)])
def test_b3_equal_accelerations_bend_the_line(v, offset, gap, tx, ty):
    seed = thesis_split((0, 0), (80, 60), v, 100.0)
    assert seed.x.accel == seed.y.accel == 100.0
    assert seed.cross_track()[0] == pytest.approx(offset, abs=1e-9)
    assert seed.arrival_gap == pytest.approx(gap, abs=1e-9)
    assert (seed.x.profile.duration, seed.y.profile.duration) == pytest.approx((tx, ty))
    fixed = split_line((0, 0), (80, 60), v, 100.0)
    assert fixed.cross_track()[0] < 1e-9 and fixed.arrival_gap < 1e-12


def test_b3_worst_direction():
    v, a = 50.0, 100.0
    worst = math.radians(20.905)
    end = (100 * math.cos(worst), 100 * math.sin(worst))
    dev = thesis_split((0, 0), end, v, a).cross_track()[0]
    assert dev == pytest.approx(0.19245 * v * v / (2 * a), rel=1e-4)


def test_b6_arc_step_undefined_for_small_radius():
    from softplc.machines.cutting import GeometryError

    with pytest.raises(GeometryError, match="asin"):
        thesis_arc_step(0.05, 2.0, 0.025)  # 3·v·T = 0.15 > 2R = 0.1
    assert Arc((0, 0), (0.05, 0), math.pi).chord_count(0.01) >= 1  # corrected: fine


@pytest.mark.parametrize("vector, matlab, cpu", [
    ((1, 0), 0, 0), ((1, 1), 45, 135), ((-1, 1), 135, 135), ((-1, 0), 180, 90),
    ((-1, -1), 225, 135), ((0, -1), 270, 90), ((1, -1), 315, 45), ((-2, 1), 116.565, 116.565)])
def test_b5_quadrant_of_the_start_angle(vector, matlab, cpu):
    assert math.degrees(thesis_beta(vector)) == pytest.approx(matlab, abs=1e-3)
    assert math.degrees(thesis_beta(vector, cpu=True)) == pytest.approx(cpu, abs=1e-3)
    true = math.degrees(math.atan2(vector[1], vector[0])) % 360
    right = {(1, 0), (-1, 1)}  # the CPU: the +x ray and, by chance, 135°
    assert (abs(math.degrees(thesis_beta(vector, cpu=True)) - true) < 1e-9) == (
        vector in right)


def test_b5_cpu_arc_starts_on_the_wrong_side():
    # E3's first arc starts below its centre (270°); the CPU's β is 90°: the first chord
    # crosses the whole circle, 20 mm through the piece.
    run = thesis_cpu_arc((40, 20), (40, 10), math.pi / 2, quadrant_bug=True)
    assert distance((40, 10), run.points[0]) > 19.9
    assert Arc((40, 20), (40, 10), math.pi / 2).chords(0.01)[0][1] < 10.2


def test_b8_end_box_full_circle_ends_at_once_and_arcs_stop_short():
    full = thesis_cpu_arc((50, 50), (65, 50), 2 * math.pi)
    assert len(full.points) == 1  # no arc point at all: just "the line to Pf" (the start)
    assert len(Arc((50, 50), (65, 50), 2 * math.pi).chords(0.01)) == 87
    quarter = thesis_cpu_arc((40, 20), (40, 10), math.pi / 2)
    assert quarter.ended and quarter.points[-1] == pytest.approx((50, 20))
    stop = quarter.points[-2]  # where the carriage entered the 0.1 box
    assert max(abs(stop[0] - 50), abs(stop[1] - 20)) == pytest.approx(0.1, abs=1e-9)


def test_b7_round_overshoots_the_arc_end_and_cuts_back():
    arc = Arc((40, 20), (40, 10), math.pi / 2)
    seed = thesis_arc_points(arc.centre, arc.start, arc.sweep)
    assert seed.overshoot == pytest.approx(0.0042, abs=5e-5)
    past = seed.points[-2]
    assert past[1] - 20 == pytest.approx(0.04218, abs=5e-6)  # 0.042 beyond the tangent point
    last_chord = (seed.points[-1][0] - past[0], seed.points[-1][1] - past[1])
    assert dot(last_chord, arc.tangent_at(arc.sweep)) < 0  # the last chord goes backwards
    fixed = arc.chords(0.01)
    assert fixed[-1] == (50.0, 20.0)
    assert all(p[1] <= 20.0 + 1e-12 for p in fixed)  # never past the end


def test_b7_clockwise_arc_becomes_one_chord():
    seed = thesis_arc_points((40, 20), (50, 20), -math.pi / 2)
    assert seed.steps == 0 and len(seed.points) == 1
    assert seed.points[0] == pytest.approx((40, 10))
    fixed = Arc((40, 20), (50, 20), -math.pi / 2).chords(0.01)
    assert len(fixed) == 18
    assert all(p[0] >= 40 - 1e-9 and p[1] <= 20 + 1e-9 for p in fixed)  # the lower right


def test_b9_cpu_truncates_setpoints():
    seed = thesis_arc_points((0, 0), (10, 0), math.pi / 2, cpu=True)
    assert seed.alpha == 0.03
    arc = Arc((0, 0), (10, 0), math.pi / 2)
    errs = []
    for i, p in enumerate(seed.points[:-1], start=1):
        true = arc.point_at(i * 0.03)
        errs.append((true[0] - p[0], true[1] - p[1]))
    # TRUNC biases towards 0: the error is always >= 0 for these positive coordinates
    assert all(-1e-12 <= e <= 0.001 + 1e-12 for pair in errs for e in pair)
    assert max(max(pair) for pair in errs) > 0.0009
    # rounding to 1 µm (what the host sends) is never more than half a µm off
    for i in range(1, 53):
        x, y = arc.point_at(i * 0.03)
        assert abs(to_um(x) / 1000 - x) <= 0.0005 and abs(to_um(y) / 1000 - y) <= 0.0005


def test_b12_nodes_not_equidistant():
    xs, ys = (10, 40, 60, 90), (11, 22, 20, 5)
    seed, fixed = ThesisNewton(xs, ys), NewtonCurve(xs, ys)
    assert seed(90) == pytest.approx(103 / 9)  # 11.444, the thesis's "about 11"
    assert seed(60) == pytest.approx(199 / 9)  # 22.111 instead of 20
    assert (fixed(90), fixed(60)) == (pytest.approx(5), pytest.approx(20))


def test_b13_last_term_lost_wrong_value_at_last_node():
    xs, ys = (0, 10, 20, 30, 40), (0, 5, 3, 8, 2)
    seed, fixed = ThesisNewton(xs, ys), NewtonCurve(xs, ys)
    for x, y in zip(xs[:-1], ys[:-1], strict=True):  # interior nodes are still exact
        assert seed(x) == pytest.approx(y, abs=1e-9)
    delta4 = 2 - 4 * 8 + 6 * 3 - 4 * 5 + 0  # Δ⁴y0
    assert seed(40) == pytest.approx(34) == 2 - delta4
    assert fixed(40) == pytest.approx(2, abs=1e-9)


def test_b16_thesis_samples_stop_at_the_penultimate_node():
    seed = ThesisNewton((0, 10, 20, 30, 40), (0, 5, 3, 8, 2)).points()
    assert seed[-1][0] == 30 and len(seed) == 61
    assert NewtonCurve((0, 10, 20, 30, 40), (0, 5, 3, 8, 2)).points()[-1] == (40, 2)


def test_b19_the_shield_is_cut_forever():
    run = run_trigger_chain(SHIELD, start=(0, 0), gated=False, max_passes=1000)
    assert run.runs_forever and not run.finished
    assert run.ops[:9] == [1, 2, 3, 4, 5, 6, 7, 8, 2]  # op 1's test fires at P2 again
    assert run.cycle_moves == 7  # ops 2..8 repeat
    assert run.passes < 1000  # detected, not run out
    fixed = run_trigger_chain(SHIELD, start=(0, 0), gated=True)
    assert fixed.finished and fixed.ops == [1, 2, 3, 4, 5, 6, 7, 8]


def test_chain_without_shared_points_finishes_either_way():
    square = [(15, 0), (15, 15), (0, 15), (0, 0)]
    run = run_trigger_chain(square, start=(0, 0))
    # Cuadrado ends where it starts: op 4's ungated end test fires on the first pass, but it
    # only clears D4 (no op 5): the chain still runs each op once.
    assert run.finished and run.ops == [1, 2, 3, 4]


def test_seed_piece_versus_corrected():
    p = load_piece(PIECES / "achaflanado.toml")
    seed = p.segments(seed=True)
    fixed = p.segments()
    assert max(s.end[1] for s in seed if 49.9 < s.end[0] <= 50 and s.end[1] < 25) > 20.04
    assert len(seed) > 5 * len(fixed)  # the 0.15 chord of v·T vs the 0.01 mm tolerance
    assert fixed[-1].end == (20.0, 10.0)
    assert seed[-1].end == pytest.approx((20.0, 10.0), abs=1e-12)


def test_b3_on_a_whole_piece_simulated_with_ideal_axes():
    from softplc.machines.cutting.motion import simulate

    p = load_piece(PIECES / "escudo.toml", speed=50.0)
    segs = p.segments()
    fixed = simulate(segs, p.accel, 0.002)
    assert max(p.deviation((s.x, s.y)) for s in fixed if s.torch) < 1e-9
    assert fixed[-1].t == pytest.approx(p.duration()) and (fixed[-1].x, fixed[-1].y) == (5, 5)
    assert [s.t for s in fixed] == sorted(s.t for s in fixed)
    seed = simulate(segs, p.accel, 0.002, thesis_split)
    worst = max(p.deviation((s.x, s.y)) for s in seed if s.torch)
    per_segment = max(thesis_split(s.start, s.end, s.speed, p.accel).cross_track()[0]
                      for s in segs if s.cut)
    assert 0.3 < worst <= per_segment + 1e-9
    assert worst == pytest.approx(per_segment, rel=1e-3)


def test_cpu_variant_steps_a_clockwise_arc_clockwise():
    """Issue 23: the CPU's step carries the sign of θ and n = floor(|θ|/α) (reference
    §2.2); k used to come from the signed θ, clamped to 0: one straight chord."""
    seed = thesis_arc_points((40, 20), (50, 20), -math.pi / 2, cpu=True)
    assert seed.alpha == -0.03 and seed.steps == math.floor((math.pi / 2) / 0.03) == 52
    assert seed.overshoot < 0  # floor: the last step stops short, the closing chord ends it
    pts = seed.points
    assert pts[-1] == pytest.approx((40, 10), abs=1e-3)
    assert all(abs(distance((40, 20), p) - 10) < 2e-3 for p in pts)  # on the circle (TRUNC)
    assert all(p[0] >= 40 - 1e-9 and p[1] <= 20 + 1e-9 for p in pts)  # the lower right
    angles = [math.atan2(p[1] - 20, p[0] - 40) for p in pts]
    assert all(b < a for a, b in zip(angles, angles[1:], strict=False))  # clockwise
    assert thesis_arc_step(10.0, cpu=True, sweep=-1.0) == -0.03
    # the Matlab variant keeps its own defect (B7): no step, one chord
    assert thesis_arc_points((40, 20), (50, 20), -math.pi / 2).steps == 0


def test_seed_mode_cpu_variant_cuts_a_clockwise_arc_of_a_piece():
    from softplc.machines.cutting import piece_from_dict

    piece = piece_from_dict({"start": [50, 20], "op": [
        {"kind": "arc", "centre": [40, 20], "sweep": -90},
        {"kind": "circle", "centre": [100, 100], "radius": 10, "direction": "cw"}]})
    matlab = [s for s in piece.segments(seed=True) if s.cut]
    cpu = [s for s in piece.segments(seed="cpu") if s.cut]
    # the Matlab (B7, shown): the quarter is one chord, the full circle nothing at all
    assert len(matlab) == 1 and matlab[0].end == pytest.approx((40, 10))
    assert len(cpu) == 53 + math.floor(2 * math.pi / 0.03) + 1
    assert cpu[52].end == pytest.approx((40, 10), abs=1e-3)
    assert cpu[-1].end == pytest.approx((110, 100), abs=1e-3)
    assert max(piece.deviation(s.end) for s in cpu) < 2e-3
    with pytest.raises(ValueError, match="seed variant"):
        piece.segments(seed="simotion")


def test_softplc_cut_seed_variants_on_a_clockwise_arc(tmp_path, capsys):
    from softplc.cli import main

    f = tmp_path / "cw.toml"
    f.write_text('start = [50, 20]\n[[op]]\nkind = "arc"\ncentre = [40, 20]\nsweep = -90\n',
                 encoding="utf-8")
    assert main(["cut", str(f), "--dry-run", "--seed"]) == 0
    out = capsys.readouterr().out
    assert "clockwise arcs of op[0] are each one chord" in out  # B7, shown
    assert "seed mode (matlab, thesis algorithms): 1 segments" in out
    assert main(["cut", "--seed-variant", "cpu", str(f), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "one chord" not in out and "seed mode (cpu, thesis algorithms): 53 segments" in out
