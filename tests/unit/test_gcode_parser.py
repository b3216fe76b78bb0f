"""The G-code reader: codes, both arc forms, units, incremental mode, seed dialect, errors."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from softplc.errors import ConfigError, SoftPLCError
from softplc.machines.gcode import GCodeConfig, GCodeError, parse_file, parse_gcode, to_steps

SAMPLES = Path(__file__).resolve().parents[2] / "ladder_programs" / "samples"


def ends(prog):
    return [tuple(round(c, 6) for c in s.end) for s in prog.segments]


def moves(prog):
    return [s for s in prog.segments if s.kind not in ("pen", "dwell")]


def test_lines_rapid_pen_and_modal_coordinates():
    prog = parse_gcode("G00 X1 Z2 Y0\nY1\nG01 X5\nZ7\nY0\n")
    assert [(s.kind, s.pen_down, s.start, s.end) for s in prog.segments] == [
        ("rapid", False, (0.0, 0.0), (1.0, 2.0)),
        ("pen", True, (1.0, 2.0), (1.0, 2.0)),
        ("line", True, (1.0, 2.0), (5.0, 2.0)),  # Z kept from before
        ("line", True, (5.0, 2.0), (5.0, 7.0)),  # G01 stays modal
        ("pen", False, (5.0, 7.0), (5.0, 7.0)),
    ]


def test_default_motion_is_linear_and_pen_starts_up():
    prog = parse_gcode("X3 Z4")
    (seg,) = prog.segments
    assert seg.kind == "line" and not seg.pen_down and seg.end == (3.0, 4.0)


@pytest.mark.parametrize("code, factor", [("G21", 0.1), ("G71", 0.1), ("G20", 2.54),
                                          ("G70", 2.54)])
def test_units(code, factor):
    prog = parse_gcode(f"{code} G01 X4 Z2")
    assert prog.segments[-1].end == pytest.approx((4 * factor, 2 * factor))


def test_default_units_are_configurable():
    prog = parse_gcode("X40 Z20", GCodeConfig(units="mm"))
    assert prog.segments[-1].end == pytest.approx((4.0, 2.0))


def test_incremental_and_back_to_absolute():
    prog = parse_gcode("X1 Z1\nG91 X2 Z3\nX1\nG90 X0.5")
    assert ends(prog) == [(1, 1), (3, 4), (4, 4), (0.5, 4)]


def test_feed_is_carried_in_drawing_units():
    prog = parse_gcode("G21 G01 X10 F600")
    assert prog.segments[0].feed == pytest.approx(60.0)


def test_dwell_with_p_and_x():
    prog = parse_gcode("X1 Z1\nG04 P0.5\nG04 X2")
    dwells = [s for s in prog.segments if s.kind == "dwell"]
    assert [d.dwell for d in dwells] == [0.5, 2.0]
    assert all(d.start == d.end == (1.0, 1.0) for d in dwells)  # X in G04 is time, not a move


def test_comments_are_ignored():
    prog = parse_gcode("(header) G01 X1 (mid) Z2 ; tail X9\n; whole line\n( X5 )")
    assert ends(prog) == [(1, 2)]


@pytest.mark.parametrize("text", ["g1x2.5z1.5", "G01 X 2.5 Z 1.5", "G1X2.5Z1.5"])
def test_compact_and_spaced_words(text):
    assert ends(parse_gcode(text)) == [(2.5, 1.5)]


def test_plane_selection_must_match_the_table():
    assert ends(parse_gcode("G18 X1 Z1")) == [(1, 1)]
    with pytest.raises(GCodeError) as e:
        parse_gcode("G17 X1 Y1")
    assert "G17 selects the XY plane" in str(e.value) and e.value.line == 1


def test_xy_plane_with_depth_pen():
    cfg = GCodeConfig(plane="XY")
    prog = parse_gcode("G17 G21\nG00 Z5\nX10 Y10\nG01 Z-1\nX50\nG00 Z5\nX0 Y0", cfg)
    drawn = [(s.start, s.end) for s in moves(prog) if s.pen_down]
    assert drawn == [((1.0, 1.0), (5.0, 1.0))]
    assert cfg.pen_axis == "Z" and cfg.pen_mode == "depth"


def test_yz_plane_uses_j_k_offsets():
    cfg = GCodeConfig(plane="YZ")
    prog = parse_gcode("G19 Y2 Z5\nG02 Y8 Z5 J3 K0", cfg)
    arc = [s for s in prog.segments if s.kind == "arc"]
    assert arc and arc[-1].end == pytest.approx((8.0, 5.0))
    assert max(s.end[1] for s in arc) == pytest.approx(8.0, abs=0.02)  # CW over the top


def test_arc_with_r_short_and_long():
    short = parse_gcode("X0 Z5\nG02 X10 Z5 R5")  # half circle, CW from left: over the top
    assert max(s.end[1] for s in short.segments) == pytest.approx(10.0, abs=0.011)
    shortq = parse_gcode("X10 Z5\nG03 X15 Z10 R5")  # quarter, CCW: centre (10, 10)
    for s in shortq.segments[1:]:
        assert math.dist(s.end, (10.0, 10.0)) == pytest.approx(5.0, abs=1e-9)
    longq = parse_gcode("X10 Z5\nG03 X15 Z10 R-5")  # three quarters: centre (15, 5)
    pts = [s.end for s in longq.segments[1:]]
    for p in pts:
        assert math.dist(p, (15.0, 5.0)) == pytest.approx(5.0, abs=1e-9)
    assert max(p[0] for p in pts) == pytest.approx(20.0, abs=0.011)  # round the far side
    assert min(p[1] for p in pts) == pytest.approx(0.0, abs=0.011)


def test_arc_on_vertical_chord_defect_6():
    # The seed's VB code divides by the chord's X difference here.
    prog = parse_gcode("X10 Z5\nG02 X10 Z15 R5\nG03 X10 Z5 R5")
    arcs = [s for s in prog.segments if s.kind == "arc"]
    first = [s for s in arcs if s.line == 2]
    second = [s for s in arcs if s.line == 3]
    # CW going up: the arc bulges to the left; CCW going down bulges left too.
    assert min(s.end[0] for s in first) == pytest.approx(5.0, abs=0.011)
    assert min(s.end[0] for s in second) == pytest.approx(5.0, abs=0.011)
    assert max(s.end[0] for s in arcs) <= 10.0 + 1e-9


def test_full_circle_with_offsets():
    prog = parse_gcode("X5 Z10\nG02 X5 Z10 I5 K0")
    arc = [s for s in prog.segments if s.kind == "arc"]
    assert len(arc) > 3
    assert arc[-1].end == (5.0, 10.0)
    xs = [s.end[0] for s in arc]
    assert max(xs) == pytest.approx(15.0, abs=0.011)
    # Full circle with offsets only, no end point: back to the start.
    again = parse_gcode("X5 Z10\nG03 I5")
    assert [s for s in again.segments if s.kind == "arc"][-1].end == (5.0, 10.0)


def test_arc_direction_with_offsets():
    # From (10, 5) around (10, 10): CCW goes right first, CW goes left first.
    ccw = parse_gcode("X10 Z5\nG03 X10 Z15 K5").segments[1]
    cw = parse_gcode("X10 Z5\nG02 X10 Z15 K5").segments[1]
    assert ccw.end[0] > 10 > cw.end[0]


def test_seed_dialect():
    text = "n1 g01 x2 z2 y0, n2 y1, n3 x12 z2, n4 g02 x12 z12 r5, n5 y0, n6 g01 x0 z0"
    prog = parse_gcode(text)
    down = [s for s in moves(prog) if s.pen_down]
    assert down[0].start == (2.0, 2.0) and down[0].end == (12.0, 2.0)
    assert down[-1].end == pytest.approx((12.0, 12.0))
    assert all(s.line == 1 for s in prog.segments)
    assert not prog.segments[-1].pen_down and prog.segments[-1].end == (0.0, 0.0)


def test_seed_dialect_sample_file():
    prog = parse_file(SAMPLES / "seed_house.gcode")
    assert not prog.warnings
    assert prog.pen_down_length() > 80


@pytest.mark.parametrize("name", ["square", "circle", "star", "seed_house"])
def test_samples_parse_without_warnings(name):
    prog = parse_file(SAMPLES / f"{name}.gcode")
    assert not prog.warnings
    steps = prog.steps()
    assert steps and not steps[-1].pen_down


def test_star_sample_has_vertical_steep_edges_and_travel():
    prog = parse_file(SAMPLES / "star.gcode")
    down = [s for s in moves(prog) if s.pen_down]
    assert any(s.start[0] == s.end[0] for s in down)
    assert any(abs(s.end[1] - s.start[1]) > 10 * abs(s.end[0] - s.start[0]) > 0 for s in down)
    assert any(not s.pen_down and s.kind == "rapid" and s.length > 5 for s in prog.segments)


def test_unsupported_codes_warn_with_line_numbers():
    prog = parse_gcode("G40 G01 X1\nM03\nT1 X2\nG41 X3")
    msgs = [(w.line, w.text) for w in prog.warnings]
    assert msgs == [(1, "G40"), (2, "M03"), (3, "T1"), (4, "G41")]
    assert ends(prog)[-1] == (3, 0)


def test_every_error_is_reported_with_line_and_column():
    text = "G01 X1 Z1\nG01 X1..2\nG01 Q\nX30 Z1\nG02 X5 Z5\nG01 X1 X2\n(open\nG01 G02 X1"
    with pytest.raises(GCodeError) as e:
        parse_gcode(text, file="bad.gcode")
    diags = e.value.diagnostics
    got = [(d.line, d.column) for d in diags]
    assert got == [(2, 5), (3, 5), (4, 1), (5, 5), (6, 8), (7, 1), (8, 5)]
    assert isinstance(e.value, SoftPLCError)
    s = str(e.value)
    assert "bad.gcode:2:5: malformed number" in s
    assert "bad.gcode:4:1: point X30 Z1 cm is outside the 25 x 25 cm table" in s
    assert "arc needs R or centre offsets" in s
    assert "word X appears twice" in s
    assert "unclosed comment" in s
    assert "conflicts with G01" in s


def test_arc_errors():
    cases = {
        "X1 Z1\nG02 X1 Z1 R3": "distinct start and end",
        "X1 Z1\nG02 X9 Z1 R2": "smaller than half the chord",
        "X1 Z1\nG02 X9 Z1 I4 R4": "both R and centre offsets",
        "X1 Z1\nG02 X9 Z1 I3": "from the centre but the start",
        "X1 Z1\nG02 X9 Z1 J4": "J is not a centre offset in the XZ plane",
    }
    for text, msg in cases.items():
        with pytest.raises(GCodeError) as e:
            parse_gcode(text)
        assert msg in str(e.value), text
        assert e.value.line == 2


def test_arc_leaving_the_table_is_an_error():
    # Both ends on the table, the bulge below Z = 0 is not.
    with pytest.raises(GCodeError) as e:
        parse_gcode("X5 Z1\nG03 X15 Z1 R5")
    assert e.value.line == 2 and "outside" in str(e.value)


def test_table_size_is_configurable():
    assert ends(parse_gcode("X30 Z40", GCodeConfig(table_width=50, table_height=50)))
    with pytest.raises(GCodeError):
        parse_gcode("X20 Z5", GCodeConfig(table_width=10))


def test_bad_config():
    with pytest.raises(ConfigError):
        GCodeConfig(plane="XQ")
    with pytest.raises(ConfigError):
        GCodeConfig(steps_per_unit=0)
    with pytest.raises(ConfigError):  # 400 cm x 111.11 steps do not fit a %MW register
        GCodeConfig(table_width=400)


def test_steps_round_and_chain():
    prog = parse_gcode("X1 Z2\nY1\nX1.002\nX2.5 Z0.0049")
    steps = to_steps(prog.segments, 111.11)
    assert steps[0].end == (111, 222)
    # X1.002 is less than half a step away: dropped; the pen change is kept.
    assert [s.kind for s in steps] == ["line", "pen", "line"]
    assert steps[-1].start == steps[-2].end and steps[-1].end == (278, 1)
    assert [s.number for s in steps] == [1, 2, 3]
    assert prog.steps() == steps


def test_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(GCodeError) as e:
        parse_file(tmp_path / "nope.gcode")
    assert "cannot read the file" in str(e.value)


# ---- errors and warnings together; XY G-code read in the seed's XZ plane ----------------------
def test_warnings_are_shown_with_the_errors_in_line_order():
    with pytest.raises(GCodeError) as e:
        parse_gcode("G18\nM3\nG1 X999 Z1\nG40\n")
    lines = str(e.value).splitlines()
    assert lines == [
        "<string>:2:1: warning: M code M3 is not supported; ignored (at 'M3')",
        "<string>:3:4: point X999 Z1 cm is outside the 25 x 25 cm table",
        "<string>:4:1: warning: G40 (cutter compensation off) is not supported; ignored "
        "(at 'G40')",
    ]
    assert len(e.value.diagnostics) == 1 and len(e.value.warnings) == 2


@pytest.mark.parametrize("text, message", [
    ("G1 X10 Y10\nG1 X0 Y0\n", "1:8: Y10 is not a pen word (Y1 down, Y0 up)"),
    ("G0 X1 Y0\nG1 X10 Y1\nX20\n", "1:7: the program moves along X with Y words but never "
                                  "names Z"),
])
def test_xy_gcode_in_the_xz_plane_is_refused_with_a_hint(text, message):
    with pytest.raises(GCodeError) as e:
        parse_gcode(text)
    assert message in str(e.value) and "--plane XY" in str(e.value)
    assert len(e.value.diagnostics) == 1  # one problem, said once


def test_the_same_program_reads_as_xy_or_as_the_seed_dialect_when_told():
    prog = parse_gcode("G1 X10 Y10\n", GCodeConfig(plane="XY", pen="depth"))
    assert prog.segments[-1].end == (10.0, 10.0)
    seed = parse_gcode("G1 X10 Y10\n", GCodeConfig(dialect="seed"))
    assert seed.segments[-1].end == (10.0, 0.0) and seed.segments[-1].pen_down
    assert "taken as down" in seed.warnings[0].message


def test_draw_command_refuses_ambiguous_y(tmp_path, capsys):
    from softplc.cli import main

    f = tmp_path / "xy.gcode"
    f.write_text("G21\nG1 X10 Y10\n")
    assert main(["draw", str(f), "--dry-run"]) == 1
    err = capsys.readouterr().err
    assert "--plane XY" in err and "Traceback" not in err
    assert main(["draw", str(f), "--dry-run", "--plane", "XY", "--pen", "depth"]) == 0
