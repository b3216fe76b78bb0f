"""Pieces from TOML and G-code, bad geometry errors, the PLC words, `softplc cut`."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest
from modbus_util import refused_port

from softplc import PLC
from softplc.cli import main
from softplc.machines.cutting import (
    Arc,
    CoincidentPointsError,
    FilletError,
    Line,
    NewtonCurve,
    NewtonError,
    PieceError,
    ZeroRadiusError,
    fillet,
    load_piece,
    piece_from_dict,
    segment_words,
)
from softplc.machines.cutting.geometry import distance, distance_to, unit
from softplc.machines.cutting.regmap import FRAME_LEN, SEG_BASE, seg_no
from softplc.modbus_codec import words_to_float, words_to_long

PIECES = Path(__file__).resolve().parents[2] / "ladder_programs" / "pieces"


# -- geometry errors -----------------------------------------------------------------------

def test_bad_geometry_raises_typed_errors():
    with pytest.raises(ZeroRadiusError, match="radius 0"):
        Arc((1, 1), (1, 1), math.pi)
    with pytest.raises(CoincidentPointsError, match=r"\(2, 3\) and \(2, 3\) coincide"):
        unit((2, 3), (2, 3))
    with pytest.raises(FilletError, match="needs 10 mm of the incoming line"):
        fillet((5, 0), (10, 0), (10, 30), 10)  # 90° corner, incoming line only 5 mm
    with pytest.raises(FilletError, match="turns back"):
        fillet((0, 0), (10, 0), (0, 0), 1)
    with pytest.raises(ZeroRadiusError):
        fillet((0, 0), (10, 0), (10, 10), 0)
    with pytest.raises(NewtonError, match="same x"):
        NewtonCurve((0, 1, 1), (0, 1, 2))
    with pytest.raises(NewtonError, match="7 nodes"):
        NewtonCurve(tuple(range(7)), tuple(range(7)))
    with pytest.raises(NewtonError, match="increasing or decreasing"):
        NewtonCurve((0, 2, 1), (0, 1, 2))
    with pytest.raises(Exception, match="within ±360"):
        Arc((0, 0), (1, 0), 7.0)


def test_fillet_construction_and_collinear_corner():
    f = fillet((0, 0), (10, 0), (10, 10), 2)
    assert f.t1 == (8, 0) and f.t2 == pytest.approx((10, 2))
    assert f.arc.centre == pytest.approx((8, 2)) and f.arc.sweep == pytest.approx(math.pi / 2)
    assert f.arc.end == pytest.approx(f.t2, abs=1e-12)
    right = fillet((0, 0), (10, 0), (10, -10), 2)  # a right turn: CW arc, centre below
    assert right.arc.sweep < 0 and right.arc.centre == pytest.approx((8, -2))
    assert fillet((0, 0), (5, 0), (10, 0), 2) is None


def test_arc_through_end_cw_ccw_and_full_circle():
    ccw = Arc.through((0, 0), (10, 0), (0, 10), ccw=True)
    cw = Arc.through((0, 0), (10, 0), (0, 10), ccw=False)
    assert ccw.sweep == pytest.approx(math.pi / 2) and cw.sweep == pytest.approx(-1.5 * math.pi)
    assert ccw.end == cw.end == (0, 10)
    full = Arc.through((0, 0), (10, 0), (10, 0), ccw=False)
    assert full.full_circle and full.sweep == -2 * math.pi and full.chords()[-1] == (10, 0)
    with pytest.raises(Exception, match="allowed difference"):
        Arc.through((0, 0), (10, 0), (0, 11), ccw=True)


def test_every_arc_chord_within_tolerance():
    for r, sweep, tol in [(15, 2 * math.pi, 0.01), (3, -2.0, 0.001), (100, 0.3, 0.05)]:
        arc = Arc((50, 50), (50 + r, 50), sweep)
        pts = [arc.start, *arc.chords(tol)]
        for a, b in zip(pts, pts[1:], strict=False):
            mid = ((a[0] + b[0]) / 2, (a[1] + b[1]) / 2)
            assert r - distance(mid, arc.centre) <= tol + 1e-12
            assert distance(b, arc.centre) == pytest.approx(r, abs=1e-9)


def test_chord_limit():
    arc = Arc((0, 0), (10, 0), math.pi / 2)
    pts = [arc.start, *arc.chords(0.01, max_chord=0.5)]
    assert max(distance(a, b) for a, b in zip(pts, pts[1:], strict=False)) <= 0.5 + 1e-12


def test_line_zero_length_is_a_no_op():
    assert Line((1, 1), (1, 1)).chords() == []


# -- TOML pieces ---------------------------------------------------------------------------

def write(tmp_path: Path, text: str, name: str = "p.toml") -> Path:
    f = tmp_path / name
    f.write_text(text)
    return f


@pytest.mark.parametrize("text, message", [
    ('[[op]]\nkind = "line"\nto = [1, 2]\nspeeed = 3\n', r"op\[0\]\.speeed: unknown key"),
    ('[[op]]\nkind = "line"\nto = [1, 2]\n[[op]]\nkind = "arc"\ncentre = [1]\nsweep = 90\n',
     r"op\[1\]\.centre"),
    ('[[op]]\nkind = "spline"\nto = [1, 2]\n',
     r"op\[0\]: unknown kind 'spline'; expected move, line"),
    ('[[op]]\nto = [1, 2]\n', r"op\[0\]: missing 'kind'"),
    ('speed = -1\n[[op]]\nkind = "move"\nto = [1, 2]\n', "speed: expected greater than 0"),
    ('colour = "red"\n[[op]]\nkind = "move"\nto = [1, 2]\n', "colour: unknown key"),
    ('name = "x"\n', "op: required key missing"),
    ('[[op]]\nkind = "arc"\ncentre = [5, 5]\n', "either 'sweep'"),
    ('[[op]]\nkind = "arc"\ncentre = [5, 5]\nsweep = 90\ndirection = "cw"\n',
     "'direction' goes with 'end'"),
    ('[[op]]\nkind = "newton"\nx = [0, 1]\ny = [0, 1]\nsamples = 0\n',
     r"op\[0\]\.samples: expected greater than or equal to 1"),
    ('[[op]]\nkind = "line"\nto = [1, nan]\n', r"op\[0\]\.to\[1\]"),
    ('[[op]\n', "not valid TOML"),
])
def test_toml_errors_name_the_key_path(tmp_path, text, message):
    f = write(tmp_path, text)
    with pytest.raises(PieceError, match=message) as e:
        load_piece(f)
    assert str(f) in str(e.value)


@pytest.mark.parametrize("ops, message", [
    ([{"kind": "move", "to": [10, 10]}, {"kind": "arc", "centre": [10, 10], "sweep": 90}],
     r"op\[1\] \(arc\): arc about \(10, 10\) starts at its centre"),
    ([{"kind": "contour", "points": [[0, 0], [10, 0], [10, 10]], "radius": 20}],
     r"op\[0\] \(contour\): fillet radius 20"),
    ([{"kind": "contour", "points": [[0, 0], [10, 0], [10, 10], [0, 10]], "closed": True,
       "radius": 6}], "its two fillets need 12 mm"),
    ([{"kind": "line", "to": [250, 10]}], r"op\[0\]: point \(250, 10\) mm is outside the 240"),
    ([{"kind": "circle", "centre": [5, 5], "radius": 10}], r"op\[0\]: point .* outside"),
    ([{"kind": "newton", "x": [0, 0, 1], "y": [1, 2, 3]}], r"op\[0\] \(newton\).*same x"),
])
def test_geometry_errors_in_pieces_name_the_op(ops, message):
    with pytest.raises(PieceError, match=message):
        piece_from_dict({"op": ops}, "piece.toml")


def test_start_outside_the_work_area():
    with pytest.raises(PieceError, match=r"start: point \(-1, 0\) mm is outside"):
        piece_from_dict({"start": [-1, 0], "op": [{"kind": "move", "to": [1, 1]}]})


def test_piece_options_speeds_and_automatic_moves():
    p = piece_from_dict({"speed": 4, "move_speed": 20, "start": [1, 1], "op": [
        {"kind": "circle", "centre": [50, 50], "radius": 5, "direction": "cw",
         "start_angle": 90},
        {"kind": "line", "to": [60, 60], "speed": 7},
        {"kind": "newton", "x": [60, 70, 80], "y": [60, 65, 60], "tolerance": 0.05}]})
    segs = p.segments()
    assert segs[0].kind == "move" and segs[0].speed == 20 and segs[0].end == (50, 55)
    circle = [s for s in segs if s.where == "op[0]" and s.cut]
    assert circle[-1].end == (50, 55) and all(s.speed == 4 for s in circle)
    assert circle[0].end[0] > 50  # clockwise from the top goes right
    line = [s for s in segs if s.where == "op[1]"]
    assert [s.speed for s in line] == [7]
    newton = [s for s in segs if s.where == "op[2]"]
    assert newton[-1].end == (80, 60) and all(s.kind == "cut" for s in newton)
    curve = NewtonCurve((60, 70, 80), (60, 65, 60))
    assert curve.chord_deviation(len(newton))[0] <= 0.05


def test_every_sample_piece_loads_and_stays_in_the_work_area():
    files = sorted(PIECES.iterdir())
    assert len(files) >= 7
    for f in files:
        p = load_piece(f)
        assert p.segments() and all(0 <= c <= 240 for s in p.segments() for c in s.end)


# -- G-code pieces -------------------------------------------------------------------------

def test_gcode_moves_cuts_feed_and_cw_arc(tmp_path):
    f = write(tmp_path, "G21 G90\nG00 X10 Y10\nG01 X30 F600\nG02 X40 Y0 I0 J-10\n"
                        "G04 P1\n", "p.gcode")
    p = load_piece(f, tolerance=0.01, speed=3.0, move_speed=15.0)
    segs = p.segments()
    assert segs[0].kind == "move" and segs[0].speed == 15.0
    assert segs[1].kind == "cut" and segs[1].end == (30, 10) and segs[1].speed == 10.0
    arc = [s for s in segs if s.where == "line 4"]
    assert arc[-1].end == pytest.approx((40, 0), abs=1e-12)
    assert all(abs(distance(s.end, (30, 0)) - 10) < 1e-9 for s in arc)
    assert all(s.end[0] >= 30 - 1e-9 for s in arc)  # clockwise: the right-hand quarter
    assert len(arc) == Arc((30, 0), (30, 10), -math.pi / 2).chord_count(0.01)
    assert not p.warnings  # G04 is a dwell now (issue 23), no longer dropped
    assert segs[-1].kind == "dwell" and segs[-1].dwell == 1.0 and segs[-1].end == (40, 0)


def test_gcode_arcs_are_rebuilt_as_arcs(tmp_path):
    p = load_piece(PIECES / "rounded_rectangle.gcode")
    arcs = [e.shape for e in p.elements if isinstance(e.shape, Arc)]
    assert [a.centre for a in arcs] == [
        pytest.approx(c, abs=1e-9) for c in [(40, 20), (40, 40), (20, 40), (20, 20)]]
    assert all(a.sweep == pytest.approx(math.pi / 2, abs=1e-12) for a in arcs)
    assert p.segments(seed=True) != p.segments()  # seed mode reaches G-code arcs
    f = write(tmp_path, "G00 X30 Y20\nG02 X30 Y20 I-10 J0\n"  # full circle, clockwise
                        "G00 X100 Y100\nN1 G03 X110 Y110 I10 N2 G03 X130 Y110 I10\n",
              "c.gcode")
    p = load_piece(f)
    kinds = [(type(e.shape).__name__, e.where) for e in p.elements if e.cut]
    assert kinds[0] == ("Arc", "line 2")
    full = p.elements[1].shape
    assert full.full_circle and full.sweep < 0 and full.centre == pytest.approx((20, 20))
    # two arcs with different centres on one line: kept as the reader's chords
    assert {k for k, w in kinds if w == "line 4"} == {"Line"}
    assert p.segments()[-1].end == pytest.approx((130, 110), abs=1e-12)


@pytest.mark.parametrize("text, message", [
    ("G00 X10 Y10\nG01 Z-1\n", "line 2: a Z \\(pen\\) word"),
    ("G00 X10 Y10\nG01 X300\n", "line 2: point \\(300, 10\\) mm is outside"),
    ("G01 X10 Y10\nG02 X20 Y10\n", "arc needs R or centre offsets"),
])
def test_gcode_errors(tmp_path, text, message):
    f = write(tmp_path, text, "bad.gcode")
    with pytest.raises(Exception, match=message) as e:
        load_piece(f)
    assert "bad.gcode" in str(e.value)


# -- PLC words -----------------------------------------------------------------------------

def test_segment_words_land_in_the_plc_words():
    p = load_piece(PIECES / "achaflanado.toml")
    plc = PLC.from_source("LD 1\n")
    for seg in p.segments()[:5]:
        frame = segment_words(seg).frame()
        assert len(frame) == FRAME_LEN == 9
        for i, v in enumerate(frame):
            plc[f"%MW{SEG_BASE + i}"] = v - 65536 if v > 32767 else v
        assert plc["%MD100"] == round(seg.end[0] * 1000)
        assert plc["%MD102"] == round(seg.end[1] * 1000)
        assert plc["%MF104"] == pytest.approx(seg.speed)
        assert (plc["%MW106"], plc["%MW107"], plc["%MW108"]) == (
            1 if seg.cut else 2, seg.number, 1)
    assert words_to_long(*segment_words(p.segments()[0]).frame()[0:2]) == 20000
    assert words_to_float(*segment_words(p.segments()[0]).frame()[4:6]) == 2.0
    assert (seg_no(1), seg_no(32767), seg_no(32768)) == (1, 32767, 1)


def test_negative_coordinates_in_words():
    from softplc.machines.cutting.piece import Segment

    seg = Segment(3, "move", (0, 0), (-30.0005, 12.0004), 10.0, "x")
    w = segment_words(seg)
    assert (w.x_um, w.y_um) == (-30001, 12000)  # halves away from zero
    assert words_to_long(*w.frame()[0:2]) == -30001


# -- the command ---------------------------------------------------------------------------

def test_cut_command_dry_run_preview_and_frames(tmp_path, capsys):
    png, svg, frames = tmp_path / "e3.png", tmp_path / "e5.svg", tmp_path / "f.csv"
    rc = main(["cut", str(PIECES / "achaflanado.toml"), "--dry-run", "--seed",
               "--preview", str(png), "--frames", str(frames)])
    assert rc == 0
    out = capsys.readouterr().out
    assert "77 segments (76 cut), cut 142.81192 mm" in out and "seed mode" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.DictReader(frames.open()))
    assert len(rows) == 77 and rows[0]["kind"] == "move" and rows[-1]["x_um"] == "20000"
    first = rows[0]  # the move (0,0) -> (20,10): split 2/sqrt(5), 1/sqrt(5)
    assert float(first["vx_mm_s"]) == pytest.approx(4 / math.sqrt(5))
    assert float(first["ay_mm_s2"]) == pytest.approx(100 / math.sqrt(5))
    assert float(first["duration_s"]) == pytest.approx(math.sqrt(500) / 2 + 2 / 100)
    assert main(["cut", str(PIECES / "polinomio.toml"), "--dry-run", "--preview",
                 str(svg)]) == 0
    assert "X (mm)" in svg.read_text()


def test_cut_command_seed_reports_the_endless_shield(capsys):
    assert main(["cut", str(PIECES / "escudo.toml"), "--dry-run", "--seed"]) == 0
    assert "would repeat segments 2-8 forever" in capsys.readouterr().out
    assert main(["cut", str(PIECES / "cuadrado.toml"), "--dry-run", "--seed"]) == 0
    assert "runs this piece once" in capsys.readouterr().out


def test_cut_command_simulates(capsys):
    assert main(["cut", str(PIECES / "achaflanado.toml"), "--dry-run", "--simulate"]) == 0
    out = capsys.readouterr().out
    assert "84.126 s of motion" in out
    assert "at most 0.009517 mm from the ideal shape" in out  # the 18-chord sagitta


def test_cut_command_errors(tmp_path, capsys):
    bad = write(tmp_path, '[[op]]\nkind = "line"\nto = [1, 2]\nspeeed = 3\n')
    assert main(["cut", str(bad), "--dry-run"]) == 1
    assert "op[0].speeed: unknown key" in capsys.readouterr().err
    with refused_port() as port:  # nobody listens there, and no parallel worker takes it
        assert main(["cut", str(PIECES / "cuadrado.toml"), "--port", str(port)]) == 1
    assert "cannot reach the PLC" in capsys.readouterr().err
    assert main(["cut", str(PIECES / "cuadrado.toml"), "--dry-run", "--start-at", "9"]) == 1
    assert main(["cut", str(PIECES / "cuadrado.toml"), "--dry-run", "--preview",
                 str(tmp_path / "x.bmp")]) == 1
    assert "unsupported format" in capsys.readouterr().err
    assert main(["cut", str(tmp_path / "missing.toml"), "--dry-run"]) == 1
    with pytest.raises(SystemExit) as e:
        main(["cut", "--help"])
    assert e.value.code == 0
    assert "--dry-run" in capsys.readouterr().out


# -- deviation from the ideal shape (the device round's trace check) -------------------------

def test_deviation_from_the_ideal_shape():
    p = load_piece(PIECES / "achaflanado.toml")
    cuts = [s for s in p.segments() if s.cut]
    assert max(p.deviation(s.end) for s in cuts) < 1e-9
    mids = [((s.start[0] + s.end[0]) / 2, (s.start[1] + s.end[1]) / 2) for s in cuts]
    worst = max(p.deviation(m) for m in mids)
    assert worst == pytest.approx(10 * (1 - math.cos(math.radians(2.5))), abs=1e-9)
    assert worst <= p.tolerance
    assert p.deviation((30, 30)) == pytest.approx(20.0)  # the middle of the piece
    arc = Arc((40, 20), (40, 10), math.pi / 2)
    inside = (40 + 10 * math.cos(-1.0), 20 + 10 * math.sin(-1.0))  # on the circle, in the sweep
    outside = (40 + 10 * math.cos(4.0), 20 + 10 * math.sin(4.0))  # on the circle, not
    assert distance_to(arc, inside) < 1e-12
    assert distance_to(arc, outside) == pytest.approx(distance(outside, (40, 10)))
    cw = Arc((40, 20), (50, 20), -math.pi / 2)  # the same quarter, clockwise
    assert distance_to(cw, inside) < 1e-12
    assert distance_to(cw, outside) == pytest.approx(distance(outside, (40, 10)))


def test_deviation_from_a_newton_curve():
    p = load_piece(PIECES / "newton5.toml")
    c = NewtonCurve((0, 10, 20, 30, 40), (0, 5, 3, 8, 2))
    for x in (0.0, 7.3, 21.1, 33.472, 40.0):
        assert p.deviation((x, c(x))) < 1e-9
        h = 1e-6
        slope = (c(x + h) - c(x - h)) / (2 * h)
        n = (-slope / math.hypot(1, slope), 1 / math.hypot(1, slope))
        off = (x + 0.05 * n[0], c(x) + 0.05 * n[1])
        assert p.deviation(off) == pytest.approx(0.05, abs=1e-4)  # curvature is small


def test_command_line_values_override_a_toml_piece(tmp_path, capsys):
    assert main(["cut", str(PIECES / "achaflanado.toml"), "--dry-run", "--tolerance", "0.5"]) == 0
    assert "17 segments (16 cut)" in capsys.readouterr().out  # 4 chords per quarter arc
    assert main(["cut", str(PIECES / "achaflanado.toml"), "--dry-run", "--work-area",
                 "30x60"]) == 1
    assert "outside the 30 x 60 mm work area" in capsys.readouterr().err
    assert main(["cut", str(PIECES / "rounded_rectangle.gcode"), "--dry-run", "--speed",
                 "0"]) == 1
    assert "speed must be a positive number" in capsys.readouterr().err


def test_seed_mode_error_names_the_op():
    p = piece_from_dict({"op": [{"kind": "move", "to": [10, 10]},
                                {"kind": "circle", "centre": [10, 10], "radius": 0.05}]})
    assert len(p.segments()) > 3  # the corrected arc is fine
    with pytest.raises(PieceError, match=r"op\[1\]: thesis arc step: asin"):
        p.segments(seed=True)


def test_the_docs_piece_example_loads():
    import tomllib

    from docs_util import fenced, page

    block = fenced(page("docs/machines/cutting-table.md"),
                   "A piece file (`ladder_programs/pieces/*.toml`", "toml")
    p = piece_from_dict(tomllib.loads(block), "docs/machines/cutting-table.md")
    kinds = [s.kind for s in p.segments()]
    assert kinds[0] == "move" and kinds.count("move") == 2  # to the contour, to the circle
    arcs = [e.shape for e in p.elements if isinstance(e.shape, Arc)]
    assert len(arcs) == 5 and arcs[-1].full_circle and arcs[-1].sweep < 0
    # the contour: 4 sides shortened by the fillets + 4 quarter arcs of radius 5
    contour = 2 * (50 - 10) + 2 * (30 - 10) + 2 * math.pi * 5
    assert sum(e.shape.length for e in p.elements if e.cut) == pytest.approx(
        contour + 2 * math.pi * 6)
